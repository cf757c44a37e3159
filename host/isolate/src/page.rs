//! The in-flight page for a supervisor that starts and talks to its worker itself (the FMU,
//! whose worker speaks the FMU's own protocol): a shared memory file holding the worker's
//! in-flight table and the names of the code it registered, so the supervisor can say which
//! law call was under way when the worker died without a word (`_exit`, a SIGKILL of its
//! group), where the worker's own guards could not speak.
//!
//! The supervisor makes an [`InflightPage`], hands it to the command it starts
//! ([`InflightPage::share_with`]); the worker calls [`adopt`] before it loads any law. The page
//! is memory the law can write: what it says names a law, it cannot prove one (fault
//! isolation, not a sandbox), so the supervisor takes only names of laws as it knows them.

use std::os::fd::{AsRawFd, OwnedFd, RawFd};
use std::os::unix::process::CommandExt;
use std::process::Command;
use std::sync::atomic::{AtomicPtr, AtomicU32, AtomicU8, Ordering};

use tribo_plugin_api::loader::inflight;

use crate::sys;

/// The environment variable that tells the worker which descriptor holds the page.
pub const PAGE_FD_ENV: &str = "TRIBO_INFLIGHT_FD";
/// Names kept on the page (ids from 1; later ones are not named).
const NAMES: usize = 64;
/// Bytes of one name (longer ones are cut).
const NAME_BYTES: usize = 1020;

/// One registered name: its bytes, then its length stored last (0: not written yet).
#[repr(C)]
struct Name {
    len: AtomicU32,
    text: [AtomicU8; NAME_BYTES],
}

/// The page: the worker's in-flight table, then the names by id.
#[repr(C)]
struct Page {
    table: inflight::Table,
    names: [Name; NAMES],
}

/// Bytes of the page (whole pages).
const PAGE_LEN: usize = std::mem::size_of::<Page>().div_ceil(4096) * 4096;

/// The supervisor's side: the page, mapped for as long as it lives (after the worker's end
/// too: the marks a dead worker left are what names the law it died in).
pub struct InflightPage {
    fd: OwnedFd,
    map: sys::Mapping,
}

impl InflightPage {
    /// A new zeroed page, or `None` where the system has no memory files (then nothing is
    /// named from it).
    pub fn new() -> Option<Self> {
        let fd = sys::memfd(PAGE_LEN)?;
        let map = sys::Mapping::new(fd.as_raw_fd(), PAGE_LEN).ok()?;
        Some(Self { fd, map })
    }

    /// Have `command` pass the page to the worker it starts: the descriptor inherited (only
    /// by that process: it stays close-on-exec here) and named in [`PAGE_FD_ENV`].
    pub fn share_with(&self, command: &mut Command) {
        let fd: RawFd = self.fd.as_raw_fd();
        command.env(PAGE_FD_ENV, fd.to_string());
        // SAFETY: fcntl is async-signal-safe; it clears close-on-exec on a descriptor this
        // process owns, in the child only.
        unsafe {
            command.pre_exec(move || {
                let flags = libc::fcntl(fd, libc::F_GETFD);
                if flags >= 0 {
                    libc::fcntl(fd, libc::F_SETFD, flags & !libc::FD_CLOEXEC);
                }
                Ok(())
            });
        }
    }

    /// The law calls under way on the page now (or when the worker died), by the names the
    /// worker registered, each once; only names of laws count (a law bound to a joint says
    /// "law `x` (file) at joint `j`").
    pub fn running(&self) -> Vec<String> {
        // SAFETY: the mapping is PAGE_LEN bytes holding a `Page` (atomics only).
        let page = unsafe { &*(self.map.ptr() as *const Page) };
        let mut out: Vec<String> = Vec::new();
        for slot in &page.table.slots {
            let id = inflight::id_of(slot.load(Ordering::Acquire));
            let Some(name) = page.names.get(id).filter(|_| id != 0) else {
                continue;
            };
            let len = (name.len.load(Ordering::Acquire) as usize).min(NAME_BYTES);
            let bytes: Vec<u8> = name.text[..len]
                .iter()
                .map(|b| b.load(Ordering::Relaxed))
                .collect();
            let text = String::from_utf8_lossy(&bytes).into_owned();
            if text.starts_with("law `") && !out.contains(&text) {
                out.push(text);
            }
        }
        out
    }
}

/// Where [`adopt`] mapped the page in the worker.
static ADOPTED: AtomicPtr<Page> = AtomicPtr::new(std::ptr::null_mut());

/// The worker's side: if its supervisor shared a page ([`PAGE_FD_ENV`]), keep the in-flight
/// table there and write every registered name into it. Call before any plugin code runs.
pub fn adopt() {
    let Some(fd) = std::env::var(PAGE_FD_ENV)
        .ok()
        .and_then(|v| v.parse::<RawFd>().ok())
        .filter(|fd| *fd > 2)
    else {
        return;
    };
    // A program a law starts does not inherit it.
    sys::set_cloexec(fd);
    let Ok(ptr) = sys::map_shared(fd, PAGE_LEN) else {
        return;
    };
    let page = ptr.cast::<Page>();
    ADOPTED.store(page, Ordering::SeqCst);
    // SAFETY: the page is PAGE_LEN zeroed bytes, page-aligned, mapped for the rest of the
    // process (never unmapped); the caller runs no plugin code yet.
    unsafe {
        inflight::use_shared_table(std::ptr::addr_of_mut!((*page).table));
    }
    inflight::set_register_hook(|id, text| {
        let page = ADOPTED.load(Ordering::SeqCst);
        if page.is_null() {
            return;
        }
        // SAFETY: set above to the page mapped for the rest of the process.
        let page = unsafe { &*page };
        let Some(name) = page.names.get(id.number()) else {
            return;
        };
        let bytes = text.as_bytes();
        let n = bytes.len().min(NAME_BYTES);
        for (cell, b) in name.text.iter().zip(&bytes[..n]) {
            cell.store(*b, Ordering::Relaxed);
        }
        name.len.store(n as u32, Ordering::Release);
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A page shared through the environment: what a worker marks and names is what the
    /// supervisor reads (here both sides in one process, the worker's side by hand).
    #[test]
    fn a_marked_call_is_read_back_by_its_name() {
        let Some(page) = InflightPage::new() else {
            eprintln!("no memory files here: nothing to test");
            return;
        };
        assert!(page.running().is_empty());
        // SAFETY: the mapping holds a zeroed `Page`.
        let p = unsafe { &*(page.map.ptr() as *const Page) };
        let text = "law `x` (/lib/libx.so) at joint `piston`";
        for (cell, b) in p.names[3].text.iter().zip(text.as_bytes()) {
            cell.store(*b, Ordering::Relaxed);
        }
        p.names[3].len.store(text.len() as u32, Ordering::Release);
        p.names[4].len.store(0, Ordering::Release);
        p.table.slots[7].store((5 << 16) | 3, Ordering::Release);
        p.table.slots[9].store((2 << 16) | 4, Ordering::Release);
        assert_eq!(page.running(), [text]);
    }
}
