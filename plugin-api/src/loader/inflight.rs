//! Which plugin code each thread is running right now, readable from a signal handler, an
//! `atexit` hook, a watchdog thread, or (through shared memory) the parent of a worker process.
//! When a law crashes, hangs, stops its process or calls `exit()`, the host can then name the
//! law, the joint it sits on and the inputs of the call instead of only the signal.
//!
//! Every call into a plugin (load, describe, create, evaluate, commit) marks its thread's slot
//! with a small number naming the code and a per-thread call count, so a watchdog that sees the
//! same mark for seconds knows one call has been running that long. The names are registered
//! once (a library loaded, a law bound to a joint), in a fixed table of write-once cells.
//! Reading needs no lock and no allocation: a handler walks the slots with atomic loads and
//! writes the names it finds with `write(2)`.
//!
//! A worker process moves the slots into memory its parent mapped too ([`use_shared_table`]),
//! and hands every name to the parent as it is registered ([`set_register_hook`]): the parent
//! can then say what was running when the worker died, even of `_exit`, SIGKILL or SIGSTOP,
//! where the worker itself has no chance to speak.

use std::sync::atomic::{AtomicPtr, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use crate::contract::LawInput;

/// Number of thread slots; threads beyond it share slots (only the diagnosis suffers).
pub const SLOTS: usize = 256;
/// Number of names that can be registered; later ones are reported by number only.
const NAMES: usize = 4096;
/// Bits of a slot's mark holding the code id (the rest count the thread's calls).
const ID_BITS: u32 = 16;
const ID_MASK: u64 = (1 << ID_BITS) - 1;

/// The marks of every thread slot: what [`use_shared_table`] may place in shared memory. A
/// mark is `calls << 16 | id`: 0 when the thread runs no plugin code.
#[repr(C)]
pub struct Table {
    /// One mark per thread slot.
    pub slots: [AtomicU64; SLOTS],
}

impl Table {
    /// An empty table (nothing running).
    pub const fn new() -> Self {
        Self {
            slots: [const { AtomicU64::new(0) }; SLOTS],
        }
    }
}

impl Default for Table {
    fn default() -> Self {
        Self::new()
    }
}

/// The marks as this process keeps them for itself (its watchdog, its signal handlers): always
/// written, and the only table read in this process.
static LOCAL: Table = Table::new();
/// The table written besides [`LOCAL`]: [`LOCAL`] itself, or the shared one a worker installed
/// at start-up for its parent.
static TABLE: AtomicPtr<Table> = AtomicPtr::new(std::ptr::addr_of!(LOCAL) as *mut Table);
/// The input of each slot's current law call (null outside evaluate and commit).
static ARG: [AtomicPtr<LawInput>; SLOTS] = [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];
static NAME: [OnceLock<Box<str>>; NAMES] = [const { OnceLock::new() }; NAMES];
static NEXT_NAME: AtomicUsize = AtomicUsize::new(1);
static NEXT_SLOT: AtomicUsize = AtomicUsize::new(0);
/// Texts already registered, so one law on one joint bound a thousand times takes one name.
static BY_TEXT: Mutex<Vec<(Box<str>, usize)>> = Mutex::new(Vec::new());
/// Called with every name registered (a worker tells its parent).
static HOOK: OnceLock<fn(CodeId, &str)> = OnceLock::new();

thread_local! {
    /// This thread's slot (`usize::MAX` until its first plugin call) and its call count. A
    /// const-initialised cell: reading it is one thread-local load, no lazy-init check.
    static MINE: std::cell::Cell<(usize, u64)> = const { std::cell::Cell::new((usize::MAX, 0)) };
}

#[inline]
fn table() -> &'static Table {
    // SAFETY: TABLE points at LOCAL or at a table that `use_shared_table`'s caller promised
    // lives for the rest of the process.
    unsafe { &*TABLE.load(Ordering::Relaxed) }
}

/// This thread's slot and the mark of its next call.
#[inline]
fn next_mark(id: CodeId) -> (usize, u64) {
    MINE.with(|m| {
        let (slot, calls) = slot_and_count(m);
        let calls = calls.wrapping_add(1);
        m.set((slot, calls));
        (slot, mark_of(calls, id))
    })
}

/// This thread's slot (taken on its first plugin call) and its call count.
#[inline]
fn slot_and_count(mine: &std::cell::Cell<(usize, u64)>) -> (usize, u64) {
    let (mut slot, calls) = mine.get();
    if slot == usize::MAX {
        slot = NEXT_SLOT.fetch_add(1, Ordering::Relaxed) % SLOTS;
        mine.set((slot, calls));
    }
    (slot, calls)
}

/// The slot mark of call number `calls` of the code `id`: a new value on every call.
#[inline]
fn mark_of(calls: u64, id: CodeId) -> u64 {
    (calls << ID_BITS) | (id.0 as u64 & ID_MASK)
}

/// A registered description of plugin code ("law `x` (file)"); 0 means nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CodeId(usize);

impl CodeId {
    /// The number that travels in slot marks and in a worker's reports to its parent.
    pub fn number(self) -> usize {
        self.0
    }
}

