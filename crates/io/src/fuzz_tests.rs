//! Fuzzing the reader (issue 14): arbitrary bytes, and valid parquet files with bytes flipped or
//! cut off, as a campaign's encoder file never panic or hang `read_campaign`: each case gives an
//! error (or, for a mutation the format cannot see, data), within a per-case timeout.
//!
//! 64 cases by default (a few seconds); a longer run:
//! `PROPTEST_CASES=5000 cargo test --release -p dbbcal-io fuzz_tests`.
//!
//! A parquet decoder may panic on some corrupt files (polars' does, e.g. "thrift bool field");
//! ingest catches those at the file boundary (`io::guard`) and names the file. So any panic that
//! reaches the caller fails here, and so does a hang. `DBBCAL_FUZZ_STRICT=0` tolerates panics
//! raised inside the parquet crate (to look at this crate's own panics alone).
//!
//! A corrupt page may make a decoder *abort* the process (polars asked for ~2.3e18 bytes on
//! `PROPTEST_RNG_SEED=14`'s page), which nothing in-process can catch. So each case is read in a child
//! process (this test binary, running [`one_case_in_a_supervised_child`]) started by the very
//! code that supervises `dbbcal` ([`dbbcal_supervise::spawn`]): a case passes when the child
//! reads it cleanly (an error of one line, or data), or when it dies from a crash signal and the
//! supervisor's trail names exactly the fuzzed file, the line `dbbcal` would print. A crash
//! whose trail names no file, or another, fails; so does a hang (the child is killed).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

use proptest::prelude::*;

use super::{read_campaign, read_campaign_binned, write_table, Column, Table};
use dbbcal_supervise::{self as supervise, Crash, Ending};
use dbbcal_testkit::cases;

/// A case that has not returned after this long is a hang.
const CASE_TIMEOUT: Duration = Duration::from_secs(20);

/// 2026-11-01T00:30:00Z in ns: inside bar B01's first mount of the shipped sample.
const T0: i64 = 1_793_493_000 * 1_000_000_000;

/// Valid encoder files to mutate: a tiny one written here (flips often hit its footer and
/// headers) and the shipped sample's.
fn bases() -> &'static [Vec<u8>] {
    static BASES: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    BASES.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let n = 120;
        let path = dir.path().join("tiny.parquet");
        write_table(
            &path,
            &Table::new()
                .with(
                    "time",
                    Column::TimeNs((0..n).map(|i| T0 + i * 60_000_000_000).collect()),
                )
                .with("bar", Column::Str(vec!["B01".to_string(); n as usize]))
                .with(
                    "counts",
                    Column::I64((0..n).map(|i| 1000 + i * 3).collect()),
                ),
        )
        .unwrap();
        vec![
            std::fs::read(&path).unwrap(),
            std::fs::read(dbbcal_testkit::repo_path(
                "data/sample/encoders/encoders.parquet",
            ))
            .unwrap(),
        ]
    })
}

/// The shipped sample's manifest and temperatures, and `encoder` as its only encoder file.
fn campaign_with(encoder: &[u8]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        dbbcal_testkit::repo_path("data/sample/campaign.toml"),
        d.join("campaign.toml"),
    )
    .unwrap();
    for sub in ["encoders", "temperatures"] {
        std::fs::create_dir_all(d.join(sub)).unwrap();
    }
    std::fs::copy(
        dbbcal_testkit::repo_path("data/sample/temperatures/temperatures.parquet"),
        d.join("temperatures/temperatures.parquet"),
    )
    .unwrap();
    std::fs::write(d.join("encoders/fuzzed.parquet"), encoder).unwrap();
    dir
}

/// How one case's bytes are made.
#[derive(Debug, Clone)]
enum Bytes {
    Random(Vec<u8>),
    /// Base file `base`, bytes at fractions of its length set to values.
    Flipped(usize, Vec<(f64, u8)>),
    /// Base file `base` cut at a fraction of its length.
    Truncated(usize, f64),
    /// Base file with its last `k` bytes (the footer) flipped.
    FooterFlipped(usize, Vec<(usize, u8)>),
}

