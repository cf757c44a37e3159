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
            relative_residual: if motor_work.abs() > 0.0 {
                residual.abs() / motor_work.abs()
            } else {
                residual.abs()
            },
        }
    }
}
