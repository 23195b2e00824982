//! The output's lock (one per name and its `.prev` generations) and the clean-up on Ctrl-C,
//! SIGTERM and SIGHUP.

use super::*;

pub(super) enum LockError {
    Busy,
    /// The lock's path holds something dbbcal did not make: why.
    NotOurs(String),
    Io(std::io::Error),
}

/// What a lock file dbbcal made holds.
pub(super) const LOCK_TEXT: &str =
    "dbbcal lock: a dbbcal run is writing the output beside this file\n";

/// Lock `path` (created if absent) without waiting. A lock taken on a file that another run
/// has meanwhile removed (it removes its lock file when done) is retried on the new file. The
/// file is opened without blocking and without following a link: anything but a regular file
/// (a FIFO, a folder, a link), or a file holding something else than [`LOCK_TEXT`], is not
/// dbbcal's and is refused.
pub(super) fn take_lock(path: &Path) -> Result<File, LockError> {
    use std::io::{Read, Seek, Write};
    use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
    for _ in 0..8 {
        if let Ok(meta) = std::fs::symlink_metadata(path) {
            if !meta.is_file() {
                let what = if meta.file_type().is_symlink() {
                    "a symbolic link"
                } else if meta.is_dir() {
                    "a folder"
                } else {
                    "not a regular file (a FIFO, socket or device)"
                };
                return Err(LockError::NotOurs(format!(
                    "it is {what}, not a lock file of dbbcal; move it elsewhere"
                )));
            }
        }
        let mut file = match std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW | libc::O_CLOEXEC)
            .open(path)
        {
            Ok(f) => f,
            Err(e) if e.raw_os_error() == Some(libc::ELOOP) => {
                return Err(LockError::NotOurs(
                    "it is a symbolic link, not a lock file of dbbcal; move it elsewhere".into(),
                ))
            }
            Err(e) => return Err(LockError::Io(e)),
        };
        let meta = file.metadata().map_err(LockError::Io)?;
        if !meta.is_file() {
            return Err(LockError::NotOurs(
                "it is not a regular file (a FIFO, socket or device), not a lock file of dbbcal; move it elsewhere".into(),
            ));
        }
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => return Err(LockError::Busy),
            Err(std::fs::TryLockError::Error(e)) => return Err(LockError::Io(e)),
        }
        let same = match std::fs::metadata(path) {
            Ok(b) => meta.ino() == b.ino() && meta.dev() == b.dev(),
            _ => false,
        };
        if !same {
            continue;
        }
        // Ours: empty (just made, or a run died before writing it) or dbbcal's text.
        let mut text = Vec::new();
        (&file)
            .take(LOCK_TEXT.len() as u64 + 1)
            .read_to_end(&mut text)
            .map_err(LockError::Io)?;
        if text.is_empty() {
            file.rewind()
                .and_then(|()| file.write_all(LOCK_TEXT.as_bytes()))
                .map_err(LockError::Io)?;
        } else if text != LOCK_TEXT.as_bytes() {
            let _ = file.unlock();
            return Err(LockError::NotOurs(
                "it holds something dbbcal did not write (not a lock file of dbbcal); move it elsewhere".into(),
            ));
        }
        return Ok(file);
    }
    Err(LockError::Busy)
}

/// What a signal must clean up while an output is being written.
pub(super) struct Cleanup {
    pub(super) partial: PathBuf,
    pub(super) lock: PathBuf,
}

pub(super) static IN_PROGRESS: Mutex<Option<Cleanup>> = Mutex::new(None);
/// The lock file of the claimed output, from the claim on (a signal during ingest removes it).
pub(super) static HELD_LOCK: Mutex<Option<PathBuf>> = Mutex::new(None);
/// The new output has been swapped into place.
pub(super) static REPLACED: std::sync::atomic::AtomicBool =
    std::sync::atomic::AtomicBool::new(false);
/// Held while the lock is taken or given back and during the swap: a signal waits until the
/// lock and `OUT` are in a state it can clean up.
pub(super) static CRITICAL: Mutex<()> = Mutex::new(());

pub(super) fn in_progress(c: Option<Cleanup>) {
    *IN_PROGRESS.lock().unwrap_or_else(|e| e.into_inner()) = c;
}

/// On SIGINT / SIGTERM / SIGHUP: wait for a swap in progress to finish, remove the partial
/// folder and the lock file, and exit with 128 + the signal number. The old output (or the
/// new one, if the swap had finished) is whole.
pub fn install_signal_handlers() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        tracing::warn!("cannot install signal handlers; an interrupted run may leave a partial folder (removed by the next run)");
        return;
    };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            let _swap = CRITICAL.lock().unwrap_or_else(|e| e.into_inner());
            // Kept until the exit: no write step runs from here on.
            let _no_more_writes = WRITING.write().unwrap_or_else(|e| e.into_inner());
            if let Some(c) = IN_PROGRESS.lock().unwrap_or_else(|e| e.into_inner()).take() {
                let _ = std::fs::remove_dir_all(&c.partial);
                let _ = std::fs::remove_file(&c.lock);
            }
            if let Some(lock) = HELD_LOCK.lock().unwrap_or_else(|e| e.into_inner()).take() {
                let _ = std::fs::remove_file(lock);
            }
            if REPLACED.load(std::sync::atomic::Ordering::SeqCst) {
                say(&format!(
                    "dbbcal: interrupted (signal {signal}) after the new output was in place"
                ));
            } else {
                say(&format!(
                    "dbbcal: interrupted (signal {signal}); the previous output is unchanged"
                ));
            }
            std::process::exit(128 + signal);
        }
    });
}
