//! The `[gas]` table: cylinder and crankcase pressures.

use super::{Check, MAX_LENGTH_M, MAX_PRESSURE_PA};
use crate::rig::{readable, CrankcasePressure, CylinderPressure, RigError};

impl Check<'_> {
    /// The gas pressures: ambient, the 4-stroke phase 0 or 360 degrees (the rig's angle 0 is a
    /// top dead centre), no 4-stroke pressure on a two-stroke engine, then the cylinder's and
    /// the crankcase's.
    pub(super) fn gas(&self) -> Result<(), RigError> {
        let f = &self.rig.file;
        let g = &f.gas;
        self.size("gas.ambient_pa", g.ambient_pa, MAX_PRESSURE_PA, "Pa")?;
        if g.cycle_angle_at_zero_deg != 0.0 && g.cycle_angle_at_zero_deg != 360.0 {
            return Err(self.rig.error(
                "gas.cycle_angle_at_zero_deg",
                format!(
                    "must be 0 (crank angle 0 is the gas-exchange TDC) or 360 (the firing TDC), got {}",
                    readable(g.cycle_angle_at_zero_deg)
                ),
            ));
        }
        if f.geometry.engine_cycle == tribo_core::model::EngineCycle::TwoStroke && g.four_stroke() {
            return Err(self.rig.error(
                "geometry.engine_cycle",
                "a two-stroke engine cannot have a 4-stroke cylinder pressure (four-stroke valves or a 720-degree trace in [gas.cylinder])",
            ));
        }
        let displacement = std::f64::consts::PI
            * 0.25
            * f.geometry.bore_m.powi(2)
            * 2.0
            * f.geometry.crank_radius_m;
        self.cylinder()?;
        self.crankcase(displacement)
    }

    /// The cylinder pressure: a motored cylinder's ratio, exponent and intake pressure, or a
    /// trace's table.
    fn cylinder(&self) -> Result<(), RigError> {
        match &self.rig.file.gas.cylinder {
            CylinderPressure::None => {}
            CylinderPressure::Motored {
                compression_ratio,
                polytropic_exponent,
                intake_pressure_pa,
                ..
            } => {
                self.within(
                    "gas.cylinder.compression_ratio",
                    *compression_ratio,
                    (1.01, 40.0),
                    "",
                    "a geometric compression ratio of a piston engine",
                )?;
                self.within(
                    "gas.cylinder.polytropic_exponent",
                    *polytropic_exponent,
                    (1.0, 1.67),
                    "",
                    "isothermal to monatomic adiabatic",
                )?;
                self.size(
                    "gas.cylinder.intake_pressure_pa",
                    *intake_pressure_pa,
                    MAX_PRESSURE_PA,
                    "Pa",
                )?;
            }
            CylinderPressure::Trace {
                crank_angle_deg,
                pressure_pa,
                ..
            } => self.trace(crank_angle_deg, pressure_pa)?,
        }
        Ok(())
    }

    /// A pressure trace: two equal-length columns, angles rising within [0, 720), pressures
    /// positive.
    fn trace(&self, crank_angle_deg: &[f64], pressure_pa: &[f64]) -> Result<(), RigError> {
        let field = if self.rig.file.gas.cylinder_file().is_some() {
            "gas.cylinder.file"
        } else {
            "gas.cylinder.crank_angle_deg"
        };
        if crank_angle_deg.len() < 2 || crank_angle_deg.len() != pressure_pa.len() {
            return Err(self.rig.error(field, format!("a trace needs at least two points and as many pressures as angles, got {} angles and {} pressures", crank_angle_deg.len(), pressure_pa.len())));
        }
        for (i, w) in crank_angle_deg.windows(2).enumerate() {
            if w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater) {
                return Err(self.rig.error(
                    field,
                    format!(
                        "crank angles must rise: point {} ({}) is not above point {} ({})",
                        i + 2,
                        readable(w[1]),
                        i + 1,
                        readable(w[0])
                    ),
                ));
            }
        }
        let (lo, hi) = (
            crank_angle_deg[0],
            crank_angle_deg[crank_angle_deg.len() - 1],
        );
        if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && hi < 720.0) {
            return Err(self.rig.error(field, format!("crank angles must lie in [0, 720) degrees of the 4-stroke cycle (0: gas-exchange TDC), got {} to {}", readable(lo), readable(hi))));
        }
        for (i, p) in pressure_pa.iter().enumerate() {
            if !(p.is_finite() && *p > 0.0 && *p <= MAX_PRESSURE_PA) {
                return Err(self.rig.error(
                    field,
                    format!(
                        "pressure at point {} must be an absolute pressure in (0, {}] Pa, got {}",
                        i + 1,
                        readable(MAX_PRESSURE_PA),
                        readable(*p)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// A sealed or vented crankcase: volume (above the displacement `displacement`, m^3),
    /// exponent, and a vented one's breather, discharge coefficient and gas temperature.
    fn crankcase(&self, displacement: f64) -> Result<(), RigError> {
        match &self.rig.file.gas.crankcase {
            CrankcasePressure::Atmospheric => {}
            CrankcasePressure::Sealed {
                volume_at_tdc_m3,
                polytropic_exponent,
                pressure_at_tdc_pa,
            } => {
                self.crankcase_volume(*volume_at_tdc_m3, *polytropic_exponent, displacement)?;
                self.size(
                    "gas.crankcase.pressure_at_tdc_pa",
                    *pressure_at_tdc_pa,
                    MAX_PRESSURE_PA,
                    "Pa",
                )?;
            }
            CrankcasePressure::Vented {
                volume_at_tdc_m3,
                polytropic_exponent,
                breather_diameter_m,
                breather_area_m2,
                discharge_coefficient,
                temperature_c,
            } => {
                self.crankcase_volume(*volume_at_tdc_m3, *polytropic_exponent, displacement)?;
                self.breather(*breather_diameter_m, *breather_area_m2)?;
                let cd = *discharge_coefficient;
                if !(cd.is_finite() && cd > 0.0 && cd <= 1.0) {
                    return Err(self.rig.error(
                        "gas.crankcase.discharge_coefficient",
                        format!(
                            "must be in (0, 1] (the breather's real flow over that of an ideal nozzle of its area; about 0.6 for a sharp-edged orifice), got {}",
                            readable(cd)
                        ),
                    ));
                }
                self.within(
                    "gas.crankcase.temperature_c",
                    *temperature_c,
                    (-50.0, 300.0),
                    "C",
                    "a crankcase gas temperature",
                )?;
            }
        }
        Ok(())
    }

    /// A vented crankcase's breather: a diameter or an area, one of the two, positive.
    fn breather(&self, diameter_m: Option<f64>, area_m2: Option<f64>) -> Result<(), RigError> {
        match (diameter_m, area_m2) {
            (Some(_), Some(_)) => Err(self.rig.error(
                "gas.crankcase.breather_area_m2",
                "give the breather's diameter (`breather_diameter_m`) or its area (`breather_area_m2`), not both",
            )),
            (None, None) => Err(self.rig.error(
                "gas.crankcase",
                "a vented crankcase needs its breather: `breather_diameter_m` (m) or `breather_area_m2` (m^2)",
            )),
            (Some(d), None) => self.size("gas.crankcase.breather_diameter_m", d, MAX_LENGTH_M, "m"),
            (None, Some(a)) => self.size(
                "gas.crankcase.breather_area_m2",
                a,
                MAX_LENGTH_M * MAX_LENGTH_M,
                "m^2",
            ),
        }
    }

    /// A closed crankcase's volume at TDC (5% above the displacement, at most 1 m^3) and its
    /// polytropic exponent.
    fn crankcase_volume(
        &self,
        volume: f64,
        exponent: f64,
        displacement: f64,
    ) -> Result<(), RigError> {
        self.size("gas.crankcase.volume_at_tdc_m3", volume, 1.0, "m^3")?;
        if volume <= 1.05 * displacement {
            return Err(self.rig.error(
                "gas.crankcase.volume_at_tdc_m3",
                format!(
                    "must exceed the displacement ({} m^3) by at least 5%, or the piston squeezes the crankcase to nothing, got {}",
                    readable(displacement),
                    readable(volume)
                ),
            ));
        }
        self.within(
            "gas.crankcase.polytropic_exponent",
            exponent,
            (1.0, 1.67),
            "",
            "isothermal to monatomic adiabatic",
        )
    }
}
