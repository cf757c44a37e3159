//! The system calls of worker processes, kept in one place: process groups, the channel's
//! socket and pipes, the shared page, `poll`, `waitid`, `killpg`, signal dispositions. Unix
//! only (tribo is tested on Linux; the shared page needs `memfd_create`, Linux).

use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::time::{Duration, Instant};

/// Turn a `-1` return into the OS error.
fn check(ret: libc::c_int) -> io::Result<libc::c_int> {
    if ret < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(ret)
    }
}

/// 16 random bytes from the operating system.
pub(crate) fn random_token() -> io::Result<[u8; 16]> {
    let mut t = [0u8; 16];
    getrandom::fill(&mut t).map_err(|e| io::Error::other(e.to_string()))?;
    Ok(t)
}

/// A connected pair of Unix stream sockets, close-on-exec.
pub(crate) fn socketpair() -> io::Result<(OwnedFd, OwnedFd)> {
    let mut fds = [0 as libc::c_int; 2];
    // SAFETY: socketpair writes two descriptors into the array on success.
    check(unsafe {
        libc::socketpair(
            libc::AF_UNIX,
            libc::SOCK_STREAM | libc::SOCK_CLOEXEC,
            0,
            fds.as_mut_ptr(),
        )
    })?;
    // SAFETY: both descriptors are fresh and owned by nobody else.
    Ok(unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) })
}

/// A pipe (read end, write end), close-on-exec.
pub(crate) fn pipe() -> io::Result<(OwnedFd, OwnedFd)> {
    let mut fds = [0 as libc::c_int; 2];
    // SAFETY: pipe2 writes two descriptors into the array on success.
    check(unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) })?;
    // SAFETY: both descriptors are fresh and owned by nobody else.
    Ok(unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) })
}

/// An anonymous shared-memory file of `len` bytes (zeroed), close-on-exec; `None` where the
/// system has none (then the parent names laws from the worker's reports only).
pub(crate) fn memfd(len: usize) -> Option<OwnedFd> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: a NUL-terminated name and valid flags.
        let fd = unsafe { libc::memfd_create(c"tribo-inflight".as_ptr(), libc::MFD_CLOEXEC) };
        if fd < 0 {
            return None;
        }
        // SAFETY: fd is fresh and ours.
        let fd = unsafe { OwnedFd::from_raw_fd(fd) };
        // SAFETY: ftruncate on our own file.
        if unsafe { libc::ftruncate(fd.as_raw_fd(), len as libc::off_t) } < 0 {
            return None;
        }
        Some(fd)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = len;
        None
    }
}

/// A shared read-write mapping of a file, unmapped when dropped (parent side).
pub(crate) struct Mapping {
    ptr: *mut libc::c_void,
    len: usize,
}

// SAFETY: the mapping is plain memory accessed only through atomics.
unsafe impl Send for Mapping {}
// SAFETY: as above.
unsafe impl Sync for Mapping {}

impl Mapping {
    /// Map `len` bytes of `fd` shared, read-write.
    pub(crate) fn new(fd: RawFd, len: usize) -> io::Result<Self> {
        let ptr = map_shared(fd, len)?;
        Ok(Self { ptr, len })
    }

    /// The start of the mapping.
    pub(crate) fn ptr(&self) -> *mut libc::c_void {
        self.ptr
    }
}

impl Drop for Mapping {
    fn drop(&mut self) {
        // SAFETY: unmapping exactly what `new` mapped; nothing refers to it any more.
        unsafe {
            libc::munmap(self.ptr, self.len);
        }
    }
}

/// Map `len` bytes of `fd` shared and read-write, for the rest of the process (worker side,
/// where the page holds the in-flight table) or until unmapped.
pub(crate) fn map_shared(fd: RawFd, len: usize) -> io::Result<*mut libc::c_void> {
    // SAFETY: a fresh mapping chosen by the kernel; failure is MAP_FAILED.
    let ptr = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            len,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_SHARED,
            fd,
            0,
        )
    };
    if ptr == libc::MAP_FAILED {
        Err(io::Error::last_os_error())
    } else {
        Ok(ptr)
    }
}

