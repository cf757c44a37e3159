//! The small value types several stages share: a joint's `Role` on the crank train, its two
//! `Bodies` at an instant, and how the crank is driven (`Control`). They live in this leaf
//! module, which imports nothing of the solver, so the joints, the law binding, the crank model
//! and the evaluation each read them without importing one another for them.

/// What a joint is on the crank train: the law-bearing joints of any crank train.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Role {
    /// Main bearing `i` (0-based, in axial order).
    Main(usize),
    /// Cylinder `k`'s big end (crank pin - rod).
    BigEnd(usize),
    /// Cylinder `k`'s small end (rod - piston pin).
    SmallEnd(usize),
    /// Cylinder `k`'s piston slide.
    Piston(usize),
}

impl Role {
    /// The joint's group, naming it in a model error and in law-set groups.
    pub(crate) fn group(self) -> &'static str {
        match self {
            Role::Main(_) => "main_*",
            Role::BigEnd(_) => "big_end_*",
            Role::SmallEnd(_) => "small_end_*",
            Role::Piston(_) => "piston_*",
        }
    }

    /// The cylinder whose gas state the joint's laws see (the mains: cylinder 1's).
    pub(crate) fn cylinder(self) -> usize {
        match self {
            Role::Main(_) => 0,
            Role::BigEnd(k) | Role::SmallEnd(k) | Role::Piston(k) => k,
        }
    }

    /// Which of the joint's bodies is the inner member: the crank's journal (A) in a main
    /// bearing, the crank pin (B, the crank) in the big end, the piston pin (A, the piston) in
    /// the small end, the piston (A) in the cylinder.
    pub(crate) fn inner(self) -> tribo_plugin_api::InnerBody {
        match self {
            Role::BigEnd(_) => tribo_plugin_api::InnerBody::B,
            _ => tribo_plugin_api::InnerBody::A,
        }
    }

    /// Revolute for bearings and pins, prismatic for a piston slide: what a law is told.
    pub(crate) fn kind(self) -> tribo_plugin_api::JointKind {
        match self {
            Role::Piston(_) => tribo_plugin_api::JointKind::Prismatic,
            _ => tribo_plugin_api::JointKind::Revolute,
        }
    }
}

/// A joint's two bodies at one instant: body A's and body B's (angle, velocity) (rad, rad/s;
/// a slide's position along its axis, m, and velocity, m/s). The joint's relative velocity is
/// A's velocity minus B's.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Bodies {
    pub(super) a: (f64, f64),
    pub(super) b: (f64, f64),
}

impl Bodies {
    /// The relative velocity, body A's minus body B's: the one place it is computed.
    #[inline(always)]
    pub(super) fn relative(&self) -> f64 {
        self.a.1 - self.b.1
    }
}

/// How the crank is driven at an evaluation: its acceleration is known (prescribed crank,
/// steady state), or a torque is applied and the acceleration follows from the dynamics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Control {
    /// Crank acceleration, rad/s^2.
    Acceleration(f64),
    /// Drive torque on the crank, N m.
    Torque(f64),
    /// An elastic crankshaft: each throw driven by the torque of the shaft's sections on it,
    /// set on the crank model before the evaluation (`Crank::set_throws`).
    Throws,
}
