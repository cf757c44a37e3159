//! Progress on standard error for long runs. A separate thread draws it (indicatif) once the
//! work has taken about a second, and only when standard error is a terminal and the user did
//! not ask for `--quiet`. The work itself only stores a position in an atomic now and then.

use std::io::IsTerminal;
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::thread::JoinHandle;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

pub use tribo_core::observe::Position;

/// A progress display; stops and clears itself when dropped.
pub struct Progress {
    position: Position,
    /// Dropped to stop the display: its thread wakes at once instead of at its next tick, so a
    /// finished run does not wait for it.
    stop: Option<Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

/// Wait up to `wait` for the work watched through `stopped` to end (its sender dropped): `true`
/// if it is still running. A watcher that sleeps instead holds the work's end until it wakes.
pub fn still_running(stopped: &Receiver<()>, wait: Duration) -> bool {
    matches!(stopped.recv_timeout(wait), Err(RecvTimeoutError::Timeout))
}

/// How long work may run before a progress display appears.
const DELAY: Duration = Duration::from_millis(1000);

/// How often the display is redrawn.
const TICK: Duration = Duration::from_millis(100);

impl Progress {
    /// Start watching work described by `what`, with `total` units if known (a spinner if not).
    pub fn start(what: &str, total: Option<u64>, quiet: bool) -> Self {
        let position = Position::default();
        let (stop, stopped) = channel::<()>();
        let thread = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let (pos, what) = (position.clone(), what.to_string());
            std::thread::spawn(move || {
                // Work done within the delay shows nothing; the sender dropped wakes this.
                let running = |wait: Duration| still_running(&stopped, wait);
                if !running(DELAY) {
                    return;
                }
                let bar = match total {
                    Some(n) => ProgressBar::new(n).with_style(
                        ProgressStyle::with_template(
                            "{msg} [{bar:40}] {percent:>3}% {elapsed} (eta {eta})",
                        )
                        .unwrap_or_else(|_| ProgressStyle::default_bar())
                        .progress_chars("=> "),
                    ),
                    None => ProgressBar::new_spinner().with_style(
                        ProgressStyle::with_template("{spinner} {msg} {pos} {elapsed}")
                            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
                    ),
                };
                bar.set_message(what);
                loop {
                    bar.set_position(pos.get());
                    bar.tick();
                    if !running(TICK) {
                        break;
                    }
                }
                bar.finish_and_clear();
            })
        });
        Self {
            position,
            stop: Some(stop),
            thread,
        }
    }

    /// The position handle to give to the work.
    pub fn position(&self) -> Position {
        self.position.clone()
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        drop(self.stop.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
