//! A crash in a dependency that no `catch_unwind` can catch (issue 14, "never lose a byte").
//!
//! A parquet decoder can be made to abort the process by a corrupt page (polars' decoder asks for
//! an allocation of ~2.3e18 bytes on one, and Rust's allocation-failure handler aborts). Nothing
//! inside the process can turn that into a line naming the file (`dbbcal-io`'s guard catches
//! panics only). So the commands that read campaign parquet run in a supervised child:
//!
//! * the **supervisor** (the process the user started) re-executes its own binary with
//!   `ENV` set, forwards SIGINT, SIGTERM and SIGHUP to it, waits, and ends with the child's
//!   exit code ([`run_self_supervised`], [`Ending`]). It reads nothing itself.
//! * the **child** ([`child_init`]) writes *breadcrumbs* into a pipe the supervisor passes it:
//!   before a parquet file is decoded, which file(s) (the read of every file goes through
//!   `io::guard`, which calls `reading`); when the decode
//!   is over; the output folder it claimed and where its swap stands ([`note`]). Several files
//!   may be decoded at once (ingest's consumer threads): the trail is the *set* in progress.
//! * when the child dies from a signal that is not an interrupt (SIGABRT, SIGSEGV, SIGBUS,
//!   SIGKILL from the OOM killer…), the supervisor reads the trail: the files that were being
//!   decoded ([`Death::reading`]), the output to clean up ([`Death::output`],
//!   `output::clean_up_after_dead_run`), and says one line ([`Crash`]).
//!
//! A write into a pipe of at most `PIPE_BUF` bytes completes before the `write` returns, so a
//! breadcrumb written before a decode is in the pipe even if the very next instruction aborts.
//! Cost on the normal path: one fork/exec and, per decoded file, two small `write`s.
//!
//! [`SupervisedAlloc`] is the binary's global allocator wrapper: in the supervised child an
//! allocation larger than the machine's memory that fails ends the process with SIGABRT at
//! once, without Rust's own "memory allocation of N bytes failed" line, so the user reads one
//! line (the supervisor's), and the trail says how many bytes were asked for.
//!
//! # How it works
//!
//! - The binary allocates with mimalloc (`src/main.rs`; why in `Cargo.toml`), through
//!   `supervise::SupervisedAlloc`, which only looks at a null result.
//! - Supervision costs one fork/exec of the binary and, per file decoded, two small writes into a
//!   pipe (measured in `bench/README.md`).
//! - When a child dies while several files were being decoded, [`probe`] decodes each alone in a
//!   supervised child of its own, so the line names the file that crashes.

use std::alloc::{GlobalAlloc, Layout};
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::fmt;
use std::io::Read;
use std::os::fd::{FromRawFd, RawFd};
use std::os::unix::ffi::{OsStrExt, OsStringExt};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex, OnceLock};

/// Set in the child's environment: `<supervisor pid>:<breadcrumb fd>`.
pub const ENV: &str = "DBBCAL_SUPERVISOR";

/// Set in a probe child's environment (see [`probe`]): the one file it decodes.
pub const PROBE_ENV: &str = "DBBCAL_PROBE";

// ---------------------------------------------------------------- the child's side

/// The breadcrumb pipe of a supervised child.
struct Channel {
    fd: RawFd,
    supervisor: u32,
    /// One record at a time (a record longer than `PIPE_BUF`, a long path, is written in parts).
    lock: Mutex<()>,
}

static CHANNEL: OnceLock<Channel> = OnceLock::new();
static NEXT_READING: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(1);

/// Record tags.
const BEGIN: u8 = b'B';
const END: u8 = b'E';
const OUTPUT: u8 = b'O';
const SWAP_BEGUN: u8 = b'W';
const SWAP_DONE: u8 = b'R';
const FAULT_KILL: u8 = b'K';
const ALLOCATION: u8 = b'A';
/// tag (1) + id (4) + payload length (4).
const HEADER: usize = 9;

