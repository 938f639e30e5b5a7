"""[events] in the compiled loop: MATLAB's ``odezero`` on each step's interpolant (numba).

This file is appended to ``kernels.py`` in one generated module (see
:func:`odelab.solvers.compiled.cache.load_kernels`). :func:`_locate` is
:func:`odelab.solvers.events.locate_events` statement for statement, each point's decision taken
from :mod:`odelab.solvers.odezero` as locate_events takes it (regula falsi with the
Illinois modification on the step's interpolant, the tolerance ``128 eps``, events at the left
end, later events of the same step, terminal events), with arrays instead of lists; the
adaptive loop (``kernels._adaptive``, compiled with an events function as
``_adaptive_events``) calls it after each accepted step, and a terminal event cuts the step at
``te``, its stages replaced by the interpolant's slopes (:func:`_cut_slopes`, as MATLAB and
the Python engine do), so Refine's points on the shortened step follow the same curve.
"""

import numpy as _np
from numba import njit as _njit

# The rule of each point of the bracket: this module follows odelab/solvers/odezero.py's text (see
# cache._KERNELS), whose pure functions locate_events calls too; inlined (numba's IR), as controller.py's.
for _rule in ("_sign", "crosses", "event_tolerance", "root_fraction", "next_try", "just_off", "halved", "stops"):
    globals()[_rule] = _njit(inline="always", error_model="numpy")(globals()[_rule])


@_njit(cache=True, error_model="numpy")
def _bracketed(V, a, b, direction, found):
    """How many events change sign from row a to row b of V in a direction they accept; their
    indices in found."""
    m = 0
    for j in range(V.shape[1]):
        if crosses(V[a, j], V[b, j], direction[j]):
            found[m] = j
            m += 1
    return m


@_njit(cache=True, error_model="numpy", _nrt=False)
def _interpolate(tq, t, y, h, K, dense, weight, out):
    """odelab.solvers.dense.step_value: stage weights sum_m cumprod((tq - t)/h)_m (h dense[k, m])
    (into ``weight``, one a stage), then y + sum_k weight_k K_k, both summed from index 0 up."""
    x = (tq - t) / h
    for k in range(K.shape[0]):
        acc = 0.0
        pw = 1.0
        for m in range(dense.shape[1]):
            pw *= x
            acc += pw * (h * dense[k, m])
        weight[k] = acc
    for j in range(y.shape[0]):
        acc = 0.0
        for k in range(K.shape[0]):
            acc += weight[k] * K[k, j]
        out[j] = y[j] + acc


# The same text inlined into the vector tspan's output (kernels._tspan_rows), called at every point.
_interpolate_inline = _njit(inline="always", error_model="numpy", _nrt=False)(_interpolate.py_func)


