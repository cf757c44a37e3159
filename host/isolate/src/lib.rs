//! Law plugins are foreign code: this crate runs them where they cannot take tribo, or its
//! caller, down with them.
//!
//! A *worker* is a process that runs laws on behalf of a parent (the `tribo` command, the Python
//! module, an FMU): the parent starts it ([`Worker::start`]) in its own session and process
//! group, with standard output on `/dev/null`, and talks to it over a channel only the two of
//! them created: a socket pair for requests and replies, a pipe for the guards' markers, and a
//! shared page where the worker's threads mark which law call they are in. Every message is
//! tagged with a random per-job token (module `frame`), so what a law prints or writes into the
//! channel is never taken for the worker's word. A request is answered by exactly one reply;
//! success is a positive reply, never an exit status. When the worker ends, stops, or runs out
//! of a limit, the parent kills its whole process group (the law's own children with it), never
//! waits for a pipe's end of file, and says what happened and which law was running, from the
//! markers and the shared page (so even `_exit`, SIGSTOP and a kill from outside are named).
//!
//! The protocol serves one request (a study's law set, a `tribo run`) or many in a row from one
//! long-lived worker ([`Worker::call`] again): a stepping simulation (an FMU) keeps its run in
//! the worker and asks it to step. [`guard`] holds the process guards of every process that
//! runs laws, isolated or not: the per-call watchdog, the limits, the `exit()` and
//! fatal-signal hooks and the panic hook.
//!
//! This is fault isolation, not a security sandbox: a worker runs with the user's rights, and a
//! law that sets out to read the token from its process's memory can forge anything.

pub mod guard;
pub mod listing;
mod terms;

#[cfg(unix)]
mod child;
#[cfg(unix)]
mod frame;
#[cfg(unix)]
pub mod page;
#[cfg(unix)]
mod parent;
#[cfg(target_os = "linux")]
pub mod planted;
#[cfg(unix)]
mod sys;

#[cfg(unix)]
pub use child::{serve, Session};
#[cfg(unix)]
pub use parent::{
    forward_stderr, handle_termination, register_temp, run_all, run_all_watched, Event, TempGuard,
    Worker,
};
pub use terms::*;
