/* Dahlquist's test equation x' = -k x, x(0) = 1: x = exp(-k t) (odelab's test model, MIT) */
#define GUID "{8c4e810f-3df3-4a00-8276-176fa3c90002}"
#define NR 3
#define NI 0
#define NB 0
#define NX 1
#define NZ 0
static const int STATE[NX] = {0};
static const int DER[NX] = {1};
#include "testfmu.h"
enum { x, der_x, k };
static void start(Model *m) { m->r[x] = 1.0; m->r[k] = 1.0; }
static void derivatives(Model *m) { m->r[der_x] = -m->r[k] * m->r[x]; }
static void indicators(Model *m, double *z) { (void)m; (void)z; }
static void event(Model *m, fmi2EventInfo *info) { (void)m; (void)info; }
