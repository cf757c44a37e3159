//! Why a run fails, in words that name the joint, law, time and what to change.

use tribo_plugin_api::loader::LawError;

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A law cannot be bound (a law name that no plugin provides, bad law parameters): `field`
    /// is its dotted path in the model, `at` where the configuration layer found it
    /// (`file:line:column`), if it knows. The configuration layer may replace `field` by the
    /// place the law was attached (a law-set entry, a `--law` argument).
    #[error("{}", setup_text(.at.as_deref(), .field, .law.as_deref(), .param.as_deref(), .message))]
    Setup {
        /// Where the field was written, if known.
        at: Option<String>,
        /// Dotted path of the field, e.g. `joints.piston.laws[0].params`.
        field: String,
        /// The law a parameter problem is about, when `field` does not already name it.
        law: Option<String>,
        /// The parameter at fault, if the problem is one parameter's.
        param: Option<String>,
        /// What is wrong.
        message: String,
    },
    /// A law failed while running.
    // The law's error is part of this message, not a separate cause: a cause would be printed
    // a second time by the CLI's error chain.
    #[error("joint `{joint}` at t = {time_s:.6} s (relative velocity {velocity}, normal load {load_n} N): {error}")]
    Law {
        /// Joint.
        joint: String,
        /// Simulation time, s.
        time_s: f64,
        /// Relative velocity at the failure.
        velocity: f64,
        /// Normal load at the failure, N.
        load_n: f64,
        /// The law's error.
        error: Box<LawError>,
    },
    /// A law returned a force that is not a finite number.
    #[error("joint `{}`, law `{}` ({}) returned a non-finite force ({}) at t = {:.6} s for inputs: velocity {}, normal load {} N", .0.joint, .0.law, .0.file, .0.force, .0.time_s, .0.velocity, .0.load_n)]
    NonFinite(Box<Fault>),
    /// A law returned a finite force (or torque) beyond any physical size, more than
    /// [`MAX_FORCE_PER_REACTION`] times the largest joint reaction at that instant, or a
    /// non-finite value in an optional output it marked present (`what` and `why` say which).
    #[error("joint `{}`, law `{}` ({}) returned {what} at t = {:.6} s for inputs: velocity {}, normal load {} N; {why}", .fault.joint, .fault.law, .fault.file, .fault.time_s, readable(.fault.velocity), readable(.fault.load_n))]
    Implausible {
        /// Where, when and with which inputs.
        fault: Box<Fault>,
        /// What was returned, e.g. `a force of 1e300 N`.
        what: String,
        /// Why it cannot be used.
        why: String,
    },
    /// The host's own model produced a value that is not finite (a reaction, the crank's
    /// acceleration, a velocity or the viscosity handed to the laws): the rig's numbers are out
    /// of proportion, and no law is to blame.
    #[error("the model produced a non-finite {quantity}{} ({value}) at t = {time_s:.6} s, before any law was given it: the rig's numbers are out of proportion; check the masses, inertias and lengths (bodies.*, geometry.*), the drive (drive.*) and the oil (oil.*) for values far outside an engine's", .joint.map(|j| format!(" at joint `{j}`")).unwrap_or_default())]
    Model {
        /// Time, s.
        time_s: f64,
        /// What is not finite, e.g. `normal load`.
        quantity: &'static str,
        /// The joint, if the quantity is a joint's.
        joint: Option<&'static str>,
        /// The value.
        value: f64,
    },
    /// A stateless law returned a force that pushes the motion (F*V > 0).
    #[error("joint `{}`, law `{}` ({}) adds energy at t = {:.6} s: force {} has the sign of the relative velocity {} (normal load {} N); a friction or damping law must oppose the motion", .0.joint, .0.law, .0.file, .0.time_s, .0.force, .0.velocity, .0.load_n)]
    AddsEnergy(Box<Fault>),
    /// The friction/reaction iteration did not converge: which joints' loads did not settle,
    /// with their laws, so the user knows which law to look at.
    #[error("{}", no_convergence_text(*.time_s, *.iterations, *.change_n, *.tol, .unsettled))]
    NoConvergence {
        /// Time.
        time_s: f64,
        /// Iterations made.
        iterations: u32,
        /// Largest last change of a normal load, N.
        change_n: f64,
        /// Tolerance, relative to the largest normal load.
        tol: f64,
        /// The law-bearing joints whose loads did not settle.
        unsettled: Vec<Unsettled>,
    },
    /// The adaptive integrator could not meet its tolerance with any usable step.
    #[error("the adaptive integrator could not meet solver.rel_tol = {rel_tol:.1e} at t = {time_s:.6} s (step down to {step_s:.3e} s): a law is probably discontinuous there; loosen solver.rel_tol or use solver.integrator = \"rk4\"")]
    StepTooSmall {
        /// Time.
        time_s: f64,
        /// The last step tried, s.
        step_s: f64,
        /// The tolerance in force.
        rel_tol: f64,
    },
    /// The crank did not turn the whole revolutions a plateau's measurement window needs
    /// within the recorded end of its hold: there is no plateau value to report (a drive at its
    /// torque limit against a load it cannot turn, typically compression under a weak PI drive).
    #[error("the {set_speed_rpm:.0} rpm plateau has no measurement: the crank turned {turned_revs:.2} revolutions over the last {span_s:.3} s of the hold, but the window needs {needed_revs} whole revolutions (the speed stayed far below the set speed){}", saturation_text(*.saturated_s))]
    Stalled {
        /// The plateau's set speed, rpm.
        set_speed_rpm: f64,
        /// Revolutions turned over the recorded end of the hold.
        turned_revs: f64,
        /// Length of that recorded end, s.
        span_s: f64,
        /// Whole revolutions the window needs.
        needed_revs: u32,
        /// Time the drive sat at its torque limit near the window, s.
        saturated_s: f64,
    },
    /// The step observer failed (the CLI's time-series writer, say): the run stops with its
    /// error. Its message is this one's; it is not also given as the cause, which an error
    /// chain (`{:#}`) would print a second time.
    #[error("{0}")]
    Observer(crate::observe::ObserverError),
    /// An input of a stepped run (`sim::Run`) that cannot be used: which, and why.
    #[error("stepping input `{input}`: {message}")]
    Input {
        /// The input, e.g. `drive_torque_nm`.
        input: &'static str,
        /// What is wrong and what is allowed.
        message: String,
    },
}