/// Called first in `main`: when `ENV` names this process' parent and an open pipe, this is a
/// supervised child and breadcrumbs go there. Otherwise (the variable absent, or inherited from
/// some other process) nothing changes and `false` is returned.
pub fn child_init() -> bool {
    let Some(value) = std::env::var_os(ENV) else {
        return false;
    };
    let Some((supervisor, fd)) = value
        .to_str()
        .and_then(|v| v.split_once(':'))
        .and_then(|(p, f)| Some((p.parse::<u32>().ok()?, f.parse::<RawFd>().ok()?)))
    else {
        return false;
    };
    // SAFETY: plain system calls on an fd number; fstat writes into a zeroed struct.
    let is_our_pipe = unsafe {
        let mut st: libc::stat = std::mem::zeroed();
        libc::getppid() as u32 == supervisor
            && fd > 2
            && libc::fstat(fd, &mut st) == 0
            && st.st_mode & libc::S_IFMT == libc::S_IFIFO
    };
    if !is_our_pipe {
        return false;
    }
    // SAFETY: fcntl on an fd we checked is open; prctl with constant arguments.
    unsafe {
        // Nothing this process starts inherits the pipe (the supervisor sees EOF when we die).
        libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC);
        // The supervisor killed (e.g. `kill -9` of the pid the user knows): stop cleanly, as
        // on SIGTERM, rather than run on unseen.
        #[cfg(target_os = "linux")]
        libc::prctl(
            libc::PR_SET_PDEATHSIG,
            libc::SIGTERM as libc::c_ulong,
            0,
            0,
            0,
        );
    }
    // SAFETY: getppid has no preconditions.
    if unsafe { libc::getppid() } as u32 != supervisor {
        return false; // the supervisor died before PDEATHSIG was set
    }
    CHANNEL
        .set(Channel {
            fd,
            supervisor,
            lock: Mutex::new(()),
        })
        .is_ok()
}

/// Whether this process is a supervised child.
pub fn is_supervised() -> bool {
    CHANNEL.get().is_some()
}

/// The pid of the run as the user sees it: the supervisor's in a supervised child, else this
/// process'. Partial output folders are named after it (`.OUT.partial-<pid>`).
pub fn run_pid() -> u32 {
    CHANNEL
        .get()
        .map_or_else(std::process::id, |c| c.supervisor)
}

/// Write `bytes` whole (a pipe takes up to `PIPE_BUF` bytes in one piece). Errors (the
/// supervisor gone: EPIPE, SIGPIPE being ignored) are dropped: breadcrumbs are advice.
fn write_all(fd: RawFd, mut bytes: &[u8]) {
    while !bytes.is_empty() {
        // SAFETY: writing from a live slice to an fd.
        let n = unsafe { libc::write(fd, bytes.as_ptr().cast(), bytes.len()) };
        if n < 0 {
            if std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            return;
        }
        bytes = &bytes[n as usize..];
    }
}

fn record(tag: u8, id: u32, payload: &[u8]) -> Vec<u8> {
    let mut r = Vec::with_capacity(HEADER + payload.len());
    r.push(tag);
    r.extend_from_slice(&id.to_le_bytes());
    r.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    r.extend_from_slice(payload);
    r
}

fn send(tag: u8, id: u32, payload: &[u8]) {
    if let Some(c) = CHANNEL.get() {
        let r = record(tag, id, payload);
        let _one_at_a_time = c.lock.lock().unwrap_or_else(|e| e.into_inner());
        write_all(c.fd, &r);
    }
}

/// The decode of some files, in progress until dropped (see [`reading`]).
#[must_use]
pub struct Reading(Option<u32>);

impl Drop for Reading {
    fn drop(&mut self) {
        if let Some(id) = self.0 {
            send(END, id, &[]);
        }
    }
}

/// Tell the supervisor that `paths` are being decoded until the returned value is dropped
/// (also when unwinding). Unsupervised: nothing, at the cost of one atomic load.
pub fn reading<'a>(paths: impl IntoIterator<Item = &'a Path>) -> Reading {
    if CHANNEL.get().is_none() {
        return Reading(None);
    }
    let id = NEXT_READING.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut payload = Vec::new();
    for p in paths {
        if !payload.is_empty() {
            payload.push(0);
        }
        payload.extend_from_slice(p.as_os_str().as_bytes());
    }
    send(BEGIN, id, &payload);
    Reading(Some(id))
}

