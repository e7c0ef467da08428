/*
 * modbot_ss3: a linear state-space system as an FMI 3.0 co-simulation FMU, in C against the
 * official FMI 3 headers (include/, as fmi-sys ships them):
 *
 *     x' = A x + B u,   y = C x + D u,   x(t0) = x0
 *
 * Its sizes are structural parameters — nx states, nu inputs, ny outputs (UInt64, 1 to 8,
 * settable in Configuration Mode) — and its matrices are two-dimensional Float64 parameters
 * (A nx×nx, B nx×nu, C ny×nx, D ny×nu, row-major) whose Dimensions refer to them, as are the
 * arrays u (nu) and y (ny): what the FMI 3 way of sizing arrays looks like to a master.
 * Changing a size zeroes the arrays it sizes. The defaults are a damped oscillator seen through
 * C = [2 0] from x0 = [1 0], so its output after initialisation is 2, not 0.
 *
 * A communication step integrates with one classical Runge-Kutta step (u held); y is computed
 * whenever it is got.
 *
 * Variables (value references): time 0, nx 1, nu 2, ny 3, A 4, B 5, C 6, D 7, x0 8, u 9, y 10.
 */

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define TOKEN "{b1f0c6e2-4a3d-4e8f-9c27-6d5e8a1f3b40}"
#define MAXN 8

enum { VR_TIME, VR_NX, VR_NU, VR_NY, VR_A, VR_B, VR_C, VR_D, VR_X0, VR_U, VR_Y, VARIABLES };

typedef enum { INSTANTIATED, CONFIGURING, INITIALISING, STEPPING, TERMINATED } Phase;

