//! The process-level guards against foreign code: a law that calls `exit()`, crashes, writes to
//! standard output, hangs inside one call, runs too long or eats memory. In a `tribo` process
//! (or a Python one running laws in process) they turn a silent death or a false success into a
//! message and exit status 1; in a worker they also enforce the limits and tell the parent,
//! with marker lines on the marker pipe, what happened and which law was running.
//!
//! They also keep tribo's own failures tribo's: a panic is reported as a bug in tribo, never
//! as a law calling `exit()`, and a write past `ulimit -f` is an error naming the file
//! (SIGXFSZ ignored) rather than a silent death.
//!
//! Everything here that can run in a signal handler or an `atexit` hook is allocation-free:
//! it reads atomics and writes with `write(2)`.

use std::fs::File;
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

use tribo_plugin_api::loader::inflight;
use tribo_plugin_api::{JointKind, LawInput};

use crate::frame;
use crate::terms::Limits;

/// Set once the command has finished and may exit; before that, `exit()` is a law's doing.
static MAY_EXIT: AtomicBool = AtomicBool::new(true);
/// This process is a worker (reports go to the parent as marker lines).
static IS_WORKER: AtomicBool = AtomicBool::new(false);
/// Tribo itself panicked: the exit that follows is its own, not a law's.
static PANICKED: AtomicBool = AtomicBool::new(false);
/// A worker's panic message, for its reply.
static PANIC_TEXT: Mutex<Option<String>> = Mutex::new(None);
/// The worker's memory limit in bytes (0: none), read by the watchdog.
static MEMORY_LIMIT: AtomicU64 = AtomicU64::new(0);
/// A worker's marker pipe (-1: not a worker).
static MARKER_FD: AtomicI32 = AtomicI32::new(-1);
/// A worker's job token in hex: the start of every marker line.
static TOKEN_HEX: OnceLock<[u8; 32]> = OnceLock::new();
/// The watchdog has been started (once per process).
static WATCHING: AtomicBool = AtomicBool::new(false);
/// When the current job of a worker started, ms after [`EPOCH`] (0: no job running). The
/// time limit counts from there, so a long-lived worker gives each request the whole limit.
static JOB_START_MS: AtomicU64 = AtomicU64::new(0);
/// The watchdog's reference instant.
static EPOCH: OnceLock<Instant> = OnceLock::new();

/// Exit status of a process stopped by its guards (the parent reads the marker lines, the user
/// the message).
const GUARD_EXIT: i32 = 1;
/// How often the watchdog looks.
const TICK: Duration = Duration::from_millis(25);
/// A call running this long gets a progress note (then again at each doubling).
const SLOW_NOTE: Duration = Duration::from_secs(3);

/// Install the guards for a process that runs laws or starts workers: an `atexit` hook that
/// turns a law's `exit()` into exit status 1 with a message, handlers for fatal signals that
/// name the law running, a panic hook that reports a panic as tribo's own bug, and SIGXFSZ
/// ignored. `exit()` counts as a law's from now until [`allow_exit`].
pub fn install() {
    MAY_EXIT.store(false, Ordering::SeqCst);
    std::panic::set_hook(Box::new(on_panic));
    #[cfg(unix)]
    {
        unsafe_unix::install();
        crate::sys::ignore_file_size_signal();
    }
}

/// The command is done: exiting from now on is tribo's own.
pub fn allow_exit() {
    MAY_EXIT.store(true, Ordering::SeqCst);
}

/// Laws run from now until [`allow_exit`]: an `exit()` meanwhile is a law's (the Python module
/// arms this around each in-process call, since the interpreter exits through `exit()` too).
pub fn forbid_exit() {
    MAY_EXIT.store(false, Ordering::SeqCst);
}

