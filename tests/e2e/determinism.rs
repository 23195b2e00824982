//! Determinism across thread counts (issue 14): the nightly pipeline on the shipped sample with
//! 1, 2 and 3 rayon threads writes byte-identical JSON, parquet and PNG files (and so do the
//! matching-study and acceptance pipelines: heat map, calibration, compensation).

use crate::corpus::snapshot;
use crate::support::run_cli_env;

#[test]
fn outputs_are_byte_identical_for_any_thread_count() {
    check("nightly", 3);
}

#[test]
fn study_and_acceptance_outputs_are_byte_identical_for_any_thread_count() {
    check("reference-match", 1);
    check("acceptance", 1);
}

/// `pipelines/<name>.toml` on the shipped sample with 1, 2 and 3 threads: the same files, byte
/// for byte; at least `min_png` figures.
fn check(name: &str, min_png: usize) {
    let tmp = tempfile::tempdir().unwrap();
    let pipeline = format!("pipelines/{name}.toml");
    let mut runs = Vec::new();
    let mut codes = Vec::new();
    for threads in ["1", "2", "3"] {
        let out = tmp.path().join(format!("threads-{threads}"));
        let (code, _, stderr) = run_cli_env(
            &["run", &pipeline, "--out", out.to_str().unwrap()],
            &[("RAYON_NUM_THREADS", threads)],
        );
        assert!(
            code == 0 || code == 2,
            "{name}, {threads} thread(s): {stderr}"
        );
        codes.push(code);
        runs.push((threads, snapshot(&out)));
    }
    assert!(
        codes.iter().all(|c| *c == codes[0]),
        "{name}: exit codes {codes:?}"
    );
    let (_, first) = &runs[0];
    let kinds = |ext: &str| {
        first
            .keys()
            .filter(|p| p.extension().is_some_and(|e| e == ext))
            .count()
    };
    assert!(kinds("json") >= 2, "{name}: {:?}", first.keys());
    assert!(kinds("parquet") >= 1, "{name}: {:?}", first.keys());
    assert!(kinds("png") >= min_png, "{name}: {:?}", first.keys());
    for (threads, files) in &runs[1..] {
        assert_eq!(
            files.keys().collect::<Vec<_>>(),
            first.keys().collect::<Vec<_>>(),
            "{name}, {threads} threads: other files"
        );
        let differ: Vec<_> = files
            .iter()
            .filter(|(path, bytes)| first[*path] != **bytes)
            .map(|(path, _)| path.display().to_string())
            .collect();
        assert!(
            differ.is_empty(),
            "{name}, {threads} threads against 1: these files differ: {differ:?}"
        );
    }
}
