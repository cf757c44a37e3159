//! The temporary [`Stepping`] adapter over today's public solver (to be replaced by the core's
//! stepping API): the crank turns at the input speed, and at each speed and oil temperature
//! the rig is the solver's periodic steady state at that speed, one cycle evaluated on the
//! steady run's own crank-angle grid (`Simulation::crank_angle_traces`: kinematics, gas,
//! the friction/reaction iteration and every law, at each angle).
//!
//! Between grid angles every quantity is linear in crank angle, and it is integrated exactly:
//! over whole cycles the friction energy is the steady run's periodic trapezoid sum, so the
//! FMU's mean torque per cycle at a plateau equals `tribo run --steady`'s. What it leaves out:
//! the crank's acceleration (the inertia torque of a changing speed and its effect on the
//! joint loads, and so on friction) and a stateful law's history across a change of speed
//! (each speed's cycle is that law's settled one). Exact at constant speed, a quasi-steady
//! approximation while the speed changes slowly against a revolution.

use std::f64::consts::TAU;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use tribo_core::cycle::Segment;
use tribo_core::model::{RigFile, Temperature};
use tribo_core::sim::Simulation;
use tribo_plugin_api::loader::LawRegistry;

use crate::interface::joint_laws;
use crate::stepping::{Inputs, JointOutput, Outputs, StepError, Stepping};

/// How many evaluated cycles (speed and oil temperature pairs) are kept: a few, so an
/// importer alternating between inputs (or restoring a state) does not recompute them.
const CACHE: usize = 4;

/// One quantity over a cycle: samples at equally spaced crank angles from 0, linear between
/// them, with its running integral over angle.
#[derive(Debug, Clone)]
struct Channel {
    /// Value at angle `k * step`.
    y: Vec<f64>,
    /// Integral over angle from 0 to `k * step` (`y.len() + 1` entries; the last one is the
    /// whole cycle's).
    integral: Vec<f64>,
}

impl Channel {
    fn new(y: Vec<f64>, step: f64) -> Self {
        let n = y.len();
        let mut integral = Vec::with_capacity(n + 1);
        integral.push(0.0);
        let mut acc = 0.0;
        for k in 0..n {
            acc += 0.5 * step * (y[k] + y[(k + 1) % n]);
            integral.push(acc);
        }
        Self { y, integral }
    }

    /// Position of angle `phi` in [0, cycle): the interval and the distance into it.
    fn locate(&self, phi: f64, step: f64) -> (usize, f64) {
        let k = ((phi / step).floor() as usize).min(self.y.len() - 1);
        (k, phi - k as f64 * step)
    }

    /// The value at angle `phi` in [0, cycle).
    fn at(&self, phi: f64, step: f64) -> f64 {
        let (k, u) = self.locate(phi, step);
        let next = self.y[(k + 1) % self.y.len()];
        self.y[k] + (next - self.y[k]) * u / step
    }

    /// The integral over angle from 0 to `phi` in [0, cycle).
    fn integral_to(&self, phi: f64, step: f64) -> f64 {
        let (k, u) = self.locate(phi, step);
        let next = self.y[(k + 1) % self.y.len()];
        self.integral[k] + u * self.y[k] + 0.5 * u * u / step * (next - self.y[k])
    }

    /// The integral over the accumulated angles from `a` to `b`, whole cycles counted apart so
    /// a long run loses no digits.
    fn integral(&self, a: f64, b: f64, cycle: f64, step: f64) -> f64 {
        let (ka, pa) = wrap(a, cycle);
        let (kb, pb) = wrap(b, cycle);
        let whole = self.integral[self.y.len()];
        (kb - ka) as f64 * whole + self.integral_to(pb, step) - self.integral_to(pa, step)
    }
}

/// `theta` as whole cycles and the angle into the cycle, in [0, cycle).
fn wrap(theta: f64, cycle: f64) -> (i64, f64) {
    let k = (theta / cycle).floor();
    let phi = (theta - k * cycle).clamp(0.0, cycle * (1.0 - f64::EPSILON));
    (k as i64, phi)
}

