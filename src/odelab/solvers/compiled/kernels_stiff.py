"""The stiff solvers' loops in numba: ode23s and ode15s for expression systems.

This file is appended to ``kernels.py`` in one generated module (see
:func:`odelab.solvers.compiled.cache.load_kernels`). :func:`_ode23s` and :func:`_ode15s` are
:func:`odelab.solvers.implicit.ode23s.integrate_ode23s` and
:func:`odelab.solvers.implicit.ode15s.integrate_ode15s` statement for statement (the same step
rules from :mod:`odelab.solvers.controller`, the same Newton iteration, order selection and
counters), without mass matrices or events. The Jacobian is the system's generated ``jac``
(complex step, :func:`odelab.solvers.compiled.codegen.jacobian_source`: the Python path's
exact Jacobian to the bit). Up to ``_SMALL_LU`` states (:data:`odelab.solvers.lu.SMALL`, written
into the module's text by the cache) the LU factorisations and solves are
:mod:`odelab.solvers.lu`'s, loop for loop (:func:`_ordered_lu`, :func:`_ordered_solve`); above,
they call the LAPACK routines that
SciPy's ``lu_factor`` and ``lu_solve`` call (``dgetrf``/``dgetrs`` of ``scipy.linalg.cython_lapack``,
bound by name with :func:`_bind_lapack`, so numba's cache keeps the machine code), on the
matrix in the same (column-major) layout: the same factors and solutions bit for bit. Where
:func:`odelab.solvers.banded.plan_band` finds the Jacobian's structure banded after a
permutation, both paths factor the permuted band with ``dgbtrf``/``dgbtrs`` instead
(:class:`odelab.solvers.banded.Band`, :func:`_factor`): the loops take that plan as ``perm``
(empty: dense), ``kl`` and ``ku``.
The products (``J @ y'`` of ode15s's first step, its difference rescaling ``RU.T @ D`` and
predictor sums ``GAMMA @ D``, its interpolant) are loops in :mod:`odelab.solvers.ordered`'s
order, as the Python path sums them (no BLAS in either: the same bits under every BLAS
kernel); everything else is elementwise and written in numpy's order of operations.
"""

import numpy as _np
from numba import njit as _njit
from numba import types as _types

#: The signature of every generated Jacobian: jac(t, y, p, J) writes df/dy into J (row i: f_i).
JAC = _types.void(_F8, _V, _V, _M)  # noqa: F821 (kernels.py's, in the same module)
_JAC_ARG = _types.FunctionType(JAC)
_P = _types.voidptr
_dgetrf = _types.ExternalFunction("odelab_dgetrf", _types.void(_P, _P, _P, _P, _P, _P))
_dgetrs = _types.ExternalFunction("odelab_dgetrs", _types.void(_P, _P, _P, _P, _P, _P, _P, _P, _P))
_dgbtrf = _types.ExternalFunction("odelab_dgbtrf", _types.void(_P, _P, _P, _P, _P, _P, _P, _P))
_dgbtrs = _types.ExternalFunction("odelab_dgbtrs", _types.void(_P, _P, _P, _P, _P, _P, _P, _P, _P, _P, _P))
_SQRT_EPS = 1.4901161193847656e-08  # sqrt(eps), odelab.solvers.implicit.common.SQRT_EPS
_EPS = 2.220446049250313e-16
_SFMIN = 2.2250738585072014e-308  # the smallest normal number, odelab.solvers.lu._SFMIN
_D23 = 1.0 / (2.0 + _np.sqrt(2.0))  # ode23s.D
_E32 = 6.0 + _np.sqrt(2.0)  # ode23s.E32


def _bind_lapack():
    """Make SciPy's LAPACK ``dgetrf``/``dgetrs`` (``dgbtrf``/``dgbtrs``: banded) known to numba's
    linker by name (once per process): the routines ``lu_factor``/``lu_solve`` (and the Python
    path's ``getrf``/``getrs``) call, so the compiled loops get their results bit for bit."""
    import llvmlite.binding as ll
    from numba.extending import get_cython_function_address

    for name in ("dgetrf", "dgetrs", "dgbtrf", "dgbtrs"):
        ll.add_symbol("odelab_" + name, get_cython_function_address("scipy.linalg.cython_lapack", name))