typedef struct {
    fmi3UInt64 nx, nu, ny;
    double a[MAXN * MAXN], b[MAXN * MAXN], c[MAXN * MAXN], d[MAXN * MAXN];
    double x0[MAXN], u[MAXN], y[MAXN], x[MAXN];
    double time;
    Phase phase;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Instance;

static const double START_A[] = {0, 1, -1, -0.2}, START_B[] = {0, 1}, START_C[] = {2, 0},
                    START_D[] = {0}, START_X0[] = {1, 0};

static fmi3Status fail(Instance *m, const char *message) {
    if (m != NULL && m->log != NULL) m->log(m->env, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

static void defaults(Instance *m) {
    memset(m->a, 0, sizeof m->a);
    memset(m->b, 0, sizeof m->b);
    memset(m->c, 0, sizeof m->c);
    memset(m->d, 0, sizeof m->d);
    memset(m->x0, 0, sizeof m->x0);
    memset(m->u, 0, sizeof m->u);
    memset(m->x, 0, sizeof m->x);
    m->nx = 2;
    m->nu = 1;
    m->ny = 1;
    memcpy(m->a, START_A, sizeof START_A);
    memcpy(m->b, START_B, sizeof START_B);
    memcpy(m->c, START_C, sizeof START_C);
    memcpy(m->d, START_D, sizeof START_D);
    memcpy(m->x0, START_X0, sizeof START_X0);
    m->time = 0.0;
    m->phase = INSTANTIATED;
}

/* The number of values of variable vr (0: no Float64 variable). */
static size_t size_of(const Instance *m, fmi3ValueReference vr) {
    switch (vr) {
    case VR_TIME: return 1;
    case VR_A: return m->nx * m->nx;
    case VR_B: return m->nx * m->nu;
    case VR_C: return m->ny * m->nx;
    case VR_D: return m->ny * m->nu;
    case VR_X0: return m->nx;
    case VR_U: return m->nu;
    case VR_Y: return m->ny;
    default: return 0;
    }
}

static double *values_of(Instance *m, fmi3ValueReference vr) {
    switch (vr) {
    case VR_TIME: return &m->time;
    case VR_A: return m->a;
    case VR_B: return m->b;
    case VR_C: return m->c;
    case VR_D: return m->d;
    case VR_X0: return m->x0;
    case VR_U: return m->u;
    case VR_Y: return m->y;
    default: return NULL;
    }
}

/* dx = A x + B u. */
static void derivative(const Instance *m, const double *x, double *dx) {
    for (size_t i = 0; i < m->nx; i++) {
        double s = 0.0;
        for (size_t j = 0; j < m->nx; j++) s += m->a[i * m->nx + j] * x[j];
        for (size_t j = 0; j < m->nu; j++) s += m->b[i * m->nu + j] * m->u[j];
        dx[i] = s;
    }
}

/* y = C x + D u. */
static void output(Instance *m) {
    for (size_t i = 0; i < m->ny; i++) {
        double s = 0.0;
        for (size_t j = 0; j < m->nx; j++) s += m->c[i * m->nx + j] * m->x[j];
        for (size_t j = 0; j < m->nu; j++) s += m->d[i * m->nu + j] * m->u[j];
        m->y[i] = s;
    }
}

/* One classical Runge-Kutta step of length h. */
static void advance(Instance *m, double h) {
    double k1[MAXN] = {0}, k2[MAXN] = {0}, k3[MAXN] = {0}, k4[MAXN] = {0}, t[MAXN] = {0};
    const size_t n = m->nx;
    derivative(m, m->x, k1);
    for (size_t i = 0; i < n; i++) t[i] = m->x[i] + 0.5 * h * k1[i];
    derivative(m, t, k2);
    for (size_t i = 0; i < n; i++) t[i] = m->x[i] + 0.5 * h * k2[i];
    derivative(m, t, k3);
    for (size_t i = 0; i < n; i++) t[i] = m->x[i] + h * k3[i];
    derivative(m, t, k4);
    for (size_t i = 0; i < n; i++) {
        m->x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
}

/* ---- common functions ---- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cat[]) {
    (void)c; (void)on; (void)n; (void)cat;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                          fmi3Boolean visible, fmi3Boolean logging,
                                          fmi3InstanceEnvironment env,
                                          fmi3LogMessageCallback log) {
    (void)name; (void)token; (void)resources; (void)visible; (void)logging;
    if (log != NULL) log(env, fmi3Error, "logStatusError", "modbot_ss3 is co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
                                         fmi3Boolean visible, fmi3Boolean logging,
                                         fmi3Boolean event_mode, fmi3Boolean early_return,
                                         const fmi3ValueReference required[], size_t n_required,
                                         fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                         fmi3IntermediateUpdateCallback intermediate) {
    (void)name; (void)resources; (void)visible; (void)logging; (void)early_return;
    (void)required; (void)n_required; (void)intermediate;
    if (token == NULL || strcmp(token, TOKEN) != 0 || event_mode) {
        if (log != NULL) {
            log(env, fmi3Error, "logStatusError",
                "modbot_ss3 has the instantiation token " TOKEN " and no event mode");
        }
        return NULL;
    }
    Instance *m = calloc(1, sizeof(Instance));
    if (m == NULL) return NULL;
    m->env = env;
    m->log = log;
    defaults(m);
    return m;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging, fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
    fmi3ClockUpdateCallback clock, fmi3LockPreemptionCallback lock,
    fmi3UnlockPreemptionCallback unlock) {
    (void)name; (void)token; (void)resources; (void)visible; (void)logging;
    (void)clock; (void)lock; (void)unlock;
    if (log != NULL) log(env, fmi3Error, "logStatusError", "modbot_ss3 is co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance c) { free(c); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol_defined, fmi3Float64 tol,
                                       fmi3Float64 start, fmi3Boolean stop_defined,
                                       fmi3Float64 stop) {
    (void)tol_defined; (void)tol; (void)stop_defined; (void)stop;
    Instance *m = c;
    if (m->phase != INSTANTIATED) return fail(m, "initialisation follows instantiation");
    m->time = start;
    m->phase = INITIALISING;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Instance *m = c;
    if (m->phase != INITIALISING) return fail(m, "not in initialisation mode");
    memcpy(m->x, m->x0, sizeof m->x);
    m->phase = STEPPING;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) { return fail(c, "modbot_ss3 has no event mode"); }

fmi3Status fmi3Terminate(fmi3Instance c) {
    ((Instance *)c)->phase = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    defaults(c);
    return fmi3OK;
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) {
    Instance *m = c;
    if (m->phase != INSTANTIATED) return fail(m, "configuration mode follows instantiation");
    m->phase = CONFIGURING;
    return fmi3OK;
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) {
    Instance *m = c;
    if (m->phase != CONFIGURING) return fail(m, "not in configuration mode");
    m->phase = INSTANTIATED;
    return fmi3OK;
}

/* ---- getting and setting ---- */

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          fmi3Float64 values[], size_t n) {
    Instance *m = c;
    size_t k = 0;
    if (m->phase == STEPPING || m->phase == INITIALISING) output(m);
    for (size_t i = 0; i < nvr; i++) {
        const size_t size = size_of(m, vr[i]);
        if (size == 0) return fail(m, "no Float64 variable has this value reference");
        if (k + size > n) return fail(m, "fewer values than the variables have");
        memcpy(&values[k], values_of(m, vr[i]), size * sizeof(double));
        k += size;
    }
    return k == n ? fmi3OK : fail(m, "more values than the variables have");
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t n) {
    Instance *m = c;
    size_t k = 0;
    for (size_t i = 0; i < nvr; i++) {
        const int param = vr[i] >= VR_A && vr[i] <= VR_X0;
        const int settable = vr[i] == VR_U
                                 ? m->phase != TERMINATED
                                 : param && (m->phase == INSTANTIATED || m->phase == INITIALISING);
        if (!settable) {
            return fail(m, "u may be set, and A, B, C, D and x0 before initialisation ends");
        }
        const size_t size = size_of(m, vr[i]);
        if (k + size > n) return fail(m, "fewer values than the variables have");
        memcpy(values_of(m, vr[i]), &values[k], size * sizeof(double));
        k += size;
    }
    return k == n ? fmi3OK : fail(m, "more values than the variables have");
}

static fmi3UInt64 *size_variable(Instance *m, fmi3ValueReference vr) {
    switch (vr) {
    case VR_NX: return &m->nx;
    case VR_NU: return &m->nu;
    case VR_NY: return &m->ny;
    default: return NULL;
    }
}

fmi3Status fmi3GetUInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         fmi3UInt64 values[], size_t n) {
    Instance *m = c;
    if (nvr != n) return fail(m, "nx, nu and ny are scalars");
    for (size_t i = 0; i < nvr; i++) {
        fmi3UInt64 *v = size_variable(m, vr[i]);
        if (v == NULL) return fail(m, "no UInt64 variable has this value reference");
        values[i] = *v;
    }
    return fmi3OK;
}

fmi3Status fmi3SetUInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         const fmi3UInt64 values[], size_t n) {
    Instance *m = c;
    if (nvr != n) return fail(m, "nx, nu and ny are scalars");
    if (m->phase != CONFIGURING) return fail(m, "nx, nu and ny are set in configuration mode");
    for (size_t i = 0; i < nvr; i++) {
        fmi3UInt64 *v = size_variable(m, vr[i]);
        if (v == NULL) return fail(m, "no UInt64 variable has this value reference");
        if (values[i] < 1 || values[i] > MAXN) {
            char message[96];
            snprintf(message, sizeof message, "a size of %llu: nx, nu and ny are 1 to %d",
                     (unsigned long long)values[i], MAXN);
            return fail(m, message);
        }
        if (*v != values[i]) {
            *v = values[i];
            /* What the size sizes starts from zeros. */
            memset(m->a, 0, sizeof m->a);
            memset(m->b, 0, sizeof m->b);
            memset(m->c, 0, sizeof m->c);
            memset(m->d, 0, sizeof m->d);
            memset(m->x0, 0, sizeof m->x0);
            memset(m->u, 0, sizeof m->u);
        }
    }
    return fmi3OK;
}

/* The variables of other types: there are none. */
static fmi3Status none(fmi3Instance c, size_t nvr) {
    return nvr == 0 ? fmi3OK : fail(c, "modbot_ss3 has Float64 and UInt64 variables only");
}

#define NO_GET_SET(NAME, TYPE)                                                                  \
    fmi3Status fmi3Get##NAME(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,         \
                             TYPE values[], size_t n) {                                         \
        (void)vr; (void)values; (void)n;                                                       \
        return none(c, nvr);                                                                   \
    }                                                                                          \
    fmi3Status fmi3Set##NAME(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,         \
                             const TYPE values[], size_t n) {                                   \
        (void)vr; (void)values; (void)n;                                                       \
        return none(c, nvr);                                                                   \
    }

