//! The process-level guards against foreign code: a law that calls `exit()`, crashes, writes to
//! standard output, hangs or eats memory. In the `tribo` process they turn a silent death or a
//! false success into a message and exit status 1; in a worker they also enforce the limits and
//! tell the parent (marker lines on standard error) which law was running.
//!
//! Everything here that can run in a signal handler or an `atexit` hook is allocation-free:
//! it reads atomics and writes with `write(2)`.

use std::fs::File;
use std::process::ExitStatus;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use tribo_plugin_api::loader::inflight;

use super::Limits;

/// Prefix of the lines a worker writes on standard error for its parent.
pub const MARKER: &str = "\u{1f}tribo-worker ";

/// Set once the command has finished and may exit; before that, `exit()` is a law's doing.
static MAY_EXIT: AtomicBool = AtomicBool::new(false);
/// This process is a worker (reports go to the parent as marker lines).
static IS_WORKER: AtomicBool = AtomicBool::new(false);
/// The worker's memory limit in bytes (0: none), read by the watchdog.
static MEMORY_LIMIT: AtomicU64 = AtomicU64::new(0);

/// Exit status of a process stopped by its guards (the parent reads the marker lines, the user
/// the message).
const GUARD_EXIT: i32 = 1;

/// Install the guards for a `tribo` process: an `atexit` hook that turns a law's `exit()` into
/// exit status 1 with a message, and handlers for fatal signals that name the law running.
pub fn install() {
    #[cfg(unix)]
    unsafe_unix::install();
}

/// The command is done: exiting from now on is tribo's own.
pub fn allow_exit() {
    MAY_EXIT.store(true, Ordering::SeqCst);
}

/// Send standard output to standard error for the rest of the process, and return a handle on
/// the real standard output, where only results are written. A law that prints cannot corrupt
/// `--json` output. `None` if standard output cannot be duplicated (it is closed).
pub fn take_stdout() -> Option<File> {
    #[cfg(unix)]
    {
        unsafe_unix::take_stdout()
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Turn this process into a worker with `limits`: core dumps off, an address-space cap as a
/// backstop, and the watchdog of [`watch`], which tells the parent which law was running.
pub fn become_worker(limits: Limits) {
    IS_WORKER.store(true, Ordering::SeqCst);
    #[cfg(unix)]
    unsafe_unix::limit_resources(limits.memory_mb);
    watch(limits);
}

/// Start a watchdog thread that ends this process with status 1 when `limits` run out (wall
/// time from now, resident memory), saying which law was running. Used by workers and by a
/// study run `--in-process`, where a hanging or leaking law would otherwise hang the study or
/// exhaust the machine.
pub fn watch(limits: Limits) {
    MEMORY_LIMIT.store(limits.memory_mb.saturating_mul(1 << 20), Ordering::SeqCst);
    let deadline = limits.time().map(|t| Instant::now() + t);
    if deadline.is_some() || limits.memory_mb > 0 {
        std::thread::spawn(move || watchdog(deadline, limits));
    }
}

/// Poll the clock and the resident size; stop the process at a limit.
fn watchdog(deadline: Option<Instant>, limits: Limits) {
    let worker = IS_WORKER.load(Ordering::Relaxed);
    loop {
        std::thread::sleep(Duration::from_millis(20));
        if deadline.is_some_and(|d| Instant::now() >= d) {
            if worker {
                report_running();
                write_stderr(MARKER.as_bytes());
                write_stderr(b"limit time\n");
            } else {
                let line = format!("error: stopped after the time limit of {} s (--time-limit-s); no results were written\n", limits.time_s);
                write_stderr(line.as_bytes());
                report_running();
            }
            stop(GUARD_EXIT);
        }
        if limits.memory_mb > 0 {
            let limit = MEMORY_LIMIT.load(Ordering::Relaxed);
            if let Some(rss) = resident_bytes().filter(|rss| *rss > limit) {
                if worker {
                    report_running();
                    let line = format!("{MARKER}limit memory {}\n", rss >> 20);
                    write_stderr(line.as_bytes());
                } else {
                    let line = format!("error: stopped at {} MiB of memory, over the limit of {} MiB (--memory-limit-mb); no results were written\n", rss >> 20, limits.memory_mb);
                    write_stderr(line.as_bytes());
                    report_running();
                }
                stop(GUARD_EXIT);
            }
        }
    }
}

/// The resident set size of this process, from /proc (Linux); `None` elsewhere.
fn resident_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = text.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * page_size())
}

fn page_size() -> u64 {
    #[cfg(unix)]
    {
        unsafe_unix::page_size()
    }
    #[cfg(not(unix))]
    {
        4096
    }
}

/// Write what plugin code is running: marker lines in a worker, a sentence otherwise.
/// Allocation-free.
fn report_running() {
    let worker = IS_WORKER.load(Ordering::Relaxed);
    inflight::for_each_running(|text| {
        if worker {
            write_stderr(MARKER.as_bytes());
            write_stderr(b"running ");
        } else {
            write_stderr(b"error: this happened while running ");
        }
        write_stderr(text.as_bytes());
        write_stderr(b"\n");
    });
}

fn write_stderr(bytes: &[u8]) {
    #[cfg(unix)]
    unsafe_unix::write_fd(2, bytes);
    #[cfg(not(unix))]
    {
        use std::io::Write;
        let _ = std::io::stderr().write_all(bytes);
    }
}

/// End the process now, without running `atexit` hooks or destructors.
fn stop(code: i32) -> ! {
    #[cfg(unix)]
    unsafe_unix::exit_now(code);
    #[cfg(not(unix))]
    std::process::exit(code)
}

