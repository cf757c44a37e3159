//! `plain-journal`: a hydrodynamic plain journal bearing under dynamic load
//! (docs/laws/plain-journal.md). The journal's eccentricity ratio vector is the law's state,
//! moved by Booker's mobility method on the finite-length Reynolds tables (or Ocvirk's short
//! bearing) under the load the outer member puts on the inner one (contract version 3); the
//! modules below are its mathematics, each tested on its own.

pub mod bearing;
pub mod reynolds;
pub mod rheology;
pub mod short;
pub mod table;
pub mod tables;
pub mod thermal;

use serde::{Deserialize, Serialize};
use tribo_plugin_api::tribology::film_regime;
use tribo_plugin_api::{
    export_law, InnerBody, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec, Regime,
    SUITS_PLAIN,
};

use bearing::{relative_torque, Bearing, Model, Squeeze, EPS_CAP};
use rheology::Cross;
use thermal::{FilmTemperature, Oil};

/// Parameters of [`PlainJournal`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Radial clearance, m.
    pub clearance_m: f64,
    /// Pressure model: `finite` (tabulated Reynolds solution) or `short` (Ocvirk).
    pub model: String,
    /// Composite roughness Rq of journal and shell, m (for the reported regime only).
    pub roughness_m: f64,
    /// Film temperature: `isothermal` (the oil's viscosity as given) or `effective` (the
    /// film's mean temperature from a heat balance, module [`thermal`]).
    pub thermal: String,
    /// The oil's kinematic viscosity at 40 C, cSt (with `oil_kv100_cst`, the Walther slope of
    /// the `effective` film).
    pub oil_kv40_cst: f64,
    /// The oil's kinematic viscosity at 100 C, cSt.
    pub oil_kv100_cst: f64,
    /// The oil's density, kg/m^3 (the rig's: it converts the given viscosity to kinematic).
    pub density_kg_m3: f64,
    /// The oil's specific heat, J/(kg K).
    pub specific_heat_j_kg_k: f64,
    /// The oil's response to shear: `newtonian` (its viscosity at any shear rate) or `cross`
    /// (a multigrade oil thinning at the film's shear rate, module [`rheology`]).
    pub shear_thinning: String,
    /// For `cross`: the oil's viscosity at 10^6 1/s over its low-shear viscosity (its HTHS
    /// ratio), -.
    pub hths_ratio: f64,
    /// For `cross`: the shear rate halfway between the two Newtonian plateaus, 1/s.
    pub critical_shear_rate_1_s: f64,
    /// For `cross`: the exponent of the thinning.
    pub cross_exponent: f64,
    /// Oil feed pressure at the shell's groove, Pa (gauge); 0: no feed flow in the heat
    /// balance.
    pub feed_pressure_pa: f64,
    /// The groove's arc, degrees (360: a full circumferential groove, 180: a grooved upper shell).
    pub groove_arc_deg: f64,
    /// Axial length of one land beside the central groove, m.
    pub land_length_m: f64,
    /// For `effective`: `cycle-mean` (the film holds its heat over the cycle: the balance of
    /// the cycle's mean power and mean carrying flow, reached through a lag) or
    /// `instantaneous` (the balance solved at every instant).
    pub heat_balance: String,
    /// For `cycle-mean`: the film's thermal time constant, crank revolutions.
    pub thermal_lag_rev: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            // estimate: automotive crank bearings, diametral 0.02-0.05 mm on 45-55 mm
            // journals (about 0.001 x D); 20 um radial.
            clearance_m: 20e-6,
            model: "finite".into(),
            // estimate: ground journal Rq ~0.15 um, shell overlay ~0.35 um.
            roughness_m: 0.4e-6,
            // The law's input viscosity is the film's unless a law set asks for the heat
            // balance, which needs the oil's own viscosity-temperature line (below).
            thermal: "isothermal".into(),
            // estimate: a typical SAE 5W-30 (KV40 ~65 cSt, KV100 ~11 cSt), the 4B11 rig's oil;
            // a law set using `effective` states its rig's oil.
            oil_kv40_cst: 65.0,
            oil_kv100_cst: 11.0,
            // estimate: a mineral or synthetic engine oil at 15 C, 0.84-0.87 kg/l.
            density_kg_m3: 850.0,
            // Cragoe, "Thermal properties of petroleum products", US Bureau of Standards Misc.
            // Publ. 97 (1929): c = (0.388 + 0.00045 t_F) / sqrt(s) Btu/(lb F), 2.16 kJ/(kg K)
            // at 90 C for s = 0.85; engine oil tables (Cengel) 2.05 at 60 C, 2.22 at 100 C.
            specific_heat_j_kg_k: 2150.0,
            // A straight oil, or a law set that has not stated its oil's shear response.
            shear_thinning: "newtonian".into(),
            // estimate: a 5W-30 of the 4B11 rig's line (65 / 11 cSt: 4.66 cSt, about 3.6 mPa s
            // at 150 C with 777 kg/m^3) with an HTHS viscosity near 3.1 mPa s (SAE J300's least
            // for a 5W-30 is 2.9, a ratio of 0.80 on this line); 0.8-0.85 is usual for
            // VI-improved oils.
            hths_ratio: 0.85,
            // estimate: viscosity-modified oils thin from about 10^4-10^5 1/s and are about
            // halfway at 10^6 1/s, the rate the HTHS viscosity is graded at.
            critical_shear_rate_1_s: 1e6,
            // Cross (1965): 2/3 described the thinning of many polymer solutions and
            // dispersions; estimate for a multigrade oil (published fits 0.5-1).
            cross_exponent: 2.0 / 3.0,
            // No feed flow unless a law set states its engine's oil pressure and grooves.
            feed_pressure_pa: 0.0,
            // estimate: a full circumferential groove, Shigley's case.
            groove_arc_deg: 360.0,
            // estimate: a 4 mm central groove in a 20 mm shell leaves two 8 mm lands.
            land_length_m: 8e-3,
            // A film and the surfaces it wets hold heat over many revolutions: under a dynamic
            // load only the cycle's means set its temperature (docs/laws/plain-journal.md,
            // "Held over the cycle"); under a steady load both balances are one.
            heat_balance: "cycle-mean".into(),
            // estimate: the oil crosses the film in about two revolutions (its mean speed is
            // half the surface speed), one four-stroke cycle; the shell and journal surfaces
            // hold heat longer, so two revolutions is the short end of the film's lag.
            thermal_lag_rev: 2.0,
        }
    }
}

/// The plain journal bearing law (crate docs).
#[derive(Debug, Clone)]
pub struct PlainJournal {
    clearance_m: f64,
    model: Model,
    roughness_m: f64,
    /// The heat balance's oil, or `None` for an isothermal film.
    thermal: Option<Oil>,
    /// The oil's shear thinning, or `None` for a Newtonian oil.
    thinning: Option<Cross>,
    /// The groove's feed flow per `R c^3 (1 + 1.5 eps^2) / mu`, m^3/s per (m^4 / (Pa s)):
    /// `(arc / 360) pi p_s / (3 l')`; 0 without feed pressure.
    feed_k: f64,
    /// The film's thermal lag, crank revolutions, for the cycle-mean heat balance; `None`
    /// for the instantaneous balance.
    lag_rev: Option<f64>,
}

/// What the heat balance needs of the oil besides its line: the shear-thinning factor of the
/// film and the groove's feed-flow coefficient.
#[derive(Debug, Clone, Copy)]
struct Supply {
    /// `eta / eta_0` at the film's shear rate (1 for a Newtonian oil).
    thin: f64,
    /// [`PlainJournal::feed_k`] times `R c^3`: the feed flow is `k (1 + 1.5 eps^2) / mu`.
    feed_k: f64,
}

impl Supply {
    /// The groove's pressure flow at eccentricity ratio `eps` and viscosity `mu` (Shigley's
    /// circumferential-groove side flow), m^3/s.
    fn feed_flow(&self, eps: f64, mu: f64) -> f64 {
        self.feed_k * (1.0 + 1.5 * eps * eps) / mu
    }
}

/// State layout: the eccentricity ratio vector (global frame) and whether it has been placed;
/// for the cycle-mean heat balance the film's effective temperature (C), the running mean of
/// its carrying flow (m^3/s) and whether they have been placed.
const STATE: usize = 6;
/// Index of the held film's effective temperature in the state, C.
const FILM_TEMP: usize = 3;
/// Index of the running mean of the carrying flow, m^3/s.
const MEAN_FLOW: usize = 4;
/// Index of the flag: the held film has been placed.
const HELD: usize = 5;

