//! Plateau measurement: the steps near the end of each hold are recorded, and the plateau's
//! values are the means over the last whole crank revolutions of the hold, the window start
//! interpolated (cubic Hermite) between recorded steps.

use std::f64::consts::TAU;

use super::rates::{RateLayout, RegimeTimes};
use super::results::{
    ComponentFmep, Fmep, GroupTotal, LawResult, PlateauFmep, PlateauResult, RegimeShare,
};
use super::stepper::Integration;
use super::{SimError, Simulation};
use crate::cycle::{rad_s_to_rpm, Plateau};

/// The steps stored near the end of one hold, for its whole-revolution window: time, crank
/// angle and speed of each, in one flat buffer its accumulated quantities followed by their
/// rates, in another the laws' regime times, and the laws' regimes (codes). Sized before the
/// run, so stepping through the window does not allocate.
#[derive(Clone)]
struct Window {
    points: Vec<(f64, f64, f64)>,
    data: Vec<f64>,
    times: Vec<f64>,
    codes: Vec<u8>,
    n: usize,
    laws: RegimeTimes,
}

impl Window {
    fn with_capacity(points: usize, (n, laws): (usize, RegimeTimes)) -> Self {
        Self {
            points: Vec::with_capacity(points),
            data: Vec::with_capacity(points * 2 * n),
            times: Vec::with_capacity(points * laws.len()),
            codes: Vec::with_capacity(points * laws.n),
            n,
            laws,
        }
    }

    fn push(&mut self, t: f64, theta: f64, omega: f64, s: &Integration) {
        self.points.push((t, theta, omega));
        self.data.extend_from_slice(&s.acc);
        self.data.extend_from_slice(&s.last_rates);
        self.times.extend_from_slice(&s.regime_time);
        self.codes.extend_from_slice(&s.last_regimes);
    }

    fn acc(&self, i: usize) -> &[f64] {
        &self.data[2 * self.n * i..2 * self.n * i + self.n]
    }

    fn rates(&self, i: usize) -> &[f64] {
        &self.data[2 * self.n * i + self.n..2 * self.n * (i + 1)]
    }

    fn regime_time(&self, i: usize) -> &[f64] {
        let m = self.laws.len();
        &self.times[m * i..m * (i + 1)]
    }

    fn regimes(&self, i: usize) -> &[u8] {
        &self.codes[self.laws.n * i..self.laws.n * (i + 1)]
    }
}

/// What the plateau windows need of a run: the measurement window, the revolutions of one
/// cycle and the step length (to size each window's storage before the run). Plain data, so
/// the single-cylinder rig and the engine measure their plateaus alike.
#[derive(Debug, Clone, Copy)]
pub(super) struct WindowSpec {
    /// The measurement window at the end of each hold, s (whole cycles within it are used).
    pub(super) window_s: f64,
    /// Crank revolutions per cycle: 2 for a 4-stroke pressure, else 1.
    pub(super) revs_per_cycle: u32,
    /// The step's crank angle, rad, and its cap in time, s.
    pub(super) step_rad: f64,
    pub(super) max_step_s: f64,
}

impl WindowSpec {
    /// One cycle's crank angle, rad: 2 pi, or 4 pi for a 4-stroke cycle.
    pub(super) fn cycle_angle(&self) -> f64 {
        TAU * self.revs_per_cycle as f64
    }

    /// Where the measurement window of hold `p` starts when the crank follows the cycle
    /// exactly (a prescribed crank), s: its whole revolutions before the hold's end.
    pub(super) fn window_start(&self, p: &Plateau) -> f64 {
        p.t_end - self.window_revs(p.omega) as f64 * TAU / p.omega
    }

    /// Whole revolutions in the measurement window at speed `omega`: whole cycles (at least
    /// one).
    pub(super) fn window_revs(&self, omega: f64) -> u32 {
        let cycles = ((self.window_s * omega / self.cycle_angle()).floor() as u32).max(1);
        cycles * self.revs_per_cycle
    }

    /// The time the crank needs to turn `angle_rad` at `omega`, capped by the largest step.
    pub(super) fn time_step(&self, angle_rad: f64, omega: f64) -> f64 {
        if omega > 0.0 {
            (angle_rad / omega).min(self.max_step_s)
        } else {
            self.max_step_s
        }
    }
}

