//! The data that crosses the plugin boundary on every evaluation.
//!
//! These types are `#[repr(C)]` and mirrored field for field by `include/tribo_law.h` (and by the
//! Fortran module `include/tribo_law.f90`), so a law written in C, C++ or Fortran sees exactly
//! what a Rust law sees. Enumerations travel as `u32` because a foreign library could hand back
//! any integer; the accessors turn them into Rust enums and reject values the contract does not
//! define. Every struct and constant here is checked against the header and the Fortran module
//! by `plugin-api/tests/header.rs`.

use std::ffi::c_char;

use abi_stable::StableAbi;
use serde::{Deserialize, Serialize};

/// Version of the law contract (the layout of [`LawInput`], [`LawOutput`], the C symbols and the
/// Rust module). A library built against another version is refused at load time.
///
/// Rule: any change a plugin could observe (a field added, moved or re-interpreted, a symbol
/// added or changed) bumps this number. Additions are not made silently "compatible": an old
/// plugin cannot know what a new field means, so the host keeps an adapter for every version it
/// still accepts ([`OLDEST_CONTRACT_VERSION`]).
///
/// Version 2 appended the gas state to [`LawInput`] (cylinder and crankcase pressure, piston
/// travel from TDC, the 4-stroke cycle angle); version 1 is its first 16 fields.
pub const CONTRACT_VERSION: u32 = 2;

/// The oldest contract version the host still loads. A version-1 library sees the first
/// fields of the same [`LawInput`] (C: the v1 struct is a prefix of the v2 struct; Rust: the
/// frozen [`v1`] module), so it gives exactly the results it gave before version 2.
pub const OLDEST_CONTRACT_VERSION: u32 = 1;

/// Absolute pressure the host reports for the cylinder and the crankcase of a rig without gas
/// loads: the standard atmosphere, Pa (ISO 2533).
pub const STANDARD_ATMOSPHERE_PA: f64 = 101_325.0;

/// Kind of joint a law is attached to; it decides the units of velocity and force.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotation about an axis: relative velocity in rad/s, the law returns a torque in N m.
    Revolute = 0,
    /// Translation along an axis: relative velocity in m/s, the law returns a force in N.
    Prismatic = 1,
}

impl JointKind {
    /// Decode the `u32` that travels in [`LawInput::joint_kind`].
    pub fn from_u32(raw: u32) -> Option<Self> {
        match raw {
            0 => Some(Self::Revolute),
            1 => Some(Self::Prismatic),
            _ => None,
        }
    }
}

/// Lubrication regime an evaluation fell in, as the law judges it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Regime {
    /// The law has no notion of regime (dry Coulomb, a viscous damper).
    #[default]
    None = 0,
    /// Asperity contact carries the load; the coefficient is the boundary value.
    Boundary = 1,
    /// Load shared between asperities and the oil film.
    Mixed = 2,
    /// A full film separates the surfaces; friction is viscous shear.
    Hydrodynamic = 3,
}

impl Regime {
    /// Decode the `u32` that travels in [`LawOutput::regime`].
    pub fn from_u32(raw: u32) -> Option<Self> {
        match raw {
            0 => Some(Self::None),
            1 => Some(Self::Boundary),
            2 => Some(Self::Mixed),
            3 => Some(Self::Hydrodynamic),
            _ => None,
        }
    }
}

