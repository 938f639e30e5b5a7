"""The stepping loops of the compiled backend (numba), shared by every system.

:mod:`odelab.solvers.compiled.cache` copies this file (after :mod:`odelab.solvers.controller`,
whose step-size rules it compiles) into the cache folder and imports it
from there, so numba's ``cache=True`` keeps its machine code beside it: the loops are compiled
once per machine (and numba version), not once per system. A system's own module holds only
its right-hand side ``rhs(t, y, p, out)`` with the signature :data:`RHS`, and is passed to the
loops as a first-class function (one indirect call per stage, a few nanoseconds).

The loops are :func:`odelab.solvers.engine.integrate_adaptive` and ``integrate_fixed``
statement for statement, with every array operation written out as a loop in the order of the
mathematics, in the order :mod:`odelab.solvers.ordered` fixes for the Python engine (stage
``sum_k hA[i, k] K[k]`` for k = i-1 down to 0, then ``+ y``; the error ``sum_k E[k] K[k]`` and
Refine's ``h * W K + y`` for k = 0 up): the same steps, the same accept/reject decisions and
the same values bit for bit, under every BLAS (neither engine calls it). The output
arrays grow geometrically (doubling), so a long run costs amortised O(1) per output row and
no list of small arrays.
"""

import numpy as _np
from numba import njit as _njit
from numba import types as _types

_F8 = _types.float64
_V = _types.float64[::1]
_M = _types.float64[:, ::1]
_I8 = _types.int64

#: The signature of every generated right-hand side: rhs(t, y, p, out) writes dy/dt into out.
RHS = _types.void(_F8, _V, _V, _V)
_RHS_ARG = _types.FunctionType(RHS)

from odelab.solvers.status import Status as _Status


# The step-size rules: this module's text begins with odelab/solvers/controller.py (see
# cache._KERNELS), whose pure functions are compiled here, so both engines take the same steps.
# Inlined into the loops (numba's IR): no compile unit or cache entry of their own.
@_njit(inline="always", error_model="numpy")
def _ulp(x):
    return _np.spacing(abs(x))


min_step = _njit(inline="always", error_model="numpy")(min_step)  # noqa: F821 (controller.py's)
given_step = _njit(inline="always", error_model="numpy")(given_step)  # noqa: F821
first_step = _njit(inline="always", error_model="numpy")(first_step)  # noqa: F821
clamp_step = _njit(inline="always", error_model="numpy")(clamp_step)  # noqa: F821
shrink = _njit(inline="always", error_model="numpy")(shrink)  # noqa: F821
shrink_after_newton = _njit(inline="always", error_model="numpy")(shrink_after_newton)  # noqa: F821
grow = _njit(inline="always", error_model="numpy")(grow)  # noqa: F821


@_njit(cache=True, error_model="numpy")
def _grow(t_out, y_out, needed):
    capacity = t_out.shape[0]
    while capacity < needed:
        capacity *= 2
    n = y_out.shape[1]
    t_new = _np.empty(capacity)
    y_new = _np.empty((capacity, n))
    for i in range(t_out.shape[0]):
        t_new[i] = t_out[i]
        for j in range(n):
            y_new[i, j] = y_out[i, j]
    return t_new, y_new


@_njit(cache=True, error_model="numpy")
def _start(f0, y0, threshold, norm_control, rtol, power, tspan, hmax, htry, capacity):
    """The run's start: the first step's size |h| (InitialStep if given, htry not NaN, else MATLAB's
    estimate from f0, engine.py's), ||y0|| for NormControl (0 otherwise), and the output's
    arrays with room for ``capacity`` rows, the first (t0, y0)."""
    n = y0.shape[0]
    t0 = tspan[0]
    t_out = _np.empty(capacity)
    y_out = _np.empty((capacity, n))
    t_out[0] = t0
    for j in range(n):
        y_out[0, j] = y0[j]
    normy = 0.0
    if norm_control:
        for j in range(n):
            normy += y0[j] * y0[j]
        normy = _np.sqrt(normy)
    if htry == htry:
        return given_step(htry, t0, hmax), normy, t_out, y_out
    if norm_control:
        nf = 0.0
        for j in range(n):
            nf += f0[j] * f0[j]
        rh = (_np.sqrt(nf) / max(normy, threshold[0])) / (0.8 * rtol ** power)
    else:
        rh = 0.0
        for j in range(n):
            q = abs(f0[j]) / max(abs(y0[j]), threshold[j])
            if q > rh or q != q:
                rh = q
        rh = rh / (0.8 * rtol ** power)
    return first_step(rh, abs(tspan[1] - t0), hmax, t0), normy, t_out, y_out