@_njit(cache=True, error_model="numpy")
def _vecmat(g, B, out):
    """out = g @ B for g (k,) and B (k, n): odelab.solvers.ordered's order (i = 0, 1, ... from 0)."""
    for j in range(B.shape[1]):
        acc = 0.0
        for i in range(B.shape[0]):
            acc += g[i] * B[i, j]
        out[j] = acc


@_njit(cache=True, error_model="numpy")
def _matvec(A, x, out):
    """out = A @ x for A (m, n): ordered.matvec's order (j = 0, 1, ... from 0)."""
    for i in range(A.shape[0]):
        acc = 0.0
        for j in range(A.shape[1]):
            acc += A[i, j] * x[j]
        out[i] = acc


@_njit(cache=True, error_model="numpy")
def _matmul(A, B, C, transpose_a=False):
    """C = A @ B (or A.T @ B) for A (q, k) and B (k, n) (A (k, q) transposed): ordered.matmul's
    order (m = 0, 1, ... from 0)."""
    q, n = C.shape[0], C.shape[1]
    k = B.shape[0]
    for i in range(q):
        for j in range(n):
            acc = 0.0
            for m in range(k):
                acc += (A[m, i] if transpose_a else A[i, m]) * B[m, j]
            C[i, j] = acc


@_njit(cache=True, error_model="numpy")
def _ordered_lu(A, piv):
    """odelab.solvers.lu.factor in place on A (row-major), the pivots into piv: the same
    operations in the same order."""
    n = A.shape[0]
    for j in range(n):
        p = j
        biggest = abs(A[j, j])
        for i in range(j + 1, n):
            m = abs(A[i, j])
            if m > biggest:
                p, biggest = i, m
        piv[j] = p
        if p != j:
            for k in range(n):
                A[j, k], A[p, k] = A[p, k], A[j, k]
        d = A[j, j]
        if d == 0:
            continue
        small = abs(d) < _SFMIN
        reciprocal = 1.0 / d
        for i in range(j + 1, n):
            li = A[i, j] / d if small else A[i, j] * reciprocal
            A[i, j] = li
            if li != 0:
                for k in range(j + 1, n):
                    A[i, k] -= li * A[j, k]


@_njit(cache=True, error_model="numpy")
def _ordered_solve(A, piv, x):
    """odelab.solvers.lu.solve in place on x."""
    n = x.shape[0]
    for j in range(n):
        p = piv[j]
        if p != j:
            x[j], x[p] = x[p], x[j]
    for j in range(n - 1):
        xj = x[j]
        if xj != 0:
            for i in range(j + 1, n):
                x[i] -= xj * A[i, j]
    for j in range(n - 1, -1, -1):
        x[j] /= A[j, j]
        xj = x[j]
        if xj != 0:
            for i in range(j):
                x[i] -= xj * A[i, j]


@_njit(cache=True, error_model="numpy")
def _new_lu(n, perm, kl, ku):
    """The LU workspace: (Wf, ipiv, ints, perm, tmp). Dense (perm empty): Wf (n, n) column-major
    for dgetrf; banded (odelab.solvers.banded.Band: position k holds state perm[k]): Wf the
    (ldab, n) band storage, ldab = 2 kl + ku + 1. ints = [n, info, nrhs, kl, ku, ldab]."""
    ldab = 2 * kl + ku + 1
    Wf = _np.empty((n, n)) if perm.shape[0] == 0 else _np.empty((n, ldab))
    ints = _np.array([n, 0, 1, kl, ku, ldab], dtype=_np.int32)
    return Wf, _np.empty(n, dtype=_np.int32), ints, perm, _np.empty(n)


