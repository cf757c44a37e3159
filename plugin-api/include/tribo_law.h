/*
 * tribo_law.h - the C ABI of a Tribo friction/damping law plugin, contract version 3.
 *
 * A law is a shared library (.so / .dylib / .dll) exporting the seven functions below with
 * C linkage, and optionally two more (tribo_law_evaluate_many, tribo_law_suits). The host (tribo) loads it at run time; nothing else needs rebuilding. Anything
 * that can produce C-callable symbols works: C, C++ (extern "C"), Fortran (bind(c), with the
 * module tribo_law.f90 beside this header). `tribo new-law NAME --lang c|cpp|fortran` writes a
 * working law, its Makefile and a unit test; docs/writing-a-law.md walks through it.
 *
 * Loading order, which the host guarantees:
 *   1. tribo_law_contract_version() is called first, before any other symbol is looked up.
 *      A version newer than the host's TRIBO_LAW_CONTRACT_VERSION, or older than the oldest it
 *      still adapts (1), is refused.
 *   2. tribo_law_describe() gives the name, version, summary and parameters (once per load);
 *      tribo_law_suits(), if exported, the bearing types the law is made for.
 *   3. tribo_law_create() makes an instance from checked parameter values.
 *   4. Per time step: tribo_law_evaluate() any number of times (the host may iterate or reject
 *      the step), or tribo_law_evaluate_many() on several inputs at once if the law exports
 *      it; then tribo_law_commit() once if the step is accepted.
 *   5. tribo_law_destroy() releases the instance.
 *
 * Units are SI (m, kg, s, N, rad/s, Pa s) except the oil temperature in degrees Celsius.
 * Sign convention: the returned force opposes the relative motion, so for a dissipative law
 * force * relative_velocity <= 0.
 *
 * Bodies: every joint joins a body A and a body B; relative_velocity is exactly
 * body_a_velocity - body_b_velocity (the host computes all three from the same numbers).
 *
 *   joint                       body A     body B      inner member (inner_body)
 *   main bearing                crank      block       journal on the crank: A (0)
 *   big end (crank pin)         rod        crank       crank pin: B (1)
 *   small end (piston pin)      piston     rod         piston pin: A (0)
 *   piston slide (prismatic)    piston     cylinder    piston: A (0)
 *
 * On an engine the same holds per cylinder and per main bearing. A revolute joint's angles are
 * absolute angles in the plane (rad); a prismatic joint's "angles" are positions along the
 * slide axis (m) and its velocities m/s.
 *
 * Output: the host hands evaluate() an output that is all zero (force 0, no flags), so a law
 * need only fill in what it computes and set the matching TRIBO_HAS_* bits. Diagnostics
 * (min film, eccentricity, peak pressure, asperity share) must make sense when flagged: finite,
 * film >= 0, |e| < 1, pressure >= 0, asperity share in [0, 1]; the host checks them and ends
 * the run naming the law, the joint and the time if not.
 *
 * State: a law that needs memory (a LuGre bristle deflection, say) declares how many doubles it
 * needs with tribo_law_state_size() (at most 2^20). The HOST owns that array and
 * zero-initialises it; evaluate() must only read it, commit() advances it. An instance must not
 * keep mutable per-step data of its own: the host may evaluate several trial steps and keep none
 * of them. evaluate() must be re-entrant for one instance (it takes a const instance pointer).
 *
 * Parameters: the host parses the user's TOML, checks every name, type and range against the
 * description below, fills in defaults, and passes the values as doubles in the order of
 * `params`. So create() only checks combinations (thresholds in order, say).
 *
 * The rules a law in C, C++ or Fortran must keep (each is a mistake someone made):
 *
 *   - Parameters are doubles only. A C law cannot declare a switch, a list or a word (Rust laws
 *     can); use a number with a documented range, e.g. 0 or 1 for a switch.
 *   - Nothing may unwind or jump across these functions. A C++ exception that escapes one aborts
 *     the process running the law (tribo cannot catch a foreign exception): catch everything
 *     inside each function and return NULL / a non-zero status. Never call exit(), abort(),
 *     Fortran STOP or ERROR STOP, or longjmp out of a call.
 *   - A crash is not contained inside the process that runs the law. tribo compare, fit,
 *     mass-response and sweep run each law set in a worker process: a crash, abort, exit(), hang
 *     (time limit) or runaway memory (memory limit) fails that law set, named with the law and the
 *     library, and the other sets still finish (exit status 1). tribo run and --in-process run the
 *     law inside tribo itself: a crash ends tribo, naming the law. It is never silent, but it loses
 *     the run: return an error status instead.
 *   - Errors are statuses: create() returns NULL with a message starting "PARAM: " when a
 *     parameter is at fault; evaluate() and commit() return non-zero. A NaN or infinite force, or
 *     a stateless law whose force pushes the motion (force * velocity > 0), ends the run with an
 *     error naming the law, the joint, the time and the inputs.
 *   - Threads: the host evaluates many instances at once on several threads (studies run in
 *     parallel) and may call evaluate() on one instance from several threads. Keep no global or
 *     static mutable data (in Fortran: no SAVE variables, and remember that a local variable
 *     initialised in its declaration is implicitly SAVE; compile with -frecursive).
 *   - Standard output belongs to tribo's results: a law must not print there (tribo moves it to
 *     standard error, a worker discards it). Print diagnostics to standard error, sparingly.
 *   - The library file is named for the law: law "my-law" is libtribo_law_my_law.so (.dylib on
 *     macOS, tribo_law_my_law.dll on Windows; "-" becomes "_"). In a plugin directory tribo only
 *     looks at files named libtribo_law_*, opens a file only when its law is asked for, and opens
 *     the file named for the law first. Another name works but is found later.
 *   - One library per law name. Two libraries that provide the law a command asks for are an
 *     error naming both files, in every command (tribo laws refuses any duplicate); remove old
 *     copies from TRIBO_PLUGIN_PATH, --plugin and the tribo executable's directory.
 *   - A plugin is native code run with the user's rights, in tribo or its worker: it is not
 *     sandboxed. Keep plugin directories writable by their owner only.
 *
 * Versions: the contract version changes with any change a plugin could observe (a field added,
 * removed, moved or re-interpreted, a symbol added or changed). The host keeps loading the
 * older versions it knows and adapts them:
 *   version 1: tribo_law_input ended at dt_s. A version-1 law is handed the same input pointer;
 *              it reads only the fields it knows (the first 120 bytes), so it gives exactly the
 *              results it gave before; its output is treated as a version-2 output's.
 *   version 2: tribo_law_input gained the gas state at its end: cylinder and crankcase
 *              pressure, the piston's travel from TDC and the angle in the 4-stroke cycle.
 *              A version-2 law reads the first 152 bytes of the input and writes the first 40
 *              of the output; the host zeroes the rest of the output and keeps only the flag
 *              bits version 2 knew (1, 2, 4), whatever the law left in the others.
 *   version 3: tribo_law_input gained both bodies' angles and velocities, the inner body, the
 *              bearing type and the load on the inner member; tribo_law_output gained
 *              dforce_dload and the diagnostics (min film, eccentricity, peak pressure,
 *              asperity share) with their flag bits; the optional symbols
 *              tribo_law_evaluate_many and tribo_law_suits (looked up in version-3 libraries
 *              only).
 * Fields are only ever appended, never moved. docs/writing-a-law.md ("Contract versions").
 * Every struct and constant below is checked against the Rust definitions
 * (plugin-api/src/contract.rs) by plugin-api/tests/header.rs, field offset by field offset.
 */