/// A plateau's measurement window: the change of every accumulated quantity over it, each
/// law's time in each regime within it (s), its length in time (s) and crank angle (rad), its
/// bounds (s) and whole revolutions.
pub(super) struct Measured {
    pub(super) delta: Vec<f64>,
    pub(super) regime_time: Vec<f64>,
    pub(super) dt: f64,
    pub(super) dtheta: f64,
    pub(super) window_s: [f64; 2],
    pub(super) revs: u32,
}

/// The recorder of every plateau's window, and the time the drive sat at its limit near it.
#[derive(Clone)]
pub(super) struct Plateaus {
    plateaus: Vec<Plateau>,
    records: Vec<Window>,
    saturated_time: Vec<f64>,
    spec: WindowSpec,
}

impl Plateaus {
    /// Storage for the cycle's `plateaus`, each sized for the steps its measurement margin
    /// will hold, for `n.0` accumulated quantities and the regime times of `n.1`.
    pub(super) fn new(plateaus: &[Plateau], spec: WindowSpec, n: (usize, RegimeTimes)) -> Self {
        let records = plateaus
            .iter()
            .map(|p| {
                let w = p.omega.max(1e-9);
                let h = spec.time_step(spec.step_rad, w);
                let margin = spec.window_s + (spec.cycle_angle() + TAU) / w;
                Window::with_capacity((margin / h).ceil() as usize + 16, n)
            })
            .collect();
        Self {
            plateaus: plateaus.to_vec(),
            records,
            saturated_time: vec![0.0; plateaus.len()],
            spec,
        }
    }

    /// Record the accepted step of length `h` ending at `t1` (crank `theta`, `omega`; the
    /// accumulated quantities, their rates and the regimes there in `s`) in every window it
    /// falls in.
    pub(super) fn record(
        &mut self,
        t1: f64,
        h: f64,
        (theta, omega): (f64, f64),
        saturated: bool,
        s: &Integration,
    ) {
        let cycle = self.spec.cycle_angle();
        for (pi, p) in self.plateaus.iter().enumerate() {
            let margin = self.spec.window_s + (cycle + TAU) / p.omega.max(1e-9) + 2.0 * h;
            if t1 >= p.t_end - margin && t1 <= p.t_end + 1e-12 {
                if saturated {
                    self.saturated_time[pi] += h;
                }
                self.records[pi].push(t1, theta, omega, s);
            }
        }
    }

    /// Every plateau's result (`result` turns plateau `pi`, measured `m`, into a
    /// [`PlateauResult`]), with the warnings of a drive at its limit or a speed
    /// that never settled.
    /// A plateau whose window cannot be placed (the crank stalled) is [`SimError::Stalled`].
    pub(super) fn results(
        &self,
        result: impl Fn(usize, &Measured) -> PlateauResult,
    ) -> Result<(Vec<PlateauResult>, Vec<String>), SimError> {
        let mut results = Vec::new();
        let mut warnings = Vec::new();
        for (pi, p) in self.plateaus.iter().enumerate() {
            let measured = measure(&self.spec, p, &self.records[pi]).map_err(|mut e| {
                if let SimError::Stalled { saturated_s, .. } = &mut e {
                    *saturated_s = self.saturated_time[pi];
                }
                e
            })?;
            results.push(result(pi, &measured));
            if self.saturated_time[pi] > 0.5 * self.spec.window_s {
                warnings.push(format!(
                    "at the {:.0} rpm plateau the drive sat at its torque limit for {:.3} s near the measurement window; the plateau torque is limited by the drive",
                    p.speed_rpm,
                    self.saturated_time[pi]
                ));
            }
            let r = &results[pi];
            if (r.mean_speed_rpm - r.set_speed_rpm).abs() > 0.02 * r.set_speed_rpm {
                warnings.push(format!("the {:.0} rpm plateau reached only {:.1} rpm on average: the speed never settled", r.set_speed_rpm, r.mean_speed_rpm));
            }
        }
        Ok((results, warnings))
    }
}

