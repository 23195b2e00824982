//! The output folder: dbbcal replaces only what it can prove it wrote, and a run leaves `OUT`
//! entirely old or entirely new.
//!
//! The life of a run's output (README, "What dbbcal promises about your data"):
//! 1. [`OutputTarget::claim`], before any work: `OUT` is refused unless it is absent, an empty
//!    folder, or a folder holding [`MARKER`]; refused too when it is a symbolic link, a file, the
//!    working or home folder, or overlaps the campaign (after resolving symlinks and `..`). The
//!    claim takes a lock (`.OUT.lock`, an advisory `flock`, released by the kernel if the process
//!    dies) so that a second run on the same `OUT` refuses at once.
//! 2. [`OutputTarget::write`]: removes the partial folders of dead runs, builds the new output in
//!    `.OUT.partial-<pid>` (the marker first), fsyncs every file and folder, then swaps it into
//!    place: the previous `OUT` becomes `OUT.prev` (one generation kept; the one before is
//!    removed only now, and only if it holds the marker). On Linux the swap is one
//!    `renameat2(RENAME_EXCHANGE)`, so `OUT` never vanishes, even for a moment.
//! 3. Ctrl-C / SIGTERM during the run: the partial folder and the lock are removed and the old
//!    output is untouched ([`install_signal_handlers`]).
//! 4. A run that died without cleaning up (a crash in a dependency, the OOM killer): its
//!    supervisor removes the partial folder and the lock ([`clean_up_after_dead_run`],
//!    `crate::supervise`), else the next run does.
//!
//! [`fault`] lets the crash tests kill the process or fail a write at every step.
//!
//! The JSON formats live here too, each converting typed results to text in one place:
//! [`summary`] (`summary.json`), [`diagnosis`] (`diagnosis.json`), [`stage_records`]
//! (`calibration.json`, `compensation.json`, `acceptance.json`).

pub(crate) mod diagnosis;
pub(crate) mod fault;
pub(crate) mod stage_records;
pub(crate) mod summary;

use std::fs::File;
use std::path::{Component, Path, PathBuf};
use std::sync::{Mutex, RwLock, RwLockReadGuard};

use serde::{Deserialize, Serialize};

/// The file that marks a folder as a dbbcal output (written first into every output).
pub const MARKER: &str = "dbbcal-output.json";

/// Why an output location is refused or could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The location is not one dbbcal may write: refused before any work.
    #[error("--out {path}: refused: {why}")]
    Refused {
        /// The output location.
        path: PathBuf,
        /// Why it is refused.
        why: String,
    },
    /// Another run holds the lock on this output.
    #[error("--out {path}: another dbbcal run is writing this output now (lock {lock}); try again when it has finished")]
    Busy {
        /// The output location.
        path: PathBuf,
        /// The lock file.
        lock: PathBuf,
    },
    /// A file-system operation failed while writing.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}

