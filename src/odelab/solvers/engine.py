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
stage matrix are bound to fixed views once (:class:`_Stages`, whose attempt is a closure over
them), the error norm's maximum is taken over a Python list for small systems (a numpy
reduction costs more than the division before it), each accepted step's end and stages go into
arrays that grow in place (:class:`odelab.solvers.output.StepStore`), and the interior
``Refine`` points are interpolated after the loop for all steps at once (a stacked product that
gives the per-step product's bits), unless an output function needs them step by step. What
is done with each accepted step (output, events, OutputFcn, the step records) is the shared
collector's, :class:`odelab.solvers.output.StepOutput`; ``NonNegative`` is
:class:`odelab.solvers.output.NonNegative`.

``integrate_adaptive``'s arguments:

* ``fun(t, y)`` the derivative (anything assignable to a row of length n); ``tspan`` MATLAB's
  output specification (2 entries ``[t0, tf]`` give ``refine`` points per step, more give output
  exactly at those times); ``y0, f0`` the initial state and ``fun(t0, y0)`` (counted by the
  caller; a complex ``y0`` integrates in complex arithmetic, the error measured on ``|y|``).
* ``A, c, E, dense`` the tableau's arrays. Without ``b`` the last stage must be FSAL (``A[-1]``
  are the solution weights). With ``b`` (the solution weights of a non-FSAL pair), ``A, c, E``
  cover the s stages of the step and ``dense`` has one row per stage of the extended step: the
  s stages, ``f(t + h, y_new)``, then the stages of ``extra = (A_extra, c_extra)`` (stage
  ``s+1+j`` is ``f(t + c_extra[j] h, y + h A_extra[j] . K)``); all in increment form
  (:attr:`~odelab.solvers.tableau.ButcherTableau.increment_form`). ``dense_basis`` says what
  the columns of ``dense`` multiply: ``"monomial"`` (s, s^2, ...) or ``"chebyshev"``.
* ``power`` the controller exponent ``1/(q+1)`` (q the embedded order); ``shrink_min`` the
  smallest factor of the first reduction after a failure (0.5 ode23, 0.1 ode45); ``rtol`` and
  ``threshold = atol/rtol`` (per component, or a scalar with ``norm_control``: the Euclidean
  norm of the error relative to that of the solution); ``hmax`` the largest step; ``htry`` the
  initial step, or NaN to choose it from ``f0`` as MATLAB does; ``max_steps`` a limit on
  successful steps (0: none).
