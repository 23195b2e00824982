//! Issue 14, outputs: dbbcal never touches what it did not write, and a run killed, interrupted
//! or short of disk at any step leaves `OUT` entirely old or entirely new.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use dbbcal::io::{write_table, Column, Table};
use dbbcal::simulate::{FleetConfig, SimConfig};

use crate::corpus::{
    assert_no_leftovers, assert_one_line, copy_dir, earlier_output, leftovers, snapshot,
};
use crate::support::simulate_campaign;

/// The `dbbcal` binary with `args` and extra environment `env`.
fn dbbcal(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .args(args)
        .envs(env.iter().copied())
        .current_dir(crate::support::root())
        .env("CI", "1")
        .output()
        .expect("run dbbcal")
}

/// One day, two bars, a reading every 2 min: quick to run many times.
fn small_config(name: &str) -> SimConfig {
    SimConfig {
        seed: 7,
        campaign_id: name.into(),
        duration_days: 1.0,
        sample_s: 120.0,
        fleet: Some(FleetConfig {
            n_bars: 2,
            ..FleetConfig::default()
        }),
        ..SimConfig::default()
    }
}

fn small_campaign(root: &Path, name: &str) -> PathBuf {
    simulate_campaign(root, name, &small_config(name)).0
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `args` (with `--campaign campaign --out out` appended) is refused with exit `code` and one
/// line holding `needles`; every path in `guarded` is byte-for-byte as before.
fn check_out_refused(
    command: &[&str],
    campaign: &Path,
    out: &Path,
    env: &[(&str, &str)],
    code: i32,
    needles: &[&str],
    guarded: &[&Path],
) {
    let before: Vec<_> = guarded.iter().map(|p| snapshot(p)).collect();
    let mut args = command.to_vec();
    args.extend(["--campaign", s(campaign), "--out", s(out)]);
    let r = dbbcal(&args, env);
    let stderr = String::from_utf8_lossy(&r.stderr);
    let what = format!("--out {}", out.display());
    assert_eq!(r.status.code(), Some(code), "{what}: {stderr}");
    assert_one_line(&stderr, needles, &what);
    for (p, b) in guarded.iter().zip(before) {
        assert!(snapshot(p) == b, "{what}: {} changed", p.display());
    }
}

#[test]
fn output_locations_dbbcal_did_not_write_are_refused_before_any_work() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let c = small_campaign(root, "camp");
    let ingest = ["ingest"];
    let refused = |out: &Path, needles: &[&str], guarded: &[&Path]| {
        check_out_refused(&ingest, &c, out, &[], 3, needles, guarded)
    };
    // The campaign itself, a folder inside it, its parent, the same through `..` and a link.
    refused(&c, &["refused", "campaign folder"], &[&c]);
    refused(&c.join("reports"), &["inside the campaign"], &[&c]);
    refused(root, &["holds the campaign"], &[&c]);
    refused(&c.join("encoders/.."), &["refused"], &[&c]);
    refused(&root.join("nothere/../camp"), &["campaign folder"], &[&c]);
    refused(&c.join("encoders/../out"), &["inside the campaign"], &[&c]);
    std::os::unix::fs::symlink(&c, root.join("link-to-camp")).unwrap();
    refused(
        &root.join("link-to-camp/out"),
        &["inside the campaign"],
        &[&c],
    );
    // A link, even to an earlier output.
    let earlier = root.join("earlier");
    copy_dir(earlier_output(), &earlier);
    std::os::unix::fs::symlink(&earlier, root.join("link-out")).unwrap();
    refused(
        &root.join("link-out"),
        &["symbolic link"],
        &[&earlier, &root.join("link-out")],
    );
    // A user's folder, a file, and an OUT.prev that is not dbbcal's.
    let user = root.join("thesis");
    std::fs::create_dir(&user).unwrap();
    std::fs::write(user.join("chapter1.tex"), "weeks of work").unwrap();
    refused(&user, &["thesis", "did not write"], &[&user]);
    let file = root.join("notes.txt");
    std::fs::write(&file, "notes").unwrap();
    refused(&file, &["notes.txt", "is a file"], &[&file]);
    let out = root.join("night");
    copy_dir(earlier_output(), &out);
    let prev = root.join("night.prev");
    std::fs::create_dir(&prev).unwrap();
    std::fs::write(prev.join("keep.txt"), "mine").unwrap();
    refused(&out, &["night.prev", "did not write"], &[&out, &prev]);
    // The working folder, the root, the home folder.
    refused(Path::new("."), &["refused"], &[]);
    refused(Path::new("/"), &["refused"], &[]);
    let home = root.join("home");
    std::fs::create_dir(&home).unwrap();
    std::fs::write(home.join(".profile"), "x").unwrap();
    check_out_refused(
        &ingest,
        &c,
        &home,
        &[("HOME", s(&home))],
        3,
        &["home folder"],
        &[&home],
    );
    assert!(leftovers(root).is_empty(), "{:?}", leftovers(root));
}