/// The window over the last whole revolutions (whole cycles) of the hold `p`, from the
/// recorded steps `recs`; [`SimError::Stalled`] when the recorded end of the hold holds fewer
/// revolutions.
fn measure(spec: &WindowSpec, p: &Plateau, recs: &Window) -> Result<Measured, SimError> {
    let (omega_ref, t_end) = (p.omega, p.t_end);
    let revs = spec.window_revs(omega_ref);
    let (t_e, theta_e, acc_e, times_e) = match recs.points.len() {
        0 => (t_end, 0.0, vec![0.0; recs.n], vec![0.0; recs.laws.len()]),
        len => (
            recs.points[len - 1].0,
            recs.points[len - 1].1,
            recs.acc(len - 1).to_vec(),
            recs.regime_time(len - 1).to_vec(),
        ),
    };
    let theta_s = theta_e - revs as f64 * TAU;
    // The window must start inside the recorded end of the hold; otherwise the crank has
    // not turned enough for a whole-cycle mean and there is no honest value to give.
    let first = recs.points.first().copied();
    if first.is_none_or(|(_, theta_0, _)| theta_0 > theta_s) {
        let (t_0, theta_0) = first.map_or((t_e, theta_e), |(t, th, _)| (t, th));
        return Err(SimError::Stalled {
            set_speed_rpm: p.speed_rpm,
            turned_revs: (theta_e - theta_0) / TAU,
            span_s: t_e - t_0,
            needed_revs: revs,
            saturated_s: 0.0,
        });
    }
    // Find the interval holding theta_s and interpolate there.
    let (mut t_s, mut acc_s, mut times_s) = (t_e, acc_e.clone(), times_e.clone());
    for i in 1..recs.points.len() {
        let ((ta, tha, wa), (tb, thb, wb)) = (recs.points[i - 1], recs.points[i]);
        if tha <= theta_s && theta_s <= thb {
            let h = tb - ta;
            // The window's start: where the crank angle's cubic reaches theta_s.
            let s = hermite_root((tha, thb), (h * wa, h * wb), theta_s);
            t_s = ta + s * h;
            (acc_s, times_s) = recs.interpolate(i, s, h);
            break;
        }
    }
    Ok(Measured {
        delta: acc_e.iter().zip(&acc_s).map(|(e, s)| e - s).collect(),
        regime_time: times_e.iter().zip(&times_s).map(|(e, s)| e - s).collect(),
        dt: (t_e - t_s).max(1e-300),
        dtheta: theta_e - theta_s,
        window_s: [t_s, t_e],
        revs,
    })
}

impl Window {
    /// The accumulated quantities and the regime times at the fraction `s` of the step of
    /// length `h` (s) ending at record `i`: cubic Hermite in time, the rates as slopes; a
    /// regime time's slope is its law's 0/1 indicator of that regime at the step's ends.
    fn interpolate(&self, i: usize, s: f64, h: f64) -> (Vec<f64>, Vec<f64>) {
        let herm = |y0: f64, y1: f64, d0: f64, d1: f64| {
            let (s2, s3) = (s * s, s * s * s);
            (2.0 * s3 - 3.0 * s2 + 1.0) * y0
                + (s3 - 2.0 * s2 + s) * h * d0
                + (-2.0 * s3 + 3.0 * s2) * y1
                + (s3 - s2) * h * d1
        };
        let (aa, ab, ra, rb) = (
            self.acc(i - 1),
            self.acc(i),
            self.rates(i - 1),
            self.rates(i),
        );
        let acc = (0..self.n)
            .map(|k| herm(aa[k], ab[k], ra[k], rb[k]))
            .collect();
        let (ta, tb) = (self.regime_time(i - 1), self.regime_time(i));
        let (ca, cb) = (self.regimes(i - 1), self.regimes(i));
        let indicator = |codes: &[u8], slot: usize| {
            let (k, r) = (slot / RegimeTimes::REGIMES, slot % RegimeTimes::REGIMES);
            if codes[k] as usize == r {
                1.0
            } else {
                0.0
            }
        };
        let times = (0..self.laws.len())
            .map(|j| herm(ta[j], tb[j], indicator(ca, j), indicator(cb, j)))
            .collect();
        (acc, times)
    }
}

impl Simulation {
    /// What the plateau windows need of this run.
    pub(super) fn window_spec(&self) -> WindowSpec {
        WindowSpec {
            window_s: self.window_s,
            revs_per_cycle: self.revolutions_per_cycle(),
            step_rad: self.step_rad,
            max_step_s: self.max_step_s,
        }
    }