* ``events, v0``: ``events(t, y) -> (value, isterminal, direction)`` and its value at t0, or
  None (zeros located on each step's extension, MATLAB's ``odezero``); ``nonnegative`` indices
  kept non-negative (``fun`` must already zero their negative slopes at zero), or None;
  ``output_fcn(t_new, y_new) -> bool`` called with each step's new output rows, True stops
  (MATLAB's ``OutputFcn`` with flag ``''``), or None.
"""

from __future__ import annotations

import math

import numpy as np

from odelab.solvers.controller import clamp_step, first_step, given_step, grow, shrink
from odelab.solvers.ordered import backwards, norm
from odelab.solvers.output import DriverResult, NonNegative, StepOutput
from odelab.solvers.status import Status

__all__ = ["integrate_adaptive", "integrate_fixed"]


#: Systems up to this size take the error norm's maximum over a Python list (cheaper than a
#: numpy reduction for a few components; the same bits).
_SMALL = 16
#: Steps per block when the Refine rows are interpolated after the loop (bounds the temporaries).
_BLOCK = 16384


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


class _Stages:
    """One embedded pair's step on preallocated arrays: the stages, the solution, the error norm,
    and the step's continuous extension (events, output, a non-FSAL pair's extra stages).

    The stages and y share one array W, its rows K_(R-1), ..., K_1, K_0, y (R stages): stage i's
    terms and y are its rows R-i .. R, and a row of [1, h*A] read backwards holds their
    coefficients, so that ``coefficients.dot(rows[None])[0]`` is the stage
    ``y + sum_k hA[i, k] K_k`` in one call, summed in the order of odelab.solvers.ordered
    (k = i-1 down to 0, then y) by numpy's own loop (see there: a backwards vector and a 3-D
    operand keep numpy.dot off BLAS): the same bits under every BLAS, and those of the compiled
    loops. K is W's stage rows in stage order (a view). A non-FSAL pair's K also holds
    f(t+h, y_new) (row s, the next step's first stage) and the interpolation stages after it,
    all as increments over K_0; K_main is the step's own s stages.
    """

    __slots__ = ('A', 'A_extra', 'E_dot', 'K', 'K_first', 'K_fnew', 'K_main_3d', 'all_nodes', 'b', 'basis', 'completed', 'dense', 'evals', 'event_evals', 'extra_rows', 'fE', 'fE_out', 'fsal', 'fun', 'hA', 'hA_extra', 'have_extra', 'hb', 'last_dot', 'middle', 'nonnegative', 'norm_control', 'rows_last', 'rtol', 'small_real', 'step', 'threshold', 'weights_T', 'y_row')

    def __init__(self, fun, A, c, E, dense, b, extra, dense_basis, y0, f0, rtol, threshold, norm_control,
                 nonnegative, refine):
        s = c.size
        self.fun, self.A, self.dense, self.basis, self.nonnegative = fun, A, dense, dense_basis, nonnegative
        self.fsal = fsal = b is None
        n = y0.size
        last = s - 1
        nodes = [float(ci) for ci in c]
        R = s if fsal else dense.shape[0]
        W = np.empty((R + 1, n), dtype=y0.dtype)
        self.K = K = W[R - 1::-1]
        W[R] = y0
        self.y_row = W[R]  # the current step's start y: the driver copies an accepted ynew into it
        K[0] = f0
        hAx = np.empty((s, s + 1))
        hAx[:, 0] = 1.0
        self.hA = hAx[:, 1:]
        # (row i of K, c_i, the coefficients, the rows) of each stage computed after the first
        # (an FSAL pair's last stage is f(tnew, ynew), computed apart); writing into a fixed
        # row view is cheaper than K[i] = ...
        self.middle = [(K[i], nodes[i], hAx[i, i::-1].dot, W[None, R - i:]) for i in range(1, last if fsal else s)]
        self.K_first, self.K_fnew = K[0], K[last if fsal else s]  # the next step's first stage is K_fnew
        self.evals = last  # evaluations per attempt
        self.have_extra = not fsal and extra is not None
        if fsal:
            self.last_dot, self.rows_last = hAx[last, last::-1].dot, W[None, R - last:]
        else:
            self.b = np.asarray(b)
            hbx = np.empty(s + 1)
            hbx[0] = 1.0
            self.hb = hbx[1:]
            self.last_dot, self.rows_last = hbx[::-1].dot, W[None, R - s:]
        if self.have_extra:
            self.A_extra, c_extra = extra
            self.hA_extra = np.empty((self.A_extra.shape[0], self.A_extra.shape[1] + 1))
            self.hA_extra[:, 0] = 1.0
            self.extra_rows = [(K[s + 1 + j], float(c_extra[j]), self.hA_extra[j, s + 1 + j::-1].dot,
                                W[None, R - (s + 1 + j):]) for j in range(len(c_extra))]
        self.all_nodes = c if fsal else np.concatenate([c, [1.0], extra[1] if self.have_extra else []])
        # fE = E . K summed for k = 0, 1, ... (numpy's own loop)
        self.E_dot, self.K_main_3d = backwards(E).dot, K[:s][None]
        self.fE_out = np.empty((1, n), dtype=np.result_type(E, y0.dtype))
        self.fE = self.fE_out[0]
        # The error norm max_i |fE_i| / max(|y_i|, |ynew_i|, threshold_i): for a small real
        # system the maximum is taken over a Python list (numpy's reductions cost more than the
        # whole division); both give the same bits.
        self.small_real = not np.iscomplexobj(y0) and n <= _SMALL
        self.rtol, self.threshold, self.norm_control = rtol, threshold, norm_control
        self.completed = True  # whether this step's interpolation stages are in K
        self.event_evals = 0  # evaluations made by completing steps for the events
        self.step = (0.0, self.y_row, 0.0, 0.0)  # (t, y, h, tnew) of the step the extension describes
        if refine > 1:
            # Interior output at s = j/refine: the extension's weights sum_m dense[:, m] s^(m+1)
            # do not depend on the step, so they are formed once (rows kept backwards).
            from odelab.solvers.dense import refine_weights

            fractions = np.arange(1, refine) / refine
            self.weights_T = [backwards(w) for w in refine_weights(fractions, dense, dense_basis)]

    def attempt_function(self):
        """``attempt(t, h, absh, done, tfinal, weight) -> (tnew, h, ynew, err, scale_new)``: one
        attempt from ``(t, y_row)`` with step ``h``, a closure over the step's arrays (the
        driver calls it every attempt: locals, no attribute lookups).

        ``weight`` is ``max(|y|, threshold)`` (or ``||y||`` with norm control); ``scale_new``
        ``|ynew|`` (or ``||ynew||``) for the next step's weight."""
        fun, A, hA, middle, K_first, K_fnew = self.fun, self.A, self.hA, self.middle, self.K_first, self.K_fnew
        last_dot, rows_last, E_dot, K_main_3d, fE_out, fE = (self.last_dot, self.rows_last, self.E_dot,
                                                            self.K_main_3d, self.fE_out, self.fE)
        fsal, norm_control, small_real, threshold = self.fsal, self.norm_control, self.small_real, self.threshold
        b, hb = (None, None) if fsal else (self.b, self.hb)
        multiply, absolute, maximum, nan = np.multiply, np.abs, np.maximum, math.nan

        def attempt(t, h, absh, done, tfinal, weight):
            multiply(A, h, hA)
            if fsal:
                for K_row, ci, stage_dot, rows in middle:
                    K_row[...] = fun(t + ci * h, stage_dot(rows)[0])
                tnew = tfinal if done else t + h  # hit the end point exactly
                h = tnew - t  # purify h
                ynew = last_dot(rows_last)[0]
                K_fnew[...] = fun(tnew, ynew)
            else:  # every stage inside the step; f(tnew, ynew) once the step is accepted
                for K_row, ci, stage_dot, rows in middle:
                    K_row[...] = fun(t + ci * h, stage_dot(rows)[0])
                    K_row -= K_first  # increment form
                tnew = tfinal if done else t + h
                multiply(b, h, hb)  # with the h the stages used, as for hA
                h = tnew - t
                ynew = last_dot(rows_last)[0]
            E_dot(K_main_3d, fE_out)
            if norm_control:
                normynew = float(norm(ynew))
                return tnew, h, ynew, absh * (float(norm(fE)) / max(weight, normynew, float(threshold))), normynew
            absynew = absolute(ynew)
            scale = maximum(weight, absynew)
            if small_real:
                q = (fE / scale).tolist()
                err = absh * max(map(abs, q))
                total = sum(q)
                if total != total:  # a NaN ratio, which max may skip
                    err = nan
            else:
                err = absh * float((absolute(fE) / scale).max())
            return tnew, h, ynew, err, absynew

        return attempt

    def complete(self, t, h) -> int:
        """Evaluate a non-FSAL step's interpolation stages into K (stage ``s+1+j`` is
        ``f(t + c_j h, y + h A_extra[j] . K)``, held as its increment over ``K_0``), for a step
        that is interpolated; returns their number."""
        np.multiply(self.A_extra, h, self.hA_extra[:, 1:])
        K0, fun = self.K[0], self.fun
        for K_row, cj, stage_dot, rows in self.extra_rows:
            K_row[...] = fun(t + cj * h, stage_dot(rows)[0])
            K_row -= K0  # increment form
        self.completed = True
        return len(self.extra_rows)

    def value_at(self, tq):
        """The step's extension at ``tq`` (events), completing a non-FSAL step first."""
        from odelab.solvers.dense import step_value

        t, y, h, _ = self.step
        if not self.completed:
            self.event_evals += self.complete(t, h)
        return step_value(tq, t, y, h, self.K, self.dense, self.nonnegative, self.basis)

    def values(self, times, rows) -> None:
        """The extension at the vector-tspan entries inside the step, into ``rows`` (an entry at
        the step's end is left to the collector: it is the end itself)."""
        from odelab.solvers.dense import step_value

        t, y, h, tnew = self.step
        for j, tn in enumerate(times):
            if tn != tnew:
                rows[j] = step_value(tn, t, y, h, self.K, self.dense, self.nonnegative, self.basis)

    def interior(self, times):
        """The step's interior Refine rows (the weights at s = j/refine are the step's own)."""
        t, y, h, _ = self.step
        return _refine_rows(self.weights_T, h, self.K, y, self.nonnegative)

    def cut(self, t, y, h, t_event) -> None:
        """A terminal event cuts the step at ``t_event``: the stages of [t, te] become the
        extension's slopes at its nodes, as MATLAB does, so output on the shortened step follows
        the same curve."""
        from odelab.solvers.dense import step_slopes

        K = self.K
        K[1:] = step_slopes(t + (t_event - t) * self.all_nodes[1:], t, y, h, K, self.dense, self.nonnegative,
                            self.basis)
        if not self.fsal:
            K[1:] -= K[0]

    def refine_after(self, store, fractions):
        """The Refine output of all steps at once, from the step records (then the step starts are
        read off the output, every refine-th row: the records' copy is dropped)."""
        t_arr, y_arr = _refine_output(store.t, store.y, store.fields[0], fractions, self.weights_T,
                                      self.nonnegative)
        store.y = None
        return t_arr, y_arr