/// Everything a law may depend on, for one joint at one instant. SI units throughout except
/// the oil temperature, which tribologists quote in degrees Celsius.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, StableAbi)]
pub struct LawInput {
    /// [`JointKind`] as `u32` (0 revolute, 1 prismatic).
    pub joint_kind: u32,
    /// Explicit padding so C and Rust agree on the layout; always zero.
    pub reserved: u32,
    /// Relative velocity across the joint, signed: rad/s (revolute) or m/s (prismatic).
    pub relative_velocity: f64,
    /// Signed sliding velocity at the contact surface in m/s: `relative_velocity * contact_radius_m`
    /// for a revolute joint, `relative_velocity` for a prismatic one. Its magnitude is the sliding speed.
    pub sliding_velocity_m_s: f64,
    /// Normal load on the contact from the joint reaction, N, never negative: the magnitude of
    /// the radial reaction (revolute) or of the lateral reaction (prismatic).
    pub normal_load_n: f64,
    /// Reaction component along x, N: global x for a revolute joint, along the slide axis for a
    /// prismatic joint.
    pub reaction_x_n: f64,
    /// Reaction component along y, N: global y for a revolute joint, normal to the slide axis for
    /// a prismatic joint.
    pub reaction_y_n: f64,
    /// In-plane reaction moment carried by a prismatic joint, N m (zero for a revolute joint).
    pub reaction_moment_nm: f64,
    /// Contact radius, m (journal or pin radius; for a slide, half the bore).
    pub contact_radius_m: f64,
    /// Contact length, m (bearing width; for a slide, the skirt or ring height).
    pub contact_length_m: f64,
    /// Oil temperature, degrees Celsius.
    pub oil_temp_c: f64,
    /// Dynamic viscosity of the oil at `oil_temp_c`, Pa s.
    pub viscosity_pa_s: f64,
    /// Engine (crank) speed, rad/s.
    pub engine_speed_rad_s: f64,
    /// Crank angle from top dead centre, rad, in `[0, 2*pi)`.
    pub crank_angle_rad: f64,
    /// Simulation time, s.
    pub time_s: f64,
    /// Size of the current time step, s (zero for a steady-state quadrature).
    pub dt_s: f64,
    // Contract version 2 from here on: a version-1 law never reads past `dt_s`.
    /// Absolute cylinder pressure on the piston crown, Pa (the ambient pressure on a rig
    /// without gas loads). With `crankcase_pressure_pa` it gives the pressure drop across the
    /// rings, the gas load behind a ring.
    pub cylinder_pressure_pa: f64,
    /// Absolute crankcase pressure under the piston, Pa (the ambient pressure unless the rig's
    /// crankcase is sealed or vented).
    pub crankcase_pressure_pa: f64,
    /// Piston travel from top dead centre, m: 0 at TDC, the stroke at BDC.
    pub piston_from_tdc_m: f64,
    /// Crank angle within the 4-stroke cycle, rad, in `[0, 4*pi)`; 0 is the gas-exchange TDC
    /// (start of intake). On a rig without a 4-stroke pressure model: the accumulated crank
    /// angle modulo `4*pi`.
    pub cycle_angle_rad: f64,
}

/// The frozen contract version 1, kept so libraries built against it load and run unchanged.
pub mod v1 {
    use abi_stable::StableAbi;

    /// Contract version 1's law input: the first fields of [`super::LawInput`], in the same
    /// order. Its name must stay `LawInput`: abi_stable compares type names when it checks a
    /// version-1 Rust library's layout.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, PartialEq, StableAbi)]
    pub struct LawInput {
        /// See [`super::LawInput::joint_kind`].
        pub joint_kind: u32,
        /// See [`super::LawInput::reserved`].
        pub reserved: u32,
        /// See [`super::LawInput::relative_velocity`].
        pub relative_velocity: f64,
        /// See [`super::LawInput::sliding_velocity_m_s`].
        pub sliding_velocity_m_s: f64,
        /// See [`super::LawInput::normal_load_n`].
        pub normal_load_n: f64,
        /// See [`super::LawInput::reaction_x_n`].
        pub reaction_x_n: f64,
        /// See [`super::LawInput::reaction_y_n`].
        pub reaction_y_n: f64,
        /// See [`super::LawInput::reaction_moment_nm`].
        pub reaction_moment_nm: f64,
        /// See [`super::LawInput::contact_radius_m`].
        pub contact_radius_m: f64,
        /// See [`super::LawInput::contact_length_m`].
        pub contact_length_m: f64,
        /// See [`super::LawInput::oil_temp_c`].
        pub oil_temp_c: f64,
        /// See [`super::LawInput::viscosity_pa_s`].
        pub viscosity_pa_s: f64,
        /// See [`super::LawInput::engine_speed_rad_s`].
        pub engine_speed_rad_s: f64,
        /// See [`super::LawInput::crank_angle_rad`].
        pub crank_angle_rad: f64,
        /// See [`super::LawInput::time_s`].
        pub time_s: f64,
        /// See [`super::LawInput::dt_s`].
        pub dt_s: f64,
    }