/// One evaluation's film: what [`PlainJournal::evaluate`] reports and [`Law::commit`] moves.
struct Film {
    bearing: Bearing,
    /// Eccentricity ratio vector, global frame.
    eps: [f64; 2],
    /// Force of the outer member on the inner one through the film, N, global frame.
    force: [f64; 2],
    /// Mean of the members' speeds, rad/s.
    omega_bar: f64,
    /// Angle of the outer member, rad (its frame for the reported eccentricity).
    outer_angle: f64,
    /// The film's viscosity (the feed oil's, or at the effective temperature), Pa s.
    mu: f64,
    /// The heat balance's answer (`thermal = "effective"`).
    temperature: Option<FilmTemperature>,
    /// The viscosity-free part of the journal's motion at `eps`, where the heat balance has
    /// computed it (the committed eccentricity of an effective film), for the peak pressure.
    squeeze: Option<Squeeze>,
}

impl PlainJournal {
    /// The film at `input` with the committed `state` (the quasi-static position of this load
    /// before the first commit).
    fn film(&self, input: &LawInput, state: &[f64]) -> Film {
        let bearing = Bearing {
            radius_m: input.contact_radius_m,
            length_m: input.contact_length_m,
            clearance_m: self.clearance_m,
            model: self.model,
        };
        let force = load_on_inner(input);
        // Which member is the journal: body A unless the host says body B.
        let (w_in, w_out, outer_angle) = match input.inner() {
            Some(InnerBody::B) => (
                input.body_b_velocity,
                input.body_a_velocity,
                input.body_a_angle,
            ),
            _ => (
                input.body_a_velocity,
                input.body_b_velocity,
                input.body_b_angle,
            ),
        };
        let omega_bar = 0.5 * (w_in + w_out);
        let mu_feed = input.viscosity_pa_s;
        let thin = self.thinning_at(input.relative_velocity * bearing.radius_m);
        let placed = state.get(2).copied().unwrap_or(0.0) != 0.0;
        let eps_at = |mu: f64| {
            if placed {
                [state[0], state[1]]
            } else {
                quasi_static(&bearing, force, omega_bar, mu)
            }
        };
        let committed = placed.then(|| [state[0], state[1]]);
        let held = self.held_temperature(state);
        // The heat balance at the committed eccentricity needs the motion at the feed
        // viscosity, the peak pressure at the film's: the mobility tables are read once.
        let squeeze = match (self.thermal, committed, held) {
            (Some(_), Some(eps), None) => bearing.squeeze_at(eps, force),
            _ => None,
        };
        let temperature = self.thermal.map(|oil| match held {
            Some(t_c) => held_film(&oil, input, t_c),
            None => effective_film(
                &oil,
                &bearing,
                input,
                committed.map(|eps| (eps, squeeze.as_ref())),
                force,
                omega_bar,
                self.supply(&bearing, thin),
            ),
        });
        let mu = thin * temperature.map_or(mu_feed, |t| t.viscosity_pa_s);
        Film {
            bearing,
            eps: eps_at(mu),
            force,
            omega_bar,
            outer_angle,
            mu,
            temperature,
            squeeze,
        }
    }

    /// What the heat balance needs besides the oil's line, for `bearing` at thinning `thin`.
    fn supply(&self, bearing: &Bearing, thin: f64) -> Supply {
        Supply {
            thin,
            feed_k: self.feed_k * bearing.radius_m * bearing.clearance_m.powi(3),
        }
    }

    /// The held film's effective temperature in `state` (C), for the cycle-mean heat balance
    /// once its first commit has placed it; `None` otherwise (the balance is then solved at
    /// the instant: before the first commit, and always for the instantaneous balance).
    fn held_temperature(&self, state: &[f64]) -> Option<f64> {
        match (self.thermal, self.lag_rev) {
            (Some(_), Some(_)) if state.len() >= STATE && state[HELD] != 0.0 => {
                Some(state[FILM_TEMP])
            }
            _ => None,
        }
    }

    /// The film's effective temperature, its rise and viscosity at `input` with the committed
    /// `state` (`None` for an isothermal film): the heat balance's diagnostic, which contract
    /// v3 has no slot for, so the sweep and the tests read it here.
    pub fn film_temperature(&self, input: &LawInput, state: &[f64]) -> Option<FilmTemperature> {
        if input.kind() != Some(JointKind::Revolute) || !Self::valid_geometry(input) {
            return None;
        }
        self.film(input, state).temperature
    }

    /// The shear-thinning factor `eta / eta_0` of the film at sliding speed `speed_m_s`
    /// (exactly 1 for a Newtonian oil): Cross's model at the concentric film's shear rate
    /// `|speed| / c` (Petroff's; an eccentric film's mean of `1 / h` is higher by
    /// `1 / sqrt(1 - eps^2)`, 1.3 at 0.65, small on the model's logarithmic scale).
    fn thinning_at(&self, speed_m_s: f64) -> f64 {
        self.thinning
            .map_or(1.0, |c| c.factor(speed_m_s / self.clearance_m))
    }

    fn valid_geometry(input: &LawInput) -> bool {
        input.contact_radius_m > 0.0
            && input.contact_length_m > 0.0
            && input.viscosity_pa_s.is_finite()
            && input.viscosity_pa_s >= 0.0
    }
}

/// The force the outer member exerts on the inner one (contract v3's `load_on_inner`). A host
/// that does not fill it (zero while the joint carries a load) leaves the joint's reaction,
/// which has the same line: the film's torque and the eccentricity's size are the same, its
/// direction possibly turned by half a turn.
fn load_on_inner(input: &LawInput) -> [f64; 2] {
    let f = [input.load_on_inner_x_n, input.load_on_inner_y_n];
    if f[0] == 0.0 && f[1] == 0.0 && input.normal_load_n > 0.0 {
        let r = [input.reaction_x_n, input.reaction_y_n];
        let m = r[0].hypot(r[1]);
        if m > 0.0 {
            return r;
        }
        return [0.0, input.normal_load_n];
    }
    f
}

/// The heat balance of a film at eccentricity `eps` with the viscosity-free part of its motion
/// (the quasi-static eccentricity of each viscosity when `None`): the heat source is the power
/// the law books on the joint's relative rotation, `-T w` (Couette shear proportional to the
/// viscosity, the load's offset moment independent of it); the heat-carrying flow is Raimondi and Boyd's `Q - Q_s / 2` (inlet flow less half the
/// side leakage, which leaves at the mean temperature) of the rotating film, `|omega_bar| R c L`
/// (exact for the short bearing at any eccentricity), or, when the squeeze dominates, half the
/// squeeze film's side leakage `c |v| R L`, whichever is larger, plus the groove's feed flow
/// where the law has a feed pressure (Shigley's, leaving at the exit temperature). The film
/// shears at `supply.thin` times the viscosity of its temperature (the oil's shear thinning,
/// 1 for a Newtonian oil).
fn effective_film(
    oil: &Oil,
    b: &Bearing,
    input: &LawInput,
    eps: Option<([f64; 2], Option<&Squeeze>)>,
    force: [f64; 2],
    omega_bar: f64,
    supply: Supply,
) -> FilmTemperature {
    let thin = supply.thin;
    let w = input.relative_velocity;
    let mu_feed = input.viscosity_pa_s;
    if mu_feed <= 0.0 {
        return FilmTemperature {
            effective_c: input.oil_temp_c,
            rise_k: 0.0,
            viscosity_pa_s: mu_feed,
        };
    }
    let rcl = b.radius_m * b.clearance_m * b.length_m;
    let q_rot = omega_bar.abs() * rcl;
    match eps {
        Some((eps, squeeze)) => {
            // At a fixed eccentricity the Couette power scales with mu and the squeeze speed
            // with 1 / mu: one evaluation at the feed viscosity gives the balance in closed form.
            let power = -relative_torque(b, eps, force, w, omega_bar, mu_feed) * w;
            let couette = b.couette(eps[0].hypot(eps[1]), mu_feed) * w * w;
            let offset = power - couette;
            let m = b.motion_with(squeeze, eps, omega_bar, mu_feed).squeeze;
            let q_squeeze = m[0].hypot(m[1]) * rcl;
            let q_feed = supply.feed_flow(eps[0].hypot(eps[1]), mu_feed);
            thermal::solve(oil, input.oil_temp_c, mu_feed, |mu| {
                let r = thin * mu / mu_feed;
                let q = q_rot.max(q_squeeze / r);
                (couette * r + offset, with_feed(q, q_feed / r))
            })
        }
        None => thermal::solve(oil, input.oil_temp_c, mu_feed, |mu| {
            let mu = thin * mu;
            let e = quasi_static(b, force, omega_bar, mu);
            let power = -relative_torque(b, e, force, w, omega_bar, mu) * w;
            let m = b.motion(e, force, omega_bar, mu).squeeze;
            let q = q_rot.max(m[0].hypot(m[1]) * rcl);
            (power, with_feed(q, supply.feed_flow(e[0].hypot(e[1]), mu)))
        }),
    }
}

