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
/// travel from TDC, the 4-stroke cycle angle); version 1 is its first 16 fields. Version 3
/// appended both bodies' angles and speeds, the inner body, the bearing type and the load on
/// the inner member to [`LawInput`], the load derivative and the film diagnostics to
/// [`LawOutput`], the suitability bits ([`SUITS_PLAIN`], ...) and batched calls.
pub const CONTRACT_VERSION: u32 = 3;

/// The oldest contract version the host still loads. An older library sees the first fields
/// of the same [`LawInput`] (C: each older struct is a prefix of the current one; Rust: the
/// frozen modules [`v1`] and [`v2`]), and the host fills in the rest of its [`LawOutput`], so
/// it gives exactly the results it gave before.
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

/// What the rig declares a joint's bearing to be ([`LawInput::bearing_type`], contract version
/// 3): so a law can tell a journal from a rolling-element bearing, and the host can warn when
/// a law that does not suit it is put there.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum BearingType {
    /// The rig does not say.
    #[default]
    Unspecified = 0,
    /// A plain (hydrodynamic journal) bearing: a shell or bush on an oil film.
    Plain = 1,
    /// A rolling-element bearing (balls, rollers, needles).
    Rolling = 2,
    /// A sliding contact along an axis: piston skirt, rings, any prismatic joint.
    Slide = 3,
}

impl BearingType {
    /// Decode the `u32` that travels in [`LawInput::bearing_type`].
    pub fn from_u32(raw: u32) -> Option<Self> {
        match raw {
            0 => Some(Self::Unspecified),
            1 => Some(Self::Plain),
            2 => Some(Self::Rolling),
            3 => Some(Self::Slide),
            _ => None,
        }
    }

    /// The word rig files use (`plain`, `rolling`, `slide`, `unspecified`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Unspecified => "unspecified",
            Self::Plain => "plain",
            Self::Rolling => "rolling",
            Self::Slide => "slide",
        }
    }

    /// The [`SUITS_PLAIN`]-style bit a law sets to say it suits this bearing type (0 for
    /// `Unspecified`, which every law suits).
    pub fn suits_bit(self) -> u32 {
        match self {
            Self::Unspecified => 0,
            Self::Plain => SUITS_PLAIN,
            Self::Rolling => SUITS_ROLLING,
            Self::Slide => SUITS_SLIDE,
        }
    }
}

/// Which of a joint's two bodies is the inner member ([`LawInput::inner_body`], contract
/// version 3): the journal, crank pin, piston pin or piston, as opposed to the shell, eye or
/// bore around it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum InnerBody {
    /// Body A is the inner member.
    #[default]
    A = 0,
    /// Body B is the inner member.
    B = 1,
}

impl InnerBody {
    /// Decode the `u32` that travels in [`LawInput::inner_body`].
    pub fn from_u32(raw: u32) -> Option<Self> {
        match raw {
            0 => Some(Self::A),
            1 => Some(Self::B),
            _ => None,
        }
    }
}

/// Suitability bit (contract version 3): the law models plain (hydrodynamic journal) bearings.
pub const SUITS_PLAIN: u32 = 1;
/// Suitability bit: the law models rolling-element bearings.
pub const SUITS_ROLLING: u32 = 2;
/// Suitability bit: the law models sliding contacts (piston skirt, rings).
pub const SUITS_SLIDE: u32 = 4;
/// Every suitability bit the contract defines.
pub const SUITS_ALL: u32 = SUITS_PLAIN | SUITS_ROLLING | SUITS_SLIDE;

/// Whether a law declaring `suits` (a set of `SUITS_*` bits, 0 = undeclared) suits a joint of
/// bearing type `bearing`: an undeclared law suits everything, and every law suits a joint
/// whose type the rig does not give.
pub fn suits(suits: u32, bearing: BearingType) -> bool {
    suits == 0 || bearing == BearingType::Unspecified || suits & bearing.suits_bit() != 0
}

/// The bearing types `suits` names, as the words rig files use (`["plain", "slide"]`; empty
/// for 0, any), for JSON listings.
pub fn suits_words(suits: u32) -> Vec<&'static str> {
    [BearingType::Plain, BearingType::Rolling, BearingType::Slide]
        .into_iter()
        .filter(|b| suits & b.suits_bit() != 0)
        .map(BearingType::as_str)
        .collect()
}