/// Register `text` (e.g. "law `coulomb` (/path/libtribo_law_coulomb.so)") and return its id;
/// the same text registered again gets the same id.
pub fn register(text: String) -> CodeId {
    let mut known = BY_TEXT.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((_, id)) = known.iter().find(|(t, _)| **t == *text) {
        return CodeId(*id);
    }
    let id = NEXT_NAME.fetch_add(1, Ordering::Relaxed);
    if let Some(cell) = NAME.get(id) {
        let _ = cell.set(text.clone().into_boxed_str());
        known.push((text.clone().into_boxed_str(), id));
    }
    drop(known);
    if let Some(hook) = HOOK.get() {
        hook(CodeId(id), &text);
    }
    CodeId(id)
}

/// Have `hook` called with every name registered from now on, and with every one registered
/// so far (in order). Set once per process; later calls are ignored.
pub fn set_register_hook(hook: fn(CodeId, &str)) {
    if HOOK.set(hook).is_err() {
        return;
    }
    let known: Vec<(Box<str>, usize)> = BY_TEXT.lock().unwrap_or_else(|p| p.into_inner()).clone();
    for (text, id) in known {
        hook(CodeId(id), &text);
    }
}

/// The registered text of id `number`, if any (allocation-free).
pub fn name(number: usize) -> Option<&'static str> {
    NAME.get(number).and_then(OnceLock::get).map(|t| &**t)
}

/// Keep the slot marks in `table` from now on (a worker: memory its parent maps too).
///
/// # Safety
///
/// `table` must be valid, zeroed, aligned for [`Table`] and live (mapped) for the rest of the
/// process, and no plugin code may be running on any thread when this is called.
pub unsafe fn use_shared_table(table: *mut Table) {
    TABLE.store(table, Ordering::SeqCst);
}

/// Marks the current thread as running plugin code until dropped (then the previous mark
/// returns, so nested calls unwind correctly).
#[must_use]
pub struct Running {
    slot: usize,
    previous: u64,
    table: &'static Table,
}

/// Mark the current thread as running the plugin code `id` (loading, describing, creating).
#[inline]
pub fn enter(id: CodeId) -> Running {
    let r = start(id);
    ARG[r.slot].store(std::ptr::null_mut(), Ordering::Relaxed);
    r
}

/// Mark the current thread as running the law call `id` on `input` (evaluate, commit): a
/// watchdog that finds the call stuck can then report its inputs.
#[inline]
pub fn enter_call(id: CodeId, input: &LawInput) -> Running {
    let r = start(id);
    ARG[r.slot].store((input as *const LawInput).cast_mut(), Ordering::Relaxed);
    r
}

#[inline]
fn start(id: CodeId) -> Running {
    let (slot, value) = next_mark(id);
    occupy(table(), slot, value)
}

/// Put `value` in `slot` of `table` (and of the private [`LOCAL`] copy) until the returned
/// guard drops.
#[inline]
fn occupy(table: &'static Table, slot: usize, value: u64) -> Running {
    // Only this thread writes its slot (threads beyond SLOTS share one, which only blurs the
    // diagnosis), so a plain load and store do; an atomic swap would cost a locked instruction
    // on every law call. The previous mark comes from the private copy, which no law can
    // find by a name in the process's memory map, as it can the shared page.
    let previous = LOCAL.slots[slot].load(Ordering::Relaxed);
    LOCAL.slots[slot].store(value, Ordering::Release);
    table.slots[slot].store(value, Ordering::Release);
    Running {
        slot,
        previous,
        table,
    }
}

impl Drop for Running {
    #[inline]
    fn drop(&mut self) {
        LOCAL.slots[self.slot].store(self.previous, Ordering::Release);
        self.table.slots[self.slot].store(self.previous, Ordering::Release);
    }
}

/// This thread's slot, looked up once for a round of law calls: each call of the round is then
/// marked by [`Round::enter_call`] with a few stores and no thread-local access (the solver
/// calls every law of a rig once per friction round). The thread's call count is carried on
/// in the round and written back when it ends.
#[must_use]
pub struct Round {
    slot: usize,
    calls: u64,
    table: &'static Table,
}

/// Start a round of law calls on this thread ([`Round`]).
#[inline]
pub fn round() -> Round {
    let (slot, calls) = MINE.with(slot_and_count);
    Round {
        slot,
        calls,
        table: table(),
    }
}

impl Round {
    /// Mark this thread as running the law call `id` on `input`, as [`enter_call`] does.
    #[inline]
    pub fn enter_call(&mut self, id: CodeId, input: &LawInput) -> Running {
        self.calls = self.calls.wrapping_add(1);
        let running = occupy(self.table, self.slot, mark_of(self.calls, id));
        ARG[self.slot].store((input as *const LawInput).cast_mut(), Ordering::Relaxed);
        running
    }
}

impl Drop for Round {
    #[inline]
    fn drop(&mut self) {
        // A call nested in the round (plugin code entering plugin code) counted on the
        // thread's own count: keep whichever went further, so marks keep changing.
        MINE.with(|m| {
            let (slot, calls) = m.get();
            m.set((slot, calls.max(self.calls)));
        });
    }
}

