//! Validation of a loaded rig: every value within its physical range and size, one validator
//! per part of the file, the first problem located in the file (or `--set`) that gives it.

use tribo_core::cycle::Segment;
use tribo_core::oil::{ViscosityModel, VALID_RANGE_C};

use super::{readable, Drive, Rig, RigError, Temperature};

mod engine;
mod gas;

/// Validate a rig again after a program changed it (a study setting the cycle from data).
pub fn revalidate(rig: &Rig) -> Result<(), Box<RigError>> {
    validate(rig).map_err(Box::new)
}

/// The highest speed a test cycle may reach, rpm.
pub const MAX_SPEED_RPM: f64 = 30_000.0;
/// The longest test cycle, s.
pub const MAX_CYCLE_S: f64 = 3600.0;
/// The allowed range of `solver.step_deg`, degrees.
pub const STEP_DEG_RANGE: (f64, f64) = (0.01, 10.0);
/// The allowed range of `solver.max_step_deg`, degrees.
pub const MAX_STEP_DEG_RANGE: (f64, f64) = (0.1, 90.0);
/// The heaviest body (and crank unbalance mass) a rig may have, kg: an engine's crankshaft is a
/// few kg, a large single cylinder's tens; ten tonnes admits any test rig, while `1e308` would
/// overflow the inertia forces into infinities.
pub const MAX_MASS_KG: f64 = 1e4;
/// The largest moment of inertia (bodies, drive motor), kg m^2.
pub const MAX_INERTIA_KG_M2: f64 = 1e4;
/// The longest length (crank radius, bore, rod, unbalance radius, joint contact radius and
/// length), m.
pub const MAX_LENGTH_M: f64 = 10.0;
/// The largest mass or inertia scale factor (the lighter-rod study scales by about 0.6).
pub const MAX_SCALE: f64 = 1e3;
/// The densest oil accepted, kg/m^3 (engine oils are about 850).
pub const MAX_DENSITY_KG_M3: f64 = 2e4;
/// The most viscous oil accepted at any of the rig's temperatures, cSt (a cold 10W-50 is a
/// few thousand).
pub const MAX_VISCOSITY_CST: f64 = 1e6;
/// Largest gas pressure, Pa (1000 bar: far above any engine's peak).
const MAX_PRESSURE_PA: f64 = 1e8;

/// Why the sizes of a rig are bounded, in an error message.
const SIZE_WHY: &str = "far beyond any engine, and large enough to overflow the model";

/// Check a rig's values part by part; the first problem found is the error, located in the
/// file (or `--set`) that gives the value.
pub(super) fn validate(rig: &Rig) -> Result<(), RigError> {
    let check = Check { rig };
    check.geometry()?;
    check.bodies()?;
    check.joints()?;
    check.load_shares()?;
    check.oil()?;
    check.max_speed()?;
    let plateaus = check.cycle()?;
    check.oil_temperatures(plateaus)?;
    check.drive()?;
    check.measurement()?;
    check.solver()?;
    check.gas()?;
    check.engine()?;
    check.drivetrain()
}

/// The rig's validators, one per part of the file, run in the order of [`validate`] so the
/// first problem reported is the same whatever the split.
struct Check<'a> {
    rig: &'a Rig,
}

