//! The output folder: dbbcal replaces only what it can prove it wrote, and a run leaves `OUT`
//! entirely old or entirely new.
//!
//! The life of a run's output (`docs/guarantees.md`):
//! 1. `OutputTarget::claim`, before any work: `OUT` and `OUT.prev` are refused unless each is
//!    absent, an empty folder, or a folder holding [`MARKER`] and nothing the marker does not
//!    list (its `files`; a marker without a list, from an older version, is judged by the names
//!    dbbcal writes); refused too when `OUT` is a symbolic link, a file, the working or home
//!    folder, a mount point, or overlaps the campaign (after resolving symlinks and `..`, by path
//!    and by device and inode, with everything a run may replace or remove). The claim takes a
//!    lock (an advisory `flock`, released by the kernel if the process dies) so that a second run
//!    refuses at once; `OUT` and its `.prev` generations share one lock (`out`, `out.prev`,
//!    `out.prev.prev` all lock `.out.lock`), because a run on `out` replaces `out.prev`.
//! 2. `OutputTarget::write`: removes the partial folders of dead runs, builds the new output in
//!    `.OUT.partial-<pid>` (the marker first, rewritten last with the list of every file and
//!    folder written), fsyncs every file and folder, then swaps it into place: the new output
//!    first takes `OUT.prev`'s place, then is exchanged with `OUT`, so the previous output never
//!    sits under a name a run removes; the generation before is removed last. On Linux each
//!    exchange is one `renameat2(RENAME_EXCHANGE)`, so `OUT` never vanishes, even for a moment.
//! 3. Ctrl-C / SIGTERM / SIGHUP during the run: the partial folder and the lock are removed and
//!    the old output is untouched ([`install_signal_handlers`]).
//! 4. A run that died without cleaning up (a crash in a dependency, the OOM killer): its
//!    supervisor removes the partial folder and the lock ([`clean_up_after_dead_run`],
//!    `crate::supervise`), else the next run does.
//!
//! `location` resolves where an output may go and what a run may replace, `refusal` says why a
//! location is refused, `lock` holds the lock and the signal clean-up; stderr lines never panic.
//! `fault` lets the crash tests kill the process or fail a write at every step.
//!
//! The JSON formats live here too, each a typed record built from core's results (`From`, the
//! same field names in the same order), converting them to text in one place: `summary`
//! (`summary.json`; its `quality`: `quality`), `inputs` (`inputs.json` and every record's
//! `inputs`), `diagnosis` (`diagnosis.json`), `before_after`, `match_study`, `stage_records`
//! (`calibration.json`, `compensation.json`, `acceptance.json`, with `calibration`,
//! `compensation`, `acceptance`), `device_record` (`device.json`, `device_errors.parquet`), the
//! machine kinds' records (`kind_record`: their shared head; `axis`, `probe`, `roll`,
//! `volumetric`), and the controller tables (`controller`, `axis_tables`).

pub(crate) mod acceptance;
pub(crate) mod axis;
pub(crate) mod axis_tables;
pub(crate) mod before_after;
pub(crate) mod calibration;
pub(crate) mod compensation;
pub mod controller;
pub(crate) mod device_record;
pub(crate) mod diagnosis;
pub(crate) mod fault;
pub(crate) mod inputs;
pub(crate) mod kind_record;
mod location;
mod lock;
pub(crate) mod match_study;
pub(crate) mod probe;
pub(crate) mod quality;
mod refusal;
pub(crate) mod roll;
pub(crate) mod stage_records;
pub(crate) mod summary;
pub(crate) mod volumetric;
use location::*;
pub use lock::install_signal_handlers;
use lock::*;
use refusal::Refusal;

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
    /// Every file and folder (a trailing `/`) dbbcal wrote into the folder, relative paths,
    /// sorted; the marker itself is not listed. Written when the output is complete (absent in a
    /// partial folder being built, and in outputs of versions before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) files: Option<Vec<String>>,
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
            files: None,
        }
    }
}

/// The marker dbbcal wrote in `dir`, if any (read from a regular file of at most 16 MB).
fn read_marker(dir: &Path) -> Option<Marker> {
    let path = dir.join(MARKER);
    let meta = std::fs::symlink_metadata(&path).ok()?;
    if !meta.is_file() || meta.len() > 16 << 20 {
        return None;
    }
    let text = std::fs::read_to_string(path).ok()?;
    serde_json::from_str::<Marker>(&text)
        .ok()
        .filter(|m| m.tool == "dbbcal")
}