/// `suits` in words (`plain bearings, slides`; `any` for 0), for listings and warnings.
pub fn suits_text(suits: u32) -> String {
    if suits == 0 {
        return "any".into();
    }
    let mut words: Vec<String> = suits_words(suits)
        .into_iter()
        .map(|w| match w {
            "slide" => "slides".to_string(),
            bearing => format!("{bearing} bearings"),
        })
        .collect();
    if suits & !SUITS_ALL != 0 {
        words.push(format!("undefined bits {:#x}", suits & !SUITS_ALL));
    }
    words.join(", ")
}

/// Everything a law may depend on, for one joint at one instant. SI units throughout except
/// the oil temperature, which tribologists quote in degrees Celsius.
///
/// Bodies: every joint connects a body A and a body B, and `relative_velocity` is body A's
/// velocity minus body B's. Main bearing: A crank, B block; big end: A rod, B crank; small end:
/// A piston, B rod; piston slide: A piston, B cylinder (the same per cylinder and per main on
/// an engine).
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
    // Contract version 3 from here on: a version-2 law never reads past `cycle_angle_rad`.
    /// Body A's position: revolute, its absolute angle in the plane, rad; prismatic, its
    /// position along the slide axis, m.
    pub body_a_angle: f64,
    /// Body A's absolute velocity: rad/s (revolute) or m/s along the slide axis (prismatic).
    /// `relative_velocity == body_a_velocity - body_b_velocity`.
    pub body_a_velocity: f64,
    /// Body B's position, as [`LawInput::body_a_angle`].
    pub body_b_angle: f64,
    /// Body B's absolute velocity, as [`LawInput::body_a_velocity`].
    pub body_b_velocity: f64,
    /// [`InnerBody`] as `u32`: 0 body A is the inner member (journal, crank pin, piston pin,
    /// piston), 1 body B is.
    pub inner_body: u32,
    /// [`BearingType`] as `u32`: 0 unspecified, 1 plain, 2 rolling element, 3 slide; what the
    /// rig declares for the joint.
    pub bearing_type: u32,
    /// The force the outer member exerts on the inner one, x component, N: global x for a
    /// revolute joint, along the slide axis for a prismatic one.
    pub load_on_inner_x_n: f64,
    /// The force the outer member exerts on the inner one, y component, N: global y for a
    /// revolute joint; for a prismatic one normal to the slide axis, signed (the side thrust,
    /// with the side it pushes towards).
    pub load_on_inner_y_n: f64,
}

/// The frozen contract version 2, kept so libraries built against it load and run unchanged:
/// its input is the first fields of [`LawInput`], its output the first fields of
/// [`LawOutput`].
pub mod v2 {
    use abi_stable::StableAbi;

    /// The flag bits version 2 (and 1) defined: the host clears every other bit of an older
    /// law's output.
    pub const FLAGS: u32 =
        super::HAS_COEFFICIENT | super::HAS_DUTY_PARAMETER | super::HAS_DERIVATIVE;

