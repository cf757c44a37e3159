//! Gas pressures on the piston: the cylinder above the crown and the crankcase below it.
//!
//! The models, all functions of the crank angle (and, for a vented crankcase, the crank speed)
//! with no state, so every evaluation of the solver sees the same pressure at the same angle
//! and speed and the force enters the multibody solve as a known applied force on the piston
//! along the cylinder axis:
//!
//! - cylinder `none`: the crown sees the ambient pressure (the thesis's head-less rig);
//! - cylinder `motored`: the trapped charge follows `p V^n = const` with `p = p_in` at BDC, the
//!   clearance volume `V_c = V_d / (r_c - 1)`. With `valves = "closed"` the cylinder never opens
//!   (compression and expansion every revolution); with `valves = "four-stroke"` ideal valves
//!   open at the dead centres: intake (0-180 degrees of the 4-stroke cycle) and exhaust
//!   (540-720) at `p_in`, compression (180-360) and expansion (360-540) polytropic. Both are
//!   reversible (no heat loss, no flow loss): the net gas work over a cycle is zero;
//! - cylinder `trace`: a pressure-vs-cycle-angle table over 720 degrees, periodic linear
//!   interpolation;
//! - crankcase `atmospheric`: ambient pressure;
//! - crankcase `sealed`: the volume under the piston `V_cc = V_tdc - A x` (x: piston travel
//!   from TDC) follows `p V^n = const` through `p_tdc` at TDC; no breather flow;
//! - crankcase `vented`: the same volume, polytropic, breathing through an orifice to the
//!   ambient (compressible nozzle flow): the pressure is a state over time, and the model
//!   takes its periodic steady solution at the crank speed ([`vented`] derives the equation
//!   and states the flow law). **Quasi-steady**: the crankcase is assumed to settle faster
//!   than the test cycle changes speed. The tables are computed at the cycle's speeds: 0
//!   (ambient), every ramp's target and hold speed, points in between at most
//!   [`MAX_SPEED_GAP_RPM`] apart, and 10% above the top speed (higher speeds take the top
//!   table); between two speeds the pressure is interpolated linearly. The breather's time
//!   constant for the bundled CRF 250 R numbers is about 0.1 s (`docs/solver.md`), against
//!   1 s holds and 0.5 s ramps: the plateaus, measured at the end of their hold, are settled;
//!   on a ramp the real crankcase lags the table by roughly a tenth of a second of speed.
//!
//! The force on the piston along +y (towards the head) is `A (p_crankcase - p_cylinder)`.
//!
//! **Engines** share one crankcase (`docs/engines.md`, "One crankcase"): its volume is
//! `V_cc = V_tdc - A (sum_k x_k - sum_k x_k,ref)`, every piston's underside pumping it, with
//! `V_tdc` and `p_tdc` given for cylinder 1 at its local angle 0 (its TDC; the single
//! cylinder's definition). The sealed and vented models above apply to that volume unchanged;
//! a vented crankcase's table is over the engine's crank angle, and every cylinder sees the
//! same crankcase pressure ([`GasModel::crankcase_pa`], [`GasModel::with_crankcase`]).

pub mod vented;

use std::f64::consts::{PI, TAU};
use std::sync::{Arc, OnceLock};

use crate::cycle::{rpm_to_rad_s, Segment};
use crate::model::{CrankcasePressure, CylinderPressure, RigFile, Valves};
use vented::{Breather, Slider, Table, Underside, VentedCycle};

/// Largest step between the crank speeds at which a vented crankcase is tabulated, rpm.
pub const MAX_SPEED_GAP_RPM: f64 = 1000.0;

/// One 4-stroke cycle, rad.
pub const CYCLE_4: f64 = 2.0 * TAU;

/// The gas model of a rig, ready to evaluate at any crank angle.
#[derive(Debug, Clone)]
pub struct GasModel {
    area_m2: f64,
    crank_radius_m: f64,
    rod_length_m: f64,
    ambient_pa: f64,
    phase_rad: f64,
    four_stroke: bool,
    cylinder: Cylinder,
    crankcase: Crankcase,
    /// The pistons pumping the crankcase (the rig's one, or an engine's every cylinder).
    underside: Underside,
}