/// The code id of a slot mark (0: nothing running).
pub fn id_of(mark: u64) -> usize {
    (mark & ID_MASK) as usize
}

/// The mark of slot `slot` now (0: nothing running there; also for a slot out of range). Read
/// from the process's private copy: the shared page a worker's parent reads can be written by
/// a law (to clear its own mark or name another), this one only by finding it first.
pub fn mark(slot: usize) -> u64 {
    LOCAL
        .slots
        .get(slot)
        .map_or(0, |m| m.load(Ordering::Acquire))
}

/// Call `f(slot, mark)` for every slot whose thread runs plugin code now. Allocation-free.
pub fn for_each_mark(mut f: impl FnMut(usize, u64)) {
    for (slot, m) in LOCAL.slots.iter().enumerate() {
        let mark = m.load(Ordering::Acquire);
        if id_of(mark) != 0 {
            f(slot, mark);
        }
    }
}

/// The input of the law call that slot `slot` is making, if it is still the call with `mark`
/// and it has one (evaluate, commit). Meant for a watchdog that saw the same mark for seconds:
/// the input lives in the caller's frame, which stays in place while the call runs; the mark
/// read again after the copy proves the call did not end meanwhile.
pub fn input_of(slot: usize, mark: u64) -> Option<LawInput> {
    let p = ARG.get(slot)?.load(Ordering::Acquire);
    if p.is_null() {
        return None;
    }
    // SAFETY: `p` was the address of the input of the call marked `mark`, in its caller's
    // frame; while that call runs the frame is live (a stuck call holds it for seconds), and
    // the check below throws the copy away if the call ended. LawInput is plain data (every
    // bit pattern is a value), read volatile so the compiler does not assume it unchanged.
    let copy = unsafe { std::ptr::read_volatile(p) };
    (LOCAL.slots[slot].load(Ordering::Acquire) == mark).then_some(copy)
}

/// Call `f` with the text of every piece of plugin code some thread is running now, each once.
/// Lock-free and allocation-free, so it may run in a signal handler (`f` must be too).
pub fn for_each_running(mut f: impl FnMut(&str)) {
    let mut seen = [0usize; 16];
    let mut n_seen = 0;
    for_each_mark(|_, mark| {
        let id = id_of(mark);
        if seen[..n_seen].contains(&id) {
            return;
        }
        if n_seen < seen.len() {
            seen[n_seen] = id;
            n_seen += 1;
        }
        match name(id) {
            Some(text) => f(text),
            None => f("plugin code (unnamed: too many libraries loaded)"),
        }
    });
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

    #[test]
    fn the_same_text_gets_the_same_id_and_each_call_a_new_mark() {
        let a = register("law `same` (s.so) at joint `piston`".into());
        let b = register("law `same` (s.so) at joint `piston`".into());
        assert_eq!(a, b);
        let mut marks = Vec::new();
        for _ in 0..2 {
            let _m = enter(a);
            for_each_mark(|_, m| {
                if id_of(m) == a.number() {
                    marks.push(m);
                }
            });
        }
        assert_eq!(marks.len(), 2);
        assert_ne!(marks[0], marks[1], "two calls, two marks");
    }

    #[test]
    fn a_round_marks_each_call_anew_and_clears_after_it() {
        let id = register("law `round` (r.so)".into());
        let input = LawInput::at_rest(crate::contract::JointKind::Revolute);
        let mut round = round();
        let mut marks = Vec::new();
        for _ in 0..3 {
            let _m = round.enter_call(id, &input);
            for_each_mark(|slot, m| {
                if id_of(m) == id.number() {
                    marks.push(m);
                    assert!(input_of(slot, m).is_some(), "the call's input is readable");
                }
            });
        }
        drop(round);
        assert_eq!(marks.len(), 3);
        assert!(
            marks[0] != marks[1] && marks[1] != marks[2],
            "each call a new mark"
        );
        assert!(!running().iter().any(|t| t == "law `round` (r.so)"));
        // The thread's own count went on from the round's: the next call's mark is new too.
        let _m = enter(id);
        for_each_mark(|_, m| {
            if id_of(m) == id.number() {
                assert!(!marks.contains(&m));
            }
        });
    }

    #[test]
    fn a_running_call_exposes_its_input_and_a_finished_one_does_not() {
        let id = register("law `in` (in.so)".into());
        let input = LawInput {
            normal_load_n: 123.5,
            ..LawInput::at_rest(crate::contract::JointKind::Prismatic)
        };
        let mut seen = None;
        {
            let _m = enter_call(id, &input);
            for_each_mark(|slot, m| {
                if id_of(m) == id.number() {
                    seen = Some((slot, m, input_of(slot, m)));
                }
            });
        }
        let (slot, mark, copy) = seen.expect("the call was marked");
        assert_eq!(copy.map(|c| c.normal_load_n), Some(123.5));
        assert!(input_of(slot, mark).is_none(), "the call ended");
    }
}