/// End this process with `code` once its output is flushed, without running `atexit`
/// handlers or library destructors: a law's destructor (in process) that calls `_exit(0)`
/// cannot turn a failed command into a success.
pub fn end(code: i32) -> ! {
    use std::io::Write as _;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    #[cfg(unix)]
    // SAFETY: _exit has no preconditions; everything tribo writes is flushed or synced above
    // or by its owners before this point.
    unsafe {
        libc::_exit(code)
    }
    #[cfg(not(unix))]
    std::process::exit(code)
}

/// Whether tribo itself panicked (a bug), and the worker's panic text if any.
pub fn take_panic() -> Option<String> {
    PANIC_TEXT.lock().unwrap_or_else(|p| p.into_inner()).take()
}

fn on_panic(info: &std::panic::PanicHookInfo<'_>) {
    PANICKED.store(true, Ordering::SeqCst);
    let payload = info
        .payload()
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| info.payload().downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".into());
    let place = info
        .location()
        .map(|l| format!(" at {}:{}", l.file(), l.line()))
        .unwrap_or_default();
    let text = format!("tribo panicked{place}: {payload}");
    if IS_WORKER.load(Ordering::Relaxed) {
        *PANIC_TEXT.lock().unwrap_or_else(|p| p.into_inner()) = Some(text);
    } else {
        let line = format!("error: internal error: {text}; this is a bug in tribo, not in a law: please report it\n");
        write_stderr(line.as_bytes());
    }
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

/// Turn this process into a worker of the job tagged `token`, reporting on `marker_fd`: core
/// dumps off, an address-space cap as a backstop of the memory limit, and the watchdog of
/// [`watch`].
pub fn become_worker(limits: Limits, token: &[u8; 16], marker_fd: i32) {
    let _ = TOKEN_HEX.set(frame::hex(token));
    MARKER_FD.store(marker_fd, Ordering::SeqCst);
    IS_WORKER.store(true, Ordering::SeqCst);
    MAY_EXIT.store(false, Ordering::SeqCst);
    #[cfg(unix)]
    unsafe_unix::limit_resources(limits.memory_mb);
    watch(limits);
}

/// Whether this process is a worker.
pub fn is_worker() -> bool {
    IS_WORKER.load(Ordering::Relaxed)
}

/// Write a marker line `TOKEN KIND TEXT` for the parent (one `write(2)`, cut to the pipe's
/// atomic size). Allocation-free; nothing outside a worker.
pub fn marker(kind: &str, text: &str) {
    let fd = MARKER_FD.load(Ordering::Relaxed);
    let Some(token) = TOKEN_HEX.get() else { return };
    if fd < 0 {
        return;
    }
    let mut buf = [0u8; frame::MARKER_MAX];
    let mut n = 0;
    for part in [&token[..], b" ", kind.as_bytes(), b" ", text.as_bytes()] {
        for &b in part {
            if n < buf.len() - 1 {
                // A line per marker: a newline inside a name would split it.
                buf[n] = if b == b'\n' { b' ' } else { b };
                n += 1;
            }
        }
    }
    buf[n] = b'\n';
    #[cfg(unix)]
    crate::sys::write_all(fd, &buf[..=n]);
}

/// Start a watchdog thread (once per process) that ends this process with status 1 when
/// `limits` run out: one law call longer than the call limit (naming the law, its joint and
/// the call's inputs), the wall time from now, the resident memory. A call running for a few
/// seconds gets a note first. Used by workers and by commands run `--in-process`.
pub fn watch(limits: Limits) {
    MEMORY_LIMIT.store(limits.memory_mb.saturating_mul(1 << 20), Ordering::SeqCst);
    if WATCHING.swap(true, Ordering::SeqCst) {
        return;
    }
    // Outside a worker the whole process is one job, from now.
    if !is_worker() {
        job_started();
    }
    let _ = std::thread::Builder::new()
        .name("tribo-watchdog".into())
        .spawn(move || watchdog(limits));
}

/// A worker's job starts now: the time limit counts from here.
pub fn job_started() {
    let epoch = *EPOCH.get_or_init(Instant::now);
    let ms = epoch.elapsed().as_millis() as u64;
    JOB_START_MS.store(ms.max(1), Ordering::SeqCst);
}

/// A worker's job has ended: no time limit runs until the next one.
pub fn job_finished() {
    JOB_START_MS.store(0, Ordering::SeqCst);
}

/// Whether the current job has run past `limit`.
fn job_past(limit: Option<Duration>) -> bool {
    let (Some(limit), Some(epoch)) = (limit, EPOCH.get()) else {
        return false;
    };
    let start = JOB_START_MS.load(Ordering::SeqCst);
    start != 0 && epoch.elapsed() >= Duration::from_millis(start) + limit
}

/// What one thread slot was last seen running, since when, and how many notes it got.
#[derive(Clone, Copy)]
struct Seen {
    mark: u64,
    since: Instant,
    notes: u32,
}

/// Poll the calls in flight, the clock and the resident size; stop the process at a limit.
fn watchdog(limits: Limits) {
    let start = Instant::now();
    let mut seen = vec![
        Seen {
            mark: 0,
            since: start,
            notes: 0
        };
        inflight::SLOTS
    ];
    let call_limit = limits.call();
    loop {
        std::thread::sleep(TICK);
        let now = Instant::now();
        for (slot, s) in seen.iter_mut().enumerate() {
            let mark = inflight::mark(slot);
            if mark != s.mark {
                *s = Seen {
                    mark,
                    since: now,
                    notes: 0,
                };
                continue;
            }
            if mark == 0 {
                continue;
            }
            let running = now - s.since;
            if call_limit.is_some_and(|l| running >= l) {
                stuck(slot, mark, running, limits.call_s);
            }
            if running >= SLOW_NOTE * 2u32.saturating_pow(s.notes) {
                s.notes += 1;
                slow(mark, running, limits.call_s);
            }
        }
        if job_past(limits.time()) {
            if is_worker() {
                report_running();
                marker("limit-time", "");
            } else {
                let line = format!("error: stopped after the time limit of {} s (--time-limit-s); no results were written\n", limits.time_s);
                write_stderr(line.as_bytes());
                report_running();
            }
            stop_at_limit();
        }
        if limits.memory_mb > 0 {
            let limit = MEMORY_LIMIT.load(Ordering::Relaxed);
            #[cfg(unix)]
            let rss = crate::sys::resident_bytes(0);
            #[cfg(not(unix))]
            let rss: Option<u64> = None;
            if let Some(rss) = rss.filter(|rss| *rss > limit) {
                if is_worker() {
                    report_running();
                    marker("limit-memory", &(rss >> 20).to_string());
                } else {
                    let line = format!("error: stopped at {} MiB of memory, over the limit of {} MiB (--memory-limit-mb); no results were written\n", rss >> 20, limits.memory_mb);
                    write_stderr(line.as_bytes());
                    report_running();
                }
                stop_at_limit();
            }
        }
    }
}

/// End the process at a limit. A worker first kills the children its laws moved out of its
/// process group (`setsid`): they are found as its descendants only while it lives, and the
/// parent's kill of the group does not reach them.
fn stop_at_limit() -> ! {
    #[cfg(unix)]
    if is_worker() {
        // SAFETY: getpid has no preconditions.
        crate::sys::kill_escaped(unsafe { libc::getpid() }, libc::SIGKILL);
    }
    stop(GUARD_EXIT)
}

/// The plugin code a slot mark names, in words.
fn code_name(mark: u64) -> &'static str {
    inflight::name(inflight::id_of(mark)).unwrap_or("plugin code")
}

