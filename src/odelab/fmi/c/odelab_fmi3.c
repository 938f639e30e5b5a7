/* odelab's FMI 3.0 runtime: Model Exchange and Co-Simulation for a generated model.c (the same
   one as FMI 2.0's), written against the Modelica Association's FMI 3.0 headers (fmi3Functions.h,
   BSD-2, shipped beside this file). The instance, the inputs' time events and the Co-Simulation
   ode45 are odelab_core.c's. Value references as in FMI 2.0, then the event indicators, then
   time (the independent variable FMI 3.0 asks for). Part of odelab (MIT). */
#include "fmi3Functions.h"

#define INSTANCE_API fmi3InstanceEnvironment env; fmi3LogMessageCallback log;
#include "odelab_core.c"

static void logmsg(Instance *m, fmi3Status status, const char *category, const char *text)
{
    if (m && m->log && (m->logging || status >= fmi3Warning)) m->log(m->env, status, category, text);
}

static fmi3Instance instantiate(fmi3String name, fmi3String token, fmi3Boolean logging, fmi3InstanceEnvironment env,
                                fmi3LogMessageCallback log, int model_exchange)
{
    Instance *m;
    if (!token || strcmp(token, MODEL_GUID) != 0) {
        if (log) log(env, fmi3Error, "error", "the instantiation token does not match this FMU's modelDescription.xml");
        return NULL;
    }
    m = (Instance *)calloc(1, sizeof(Instance));
    if (!m) return NULL;
    strncpy(m->name, name ? name : "", sizeof(m->name) - 1);
    m->env = env;
    m->log = log;
    m->logging = logging;
    m->model_exchange = model_exchange;
    m->phase = S_INSTANTIATED;
    start_values(m);
    return m;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cats[])
{
    (void)n; (void)cats;
    if (!c) return fmi3Error;
    ((Instance *)c)->logging = on;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                          fmi3Boolean logging, fmi3InstanceEnvironment env, fmi3LogMessageCallback log)
{
    (void)resources; (void)visible;
    return instantiate(name, token, logging, env, log, 1);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                         fmi3Boolean logging, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference required[], size_t nRequired,
                                         fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                         fmi3IntermediateUpdateCallback update)
{
    (void)resources; (void)visible; (void)eventModeUsed; (void)earlyReturnAllowed; (void)required; (void)nRequired;
    (void)update;
    return instantiate(name, token, logging, env, log, 0);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String resources,
                                               fmi3Boolean visible, fmi3Boolean logging, fmi3InstanceEnvironment env,
                                               fmi3LogMessageCallback log, fmi3ClockUpdateCallback clock,
                                               fmi3LockPreemptionCallback lock, fmi3UnlockPreemptionCallback unlock)
{
    (void)name; (void)token; (void)resources; (void)visible; (void)logging; (void)clock; (void)lock; (void)unlock;
    if (log) log(env, fmi3Error, "error", "this FMU offers no Scheduled Execution");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance c) { free(c); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tolDefined, fmi3Float64 tol, fmi3Float64 start,
                                       fmi3Boolean stopDefined, fmi3Float64 stop)
{
    Instance *m = (Instance *)c;
    if (!m || m->phase != S_INSTANTIATED) return fmi3Error;
    if (tolDefined && tol > 0.0) m->rtol = tol;
    m->t = m->t_start = start;
    if (stopDefined && stop > start) m->t_stop = stop;
    m->next_event = 0;
    while (m->next_event < NTE && TIME_EVENTS[m->next_event] < start) m->next_event++;
    set_bounds(m);
    m->phase = S_INIT;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c)
{
    Instance *m = (Instance *)c;
    if (!m || m->phase != S_INIT) return fmi3Error;
    pass_events(m, m->t);  /* an input jumping at the start time holds its value after the jump */
    m->phase = m->model_exchange ? S_EVENT : S_STEP;
    m->h = 0.0;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance c)
{
    Instance *m = (Instance *)c;
    if (!m) return fmi3Error;
    m->phase = S_EVENT;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance c)
{
    if (!c) return fmi3Error;
    ((Instance *)c)->phase = S_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c)
{
    Instance *m = (Instance *)c;
    if (!m) return fmi3Error;
    start_values(m);
    m->phase = S_INSTANTIATED;
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 values[], size_t nv)
{
    Instance *m = (Instance *)c;
    double dx[NXA], y[NYA], z[NZA];
    size_t i;
    if (!m || nv != n || (n && (!vr || !values))) return fmi3Error;
    evaluate(m, dx, y, z);
    for (i = 0; i < n; i++) {
        if (get_value(m, vr[i], dx, y, z, &values[i]) != 0) {
            logmsg(m, fmi3Error, "error", "fmi3GetFloat64: unknown value reference");
            return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 values[],
                          size_t nv)
{
    Instance *m = (Instance *)c;
    size_t i;
    if (!m || nv != n || (n && (!vr || !values))) return fmi3Error;
    for (i = 0; i < n; i++) {
        if (set_value(m, vr[i], values[i]) != 0) {
            logmsg(m, fmi3Error, "error", "fmi3SetFloat64: the variable cannot be set now, or is unknown");
            return fmi3Error;
        }
    }
    return fmi3OK;
}

/* no variables of the other types: asking for none is fine, for any an error */
#define NO_GET(NAME, TYPE) \
    fmi3Status NAME(fmi3Instance c, const fmi3ValueReference vr[], size_t n, TYPE values[], size_t nv) \
    { (void)vr; (void)values; (void)nv; return c && n == 0 ? fmi3OK : fmi3Error; }
#define NO_SET(NAME, TYPE) \
    fmi3Status NAME(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const TYPE values[], size_t nv) \
    { (void)vr; (void)values; (void)nv; return c && n == 0 ? fmi3OK : fmi3Error; }
NO_GET(fmi3GetFloat32, fmi3Float32)
NO_GET(fmi3GetInt8, fmi3Int8)
NO_GET(fmi3GetUInt8, fmi3UInt8)
NO_GET(fmi3GetInt16, fmi3Int16)
NO_GET(fmi3GetUInt16, fmi3UInt16)
NO_GET(fmi3GetInt32, fmi3Int32)
NO_GET(fmi3GetUInt32, fmi3UInt32)
NO_GET(fmi3GetInt64, fmi3Int64)
NO_GET(fmi3GetUInt64, fmi3UInt64)
NO_GET(fmi3GetBoolean, fmi3Boolean)
NO_GET(fmi3GetString, fmi3String)
NO_SET(fmi3SetFloat32, fmi3Float32)
NO_SET(fmi3SetInt8, fmi3Int8)
NO_SET(fmi3SetUInt8, fmi3UInt8)
NO_SET(fmi3SetInt16, fmi3Int16)
NO_SET(fmi3SetUInt16, fmi3UInt16)
NO_SET(fmi3SetInt32, fmi3Int32)
NO_SET(fmi3SetUInt32, fmi3UInt32)
NO_SET(fmi3SetInt64, fmi3Int64)
NO_SET(fmi3SetUInt64, fmi3UInt64)
NO_SET(fmi3SetBoolean, fmi3Boolean)
NO_SET(fmi3SetString, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n, size_t sizes[], fmi3Binary v[],
                         size_t nv)
{ (void)vr; (void)sizes; (void)v; (void)nv; return c && n == 0 ? fmi3OK : fmi3Error; }
fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const size_t sizes[],
                         const fmi3Binary v[], size_t nv)
{ (void)vr; (void)sizes; (void)v; (void)nv; return c && n == 0 ? fmi3OK : fmi3Error; }
fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Clock v[])
{ (void)vr; (void)v; return c && n == 0 ? fmi3OK : fmi3Error; }
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Clock v[])
{ (void)vr; (void)v; return c && n == 0 ? fmi3OK : fmi3Error; }

