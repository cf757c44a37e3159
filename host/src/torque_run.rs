//! `tribo run --drive-torque`: the crank driven by a constant torque from a start speed instead
//! of the rig's test cycle (a coast-down with torque 0). It is the FMU's run
//! ([`tribo_fmu::dynamic::Dynamic`], `tribo fmu export --input drive-torque`) stepped from the
//! command line, each `--every` a communication point, so an FMU import can be checked against
//! it.

use std::fmt::Write as _;
use std::sync::Arc;

use serde::Serialize;
use tribo_core::model::{RigFile, Temperature};
use tribo_fmu::dynamic::Dynamic;
use tribo_fmu::interface::DriveMode;
use tribo_fmu::stepping::Inputs;
use tribo_plugin_api::loader::LawRegistry;

/// What to run: the torque, where the crank starts, how long and how often to report.
#[derive(Debug, Clone, Copy)]
pub struct TorqueRun {
    /// Drive torque on the crank, N m.
    pub drive_torque_nm: f64,
    /// Crank speed at time 0, rad/s.
    pub start_speed_rad_s: f64,
    /// Length of the run, s.
    pub duration_s: f64,
    /// Time between reported samples, s.
    pub every_s: f64,
}

/// The run at one reported time.
#[derive(Debug, Clone, Serialize)]
pub struct Sample {
    /// Time, s.
    pub time_s: f64,
    /// Accumulated crank angle, rad.
    pub crank_angle_rad: f64,
    /// Crank speed, rad/s.
    pub crank_speed_rad_s: f64,
    /// Every law's friction torque at the crank, summed, N m.
    pub friction_torque_nm: f64,
    /// Energy every law dissipated since the start, J.
    pub friction_energy_j: f64,
    /// Work the drive torque did since the start, J.
    pub drive_work_j: f64,
}

/// The oil temperature the run holds: the rig's (its first plateau's if it has one per
/// plateau), C.
fn oil_temperature_c(model: &RigFile) -> f64 {
    match &model.oil.temperature_c {
        Temperature::Constant(t) => *t,
        Temperature::PerPlateau(v) => v.first().copied().unwrap_or(20.0),
    }
}

impl TorqueRun {
    /// Check the numbers a user gave, naming the option.
    pub fn check(&self) -> Result<(), String> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !self.drive_torque_nm.is_finite() {
            return Err(format!(
                "--drive-torque must be a finite torque in N.m, got {}",
                self.drive_torque_nm
            ));
        }
        if !(self.start_speed_rad_s.is_finite() && self.start_speed_rad_s >= 0.0) {
            return Err("--start-rpm must be a speed >= 0 rpm".into());
        }
        if !positive(self.duration_s) {
            return Err(format!(
                "--duration must be a time > 0 s, got {}",
                self.duration_s
            ));
        }
        if !positive(self.every_s) || self.duration_s / self.every_s > 1e7 {
            return Err(format!(
                "--every must be a time > 0 s giving at most 10 million samples over --duration, got {}",
                self.every_s
            ));
        }
        Ok(())
    }

    /// Run `model` (laws from `registry`): the samples at 0, `every`, 2 `every`, ... up to
    /// `duration` (the last one at `duration` exactly), and the run's warnings.
    pub fn run(
        &self,
        model: &RigFile,
        registry: Arc<LawRegistry>,
    ) -> Result<(Vec<Sample>, Vec<String>), tribo_fmu::stepping::StepError> {
        let inputs = Inputs {
            drive: self.drive_torque_nm,
            oil_temperature_c: oil_temperature_c(model),
        };
        let mut run = Dynamic::start(
            model,
            registry,
            DriveMode::Torque,
            self.start_speed_rad_s,
            &inputs,
        )?;
        let sample = |run: &Dynamic| {
            let o = run.outputs();
            Sample {
                time_s: o.time_s,
                crank_angle_rad: o.crank_angle_rad,
                crank_speed_rad_s: o.crank_speed_rad_s,
                friction_torque_nm: o.friction_torque_nm(),
                friction_energy_j: o.friction_energy_j(),
                drive_work_j: o.drive_work_j,
            }
        };
        let mut samples = vec![sample(&run)];
        let n = (self.duration_s / self.every_s).ceil() as u64;
        for k in 1..=n {
            let t = if k == n {
                self.duration_s
            } else {
                k as f64 * self.every_s
            };
            run.advance_to(t)?;
            samples.push(sample(&run));
        }
        Ok((samples, run.take_warnings()))
    }
}

/// The samples as a table.
pub fn to_text(samples: &[Sample]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:>10} {:>14} {:>12} {:>18} {:>16}",
        "time_s", "crank_speed", "speed_rpm", "friction_torque", "friction_energy"
    );
    let _ = writeln!(
        out,
        "{:>10} {:>14} {:>12} {:>18} {:>16}",
        "", "rad/s", "rpm", "N.m", "J"
    );
    for s in samples {
        let _ = writeln!(
            out,
            "{:>10.4} {:>14.6} {:>12.2} {:>18.6} {:>16.6}",
            s.time_s,
            s.crank_speed_rad_s,
            s.crank_speed_rad_s * 30.0 / std::f64::consts::PI,
            s.friction_torque_nm,
            s.friction_energy_j
        );
    }
    out
}