def _initial_step(f0, y0, threshold, rtol, power, norm_control, htry, hmax, tspan) -> float:
    """MATLAB's first step: from ``InitialStep``, or (NaN) from the derivative at t0."""
    t0 = float(tspan[0])
    if htry == htry:
        return given_step(htry, t0, hmax)
    if norm_control:
        rh = (float(norm(f0)) / max(float(norm(y0)), float(threshold))) / (0.8 * rtol**power)
    else:
        rh = float((np.abs(f0) / np.maximum(np.abs(y0), threshold)).max()) / (0.8 * rtol**power)
    return first_step(rh, abs(float(tspan[1]) - t0), hmax, t0)


def integrate_adaptive(fun, tspan: np.ndarray, y0: np.ndarray, f0: np.ndarray, A: np.ndarray, c: np.ndarray,
                       E: np.ndarray, dense: np.ndarray, power: float, shrink_min: float, rtol: float,
                       threshold: np.ndarray, hmax: float, htry: float, refine: int, norm_control: bool,
                       max_steps: int, events=None, v0=None, nonnegative=None, output_fcn=None, b=None, extra=None,
                       dense_basis="monomial") -> DriverResult:
    """Integrate with an embedded Runge-Kutta pair and MATLAB's controller (the parameters are
    described in the module docstring); returns a :class:`~odelab.solvers.output.DriverResult`
    whose ``steps`` are ``(t, h, y, K)`` arrays of every accepted step for dense output (and with
    ``extra`` a fifth: which steps have their extra stages computed, the others are completed on
    demand by :class:`odelab.solvers.dense.StageCompletion`)."""
    fsal = b is None
    t0, tfinal = float(tspan[0]), float(tspan[-1])
    tdir = 1.0 if tfinal > t0 else -1.0
    st = _Stages(fun, A, c, E, dense, b, extra, dense_basis, y0, f0, rtol, threshold, norm_control, nonnegative,
                 refine if tspan.size == 2 else 1)
    K, K_first, K_fnew, y_row, have_extra, attempt = st.K, st.K_first, st.K_fnew, st.y_row, st.have_extra, st.attempt_function()
    evals, maximum = st.evals, np.maximum
    nn = None if nonnegative is None else NonNegative(nonnegative, threshold, norm_control)
    fields = [(K.shape, y0.dtype)] + ([((), bool)] if have_extra else [])
    out = StepOutput(tspan, y0, refine, fields, events, v0, output_fcn, refine_after=st.refine_after)
    per_step, add = out.per_step, out.store.add
    # max(|y|, threshold), the part of the error weight known before the step (or ||y||)
    weight = float(norm(y0)) if norm_control else np.maximum(np.abs(y0), threshold)
    absh = _initial_step(f0, y0, threshold, rtol, power, norm_control, htry, hmax, tspan)
    t, y = t0, y_row
    nsteps = nfailed = nfevals = 0
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
                tnew, h, ynew, err, scale_new = attempt(t, h, absh, done, tfinal, weight)
                nfevals += evals
                nn_reject = False
                if nn is not None and err <= rtol and nn.negative(ynew):
                    # a negative value of a non-negative component counts as error
                    err_nn = (float(norm(nn.excess(ynew))) / max(weight, scale_new, float(threshold)) if norm_control
                              else nn.error(ynew))
                    if err_nn > rtol:
                        err, nn_reject = err_nn, True
                if err > rtol:  # failed attempt
                    nfailed += 1
                    if absh <= hmin:
                        status = Status.STEP_UNDERFLOW
                        break
                    # a negative non-negative component halves the step, as a second failure
                    absh = shrink(absh, hmin, err, rtol, power, shrink_min, 0.8, nofailed and not nn_reject)
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
                st.completed = not have_extra
            # Accepted: clip to the constraint; the interpolant keeps the unclipped stages.
            nn_reset = nn is not None and nn.clip(ynew)
            if nn_reset:
                scale_new = float(norm(ynew)) if norm_control else np.abs(ynew)
            stop = False
            if events is not None or per_step:
                st.step = (t, y, h, tnew)
            if events is not None:
                cut = out.locate(st.value_at, t, y, tnew, ynew)
                if cut is not None:
                    st.cut(t, y, h, cut[0])
                    tnew, ynew = cut
                    h = tnew - t
                    st.step = (t, y, h, tnew)
                    done = stop = True
                    status = Status.TERMINAL_EVENT
            if have_extra and not st.completed and out.interpolates(tnew):
                nfevals += st.complete(t, h)  # the step is interpolated: its extra stages are needed now
            if have_extra:
                add(tnew, ynew, K, st.completed)
            else:
                add(tnew, ynew, K)
            if per_step and out.emit(t, tnew, ynew, stop, st.values, st.interior):
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
            if nofailed:  # no failures in this step: choose the next step from the error estimate
                absh = grow(absh, err, rtol, power, 1.25, 5.0)
            t = tnew
            y_row[...] = ynew  # y is y_row: the rows of the next step's stages
            weight = scale_new if norm_control else maximum(scale_new, threshold)
            if nn_reset:  # the stages interpolated the unclipped solution; go on along the clipped one
                if fsal:
                    K_fnew[...] = fun(tnew, ynew)
                else:
                    fnew = fun(tnew, ynew)
                nfevals += 1
            K_first[...] = K_fnew if fsal else fnew
    except Exception as exc:  # the user's right-hand side (or events function) failed
        status = Status.FUN_RAISED
        exception = exc
    nfevals += st.event_evals
    t_arr, y_arr = out.finish()
    store = out.store
    steps = None
    if store.count:
        step_y = (y_arr[::refine] if tspan.size == 2 else store.y)[:-1]
        steps = (store.t[:-1], np.diff(store.t), step_y, store.fields[0])
        if have_extra:
            steps += (store.fields[1],)
    return DriverResult(t_arr, y_arr, nsteps, nfailed, nfevals, status, t, abs(h), exception, out.found, steps)



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