#[derive(Debug, Clone)]
enum Cylinder {
    Ambient,
    Polytropic {
        clearance_m3: f64,
        bdc_m3: f64,
        n: f64,
        p_in: f64,
        four_stroke: bool,
    },
    Trace {
        angles_rad: Vec<f64>,
        pressures_pa: Vec<f64>,
    },
}

#[derive(Debug, Clone)]
enum Crankcase {
    Ambient,
    /// `p_tdc (V_tdc / V_cc)^n`, `V_cc = V_tdc - A x` with `x` the pistons' summed travel from
    /// the reference state (`Underside`).
    Sealed {
        v_tdc_m3: f64,
        n: f64,
        p_tdc: f64,
    },
    Vented(Box<VentedTables>),
}

/// A vented crankcase's periodic cycles at rising crank speeds, each computed when first
/// needed (a steady run needs only its plateaus'; building a simulation to check its laws,
/// none).
#[derive(Debug, Clone)]
struct VentedTables {
    breather: Breather,
    /// Crank speeds, rad/s, rising; the first is 0 (no table: the ambient pressure).
    speeds: Vec<f64>,
    /// One table per speed after the first.
    tables: Vec<OnceLock<Arc<Table>>>,
}

impl VentedTables {
    /// The tables of `breather` at `speeds` (rising, the first 0), none computed yet.
    fn new(breather: Breather, speeds: Vec<f64>) -> Self {
        let tables = speeds[1..].iter().map(|_| OnceLock::new()).collect();
        Self {
            breather,
            speeds,
            tables,
        }
    }

    /// The pressure of speed `i`'s table at crank angle `theta`.
    fn table_at(&self, i: usize, theta: f64) -> f64 {
        if i == 0 {
            return self.breather.ambient_pa;
        }
        self.tables[i - 1]
            .get_or_init(|| vented::table(&self.breather, self.speeds[i]))
            .at(theta)
    }

    /// Crankcase pressure at crank angle `theta` and speed `omega`: linear in speed between
    /// the two tabulated speeds around it; the ambient at or below 0, the top table above it.
    fn at(&self, theta: f64, omega: f64) -> f64 {
        if omega.is_nan() || omega <= 0.0 {
            return self.breather.ambient_pa;
        }
        let last = self.speeds.len() - 1;
        if omega >= self.speeds[last] {
            return self.table_at(last, theta);
        }
        // First speed above omega (>= 1: speeds[0] = 0 < omega).
        let i = self.speeds.partition_point(|w| *w <= omega);
        let (w0, w1) = (self.speeds[i - 1], self.speeds[i]);
        let f = (omega - w0) / (w1 - w0);
        let low = self.table_at(i - 1, theta);
        if f == 0.0 {
            low
        } else {
            low + f * (self.table_at(i, theta) - low)
        }
    }
}

/// The crank speeds at which a vented crankcase is tabulated for the cycle `segments`, rad/s:
/// 0, every ramp's target, points between them at most [`MAX_SPEED_GAP_RPM`] apart, and 10%
/// above the top speed.
fn table_speeds(segments: &[Segment]) -> Vec<f64> {
    let mut rpm: Vec<f64> = segments
        .iter()
        .filter_map(|s| match s {
            Segment::Ramp { to_rpm, .. } if to_rpm.is_finite() && *to_rpm > 0.0 => Some(*to_rpm),
            _ => None,
        })
        .collect();
    rpm.push(0.0);
    rpm.sort_by(f64::total_cmp);
    rpm.dedup();
    let top = rpm[rpm.len() - 1];
    if top > 0.0 {
        rpm.push(1.1 * top);
    } else {
        // No speed at all in the cycle: one table, so a run at any speed has one.
        rpm.push(MAX_SPEED_GAP_RPM);
    }
    let mut filled = vec![0.0];
    for pair in rpm.windows(2) {
        let gaps = ((pair[1] - pair[0]) / MAX_SPEED_GAP_RPM).ceil().max(1.0) as usize;
        for k in 1..gaps {
            filled.push(pair[0] + (pair[1] - pair[0]) * k as f64 / gaps as f64);
        }
        filled.push(pair[1]);
    }
    // Speeds given exactly (a hold's speed) keep their exact value in rad/s.
    filled.into_iter().map(rpm_to_rad_s).collect()
}

