//! Which entries a worker's own code created in a result folder while its laws ran.
//!
//! tribo writes a result folder only after every law has finished, so an entry that appears
//! in it while laws run was made by a law. Several law sets run at once, in workers of their
//! own, so the parent cannot tell whose law it was; each worker watches the folder itself with
//! fanotify, which tells a listener without privileges which events its own process made
//! (events of other processes carry no process id). A worker that made one fails its set
//! naming the entry (`tribo compare`'s other sets are written).
//!
//! Linux 5.13 or later (fanotify for unprivileged users); elsewhere, or where fanotify is not
//! allowed, [`Planted::watch`] gives `None` and only the parent's check at writing time (which
//! removes the entry and warns) remains.

use std::ffi::CString;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};

/// A watch on the result folder `dir` for entries this process creates there (or on its
/// parent for `dir` itself, when it does not exist yet).
pub struct Planted {
    fd: OwnedFd,
    /// The name of `dir` when its parent is watched (only that name counts there).
    only: Option<Vec<u8>>,
    dir: PathBuf,
}

impl Planted {
    /// Start watching `dir`, or `None` where fanotify cannot be used.
    pub fn watch(dir: &Path) -> Option<Self> {
        let (watched, only) = if dir.is_dir() {
            (dir.to_path_buf(), None)
        } else {
            let parent = match dir.parent() {
                Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                _ => PathBuf::from("."),
            };
            (parent, Some(dir.file_name()?.as_bytes().to_vec()))
        };
        // SAFETY: fanotify_init with constant flags; the descriptor is owned below.
        let raw = unsafe {
            libc::fanotify_init(
                libc::FAN_CLASS_NOTIF
                    | libc::FAN_REPORT_DFID_NAME
                    | libc::FAN_NONBLOCK
                    | libc::FAN_CLOEXEC,
                libc::O_RDONLY as libc::c_uint,
            )
        };
        if raw < 0 {
            return None;
        }
        // SAFETY: a descriptor fanotify_init just returned, owned by nobody else.
        let fd = unsafe { OwnedFd::from_raw_fd(raw) };
        let path = CString::new(watched.as_os_str().as_bytes()).ok()?;
        // SAFETY: a valid fanotify descriptor and a NUL-terminated path.
        let marked = unsafe {
            libc::fanotify_mark(
                fd.as_raw_fd(),
                libc::FAN_MARK_ADD,
                libc::FAN_CREATE | libc::FAN_MOVED_TO | libc::FAN_ONDIR,
                libc::AT_FDCWD,
                path.as_ptr(),
            )
        };
        (marked == 0).then(|| Self {
            fd,
            only,
            dir: dir.to_path_buf(),
        })
    }

    /// The folder watched.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The names of the entries this process (any of its threads) created or moved into the
    /// folder since the watch began, each once, in the order made.
    pub fn made_here(&self) -> Vec<String> {
        // SAFETY: getpid has no preconditions.
        let me = unsafe { libc::getpid() };
        self.made_by(|pid| pid == me)
    }

    /// The names of the entries any process created or moved into the folder since the last
    /// look, each once, in the order made (the parent's watch: its workers, their children).
    pub fn made_by_anyone(&self) -> Vec<String> {
        self.made_by(|_| true)
    }

    /// The entries made by the processes `pid` accepts (an unprivileged listener sees 0 for
    /// every process but its own).
    fn made_by(&self, accept: impl Fn(i32) -> bool) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        let mut buf = vec![0u8; 64 << 10];
        loop {
            // SAFETY: reading into a buffer of its length from a descriptor we own.
            let n = unsafe { libc::read(self.fd.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
            let Ok(n) = usize::try_from(n) else { break };
            if n == 0 {
                break;
            }
            for (pid, name) in events(&buf[..n]) {
                let counts = self.only.as_deref().is_none_or(|o| o == name.as_slice());
                if accept(pid) && counts {
                    let name = String::from_utf8_lossy(&name).into_owned();
                    if !names.contains(&name) {
                        names.push(name);
                    }
                }
            }
        }
        names
    }
}

/// The (process id, entry name) of each event in `buf`, as fanotify reports them with
/// `FAN_REPORT_DFID_NAME`: a metadata header, then information records, one of them the
/// directory's handle followed by the entry's NUL-terminated name.
fn events(buf: &[u8]) -> Vec<(i32, Vec<u8>)> {
    const META: usize = std::mem::size_of::<libc::fanotify_event_metadata>();
    let u32_at = |b: &[u8], at: usize| -> Option<u32> {
        Some(u32::from_ne_bytes(b.get(at..at + 4)?.try_into().ok()?))
    };
    let mut out = Vec::new();
    let mut at = 0;
    while at + META <= buf.len() {
        let Some(len) = u32_at(buf, at).map(|l| l as usize) else {
            break;
        };
        let Some(event) = buf.get(at..at + len).filter(|_| len >= META) else {
            break;
        };
        // event_len u32, vers u8, reserved u8, metadata_len u16, mask u64, fd i32, pid i32.
        let meta_len = usize::from(u16::from_ne_bytes([event[6], event[7]]));
        let pid = u32_at(event, 20).map_or(0, |p| p as i32);
        let mut info = meta_len;
        while info + 4 <= event.len() {
            let kind = event[info];
            let info_len = usize::from(u16::from_ne_bytes([event[info + 2], event[info + 3]]));
            if info_len < 4 || info + info_len > event.len() {
                break;
            }
            if kind == libc::FAN_EVENT_INFO_TYPE_DFID_NAME {
                // header (4), fsid (8), handle_bytes (4), handle_type (4), handle, name.
                let record = &event[info..info + info_len];
                if let Some(handle_bytes) = u32_at(record, 12).map(|h| h as usize) {
                    if let Some(rest) = record.get(20 + handle_bytes..) {
                        let name = rest.split(|&b| b == 0).next().unwrap_or_default();
                        out.push((pid, name.to_vec()));
                    }
                }
            }
            info += info_len;
        }
        at += len;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_this_process_makes_are_seen_and_only_those() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("out");
        std::fs::create_dir(&out).expect("out");
        let Some(watch) = Planted::watch(&out) else {
            eprintln!("fanotify is not available here: nothing to test");
            return;
        };
        std::fs::write(out.join("planted.txt"), "x").expect("plant");
        std::fs::create_dir(out.join("sub")).expect("dir");
        std::fs::write(dir.path().join("beside.txt"), "x").expect("beside");
        // Another process's entry is not this process's.
        let status = std::process::Command::new("touch")
            .arg(out.join("other.txt"))
            .status()
            .expect("touch runs");
        assert!(status.success());
        let made = watch.made_here();
        let privileged = made.iter().any(|n| n == "other.txt");
        let mine: Vec<&String> = made.iter().filter(|n| *n != "other.txt").collect();
        assert_eq!(
            mine,
            ["planted.txt", "sub"],
            "privileged listener: {privileged}"
        );
        assert!(watch.made_here().is_empty(), "each event is reported once");

        // A folder not there yet: its parent is watched for that name only.
        let later = dir.path().join("later");
        let watch = Planted::watch(&later).expect("watch the parent");
        std::fs::write(dir.path().join("unrelated.txt"), "x").expect("unrelated");
        std::fs::create_dir(&later).expect("later");
        assert_eq!(watch.made_here(), ["later"]);
    }
}