#ifndef TRIBO_LAW_H
#define TRIBO_LAW_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Version of this contract. The host refuses a library whose tribo_law_contract_version()
 * returns anything else. */
#define TRIBO_LAW_CONTRACT_VERSION 3u

/* Joint kinds (tribo_law_input.joint_kind). */
#define TRIBO_JOINT_REVOLUTE 0u  /* velocity in rad/s, return a torque in N m */
#define TRIBO_JOINT_PRISMATIC 1u /* velocity in m/s, return a force in N */

/* Lubrication regimes (tribo_law_output.regime). */
#define TRIBO_REGIME_NONE 0u         /* the law has no notion of regime */
#define TRIBO_REGIME_BOUNDARY 1u
#define TRIBO_REGIME_MIXED 2u
#define TRIBO_REGIME_HYDRODYNAMIC 3u

/* Bits of tribo_law_output.flags: which optional outputs are filled in. */
#define TRIBO_HAS_COEFFICIENT 1u
#define TRIBO_HAS_DUTY_PARAMETER 2u
#define TRIBO_HAS_DERIVATIVE 4u
#define TRIBO_HAS_LOAD_DERIVATIVE 8u  /* version 3: dforce_dload */
#define TRIBO_HAS_MIN_FILM 16u        /* version 3: min_film_m */
#define TRIBO_HAS_ECCENTRICITY 32u    /* version 3: eccentricity_x and eccentricity_y */
#define TRIBO_HAS_PEAK_PRESSURE 64u   /* version 3: peak_pressure_pa */
#define TRIBO_HAS_ASPERITY_SHARE 128u /* version 3: asperity_share */
/* Version 3: the force is affine in normal_load_n with slope dforce_dload (flag it too), the
   rest of the output independent of the load: the host may move the force along the slope
   instead of calling again when only the load changes. 0 slope: independent of the load. */