/// The gas state at one crank angle: what a law could be handed (contract v2) and the force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GasState {
    /// Absolute cylinder pressure on the crown, Pa.
    pub cylinder_pa: f64,
    /// Absolute crankcase pressure under the piston, Pa.
    pub crankcase_pa: f64,
    /// Piston travel from TDC, m (0 at TDC, the stroke at BDC).
    pub piston_from_tdc_m: f64,
    /// Crank angle within the 4-stroke cycle, rad, [0, 4 pi) (0: gas-exchange TDC).
    pub cycle_angle_rad: f64,
    /// Net gas force on the piston along the cylinder axis towards the head, N.
    pub force_n: f64,
}

impl GasModel {
    /// The rig's gas model, or `None` for a rig without gas load (then nothing changes in the
    /// solve). The rig is assumed validated (`tribo-config` checks the ranges).
    pub fn from_rig(f: &RigFile) -> Option<GasModel> {
        if f.gas.is_none() {
            return None;
        }
        Some(Self::build(f))
    }

    /// The ambient model of the rig `f`: both sides of the piston at the rig's ambient
    /// pressure, whatever its `[gas]` says. What a cylinder pressure set from outside (the
    /// stepping API) replaces its cylinder side of, on a rig without gas loads.
    pub fn ambient(f: &RigFile) -> GasModel {
        let mut fk = f.clone();
        fk.gas.cylinder = CylinderPressure::None;
        fk.gas.crankcase = CrankcasePressure::Atmospheric;
        Self::build(&fk)
    }

    /// The gas state `s` with the cylinder pressure `cylinder_pa` (absolute, Pa) instead of
    /// the model's: the force follows from it and the crankcase pressure.
    pub fn with_cylinder_pressure(&self, s: GasState, cylinder_pa: f64) -> GasState {
        GasState {
            cylinder_pa,
            force_n: self.area_m2 * (s.crankcase_pa - cylinder_pa),
            ..s
        }
    }

    /// The model of the rig `f`'s `[gas]`, whatever it is.
    fn build(f: &RigFile) -> GasModel {
        let g = &f.gas;
        let r = f.geometry.crank_radius_m;
        let area = PI * 0.25 * f.geometry.bore_m * f.geometry.bore_m;
        let vd = area * 2.0 * r;
        let underside = underside(f, area);
        let cylinder = match &g.cylinder {
            CylinderPressure::None => Cylinder::Ambient,
            CylinderPressure::Motored {
                compression_ratio,
                polytropic_exponent,
                intake_pressure_pa,
                valves,
            } => {
                let vc = vd / (compression_ratio - 1.0);
                Cylinder::Polytropic {
                    clearance_m3: vc,
                    bdc_m3: vc + vd,
                    n: *polytropic_exponent,
                    p_in: *intake_pressure_pa,
                    four_stroke: *valves == Valves::FourStroke,
                }
            }
            CylinderPressure::Trace {
                crank_angle_deg,
                pressure_pa,
                ..
            } => Cylinder::Trace {
                angles_rad: crank_angle_deg.iter().map(|d| d.to_radians()).collect(),
                pressures_pa: pressure_pa.clone(),
            },
        };
        let crankcase = match &g.crankcase {
            CrankcasePressure::Atmospheric => Crankcase::Ambient,
            CrankcasePressure::Sealed {
                volume_at_tdc_m3,
                polytropic_exponent,
                pressure_at_tdc_pa,
            } => Crankcase::Sealed {
                v_tdc_m3: *volume_at_tdc_m3,
                n: *polytropic_exponent,
                p_tdc: *pressure_at_tdc_pa,
            },
            CrankcasePressure::Vented {
                volume_at_tdc_m3,
                polytropic_exponent,
                discharge_coefficient,
                temperature_c,
                ..
            } => {
                let breather = Breather {
                    volume_at_tdc_m3: *volume_at_tdc_m3,
                    underside: underside.clone(),
                    polytropic_exponent: *polytropic_exponent,
                    discharge_area_m2: discharge_coefficient
                        * g.crankcase.breather_area_m2().unwrap_or(0.0),
                    ambient_pa: g.ambient_pa,
                    temperature_k: temperature_c + 273.15,
                };
                Crankcase::Vented(Box::new(VentedTables::new(
                    breather,
                    table_speeds(&f.cycle.segments()),
                )))
            }
        };
        GasModel {
            area_m2: area,
            crank_radius_m: r,
            rod_length_m: f.bodies.rod.length_m,
            ambient_pa: g.ambient_pa,
            phase_rad: g.cycle_angle_at_zero_deg.to_radians(),
            four_stroke: g.four_stroke(),
            cylinder,
            crankcase,
            underside,
        }
    }

