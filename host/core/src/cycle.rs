//! The test cycle: the reference crank speed as ramps and holds, and the plateaus measured.
//!
//! The reference motion is exact (piecewise quadratic crank angle), so a ramp's angle, speed and
//! acceleration follow from kinematics alone:
//!
//! ```
//! use tribo_core::cycle::{rpm_to_rad_s, thesis_cycle, Cycle, Segment};
//!
//! let cycle = Cycle::new(&[
//!     Segment::Ramp { to_rpm: 3000.0, duration_s: 1.0 },
//!     Segment::Hold { duration_s: 2.0 },
//! ]);
//! assert_eq!(cycle.duration(), 3.0);
//! let p = cycle.plateaus()[0];
//! assert_eq!((p.t_start, p.t_end), (1.0, 3.0));
//! // Half-way up the ramp: half the speed, the ramp's acceleration, a quarter of the angle.
//! let w = rpm_to_rad_s(3000.0);
//! let (theta, omega, alpha) = cycle.reference(0.5);
//! assert!((omega - 0.5 * w).abs() < 1e-12 && (alpha - w).abs() < 1e-12);
//! assert!((theta - 0.125 * w).abs() < 1e-12);
//! // The thesis's cycle: seven plateaus, 11.5 s.
//! let thesis = Cycle::new(&thesis_cycle());
//! assert_eq!(thesis.plateaus().len(), 7);
//! assert!((thesis.duration() - 11.5).abs() < 1e-12);
//! ```

use tribo_plugin_api::serde::{Deserialize, Serialize};

/// One piece of a test cycle, as written in a rig file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Segment {
    /// Linear change of the reference speed to `to_rpm` over `duration_s`.
    Ramp {
        /// Speed at the end of the ramp, rpm.
        to_rpm: f64,
        /// Duration, s.
        duration_s: f64,
    },
    /// Constant reference speed for `duration_s`; every hold is a measured plateau.
    Hold {
        /// Duration, s.
        duration_s: f64,
    },
}

/// The thesis cycle (section 9.1.1): 0 to 3000 rpm in 1.5 s, hold 1 s, then +1000 rpm in 0.5 s
/// and hold 1 s, up to 9000 rpm; 11.5 s in all.
pub fn thesis_cycle() -> Vec<Segment> {
    let mut s = vec![
        Segment::Ramp {
            to_rpm: 3000.0,
            duration_s: 1.5,
        },
        Segment::Hold { duration_s: 1.0 },
    ];
    for rpm in (4000..=9000).step_by(1000) {
        s.push(Segment::Ramp {
            to_rpm: rpm as f64,
            duration_s: 0.5,
        });
        s.push(Segment::Hold { duration_s: 1.0 });
    }
    s
}

/// A compiled piece: constant angular acceleration between `t0` and `t1`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    t0: f64,
    t1: f64,
    omega0: f64,
    alpha: f64,
    theta0: f64,
}

/// A measured plateau: a hold of the cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plateau {
    /// Start of the hold, s.
    pub t_start: f64,
    /// End of the hold, s.
    pub t_end: f64,
    /// Reference speed, rad/s.
    pub omega: f64,
    /// The same speed in rpm as the cycle gives it (exact: reports show the set speed as
    /// written, not its round trip through rad/s).
    pub speed_rpm: f64,
}

/// The reference speed profile as exact piecewise-quadratic crank angle.
#[derive(Debug, Clone, PartialEq)]
pub struct Cycle {
    pieces: Vec<Piece>,
    plateaus: Vec<Plateau>,
    /// The piece the last look-up found: a run asks for the same piece many times in a row.
    last: PieceHint,
}

/// The index of the piece a cycle's last look-up found: only where the next look-up starts,
/// never what it finds, so it takes no part in comparisons and a clone starts from it. Relaxed
/// atomic, so a cycle shared between threads stays correct (a stale hint costs a search).
#[derive(Debug, Default)]
struct PieceHint(std::sync::atomic::AtomicUsize);

impl Clone for PieceHint {
    fn clone(&self) -> Self {
        Self(self.0.load(std::sync::atomic::Ordering::Relaxed).into())
    }
}

