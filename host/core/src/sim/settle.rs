//! A PI hold's settling extrapolated to its end. Once the crank is near the hold's periodic
//! orbit, each cycle's change of the cycle-end state is the change before it times the cycle
//! map's multipliers, as in a linear periodic system: the changes obey a recurrence of order
//! one (a real multiplier) or two (a complex pair, the PI loop's oscillation). Fitted to the
//! last few cycles, the recurrence sums the changes still to come, which gives the limit of
//! every cycle quantity and what the rest of the settling adds to each total. This is minimal
//! polynomial extrapolation to the periodic steady state (K. Skelboe, "Computation of the
//! periodic steady-state response of nonlinear networks by extrapolation methods", IEEE Trans.
//! Circuits and Systems 27(3), 1980), with the recurrence's order kept to the loop's two
//! states.

/// Cycles a fit looks at: four changes, so a two-multiplier recurrence is fitted over two
/// shifts and checked against the data it did not need.
pub(super) const CYCLES: usize = 5;

/// A recurrence is trusted only when it reproduces the changes it was fitted to within this,
/// relative to their size: the settling is linear to that much.
const FIT_TOL: f64 = 1e-3;

/// The largest multiplier trusted. The sum of the changes to come grows as 1 / (1 - |λ|),
/// and so does the fit's error in it; a loop settling slower than this gains little anyway.
const MAX_MULTIPLIER: f64 = 0.98;

/// The recurrence `d[j+m] + a[m-1] d[j+m-1] + ... + a[0] d[j] = 0` obeyed by a settling
/// sequence's changes, `a[m] = 1`, of order `m` (1 or 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Recurrence {
    a: [f64; 3],
    m: usize,
}

impl Recurrence {
    /// Its order: how many consecutive terms of a sequence [`Recurrence::sum`] needs.
    pub(super) fn order(&self) -> usize {
        self.m
    }

    /// The recurrence of the changes `d(j, c)`, `j < CYCLES - 1`, fitted on components
    /// `c < n` (each scaled by its largest change): a complex or real pair of multipliers
    /// when the data determine two, one real multiplier otherwise. `None` when neither
    /// reproduces the changes within [`FIT_TOL`] or a multiplier is not inside
    /// [`MAX_MULTIPLIER`]: the cycles are not yet settling linearly, or not settling.
    pub(super) fn fit(d: impl Fn(usize, usize) -> f64, n: usize) -> Option<Self> {
        let scale: Vec<f64> = (0..n)
            .map(|c| (0..CYCLES - 1).fold(0.0_f64, |m, j| m.max(d(j, c).abs())))
            .collect();
        let x = |j: usize, c: usize| match scale[c] {
            s if s > 0.0 => d(j, c) / s,
            _ => 0.0,
        };
        let rec = Self::pair(&x, n).or_else(|| Self::single(&x, n))?;
        (rec.residual(&x, 0..n) <= FIT_TOL && rec.largest_multiplier() <= MAX_MULTIPLIER)
            .then_some(rec)
    }

    /// The order-two fit by least squares over the shifts `j = 0, 1`; `None` when the two
    /// columns are nearly parallel (one multiplier: the order-one fit).
    fn pair(x: &impl Fn(usize, usize) -> f64, n: usize) -> Option<Self> {
        let (mut m00, mut m01, mut m11, mut r0, mut r1) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for j in 0..CYCLES - 3 {
            for c in 0..n {
                let (u, v, b) = (x(j, c), x(j + 1, c), -x(j + 2, c));
                m00 += u * u;
                m01 += u * v;
                m11 += v * v;
                r0 += u * b;
                r1 += v * b;
            }
        }
        let det = m00 * m11 - m01 * m01;
        // (A NaN change fails this too.)
        if det.partial_cmp(&(1e-10 * m00 * m11)) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let a0 = (r0 * m11 - r1 * m01) / det;
        let a1 = (m00 * r1 - m01 * r0) / det;
        Some(Self {
            a: [a0, a1, 1.0],
            m: 2,
        })
    }

    /// The order-one fit `d[j+1] = λ d[j]` by least squares over every shift.
    fn single(x: &impl Fn(usize, usize) -> f64, n: usize) -> Option<Self> {
        let (mut uu, mut uv) = (0.0, 0.0);
        for j in 0..CYCLES - 2 {
            for c in 0..n {
                uu += x(j, c) * x(j, c);
                uv += x(j, c) * x(j + 1, c);
            }
        }
        (uu > 0.0).then(|| Self {
            a: [-uv / uu, 1.0, 0.0],
            m: 1,
        })
    }

    /// How far the changes `d(j, c)` of one more component miss the recurrence, relative to
    /// their size: the relative error of what [`Recurrence::sum`] makes of that component.
    pub(super) fn misses(&self, d: impl Fn(usize, usize) -> f64, c: usize) -> f64 {
        self.residual(&d, c..c + 1)
    }

    /// How far the recurrence misses the changes of components `cs`, relative to their size.
    fn residual(&self, x: &impl Fn(usize, usize) -> f64, cs: std::ops::Range<usize>) -> f64 {
        let (mut miss, mut size) = (0.0, 0.0);
        for j in 0..CYCLES - 1 - self.m {
            for c in cs.clone() {
                let r: f64 = (0..=self.m).map(|i| self.a[i] * x(j + i, c)).sum();
                miss += r * r;
                size += x(j + self.m, c) * x(j + self.m, c);
            }
        }
        match size {
            s if s > 0.0 => (miss / s).sqrt(),
            _ => f64::INFINITY,
        }
    }