#[test]
fn a_second_run_on_a_locked_output_refuses_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let out = tmp.path().join("out");
    copy_dir(earlier_output(), &out);
    let lock = std::fs::File::create(tmp.path().join(".out.lock")).unwrap();
    lock.try_lock().unwrap();
    check_out_refused(
        &["identify"],
        &c,
        &out,
        &[],
        6,
        &["another dbbcal run", ".out.lock"],
        &[&out],
    );
    drop(lock);
}

#[test]
fn replacing_keeps_one_previous_output_and_cleans_dead_partials() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let out = tmp.path().join("out");
    let run = |extra: &[&str]| {
        let mut args = vec!["identify", "--campaign", s(&c), "--out", s(&out)];
        args.extend(extra);
        let r = dbbcal(&args, &[]);
        assert_eq!(
            r.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&r.stderr)
        );
        snapshot(&out)
    };
    // A dead run's partial folder (marker inside), an empty one, and a user's look-alike.
    let dead = tmp.path().join(".out.partial-4000000");
    copy_dir(earlier_output(), &dead);
    std::fs::create_dir(tmp.path().join(".out.partial-4000001")).unwrap();
    let mine = tmp.path().join(".out.partial-mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("x"), "x").unwrap();
    let first = run(&[]);
    assert!(first.contains_key(Path::new(dbbcal::output::MARKER)));
    assert!(!dead.exists() && !tmp.path().join(".out.partial-4000001").exists());
    assert!(mine.exists(), "a folder dbbcal did not write was removed");
    let second = run(&["--bin-s", "600"]);
    assert!(first != second);
    assert!(snapshot(&tmp.path().join("out.prev")) == first);
    run(&[]);
    assert!(snapshot(&tmp.path().join("out.prev")) == second);
    assert_eq!(leftovers(tmp.path()), vec![".out.partial-mine".to_string()]);
}

#[test]
fn a_run_where_no_bar_succeeds_keeps_the_previous_output() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    // Three readings a bar: too few for any model.
    let ns = 1_793_491_200_000_000_000i64;
    for f in std::fs::read_dir(c.join("encoders")).unwrap() {
        std::fs::remove_file(f.unwrap().path()).unwrap();
    }
    let times: Vec<i64> = (0..3).map(|k| ns + k * 60_000_000_000).collect();
    let table = Table::new()
        .with("time", Column::TimeNs([times.clone(), times].concat()))
        .with(
            "bar",
            Column::Str(
                ["B01", "B01", "B01", "B02", "B02", "B02"]
                    .map(String::from)
                    .to_vec(),
            ),
        )
        .with("counts", Column::I64(vec![1, 2, 3, 1, 2, 3]));
    write_table(&c.join("encoders/few.parquet"), &table).unwrap();
    let out = tmp.path().join("out");
    copy_dir(earlier_output(), &out);
    check_out_refused(
        &["identify"],
        &c,
        &out,
        &[],
        5,
        &[
            "no bar succeeded",
            "B01: no readings",
            "B02: no readings",
            "unchanged",
        ],
        &[&out],
    );
    assert_no_leftovers(tmp.path(), "no bar succeeded");
}

/// The clean result of `identify` + figures on the campaign `c` (with `--out` `fresh`).
fn reference_output(c: &Path, fresh: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let r = dbbcal(&["report", "--campaign", s(c), "--out", s(fresh)], &[]);
    assert_eq!(
        r.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    snapshot(fresh)
}

#[test]
fn killed_at_any_write_step_the_output_is_entirely_old_or_entirely_new() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let new = reference_output(&c, &tmp.path().join("fresh"));
    let old = snapshot(earlier_output());
    let out = tmp.path().join("out");
    let (mut killed, mut saw_new) = (0, false);
    for k in 1..200 {
        let _ = std::fs::remove_dir_all(&out);
        let _ = std::fs::remove_dir_all(tmp.path().join("out.prev"));
        copy_dir(earlier_output(), &out);
        let fault = format!("kill@{k}");
        let args = ["report", "--campaign", s(&c), "--out", s(&out)];
        let r = dbbcal(&args, &[("DBBCAL_FAULT", &fault)]);
        let now = snapshot(&out);
        let now_prev = snapshot(&tmp.path().join("out.prev"));
        assert!(
            now == old || now == new,
            "{fault}: OUT is neither old nor new"
        );
        // The old output is never lost: in OUT, or kept in OUT.prev.
        assert!(
            now == old || now_prev == old,
            "{fault}: the old output is in neither OUT nor OUT.prev"
        );
        assert!(
            now_prev.is_empty() || now_prev == old || now_prev == new,
            "{fault}: OUT.prev is neither absent, old nor new"
        );
        saw_new |= now == new;
        if r.status.code().is_some() {
            assert_eq!(
                r.status.code(),
                Some(0),
                "{fault}: {}",
                String::from_utf8_lossy(&r.stderr)
            );
            break; // past the last point: the run finished
        }
        killed += 1;
        // The rerun cleans up after the dead run and gives the clean result.
        let r = dbbcal(&args, &[]);
        assert_eq!(r.status.code(), Some(0), "rerun after {fault}");
        assert!(
            snapshot(&out) == new,
            "rerun after {fault} differs from a clean run"
        );
        assert_no_leftovers(tmp.path(), &fault);
    }
    assert!(killed >= 10, "only {killed} kill points");
    assert!(saw_new);
}