@_njit(cache=True, error_model="numpy")
def _factor(J, c, lu):
    """LU of I - c J: lu_factor's dgetrf on the column-major matrix (Wf[j, i] holds (i, j)), or
    Band.factor's dgbtrf on the permuted matrix's band (Wf[j', kl + ku + i' - j'] holds the
    entry (perm[i'], perm[j'])): the same numbers as the Python path's ``M - c J``."""
    Wf, ipiv, ints, perm = lu[0], lu[1], lu[2], lu[3]
    n = J.shape[0]
    if perm.shape[0] == 0 and n <= _SMALL_LU:  # odelab.solvers.lu: row-major, the same bits everywhere
        for i in range(n):
            for j in range(n):
                Wf[i, j] = (1.0 if i == j else 0.0) - c * J[i, j]
        _ordered_lu(Wf, ipiv)
        return
    if perm.shape[0] == 0:
        for i in range(n):
            for j in range(n):
                Wf[j, i] = (1.0 if i == j else 0.0) - c * J[i, j]
        _dgetrf(ints[0:1].ctypes, ints[0:1].ctypes, Wf.ctypes, ints[0:1].ctypes, ipiv.ctypes, ints[1:2].ctypes)
        return
    kl, ku = ints[3], ints[4]
    for jp in range(n):
        j = perm[jp]
        for ip in range(max(0, jp - ku), min(n, jp + kl + 1)):
            i = perm[ip]
            Wf[jp, kl + ku + ip - jp] = (1.0 if i == j else 0.0) - c * J[i, j]
    _dgbtrf(ints[0:1].ctypes, ints[0:1].ctypes, ints[3:4].ctypes, ints[4:5].ctypes, Wf.ctypes, ints[5:6].ctypes,
            ipiv.ctypes, ints[1:2].ctypes)


@_njit(cache=True, error_model="numpy")
def _lsolve(lu, trans, b):
    """b <- (I - c J) \\ b with the factors of _factor (lu_solve's dgetrs, or Band.solve's dgbtrs
    on b permuted)."""
    Wf, ipiv, ints, perm, tmp = lu
    if perm.shape[0] == 0 and b.shape[0] <= _SMALL_LU:
        _ordered_solve(Wf, ipiv, b)
        return
    if perm.shape[0] == 0:
        _dgetrs(trans.ctypes, ints[0:1].ctypes, ints[2:3].ctypes, Wf.ctypes, ints[0:1].ctypes, ipiv.ctypes, b.ctypes,
                ints[0:1].ctypes, ints[1:2].ctypes)
        return
    n = b.shape[0]
    for k in range(n):
        tmp[k] = b[perm[k]]
    _dgbtrs(trans.ctypes, ints[0:1].ctypes, ints[3:4].ctypes, ints[4:5].ctypes, ints[2:3].ctypes, Wf.ctypes,
            ints[5:6].ctypes, ipiv.ctypes, tmp.ctypes, ints[0:1].ctypes, ints[1:2].ctypes)
    for k in range(n):
        b[perm[k]] = tmp[k]


@_njit(cache=True, error_model="numpy")
def _wmax(v, w):
    """np.max(np.abs(v) / w), NaN if any quotient is NaN."""
    m = 0.0
    for j in range(v.shape[0]):
        q = abs(v[j]) / w[j]
        if q != q:
            return _np.nan
        if q > m:
            m = q
    return m


@_njit(cache=True, error_model="numpy")
def _npmax(a, b):
    """np.maximum: NaN if either is NaN."""
    if a != a or b != b:
        return a + b
    return a if a >= b else b


@_njit(cache=True, error_model="numpy")
def _interp(kind, times, q, t, h, y, A1, A2, D, k, out):
    """The step's interpolant at times[:q] into the rows of out: ode23s's (kind 0; y, k1 = A1,
    k2 = A2), or ode15s's backward differences (kind 1; D[0..k] at the step's end t), whose
    ``cumprod(x) @ D[1:]`` is ordered.combine's sum (_matmul)."""
    n = out.shape[1]
    if kind == 0:
        for r in range(q):
            s = (times[r] - t) / h
            a = s * (1.0 - s) / (1.0 - 2.0 * _D23)
            b = s * (s - 2.0 * _D23) / (1.0 - 2.0 * _D23)
            for j in range(n):
                out[r, j] = y[j] + h * (a * A1[j] + b * A2[j])
        return
    X = _np.empty((q, k))
    for r in range(q):
        prod = 1.0
        for m in range(k):
            prod *= (times[r] - (t - h * m)) / (h * (m + 1))
            X[r, m] = prod
    _matmul(X, D[1:k + 1], out[:q])
    for r in range(q):
        for j in range(n):
            out[r, j] = D[0, j] + out[r, j]


