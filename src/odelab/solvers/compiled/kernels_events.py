"""The compiled loop with [events]: MATLAB's ``odezero`` on each step's interpolant (numba).

This file is appended to ``kernels.py`` in one generated module (see
:func:`odelab.solvers.compiled.cache.load_kernels`) and uses its names (``_grow``, ``_Status``).
:func:`_locate` is :func:`odelab.solvers.events.locate_events` statement for statement
(regula falsi with the Illinois modification on the step's interpolant, the tolerance
``128 eps``, events at the left end, later events of the same step, terminal events), with
arrays instead of lists; :func:`_adaptive_events` is the adaptive loop with the engine's event
block: after each accepted step the events are located, and a terminal one cuts the step at
``te``, its stages replaced by the interpolant's slopes (as MATLAB and the Python engine do),
so Refine's points on the shortened step follow the same curve. It is compiled only when a run
has events.
"""

import numpy as _np
from numba import njit as _njit



_TINY = 2.2250738585072014e-308  # realmin: Illinois halving keeps values above it


@_njit(cache=True, error_model="numpy")
def _sgn(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else (0.0 if x == 0.0 else x))


@_njit(cache=True, error_model="numpy")
def _bracketed(V, a, b, direction, found):
    """How many events change sign from row a to row b of V in a direction they accept; their
    indices in found."""
    m = 0
    for j in range(V.shape[1]):
        if _sgn(V[a, j]) != _sgn(V[b, j]) and direction[j] * (V[b, j] - V[a, j]) >= 0:
            found[m] = j
            m += 1
    return m


@_njit(cache=True, error_model="numpy")
def _interpolate(tq, t, y, h, K, dense, out):
    """odelab.solvers.dense.step_value: stage weights sum_m cumprod((tq - t)/h)_m (h dense[k, m]),
    then y + sum_k weight_k K_k, both summed from index 0 up."""
    s = K.shape[0]
    ndense = dense.shape[1]
    x = (tq - t) / h
    weight = _np.empty(s)
    for k in range(s):
        acc = 0.0
        pw = 1.0
        for m in range(ndense):
            pw *= x
            acc += pw * (h * dense[k, m])
        weight[k] = acc
    for j in range(y.shape[0]):
        acc = 0.0
        for k in range(s):
            acc += weight[k] * K[k, j]
        out[j] = y[j] + acc


@_njit(cache=True, error_model="numpy")
def _locate(_ev, p, isterminal, direction, v, t, y, tnew, ynew, h, K, dense, t0, vnew, te, ye, ie, nev):
    """One step's events (locate_events, statement for statement); writes vnew (the values at tnew),
    appends to te/ye/ie from index nev. Returns (nev, stop); te, ye, ie must have room for every
    event of the step. The bracket's ends and the point tried are rows L, R, T of Y and V: where
    the Python code swaps arrays, this swaps row numbers."""
    k = v.shape[0]
    n = y.shape[0]
    tol = min(128.0 * max(_np.spacing(abs(t)), _np.spacing(abs(tnew))), abs(tnew - t))
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
            tL = t + tdir * 0.5 * tol
            _interpolate(tL, t, y, h, K, dense, Y[L])
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
                ttry = tL + tdir * 0.5 * tol
            else:
                change = 1.0
                for q in range(nfound):
                    j = found[q]
                    if V[L, j] == 0:
                        maybe = 0.5
                        if tdir * ttry > tdir * tR and V[T, j] != V[R, j]:
                            maybe = 1.0 - V[R, j] * (ttry - tR) / ((V[T, j] - V[R, j]) * delta)
                            if maybe < 0 or maybe > 1:
                                maybe = 0.5
                    elif V[R, j] == 0:
                        maybe = 0.5
                        if tdir * ttry < tdir * tL and V[T, j] != V[L, j]:
                            maybe = V[L, j] * (tL - ttry) / ((V[T, j] - V[L, j]) * delta)
                            if maybe < 0 or maybe > 1:
                                maybe = 0.5
                    else:
                        maybe = -V[L, j] / (V[R, j] - V[L, j])
                    change = min(change, maybe)
                change = max(0.5 * tol, min(change * abs(delta), abs(delta) - 0.5 * tol))
                ttry = tL + tdir * change
            _interpolate(ttry, t, y, h, K, dense, Y[T])
            _ev(ttry, Y[T], p, V[T])
            if _bracketed(V, L, T, direction, found) > 0:  # a crossing in [tL, ttry]: R moves left
                tR, ttry = ttry, tR
                R, T = T, R
                if lastmoved == 2:  # Illinois: the left end stayed twice, halve its value
                    for j in range(k):
                        half = 0.5 * V[L, j]
                        if abs(half) >= _TINY:
                            V[L, j] = half
                lastmoved = 2
            else:
                tL, ttry = ttry, tL
                L, T = T, L
                if lastmoved == 1:
                    for j in range(k):
                        half = 0.5 * V[R, j]
                        if abs(half) >= _TINY:
                            V[R, j] = half
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
            if t != t0 or tL != search_start:
                stop = True
            break
        if abs(tnew - tR) <= tol:
            break
        # later events of the same step, in [tR + tol/2, tnew]: the old R becomes the point tried
        ttry = tR
        L, R, T = T, L, R
        tL = tR + tdir * 0.5 * tol
        _interpolate(tL, t, y, h, K, dense, Y[L])
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


