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
#include "fmi2Functions.h"

#define INSTANCE_API fmi2CallbackFunctions cb;  /* a copy: the host's struct may not outlive fmi2Instantiate */
#include "odelab_core.c"

static void logmsg(Instance *m, fmi2Status status, const char *category, const char *text)
{
    if (m && m->cb.logger && (m->logging || status >= fmi2Warning))
        m->cb.logger(m->cb.componentEnvironment, m->name, status, category, "%s", text);
}

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
    m->model_exchange = type == fmi2ModelExchange;
    m->cb = *cb;
    m->logging = logging;
    m->phase = S_INSTANTIATED;
    start_values(m);
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
    m->phase = m->model_exchange ? S_EVENT : S_STEP;
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
    start_values(m);
    m->phase = S_INSTANTIATED;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    Instance *m = (Instance *)c;
    double dx[NXA], y[NYA], z[NZA];
    size_t i;
    if (!m || (n && (!vr || !value))) return fmi2Error;
    evaluate(m, dx, y, z);
    for (i = 0; i < n; i++) {
        if (vr[i] >= VR_END || get_value(m, vr[i], dx, y, z, &value[i]) != 0) {
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
        if (set_value(m, vr[i], value[i]) != 0) {
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

/* --- Co-Simulation -------------------------------------------------------------------------- */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real H, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *m = (Instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!m || m->phase != S_STEP || H < 0.0) return fmi2Error;
    if (fabs(t - m->t) > 1e-12 * fmax(1.0, fabs(t))) {
        logmsg(m, fmi2Error, "error", "fmi2DoStep: the communication point is not the FMU's current time");
        return fmi2Error;
    }
    m->t = t;
    if (advance(m, t + H) != 0) {
        logmsg(m, fmi2Error, "error", "fmi2DoStep: ode45 could not reach the end of the step "
                                      "(step size below its minimum, or too many steps)");
        m->phase = S_ERROR;
        return fmi2Error;
    }
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