@_njit(cache=True, error_model="numpy")
def _event_room(te, ye, ie, nev, nevents):
    """te, ye, ie grown (geometrically) to hold ``nevents`` more events after the first ``nev``; the
    loop calls it when they would not fit."""
    cap = 2 * te.shape[0] + nevents
    te2 = _np.empty(cap)
    ye2 = _np.empty((cap, ye.shape[1]))
    ie2 = _np.empty(cap, dtype=_np.int64)
    for q in range(nev):
        te2[q] = te[q]
        ie2[q] = ie[q]
        for j in range(ye.shape[1]):
            ye2[q, j] = ye[q, j]
    return te2, ye2, ie2


@_njit(cache=True, error_model="numpy", _nrt=False)
def _error(absh, ynew, absy, absynew, fE, threshold, normy, norm_control):
    """The step's error estimate err (engine.py's, MATLAB's) from fE = sum_k E_k K_k; writes |ynew|
    into absynew (or returns ||ynew||, NormControl's)."""
    n = ynew.shape[0]
    if norm_control:
        nn = 0.0
        ne = 0.0
        for j in range(n):
            nn += ynew[j] * ynew[j]
            ne += fE[j] * fE[j]
        normynew = _np.sqrt(nn)
        return absh * (_np.sqrt(ne) / max(normy, normynew, threshold[0])), normynew
    emax = 0.0
    nan = False
    for j in range(n):
        absynew[j] = abs(ynew[j])
        # np.maximum's rule: a NaN operand gives NaN (it reaches err below)
        sc = absy[j] if absy[j] >= absynew[j] else absynew[j]
        sc = sc if sc >= threshold[j] else threshold[j]
        q = abs(fE[j]) / sc
        if q != q or absy[j] != absy[j] or absynew[j] != absynew[j]:
            nan = True
        elif q > emax:
            emax = q
    if nan:
        emax = _np.nan
    return absh * emax, normy


@_njit(cache=True, error_model="numpy", _nrt=False)
def _refine_rows(t_out, y_out, count, t, h, y, K, weights, refine):
    """Refine's points inside a step from row ``count`` on: refine - 1 of them, ``t + h*(j/refine)``
    (its interpolant's weights ``weights[j-1]``, summed from the first stage up). The rows must
    exist; returns the next row."""
    for r in range(refine - 1):
        t_out[count] = t + h * ((r + 1) / refine)
        for j in range(y.shape[0]):
            acc = 0.0
            for k in range(K.shape[0]):
                acc += weights[r, k] * K[k, j]
            y_out[count, j] = h * acc + y[j]
        count += 1
    return count


@_njit(cache=True, error_model="numpy", _nrt=False)
def _tspan_rows(t_out, y_out, count, nxt, tspan, tdir, t, h, y, tnew, ynew, K, dense, weight, stop):
    """A vector tspan's entries tspan[nxt:] the step reached, from row ``count`` on (the
    interpolant's value, ynew on tnew itself), and after a terminal event (``stop``) its point
    too, as MATLAB outputs it. The rows must exist; returns the next row and the next entry."""
    while nxt < tspan.shape[0]:
        tn = tspan[nxt]
        if tdir * (tnew - tn) < 0:
            break
        t_out[count] = tn
        if tn == tnew:
            for j in range(y.shape[0]):
                y_out[count, j] = ynew[j]
        else:  # odelab.solvers.dense.step_value, as [events] interpolates (kernels_events.py)
            _interpolate_inline(tn, t, y, h, K, dense, weight, y_out[count])  # noqa: F821 (kernels_events.py's)
        count += 1
        nxt += 1
    if stop and nxt < tspan.shape[0]:
        t_out[count] = tnew
        for j in range(y.shape[0]):
            y_out[count, j] = ynew[j]
        count += 1
    return count, nxt