    /// Contract version 2's law input: the first fields of [`super::LawInput`], in the same
    /// order. Its name must stay `LawInput`: abi_stable compares type names when it checks a
    /// version-2 Rust library's layout.
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
        /// See [`super::LawInput::cylinder_pressure_pa`].
        pub cylinder_pressure_pa: f64,
        /// See [`super::LawInput::crankcase_pressure_pa`].
        pub crankcase_pressure_pa: f64,
        /// See [`super::LawInput::piston_from_tdc_m`].
        pub piston_from_tdc_m: f64,
        /// See [`super::LawInput::cycle_angle_rad`].
        pub cycle_angle_rad: f64,
    }

    /// Contract version 2's law output (also version 1's): the first fields of
    /// [`super::LawOutput`]. Its name must stay `LawOutput`, as for the input.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, PartialEq, StableAbi)]
    pub struct LawOutput {
        /// See [`super::LawOutput::force`].
        pub force: f64,
        /// See [`super::LawOutput::coefficient`].
        pub coefficient: f64,
        /// See [`super::LawOutput::duty_parameter`].
        pub duty_parameter: f64,
        /// See [`super::LawOutput::dforce_dvelocity`].
        pub dforce_dvelocity: f64,
        /// See [`super::LawOutput::regime`].
        pub regime: u32,
        /// See [`super::LawOutput::flags`]; only the bits of [`FLAGS`] mean anything.
        pub flags: u32,
    }

    impl From<&LawInput> for super::LawInput {
        /// The current input rebuilt from a version-2 one, the version-3 fields at rest (both
        /// bodies at zero, body B moving at zero so body A moves at the relative velocity, no
        /// load on the inner member, bearing unspecified): what a version-2 Rust library hands
        /// its law.
        fn from(v2: &LawInput) -> Self {
            let mut input = super::LawInput::at_rest(super::JointKind::Revolute);
            input.joint_kind = v2.joint_kind;
            input.reserved = v2.reserved;
            input.relative_velocity = v2.relative_velocity;
            input.sliding_velocity_m_s = v2.sliding_velocity_m_s;
            input.normal_load_n = v2.normal_load_n;
            input.reaction_x_n = v2.reaction_x_n;
            input.reaction_y_n = v2.reaction_y_n;
            input.reaction_moment_nm = v2.reaction_moment_nm;
            input.contact_radius_m = v2.contact_radius_m;
            input.contact_length_m = v2.contact_length_m;
            input.oil_temp_c = v2.oil_temp_c;
            input.viscosity_pa_s = v2.viscosity_pa_s;
            input.engine_speed_rad_s = v2.engine_speed_rad_s;
            input.crank_angle_rad = v2.crank_angle_rad;
            input.time_s = v2.time_s;
            input.dt_s = v2.dt_s;
            input.cylinder_pressure_pa = v2.cylinder_pressure_pa;
            input.crankcase_pressure_pa = v2.crankcase_pressure_pa;
            input.piston_from_tdc_m = v2.piston_from_tdc_m;
            input.cycle_angle_rad = v2.cycle_angle_rad;
            input.body_a_velocity = v2.relative_velocity;
            input
        }
    }

    impl From<&super::LawOutput> for LawOutput {
        /// What a version-2 law returns of a current output: its first fields, the flags
        /// limited to [`FLAGS`].
        fn from(out: &super::LawOutput) -> Self {
            Self {
                force: out.force,
                coefficient: out.coefficient,
                duty_parameter: out.duty_parameter,
                dforce_dvelocity: out.dforce_dvelocity,
                regime: out.regime,
                flags: out.flags & FLAGS,
            }
        }
    }

    impl From<&LawOutput> for super::LawOutput {
        /// A version-2 law's output as the host reads it: the version-3 fields zero and the
        /// flags limited to the bits version 2 knew ([`FLAGS`]), so no stray bit claims a
        /// diagnostic the law never computed.
        fn from(v2: &LawOutput) -> Self {
            let mut out = super::LawOutput::force(v2.force);
            out.coefficient = v2.coefficient;
            out.duty_parameter = v2.duty_parameter;
            out.dforce_dvelocity = v2.dforce_dvelocity;
            out.regime = v2.regime;
            out.flags = v2.flags & FLAGS;
            out
        }
    }

    // The v2 structs must be prefixes of the current ones, field for field: the host hands a
    // v2 law a view of the current input (`LawInput::as_v2`) and a v2 C law the pointers
    // themselves.
    macro_rules! same_offset {
        ($t:ident: $($f:ident),*) => {
            $(const _: () = assert!(
                std::mem::offset_of!($t, $f) == std::mem::offset_of!(super::$t, $f)
            );)*
        };
    }
    same_offset!(
        LawInput: joint_kind,
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
        dt_s,
        cylinder_pressure_pa,
        crankcase_pressure_pa,
        piston_from_tdc_m,
        cycle_angle_rad
    );
    same_offset!(
        LawOutput: force,
        coefficient,
        duty_parameter,
        dforce_dvelocity,
        regime,
        flags
    );
    const _: () = assert!(std::mem::size_of::<LawInput>() == 152);
    const _: () = assert!(std::mem::size_of::<super::LawInput>() == 208);
    const _: () = assert!(std::mem::size_of::<LawOutput>() == 40);
    const _: () = assert!(std::mem::size_of::<super::LawOutput>() == 88);
    const _: () =
        assert!(std::mem::align_of::<LawInput>() == std::mem::align_of::<super::LawInput>());
    const _: () =
        assert!(std::mem::align_of::<LawOutput>() == std::mem::align_of::<super::LawOutput>());
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
        /// pressures, piston at TDC) and the version-3 fields as for a version-2 input: what a
        /// version-1 Rust library hands its law.
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
            input.body_a_velocity = v1.relative_velocity;
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
    const _: () =
        assert!(std::mem::align_of::<LawInput>() == std::mem::align_of::<super::LawInput>());
}