@_njit(cache=True, error_model="numpy")
def _locate(_ev, p, isterminal, direction, v, t, y, tnew, ynew, h, K, dense, t0, vnew, te, ye, ie, nev, weight):
    """One step's events (locate_events, statement for statement); writes vnew (the values at tnew),
    appends to te/ye/ie from index nev. Returns (nev, stop); te, ye, ie must have room for every
    event of the step; ``weight`` (one a stage) is _interpolate's work array. The bracket's ends
    and the point tried are rows L, R, T of Y and V: where the Python code swaps arrays, this
    swaps row numbers."""
    k = v.shape[0]
    n = y.shape[0]
    tol = event_tolerance(t, tnew)
    tdir = 1.0 if tnew > t else -1.0
    stop = False
    _ev(tnew, ynew, p, vnew)
    found = _np.empty(k, dtype=_np.int64)
    Y = _np.empty((3, n))
    V = _np.empty((3, k))
    L, R, T = 0, 1, 2
    for i in range(n):
        Y[L, i] = y[i]
        Y[R, i] = ynew[i]
        Y[T, i] = ynew[i]
    for j in range(k):
        V[L, j] = v[j]
        V[R, j] = vnew[j]
        V[T, j] = vnew[j]
    tL = t
    if t == t0:
        any_zero = False
        for j in range(k):
            if v[j] == 0:
                any_zero = True
        if any_zero:  # MATLAB ignores a zero at the initial point: search from just off it
            tL = just_off(t, tol, tdir)
            _interpolate(tL, t, y, h, K, dense, weight, Y[L])
            _ev(tL, Y[L], p, V[L])
    search_start = tL
    tR = tnew
    ttry = tR
    while True:
        lastmoved = 0
        nfound = 0
        while True:
            nfound = _bracketed(V, L, R, direction, found)
            if nfound == 0:
                return nev, stop
            delta = tR - tL
            if abs(delta) <= tol:
                break
            at_zero = False
            if tL == t:
                for q in range(nfound):
                    j = found[q]
                    if V[L, j] == 0 and V[R, j] != 0:
                        at_zero = True
            if at_zero:  # a zero at the step's left end: step just off it
                ttry = just_off(tL, tol, tdir)
            else:
                change = 1.0
                for q in range(nfound):
                    j = found[q]
                    change = min(change, root_fraction(V[L, j], V[R, j], V[T, j], tL, tR, ttry, delta, tdir))
                ttry = next_try(change, tL, delta, tol, tdir)
            _interpolate(ttry, t, y, h, K, dense, weight, Y[T])
            _ev(ttry, Y[T], p, V[T])
            if _bracketed(V, L, T, direction, found) > 0:  # a crossing in [tL, ttry]: R moves left
                tR, ttry = ttry, tR
                R, T = T, R
                if lastmoved == 2:  # Illinois: the left end stayed twice, halve its value
                    for j in range(k):
                        V[L, j] = halved(V[L, j])
                lastmoved = 2
            else:
                tL, ttry = ttry, tL
                L, T = T, L
                if lastmoved == 1:
                    for j in range(k):
                        V[R, j] = halved(V[R, j])
                lastmoved = 1
        terminal = False
        for q in range(nfound):
            j = found[q]
            te[nev] = tR
            for i in range(n):
                ye[nev, i] = Y[R, i]
            ie[nev] = j
            nev += 1
            if isterminal[j] != 0.0:
                terminal = True
        if terminal:
            if stops(t, t0, tL, search_start):
                stop = True
            break
        if abs(tnew - tR) <= tol:
            break
        # later events of the same step, in [tR + tol/2, tnew]: the old R becomes the point tried
        ttry = tR
        L, R, T = T, L, R
        tL = just_off(tR, tol, tdir)
        _interpolate(tL, t, y, h, K, dense, weight, Y[L])
        _ev(tL, Y[L], p, V[L])
        tR = tnew
        for i in range(n):
            Y[R, i] = ynew[i]
        for j in range(k):
            V[R, j] = vnew[j]
    return nev, stop


@_njit(cache=True, error_model="numpy")
def _cut_slopes(t, te, h, K, dense, c):
    """odelab.solvers.dense.step_slopes at the nodes of [t, te]: the stages of the shortened step
    (stage weights sum_m (m+1) x^m dense[k, m], x^m a running product, then sum_k weight_k K_k,
    from index 0 up)."""
    s = K.shape[0]
    n = K.shape[1]
    q = dense.shape[1]
    weight = _np.empty(s)
    slopes = _np.empty((s - 1, n))
    for i in range(1, s):
        x = ((t + (te - t) * c[i]) - t) / h
        for k in range(s):
            acc = 0.0
            pw = 1.0
            for m in range(q):
                acc += ((m + 1) * pw) * dense[k, m]
                pw *= x
            weight[k] = acc
        for j in range(n):
            acc = 0.0
            for k in range(s):
                acc += weight[k] * K[k, j]
            slopes[i - 1, j] = acc
    for i in range(1, s):
        for j in range(n):
            K[i, j] = slopes[i - 1, j]