/// The rig's steady cycle at one speed and oil temperature.
#[derive(Debug)]
struct Table {
    omega: f64,
    oil_temperature_c: f64,
    /// Each joint's dissipated power, W.
    power: Vec<Channel>,
    /// The drive torque, N m.
    drive: Channel,
    /// The transducer's figures in the drivetrain's periodic cycle (a rig with a drivetrain).
    instrument: Option<tribo_core::sim::Instrument>,
}

/// Where the run is: what a saved state holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct State {
    t: f64,
    theta: f64,
    energy_j: Vec<f64>,
    drive_work_j: f64,
    inputs: Inputs,
}

/// The quasi-steady adapter (see the module documentation).
pub struct QuasiSteady {
    model: RigFile,
    registry: Arc<LawRegistry>,
    joints: Vec<String>,
    /// Crank angle of one cycle, rad (2 pi; 4 pi for a 4-stroke cycle).
    cycle: f64,
    /// The steady run's angular step over the cycle, rad.
    step: f64,
    table: Arc<Table>,
    cache: Vec<Arc<Table>>,
    state: State,
    /// What the rig's notes and the tables built since the last [`Stepping::take_warnings`]
    /// warned of.
    warnings: Vec<String>,
}

impl QuasiSteady {
    /// Start `model` at time `t0` with `inputs`, the crank at angle 0.
    pub fn new(
        model: RigFile,
        registry: Arc<LawRegistry>,
        t0: f64,
        inputs: &Inputs,
    ) -> Result<Self, StepError> {
        let joints: Vec<String> = joint_laws(&model)
            .into_iter()
            .filter(|(_, laws)| !laws.is_empty())
            .map(|(j, _)| j)
            .collect();
        let revolutions = if model.gas.four_stroke() { 2.0 } else { 1.0 };
        let cycle = revolutions * TAU;
        // The steady run's grid: as many equal steps as `solver.step_deg` needs, at least 16.
        let steps = ((cycle / model.solver.step_deg.to_radians()).ceil() as usize).max(16);
        let mut s = Self {
            joints,
            cycle,
            step: cycle / steps as f64,
            table: Arc::new(Table {
                omega: f64::NAN,
                oil_temperature_c: f64::NAN,
                power: Vec::new(),
                drive: Channel::new(vec![0.0], 1.0),
                instrument: None,
            }),
            cache: Vec::new(),
            state: State {
                t: t0,
                theta: 0.0,
                energy_j: Vec::new(),
                drive_work_j: 0.0,
                inputs: *inputs,
            },
            model,
            registry,
            warnings: Vec::new(),
        };
        s.state.energy_j = vec![0.0; s.joints.len()];
        // The rig's own notes (a law on a bearing it is not made for), as every result of
        // `tribo run` carries them first: once, at the start.
        s.warnings = tribo_core::sim::suitability_notes(&s.model, &s.registry);
        s.set_inputs(inputs)?;
        Ok(s)
    }

    /// The steady cycle at `inputs` (from the cache, or evaluated).
    fn table(&mut self, inputs: &Inputs) -> Result<Arc<Table>, StepError> {
        let (omega, temp) = (inputs.drive, inputs.oil_temperature_c);
        if !(omega.is_finite() && omega > 0.0) {
            return Err(StepError::Input(format!(
                "crank_speed must be a positive number of rad/s, got {omega}: this FMU evaluates the rig in its steady state at the input speed, which needs the crank turning"
            )));
        }
        let (lo, hi) = tribo_core::oil::VALID_RANGE_C;
        if !(temp >= lo && temp <= hi) {
            return Err(StepError::Input(format!(
                "oil_temperature must be within [{lo}, {hi}] C (the viscosity model's valid range), got {temp}"
            )));
        }
        if let Some(t) = self
            .cache
            .iter()
            .find(|t| t.omega == omega && t.oil_temperature_c == temp)
        {
            return Ok(Arc::clone(t));
        }
        let (table, warnings) = self.evaluate(omega, temp)?;
        let table = Arc::new(table);
        self.warnings.extend(warnings);
        if self.cache.len() == CACHE {
            self.cache.remove(0);
        }
        self.cache.push(Arc::clone(&table));
        Ok(table)
    }

