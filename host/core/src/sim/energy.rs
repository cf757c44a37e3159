//! Energy bookkeeping: the balance of motor work, energy change (the crank model's
//! mechanical energy, `Crank::mechanical_energy`), dissipation and gas work a run reports (its
//! residual checks the integration).

use super::results::EnergyBalance;

impl EnergyBalance {
    /// The balance of `motor_work` (J) against the mechanical energy's `change` and the
    /// energy `dissipated` by the laws: what is left is the integration's residual.
    pub fn from_terms(motor_work: f64, change: f64, dissipated: f64) -> Self {
        Self::from_terms_with_gas(motor_work, change, dissipated, 0.0)
    }

    /// [`EnergyBalance::from_terms`] with the work `gas_work` (J) the mechanism did on the gas
    /// above and below the piston.
    pub fn from_terms_with_gas(
        motor_work: f64,
        change: f64,
        dissipated: f64,
        gas_work: f64,
    ) -> Self {
        let residual = motor_work - change - dissipated - gas_work;
        Self {
            motor_work_j: motor_work,
            mechanical_energy_change_j: change,
            dissipated_j: dissipated,
            gas_work_j: gas_work,
            residual_j: residual,
            relative_residual: 0.0,
        }
        .relative_to(0.0)
    }

    /// The residual relative to the run's energy scale: the largest of the motor work, the
    /// energy change, the dissipation, the gas work and `inertial_j` (the mechanism's
    /// mechanical energy at the run's speeds, so a run without friction, whose other terms are
    /// all near zero, is not judged by a ratio of two roundoff errors). Zero when every term
    /// is zero.
    pub fn relative_to(mut self, inertial_j: f64) -> Self {
        let scale = [
            self.motor_work_j,
            self.mechanical_energy_change_j,
            self.dissipated_j,
            self.gas_work_j,
            inertial_j,
        ]
        .iter()
        .fold(0.0_f64, |a, x| a.max(x.abs()));
        self.relative_residual = if scale > 0.0 {
            self.residual_j.abs() / scale
        } else {
            0.0
        };
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_residual_is_taken_over_the_largest_energy_never_zero_over_zero() {
        // A frictionless steady run: motor work and residual are roundoff, nothing dissipated.
        let e = EnergyBalance::from_terms(1e-16, 0.0, 0.0);
        assert!(e.relative_residual <= 1.0);
        let e = e.relative_to(25.0);
        assert!(e.relative_residual < 1e-17, "{}", e.relative_residual);
        // All zero: zero, not NaN.
        assert_eq!(
            EnergyBalance::from_terms(0.0, 0.0, 0.0).relative_residual,
            0.0
        );
        // With friction the motor work is the scale when it is the largest term.
        let e = EnergyBalance::from_terms(10.0, 2.0, 7.9).relative_to(5.0);
        assert!((e.relative_residual - 0.01).abs() < 1e-12);
        // A transient run whose energy change dwarfs the motor work's other part.
        let e = EnergyBalance::from_terms(100.0, 99.0, 0.5);
        assert!((e.relative_residual - 0.005).abs() < 1e-12);
    }
}
