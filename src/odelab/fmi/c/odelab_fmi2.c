/* odelab's FMI 2.0 runtime: Model Exchange and Co-Simulation for a generated model.c, which
   defines NX, NY, NPAR, NP, PAR_OFFSET, NTE, NZ, P_START, X_START, TIME_EVENTS, model_rhs,
   model_outputs and model_indicators, then includes this file. Written against the FMI 2.0 standard headers of the
   Modelica Association (fmi2Functions.h, BSD-2, shipped beside this file).

   Value references: 0..NX-1 the states, NX..2NX-1 their derivatives, 2NX..2NX+NY-1 the outputs,
   then the NPAR parameters (entries PAR_OFFSET.. of the run-time vector p).

   Co-Simulation integrates with odelab's ode45: the Dormand-Prince 5(4) pair with MATLAB's
   initial step, error norm and step-size control (Shampine & Reichelt, SIAM J. Sci. Comput. 18,
   1997), relative tolerance from fmi2SetupExperiment (else the DefaultExperiment's) and absolute
   tolerance 1e-3 of it (MATLAB's default ratio), restarting at each time event of the inputs.
   Part of odelab (MIT). */
#include <float.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

#define NXA (NX > 0 ? NX : 1)
#define NYA (NY > 0 ? NY : 1)
#define VR_DER (NX)
#define VR_OUT (2 * NX)
#define VR_PAR (2 * NX + NY)
#define VR_END (2 * NX + NY + NPAR)
#define MAX_CS_STEPS 10000000L

typedef enum { S_INSTANTIATED, S_INIT, S_EVENT, S_CONT, S_STEP, S_TERMINATED, S_ERROR } Phase;

typedef struct {
    char name[128];
    fmi2Type type;
    fmi2CallbackFunctions cb;  /* a copy: the host's struct may not outlive fmi2Instantiate */
    fmi2Boolean logging;
    Phase phase;
    double t, t_start, t_stop;
    double x[NXA];
    double p[NP];
    double rtol;
    int next_event;   /* index of the first time event not yet handled */
    double h;         /* Co-Simulation: the integrator's next step size (0: not started) */
    double k[7][NXA]; /* Dormand-Prince stages */
} Instance;

static void logmsg(Instance *m, fmi2Status status, const char *category, const char *text)
{
    if (m && m->cb.logger && (m->logging || status >= fmi2Warning))
        m->cb.logger(m->cb.componentEnvironment, m->name, status, category, "%s", text);
}

/* inputs are read at t clipped to the current piece, as odelab's simulate does: the last stage of
   a step that lands on a jump sees the value before it */
static void set_bounds(Instance *m)
{
    double lo = -INFINITY, hi = INFINITY;
    if (NTE > 0 && m->next_event > 0) lo = TIME_EVENTS[m->next_event - 1];
    if (NTE > 0 && m->next_event < NTE) hi = nextafter(TIME_EVENTS[m->next_event], -INFINITY);
    if (PAR_OFFSET == 2) {
        m->p[0] = lo;
        m->p[1] = hi;
    }
}

static void pass_events(Instance *m, double t)
{
    while (m->next_event < NTE && TIME_EVENTS[m->next_event] <= t) m->next_event++;
    set_bounds(m);
}

static void rhs(Instance *m, double t, const double *x, double *dx) { model_rhs(t, x, m->p, dx); }