    /// Whether the pressure repeats only every 720 degrees.
    pub fn four_stroke(&self) -> bool {
        self.four_stroke
    }

    /// Piston crown area, m^2.
    pub fn area_m2(&self) -> f64 {
        self.area_m2
    }

    /// Piston travel from TDC at crank angle `theta`, m (exact slider-crank).
    pub fn piston_from_tdc(&self, theta: f64) -> f64 {
        piston_from_tdc(self.crank_radius_m, self.rod_length_m, theta)
    }

    /// The 4-stroke cycle angle of the rig's crank angle `theta` (accumulated), [0, 4 pi).
    pub fn cycle_angle(&self, theta: f64) -> f64 {
        cycle_angle(theta + self.phase_rad)
    }

    /// The periodic steady cycle of a vented crankcase at crank speed `omega` (> 0, rad/s),
    /// computed afresh (not from the tables): pressures over a revolution, pumping work, time
    /// constant. `None` for other crankcases.
    pub fn vented_cycle(&self, omega: f64) -> Option<VentedCycle> {
        match &self.crankcase {
            Crankcase::Vented(v) if omega > 0.0 => {
                Some(v.breather.periodic(omega, v.breather.ambient_pa))
            }
            _ => None,
        }
    }

    /// The ambient pressure, Pa: what a vented crankcase breathes to and from (its breather
    /// flow reverses where the crankcase pressure crosses it).
    pub fn ambient_pa(&self) -> f64 {
        self.ambient_pa
    }

    /// The crank angles (this model's, as [`GasModel::at`] takes them; rad, in [0, 4 pi)) where
    /// the cylinder pressure is not smooth, sorted: a pressure trace's samples where its slope
    /// changes (it is linear between them), known before any run. Empty for the closed-form
    /// models. The prescribed crank's error-controlled quadrature ends its steps on them.
    pub fn pressure_kinks(&self) -> Vec<f64> {
        let Cylinder::Trace {
            angles_rad,
            pressures_pa,
        } = &self.cylinder
        else {
            return Vec::new();
        };
        let n = angles_rad.len().min(pressures_pa.len());
        if n < 2 {
            return Vec::new();
        }
        // Sample k's angle and pressure, periodic in the 4-stroke cycle.
        let at = |k: isize| {
            let i = k.rem_euclid(n as isize) as usize;
            let wraps = k.div_euclid(n as isize) as f64;
            (angles_rad[i] + wraps * CYCLE_4, pressures_pa[i])
        };
        let slope = |(a0, p0): (f64, f64), (a1, p1): (f64, f64)| {
            if a1 > a0 {
                (p1 - p0) / (a1 - a0)
            } else {
                0.0
            }
        };
        let mut kinks: Vec<f64> = (0..n as isize)
            .filter(|&k| {
                let (left, right) = (slope(at(k - 1), at(k)), slope(at(k), at(k + 1)));
                (right - left).abs() > 1e-12 * (left.abs() + right.abs())
            })
            .map(|k| cycle_angle(at(k).0 - self.phase_rad))
            .collect();
        kinks.sort_by(f64::total_cmp);
        kinks
    }

    /// Whether the pressures depend on the crank speed (a vented crankcase).
    pub fn depends_on_speed(&self) -> bool {
        matches!(self.crankcase, Crankcase::Vented(_))
    }

    /// The crank speeds, rad/s, at which a vented crankcase is tabulated (empty for others).
    pub fn tabulated_speeds(&self) -> &[f64] {
        match &self.crankcase {
            Crankcase::Vented(v) => &v.speeds,
            _ => &[],
        }
    }

    /// Pressures and force at crank angle `theta` (accumulated, rad) and crank speed `omega`
    /// (rad/s; only a vented crankcase depends on it).
    pub fn at(&self, theta: f64, omega: f64) -> GasState {
        self.at_travel(theta, omega, self.piston_from_tdc(theta))
    }

    /// [`GasModel::at`] with the piston `x` m from its top dead centre, the only piston pumping
    /// the crankcase (the single-cylinder rig).
    pub fn at_travel(&self, theta: f64, omega: f64, x: f64) -> GasState {
        self.with_crankcase(theta, x, self.crankcase_pa(theta, omega, x))
    }