impl OutputError {
    fn io(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
        move |source| OutputError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// What the marker file says: which tool and version wrote the folder, from which inputs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Marker {
    pub(crate) tool: String,
    pub(crate) version: String,
    /// The campaign id, the stages run and the model's effects.
    pub(crate) campaign: String,
    pub(crate) stages: serde_json::Value,
    pub(crate) effects: serde_json::Value,
    /// Every input file (relative path, bytes, sha256), as in `inputs.json`.
    pub(crate) inputs: serde_json::Value,
}

impl Marker {
    pub(crate) fn new(
        campaign: &str,
        stages: serde_json::Value,
        effects: serde_json::Value,
        inputs: serde_json::Value,
    ) -> Marker {
        Marker {
            tool: "dbbcal".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            campaign: campaign.into(),
            stages,
            effects,
            inputs,
        }
    }
}

/// Whether `dir` holds a marker file that dbbcal wrote.
fn holds_marker(dir: &Path) -> bool {
    let Ok(text) = std::fs::read_to_string(dir.join(MARKER)) else {
        return false;
    };
    serde_json::from_str::<Marker>(&text).is_ok_and(|m| m.tool == "dbbcal")
}

/// An output location that passed every check and is locked for this run.
#[derive(Debug)]
pub(crate) struct OutputTarget {
    out: PathBuf,
    parent: PathBuf,
    name: String,
    lock_path: PathBuf,
    lock: File,
}

impl OutputTarget {
    /// Check `out` against `campaign` and take the lock; nothing is written but the parent
    /// folder (created) and the lock file.
    pub(crate) fn claim(out: &Path, campaign: &Path) -> Result<OutputTarget, OutputError> {
        let refused = |why: String| OutputError::Refused {
            path: out.to_path_buf(),
            why,
        };
        let name = final_name(out).ok_or_else(|| {
            refused("name a folder (not the current, parent or root folder)".into())
        })?;
        let resolved =
            resolve(out).map_err(|e| refused(format!("cannot resolve the path: {e}")))?;
        if home_dir().is_some_and(|home| resolved == home) {
            return Err(refused("that is the home folder".into()));
        }
        check_overlap(&resolved, campaign).map_err(refused)?;
        check_replaceable(out, "")?;
        let prev = sibling(out, &format!("{name}.prev"));
        check_replaceable(&prev, " (the previous output, kept as OUT.prev)").map_err(
            |e| match e {
                OutputError::Refused { why, .. } => refused(format!("{}: {why}", prev.display())),
                other => other,
            },
        )?;
        let parent = parent_of(out);
        std::fs::create_dir_all(&parent).map_err(OutputError::io(&parent))?;
        let lock_path = parent.join(format!(".{name}.lock"));
        crate::supervise::note(crate::supervise::Note::Output(out));
        // A signal waits until the lock is taken and known to the handler, which removes it.
        let _signals_wait = CRITICAL.lock().unwrap_or_else(|e| e.into_inner());
        let lock = take_lock(&lock_path).map_err(|e| match e {
            LockError::Busy => OutputError::Busy {
                path: out.to_path_buf(),
                lock: lock_path.clone(),
            },
            LockError::Io(source) => OutputError::Io {
                path: lock_path.clone(),
                source,
            },
        })?;
        *HELD_LOCK.lock().unwrap_or_else(|e| e.into_inner()) = Some(lock_path.clone());
        Ok(OutputTarget {
            out: out.to_path_buf(),
            parent,
            name,
            lock_path,
            lock,
        })
    }

    pub(crate) fn path(&self) -> &Path {
        &self.out
    }

    /// Build the new output with `build` (given the partial folder, which already holds the
    /// marker) and swap it into place. On any error the partial folder is removed and `OUT`
    /// is as it was.
    pub(crate) fn write<E>(
        self,
        marker: &Marker,
        build: impl FnOnce(&Path) -> Result<(), E>,
    ) -> Result<(), WriteFailure<E>> {
        self.remove_dead_partials();
        let partial = self.parent.join(format!(
            ".{}.partial-{}",
            self.name,
            crate::supervise::run_pid()
        ));
        let _ = std::fs::remove_dir_all(&partial);
        in_progress(Some(Cleanup {
            partial: partial.clone(),
            lock: self.lock_path.clone(),
        }));
        let result = self.fill(&partial, marker, build).and_then(|()| {
            sync_tree(&partial).map_err(WriteFailure::Output)?;
            self.swap(&partial).map_err(WriteFailure::Output)
        });
        if result.is_err() {
            let _ = std::fs::remove_dir_all(&partial);
        }
        in_progress(None);
        result
    }