/// Kill the process `pid` (SIGKILL): a worker past its limit that did not stop itself.
pub fn kill(pid: u32) {
    #[cfg(unix)]
    unsafe_unix::kill(pid);
}

/// The signal that ended a process, if one did.
pub fn signal_of(status: &ExitStatus) -> Option<i32> {
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        status.signal()
    }
    #[cfg(not(unix))]
    {
        let _ = status;
        None
    }
}

/// Called by `exit()` (through `atexit`): if the command has not finished, a law called it.
extern "C" fn at_exit() {
    if MAY_EXIT.load(Ordering::SeqCst) {
        return;
    }
    if IS_WORKER.load(Ordering::Relaxed) {
        report_running();
        write_stderr(MARKER.as_bytes());
        write_stderr(b"exit called\n");
    } else {
        write_stderr(b"error: a law plugin ended tribo by calling exit() before the results were written; the run failed\n");
        report_running();
    }
    stop(GUARD_EXIT);
}

/// The fatal-signal handler: say which law was running, then die of the same signal.
#[cfg(unix)]
extern "C" fn on_fatal_signal(signal: libc::c_int) {
    if IS_WORKER.load(Ordering::Relaxed) {
        report_running();
    } else {
        write_stderr(b"error: tribo was stopped by a fatal signal (");
        write_stderr(super::signal_name(signal).as_bytes());
        write_stderr(b"); no results were written\n");
        report_running();
        write_stderr(b"note: the study commands (compare, fit, mass-response, sweep) run each law set in its own process unless --in-process is given, so one crashing law fails only its own set\n");
    }
    unsafe_unix::reraise(signal);
}

/// The few libc calls, kept in one place.
#[cfg(unix)]
mod unsafe_unix {
    use std::fs::File;
    use std::os::fd::FromRawFd;

    pub(super) fn install() {
        // SAFETY: `at_exit` is a plain extern "C" fn with no arguments, as atexit requires.
        unsafe {
            libc::atexit(super::at_exit);
        }
        for signal in [
            libc::SIGSEGV,
            libc::SIGBUS,
            libc::SIGILL,
            libc::SIGFPE,
            libc::SIGABRT,
        ] {
            // SAFETY: a zeroed sigaction is valid; the handler only reads atomics and calls
            // write(2) and raise(3), which are async-signal-safe. SA_ONSTACK uses the alternate
            // stack Rust's runtime sets up, so a stack overflow is reported too.
            unsafe {
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = super::on_fatal_signal as extern "C" fn(libc::c_int) as usize;
                action.sa_flags = libc::SA_RESETHAND | libc::SA_ONSTACK | libc::SA_NODEFER;
                libc::sigemptyset(&mut action.sa_mask);
                libc::sigaction(signal, &action, std::ptr::null_mut());
            }
        }
    }

    pub(super) fn reraise(signal: libc::c_int) {
        // SAFETY: raise is async-signal-safe; SA_RESETHAND put the default action back, and
        // SA_NODEFER leaves the signal unblocked, so this ends the process with it (also when
        // a law raised the signal itself rather than faulting).
        unsafe {
            libc::raise(signal);
        }
    }

    pub(super) fn take_stdout() -> Option<File> {
        // SAFETY: dup/dup2 on the standard descriptors; the duplicate is owned by the File.
        unsafe {
            let saved = libc::dup(1);
            if saved < 0 {
                return None;
            }
            libc::fcntl(saved, libc::F_SETFD, libc::FD_CLOEXEC);
            if libc::dup2(2, 1) < 0 {
                libc::close(saved);
                return None;
            }
            Some(File::from_raw_fd(saved))
        }
    }

    pub(super) fn limit_resources(memory_mb: u64) {
        // A worker dies with its parent: a killed `tribo` leaves no study running on.
        #[cfg(target_os = "linux")]
        // SAFETY: prctl(PR_SET_PDEATHSIG) takes a signal number; failure leaves it off.
        unsafe {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
        }
        // SAFETY: setrlimit with valid structures; failure only leaves the limit off.
        unsafe {
            let none = libc::rlimit {
                rlim_cur: 0,
                rlim_max: 0,
            };
            libc::setrlimit(libc::RLIMIT_CORE, &none);
            if memory_mb > 0 {
                // A backstop far above the watched resident limit: virtual reservations (thread
                // stacks, allocator arenas) are not memory in use.
                let bytes = memory_mb
                    .saturating_mul(2)
                    .saturating_add(4096)
                    .saturating_mul(1 << 20);
                let cap = libc::rlimit {
                    rlim_cur: bytes as libc::rlim_t,
                    rlim_max: bytes as libc::rlim_t,
                };
                libc::setrlimit(libc::RLIMIT_AS, &cap);
            }
        }
    }

    pub(super) fn page_size() -> u64 {
        // SAFETY: sysconf has no preconditions.
        let n = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
        if n > 0 {
            n as u64
        } else {
            4096
        }
    }

    pub(super) fn write_fd(fd: libc::c_int, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            // SAFETY: writing an initialised buffer of the given length.
            let n = unsafe { libc::write(fd, bytes.as_ptr().cast(), bytes.len()) };
            if n <= 0 {
                return;
            }
            bytes = &bytes[n as usize..];
        }
    }

    pub(super) fn exit_now(code: i32) -> ! {
        // SAFETY: _exit ends the process at once; nothing after it runs.
        unsafe { libc::_exit(code) }
    }

    pub(super) fn kill(pid: u32) {
        // SAFETY: sending a signal to a child we started; failure (already gone) is harmless.
        unsafe {
            libc::kill(pid as libc::pid_t, libc::SIGKILL);
        }
    }
}
