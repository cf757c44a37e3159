//! Which plugin code each thread is running right now, readable from a signal handler, an
//! `atexit` hook or a watchdog thread. When a law crashes, hangs or calls `exit()`, the host
//! can then name the law and its library instead of only the signal.
//!
//! Every call into a plugin (load, describe, create, evaluate, commit) marks its thread's slot
//! with a small number naming the code; the names are registered once, when a library is
//! loaded, in a fixed table of write-once cells. Reading needs no lock and no allocation: a
//! handler walks the slots with atomic loads and writes the names it finds with `write(2)`.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

/// Number of thread slots; threads beyond it share slots (only the diagnosis suffers).
const SLOTS: usize = 256;
/// Number of names that can be registered; later libraries are reported by number only.
const NAMES: usize = 4096;

static SLOT: [AtomicUsize; SLOTS] = [const { AtomicUsize::new(0) }; SLOTS];
static NAME: [OnceLock<Box<str>>; NAMES] = [const { OnceLock::new() }; NAMES];
static NEXT_NAME: AtomicUsize = AtomicUsize::new(1);
static NEXT_SLOT: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// This thread's slot, assigned at its first plugin call (`usize::MAX` until then). A
    /// const-initialised cell: reading it is one thread-local load, no lazy-init check.
    static MY_SLOT: std::cell::Cell<usize> = const { std::cell::Cell::new(usize::MAX) };
}

/// This thread's slot.
#[inline]
fn my_slot() -> usize {
    MY_SLOT.with(|s| {
        let slot = s.get();
        if slot != usize::MAX {
            return slot;
        }
        let slot = NEXT_SLOT.fetch_add(1, Ordering::Relaxed) % SLOTS;
        s.set(slot);
        slot
    })
}

/// A registered description of plugin code ("law `x` (file)"); 0 means nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CodeId(usize);

/// Register `text` (e.g. "law `coulomb` (/path/libtribo_law_coulomb.so)") and return its id.
pub fn register(text: String) -> CodeId {
    let id = NEXT_NAME.fetch_add(1, Ordering::Relaxed);
    if let Some(cell) = NAME.get(id) {
        let _ = cell.set(text.into_boxed_str());
    }
    CodeId(id)
}

/// Marks the current thread as running `id` until dropped (then the previous mark returns, so
/// nested calls unwind correctly).
#[must_use]
pub struct Running {
    slot: usize,
    previous: usize,
}

/// Mark the current thread as running the plugin code `id`.
#[inline]
pub fn enter(id: CodeId) -> Running {
    let slot = my_slot();
    // Only this thread writes its slot (threads beyond SLOTS share one, which only blurs the
    // diagnosis), so a plain load and store do; an atomic swap would cost a locked instruction
    // on every law call.
    let previous = SLOT[slot].load(Ordering::Relaxed);
    SLOT[slot].store(id.0, Ordering::Relaxed);
    Running { slot, previous }
}

impl Drop for Running {
    #[inline]
    fn drop(&mut self) {
        SLOT[self.slot].store(self.previous, Ordering::Relaxed);
    }
}

/// Call `f` with the text of every piece of plugin code some thread is running now, each once.
/// Lock-free and allocation-free, so it may run in a signal handler (`f` must be too).
pub fn for_each_running(mut f: impl FnMut(&str)) {
    let mut seen = [0usize; 16];
    let mut n_seen = 0;
    for slot in &SLOT {
        let id = slot.load(Ordering::Relaxed);
        if id == 0 || seen[..n_seen].contains(&id) {
            continue;
        }
        if n_seen < seen.len() {
            seen[n_seen] = id;
            n_seen += 1;
        }
        match NAME.get(id).and_then(OnceLock::get) {
            Some(text) => f(text),
            None => f("plugin code (unnamed: too many libraries loaded)"),
        }
    }
}

/// The texts of the plugin code running now (for ordinary, non-signal contexts).
pub fn running() -> Vec<String> {
    let mut v = Vec::new();
    for_each_running(|t| v.push(t.to_string()));
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mark_is_seen_while_held_and_gone_after() {
        let a = register("law `a` (a.so)".into());
        let b = register("law `b` (b.so)".into());
        {
            let _outer = enter(a);
            assert!(running().iter().any(|t| t == "law `a` (a.so)"));
            {
                let _inner = enter(b);
                let now = running();
                assert!(now.iter().any(|t| t == "law `b` (b.so)"));
                assert!(!now.iter().any(|t| t == "law `a` (a.so)"));
            }
            assert!(running().iter().any(|t| t == "law `a` (a.so)"));
        }
        assert!(!running()
            .iter()
            .any(|t| t.contains("(a.so)") || t.contains("(b.so)")));
    }

    #[test]
    fn another_threads_mark_is_visible() {
        let c = register("law `c` (c.so)".into());
        let (tx, rx) = std::sync::mpsc::channel();
        let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
        let t = std::thread::spawn(move || {
            let _m = enter(c);
            tx.send(()).expect("send");
            let _ = done_rx.recv();
        });
        rx.recv().expect("the thread marked itself");
        assert!(running().iter().any(|t| t == "law `c` (c.so)"));
        done_tx.send(()).expect("send");
        t.join().expect("join");
        assert!(!running().iter().any(|t| t == "law `c` (c.so)"));
    }
}