#define TRIBO_AFFINE_IN_LOAD 256u

/* Bearing types (tribo_law_input.bearing_type): what the rig declares for the joint. */
#define TRIBO_BEARING_UNSPECIFIED 0u
#define TRIBO_BEARING_PLAIN 1u   /* hydrodynamic journal bearing: shell or bush on an oil film */
#define TRIBO_BEARING_ROLLING 2u /* rolling elements: balls, rollers, needles */
#define TRIBO_BEARING_SLIDE 3u   /* sliding along an axis: piston skirt, rings (every slide) */

/* Which body is the inner member (tribo_law_input.inner_body). */
#define TRIBO_INNER_BODY_A 0u
#define TRIBO_INNER_BODY_B 1u

/* Bits of tribo_law_suits(): the bearing types a law is made for (0: any joint). The host
 * warns when a law is put on a joint whose declared bearing type it does not suit. */
#define TRIBO_SUITS_PLAIN 1u
#define TRIBO_SUITS_ROLLING 2u
#define TRIBO_SUITS_SLIDE 4u

/* Everything a law may depend on, for one joint at one instant. */
typedef struct tribo_law_input {
    uint32_t joint_kind;          /* TRIBO_JOINT_* */
    uint32_t reserved;            /* always 0 */
    double relative_velocity;     /* rad/s (revolute) or m/s (prismatic), signed */
    double sliding_velocity_m_s;  /* signed sliding velocity at the contact, m/s */
    double normal_load_n;         /* normal load from the joint reaction, N, >= 0 */
    double reaction_x_n;          /* reaction x: global x (revolute) or along the slide (prismatic), N */
    double reaction_y_n;          /* reaction y: global y (revolute) or normal to the slide (prismatic), N */
    double reaction_moment_nm;    /* in-plane reaction moment of a prismatic joint, N m */
    double contact_radius_m;      /* journal/pin radius, or half the bore for a slide, m */
    double contact_length_m;      /* bearing width, or skirt/ring height, m */
    double oil_temp_c;            /* oil temperature, degrees C */
    double viscosity_pa_s;        /* dynamic viscosity at oil_temp_c, Pa s */
    double engine_speed_rad_s;    /* crank speed, rad/s */
    double crank_angle_rad;       /* crank angle from TDC, rad, [0, 2 pi) */
    double time_s;                /* simulation time, s */
    double dt_s;                  /* current step size, s (0 in steady-state quadrature) */
    /* Version 2: */
    double cylinder_pressure_pa;  /* absolute pressure on the piston crown, Pa (ambient without gas) */
    double crankcase_pressure_pa; /* absolute pressure under the piston, Pa */
    double piston_from_tdc_m;     /* piston travel from TDC, m (0 at TDC, the stroke at BDC) */
    double cycle_angle_rad;       /* angle in the 4-stroke cycle, rad, [0, 4 pi); 0 = gas-exchange TDC */
    /* Version 3 (bodies A and B per joint: the table above): */
    double body_a_angle;          /* body A's absolute angle, rad (prismatic: position on the axis, m) */
    double body_a_velocity;       /* body A's absolute velocity, rad/s (prismatic: m/s) */
    double body_b_angle;          /* body B's, as body_a_angle */
    double body_b_velocity;       /* body B's, as body_a_velocity; relative_velocity = a - b */
    uint32_t inner_body;          /* TRIBO_INNER_BODY_*: which body is the journal, pin or piston */
    uint32_t bearing_type;        /* TRIBO_BEARING_*: what the rig declares for the joint */
    double load_on_inner_x_n;     /* force of the outer member on the inner one, N: global x */
                                  /* (revolute) or along the slide axis (prismatic) */
    double load_on_inner_y_n;     /* global y (revolute) or normal to the slide axis, signed (prismatic) */
} tribo_law_input;

