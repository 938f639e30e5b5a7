/* A small FMI 2.0 Model Exchange framework for odelab's test FMUs (written for odelab's tests,
   MIT): each model file defines its variables and hooks, then includes this file.

   A model defines NR, NI, NB (its Real, Integer and Boolean variables, by value reference),
   NX (continuous states: the Reals STATE[k], whose derivatives are the Reals DER[k]), NZ
   (event indicators), and the hooks start(m), derivatives(m), indicators(m, z) and
   event(m, info) (called in event mode: time events, and the resets of state events). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

typedef struct {
    double time, next_time;
    int has_next_time;
    double r[NR > 0 ? NR : 1];
    int i[NI > 0 ? NI : 1];
    int b[NB > 0 ? NB : 1];
    const fmi2CallbackFunctions *cb;
} Model;

static void start(Model *m);
static void derivatives(Model *m);
static void indicators(Model *m, double *z);
static void event(Model *m, fmi2EventInfo *info);

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String k[])
{ (void)c; (void)on; (void)n; (void)k; return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging)
{
    Model *m;
    (void)name; (void)location; (void)visible; (void)logging;
    if (type != fmi2ModelExchange || !guid || strcmp(guid, GUID) != 0) return NULL;
    m = (Model *)calloc(1, sizeof(Model));
    if (!m) return NULL;
    m->cb = cb;
    start(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real tol, fmi2Real t0, fmi2Boolean b, fmi2Real t1)
{ (void)a; (void)tol; (void)b; (void)t1; ((Model *)c)->time = t0; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { derivatives((Model *)c); return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { Model *m = (Model *)c; memset(m->r, 0, sizeof(m->r)); start(m); return fmi2OK; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[])
{
    Model *m = (Model *)c; size_t k;
    derivatives(m);
    for (k = 0; k < n; k++) { if (vr[k] >= NR) return fmi2Error; v[k] = m->r[vr[k]]; }
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
{
    Model *m = (Model *)c; size_t k;
    derivatives(m);
    for (k = 0; k < n; k++) { if (vr[k] >= NI) return fmi2Error; v[k] = m->i[vr[k]]; }
    return fmi2OK;
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
{
    Model *m = (Model *)c; size_t k;
    derivatives(m);
    for (k = 0; k < n; k++) { if (vr[k] >= NB) return fmi2Error; v[k] = m->b[vr[k]]; }
    return fmi2OK;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
{ (void)c; (void)vr; (void)v; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[])
{
    Model *m = (Model *)c; size_t k;
    for (k = 0; k < n; k++) { if (vr[k] >= NR) return fmi2Error; m->r[vr[k]] = v[k]; }
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
{
    Model *m = (Model *)c; size_t k;
    for (k = 0; k < n; k++) { if (vr[k] >= NI) return fmi2Error; m->i[vr[k]] = v[k]; }
    return fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
{
    Model *m = (Model *)c; size_t k;
    for (k = 0; k < n; k++) { if (vr[k] >= NB) return fmi2Error; m->b[vr[k]] = v[k] != 0; }
    return fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
{ (void)c; (void)vr; (void)v; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) { (void)c; (void)s; (void)n; return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
{ (void)c; (void)s; (void)b; (void)n; return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s)
{ (void)c; (void)b; (void)n; (void)s; return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb, const fmi2Real d[], fmi2Real e[])
{ (void)c; (void)a; (void)na; (void)b; (void)nb; (void)d; (void)e; return fmi2Error; }

fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    Model *m = (Model *)c;
    memset(info, 0, sizeof(*info));
    event(m, info);
    derivatives(m);
    info->nextEventTimeDefined = m->has_next_time;
    info->nextEventTime = m->next_time;
    return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean a, fmi2Boolean *enter, fmi2Boolean *stop)
{ (void)c; (void)a; *enter = fmi2False; *stop = fmi2False; return fmi2OK; }
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Model *)c)->time = t; return fmi2OK; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n)
{
    Model *m = (Model *)c; size_t k;
    if (n != NX) return fmi2Error;
    for (k = 0; k < n; k++) m->r[STATE[k]] = x[k];
    return fmi2OK;
}
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n)
{
    Model *m = (Model *)c; size_t k;
    if (n != NX) return fmi2Error;
    for (k = 0; k < n; k++) x[k] = m->r[STATE[k]];
    return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n)
{
    Model *m = (Model *)c; size_t k;
    if (n != NX) return fmi2Error;
    derivatives(m);
    for (k = 0; k < n; k++) dx[k] = m->r[DER[k]];
    return fmi2OK;
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n)
{
    if (n != NZ) return fmi2Error;
    if (n) indicators((Model *)c, z);
    return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n)
{ size_t k; (void)c; for (k = 0; k < n; k++) x[k] = 1.0; return fmi2OK; }

/* Co-Simulation is not offered by the test models */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[])
{ (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[])
{ (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean a)
{ (void)c; (void)t; (void)h; (void)a; return fmi2Error; }
fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) { (void)c; (void)s; (void)v; return fmi2Error; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) { (void)c; (void)s; (void)v; return fmi2Error; }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) { (void)c; (void)s; (void)v; return fmi2Error; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) { (void)c; (void)s; (void)v; return fmi2Error; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) { (void)c; (void)s; (void)v; return fmi2Error; }
