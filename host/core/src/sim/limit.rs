//! The PI drive's torque limit as an event of the adaptive integrator. Where the controller's
//! torque reaches the limit, the conditional integration stops (or restarts) the integral: its
//! rate jumps. A step across that jump cannot meet the error test unless it is tiny, so the
//! integrator used to crawl across each crossing (on the thesis cycle's 8000-9000 rpm ramp, which
//! meets the limit several times a revolution, a quarter of all attempts). Instead a step's
//! stages are held on the side of the limit its start is on (`Side`), one smooth field, and a
//! step whose end has left that side is tried again to end on the crossing, located by the
//! Illinois variant of regula falsi on the end margin as a function of the step's length; the
//! next step starts on the other side.

use super::stepper::Side;

/// Tries to land one step on a crossing before the step is taken as it is.
const MAX_TRIES: u32 = 12;

/// A crossing nearer the step's start than this fraction of its first try is the limit slid
/// along or grazed, not passed: that step follows the drive's own switching (`Side::Live`).
const MIN_LANDING: f64 = 1e-6;

/// What to do with an attempted step that met the error test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Landing {
    /// Take it; `on_crossing`: it ends on the limit, the next step starts on the other side.
    Take { on_crossing: bool },
    /// Try again with this length, on the same side.
    Retry(f64),
    /// Try the same length again on the side the search now holds: the side the margin is
    /// on when the crossing the step started on was grazed, not passed; `Side::Live` (the
    /// drive switching as it goes, under error control alone) when the crossing is at the
    /// step's very start.
    Again,
}

/// One step's search for the crossing of the torque limit: the side its stages are held on,
/// the margin at its start, and the bracket so far (the longest length known to end on the
/// side and the shortest known to leave it, each with the margin there).
#[derive(Debug, Clone, Copy)]
pub(super) struct LimitCrossing {
    side: Side,
    forced: bool,
    m0: f64,
    /// The first try's length, s.
    first: f64,
    inside: (f64, f64),
    outside: Option<(f64, f64)>,
    /// Which end the last try replaced (`true`: inside), for the Illinois halving.
    last_inside: Option<bool>,
    /// The last try's length and end margin as they were (the bracket's may be halved).
    last_try: Option<(f64, f64)>,
    tries: u32,
}

impl LimitCrossing {
    /// A step from margin `m0` (N m): held on `forced` (a crossing the step before landed on),
    /// else on the side `m0` is on.
    pub(super) fn start(forced: Option<Side>, m0: f64) -> Self {
        let side = forced.unwrap_or(if m0 < 0.0 { Side::Beyond } else { Side::Within });
        Self {
            side,
            forced: forced.is_some(),
            m0,
            first: 0.0,
            inside: (0.0, m0),
            outside: None,
            last_inside: None,
            last_try: None,
            tries: 0,
        }
    }

    /// The side the step's stages are held on.
    pub(super) fn side(&self) -> Side {
        self.side
    }

    /// Whether the step is being landed on a crossing (its length is the search's, not to be
    /// stretched to a breakpoint).
    pub(super) fn landing(&self) -> bool {
        self.outside.is_some()
    }

    /// A try of length `h` (s) met the error test and ends with margin `m1` (N m); a middle
    /// stage `stage_past` (its time from the start, s, and margin) may have been past the limit
    /// though the end is not. `tol_t` (s) is how long the step may run on the wrong side's law
    /// without erring more than the error test allows (the integral's rate is off by the error
    /// there).
    pub(super) fn check(
        &mut self,
        (h, m1): (f64, f64),
        stage_past: Option<(f64, f64)>,
        tol_t: f64,
    ) -> Landing {
        if self.side == Side::Live {
            return Landing::Take { on_crossing: false };
        }
        let left = |m: f64| self.side.left_by(m);
        if self.first == 0.0 {
            self.first = h;
        }
        if self.forced && self.outside.is_none() && left(m1) && left(self.m0) {
            // Started on the crossing but went back: the limit was grazed. The side the start
            // is on is the other one.
            *self = Self::start(None, self.m0);
            return Landing::Again;
        }
        // How fast the margin moves at the step's end: its mean rate over the step, or where
        // it is faster, the secant through the try before and this one. The mean understates
        // it where the margin dips and comes back within the step (a step started on the
        // crossing it leaves), which held the test below to a margin no try could reach.
        let mean = ((m1 - self.m0) / h).abs();
        let rate = match self.last_try {
            Some((h_last, m_last)) if h_last != h => mean.max(((m1 - m_last) / (h - h_last)).abs()),
            _ => mean,
        };
        self.last_try = Some((h, m1));
        let near = m1.abs() <= tol_t * rate;
        let crossed = left(m1);
        // Out and back within the step: the first crossing is before the stage.
        let grazed = stage_past.filter(|_| !crossed);
        if near && grazed.is_none() && (crossed || self.landing() || m1.abs() < self.m0.abs()) {
            return Landing::Take { on_crossing: true };
        }
        if !crossed && grazed.is_none() && !self.landing() {
            return Landing::Take { on_crossing: false };
        }
        self.tries += 1;
        // The crossing is bracketed more tightly than the step may run on the wrong side's law
        // (typically a graze, where a middle stage's low-order margin and the end's disagree
        // by more than the landing test allows on a bracket of picoseconds): no further try
        // can place it better.
        let bracketed = self
            .outside
            .is_some_and(|(h_out, _)| (h_out - self.inside.0).abs() <= tol_t);
        if bracketed || self.tries > MAX_TRIES {
            return Landing::Take {
                on_crossing: crossed,
            };
        }
        // Past the limit at the end and already at a middle stage: the crossing is before the
        // stage, the nearer far end of the bracket.
        let early = stage_past.filter(|_| crossed);
        let next = match grazed.or(early) {
            Some((h_stage, m_stage)) => self.narrow(h_stage, m_stage, true),
            None => self.narrow(h, m1, crossed),
        };
        if next < MIN_LANDING * self.first {
            self.side = Side::Live;
            return Landing::Again;
        }
        Landing::Retry(next)
    }