@_njit(cache=True, error_model="numpy")
def _record(t_out, y_out, count, nxt, tspan, refine, t, tnew, ynew, kind, tk, h, y, A1, A2, D, k):
    """output.StepOutput's rows with the stiff solvers' rules (output.STIFF_RULES), without
    events: Refine points and the step's end for a two-element tspan, else the tspan times the
    step passed (those inside it interpolated in one call, as implicit.driver's values does).
    Returns (t_out, y_out, count, nxt)."""
    ntspan = tspan.shape[0]
    n = ynew.shape[0]
    if ntspan == 2:
        if count + refine > t_out.shape[0]:
            t_out, y_out = _grow(t_out[:count], y_out[:count], count + refine)  # noqa: F821
        if refine > 1:
            times = _np.empty(refine - 1)
            for r in range(1, refine):
                times[r - 1] = t + (tnew - t) * r / refine  # STIFF_RULES' order
            _interp(kind, times, refine - 1, tk, h, y, A1, A2, D, k, y_out[count:count + refine - 1])
            t_out[count:count + refine - 1] = times
            count += refine - 1
        t_out[count] = tnew
        y_out[count, :] = ynew
        return t_out, y_out, count + 1, nxt
    tdir = 1.0 if tspan[ntspan - 1] > tspan[0] else -1.0
    start = nxt
    while nxt < ntspan and tdir * (tnew - tspan[nxt]) >= 0:
        nxt += 1
    q = 0
    inside = _np.empty(nxt - start)
    for i in range(start, nxt):
        if tspan[i] != tnew:
            inside[q] = tspan[i]
            q += 1
    values = _np.empty((q, n))
    if q:
        _interp(kind, inside, q, tk, h, y, A1, A2, D, k, values)
    r = 0
    for i in range(start, nxt):
        t_out[count] = tspan[i]
        if tspan[i] == tnew:
            y_out[count, :] = ynew
        else:
            y_out[count, :] = values[r]
            r += 1
        count += 1
    return t_out, y_out, count, nxt


@_njit(cache=True, error_model="numpy")
def _slope_dt(_rhs, t, y, F0, p, h, absh, tdir, out):
    """df/dt by a forward difference (ode23s's T, ode15s's first step): out = (f(t + tdel, y) - F0) / tdel."""
    tdel = (t + tdir * min(_SQRT_EPS * max(abs(t), abs(t + h)), absh)) - t
    _rhs(t + tdel, y, p, out)
    for j in range(y.shape[0]):
        out[j] = (out[j] - F0[j]) / tdel