/// What the output code tells the supervisor (`output::OutputTarget`, `output::fault`).
#[derive(Debug, Clone, Copy)]
pub enum Note<'a> {
    /// The output folder about to be locked: cleaned up after a crash.
    Output(&'a Path),
    /// The swap into place begins.
    SwapBegun,
    /// The new output is in place.
    SwapDone,
    /// `DBBCAL_FAULT=kill@K` kills the process now: the supervisor dies too, like a power cut,
    /// cleaning up nothing (the crash tests check what the next run finds).
    FaultKill,
}

/// Tell the supervisor (nothing when unsupervised).
pub fn note(n: Note<'_>) {
    match n {
        Note::Output(p) => send(OUTPUT, 0, p.as_os_str().as_bytes()),
        Note::SwapBegun => send(SWAP_BEGUN, 0, &[]),
        Note::SwapDone => send(SWAP_DONE, 0, &[]),
        Note::FaultKill => send(FAULT_KILL, 0, &[]),
    }
}

/// The binary's global allocator, around `A` (mimalloc): see the module doc. Every call is
/// `A`'s; only a null returned in a supervised child for more bytes than the machine has is
/// turned into an immediate, silent SIGABRT (no valid campaign asks for that: it is a corrupt
/// length). Anything else is as `A` does it: `try_reserve` still gets its error.
pub struct SupervisedAlloc<A>(pub A);

// SAFETY: every method delegates to `A` with the same arguments and returns its result.
unsafe impl<A: GlobalAlloc> GlobalAlloc for SupervisedAlloc<A> {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { self.0.alloc(layout) };
        if p.is_null() {
            failed(layout.size());
        }
        p
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { self.0.alloc_zeroed(layout) };
        if p.is_null() {
            failed(layout.size());
        }
        p
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { self.0.dealloc(ptr, layout) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { self.0.realloc(ptr, layout, new_size) };
        if p.is_null() {
            failed(new_size);
        }
        p
    }
}

/// An allocation of `size` bytes failed. Must not allocate.
#[cold]
#[inline(never)]
fn failed(size: usize) {
    let Some(c) = CHANNEL.get() else {
        return;
    };
    // SAFETY: sysconf has no preconditions.
    let memory = unsafe {
        let pages = libc::sysconf(libc::_SC_PHYS_PAGES);
        let page = libc::sysconf(libc::_SC_PAGESIZE);
        (pages.max(0) as u64).saturating_mul(page.max(0) as u64)
    };
    if memory == 0 || (size as u64) <= memory {
        return;
    }
    let mut r = [0u8; HEADER + 8];
    r[0] = ALLOCATION;
    r[5..9].copy_from_slice(&8u32.to_le_bytes());
    r[9..].copy_from_slice(&(size as u64).to_le_bytes());
    // A record half-written by another thread is in the way only while it holds the lock.
    if let Ok(_g) = c.lock.try_lock() {
        write_all(c.fd, &r);
    }
    // SAFETY: abort has no preconditions; it raises SIGABRT without running any Rust code.
    unsafe { libc::abort() }
}

// ---------------------------------------------------------------- the supervisor's side

/// Where the child's output swap stood when it died.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Swap {
    /// The swap had not begun: `OUT` is the previous output.
    #[default]
    NotBegun,
    /// The swap had begun but not ended: `OUT` and `OUT.prev` may be mid-exchange.
    Begun,
    /// The swap was over: `OUT` is the new output.
    Done,
}

/// The child's breadcrumbs, as read so far.
#[derive(Debug, Default)]
struct Trail {
    reading: BTreeMap<u32, Vec<PathBuf>>,
    output: Option<PathBuf>,
    swap: Swap,
    allocation: Option<u64>,
    fault_kill: bool,
}

