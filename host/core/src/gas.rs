//! Gas pressures on the piston: the cylinder above the crown and the crankcase below it.
//!
//! The models, all functions of the crank angle alone (no state, so every evaluation of the
//! solver sees the same pressure at the same angle and the force enters the multibody solve as
//! a known applied force on the piston along the cylinder axis):
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
//!   from TDC) follows `p V^n = const` through `p_tdc` at TDC; no breather flow.
//!
//! The force on the piston along +y (towards the head) is `A (p_crankcase - p_cylinder)`.

use std::f64::consts::{PI, TAU};

use crate::model::{CrankcasePressure, CylinderPressure, RigFile, Valves};

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
    Sealed { v_tdc_m3: f64, n: f64, p_tdc: f64 },
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
        let g = &f.gas;
        if g.is_none() {
            return None;
        }
        let r = f.geometry.crank_radius_m;
        let area = PI * 0.25 * f.geometry.bore_m * f.geometry.bore_m;
        let vd = area * 2.0 * r;
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
        };
        Some(GasModel {
            area_m2: area,
            crank_radius_m: r,
            rod_length_m: f.bodies.rod.length_m,
            ambient_pa: g.ambient_pa,
            phase_rad: g.cycle_angle_at_zero_deg.to_radians(),
            four_stroke: g.four_stroke(),
            cylinder,
            crankcase,
        })
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

    /// Pressures and force at crank angle `theta` (accumulated, rad).
    pub fn at(&self, theta: f64) -> GasState {
        self.at_travel(theta, self.piston_from_tdc(theta))
    }

    /// Pressures and force at crank angle `theta` with the piston `x` m from its top dead
    /// centre: an engine's cylinder with a pin or crank offset, whose travel is not the
    /// centred slider-crank's (`crate::engine`).
    pub fn at_travel(&self, theta: f64, x: f64) -> GasState {
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
        let crankcase_pa = match self.crankcase {
            Crankcase::Ambient => self.ambient_pa,
            Crankcase::Sealed { v_tdc_m3, n, p_tdc } => {
                p_tdc * (v_tdc_m3 / (v_tdc_m3 - self.area_m2 * x)).powf(n)
            }
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