/// Names an output of a version without a file list in its marker may hold (top level; and
/// `figures/*.png`).
const LEGACY_OUTPUT_FILES: [&str; 16] = [
    "summary.json",
    "inputs.json",
    "models.parquet",
    "models.csv",
    "diagnosis.json",
    "before_after.json",
    "match_study.json",
    "calibration.json",
    "compensation.json",
    "compensated.parquet",
    "compensated.csv",
    "acceptance.json",
    "report.md",
    "index.html",
    "figures/",
    MARKER,
];

/// Every entry under `dir` (not following symbolic links): relative `/`-separated paths,
/// folders with a trailing `/`, sorted. At most `limit` entries (`None` beyond).
fn tree_entries(dir: &Path, limit: usize) -> std::io::Result<Option<Vec<String>>> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>, limit: usize) -> std::io::Result<bool> {
        for e in std::fs::read_dir(dir)? {
            let e = e?;
            let path = e.path();
            let rel = path
                .strip_prefix(root)
                .unwrap_or(&path)
                .to_string_lossy()
                .replace('\\', "/");
            if out.len() >= limit {
                return Ok(false);
            }
            if e.file_type()?.is_dir() {
                out.push(format!("{rel}/"));
                if !walk(root, &path, out, limit)? {
                    return Ok(false);
                }
            } else {
                out.push(rel);
            }
        }
        Ok(true)
    }
    let mut out = Vec::new();
    if !walk(dir, dir, &mut out, limit)? {
        return Ok(None);
    }
    out.sort();
    Ok(Some(out))
}

/// Whether `dir` is wholly dbbcal's: it holds the marker, and nothing but what the marker lists
/// (or, for a marker without a list, the names an output may hold). `Err` says why not.
fn dbbcal_output(dir: &Path) -> Result<(), Refusal> {
    let Some(marker) = read_marker(dir) else {
        return Err(Refusal::NoMarker);
    };
    let entries = match tree_entries(dir, 100_000) {
        Ok(Some(e)) => e,
        Ok(None) => return Err(Refusal::TooManyFiles),
        Err(e) => return Err(Refusal::Unlistable(e)),
    };
    let listed = |rel: &str| match &marker.files {
        Some(files) => rel == MARKER || files.binary_search_by(|f| f.as_str().cmp(rel)).is_ok(),
        None => {
            LEGACY_OUTPUT_FILES.contains(&rel)
                || rel
                    .strip_prefix("figures/")
                    .is_some_and(|f| f.ends_with(".png") && !f.contains('/'))
        }
    };
    match entries.iter().find(|rel| !listed(rel)) {
        None => Ok(()),
        Some(rel) => Err(Refusal::NotWritten { file: rel.clone() }),
    }
}

/// Whether a partial folder is dbbcal's: empty, or holding the marker (and, once complete,
/// nothing but what it lists).
fn dbbcal_partial(dir: &Path) -> bool {
    let Ok(meta) = std::fs::symlink_metadata(dir) else {
        return false;
    };
    if !meta.is_dir() {
        return false;
    }
    let empty = std::fs::read_dir(dir).is_ok_and(|mut d| d.next().is_none());
    empty
        || match read_marker(dir) {
            Some(m) if m.files.is_some() => dbbcal_output(dir).is_ok(),
            Some(_) => true,
            None => false,
        }
}

/// `text` with control characters escaped (`\n`, `\u{1b}`), for one-line messages.
pub fn escape(text: &str) -> String {
    if !text.chars().any(char::is_control) {
        return text.to_string();
    }
    text.chars()
        .flat_map(|c| {
            if c.is_control() {
                c.escape_default().collect::<Vec<_>>()
            } else {
                vec![c]
            }
        })
        .collect()
}

