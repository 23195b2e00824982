//! Fault injection for the crash tests (tests/e2e/safe_outputs.rs): every step that writes,
//! fsyncs or renames in an output is a numbered point, and `DBBCAL_FAULT` picks one:
//!
//! * `kill@K`: the process kills itself with SIGKILL at point K (a power cut as far as the
//!   output folder can tell, but for the page cache);
//! * `enospc@K`: the step at point K fails with "No space left on device";
//! * `stall@K`: the process waits 60 s at point K (the signal tests interrupt it there).
//!
//! Unset (every normal run), each point costs one relaxed atomic increment.

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    Kill(usize),
    NoSpace(usize),
    Stall(usize),
}

fn configured() -> Option<Fault> {
    static FAULT: OnceLock<Option<Fault>> = OnceLock::new();
    *FAULT.get_or_init(|| {
        let spec = std::env::var("DBBCAL_FAULT").ok()?;
        let (kind, at) = spec.split_once('@')?;
        let at: usize = at.parse().ok()?;
        match kind {
            "kill" => Some(Fault::Kill(at)),
            "enospc" => Some(Fault::NoSpace(at)),
            "stall" => Some(Fault::Stall(at)),
            _ => None,
        }
    })
}

static POINTS: AtomicUsize = AtomicUsize::new(0);

fn next(what: &str, path: &Path) -> Option<Fault> {
    let fault = configured()?;
    let k = POINTS.fetch_add(1, Ordering::Relaxed) + 1;
    let hit = match fault {
        Fault::Kill(at) | Fault::NoSpace(at) | Fault::Stall(at) => at == k,
    };
    hit.then(|| {
        super::say(&format!(
            "dbbcal: fault point {k} ({what} {})",
            path.display()
        ));
        fault
    })
}

/// A step that may fail: killed or failed with ENOSPC when the configured point is this one.
pub(crate) fn point(what: &str, path: &Path) -> std::io::Result<()> {
    match next(what, path) {
        Some(Fault::Kill(_)) => kill(),
        Some(Fault::NoSpace(_)) => Err(std::io::Error::from_raw_os_error(libc::ENOSPC)),
        Some(Fault::Stall(_)) => {
            std::thread::sleep(std::time::Duration::from_secs(60));
            Ok(())
        }
        None => Ok(()),
    }
}

/// A step after which an error can no longer be undone: only a kill is injected here.
pub(crate) fn kill_point(what: &str, path: &Path) {
    match next(what, path) {
        Some(Fault::Kill(_)) => kill(),
        Some(_) => super::say("dbbcal: fault point takes kills only: nothing injected"),
        None => {}
    }
}

fn kill() -> ! {
    crate::supervise::note(crate::supervise::Note::FaultKill);
    // SAFETY: sending a signal to our own process.
    unsafe {
        libc::kill(libc::getpid(), libc::SIGKILL);
    }
    unreachable!("SIGKILL returned")
}