def _adaptive_events(_rhs, tspan, y0, f0, p, A, c, E, dense, weights, power, shrink_min, rtol, threshold, hmax, htry,
                     refine, norm_control, max_steps, capacity, _ev, v0, isterminal, direction):
    """_adaptive with [events]: after each accepted step, _locate (MATLAB's odezero); a terminal
    event cuts the step at te, its stages replaced by the interpolant's slopes (engine.py)."""
    s = c.shape[0]
    n = y0.shape[0]
    t0 = tspan[0]
    tfinal = tspan[tspan.shape[0] - 1]
    ntspan = tspan.shape[0]
    tdir = 1.0 if tfinal > t0 else -1.0
    last = s - 1
    ndense = dense.shape[1]
    K = _np.empty((s, n))
    hA = _np.empty((s, s))
    stage = _np.empty(n)
    y = _np.empty(n)
    absy = _np.empty(n)
    for j in range(n):
        K[0, j] = f0[j]
        y[j] = y0[j]
        absy[j] = abs(y0[j])
    ynew = _np.empty(n)
    absynew = _np.empty(n)
    fE = _np.empty(n)
    weight = _np.empty(s)
    powers = _np.empty(ndense)
    thr = threshold[0]

    t = t0
    normy = 0.0
    if norm_control:
        for j in range(n):
            normy += y0[j] * y0[j]
        normy = _np.sqrt(normy)
    normynew = normy

    if htry != htry:
        if norm_control:
            nf = 0.0
            for j in range(n):
                nf += f0[j] * f0[j]
            rh = (_np.sqrt(nf) / max(normy, thr)) / (0.8 * rtol ** power)
        else:
            rh = 0.0
            for j in range(n):
                q = abs(f0[j]) / max(absy[j], threshold[j])
                if q > rh or q != q:
                    rh = q
            rh = rh / (0.8 * rtol ** power)
        absh = first_step(rh, abs(tspan[1] - t0), hmax, t0)
    else:
        absh = given_step(htry, t0, hmax)

    t_out = _np.empty(capacity)
    y_out = _np.empty((capacity, n))
    t_out[0] = t0
    for j in range(n):
        y_out[0, j] = y0[j]
    count = 1
    refine_output = ntspan == 2
    nxt = 1

    nevents = v0.shape[0]
    v_left = v0.copy()
    vnew = _np.empty(nevents)
    te = _np.empty(4 * nevents + 4)
    ye = _np.empty((te.shape[0], n))
    ie = _np.empty(te.shape[0], dtype=_np.int64)
    nev = 0
    nsteps = 0
    nfailed = 0
    nfevals = 0
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
            tnew = t + h
            if done:
                tnew = tfinal
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
            if norm_control:
                nn = 0.0
                ne = 0.0
                for j in range(n):
                    nn += ynew[j] * ynew[j]
                    ne += fE[j] * fE[j]
                normynew = _np.sqrt(nn)
                err = absh * (_np.sqrt(ne) / max(normy, normynew, thr))
            else:
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
                err = absh * emax

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

        stop = False
        if nev + nevents > te.shape[0]:
            cap = 2 * te.shape[0] + nevents
            te2 = _np.empty(cap)
            ye2 = _np.empty((cap, n))
            ie2 = _np.empty(cap, dtype=_np.int64)
            for q in range(nev):
                te2[q] = te[q]
                ie2[q] = ie[q]
                for j in range(n):
                    ye2[q, j] = ye[q, j]
            te, ye, ie = te2, ye2, ie2
        before = nev
        nev, stop = _locate(_ev, p, isterminal, direction, v_left, t, y, tnew, ynew, h, K, dense, t0, vnew, te, ye, ie,
                            nev)
        for j in range(nevents):
            v_left[j] = vnew[j]
        if nev > before and stop:
            t_event = te[nev - 1]
            _cut_slopes(t, t_event, h, K, dense, c)
            tnew = t_event
            for j in range(n):
                ynew[j] = ye[nev - 1, j]
            h = tnew - t
            done = True
            status = _Status.TERMINAL_EVENT

        if refine_output:
            needed = count + refine
            if needed > t_out.shape[0]:
                t_out, y_out = _grow(t_out[:count], y_out[:count], needed)
            if refine > 1:
                for r in range(refine - 1):
                    t_out[count] = t + h * ((r + 1) / refine)
                    for j in range(n):
                        acc = 0.0
                        for k in range(s):
                            acc += weights[r, k] * K[k, j]
                        y_out[count, j] = h * acc + y[j]
                    count += 1
            t_out[count] = tnew
            for j in range(n):
                y_out[count, j] = ynew[j]
            count += 1
        else:
            while nxt < ntspan:
                tn = tspan[nxt]
                if tdir * (tnew - tn) < 0:
                    if stop:  # MATLAB outputs the terminal event's point too
                        if count + 1 > t_out.shape[0]:
                            t_out, y_out = _grow(t_out[:count], y_out[:count], count + 1)
                        t_out[count] = tnew
                        for j in range(n):
                            y_out[count, j] = ynew[j]
                        count += 1
                    break
                t_out[count] = tn
                if tn == tnew:
                    for j in range(n):
                        y_out[count, j] = ynew[j]
                else:
                    x = (tn - t) / h
                    pw = 1.0
                    for m in range(ndense):
                        pw *= x
                        powers[m] = pw
                    # odelab.solvers.dense.step_value: stage weights, then the stages
                    for k in range(s):
                        acc = 0.0
                        for m in range(ndense):
                            acc += powers[m] * (h * dense[k, m])
                        weight[k] = acc
                    for j in range(n):
                        acc = 0.0
                        for k in range(s):
                            acc += weight[k] * K[k, j]
                        y_out[count, j] = y[j] + acc
                count += 1
                nxt += 1

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