impl LawInput {
    /// The joint kind, or `None` if the host sent a value the contract does not define.
    pub fn kind(&self) -> Option<JointKind> {
        JointKind::from_u32(self.joint_kind)
    }

    /// The bearing type, or `None` if the host sent a value the contract does not define.
    pub fn bearing(&self) -> Option<BearingType> {
        BearingType::from_u32(self.bearing_type)
    }

    /// Which body is the inner member, or `None` for a value the contract does not define.
    pub fn inner(&self) -> Option<InnerBody> {
        InnerBody::from_u32(self.inner_body)
    }

    /// A neutral input for a joint of `kind`: everything zero, 40 C oil, both pressures
    /// atmospheric, body A the inner member, the bearing unspecified. Tests and tools fill in
    /// the fields they care about.
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
            body_a_angle: 0.0,
            body_a_velocity: 0.0,
            body_b_angle: 0.0,
            body_b_velocity: 0.0,
            inner_body: InnerBody::A as u32,
            bearing_type: BearingType::Unspecified as u32,
            load_on_inner_x_n: 0.0,
            load_on_inner_y_n: 0.0,
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

    /// This input as contract version 2 sees it: its first fields, without copying.
    #[inline(always)]
    pub fn as_v2(&self) -> &v2::LawInput {
        // SAFETY: as for `as_v1`: `v2::LawInput`'s fields are the first fields of `LawInput`
        // at the same offsets, with the same alignment (asserted at compile time in `v2`).
        unsafe { &*(self as *const LawInput).cast::<v2::LawInput>() }
    }

    /// Set the relative velocity and derive the signed sliding velocity from the joint kind and
    /// the contact radius, the one place this relation is written down. Body B keeps its
    /// velocity and body A's becomes body B's plus `relative_velocity` (so the two agree with
    /// it to rounding; exactly when body B is at rest, as in [`LawInput::at_rest`]).
    pub fn with_velocity(mut self, relative_velocity: f64) -> Self {
        self.relative_velocity = relative_velocity;
        self.body_a_velocity = self.body_b_velocity + relative_velocity;
        self.sliding_velocity_m_s = match self.kind() {
            Some(JointKind::Revolute) => relative_velocity * self.contact_radius_m,
            _ => relative_velocity,
        };
        self
    }

    /// Set both bodies' positions and velocities (`(angle, velocity)` of A, then of B) and the
    /// relative and sliding velocity from them: `relative_velocity` is exactly
    /// `body_a_velocity - body_b_velocity`, as the host computes it.
    pub fn with_bodies(mut self, a: (f64, f64), b: (f64, f64)) -> Self {
        (self.body_a_angle, self.body_b_angle) = (a.0, b.0);
        self.body_b_velocity = b.1;
        let rel = a.1 - b.1;
        self = self.with_velocity(rel);
        self.body_a_velocity = a.1;
        self
    }
}

/// [`LawOutput::flags`] bit: `coefficient` holds a value.
pub const HAS_COEFFICIENT: u32 = 1;
/// [`LawOutput::flags`] bit: `duty_parameter` holds a value.
pub const HAS_DUTY_PARAMETER: u32 = 2;
/// [`LawOutput::flags`] bit: `dforce_dvelocity` holds a value.
pub const HAS_DERIVATIVE: u32 = 4;
/// [`LawOutput::flags`] bit (contract version 3): `dforce_dload` holds a value.
pub const HAS_LOAD_DERIVATIVE: u32 = 8;
/// [`LawOutput::flags`] bit (contract version 3): `min_film_m` holds a value.
pub const HAS_MIN_FILM: u32 = 16;
/// [`LawOutput::flags`] bit (contract version 3): `eccentricity_x` and `eccentricity_y` hold
/// a value.
pub const HAS_ECCENTRICITY: u32 = 32;
/// [`LawOutput::flags`] bit (contract version 3): `peak_pressure_pa` holds a value.
pub const HAS_PEAK_PRESSURE: u32 = 64;
/// [`LawOutput::flags`] bit (contract version 3): `asperity_share` holds a value.
pub const HAS_ASPERITY_SHARE: u32 = 128;
/// [`LawOutput::flags`] bit (contract version 3): the output depends on the load only through
/// `normal_load_n`, and affinely. At the same input (and state) but any other load (normal
/// load, components, moment) the law would return the same output but for a force of
/// `force + dforce_dload * (new normal_load_n - normal_load_n)`. The slope must be flagged
/// ([`HAS_LOAD_DERIVATIVE`]); 0 says the output does not depend on the load at all. The host
/// may then compute the output at another load instead of calling the law again: the later
/// rounds of one evaluation's friction/reaction iteration change only the loads. A Coulomb law
/// (`mu N`) or a damper may set it; a law whose coefficient depends on the load may not.
pub const AFFINE_IN_LOAD: u32 = 256;
/// The flag bits of the diagnostics (film, eccentricity, pressure, asperity share): what the
/// host checks for sense and carries into results.
pub const DIAGNOSTIC_FLAGS: u32 =
    HAS_MIN_FILM | HAS_ECCENTRICITY | HAS_PEAK_PRESSURE | HAS_ASPERITY_SHARE;