/* providesDirectionalDerivative, canGetAndSetFMUState, canSerializeFMUState are false; no clocks */
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr, size_t *n)
{ (void)c; (void)vr; (void)n; return fmi3Error; }
fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference d, size_t e[], fmi3ValueReference i[],
                                       size_t k[], fmi3DependencyKind kinds[], size_t n)
{ (void)c; (void)d; (void)e; (void)i; (void)k; (void)kinds; (void)n; return fmi3Error; }
fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *s) { (void)c; (void)s; return fmi3Error; }
fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState s) { (void)c; (void)s; return fmi3Error; }
fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *s) { (void)c; (void)s; return fmi3Error; }
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState s, size_t *n) { (void)c; (void)s; (void)n; return fmi3Error; }
fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState s, fmi3Byte b[], size_t n)
{ (void)c; (void)s; (void)b; (void)n; return fmi3Error; }
fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte b[], size_t n, fmi3FMUState *s)
{ (void)c; (void)b; (void)n; (void)s; return fmi3Error; }
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                        const fmi3ValueReference k[], size_t nk, const fmi3Float64 s[], size_t ns,
                                        fmi3Float64 r[], size_t nr)
{ (void)c; (void)u; (void)nu; (void)k; (void)nk; (void)s; (void)ns; (void)r; (void)nr; return fmi3Error; }
fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                    const fmi3ValueReference k[], size_t nk, const fmi3Float64 s[], size_t ns,
                                    fmi3Float64 r[], size_t nr)
{ (void)c; (void)u; (void)nu; (void)k; (void)nk; (void)s; (void)ns; (void)r; (void)nr; return fmi3Error; }
fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) { (void)c; return fmi3Error; }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) { (void)c; return fmi3Error; }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 i[],
                                  fmi3IntervalQualifier q[])
{ (void)c; (void)vr; (void)n; (void)i; (void)q; return fmi3Error; }
fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 a[],
                                   fmi3UInt64 b[], fmi3IntervalQualifier q[])
{ (void)c; (void)vr; (void)n; (void)a; (void)b; (void)q; return fmi3Error; }
fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 s[])
{ (void)c; (void)vr; (void)n; (void)s; return fmi3Error; }
fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 a[], fmi3UInt64 b[])
{ (void)c; (void)vr; (void)n; (void)a; (void)b; return fmi3Error; }
fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 i[])
{ (void)c; (void)vr; (void)n; (void)i; return fmi3Error; }
fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 a[],
                                   const fmi3UInt64 b[])
{ (void)c; (void)vr; (void)n; (void)a; (void)b; return fmi3Error; }
fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 s[])
{ (void)c; (void)vr; (void)n; (void)s; return fmi3Error; }
fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 a[],
                                const fmi3UInt64 b[])
{ (void)c; (void)vr; (void)n; (void)a; (void)b; return fmi3Error; }
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) { return c ? fmi3OK : fmi3Error; }
fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference k, fmi3Float64 t)
{ (void)c; (void)k; (void)t; return fmi3Error; }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *need, fmi3Boolean *terminate,
                                    fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged,
                                    fmi3Boolean *nextDefined, fmi3Float64 *next)
{
    Instance *m = (Instance *)c;
    if (!m || !need || !terminate || !nominalsChanged || !valuesChanged || !nextDefined || !next) return fmi3Error;
    pass_events(m, m->t);
    *need = fmi3False;
    *terminate = fmi3False;
    *nominalsChanged = fmi3False;
    *valuesChanged = fmi3False;
    *nextDefined = m->next_event < NTE ? fmi3True : fmi3False;
    *next = m->next_event < NTE ? TIME_EVENTS[m->next_event] : 0.0;
    return fmi3OK;
}

