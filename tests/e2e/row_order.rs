//! Results do not depend on the row order or the file layout (issue 13, item 4): the campaign
//! format allows unsorted rows, and a logger of many bars writes them interleaved.

use dbbcal::io::WriteOptions;
use dbbcal::simulate::{FleetConfig, SimConfig};

use crate::support::run_cli;

/// One 1 Hz campaign written four ways (one file per table sorted by bar; day files holding all
/// bars sorted by bar, interleaved by time, shuffled): `dbbcal identify` with no option
/// compresses each into 60-s bins (chosen automatically) and writes byte-identical
/// summary.json, but for its `inputs` record, which lists the files read and their hashes. At
/// full rate (`--bin-s 0`) the shuffled and interleaved layouts give the same bytes too.
#[test]
fn summaries_do_not_depend_on_row_order_or_file_layout() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = SimConfig {
        seed: 13,
        campaign_id: "row-order".into(),
        duration_days: 2.0,
        sample_s: 1.0,
        noise_um: 0.02,
        fleet: Some(FleetConfig {
            n_bars: 3,
            ..FleetConfig::default()
        }),
        ..SimConfig::default()
    };
    let sim = dbbcal::simulate::generate(&cfg).expect("simulate");
    let day_files = |interleave_rows: bool, shuffle_rows: bool| WriteOptions {
        split_by_day: true,
        interleave_rows,
        shuffle_rows,
        seed: 5,
        ..WriteOptions::default()
    };
    let layouts = [
        ("one-file", WriteOptions::default()),
        ("by-bar", day_files(false, false)),
        ("interleaved", day_files(true, false)),
        ("shuffled", day_files(false, true)),
    ];
    let mut summaries = Vec::new();
    for (name, opts) in &layouts {
        let dir = tmp.path().join(name);
        dbbcal::simulate::write(&sim, &dir, opts).expect("write");
        let mut runs = vec![(None, tmp.path().join(format!("{name}-auto")))];
        if *name != "by-bar" {
            runs.push((Some("0"), tmp.path().join(format!("{name}-full"))));
        }
        for (bin_s, out) in runs {
            let (dir_s, out_s) = (dir.to_str().unwrap(), out.to_str().unwrap());
            let mut args = vec!["identify", "--campaign", dir_s, "--out", out_s];
            if let Some(b) = bin_s {
                args.extend(["--bin-s", b]);
            }
            let (code, _, stderr) = run_cli(&args);
            assert_eq!(code, 0, "{name}: {stderr}");
            let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
            let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
            let inputs = json.as_object_mut().unwrap().remove("inputs").unwrap();
            let encoder_files = inputs
                .as_array()
                .unwrap()
                .iter()
                .filter(|f| f["path"].as_str().unwrap().starts_with("encoders/"))
                .count();
            assert_eq!(
                encoder_files > 1,
                *name != "one-file",
                "{name}: {encoder_files}"
            );
            let expected_bin = if bin_s.is_some() { 0.0 } else { 60.0 };
            assert_eq!(json["model"]["bin_s"], expected_bin, "{name}");
            summaries.push((
                format!("{name} bin_s {expected_bin}"),
                bin_s.is_some(),
                serde_json::to_string_pretty(&json).unwrap(),
            ));
        }
    }
    for full_rate in [false, true] {
        let mut these = summaries.iter().filter(|(_, f, _)| *f == full_rate);
        let (first_name, _, first) = these.next().unwrap();
        for (name, _, text) in these {
            assert!(
                text == first,
                "{name} differs from {first_name}:\n{text}\nvs\n{first}"
            );
        }
    }
}