impl Check<'_> {
    /// `v` must be finite and above zero.
    fn positive(&self, field: &str, v: f64, unit: &str) -> Result<(), RigError> {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(self.rig.error(
                field,
                format!("must be a positive number ({unit}), got {v}"),
            ))
        }
    }

    /// `v` must be finite and not below zero.
    fn non_negative(&self, field: &str, v: f64, unit: &str) -> Result<(), RigError> {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            Err(self
                .rig
                .error(field, format!("must be zero or positive ({unit}), got {v}")))
        }
    }

    /// `v` must be finite, above zero and at most `max` (a physical size; beyond it the model's
    /// forces overflow).
    fn size(&self, field: &str, v: f64, max: f64, unit: &str) -> Result<(), RigError> {
        self.positive(field, v, unit)?;
        self.at_most(field, v, max, unit)
    }

    /// `v` must be finite, not below zero and at most `max`.
    fn size_or_zero(&self, field: &str, v: f64, max: f64, unit: &str) -> Result<(), RigError> {
        self.non_negative(field, v, unit)?;
        self.at_most(field, v, max, unit)
    }

    /// `v` (finite) must be at most `max`.
    fn at_most(&self, field: &str, v: f64, max: f64, unit: &str) -> Result<(), RigError> {
        if v <= max {
            Ok(())
        } else {
            Err(self.rig.error(
                field,
                format!(
                    "must be at most {}{} ({SIZE_WHY}), got {}",
                    readable(max),
                    if unit == "-" {
                        String::new()
                    } else {
                        format!(" {unit}")
                    },
                    readable(v)
                ),
            ))
        }
    }

    /// `v` must be finite and within `[lo, hi]` (`why` says what the limits protect).
    fn within(
        &self,
        field: &str,
        v: f64,
        (lo, hi): (f64, f64),
        unit: &str,
        why: &str,
    ) -> Result<(), RigError> {
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(())
        } else {
            Err(self.rig.error(
                field,
                format!(
                    "must be in [{lo}, {hi}] {unit} ({why}), got {}",
                    readable(v)
                ),
            ))
        }
    }

    /// Crank radius and bore.
    fn geometry(&self) -> Result<(), RigError> {
        let g = &self.rig.file.geometry;
        self.size(
            "geometry.crank_radius_m",
            g.crank_radius_m,
            MAX_LENGTH_M,
            "m",
        )?;
        self.size("geometry.bore_m", g.bore_m, MAX_LENGTH_M, "m")
    }

    /// Masses, inertias and scales of crank, rod and piston; a rod longer than the crank radius
    /// with its centre of mass between the pins.
    fn bodies(&self) -> Result<(), RigError> {
        let f = &self.rig.file;
        let c = &f.bodies.crank;
        let (m, j, l) = (MAX_MASS_KG, MAX_INERTIA_KG_M2, MAX_LENGTH_M);
        self.size("bodies.crank.inertia_kg_m2", c.inertia_kg_m2, j, "kg m^2")?;
        self.size("bodies.crank.mass_kg", c.mass_kg, m, "kg")?;
        self.size_or_zero(
            "bodies.crank.unbalance_mass_kg",
            c.unbalance_mass_kg,
            m,
            "kg",
        )?;
        self.size_or_zero(
            "bodies.crank.unbalance_radius_m",
            c.unbalance_radius_m,
            l,
            "m",
        )?;
        self.size("bodies.crank.mass_scale", c.mass_scale, MAX_SCALE, "-")?;
        self.size(
            "bodies.crank.inertia_scale",
            c.inertia_scale,
            MAX_SCALE,
            "-",
        )?;
        let r = &f.bodies.rod;
        self.size("bodies.rod.mass_kg", r.mass_kg, m, "kg")?;
        self.size("bodies.rod.inertia_kg_m2", r.inertia_kg_m2, j, "kg m^2")?;
        self.size("bodies.rod.length_m", r.length_m, l, "m")?;
        self.size("bodies.rod.mass_scale", r.mass_scale, MAX_SCALE, "-")?;
        self.size("bodies.rod.inertia_scale", r.inertia_scale, MAX_SCALE, "-")?;
        if r.length_m <= f.geometry.crank_radius_m {
            return Err(self.rig.error(
                "bodies.rod.length_m",
                format!(
                    "the rod ({} m) must be longer than the crank radius ({} m), or the mechanism locks",
                    r.length_m, f.geometry.crank_radius_m
                ),
            ));
        }
        if !(r.com_from_big_end_m.is_finite()
            && r.com_from_big_end_m >= 0.0
            && r.com_from_big_end_m <= r.length_m)
        {
            return Err(self.rig.error(
                "bodies.rod.com_from_big_end_m",
                format!(
                    "must lie between the pin centres, [0, {}] m, got {}",
                    r.length_m, r.com_from_big_end_m
                ),
            ));
        }
        let p = &f.bodies.piston;
        self.size("bodies.piston.mass_kg", p.mass_kg, m, "kg")?;
        self.size("bodies.piston.mass_scale", p.mass_scale, MAX_SCALE, "-")
    }

    /// Each joint's contact radius and length, no empty law name, and no bearing type on the
    /// piston (a slide).
    fn joints(&self) -> Result<(), RigError> {
        let engine = self.rig.file.engine.is_some();
        for (name, j) in self.rig.file.joints.named() {
            if name.starts_with("main_") {
                match (engine, j.is_absent()) {
                    (true, true) => continue,
                    (true, false) => {
                        return Err(self.rig.error(
                            &format!("joints.{name}"),
                            "an engine rig gives its main bearings as [[engine.mains]] (joints main_1 .. main_n); leave [joints.main_a] and [joints.main_b] out",
                        ))
                    }
                    (false, true) => {
                        return Err(self.rig.error(
                            &format!("joints.{name}"),
                            format!("missing table [joints.{name}]: the single-cylinder rig has two main bearings, main_a and main_b (an engine rig gives [[engine.mains]] instead)"),
                        ))
                    }
                    (false, false) => {}
                }
            }
            self.size(
                &format!("joints.{name}.radius_m"),
                j.radius_m,
                MAX_LENGTH_M,
                "m",
            )?;
            self.size(
                &format!("joints.{name}.length_m"),
                j.length_m,
                MAX_LENGTH_M,
                "m",
            )?;
            for (i, l) in j.laws.iter().enumerate() {
                if l.law.trim().is_empty() {
                    let field = format!("joints.{name}.laws[{i}].law");
                    return Err(self.rig.error(&field, "law name is empty"));
                }
            }
            if name == "piston" && j.bearing.is_some() {
                return Err(self.rig.error(
                    "joints.piston.bearing",
                    "the piston is a slide, always: `bearing` (\"plain\" or \"rolling\") is for the main bearings, the big end and the small end",
                ));
            }
        }
        Ok(())
    }

    /// The main bearings' load shares: each in [0, 1], together 1.
    fn load_shares(&self) -> Result<(), RigError> {
        let j = &self.rig.file.joints;
        // An engine splits its main loads by the lever rule (docs/engines.md).
        if self.rig.file.engine.is_some() {
            return Ok(());
        }
        for (name, share) in [
            ("main_a", j.main_a.load_share),
            ("main_b", j.main_b.load_share),
        ] {
            if !(share.is_finite() && (0.0..=1.0).contains(&share)) {
                return Err(self.rig.error(
                    &format!("joints.{name}.load_share"),
                    format!("must be in [0, 1], got {share}"),
                ));
            }
        }
        let sum = j.main_a.load_share + j.main_b.load_share;
        if (sum - 1.0).abs() > 1e-9 {
            return Err(self.rig.error(
                "joints.main_b.load_share",
                format!("the two main-bearing load shares must add up to 1, they add up to {sum}"),
            ));
        }
        Ok(())
    }

    /// Oil density and the viscosity model's constants (temperatures: [`Self::oil_temperatures`],
    /// once the number of plateaus is known).
    fn oil(&self) -> Result<(), RigError> {
        let oil = &self.rig.file.oil;
        self.size(
            "oil.density_kg_m3",
            oil.density_kg_m3,
            MAX_DENSITY_KG_M3,
            "kg/m^3",
        )?;
        match oil.viscosity {
            ViscosityModel::Vogel {
                k_cst,
                theta1_c,
                theta2_c,
            } => {
                self.positive("oil.viscosity.k_cst", k_cst, "cSt")?;
                if !theta1_c.is_finite() || !theta2_c.is_finite() {
                    return Err(self
                        .rig
                        .error("oil.viscosity", "Vogel constants must be finite"));
                }
            }
            ViscosityModel::TwoPoint {
                kv40_cst,
                kv100_cst,
            } => {
                self.positive("oil.viscosity.kv40_cst", kv40_cst, "cSt")?;
                self.positive("oil.viscosity.kv100_cst", kv100_cst, "cSt")?;
                if kv100_cst >= kv40_cst {
                    return Err(self.rig.error("oil.viscosity.kv100_cst", format!("must be below kv40_cst ({kv40_cst} cSt): oil thins as it warms, got {kv100_cst}")));
                }
            }
        }
        Ok(())
    }

    /// The engine's declared top speed, if any: positive, within the general limit.
    fn max_speed(&self) -> Result<(), RigError> {
        match self.rig.file.max_speed_rpm {
            Some(v) => self.size("max_speed_rpm", v, MAX_SPEED_RPM, "rpm"),
            None => Ok(()),
        }
    }

    /// The test cycle: not empty, non-negative target speeds (at most the rig's top speed),
    /// positive durations, at least one hold. Returns the number of holds (plateaus).
    fn cycle(&self) -> Result<usize, RigError> {
        let segments = self.rig.file.cycle.segments();
        if segments.is_empty() {
            return Err(self.rig.error("cycle.segments", "the test cycle is empty; give at least one ramp and one hold, or leave `segments` out for the thesis cycle"));
        }
        let window_s = self.rig.file.measurement.window_s;
        let mut holds = 0;
        let mut speed_rpm = 0.0;
        let mut total_s = 0.0;
        for (i, s) in segments.iter().enumerate() {
            let (d, field) = match s {
                Segment::Ramp { duration_s, to_rpm } => {
                    if !(to_rpm.is_finite() && (0.0..=MAX_SPEED_RPM).contains(to_rpm)) {
                        return Err(self.rig.error(
                            &format!("cycle.segments[{i}].to_rpm"),
                            format!(
                                "must be in [0, {MAX_SPEED_RPM}] rpm, got {}",
                                readable(*to_rpm)
                            ),
                        ));
                    }
                    if let Some(top) = self.rig.file.max_speed_rpm {
                        if *to_rpm > top {
                            return Err(self.rig.error(
                                &format!("cycle.segments[{i}].to_rpm"),
                                format!(
                                    "{} rpm is above the engine's top speed, max_speed_rpm = {} rpm",
                                    readable(*to_rpm),
                                    readable(top)
                                ),
                            ));
                        }
                    }
                    speed_rpm = *to_rpm;
                    (*duration_s, "ramp")
                }
                Segment::Hold { duration_s } => {
                    holds += 1;
                    // The window is checked in `measurement`; a bad one is reported there.
                    let min_rpm = 60.0 / window_s;
                    if window_s.is_finite() && window_s > 0.0 && speed_rpm < min_rpm {
                        return Err(self.rig.error(
                            &format!("cycle.segments[{i}]"),
                            format!(
                                "a hold at {speed_rpm} rpm turns less than one whole revolution in the {window_s} s measurement window (measurement.window_s); a plateau needs at least 60 / window_s = {min_rpm} rpm"
                            ),
                        ));
                    }
                    (*duration_s, "hold")
                }
            };
            if !(d.is_finite() && d > 0.0) {
                return Err(self.rig.error(
                    &format!("cycle.segments[{i}].duration_s"),
                    format!("{field} time must be positive, got {d} s"),
                ));
            }
            total_s += d;
            if total_s > MAX_CYCLE_S {
                return Err(self.rig.error(
                    &format!("cycle.segments[{i}].duration_s"),
                    format!(
                        "the test cycle lasts {total_s} s up to this segment; it must last at most {MAX_CYCLE_S} s"
                    ),
                ));
            }
        }
        if holds == 0 {
            return Err(self.rig.error(
                "cycle.segments",
                "the test cycle has no hold, so nothing would be measured",
            ));
        }
        Ok(holds)
    }

    /// Oil temperatures: one, or one per plateau, each within the viscosity model's range and
    /// giving a physical viscosity.
    fn oil_temperatures(&self, plateaus: usize) -> Result<(), RigError> {
        let oil = &self.rig.file.oil;
        let temps: &[f64] = match &oil.temperature_c {
            Temperature::Constant(t) => std::slice::from_ref(t),
            Temperature::PerPlateau(v) => {
                if v.len() != plateaus {
                    return Err(self.rig.error(
                        "oil.temperature_c",
                        format!(
                            "gives {} temperatures but the cycle has {plateaus} plateaus",
                            v.len()
                        ),
                    ));
                }
                v
            }
        };
        for &t in temps {
            if !(t >= VALID_RANGE_C.0 && t <= VALID_RANGE_C.1) {
                return Err(self.rig.error(
                    "oil.temperature_c",
                    format!(
                        "{t} C is outside the viscosity model's range [{}, {}] C",
                        VALID_RANGE_C.0, VALID_RANGE_C.1
                    ),
                ));
            }
            let nu = oil.viscosity.kinematic_cst(t);
            if !(nu.is_finite() && nu > 0.0 && nu <= MAX_VISCOSITY_CST) {
                return Err(self.rig.error(
                    "oil.viscosity",
                    format!(
                        "gives a non-physical viscosity ({} cSt) at {t} C; an oil's is positive and at most {} cSt",
                        readable(nu),
                        readable(MAX_VISCOSITY_CST)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The PI drive's gains, torque limit, belt ratio and motor inertia (a prescribed drive has
    /// nothing to check).
    fn drive(&self) -> Result<(), RigError> {
        if let Drive::Pi {
            kp,
            ki,
            torque_limit_nm,
            belt_ratio,
            motor_inertia_kg_m2,
        } = self.rig.file.drive
        {
            self.size_or_zero("drive.kp", kp, 1e4, "N m s/rad")?;
            self.size_or_zero("drive.ki", ki, 1e6, "N m/rad")?;
            self.size("drive.torque_limit_nm", torque_limit_nm, 1e5, "N m")?;
            self.size("drive.belt_ratio", belt_ratio, 100.0, "-")?;
            self.size_or_zero(
                "drive.motor_inertia_kg_m2",
                motor_inertia_kg_m2,
                MAX_INERTIA_KG_M2,
                "kg m^2",
            )?;
        }
        Ok(())
    }

    /// The drivetrain's chain (alternating compliant elements and inertias, one transducer,
    /// every value in range); with one, the motor's inertia and the belt belong to it, not to
    /// `[drive]`.
    fn drivetrain(&self) -> Result<(), RigError> {
        let Some(spec) = &self.rig.file.drivetrain else {
            return Ok(());
        };
        // Any positive crank inertia checks the chain's own values; the run uses the crank's.
        spec.chain(1.0).map_err(|e| {
            self.rig
                .error(&format!("drivetrain.{}", e.field), e.message)
        })?;
        if let Drive::Pi {
            belt_ratio,
            motor_inertia_kg_m2,
            ..
        } = self.rig.file.drive
        {
            if belt_ratio != 1.0 || motor_inertia_kg_m2 != 0.0 {
                return Err(self.rig.error(
                    "drive",
                    "with a [drivetrain] the motor's inertia and the belt are elements of the chain: leave drive.belt_ratio and drive.motor_inertia_kg_m2 out",
                ));
            }
        }
        Ok(())
    }

    /// The measurement window and low-pass frequency.
    fn measurement(&self) -> Result<(), RigError> {
        let m = &self.rig.file.measurement;
        self.positive("measurement.window_s", m.window_s, "s")?;
        self.positive("measurement.lowpass_hz", m.lowpass_hz, "Hz")
    }

    /// Step sizes, tolerances and the friction iteration's limit.
    fn solver(&self) -> Result<(), RigError> {
        let s = &self.rig.file.solver;
        self.within(
            "solver.step_deg",
            s.step_deg,
            STEP_DEG_RANGE,
            "degrees",
            "smaller steps take days, larger ones miss a stroke's friction",
        )?;
        self.positive("solver.max_step_s", s.max_step_s, "s")?;
        self.positive("solver.friction_tol", s.friction_tol, "-")?;
        self.positive("solver.rel_tol", s.rel_tol, "-")?;
        if let Some(max_step_deg) = s.max_step_deg {
            self.within(
                "solver.max_step_deg",
                max_step_deg,
                MAX_STEP_DEG_RANGE,
                "degrees",
                "a step must resolve a stroke",
            )?;
        }
        if s.rel_tol > 1e-2 {
            return Err(self.rig.error(
                "solver.rel_tol",
                format!(
                    "must be at most 1e-2 (a relative error per unit time), got {}",
                    s.rel_tol
                ),
            ));
        }
        if s.friction_max_iter == 0 {
            return Err(self
                .rig
                .error("solver.friction_max_iter", "must be at least 1"));
        }
        Ok(())
    }
}
