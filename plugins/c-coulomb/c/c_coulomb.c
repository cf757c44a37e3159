/*
 * c-coulomb: the example law of Tribo's C ABI (see plugin-api/include/tribo_law.h).
 *
 * Coulomb friction on the joint's normal load plus a viscous term, the same physics as the
 * Rust `coulomb` law so the two ABI paths can be compared number for number:
 *
 *   F = -( mu * N * arm * v_s / sqrt(v_s^2 + eps^2) + c * v )
 *
 * arm is the contact radius for a revolute joint (F is then a torque) and 1 for a slide,
 * v_s the sliding velocity at the contact, v the joint's relative velocity, eps = v_smooth.
 *
 * Build by hand:  cc -shared -fPIC -O2 -I plugin-api/include c_coulomb.c -o libtribo_law_c_coulomb.so -lm
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "tribo_law.h"

enum { P_MU, P_C_VISCOUS, P_V_SMOOTH, N_PARAMS };

static const tribo_param_spec PARAMS[N_PARAMS] = {
    {"mu", "-", "Coulomb friction coefficient", 0.1, 0.0, 10.0},
    {"c_viscous", "N s/m | N m s/rad",
     "viscous coefficient on the relative velocity (slide: N s/m, revolute: N m s/rad)", 0.0, 0.0, 1e6},
    /* estimate: 1 mm/s is far below engine sliding speeds yet keeps the law smooth at reversal */
    {"v_smooth", "m/s", "sliding-velocity scale over which the Coulomb sign is smoothed through zero",
     1e-3, 1e-9, 1.0},
};

static const tribo_law_description DESCRIPTION = {
    "c-coulomb", "0.1.0",
    "Coulomb friction plus viscous term, written in C (example of the C plugin ABI)",
    N_PARAMS, PARAMS,
};

typedef struct {
    double mu, c_viscous, v_smooth;
} c_coulomb;

uint32_t tribo_law_contract_version(void) { return TRIBO_LAW_CONTRACT_VERSION; }

const tribo_law_description *tribo_law_describe(void) { return &DESCRIPTION; }

void *tribo_law_create(const double *params, size_t n_params, char *error, size_t error_len) {
    if (n_params != N_PARAMS) {
        snprintf(error, error_len, "expected %d parameters, got %zu", N_PARAMS, n_params);
        return NULL;
    }
    c_coulomb *law = malloc(sizeof *law);
    if (!law) {
        snprintf(error, error_len, "out of memory");
        return NULL;
    }
    law->mu = params[P_MU];
    law->c_viscous = params[P_C_VISCOUS];
    law->v_smooth = params[P_V_SMOOTH];
    return law;
}

size_t tribo_law_state_size(const void *instance) {
    (void)instance;
    return 0;
}

int32_t tribo_law_evaluate(const void *instance, const tribo_law_input *in, const double *state,
                           tribo_law_output *out) {
    (void)state;
    const c_coulomb *law = instance;
    double arm = in->joint_kind == TRIBO_JOINT_REVOLUTE ? in->contact_radius_m : 1.0;
    double vs = in->sliding_velocity_m_s, eps = law->v_smooth;
    double r = sqrt(vs * vs + eps * eps);
    double coulomb = law->mu * in->normal_load_n * arm;
    out->force = -(coulomb * vs / r + law->c_viscous * in->relative_velocity);
    out->coefficient = law->mu;
    out->duty_parameter = 0.0;
    out->dforce_dvelocity = -(coulomb * eps * eps / (r * r * r) * arm + law->c_viscous);
    out->regime = TRIBO_REGIME_NONE;
    out->flags = TRIBO_HAS_COEFFICIENT | TRIBO_HAS_DERIVATIVE;
    return 0;
}

int32_t tribo_law_commit(const void *instance, const tribo_law_input *in, double *state) {
    (void)instance;
    (void)in;
    (void)state;
    return 0;
}

void tribo_law_destroy(void *instance) { free(instance); }
