//! Progress on standard error for long runs. A separate thread draws it (indicatif) once the
//! work has taken about a second, and only when standard error is a terminal and the user did
//! not ask for `--quiet`. The work itself only stores a position in an atomic now and then.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

pub use tribo_core::observe::Position;

/// A progress display; stops and clears itself when dropped.
pub struct Progress {
    position: Position,
    done: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

/// How long work may run before a progress display appears.
const DELAY: Duration = Duration::from_millis(1000);

impl Progress {
    /// Start watching work described by `what`, with `total` units if known (a spinner if not).
    pub fn start(what: &str, total: Option<u64>, quiet: bool) -> Self {
        let position = Position::default();
        let done = Arc::new(AtomicBool::new(false));
        let thread = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let (pos, stop, what) = (position.clone(), done.clone(), what.to_string());
            std::thread::spawn(move || {
                let start = Instant::now();
                while start.elapsed() < DELAY {
                    if stop.load(Ordering::Relaxed) {
                        return;
                    }
                    std::thread::sleep(Duration::from_millis(20));
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
                while !stop.load(Ordering::Relaxed) {
                    bar.set_position(pos.get());
                    bar.tick();
                    std::thread::sleep(Duration::from_millis(100));
                }
                bar.finish_and_clear();
            })
        });
        Self {
            position,
            done,
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
        self.done.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