impl PartialEq for PieceHint {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// rpm to rad/s.
pub fn rpm_to_rad_s(rpm: f64) -> f64 {
    rpm * std::f64::consts::PI / 30.0
}

/// rad/s to rpm.
pub fn rad_s_to_rpm(w: f64) -> f64 {
    w * 30.0 / std::f64::consts::PI
}

impl Cycle {
    /// Compile segments (already validated: positive durations, finite speeds).
    pub fn new(segments: &[Segment]) -> Self {
        let (mut t, mut w, mut th, mut rpm) = (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
        let mut pieces = Vec::new();
        let mut plateaus = Vec::new();
        for s in segments {
            let (dur, w1, rpm1) = match *s {
                Segment::Ramp { to_rpm, duration_s } => (duration_s, rpm_to_rad_s(to_rpm), to_rpm),
                Segment::Hold { duration_s } => (duration_s, w, rpm),
            };
            let alpha = (w1 - w) / dur;
            pieces.push(Piece {
                t0: t,
                t1: t + dur,
                omega0: w,
                alpha,
                theta0: th,
            });
            if matches!(s, Segment::Hold { .. }) {
                plateaus.push(Plateau {
                    t_start: t,
                    t_end: t + dur,
                    omega: w,
                    speed_rpm: rpm,
                });
            }
            th += w * dur + 0.5 * alpha * dur * dur;
            t += dur;
            w = w1;
            rpm = rpm1;
        }
        Self {
            pieces,
            plateaus,
            last: PieceHint::default(),
        }
    }

    /// Total duration, s.
    pub fn duration(&self) -> f64 {
        self.pieces.last().map_or(0.0, |p| p.t1)
    }

    /// The holds, in order.
    pub fn plateaus(&self) -> &[Plateau] {
        &self.plateaus
    }

    /// Times where the reference acceleration changes (segment boundaries).
    pub fn breakpoints(&self) -> Vec<f64> {
        self.pieces.iter().map(|p| p.t1).collect()
    }

    /// Reference crank angle, speed and acceleration at `t` (at a segment boundary: the
    /// segment that ends there).
    pub fn reference(&self, t: f64) -> (f64, f64, f64) {
        let idx = self.locate(|p| p.t1 < t);
        self.piece_reference(idx, t)
    }

    /// As [`Cycle::reference`], but at a segment boundary the segment that starts there: the
    /// acceleration jumps at boundaries and each step must integrate one side only.
    pub fn reference_after(&self, t: f64) -> (f64, f64, f64) {
        let idx = self.locate(|p| p.t1 <= t);
        self.piece_reference(idx, t)
    }

    /// `self.pieces.partition_point(before)` (`before` true for the pieces ending before the
    /// time sought, false from its piece on), checked first at the last look-up's answer: the
    /// same index, without the search on nearly every call of a run.
    #[inline]
    fn locate(&self, before: impl Fn(&Piece) -> bool) -> usize {
        use std::sync::atomic::Ordering::Relaxed;
        let hint = self.last.0.load(Relaxed);
        let ends_at = |i: usize| self.pieces.get(i).is_none_or(|p| !before(p));
        let starts_at = |i: usize| i == 0 || self.pieces.get(i - 1).is_some_and(&before);
        if hint <= self.pieces.len() && starts_at(hint) && ends_at(hint) {
            return hint;
        }
        let idx = self.pieces.partition_point(before);
        self.last.0.store(idx, Relaxed);
        idx
    }

    fn piece_reference(&self, idx: usize, t: f64) -> (f64, f64, f64) {
        match self
            .pieces
            .get(idx.min(self.pieces.len().saturating_sub(1)))
        {
            Some(p) => {
                let tau = t - p.t0;
                (
                    p.theta0 + p.omega0 * tau + 0.5 * p.alpha * tau * tau,
                    p.omega0 + p.alpha * tau,
                    p.alpha,
                )
            }
            None => (0.0, 0.0, 0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_cycle_is_11_5_s_with_seven_plateaus() {
        let c = Cycle::new(&thesis_cycle());
        assert!((c.duration() - 11.5).abs() < 1e-12);
        let speeds: Vec<f64> = c.plateaus().iter().map(|p| rad_s_to_rpm(p.omega)).collect();
        for (s, want) in speeds.iter().zip((3000..=9000).step_by(1000)) {
            assert!((s - want as f64).abs() < 1e-9);
        }
        assert_eq!(speeds.len(), 7);
    }

    /// The look-up that starts from the last piece found answers as the plain search does,
    /// at every time in any order: inside pieces, on their boundaries (both sides), before the
    /// cycle and after it.
    #[test]
    fn the_remembered_piece_changes_no_look_up() {
        let c = Cycle::new(&thesis_cycle());
        let mut times: Vec<f64> = c.pieces.iter().flat_map(|p| [p.t0, p.t1]).collect();
        times.extend((0..400).map(|k| f64::from(k) * 0.0317 - 0.5));
        times.extend(times.clone().iter().rev());
        for t in times {
            let before = c.pieces.partition_point(|p| p.t1 < t);
            let after = c.pieces.partition_point(|p| p.t1 <= t);
            assert_eq!(c.locate(|p| p.t1 < t), before, "{t}");
            assert_eq!(c.locate(|p| p.t1 <= t), after, "{t}");
            assert_eq!(c.reference(t), c.piece_reference(before, t));
        }
    }

    #[test]
    fn reference_angle_integrates_speed() {
        let c = Cycle::new(&thesis_cycle());
        // First ramp: theta = 0.5 * alpha * t^2 with alpha = 3000 rpm / 1.5 s.
        let alpha = rpm_to_rad_s(3000.0) / 1.5;
        let (th, w, a) = c.reference(1.0);
        assert!(
            (th - 0.5 * alpha).abs() < 1e-12
                && (w - alpha).abs() < 1e-12
                && (a - alpha).abs() < 1e-12
        );
        // At a boundary, `reference` belongs to the segment ending there, `reference_after` to
        // the one starting there: same angle and speed, the new acceleration.
        let (th_a, w_a, acc_a) = c.reference(1.5);
        let (th_b, w_b, acc_b) = c.reference_after(1.5);
        assert_eq!((th_a, w_a), (th_b, w_b));
        assert!((acc_a - alpha).abs() < 1e-9 && acc_b == 0.0);
        // Continuity across a boundary.
        let (a1, b1, _) = c.reference(2.5 - 1e-9);
        let (a2, b2, _) = c.reference(2.5 + 1e-9);
        assert!((a1 - a2).abs() < 1e-6 && (b1 - b2).abs() < 1e-6);
    }
}
