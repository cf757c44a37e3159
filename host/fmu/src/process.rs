//! The FMU's side of its worker process: start it (in its own process group), send a request
//! and wait for the reply within a time limit, and when the worker dies or stops answering,
//! say why in words (its exit status or signal, and its last lines on standard error, where
//! the worker's guards name the law that was running).

use std::collections::VecDeque;
use std::io::Read;
use std::os::fd::{AsRawFd, OwnedFd};
use std::os::unix::fs::PermissionsExt;
use std::os::unix::net::UnixStream;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::protocol::{read_frame, write_frame, FrameError, Reply, Request, PROTOCOL_VERSION};
use crate::worker::{WORKER_EXE, WORKER_SUBCOMMAND};

/// How long past the worker's own per-request limit the FMU waits before it kills the worker
/// (the worker normally stops itself first and names the law).
const GRACE: Duration = Duration::from_secs(5);
/// How much of the worker's standard error is kept for messages.
const TAIL_BYTES: usize = 8192;
/// Lines of it quoted in a message.
const TAIL_LINES: usize = 6;

/// A running worker process.
pub struct Worker {
    child: Child,
    /// Our end of the worker's standard input: a socket, so a write to a worker that has died
    /// fails with EPIPE instead of raising SIGPIPE, which would end an importer that does not
    /// ignore it (a C program; Python ignores it).
    requests: Requests,
    stdout: ChildStdout,
    stderr: Arc<Mutex<Tail>>,
    /// The thread reading it: joined before the worker is dropped, so no thread of the FMU's
    /// library outlives its instance (an importer may unload the library right after).
    reader: Option<std::thread::JoinHandle<()>>,
    /// The worker's own per-request limit.
    limit: Duration,
    /// The laws the worker runs, as a failure names them ("law `x` (file) at joint `j`").
    laws: Vec<String>,
    /// The worker's in-flight marks and names (shared memory that outlives it): the law
    /// call it died in, when it died without a word.
    page: Option<tribo_isolate::page::InflightPage>,
}

/// The end of the worker's standard error, filled by a reading thread.
#[derive(Default)]
struct Tail {
    bytes: VecDeque<u8>,
    closed: bool,
}

impl Worker {
    /// Start the worker shipped in `resources` and wait for it to read them, within `limit`.
    /// `laws` are the laws it runs, named in a failure its own words do not explain.
    pub fn spawn(resources: &Path, limit: Duration, laws: Vec<String>) -> Result<Self, String> {
        let exe = resources.join(WORKER_EXE);
        let (program, _copy) = executable(&exe)?;
        let (ours, theirs) = UnixStream::pair()
            .map_err(|e| format!("cannot make the channel to the FMU's worker process: {e}"))?;
        let page = tribo_isolate::page::InflightPage::new();
        let mut command = Command::new(&program);
        if let Some(p) = &page {
            p.share_with(&mut command);
        }
        let mut child = command
            .arg(WORKER_SUBCOMMAND)
            .arg(resources)
            .env_remove("TRIBO_PLUGIN_PATH")
            .stdin(Stdio::from(OwnedFd::from(theirs)))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            // Its own process group: a stop takes whatever a law started with it.
            .process_group(0)
            .spawn()
            .map_err(|e| {
                format!(
                    "cannot start the FMU's worker process {}: {e}",
                    exe.display()
                )
            })?;
        let (Some(stdout), Some(stderr)) = (child.stdout.take(), child.stderr.take()) else {
            let _ = child.kill();
            let _ = child.wait();
            return Err("the worker process's pipes were not opened".into());
        };
        let tail = Arc::new(Mutex::new(Tail::default()));
        let sink = Arc::clone(&tail);
        let reader = std::thread::spawn(move || drain(stderr, &sink));
        let mut w = Self {
            child,
            requests: Requests(ours),
            stdout,
            stderr: tail,
            reader: Some(reader),
            limit,
            laws,
            page,
        };
        match w.receive() {
            Ok(Reply::Ready(PROTOCOL_VERSION)) => Ok(w),
            Ok(Reply::Ready(v)) => {
                w.stop();
                Err(format!(
                    "the FMU's worker {} speaks protocol version {v}, its library version {PROTOCOL_VERSION}: they come from different builds of Tribo; export the FMU again",
                    exe.display()
                ))
            }
            Ok(Reply::Error(e)) => {
                w.stop();
                Err(e)
            }
            Ok(other) => {
                w.stop();
                Err(format!(
                    "the worker process answered {other:?} instead of being ready"
                ))
            }
            Err(e) => Err(e),
        }
    }

    /// The worker's per-request time limit from now on.
    pub fn set_limit(&mut self, limit: Duration) {
        self.limit = limit;
    }

    /// Send `request` and wait for the reply. A worker that died, garbled its answer or did
    /// not answer in time is stopped, and the error says what happened.
    pub fn call(&mut self, request: &Request) -> Result<Reply, String> {
        if let Err(e) = write_frame(&mut self.requests, request) {
            return Err(self.failed(&format!("could not be sent a request ({e})")));
        }
        self.receive()
    }