/// The advice of [`SimError::Stalled`]: the drive's limit when it was the cause.
fn saturation_text(saturated_s: f64) -> String {
    if saturated_s > 0.0 {
        format!("; the drive sat at its torque limit for {saturated_s:.3} s there: raise drive.torque_limit_nm (or use the prescribed drive, drive.kind = \"prescribed\")")
    } else {
        String::new()
    }
}

/// A law's force (N) or torque (N m) may be at most this many times the largest joint reaction
/// (N) at the instant: friction is a coefficient (rarely above 1) times a load, a torque that
/// times a lever far below a metre, so a million times the largest load is no physics but a
/// wrong law (an overflow, a unit error). See [`REACTION_FLOOR_N`].
pub const MAX_FORCE_PER_REACTION: f64 = 1e6;

/// The reaction the bound of [`MAX_FORCE_PER_REACTION`] is taken from is at least this, N: a
/// joint at (nearly) zero load may still feel viscous drag, and the rig's weight alone loads its
/// joints with tens of N, so a force of up to 1e6 N is never refused.
pub const REACTION_FLOOR_N: f64 = 1.0;

/// A number as a person reads it in a message: `1e308` and `1e-9` rather than hundreds of
/// digits, ordinary numbers as they are.
pub fn readable(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-3..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Where, when and with which inputs a law returned an unusable force.
#[derive(Debug, Clone)]
pub struct Fault {
    /// Joint.
    pub joint: String,
    /// Law.
    pub law: String,
    /// Library file.
    pub file: String,
    /// Simulation time, s.
    pub time_s: f64,
    /// The force (or torque) returned.
    pub force: f64,
    /// Relative velocity given to the law.
    pub velocity: f64,
    /// Normal load given to the law, N.
    pub load_n: f64,
}
/// A joint whose normal load did not settle, with its laws (for the error message).
#[derive(Debug, Clone)]
pub struct Unsettled {
    /// Joint.
    pub joint: String,
    /// Laws bound to it.
    pub laws: Vec<String>,
    /// Last change (or residual) of its normal load, N.
    pub change_n: f64,
}

/// The message of [`SimError::Setup`]: where, which field, law and parameter, what is wrong;
/// each said once.
fn setup_text(
    at: Option<&str>,
    field: &str,
    law: Option<&str>,
    param: Option<&str>,
    message: &str,
) -> String {
    let mut s = String::new();
    if let Some(at) = at {
        s.push_str(at);
        s.push_str(": ");
    }
    s.push_str(field);
    s.push_str(": ");
    match (law, param) {
        (Some(l), Some(p)) => s.push_str(&format!("law `{l}`, parameter `{p}`: ")),
        (Some(l), None) => s.push_str(&format!("law `{l}`: ")),
        (None, Some(p)) => s.push_str(&format!("parameter `{p}`: ")),
        (None, None) => {}
    }
    s.push_str(message);
    s
}

/// The message of [`SimError::NoConvergence`]: where, which joints and laws, what to do.
fn no_convergence_text(
    time_s: f64,
    iterations: u32,
    change_n: f64,
    tol: f64,
    unsettled: &[Unsettled],
) -> String {
    let head = format!(
        "the friction/reaction iteration did not converge at t = {time_s:.6} s after {iterations} iterations"
    );
    if unsettled.is_empty() {
        return format!(
            "{head}, too few to see the normal loads settle: raise solver.friction_max_iter"
        );
    }
    let one = |x: &Unsettled| {
        let laws: Vec<String> = x.laws.iter().map(|l| format!("`{l}`")).collect();
        let noun = if x.laws.len() == 1 { "law" } else { "laws" };
        format!("`{}` ({noun} {})", x.joint, laws.join(", "))
    };
    let items: Vec<String> = unsettled.iter().map(one).collect();
    let joints = match items.split_last() {
        Some((last, [])) => format!("joint {last}"),
        Some((last, rest)) => format!("joints {} and {last}", rest.join(", ")),
        None => String::new(),
    };
    let n_laws: usize = unsettled.iter().map(|x| x.laws.len()).sum();
    let (whose, its) = if n_laws == 1 {
        ("that law's", "its")
    } else {
        ("those laws'", "their")
    };
    format!(
        "{head}: the normal load of {joints} did not settle (last change {change_n:.3e} N, \
         tolerance {tol:.1e} of the largest load); check {whose} parameters at these loads ({its} load \
         sensitivity may be too strong or discontinuous there) or raise \
         solver.friction_max_iter"
    )
}
