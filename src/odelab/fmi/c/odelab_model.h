/* odelab's FMU runtime: the expression language's functions with numpy's rules (NaN in, NaN
   out; mod with the sign of the divisor), as odelab's compiled backend evaluates them.
   Part of odelab (MIT); shipped in every exported FMU's sources/. */
#ifndef ODELAB_MODEL_H
#define ODELAB_MODEL_H

#include <math.h>
#include <stddef.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static double odelab_heaviside(double x) { return x < 0.0 ? 0.0 : (x == 0.0 ? 0.5 : (x > 0.0 ? 1.0 : x)); }
static double odelab_step(double x) { return x < 0.0 ? 0.0 : (x >= 0.0 ? 1.0 : x); }
static double odelab_where(double c, double a, double b) { return c != 0.0 ? a : b; }
static double odelab_min(double a, double b) { if (a != a || b != b) return a + b; return a <= b ? a : b; }
static double odelab_max(double a, double b) { if (a != a || b != b) return a + b; return a >= b ? a : b; }
static double odelab_sign(double x) { return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : x); }

/* numpy's mod (Python's %): the result takes the sign of the divisor */
static double odelab_npmod(double a, double m)
{
    double r;
    if (m == 0.0) return NAN;
    r = fmod(a, m);
    if (r != 0.0) {
        if ((r < 0.0) != (m < 0.0)) r += m;
    } else {
        r = copysign(0.0, m);
    }
    return r;
}

static double odelab_mod(double a, double m) { return m == 0.0 ? a : odelab_npmod(a, m); }

static double odelab_square(double t, double duty)
{
    return odelab_npmod(t, 2.0 * M_PI) < 2.0 * M_PI * duty / 100.0 ? 1.0 : -1.0;
}

static double odelab_sawtooth(double t, double width)
{
    double phase = odelab_npmod(t, 2.0 * M_PI);
    if (phase < 2.0 * M_PI * width || width >= 1.0) return phase / (M_PI * width) - 1.0;
    return 1.0 - (phase - 2.0 * M_PI * width) / (M_PI * (1.0 - width));
}

static double odelab_pulse(double t, double amplitude, double period, double width, double delay)
{
    double k = floor((t - delay) / period);
    if (t < delay + k * period) k = k - 1.0;
    if (t >= delay + (k + 1.0) * period) k = k + 1.0;
    if (k >= 0.0 && t < (delay + k * period) + width * period) return amplitude;
    return 0.0;
}

/* numpy's interp: the end values outside the table, linear inside */
static double odelab_interp(double x, const double *xp, const double *fp, int n)
{
    int lo = 0, hi = n - 1;
    if (n <= 0 || x != x) return NAN;
    if (x <= xp[0]) return fp[0];
    if (x >= xp[n - 1]) return fp[n - 1];
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (xp[mid] <= x) lo = mid; else hi = mid;
    }
    if (xp[hi] == xp[lo]) return fp[hi];
    return fp[lo] + (x - xp[lo]) * (fp[hi] - fp[lo]) / (xp[hi] - xp[lo]);
}

#endif