/* --- common functions ------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    (void)n; (void)cats;
    if (!c) return fmi2Error;
    ((Instance *)c)->logging = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging)
{
    Instance *m;
    (void)location; (void)visible;
    if (!cb || !cb->allocateMemory || !cb->freeMemory) return NULL;
    if (!guid || strcmp(guid, MODEL_GUID) != 0) {
        if (cb->logger) cb->logger(cb->componentEnvironment, name ? name : "", fmi2Error, "error",
                                   "the GUID does not match this FMU's modelDescription.xml");
        return NULL;
    }
    m = (Instance *)cb->allocateMemory(1, sizeof(Instance));
    if (!m) return NULL;
    memset(m, 0, sizeof(Instance));
    strncpy(m->name, name ? name : "", sizeof(m->name) - 1);
    m->type = type;
    m->cb = *cb;
    m->logging = logging;
    m->phase = S_INSTANTIATED;
    memcpy(m->p, P_START, sizeof(m->p));
    if (NX > 0) memcpy(m->x, X_START, sizeof(double) * NX);
    m->rtol = DEFAULT_TOLERANCE;
    m->t = m->t_start = DEFAULT_START;
    m->t_stop = DEFAULT_STOP;
    set_bounds(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (m) m->cb.freeMemory(m);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop)
{
    Instance *m = (Instance *)c;
    if (!m || m->phase != S_INSTANTIATED) return fmi2Error;
    if (tolDefined && tol > 0.0) m->rtol = tol;
    m->t = m->t_start = start;
    if (stopDefined && stop > start) m->t_stop = stop;
    m->next_event = 0;
    while (m->next_event < NTE && TIME_EVENTS[m->next_event] < start) m->next_event++;
    set_bounds(m);
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!m || m->phase != S_INSTANTIATED) return fmi2Error;
    m->phase = S_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!m || m->phase != S_INIT) return fmi2Error;
    pass_events(m, m->t);  /* an input jumping at the start time holds its value after the jump */
    m->phase = m->type == fmi2ModelExchange ? S_EVENT : S_STEP;
    m->h = 0.0;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!m) return fmi2Error;
    m->phase = S_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!m) return fmi2Error;
    memcpy(m->p, P_START, sizeof(m->p));
    if (NX > 0) memcpy(m->x, X_START, sizeof(double) * NX);
    m->rtol = DEFAULT_TOLERANCE;
    m->t = m->t_start = DEFAULT_START;
    m->t_stop = DEFAULT_STOP;
    m->next_event = 0;
    m->h = 0.0;
    set_bounds(m);
    m->phase = S_INSTANTIATED;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    Instance *m = (Instance *)c;
    double dx[NXA], y[NYA];
    size_t i;
    if (!m || (n && (!vr || !value))) return fmi2Error;
    if (NX > 0) rhs(m, m->t, m->x, dx);
    if (NY > 0) model_outputs(m->t, m->x, m->p, y);
    for (i = 0; i < n; i++) {
        fmi2ValueReference r = vr[i];
        if (r < VR_DER) value[i] = m->x[r];
        else if (r < VR_OUT) value[i] = dx[r - VR_DER];
        else if (r < VR_PAR) value[i] = y[r - VR_OUT];
        else if (r < VR_END) value[i] = m->p[PAR_OFFSET + (r - VR_PAR)];
        else {
            logmsg(m, fmi2Error, "error", "fmi2GetReal: unknown value reference");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    Instance *m = (Instance *)c;
    size_t i;
    if (!m || (n && (!vr || !value))) return fmi2Error;
    for (i = 0; i < n; i++) {
        fmi2ValueReference r = vr[i];
        if (r < VR_DER && (m->phase == S_INSTANTIATED || m->phase == S_INIT)) m->x[r] = value[i];
        else if (r >= VR_PAR && r < VR_END && m->phase != S_TERMINATED && m->phase != S_ERROR) {
            m->p[PAR_OFFSET + (r - VR_PAR)] = value[i];
            m->h = 0.0;  /* a tuned parameter: the integrator starts afresh */
        } else {
            logmsg(m, fmi2Error, "error", "fmi2SetReal: the variable cannot be set now, or is unknown");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

static fmi2Status none(fmi2Component c, size_t n)
{
    if (!c) return fmi2Error;
    return n == 0 ? fmi2OK : fmi2Error;  /* no Integer, Boolean or String variables */
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
{ (void)vr; (void)v; return none(c, n); }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
{ (void)vr; (void)v; return none(c, n); }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
{ (void)vr; (void)v; return none(c, n); }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
{ (void)vr; (void)v; return none(c, n); }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
{ (void)vr; (void)v; return none(c, n); }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
{ (void)vr; (void)v; return none(c, n); }

/* canGetAndSetFMUstate, canSerializeFMUstate and providesDirectionalDerivative are false */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n)
{ (void)c; (void)s; (void)n; return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
{ (void)c; (void)s; (void)b; (void)n; return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s)
{ (void)c; (void)b; (void)n; (void)s; return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
{ (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz; return fmi2Error; }

/* --- Model Exchange ------------------------------------------------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!m) return fmi2Error;
    m->phase = S_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    Instance *m = (Instance *)c;
    if (!m || !info) return fmi2Error;
    pass_events(m, m->t);
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = m->next_event < NTE ? fmi2True : fmi2False;
    info->nextEventTime = m->next_event < NTE ? TIME_EVENTS[m->next_event] : 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!m) return fmi2Error;
    m->phase = S_CONT;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!c || !enterEventMode || !terminateSimulation) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t)
{
    Instance *m = (Instance *)c;
    if (!m) return fmi2Error;
    m->t = t;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n)
{
    Instance *m = (Instance *)c;
    if (!m || n != (size_t)NX || (n && !x)) return fmi2Error;
    if (NX > 0) memcpy(m->x, x, sizeof(double) * NX);
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n)
{
    Instance *m = (Instance *)c;
    if (!m || n != (size_t)NX || (n && !dx)) return fmi2Error;
    if (NX > 0) rhs(m, m->t, m->x, dx);
    return fmi2OK;
}

/* the switching functions of the diagram's saturations and dead zones: the host locates their
   zeros and restarts its integrator there (nothing changes in event mode: the corners are in the
   formulas) */
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n)
{
    Instance *m = (Instance *)c;
    if (!m || n != (size_t)NZ || (n && !z)) return fmi2Error;
    if (NZ > 0) model_indicators(m->t, m->x, m->p, z);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n)
{
    Instance *m = (Instance *)c;
    if (!m || n != (size_t)NX || (n && !x)) return fmi2Error;
    if (NX > 0) memcpy(x, m->x, sizeof(double) * NX);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n)
{
    size_t i;
    if (!c || n != (size_t)NX || (n && !x)) return fmi2Error;
    for (i = 0; i < n; i++) x[i] = 1.0;
    return fmi2OK;
}

/* --- Co-Simulation: odelab's ode45 ----------------------------------------------------------- */

/* Dormand & Prince, J. Comput. Appl. Math. 6 (1980); MATLAB's ode45 weights and error row */
static const double A2 = 1.0 / 5.0;
static const double A3[2] = {3.0 / 40.0, 9.0 / 40.0};
static const double A4[3] = {44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0};
static const double A5[4] = {19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0};
static const double A6[5] = {9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0};
static const double B[6] = {35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0};
static const double C[6] = {0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0};
static const double E[7] = {71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0,
                            22.0 / 525.0, -1.0 / 40.0};

static double hmin_at(double t) { return 16.0 * (nextafter(fabs(t), INFINITY) - fabs(t)); }

/* MATLAB's initial step (ode45: the first derivative scaled by the tolerance) */
static double first_step(Instance *m, double t, double tend, double hmax, double atol)
{
    double threshold = atol / m->rtol, rh = 0.0, absh = fmin(hmax, fabs(tend - t));
    int i;
    for (i = 0; i < NX; i++) {
        double w = fmax(fabs(m->x[i]), threshold);
        rh = fmax(rh, fabs(m->k[0][i]) / w);
    }
    rh /= 0.8 * pow(m->rtol, 0.2);
    if (absh * rh > 1.0) absh = 1.0 / rh;
    return fmax(absh, hmin_at(t));
}

/* integrate m->x from m->t to tend (no time event inside); returns 0, or -1 if the step size
   underflows or the steps run out */
static int dopri(Instance *m, double tend, long *steps)
{
    const double atol = m->rtol * 1e-3, threshold = atol / m->rtol, pw = 0.2;
    double hmax = 0.1 * fabs(m->t_stop - m->t_start), y[NXA], ynew[NXA];
    int i, j, done = 0;
    if (NX == 0 || tend <= m->t) { m->t = tend; return 0; }
    if (!(hmax > 0.0)) hmax = fabs(tend - m->t);
    rhs(m, m->t, m->x, m->k[0]);
    if (m->h <= 0.0) m->h = first_step(m, m->t, tend, hmax, atol);
    while (!done) {
        double t = m->t, absh = fmin(hmax, fmax(hmin_at(t), m->h)), h, err;
        int nofailed = 1;
        if (1.1 * absh >= tend - t) { absh = tend - t; done = 1; }
        for (;;) {
            h = absh;
            for (i = 0; i < NX; i++) y[i] = m->x[i] + h * A2 * m->k[0][i];
            rhs(m, t + C[1] * h, y, m->k[1]);
            for (i = 0; i < NX; i++) y[i] = m->x[i] + h * (A3[0] * m->k[0][i] + A3[1] * m->k[1][i]);
            rhs(m, t + C[2] * h, y, m->k[2]);
            for (i = 0; i < NX; i++)
                y[i] = m->x[i] + h * (A4[0] * m->k[0][i] + A4[1] * m->k[1][i] + A4[2] * m->k[2][i]);
            rhs(m, t + C[3] * h, y, m->k[3]);
            for (i = 0; i < NX; i++)
                y[i] = m->x[i] + h * (A5[0] * m->k[0][i] + A5[1] * m->k[1][i] + A5[2] * m->k[2][i] +
                                       A5[3] * m->k[3][i]);
            rhs(m, t + C[4] * h, y, m->k[4]);
            for (i = 0; i < NX; i++)
                y[i] = m->x[i] + h * (A6[0] * m->k[0][i] + A6[1] * m->k[1][i] + A6[2] * m->k[2][i] +
                                       A6[3] * m->k[3][i] + A6[4] * m->k[4][i]);
            rhs(m, done ? tend : t + h, y, m->k[5]);
            for (i = 0; i < NX; i++) {
                double s = 0.0;
                for (j = 0; j < 6; j++) s += B[j] * m->k[j][i];
                ynew[i] = m->x[i] + h * s;
            }
            rhs(m, done ? tend : t + h, ynew, m->k[6]);
            err = 0.0;
            for (i = 0; i < NX; i++) {
                double e = 0.0, w = fmax(fmax(fabs(m->x[i]), fabs(ynew[i])), threshold);
                for (j = 0; j < 7; j++) e += E[j] * m->k[j][i];
                err = fmax(err, fabs(e) / w);
            }
            err *= absh;
            if (++*steps > MAX_CS_STEPS) return -1;
            if (err > m->rtol) {
                if (absh <= hmin_at(t)) return -1;
                if (nofailed) {
                    nofailed = 0;
                    absh = fmax(hmin_at(t), absh * fmax(0.1, 0.8 * pow(m->rtol / err, pw)));
                } else {
                    absh = fmax(hmin_at(t), 0.5 * absh);
                }
                done = 0;
                if (1.1 * absh >= tend - t) { absh = tend - t; done = 1; }
                continue;
            }
            break;
        }
        m->t = done ? tend : t + h;
        for (i = 0; i < NX; i++) { m->x[i] = ynew[i]; m->k[0][i] = m->k[6][i]; }
        if (nofailed) {
            double temp = 1.25 * pow(err / m->rtol, pw);
            absh = temp > 0.2 ? absh / temp : 5.0 * absh;
        }
        if (!done) m->h = absh;
    }
    return 0;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real H, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *m = (Instance *)c;
    double tend = t + H;
    long steps = 0;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!m || m->phase != S_STEP || H < 0.0) return fmi2Error;
    if (fabs(t - m->t) > 1e-12 * fmax(1.0, fabs(t))) {
        logmsg(m, fmi2Error, "error", "fmi2DoStep: the communication point is not the FMU's current time");
        return fmi2Error;
    }
    m->t = t;
    while (m->t < tend) {
        double piece = tend;
        if (m->next_event < NTE && TIME_EVENTS[m->next_event] < tend) piece = TIME_EVENTS[m->next_event];
        if (dopri(m, piece, &steps) != 0) {
            logmsg(m, fmi2Error, "error", "fmi2DoStep: ode45 could not reach the end of the step "
                                          "(step size below its minimum, or too many steps)");
            m->phase = S_ERROR;
            return fmi2Error;
        }
        if (piece < tend || (m->next_event < NTE && TIME_EVENTS[m->next_event] <= m->t)) {
            pass_events(m, m->t);  /* an input jumps: the integrator restarts after it */
            m->h = 0.0;
        }
    }
    m->t = tend;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real v[])
{ (void)vr; (void)order; (void)v; return none(c, n); }

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real v[])
{ (void)vr; (void)order; (void)v; return none(c, n); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
{
    Instance *m = (Instance *)c;
    if (!m || !v || s != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = m->t;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