    /// Wait for one reply.
    fn receive(&mut self) -> Result<Reply, String> {
        let deadline = Instant::now() + self.limit + GRACE;
        let mut reader = Deadline {
            inner: &mut self.stdout,
            deadline,
        };
        match read_frame(&mut reader) {
            Ok(reply) => Ok(reply),
            Err(FrameError::Io(e)) if e.kind() == std::io::ErrorKind::TimedOut => {
                let waited = self.limit + GRACE;
                Err(self.failed(&format!(
                    "gave no answer within {:.1} s (worker.call_timeout plus {} s) and was stopped",
                    waited.as_secs_f64(),
                    GRACE.as_secs()
                )))
            }
            Err(FrameError::Closed) => Err(self.failed("ended before answering")),
            Err(e) => Err(self.failed(&format!("broke off its answer ({e})"))),
        }
    }

    /// Stop the worker and describe its end: `what` it did, then its exit status or signal
    /// and its last lines on standard error.
    fn failed(&mut self, what: &str) -> String {
        let pid = self.child.id();
        let status = self.end();
        let mut text = format!("the FMU's worker process (pid {pid}) {what}");
        if let Some(s) = status {
            text.push_str(&format!("; {}", describe_status(&s)));
        }
        let tail = self.tail();
        if !tail.is_empty() {
            text.push_str(&format!("; its last words: {tail}"));
        }
        // The guards name the law when they can (a crash, exit()); an `_exit`, a SIGKILL or a
        // hang before the watchdog speaks leave no word: then the law call its in-flight page
        // shows under way (one of the laws it runs), else the laws it runs.
        let running: Vec<String> = self
            .page
            .as_ref()
            .map(|p| p.running())
            .unwrap_or_default()
            .into_iter()
            .filter(|r| self.laws.iter().any(|l| same_law(l, r)))
            .collect();
        if !tail.contains("law `") && !running.is_empty() {
            text.push_str(&format!("; it died in a call of {}", running.join(" and ")));
        } else if !tail.contains("law `") && !self.laws.is_empty() {
            text.push_str(&format!(
                "; it gave no word of which law was running; the laws it runs: {}",
                self.laws.join(", ")
            ));
        }
        text
    }

    /// End the worker: given a moment to finish dying by itself (so its own exit status is
    /// seen), then its whole process group killed. Returns how it ended.
    fn end(&mut self) -> Option<ExitStatus> {
        let until = Instant::now() + Duration::from_millis(500);
        while Instant::now() < until {
            match self.child.try_wait() {
                Ok(Some(s)) => {
                    kill_group(self.child.id());
                    return Some(s);
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(5)),
                Err(_) => break,
            }
        }
        kill_group(self.child.id());
        self.child.wait().ok()
    }

    /// Wait up to `limit` for the reader to see the end of the worker's standard error.
    fn wait_for_stderr_end(&self, limit: Duration) -> bool {
        let until = Instant::now() + limit;
        loop {
            let closed = self.stderr.lock().map(|t| t.closed).unwrap_or(true);
            if closed {
                return true;
            }
            if Instant::now() >= until {
                return false;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// The last lines the worker wrote on standard error, joined.
    fn tail(&self) -> String {
        // The reading thread sees the end of the pipe shortly after the process is gone.
        self.wait_for_stderr_end(Duration::from_millis(500));
        let bytes: Vec<u8> = self
            .stderr
            .lock()
            .map(|t| t.bytes.iter().copied().collect())
            .unwrap_or_default();
        let text = String::from_utf8_lossy(&bytes);
        // The guards' notes are advice for the command line, not for an importer.
        let lines: Vec<&str> = text
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with("note:"))
            .collect();
        lines[lines.len().saturating_sub(TAIL_LINES)..].join(" | ")
    }

    /// Ask the worker to quit, and make sure it is gone.
    pub fn stop(&mut self) {
        self.limit = Duration::from_secs(1);
        let polite = write_frame(&mut self.requests, &Request::Quit).is_ok()
            && matches!(
                read_frame::<Reply>(&mut Deadline {
                    inner: &mut self.stdout,
                    deadline: Instant::now() + Duration::from_secs(2),
                }),
                Ok(Reply::Bye)
            );
        if polite {
            let _ = self.child.wait();
        } else {
            kill_group(self.child.id());
            let _ = self.child.wait();
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            kill_group(self.child.id());
            let _ = self.child.wait();
        }
        // The process group is gone, so its end of the pipe closes and the reader ends; a
        // process that left the group and kept the pipe would hold it: then it is left alone.
        if self.wait_for_stderr_end(Duration::from_secs(2)) {
            if let Some(r) = self.reader.take() {
                let _ = r.join();
            }
        }
    }
}

/// Whether two names of a law bound to a joint ("law `x` (file) at joint `j`") name the same
/// law at the same joint, whichever way each spells the library's path.
fn same_law(a: &str, b: &str) -> bool {
    let parts = |s: &str| -> Option<(String, String)> {
        let (law, rest) = s.split_once(" (")?;
        let (_, joint) = rest.rsplit_once(") at joint ")?;
        Some((law.to_string(), joint.to_string()))
    };
    matches!((parts(a), parts(b)), (Some(x), Some(y)) if x == y)
}

/// Kill the process group led by `pid` (the worker and anything a law started).
fn kill_group(pid: u32) {
    if let Ok(pid) = libc::pid_t::try_from(pid) {
        // SAFETY: kill(2) on our child's process group; an already gone group is harmless.
        unsafe {
            libc::kill(-pid, libc::SIGKILL);
        }
    }
}

/// Keep the last [`TAIL_BYTES`] of the worker's standard error.
fn drain(mut stderr: impl Read, tail: &Mutex<Tail>) {
    let mut buf = [0u8; 4096];
    loop {
        match stderr.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => {
                if let Ok(mut t) = tail.lock() {
                    t.bytes.extend(&buf[..n]);
                    let excess = t.bytes.len().saturating_sub(TAIL_BYTES);
                    t.bytes.drain(..excess);
                }
            }
        }
    }
    if let Ok(mut t) = tail.lock() {
        t.closed = true;
    }
}

/// How a process ended, in words.
fn describe_status(s: &ExitStatus) -> String {
    match (s.code(), s.signal()) {
        (_, Some(sig)) => format!("killed by signal {sig} ({})", signal_name(sig)),
        (Some(crate::worker::TIMEOUT_EXIT), _) => {
            format!(
                "it stopped itself at worker.call_timeout (exit status {})",
                crate::worker::TIMEOUT_EXIT
            )
        }
        (Some(code), _) => format!("exit status {code}"),
        (None, None) => "ended".into(),
    }
}

/// The name of a fatal signal.
fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGSEGV => "SIGSEGV, a segmentation fault",
        libc::SIGBUS => "SIGBUS, a bus error",
        libc::SIGILL => "SIGILL, an illegal instruction",
        libc::SIGFPE => "SIGFPE, an arithmetic fault",
        libc::SIGABRT => "SIGABRT, an abort",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        _ => "a signal",
    }
}