    fn fill<E>(
        &self,
        partial: &Path,
        marker: &Marker,
        build: impl FnOnce(&Path) -> Result<(), E>,
    ) -> Result<(), WriteFailure<E>> {
        {
            let _step = writing();
            std::fs::create_dir(partial)
                .map_err(OutputError::io(partial))
                .map_err(WriteFailure::Output)?;
        }
        let mut text = serde_json::to_string_pretty(marker).expect("the marker serialises");
        text.push('\n');
        write_file(&partial.join(MARKER), text.as_bytes()).map_err(WriteFailure::Output)?;
        build(partial).map_err(WriteFailure::Build)
    }

    fn remove_dead_partials(&self) {
        remove_dead_partials(&self.parent, &self.name);
    }

    /// `partial` → `OUT`, the previous `OUT` → `OUT.prev`. Signals wait until this is done.
    fn swap(&self, partial: &Path) -> Result<(), OutputError> {
        let _guard = CRITICAL.lock().unwrap_or_else(|e| e.into_inner());
        crate::supervise::note(crate::supervise::Note::SwapBegun);
        let result = self.swap_in(partial);
        if result.is_ok() {
            // From here a signal finds the new output in place and nothing to clean up.
            in_progress(None);
            REPLACED.store(true, std::sync::atomic::Ordering::SeqCst);
            crate::supervise::note(crate::supervise::Note::SwapDone);
        }
        result
    }

    fn swap_in(&self, partial: &Path) -> Result<(), OutputError> {
        let prev = self.parent.join(format!("{}.prev", self.name));
        let out = &self.out;
        if std::fs::symlink_metadata(out).is_err() {
            fault::point("rename", out).map_err(OutputError::io(out))?;
            std::fs::rename(partial, out).map_err(OutputError::io(out))?;
            return sync_dir(&self.parent).map_err(OutputError::io(&self.parent));
        }
        if std::fs::symlink_metadata(&prev).is_ok() {
            if !holds_marker(&prev) {
                return Err(OutputError::Refused {
                    path: out.clone(),
                    why: format!("{} appeared and is not a dbbcal output", prev.display()),
                });
            }
            fault::point("remove OUT.prev", &prev).map_err(OutputError::io(&prev))?;
            std::fs::remove_dir_all(&prev).map_err(OutputError::io(&prev))?;
        }
        fault::point("exchange", out).map_err(OutputError::io(out))?;
        match exchange(partial, out) {
            Ok(()) => {
                // `partial` now holds the previous output.
                sync_dir(&self.parent).map_err(OutputError::io(&self.parent))?;
                fault::kill_point("keep OUT.prev", &prev);
                if let Err(e) = std::fs::rename(partial, &prev) {
                    tracing::warn!("the previous output stays in {}: {e}", partial.display());
                }
            }
            Err(_) => {
                // No atomic exchange here: two renames. A crash between them leaves the old
                // output in OUT.prev and no OUT; nothing is lost.
                std::fs::rename(out, &prev).map_err(OutputError::io(out))?;
                fault::kill_point("rename into place", out);
                std::fs::rename(partial, out).map_err(OutputError::io(out))?;
            }
        }
        sync_dir(&self.parent).map_err(OutputError::io(&self.parent))
    }
}

impl Drop for OutputTarget {
    /// The lock file goes while the lock is still held (a run waiting on the old file then sees
    /// it replaced and locks the new one; see [`take_lock`]).
    fn drop(&mut self) {
        let _signals_wait = CRITICAL.lock().unwrap_or_else(|e| e.into_inner());
        *HELD_LOCK.lock().unwrap_or_else(|e| e.into_inner()) = None;
        let _ = std::fs::remove_file(&self.lock_path);
        let _ = self.lock.unlock();
    }
}

/// Partial folders of runs that died, beside the output `name` in `parent` (the caller holds the
/// lock, so no live run owns one): only `.OUT.partial-<digits>` folders that are empty or hold
/// the marker.
fn remove_dead_partials(parent: &Path, name: &str) {
    let prefix = format!(".{name}.partial-");
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for e in entries.flatten() {
        let file_name = e.file_name();
        let Some(pid) = file_name.to_str().and_then(|n| n.strip_prefix(&prefix)) else {
            continue;
        };
        let path = e.path();
        let is_dir = e.file_type().is_ok_and(|t| t.is_dir());
        let empty = std::fs::read_dir(&path).is_ok_and(|mut d| d.next().is_none());
        if is_dir && pid.bytes().all(|b| b.is_ascii_digit()) && (empty || holds_marker(&path)) {
            tracing::info!("removing {} (left by a run that died)", path.display());
            let _ = std::fs::remove_dir_all(&path);
        }
    }
}

/// After a run on `out` died without cleaning up (killed by a signal it could not handle; its
/// supervisor calls this, `crate::supervise`): removes what the next run would, the partial
/// folders of dead runs and the lock file, taking the lock first. Nothing is touched when
/// another run holds the lock by now (`Ok(false)`), nor when the folder beside `out` is gone.
pub fn clean_up_after_dead_run(out: &Path) -> Result<bool, OutputError> {
    let Some(name) = final_name(out) else {
        return Ok(false);
    };
    let parent = parent_of(out);
    let lock_path = parent.join(format!(".{name}.lock"));
    let lock = match take_lock(&lock_path) {
        Ok(lock) => lock,
        Err(LockError::Busy) => return Ok(false),
        Err(LockError::Io(e)) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(LockError::Io(source)) => {
            return Err(OutputError::Io {
                path: lock_path,
                source,
            })
        }
    };
    remove_dead_partials(&parent, &name);
    // As in `OutputTarget::drop`: the file goes while the lock is held.
    let removed = std::fs::remove_file(&lock_path).map_err(OutputError::io(&lock_path));
    let _ = lock.unlock();
    removed.map(|()| true)
}

/// A failed [`OutputTarget::write`]: the build's own error, or the output's.
#[derive(Debug)]
pub(crate) enum WriteFailure<E> {
    Build(E),
    Output(OutputError),
}

/// Write `bytes` to `path` (a new file in a partial folder), through the fault points.
pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    fault::point("write", path).map_err(OutputError::io(path))?;
    let _step = writing();
    std::fs::write(path, bytes).map_err(OutputError::io(path))
}