    impl From<&LawInput> for super::LawInput {
        /// The current input rebuilt from a version-1 one, the gas fields at rest (atmospheric
        /// pressures, piston at TDC): what a version-1 Rust library hands its law.
        fn from(v1: &LawInput) -> Self {
            let mut input = super::LawInput::at_rest(super::JointKind::Revolute);
            input.joint_kind = v1.joint_kind;
            input.reserved = v1.reserved;
            input.relative_velocity = v1.relative_velocity;
            input.sliding_velocity_m_s = v1.sliding_velocity_m_s;
            input.normal_load_n = v1.normal_load_n;
            input.reaction_x_n = v1.reaction_x_n;
            input.reaction_y_n = v1.reaction_y_n;
            input.reaction_moment_nm = v1.reaction_moment_nm;
            input.contact_radius_m = v1.contact_radius_m;
            input.contact_length_m = v1.contact_length_m;
            input.oil_temp_c = v1.oil_temp_c;
            input.viscosity_pa_s = v1.viscosity_pa_s;
            input.engine_speed_rad_s = v1.engine_speed_rad_s;
            input.crank_angle_rad = v1.crank_angle_rad;
            input.time_s = v1.time_s;
            input.dt_s = v1.dt_s;
            input
        }
    }

    // The v1 input must be a prefix of the v2 input, field for field: the host hands a v1 law
    // a view of the v2 input (`LawInput::as_v1`) and a v1 C law the v2 pointer itself.
    macro_rules! same_offset {
        ($($f:ident),*) => {
            $(const _: () = assert!(
                std::mem::offset_of!(LawInput, $f) == std::mem::offset_of!(super::LawInput, $f)
            );)*
        };
    }
    same_offset!(
        joint_kind,
        reserved,
        relative_velocity,
        sliding_velocity_m_s,
        normal_load_n,
        reaction_x_n,
        reaction_y_n,
        reaction_moment_nm,
        contact_radius_m,
        contact_length_m,
        oil_temp_c,
        viscosity_pa_s,
        engine_speed_rad_s,
        crank_angle_rad,
        time_s,
        dt_s
    );
    const _: () = assert!(std::mem::size_of::<LawInput>() == 120);
    const _: () = assert!(std::mem::size_of::<super::LawInput>() == 152);
    const _: () =
        assert!(std::mem::align_of::<LawInput>() == std::mem::align_of::<super::LawInput>());
}

impl LawInput {
    /// The joint kind, or `None` if the host sent a value the contract does not define.
    pub fn kind(&self) -> Option<JointKind> {
        JointKind::from_u32(self.joint_kind)
    }

    /// A neutral input for a joint of `kind`: everything zero, 40 C oil, both pressures
    /// atmospheric. Tests and tools fill in the fields they care about.
    pub fn at_rest(kind: JointKind) -> Self {
        Self {
            joint_kind: kind as u32,
            reserved: 0,
            relative_velocity: 0.0,
            sliding_velocity_m_s: 0.0,
            normal_load_n: 0.0,
            reaction_x_n: 0.0,
            reaction_y_n: 0.0,
            reaction_moment_nm: 0.0,
            contact_radius_m: 0.0,
            contact_length_m: 0.0,
            oil_temp_c: 40.0,
            viscosity_pa_s: 0.0,
            engine_speed_rad_s: 0.0,
            crank_angle_rad: 0.0,
            time_s: 0.0,
            dt_s: 0.0,
            cylinder_pressure_pa: STANDARD_ATMOSPHERE_PA,
            crankcase_pressure_pa: STANDARD_ATMOSPHERE_PA,
            piston_from_tdc_m: 0.0,
            cycle_angle_rad: 0.0,
        }
    }

