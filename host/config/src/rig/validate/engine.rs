//! The `[engine]` table: mains, throws, cylinders, rods, firing order.

use super::{Check, MAX_INERTIA_KG_M2, MAX_LENGTH_M, MAX_MASS_KG, SIZE_WHY};
use crate::rig::{readable, CrankcasePressure, EngineSpec, RigError, MAX_CYLINDERS};

impl Check<'_> {
    /// A multi-cylinder engine (`docs/engines.md`): mains in axial order, throws between them
    /// and apart, at most two counterweights per throw, cylinders on existing throws with bank
    /// angles (or a V angle in [0, 180] and a bank each), offsets the rod can reach, exactly one
    /// rod per cylinder, a firing order that is a permutation of the cylinders and fits the
    /// crank, and laws only on the engine's joints.
    pub(super) fn engine(&self) -> Result<(), RigError> {
        let f = &self.rig.file;
        let Some(e) = &f.engine else {
            return Ok(());
        };
        let c = &f.bodies.crank;
        if c.unbalance_mass_kg != 0.0 {
            return Err(self.rig.error(
                "bodies.crank.unbalance_mass_kg",
                "an engine's unbalance is its counterweights, one per web: give them as `counterweights` of each [[engine.throws]] and leave the crank's unbalance at 0",
            ));
        }
        if e.cylinders.is_empty() || e.cylinders.len() > MAX_CYLINDERS {
            return Err(self.rig.error(
                "engine.cylinders",
                format!(
                    "an engine has 1 to {MAX_CYLINDERS} cylinders ([[engine.cylinders]]), got {}",
                    e.cylinders.len()
                ),
            ));
        }
        self.mains(e)?;
        self.throws(e)?;
        self.cylinders(e)?;
        self.rods(e)?;
        self.firing_order(e)?;
        self.shared_crankcase()?;
        let names = e.joint_names();
        if let Some(k) = e.laws.keys().find(|k| !names.contains(k)) {
            return Err(self.rig.error(
                &format!("engine.laws.{k}"),
                format!(
                    "the engine has no joint `{k}`; its joints are {} .. {}",
                    names[0],
                    names[names.len() - 1]
                ),
            ));
        }
        Ok(())
    }

    /// A sealed or vented crankcase on an engine: one volume under every piston, given at
    /// cylinder 1's TDC, whose smallest value over a revolution must stay above 5% of one
    /// cylinder's displacement (the single cylinder's rule, `volume_at_tdc_m3` at least 1.05
    /// displacements, in the form that holds for any crank train).
    fn shared_crankcase(&self) -> Result<(), RigError> {
        let f = &self.rig.file;
        if matches!(f.gas.crankcase, CrankcasePressure::Atmospheric) {
            return Ok(());
        }
        let Some(smallest) =
            tribo_core::gas::GasModel::from_rig(f).and_then(|g| g.crankcase_min_volume_m3())
        else {
            return Ok(());
        };
        let displacement = std::f64::consts::PI
            * 0.25
            * f.geometry.bore_m.powi(2)
            * 2.0
            * f.geometry.crank_radius_m;
        let volume = match &f.gas.crankcase {
            CrankcasePressure::Sealed {
                volume_at_tdc_m3, ..
            }
            | CrankcasePressure::Vented {
                volume_at_tdc_m3, ..
            } => *volume_at_tdc_m3,
            CrankcasePressure::Atmospheric => return Ok(()),
        };
        if smallest < 0.05 * displacement {
            return Err(self.rig.error(
                "gas.crankcase.volume_at_tdc_m3",
                format!(
                    "the engine's pistons share one crankcase, given at cylinder 1's TDC; with {} m^3 there it shrinks to {} m^3 over a revolution, under 5% of one cylinder's displacement ({} m^3): give at least {} m^3",
                    readable(volume),
                    readable(smallest),
                    readable(displacement),
                    readable(volume - smallest + 0.05 * displacement)
                ),
            ));
        }
        Ok(())
    }

    /// The main bearings: at least two, in axial order, each with its journal's size.
    fn mains(&self, e: &EngineSpec) -> Result<(), RigError> {
        let l = MAX_LENGTH_M;
        if e.mains.len() < 2 {
            return Err(self.rig.error(
                "engine.mains",
                format!(
                    "a crank runs in at least two main bearings ([[engine.mains]]), got {}",
                    e.mains.len()
                ),
            ));
        }
        for (i, m) in e.mains.iter().enumerate() {
            let at = |k: &str| format!("engine.mains[{i}].{k}");
            self.within(
                &at("axial_position_m"),
                m.axial_position_m,
                (-l, l),
                "m",
                SIZE_WHY,
            )?;
            self.size(&at("radius_m"), m.radius_m, l, "m")?;
            self.size(&at("length_m"), m.length_m, l, "m")?;
            if i > 0 && m.axial_position_m <= e.mains[i - 1].axial_position_m {
                return Err(self.rig.error(
                    &at("axial_position_m"),
                    format!(
                        "main bearings are listed in axial order: main_{} at {} m must lie beyond main_{i} at {} m",
                        i + 1,
                        m.axial_position_m,
                        e.mains[i - 1].axial_position_m
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The throws: between the outer mains and apart, at most two counterweights each.
    fn throws(&self, e: &EngineSpec) -> Result<(), RigError> {
        let l = MAX_LENGTH_M;
        if e.throws.is_empty() {
            return Err(self.rig.error(
                "engine.throws",
                "the crank needs at least one throw ([[engine.throws]])",
            ));
        }
        let (first, last) = (
            e.mains[0].axial_position_m,
            e.mains[e.mains.len() - 1].axial_position_m,
        );
        for (j, t) in e.throws.iter().enumerate() {
            let at = |k: &str| format!("engine.throws[{j}].{k}");
            self.within(
                &at("angle_deg"),
                t.angle_deg,
                (-720.0, 720.0),
                "degrees",
                "a pin angle",
            )?;
            let z = t.axial_position_m;
            if !(z.is_finite() && z > first && z < last) {
                return Err(self.rig.error(
                    &at("axial_position_m"),
                    format!(
                        "a throw lies between two main bearings, strictly inside ({first}, {last}) m, got {}",
                        readable(z)
                    ),
                ));
            }
            if let Some(i) = e.throws[..j].iter().position(|o| o.axial_position_m == z) {
                return Err(self.rig.error(
                    &at("axial_position_m"),
                    format!(
                        "throw {} is at {z} m like throw {}: a throw listed twice? Rods sharing a pin (a V engine) name the same throw in [[engine.cylinders]]",
                        j + 1,
                        i + 1
                    ),
                ));
            }
            if t.counterweights.len() > 2 {
                return Err(self.rig.error(
                    &at("counterweights"),
                    format!(
                        "a throw has two webs, so at most two counterweights, got {}",
                        t.counterweights.len()
                    ),
                ));
            }
            for (w, cw) in t.counterweights.iter().enumerate() {
                let at = |k: &str| format!("engine.throws[{j}].counterweights[{w}].{k}");
                self.size_or_zero(&at("mass_kg"), cw.mass_kg, MAX_MASS_KG, "kg")?;
                self.size_or_zero(&at("radius_m"), cw.radius_m, l, "m")?;
                self.within(
                    &at("angle_deg"),
                    cw.angle_deg,
                    (-360.0, 360.0),
                    "degrees",
                    "an angle from the pin",
                )?;
            }
        }
        if let Some(v) = e.v_angle_deg {
            if !(v.is_finite() && (0.0..=180.0).contains(&v)) {
                return Err(self.rig.error(
                    "engine.v_angle_deg",
                    format!(
                        "the V angle is the angle between the two banks, in [0, 180] degrees (0: inline, 180: a boxer or 180-degree V), got {}",
                        readable(v)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The cylinders: on existing throws, bank angles (or a V angle and a bank each), offsets.
    fn cylinders(&self, e: &EngineSpec) -> Result<(), RigError> {
        let l = MAX_LENGTH_M;
        for (k, cyl) in e.cylinders.iter().enumerate() {
            let at = |f: &str| format!("engine.cylinders[{k}].{f}");
            if !(1..=e.throws.len()).contains(&cyl.throw) {
                return Err(self.rig.error(
                    &at("throw"),
                    format!(
                        "cylinder {} runs on throw {}, but the crank has throws 1 to {}",
                        k + 1,
                        cyl.throw,
                        e.throws.len()
                    ),
                ));
            }
            match (e.v_angle_deg, cyl.bank, cyl.bank_deg) {
                (Some(_), None, _) => {
                    return Err(self.rig.error(
                        &at("throw"),
                        format!("cylinder {}: a V engine (engine.v_angle_deg) names each cylinder's `bank`, \"left\" or \"right\"", k + 1),
                    ))
                }
                (Some(_), Some(_), Some(_)) => {
                    return Err(self.rig.error(
                        &at("bank_deg"),
                        "give either `bank` (with engine.v_angle_deg) or `bank_deg`, not both",
                    ))
                }
                (None, Some(_), _) => {
                    return Err(self.rig.error(
                        &at("bank"),
                        "`bank` (left or right) needs the engine's V angle, engine.v_angle_deg; or give the cylinder's `bank_deg`",
                    ))
                }
                (None, None, Some(b)) => self.within(
                    &at("bank_deg"),
                    b,
                    (-180.0, 180.0),
                    "degrees",
                    "the cylinder axis from the vertical; two banks are at most 180 degrees apart, a V angle in [0, 180]",
                )?,
                _ => {}
            }
            self.within(
                &at("pin_offset_m"),
                cyl.pin_offset_m,
                (-l, l),
                "m",
                SIZE_WHY,
            )?;
            self.within(
                &at("crank_offset_m"),
                cyl.crank_offset_m,
                (-l, l),
                "m",
                SIZE_WHY,
            )?;
        }
        Ok(())
    }

    /// The rods: exactly one per cylinder, each longer than its cylinder's reach.
    fn rods(&self, e: &EngineSpec) -> Result<(), RigError> {
        let (f, l) = (&self.rig.file, MAX_LENGTH_M);
        let r = f.geometry.crank_radius_m;
        let mut rod_of: Vec<Option<usize>> = vec![None; e.cylinders.len()];
        for (i, rod) in e.rods.iter().enumerate() {
            let at = |f: &str| format!("engine.rods[{i}].{f}");
            if !(1..=e.cylinders.len()).contains(&rod.cylinder) {
                return Err(self.rig.error(
                    &at("cylinder"),
                    format!(
                        "rod {} names cylinder {}, but the engine has cylinders 1 to {}",
                        i + 1,
                        rod.cylinder,
                        e.cylinders.len()
                    ),
                ));
            }
            if let Some(other) = rod_of[rod.cylinder - 1].replace(i) {
                return Err(self.rig.error(
                    &at("cylinder"),
                    format!(
                        "cylinder {} has two rods, engine.rods[{other}] and engine.rods[{i}]: one rod per cylinder (rods sharing a pin belong to different cylinders on one throw)",
                        rod.cylinder
                    ),
                ));
            }
            let base = &f.bodies.rod;
            if let Some(m) = rod.mass_kg {
                self.size(&at("mass_kg"), m, MAX_MASS_KG, "kg")?;
            }
            if let Some(j) = rod.inertia_kg_m2 {
                self.size(&at("inertia_kg_m2"), j, MAX_INERTIA_KG_M2, "kg m^2")?;
            }
            if let Some(len) = rod.length_m {
                self.size(&at("length_m"), len, l, "m")?;
            }
            let len = rod.length_m.unwrap_or(base.length_m);
            let com = rod.com_from_big_end_m.unwrap_or(base.com_from_big_end_m);
            if !(com.is_finite() && (0.0..=len).contains(&com)) {
                return Err(self.rig.error(
                    &at("com_from_big_end_m"),
                    format!("must lie between the pin centres, [0, {len}] m, got {com}"),
                ));
            }
            let cyl = &e.cylinders[rod.cylinder - 1];
            let reach = r + (cyl.pin_offset_m + cyl.crank_offset_m).abs();
            if len <= reach {
                return Err(self.rig.error(
                    &at("length_m"),
                    format!(
                        "the rod ({len} m) must be longer than the crank radius plus the cylinder's offsets ({reach} m), or the mechanism locks"
                    ),
                ));
            }
        }
        if let Some(k) = rod_of.iter().position(Option::is_none) {
            return Err(self.rig.error(
                &format!("engine.cylinders[{k}]"),
                format!(
                    "cylinder {} has no rod: add [[engine.rods]] with cylinder = {} (its mass, inertia and length default to [bodies.rod])",
                    k + 1,
                    k + 1
                ),
            ));
        }
        Ok(())
    }

    /// The firing order: a permutation of the cylinders that fits the crank; then the core's
    /// own checks of the crank train as a backstop.
    fn firing_order(&self, e: &EngineSpec) -> Result<(), RigError> {
        let f = &self.rig.file;
        // The firing order: a permutation that fits the crank.
        let geo =
            tribo_core::engine::geometry(f).ok_or_else(|| self.rig.error("engine", "no engine"))?;
        let phase0 = f.gas.cycle_angle_at_zero_deg.to_radians();
        tribo_core::engine::cylinder_phases(
            &tribo_core::engine::top_dead_centres(&geo),
            &e.firing_order,
            phase0,
        )
        .map_err(|err| self.rig.error("engine.firing_order", err.to_string()))?;
        // The core's own checks (the same as above): a backstop, named at the engine table.
        tribo_core::engine::CrankTrain::new(geo)
            .map_err(|err| self.rig.error("engine", err.to_string()))?;
        Ok(())
    }
}