/// Held shared by each step that creates or writes something in a partial folder, and taken
/// exclusively by the signal handler: it removes the folder between two steps, never during
/// one, and no step starts after it (a step half done could recreate the folder it just
/// removed: `create_dir_all` of `figures/`).
static WRITING: RwLock<()> = RwLock::new(());

/// The guard of one write step into the output being built ([`WRITING`]). Not re-entrant:
/// a step holding it must not call another that takes it (a signal waiting in between would
/// deadlock the two); and taken after the step's fault point, whose `stall` must not hold it.
pub(crate) fn writing() -> RwLockReadGuard<'static, ()> {
    WRITING.read().unwrap_or_else(|e| e.into_inner())
}

/// fsync every file, then every folder, under `dir` (children before parents).
fn sync_tree(dir: &Path) -> Result<(), OutputError> {
    for e in std::fs::read_dir(dir).map_err(OutputError::io(dir))? {
        let path = e.map_err(OutputError::io(dir))?.path();
        if path.is_dir() {
            sync_tree(&path)?;
        } else {
            fault::point("fsync", &path).map_err(OutputError::io(&path))?;
            File::open(&path)
                .and_then(|f| f.sync_all())
                .map_err(OutputError::io(&path))?;
        }
    }
    fault::point("fsync", dir).map_err(OutputError::io(dir))?;
    sync_dir(dir).map_err(OutputError::io(dir))
}

fn sync_dir(dir: &Path) -> std::io::Result<()> {
    File::open(dir)?.sync_all()
}

/// Atomically exchange two paths (Linux `renameat2(RENAME_EXCHANGE)`); an error where the
/// system or file system cannot.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| CString::new(p.as_os_str().as_bytes()).map_err(std::io::Error::other);
    let (a, b) = (c(a)?, c(b)?);
    // SAFETY: two valid NUL-terminated paths, relative to the working directory.
    let rc = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            a.as_ptr(),
            libc::AT_FDCWD,
            b.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> std::io::Result<()> {
    Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
}