/// One diagnostic a law reported that makes no physical sense (a negative film, an
/// eccentricity ratio of 1 or more, ...): what it is, its value and what was expected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadDiagnostic {
    /// The output field (`min_film_m`, `eccentricity`, `peak_pressure_pa`, `asperity_share`).
    pub field: &'static str,
    /// The value the law returned (for the eccentricity, the ratio's magnitude).
    pub value: f64,
    /// What the contract allows, in words.
    pub expected: &'static str,
}

impl std::fmt::Display for BadDiagnostic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} = {:e}, expected {}",
            self.field, self.value, self.expected
        )
    }
}

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
    // Contract version 3 from here on: a version-2 law writes nothing past `flags`; the host
    // zeroes the rest and clears the flag bits that version did not know.
    /// Derivative of `force` with respect to `normal_load_n`, the load direction held fixed
    /// (if `HAS_LOAD_DERIVATIVE`): m for a revolute joint (N m per N), dimensionless for a slide.
    pub dforce_dload: f64,
    /// Minimum oil-film thickness, m, `>= 0` (if `HAS_MIN_FILM`).
    pub min_film_m: f64,
    /// Eccentricity ratio e/c of the inner member, x component in the outer member's frame,
    /// `|e| < 1` (if `HAS_ECCENTRICITY`).
    pub eccentricity_x: f64,
    /// Eccentricity ratio, y component in the outer member's frame (if `HAS_ECCENTRICITY`).
    pub eccentricity_y: f64,
    /// Peak oil-film pressure, Pa, `>= 0` (if `HAS_PEAK_PRESSURE`).
    pub peak_pressure_pa: f64,
    /// Fraction of the normal load carried by asperity contact, in `[0, 1]` (if
    /// `HAS_ASPERITY_SHARE`).
    pub asperity_share: f64,
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
            dforce_dload: 0.0,
            min_film_m: 0.0,
            eccentricity_x: 0.0,
            eccentricity_y: 0.0,
            peak_pressure_pa: 0.0,
            asperity_share: 0.0,
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

    /// Attach d(force)/d(normal load).
    pub fn with_load_derivative(mut self, dfdn: f64) -> Self {
        self.dforce_dload = dfdn;
        self.flags |= HAS_LOAD_DERIVATIVE;
        self
    }

    /// Mark the force as affine in the normal load with slope `dfdn`, everything else as
    /// independent of the load ([`AFFINE_IN_LOAD`], with [`HAS_LOAD_DERIVATIVE`]).
    pub fn affine_in_load(self, dfdn: f64) -> Self {
        let mut out = self.with_load_derivative(dfdn);
        out.flags |= AFFINE_IN_LOAD;
        out
    }

    /// The slope of the force in the normal load, if the law marked the output as affine in
    /// it ([`AFFINE_IN_LOAD`] with [`HAS_LOAD_DERIVATIVE`]; the slope finite).
    pub fn load_slope(&self) -> Option<f64> {
        let both = AFFINE_IN_LOAD | HAS_LOAD_DERIVATIVE;
        (self.flags & both == both && self.dforce_dload.is_finite()).then_some(self.dforce_dload)
    }

    /// Attach the minimum film thickness, m.
    pub fn with_min_film(mut self, h_m: f64) -> Self {
        self.min_film_m = h_m;
        self.flags |= HAS_MIN_FILM;
        self
    }

    /// Attach the eccentricity ratio vector (x, y) in the outer member's frame.
    pub fn with_eccentricity(mut self, x: f64, y: f64) -> Self {
        (self.eccentricity_x, self.eccentricity_y) = (x, y);
        self.flags |= HAS_ECCENTRICITY;
        self
    }

    /// Attach the peak film pressure, Pa.
    pub fn with_peak_pressure(mut self, p_pa: f64) -> Self {
        self.peak_pressure_pa = p_pa;
        self.flags |= HAS_PEAK_PRESSURE;
        self
    }

    /// Attach the share of the load carried by asperities, 0 to 1.
    pub fn with_asperity_share(mut self, share: f64) -> Self {
        self.asperity_share = share;
        self.flags |= HAS_ASPERITY_SHARE;
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

    /// d(force)/d(normal load), if the law reported it.
    pub fn load_derivative(&self) -> Option<f64> {
        (self.flags & HAS_LOAD_DERIVATIVE != 0).then_some(self.dforce_dload)
    }

    /// The minimum film thickness, m, if the law reported it.
    pub fn min_film(&self) -> Option<f64> {
        (self.flags & HAS_MIN_FILM != 0).then_some(self.min_film_m)
    }

    /// The eccentricity ratio vector (x, y), if the law reported it.
    pub fn eccentricity(&self) -> Option<(f64, f64)> {
        (self.flags & HAS_ECCENTRICITY != 0).then_some((self.eccentricity_x, self.eccentricity_y))
    }

    /// The peak film pressure, Pa, if the law reported it.
    pub fn peak_pressure(&self) -> Option<f64> {
        (self.flags & HAS_PEAK_PRESSURE != 0).then_some(self.peak_pressure_pa)
    }

    /// The asperity share of the load, if the law reported it.
    pub fn asperity_share(&self) -> Option<f64> {
        (self.flags & HAS_ASPERITY_SHARE != 0).then_some(self.asperity_share)
    }

    /// The first flagged diagnostic that makes no physical sense: not finite, a negative film
    /// or peak pressure, an eccentricity ratio of magnitude 1 or more, an asperity share
    /// outside `[0, 1]`. Unflagged fields are not looked at. The host and `tribo check-law`
    /// both judge diagnostics with this.
    pub fn bad_diagnostic(&self) -> Option<BadDiagnostic> {
        if self.flags & DIAGNOSTIC_FLAGS == 0 {
            return None;
        }
        let bad = |field, value, expected| {
            Some(BadDiagnostic {
                field,
                value,
                expected,
            })
        };
        if let Some(h) = self.min_film().filter(|h| !(h.is_finite() && *h >= 0.0)) {
            return bad("min_film_m", h, "a finite film thickness >= 0 m");
        }
        if let Some((x, y)) = self.eccentricity() {
            let e = x.hypot(y);
            if !(e.is_finite() && e < 1.0) {
                return bad(
                    "eccentricity",
                    e,
                    "a finite eccentricity ratio of magnitude < 1 (the journal inside its clearance)",
                );
            }
        }
        if let Some(p) = self
            .peak_pressure()
            .filter(|p| !(p.is_finite() && *p >= 0.0))
        {
            return bad("peak_pressure_pa", p, "a finite pressure >= 0 Pa");
        }
        if let Some(s) = self
            .asperity_share()
            .filter(|s| !(s.is_finite() && (0.0..=1.0).contains(s)))
        {
            return bad("asperity_share", s, "a fraction in [0, 1]");
        }
        None
    }

    /// This output as contract version 2 wrote it: its first fields, without copying.
    #[inline(always)]
    pub fn as_v2(&self) -> &v2::LawOutput {
        // SAFETY: `v2::LawOutput`'s fields are the first fields of `LawOutput` at the same
        // offsets, with the same alignment (asserted at compile time in `v2`).
        unsafe { &*(self as *const LawOutput).cast::<v2::LawOutput>() }
    }

    /// Keep only what a law built against contract `version` can have written: for versions
    /// before 3 the version-3 fields are zeroed and the flags cut to the bits that version
    /// knew ([`v2::FLAGS`]); a current output is left as it is.
    #[inline(always)]
    pub fn limit_to_version(&mut self, version: u32) {
        if version < 3 {
            *self = LawOutput::from(self.as_v2());
        }
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
    fn bodies_give_the_relative_velocity_exactly() {
        let mut input = LawInput::at_rest(JointKind::Revolute);
        input.contact_radius_m = 0.02;
        // Velocities whose difference rounds: body A's and B's are kept as given, and the
        // relative velocity is their difference as the host computes it.
        let (a, b) = (0.1 + 1e-17, 0.3);
        let i = input.with_bodies((1.0, a), (2.0, b));
        assert_eq!(i.relative_velocity, a - b);
        assert_eq!((i.body_a_velocity, i.body_b_velocity), (a, b));
        assert_eq!((i.body_a_angle, i.body_b_angle), (1.0, 2.0));
        assert_eq!(i.sliding_velocity_m_s, (a - b) * 0.02);
        // From rest, with_velocity moves body A alone, exactly.
        let j = input.with_velocity(-7.25);
        assert_eq!(j.body_a_velocity - j.body_b_velocity, j.relative_velocity);
    }

    #[test]
    fn older_outputs_keep_only_their_fields_and_flags() {
        let out = LawOutput::force(-2.0)
            .with_coefficient(0.1)
            .with_derivative(-3.0)
            .with_load_derivative(0.01)
            .with_min_film(1e-6)
            .with_asperity_share(0.2);
        let mut stray = out;
        stray.flags |= 1 << 20;
        for version in [1, 2] {
            let mut o = stray;
            o.limit_to_version(version);
            assert_eq!(o.flags, HAS_COEFFICIENT | HAS_DERIVATIVE);
            assert_eq!(
                (o.force, o.coefficient, o.dforce_dvelocity),
                (-2.0, 0.1, -3.0)
            );
            assert_eq!(
                (o.dforce_dload, o.min_film_m, o.asperity_share),
                (0.0, 0.0, 0.0)
            );
            assert_eq!(o.load_derivative(), None);
        }
        let mut current = stray;
        current.limit_to_version(CONTRACT_VERSION);
        assert_eq!(current, stray);
        // The frozen view is the prefix, field for field.
        assert_eq!(out.as_v2().force, -2.0);
        assert_eq!(
            v2::LawOutput::from(&stray).flags,
            HAS_COEFFICIENT | HAS_DERIVATIVE
        );
    }

    #[test]
    fn diagnostics_are_judged_only_when_flagged_and_by_their_physics() {
        let ok = LawOutput::force(0.0)
            .with_min_film(0.0)
            .with_eccentricity(0.6, -0.79)
            .with_peak_pressure(0.0)
            .with_asperity_share(1.0);
        assert_eq!(ok.bad_diagnostic(), None);
        let mut unflagged = LawOutput::force(0.0);
        unflagged.min_film_m = -1.0;
        unflagged.eccentricity_x = 5.0;
        unflagged.asperity_share = f64::NAN;
        assert_eq!(unflagged.bad_diagnostic(), None);
        for (out, field) in [
            (ok.with_min_film(-1e-9), "min_film_m"),
            (ok.with_min_film(f64::INFINITY), "min_film_m"),
            (ok.with_eccentricity(0.6, 0.8), "eccentricity"),
            (ok.with_eccentricity(f64::NAN, 0.0), "eccentricity"),
            (ok.with_peak_pressure(-1.0), "peak_pressure_pa"),
            (ok.with_asperity_share(1.0 + 1e-12), "asperity_share"),
            (ok.with_asperity_share(-0.1), "asperity_share"),
        ] {
            let bad = out.bad_diagnostic().map(|b| b.field);
            assert_eq!(bad, Some(field), "{out:?}");
        }
    }

    #[test]
    fn suitability_bits() {
        assert!(suits(0, BearingType::Plain));
        assert!(suits(SUITS_ROLLING, BearingType::Unspecified));
        assert!(suits(SUITS_ROLLING, BearingType::Rolling));
        assert!(!suits(SUITS_ROLLING, BearingType::Plain));
        assert!(!suits(SUITS_PLAIN | SUITS_ROLLING, BearingType::Slide));
        assert_eq!(suits_text(0), "any");
        assert_eq!(
            suits_text(SUITS_PLAIN | SUITS_SLIDE),
            "plain bearings, slides"
        );
        for raw in 0..4 {
            let b = BearingType::from_u32(raw).map(|b| b as u32);
            assert_eq!(b, Some(raw));
        }
        assert_eq!(BearingType::from_u32(4), None);
        assert_eq!(InnerBody::from_u32(2), None);
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
