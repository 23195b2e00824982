//! Issue 16: the report page (`index.html`), the fit report (`report.md`), `dbbcal show` and the
//! command line's closing block, on a campaign with a hidden effect (head heating), and the page
//! in a real browser (headless Chromium, when installed).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use dbbcal::simulate::{FleetConfig, SimConfig};

use crate::support::{run_cli, run_pipeline_ok, sim_config, simulate_campaign};

/// A 2-bar, 3-day campaign with head heating, run through `pipelines/nightly.toml` once per
/// test process: (campaign, output, stderr of the run).
fn night() -> &'static (PathBuf, PathBuf, String) {
    static NIGHT: OnceLock<(PathBuf, PathBuf, String)> = OnceLock::new();
    NIGHT.get_or_init(|| {
        let root = tempfile::tempdir().unwrap().keep();
        let mut cfg: SimConfig = sim_config("pipelines/sim-sample.toml");
        cfg.campaign_id = "page-night".into();
        cfg.duration_days = 3.0;
        cfg.fleet = Some(FleetConfig {
            n_bars: 2,
            ..FleetConfig::default()
        });
        cfg.effects.head_heating.enabled = true;
        let (campaign, _) = simulate_campaign(&root, "campaign", &cfg);
        let out = root.join("night");
        let stderr = run_night(&campaign, &out);
        (campaign, out, stderr)
    })
}

