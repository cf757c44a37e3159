//! What a run reports while it runs, without doing any I/O itself: a shared progress position
//! that a front end may draw (the CLI's progress bar, a notebook widget).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// Shared position of a long computation, cheap to update from any thread.
#[derive(Debug, Clone, Default)]
pub struct Position(Arc<AtomicU64>);

impl Position {
    /// Set the position (units of whatever total the reader was told).
    pub fn set(&self, pos: u64) {
        self.0.store(pos, Ordering::Relaxed);
    }

    /// Add one.
    pub fn inc(&self) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }

    /// The position now.
    pub fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}