/// One call ran past the limit: say which, where and with what inputs, and stop.
fn stuck(slot: usize, mark: u64, running: Duration, limit_s: f64) -> ! {
    let mut text = format!(
        "{} did not return from one call in {:.1} s, the limit for one law call (--call-limit-s, in Python call_limit_s; 0: none)",
        code_name(mark),
        running.as_secs_f64().max(limit_s)
    );
    if let Some(input) = inflight::input_of(slot, mark) {
        text.push_str("; the call's inputs: ");
        text.push_str(&describe_input(&input));
    }
    if is_worker() {
        marker("stuck", &text);
    } else {
        write_stderr(format!("error: {text}; no results were written\n").as_bytes());
    }
    stop_at_limit()
}

/// A call has been running for a few seconds: say so (a worker tells its parent).
fn slow(mark: u64, running: Duration, limit_s: f64) {
    let secs = running.as_secs_f64().round();
    if is_worker() {
        marker("slow", &format!("{secs} {}", code_name(mark)));
    } else {
        let line = format!("note: {}\n", slow_note(code_name(mark), secs, limit_s));
        write_stderr(line.as_bytes());
    }
}

/// What to say of a law call running for `secs` seconds (after "note: ").
pub(crate) fn slow_note(code: &str, secs: f64, limit_s: f64) -> String {
    let limit = if limit_s > 0.0 {
        format!("it is stopped at {limit_s} s (--call-limit-s)")
    } else {
        "no limit is set (--call-limit-s 0)".into()
    };
    format!("{code} has been inside one call for {secs} s; {limit}")
}