/// Set or clear `O_NONBLOCK` on `fd`.
pub(crate) fn set_nonblocking(fd: RawFd) -> io::Result<()> {
    // SAFETY: fcntl on a descriptor the caller owns.
    unsafe {
        let flags = check(libc::fcntl(fd, libc::F_GETFL))?;
        check(libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK))?;
    }
    Ok(())
}

/// Set close-on-exec on `fd`, so programs a law starts do not inherit it.
pub(crate) fn set_cloexec(fd: RawFd) {
    // SAFETY: fcntl on a descriptor of this process; failure leaves it as it was.
    unsafe {
        libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC);
    }
}

/// Read what is available from a non-blocking `fd` into `buf`: `Ok(0)` at end of file,
/// `Err(WouldBlock)` when nothing is there.
pub(crate) fn read(fd: RawFd, buf: &mut [u8]) -> io::Result<usize> {
    // SAFETY: reading into a buffer of the given length.
    let n = unsafe { libc::read(fd, buf.as_mut_ptr().cast(), buf.len()) };
    if n < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(n as usize)
    }
}

/// Write as much of `buf` as `fd` takes now (socket: never SIGPIPE).
pub(crate) fn send(fd: RawFd, buf: &[u8]) -> io::Result<usize> {
    // SAFETY: writing from a buffer of the given length.
    let n = unsafe { libc::send(fd, buf.as_ptr().cast(), buf.len(), libc::MSG_NOSIGNAL) };
    if n < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(n as usize)
    }
}

/// Write all of `bytes` to `fd`, retrying on interruption; allocation-free (signal handlers).
pub(crate) fn write_all(fd: RawFd, mut bytes: &[u8]) -> bool {
    while !bytes.is_empty() {
        // SAFETY: writing an initialised buffer of the given length.
        let n = unsafe { libc::write(fd, bytes.as_ptr().cast(), bytes.len()) };
        if n < 0 {
            if io::Error::last_os_error().kind() == io::ErrorKind::Interrupted {
                continue;
            }
            return false;
        }
        if n == 0 {
            return false;
        }
        bytes = &bytes[n as usize..];
    }
    true
}

/// Wait until one of `fds` is ready or `timeout` passes; the `revents` are filled in.
pub(crate) fn poll(fds: &mut [libc::pollfd], timeout: Duration) {
    let ms = timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
    // SAFETY: a valid array of pollfd of the given length.
    unsafe {
        libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, ms);
    }
}

/// How a child process stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum State {
    /// Ended with this exit status.
    Exited(i32),
    /// Killed by this signal.
    Signaled(i32),
    /// Stopped by this signal (SIGSTOP, SIGTSTP, ...).
    Stopped(i32),
}

/// Whether child `pid` has ended or stopped, without reaping it (so its process id, and so its
/// process group's, cannot be reused until [`reap`]).
pub(crate) fn peek(pid: libc::pid_t) -> Option<State> {
    // SAFETY: a zeroed siginfo_t is valid; waitid fills it for our own child.
    unsafe {
        let mut info: libc::siginfo_t = std::mem::zeroed();
        let r = libc::waitid(
            libc::P_PID,
            pid as libc::id_t,
            &mut info,
            libc::WEXITED | libc::WSTOPPED | libc::WNOHANG | libc::WNOWAIT,
        );
        if r < 0 || info.si_pid() == 0 {
            return None;
        }
        let status = info.si_status();
        match info.si_code {
            libc::CLD_EXITED => Some(State::Exited(status)),
            libc::CLD_KILLED | libc::CLD_DUMPED => Some(State::Signaled(status)),
            libc::CLD_STOPPED | libc::CLD_TRAPPED => Some(State::Stopped(status)),
            _ => None,
        }
    }
}