    /// One steady cycle of the rig at crank speed `omega` and oil temperature `temp`, and what
    /// the solver warned of it (stateful laws that did not settle to a cycle; the solver's
    /// words name the speed, the oil temperature is added).
    fn evaluate(&self, omega: f64, temp: f64) -> Result<(Table, Vec<String>), StepError> {
        let mut m = self.model.clone();
        let rpm = omega * 30.0 / std::f64::consts::PI;
        m.cycle.segments = Some(vec![
            Segment::Ramp {
                to_rpm: rpm,
                duration_s: 1.0,
            },
            Segment::Hold { duration_s: 1.0 },
        ]);
        m.oil.temperature_c = Temperature::Constant(temp);
        let mut sim = Simulation::new(&m, &self.registry)?;
        let n = (self.cycle / self.step).round() as usize;
        let resolution_deg = self.cycle.to_degrees() / n as f64;
        let trace = sim
            .crank_angle_traces(resolution_deg)?
            .into_iter()
            .next()
            .ok_or_else(|| StepError::Input("the rig gave no cycle at this speed".into()))?;
        let mut power = vec![vec![0.0; trace.samples.len()]; self.joints.len()];
        for (k, sample) in trace.samples.iter().enumerate() {
            for ((joint, _), law) in trace.laws.iter().zip(&sample.laws) {
                if let Some(j) = self.joints.iter().position(|n| n == joint) {
                    power[j][k] += law.power_w;
                }
            }
        }
        let step = self.cycle / trace.samples.len() as f64;
        // The evaluated grid must be the steady run's, or the cycle integrals differ from it.
        debug_assert!((step - self.step).abs() <= 1e-12 * self.step);
        let drive: Vec<f64> = trace.samples.iter().map(|s| s.drive_torque_nm).collect();
        let mut warnings = trace.warnings;
        // With a drivetrain, its periodic cycle at this speed as `tribo run --steady` computes
        // it: the transducer's figures, and its warnings (the rating exceeded, a cycle that did
        // not repeat) that the crank's own cycle has not already given.
        let instrument = match m.drivetrain {
            Some(_) => {
                let run = Simulation::new(&m, &self.registry)?.run_steady()?;
                for w in run.warnings {
                    if !warnings.contains(&w) {
                        warnings.push(w);
                    }
                }
                run.plateaus.into_iter().next().and_then(|p| p.instrument)
            }
            None => None,
        };
        let table = Table {
            omega,
            oil_temperature_c: temp,
            power: power.into_iter().map(|p| Channel::new(p, step)).collect(),
            drive: Channel::new(drive, step),
            instrument,
        };
        Ok((
            table,
            warnings
                .into_iter()
                .map(|w| format!("oil at {temp} C, {w}"))
                .collect(),
        ))
    }
}

impl Stepping for QuasiSteady {
    fn joints(&self) -> &[String] {
        &self.joints
    }

    fn set_inputs(&mut self, inputs: &Inputs) -> Result<(), StepError> {
        self.table = self.table(inputs)?;
        self.state.inputs = *inputs;
        Ok(())
    }

    fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
    }

    fn advance_to(&mut self, t_s: f64) -> Result<(), StepError> {
        let s = &mut self.state;
        if t_s.is_nan() || t_s < s.t {
            return Err(StepError::Input(format!(
                "cannot step back in time, from {} s to {t_s} s",
                s.t
            )));
        }
        let omega = self.table.omega;
        let a = s.theta;
        let b = a + omega * (t_s - s.t);
        for (e, p) in s.energy_j.iter_mut().zip(&self.table.power) {
            // Energy = integral of power over time = integral of power / omega over angle.
            *e += p.integral(a, b, self.cycle, self.step) / omega;
        }
        s.drive_work_j += self.table.drive.integral(a, b, self.cycle, self.step);
        s.theta = b;
        s.t = t_s;
        Ok(())
    }

    fn outputs(&self) -> Outputs {
        let s = &self.state;
        let omega = self.table.omega;
        let (_, phi) = wrap(s.theta, self.cycle);
        let joints = self
            .table
            .power
            .iter()
            .zip(&s.energy_j)
            .map(|(p, e)| {
                let power_w = p.at(phi, self.step);
                JointOutput {
                    torque_nm: power_w / omega,
                    power_w,
                    energy_j: *e,
                }
            })
            .collect();
        Outputs {
            time_s: s.t,
            crank_angle_rad: s.theta,
            crank_speed_rad_s: omega,
            drive_torque_nm: self.table.drive.at(phi, self.step),
            drive_work_j: s.drive_work_j,
            joints,
            instrument: self.table.instrument.clone(),
        }
    }

    fn save(&self) -> Vec<u8> {
        // Serialising plain numbers into a vector cannot fail.
        rmp_serde::to_vec(&self.state).unwrap_or_default()
    }

    fn restore(&mut self, state: &[u8]) -> Result<(), StepError> {
        let s: State = rmp_serde::from_slice(state).map_err(|e| StepError::State(e.to_string()))?;
        if s.energy_j.len() != self.joints.len() {
            return Err(StepError::State(format!(
                "it has {} joints with laws, this rig {}",
                s.energy_j.len(),
                self.joints.len()
            )));
        }
        self.table = self.table(&s.inputs)?;
        self.state = s;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y = 1 + sin(phi) sampled on 8 steps: the integral over any span equals the trapezoid
    /// areas of the linear interpolant, summed by hand here.
    #[test]
    fn channel_integrals_are_those_of_the_linear_interpolant() {
        let n = 8;
        let step = TAU / n as f64;
        let y: Vec<f64> = (0..n).map(|k| 1.0 + (k as f64 * step).sin()).collect();
        let c = Channel::new(y.clone(), step);
        // Whole cycle: the trapezoid sum = step * sum(y) (periodic).
        let total: f64 = step * y.iter().sum::<f64>();
        assert!((c.integral(0.0, TAU, TAU, step) - total).abs() < 1e-12);
        // Three cycles and a bit, starting mid-interval.
        let (a, b) = (0.3, 3.0 * TAU + 0.3 + 0.5 * step);
        let lin = |phi: f64| c.at(phi, step);
        // Half an interval from 0.3, inside the first grid interval, where the interpolant is
        // one straight line: the trapezoid over it is exact.
        assert!(0.3 + 0.5 * step < step);
        let extra = 0.25 * step * (lin(0.3) + lin(0.3 + 0.5 * step));
        let got = c.integral(a, b, TAU, step);
        assert!((got - (3.0 * total + extra)).abs() < 1e-12, "{got}");
        // Additive over a split point, and zero over nothing.
        let m = 1.7;
        let split = c.integral(a, m, TAU, step) + c.integral(m, b, TAU, step);
        assert!((split - got).abs() < 1e-12);
        assert_eq!(c.integral(2.0, 2.0, TAU, step), 0.0);
        // The value at a grid angle is the sample, between two the straight line.
        assert!((c.at(2.0 * step, step) - y[2]).abs() < 1e-15);
        assert!((c.at(2.5 * step, step) - 0.5 * (y[2] + y[3])).abs() < 1e-15);
        // The last interval closes on the first sample.
        assert!((c.at(TAU - 0.5 * step, step) - 0.5 * (y[n - 1] + y[0])).abs() < 1e-15);
    }

    #[test]
    fn wrapping_keeps_the_angle_in_the_cycle() {
        assert_eq!(wrap(0.0, TAU), (0, 0.0));
        let (k, phi) = wrap(-0.5, TAU);
        assert_eq!(k, -1);
        assert!((phi - (TAU - 0.5)).abs() < 1e-15);
        let (k, phi) = wrap(5.0 * TAU + 1.0, TAU);
        assert_eq!(k, 5);
        assert!((phi - 1.0).abs() < 1e-12);
    }
}