impl Trail {
    /// Apply every whole record at the front of `buf`; returns the bytes used.
    fn apply(&mut self, buf: &[u8]) -> usize {
        let mut at = 0;
        while buf.len() - at >= HEADER {
            let tag = buf[at];
            let id = u32::from_le_bytes(buf[at + 1..at + 5].try_into().expect("4 bytes"));
            let len = u32::from_le_bytes(buf[at + 5..at + 9].try_into().expect("4 bytes"));
            let Some(end) = (at + HEADER).checked_add(len as usize) else {
                break;
            };
            if end > buf.len() {
                break;
            }
            let payload = &buf[at + HEADER..end];
            let path = |b: &[u8]| PathBuf::from(OsString::from_vec(b.to_vec()));
            match tag {
                BEGIN => {
                    let paths = payload.split(|&b| b == 0).map(path).collect();
                    self.reading.insert(id, paths);
                }
                END => {
                    self.reading.remove(&id);
                }
                OUTPUT => self.output = Some(path(payload)),
                SWAP_BEGUN => self.swap = Swap::Begun,
                SWAP_DONE => self.swap = Swap::Done,
                FAULT_KILL => self.fault_kill = true,
                ALLOCATION => {
                    self.allocation = payload.try_into().ok().map(u64::from_le_bytes);
                }
                _ => {}
            }
            at = end;
        }
        at
    }
}

/// A child process to signal only while it has not been reaped (its pid cannot be reused).
pub struct ChildHandle {
    pid: u32,
    alive: Mutex<bool>,
}

impl ChildHandle {
    /// Send `signal` to the child if it has not been reaped yet; whether it was sent.
    pub(crate) fn signal(&self, signal: i32) -> bool {
        let alive = self.alive.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: a signal to our own, not yet reaped child.
        *alive && unsafe { libc::kill(self.pid as libc::pid_t, signal) } == 0
    }
}

/// A running supervised child (see [`spawn`]).
pub struct Supervised {
    child: std::process::Child,
    handle: Arc<ChildHandle>,
    trail: std::thread::JoinHandle<Trail>,
}