def _ode23s(_rhs, _jac, tspan, y0, f0, p, rtol, atol, hmax, htry, refine, max_steps, capacity, perm, kl, ku):
    """integrate_ode23s (no mass, no events); returns (t_out, y_out, count, nsteps, nfailed,
    nfevals, npds, ndecomps, nsolves, status, t, absh)."""
    n = y0.shape[0]
    t0 = tspan[0]
    tf = tspan[tspan.shape[0] - 1]
    tdir = 1.0 if tf > t0 else -1.0
    power = 1.0 / 3.0
    thr = atol / rtol
    J = _np.zeros((n, n))  # jac writes the structural nonzeros only
    lu = _new_lu(n, perm, kl, ku)
    trans = _np.array([78], dtype=_np.uint8)  # "N"
    T, k1, k2, k3 = _np.empty(n), _np.empty(n), _np.empty(n), _np.empty(n)
    F0, F1, F2, stage, ynew, scale = f0.copy(), _np.empty(n), _np.empty(n), _np.empty(n), _np.empty(n), _np.empty(n)
    y = y0.copy()
    if htry == htry:
        absh = given_step(htry, t0, hmax)  # noqa: F821 (controller.py's, in the same module)
    else:
        for j in range(n):
            scale[j] = _npmax(abs(y0[j]), thr[j])
        absh = first_step(_wmax(f0, scale) / (0.8 * rtol ** power), abs(tspan[1] - t0), hmax, t0)  # noqa: F821
    t_out = _np.empty(capacity)
    y_out = _np.empty((capacity, n))
    t_out[0] = t0
    y_out[0, :] = y0
    count, nxt = 1, 1
    nsteps = nfailed = nfevals = npds = ndecomps = nsolves = 0
    status = _Status.SUCCESS  # noqa: F821
    t = t0
    err = 0.0
    while True:
        hmin, absh, done = clamp_step(t, tf, absh, hmax)  # noqa: F821
        h = tf - t if done else tdir * absh
        _jac(t, y, p, J)
        npds += 1
        _slope_dt(_rhs, t, y, F0, p, h, absh, tdir, T)
        nfevals += 1
        nofailed = True
        tnew = t
        while True:
            hd = h * _D23
            _factor(J, hd, lu)
            ndecomps += 1
            for j in range(n):
                k1[j] = F0[j] + hd * T[j]
            _lsolve(lu, trans, k1)
            hh = 0.5 * h
            for j in range(n):
                stage[j] = y[j] + hh * k1[j]
            _rhs(t + 0.5 * h, stage, p, F1)
            for j in range(n):
                k2[j] = F1[j] - k1[j]
            _lsolve(lu, trans, k2)
            for j in range(n):
                k2[j] = k2[j] + k1[j]
            tnew = tf if done else t + h
            h = tnew - t
            for j in range(n):
                ynew[j] = y[j] + h * k2[j]
            _rhs(tnew, ynew, p, F2)
            nfevals += 2
            for j in range(n):
                k3[j] = ((F2[j] - _E32 * (k2[j] - F1[j])) - 2.0 * (k1[j] - F0[j])) + hd * T[j]
            _lsolve(lu, trans, k3)
            nsolves += 3
            for j in range(n):
                scale[j] = _npmax(_npmax(abs(y[j]), abs(ynew[j])), thr[j])
                stage[j] = (k1[j] - 2.0 * k2[j]) + k3[j]
            err = (absh / 6.0) * _wmax(stage, scale)
            if err > rtol:
                nfailed += 1
                if absh <= hmin:
                    status = _Status.STEP_UNDERFLOW  # noqa: F821
                    break
                absh = shrink(absh, hmin, err, rtol, power, 0.5, 0.8, nofailed)  # noqa: F821
                nofailed = False
                h = tdir * absh
                done = False
            elif err <= rtol:
                break
            else:
                status = _Status.NONFINITE  # noqa: F821
                break
        if status != _Status.SUCCESS:  # noqa: F821
            break
        nsteps += 1
        t_out, y_out, count, nxt = _record(t_out, y_out, count, nxt, tspan, refine, t, tnew, ynew, 0, t, h, y, k1,
                                           k2, J, 0)
        if done:
            t = tnew
            break
        if max_steps > 0 and nsteps >= max_steps:
            t = tnew
            status = _Status.MAX_STEPS  # noqa: F821
            break
        if nofailed:
            absh = grow(absh, err, rtol, power, 1.25, 5.0)  # noqa: F821
        t = tnew
        for j in range(n):
            y[j] = ynew[j]
            F0[j] = F2[j]
    return t_out, y_out, count, nsteps, nfailed, nfevals, npds, ndecomps, nsolves, status, t, absh


@_njit(cache=True, error_model="numpy")
def _rescale(order, factor, R):
    """ode15s._rescale: the paper's R(factor), (order+1) x (order+1), into R."""
    for c in range(order + 1):
        R[0, c] = 1.0
    for i in range(1, order + 1):
        R[i, 0] = 0.0
        for c in range(1, order + 1):
            R[i, c] = R[i - 1, c] * (((i - 1) - factor * c) / i)