#[test]
fn a_full_disk_at_any_write_step_leaves_the_previous_output_intact() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let new = reference_output(&c, &tmp.path().join("fresh"));
    let old = snapshot(earlier_output());
    // The generation before, when there is one: a third, distinct output.
    let before_old = tmp.path().join("before-old");
    let r = dbbcal(
        &["ingest", "--campaign", s(&c), "--out", s(&before_old)],
        &[],
    );
    assert_eq!(r.status.code(), Some(0));
    let out = tmp.path().join("out");
    let prev = tmp.path().join("out.prev");
    for with_prev in [false, true] {
        let older = if with_prev {
            snapshot(&before_old)
        } else {
            Default::default()
        };
        let mut failed = 0;
        for k in 1..200 {
            let _ = std::fs::remove_dir_all(&out);
            let _ = std::fs::remove_dir_all(&prev);
            copy_dir(earlier_output(), &out);
            if with_prev {
                copy_dir(&before_old, &prev);
            }
            let fault = format!("enospc@{k} (OUT.prev: {with_prev})");
            let args = ["report", "--campaign", s(&c), "--out", s(&out)];
            let r = dbbcal(&args, &[("DBBCAL_FAULT", &format!("enospc@{k}"))]);
            let stderr = String::from_utf8_lossy(&r.stderr);
            if r.status.code() == Some(0) {
                // Past the last point, or at a step after the exchange, where only kills are
                // injected: the new output is in place, the old one kept.
                assert!(snapshot(&out) == new, "{fault}: {stderr}");
                assert!(
                    snapshot(&prev) == old,
                    "{fault}: OUT.prev is not the old output"
                );
                if stderr.contains("kills only") {
                    continue;
                }
                assert!(
                    !stderr.contains("fault point"),
                    "{fault}: exit 0 after an injected error"
                );
                break;
            }
            failed += 1;
            assert_eq!(r.status.code(), Some(1), "{fault}: {stderr}");
            let last = stderr.lines().last().unwrap_or("");
            assert!(
                last.contains("No space left on device"),
                "{fault}: {stderr}"
            );
            assert!(
                snapshot(&out) == old,
                "{fault}: the previous output changed"
            );
            assert!(snapshot(&prev) == older, "{fault}: OUT.prev changed");
            assert_no_leftovers(tmp.path(), &fault);
        }
        assert!(failed >= 10, "only {failed} write steps");
    }
}

#[test]
fn an_interrupted_run_removes_its_partial_folder_and_keeps_the_old_output() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    for (signal, code) in [(libc::SIGINT, 130), (libc::SIGTERM, 143)] {
        let out = tmp.path().join("out");
        let _ = std::fs::remove_dir_all(&out);
        copy_dir(earlier_output(), &out);
        let old = snapshot(&out);
        // Stalled at its third write step, inside the partial folder.
        let child = Command::new(env!("CARGO_BIN_EXE_dbbcal"))
            .args(["report", "--campaign", s(&c), "--out", s(&out)])
            .env("DBBCAL_FAULT", "stall@3")
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let partial = tmp.path().join(format!(".out.partial-{}", child.id()));
        let start = std::time::Instant::now();
        while !partial.join(dbbcal::output::MARKER).exists() {
            assert!(start.elapsed().as_secs() < 30, "no partial folder appeared");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        std::thread::sleep(std::time::Duration::from_millis(200));
        // SAFETY: a signal to our own child.
        unsafe { libc::kill(child.id() as i32, signal) };
        let r = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(code), "{stderr}");
        assert!(stderr.contains("interrupted"), "{stderr}");
        assert!(!partial.exists(), "the partial folder is left");
        assert!(snapshot(&out) == old);
        assert_no_leftovers(tmp.path(), &format!("signal {signal}"));
    }
}