/* --- Model Exchange ------------------------------------------------------------------------- */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c)
{
    if (!c) return fmi3Error;
    ((Instance *)c)->phase = S_CONT;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!c || !enterEventMode || !terminateSimulation) return fmi3Error;
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 t)
{
    if (!c) return fmi3Error;
    ((Instance *)c)->t = t;
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t n)
{
    Instance *m = (Instance *)c;
    if (!m || n != (size_t)NX || (n && !x)) return fmi3Error;
    if (NX > 0) memcpy(m->x, x, sizeof(double) * NX);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t n)
{
    Instance *m = (Instance *)c;
    if (!m || n != (size_t)NX || (n && !dx)) return fmi3Error;
    if (NX > 0) rhs(m, m->t, m->x, dx);
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t n)
{
    Instance *m = (Instance *)c;
    if (!m || n != (size_t)NZ || (n && !z)) return fmi3Error;
    if (NZ > 0) model_indicators(m->t, m->x, m->p, z);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n)
{
    Instance *m = (Instance *)c;
    if (!m || n != (size_t)NX || (n && !x)) return fmi3Error;
    if (NX > 0) memcpy(x, m->x, sizeof(double) * NX);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n)
{
    size_t i;
    if (!c || n != (size_t)NX || (n && !x)) return fmi3Error;
    for (i = 0; i < n; i++) x[i] = 1.0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n)
{
    if (!c || !n) return fmi3Error;
    *n = NZ;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n)
{
    if (!c || !n) return fmi3Error;
    *n = NX;
    return fmi3OK;
}

/* --- Co-Simulation ------------------------------------------------------------------------- */

fmi3Status fmi3EnterStepMode(fmi3Instance c)
{
    Instance *m = (Instance *)c;
    if (!m) return fmi3Error;
    m->phase = S_STEP;
    return fmi3OK;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Int32 order[],
                                    fmi3Float64 values[], size_t nv)
{ (void)vr; (void)order; (void)values; (void)nv; return c && n == 0 ? fmi3OK : fmi3Error; }

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 H, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    Instance *m = (Instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!m || m->phase != S_STEP || H < 0.0) return fmi3Error;
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (fabs(t - m->t) > 1e-12 * fmax(1.0, fabs(t))) {
        logmsg(m, fmi3Error, "error", "fmi3DoStep: the communication point is not the FMU's current time");
        return fmi3Error;
    }
    m->t = t;
    if (advance(m, t + H) != 0) {
        logmsg(m, fmi3Error, "error", "fmi3DoStep: ode45 could not reach the end of the step "
                                      "(step size below its minimum, or too many steps)");
        m->phase = S_ERROR;
        if (lastSuccessfulTime) *lastSuccessfulTime = m->t;
        return fmi3Error;
    }
    if (lastSuccessfulTime) *lastSuccessfulTime = m->t;
    return fmi3OK;
}