    /// This input as contract version 1 sees it: its first fields, without copying.
    #[inline(always)]
    pub fn as_v1(&self) -> &v1::LawInput {
        // SAFETY: both types are `repr(C)`, `v1::LawInput`'s fields are the first fields of
        // `LawInput` at the same offsets (asserted at compile time in `v1`), and the
        // alignments are equal, so a `LawInput` reference is a valid `v1::LawInput` reference.
        unsafe { &*(self as *const LawInput).cast::<v1::LawInput>() }
    }

    /// Set the relative velocity and derive the signed sliding velocity from the joint kind and
    /// the contact radius, the one place this relation is written down.
    pub fn with_velocity(mut self, relative_velocity: f64) -> Self {
        self.relative_velocity = relative_velocity;
        self.sliding_velocity_m_s = match self.kind() {
            Some(JointKind::Revolute) => relative_velocity * self.contact_radius_m,
            _ => relative_velocity,
        };
        self
    }
}

/// [`LawOutput::flags`] bit: `coefficient` holds a value.
pub const HAS_COEFFICIENT: u32 = 1;
/// [`LawOutput::flags`] bit: `duty_parameter` holds a value.
pub const HAS_DUTY_PARAMETER: u32 = 2;
/// [`LawOutput::flags`] bit: `dforce_dvelocity` holds a value.
pub const HAS_DERIVATIVE: u32 = 4;

/// What a law returns for one evaluation. Optional quantities are marked present by bits in
/// `flags`, so no value (not even NaN) has a special meaning.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, StableAbi)]
pub struct LawOutput {
    /// Friction/damping force (N, prismatic) or torque (N m, revolute) acting on the joint's
    /// relative motion: it opposes it, so `force * relative_velocity <= 0` for a dissipative law.
    pub force: f64,
    /// Effective friction coefficient, dimensionless (if `HAS_COEFFICIENT`).
    pub coefficient: f64,
    /// Duty (Hersey) parameter the law used, dimensionless (if `HAS_DUTY_PARAMETER`).
    pub duty_parameter: f64,
    /// Derivative of `force` with respect to `relative_velocity` (if `HAS_DERIVATIVE`).
    pub dforce_dvelocity: f64,
    /// [`Regime`] as `u32`.
    pub regime: u32,
    /// Bit set of `HAS_*` flags.
    pub flags: u32,
}

impl LawOutput {
    /// An output carrying only a force (or torque); add the optional parts with the `with_*`
    /// methods.
    pub fn force(force: f64) -> Self {
        Self {
            force,
            coefficient: 0.0,
            duty_parameter: 0.0,
            dforce_dvelocity: 0.0,
            regime: Regime::None as u32,
            flags: 0,
        }
    }

    /// Attach the effective friction coefficient.
    pub fn with_coefficient(mut self, mu: f64) -> Self {
        self.coefficient = mu;
        self.flags |= HAS_COEFFICIENT;
        self
    }

    /// Attach the duty parameter.
    pub fn with_duty_parameter(mut self, h: f64) -> Self {
        self.duty_parameter = h;
        self.flags |= HAS_DUTY_PARAMETER;
        self
    }

    /// Attach d(force)/d(relative velocity).
    pub fn with_derivative(mut self, dfdv: f64) -> Self {
        self.dforce_dvelocity = dfdv;
        self.flags |= HAS_DERIVATIVE;
        self
    }

    /// Attach the lubrication regime.
    pub fn with_regime(mut self, regime: Regime) -> Self {
        self.regime = regime as u32;
        self
    }