/// The last component of `out` when it names a folder (not `.`, `..`, `/` or empty).
fn final_name(out: &Path) -> Option<String> {
    match out.components().next_back()? {
        Component::Normal(n) => n.to_str().map(str::to_string),
        _ => None,
    }
}

fn parent_of(out: &Path) -> PathBuf {
    out.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf()
}

fn sibling(out: &Path, name: &str) -> PathBuf {
    parent_of(out).join(name)
}

/// `path` made absolute, symlinks resolved in the part that exists, `.` and `..` removed.
pub(crate) fn resolve(path: &Path) -> std::io::Result<PathBuf> {
    let absolute = std::path::absolute(path)?;
    let mut existing = absolute.as_path();
    let mut rest = Vec::new();
    while std::fs::symlink_metadata(existing).is_err() {
        rest.push(existing.file_name().map(|n| n.to_os_string()));
        existing = existing.parent().unwrap_or(Path::new("/"));
    }
    let mut resolved = existing.canonicalize()?;
    for part in rest.into_iter().rev() {
        match part {
            Some(name) => resolved.push(name),
            None => {
                resolved.pop();
            }
        }
    }
    Ok(resolved)
}

fn home_dir() -> Option<PathBuf> {
    std::env::var_os("HOME")
        .filter(|h| !h.is_empty())
        .and_then(|h| PathBuf::from(h).canonicalize().ok())
}

/// `path` may be replaced: absent, an empty folder, or a folder with the marker.
fn check_replaceable(path: &Path, what: &str) -> Result<(), OutputError> {
    let refused = |why: &str| OutputError::Refused {
        path: path.to_path_buf(),
        why: format!("{why}{what}"),
    };
    let meta = match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(OutputError::io(path)(e)),
        Ok(m) => m,
    };
    if meta.file_type().is_symlink() {
        return Err(refused(
            "it is a symbolic link; give the folder it points to, or a new path",
        ));
    }
    if !meta.is_dir() {
        return Err(refused("it is a file, not an output folder"));
    }
    let empty = std::fs::read_dir(path)
        .map_err(OutputError::io(path))?
        .next()
        .is_none();
    if empty || holds_marker(path) {
        Ok(())
    } else {
        Err(refused(&format!(
            "the folder exists and holds files dbbcal did not write (no {MARKER}); choose a new or empty folder"
        )))
    }
}

/// OUT inside the campaign, the campaign inside OUT, or the same folder: the reason.
fn check_overlap(out: &Path, campaign: &Path) -> Result<(), String> {
    let Ok(campaign) = resolve(campaign) else {
        return Ok(()); // ingest names a missing campaign itself
    };
    if out == campaign {
        Err(format!("it is the campaign folder {}", campaign.display()))
    } else if out.starts_with(&campaign) {
        Err(format!(
            "it is inside the campaign folder {}",
            campaign.display()
        ))
    } else if campaign.starts_with(out) {
        Err(format!(
            "it holds the campaign folder {}",
            campaign.display()
        ))
    } else {
        Ok(())
    }
}

enum LockError {
    Busy,
    Io(std::io::Error),
}

/// Lock `path` (created if absent) without waiting. A lock taken on a file that another run
/// has meanwhile removed (it removes its lock file when done) is retried on the new file.
fn take_lock(path: &Path) -> Result<File, LockError> {
    use std::os::unix::fs::MetadataExt;
    for _ in 0..8 {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(path)
            .map_err(LockError::Io)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => return Err(LockError::Busy),
            Err(std::fs::TryLockError::Error(e)) => return Err(LockError::Io(e)),
        }
        let same = match (file.metadata(), std::fs::metadata(path)) {
            (Ok(a), Ok(b)) => a.ino() == b.ino() && a.dev() == b.dev(),
            _ => false,
        };
        if same {
            return Ok(file);
        }
    }
    Err(LockError::Busy)
}