/// The bars B01 and B02 of the small campaign renamed `a` and `b`, run through `report`: exit 0
/// and two `bar-*.png` figures (W4: hostile ids that collided; H5: an id too long for a file
/// name, which failed every report at its write step).
fn two_bar_figures(root: &Path, case: &str, a: &str, b: &str) {
    let mut sim = dbbcal::simulate::generate(&small_config("names")).unwrap();
    let rename = |id: &str| match id {
        "B01" => a.to_string(),
        "B02" => b.to_string(),
        other => other.to_string(),
    };
    use dbbcal::io::manifest::TomlManifest;
    let text = sim.manifest.to_toml_string().unwrap();
    let text = text
        .replace("\"B01\"", &format!("\"{a}\""))
        .replace("\"B02\"", &format!("\"{b}\""));
    sim.manifest = dbbcal::campaign::Manifest::from_toml_str(&text, "campaign.toml").unwrap();
    let encoders = std::mem::take(&mut sim.tables.encoders);
    sim.tables.encoders = encoders.into_iter().map(|(k, v)| (rename(&k), v)).collect();
    for e in &mut sim.tables.events {
        e.bar = e.bar.as_deref().map(rename);
    }
    let c = root.join(case);
    dbbcal::simulate::write(&sim, &c, &dbbcal::io::WriteOptions::default()).unwrap();
    let out = root.join(format!("{case}-out"));
    let r = dbbcal(&["report", "--campaign", s(&c), "--out", s(&out)], &[]);
    assert_eq!(
        r.status.code(),
        Some(0),
        "{case}: {}",
        String::from_utf8_lossy(&r.stderr)
    );
    let bars: Vec<String> = std::fs::read_dir(out.join("figures"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("bar-"))
        .collect();
    assert_eq!(bars.len(), 2, "{case}: {bars:?}");
    assert!(bars.iter().all(|n| n.len() < 100), "{case}: {bars:?}");
}

#[test]
fn figure_names_from_bar_ids_never_collide() {
    let tmp = tempfile::tempdir().unwrap();
    two_bar_figures(tmp.path(), "dot-underscore", "B.1", "B_1");
    // `B/1` is written `B_1-` and 8 hex digits of its hash: an id of that form is encoded too.
    two_bar_figures(tmp.path(), "encoded-look-alike", "B/1", "B_1-fb95c374");
    two_bar_figures(tmp.path(), "long", &"B".repeat(252), "B02");
    let out = tmp.path().join("dot-underscore-out");
    assert!(out.join("figures/bar-B.1.png").is_file());
    assert!(out.join("figures/bar-B_1.png").is_file());
}

/// Ctrl-C at whatever moment the run has reached once its lock exists (ingest, fits, writing):
/// exit 130 with the old output (or, after the swap, the new one, and it says so) and no lock or
/// partial folder left, or the run had finished.
#[test]
fn an_interrupt_at_any_moment_leaves_no_lock_and_no_partial_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let out = tmp.path().join("out");
    let mut interrupted = 0;
    for delay_ms in [0u64, 5, 20, 50, 100, 200] {
        let _ = std::fs::remove_dir_all(&out);
        let _ = std::fs::remove_dir_all(tmp.path().join("out.prev"));
        copy_dir(earlier_output(), &out);
        let old = snapshot(&out);
        let child = Command::new(env!("CARGO_BIN_EXE_dbbcal"))
            .args(["report", "--campaign", s(&c), "--out", s(&out)])
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let lock = tmp.path().join(".out.lock");
        let start = std::time::Instant::now();
        while !lock.exists() && start.elapsed().as_secs() < 20 {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        // SAFETY: a signal to our own child.
        unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
        let r = child.wait_with_output().unwrap();
        let what = format!("SIGINT {delay_ms} ms after the lock");
        match r.status.code() {
            Some(130) => {
                interrupted += 1;
                let stderr = String::from_utf8_lossy(&r.stderr);
                if stderr.contains("after the new output was in place") {
                    assert!(out.join(dbbcal::output::MARKER).is_file(), "{what}");
                    assert!(snapshot(&out) != old, "{what}: said new, is old");
                    let prev = snapshot(&tmp.path().join("out.prev"));
                    assert!(prev == old, "{what}: the old output is not in OUT.prev");
                } else {
                    assert!(
                        snapshot(&out) == old,
                        "{what}: the old output changed: {stderr}"
                    );
                }
            }
            Some(0) => {}
            other => panic!(
                "{what}: exit {other:?}: {}",
                String::from_utf8_lossy(&r.stderr)
            ),
        }
        assert_no_leftovers(tmp.path(), &what);
    }
    assert!(interrupted >= 1, "no run was interrupted");
}

/// The analysis runs in a child of the `dbbcal` the user started (`dbbcal::supervise`); the
/// partial folder is named after the latter. The child's pid (the only child of `parent`).
fn analysis_child(parent: u32) -> u32 {
    let start = std::time::Instant::now();
    loop {
        let path = format!("/proc/{parent}/task/{parent}/children");
        let children = std::fs::read_to_string(&path).unwrap_or_default();
        if let Some(pid) = children.split_whitespace().next() {
            return pid.parse().unwrap();
        }
        assert!(start.elapsed().as_secs() < 30, "no child of {parent}");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// Start `report` stalled at its third write step (inside the partial folder) and wait until the
/// partial folder holds the marker; `group`: in a process group of its own (a terminal's job).
fn stalled_run(c: &Path, out: &Path, group: bool) -> (std::process::Child, PathBuf) {
    use std::os::unix::process::CommandExt;
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_dbbcal"));
    cmd.args(["report", "--campaign", s(c), "--out", s(out)])
        .env("DBBCAL_FAULT", "stall@3")
        .stderr(std::process::Stdio::piped());
    if group {
        cmd.process_group(0);
    }
    let child = cmd.spawn().unwrap();
    let partial = out
        .parent()
        .unwrap()
        .join(format!(".out.partial-{}", child.id()));
    let start = std::time::Instant::now();
    while !partial.join(dbbcal::output::MARKER).exists() {
        assert!(start.elapsed().as_secs() < 30, "no partial folder appeared");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::thread::sleep(std::time::Duration::from_millis(200));
    (child, partial)
}

/// `stderr` without the fault injection's own line (`dbbcal: fault point K (...)`).
fn without_fault_line(stderr: &[u8]) -> String {
    String::from_utf8_lossy(stderr)
        .lines()
        .filter(|l| !l.starts_with("dbbcal: fault point"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The OOM killer (or anyone) kills the analysis process with SIGKILL while it writes: the
/// `dbbcal` the user started removes the partial folder and the lock, says one line, exits 1;
/// the old output is unchanged.
#[test]
fn an_analysis_killed_by_sigkill_is_cleaned_up_after_by_its_supervisor() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let out = tmp.path().join("out");
    copy_dir(earlier_output(), &out);
    let old = snapshot(&out);
    let (child, partial) = stalled_run(&c, &out, false);
    let analysis = analysis_child(child.id());
    assert_ne!(analysis, child.id());
    // SAFETY: a signal to a process this test started (through `dbbcal`).
    unsafe { libc::kill(analysis as i32, libc::SIGKILL) };
    let r = child.wait_with_output().unwrap();
    let stderr = without_fault_line(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert_one_line(
        &stderr,
        &["killed (SIGKILL", "the previous output is unchanged"],
        "SIGKILL",
    );
    assert!(!partial.exists(), "the partial folder is left");
    assert!(snapshot(&out) == old);
    assert_no_leftovers(tmp.path(), "SIGKILL to the analysis");
}

/// Ctrl-C (or a hang-up) on a terminal reaches every process of the job, `dbbcal` and its
/// analysis child: exit 130 (129), one line, no partial folder or lock, the old output unchanged.
#[test]
fn a_terminal_interrupt_reaching_both_processes_ends_cleanly() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let out = tmp.path().join("out");
    for (signal, code) in [(libc::SIGINT, 130), (libc::SIGHUP, 129)] {
        let _ = std::fs::remove_dir_all(&out);
        copy_dir(earlier_output(), &out);
        let old = snapshot(&out);
        let (child, partial) = stalled_run(&c, &out, true);
        assert_ne!(analysis_child(child.id()), child.id());
        // SAFETY: a signal to the process group of a process this test started.
        unsafe { libc::kill(-(child.id() as i32), signal) };
        let r = child.wait_with_output().unwrap();
        let stderr = without_fault_line(&r.stderr);
        let what = format!("signal {signal} to the job");
        assert_eq!(r.status.code(), Some(code), "{what}: {stderr}");
        assert_one_line(&stderr, &["interrupted", "unchanged"], &what);
        assert!(!partial.exists(), "{what}: the partial folder is left");
        assert!(snapshot(&out) == old, "{what}");
        assert_no_leftovers(tmp.path(), &what);
    }
}

// ---------------------------------------------------------------- issue 27: round 2

/// `command` on `c` into `out`: (exit code, stderr).
fn run_on(command: &[&str], c: &Path, out: &Path) -> (Option<i32>, String) {
    let mut args = command.to_vec();
    args.extend(["--campaign", s(c), "--out", s(out)]);
    let r = dbbcal(&args, &[]);
    (
        r.status.code(),
        String::from_utf8_lossy(&r.stderr).into_owned(),
    )
}

/// D1: a file of the user's in `OUT` or `OUT.prev` (notes, a signed PDF, a folder) is never
/// moved or removed: every run refuses with one line naming it, however many times it runs.
#[test]
fn a_users_file_in_an_output_folder_survives_any_number_of_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let c = small_campaign(root, "camp");
    let out = root.join("out");
    let prev = root.join("out.prev");
    let cases: [(&Path, &str); 4] = [
        (&out, "NOTES.txt"),
        (&out, "figures/signed.pdf"),
        (&out, "mine/notes.txt"),
        (&prev, "NOTES.txt"),
    ];
    for (folder, user_file) in cases {
        let _ = std::fs::remove_dir_all(&out);
        let _ = std::fs::remove_dir_all(&prev);
        assert_eq!(run_on(&["ingest"], &c, &out).0, Some(0));
        assert_eq!(run_on(&["ingest"], &c, &out).0, Some(0));
        assert!(prev.join(dbbcal::output::MARKER).is_file());
        let path = folder.join(user_file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, "signed").unwrap();
        let what = format!("{}", path.display());
        let (out_before, prev_before) = (snapshot(&out), snapshot(&prev));
        for _ in 0..3 {
            check_out_refused(
                &["ingest"],
                &c,
                &out,
                &[],
                3,
                &[user_file.split('/').next().unwrap(), "did not write"],
                &[&out, &prev],
            );
            assert_eq!(std::fs::read(&path).unwrap(), b"signed", "{what}");
        }
        assert!(snapshot(&out) == out_before && snapshot(&prev) == prev_before);
        assert_no_leftovers(root, &what);
    }
}

/// D2: the crash test with an `OUT.prev` present: at every kill point `OUT` is old or new, the
/// old output is in `OUT` or `OUT.prev` (never under a name the next run removes), and after the
/// rerun `OUT` is the clean result.
#[test]
fn killed_at_any_write_step_with_a_kept_previous_output_nothing_is_lost() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let new = reference_output(&c, &tmp.path().join("fresh"));
    let old = snapshot(earlier_output());
    // A third output, distinct from both, as the generation before.
    let before_old = tmp.path().join("before-old");
    assert_eq!(run_on(&["ingest"], &c, &before_old).0, Some(0));
    let older = snapshot(&before_old);
    assert!(older != old && older != new);
    let out = tmp.path().join("out");
    let prev = tmp.path().join("out.prev");
    let (mut killed, mut saw_new) = (0, false);
    for k in 1..200 {
        let _ = std::fs::remove_dir_all(&out);
        let _ = std::fs::remove_dir_all(&prev);
        copy_dir(earlier_output(), &out);
        copy_dir(&before_old, &prev);
        let fault = format!("kill@{k}");
        let args = ["report", "--campaign", s(&c), "--out", s(&out)];
        let r = dbbcal(&args, &[("DBBCAL_FAULT", &fault)]);
        let (now, now_prev) = (snapshot(&out), snapshot(&prev));
        assert!(
            now == old || now == new,
            "{fault}: OUT is neither old nor new"
        );
        assert!(
            now == old || now_prev == old,
            "{fault}: the previous output is in neither OUT nor OUT.prev"
        );
        assert!(
            now_prev == older || now_prev == old || now_prev == new,
            "{fault}: OUT.prev is none of the outputs"
        );
        saw_new |= now == new;
        if r.status.code().is_some() {
            assert_eq!(r.status.code(), Some(0), "{fault}");
            assert!(now == new && now_prev == old, "{fault}: finished");
            break;
        }
        killed += 1;
        // The next run cleans up and must not lose the previous output either.
        let r = dbbcal(&args, &[]);
        assert_eq!(r.status.code(), Some(0), "rerun after {fault}");
        assert!(snapshot(&out) == new, "rerun after {fault}");
        assert_no_leftovers(tmp.path(), &fault);
    }
    assert!(killed >= 10, "only {killed} kill points");
    assert!(saw_new);
}

/// D3: the campaign inside anything a run may remove (`OUT.prev`, a partial folder), or
/// reached through a link to one of its files, is refused before any work and left whole.
#[test]
fn a_campaign_inside_what_a_run_may_remove_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let c = small_campaign(root, "camp");
    let out = root.join("out");
    assert_eq!(run_on(&["ingest"], &c, &out).0, Some(0));
    assert_eq!(run_on(&["ingest"], &c, &out).0, Some(0));
    let prev = root.join("out.prev");
    let inside_prev = prev.join("c");
    copy_dir(&c, &inside_prev);
    check_out_refused(
        &["identify"],
        &inside_prev,
        &out,
        &[],
        3,
        &["out.prev", "campaign"],
        &[&inside_prev, &out],
    );
    std::fs::remove_dir_all(&inside_prev).unwrap();
    // In a dead run's partial folder.
    let dead = root.join(".out.partial-4000000");
    copy_dir(&c, &dead.join("c"));
    check_out_refused(
        &["identify"],
        &dead.join("c"),
        &out,
        &[],
        3,
        &[".out.partial-4000000", "campaign"],
        &[&dead, &out],
    );
    std::fs::remove_dir_all(&dead).unwrap();
    // A campaign whose encoder file is a link into OUT.prev.
    let linked = root.join("linked");
    copy_dir(&c, &linked);
    let enc = std::fs::read_dir(linked.join("encoders"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let kept = prev.join("kept.parquet");
    std::fs::rename(&enc, &kept).unwrap();
    std::os::unix::fs::symlink(&kept, &enc).unwrap();
    check_out_refused(
        &["identify"],
        &linked,
        &out,
        &[],
        3,
        &["kept.parquet", "campaign"],
        &[&prev, &linked],
    );
    assert_no_leftovers(root, "campaign in OUT.prev");
}

/// D4: a run on `out.prev` while a run on `out` (which would replace `out.prev`) holds its lock
/// is refused at once, and the other way round: one lock for a name and its `.prev`.
#[test]
fn runs_on_an_output_and_on_its_previous_output_never_run_together() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let out = tmp.path().join("out");
    let prev = tmp.path().join("out.prev");
    copy_dir(earlier_output(), &out);
    copy_dir(earlier_output(), &prev);
    let lock = std::fs::File::create(tmp.path().join(".out.lock")).unwrap();
    lock.try_lock().unwrap();
    for target in [&out, &prev] {
        check_out_refused(
            &["identify"],
            &c,
            target,
            &[],
            6,
            &["another dbbcal run", ".out.lock"],
            &[&out, &prev],
        );
    }
    drop(lock);
}

/// D5, H1: what sits where the lock or this run's partial folder go and is not dbbcal's (a
/// user's file `.OUT.lock`, a FIFO, a folder `.OUT.partial-<pid>` of the user's) is refused with
/// one line, at once, and left as it was.
#[test]
fn a_lock_or_partial_name_holding_something_else_is_refused_and_kept() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let c = small_campaign(root, "camp");
    let out = root.join("out");
    copy_dir(earlier_output(), &out);
    let lock = root.join(".out.lock");
    std::fs::write(&lock, "my notes").unwrap();
    check_out_refused(
        &["identify"],
        &c,
        &out,
        &[],
        3,
        &[".out.lock"],
        &[&out, &lock],
    );
    std::fs::remove_file(&lock).unwrap();
    // A FIFO: opened without blocking, so the run ends at once (it hung forever).
    let status = Command::new("mkfifo").arg(&lock).status().unwrap();
    assert!(status.success());
    let mut child = Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .args(["identify", "--campaign", s(&c), "--out", s(&out)])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed().as_secs() > 60 {
            child.kill().unwrap();
            panic!("a FIFO named .out.lock hangs the run");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let r = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{stderr}");
    assert_one_line(&stderr, &[".out.lock", "not a regular file"], "FIFO");
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::symlink_metadata(&lock)
        .unwrap()
        .file_type()
        .is_fifo());
    std::fs::remove_file(&lock).unwrap();
    // User folders named like partial folders of the next pids (the run's pid among them).
    let last: u32 = std::fs::read_to_string("/proc/sys/kernel/ns_last_pid")
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    let mine: Vec<PathBuf> = (last + 1..last + 400)
        .map(|pid| root.join(format!(".out.partial-{pid}")))
        .collect();
    for m in &mine {
        std::fs::create_dir(m).unwrap();
        std::fs::write(m.join("thesis.tex"), "weeks of work").unwrap();
    }
    let (code, stderr) = run_on(&["identify"], &c, &out);
    assert!(code == Some(0) || code == Some(3), "{stderr}");
    for m in &mine {
        assert_eq!(
            std::fs::read(m.join("thesis.tex")).unwrap(),
            b"weeks of work",
            "{} lost",
            m.display()
        );
    }
}

/// H4: stderr a closed pipe (`2>&1 | logger` when the logger died) is no panic: the run ends
/// with its own exit code and the output in place.
#[test]
fn a_closed_stderr_is_no_panic() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    let out = tmp.path().join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .args(["report", "--campaign", s(&c), "--out", s(&out)])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    assert!(out.join("summary.json").is_file());
}

/// A refused run leaves no folder it created for `--out`'s parents.
#[test]
fn a_refused_run_leaves_no_parent_folder_it_created() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    // Found by ingest, after the output was claimed.
    std::fs::write(c.join("encoders/broken.parquet"), b"PAR1 not parquet").unwrap();
    let out = tmp.path().join("a/b/c/out");
    let (code, stderr) = run_on(&["identify"], &c, &out);
    assert_eq!(code, Some(3), "{stderr}");
    assert!(!tmp.path().join("a").exists(), "a/ was left");
}

/// A bind mount made by the test, undone when dropped (also when the test fails).
struct BindMount(PathBuf);

impl BindMount {
    /// `mount --bind from to`; `None` where the test may not mount (not root).
    fn new(from: &Path, to: &Path) -> Option<BindMount> {
        std::fs::create_dir_all(to).unwrap();
        let ok = Command::new("mount")
            .args(["--bind", s(from), s(to)])
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|st| st.success());
        ok.then(|| BindMount(to.to_path_buf()))
    }
}