@_njit(cache=True, error_model="numpy")
def _change_differences(D, order, factor):
    """ode15s.change_differences: D[0..order] <- (R(factor) @ R(1))^T @ D[0..order] (numpy's BLAS calls)."""
    m = order + 1
    R, U, RU = _np.empty((m, m)), _np.empty((m, m)), _np.empty((m, m))
    _rescale(order, factor, R)
    _rescale(order, 1.0, U)
    _matmul(R, U, RU)
    new = _np.empty((m, D.shape[1]))
    _matmul(RU, D[:m], new, True)
    D[:m] = new


@_njit(cache=True, error_model="numpy")
def _first_step_15s(_rhs, J, t0, y0, f0, p, thr, rtol, hmax, htry, htspan, tdir, wt, ypp):
    """ode15s's first step: from y' (or InitialStep), then from the BDF1 error h^2/2 |y''|.
    Returns (absh, evaluations)."""
    n = y0.shape[0]
    for j in range(n):
        wt[j] = _npmax(abs(y0[j]), thr[j])
    if htry == htry:
        return given_step(htry, t0, hmax), 0  # noqa: F821
    absh = first_step(1.25 * _wmax(f0, wt) / _np.sqrt(rtol), htspan, hmax, t0)  # noqa: F821
    _slope_dt(_rhs, t0, y0, f0, p, tdir * absh, absh, tdir, ypp)
    Jf = _np.empty(n)
    _matvec(J, f0, Jf)
    for i in range(n):
        ypp[i] = ypp[i] + Jf[i]
    return first_step(1.25 * _np.sqrt(0.5 * _wmax(ypp, wt) / rtol), htspan, hmax, t0), 1  # noqa: F821


@_njit(cache=True, error_model="numpy")
def _newton_15s(_rhs, p, tnew, c, D, k, psi, ypred, ynew, d, dy, wt, minnrm, rtol, lu, trans, memory):
    """ode15s's simplified Newton iteration (at most 4). memory = [rate, havrate]; returns
    (converged, evaluations = solves)."""
    n = ynew.shape[0]
    for j in range(n):
        d[j] = 0.0
        ynew[j] = ypred[j]
    oldnrm = 0.0
    for it in range(1, 5):
        _rhs(tnew, ynew, p, dy)
        for j in range(n):
            dy[j] = c * dy[j] - (psi[j] + d[j])
        _lsolve(lu, trans, dy)
        newnrm = _wmax(dy, wt)
        for j in range(n):
            d[j] = d[j] + dy[j]
            ynew[j] = ypred[j] + d[j]
        if not _np.isfinite(newnrm):
            return False, it
        if newnrm <= minnrm:
            return True, it
        rate = memory[0]
        if it == 1:
            if memory[1] != 0.0:
                if newnrm * rate / (1 - rate) <= 0.05 * rtol:
                    return True, it
            else:
                memory[0] = 0.0
        elif newnrm > 0.9 * oldnrm:
            return False, it
        else:
            rate = max(0.9 * rate, newnrm / oldnrm)
            memory[0] = rate
            memory[1] = 1.0
            errit = newnrm * rate / (1 - rate)
            if errit <= 0.5 * rtol:
                return True, it
            if it == 4 or 0.5 * rtol < errit * rate ** (4 - it):
                return False, it
        oldnrm = newnrm
    return False, 4


@_njit(cache=True, error_model="numpy")
def _predict_15s(D, k, gamma, alpha, y, thr, ypred, psi, wt):
    """The predictor sum(D[0..k]), psi = (GAMMA[1..k] @ D[1..k]) / alpha[k], the weights and minnrm."""
    n = y.shape[0]
    _vecmat(gamma[1:k + 1], D[1:k + 1], psi)
    for j in range(n):
        acc = D[0, j]
        for i in range(1, k + 1):
            acc += D[i, j]
        ypred[j] = acc
        psi[j] = psi[j] / alpha[k]
        wt[j] = _npmax(abs(y[j]), thr[j])
    return (100 * _EPS) * _wmax(y, wt)