impl Bytes {
    fn make(&self) -> Vec<u8> {
        let base = |b: usize| bases()[b % bases().len()].clone();
        match self {
            Bytes::Random(v) => v.clone(),
            Bytes::Flipped(b, flips) => {
                let mut v = base(*b);
                let n = v.len();
                for (at, byte) in flips {
                    v[((n as f64 * at) as usize).min(n - 1)] = *byte;
                }
                v
            }
            Bytes::Truncated(b, at) => {
                let mut v = base(*b);
                v.truncate((v.len() as f64 * at) as usize);
                v
            }
            Bytes::FooterFlipped(b, flips) => {
                let mut v = base(*b);
                let n = v.len();
                for (back, byte) in flips {
                    v[n - 1 - back % n.min(512)] = *byte;
                }
                v
            }
        }
    }
}

fn bytes() -> impl Strategy<Value = Bytes> {
    prop_oneof![
        1 => prop::collection::vec(any::<u8>(), 0..2048).prop_map(Bytes::Random),
        1 => prop::collection::vec(any::<u8>(), 0..64).prop_map(|mut v| {
            // Random bytes between parquet's magic numbers.
            let mut b = b"PAR1".to_vec();
            b.append(&mut v);
            b.extend_from_slice(b"PAR1");
            Bytes::Random(b)
        }),
        2 => (0..2usize, prop::collection::vec((0.0..1.0f64, any::<u8>()), 1..8))
            .prop_map(|(b, f)| Bytes::Flipped(b, f)),
        1 => (0..2usize, 0.0..1.0f64).prop_map(|(b, at)| Bytes::Truncated(b, at)),
        2 => (0..2usize, prop::collection::vec((any::<usize>(), any::<u8>()), 1..6))
            .prop_map(|(b, f)| Bytes::FooterFlipped(b, f)),
    ]
}

/// Read `dir` on a thread (`bin_s` 0: every reading; else binned while streaming): `Ok(Ok|Err
/// message)` when it returned, `Err` when it panicked or did not return in time.
fn read_with_timeout(dir: PathBuf, bin_s: f64) -> Result<Result<(), String>, String> {
    let (tx, rx) = mpsc::channel();
    let handle = std::thread::spawn(move || {
        let r = if bin_s > 0.0 {
            read_campaign_binned(&dir, bin_s)
        } else {
            read_campaign(&dir)
        };
        let _ = tx.send(r.map(|_| ()).map_err(|e| e.to_string()));
    });
    match rx.recv_timeout(CASE_TIMEOUT) {
        Ok(r) => {
            let _ = handle.join();
            Ok(r)
        }
        Err(mpsc::RecvTimeoutError::Disconnected) => Err(match handle.join() {
            Err(p) => format!(
                "panicked: {}",
                p.downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default()
            ),
            Ok(()) => "the reader thread ended without an answer".into(),
        }),
        Err(mpsc::RecvTimeoutError::Timeout) => {
            Err(format!("no answer within {CASE_TIMEOUT:?} (hang)"))
        }
    }
}

/// Where panics happened since the hook was installed (file:line of each).
fn panic_locations() -> &'static Mutex<Vec<String>> {
    static LOCATIONS: OnceLock<Mutex<Vec<String>>> = OnceLock::new();
    LOCATIONS.get_or_init(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if let Some(l) = info.location() {
                if let Ok(mut v) = panic_locations().lock() {
                    v.push(format!("{}:{}", l.file(), l.line()));
                }
            }
            previous(info);
        }));
        Mutex::new(Vec::new())
    })
}

/// A panic location in a dependency (the parquet decoder), not in this crate.
fn upstream(location: &str) -> bool {
    location.contains(".cargo/registry") || location.contains("parquet")
}

fn check(dir: &Path) {
    let strict = std::env::var("DBBCAL_FUZZ_STRICT").map_or(true, |v| v != "0");
    for bin_s in [0.0, 60.0] {
        let seen = panic_locations().lock().map(|v| v.len()).unwrap_or(0);
        match read_with_timeout(dir.to_path_buf(), bin_s) {
            Ok(Ok(())) => {}
            Ok(Err(msg)) => assert!(!msg.contains('\n'), "not one line: {msg}"),
            Err(e) if e.starts_with("panicked") && !strict => {
                let locations: Vec<String> = panic_locations()
                    .lock()
                    .map(|v| v[seen.min(v.len())..].to_vec())
                    .unwrap_or_default();
                assert!(
                    !locations.is_empty() && locations.iter().all(|l| upstream(l)),
                    "bin_s {bin_s}: {e} at {locations:?}"
                );
                eprintln!("bin_s {bin_s}: tolerated upstream panic ({e}) at {locations:?}");
            }
            Err(e) => panic!("bin_s {bin_s}: {e}"),
        }
    }
}