def _adaptive(_rhs, tspan, y0, f0, p, A, c, E, dense, weights, power, shrink_min, rtol, threshold, hmax, htry, refine,
              norm_control, max_steps, capacity, _ev, v0, isterminal, direction):
    """integrate_adaptive: MATLAB's controller on an FSAL pair; with [events] if ``_ev`` is a function
    (None: numba prunes each ``_ev is not None`` branch), _locate (odezero) after each accepted step,
    a terminal event cutting the step at te, its stages the interpolant's slopes (engine.py)."""
    s = c.shape[0]
    n = y0.shape[0]
    t0 = tspan[0]
    tfinal = tspan[tspan.shape[0] - 1]
    ntspan = tspan.shape[0]
    tdir = 1.0 if tfinal > t0 else -1.0
    last = s - 1
    K = _np.empty((s, n))
    y = _np.empty(n)
    absy = _np.empty(n)
    for j in range(n):
        K[0, j] = f0[j]
        y[j] = y0[j]
        absy[j] = abs(y0[j])
    hA = _np.empty((s, s))
    stage = _np.empty(n)
    ynew = _np.empty(n)
    absynew = _np.empty(n)
    fE = _np.empty(n)
    weight = _np.empty(s)
    absh, normy, t_out, y_out = _start(f0, y0, threshold, norm_control, rtol, power, tspan, hmax, htry, capacity)
    normynew = normy
    t = t0
    count = _np.int64(1)  # typed int64 from the start: each helper is compiled once, not also for a literal 1
    refine_output = ntspan == 2
    nxt = _np.int64(1)

    nevents = v0.shape[0]
    v_left = v0.copy()
    vnew = _np.empty(nevents)
    te = _np.empty(4 * nevents + 4)
    ye = _np.empty((te.shape[0], n))
    ie = _np.empty(te.shape[0], dtype=_np.int64)
    nev = nsteps = nfailed = nfevals = 0
    status = _Status.SUCCESS
    h = tdir * absh
    tnew = t
    err = 0.0
    while True:
        hmin, absh, done = clamp_step(t, tfinal, absh, hmax)
        h = tfinal - t if done else tdir * absh

        nofailed = True
        while True:
            for i in range(s):
                for k in range(s):
                    hA[i, k] = A[i, k] * h
            for i in range(1, last):
                for j in range(n):
                    acc = 0.0
                    for k in range(i - 1, -1, -1):  # odelab.solvers.ordered.stage's order
                        acc += hA[i, k] * K[k, j]
                    stage[j] = acc + y[j]
                _rhs(t + c[i] * h, stage, p, K[i])
            tnew = tfinal if done else t + h
            h = tnew - t
            for j in range(n):
                acc = 0.0
                for k in range(last - 1, -1, -1):
                    acc += hA[last, k] * K[k, j]
                ynew[j] = acc + y[j]
            _rhs(tnew, ynew, p, K[last])
            nfevals += last

            for j in range(n):
                acc = 0.0
                for k in range(s):
                    acc += E[k] * K[k, j]
                fE[j] = acc
            err, normynew = _error(absh, ynew, absy, absynew, fE, threshold, normy, norm_control)

            if err > rtol:
                nfailed += 1
                if absh <= hmin:
                    status = _Status.STEP_UNDERFLOW
                    break
                absh = shrink(absh, hmin, err, rtol, power, shrink_min, 0.8, nofailed)
                nofailed = False
                h = tdir * absh
                done = False
            elif err <= rtol:
                break
            else:
                status = _Status.NONFINITE
                break
        if status != _Status.SUCCESS:
            break
        nsteps += 1

        stop = _np.bool_(False)
        if _ev is not None:  # pruned from the loop compiled without events
            if nev + nevents > te.shape[0]:
                te, ye, ie = _event_room(te, ye, ie, nev, nevents)
            before = nev
            nev, stop = _locate(_ev, p, isterminal, direction, v_left, t, y, tnew, ynew, h, K, dense, t0, vnew, te, ye, ie,
                                nev, weight)
            for j in range(nevents):
                v_left[j] = vnew[j]
            if nev > before and stop:  # cut the step at the terminal event
                tnew = te[nev - 1]
                _cut_slopes(t, tnew, h, K, dense, c)
                for j in range(n):
                    ynew[j] = ye[nev - 1, j]
                h = tnew - t
                done = True
                status = _Status.TERMINAL_EVENT

        if refine_output:
            if count + refine > t_out.shape[0]:
                t_out, y_out = _grow(t_out[:count], y_out[:count], count + refine)
            if refine > 1:
                count = _refine_rows(t_out, y_out, count, t, h, y, K, weights, refine)
            t_out[count] = tnew
            for j in range(n):
                y_out[count, j] = ynew[j]
            count += 1
        else:
            if stop and count + ntspan - nxt + 1 > t_out.shape[0]:  # room for the terminal event's row
                t_out, y_out = _grow(t_out[:count], y_out[:count], count + ntspan - nxt + 1)
            if stop or (nxt < ntspan and tdir * (tnew - tspan[nxt]) >= 0):  # the step reached an entry
                count, nxt = _tspan_rows(t_out, y_out, count, nxt, tspan, tdir, t, h, y, tnew, ynew, K, dense, weight, stop)

        if done:
            break
        if max_steps > 0 and nsteps >= max_steps:
            status = _Status.MAX_STEPS
            t = tnew
            break

        if nofailed:
            absh = grow(absh, err, rtol, power, 1.25, 5.0)

        t = tnew
        for j in range(n):
            y[j] = ynew[j]
        if norm_control:
            normy = normynew
        else:
            for j in range(n):
                absy[j] = absynew[j]
        for j in range(n):
            K[0, j] = K[last, j]

    return t_out, y_out, count, nsteps, nfailed, nfevals, status, t, abs(h), te[:nev].copy(), ye[:nev].copy(), ie[:nev].copy()