impl Drop for BindMount {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

/// D3 through a bind mount (paths alone do not see it): the campaign mounted inside `OUT.prev`
/// is refused by (device, inode) and left whole; `OUT` a mount point is refused before any work
/// (it exited 1 after the analysis). Skipped where the test may not mount.
#[test]
fn a_campaign_reached_through_a_mount_and_a_mount_point_out_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let c = small_campaign(root, "camp");
    let out = root.join("out");
    assert_eq!(run_on(&["ingest"], &c, &out).0, Some(0));
    assert_eq!(run_on(&["ingest"], &c, &out).0, Some(0));
    let prev = root.join("out.prev");
    let Some(mount) = BindMount::new(&c, &prev.join("c")) else {
        eprintln!("bind mounts not permitted here: skipped");
        return;
    };
    check_out_refused(
        &["identify"],
        &c,
        &out,
        &[],
        3,
        &["out.prev", "campaign"],
        &[&c, &out],
    );
    drop(mount);
    std::fs::remove_dir(prev.join("c")).unwrap();
    let elsewhere = root.join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let mounted_out = root.join("mounted");
    let _mount = BindMount::new(&elsewhere, &mounted_out).unwrap();
    check_out_refused(
        &["identify"],
        &c,
        &mounted_out,
        &[],
        3,
        &["mount point"],
        &[&elsewhere],
    );
    // A read-only parent (root may write anywhere else): refused before the analysis.
    let ro = root.join("ro");
    let _ro = BindMount::new(&elsewhere, &ro).unwrap();
    let remounted = Command::new("mount")
        .args(["-o", "remount,bind,ro", s(&ro)])
        .status()
        .unwrap();
    assert!(remounted.success());
    check_out_refused(
        &["identify"],
        &c,
        &ro.join("out"),
        &[],
        3,
        &["cannot write in", "Read-only"],
        &[&elsewhere],
    );
}

