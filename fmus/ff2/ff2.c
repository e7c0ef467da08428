/*
 * modbot_ff2: the elastic-joint feed-forward of the arm as an FMI 2.0 co-simulation FMU, in C
 * against the official FMI 2 headers (include/, as fmi-sys ships them).
 *
 * Each of the 6 joints is a two-mass system (see runtime/grid/src/bus/plant.rs): the motor
 * (inertia Jm, position qm) drives the link (inertia Jl, position q) through a gear of
 * stiffness k, with viscous (b) and Coulomb friction (tau_c tanh(qm'/omega_c)) on the motor.
 * Its inverse (the link position is the flat output; the gear's damping is left out):
 *
 *     qm   = q + Jl q''/k                  the motor position that puts the link at q
 *     qm'  = q' + Jl q'''/k
 *     tau  = (Jm + Jl) q'' + Jm Jl/k q'''' + b qm' + tau_c tanh(qm'/omega_c)
 *
 * The inputs are q, q' and q'' (a trajectory generator's); q''' and q'''' are estimated from q''
 * by a critically damped second-order state-variable filter with time constant Tf:
 *
 *     x1' = x2,   x2' = w^2 (q'' - x1) - 2 w x2,   w = 1/Tf:   q''' ~ x2,   q'''' ~ x2'
 *
 * integrated over a step (q'' held) with semi-implicit Euler in sub-steps of at most Tf/5.
 * Outputs are computed at the end of every step (and when initialisation ends). A result that
 * is not finite is 0 on that axis.
 *
 * Variables (value references): q[1..6] 0-5, qd[1..6] 6-11, qdd[1..6] 12-17 (inputs),
 * tau[1..6] 18-23, qm[1..6] 24-29 (outputs), Jm 30, Jl 31, k 32, b 33, tau_c 34, omega_c 35,
 * Tf 36 (parameters).
 */

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define AXES 6
#define GUID "{8c4e810f-3df3-4a00-8276-176fa3c9f3e0}"

enum { VR_Q = 0, VR_QD = 6, VR_QDD = 12, VR_TAU = 18, VR_QM = 24, VR_PARAMS = 30 };
enum { P_JM, P_JL, P_K, P_B, P_TAU_C, P_OMEGA_C, P_TF, PARAMS };
#define VARIABLES (VR_PARAMS + PARAMS)

static const double START[PARAMS] = {0.5, 2.0, 2.0e4, 1.0, 3.0, 0.05, 0.005};

typedef enum { INSTANTIATED, INITIALISING, STEPPING, TERMINATED } Phase;

typedef struct {
    /* Every variable by value reference: inputs, outputs, parameters. */
    double v[VARIABLES];
    /* The filter's states per axis: x1 (q'' filtered), x2 (q''' estimated). */
    double x1[AXES], x2[AXES];
    double time;
    Phase phase;
    const fmi2CallbackFunctions *cb;
    fmi2String name;
} Instance;

static void log_error(Instance *m, const char *message) {
    if (m != NULL && m->cb != NULL && m->cb->logger != NULL) {
        m->cb->logger(m->cb->componentEnvironment, m->name, fmi2Error, "error", "%s", message);
    }
}

static double finite_or_zero(double x) { return isfinite(x) ? x : 0.0; }

/* The outputs from the inputs, parameters and filter states. */
static void calculate(Instance *m) {
    const double *p = &m->v[VR_PARAMS];
    const double jm = p[P_JM], jl = p[P_JL], k = p[P_K], w = 1.0 / p[P_TF];
    for (int i = 0; i < AXES; i++) {
        const double q = m->v[VR_Q + i], qd = m->v[VR_QD + i], qdd = m->v[VR_QDD + i];
        const double jerk = m->x2[i];
        const double snap = w * w * (qdd - m->x1[i]) - 2.0 * w * m->x2[i];
        const double qmd = qd + jl / k * jerk;
        const double tau = (jm + jl) * qdd + jm * jl / k * snap + p[P_B] * qmd
                           + p[P_TAU_C] * tanh(qmd / p[P_OMEGA_C]);
        m->v[VR_TAU + i] = finite_or_zero(tau);
        m->v[VR_QM + i] = finite_or_zero(q + jl / k * qdd);
    }
}

/* Advances the filter by h with q'' held. */
static void advance(Instance *m, double h) {
    const double tf = m->v[VR_PARAMS + P_TF], w = 1.0 / tf;
    int n = (int)ceil(5.0 * h / tf);
    if (n < 1) n = 1;
    const double dt = h / n;
    for (int i = 0; i < AXES; i++) {
        const double qdd = m->v[VR_QDD + i];
        for (int s = 0; s < n; s++) {
            m->x2[i] += dt * (w * w * (qdd - m->x1[i]) - 2.0 * w * m->x2[i]);
            m->x1[i] += dt * m->x2[i];
        }
    }
}

