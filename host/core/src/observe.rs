//! What a run reports while it runs, without doing any I/O itself: a shared progress position
//! that a front end may draw (the CLI's progress bar, a notebook widget), and the per-step
//! [`StepObserver`] a front end implements to write a time series or draw live.

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

/// What an observer's failure is: any error (an I/O error of the CLI's time-series writer,
/// say); the run stops and returns it as [`crate::sim::SimError::Observer`].
pub type ObserverError = Box<dyn std::error::Error + Send + Sync>;

/// The state of the rig at the end of one accepted step, handed to a [`StepObserver`].
#[derive(Debug, Clone, Copy)]
pub struct StepSample<'a> {
    /// Time at the end of the step, s.
    pub time_s: f64,
    /// Crank angle, accumulated over the run (not wrapped), rad.
    pub crank_angle_rad: f64,
    /// Crank speed, rad/s.
    pub speed_rad_s: f64,
    /// Motoring (drive) torque on the crank, N m.
    pub motoring_torque_nm: f64,
    /// The motoring torque through the rig's first-order low-pass filter
    /// (`measurement.lowpass_hz`), N m.
    pub filtered_torque_nm: f64,
    /// Normal load per joint, in the order of the names [`StepObserver::start`] was given, N.
    pub normal_loads_n: &'a [f64],
}

/// Per-step output of a run (time series, live plots, progress), so the solver core itself
/// does no I/O. Every method may fail; a failure stops the run with that error.
pub trait StepObserver {
    /// Called once before the first step with the joints' names: `JOINT_NAMES` on the
    /// single-cylinder rig, an engine's `main_1 .. main_n`, then each cylinder's big end,
    /// small end and piston.
    fn start(&mut self, joints: &[&str]) -> Result<(), ObserverError> {
        let _ = joints;
        Ok(())
    }

    /// Called after every accepted step of a transient run.
    fn step(&mut self, sample: &StepSample<'_>) -> Result<(), ObserverError>;

    /// Whether [`StepObserver::step`] reads its samples. An observer that does not is not
    /// called per step, and the run skips making the samples (the filtered torque's
    /// exponential, every step). Asked once per call of the run; the default is yes.
    fn reads_samples(&self) -> bool {
        true
    }

    /// Progress of the run in permille of the simulated cycle (every few thousand steps).
    fn progress(&mut self, permille: u64) {
        let _ = permille;
    }
}

/// The observer that ignores everything: a run without per-step output.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoObserver;

impl StepObserver for NoObserver {
    fn step(&mut self, _sample: &StepSample<'_>) -> Result<(), ObserverError> {
        Ok(())
    }

    fn reads_samples(&self) -> bool {
        false
    }
}