/// The held film (the cycle-mean balance) at temperature `t_c`: its rise over the feed and the
/// viscosity of that temperature on the oil's line through the feed oil.
fn held_film(oil: &Oil, input: &LawInput, t_c: f64) -> FilmTemperature {
    let mu_feed = input.viscosity_pa_s;
    let viscosity_pa_s = if mu_feed > 0.0 {
        oil.viscosity_at(mu_feed, input.oil_temp_c, t_c)
    } else {
        mu_feed
    };
    FilmTemperature {
        effective_c: t_c,
        rise_k: 2.0 * (t_c - input.oil_temp_c),
        viscosity_pa_s,
    }
}

/// The heat balance's power (W) and carrying flow (m^3/s) of `film` at its eccentricity and
/// viscosity: the power booked on the relative rotation, `-T w`, and the larger of the
/// rotating film's `|omega_bar| R c L` and half the squeeze film's side leakage, plus the
/// groove's feed flow (the terms of [`effective_film`], at one viscosity).
fn power_and_flow(film: &Film, input: &LawInput, supply: Supply) -> (f64, f64) {
    let b = &film.bearing;
    let w = input.relative_velocity;
    let power = -relative_torque(b, film.eps, film.force, w, film.omega_bar, film.mu) * w;
    let rcl = b.radius_m * b.clearance_m * b.length_m;
    let m = b
        .motion(film.eps, film.force, film.omega_bar, film.mu)
        .squeeze;
    let q = (film.omega_bar.abs() * rcl).max(m[0].hypot(m[1]) * rcl);
    let e = film.eps[0].hypot(film.eps[1]);
    (power, with_feed(q, supply.feed_flow(e, film.mu)))
}

/// The film's heat-carrying flow `q` with the groove's feed flow `q_feed` added (`q` itself,
/// to the bit, without a feed).
fn with_feed(q: f64, q_feed: f64) -> f64 {
    if q_feed > 0.0 {
        q + q_feed
    } else {
        q
    }
}

/// The journal's steady position under `force` at mean speed `omega_bar`: the steady
/// eccentricity at the attitude angle from the load line, turned in the direction of rotation.
fn quasi_static(b: &Bearing, force: [f64; 2], omega_bar: f64, mu: f64) -> [f64; 2] {
    let w = force[0].hypot(force[1]);
    if w <= 0.0 || omega_bar == 0.0 || mu <= 0.0 {
        return [0.0, 0.0];
    }
    let (e, attitude) = b.steady(w, omega_bar, mu);
    // The load the journal carries points against the film's force on it.
    let theta = (-force[1]).atan2(-force[0]) + attitude * omega_bar.signum();
    [e * theta.cos(), e * theta.sin()]
}

impl Law for PlainJournal {
    type Params = Params;
    const NAME: &'static str = "plain-journal";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str = "Hydrodynamic plain journal bearing under dynamic load: finite-length Reynolds (Swift-Stieber rupture) tables, Booker mobility, eccentricity as state";
    const SUITS: u32 = SUITS_PLAIN;

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number(
                "clearance_m",
                "m",
                "radial clearance c between journal and shell",
                1e-7,
                1e-3,
            ),
            ParamSpec::choice(
                "model",
                "finite: tabulated finite-length Reynolds solution (Swift-Stieber rupture); short: Ocvirk's short bearing (half-Sommerfeld, closed form)",
                &["finite", "short"],
            ),
            ParamSpec::number(
                "roughness_m",
                "m",
                "composite roughness Rq of journal and shell; sets the reported regime from h_min / Rq",
                1e-9,
                1e-4,
            ),
            ParamSpec::choice(
                "thermal",
                "isothermal: the film shears at the oil's given viscosity; effective: at the viscosity of its mean temperature from a heat balance (Raimondi-Boyd effective temperature)",
                &["isothermal", "effective"],
            ),
            ParamSpec::number(
                "oil_kv40_cst",
                "cSt",
                "the oil's kinematic viscosity at 40 C (its Walther slope, for thermal = effective)",
                1.0,
                1e4,
            ),
            ParamSpec::number(
                "oil_kv100_cst",
                "cSt",
                "the oil's kinematic viscosity at 100 C (its Walther slope, for thermal = effective)",
                1.0,
                1e3,
            ),
            ParamSpec::number(
                "density_kg_m3",
                "kg/m^3",
                "the oil's density (the rig's), for thermal = effective",
                500.0,
                1200.0,
            ),
            ParamSpec::number(
                "specific_heat_j_kg_k",
                "J/(kg K)",
                "the oil's specific heat, for thermal = effective",
                1000.0,
                4000.0,
            ),
            ParamSpec::choice(
                "shear_thinning",
                "newtonian: the oil's viscosity at any shear rate; cross: a multigrade oil thinning at the film's shear rate |w| R / c (Cross's equation between its low-shear viscosity and a second plateau)",
                &["newtonian", "cross"],
            ),
            ParamSpec::number(
                "hths_ratio",
                "-",
                "the oil's viscosity at 10^6 1/s over its low-shear viscosity, for shear_thinning = cross (HTHS over low-shear viscosity at 150 C; 0.8-0.85 usual for VI-improved oils)",
                0.3,
                1.0,
            ),
            ParamSpec::number(
                "critical_shear_rate_1_s",
                "1/s",
                "the shear rate halfway between the oil's two Newtonian plateaus, for shear_thinning = cross",
                1e3,
                1e9,
            ),
            ParamSpec::number(
                "cross_exponent",
                "-",
                "the exponent m of Cross's equation, for shear_thinning = cross (at most 1: the shear stress keeps rising with the rate)",
                0.3,
                1.0,
            ),
            ParamSpec::number(
                "feed_pressure_pa",
                "Pa",
                "oil feed pressure (gauge) at the shell's groove; its pressure flow through the lands joins the heat balance's carrying flow, for thermal = effective (0: none)",
                0.0,
                2e6,
            ),
            ParamSpec::number(
                "groove_arc_deg",
                "deg",
                "the feed groove's arc (360: full circumferential groove; 180: grooved upper shell), scaling the feed flow",
                0.0,
                360.0,
            ),
            ParamSpec::number(
                "land_length_m",
                "m",
                "axial length of one land beside the central groove (the feed flow's path)",
                1e-4,
                0.1,
            ),
            ParamSpec::choice(
                "heat_balance",
                "for thermal = effective: cycle-mean: the film holds its heat, its temperature lags towards the balance of the cycle's mean power and mean carrying flow (the law's state); instantaneous: the balance solved at every instant",
                &["cycle-mean", "instantaneous"],
            ),
            ParamSpec::number(
                "thermal_lag_rev",
                "rev",
                "for heat_balance = cycle-mean: the film's thermal time constant in crank revolutions",
                0.1,
                1000.0,
            ),
        ]
    }

    fn new_given(p: Params, given: &[&str]) -> Result<Self, ParamError> {
        refuse_unused_heat_parameters(&p, given)?;
        Self::new(p)
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        let model = match p.model.as_str() {
            "finite" => Model::Finite,
            "short" => Model::Short,
            other => {
                return Err(ParamError::new(
                    "model",
                    format!("expected `finite` or `short`, got `{other}`"),
                ))
            }
        };
        let thermal = match p.thermal.as_str() {
            "isothermal" => None,
            "effective" => {
                if p.oil_kv40_cst <= p.oil_kv100_cst {
                    return Err(ParamError::new(
                        "oil_kv40_cst",
                        format!(
                            "an oil thins as it warms: expected oil_kv40_cst ({}) above oil_kv100_cst ({})",
                            p.oil_kv40_cst, p.oil_kv100_cst
                        ),
                    ));
                }
                Some(Oil {
                    walther_b: thermal::walther_slope(p.oil_kv40_cst, p.oil_kv100_cst),
                    density_kg_m3: p.density_kg_m3,
                    specific_heat_j_kg_k: p.specific_heat_j_kg_k,
                })
            }
            other => {
                return Err(ParamError::new(
                    "thermal",
                    format!("expected `isothermal` or `effective`, got `{other}`"),
                ))
            }
        };
        let thinning = match p.shear_thinning.as_str() {
            "newtonian" => None,
            "cross" => Some(
                Cross::from_hths_ratio(
                    p.hths_ratio,
                    p.critical_shear_rate_1_s,
                    p.cross_exponent,
                )
                .map_err(|e| {
                    ParamError::new(
                        "hths_ratio",
                        format!(
                            "more thinning at 10^6 1/s than Cross's curve with critical_shear_rate_1_s = {} and cross_exponent = {} can give: expected hths_ratio at least {:.4}, got {}",
                            p.critical_shear_rate_1_s, p.cross_exponent, e.least_ratio, p.hths_ratio
                        ),
                    )
                })?,
            ),
            other => {
                return Err(ParamError::new(
                    "shear_thinning",
                    format!("expected `newtonian` or `cross`, got `{other}`"),
                ))
            }
        };
        let lag_rev = match p.heat_balance.as_str() {
            "cycle-mean" => Some(p.thermal_lag_rev),
            "instantaneous" => None,
            other => {
                return Err(ParamError::new(
                    "heat_balance",
                    format!("expected `cycle-mean` or `instantaneous`, got `{other}`"),
                ))
            }
        };
        Ok(Self {
            clearance_m: p.clearance_m,
            model,
            roughness_m: p.roughness_m,
            thermal,
            thinning,
            feed_k: p.groove_arc_deg / 360.0 * std::f64::consts::PI * p.feed_pressure_pa
                / (3.0 * p.land_length_m),
            lag_rev,
        })
    }

    fn state_size(&self) -> usize {
        STATE
    }

    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        if !Self::valid_geometry(input) {
            return LawOutput::force(0.0);
        }
        let r = input.contact_radius_m;
        let l = input.contact_length_m;
        let mu = input.viscosity_pa_s;
        if input.kind() != Some(JointKind::Revolute) {
            // A sleeve on a slide: the concentric film's shear.
            let k = mu * 2.0 * std::f64::consts::PI * r * l / self.clearance_m;
            let rate = input.relative_velocity / self.clearance_m;
            let (thin, slope) = self
                .thinning
                .map_or((1.0, 1.0), |c| (c.factor(rate), c.stress_slope(rate)));
            return LawOutput::force(-k * thin * input.relative_velocity)
                .with_derivative(-k * slope)
                .with_regime(Regime::Hydrodynamic)
                .with_min_film(self.clearance_m);
        }
        let f = self.film(input, state);
        let torque = relative_torque(
            &f.bearing,
            f.eps,
            f.force,
            input.relative_velocity,
            f.omega_bar,
            f.mu,
        );
        let e = f.eps[0].hypot(f.eps[1]).min(EPS_CAP);
        let h_min = self.clearance_m * (1.0 - e);
        let motion = match f.squeeze {
            Some(sq) => f.bearing.motion_with(Some(&sq), f.eps, f.omega_bar, f.mu),
            None => f.bearing.motion(f.eps, f.force, f.omega_bar, f.mu),
        };
        let peak = motion.peak_pressure_pa;
        // The eccentricity in the outer member's frame.
        let (s, c) = (-f.outer_angle).sin_cos();
        let scale = if f.eps[0].hypot(f.eps[1]) > EPS_CAP {
            EPS_CAP / f.eps[0].hypot(f.eps[1])
        } else {
            1.0
        };
        let (ex, ey) = (f.eps[0] * scale, f.eps[1] * scale);
        let lambda = h_min / self.roughness_m;
        let regime = film_regime(lambda);
        let mut out = LawOutput::force(torque)
            .with_regime(regime)
            .with_min_film(h_min)
            .with_eccentricity(c * ex - s * ey, s * ex + c * ey)
            .with_peak_pressure(peak.max(0.0));
        if input.normal_load_n > 0.0 {
            out = out.with_coefficient(torque.abs() / (input.normal_load_n * r));
        }
        out
    }

    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        if state.len() < STATE
            || input.kind() != Some(JointKind::Revolute)
            || !Self::valid_geometry(input)
        {
            return;
        }
        let f = self.film(input, state);
        let next = if input.dt_s > 0.0 {
            f.bearing
                .advance(f.eps, f.force, f.omega_bar, f.mu, input.dt_s)
        } else {
            f.eps
        };
        self.hold_heat(input, &f, state);
        if next[0].is_finite() && next[1].is_finite() {
            state[0] = next[0];
            state[1] = next[1];
            state[2] = 1.0;
        }
    }
}

