//! The `axis` machine kind end to end (issue 29): `dbbcal simulate` with
//! `pipelines/sim-axis.toml` writes an axis campaign that `io::read_axis_campaign` reads back
//! whole, with the truth beside it.

use crate::support::run_cli;

#[test]
fn simulate_writes_an_axis_campaign_that_reads_back() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("axis");
    let out_arg = out.display().to_string();
    let (code, stdout, stderr) = run_cli(&[
        "simulate",
        "--config",
        "pipelines/sim-axis.toml",
        "--out",
        &out_arg,
    ]);
    assert_eq!(code, 0, "stdout: {stdout}\nstderr: {stderr}");
    for file in [
        "campaign.toml",
        "readings/readings.parquet",
        "fixture/fixture.parquet",
        "environment/environment.parquet",
        "truth.json",
        "truth/axis_truth.parquet",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    let text = std::fs::read_to_string(out.join("campaign.toml")).unwrap();
    assert_eq!(
        dbbcal::axis_campaign::campaign_kind(&text, "campaign.toml").unwrap(),
        dbbcal::axis_campaign::CampaignKind::Axis
    );
    let logs = dbbcal::io::read_axis_campaign(&out).unwrap();
    assert_eq!(logs.campaign.id, "sim-axis");
    assert_eq!(logs.campaign.line_ids(), [1, 2, 3]);
    // 6 channels over 3 lines, 5 runs up and down, 15 targets.
    assert_eq!(logs.readings.len(), 6 * 5 * 2 * 15);
    assert_eq!(logs.environment.len(), 3 * 5 * 2 * 15);
    assert!(logs.inputs.iter().all(|f| !f.path.starts_with("truth")));
    // The same seed gives the same campaign; another seed another.
    let again = tmp.path().join("again");
    let again_arg = again.display().to_string();
    let (code, ..) = run_cli(&[
        "simulate",
        "--config",
        "pipelines/sim-axis.toml",
        "--out",
        &again_arg,
    ]);
    assert_eq!(code, 0);
    assert_eq!(
        dbbcal::io::read_axis_campaign(&again).unwrap().readings,
        logs.readings
    );
    // The axis reader refuses a ballbar campaign, by name.
    let e = dbbcal::io::read_axis_campaign(&crate::support::root().join("data/sample"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("is a ballbar campaign"), "{e}");
}