/// The campaign a child reads (set by [`check_in_child`]).
const CASE_ENV: &str = "DBBCAL_FUZZ_CASE";

/// The child's half of [`check_in_child`]: reads the campaign named by [`CASE_ENV`] as
/// [`check`] does. Run alone (no [`CASE_ENV`]) it has nothing to read and returns.
#[test]
fn one_case_in_a_supervised_child() {
    let Some(dir) = std::env::var_os(CASE_ENV) else {
        return;
    };
    assert!(supervise::child_init(), "{CASE_ENV} set, but no supervisor");
    check(Path::new(&dir));
}

/// How a case read in a child ended: `Ok(None)` read (data or one-line errors), `Ok(Some(line))`
/// crashed with the trail naming exactly `dir`'s fuzzed file (`line`: what `dbbcal` says),
/// `Err` anything else.
fn check_in_child(dir: &Path) -> Result<Option<String>, String> {
    let log = tempfile::NamedTempFile::new().unwrap();
    let mut cmd = Command::new(std::env::current_exe().unwrap());
    cmd.args([
        "--exact",
        "fuzz_tests::one_case_in_a_supervised_child",
        "--test-threads=1",
        "--nocapture",
    ])
    .env(CASE_ENV, dir)
    .stdin(Stdio::null())
    .stdout(log.reopen().unwrap())
    .stderr(log.reopen().unwrap());
    let (ending, timed_out) = supervise::spawn(&mut cmd)
        .unwrap()
        .wait_at_most(3 * CASE_TIMEOUT)
        .unwrap();
    let output = std::fs::read_to_string(log.path()).unwrap_or_default();
    if timed_out {
        return Err(format!(
            "no answer within {:?} (hang): {output}",
            3 * CASE_TIMEOUT
        ));
    }
    let fuzzed = dir.join("encoders/fuzzed.parquet");
    match ending {
        Ending::Exited(0) if output.contains("1 passed") => Ok(None),
        Ending::Exited(code) => Err(format!("the child exited {code}: {output}")),
        Ending::Crashed(d) if d.reading == [fuzzed.clone()] && d.signal != libc::SIGKILL => {
            Ok(Some(Crash(d).to_string()))
        }
        Ending::Crashed(d) | Ending::Interrupted(d) => Err(format!(
            "the child died from {} with {:?} in progress (expected {}): {output}",
            supervise::signal_name(d.signal),
            d.reading,
            fuzzed.display()
        )),
    }
}

/// A page of the tiny base with four bytes set (the case `PROPTEST_RNG_SEED=14` found), on
/// which polars' decoder asks for 2 305 843 009 213 693 936 bytes to decode its validity and
/// aborts. The parquet crate refuses the page with an error: an ordinary corrupt case, named
/// in one line (the same file is in the e2e tests, `bad_input`). Read in a supervised child as
/// every fuzz case: no crash.
#[test]
fn a_page_that_aborts_polars_decoder_is_refused_in_one_line_naming_the_file() {
    let bytes = std::fs::read(dbbcal_testkit::repo_path(
        "tests/data/page-validity-abort.parquet",
    ))
    .unwrap();
    let dir = campaign_with(&bytes);
    assert_eq!(check_in_child(dir.path()).unwrap(), None, "no crash");
    let e = read_campaign(dir.path()).unwrap_err().to_string();
    let named = format!(
        "{}: not a valid parquet file",
        dir.path().join("encoders/fuzzed.parquet").display()
    );
    assert!(e.starts_with(&named) && !e.contains('\n'), "{e}");
}

#[test]
fn the_unmutated_bases_read() {
    for b in bases() {
        let dir = campaign_with(b);
        read_campaign(dir.path()).expect("a valid base");
    }
}

proptest! {
    #![proptest_config(cases(64))]

    #[test]
    fn fuzzed_encoder_files_never_panic_or_hang(b in bytes()) {
        let dir = campaign_with(&b.make());
        match check_in_child(dir.path()) {
            Ok(None) => {}
            Ok(Some(line)) => eprintln!("{b:?}: crash named: {line}"),
            Err(e) => panic!("{b:?}: {e}"),
        }
    }
}