    /// The effective coefficient, if the law reported one.
    pub fn coefficient(&self) -> Option<f64> {
        (self.flags & HAS_COEFFICIENT != 0).then_some(self.coefficient)
    }

    /// The duty parameter, if the law reported one.
    pub fn duty_parameter(&self) -> Option<f64> {
        (self.flags & HAS_DUTY_PARAMETER != 0).then_some(self.duty_parameter)
    }

    /// d(force)/d(velocity), if the law reported it.
    pub fn derivative(&self) -> Option<f64> {
        (self.flags & HAS_DERIVATIVE != 0).then_some(self.dforce_dvelocity)
    }

    /// The regime, or `None` if the law returned a value the contract does not define.
    pub fn regime(&self) -> Option<Regime> {
        Regime::from_u32(self.regime)
    }
}

/// `tribo_param_spec` of the C header: one scalar parameter as a C law describes it. The strings
/// are NUL-terminated and owned by the law (static storage).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct CParamSpec {
    /// Key in the TOML table.
    pub name: *const c_char,
    /// Unit in plain text, `-` for dimensionless.
    pub unit: *const c_char,
    /// Physical meaning.
    pub doc: *const c_char,
    /// Value used when the user gives none.
    pub default_value: f64,
    /// Smallest allowed value, inclusive.
    pub min: f64,
    /// Largest allowed value, inclusive.
    pub max: f64,
}

/// `tribo_law_description` of the C header: what `tribo_law_describe` returns. It must stay
/// valid while the library is loaded.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct CLawDescription {
    /// Unique law name, NUL-terminated.
    pub name: *const c_char,
    /// Implementation version, NUL-terminated.
    pub version: *const c_char,
    /// One-line summary, NUL-terminated.
    pub summary: *const c_char,
    /// Number of entries at `params`.
    pub n_params: u32,
    /// The parameters, in the order `tribo_law_create` receives their values.
    pub params: *const CParamSpec,
}

/// A sign function that is smooth through zero: `x / sqrt(x^2 + eps^2)`. Laws share it so the
/// regularisation of the Coulomb discontinuity is written once; `eps` is the velocity scale below
/// which friction fades linearly to zero. Returns the value and its derivative in `x`.
pub fn smooth_sign(x: f64, eps: f64) -> (f64, f64) {
    if eps <= 0.0 {
        return (
            if x > 0.0 {
                1.0
            } else if x < 0.0 {
                -1.0
            } else {
                0.0
            },
            0.0,
        );
    }
    let r = (x * x + eps * eps).sqrt();
    (x / r, eps * eps / (r * r * r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_sign_limits_and_derivative() {
        let eps = 1e-3;
        assert!((smooth_sign(1.0, eps).0 - 1.0).abs() < 1e-6);
        assert!((smooth_sign(-1.0, eps).0 + 1.0).abs() < 1e-6);
        assert_eq!(smooth_sign(0.0, eps).0, 0.0);
        for &x in &[-2e-3, -1e-4, 0.0, 3e-4, 5e-2] {
            let h = 1e-9;
            let fd = (smooth_sign(x + h, eps).0 - smooth_sign(x - h, eps).0) / (2.0 * h);
            assert!((fd - smooth_sign(x, eps).1).abs() < 1e-4 * (1.0 + fd.abs()));
        }
    }

    #[test]
    fn revolute_sliding_velocity_uses_radius() {
        let mut input = LawInput::at_rest(JointKind::Revolute);
        input.contact_radius_m = 0.02;
        let input = input.with_velocity(300.0);
        assert_eq!(input.sliding_velocity_m_s, 300.0 * 0.02);
    }

    #[test]
    fn unknown_enum_values_are_rejected() {
        assert_eq!(JointKind::from_u32(7), None);
        let mut out = LawOutput::force(1.0);
        out.regime = 9;
        assert_eq!(out.regime(), None);
        assert_eq!(out.coefficient(), None);
    }
}