/// What a signal must clean up while an output is being written.
struct Cleanup {
    partial: PathBuf,
    lock: PathBuf,
}

static IN_PROGRESS: Mutex<Option<Cleanup>> = Mutex::new(None);
/// The lock file of the claimed output, from the claim on (a signal during ingest removes it).
static HELD_LOCK: Mutex<Option<PathBuf>> = Mutex::new(None);
/// The new output has been swapped into place.
static REPLACED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
/// Held while the lock is taken or given back and during the swap: a signal waits until the
/// lock and `OUT` are in a state it can clean up.
static CRITICAL: Mutex<()> = Mutex::new(());

fn in_progress(c: Option<Cleanup>) {
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
                eprintln!(
                    "dbbcal: interrupted (signal {signal}) after the new output was in place"
                );
            } else {
                eprintln!(
                    "dbbcal: interrupted (signal {signal}); the previous output is unchanged"
                );
            }
            std::process::exit(128 + signal);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolve_removes_dots_beyond_the_existing_part() {
        let tmp = tempfile::tempdir().unwrap();
        let base = tmp.path().canonicalize().unwrap();
        std::fs::create_dir(base.join("c")).unwrap();
        let p = base.join("x/../c/y/./z/..");
        assert_eq!(resolve(&p).unwrap(), base.join("c/y"));
        assert_eq!(resolve(&base.join("c/..")).unwrap(), base);
    }

    #[test]
    fn overlap_is_found_in_each_direction() {
        let tmp = tempfile::tempdir().unwrap();
        let c = tmp.path().canonicalize().unwrap().join("camp");
        std::fs::create_dir(&c).unwrap();
        assert!(check_overlap(&c, &c).is_err());
        assert!(check_overlap(&c.join("out"), &c).is_err());
        assert!(check_overlap(c.parent().unwrap(), &c).is_err());
        assert!(check_overlap(&c.with_file_name("camp-out"), &c).is_ok());
    }

    #[test]
    fn after_a_dead_run_its_partial_folders_and_lock_go_unless_another_run_holds_the_lock() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let marker = serde_json::to_string(&Marker::new(
            "c",
            Default::default(),
            Default::default(),
            Default::default(),
        ))
        .unwrap();
        let make = |held: bool| {
            std::fs::create_dir_all(d.join(".out.partial-123")).unwrap();
            std::fs::write(d.join(".out.partial-123").join(MARKER), &marker).unwrap();
            std::fs::create_dir_all(d.join(".out.partial-124")).unwrap();
            std::fs::create_dir_all(d.join(".out.partial-mine")).unwrap();
            std::fs::write(d.join(".out.partial-mine/x"), "x").unwrap();
            let lock = File::create(d.join(".out.lock")).unwrap();
            if held {
                lock.try_lock().unwrap();
            }
            lock
        };
        let names = || {
            let mut v: Vec<String> = std::fs::read_dir(d)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            v.sort();
            v
        };
        let other_run = make(true);
        assert!(!clean_up_after_dead_run(&d.join("out")).unwrap());
        assert_eq!(names().len(), 4, "{:?}", names());
        drop(other_run);
        let _file = make(false);
        assert!(clean_up_after_dead_run(&d.join("out")).unwrap());
        assert_eq!(names(), [".out.partial-mine"]);
        assert!(!clean_up_after_dead_run(&d.join("gone/out")).unwrap());
        assert!(!d.join("gone").exists());
    }

    #[test]
    fn names_that_are_not_folders_are_refused() {
        for p in [".", "..", "/", "a/..", ""] {
            assert!(final_name(Path::new(p)).is_none(), "{p}");
        }
        assert_eq!(final_name(Path::new("a/b")).as_deref(), Some("b"));
    }
}