/// A law input in words: time, crank angle, velocities, load, oil, engine speed.
pub fn describe_input(i: &LawInput) -> String {
    let unit = match i.kind() {
        Some(JointKind::Prismatic) => "m/s",
        _ => "rad/s",
    };
    format!(
        "t = {} s, crank angle {:.2} deg, relative velocity {} {unit}, sliding velocity {} m/s, normal load {} N, oil {} C (viscosity {} Pa s), engine speed {:.1} rpm, step {} s",
        i.time_s,
        i.crank_angle_rad.to_degrees(),
        i.relative_velocity,
        i.sliding_velocity_m_s,
        i.normal_load_n,
        i.oil_temp_c,
        i.viscosity_pa_s,
        i.engine_speed_rad_s * 60.0 / std::f64::consts::TAU,
        i.dt_s
    )
}

/// Write what plugin code is running: marker lines in a worker, a sentence otherwise.
/// Allocation-free.
fn report_running() {
    let worker = is_worker();
    inflight::for_each_running(|text| {
        if worker {
            marker("running", text);
        } else {
            write_stderr(b"error: this happened while running ");
            write_stderr(text.as_bytes());
            write_stderr(b"\n");
        }
    });
}

fn write_stderr(bytes: &[u8]) {
    #[cfg(unix)]
    crate::sys::write_all(2, bytes);
    #[cfg(not(unix))]
    {
        use std::io::Write;
        let _ = std::io::stderr().write_all(bytes);
    }
}

/// End the process now, without running `atexit` hooks or destructors (a law's threads may
/// still run its code, and its `atexit` handlers are not tribo's to run).
pub fn stop(code: i32) -> ! {
    #[cfg(unix)]
    // SAFETY: _exit ends the process at once; nothing after it runs.
    unsafe {
        libc::_exit(code)
    }
    #[cfg(not(unix))]
    std::process::exit(code)
}

/// Called by `exit()` (through `atexit`): if the command has not finished, a law called it.
extern "C" fn at_exit() {
    if MAY_EXIT.load(Ordering::SeqCst) || PANICKED.load(Ordering::SeqCst) {
        return;
    }
    if is_worker() {
        report_running();
        marker("exit", "");
    } else {
        write_stderr(b"error: a law plugin ended tribo by calling exit() before the results were written; the run failed\n");
        report_running();
    }
    stop(GUARD_EXIT);
}

/// The fatal-signal handler: say which law was running, then die of the same signal.
#[cfg(unix)]
extern "C" fn on_fatal_signal(signal: libc::c_int) {
    if is_worker() {
        report_running();
    } else {
        write_stderr(b"error: tribo was stopped by a fatal signal (");
        write_stderr(crate::terms::signal_name(signal).as_bytes());
        write_stderr(b"); no results were written\n");
        report_running();
        write_stderr(b"note: without --in-process, tribo runs laws in a separate process, so one crashing law fails only its own run or law set\n");
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
}