static int params_valid(Instance *m) {
    const double *p = &m->v[VR_PARAMS];
    for (int i = 0; i < PARAMS; i++) {
        if (!isfinite(p[i])) return 0;
    }
    return p[P_JM] > 0 && p[P_JL] > 0 && p[P_K] > 0 && p[P_B] >= 0 && p[P_TAU_C] >= 0
           && p[P_OMEGA_C] > 0 && p[P_TF] > 0;
}

static void reset(Instance *m) {
    memset(m->v, 0, sizeof m->v);
    memcpy(&m->v[VR_PARAMS], START, sizeof START);
    memset(m->x1, 0, sizeof m->x1);
    memset(m->x2, 0, sizeof m->x2);
    m->time = 0.0;
    m->phase = INSTANTIATED;
}

/* ---- common functions ---- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) {
    (void)c; (void)on; (void)n; (void)cat;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions *cb,
                              fmi2Boolean visible, fmi2Boolean logging) {
    (void)resources; (void)visible; (void)logging;
    if (type != fmi2CoSimulation || guid == NULL || strcmp(guid, GUID) != 0) {
        if (cb != NULL && cb->logger != NULL) {
            cb->logger(cb->componentEnvironment, name, fmi2Error, "error",
                       "modbot_ff2 is a co-simulation FMU with GUID %s", GUID);
        }
        return NULL;
    }
    Instance *m = (cb != NULL && cb->allocateMemory != NULL)
                      ? cb->allocateMemory(1, sizeof(Instance))
                      : calloc(1, sizeof(Instance));
    if (m == NULL) return NULL;
    m->cb = cb;
    m->name = name;
    reset(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *m = c;
    if (m == NULL) return;
    if (m->cb != NULL && m->cb->freeMemory != NULL) {
        m->cb->freeMemory(m);
    } else {
        free(m);
    }
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                               fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    (void)tol_defined; (void)tol; (void)stop_defined; (void)stop;
    Instance *m = c;
    m->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *m = c;
    if (!params_valid(m)) {
        log_error(m, "parameters must be finite; Jm, Jl, k, omega_c and Tf positive; b and tau_c >= 0");
        return fmi2Error;
    }
    m->phase = INITIALISING;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *m = c;
    /* The filter starts at rest on the initial acceleration. */
    for (int i = 0; i < AXES; i++) {
        m->x1[i] = m->v[VR_QDD + i];
        m->x2[i] = 0.0;
    }
    calculate(m);
    m->phase = STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    ((Instance *)c)->phase = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    reset(c);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Instance *m = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= VARIABLES) {
            log_error(m, "no Real variable has this value reference");
            return fmi2Error;
        }
        value[i] = m->v[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real value[]) {
    Instance *m = c;
    for (size_t i = 0; i < n; i++) {
        const int input = vr[i] < VR_TAU;
        const int param = vr[i] >= VR_PARAMS && vr[i] < VARIABLES;
        if (!input && !(param && m->phase != STEPPING)) {
            log_error(m, "only inputs may be set, and parameters before initialisation ends");
            return fmi2Error;
        }
        m->v[vr[i]] = value[i];
    }
    return fmi2OK;
}

static fmi2Status no_such(fmi2Component c, size_t n) {
    if (n == 0) return fmi2OK;
    log_error(c, "this FMU has Real variables only");
    return fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    (void)vr; (void)v;
    return no_such(c, n);
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    (void)vr; (void)v;
    return no_such(c, n);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    (void)vr; (void)v;
    return no_such(c, n);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    (void)vr; (void)v;
    return no_such(c, n);
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)vr; (void)v;
    return no_such(c, n);
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)vr; (void)v;
    return no_such(c, n);
}

/* The FMU's state is not saved or restored (canGetAndSetFMUstate="false"). */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)c; (void)s; (void)n;
    return fmi2Error;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)c; (void)s; (void)b; (void)n;
    return fmi2Error;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) {
    (void)c; (void)b; (void)n; (void)s;
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz,
                                        const fmi2Real dv[], fmi2Real dz[]) {
    (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fmi2Error;
}

/* ---- co-simulation ---- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)c; (void)vr; (void)n; (void)order; (void)value;
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)c; (void)vr; (void)n; (void)order; (void)value;
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)no_prior;
    Instance *m = c;
    if (m->phase != STEPPING || !(h >= 0.0)) {
        log_error(m, "doStep needs an initialised FMU and a step of 0 or more");
        return fmi2Error;
    }
    advance(m, h);
    calculate(m);
    m->time = t + h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = ((Instance *)c)->time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    (void)c;
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