/// Start `cmd` as a supervised child: a breadcrumb pipe is passed to it ([`ENV`]) and read on
/// a thread. The child must call [`child_init`].
pub fn spawn(cmd: &mut Command) -> std::io::Result<Supervised> {
    let mut fds = [0 as RawFd; 2];
    // SAFETY: pipe2/pipe write two fds into the array; fcntl on those fds.
    #[cfg(target_os = "linux")]
    let failed = unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) } != 0;
    #[cfg(not(target_os = "linux"))]
    let failed = unsafe {
        libc::pipe(fds.as_mut_ptr()) != 0
            || fds
                .iter()
                .any(|&fd| libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC) == -1)
    };
    if failed {
        return Err(std::io::Error::last_os_error());
    }
    let [read_fd, write_fd] = fds;
    // SAFETY: both fds are new and owned here; each is closed once, by its File.
    let (reader, writer) = unsafe {
        (
            std::fs::File::from_raw_fd(read_fd),
            std::fs::File::from_raw_fd(write_fd),
        )
    };
    cmd.env(ENV, format!("{}:{write_fd}", std::process::id()));
    // SAFETY: between fork and exec only fcntl, which is async-signal-safe. Clearing
    // close-on-exec in the child alone keeps the write end out of any other process the
    // supervisor (a test harness, say) starts meanwhile.
    unsafe {
        cmd.pre_exec(move || {
            if libc::fcntl(write_fd, libc::F_SETFD, 0) == -1 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let child = cmd.spawn()?;
    drop(writer); // the child holds the only write end: EOF when it dies
    let trail = std::thread::spawn(move || read_trail(reader));
    let handle = Arc::new(ChildHandle {
        pid: child.id(),
        alive: Mutex::new(true),
    });
    Ok(Supervised {
        child,
        handle,
        trail,
    })
}

fn read_trail(mut reader: std::fs::File) -> Trail {
    let mut trail = Trail::default();
    let mut buf = Vec::new();
    let mut chunk = [0u8; 4096];
    loop {
        match reader.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => {
                buf.extend_from_slice(&chunk[..n]);
                let used = trail.apply(&buf);
                buf.drain(..used);
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(_) => break,
        }
    }
    trail
}

/// How a supervised child ended.
#[derive(Debug)]
pub enum Ending {
    /// It exited with this code (it said what there was to say).
    Exited(i32),
    /// It died from SIGINT, SIGTERM or SIGHUP before its own handler could run.
    Interrupted(Death),
    /// It died from any other signal.
    Crashed(Death),
}

/// A child that died from a signal, and what its trail says.
#[derive(Debug, Clone)]
pub struct Death {
    /// The signal that killed it.
    pub signal: i32,
    /// The files it was decoding (each once, sorted).
    pub reading: Vec<PathBuf>,
    /// The output folder it had claimed.
    pub output: Option<PathBuf>,
    pub(crate) swap: Swap,
    /// The bytes of the allocation that failed ([`SupervisedAlloc`]).
    pub(crate) allocation: Option<u64>,
    /// It killed itself at an injected fault point (`DBBCAL_FAULT=kill@K`).
    pub fault_kill: bool,
}

impl Supervised {
    pub(crate) fn handle(&self) -> Arc<ChildHandle> {
        self.handle.clone()
    }

    /// [`Supervised::wait`], killing the child (SIGKILL) if it has not ended within `limit`;
    /// whether it was killed so.
    pub fn wait_at_most(self, limit: std::time::Duration) -> std::io::Result<(Ending, bool)> {
        use std::sync::atomic::{AtomicBool, Ordering};
        let (handle, done, late) = (
            self.handle(),
            Arc::new(AtomicBool::new(false)),
            Arc::new(AtomicBool::new(false)),
        );
        let watchdog = {
            let (done, late) = (done.clone(), late.clone());
            std::thread::spawn(move || {
                let start = std::time::Instant::now();
                while !done.load(Ordering::SeqCst) {
                    if start.elapsed() > limit {
                        late.store(true, Ordering::SeqCst);
                        handle.signal(libc::SIGKILL);
                        return;
                    }
                    std::thread::sleep(std::time::Duration::from_millis(20));
                }
            })
        };
        let ending = self.wait();
        done.store(true, Ordering::SeqCst);
        let _ = watchdog.join();
        Ok((ending?, late.load(Ordering::SeqCst)))
    }

    /// Wait for the child to end, then read the rest of its trail.
    pub fn wait(mut self) -> std::io::Result<Ending> {
        // Wait without reaping: until `alive` is false the pid stays the child's, so a signal
        // forwarded meanwhile cannot reach another process.
        loop {
            // SAFETY: waitid writes into a zeroed siginfo_t.
            let rc = unsafe {
                let mut info: libc::siginfo_t = std::mem::zeroed();
                libc::waitid(
                    libc::P_PID,
                    self.handle.pid as libc::id_t,
                    &mut info,
                    libc::WEXITED | libc::WNOWAIT,
                )
            };
            if rc == 0 {
                break;
            }
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::Interrupted {
                return Err(e);
            }
        }
        *self.handle.alive.lock().unwrap_or_else(|e| e.into_inner()) = false;
        let status = self.child.wait()?;
        let trail = self
            .trail
            .join()
            .map_err(|_| std::io::Error::other("the breadcrumb reader panicked"))?;
        if let Some(code) = status.code() {
            return Ok(Ending::Exited(code));
        }
        let signal = status.signal().unwrap_or(0);
        let mut reading: Vec<PathBuf> = trail.reading.into_values().flatten().collect();
        reading.sort();
        reading.dedup();
        let death = Death {
            signal,
            reading,
            output: trail.output,
            swap: trail.swap,
            allocation: trail.allocation,
            fault_kill: trail.fault_kill,
        };
        Ok(
            if [libc::SIGINT, libc::SIGTERM, libc::SIGHUP].contains(&signal) {
                Ending::Interrupted(death)
            } else {
                Ending::Crashed(death)
            },
        )
    }
}

/// Re-run this very program (same arguments, same environment plus `ENV`) as a supervised
/// child, forwarding SIGINT, SIGTERM and SIGHUP to it, and wait for it. A Ctrl-C on a terminal
/// reaches both processes: this one then only forwards (the child sees the signal twice, which
/// its handler takes as one) and outlives the child. An error: the child could not be started
/// (the caller runs the command itself, unsupervised).
pub fn run_self_supervised() -> std::io::Result<Ending> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    enum Target {
        NotYet(Vec<i32>),
        Running(Arc<ChildHandle>),
    }
    let target = Arc::new(Mutex::new(Target::NotYet(Vec::new())));
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    let forwarding = target.clone();
    std::thread::spawn(move || {
        for signal in signals.forever() {
            match &mut *forwarding.lock().unwrap_or_else(|e| e.into_inner()) {
                Target::NotYet(pending) => pending.push(signal),
                Target::Running(child) => {
                    child.signal(signal);
                }
            }
        }
    });
    let mut args = std::env::args_os();
    let mut cmd = this_program()?;
    if let Some(arg0) = args.next() {
        cmd.arg0(arg0);
    }
    cmd.args(args).env_remove(PROBE_ENV);
    let supervised = {
        let mut target = target.lock().unwrap_or_else(|e| e.into_inner());
        let supervised = spawn(&mut cmd)?;
        if let Target::NotYet(pending) = &*target {
            for &signal in pending {
                supervised.handle.signal(signal);
            }
        }
        *target = Target::Running(supervised.handle());
        supervised
    };
    supervised.wait()
}

/// This program, to run again as a child: `/proc/self/exe` (this very binary even if its file
/// was replaced since it started), else [`std::env::current_exe`].
fn this_program() -> std::io::Result<Command> {
    let exe = Path::new("/proc/self/exe");
    Ok(Command::new(if exe.exists() {
        exe.to_path_buf()
    } else {
        std::env::current_exe()?
    }))
}

/// After a scan of several files crashed: decode each of `files` alone, each in a supervised
/// child of this program with [`PROBE_ENV`] set (its `main` calls
/// `io::decode_whole_file`), and return those whose child crashed too (not a kill, not a probe
/// still running after `limit`). Runs only on the crash path; a campaign's files are decoded
/// once more, one at a time.
pub fn probe(files: &[PathBuf], limit: std::time::Duration) -> Vec<PathBuf> {
    let mut crashed = Vec::new();
    for file in files {
        let Ok(mut cmd) = this_program() else {
            return Vec::new();
        };
        cmd.env(PROBE_ENV, file)
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null());
        let Ok(child) = spawn(&mut cmd) else {
            return Vec::new();
        };
        if let Ok((Ending::Crashed(d), false)) = child.wait_at_most(limit) {
            if d.signal != libc::SIGKILL {
                crashed.push(file.clone());
            }
        }
    }
    crashed
}

