"""The explicit Runge-Kutta stepping engine.

Two drivers share one step formula (stages ``k_i = f(t + c_i h, y + h sum_j A_ij k_j)``,
solution ``y + h sum_j b_j k_j``) read from a :class:`~odelab.solvers.tableau.ButcherTableau`:

* :func:`integrate_adaptive` — an embedded pair with MATLAB's step-size controller,
  error norm, initial step and output rules (Shampine & Reichelt, *The MATLAB ODE Suite*,
  SIAM J. Sci. Comput. 18(1), 1997). ``ode23`` is this driver with the Bogacki-Shampine
  tableau, ``ode45`` with Dormand-Prince; nothing else differs. FSAL pairs (the last stage
  is ``f(t+h, y_new)``) are the default; a non-FSAL pair (``ode78``/``ode89``, Verner's)
  passes its weights ``b``: ``f(t+h, y_new)`` is evaluated once the step is accepted, and the
  extra stages of its continuous extension only for a step whose interpolant is used. Its
  stages are held as increments ``K_j - K_0`` (Verner's coefficients reach 120, and summing
  them against the nearly equal stages themselves would lose two digits to cancellation).
* :func:`integrate_fixed` — the same stages on a prescribed grid of steps.

The drivers are written for a later compiled backend: scalars and float arrays in, a tuple of
arrays and integer codes out, no objects, no strings, no closures. Every operation follows the
order of MATLAB's ``ode23.m``/``ode45.m`` so that results agree to round-off (for example the
step multiplies ``h`` into the tableau first, ``hA = h*A``, then sums the stages, as MATLAB's
``f*hB`` does).

The adaptive driver's step is a few small numpy calls around the right-hand side, so the loop
avoids every call it can without changing a bit of the result: the tableau's rows and the
stage matrix are bound to fixed views once, the error norm's maximum is taken over a Python
list for small systems (a numpy reduction costs more than the division before it), each
accepted step's end and stages go into arrays that grow in place, and the interior ``Refine``
points are interpolated after the loop for all steps at once (a stacked product that gives the
per-step product's bits), unless an output function needs them step by step.
"""

from __future__ import annotations

import math

import numpy as np

from odelab.solvers.controller import clamp_step, first_step, given_step, grow, shrink
from odelab.solvers.ordered import backwards, combine, norm
from odelab.solvers.status import Status

__all__ = ["integrate_adaptive", "integrate_fixed"]


#: Systems up to this size take the error norm's maximum over a Python list (cheaper than a
#: numpy reduction for a few components; the same bits).
_SMALL = 16
#: Steps the step arrays hold at first; they grow by a quarter (at least this many) when full.
_FIRST_CAPACITY = 64
#: Steps per block when the Refine rows are interpolated after the loop (bounds the temporaries).
_BLOCK = 16384


def _grow(arr: np.ndarray, rows: int) -> None:
    """Resize ``arr`` to ``rows`` rows in place.

    A realloc: the first rows keep their values, and the operating system remaps a long run's
    arrays instead of copying them (so growing one never holds two copies). The engine never
    takes views of these arrays before their last resize.
    """
    arr.resize((rows,) + arr.shape[1:], refcheck=False)


def _complete(fun, t: float, h: float, K: np.ndarray, A_extra: np.ndarray, hA_extra: np.ndarray,
              extra_rows) -> int:
    """Evaluate a non-FSAL step's interpolation stages into K (stage ``s+1+j`` is
    ``f(t + c_j h, y + h A_extra[j] . K)``, held as its increment over ``K_0``), for a step that
    is interpolated; returns their number. ``hA_extra`` is ``[1, h*A_extra]`` by rows and each
    of ``extra_rows`` pairs a row of it read backwards with the stages and ``y`` above it (the
    stage's sum in :mod:`odelab.solvers.ordered`'s order, one non-BLAS product)."""
    np.multiply(A_extra, h, hA_extra[:, 1:])
    for K_row, cj, stage_dot, rows in extra_rows:
        K_row[...] = fun(t + cj * h, stage_dot(rows)[0])
        K_row -= K[0]  # increment form
    return len(extra_rows)