/// Reap child `pid` once it has ended, waiting at most `wait` (a process stuck in the kernel is
/// left as a zombie rather than hanging tribo).
pub(crate) fn reap(pid: libc::pid_t, wait: Duration) {
    let start = Instant::now();
    loop {
        let mut status = 0;
        // SAFETY: waitpid on our own child.
        let r = unsafe { libc::waitpid(pid, &mut status, libc::WNOHANG) };
        if r != 0 || start.elapsed() >= wait {
            return;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Send `signal` to the whole process group `pgid` (a worker and everything it started).
pub(crate) fn killpg(pgid: libc::pid_t, signal: libc::c_int) {
    if pgid > 1 {
        // SAFETY: signalling a process group; failure (already gone) is harmless.
        unsafe {
            libc::killpg(pgid, signal);
        }
    }
}

/// In the child between fork and exec (async-signal-safe calls only): a new session and process
/// group, death with the parent, a child subreaper (its laws' orphans stay its own), and the channel's descriptors moved to their fixed numbers
/// (`moves`: from, to; every `from` is close-on-exec, every `to` will not be).
///
/// # Safety
///
/// Only between fork and exec, as `CommandExt::pre_exec` runs it.
pub(crate) unsafe fn child_setup(moves: &[(RawFd, RawFd)], parent: libc::pid_t) -> io::Result<()> {
    check(libc::setsid())?;
    #[cfg(target_os = "linux")]
    {
        check(libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL))?;
        // The worker adopts its laws' orphans (a double fork): they stay its descendants,
        // where its parent finds, counts and kills them, instead of going to init.
        check(libc::prctl(libc::PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0))?;
        if libc::getppid() != parent {
            libc::_exit(1);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = parent;
    // First out of the way (a `from` may sit on another move's `to`), then into place.
    let mut high = [0 as RawFd; 8];
    for (i, (from, _)) in moves.iter().enumerate().take(high.len()) {
        high[i] = check(libc::fcntl(*from, libc::F_DUPFD_CLOEXEC, 64))?;
    }
    for (i, (_, to)) in moves.iter().enumerate().take(high.len()) {
        check(libc::dup2(high[i], *to))?;
    }
    Ok(())
}

/// Ignore SIGXFSZ, so a write past `ulimit -f` fails with EFBIG (a clean error naming the
/// file) instead of killing the process without a word.
pub(crate) fn ignore_file_size_signal() {
    // SAFETY: setting a standard disposition.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// Restore the default action of `signal` and raise it (to end with it after cleaning up).
pub(crate) fn die_of(signal: libc::c_int) -> ! {
    // SAFETY: restoring the default disposition and raising; _exit as a fallback.
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        libc::sigaddset(&mut set, signal);
        libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
        libc::raise(signal);
        libc::_exit(128 + signal)
    }
}

/// The write end of the self-pipe the termination signals are reported through.
static SIGNAL_PIPE: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(-1);

extern "C" fn on_termination(signal: libc::c_int) {
    let fd = SIGNAL_PIPE.load(std::sync::atomic::Ordering::Relaxed);
    if fd >= 0 {
        let byte = [signal as u8];
        // SAFETY: write(2) is async-signal-safe; a full pipe just drops the byte.
        unsafe {
            libc::write(fd, byte.as_ptr().cast(), 1);
        }
    }
}

/// Report SIGINT, SIGTERM and SIGHUP through a pipe: returns its read end, which yields one
/// byte (the signal number) per signal. `None` if it cannot be set up.
pub(crate) fn termination_pipe() -> Option<OwnedFd> {
    let (r, w) = pipe().ok()?;
    set_nonblocking(w.as_raw_fd()).ok()?;
    SIGNAL_PIPE.store(w.as_raw_fd(), std::sync::atomic::Ordering::SeqCst);
    std::mem::forget(w);
    for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: a zeroed sigaction is valid; the handler only calls write(2).
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_termination as extern "C" fn(libc::c_int) as usize;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
    Some(r)
}

/// The resident set size of process `pid` (0: this one), bytes, from /proc (Linux).
pub(crate) fn resident_bytes(pid: libc::pid_t) -> Option<u64> {
    let path = if pid == 0 {
        "/proc/self/statm".to_string()
    } else {
        format!("/proc/{pid}/statm")
    };
    let text = std::fs::read_to_string(path).ok()?;
    let pages: u64 = text.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * page_size())
}

/// The memory page size, bytes.
pub(crate) fn page_size() -> u64 {
    // SAFETY: sysconf has no preconditions.
    let n = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    if n > 0 {
        n as u64
    } else {
        4096
    }
}

/// One process as /proc/PID/stat shows it (Linux).
#[cfg(target_os = "linux")]
#[derive(Debug, Clone, Copy)]
struct Proc {
    pid: libc::pid_t,
    parent: libc::pid_t,
    group: libc::pid_t,
    session: libc::pid_t,
    zombie: bool,
}

/// Every process /proc lists now (Linux).
#[cfg(target_os = "linux")]
fn processes() -> Vec<Proc> {
    let Ok(procs) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    procs
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<libc::pid_t>().ok())
        .filter_map(stat)
        .collect()
}

/// The processes of `all` in group `pgid` and every descendant of one of them, and of `roots`
/// (by parent links; a child that left the group with `setsid` is found while its parent
/// lives, and, where the worker is a child subreaper, its orphans stay its children).
#[cfg(target_os = "linux")]
fn descendants(all: &[Proc], pgid: libc::pid_t, roots: &[libc::pid_t]) -> Vec<Proc> {
    let mut members: Vec<Proc> = all
        .iter()
        .filter(|p| p.group == pgid || roots.contains(&p.pid))
        .copied()
        .collect();
    let mut k = 0;
    while k < members.len() {
        let parent = members[k].pid;
        for p in all.iter().filter(|p| p.parent == parent) {
            if !members.iter().any(|m| m.pid == p.pid) {
                members.push(*p);
            }
        }
        k += 1;
    }
    members
}

/// The processes of worker `pgid` (Linux; empty elsewhere): every process in its process
/// group, and every descendant of one of them, including a child that left the group with
/// `setsid`. Read from /proc in one pass.
pub(crate) fn family(pgid: libc::pid_t) -> Vec<libc::pid_t> {
    #[cfg(target_os = "linux")]
    {
        descendants(&processes(), pgid, &[])
            .iter()
            .map(|p| p.pid)
            .collect()
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = pgid;
        Vec::new()
    }
}

/// This process adopts the orphans of its workers (Linux: a child subreaper), so a process
/// a law started that outlives its worker (a double fork, a worker that `_exit`ed) is found,
/// counted and killed with the worker's group instead of escaping to init.
static ADOPTING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Make this process a child subreaper (Linux; a no-op elsewhere): for a process whose only
/// children are workers and programs it waits for (the `tribo` command).
pub(crate) fn adopt_orphans() {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: prctl with constant arguments on this process.
        if unsafe { libc::prctl(libc::PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) } == 0 {
            ADOPTING.store(true, std::sync::atomic::Ordering::SeqCst);
        }
    }
}

/// Kill worker `pgid`'s whole family with SIGKILL: the children that left its group (before
/// `killpg`, while they can still be found as its descendants), its group, and, where this
/// process adopts orphans ([`adopt_orphans`]), the orphans it adopted that are not one of the
/// live workers `others` (and their descendants). Returns how many processes besides the
/// worker itself were still running (not zombies) and were killed.
pub(crate) fn end_family(pgid: libc::pid_t, others: &[libc::pid_t]) -> usize {
    #[cfg(target_os = "linux")]
    {
        let all = processes();
        // SAFETY: getpid and getsid(0) have no preconditions.
        let (me, my_session) = unsafe { (libc::getpid(), libc::getsid(0)) };
        // Orphans adopted by this process: its children in a session other than its own (its
        // own helpers stay in its session) that are not a live worker.
        let adopted: Vec<libc::pid_t> = if ADOPTING.load(std::sync::atomic::Ordering::SeqCst) {
            all.iter()
                .filter(|p| p.parent == me && p.session != my_session)
                .filter(|p| p.pid != pgid && !others.contains(&p.pid))
                .map(|p| p.pid)
                .collect()
        } else {
            Vec::new()
        };
        let members = descendants(&all, pgid, &adopted);
        let mut running = 0;
        for p in &members {
            if p.pid > 1 && p.pid != me {
                if p.pid != pgid && !p.zombie {
                    running += 1;
                }
                // SAFETY: signalling a process of our own worker's family.
                unsafe {
                    libc::kill(p.pid, libc::SIGKILL);
                }
            }
        }
        killpg(pgid, libc::SIGKILL);
        // The adopted ones are this process's children now: reaped, so no zombie is left.
        for pid in adopted {
            reap(pid, Duration::from_millis(500));
        }
        running
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = others;
        killpg(pgid, libc::SIGKILL);
        0
    }
}

/// Send `signal` to every process of worker `pgid`'s [`family`] but those in its group (which
/// `killpg` reaches): the children that left the group while their parent lived.
pub(crate) fn kill_escaped(pgid: libc::pid_t, signal: libc::c_int) {
    #[cfg(target_os = "linux")]
    for p in descendants(&processes(), pgid, &[]) {
        if p.pid > 1 && p.group != pgid {
            // SAFETY: signalling a descendant of our own worker.
            unsafe {
                libc::kill(p.pid, signal);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (pgid, signal);
}

/// The memory a worker holds, bytes, from /proc (Linux; 0 elsewhere): the anonymous resident
/// memory of every process of its [`family`] (the worker, the children its laws started in
/// its group, and those that left the group while their parent lived) and the pages allocated
/// to the memory files (memfd) any of them holds open, each file counted once. Library code
/// and other file pages are not counted.
pub(crate) fn group_memory_bytes(pgid: libc::pid_t) -> u64 {
    #[cfg(target_os = "linux")]
    {
        use std::collections::HashSet;
        use std::os::unix::fs::MetadataExt;
        let page = page_size();
        let mut total = 0u64;
        let mut files: HashSet<(u64, u64)> = HashSet::new();
        for pid in family(pgid) {
            if let Ok(text) = std::fs::read_to_string(format!("/proc/{pid}/statm")) {
                let mut f = text.split_whitespace().skip(1);
                let resident: u64 = f.next().and_then(|x| x.parse().ok()).unwrap_or(0);
                let shared: u64 = f.next().and_then(|x| x.parse().ok()).unwrap_or(0);
                total += resident.saturating_sub(shared) * page;
            }
            let Ok(fds) = std::fs::read_dir(format!("/proc/{pid}/fd")) else {
                continue;
            };
            for fd in fds.flatten() {
                let is_memfd = std::fs::read_link(fd.path())
                    .is_ok_and(|t| t.to_string_lossy().starts_with("/memfd:"));
                if !is_memfd {
                    continue;
                }
                if let Ok(m) = std::fs::metadata(fd.path()) {
                    if files.insert((m.dev(), m.ino())) {
                        total += m.blocks() * 512;
                    }
                }
            }
        }
        total
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = pgid;
        0
    }
}

/// Process `pid` from /proc/PID/stat (Linux).
#[cfg(target_os = "linux")]
fn stat(pid: libc::pid_t) -> Option<Proc> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (in parentheses) may hold spaces: the fields follow its last `)`.
    let rest = &text[text.rfind(')')? + 1..];
    let mut f = rest.split_whitespace();
    let zombie = matches!(f.next()?, "Z" | "X");
    let parent = f.next()?.parse().ok()?;
    let group = f.next()?.parse().ok()?;
    let session = f.next()?.parse().ok()?;
    Some(Proc {
        pid,
        parent,
        group,
        session,
        zombie,
    })
}