/* What a law returns for one evaluation. */
typedef struct tribo_law_output {
    double force;             /* N (prismatic) or N m (revolute), opposing the motion */
    double coefficient;       /* effective friction coefficient, if TRIBO_HAS_COEFFICIENT */
    double duty_parameter;    /* duty parameter H, if TRIBO_HAS_DUTY_PARAMETER */
    double dforce_dvelocity;  /* d force / d relative_velocity, if TRIBO_HAS_DERIVATIVE */
    uint32_t regime;          /* TRIBO_REGIME_* */
    uint32_t flags;           /* TRIBO_HAS_* bits */
    /* Version 3: */
    double dforce_dload;      /* d force / d normal_load_n (load direction fixed), if TRIBO_HAS_LOAD_DERIVATIVE */
    double min_film_m;        /* minimum oil-film thickness, m, >= 0, if TRIBO_HAS_MIN_FILM */
    double eccentricity_x;    /* eccentricity ratio e/c in the outer member's frame, x and y, */
    double eccentricity_y;    /* |e| < 1, if TRIBO_HAS_ECCENTRICITY */
    double peak_pressure_pa;  /* peak film pressure, Pa, >= 0, if TRIBO_HAS_PEAK_PRESSURE */
    double asperity_share;    /* share of the normal load carried by asperities, [0, 1], if TRIBO_HAS_ASPERITY_SHARE */
} tribo_law_output;

/* One scalar parameter. */
typedef struct tribo_param_spec {
    const char *name;       /* key in the TOML table */
    const char *unit;       /* "-" for dimensionless */
    const char *doc;        /* physical meaning */
    double default_value;
    double min;             /* allowed range, inclusive */
    double max;
} tribo_param_spec;

/* The law's self-description; must stay valid while the library is loaded. */
typedef struct tribo_law_description {
    const char *name;       /* unique law name, e.g. "c-coulomb" */
    const char *version;    /* implementation version, e.g. "0.1.0" */
    const char *summary;    /* one line */
    uint32_t n_params;
    const tribo_param_spec *params;
} tribo_law_description;

/* Returns TRIBO_LAW_CONTRACT_VERSION as compiled into the library. */
uint32_t tribo_law_contract_version(void);

/* Returns the law's description (static storage). */
const tribo_law_description *tribo_law_describe(void);

/* Creates an instance from n_params checked values (in description order). On failure returns
 * NULL and writes a NUL-terminated message of at most error_len bytes, starting with the name
 * of the offending parameter followed by ": ". */
void *tribo_law_create(const double *params, size_t n_params, char *error, size_t error_len);

/* Number of doubles of host-owned state this instance needs (0 for a stateless law). */
size_t tribo_law_state_size(const void *instance);

/* Evaluates the law. `state` points to tribo_law_state_size() doubles (may be NULL when 0);
 * `output` arrives zeroed. Returns 0 on success; any other value is reported to the user as an
 * error of this law. */
int32_t tribo_law_evaluate(const void *instance, const tribo_law_input *input,
                           const double *state, tribo_law_output *output);

/* Optional (version 3): evaluates n inputs at once, exactly as n calls of tribo_law_evaluate
 * would. Input k reads the state at states + k * state_stride (state_stride 0: all share the
 * one state at `states`) and writes outputs[k], which arrives zeroed. Returns 0 on success; on
 * any other value the host evaluates the inputs one at a time to find the one that fails.
 * Without it the host calls tribo_law_evaluate in a loop. */
int32_t tribo_law_evaluate_many(const void *instance, size_t n, const tribo_law_input *inputs,
                                const double *states, size_t state_stride,
                                tribo_law_output *outputs);

/* Optional (version 3): the TRIBO_SUITS_* bits of the bearing types the law is made for; 0,
 * or no such function, means any joint. */
uint32_t tribo_law_suits(void);

/* Advances `state` over the accepted step described by `input` (input->dt_s is its length).
 * Returns 0 on success. */
int32_t tribo_law_commit(const void *instance, const tribo_law_input *input, double *state);

/* Releases an instance made by tribo_law_create. */
void tribo_law_destroy(void *instance);

#ifdef __cplusplus
}
#endif

#endif /* TRIBO_LAW_H */
