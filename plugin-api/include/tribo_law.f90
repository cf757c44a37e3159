! tribo_law.f90 - the Fortran interface to Tribo's law plugin ABI, contract version 3.
!
! The Fortran mirror of tribo_law.h (read its opening comment: the call order, the state rules
! and the rules every law keeps). It gives, through iso_c_binding:
!
!   - the constants of the header (contract version, joint kinds, regimes, output flags,
!     bearing types, inner body, suitability bits);
!   - bind(c) derived types laid out exactly as the header's structs: tribo_law_input,
!     tribo_law_output, tribo_param_spec, tribo_law_description (checked field by field against
!     the C and Rust layouts by plugin-api/tests/header.rs);
!   - abstract interfaces of the seven functions a law exports and of the two optional ones
!     (tribo_law_evaluate_many_fn, tribo_law_suits_fn), so a test program can check a law's
!     signatures at compile time (procedure(tribo_law_evaluate_fn), pointer :: p => ...);
!   - tribo_set_error, which writes a message into create()'s error buffer as a C string.
!
! A law implements the seven functions as module procedures with
! bind(c, name="tribo_law_evaluate") and so on; `tribo new-law NAME --lang fortran` writes one.
! Give them Fortran names other than their C names (abi_evaluate, say): Fortran ignores case, so
! a function tribo_law_contract_version would clash with the constant TRIBO_LAW_CONTRACT_VERSION.
! Compile this file with the law (it is a module, so before it) into one shared library:
!
!   gfortran -shared -fPIC -O2 -frecursive tribo_law.f90 my_law.f90 -o libtribo_law_my_law.so
!
! Fortran-specific rules:
!
!   - C's uint32_t is integer(c_int32_t) here (Fortran has no unsigned integers; every value the
!     contract uses is small and positive) and size_t is integer(c_size_t).
!   - The description's strings are C strings with static storage: module variables declared
!     character(kind=c_char, len=...), target, save, ending in c_null_char, passed with c_loc.
!   - Tribo calls evaluate() from several threads at once. Keep no SAVE variables that change,
!     and remember that a local variable initialised in its declaration is implicitly SAVE.
!     Compile with -frecursive so every local lives on the stack.
!   - Never STOP or ERROR STOP: that ends the process running the law (tribo itself, or the
!     study's worker, failing the law set). Return a non-zero status instead.
module tribo_law
  use, intrinsic :: iso_c_binding, only: c_int32_t, c_double, c_ptr, c_size_t, c_char, &
                                         c_null_char
  implicit none
  private

  !> Version of the contract (3: both bodies, the bearing type and the load on the inner member
  !> in tribo_law_input; the load derivative and the diagnostics in tribo_law_output); the host
  !> still loads version-1 and version-2 libraries and refuses newer ones.
  integer(c_int32_t), parameter, public :: TRIBO_LAW_CONTRACT_VERSION = 3

  !> Joint kinds (tribo_law_input%joint_kind).
  integer(c_int32_t), parameter, public :: TRIBO_JOINT_REVOLUTE = 0   ! rad/s in, a torque in N m out
  integer(c_int32_t), parameter, public :: TRIBO_JOINT_PRISMATIC = 1  ! m/s in, a force in N out

  !> Lubrication regimes (tribo_law_output%regime).
  integer(c_int32_t), parameter, public :: TRIBO_REGIME_NONE = 0
  integer(c_int32_t), parameter, public :: TRIBO_REGIME_BOUNDARY = 1
  integer(c_int32_t), parameter, public :: TRIBO_REGIME_MIXED = 2
  integer(c_int32_t), parameter, public :: TRIBO_REGIME_HYDRODYNAMIC = 3

  !> Bits of tribo_law_output%flags: which optional outputs are filled in (combine with ior).
  integer(c_int32_t), parameter, public :: TRIBO_HAS_COEFFICIENT = 1
  integer(c_int32_t), parameter, public :: TRIBO_HAS_DUTY_PARAMETER = 2
  integer(c_int32_t), parameter, public :: TRIBO_HAS_DERIVATIVE = 4
  integer(c_int32_t), parameter, public :: TRIBO_HAS_LOAD_DERIVATIVE = 8    ! version 3
  integer(c_int32_t), parameter, public :: TRIBO_HAS_MIN_FILM = 16          ! version 3
  integer(c_int32_t), parameter, public :: TRIBO_HAS_ECCENTRICITY = 32      ! version 3
  integer(c_int32_t), parameter, public :: TRIBO_HAS_PEAK_PRESSURE = 64     ! version 3
  integer(c_int32_t), parameter, public :: TRIBO_HAS_ASPERITY_SHARE = 128   ! version 3
  !> Version 3: force affine in normal_load_n, slope dforce_dload (flag it too); the rest of
  !> the output independent of the load, so the host may skip calls where only the load changes.
  integer(c_int32_t), parameter, public :: TRIBO_AFFINE_IN_LOAD = 256       ! version 3

  !> Bearing types (tribo_law_input%bearing_type): what the rig declares for the joint.
  integer(c_int32_t), parameter, public :: TRIBO_BEARING_UNSPECIFIED = 0
  integer(c_int32_t), parameter, public :: TRIBO_BEARING_PLAIN = 1     ! hydrodynamic journal
  integer(c_int32_t), parameter, public :: TRIBO_BEARING_ROLLING = 2   ! rolling elements
  integer(c_int32_t), parameter, public :: TRIBO_BEARING_SLIDE = 3     ! piston skirt, rings

  !> Which body is the inner member (tribo_law_input%inner_body); tribo_law.h has the table of
  !> bodies A and B per joint.
  integer(c_int32_t), parameter, public :: TRIBO_INNER_BODY_A = 0
  integer(c_int32_t), parameter, public :: TRIBO_INNER_BODY_B = 1

  !> Bits of tribo_law_suits(): the bearing types a law is made for (0: any joint).
  integer(c_int32_t), parameter, public :: TRIBO_SUITS_PLAIN = 1
  integer(c_int32_t), parameter, public :: TRIBO_SUITS_ROLLING = 2
  integer(c_int32_t), parameter, public :: TRIBO_SUITS_SLIDE = 4

  !> Everything a law may depend on, for one joint at one instant (tribo_law.h has the units).
  type, bind(c), public :: tribo_law_input
    integer(c_int32_t) :: joint_kind          ! TRIBO_JOINT_*
    integer(c_int32_t) :: reserved            ! always 0
    real(c_double) :: relative_velocity       ! rad/s (revolute) or m/s (prismatic), signed
    real(c_double) :: sliding_velocity_m_s    ! signed sliding velocity at the contact, m/s
    real(c_double) :: normal_load_n           ! normal load from the joint reaction, N, >= 0
    real(c_double) :: reaction_x_n            ! reaction x (global x, or along the slide), N
    real(c_double) :: reaction_y_n            ! reaction y (global y, or normal to the slide), N
    real(c_double) :: reaction_moment_nm      ! in-plane reaction moment of a slide, N m
    real(c_double) :: contact_radius_m        ! journal/pin radius, or half the bore, m
    real(c_double) :: contact_length_m        ! bearing width, or skirt/ring height, m
    real(c_double) :: oil_temp_c              ! oil temperature, degrees C
    real(c_double) :: viscosity_pa_s          ! dynamic viscosity at oil_temp_c, Pa s
    real(c_double) :: engine_speed_rad_s      ! crank speed, rad/s
    real(c_double) :: crank_angle_rad         ! crank angle from TDC, rad, [0, 2 pi)
    real(c_double) :: time_s                  ! simulation time, s
    real(c_double) :: dt_s                    ! current step size, s (0 in steady state)
    ! Version 2:
    real(c_double) :: cylinder_pressure_pa    ! absolute pressure on the crown, Pa
    real(c_double) :: crankcase_pressure_pa   ! absolute pressure under the piston, Pa
    real(c_double) :: piston_from_tdc_m       ! piston travel from TDC, m
    real(c_double) :: cycle_angle_rad         ! angle in the 4-stroke cycle, rad, [0, 4 pi)
    ! Version 3 (bodies A and B per joint: the table in tribo_law.h):
    real(c_double) :: body_a_angle            ! body A's absolute angle, rad (slide: position, m)
    real(c_double) :: body_a_velocity         ! body A's velocity, rad/s (slide: m/s)
    real(c_double) :: body_b_angle            ! body B's, as body_a_angle
    real(c_double) :: body_b_velocity         ! body B's; relative_velocity = a - b
    integer(c_int32_t) :: inner_body          ! TRIBO_INNER_BODY_*
    integer(c_int32_t) :: bearing_type        ! TRIBO_BEARING_*
    real(c_double) :: load_on_inner_x_n       ! force of the outer member on the inner one, N:
    real(c_double) :: load_on_inner_y_n       ! global x, y (revolute); along, normal to the slide
  end type tribo_law_input

  !> What a law returns for one evaluation.
  type, bind(c), public :: tribo_law_output
    real(c_double) :: force                   ! N or N m, opposing the motion
    real(c_double) :: coefficient             ! if TRIBO_HAS_COEFFICIENT
    real(c_double) :: duty_parameter          ! if TRIBO_HAS_DUTY_PARAMETER
    real(c_double) :: dforce_dvelocity        ! if TRIBO_HAS_DERIVATIVE
    integer(c_int32_t) :: regime              ! TRIBO_REGIME_*
    integer(c_int32_t) :: flags               ! TRIBO_HAS_* bits
    ! Version 3:
    real(c_double) :: dforce_dload            ! d force / d normal load, if TRIBO_HAS_LOAD_DERIVATIVE
    real(c_double) :: min_film_m              ! minimum film, m, >= 0, if TRIBO_HAS_MIN_FILM
    real(c_double) :: eccentricity_x          ! e/c in the outer member's frame, |e| < 1,
    real(c_double) :: eccentricity_y          ! if TRIBO_HAS_ECCENTRICITY
    real(c_double) :: peak_pressure_pa        ! peak film pressure, Pa, if TRIBO_HAS_PEAK_PRESSURE
    real(c_double) :: asperity_share          ! load share on asperities, [0, 1], if TRIBO_HAS_ASPERITY_SHARE
  end type tribo_law_output

  !> One scalar parameter; the strings are c_loc of NUL-terminated static character variables.
  type, bind(c), public :: tribo_param_spec
    type(c_ptr) :: name                       ! key in the TOML table
    type(c_ptr) :: unit                       ! "-" for dimensionless
    type(c_ptr) :: doc                        ! physical meaning
    real(c_double) :: default_value
    real(c_double) :: min                     ! allowed range, inclusive
    real(c_double) :: max
  end type tribo_param_spec

  !> The law's self-description; a SAVE (module) variable, valid while the library is loaded.
  type, bind(c), public :: tribo_law_description
    type(c_ptr) :: name                       ! unique law name, e.g. "my-law"
    type(c_ptr) :: version                    ! implementation version, e.g. "0.1.0"
    type(c_ptr) :: summary                    ! one line
    integer(c_int32_t) :: n_params
    type(c_ptr) :: params                     ! c_loc of a tribo_param_spec array
  end type tribo_law_description

  !> The seven functions a law exports, and the two optional ones, as tribo_law.h declares them.
  abstract interface
    function tribo_law_contract_version_fn() bind(c) result(version)
      import :: c_int32_t
      integer(c_int32_t) :: version
    end function tribo_law_contract_version_fn

    function tribo_law_describe_fn() bind(c) result(description)
      import :: c_ptr
      type(c_ptr) :: description
    end function tribo_law_describe_fn

    function tribo_law_create_fn(params, n_params, error, error_len) bind(c) result(instance)
      import :: c_double, c_size_t, c_char, c_ptr
      real(c_double), intent(in) :: params(*)
      integer(c_size_t), value :: n_params
      character(kind=c_char), intent(inout) :: error(*)
      integer(c_size_t), value :: error_len
      type(c_ptr) :: instance
    end function tribo_law_create_fn

    function tribo_law_state_size_fn(instance) bind(c) result(n)
      import :: c_ptr, c_size_t
      type(c_ptr), value :: instance
      integer(c_size_t) :: n
    end function tribo_law_state_size_fn

    function tribo_law_evaluate_fn(instance, input, state, output) bind(c) result(status)
      import :: c_ptr, c_int32_t, tribo_law_input, tribo_law_output
      type(c_ptr), value :: instance
      type(tribo_law_input), intent(in) :: input
      type(c_ptr), value :: state               ! const double *, C_NULL_PTR when the size is 0
      type(tribo_law_output), intent(out) :: output
      integer(c_int32_t) :: status
    end function tribo_law_evaluate_fn

    function tribo_law_commit_fn(instance, input, state) bind(c) result(status)
      import :: c_ptr, c_int32_t, tribo_law_input
      type(c_ptr), value :: instance
      type(tribo_law_input), intent(in) :: input
      type(c_ptr), value :: state               ! double *, tribo_law_state_size values
      integer(c_int32_t) :: status
    end function tribo_law_commit_fn

    subroutine tribo_law_destroy_fn(instance) bind(c)
      import :: c_ptr
      type(c_ptr), value :: instance
    end subroutine tribo_law_destroy_fn

    ! Optional (version 3): n inputs at once; input k reads the state at k * state_stride
    ! doubles from `states` (stride 0: one shared state).
    function tribo_law_evaluate_many_fn(instance, n, inputs, states, state_stride, outputs) &
        bind(c) result(status)
      import :: c_ptr, c_size_t, c_int32_t, tribo_law_input, tribo_law_output
      type(c_ptr), value :: instance
      integer(c_size_t), value :: n
      type(tribo_law_input), intent(in) :: inputs(*)
      type(c_ptr), value :: states              ! const double *
      integer(c_size_t), value :: state_stride
      type(tribo_law_output), intent(inout) :: outputs(*)
      integer(c_int32_t) :: status
    end function tribo_law_evaluate_many_fn

    ! Optional (version 3): the TRIBO_SUITS_* bits (0: any joint).
    function tribo_law_suits_fn() bind(c) result(suits)
      import :: c_int32_t
      integer(c_int32_t) :: suits
    end function tribo_law_suits_fn
  end interface

  public :: tribo_law_contract_version_fn, tribo_law_describe_fn, tribo_law_create_fn, &
            tribo_law_state_size_fn, tribo_law_evaluate_fn, tribo_law_commit_fn, &
            tribo_law_destroy_fn, tribo_law_evaluate_many_fn, tribo_law_suits_fn
  public :: tribo_set_error

contains

  !> Copy `message` into create()'s error buffer of `error_len` bytes as a NUL-terminated C
  !> string, cut short if needed. Start it with "PARAM: " to name the parameter at fault.
  subroutine tribo_set_error(error, error_len, message)
    character(kind=c_char), intent(inout) :: error(*)
    integer(c_size_t), intent(in) :: error_len
    character(len=*), intent(in) :: message
    integer(c_size_t) :: i, n
    if (error_len < 1) return
    n = min(int(len(message), c_size_t), error_len - 1)
    do i = 1, n
      error(i) = message(i:i)
    end do
    error(n + 1) = c_null_char
  end subroutine tribo_set_error

end module tribo_law