/// One line on stderr; a stderr that is gone (a closed pipe) is no error.
pub(crate) fn say(line: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// A path for a one-line message: control characters escaped.
pub fn shown(path: &Path) -> String {
    escape(&path.display().to_string())
}

/// An output location that passed every check and is locked for this run.
#[derive(Debug)]
pub(crate) struct OutputTarget {
    out: PathBuf,
    parent: PathBuf,
    name: String,
    lock_path: PathBuf,
    lock: File,
    /// The folders the claim created above `OUT` (deepest first): removed again, when empty,
    /// if the run writes nothing.
    created: Vec<PathBuf>,
    written: bool,
}

/// The lock file of the output `name` in `parent`: one for a name and its `.prev` generations
/// (`out`, `out.prev`, `out.prev.prev` share `.out.lock`), so a run on `out.prev` and one on
/// `out`, which would replace it, never run together.
fn lock_file(parent: &Path, name: &str) -> PathBuf {
    let mut base = name;
    while let Some(b) = base.strip_suffix(".prev").filter(|b| !b.is_empty()) {
        base = b;
    }
    parent.join(format!(".{base}.lock"))
}

/// The partial folder this run builds its output in.
fn own_partial(parent: &Path, name: &str) -> PathBuf {
    parent.join(format!(".{name}.partial-{}", crate::supervise::run_pid()))
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
        if name.len() > 200 {
            return Err(refused(format!(
                "the folder name is {} bytes long; at most 200 (its partial folder's name must fit the file system's 255)",
                name.len()
            )));
        }
        let resolved =
            resolve(out).map_err(|e| refused(format!("cannot resolve the path: {e}")))?;
        if home_dir().is_some_and(|home| resolved == home) {
            return Err(refused("that is the home folder".into()));
        }
        let parent = parent_of(out);
        check_overlap(&resolved, &parent, &name, campaign).map_err(|r| refused(r.to_string()))?;
        check_replaceable(out, "")?;
        let prev = sibling(out, &format!("{name}.prev"));
        check_replaceable(&prev, " (the previous output, kept as OUT.prev)").map_err(
            |e| match e {
                OutputError::Refused { why, .. } => refused(format!("{}: {why}", shown(&prev))),
                other => other,
            },
        )?;
        check_mount_point(&resolved).map_err(|r| refused(r.to_string()))?;
        let partial = own_partial(&parent, &name);
        if std::fs::symlink_metadata(&partial).is_ok() && !dbbcal_partial(&partial) {
            return Err(refused(format!(
                "{} exists and is not a partial folder of dbbcal (it would be replaced); move it elsewhere",
                shown(&partial)
            )));
        }
        let created = create_parents(&parent).map_err(|e| match e.kind() {
            std::io::ErrorKind::PermissionDenied | std::io::ErrorKind::ReadOnlyFilesystem => {
                refused(format!("cannot create {}: {e}", shown(&parent)))
            }
            _ => OutputError::io(&parent)(e),
        })?;
        let undo_parents = |e: OutputError| {
            remove_created(&created);
            e
        };
        check_writable(&parent)
            .map_err(|r| refused(r.to_string()))
            .map_err(undo_parents)?;
        let lock_path = lock_file(&parent, &name);
        crate::supervise::note(crate::supervise::Note::Output(out));
        // A signal waits until the lock is taken and known to the handler, which removes it.
        let _signals_wait = CRITICAL.lock().unwrap_or_else(|e| e.into_inner());
        let lock = take_lock(&lock_path)
            .map_err(|e| match e {
                LockError::Busy => OutputError::Busy {
                    path: out.to_path_buf(),
                    lock: lock_path.clone(),
                },
                LockError::NotOurs(why) => refused(format!("{}: {why}", shown(&lock_path))),
                LockError::Io(source) => OutputError::Io {
                    path: lock_path.clone(),
                    source,
                },
            })
            .map_err(undo_parents)?;
        *HELD_LOCK.lock().unwrap_or_else(|e| e.into_inner()) = Some(lock_path.clone());
        Ok(OutputTarget {
            out: out.to_path_buf(),
            parent,
            name,
            lock_path,
            lock,
            created,
            written: false,
        })
    }

    pub(crate) fn path(&self) -> &Path {
        &self.out
    }

    /// Build the new output with `build` (given the partial folder, which already holds the
    /// marker) and swap it into place. On any error the partial folder is removed and `OUT`
    /// and `OUT.prev` are as they were.
    pub(crate) fn write<E>(
        mut self,
        marker: &Marker,
        build: impl FnOnce(&Path) -> Result<(), E>,
    ) -> Result<(), WriteFailure<E>> {
        self.written = true;
        self.remove_dead_partials();
        let partial = own_partial(&self.parent, &self.name);
        if std::fs::symlink_metadata(&partial).is_ok() {
            if !dbbcal_partial(&partial) {
                return Err(WriteFailure::Output(OutputError::Refused {
                    path: self.out.clone(),
                    why: format!("{} appeared and is not dbbcal's", shown(&partial)),
                }));
            }
            let _ = std::fs::remove_dir_all(&partial);
        }
        in_progress(Some(Cleanup {
            partial: partial.clone(),
            lock: self.lock_path.clone(),
        }));
        let result = self.fill(&partial, marker, build).and_then(|()| {
            sync_tree(&partial).map_err(WriteFailure::Output)?;
            self.swap(&partial).map_err(WriteFailure::Output)
        });
        if result.is_err() && dbbcal_partial(&partial) {
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
        let marker_text = |m: &Marker| {
            let mut text = serde_json::to_string_pretty(m).expect("the marker serialises");
            text.push('\n');
            text
        };
        write_file(&partial.join(MARKER), marker_text(marker).as_bytes())
            .map_err(WriteFailure::Output)?;
        build(partial).map_err(WriteFailure::Build)?;
        // The marker again, now listing every file written: what a later run may replace.
        let files = tree_entries(partial, usize::MAX)
            .map_err(OutputError::io(partial))
            .map_err(WriteFailure::Output)?
            .unwrap_or_default()
            .into_iter()
            .filter(|f| f != MARKER)
            .collect();
        let complete = Marker {
            files: Some(files),
            ..marker.clone()
        };
        let next = partial.join(format!(".{MARKER}.new"));
        write_file(&next, marker_text(&complete).as_bytes()).map_err(WriteFailure::Output)?;
        let target = partial.join(MARKER);
        fault::point("rename", &target)
            .map_err(OutputError::io(&target))
            .map_err(WriteFailure::Output)?;
        let _step = writing();
        std::fs::rename(&next, &target)
            .map_err(OutputError::io(&target))
            .map_err(WriteFailure::Output)
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

    /// The previous output is never under a name a later run removes: first the new output
    /// takes `OUT.prev`'s place (the one before it goes to the partial folder's name), then it
    /// is exchanged with `OUT`. Killed in between, `OUT` is the old output and `OUT.prev` the new
    /// one; after, `OUT` is new and `OUT.prev` old; the generation before is removed last.
    fn swap_in(&self, partial: &Path) -> Result<(), OutputError> {
        let prev = self.parent.join(format!("{}.prev", self.name));
        let out = &self.out;
        let sync_parent = || sync_dir(&self.parent).map_err(OutputError::io(&self.parent));
        if std::fs::symlink_metadata(out).is_err() {
            fault::point("rename", out).map_err(OutputError::io(out))?;
            std::fs::rename(partial, out).map_err(OutputError::io(out))?;
            return sync_parent();
        }
        let had_prev = std::fs::symlink_metadata(&prev).is_ok();
        if had_prev {
            if let Err(why) = dbbcal_output(&prev) {
                return Err(OutputError::Refused {
                    path: out.clone(),
                    why: format!("{} changed meanwhile: it {why}", shown(&prev)),
                });
            }
            fault::point("exchange", &prev).map_err(OutputError::io(&prev))?;
            if exchange(partial, &prev).is_err() {
                return self.swap_by_renames(partial, &prev);
            }
        } else {
            fault::point("rename", &prev).map_err(OutputError::io(&prev))?;
            std::fs::rename(partial, &prev).map_err(OutputError::io(&prev))?;
        }
        // The new output is in OUT.prev's place; the generation before in `partial`.
        let undo = |e: OutputError| {
            let _ = if had_prev {
                exchange(partial, &prev)
            } else {
                std::fs::rename(&prev, partial)
            };
            e
        };
        sync_parent().map_err(undo)?;
        fault::point("exchange", out)
            .map_err(OutputError::io(out))
            .map_err(undo)?;
        exchange(&prev, out)
            .map_err(OutputError::io(out))
            .map_err(undo)?;
        sync_parent()?;
        if had_prev {
            fault::kill_point("remove the output before OUT.prev", partial);
            if let Err(e) = std::fs::remove_dir_all(partial) {
                tracing::warn!(
                    "the output before the previous one stays in {}: {e}",
                    partial.display()
                );
            }
        }
        sync_parent()
    }

    /// No atomic exchange here: two renames. A crash between them leaves the old output in
    /// OUT.prev and no OUT; nothing is lost.
    fn swap_by_renames(&self, partial: &Path, prev: &Path) -> Result<(), OutputError> {
        let out = &self.out;
        fault::point("remove OUT.prev", prev).map_err(OutputError::io(prev))?;
        std::fs::remove_dir_all(prev).map_err(OutputError::io(prev))?;
        std::fs::rename(out, prev).map_err(OutputError::io(out))?;
        fault::kill_point("rename into place", out);
        std::fs::rename(partial, out).map_err(OutputError::io(out))?;
        sync_dir(&self.parent).map_err(OutputError::io(&self.parent))
    }
}

impl Drop for OutputTarget {
    /// The lock file goes while the lock is still held (a run waiting on the old file then sees
    /// it replaced and locks the new one; see [`take_lock`]); then the parent folders the claim
    /// made, when nothing was written.
    fn drop(&mut self) {
        let _signals_wait = CRITICAL.lock().unwrap_or_else(|e| e.into_inner());
        *HELD_LOCK.lock().unwrap_or_else(|e| e.into_inner()) = None;
        let _ = std::fs::remove_file(&self.lock_path);
        let _ = self.lock.unlock();
        if !self.written {
            remove_created(&self.created);
        }
    }
}

/// `dir` and its missing ancestors created; returns those created, deepest first.
fn create_parents(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut missing = Vec::new();
    let mut d = dir;
    while std::fs::symlink_metadata(d).is_err() {
        missing.push(d.to_path_buf());
        match d.parent().filter(|p| !p.as_os_str().is_empty()) {
            Some(p) => d = p,
            None => break,
        }
    }
    std::fs::create_dir_all(dir)?;
    Ok(missing)
}

/// Remove the folders [`create_parents`] made, while empty.
fn remove_created(created: &[PathBuf]) {
    for d in created {
        if std::fs::remove_dir(d).is_err() {
            break;
        }
    }
}

/// The folder that will hold `OUT` must take new entries (a read-only folder or file system is
/// refused before any work, not found at the end).
fn check_writable(parent: &Path) -> Result<(), Refusal> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(parent.as_os_str().as_bytes()).map_err(Refusal::NulInPath)?;
    // SAFETY: a valid NUL-terminated path.
    let rc = unsafe { libc::access(c.as_ptr(), libc::W_OK | libc::X_OK) };
    if rc == 0 {
        Ok(())
    } else {
        Err(Refusal::NotWritable {
            parent: parent.to_path_buf(),
            error: std::io::Error::last_os_error(),
        })
    }
}

/// `OUT` a mount point (its own file system or a bind mount): it cannot be renamed, so it is
/// refused before any work.
fn check_mount_point(resolved: &Path) -> Result<(), Refusal> {
    let Ok(meta) = std::fs::symlink_metadata(resolved) else {
        return Ok(());
    };
    use std::os::unix::fs::MetadataExt;
    let parent_dev = resolved
        .parent()
        .and_then(|p| std::fs::metadata(p).ok())
        .map(|m| m.dev());
    let own_fs = parent_dev.is_some_and(|d| d != meta.dev());
    let listed = std::fs::read_to_string("/proc/self/mountinfo").is_ok_and(|info| {
        info.lines().any(|l| {
            l.split(' ')
                .nth(4)
                .is_some_and(|m| Path::new(&unescape_mountinfo(m)) == resolved)
        })
    });
    if own_fs || listed {
        Err(Refusal::MountPoint)
    } else {
        Ok(())
    }
}

/// A path field of `/proc/self/mountinfo` (space, tab, newline and `\` are octal escapes).
fn unescape_mountinfo(field: &str) -> String {
    let b = field.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'\\' && i + 3 < b.len() {
            if let Ok(v) = u8::from_str_radix(&field[i + 1..i + 4], 8) {
                out.push(v);
                i += 4;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Partial folders of runs that died, beside the output `name` in `parent` (the caller holds the
/// lock, so no live run owns one): only `.OUT.partial-<digits>` folders that are empty or hold
/// the marker (and nothing it does not list, once complete).
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
        if !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()) && dbbcal_partial(&path) {
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
    let lock_path = lock_file(&parent, &name);
    let lock = match take_lock(&lock_path) {
        Ok(lock) => lock,
        Err(LockError::Busy | LockError::NotOurs(_)) => return Ok(false),
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

/// Create the folder `path` inside a partial folder, as one write step. `create_dir`, not
/// `_all`: a partial folder a signal removed is not made again.
pub(crate) fn create_dir(path: &Path) -> Result<(), OutputError> {
    fault::point("write", path).map_err(OutputError::io(path))?;
    let _step = writing();
    std::fs::create_dir(path).map_err(OutputError::io(path))
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

#[cfg(test)]
mod tests;
