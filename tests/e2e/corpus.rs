//! The bad-input corpus harness (issue 14): a refused run exits with its code, says one line that
//! names what and where, leaves no output or partial folder behind, and leaves an earlier output
//! byte-for-byte as it was.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::support::run_cli;

/// Every file under `dir` (relative path → bytes); empty when `dir` does not exist.
pub(crate) fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, files: &mut BTreeMap<PathBuf, Vec<u8>>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let path = e.path();
            let rel = path.strip_prefix(root).unwrap().to_path_buf();
            let special = std::fs::metadata(&path).is_ok_and(|m| !m.is_file() && !m.is_dir());
            if special {
                // A FIFO or device is never read (a FIFO would block): its kind stands for it.
                files.insert(rel, b"<not a regular file>".to_vec());
            } else if path.is_dir() {
                walk(root, &path, files);
            } else {
                files.insert(rel, std::fs::read(&path).unwrap_or_default());
            }
        }
    }
    let mut files = BTreeMap::new();
    if dir.is_file() {
        files.insert(PathBuf::new(), std::fs::read(dir).unwrap_or_default());
    } else {
        walk(dir, dir, &mut files);
    }
    files
}

/// Copy the folder `from` to `to` (which must not exist).
pub(crate) fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let target = to.join(e.file_name());
        if e.path().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), &target).unwrap();
        }
    }
}

/// A real output folder of an earlier, successful run (`dbbcal ingest` on the shipped sample),
/// made once per test process.
pub(crate) fn earlier_output() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = tempfile::tempdir().unwrap().keep();
        let out = root.join("earlier");
        let (code, _, stderr) = run_cli(&[
            "ingest",
            "--campaign",
            "data/sample",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "earlier output: {stderr}");
        out
    })
}

/// Names in `dir` that look like leftovers of a run (partial folders, old outputs, locks).
pub(crate) fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.contains(".partial") || n.contains(".old-") || n.ends_with(".lock"))
                .collect()
        })
        .unwrap_or_default()
}

/// Run `command` on `campaign` with `--out` a sibling folder `<campaign>-out` that holds an
/// earlier output; expect exit `code`, exactly one non-empty stderr line containing every
/// `needles`, no panic, the earlier output unchanged byte for byte and no leftovers beside it.
pub(crate) fn check_refused(campaign: &Path, command: &[&str], code: i32, needles: &[&str]) {
    let name = campaign.file_name().unwrap().to_str().unwrap();
    let out = campaign.parent().unwrap().join(format!("{name}-out"));
    let _ = std::fs::remove_dir_all(&out);
    copy_dir(earlier_output(), &out);
    let before = snapshot(&out);
    let campaign_before = snapshot(campaign);
    let mut args = command.to_vec();
    args.extend([
        "--campaign",
        campaign.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let (got, _stdout, stderr) = run_cli(&args);
    let what = format!("{} on {}", command.join(" "), campaign.display());
    assert_eq!(got, code, "exit code of {what}: stderr {stderr}");
    assert_one_line(&stderr, needles, &what);
    assert!(
        snapshot(&out) == before,
        "{what}: the earlier output changed"
    );
    assert!(
        snapshot(campaign) == campaign_before,
        "{what}: the campaign changed"
    );
    assert_no_leftovers(campaign.parent().unwrap(), &what);
}

/// No partial folder, old output or lock is left in `dir`.
pub(crate) fn assert_no_leftovers(dir: &Path, what: &str) {
    let left = leftovers(dir);
    assert!(left.is_empty(), "{what}: leftovers {left:?}");
}

/// `stderr` is one non-empty line holding every `needles`, and no panic.
pub(crate) fn assert_one_line(stderr: &str, needles: &[&str], what: &str) {
    assert!(!stderr.contains("panicked"), "{what}: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{what}: one line expected, got: {stderr}");
    for n in needles {
        assert!(
            lines[0].contains(n),
            "{what}: {n:?} missing from: {}",
            lines[0]
        );
    }
}
