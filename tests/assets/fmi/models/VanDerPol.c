/* van der Pol's oscillator x0'' - mu (1 - x0^2) x0' + x0 = 0 (odelab's test model, MIT) */
#define GUID "{8c4e810f-3df3-4a00-8276-176fa3c90003}"
#define NR 5
#define NI 0
#define NB 0
#define NX 2
#define NZ 0
static const int STATE[NX] = {0, 2};
static const int DER[NX] = {1, 3};
#include "testfmu.h"
enum { x0, der_x0, x1, der_x1, mu };
static void start(Model *m) { m->r[x0] = 2.0; m->r[x1] = 0.0; m->r[mu] = 1.0; }
static void derivatives(Model *m)
{
    m->r[der_x0] = m->r[x1];
    m->r[der_x1] = m->r[mu] * ((1.0 - m->r[x0] * m->r[x0]) * m->r[x1]) - m->r[x0];
}
static void indicators(Model *m, double *z) { (void)m; (void)z; }
static void event(Model *m, fmi2EventInfo *info) { (void)m; (void)info; }