    /// The largest multiplier's magnitude: the largest root of the characteristic polynomial.
    fn largest_multiplier(&self) -> f64 {
        match self.m {
            1 => self.a[0].abs(),
            _ => {
                let (a0, a1) = (self.a[0], self.a[1]);
                let disc = a1 * a1 - 4.0 * a0;
                if disc < 0.0 {
                    a0.sqrt()
                } else {
                    (a1.abs() + disc.sqrt()) / 2.0
                }
            }
        }
    }

    /// The term `k` places after the last of `last` (a sequence's latest terms, oldest first,
    /// at least `order()` of them) of a sequence obeying the recurrence.
    pub(super) fn ahead(&self, last: &[f64], k: usize) -> f64 {
        let m = self.m;
        let mut w = [0.0; 2];
        w[..m].copy_from_slice(&last[last.len() - m..]);
        for _ in 0..k {
            let next = -(0..m).map(|i| self.a[i] * w[i]).sum::<f64>();
            w.copy_within(1..m, 0);
            w[m - 1] = next;
        }
        w[m - 1]
    }

    /// The sum of every term of a sequence obeying the recurrence, from the first `m` terms
    /// `e(0), ..., e(m - 1)`: summing the recurrence over the sequence gives
    /// `sum(a) S = sum over i of a[i] (e(0) + ... + e(i - 1))`.
    pub(super) fn sum(&self, e: impl Fn(usize) -> f64) -> f64 {
        let mut partial = 0.0;
        let mut weighted = 0.0;
        for i in 1..=self.m {
            partial += e(i - 1);
            weighted += self.a[i] * partial;
        }
        let total: f64 = self.a[..=self.m].iter().sum();
        weighted / total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The limits of the test sequence's three components: an angle turned, a speed, an integral.
    const LIMITS: [f64; 3] = [std::f64::consts::TAU, 320.0, 0.13];

    /// A damped oscillation `x*  + A r^j cos(j w + p)` in each component, with the
    /// components' phases apart, as the PI loop's two states settle.
    fn settling(j: usize, c: usize) -> f64 {
        let (r, w) = (0.8_f64, 0.4_f64);
        let limit = LIMITS[c];
        let amp = [1e-2, 0.5, 0.05][c];
        limit + amp * r.powi(j as i32) * (j as f64 * w + c as f64).cos()
    }

    #[test]
    fn a_damped_oscillation_is_summed_to_its_limit() {
        let d = |j: usize, c: usize| settling(j + 1, c) - settling(j, c);
        let rec = Recurrence::fit(d, 3).expect("a linear settling is fitted");
        assert_eq!(rec.order(), 2);
        // The closed form: r e^{±iw} are the multipliers, a0 = r^2, a1 = -2 r cos w.
        assert!((rec.a[0] - 0.64).abs() < 1e-12, "{:?}", rec);
        assert!((rec.a[1] + 1.6 * 0.4_f64.cos()).abs() < 1e-12, "{:?}", rec);
        for (c, exact) in LIMITS.into_iter().enumerate() {
            // From the last two changes: the limit of the sequence.
            let from = CYCLES - 3;
            let limit = settling(from, c) + rec.sum(|l| d(from + l, c));
            assert!(
                (limit - exact).abs() < 1e-12 * exact,
                "{c}: {limit} vs {exact}"
            );
            // And its deviation 20 cycles after the last one kept, as the closed form has it.
            let last = [
                settling(CYCLES - 2, c) - exact,
                settling(CYCLES - 1, c) - exact,
            ];
            let later = settling(CYCLES - 1 + 20, c) - exact;
            assert!((rec.ahead(&last, 20) - later).abs() < 1e-12 * exact, "{c}");
        }
    }

    #[test]
    fn one_real_multiplier_is_fitted_as_such() {
        let x = |j: usize, c: usize| [1.0, 2.0][c] + [0.3, -0.1][c] * 0.5_f64.powi(j as i32);
        let d = |j: usize, c: usize| x(j + 1, c) - x(j, c);
        let rec = Recurrence::fit(d, 2).expect("a geometric settling is fitted");
        assert_eq!(rec.order(), 1);
        let limit = x(3, 0) + rec.sum(|_| d(3, 0));
        assert!((limit - 1.0).abs() < 1e-14);
        // The series of the deviations themselves: 0.3 (1 + 1/2 + ...) = 0.6.
        assert!((rec.sum(|_| x(0, 0) - 1.0) - 0.6).abs() < 1e-14);
    }

    #[test]
    fn changes_no_recurrence_reproduces_are_refused() {
        // Halving changes, then a kink (the drive reaching its torque limit): not a linear
        // settling.
        let x = |j: usize, c: usize| [0.0, 1.0, 1.5, 1.75, 4.75, 9.0][j] * (c as f64 + 1.0);
        let d = |j: usize, c: usize| x(j + 1, c) - x(j, c);
        assert_eq!(Recurrence::fit(d, 2), None);
        // Nor is a growing one.
        let g = |j: usize, _c: usize| 1.2_f64.powi(j as i32);
        assert_eq!(Recurrence::fit(g, 1), None);
    }
}