NO_GET_SET(Float32, fmi3Float32)
NO_GET_SET(Int8, fmi3Int8)
NO_GET_SET(UInt8, fmi3UInt8)
NO_GET_SET(Int16, fmi3Int16)
NO_GET_SET(UInt16, fmi3UInt16)
NO_GET_SET(Int32, fmi3Int32)
NO_GET_SET(UInt32, fmi3UInt32)
NO_GET_SET(Int64, fmi3Int64)
NO_GET_SET(Boolean, fmi3Boolean)
NO_GET_SET(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         size_t sizes[], fmi3Binary values[], size_t n) {
    (void)vr; (void)sizes; (void)values; (void)n;
    return none(c, nvr);
}
fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         const size_t sizes[], const fmi3Binary values[], size_t n) {
    (void)vr; (void)sizes; (void)values; (void)n;
    return none(c, nvr);
}
fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Clock values[]) {
    (void)vr; (void)values;
    return none(c, nvr);
}
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Clock values[]) {
    (void)vr; (void)values;
    return none(c, nvr);
}

/* ---- what this FMU does not do ---- */

#define UNSUPPORTED(WHAT) return fail(c, "modbot_ss3 does not support " WHAT)

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr, size_t *n) {
    (void)vr; (void)n;
    UNSUPPORTED("variable dependencies");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent,
                                       size_t element_of_dependent[],
                                       fmi3ValueReference independents[],
                                       size_t element_of_independents[],
                                       fmi3DependencyKind kinds[], size_t n) {
    (void)dependent; (void)element_of_dependent; (void)independents;
    (void)element_of_independents; (void)kinds; (void)n;
    UNSUPPORTED("variable dependencies");
}
fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *s) {
    (void)s;
    UNSUPPORTED("FMU states");
}
fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState s) {
    (void)s;
    UNSUPPORTED("FMU states");
}
fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *s) {
    (void)s;
    UNSUPPORTED("FMU states");
}
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState s, size_t *size) {
    (void)s; (void)size;
    UNSUPPORTED("FMU states");
}
fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState s, fmi3Byte b[], size_t size) {
    (void)s; (void)b; (void)size;
    UNSUPPORTED("FMU states");
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte b[], size_t size,
                                   fmi3FMUState *s) {
    (void)b; (void)size; (void)s;
    UNSUPPORTED("FMU states");
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference unknowns[],
                                        size_t n_unknowns, const fmi3ValueReference knowns[],
                                        size_t n_knowns, const fmi3Float64 seed[], size_t n_seed,
                                        fmi3Float64 sensitivity[], size_t n_sensitivity) {
    (void)unknowns; (void)n_unknowns; (void)knowns; (void)n_knowns; (void)seed; (void)n_seed;
    (void)sensitivity; (void)n_sensitivity;
    UNSUPPORTED("derivatives");
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference unknowns[],
                                    size_t n_unknowns, const fmi3ValueReference knowns[],
                                    size_t n_knowns, const fmi3Float64 seed[], size_t n_seed,
                                    fmi3Float64 sensitivity[], size_t n_sensitivity) {
    (void)unknowns; (void)n_unknowns; (void)knowns; (void)n_knowns; (void)seed; (void)n_seed;
    (void)sensitivity; (void)n_sensitivity;
    UNSUPPORTED("derivatives");
}
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)intervals; (void)qualifiers;
    UNSUPPORTED("clocks");
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions; (void)qualifiers;
    UNSUPPORTED("clocks");
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    UNSUPPORTED("clocks");
}
fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED("clocks");
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)vr; (void)nvr; (void)intervals;
    UNSUPPORTED("clocks");
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED("clocks");
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    UNSUPPORTED("clocks");
}
fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED("clocks");
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) { UNSUPPORTED("event mode"); }
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *update, fmi3Boolean *terminate,
                                    fmi3Boolean *nominals_changed, fmi3Boolean *values_changed,
                                    fmi3Boolean *next_defined, fmi3Float64 *next) {
    (void)update; (void)terminate; (void)nominals_changed; (void)values_changed;
    (void)next_defined; (void)next;
    UNSUPPORTED("event mode");
}

