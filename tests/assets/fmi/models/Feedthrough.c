/* Inputs passed to outputs: real (and a tunable gain on a second output), integer, boolean
   (odelab's test model, MIT) */
#define GUID "{8c4e810f-3df3-4a00-8276-176fa3c90005}"
#define NR 4
#define NI 2
#define NB 2
#define NX 0
#define NZ 0
static const int STATE[1] = {0};
static const int DER[1] = {0};
#include "testfmu.h"
enum { real_in, real_out, gain, scaled_out };
static void start(Model *m) { m->r[gain] = 2.0; }
static void derivatives(Model *m)
{
    m->r[real_out] = m->r[real_in];
    m->r[scaled_out] = m->r[gain] * m->r[real_in];
    m->i[1] = m->i[0];
    m->b[1] = m->b[0];
}
static void indicators(Model *m, double *z) { (void)m; (void)z; }
static void event(Model *m, fmi2EventInfo *info) { (void)info; derivatives(m); }