/// The heat balance's parameters given (`given`) where `p` leaves them without effect: both
/// with an isothermal film (no film temperature to balance), the lag with the instantaneous
/// balance (nothing held). Refused, naming the parameter, its value, why and what to do.
fn refuse_unused_heat_parameters(p: &Params, given: &[&str]) -> Result<(), ParamError> {
    let is_given = |name: &str| given.contains(&name);
    if p.thermal == "isothermal" {
        let unused = [
            ("heat_balance", format!("\"{}\"", p.heat_balance)),
            ("thermal_lag_rev", p.thermal_lag_rev.to_string()),
        ];
        if let Some((name, value)) = unused.into_iter().find(|(n, _)| is_given(n)) {
            return Err(ParamError::new(
                name,
                format!(
                    "{name} = {value} is given with thermal = \"isothermal\", which shears the film at the oil's given viscosity and has no film temperature to balance, so it would be ignored; remove {name}, or set thermal = \"effective\" (with the oil's oil_kv40_cst and oil_kv100_cst) for the heat balance to use it"
                ),
            ));
        }
    } else if p.heat_balance == "instantaneous" && is_given("thermal_lag_rev") {
        return Err(ParamError::new(
            "thermal_lag_rev",
            format!(
                "thermal_lag_rev = {} is given with heat_balance = \"instantaneous\", which solves the balance at every instant and holds no heat, so the lag would be ignored; remove thermal_lag_rev, or set heat_balance = \"cycle-mean\" for the film to hold its heat with that lag",
                p.thermal_lag_rev
            ),
        ));
    }
    Ok(())
}

impl PlainJournal {
    /// The cycle-mean heat balance's commit: the film's temperature and mean flow advanced over
    /// the step ([`thermal::HeldFilm`]) with the step's power and flow at the committed
    /// eccentricity and the held viscosity: first-order lags (not delays), the mean flow's
    /// with the time constant `tau`, the temperature's with `tau` at the mean flow (`tau` times
    /// the mean over the step's flow). `tau` is `thermal_lag_rev` revolutions at the faster of
    /// the engine speed and the film's mean angular speed `|omega_bar|` (on the host's mains
    /// and big ends the engine speed; the film's where no engine speed is given). The first
    /// commit places the film at the instantaneous balance's root and flow.
    fn hold_heat(&self, input: &LawInput, f: &Film, state: &mut [f64]) {
        let (Some(oil), Some(lag_rev), Some(t)) = (self.thermal, self.lag_rev, f.temperature)
        else {
            return;
        };
        if state.len() < STATE || input.viscosity_pa_s <= 0.0 {
            return;
        }
        let thin = self.thinning_at(input.relative_velocity * f.bearing.radius_m);
        let (power, flow) = power_and_flow(f, input, self.supply(&f.bearing, thin));
        if state[HELD] == 0.0 {
            if t.effective_c.is_finite() && flow.is_finite() {
                state[FILM_TEMP] = t.effective_c;
                state[MEAN_FLOW] = flow;
                state[HELD] = 1.0;
            }
            return;
        }
        let omega = input.engine_speed_rad_s.abs().max(f.omega_bar.abs());
        if !(omega > 0.0 && input.dt_s > 0.0) {
            return;
        }
        let lag_s = lag_rev * 2.0 * std::f64::consts::PI / omega;
        let held = thermal::HeldFilm {
            half_rise_k: state[FILM_TEMP] - input.oil_temp_c,
            mean_flow_m3_s: state[MEAN_FLOW],
        }
        .step(oil.heat_capacity_j_m3_k(), power, flow, input.dt_s / lag_s);
        let t_c = input.oil_temp_c + held.half_rise_k;
        if t_c.is_finite() && held.mean_flow_m3_s.is_finite() {
            state[FILM_TEMP] = t_c;
            state[MEAN_FLOW] = held.mean_flow_m3_s;
        }
    }
}