/* Model exchange. */
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) { UNSUPPORTED("model exchange"); }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean no_prior,
                                       fmi3Boolean *enter_event_mode, fmi3Boolean *terminate) {
    (void)no_prior; (void)enter_event_mode; (void)terminate;
    UNSUPPORTED("model exchange");
}
fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    (void)time;
    UNSUPPORTED("model exchange");
}
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t n) {
    (void)x; (void)n;
    UNSUPPORTED("model exchange");
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t n) {
    (void)dx; (void)n;
    UNSUPPORTED("model exchange");
}
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 indicators[], size_t n) {
    (void)indicators; (void)n;
    UNSUPPORTED("model exchange");
}
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) {
    (void)x; (void)n;
    UNSUPPORTED("model exchange");
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[], size_t n) {
    (void)nominals; (void)n;
    UNSUPPORTED("model exchange");
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    (void)n;
    UNSUPPORTED("model exchange");
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    (void)n;
    UNSUPPORTED("model exchange");
}

/* Scheduled execution. */
fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clock,
                                      fmi3Float64 activation_time) {
    (void)clock; (void)activation_time;
    UNSUPPORTED("scheduled execution");
}

/* ---- co-simulation ---- */

fmi3Status fmi3EnterStepMode(fmi3Instance c) { (void)c; return fmi3OK; }

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t n) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)n;
    UNSUPPORTED("output derivatives");
}

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean no_prior,
                      fmi3Boolean *event_handling_needed, fmi3Boolean *terminate,
                      fmi3Boolean *early_return, fmi3Float64 *last_successful_time) {
    (void)no_prior;
    Instance *m = c;
    if (m->phase != STEPPING || !(h >= 0.0)) {
        return fail(m, "doStep needs an initialised FMU and a step of 0 or more");
    }
    advance(m, h);
    m->time = t + h;
    *event_handling_needed = fmi3False;
    *terminate = fmi3False;
    *early_return = fmi3False;
    *last_successful_time = m->time;
    return fmi3OK;
}