/// The one line for a child that crashed (see [`Death`]).
#[derive(Debug)]
pub struct Crash(pub Death);

impl Crash {
    /// The crash names input files: the decoder crashed while reading them (a kill, e.g. by
    /// the OOM killer, does not blame them).
    pub fn blames_input(&self) -> bool {
        !self.0.reading.is_empty() && self.0.signal != libc::SIGKILL
    }
}

/// `SIGABRT`, or `signal N` for a number without a name here.
pub fn signal_name(signal: i32) -> String {
    let name = match signal {
        libc::SIGABRT => "SIGABRT",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGBUS => "SIGBUS",
        libc::SIGILL => "SIGILL",
        libc::SIGFPE => "SIGFPE",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTRAP => "SIGTRAP",
        libc::SIGSYS => "SIGSYS",
        libc::SIGQUIT => "SIGQUIT",
        libc::SIGINT => "SIGINT",
        libc::SIGTERM => "SIGTERM",
        libc::SIGHUP => "SIGHUP",
        _ => return format!("signal {signal}"),
    };
    name.into()
}

impl fmt::Display for Crash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = &self.0;
        let mut why = signal_name(d.signal);
        if let Some(bytes) = d.allocation {
            why.push_str(&format!(": it asked for {bytes} bytes"));
        }
        let output = match d.swap {
            Swap::NotBegun => "the previous output is unchanged",
            Swap::Begun => "the output is whole, the previous one or the new one",
            Swap::Done => "the new output was already in place",
        };
        let files = || {
            d.reading
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let killed = "the analysis process was killed (SIGKILL: out of memory, or by someone)";
        match d.reading.len() {
            0 if d.signal == libc::SIGKILL => write!(f, "{killed}; {output}"),
            _ if d.signal == libc::SIGKILL => write!(f, "{killed} while reading {}; {output}", files()),
            0 => write!(f, "the analysis process crashed ({why}); {output}"),
            1 => write!(
                f,
                "{}: the parquet decoder crashed ({why}) while reading this file; it is probably corrupt; {output}",
                files()
            ),
            _ => write!(
                f,
                "the parquet decoder crashed ({why}) while reading one of these files: {}; one of them is probably corrupt; {output}",
                files()
            ),
        }
    }
}

