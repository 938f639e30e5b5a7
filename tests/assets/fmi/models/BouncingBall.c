/* A ball dropped from h = 1 m, bouncing with restitution e (odelab's test model, MIT) */
#define GUID "{8c4e810f-3df3-4a00-8276-176fa3c90001}"
#define NR 7
#define NI 0
#define NB 0
#define NX 2
#define NZ 1
static const int STATE[NX] = {0, 2};
static const int DER[NX] = {1, 3};
#include "testfmu.h"
enum { h, der_h, v, der_v, g, e, v_min };
static void start(Model *m) { m->r[h] = 1.0; m->r[v] = 0.0; m->r[g] = -9.81; m->r[e] = 0.7; m->r[v_min] = 0.1; }
static void derivatives(Model *m) { m->r[der_h] = m->r[v]; m->r[der_v] = m->r[g]; }
static void indicators(Model *m, double *z) { z[0] = (m->r[h] == 0.0 && m->r[v] == 0.0) ? 1.0 : m->r[h]; }
static void event(Model *m, fmi2EventInfo *info)
{
    if (m->r[h] <= 0.0 && m->r[v] < 0.0) {  /* the bounce: v reversed and damped, h back on the floor */
        m->r[h] = 0.0;
        m->r[v] = -m->r[e] * m->r[v];
        if (m->r[v] < m->r[v_min]) { m->r[v] = 0.0; m->r[g] = 0.0; }  /* at rest */
        info->valuesOfContinuousStatesChanged = fmi2True;
    }
}