def _refine_rows(weights_T: np.ndarray, h, K: np.ndarray, y: np.ndarray, nonnegative) -> np.ndarray:
    """MATLAB's interior Refine points of one step, ``y + h * W K`` with ``W`` the extension's
    weights at s = j/refine (``weights_T`` holds its rows read backwards, see
    :func:`odelab.solvers.ordered.backwards`): shape (refine-1, n) for one step's K (s, n)."""
    block = np.empty((len(weights_T), K.shape[1]), dtype=K.dtype)
    for r, w in enumerate(weights_T):
        block[r] = h * (w @ K) + y
    if nonnegative is not None:
        block[:, nonnegative] = np.maximum(block[:, nonnegative], 0.0)
    return block


def _refine_output(t_ends, y_ends, step_K, fractions, weights_T, nonnegative):
    """The output of a two-element tspan with Refine > 1, from every step's end and stages.

    Row ``k*refine`` is the end of step k (t0 for k = 0) and the ``refine - 1`` rows after it
    are the step's interior points, computed with :func:`_refine_rows`' formula for blocks of
    steps at once (a backwards weight row times a stack of steps' stages: numpy's own loop,
    the same bits as the per-step product).
    """
    N = t_ends.size - 1
    r = fractions.size + 1
    h = np.diff(t_ends)
    t_arr = np.empty(N * r + 1)
    t_arr[0] = t_ends[0]
    t_view = t_arr[1:].reshape(N, r)
    t_view[:, :-1] = t_ends[:-1, None] + h[:, None] * fractions
    t_view[:, -1] = t_ends[1:]
    y_arr = np.empty((N * r + 1, y_ends.shape[1]), dtype=y_ends.dtype)
    y_arr[0] = y_ends[0]
    y_view = y_arr[1:].reshape(N, r, y_ends.shape[1])
    y_view[:, -1] = y_ends[1:]
    for a in range(0, N, _BLOCK):
        b = min(N, a + _BLOCK)
        for r, w in enumerate(weights_T):
            y_view[a:b, r] = h[a:b, None] * (w @ step_K[a:b]) + y_ends[a:b]
    if nonnegative is not None:
        interior = y_view[:, :-1]
        interior[..., nonnegative] = np.maximum(interior[..., nonnegative], 0.0)
    return t_arr, y_arr