def _fixed(_rhs, grid, y0, p, A, b, c):
    s = c.shape[0]
    n = y0.shape[0]
    K = _np.empty((s, n))
    hA = _np.empty((s, s))
    hb = _np.empty(s)
    stage = _np.empty(n)
    ys = _np.empty((grid.shape[0], n))
    y = _np.empty(n)
    for j in range(n):
        ys[0, j] = y0[j]
        y[j] = y0[j]
    nsteps = 0
    nfevals = 0
    status = _Status.SUCCESS
    t = grid[0]
    for step in range(grid.shape[0] - 1):
        t = grid[step]
        h = grid[step + 1] - t
        for i in range(s):
            hb[i] = h * b[i]
            for k in range(s):
                hA[i, k] = h * A[i, k]
        _rhs(t, y, p, K[0])
        for i in range(1, s):
            for j in range(n):
                acc = 0.0
                for k in range(i - 1, -1, -1):  # odelab.solvers.ordered.stage's order
                    acc += hA[i, k] * K[k, j]
                stage[j] = acc + y[j]
            _rhs(t + c[i] * h, stage, p, K[i])
        nfevals += s
        total = 0.0
        for j in range(n):
            acc = 0.0
            for k in range(s - 1, -1, -1):
                acc += hb[k] * K[k, j]
            stage[j] = acc + y[j]
            total += stage[j]
        if not _np.isfinite(total):
            status = _Status.NONFINITE
            break
        for j in range(n):
            y[j] = stage[j]
            ys[step + 1, j] = y[j]
        nsteps += 1
        t = grid[step + 1]
    return ys, nsteps, nfevals, status, t


# Each loop is compiled (or loaded from numba's cache) when first asked for: a fixed-step run
# never pays for the adaptive loop's compile, nor the other way round.
_ADAPTIVE = (_RHS_ARG, _V, _V, _V, _V, _M, _V, _V, _M, _M, _F8, _F8, _F8, _V, _F8, _F8, _I8, _types.boolean, _I8, _I8)
_SIGNATURES = {
    "adaptive": (*_ADAPTIVE, _types.none, _V, _V, _V),  # _adaptive without events (_ev None)
    "fixed": (_RHS_ARG, _V, _V, _V, _M, _V, _V),
    "events": (*_ADAPTIVE, _RHS_ARG, _V, _V, _V),  # the same loop with an events function
}
_LOOPS = {"adaptive": "_adaptive", "fixed": "_fixed", "events": "_adaptive_events"}
_COMPILED = {}


def _named(function, name):
    """``function`` under another name: numba caches a function's machine code by its name, so
    the loop with events and the one without are kept (and found by is_built) apart."""
    import types

    copy = types.FunctionType(function.__code__.replace(co_name=name), function.__globals__, name,
                              function.__defaults__, function.__closure__)
    copy.__qualname__ = name
    return copy


_adaptive_events = _named(_adaptive, "_adaptive_events")


def loop(name):
    """The compiled loop ``"adaptive"``, ``"fixed"``, ``"events"`` (adaptive with [events]), or a
    stiff solver's, ``"ode23s"`` or ``"ode15s"`` (kernels_stiff.py)."""
    if name not in _COMPILED:
        if name in ("ode23s", "ode15s"):
            _bind_lapack()  # noqa: F821 (kernels_stiff.py's, in the same module)
        _COMPILED[name] = _njit(_SIGNATURES[name], cache=True, error_model="numpy")(globals()[_LOOPS[name]])
    return _COMPILED[name]
