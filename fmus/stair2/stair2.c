/*
 * modbot_stair2: a staircase as an FMI 2.0 co-simulation FMU, in C against the official FMI 2
 * headers (../ff2/include, as fmi-sys ships them) — the project's stand-in for the Reference
 * FMU Stair, made to end: an FMU that asks its master to terminate.
 *
 * The counter is `start` when initialisation ends and steps up by the input `step` at every
 * communication step (saturating at the ends of an Integer). A step that would end after `t_stop` is not taken: the FMU logs why
 * through the master's logger (status fmi2Discard, category "logStatusDiscard") and returns
 * fmi2Discard, and from then on fmi2GetBooleanStatus(fmi2Terminated) says true — what FMI 2.0
 * asks of a co-simulation slave that wants the simulation to end.
 *
 * Variables (value references): counter 0 (Integer output), step 1 (Integer input), start 2
 * (Integer parameter, -1000 to 1000), t_stop 3 (Real parameter, s, 0 or more).
 */

#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define GUID "{5d0c1a8e-7b3f-4c52-9e61-2f4a7d9b8c13}"

enum { VR_COUNTER, VR_STEP, VR_START, VR_T_STOP };

/* Steps that end this close past t_stop still end in time (the master's time is a sum). */
#define TIME_TOLERANCE 1e-9

typedef enum { INSTANTIATED, INITIALISING, STEPPING, TERMINATED } Phase;

typedef struct {
    int counter, step, start;
    double t_stop;
    double time;
    /* A step asked to terminate: no more steps are taken. */
    int terminated;
    Phase phase;
    const fmi2CallbackFunctions *cb;
    fmi2String name;
} Instance;

static void logf2(Instance *m, fmi2Status status, const char *category, const char *format,
                  double a, double b) {
    if (m != NULL && m->cb != NULL && m->cb->logger != NULL) {
        m->cb->logger(m->cb->componentEnvironment, m->name, status, category, format, a, b);
    }
}

static void log_error(Instance *m, const char *message) {
    if (m != NULL && m->cb != NULL && m->cb->logger != NULL) {
        m->cb->logger(m->cb->componentEnvironment, m->name, fmi2Error, "logStatusError", "%s",
                      message);
    }
}

static void reset(Instance *m) {
    m->counter = 0;
    m->step = 1;
    m->start = 3;
    m->t_stop = 10.0;
    m->time = 0.0;
    m->terminated = 0;
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
            cb->logger(cb->componentEnvironment, name, fmi2Error, "logStatusError",
                       "modbot_stair2 is a co-simulation FMU with GUID %s", GUID);
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
    ((Instance *)c)->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *m = c;
    if (m->start < -1000 || m->start > 1000 || !(m->t_stop >= 0.0)) {
        log_error(m, "start must be from -1000 to 1000 and t_stop 0 or more");
        return fmi2Error;
    }
    m->phase = INITIALISING;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *m = c;
    m->counter = m->start;
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
        if (vr[i] != VR_T_STOP) {
            log_error(m, "no Real variable has this value reference");
            return fmi2Error;
        }
        value[i] = m->t_stop;
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real value[]) {
    Instance *m = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != VR_T_STOP || m->phase == STEPPING) {
            log_error(m, "t_stop may be set before initialisation ends; no other Real exists");
            return fmi2Error;
        }
        m->t_stop = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer value[]) {
    Instance *m = c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_COUNTER: value[i] = m->counter; break;
        case VR_STEP: value[i] = m->step; break;
        case VR_START: value[i] = m->start; break;
        default:
            log_error(m, "no Integer variable has this value reference");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer value[]) {
    Instance *m = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_STEP) {
            m->step = value[i];
        } else if (vr[i] == VR_START && m->phase != STEPPING) {
            m->start = value[i];
        } else {
            log_error(m, "only step may be set, and start before initialisation ends");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

static fmi2Status no_such(fmi2Component c, size_t n) {
    if (n == 0) return fmi2OK;
    log_error(c, "this FMU has Integer and Real variables only");
    return fmi2Error;
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
    if (m->terminated || t + h > m->t_stop + TIME_TOLERANCE) {
        m->terminated = 1;
        logf2(m, fmi2Discard, "logStatusDiscard",
              "the stair ends at t_stop = %g s: the step from t = %g s is not taken, "
              "please terminate",
              m->t_stop, t);
        return fmi2Discard;
    }
    const long long next = (long long)m->counter + m->step;
    m->counter = next > INT_MAX ? INT_MAX : next < INT_MIN ? INT_MIN : (int)next;
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
    *value = ((Instance *)c)->terminated ? fmi2True : fmi2False;
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