/// The worker executable to run: `exe` itself when it may be executed (made so if an
/// extraction dropped the permission, as Python's zipfile does), else a private copy in a
/// temporary directory, kept until the process has started.
fn executable(exe: &Path) -> Result<(std::path::PathBuf, Option<tempfile::TempDir>), String> {
    let meta = std::fs::metadata(exe).map_err(|e| {
        format!(
            "the FMU's worker executable {} cannot be read: {e}",
            exe.display()
        )
    })?;
    if !meta.is_file() {
        return Err(format!(
            "the FMU's worker executable {} is not a file",
            exe.display()
        ));
    }
    let mode = meta.permissions().mode();
    if mode & 0o100 != 0 {
        return Ok((exe.to_path_buf(), None));
    }
    if std::fs::set_permissions(exe, std::fs::Permissions::from_mode(mode | 0o700)).is_ok() {
        return Ok((exe.to_path_buf(), None));
    }
    let dir = tempfile::Builder::new()
        .prefix("tribo-fmu-")
        .tempdir()
        .map_err(|e| format!("cannot make a temporary directory for the worker executable: {e}"))?;
    let copy = dir.path().join("tribo");
    std::fs::copy(exe, &copy)
        .and_then(|_| std::fs::set_permissions(&copy, std::fs::Permissions::from_mode(0o700)))
        .map_err(|e| {
            format!(
                "cannot copy the worker executable {} to {}: {e}",
                exe.display(),
                copy.display()
            )
        })?;
    Ok((copy, Some(dir)))
}

/// The request channel: writes with `MSG_NOSIGNAL`, so a dead reader is an error, not a
/// signal.
struct Requests(UnixStream);

impl std::io::Write for Requests {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        loop {
            // SAFETY: send(2) of an initialised buffer of its length on a socket we own.
            let n = unsafe {
                libc::send(
                    self.0.as_raw_fd(),
                    buf.as_ptr().cast(),
                    buf.len(),
                    libc::MSG_NOSIGNAL,
                )
            };
            if n >= 0 {
                return Ok(n as usize);
            }
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::Interrupted {
                return Err(e);
            }
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// A reader that gives up at a deadline (poll(2) before each read).
struct Deadline<'a> {
    inner: &'a mut ChildStdout,
    deadline: Instant,
}

impl Read for Deadline<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        loop {
            let left = self.deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(std::io::ErrorKind::TimedOut.into());
            }
            let mut fd = libc::pollfd {
                fd: self.inner.as_raw_fd(),
                events: libc::POLLIN,
                revents: 0,
            };
            let ms = libc::c_int::try_from(left.as_millis().max(1)).unwrap_or(libc::c_int::MAX);
            // SAFETY: one valid pollfd for a descriptor we own, for the duration of the call.
            let n = unsafe { libc::poll(&mut fd, 1, ms) };
            if n < 0 {
                let e = std::io::Error::last_os_error();
                if e.kind() == std::io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(e);
            }
            if n > 0 {
                return self.inner.read(buf);
            }
        }
    }
}