    /// One cycle's crank angle, rad: 2 pi, or 4 pi for a 4-stroke cycle.
    pub(super) fn cycle_angle(&self) -> f64 {
        TAU * self.revolutions_per_cycle() as f64
    }

    /// Plateau `pi`'s values from the change of the accumulated quantities over its measured
    /// `window`; an engine's with its groups (per component and per cylinder).
    pub(super) fn plateau_result(&self, pi: usize, window: &Measured) -> PlateauResult {
        let laws = self.joints.iter().flat_map(|j| {
            j.laws
                .iter()
                .map(move |l| (j.name.as_str(), l.name.as_str()))
        });
        let mut result = plateau_values(
            laws,
            self.layout(),
            &self.fmep(),
            window,
            self.cycle.plateaus()[pi].speed_rpm,
            window.dtheta / window.dt,
            (self.temps[pi], self.viscosities[pi]),
        );
        result.correlation = Some(
            self.correlation
                .at(self.cycle.plateaus()[pi].speed_rpm, self.viscosities[pi]),
        );
        result.crankcase_pumping_torque_nm = self.gas.first().and_then(|g| {
            g.crankcase_pumping_torque_nm(crate::cycle::rpm_to_rad_s(
                self.cycle.plateaus()[pi].speed_rpm,
            ))
        });
        if self.engine {
            result.groups = group_totals(&result.joints, self.crank.cylinders());
        }
        result
    }
}

/// Per-component (all mains, every cylinder's big ends, ...) and per-cylinder totals of the
/// friction torque and power.
fn group_totals(joints: &[LawResult], cylinders: usize) -> Vec<GroupTotal> {
    let total = |name: String, pick: &dyn Fn(&str) -> bool| {
        let (t, p) = joints
            .iter()
            .filter(|l| pick(&l.joint))
            .fold((0.0, 0.0), |(t, p), l| {
                (t + l.friction_torque_nm, p + l.power_w)
            });
        GroupTotal {
            group: name,
            friction_torque_nm: t,
            power_w: p,
        }
    };
    let mut out = Vec::new();
    for kind in crate::model::JOINT_KINDS {
        let prefix = format!("{kind}_");
        out.push(total(format!("{kind}_*"), &|j: &str| {
            j.starts_with(&prefix)
        }));
    }
    for k in 1..=cylinders {
        let suffix = format!("_{k}");
        out.push(total(format!("cylinder {k}"), &|j: &str| {
            !j.starts_with("main_") && j.ends_with(&suffix)
        }));
    }
    out
}

/// A plateau's result from the change of the accumulated quantities (in `layout`) over its
/// measured `window`: each law's values (`laws`: joint and law names in rate order), the FMEP
/// breakdown by `fmep`, the set speed (rpm), the mean speed `mean_omega` (rad/s) and the oil
/// (C, Pa s).
fn plateau_values<'a>(
    laws: impl Iterator<Item = (&'a str, &'a str)>,
    layout: RateLayout,
    fmep: &Fmep,
    window: &Measured,
    set_speed_rpm: f64,
    mean_omega: f64,
    (oil_temp_c, viscosity_pa_s): (f64, f64),
) -> PlateauResult {
    let (d, dt, dtheta) = (&window.delta, window.dt, window.dtheta);
    let joints: Vec<LawResult> = laws
        .enumerate()
        .map(|(k, (joint, law))| {
            let share = |r: usize| window.regime_time[RegimeTimes::slot(k, r)] / dt;
            LawResult {
                joint: joint.into(),
                law: law.into(),
                friction_torque_nm: d[layout.power(k)] / dtheta,
                power_w: d[layout.power(k)] / dt,
                mean_normal_load_n: d[layout.normal(k)] / dt,
                regime_share: RegimeShare {
                    none: share(0),
                    boundary: share(1),
                    mixed: share(2),
                    hydrodynamic: share(3),
                },
            }
        })
        .collect();
    let mut components: Vec<ComponentFmep> = Vec::new();
    for l in &joints {
        match components.iter_mut().find(|c| c.joint == l.joint) {
            Some(c) => c.kpa += fmep.kpa(l.friction_torque_nm),
            None => components.push(ComponentFmep {
                joint: l.joint.clone(),
                kpa: fmep.kpa(l.friction_torque_nm),
            }),
        }
    }
    let motoring_torque_nm = d[RateLayout::MOTOR] / dtheta;
    PlateauResult {
        fmep: PlateauFmep {
            total_kpa: fmep.kpa(joints.iter().map(|l| l.friction_torque_nm).sum()),
            motoring_kpa: fmep.kpa(motoring_torque_nm),
            components,
        },
        set_speed_rpm,
        mean_speed_rpm: rad_s_to_rpm(mean_omega),
        motoring_torque_nm,
        gas_torque_nm: d[layout.gas()] / dtheta,
        crankcase_pumping_torque_nm: None,
        oil_temp_c,
        viscosity_pa_s,
        window_s: window.window_s,
        revolutions: window.revs,
        joints,
        groups: Vec::new(),
        correlation: None,
        instrument: None,
    }
}

