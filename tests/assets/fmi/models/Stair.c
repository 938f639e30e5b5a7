/* A counter that steps up by one at every whole second (time events; odelab's test model, MIT) */
#define GUID "{8c4e810f-3df3-4a00-8276-176fa3c90004}"
#define NR 1
#define NI 1
#define NB 0
#define NX 0
#define NZ 0
static const int STATE[1] = {0};
static const int DER[1] = {0};
#include "testfmu.h"
static void start(Model *m) { m->i[0] = 1; m->next_time = 1.0; m->has_next_time = 1; }
static void derivatives(Model *m) { (void)m; }
static void indicators(Model *m, double *z) { (void)m; (void)z; }
static void event(Model *m, fmi2EventInfo *info)
{
    (void)info;
    if (m->time >= m->next_time) { m->i[0] += 1; m->next_time += 1.0; }
}