def integrate_adaptive(
    fun,
    tspan: np.ndarray,
    y0: np.ndarray,
    f0: np.ndarray,
    A: np.ndarray,
    c: np.ndarray,
    E: np.ndarray,
    dense: np.ndarray,
    power: float,
    shrink_min: float,
    rtol: float,
    threshold: np.ndarray,
    hmax: float,
    htry: float,
    refine: int,
    norm_control: bool,
    max_steps: int,
    events=None,
    v0=None,
    nonnegative=None,
    output_fcn=None,
    b=None,
    extra=None,
    dense_basis="monomial",
):
    """Integrate with an embedded Runge-Kutta pair and MATLAB's controller.

    Parameters
    ----------
    fun
        ``fun(t, y)`` returning the derivative (anything assignable to a row of length n).
    tspan
        Output specification, MATLAB semantics: 2 entries ``[t0, tf]`` give ``refine`` points
        per step; more entries give output exactly at those times.
    y0, f0
        Initial state and ``fun(t0, y0)`` (counted by the caller). A complex ``y0`` integrates
        in complex arithmetic, the error measured on ``|y|``, as MATLAB does.
    A, c, E, dense
        Tableau arrays. Without ``b`` the last stage must be FSAL (``A[-1]`` are the solution
        weights). With ``b``, ``A``, ``c`` and ``E`` cover the s stages of the step and
        ``dense`` has one row per stage of the extended step: the s stages,
        ``f(t + h, y_new)``, then the stages of ``extra``; all of them (with ``b``, ``extra``)
        in increment form (:attr:`~odelab.solvers.tableau.ButcherTableau.increment_form`): they
        act on ``K_0`` and the increments ``K_j - K_0``, which is what ``K`` then holds.
    power
        Controller exponent ``1/(q+1)`` with q the embedded order (1/3 ode23, 1/5 ode45).
    shrink_min
        Smallest factor of the first step-size reduction after a failure (0.5 ode23, 0.1 ode45).
    rtol, threshold
        Relative tolerance and ``atol/rtol`` (per component, or a scalar with norm_control).
    hmax
        Largest step.
    htry
        Initial step, or NaN to choose it from ``f0`` as MATLAB does.
    refine
        Output points per step for a two-element ``tspan``.
    norm_control
        Control the Euclidean norm of the error relative to the norm of the solution.
    max_steps
        Stop after this many successful steps (0: no limit).
    events, v0
        ``events(t, y) -> (value, isterminal, direction)`` arrays and its value at ``t0``, or
        None: after each accepted step :func:`odelab.solvers.events.locate_events` finds the
        zeros on the step's continuous extension (MATLAB's ``odezero``).
    nonnegative
        Integer indices of components kept non-negative (MATLAB's ``NonNegative``; ``fun``
        must already zero their negative slopes at zero), or None.
    output_fcn
        ``output_fcn(t_new, y_new) -> bool`` called after each step with that step's new output
        rows; True stops the integration (MATLAB's ``OutputFcn`` with flag ``''``), or None.

    Returns
    -------
    tuple
        ``(t_out, y_out, nsteps, nfailed, nfevals, status, t_stop, h_stop, exception, found, steps)``
        where ``t_stop`` is the time where integration stopped, ``h_stop`` the last step size
        tried, ``exception`` the exception ``fun`` (or ``events``) raised (or None),
        ``found = (te, ye, ie)`` lists of located events and ``steps = (t, h, y, K)`` arrays of
        every accepted step for dense output. With ``extra``, ``steps`` has a fifth array: which
        steps have their extra stages computed (the others are completed on demand by
        :class:`odelab.solvers.dense.StageCompletion`).
    b
        Solution weights (s,) of a non-FSAL pair, or None for an FSAL pair.
    extra
        ``(A_extra, c_extra)``, the interpolation stages of a non-FSAL pair: stage ``s+1+j`` is
        ``f(t + c_extra[j] h, y + h A_extra[j] . K)`` over the stages before it; or None.
    dense_basis
        What the columns of ``dense`` multiply: ``"monomial"`` (s, s^2, ...) or ``"chebyshev"``
        (:func:`odelab.solvers.dense.basis_values`).
    """
    s = c.size
    fsal = b is None
    n = y0.size
    t0 = float(tspan[0])
    tfinal = float(tspan[-1])
    ntspan = tspan.size
    tdir = 1.0 if tfinal > t0 else -1.0
    last = s - 1
    nodes = [float(ci) for ci in c]
    is_complex = np.iscomplexobj(y0)
    dtype = y0.dtype
    # Preallocated work arrays and fixed views into them. The stages and y share one array W,
    # its rows K_(R-1), ..., K_1, K_0, y (R stages): stage i's terms and y are its rows
    # R-i .. R, and a row of [1, h*A] read backwards holds their coefficients, so that
    # ``coefficients.dot(rows[None])[0]`` is the stage ``y + sum_k hA[i, k] K_k`` in one call,
    # summed in the order of odelab.solvers.ordered (k = i-1 down to 0, then y) by numpy's own
    # loop (see there: a backwards vector and a 3-D operand keep numpy.dot off BLAS): the same
    # bits under every BLAS, and those of the compiled loops. K is W's stage rows in stage
    # order (a view).
    # A non-FSAL pair's K also holds f(t+h, y_new) (row s, the next step's first stage) and
    # the interpolation stages after it; K_main is the step's own s stages.
    R = s if fsal else dense.shape[0]
    W = np.empty((R + 1, n), dtype=dtype)
    K = W[R - 1::-1]
    W[R] = y0
    y_row = W[R]  # the current step's start y: the loop copies an accepted ynew into it
    K[0] = f0
    K_main = K[:s]
    hAx = np.empty((s, s + 1))
    hAx[:, 0] = 1.0
    hA = hAx[:, 1:]
    # (row i of K, c_i, the coefficients, the rows) of each stage the loop computes after the
    # first (an FSAL pair's last stage is f(tnew, ynew), computed apart); writing into a fixed
    # row view is cheaper than K[i] = ...
    middle = [(K[i], nodes[i], hAx[i, i::-1].dot, W[None, R - i:]) for i in range(1, last if fsal else s)]
    K_first, K_fnew = K[0], K[last if fsal else s]  # the next step's first stage is K_fnew
    if fsal:
        last_dot, rows_last = hAx[last, last::-1].dot, W[None, R - last:]
    else:
        b = np.asarray(b)
        hbx = np.empty(s + 1)
        hbx[0] = 1.0
        hb = hbx[1:]
        last_dot, rows_last = hbx[::-1].dot, W[None, R - s:]
        if extra is not None:
            A_extra, c_extra = extra
            hA_extra = np.empty((A_extra.shape[0], A_extra.shape[1] + 1))
            hA_extra[:, 0] = 1.0
            extra_rows = [(K[s + 1 + j], float(c_extra[j]), hA_extra[j, s + 1 + j::-1].dot, W[None, R - (s + 1 + j):])
                          for j in range(len(c_extra))]
    have_extra = not fsal and extra is not None
    step_complete: list[bool] = []
    # [whether this step's interpolation stages are in K, evaluations made by the events'
    # closure] (a list: the closure updates it)
    completed = [True, 0]
    all_nodes = c if fsal else np.concatenate([c, [1.0], extra[1] if have_extra else []])
    # fE = E . K summed for k = 0, 1, ... (numpy's own loop), into fE_row
    E_dot, K_main_3d = backwards(E).dot, K_main[None]
    fE_out = np.empty((1, n), dtype=np.result_type(E, dtype))
    fE = fE_out[0]
    absy = np.abs(y0)
    have_nonneg = nonnegative is not None
    if have_nonneg:
        threshold_nn = threshold if norm_control else threshold[nonnegative]
    # The error norm max_i |fE_i| / max(|y_i|, |ynew_i|, threshold_i): for a small real system
    # the maximum is taken over a Python list (numpy's reductions cost more than the whole
    # division); both give the same bits.
    small_real = not is_complex and n <= _SMALL
    if not norm_control:
        ywt = np.maximum(absy, threshold)  # max(|y|, threshold), the part known before the step

    absolute = np.abs
    maximum = np.maximum
    t = t0
    y = y_row
    normy = float(norm(y0)) if norm_control else 0.0
    normynew = normy

    if htry != htry:  # NaN: MATLAB's initial step from the derivative at t0
        if norm_control:
            rh = (float(norm(f0)) / max(normy, float(threshold))) / (0.8 * rtol**power)
        else:
            rh = float((np.abs(f0) / np.maximum(absy, threshold)).max()) / (0.8 * rtol**power)
        absh = first_step(rh, abs(float(tspan[1]) - t0), hmax, t0)
    else:
        absh = given_step(htry, t0, hmax)

    refine_output = ntspan == 2
    if refine_output and refine > 1:
        # Interior output at s = j/refine: the extension's weights sum_m dense[:, m] s^(m+1)
        # do not depend on the step, so they are formed once.
        from odelab.solvers.dense import refine_weights

        fractions = np.arange(1, refine) / refine
        # row j: the weight of each stage at s = fractions[j] (sum_m dense[:, m] * basis_m(s)),
        # kept backwards for the products with the stages
        weights_T = [backwards(w) for w in refine_weights(fractions, dense, dense_basis)]
    nxt = 1  # next tspan entry to output (vector tspan)
    if not refine_output:
        # MATLAB's output at the given times only: at most one row per entry, plus a terminal
        # event's point.
        t_out = [t0]
        y_out = np.empty((ntspan + 1, n), dtype=dtype)
        y_out[0] = y0
        nout = 1

    # Every accepted step's end time, end state and stages, in arrays grown in place (they
    # serve the output, deval and the events' interpolation; the interior Refine points are
    # interpolated from them after the loop, all steps at once).
    capacity = _FIRST_CAPACITY
    t_ends = np.empty(capacity + 1)
    y_ends = np.empty((capacity + 1, n), dtype=dtype)
    step_K = np.empty((capacity, K.shape[0], n), dtype=dtype)
    t_ends[0] = t0
    y_ends[0] = y0
    stored = 0
    te: list[float] = []
    ye: list[np.ndarray] = []
    ie: list[int] = []
    v_left = v0
    if events is not None:
        from odelab.solvers.dense import step_slopes, step_value
        from odelab.solvers.events import locate_events

    nsteps = 0
    nfailed = 0
    nfevals = 0
    status = success = Status.SUCCESS  # a local: the enum's attribute lookup costs more than a step's test
    exception = None
    h = tdir * absh
    try:
        while True:
            # hmin <= absh <= hmax, stretched (or shrunk) to land on tfinal if within 10% of it
            hmin, absh, done = clamp_step(t, tfinal, absh, hmax)
            h = tfinal - t if done else tdir * absh

            nofailed = True
            while True:
                np.multiply(A, h, hA)
                if fsal:
                    for K_row, ci, stage_dot, rows in middle:
                        K_row[...] = fun(t + ci * h, stage_dot(rows)[0])
                    tnew = t + h
                    if done:
                        tnew = tfinal  # hit the end point exactly
                    h = tnew - t  # purify h
                    ynew = last_dot(rows_last)[0]
                    K_fnew[...] = fun(tnew, ynew)
                else:  # every stage inside the step; f(tnew, ynew) once the step is accepted
                    for K_row, ci, stage_dot, rows in middle:
                        K_row[...] = fun(t + ci * h, stage_dot(rows)[0])
                        K_row -= K_first  # increment form
                    tnew = t + h
                    if done:
                        tnew = tfinal
                    np.multiply(b, h, hb)  # with the h the stages used, as for hA
                    h = tnew - t
                    ynew = last_dot(rows_last)[0]
                nfevals += last

                E_dot(K_main_3d, fE_out)
                if have_nonneg:
                    nn_reject = False
                if norm_control:
                    normynew = float(norm(ynew))
                    err = absh * (float(norm(fE)) / max(normy, normynew, float(threshold)))
                    if have_nonneg and err <= rtol and (ynew[nonnegative] < 0).any():
                        err_nn = float(norm(np.maximum(0.0, -ynew[nonnegative]))) / max(
                            normy, normynew, float(threshold))
                        if err_nn > rtol:
                            err, nn_reject = err_nn, True
                else:
                    absynew = absolute(ynew)
                    scale = maximum(ywt, absynew)
                    if small_real:
                        q = (fE / scale).tolist()
                        err = absh * max(map(abs, q))
                        total = sum(q)
                        if total != total:  # a NaN ratio, which max may skip
                            err = math.nan
                    else:
                        err = absh * float((absolute(fE) / scale).max())
                    if have_nonneg and err <= rtol and (ynew[nonnegative] < 0).any():
                        # Shampine, Thompson, Kierzenka & Byrne (2005): a negative value of a
                        # non-negative component counts as error.
                        err_nn = float((np.maximum(0.0, -ynew[nonnegative]) / threshold_nn).max())
                        if err_nn > rtol:
                            err, nn_reject = err_nn, True

                if err > rtol:  # failed attempt
                    nfailed += 1
                    if absh <= hmin:
                        status = Status.STEP_UNDERFLOW
                        break
                    # a negative non-negative component halves the step, as a second failure
                    absh = shrink(absh, hmin, err, rtol, power, shrink_min, 0.8,
                                  nofailed and not (have_nonneg and nn_reject))
                    nofailed = False
                    h = tdir * absh
                    done = False
                elif err <= rtol:
                    break
                else:  # err is NaN: a derivative or the solution is not finite
                    status = Status.NONFINITE
                    break
            if status != success:
                break
            nsteps += 1
            if not fsal:
                fnew = fun(tnew, ynew)
                np.subtract(fnew, K_first, K_fnew)
                nfevals += 1
                completed[0] = not have_extra
            nn_reset = False
            if have_nonneg and (ynew[nonnegative] < 0).any():
                # Accepted: clip to the constraint; the interpolant keeps the unclipped stages.
                ynew[nonnegative] = np.maximum(ynew[nonnegative], 0.0)
                if norm_control:
                    normynew = float(norm(ynew))
                else:
                    absynew = np.abs(ynew)
                nn_reset = True

            stop = False
            if events is not None:
                step_t0, step_y0, step_h0 = t, y, h

                def interpolate(tq):
                    if not completed[0]:
                        completed[1] += _complete(fun, step_t0, step_h0, K, A_extra, hA_extra, extra_rows)
                        completed[0] = True
                    return step_value(tq, step_t0, step_y0, step_h0, K, dense, nonnegative, dense_basis)

                found_t, found_y, found_i, v_left, stop = locate_events(
                    interpolate, events, v_left, t, y, tnew, ynew, t0)
                if found_t:
                    te.extend(found_t)
                    ye.extend(found_y)
                    ie.extend(found_i)
                    if stop:
                        # A terminal event cuts the step at te: the stages of [t, te] become the
                        # extension's slopes at its nodes, as MATLAB does, so output on the
                        # shortened step follows the same curve.
                        t_event = found_t[-1]
                        K[1:] = step_slopes(t + (t_event - t) * all_nodes[1:], t, y, h, K, dense, nonnegative,
                                            dense_basis)
                        if not fsal:
                            K[1:] -= K[0]
                        tnew = t_event
                        ynew = found_y[-1]
                        h = tnew - t
                        done = True
                        status = Status.TERMINAL_EVENT

            if not completed[0] and (
                    (refine_output and refine > 1)
                    or (not refine_output and nxt < ntspan and tdir * (tnew - float(tspan[nxt])) > 0)):
                # The step is interpolated (Refine, or an output time inside it): its
                # interpolation stages are needed now.
                nfevals += _complete(fun, t, h, K, A_extra, hA_extra, extra_rows)
                completed[0] = True
            if stored == capacity:
                capacity += max(capacity >> 2, _FIRST_CAPACITY)
                _grow(t_ends, capacity + 1)
                _grow(y_ends, capacity + 1)
                _grow(step_K, capacity)
            step_K[stored] = K
            if have_extra:
                step_complete.append(completed[0])
            stored += 1
            t_ends[stored] = tnew
            y_ends[stored] = ynew
            if not refine_output:
                n_before = nout
                while nxt < ntspan:
                    tn = float(tspan[nxt])
                    if tdir * (tnew - tn) < 0:
                        if stop:  # MATLAB outputs the terminal event's point too
                            t_out.append(tnew)
                            y_out[nout] = ynew
                            nout += 1
                        break
                    t_out.append(tn)
                    if tn == tnew:
                        y_out[nout] = ynew
                    else:
                        from odelab.solvers.dense import step_value

                        y_out[nout] = step_value(tn, t, y, h, K, dense, nonnegative, dense_basis)
                    nout += 1
                    nxt += 1
                if output_fcn is not None and nout > n_before:
                    if output_fcn(np.array(t_out[n_before:]), y_out[n_before:nout].copy()):
                        status = Status.OUTPUT_STOP
                        t = tnew
                        break
            elif output_fcn is not None:  # this step's Refine rows, as the output will hold them
                if refine > 1:
                    t_new_rows = np.append(t + h * fractions, tnew)
                    y_new_rows = np.vstack([_refine_rows(weights_T, h, K, y, nonnegative), ynew])
                else:
                    t_new_rows, y_new_rows = np.array([tnew]), ynew.reshape(1, n).copy()
                if output_fcn(t_new_rows, y_new_rows):
                    status = Status.OUTPUT_STOP
                    t = tnew
                    break

            if done:
                t = tnew
                break
            if max_steps and nsteps >= max_steps:
                status = Status.MAX_STEPS
                t = tnew
                break

            # No failures in this step: choose the next step from the error estimate.
            if nofailed:
                absh = grow(absh, err, rtol, power, 1.25, 5.0)

            t = tnew
            y_row[...] = ynew  # y is y_row: the rows of the next step's stages
            if norm_control:
                normy = normynew
            else:
                ywt = maximum(absynew, threshold)
            if nn_reset:
                # The stages interpolated the unclipped solution; move on along the clipped one.
                if fsal:
                    K_fnew[...] = fun(tnew, ynew)
                else:
                    fnew = fun(tnew, ynew)
                nfevals += 1
            if fsal:
                K_first[...] = K_fnew
            else:
                K_first[...] = fnew
    except Exception as exc:  # the user's right-hand side (or events function) failed
        status = Status.FUN_RAISED
        exception = exc
    nfevals += completed[1]

    # Trim the step arrays to the steps taken (in place: no copy of a long run's arrays).
    _grow(t_ends, stored + 1)
    _grow(y_ends, stored + 1)
    _grow(step_K, stored)
    if refine_output:
        t_arr, y_arr = t_ends, y_ends
        if refine > 1 and stored:
            t_arr, y_arr = _refine_output(t_ends, y_ends, step_K, fractions, weights_T, nonnegative)
            del y_ends  # the step starts are read off the output, every refine-th row
        step_y = y_arr[::refine][:-1]
    else:
        t_arr = np.array(t_out)
        _grow(y_out, nout)
        y_arr = y_out
        step_y = y_ends[:-1]
    steps = (t_ends[:-1], np.diff(t_ends), step_y, step_K) if stored else None
    if steps is not None and have_extra:
        steps += (np.array(step_complete),)
    return (t_arr, y_arr, nsteps, nfailed, nfevals, status, t, abs(h), exception, (te, ye, ie), steps)