/// The cubic Hermite interpolant on `[0, 1]` with values `y0`, `y1` and slopes (per unit `s`)
/// `m0`, `m1` at its ends, at `s`.
fn hermite(y0: f64, y1: f64, m0: f64, m1: f64, s: f64) -> f64 {
    let (s2, s3) = (s * s, s * s * s);
    (2.0 * s3 - 3.0 * s2 + 1.0) * y0
        + (s3 - 2.0 * s2 + s) * m0
        + (-2.0 * s3 + 3.0 * s2) * y1
        + (s3 - s2) * m1
}

/// Its derivative with respect to `s`.
fn hermite_slope(y0: f64, y1: f64, m0: f64, m1: f64, s: f64) -> f64 {
    let s2 = s * s;
    (6.0 * s2 - 6.0 * s) * (y0 - y1) + (3.0 * s2 - 4.0 * s + 1.0) * m0 + (3.0 * s2 - 2.0 * s) * m1
}

/// Where on `[0, 1]` the Hermite cubic through `ends` with slopes `slopes` reaches `target`,
/// for a cubic that is monotonic there with `target` between its end values (the crank angle
/// over a step). Newton's method on the cubic from the linear interpolate, safeguarded by the
/// bracket it keeps (a step leaving the bracket is replaced by bisection): converged to
/// rounding in 3-4 iterations where the bisection it replaces took 60.
fn hermite_root(ends: (f64, f64), slopes: (f64, f64), target: f64) -> f64 {
    let ((y0, y1), (m0, m1)) = (ends, slopes);
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut s = if y1 > y0 {
        ((target - y0) / (y1 - y0)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    for _ in 0..60 {
        let r = hermite(y0, y1, m0, m1, s) - target;
        if r == 0.0 {
            return s;
        }
        if r < 0.0 {
            lo = s;
        } else {
            hi = s;
        }
        let d = hermite_slope(y0, y1, m0, m1, s);
        let newton = s - r / d;
        let next = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - s).abs() <= 4.0 * f64::EPSILON || hi - lo <= 4.0 * f64::EPSILON {
            return next;
        }
        s = next;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite_root_solves_the_cubic_like_a_long_bisection() {
        // Crank-like steps: angle rising with speeds that differ (accelerating, decelerating).
        for (y0, y1, m0, m1) in [
            (0.0, 1.0, 0.8, 1.2),
            (2.0, 2.5, 0.6, 0.4),
            (0.0, 1e-3, 1e-3, 1e-3),
        ] {
            for k in 0..=20 {
                let target = y0 + (y1 - y0) * k as f64 / 20.0;
                let s = hermite_root((y0, y1), (m0, m1), target);
                assert!((0.0..=1.0).contains(&s));
                let (mut lo, mut hi) = (0.0, 1.0);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if hermite(y0, y1, m0, m1, mid) < target {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let b = 0.5 * (lo + hi);
                assert!(
                    (s - b).abs() < 1e-12,
                    "{y0} {y1} {m0} {m1} {target}: {s} vs {b}"
                );
                let r = hermite(y0, y1, m0, m1, s) - target;
                assert!(r.abs() <= 1e-14 * (1.0 + y1.abs()), "residual {r}");
            }
        }
    }
}
