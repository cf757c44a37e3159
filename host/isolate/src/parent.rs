//! The parent's side of a worker: start it in its own session and process group, send it
//! requests, read its replies, markers and standard error without ever blocking on them, watch
//! it (ended, stopped, past a limit), and kill its whole group when done.

use std::collections::{BTreeMap, HashSet};
use std::io::Write as _;
use std::os::fd::{AsRawFd, OwnedFd};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{mpsc, Mutex};
use std::time::{Duration, Instant};

use serde::de::DeserializeOwned;
use serde::Serialize;
use tribo_plugin_api::loader::inflight;

use crate::child::{Shared, CHANNEL_FD, MARKER_FD, SHARED_FD, SHARED_LEN};
use crate::frame::{self, Kind, Parsed};
use crate::guard;
use crate::sys::{self, State};
use crate::terms::{Limits, Reply, WorkerFailure, NO_CALL_PREFIX};

/// How often the parent looks at its workers.
const TICK: Duration = Duration::from_millis(20);
/// How long the parent waits past a limit the worker should have enforced itself before it
/// kills the worker (its own watchdog normally ends it first and names the law).
const KILL_GRACE: Duration = Duration::from_secs(3);
/// After the worker has ended, how long its pipes are still read: a law's child may hold them
/// open for ever, and tribo never waits for their end of file.
const DRAIN: Duration = Duration::from_millis(150);
/// Keep at most this much of a worker's standard error (its tail) for the failure message.
const STDERR_TAIL_BYTES: usize = 4096;
/// How often the parent adds up the memory of a worker's process group.
const MEMORY_TICK: Duration = Duration::from_millis(250);
/// Read at most this much from one pipe before looking at the clock and the limits again.
const READ_BUDGET: usize = 1 << 20;
/// Forward at most this much of a worker's standard error per request; the rest is counted.
const STDERR_FORWARD_BYTES: usize = 1 << 20;