/// `dbbcal run pipelines/nightly.toml` on `campaign` into `out`; its stderr.
fn run_night(campaign: &Path, out: &Path) -> String {
    let (code, _, stderr) = run_cli(&[
        "run",
        "pipelines/nightly.toml",
        "--campaign",
        campaign.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    stderr
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_page_opens_with_the_verdict_and_the_command_that_adds_the_effect() {
    let (campaign, out, _) = night();
    let page = read(&out.join("index.html"));
    assert!(
        page.contains("missing effect: head_heating; adding it cuts the fleet RMS from"),
        "verdict missing"
    );
    let command = format!(
        "dbbcal run pipelines/nightly.toml --campaign {} --out {} --add-effect head_heating",
        campaign.display(),
        out.display()
    );
    assert!(
        page.contains(&format!("<code>{command}</code>")),
        "command missing"
    );
    // Sections in the order a reader needs them.
    let at = |needle: &str| {
        page.find(needle)
            .unwrap_or_else(|| panic!("{needle} missing"))
    };
    let order = [
        "id=\"night\"",
        "id=\"bars\"",
        "id=\"loop\"",
        "id=\"figures\"",
        "id=\"fit-report\"",
        "id=\"provenance\"",
    ];
    assert!(
        order.windows(2).all(|w| at(w[0]) < at(w[1])),
        "section order"
    );
    // A row per bar with its parameters ± U (k = 2), every figure referenced exists.
    for bar in ["B01", "B02"] {
        assert!(page.contains(&format!("<tr><td>{bar}</td>")), "{bar} row");
        assert!(page.contains(&format!("figures/bar-{bar}.png")));
    }
    for src in page.split("src=\"").skip(1) {
        let file = &src[..src.find('"').unwrap()];
        assert!(out.join(file).is_file(), "{file} referenced but absent");
    }
    // Self-contained: nothing fetched from elsewhere.
    for needle in ["http://", "https://", "<script src", "<link"] {
        assert!(!page.contains(needle), "{needle} in the page");
    }
    // Provenance: every input file's sha256.
    let inputs: serde_json::Value = serde_json::from_str(&read(&out.join("inputs.json"))).unwrap();
    for f in inputs.as_array().unwrap() {
        assert!(page.contains(f["sha256"].as_str().unwrap()));
    }
}

#[test]
fn the_fit_report_reads_like_lmfit_and_show_prints_it() {
    let (_, out, _) = night();
    let report = read(&out.join("report.md"));
    for bar in ["B01", "B02"] {
        assert!(report.contains(&format!("## Bar {bar}")));
    }
    for needle in [
        "[[Fit statistics]]",
        "data points",
        "BIC",
        "[[Variables]]",
        "alpha_ppm_per_k",
        "95 %: [",
        "whiteness p",
    ] {
        assert!(report.contains(needle), "{needle} missing from report.md");
    }
    let (code, stdout, stderr) = run_cli(&["show", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(stdout.trim_end(), report.trim_end());
    assert!(!stdout.contains('\x1b'), "colour written into a pipe");
    let (code, _, stderr) = run_cli(&["show", "/nonexistent"]);
    assert_eq!(code, 1);
    assert!(stderr.contains("no fit report here"), "{stderr}");
}

#[test]
fn the_command_line_says_where_the_output_went_and_what_to_do_next() {
    let (_, out, stderr) = night();
    for needle in [
        "Finished",
        &format!("Output {}", out.display()),
        "Diagnosis missing effect: head_heating",
        "Next dbbcal run pipelines/nightly.toml",
    ] {
        assert!(stderr.contains(needle), "{needle:?} missing from: {stderr}");
    }
    assert!(
        !stderr.contains('\x1b'),
        "colour written into a pipe: {stderr}"
    );
    // -q: silent on success.
    let tmp = tempfile::tempdir().unwrap();
    let o = tmp.path().join("q");
    let (code, stdout, stderr) = run_cli(&["-q", "ingest", "--out", o.to_str().unwrap()]);
    assert_eq!(code, 0);
    assert!(stdout.is_empty() && stderr.is_empty(), "{stdout}{stderr}");
    // --help lists every exit code; completions are generated.
    let (_, help, _) = run_cli(&["--help"]);
    for code in ["0 ", "1 ", "2 ", "3 ", "4 ", "5 ", "6 ", "130"] {
        assert!(
            help.contains(&format!("\n  {code}")),
            "exit code {code} not in --help"
        );
    }
    let (code, script, _) = run_cli(&["completions", "bash"]);
    assert_eq!(code, 0);
    assert!(script.contains("dbbcal") && script.contains("--add-effect"));
    let (code, _, _) = run_cli(&["--no-such-flag"]);
    assert_eq!(code, 2, "a usage error exits 2, not a code of a run");
}

#[test]
fn page_and_report_are_byte_identical_across_runs() {
    let (campaign, out, _) = night();
    // The same --out string, so the command lines in the page are the same: rerun in place.
    let before = (read(&out.join("index.html")), read(&out.join("report.md")));
    run_night(campaign, out);
    let after = (read(&out.join("index.html")), read(&out.join("report.md")));
    assert!(
        before == after,
        "the page or the report changed between identical runs"
    );
}

/// Chromium from the distribution, if installed.
fn chromium() -> Option<PathBuf> {
    ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
}

fn headless(profile: &Path) -> Command {
    let mut c = Command::new(chromium().unwrap());
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--allow-file-access-from-files",
        "--enable-logging=stderr",
        "--v=0",
        "--virtual-time-budget=10000",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

#[test]
fn the_page_in_a_real_browser_loads_every_figure_and_prints_on_a4() {
    let Some(browser) = chromium() else {
        eprintln!("SKIPPED the_page_in_a_real_browser: no chromium (apt-get install chromium)");
        return;
    };
    let (_, out, _) = night();
    let tmp = tempfile::tempdir().unwrap();
    // A harness page opens the report in a frame and writes what loaded into its own DOM.
    let harness = tmp.path().join("harness.html");
    let page_url = format!("file://{}", out.join("index.html").display());
    std::fs::write(
        &harness,
        format!(
            r#"<!doctype html><html><body><iframe id="f" src="{page_url}" width="1200" height="900"></iframe>
<pre id="result">pending</pre>
<script>
document.getElementById("f").addEventListener("load", () => {{
  const doc = document.getElementById("f").contentDocument;
  const imgs = Array.from(doc.images);
  const broken = imgs.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.getAttribute("src"));
  document.getElementById("result").textContent =
    "images=" + imgs.length + " broken=" + JSON.stringify(broken) + " title=" + doc.title;
}});
</script></body></html>"#
        ),
    )
    .unwrap();
    let r = headless(&tmp.path().join("profile-dom"))
        .arg("--dump-dom")
        .arg(format!("file://{}", harness.display()))
        .output()
        .expect("run chromium");
    let dom = String::from_utf8_lossy(&r.stdout);
    let log = String::from_utf8_lossy(&r.stderr);
    assert!(
        dom.contains("broken=[]"),
        "{}: broken figures or no load: {}",
        browser.display(),
        dom.lines().find(|l| l.contains("result")).unwrap_or(&dom)
    );
    let images: usize = dom
        .split("images=")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap();
    let files = std::fs::read_dir(out.join("figures")).unwrap().count();
    assert_eq!(images, files, "every figure is on the page");
    // The page has no script: any console message (Chromium logs them as `INFO:CONSOLE`,
    // errors included) is a fault.
    let console: Vec<&str> = log.lines().filter(|l| l.contains(":CONSOLE")).collect();
    assert!(console.is_empty(), "console messages: {console:?}");
    // Print to PDF: A4 pages (595 × 842 pt), the fit report on a page of its own.
    let pdf = tmp.path().join("page.pdf");
    let r = headless(&tmp.path().join("profile-pdf"))
        .arg("--no-pdf-header-footer")
        .arg(format!("--print-to-pdf={}", pdf.display()))
        .arg(&page_url)
        .output()
        .expect("run chromium");
    assert!(pdf.is_file(), "{}", String::from_utf8_lossy(&r.stderr));
    let bytes = std::fs::read(&pdf).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    // One media box per page (Chromium writes them uncompressed), each A4: 595.28 × 841.89 pt.
    let boxes: Vec<Vec<f64>> = text
        .split("/MediaBox [")
        .skip(1)
        .map(|s| {
            s[..s.find(']').unwrap()]
                .split_whitespace()
                .map(|v| v.parse().unwrap())
                .collect()
        })
        .collect();
    let pages = boxes.len();
    assert!(
        boxes
            .iter()
            .all(|b| (b[2] - 595.3).abs() < 1.0 && (b[3] - 841.9).abs() < 1.0),
        "not A4: {boxes:?}"
    );
    // Expected: the headline, bars and loop (1–2 pages), 1–2 figures a page, the fit report
    // from a new page (about a page for two bars), provenance.
    let lower = 2 + files / 3;
    let upper = 4 + files + 4;
    assert!(
        (lower..=upper).contains(&pages),
        "{pages} pages printed, expected {lower}..={upper} for {files} figures"
    );
}

#[test]
fn acceptance_with_nothing_to_accept_says_why() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("acc");
    let stderr = run_pipeline_ok("pipelines/acceptance.toml", &out);
    assert!(
        stderr.contains("nothing to accept") && stderr.contains("purpose = \"check\""),
        "{stderr}"
    );
    let page = read(&out.join("index.html"));
    assert!(
        page.contains("Nothing to accept"),
        "the page does not say why"
    );
}

#[test]
fn the_fit_report_warns_when_bins_are_coarse_for_a_time_constant() {
    let tmp = tempfile::tempdir().unwrap();
    // The sample's time constants, 1 100-3 400 s, span fewer than 10 bins of 600 s (bins longer
    // than the automatic 60 s are held to 10), and at least 2 of 60 s.
    for (bin_s, warned) in [("600", true), ("60", false), ("0", false)] {
        let out = tmp.path().join(format!("bins-{bin_s}"));
        let (code, _, stderr) = run_cli(&[
            "-q",
            "identify",
            "--out",
            out.to_str().unwrap(),
            "--bin-s",
            bin_s,
        ]);
        assert_eq!(code, 0, "{stderr}");
        let report = read(&out.join("report.md"));
        assert_eq!(
            report.contains("spans fewer than"),
            warned,
            "--bin-s {bin_s}"
        );
        if warned {
            assert!(
                report.contains(&format!("spans fewer than 10 bins of {bin_s} s")),
                "--bin-s {bin_s}"
            );
        }
    }
}