def integrate_fixed(fun, grid: np.ndarray, keep: np.ndarray, y0: np.ndarray, A: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Integrate with a fixed-step explicit Runge-Kutta method on a prescribed grid.

    Parameters
    ----------
    fun
        ``fun(t, y)`` returning the derivative.
    grid
        Step points ``t_0, t_1, ..., t_N`` (monotonic); step k goes from ``grid[k]`` to ``grid[k+1]``.
    keep
        Boolean mask over ``grid``: which points are output.
    y0
        Initial state.
    A, b, c
        The tableau.

    Returns
    -------
    tuple
        ``(t_out, y_out, nsteps, nfevals, status, t_stop, exception)``.
    """
    s = c.size
    n = y0.size
    # integrate_adaptive's layout: W's rows are K_(s-1), ..., K_0, y, and a row of [1, h*A]
    # read backwards times the rows from R-i on is stage i in the order of odelab.solvers.ordered
    W = np.empty((s + 1, n))
    K = W[s - 1::-1]
    y_row = W[s]
    hAx = np.empty((s, s + 1))
    hbx = np.empty(s + 1)
    hAx[:, 0] = hbx[0] = 1.0
    rows = [(K[i], hAx[i, i::-1].dot, W[None, s - i:]) for i in range(1, s)]
    b_dot, W_3d = hbx[::-1].dot, W[None]
    ys = np.empty((grid.size, n))
    ys[0] = y0
    y_row[...] = y0
    y = y_row
    nsteps = 0
    nfevals = 0
    status = Status.SUCCESS
    exception = None
    # Hundreds of thousands of steps: keep the loop on Python floats, and form h*A and h*b only
    # when h changes (once for a uniform grid, again for its shortened last step). The
    # arithmetic is the same as forming them every step, so the results are bit for bit equal.
    times = grid.tolist()
    nodes = c.tolist()
    t = times[0]
    h_prev = math.nan
    try:
        for k in range(grid.size - 1):
            t = times[k]
            h = times[k + 1] - t
            if h != h_prev:
                np.multiply(A, h, hAx[:, 1:])
                np.multiply(b, h, hbx[1:])
                h_prev = h
            K[0] = fun(t, y)
            for i, (K_row, stage_dot, stage_rows) in enumerate(rows, start=1):
                K_row[...] = fun(t + nodes[i] * h, stage_dot(stage_rows)[0])
            nfevals += s
            ynew = b_dot(W_3d)[0]
            if not math.isfinite(float(ynew.sum())):
                status = Status.NONFINITE
                break
            y_row[...] = ynew
            ys[k + 1] = y
            nsteps += 1
            t = times[k + 1]
    except Exception as exc:
        status = Status.FUN_RAISED
        exception = exc
    done = nsteps + 1
    mask = keep[:done].copy()
    mask[done - 1] = True  # always return the last point reached
    return grid[:done][mask], ys[:done][mask], nsteps, nfevals, status, t, exception