    /// The crankcase pressure, Pa, at crank angle `theta` (the engine's, accumulated; a vented
    /// crankcase's table is over it) and speed `omega`, with the pistons' travels from their
    /// TDCs summing to `travel_m` (a sealed crankcase's volume follows it): one pressure for
    /// every cylinder of an engine.
    pub fn crankcase_pa(&self, theta: f64, omega: f64, travel_m: f64) -> f64 {
        match &self.crankcase {
            Crankcase::Ambient => self.ambient_pa,
            Crankcase::Sealed { v_tdc_m3, n, p_tdc } => {
                let x = travel_m - self.underside.travel_at_reference_m;
                p_tdc * (v_tdc_m3 / (v_tdc_m3 - self.area_m2 * x)).powf(*n)
            }
            Crankcase::Vented(v) => v.at(theta, omega),
        }
    }

    /// The crankcase volume, m^3, at crank angle `theta` (`None` for an atmospheric
    /// crankcase, whose volume the model never needs).
    pub fn crankcase_volume_m3(&self, theta: f64) -> Option<f64> {
        let v_tdc = match &self.crankcase {
            Crankcase::Ambient => return None,
            Crankcase::Sealed { v_tdc_m3, .. } => *v_tdc_m3,
            Crankcase::Vented(v) => v.breather.volume_at_tdc_m3,
        };
        Some(v_tdc - self.area_m2 * self.underside.travel(theta).0)
    }

    /// The smallest crankcase volume over a revolution, m^3, sampled every half degree (`None`
    /// for an atmospheric crankcase): what rig validation keeps above zero.
    pub fn crankcase_min_volume_m3(&self) -> Option<f64> {
        (0..vented::NODES_PER_REV)
            .map(|k| self.crankcase_volume_m3(TAU * k as f64 / vented::NODES_PER_REV as f64))
            .try_fold(f64::INFINITY, |m, v| v.map(|v| m.min(v)))
    }

    /// The crankcase's mean pumping torque at the steady crank speed `omega` (> 0), N m: a
    /// vented crankcase's breather loss per revolution over 2 pi (its periodic cycle, the
    /// one the run's tables hold); 0 for a sealed one (a reversible polytrope); `None` for an
    /// atmospheric crankcase.
    pub fn crankcase_pumping_torque_nm(&self, omega: f64) -> Option<f64> {
        match &self.crankcase {
            Crankcase::Ambient => None,
            Crankcase::Sealed { .. } => Some(0.0),
            Crankcase::Vented(_) => self.vented_cycle(omega).map(|c| c.pumping_work_j / TAU),
        }
    }

    /// The gas state of a cylinder at its local crank angle `theta`, its piston `x` m from its
    /// TDC (an offset cylinder's true travel), under the crankcase pressure `crankcase_pa`.
    pub fn with_crankcase(&self, theta: f64, x: f64, crankcase_pa: f64) -> GasState {
        let phi = self.cycle_angle(theta);
        let cylinder_pa = match &self.cylinder {
            Cylinder::Ambient => self.ambient_pa,
            Cylinder::Polytropic {
                clearance_m3,
                bdc_m3,
                n,
                p_in,
                four_stroke,
            } => {
                let gas_exchange = *four_stroke && !(PI..3.0 * PI).contains(&phi);
                if gas_exchange {
                    *p_in
                } else {
                    p_in * (bdc_m3 / (clearance_m3 + self.area_m2 * x)).powf(*n)
                }
            }
            Cylinder::Trace {
                angles_rad,
                pressures_pa,
            } => periodic_linear(angles_rad, pressures_pa, phi, CYCLE_4),
        };
        GasState {
            cylinder_pa,
            crankcase_pa,
            piston_from_tdc_m: x,
            cycle_angle_rad: phi,
            force_n: self.area_m2 * (crankcase_pa - cylinder_pa),
        }
    }
}