/// Raw newlines and escape codes in `--out` and in ids read from parquet are escaped in what
/// dbbcal prints: a refusal stays one line, and no escape code reaches the terminal.
#[test]
fn control_characters_in_paths_and_ids_are_escaped() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_campaign(tmp.path(), "camp");
    // `--out` a file whose name holds a newline and an escape code: the refusal names it.
    let out = tmp.path().join("out\n\u{1b}[31mred");
    std::fs::write(&out, "mine").unwrap();
    let (code, stderr) = run_on(&["identify"], &c, &out);
    assert_eq!(code, Some(3), "{stderr}");
    assert!(!stderr.contains('\u{1b}'), "{stderr:?}");
    assert_one_line(
        &stderr,
        &["out\\n\\u{1b}[31mred", "is a file"],
        "escaped --out",
    );
    // An undeclared bar id with an escape code: dropped, and its note printed escaped.
    let t0 = 1_793_491_200_000_000_000i64 + 3_600_000_000_000;
    let id = "B\u{1b}[2J\nX".to_string();
    let table = Table::new()
        .with("time", Column::TimeNs(vec![t0]))
        .with("bar", Column::Str(vec![id]))
        .with("counts", Column::I64(vec![1]));
    write_table(&c.join("encoders/ghost.parquet"), &table).unwrap();
    let (code, stderr) = run_on(&["identify"], &c, &tmp.path().join("out2"));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains('\u{1b}'), "{stderr:?}");
    assert!(stderr.contains("ghost.parquet"), "{stderr}");
}