export_law!(PlainJournal);

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> Result<PlainJournal, ParamError> {
        create_from_table::<PlainJournal>(&text.parse().expect("toml"))
    }

    /// A main bearing: the crank (body A, inner) turning at `omega` in the block, loaded
    /// downwards by `w` N (the film pushes the journal up).
    fn main_bearing(omega: f64, w: f64, dt: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Revolute).with_velocity(omega);
        i.contact_radius_m = 0.025;
        i.contact_length_m = 0.020;
        i.viscosity_pa_s = 0.0117;
        i.normal_load_n = w;
        i.reaction_y_n = w;
        i.load_on_inner_y_n = w;
        i.dt_s = dt;
        i
    }

    #[test]
    fn conforms() {
        assert_law_conforms::<PlainJournal>();
    }

    #[test]
    fn rejects_an_unknown_model() {
        let e = law("model = \"long\"").expect_err("unknown model");
        assert!(e.to_string().contains("model"), "{e}");
    }

    /// At zero load the journal is centred and the torque is Petroff's.
    #[test]
    fn petroff_at_zero_load() {
        let l = law("clearance_m = 2e-5").expect("law");
        let i = main_bearing(300.0, 0.0, 0.0);
        let out = l.evaluate(&i, &[0.0; STATE]);
        let petroff = 2.0 * PI * 0.0117 * 0.025f64.powi(3) * 0.020 * 300.0 / 2e-5;
        assert!(
            (out.force + petroff).abs() <= 1e-12 * petroff,
            "{}",
            out.force
        );
        assert_eq!(out.min_film(), Some(2e-5));
    }

    /// Under a steady load the first commit places the journal at its steady position and
    /// further commits keep it there (Booker's mobility of the steady state is zero); the
    /// torque is the steady journal's `K omega + e W sin(phi) / 2`, above Petroff's.
    #[test]
    fn a_steady_load_keeps_the_journal_at_its_steady_position() {
        let l = law("clearance_m = 2e-5").expect("law");
        let i = main_bearing(300.0, 5000.0, 1e-4);
        let mut s = [0.0; STATE];
        l.commit(&i, &mut s);
        let first = [s[0], s[1]];
        for _ in 0..200 {
            l.commit(&i, &mut s);
        }
        let moved = (s[0] - first[0]).hypot(s[1] - first[1]);
        assert!(moved < 0.02 * first[0].hypot(first[1]), "moved {moved}");
        let out = l.evaluate(&i, &s);
        let petroff = 2.0 * PI * 0.0117 * 0.025f64.powi(3) * 0.020 * 300.0 / 2e-5;
        assert!(out.force < -petroff, "{} vs Petroff {petroff}", out.force);
        let (ex, ey) = out.eccentricity().expect("eccentricity");
        // Loaded downwards, the journal sits below the centre, turned towards the rotation.
        assert!(ey < 0.0 && ex > 0.0, "({ex}, {ey})");
        let h = out.min_film().expect("film");
        assert!((h - 2e-5 * (1.0 - ex.hypot(ey))).abs() < 1e-15);
        assert!(out.peak_pressure().expect("peak") > 5000.0 / (0.05 * 0.020));
    }

    /// The reported eccentricity is in the outer member's frame: the same state seen from a
    /// bearing turned by a quarter turn is turned back by a quarter turn.
    #[test]
    fn the_eccentricity_is_reported_in_the_outer_members_frame() {
        let l = law("clearance_m = 2e-5").expect("law");
        let mut i = main_bearing(300.0, 5000.0, 0.0);
        let s = [0.3, -0.4, 1.0];
        let (x0, y0) = l.evaluate(&i, &s).eccentricity().expect("ecc");
        i.body_b_angle = 0.5 * PI;
        let (x1, y1) = l.evaluate(&i, &s).eccentricity().expect("ecc");
        assert!((x0 - 0.3).abs() < 1e-15 && (y0 + 0.4).abs() < 1e-15);
        assert!(
            (x1 - y0).abs() < 1e-12 && (y1 + x0).abs() < 1e-12,
            "({x1}, {y1})"
        );
    }

    /// The rig's oil (Walther through 65 cSt at 40 C and 11 cSt at 100 C, 850 kg/m^3), written
    /// out here independently of the law's anchored line, Pa s.
    fn rig_oil_viscosity(t_c: f64) -> f64 {
        let w = |nu: f64| (nu + 0.7f64).log10().log10();
        let (x1, x2) = ((313.15f64).log10(), (373.15f64).log10());
        let b = (w(65.0) - w(11.0)) / (x2 - x1);
        let a = w(65.0) + b * x1;
        (10f64.powf(10f64.powf(a - b * (t_c + 273.15).log10())) - 0.7) * 1e-6 * 850.0
    }

    const EFFECTIVE: &str = "clearance_m = 2e-5\nthermal = \"effective\"\noil_kv40_cst = 65.0\noil_kv100_cst = 11.0\ndensity_kg_m3 = 850.0\nspecific_heat_j_kg_k = 2150.0";

    /// [`EFFECTIVE`] with the cycle-mean heat balance (the film holding its heat).
    fn held_film() -> String {
        format!("{EFFECTIVE}\nheat_balance = \"cycle-mean\"")
    }

    /// Unloaded, the journal is centred and the film is Petroff's; its heat leaves with the
    /// Couette flow `omega/2 R c L`: the effective temperature satisfies
    /// `T = T_feed + P / (2 rho c_p Q)` with `P` Petroff's power at the viscosity of `T` on the
    /// oil's own Walther line, and the torque is Petroff's at that viscosity.
    #[test]
    fn an_unloaded_effective_film_is_petroff_at_its_heat_balance_temperature() {
        let l = law(EFFECTIVE).expect("law");
        let mut i = main_bearing(300.0, 0.0, 0.0);
        i.oil_temp_c = 90.0;
        i.viscosity_pa_s = rig_oil_viscosity(90.0);
        let t = l.film_temperature(&i, &[0.0; STATE]).expect("effective");
        let petroff = |mu: f64| 2.0 * PI * mu * 0.025f64.powi(3) * 0.020 * 300.0 / 2e-5;
        let mu = rig_oil_viscosity(t.effective_c);
        assert!(
            (t.viscosity_pa_s - mu).abs() < 1e-9 * mu,
            "{} vs {mu}",
            t.viscosity_pa_s
        );
        let q = 150.0 * 0.025 * 2e-5 * 0.020;
        let rise = petroff(mu) * 300.0 / (850.0 * 2150.0 * q);
        assert!(
            (t.rise_k - rise).abs() < 1e-6 * rise,
            "{} vs {rise}",
            t.rise_k
        );
        assert!((t.effective_c - 90.0 - rise / 2.0).abs() < 1e-6);
        let out = l.evaluate(&i, &[0.0; STATE]);
        assert!(
            (out.force + petroff(mu)).abs() <= 1e-9 * petroff(mu),
            "{} vs {}",
            out.force,
            petroff(mu)
        );
        // The film is warmer than the sump, so it drags less than the isothermal film.
        let iso = law("clearance_m = 2e-5")
            .expect("law")
            .evaluate(&i, &[0.0; STATE]);
        assert!(out.force.abs() < iso.force.abs());
    }

    /// `thermal = "isothermal"` (the default) is the film at the given viscosity, whatever the
    /// oil parameters say: the same torque, film and pressure to the last bit.
    #[test]
    fn the_isothermal_option_ignores_the_oil() {
        let a = law("clearance_m = 2e-5").expect("law");
        let b = law("clearance_m = 2e-5\nthermal = \"isothermal\"\noil_kv40_cst = 300.0\noil_kv100_cst = 20.0\nspecific_heat_j_kg_k = 1500.0").expect("law");
        let i = main_bearing(300.0, 5000.0, 1e-4);
        let s = [0.3, -0.5, 1.0];
        let (oa, ob) = (a.evaluate(&i, &s), b.evaluate(&i, &s));
        assert!((oa.force - ob.force).abs() <= 1e-12 * oa.force.abs());
        assert_eq!(oa.min_film(), ob.min_film());
        assert_eq!(oa.peak_pressure(), ob.peak_pressure());
        assert!(b.film_temperature(&i, &s).is_none());
    }

    /// A loaded effective film at its steady position: the balance holds with the law's own
    /// power (the torque times the speed) and flow, the film is hotter under more load (more
    /// power through the same flow) and at higher speed.
    #[test]
    fn a_loaded_effective_film_balances_its_own_power() {
        let l = law(EFFECTIVE).expect("law");
        let film = |omega: f64, w: f64| {
            let mut i = main_bearing(omega, w, 0.0);
            i.oil_temp_c = 90.0;
            i.viscosity_pa_s = rig_oil_viscosity(90.0);
            let t = l.film_temperature(&i, &[0.0; STATE]).expect("effective");
            let p = -l.evaluate(&i, &[0.0; STATE]).force * omega;
            let q = 0.5 * omega * 0.025 * 2e-5 * 0.020;
            let rise = p / (850.0 * 2150.0 * q);
            assert!(
                (t.rise_k - rise).abs() < 1e-6 * rise,
                "{} vs {rise}",
                t.rise_k
            );
            t.effective_c
        };
        assert!(film(300.0, 5000.0) > film(300.0, 1000.0));
        assert!(film(600.0, 5000.0) > film(300.0, 5000.0));
    }

    /// The effective-temperature rule against the film it stands for. The law lumps the film
    /// into one temperature, `T_feed + dT / 2`, and one exit temperature, `T_feed + dT`. The
    /// adiabatic film it models can be solved without lumping: the Couette flow
    /// `Q = omega R c L / 2` carries the oil round from the feed, heated on the way by the shear
    /// at its own temperature,
    ///
    /// ```text
    /// rho c_p Q dT/dtheta = mu(T) omega^2 R^3 L / c,   T(0) = T_feed,   T_max = T(2 pi)
    /// torque = rho c_p Q (T(2 pi) - T_feed) / omega     (all the heat leaves with the flow)
    /// ```
    ///
    /// integrated here by fourth-order Runge-Kutta on the oil's Walther line written out
    /// independently of the law. On the 4B11's main (50 x 20 mm, 10.5 um radial) from 1000 to
    /// 6000 rpm the law's torque is asked to be within 10% of the distributed film's and its
    /// exit temperature within 5 K of the film's maximum (the issue's thresholds for a heat
    /// balance), at warm sumps (70-110 C). Both must be high, never low: the distributed film
    /// heats fastest where it enters cold and thick, so its temperature averaged round the
    /// bearing is above the mean of its ends, and the lumped rule over-weights the viscosity.
    /// At a 40 C sump the lumped exit temperature is up to 10 K above the distributed film's
    /// maximum (6.6 K at 3000 rpm, 9.6 K at 6000): within the torque's 10% still, outside the
    /// 5 K, and asserted as found. This checks the lumping, not the adiabatic premise: metal
    /// conduction, which the law leaves out, would make both films cooler. The table:
    /// `cargo test --release -p tribo-law-plain-journal --lib -- the_lumped --nocapture`.
    #[test]
    fn the_lumped_heat_balance_matches_the_distributed_adiabatic_film() {
        let (r, l, c, rho, cp) = (0.025_f64, 0.020_f64, 10.5e-6_f64, 850.0_f64, 2150.0_f64);
        let params = "clearance_m = 10.5e-6\nthermal = \"effective\"\noil_kv40_cst = 65.0\noil_kv100_cst = 11.0\ndensity_kg_m3 = 850.0\nspecific_heat_j_kg_k = 2150.0";
        let lumped = law(params).expect("law");
        for feed_c in [40.0, 70.0, 90.0, 110.0] {
            for rpm in [1000.0, 3000.0, 6000.0] {
                let omega = rpm * PI / 30.0;
                let q = 0.5 * omega * r * c * l;
                let slope = |t: f64| {
                    rig_oil_viscosity(t) * omega * omega * r.powi(3) * l / c / (rho * cp * q)
                };
                let (n, mut t) = (4000, feed_c);
                let h = 2.0 * PI / n as f64;
                for _ in 0..n {
                    let k1 = slope(t);
                    let k2 = slope(t + 0.5 * h * k1);
                    let k3 = slope(t + 0.5 * h * k2);
                    let k4 = slope(t + h * k3);
                    t += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
                }
                let film_torque = rho * cp * q * (t - feed_c) / omega;
                let mut i = main_bearing(omega, 0.0, 0.0);
                i.oil_temp_c = feed_c;
                i.viscosity_pa_s = rig_oil_viscosity(feed_c);
                let temp = lumped
                    .film_temperature(&i, &[0.0; STATE])
                    .expect("effective");
                let torque = -lumped.evaluate(&i, &[0.0; STATE]).force;
                let ratio = torque / film_torque;
                let over_k = feed_c + temp.rise_k - t;
                let at = format!(
                    "{feed_c} C, {rpm} rpm: torque x{ratio:.4}, exit +{over_k:.2} K (law: effective {:.1} C, exit {:.1} C)",
                    temp.effective_c,
                    feed_c + temp.rise_k
                );
                println!("{at}");
                assert!((1.0..1.10).contains(&ratio), "{at}");
                let limit_k = if feed_c >= 70.0 { 5.0 } else { 10.0 };
                assert!(over_k >= 0.0 && over_k < limit_k, "{at}");
            }
        }
    }

    #[test]
    fn an_oil_that_thickens_as_it_warms_is_refused() {
        let e = law("thermal = \"effective\"\noil_kv40_cst = 10.0\noil_kv100_cst = 11.0")
            .expect_err("kv40 below kv100");
        assert!(e.to_string().contains("oil_kv40_cst"), "{e}");
        let e = law("thermal = \"adiabatic\"").expect_err("unknown");
        assert!(e.to_string().contains("thermal"), "{e}");
    }

    /// Cross's factor at the concentric film's shear rate `omega R / c`, written out by hand
    /// with the law's defaults (HTHS ratio 0.85 at 10^6 1/s, `gamma_c` = 10^6 1/s, `m` = 2/3:
    /// plateau 0.70).
    fn cross_by_hand(omega: f64) -> f64 {
        let rate = omega.abs() * 0.025 / 2e-5;
        0.70 + 0.30 / (1.0 + (rate / 1e6f64).powf(2.0 / 3.0))
    }

    /// A Newtonian oil is today's film to the last bit: the default, `shear_thinning =
    /// "newtonian"` and Cross's model with an HTHS ratio of one (no thinning at any rate) give
    /// the same torque, film, pressure, temperature and committed state, isothermal and
    /// effective, placed and not.
    #[test]
    fn the_newtonian_limit_is_the_newtonian_film_exactly() {
        for thermal in ["clearance_m = 2e-5", EFFECTIVE] {
            let laws = [
                law(thermal).expect("law"),
                law(&format!("{thermal}\nshear_thinning = \"newtonian\"")).expect("law"),
                law(&format!(
                    "{thermal}\nshear_thinning = \"cross\"\nhths_ratio = 1.0"
                ))
                .expect("law"),
            ];
            let mut i = main_bearing(600.0, 5000.0, 1e-4);
            i.oil_temp_c = 90.0;
            i.body_b_velocity = -150.0;
            i.relative_velocity = 750.0;
            for s in [[0.0; STATE], [0.3, -0.5, 1.0, 0.0, 0.0, 0.0]] {
                let base = laws[0].evaluate(&i, &s);
                let mut committed = s;
                laws[0].commit(&i, &mut committed);
                for l in &laws[1..] {
                    let out = l.evaluate(&i, &s);
                    assert_eq!(out.force.to_bits(), base.force.to_bits(), "{thermal}");
                    assert_eq!(out.min_film(), base.min_film());
                    assert_eq!(out.peak_pressure(), base.peak_pressure());
                    assert_eq!(out.eccentricity(), base.eccentricity());
                    assert_eq!(l.film_temperature(&i, &s), laws[0].film_temperature(&i, &s));
                    let mut c = s;
                    l.commit(&i, &mut c);
                    assert_eq!(c, committed);
                }
            }
        }
    }

    /// Unloaded and isothermal, a thinning oil's film is Petroff's at Cross's viscosity of the
    /// concentric film's shear rate, at every speed; the thinning grows with speed.
    #[test]
    fn an_unloaded_thinning_film_is_petroff_at_the_cross_viscosity() {
        let l = law("clearance_m = 2e-5\nshear_thinning = \"cross\"").expect("law");
        let mut last = 1.0;
        for omega in [50.0, 105.0, 314.0, 733.0, -314.0] {
            let i = main_bearing(omega, 0.0, 0.0);
            let out = l.evaluate(&i, &[0.0; STATE]);
            let f = cross_by_hand(omega);
            let petroff = 2.0 * PI * 0.0117 * f * 0.025f64.powi(3) * 0.020 * omega / 2e-5;
            assert!(
                (out.force + petroff).abs() <= 1e-12 * petroff.abs(),
                "{omega}: {} vs {}",
                out.force,
                -petroff
            );
            if omega > 0.0 {
                assert!(f < last && f > 0.70, "{omega}: {f}");
                last = f;
            }
        }
    }

    /// Unloaded with the heat balance, the thinned film is Petroff's at Cross's factor times
    /// the viscosity of its effective temperature, and that temperature balances the thinned
    /// film's power: cooler than the Newtonian film's, and dragging less.
    #[test]
    fn an_unloaded_effective_thinning_film_balances_its_thinned_power() {
        let l = law(&format!("{EFFECTIVE}\nshear_thinning = \"cross\"")).expect("law");
        let newtonian = law(EFFECTIVE).expect("law");
        let mut i = main_bearing(300.0, 0.0, 0.0);
        i.oil_temp_c = 90.0;
        i.viscosity_pa_s = rig_oil_viscosity(90.0);
        let t = l.film_temperature(&i, &[0.0; STATE]).expect("effective");
        let f = cross_by_hand(300.0);
        let mu = f * rig_oil_viscosity(t.effective_c);
        let petroff = 2.0 * PI * mu * 0.025f64.powi(3) * 0.020 * 300.0 / 2e-5;
        let q = 150.0 * 0.025 * 2e-5 * 0.020;
        let rise = petroff * 300.0 / (850.0 * 2150.0 * q);
        assert!(
            (t.rise_k - rise).abs() < 1e-6 * rise,
            "{} vs {rise}",
            t.rise_k
        );
        let out = l.evaluate(&i, &[0.0; STATE]);
        assert!(
            (out.force + petroff).abs() <= 1e-9 * petroff,
            "{} vs {}",
            out.force,
            -petroff
        );
        let tn = newtonian
            .film_temperature(&i, &[0.0; STATE])
            .expect("effective");
        assert!(t.effective_c < tn.effective_c);
        assert!(out.force.abs() < newtonian.evaluate(&i, &[0.0; STATE]).force.abs());
    }

    /// A thinning film dissipates: its torque opposes the relative rotation on mains, on a big
    /// end's swinging eye and on co-rotating members, loaded or not, isothermal or effective, at
    /// the load's steady position (elsewhere the booked rotational power leaves out the
    /// journal's translation work, docs/laws/plain-journal.md); and it drags less than the
    /// Newtonian film.
    #[test]
    fn a_thinning_film_dissipates_and_drags_less() {
        for thermal in ["clearance_m = 2e-5", EFFECTIVE] {
            let l = law(&format!("{thermal}\nshear_thinning = \"cross\"")).expect("law");
            let n = law(thermal).expect("law");
            for (wa, wb) in [(300.0, 0.0), (600.0, -140.0), (100.0, 60.0), (-400.0, 0.0)] {
                for w in [0.0, 2000.0, 20000.0] {
                    let mut i = main_bearing(wa, w, 0.0);
                    i.oil_temp_c = 90.0;
                    i.body_b_velocity = wb;
                    i.relative_velocity = wa - wb;
                    let s = [0.0; STATE];
                    let t = l.evaluate(&i, &s).force;
                    assert!(t * (wa - wb) < 0.0, "{wa} {wb} {w}: {t}");
                    assert!(t.abs() < n.evaluate(&i, &s).force.abs());
                }
            }
        }
    }

    /// More thinning at 10^6 1/s than Cross's curve can give is refused, naming the ratio;
    /// an unknown shear model is refused naming its key.
    #[test]
    fn an_impossible_thinning_is_refused() {
        let e = law("shear_thinning = \"cross\"\nhths_ratio = 0.45\ncross_exponent = 1.0")
            .expect_err("plateau below zero");
        assert!(e.to_string().contains("hths_ratio"), "{e}");
        let e = law("shear_thinning = \"power-law\"").expect_err("unknown");
        assert!(e.to_string().contains("shear_thinning"), "{e}");
    }

    /// Without feed pressure the groove's parameters change nothing, to the bit.
    #[test]
    fn no_feed_pressure_is_no_feed_flow() {
        let a = law(EFFECTIVE).expect("law");
        let b = law(&format!(
            "{EFFECTIVE}\nfeed_pressure_pa = 0.0\ngroove_arc_deg = 180.0\nland_length_m = 3e-3"
        ))
        .expect("law");
        let mut i = main_bearing(300.0, 5000.0, 1e-4);
        i.oil_temp_c = 90.0;
        for s in [[0.0; STATE], [0.3, -0.5, 1.0, 0.0, 0.0, 0.0]] {
            assert_eq!(
                a.evaluate(&i, &s).force.to_bits(),
                b.evaluate(&i, &s).force.to_bits()
            );
            assert_eq!(a.film_temperature(&i, &s), b.film_temperature(&i, &s));
        }
    }

    /// Unloaded with a feed pressure, the balance's flow is the Couette flow plus Shigley's
    /// circumferential-groove flow `(arc / 360) pi p_s R c^3 / (3 mu l')` (concentric: `eps` =
    /// 0) at the film's viscosity: the rise is Petroff's power over `rho c_p` times their sum.
    /// More pressure, more flow: a cooler film, more torque.
    #[test]
    fn a_fed_film_carries_its_heat_in_the_couette_and_the_feed_flow() {
        let fed = |p_s: f64| {
            law(&format!(
                "{EFFECTIVE}\nfeed_pressure_pa = {p_s}\ngroove_arc_deg = 180.0\nland_length_m = 8e-3"
            ))
            .expect("law")
        };
        let mut i = main_bearing(300.0, 0.0, 0.0);
        i.oil_temp_c = 90.0;
        i.viscosity_pa_s = rig_oil_viscosity(90.0);
        let l = fed(3e5);
        let t = l.film_temperature(&i, &[0.0; STATE]).expect("effective");
        let mu = rig_oil_viscosity(t.effective_c);
        let petroff = 2.0 * PI * mu * 0.025f64.powi(3) * 0.020 * 300.0 / 2e-5;
        let q_couette = 150.0 * 0.025 * 2e-5 * 0.020;
        let q_feed = 0.5 * PI * 3e5 * 0.025 * 2e-5f64.powi(3) / (3.0 * mu * 8e-3);
        let rise = petroff * 300.0 / (850.0 * 2150.0 * (q_couette + q_feed));
        assert!(
            (t.rise_k - rise).abs() < 1e-6 * rise,
            "{} vs {rise}",
            t.rise_k
        );
        let films: Vec<(f64, f64)> = [0.0, 1e5, 3e5, 6e5]
            .iter()
            .map(|&p_s| {
                let l = fed(p_s);
                let t = l.film_temperature(&i, &[0.0; STATE]).expect("effective");
                (t.effective_c, l.evaluate(&i, &[0.0; STATE]).force.abs())
            })
            .collect();
        for w in films.windows(2) {
            assert!(w[1].0 < w[0].0 && w[1].1 > w[0].1, "{films:?}");
        }
    }

    /// An effective film under a steady rotating load, committed step after step with the
    /// cycle-mean balance, settles at the instantaneous balance's root at its
    /// committed position: with constant power and flow the two balances are one.
    #[test]
    fn a_steady_load_holds_the_instantaneous_balance() {
        let held = law(&held_film()).expect("law");
        let instant = law(&format!("{EFFECTIVE}\nheat_balance = \"instantaneous\"")).expect("law");
        let mut i = main_bearing(300.0, 5000.0, 1e-4);
        i.oil_temp_c = 90.0;
        i.viscosity_pa_s = rig_oil_viscosity(90.0);
        i.engine_speed_rad_s = 300.0;
        let mut s = [0.0; STATE];
        for _ in 0..20_000 {
            held.commit(&i, &mut s);
        }
        assert_eq!(s[HELD], 1.0);
        let t = held.film_temperature(&i, &s).expect("effective");
        let mut unheld = s;
        unheld[HELD] = 0.0;
        let root = instant.film_temperature(&i, &unheld).expect("effective");
        assert!(
            (t.effective_c - root.effective_c).abs() < 1e-9 * root.rise_k,
            "{t:?} vs {root:?}"
        );
        assert!(t.rise_k > 1.0, "{t:?}");
        let torque = held.evaluate(&i, &s).force;
        let instant_torque = instant.evaluate(&i, &unheld).force;
        assert!((torque - instant_torque).abs() < 1e-9 * instant_torque.abs());
    }

    /// A load switching between 500 N and 20 kN every half revolution: with the cycle-mean
    /// balance the film's temperature no longer follows the load within the cycle (its swing
    /// over the last revolution is under a tenth of the instantaneous balance's), it stays
    /// above the feed (the film only gains heat: its dissipation is not negative), and the
    /// film's mean temperature lies within the instantaneous balance's swing.
    #[test]
    fn a_held_film_does_not_swing_with_the_load() {
        let held = law(&held_film()).expect("law");
        let instant = law(&format!("{EFFECTIVE}\nheat_balance = \"instantaneous\"")).expect("law");
        let omega = 300.0;
        let steps_per_rev = 360;
        let dt = 2.0 * PI / omega / steps_per_rev as f64;
        let run = |l: &PlainJournal| {
            let mut s = [0.0; STATE];
            let mut last = Vec::new();
            for k in 0..40 * steps_per_rev {
                let w = if (k / (steps_per_rev / 2)) % 2 == 0 {
                    500.0
                } else {
                    20_000.0
                };
                let mut i = main_bearing(omega, w, dt);
                i.oil_temp_c = 90.0;
                i.viscosity_pa_s = rig_oil_viscosity(90.0);
                i.engine_speed_rad_s = omega;
                l.commit(&i, &mut s);
                let t = l.film_temperature(&i, &s).expect("effective");
                assert!(l.evaluate(&i, &s).force.is_finite());
                if k >= 39 * steps_per_rev {
                    last.push(t.effective_c);
                }
            }
            let lo = last.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = last.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            (lo, hi, last.iter().sum::<f64>() / last.len() as f64)
        };
        let (lo, hi, mean) = run(&held);
        let (ilo, ihi, _) = run(&instant);
        assert!(ihi - ilo > 2.0, "instantaneous swing {ilo}..{ihi}");
        assert!(
            hi - lo < 0.1 * (ihi - ilo),
            "held {lo}..{hi} vs {ilo}..{ihi}"
        );
        assert!(
            lo > 90.0 && mean > ilo && mean < ihi,
            "{lo} {mean} {ilo} {ihi}"
        );
    }

    /// The law conforms with the heat balance, held or instantaneous, with shear thinning and a
    /// feed flow (what `tribo check-law` runs).
    #[test]
    fn conforms_with_the_heat_balance() {
        let fed = "shear_thinning = \"cross\"\nfeed_pressure_pa = 3e5\ngroove_arc_deg = 180.0";
        assert_law_conforms_with::<PlainJournal>(&format!("{}\n{fed}", held_film()));
        assert_law_conforms_with::<PlainJournal>(&format!(
            "{EFFECTIVE}\n{fed}\nheat_balance = \"instantaneous\""
        ));
        assert_law_conforms_with::<PlainJournal>(&format!(
            "{}\nthermal_lag_rev = 0.1",
            held_film()
        ));
    }

    /// A heat-balance parameter given where it has no effect is refused naming it, its value,
    /// why and what to do: both with an isothermal film (the default or stated), the lag with
    /// the balance of the instant. Left at their defaults they are not refused, and given
    /// where they act they are accepted.
    #[test]
    fn heat_balance_parameters_given_where_they_do_nothing_are_refused() {
        for (text, name, value) in [
            (
                "heat_balance = \"instantaneous\"",
                "heat_balance",
                "\"instantaneous\"",
            ),
            (
                "thermal = \"isothermal\"\nheat_balance = \"cycle-mean\"",
                "heat_balance",
                "\"cycle-mean\"",
            ),
            ("thermal_lag_rev = 4.0", "thermal_lag_rev", "4"),
            (
                "thermal = \"isothermal\"\nthermal_lag_rev = 2.0",
                "thermal_lag_rev",
                "2",
            ),
        ] {
            let e = law(text).expect_err(text).to_string();
            for word in [
                format!("{name} = {value}"),
                "isothermal".into(),
                "no film temperature".into(),
                format!("remove {name}"),
                "thermal = \"effective\"".into(),
            ] {
                assert!(e.contains(&word), "{text}: `{word}` not in: {e}");
            }
        }
        let e = law(&format!(
            "{EFFECTIVE}\nheat_balance = \"instantaneous\"\nthermal_lag_rev = 0.5"
        ))
        .expect_err("a lag without a held film")
        .to_string();
        for word in [
            "thermal_lag_rev = 0.5",
            "instantaneous",
            "holds no heat",
            "remove thermal_lag_rev",
        ] {
            assert!(e.contains(word), "`{word}` not in: {e}");
        }
        law("clearance_m = 2e-5").expect("defaults left alone");
        law(&format!("{}\nthermal_lag_rev = 0.5", held_film())).expect("a held film's lag");
        law(&format!("{EFFECTIVE}\nheat_balance = \"instantaneous\"")).expect("balance given");
    }

    /// The lag given to a held film is used, as `hold_heat` says: a first-order lag whose time
    /// constant is `thermal_lag_rev` revolutions at the faster of the engine speed and the
    /// film's mean angular speed (150 rad/s here: journal 300, shell still). One step `dt` from
    /// the same film, 10 K off its balance, moves it by the same offset times
    /// `1 - exp(-dt / tau)`, so the ratio of two steps' moves is that of their factors (to 2%:
    /// the held mean flow follows its own lag).
    #[test]
    fn a_given_lag_is_used_at_the_faster_speed() {
        let dt = 1e-4;
        let moved = |lag: f64, engine_rad_s: f64| {
            let mut i = main_bearing(300.0, 5000.0, dt);
            i.oil_temp_c = 90.0;
            i.viscosity_pa_s = rig_oil_viscosity(90.0);
            i.engine_speed_rad_s = engine_rad_s;
            let l = law(&format!("{}\nthermal_lag_rev = {lag}", held_film())).expect("law");
            let mut state = [0.0; STATE];
            l.commit(&i, &mut state);
            let balance = state[FILM_TEMP];
            state[FILM_TEMP] = balance + 10.0;
            l.commit(&i, &mut state);
            balance + 10.0 - state[FILM_TEMP]
        };
        let factor = |lag: f64, omega: f64| 1.0 - (-dt * omega / (lag * 2.0 * PI)).exp();
        let close = |a: f64, b: f64| (a / b - 1.0).abs() < 0.02;
        let (short, long) = (moved(0.5, 0.0), moved(8.0, 0.0));
        let expected = factor(0.5, 150.0) / factor(8.0, 150.0);
        assert!(
            close(short / long, expected),
            "{short} / {long} vs {expected}"
        );
        let fast = moved(2.0, 600.0) / moved(2.0, 0.0);
        let expected = factor(2.0, 600.0) / factor(2.0, 150.0);
        assert!(
            close(fast, expected),
            "engine 600 rad/s: {fast} vs {expected}"
        );
        // An engine slower than the film's mean speed leaves the film's.
        assert_eq!(moved(2.0, 100.0), moved(2.0, 0.0));
    }

    #[test]
    fn an_unknown_heat_balance_is_refused() {
        let e = law("heat_balance = \"averaged\"").expect_err("unknown");
        assert!(e.to_string().contains("heat_balance"), "{e}");
    }

    /// Hotter, thinner oil: the journal runs more eccentric, the film thinner, the torque
    /// lower (the sweep of docs/laws/plain-journal.md in one line).
    #[test]
    fn thinner_oil_means_a_thinner_film_and_less_torque() {
        let l = law("clearance_m = 2e-5").expect("law");
        let mut cold = main_bearing(300.0, 5000.0, 0.0);
        cold.viscosity_pa_s = 0.055;
        let hot = main_bearing(300.0, 5000.0, 0.0);
        let (oc, oh) = (l.evaluate(&cold, &[0.0; 3]), l.evaluate(&hot, &[0.0; 3]));
        assert!(oh.min_film() < oc.min_film());
        assert!(oh.force.abs() < oc.force.abs());
    }
}