@_njit(cache=True, error_model="numpy")
def _diff_norm(a, b, scale, tmp):
    """np.max(np.abs(a + b) / scale) (b may be a zero row)."""
    for j in range(a.shape[0]):
        tmp[j] = a[j] + b[j]
    return _wmax(tmp, scale)


@_njit(cache=True, error_model="numpy")
def _choose_order_15s(D, k, absh, err, rtol, erconst, scale, max_order, zero, tmp):
    """After a step at constant h and order for k+2 steps: the step and order (k-1, k, k+1) that
    go furthest, as ode15s. Returns (hopt, kopt)."""
    hopt = grow(absh, err, rtol, 1 / (k + 1), 1.2, 10.0)  # noqa: F821
    kopt = k
    if k > 1:
        errkm1 = erconst[k - 1] * _diff_norm(D[k], zero, scale, tmp)
        hkm1 = absh / max(0.1, 1.3 * (errkm1 / rtol) ** (1 / k))
        if hkm1 > hopt:
            hopt, kopt = hkm1, k - 1
    if k < max_order:
        errkp1 = erconst[k + 1] * _diff_norm(D[k + 2], zero, scale, tmp)
        hkp1 = absh / max(0.1, 1.4 * (errkp1 / rtol) ** (1 / (k + 2)))
        if hkp1 > hopt:
            hopt, kopt = hkp1, k + 1
    return hopt, kopt


@_njit(cache=True, error_model="numpy")
def _after_error_15s(D, k, absh, hmin, err, rtol, erconst, d, scale, nfails, tmp):
    """The step (and order) after a failed error test, as ode15s. Returns (absh, k)."""
    if nfails == 1:
        hopt = shrink(absh, 0.0, err, rtol, 1 / (k + 1), 0.1, 0.833, True)  # noqa: F821
        if k > 1:
            errkm1 = erconst[k - 1] * _diff_norm(D[k], d, scale, tmp)
            hkm1 = shrink(absh, 0.0, errkm1, rtol, 1 / k, 0.1, 0.769, True)  # noqa: F821
            if hkm1 > hopt:
                hopt = min(absh, hkm1)
                k -= 1
        return max(hmin, hopt), k
    return shrink(absh, hmin, err, rtol, 0.0, 0.0, 0.0, False), k  # noqa: F821