/// The pistons under the crankcase of the rig `f`: its one centred slider-crank, or every
/// cylinder of its `[engine]` at its own phase, rod and offset, with the summed travel of the
/// reference state (cylinder 1 at its local angle 0).
fn underside(f: &RigFile, area: f64) -> Underside {
    let Some(geo) = crate::engine::geometry(f) else {
        return Underside {
            piston_area_m2: area,
            pistons: vec![Slider {
                phase_rad: 0.0,
                crank_radius_m: f.geometry.crank_radius_m,
                rod_length_m: f.bodies.rod.length_m,
                offset_m: 0.0,
            }],
            travel_at_reference_m: 0.0,
        };
    };
    let pistons: Vec<Slider> = geo
        .cylinders
        .iter()
        .enumerate()
        .map(|(k, c)| Slider {
            phase_rad: geo.cylinder_offset_rad(k),
            crank_radius_m: geo.crank_radius_m,
            rod_length_m: c.rod.length_m,
            offset_m: c.pin_offset_m + c.crank_offset_m,
        })
        .collect();
    let reference = -pistons.first().map_or(0.0, |p| p.phase_rad);
    let travel_at_reference_m = pistons.iter().map(|p| p.travel(reference).0).sum();
    Underside {
        piston_area_m2: area,
        pistons,
        travel_at_reference_m,
    }
}

/// Piston travel from TDC of a slider-crank of crank radius `r` and rod length `l` (m, pin on
/// the cylinder axis) at crank angle `theta`, m.
pub fn piston_from_tdc(r: f64, l: f64, theta: f64) -> f64 {
    let s = r * theta.sin();
    r + l - r * theta.cos() - (l * l - s * s).sqrt()
}

/// An accumulated angle (rad) reduced to one 4-stroke cycle, [0, 4 pi).
pub fn cycle_angle(angle: f64) -> f64 {
    let r = angle - CYCLE_4 * (angle / CYCLE_4).floor();
    if (0.0..CYCLE_4).contains(&r) {
        r
    } else {
        0.0
    }
}

/// The gas state a law is handed (contract version 2): both absolute pressures, the piston
/// travel from TDC and the 4-stroke cycle angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LawGas {
    /// Absolute cylinder pressure on the crown, Pa.
    pub cylinder_pa: f64,
    /// Absolute crankcase pressure under the piston, Pa.
    pub crankcase_pa: f64,
    /// Piston travel from TDC, m.
    pub piston_from_tdc_m: f64,
    /// Crank angle within the 4-stroke cycle, rad, [0, 4 pi).
    pub cycle_angle_rad: f64,
}

impl From<&GasState> for LawGas {
    fn from(s: &GasState) -> Self {
        LawGas {
            cylinder_pa: s.cylinder_pa,
            crankcase_pa: s.crankcase_pa,
            piston_from_tdc_m: s.piston_from_tdc_m,
            cycle_angle_rad: s.cycle_angle_rad,
        }
    }
}

/// Linear interpolation in the table `(xs, ys)` (xs rising within one `period`) at `x` in
/// `[0, period)`, wrapping from the last point to the first plus one period.
fn periodic_linear(xs: &[f64], ys: &[f64], x: f64, period: f64) -> f64 {
    let n = xs.len().min(ys.len());
    match n {
        0 => return 0.0,
        1 => return ys[0],
        _ => {}
    }
    // First index whose angle exceeds x.
    let i = xs[..n].partition_point(|a| *a <= x);
    let (x0, y0, x1, y1) = if i == 0 {
        (xs[n - 1] - period, ys[n - 1], xs[0], ys[0])
    } else if i == n {
        (xs[n - 1], ys[n - 1], xs[0] + period, ys[0])
    } else {
        (xs[i - 1], ys[i - 1], xs[i], ys[i])
    };
    let span = x1 - x0;
    if span > 0.0 {
        y0 + (y1 - y0) * (x - x0) / span
    } else {
        y0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periodic_interpolation_wraps_and_hits_the_nodes() {
        let xs = [0.5, 1.0, 3.0];
        let ys = [10.0, 20.0, 40.0];
        assert_eq!(periodic_linear(&xs, &ys, 1.0, 4.0), 20.0);
        assert!((periodic_linear(&xs, &ys, 2.0, 4.0) - 30.0).abs() < 1e-12);
        // Between 3.0 (40) and 4.5 (10): at 3.75 halfway, 25; at 0.25 (= 4.25) 15.
        assert!((periodic_linear(&xs, &ys, 3.75, 4.0) - 25.0).abs() < 1e-12);
        assert!((periodic_linear(&xs, &ys, 0.25, 4.0) - 15.0).abs() < 1e-12);
    }
}
