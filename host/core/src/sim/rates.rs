//! Where each accumulated quantity sits in an evaluation's rate vector, and which of them the
//! adaptive step controls.

/// How much looser than `solver.rel_tol` the error-controlled step holds the integrated normal
/// loads: they are reported as means (to four significant figures), not fed back into the
/// motion, and at 100 the mean loads still agree with fine fixed-step RK4 to about 1e-4.
const NORMALS_TOL_FACTOR: f64 = 100.0;

/// Where each accumulated quantity sits in an evaluation's rate vector, for `n` laws: the motor
/// power, then each law's dissipated power, its four regime indicators and its normal load,
/// and last the power the mechanism puts into the gas (zero without gas loads).
#[derive(Debug, Clone, Copy)]
pub(super) struct RateLayout {
    pub(super) n: usize,
}

impl RateLayout {
    /// The motor power.
    pub(super) const MOTOR: usize = 0;
    /// Length of the rate vector.
    pub(super) fn len(self) -> usize {
        2 + 6 * self.n
    }
    /// The power into the gas (minus the gas force's power on the piston).
    pub(super) fn gas(self) -> usize {
        1 + 6 * self.n
    }
    /// Every law's dissipated power.
    pub(super) fn powers(self) -> std::ops::Range<usize> {
        1..1 + self.n
    }
    /// Every law's regime indicators.
    pub(super) fn regimes(self) -> std::ops::Range<usize> {
        1 + self.n..1 + 5 * self.n
    }
    /// Every law's normal load.
    pub(super) fn normals(self) -> std::ops::Range<usize> {
        1 + 5 * self.n..1 + 6 * self.n
    }
    /// Law `k`'s dissipated power.
    pub(super) fn power(self, k: usize) -> usize {
        1 + k
    }
    /// Law `k`'s indicator of `regime` (a `Regime` as index).
    pub(super) fn regime(self, k: usize, regime: usize) -> usize {
        1 + self.n + 4 * k + regime
    }
    /// Law `k`'s normal load.
    pub(super) fn normal(self, k: usize) -> usize {
        1 + 5 * self.n + k
    }
    /// The error-controlled groups with their tolerance factors: the motor and law powers at
    /// `rel_tol`; the normal loads, only reported as means and never fed back, at
    /// `NORMALS_TOL_FACTOR` times it (a magnitude's valleys near zero need no steps the powers
    /// do not). Regime times are not controlled: their indicators jump by nature.
    pub(super) fn controlled(self) -> [(std::ops::Range<usize>, f64); 2] {
        [
            (Self::MOTOR..self.powers().end, 1.0),
            (self.normals(), NORMALS_TOL_FACTOR),
        ]
    }
}