def _ode15s(_rhs, _jac, tspan, y0, f0, p, rtol, atol, hmax, htry, refine, max_steps, capacity, perm, kl, ku,
            max_order, gamma, alpha, erconst):
    """integrate_ode15s (no mass, no events; kappa in alpha and erconst); returns as _ode23s."""
    n = y0.shape[0]
    t0 = tspan[0]
    tf = tspan[tspan.shape[0] - 1]
    tdir = 1.0 if tf > t0 else -1.0
    thr = atol / rtol
    J = _np.zeros((n, n))  # jac writes the structural nonzeros only
    lu = _new_lu(n, perm, kl, ku)
    trans = _np.array([78], dtype=_np.uint8)  # "N"
    ypred, psi, wt, scale, d, dy, ynew, tmp = (_np.empty(n), _np.empty(n), _np.empty(n), _np.empty(n),
                                               _np.empty(n), _np.empty(n), _np.empty(n), _np.empty(n))
    zero = _np.zeros(n)
    memory = _np.zeros(2)  # the Newton rate, and whether it is known
    _jac(t0, y0, p, J)
    npds, jcurrent = 1, True
    absh, nfevals = _first_step_15s(_rhs, J, t0, y0, f0, p, thr, rtol, hmax, htry, abs(tspan[1] - t0), tdir, wt, dy)
    D = _np.zeros((max_order + 3, n))
    D[0, :] = y0
    for j in range(n):
        D[1, j] = (tdir * absh) * f0[j]
    y = y0.copy()
    t_out = _np.empty(capacity)
    y_out = _np.empty((capacity, n))
    t_out[0] = t0
    y_out[0, :] = y0
    count, nxt = 1, 1
    k, absh_D, nconhk = 1, absh, 0
    lu_ok, key_absh, key_k, c = False, 0.0, 0, 0.0
    nsteps = nfailed = ndecomps = nsolves = 0
    status = _Status.SUCCESS  # noqa: F821
    t, h, err = t0, tdir * absh, 0.0
    while True:
        hmin, absh, done = clamp_step(t, tf, absh, hmax)  # noqa: F821
        if absh != absh_D:
            _change_differences(D, k, absh / absh_D)
            absh_D, nconhk = absh, 0
        nofailed, nfails = True, 0
        tnew = t
        while True:  # attempts at this step
            h = tf - t if done else tdir * absh
            tnew = tf if done else t + h
            if not lu_ok or key_absh != absh or key_k != k:
                c = h / alpha[k]
                _factor(J, c, lu)
                ndecomps += 1
                lu_ok, key_absh, key_k = True, absh, k
                memory[1] = 0.0
            minnrm = _predict_15s(D, k, gamma, alpha, y, thr, ypred, psi, wt)
            converged, its = _newton_15s(_rhs, p, tnew, c, D, k, psi, ypred, ynew, d, dy, wt, minnrm, rtol, lu, trans,
                                         memory)
            nfevals += its
            nsolves += its
            if not converged:
                nfailed += 1
                if not jcurrent:
                    _jac(t, y, p, J)
                    npds += 1
                    jcurrent, lu_ok = True, False
                    continue
                if absh <= hmin:
                    status = _Status.STEP_UNDERFLOW  # noqa: F821
                    break
                absh_old = absh
                absh = shrink_after_newton(absh, hmin)  # noqa: F821
                _change_differences(D, k, absh / absh_old)
                absh_D, done, nofailed, nconhk = absh, False, False, 0
                continue
            for j in range(n):
                scale[j] = _npmax(_npmax(abs(y[j]), abs(ynew[j])), thr[j])
            err = erconst[k] * _wmax(d, scale)
            if err > rtol:
                nfailed += 1
                nfails += 1
                if absh <= hmin:
                    status = _Status.STEP_UNDERFLOW  # noqa: F821
                    break
                absh_old = absh
                absh, k = _after_error_15s(D, k, absh, hmin, err, rtol, erconst, d, scale, nfails, tmp)
                _change_differences(D, k, absh / absh_old)
                absh_D, done, nofailed, nconhk = absh, False, False, 0
                continue
            if err != err:
                status = _Status.NONFINITE  # noqa: F821
            break
        if status != _Status.SUCCESS:  # noqa: F821
            break
        nsteps += 1
        for j in range(n):
            D[k + 2, j] = d[j] - D[k + 1, j]
            D[k + 1, j] = d[j]
        for i in range(k, -1, -1):
            for j in range(n):
                D[i, j] += D[i + 1, j]
        jcurrent = False
        t_out, y_out, count, nxt = _record(t_out, y_out, count, nxt, tspan, refine, t, tnew, D[0], 1, tnew, h, y, d,
                                           d, D, k)
        t = tnew
        y[:] = D[0]
        nconhk = min(nconhk + 1, max_order + 2)
        if done:
            break
        if max_steps > 0 and nsteps >= max_steps:
            status = _Status.MAX_STEPS  # noqa: F821
            break
        if nofailed and nconhk >= k + 2:
            hopt, kopt = _choose_order_15s(D, k, absh, err, rtol, erconst, scale, max_order, zero, tmp)
            if hopt > absh:
                absh = hopt
                if kopt != k:
                    k, nconhk = kopt, 0
    return t_out, y_out, count, nsteps, nfailed, nfevals, npds, ndecomps, nsolves, status, t, absh


_STIFF = (_RHS_ARG, _JAC_ARG, _V, _V, _V, _V, _F8, _V, _F8, _F8, _I8, _I8, _I8, _types.int64[::1], _I8, _I8)  # noqa: F821
_SIGNATURES["ode23s"] = _STIFF  # noqa: F821 (kernels.py's registry of loops)
_SIGNATURES["ode15s"] = (*_STIFF, _I8, _V, _V, _V)  # noqa: F821
_LOOPS["ode23s"] = "_ode23s"  # noqa: F821
_LOOPS["ode15s"] = "_ode15s"  # noqa: F821