impl std::error::Error for Crash {}

#[cfg(test)]
mod tests {
    use super::*;

    fn death(signal: i32, reading: &[&str]) -> Death {
        Death {
            signal,
            reading: reading.iter().map(PathBuf::from).collect(),
            output: None,
            swap: Swap::NotBegun,
            allocation: None,
            fault_kill: false,
        }
    }

    #[test]
    fn records_split_anywhere_give_the_same_trail() {
        let mut bytes = Vec::new();
        bytes.extend(record(OUTPUT, 0, b"/o/out"));
        bytes.extend(record(BEGIN, 1, b"a.parquet"));
        bytes.extend(record(BEGIN, 2, b"b.parquet\0c.parquet"));
        bytes.extend(record(END, 1, &[]));
        bytes.extend(record(SWAP_BEGUN, 0, &[]));
        bytes.extend(record(ALLOCATION, 0, &7u64.to_le_bytes()));
        for cut in 0..bytes.len() {
            let mut t = Trail::default();
            let used = t.apply(&bytes[..cut]);
            let mut rest = bytes[used..cut].to_vec();
            rest.extend_from_slice(&bytes[cut..]);
            assert_eq!(t.apply(&rest), rest.len(), "cut at {cut}");
            assert_eq!(t.output.as_deref(), Some(Path::new("/o/out")));
            let open: Vec<_> = t.reading.values().flatten().cloned().collect();
            assert_eq!(open, [PathBuf::from("b.parquet"), "c.parquet".into()]);
            assert_eq!((t.swap, t.allocation), (Swap::Begun, Some(7)));
        }
        // A record cut short by the death stays unapplied.
        let mut t = Trail::default();
        let r = record(BEGIN, 9, b"x.parquet");
        assert_eq!(t.apply(&r[..r.len() - 1]), 0);
        assert!(t.reading.is_empty());
    }

    #[test]
    fn the_line_names_the_files_and_says_what_became_of_the_output() {
        let one = Crash(Death {
            allocation: Some(2305843009213693936),
            ..death(libc::SIGABRT, &["/c/encoders/day1.parquet"])
        });
        let line = one.to_string();
        assert!(
            line.starts_with("/c/encoders/day1.parquet: the parquet decoder crashed (SIGABRT: it asked for 2305843009213693936 bytes)"),
            "{line}"
        );
        assert!(line.ends_with("the previous output is unchanged") && !line.contains('\n'));
        assert!(one.blames_input());
        let two = Crash(death(libc::SIGSEGV, &["a.parquet", "b.parquet"]));
        assert!(two
            .to_string()
            .contains("one of these files: a.parquet, b.parquet"));
        assert!(two.blames_input());
        let killed = Crash(death(libc::SIGKILL, &["a.parquet"]));
        assert!(killed.to_string().contains("killed (SIGKILL"));
        assert!(killed.to_string().contains("while reading a.parquet"));
        assert!(!killed.blames_input());
        assert!(!Crash(death(libc::SIGKILL, &[]))
            .to_string()
            .contains("reading"));
        let none = Crash(Death {
            swap: Swap::Done,
            ..death(libc::SIGBUS, &[])
        });
        assert_eq!(
            none.to_string(),
            "the analysis process crashed (SIGBUS); the new output was already in place"
        );
        assert!(!none.blames_input());
    }

    #[test]
    fn unsupervised_breadcrumbs_cost_nothing_and_say_nothing() {
        assert!(!is_supervised());
        let r = reading([Path::new("x.parquet")]);
        assert!(r.0.is_none());
        assert_eq!(run_pid(), std::process::id());
    }
}
