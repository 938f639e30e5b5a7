/* odelab's FMU runtime core, shared by its FMI 2.0 and FMI 3.0 interfaces (odelab_fmi2.c,
   odelab_fmi3.c): the instance, the inputs' time events and odelab's ode45 for Co-Simulation.
   The including file defines INSTANCE_API (its own fields: the host's callbacks) first.
   Part of odelab (MIT). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NXA (NX > 0 ? NX : 1)
#define NYA (NY > 0 ? NY : 1)
#define VR_DER (NX)
#define VR_OUT (2 * NX)
#define VR_PAR (2 * NX + NY)
#define VR_END (2 * NX + NY + NPAR)
#define NZA (NZ > 0 ? NZ : 1)
#define VR_TIME (VR_END + NZ)  /* FMI 3's independent variable */
#define MAX_CS_STEPS 10000000L

typedef enum { S_INSTANTIATED, S_INIT, S_EVENT, S_CONT, S_STEP, S_TERMINATED, S_ERROR } Phase;

typedef struct {
    char name[128];
    INSTANCE_API
    int model_exchange;
    int logging;
    Phase phase;
    double t, t_start, t_stop;
    double x[NXA];
    double p[NP];
    double rtol;
    int next_event;   /* index of the first time event not yet handled */
    double h;         /* Co-Simulation: the integrator's next step size (0: not started) */
    double k[7][NXA]; /* Dormand-Prince stages */
} Instance;

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

/* Co-Simulation: integrate from m->t to tend, restarting at each time event; 0, or -1 if ode45 fails */
static int advance(Instance *m, double tend)
{
    long steps = 0;
    while (m->t < tend) {
        double piece = tend;
        if (m->next_event < NTE && TIME_EVENTS[m->next_event] < tend) piece = TIME_EVENTS[m->next_event];
        if (dopri(m, piece, &steps) != 0) return -1;
        if (piece < tend || (m->next_event < NTE && TIME_EVENTS[m->next_event] <= m->t)) {
            pass_events(m, m->t);  /* an input jumps: the integrator restarts after it */
            m->h = 0.0;
        }
    }
    m->t = tend;
    return 0;
}

/* the instance's values as instantiated */
static void start_values(Instance *m)
{
    memcpy(m->p, P_START, sizeof(m->p));
    if (NX > 0) memcpy(m->x, X_START, sizeof(double) * NX);
    m->rtol = DEFAULT_TOLERANCE;
    m->t = m->t_start = DEFAULT_START;
    m->t_stop = DEFAULT_STOP;
    m->next_event = 0;
    m->h = 0.0;
    set_bounds(m);
}

/* the value of a Float64 variable (value references as in the file's head); -1 if unknown */
static int get_value(Instance *m, unsigned int r, const double *dx, const double *y, const double *z, double *value)
{
    if (r < VR_DER) *value = m->x[r];
    else if (r < VR_OUT) *value = dx[r - VR_DER];
    else if (r < VR_PAR) *value = y[r - VR_OUT];
    else if (r < VR_END) *value = m->p[PAR_OFFSET + (r - VR_PAR)];
    else if (r < VR_END + NZ) *value = z[r - VR_END];
    else if (r == VR_TIME) *value = m->t;
    else return -1;
    return 0;
}

/* set a state (before initialisation ends) or a parameter; -1 if it cannot be set now */
static int set_value(Instance *m, unsigned int r, double value)
{
    if (r < VR_DER && (m->phase == S_INSTANTIATED || m->phase == S_INIT)) m->x[r] = value;
    else if (r >= VR_PAR && r < VR_END && m->phase != S_TERMINATED && m->phase != S_ERROR) {
        m->p[PAR_OFFSET + (r - VR_PAR)] = value;
        m->h = 0.0;  /* a tuned parameter: the integrator starts afresh */
    } else return -1;
    return 0;
}

/* the derivatives, outputs and event indicators at the instance's time and states */
static void evaluate(Instance *m, double *dx, double *y, double *z)
{
    if (NX > 0) rhs(m, m->t, m->x, dx);
    if (NY > 0) model_outputs(m->t, m->x, m->p, y);
    if (NZ > 0) model_indicators(m->t, m->x, m->p, z);
}

