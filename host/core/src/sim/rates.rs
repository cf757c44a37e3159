//! Where each accumulated quantity sits in an evaluation's rate vector, and which of them the
//! adaptive step controls.

/// How much looser than `solver.rel_tol` the error-controlled step holds the integrated normal
/// loads: they are reported as means (to four significant figures), not fed back into the
/// motion, and at 100 the mean loads still agree with fine fixed-step RK4 to about 1e-4.
const NORMALS_TOL_FACTOR: f64 = 100.0;

/// Where each accumulated quantity sits in an evaluation's rate vector, for `n` laws: the motor
/// power, then each law's dissipated power and its normal load, and last the power the
/// mechanism puts into the gas (zero without gas loads). The laws' regimes are not rates: an
/// evaluation carries each law's regime as a code ([`RegimeTimes`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct RateLayout {
    pub(super) n: usize,
}

impl RateLayout {
    /// The motor power.
    pub(super) const MOTOR: usize = 0;
    /// Length of the rate vector.
    pub(super) fn len(self) -> usize {
        2 + 2 * self.n
    }
    /// The power into the gas (minus the gas force's power on the piston).
    pub(super) fn gas(self) -> usize {
        1 + 2 * self.n
    }
    /// Every law's dissipated power.
    pub(super) fn powers(self) -> std::ops::Range<usize> {
        1..1 + self.n
    }
    /// Every law's normal load.
    pub(super) fn normals(self) -> std::ops::Range<usize> {
        1 + self.n..1 + 2 * self.n
    }
    /// Law `k`'s dissipated power.
    pub(super) fn power(self, k: usize) -> usize {
        1 + k
    }
    /// Law `k`'s normal load.
    pub(super) fn normal(self, k: usize) -> usize {
        1 + self.n + k
    }
    /// The error-controlled groups with their tolerance factors: the motor and law powers at
    /// `rel_tol`; the normal loads, only reported as means and never fed back, at
    /// `NORMALS_TOL_FACTOR` times it (a magnitude's valleys near zero need no steps the powers
    /// do not).
    pub(super) fn controlled(self) -> [(std::ops::Range<usize>, f64); 2] {
        [
            (Self::MOTOR..self.powers().end, 1.0),
            (self.normals(), NORMALS_TOL_FACTOR),
        ]
    }
}

/// The time each of `n` laws spends in each lubrication regime (`Regime` as index), s, kept
/// apart from the rates: a law is in one regime at an evaluation, so its indicators are a code
/// per law (`Eval::regimes`), and a step adds its quadrature weights only to the regimes its
/// stages were in, where the rate vector carried four indicators per law through every
/// stage's vector operations. The weights and their order are the quadrature's, so the times
/// are those of integrating the 0/1 indicators as rates, to the bit.
#[derive(Debug, Clone, Copy)]
pub(super) struct RegimeTimes {
    pub(super) n: usize,
}

impl RegimeTimes {
    /// Regimes per law (none, boundary, mixed, hydrodynamic).
    pub(super) const REGIMES: usize = 4;

    /// Length of a vector of regime times.
    pub(super) fn len(self) -> usize {
        Self::REGIMES * self.n
    }

    /// Law `k`'s time in `regime` (a `Regime` as index).
    pub(super) fn slot(k: usize, regime: usize) -> usize {
        Self::REGIMES * k + regime
    }

    /// Add `weight` (s) to each law's time in its regime `codes[k]`: one stage's term of a
    /// quadrature whose weights are summed stage by stage (the error-controlled step).
    pub(super) fn add(times: &mut [f64], codes: &[u8], weight: f64) {
        for (k, &c) in codes.iter().enumerate() {
            times[Self::slot(k, c as usize)] += weight;
        }
    }

    /// Add `scale * (c_0 r_0 + c_1 r_1 + ...)` to each law's times, `r_j` the 0/1 indicator of
    /// stage `j` (regime codes `stages[j]`) and `c_j` its small whole coefficient: Simpson's
    /// `h/6 (1, 4, 1)` and RK4's `h/6 (1, 2, 2, 1)`. The coefficients of a regime sum exactly,
    /// so each time is the rule applied to the indicators, bit for bit; a regime no stage was
    /// in would add `scale * 0`, nothing.
    pub(super) fn add_rule<const S: usize>(
        times: &mut [f64],
        stages: [&[u8]; S],
        coefficients: [f64; S],
        scale: f64,
    ) {
        let Some(first) = stages.first() else {
            return;
        };
        let total: f64 = coefficients.iter().sum();
        for (k, &regime) in first.iter().enumerate() {
            // Mostly every stage is in one regime.
            if stages.iter().all(|codes| codes[k] == regime) {
                times[Self::slot(k, regime as usize)] += scale * total;
                continue;
            }
            let mut sums = [0.0; Self::REGIMES];
            for (codes, c) in stages.iter().zip(coefficients) {
                sums[codes[k] as usize] += c;
            }
            for (r, sum) in sums.iter().enumerate() {
                if *sum != 0.0 {
                    times[Self::slot(k, r)] += scale * sum;
                }
            }
        }
    }
}