/// What happens while a request runs, for the caller to act on.
pub enum Event<'a> {
    /// A chunk of streamed output (a time series).
    Data(&'a [u8]),
    /// The worker's progress position (what its job counts in).
    Progress(u64),
    /// A line the worker (a law) wrote on standard error.
    Stderr(&'a str),
    /// A law call has been running for a while: what to say (to follow "note: ").
    Slow(String),
    /// Nothing happened this tick (a chance to check for Ctrl-C).
    Tick,
}

/// The process groups of running workers, killed when tribo is interrupted.
static LIVE: Mutex<Vec<libc::pid_t>> = Mutex::new(Vec::new());
/// Temporary paths to remove when tribo is interrupted.
static TEMPS: Mutex<Vec<(u64, PathBuf)>> = Mutex::new(Vec::new());
static NEXT_TEMP: AtomicU64 = AtomicU64::new(1);

/// A temporary path removed when tribo is interrupted (SIGINT, SIGTERM, SIGHUP) while this
/// guard lives; dropping it forgets the path (its owner removes or keeps it).
#[must_use]
pub struct TempGuard(u64);

impl Drop for TempGuard {
    fn drop(&mut self) {
        TEMPS
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .retain(|(id, _)| *id != self.0);
    }
}

/// Remove `path` (a file or a directory tree) if tribo is interrupted while the guard lives.
pub fn register_temp(path: &Path) -> TempGuard {
    let id = NEXT_TEMP.fetch_add(1, Ordering::Relaxed);
    TEMPS
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .push((id, path.to_path_buf()));
    TempGuard(id)
}

/// On SIGINT, SIGTERM or SIGHUP: kill every worker's process group, remove the registered
/// temporary paths, then end with the signal. For a command-line process (Python has its own
/// Ctrl-C handling, [`Event::Tick`]).
///
/// The process also becomes a child subreaper (Linux): a process a law started that outlives
/// its worker (a double fork, a worker that `_exit`ed) is adopted by it instead of by init, and
/// killed and counted with its worker's family.
pub fn handle_termination() {
    sys::adopt_orphans();
    let Some(pipe) = sys::termination_pipe() else {
        return;
    };
    let _ = std::thread::Builder::new()
        .name("tribo-signals".into())
        .spawn(move || {
            let mut byte = [0u8; 1];
            loop {
                let mut fds = [libc::pollfd {
                    fd: pipe.as_raw_fd(),
                    events: libc::POLLIN,
                    revents: 0,
                }];
                sys::poll(&mut fds, Duration::from_secs(3600));
                if let Ok(1) = sys::read(pipe.as_raw_fd(), &mut byte) {
                    break;
                }
            }
            let signal = i32::from(byte[0]);
            let live = LIVE.lock().unwrap_or_else(|p| p.into_inner());
            for pgid in live.iter() {
                sys::end_family(*pgid, &live);
            }
            // Held until the process is gone: an owner that drops its guard to put its
            // temporary in place (a result set's swap) waits, and never moves a half-removed one.
            let temps = TEMPS.lock().unwrap_or_else(|p| p.into_inner());
            for (_, path) in temps.iter() {
                // Never following a link: remove_dir_all does not, and a file is unlinked.
                let _ = std::fs::remove_dir_all(path).or_else(|_| std::fs::remove_file(path));
            }
            guard::allow_exit();
            sys::die_of(signal)
        });
}

/// Lines already forwarded once (warnings repeated by every worker of a study).
static FORWARDED: Mutex<Option<HashSet<String>>> = Mutex::new(None);

/// Forward a worker's standard-error line to this process's standard error; a `warning:` line
/// only the first time (every worker of a study finds the same plugin directories).
pub fn forward_stderr(line: &str) {
    if line.starts_with("warning:") {
        let mut seen = FORWARDED.lock().unwrap_or_else(|p| p.into_inner());
        if !seen
            .get_or_insert_with(HashSet::new)
            .insert(line.to_string())
        {
            return;
        }
    }
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// A running worker process.
pub struct Worker {
    pid: libc::pid_t,
    token: [u8; 16],
    limits: Limits,
    started: Instant,
    chan: OwnedFd,
    markers: OwnedFd,
    stderr: OwnedFd,
    shared: Option<sys::Mapping>,
    /// Bytes of the channel not yet parsed.
    inbuf: Vec<u8>,
    /// Bytes to send.
    outbuf: Vec<u8>,
    marker_buf: Vec<u8>,
    stderr_buf: Vec<u8>,
    stderr_tail: Vec<u8>,
    /// Bytes of standard error forwarded during the current request.
    stderr_forwarded: usize,
    /// Bytes of standard error dropped past [`STDERR_FORWARD_BYTES`], not yet reported.
    stderr_dropped: u64,
    /// Registered names of plugin code, by id (told by the worker).
    names: BTreeMap<usize, String>,
    /// Marker reports: (kind, text).
    reports: Vec<(String, String)>,
    /// The shared-page marks the parent has seen: per slot, the mark and since when.
    seen: Vec<(u64, Instant)>,
    progress: u64,
    /// When the group's memory was last added up.
    memory_checked: Instant,
    ended: bool,
}

impl Worker {
    /// Start `command` as a worker with `limits`: its own session and process group, standard
    /// input and output on `/dev/null`, standard error piped to this process, the channel on
    /// descriptors 3 (socket), 4 (marker pipe) and 5 (shared page). The command must run
    /// [`crate::serve`].
    pub fn start(mut command: Command, limits: Limits) -> Result<Self, WorkerFailure> {
        let io = |what: &str, e: std::io::Error| WorkerFailure::Io(format!("{what}: {e}"));
        let token = sys::random_token().map_err(|e| io("drawing the job token", e))?;
        let (chan, child_chan) = sys::socketpair().map_err(|e| io("creating the channel", e))?;
        let (markers, child_markers) =
            sys::pipe().map_err(|e| io("creating the marker pipe", e))?;
        let shared_fd = sys::memfd(SHARED_LEN);
        let shared = shared_fd
            .as_ref()
            .and_then(|fd| sys::Mapping::new(fd.as_raw_fd(), SHARED_LEN).ok());
        let mut moves = vec![
            (child_chan.as_raw_fd(), CHANNEL_FD),
            (child_markers.as_raw_fd(), MARKER_FD),
        ];
        if let (Some(fd), Some(_)) = (&shared_fd, &shared) {
            moves.push((fd.as_raw_fd(), SHARED_FD));
        }
        // SAFETY: getpid has no preconditions.
        let parent = unsafe { libc::getpid() };
        command
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        // SAFETY: child_setup makes only async-signal-safe calls (setsid, prctl, fcntl, dup2).
        unsafe {
            command.pre_exec(move || sys::child_setup(&moves, parent));
        }
        // Started and listed under the lock, so another worker's end never takes this one,
        // seen before it is listed, for an orphan to kill.
        let mut live = LIVE.lock().unwrap_or_else(|p| p.into_inner());
        let mut child = command
            .spawn()
            .map_err(|e| io("starting a worker process", e))?;
        let pid = child.id() as libc::pid_t;
        live.push(pid);
        drop(live);
        drop((child_chan, child_markers, shared_fd));
        let stderr: OwnedFd = match child.stderr.take() {
            Some(e) => e.into(),
            None => return Err(WorkerFailure::Io("the worker has no standard error".into())),
        };
        for fd in [chan.as_raw_fd(), markers.as_raw_fd(), stderr.as_raw_fd()] {
            sys::set_nonblocking(fd).map_err(|e| io("setting up the channel", e))?;
        }
        // The Child handle is dropped without waiting: this worker is reaped by `finish`.
        drop(child);
        let hello = rmp_serde::to_vec_named(&limits)
            .map_err(|e| WorkerFailure::Io(format!("encoding the limits: {e}")))?;
        Ok(Self {
            pid,
            token,
            limits,
            started: Instant::now(),
            chan,
            markers,
            stderr,
            shared,
            inbuf: Vec::new(),
            outbuf: frame::encode(&token, Kind::Hello, &hello),
            marker_buf: Vec::new(),
            stderr_buf: Vec::new(),
            stderr_tail: Vec::new(),
            stderr_forwarded: 0,
            stderr_dropped: 0,
            names: BTreeMap::new(),
            reports: Vec::new(),
            seen: vec![(0, Instant::now()); inflight::SLOTS],
            progress: 0,
            memory_checked: Instant::now(),
            ended: false,
        })
    }

    /// The worker's process id (its process group's too).
    pub fn pid(&self) -> u32 {
        self.pid as u32
    }

    /// The limits the worker was started with.
    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// Whether the worker can take another request (it has not ended, stopped or failed).
    pub fn alive(&self) -> bool {
        !self.ended && sys::peek(self.pid).is_none()
    }

    /// Send `request` and wait for its reply, reporting what happens meanwhile to `events`
    /// (which may stop the wait by returning an error). A failure of the worker (it ended,
    /// stopped, ran out of a limit, or forged its channel) is the error; after it the worker is
    /// gone and only [`Worker::finish`] is left to call.
    pub fn call<Q: Serialize, A: DeserializeOwned>(
        &mut self,
        request: &Q,
        events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>,
    ) -> Result<A, WorkerFailure> {
        if self.ended {
            return Err(WorkerFailure::Io("the worker has already ended".into()));
        }
        let job = rmp_serde::to_vec_named(request)
            .map_err(|e| WorkerFailure::Io(format!("encoding the job: {e}")))?;
        // The time limit is per request (a long-lived worker serves many).
        self.started = Instant::now();
        let nonce = sys::random_token()
            .map_err(|e| WorkerFailure::Io(format!("drawing the request's nonce: {e}")))?;
        let mut payload = Vec::with_capacity(frame::NONCE + job.len());
        payload.extend_from_slice(&nonce);
        payload.extend_from_slice(&job);
        self.outbuf
            .extend_from_slice(&frame::encode(&self.token, Kind::Job, &payload));
        self.stderr_forwarded = 0;
        let reply = self.confirmed_reply(&nonce, events);
        self.report_dropped(events);
        match reply {
            Ok(payload) => match rmp_serde::from_slice::<Reply<A>>(&payload) {
                Ok(Reply::Ok(a)) => Ok(a),
                Ok(Reply::Err(message)) => Err(WorkerFailure::Study(message)),
                Ok(Reply::Internal(message)) => Err(WorkerFailure::Internal(message)),
                Err(e) => {
                    self.kill();
                    Err(WorkerFailure::Internal(format!(
                        "reading the worker's reply: {e}"
                    )))
                }
            },
            Err(e) => {
                self.kill();
                Err(e)
            }
        }
    }

    /// End the worker: tell it there is nothing more, give it a moment to exit, then kill its
    /// whole process group (whatever a law started in it goes too) and reap it.
    pub fn finish(mut self) {
        if !self.ended {
            self.outbuf
                .extend_from_slice(&frame::encode(&self.token, Kind::Bye, &[]));
            let _ = self.flush_out();
            let until = Instant::now() + Duration::from_millis(200);
            while Instant::now() < until && sys::peek(self.pid).is_none() {
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        self.kill();
    }

    /// Kill the process group and reap the worker (once).
    fn kill(&mut self) {
        if self.pid <= 0 {
            return;
        }
        // The worker is not reaped yet (peek does not reap), so its process group's id cannot
        // have been reused. Its children that left the group (`setsid`) first, while they are
        // still its children and so can be found; then the orphans it or this process adopted.
        let left = {
            let mut live = LIVE.lock().unwrap_or_else(|p| p.into_inner());
            live.retain(|p| *p != self.pid);
            sys::end_family(self.pid, &live)
        };
        sys::reap(self.pid, Duration::from_secs(2));
        self.pid = 0;
        self.ended = true;
        if left > 0 {
            let laws = match self.running_or_loaded().first() {
                Some(l) => l.strip_prefix(NO_CALL_PREFIX).unwrap_or(l).to_string(),
                None => "no law".to_string(),
            };
            forward_stderr(&format!(
                "warning: {left} process{} started by the laws of a worker ({laws}) {} still running when the worker ended (a daemon, or a double fork); tribo killed {}",
                if left == 1 { "" } else { "es" },
                if left == 1 { "was" } else { "were" },
                if left == 1 { "it" } else { "them" },
            ));
        }
    }

    /// Send what is queued, as far as the socket takes it now.
    fn flush_out(&mut self) -> std::io::Result<()> {
        while !self.outbuf.is_empty() {
            match sys::send(self.chan.as_raw_fd(), &self.outbuf) {
                Ok(n) => {
                    self.outbuf.drain(..n);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return Ok(()),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// The reply to the request of `nonce`, once the worker, still alive, has echoed a fresh
    /// nonce sent after it: a reply with another nonce, or one the worker does not stand behind
    /// (a law forged it and died), is not accepted.
    fn confirmed_reply(
        &mut self,
        nonce: &[u8; 16],
        events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>,
    ) -> Result<Vec<u8>, WorkerFailure> {
        let reply = self.wait_frame(Kind::Reply, events)?;
        if reply.get(..frame::NONCE) != Some(&nonce[..]) {
            return Err(WorkerFailure::Forged {
                running: self.running_now(),
            });
        }
        let check = sys::random_token()
            .map_err(|e| WorkerFailure::Io(format!("drawing the confirmation nonce: {e}")))?;
        self.outbuf
            .extend_from_slice(&frame::encode(&self.token, Kind::Confirm, &check));
        let echo = self.wait_frame(Kind::Ack, events)?;
        if echo != check {
            return Err(WorkerFailure::Forged {
                running: self.running_now(),
            });
        }
        Ok(reply[frame::NONCE..].to_vec())
    }

    /// Pump the channel until a frame of `kind` (a reply, an acknowledgement) arrives or the
    /// worker fails; any other frame but streamed data is forged.
    fn wait_frame(
        &mut self,
        kind: Kind,
        events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>,
    ) -> Result<Vec<u8>, WorkerFailure> {
        loop {
            let _ = self.flush_out();
            let mut fds = [
                pollfd(&self.chan, !self.outbuf.is_empty()),
                pollfd(&self.markers, false),
                pollfd(&self.stderr, false),
            ];
            sys::poll(&mut fds, TICK);
            if let Some((got, payload)) = self.read_all(events)? {
                if got != kind {
                    return Err(WorkerFailure::Forged {
                        running: self.running_now(),
                    });
                }
                return Ok(payload);
            }
            if let Some(state) = sys::peek(self.pid) {
                return Err(self.ended_with(state, events));
            }
            self.backstops()?;
            if let Some(p) = self.shared_progress() {
                if p != self.progress {
                    self.progress = p;
                    events(Event::Progress(p))?;
                }
            }
            events(Event::Tick)?;
        }
    }

    /// The worker has ended or stopped: read what it left (for a bounded time), and say why it
    /// gave no reply. A reply that arrived meanwhile still counts.
    fn ended_with(
        &mut self,
        state: State,
        events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>,
    ) -> WorkerFailure {
        let running = self.running_now();
        let until = Instant::now() + DRAIN;
        while Instant::now() < until {
            let mut fds = [
                pollfd(&self.chan, false),
                pollfd(&self.markers, false),
                pollfd(&self.stderr, false),
            ];
            sys::poll(&mut fds, Duration::from_millis(10));
            match self.read_all(events) {
                Ok(Some(_)) | Err(_) => break,
                Ok(None) => {}
            }
            if fds.iter().all(|f| f.revents == 0) {
                break;
            }
        }
        self.flush_stderr_line(events);
        self.kill();
        self.interpret(state, running)
    }

    /// Read what is available on the three pipes (a bounded amount of each); a reply or an
    /// acknowledgement, with its payload, once it is whole.
    fn read_all(
        &mut self,
        events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>,
    ) -> Result<Option<(Kind, Vec<u8>)>, WorkerFailure> {
        let mut buf = [0u8; 65536];
        // Each pipe is read for at most READ_BUDGET bytes a turn, then the caller checks the
        // limits: a writer that never pauses (a law's thread, or a process it detached with
        // `setsid`, flooding standard error) cannot hold the parent in here.
        // Markers first: a law's name registered before a reply or a death is then known.
        let mut budget = READ_BUDGET;
        while let Ok(n @ 1..) = sys::read(self.markers.as_raw_fd(), &mut buf) {
            self.marker_buf.extend_from_slice(&buf[..n]);
            self.parse_markers(events)?;
            budget = budget.saturating_sub(n);
            if budget == 0 {
                break;
            }
        }
        let mut budget = READ_BUDGET;
        while let Ok(n @ 1..) = sys::read(self.stderr.as_raw_fd(), &mut buf) {
            for &b in &buf[..n] {
                if b == b'\n' {
                    self.flush_stderr_line(events);
                } else if self.stderr_buf.len() < 64 * 1024 {
                    self.stderr_buf.push(b);
                }
            }
            budget = budget.saturating_sub(n);
            if budget == 0 {
                break;
            }
        }
        let mut budget = READ_BUDGET;
        while let Ok(n @ 1..) = sys::read(self.chan.as_raw_fd(), &mut buf) {
            self.inbuf.extend_from_slice(&buf[..n]);
            budget = budget.saturating_sub(n);
            if budget == 0 {
                break;
            }
        }
        loop {
            match frame::parse(&self.inbuf, &self.token) {
                Parsed::Partial => return Ok(None),
                Parsed::Forged => {
                    let running = self.running_now();
                    return Err(WorkerFailure::Forged { running });
                }
                Parsed::Frame { kind, len } => {
                    let payload: Vec<u8> = self.inbuf[frame::HEADER..frame::HEADER + len].to_vec();
                    self.inbuf.drain(..frame::HEADER + len);
                    match kind {
                        Kind::Reply | Kind::Ack => return Ok(Some((kind, payload))),
                        Kind::Data => events(Event::Data(&payload))?,
                        _ => {
                            let running = self.running_now();
                            return Err(WorkerFailure::Forged { running });
                        }
                    }
                }
            }
        }
    }

    /// One whole line of the worker's standard error: forwarded, and kept for the tail.
    fn flush_stderr_line(
        &mut self,
        events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>,
    ) {
        if self.stderr_buf.is_empty() {
            return;
        }
        let line = String::from_utf8_lossy(&self.stderr_buf).into_owned();
        self.stderr_buf.clear();
        self.stderr_tail.extend_from_slice(line.as_bytes());
        self.stderr_tail.push(b'\n');
        if self.stderr_tail.len() > 2 * STDERR_TAIL_BYTES {
            self.stderr_tail
                .drain(..self.stderr_tail.len() - STDERR_TAIL_BYTES);
        }
        // Past the cap, lines are counted, not forwarded: a flood of output costs the user's
        // terminal nothing, and the count is said once the request ends.
        if self.stderr_forwarded < STDERR_FORWARD_BYTES {
            self.stderr_forwarded += line.len() + 1;
            let _ = events(Event::Stderr(&line));
        } else {
            self.stderr_dropped += line.len() as u64 + 1;
        }
    }

    /// Say, once, how much of the worker's standard error was dropped past the cap.
    fn report_dropped(&mut self, events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>) {
        if self.stderr_dropped > 0 {
            let line = format!(
                "note: the worker's standard error (what its laws printed) was cut after {} KiB; {} more bytes were dropped",
                STDERR_FORWARD_BYTES >> 10,
                self.stderr_dropped
            );
            self.stderr_dropped = 0;
            let _ = events(Event::Stderr(&line));
        }
    }

    /// Parse whole marker lines; lines without the job's token (a law writing to the pipe)
    /// are ignored.
    fn parse_markers(
        &mut self,
        events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>,
    ) -> Result<(), WorkerFailure> {
        let hex = frame::hex(&self.token);
        while let Some(end) = self.marker_buf.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.marker_buf.drain(..=end).collect();
            let Some(rest) = line[..line.len() - 1].strip_prefix(&hex[..]) else {
                continue;
            };
            let text = String::from_utf8_lossy(rest).into_owned();
            let text = text.strip_prefix(' ').unwrap_or(&text);
            let (kind, body) = text.split_once(' ').unwrap_or((text, ""));
            match kind {
                "name" => {
                    if let Some((id, name)) = body.split_once(' ') {
                        if let Ok(id) = id.parse() {
                            self.names.insert(id, name.to_string());
                        }
                    }
                }
                "slow" => {
                    let (secs, code) = body.split_once(' ').unwrap_or(("?", body));
                    let secs: f64 = secs.parse().unwrap_or(0.0);
                    events(Event::Slow(guard::slow_note(
                        code,
                        secs,
                        self.limits.call_s,
                    )))?;
                }
                _ => self.reports.push((kind.to_string(), body.to_string())),
            }
        }
        if self.marker_buf.len() > 1 << 20 {
            self.marker_buf.clear();
        }
        Ok(())
    }

    /// The progress position the worker published, if it has a shared page.
    fn shared_progress(&self) -> Option<u64> {
        let shared = self.shared.as_ref()?;
        // SAFETY: the mapping is SHARED_LEN bytes holding a `Shared` (atomics only).
        let s = unsafe { &*(shared.ptr() as *const Shared) };
        Some(s.progress.load(Ordering::Relaxed))
    }

    /// The marks of the worker's threads now: (slot, mark) of every slot in a call.
    fn marks(&self) -> Vec<(usize, u64)> {
        let Some(shared) = self.shared.as_ref() else {
            return Vec::new();
        };
        // SAFETY: as in `shared_progress`.
        let s = unsafe { &*(shared.ptr() as *const Shared) };
        s.table
            .slots
            .iter()
            .enumerate()
            .map(|(i, m)| (i, m.load(Ordering::Acquire)))
            .filter(|(_, m)| inflight::id_of(*m) != 0)
            .collect()
    }

    /// The plugin code the worker runs now (from its shared page), by name.
    fn running_now(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for (_, mark) in self.marks() {
            let id = inflight::id_of(mark);
            let name = self
                .names
                .get(&id)
                .cloned()
                .unwrap_or_else(|| format!("plugin code #{id}"));
            if !out.contains(&name) {
                out.push(name);
            }
        }
        out
    }

    /// The plugin code running now; when none is, the laws the worker has loaded, said as
    /// such (a child a law started, or a law's thread, may be what failed).
    fn running_or_loaded(&self) -> Vec<String> {
        let running = self.running_now();
        if !running.is_empty() {
            return running;
        }
        let laws = self.loaded_laws();
        if laws.is_empty() {
            return Vec::new();
        }
        vec![format!("{}{}", NO_CALL_PREFIX, laws.join(", "))]
    }

    /// The laws the worker has loaded, each once ("law `x` (file) at joint `j`" where bound).
    fn loaded_laws(&self) -> Vec<String> {
        let mut laws: Vec<&str> = self
            .names
            .values()
            .map(String::as_str)
            .filter(|n| n.starts_with("law `"))
            .collect();
        laws.sort_unstable();
        laws.dedup();
        // "law `x` (file)" is said by "law `x` (file) at joint `j`" already.
        let all = laws.clone();
        laws.retain(|l| !all.iter().any(|o| o != l && o.starts_with(l)));
        laws.into_iter().map(str::to_string).collect()
    }

    /// The limits the worker enforces itself, enforced again from outside a little later: a
    /// stopped, deadlocked or signal-blocking worker cannot report.
    fn backstops(&mut self) -> Result<(), WorkerFailure> {
        let now = Instant::now();
        if let Some(t) = self.limits.time() {
            if now >= self.started + t + KILL_GRACE {
                let running = self.running_now();
                self.kill();
                return Err(WorkerFailure::TimeLimit {
                    limit_s: self.limits.time_s,
                    running,
                });
            }
        }
        // The worker's group as a whole (the children its laws started, the memory files they
        // hold): counted from outside, where no law can hide it.
        if self.limits.memory_mb > 0 && now >= self.memory_checked + MEMORY_TICK {
            self.memory_checked = now;
            let bytes = sys::group_memory_bytes(self.pid);
            if bytes > self.limits.memory_mb.saturating_mul(1 << 20) {
                let running = self.running_or_loaded();
                self.kill();
                return Err(WorkerFailure::MemoryLimit {
                    limit_mb: self.limits.memory_mb,
                    resident_mb: bytes >> 20,
                    running,
                });
            }
        }
        let marks = self.marks();
        let mut current = vec![0u64; inflight::SLOTS];
        for (slot, mark) in marks {
            current[slot] = mark;
        }
        for (slot, mark) in current.into_iter().enumerate() {
            let (seen, since) = self.seen[slot];
            if seen != mark {
                self.seen[slot] = (mark, now);
            } else if mark != 0 {
                if let Some(limit) = self.limits.call() {
                    if now - since >= limit + KILL_GRACE {
                        let id = inflight::id_of(mark);
                        let code = self
                            .names
                            .get(&id)
                            .cloned()
                            .unwrap_or_else(|| "plugin code".into());
                        self.kill();
                        return Err(WorkerFailure::CallLimit {
                            text: format!(
                                "{code} did not return from one call in {} s, the limit for one law call (--call-limit-s, in Python call_limit_s; 0: none); the worker process did not answer its watchdog, so the call's inputs are unknown",
                                self.limits.call_s
                            ),
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// Why the worker, ended or stopped as `state`, gave no reply.
    fn interpret(&self, state: State, running: Vec<String>) -> WorkerFailure {
        // What the worker itself said was running (from its private marks) is believed over
        // the shared page, which a law can write; the page is for when the worker could not
        // speak (`_exit`, SIGKILL, SIGSTOP).
        let mut reported: Vec<String> = Vec::new();
        for (kind, body) in &self.reports {
            if kind == "running" && !reported.contains(body) {
                reported.push(body.clone());
            }
        }
        let mut running = if reported.is_empty() {
            running
        } else {
            reported
        };
        if running.is_empty() {
            running = self.running_or_loaded();
        }
        let report = |k: &str| self.reports.iter().find(|(kind, _)| kind == k);
        let last_words = String::from_utf8_lossy(&self.stderr_tail)
            .lines()
            .map(str::trim)
            .rfind(|l| !l.is_empty())
            .map(|l| l.chars().take(300).collect::<String>());
        if let Some((_, text)) = report("stuck") {
            return WorkerFailure::CallLimit { text: text.clone() };
        }
        if let Some((_, mb)) = report("limit-memory") {
            return WorkerFailure::MemoryLimit {
                limit_mb: self.limits.memory_mb,
                resident_mb: mb.trim().parse().unwrap_or(0),
                running,
            };
        }
        if report("limit-time").is_some() {
            return WorkerFailure::TimeLimit {
                limit_s: self.limits.time_s,
                running,
            };
        }
        if report("exit").is_some() {
            return WorkerFailure::PluginExit { running };
        }
        match state {
            State::Stopped(signal) => WorkerFailure::Stopped { signal, running },
            State::Signaled(signal) => WorkerFailure::Signal {
                signal,
                running,
                last_words,
            },
            State::Exited(code) => WorkerFailure::NoReply {
                code,
                running,
                last_words,
            },
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.kill();
    }
}

fn pollfd(fd: &OwnedFd, write: bool) -> libc::pollfd {
    libc::pollfd {
        fd: fd.as_raw_fd(),
        events: libc::POLLIN | if write { libc::POLLOUT } else { 0 },
        revents: 0,
    }
}

/// Run each task in its own worker process (`command` makes the command that starts one; at
/// most as many at once as the machine has cores), returning the results in the order of
/// `tasks` as soon as every one has finished or failed. `events` hears each worker's events
/// with the task's index.
pub fn run_all<J, T>(
    tasks: &[J],
    command: &(dyn Fn() -> Command + Sync),
    limits: Limits,
    events: &(dyn Fn(usize, Event<'_>) + Sync),
) -> Vec<Result<T, WorkerFailure>>
where
    J: Serialize + Sync,
    T: DeserializeOwned + Send,
{
    run_all_watched(tasks, command, limits, events, None)
}

/// [`run_all`], with the result folder `watched` (where tribo writes only after every task
/// has finished) watched while the tasks run: an entry that appears there fails the task whose
/// worker made it ([`WorkerFailure::Planted`]), also when a process a law started made it.
/// A worker names what its own process made; what another process made is charged to the
/// task whose worker was running then; when several were, each of them runs again alone and
/// the one that makes an entry again is charged (the others keep their second result); where
/// none does, each of them is (said as such). Linux with fanotify; elsewhere as [`run_all`].
pub fn run_all_watched<J, T>(
    tasks: &[J],
    command: &(dyn Fn() -> Command + Sync),
    limits: Limits,
    events: &(dyn Fn(usize, Event<'_>) + Sync),
    watched: Option<&Path>,
) -> Vec<Result<T, WorkerFailure>>
where
    J: Serialize + Sync,
    T: DeserializeOwned + Send,
{
    // Only a folder that exists is watched: the appearance of one that does not may be
    // another tribo command committing the same folder at the same time (a supported use),
    // which an unprivileged watch cannot tell from a law's child (it sees no process ids).
    #[cfg(target_os = "linux")]
    let watch = watched.filter(|d| d.is_dir()).and_then(FolderWatch::new);
    #[cfg(not(target_os = "linux"))]
    let watch: Option<FolderWatch> = {
        let _ = watched;
        None
    };
    let watch = watch.as_ref();
    let parallel = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(tasks.len().max(1));
    let next = AtomicUsize::new(0);
    let mut runs: Vec<Option<Run<T>>> = (0..tasks.len()).map(|_| None).collect();
    let (tx, rx) = mpsc::channel();
    std::thread::scope(|s| {
        for _ in 0..parallel {
            let tx = tx.clone();
            let next = &next;
            s.spawn(move || loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(task) = tasks.get(i) else { break };
                let r = run_watched(task, i, command(), limits, watch, &mut |e| {
                    events(i, e);
                    Ok(())
                });
                if tx.send((i, r)).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        for (i, r) in rx {
            runs[i] = Some(r);
        }
    });
    let mut runs: Vec<Run<T>> = runs
        .into_iter()
        .map(|r| {
            r.unwrap_or_else(|| Run {
                result: Err(WorkerFailure::Io("a worker thread stopped early".into())),
                laws: Vec::new(),
                claimed: Vec::new(),
            })
        })
        .collect();
    #[cfg(target_os = "linux")]
    if let Some(watch) = watch {
        watch.charge(tasks, command, limits, events, &mut runs);
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (&mut runs, watch);
    runs.into_iter().map(|r| r.result).collect()
}

/// One task's run: its result, the laws its worker loaded, and the entries of the watched
/// folder its worker said its own process made.
struct Run<T> {
    result: Result<T, WorkerFailure>,
    laws: Vec<String>,
    claimed: Vec<String>,
}

/// Task `i` in a fresh worker, ended afterwards, with the watched folder (if any) told when
/// the worker starts and once its whole family is gone.
fn run_watched<J: Serialize, T: DeserializeOwned>(
    task: &J,
    i: usize,
    command: Command,
    limits: Limits,
    watch: Option<&FolderWatch>,
    events: &mut dyn FnMut(Event<'_>) -> Result<(), WorkerFailure>,
) -> Run<T> {
    if let Some(w) = watch {
        w.enter(i);
    }
    let run = match Worker::start(command, limits) {
        Err(e) => Run {
            result: Err(e),
            laws: Vec::new(),
            claimed: Vec::new(),
        },
        Ok(mut w) => {
            let result = w.call(task, events);
            let laws = w.loaded_laws();
            let claimed = w
                .reports
                .iter()
                .filter(|(k, _)| k == "planted")
                .map(|(_, name)| name.clone())
                .collect();
            w.finish();
            Run {
                result,
                laws,
                claimed,
            }
        }
    };
    if let Some(w) = watch {
        w.leave(i);
    }
    run
}

/// The parent's watch on a result folder while tasks run: each entry made there, with the
/// tasks whose workers were running when it was made (the one that made it among them: a
/// worker's family is killed before its task is said to have left).
#[cfg(target_os = "linux")]
struct FolderWatch {
    watch: crate::planted::Planted,
    state: Mutex<Seen>,
}

/// The tasks running now, and each entry seen with its suspects.
#[cfg(target_os = "linux")]
#[derive(Default)]
struct Seen {
    live: Vec<usize>,
    entries: Vec<(String, Vec<usize>)>,
}

#[cfg(not(target_os = "linux"))]
enum FolderWatch {}

#[cfg(target_os = "linux")]
impl FolderWatch {
    fn new(dir: &Path) -> Option<Self> {
        Some(Self {
            watch: crate::planted::Planted::watch(dir)?,
            state: Mutex::new(Seen::default()),
        })
    }

    /// Record the entries made since the last look, each with the tasks running now.
    fn look(state: &mut Seen, made: Vec<String>) {
        for name in made {
            let live = state.live.clone();
            match state.entries.iter_mut().find(|(n, _)| *n == name) {
                Some((_, suspects)) => {
                    for t in live {
                        if !suspects.contains(&t) {
                            suspects.push(t);
                        }
                    }
                }
                None => state.entries.push((name, live)),
            }
        }
    }

    fn enter(&self, task: usize) {
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        Self::look(&mut s, self.watch.made_by_anyone());
        s.live.push(task);
    }

    fn leave(&self, task: usize) {
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        Self::look(&mut s, self.watch.made_by_anyone());
        s.live.retain(|t| *t != task);
    }

    /// The entries seen so far, with their suspects, taken.
    fn take(&self) -> Vec<(String, Vec<usize>)> {
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        Self::look(&mut s, self.watch.made_by_anyone());
        std::mem::take(&mut s.entries)
    }

    /// Charge each entry made while the tasks ran to the task that made it, running the
    /// suspects of an entry made while several ran again, one at a time.
    fn charge<J: Serialize, T: DeserializeOwned>(
        &self,
        tasks: &[J],
        command: &(dyn Fn() -> Command + Sync),
        limits: Limits,
        events: &(dyn Fn(usize, Event<'_>) + Sync),
        runs: &mut [Run<T>],
    ) {
        let mut charged: BTreeMap<usize, (Vec<String>, bool)> = BTreeMap::new();
        let mut ambiguous: Vec<(String, Vec<usize>)> = Vec::new();
        for (name, suspects) in self.take() {
            // Named by the worker that made it: that task has failed already, naming it.
            if runs.iter().any(|r| r.claimed.contains(&name)) {
                continue;
            }
            match suspects[..] {
                [] => {}
                [one] => charged.entry(one).or_default().0.push(name),
                _ => ambiguous.push((name, suspects)),
            }
        }
        let mut again: Vec<usize> = ambiguous
            .iter()
            .flat_map(|(_, s)| s.iter().copied())
            .filter(|t| !charged.contains_key(t))
            .collect();
        again.sort_unstable();
        again.dedup();
        if !again.is_empty() {
            // What they made is removed, so making it again is seen again.
            for (name, _) in &ambiguous {
                remove_entry(&self.watch.dir().join(name));
            }
            let _ = self.take();
        }
        for t in again {
            let rerun: Run<T> =
                run_watched(&tasks[t], t, command(), limits, Some(self), &mut |e| {
                    events(t, e);
                    Ok(())
                });
            let made: Vec<String> = self
                .take()
                .into_iter()
                .map(|(n, _)| n)
                .filter(|n| !rerun.claimed.contains(n))
                .collect();
            runs[t] = rerun;
            if !made.is_empty() {
                charged.entry(t).or_default().0.extend(made);
            }
        }
        for (name, suspects) in ambiguous {
            if !suspects.iter().any(|t| charged.contains_key(t)) {
                for t in suspects {
                    let c = charged.entry(t).or_default();
                    c.0.push(name.clone());
                    c.1 = true;
                }
            }
        }
        for (t, (mut entries, uncertain)) in charged {
            entries.dedup();
            let run = &mut runs[t];
            if run.result.is_ok() {
                run.result = Err(WorkerFailure::Planted {
                    entries,
                    dir: self.watch.dir().display().to_string(),
                    laws: run.laws.clone(),
                    uncertain,
                });
            }
        }
    }
}

#[cfg(not(target_os = "linux"))]
impl FolderWatch {
    fn enter(&self, _: usize) {
        match *self {}
    }

    fn leave(&self, _: usize) {
        match *self {}
    }
}

/// Remove a planted entry, never following a link.
#[cfg(target_os = "linux")]
fn remove_entry(path: &Path) {
    let _ = match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => std::fs::remove_dir_all(path),
        Ok(_) => std::fs::remove_file(path),
        Err(_) => Ok(()),
    };
}