    /// The bracket narrowed by a try of length `h` ending at margin `m`, and the next length:
    /// where the line through the bracket's ends meets the limit (with an end kept twice in a
    /// row its margin halved, the Illinois rule, so the search does not stall on one side).
    fn narrow(&mut self, h: f64, m: f64, crossed: bool) -> f64 {
        let (mut h_in, mut m_in) = self.inside;
        let (mut h_out, mut m_out) = self.outside.unwrap_or((h, m));
        if crossed {
            (h_out, m_out) = (h, m);
            if self.last_inside == Some(false) {
                m_in *= 0.5;
            }
        } else {
            (h_in, m_in) = (h, m);
            if self.last_inside == Some(true) {
                m_out *= 0.5;
            }
        }
        self.last_inside = Some(!crossed);
        self.inside = (h_in, m_in);
        self.outside = Some((h_out, m_out));
        let f = (m_in / (m_in - m_out)).clamp(0.0, 1.0);
        h_in + f * (h_out - h_in)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The margin at the end of a step of length `h` from a start 1 N m within the limit,
    /// falling at 2000 N m/s and curving: the limit is met at the root of 1 - 2000 h - 4e5 h^2.
    fn margin(h: f64) -> f64 {
        1.0 - 2000.0 * h - 4e5 * h * h
    }

    #[test]
    fn a_step_past_the_limit_is_landed_on_it() {
        let root = (-2000.0 + (2000.0_f64.powi(2) + 4.0 * 4e5).sqrt()) / (2.0 * 4e5);
        let tol_t = 1e-6 * 1e-3;
        let search = LimitCrossing::start(None, margin(0.0));
        assert_eq!(search.side(), Side::Within);
        assert_lands(search, margin, None, 1e-3, tol_t, root);
    }

    /// A step that starts just past the crossing the step before landed on (held beyond the
    /// limit) and whose margin first dips further beyond, then comes back within: the root of
    /// -1e-6 - 2000 h + 4e7 h^2, near 5e-5 s, with the first try's stage at 0.3 of it past the
    /// limit. The margin's mean rate from the start is near zero at the crossing, so a test
    /// held to it asked for a margin no try could reach (the search ran to its limit of
    /// tries); the local rate lands it.
    #[test]
    fn a_crossing_after_a_dip_is_landed_on() {
        let dip = |h: f64| -1e-6 - 2000.0 * h + 4e7 * h * h;
        let root = (2000.0 + (2000.0_f64.powi(2) - 4.0 * 4e7 * -1e-6).sqrt()) / (2.0 * 4e7);
        let tol_t = 1e-6 * 2e-4;
        let search = LimitCrossing::start(Some(Side::Beyond), dip(0.0));
        assert_lands(search, dip, Some(0.3), 2e-4, tol_t, root);
    }

    /// Tries from length `h` on the end margin `margin(h)` (with the middle stage at the
    /// fraction `stage` of each try reported when it is past the limit) until `search` takes
    /// one, which must end on the crossing, within `tol_t` of `root`.
    fn assert_lands(
        mut search: LimitCrossing,
        margin: impl Fn(f64) -> f64,
        stage: Option<f64>,
        mut h: f64,
        tol_t: f64,
        root: f64,
    ) {
        for _ in 0..MAX_TRIES {
            let stage_past = stage
                .map(|c| c * h)
                .filter(|s| search.side().left_by(margin(*s)))
                .map(|s| (s, margin(s)));
            match search.check((h, margin(h)), stage_past, tol_t) {
                Landing::Retry(next) => h = next,
                Landing::Take { on_crossing } => {
                    assert!(on_crossing);
                    assert!((h - root).abs() <= tol_t, "{h} vs the root {root}");
                    return;
                }
                other => panic!("no grazing here: {other:?}"),
            }
        }
        panic!("not landed within {MAX_TRIES} tries");
    }

    #[test]
    fn a_step_that_stays_on_its_side_is_taken() {
        let mut search = LimitCrossing::start(None, -0.5);
        assert_eq!(search.side(), Side::Beyond);
        assert_eq!(
            search.check((1e-4, -0.3), None, 1e-10),
            Landing::Take { on_crossing: false }
        );
    }

    #[test]
    fn a_grazed_crossing_is_stepped_again_on_the_side_it_is_on() {
        // Landed on the limit from within, held beyond, but the margin went back up.
        let mut search = LimitCrossing::start(Some(Side::Beyond), 1e-12);
        assert_eq!(search.check((1e-4, 0.2), None, 1e-10), Landing::Again);
        assert_eq!(search.side(), Side::Within);
    }
}
