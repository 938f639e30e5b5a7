"""What the implicit solvers share: Jacobians, LU factorisations, counters and output.

MATLAB's stiff solvers report, besides steps, failures and function evaluations, the partial
derivatives (Jacobians) formed, the LU decompositions and the linear solves. :class:`Work`
holds those counters and the three operations that produce them:

* :meth:`Work.jacobian` — ``df/dy`` at ``(t, y)``: the user's analytic Jacobian (a matrix or a
  callable), or MATLAB's ``numjac`` (:mod:`odelab.solvers.numjac`: adaptive increments whose
  factors are kept from one Jacobian to the next; one evaluation per column, fewer with a
  ``JPattern`` sparsity pattern by grouping structurally orthogonal columns, one vectorised call
  with ``Vectorized``);
* :meth:`Work.factor` — LU of an iteration matrix ``M - c J`` (dense LAPACK, or SuperLU when a
  sparsity pattern makes the matrix sparse);
* :meth:`Work.solve` — one solve with that factorisation.

:class:`Output` turns accepted steps into MATLAB's output points (``Refine`` points per step
for a two-element ``tspan``, exactly the ``tspan`` times otherwise) from each solver's own
interpolant.
"""

from __future__ import annotations

import math

import numpy as np

from odelab.solvers.controller import first_step, given_step

__all__ = ["Work", "Output", "rms_or_max", "initial_step", "newton", "rate_test", "Newton",
           "QuadraticSteps", "quadratic_through"]

EPS = float(np.finfo(float).eps)
SQRT_EPS = math.sqrt(EPS)


class Work:
    """The right-hand side, the Jacobian source and MATLAB's cost counters for one solve."""

    def __init__(self, fun, n: int, *, jacobian=None, jpattern=None, vectorized: bool = False, mass=None):
        self.fun = fun
        self.n = n
        self.vectorized = vectorized
        self.nfevals = 0
        self.npds = 0
        self.ndecomps = 0
        self.nsolves = 0
        self.sparse = jpattern is not None
        self._jac = jacobian
        self._groups = None
        self.fac = None  # numjac's increment factors, carried from one Jacobian to the next
        if jpattern is not None:
            from scipy import sparse

            from odelab.solvers.numjac import column_groups

            self.pattern = sparse.csc_matrix(jpattern, dtype=bool)
            self.pattern.eliminate_zeros()
            self._groups = column_groups(self.pattern)
        if mass is None:
            self.mass = None
        else:
            self.mass = mass
        self.identity = self._identity()
        self.dense = None  # a solver with dense output leaves its DenseOutput here
        self.found = ([], [], [])  # the events located (te, ye, ie), left here by the solver

    def _identity(self):
        if self.sparse:
            from scipy import sparse

            return sparse.identity(self.n, format="csc")
        return np.eye(self.n)

    @property
    def M(self):
        """The mass matrix (the identity when there is none)."""
        return self.identity if self.mass is None else self.mass

    def f(self, t: float, y: np.ndarray) -> np.ndarray:
        self.nfevals += 1
        return np.asarray(self.fun(t, y), dtype=float).reshape(self.n)

    # --- Jacobian -------------------------------------------------------------------------

    def jacobian(self, t: float, y: np.ndarray, fy, threshold):
        """``df/dy`` at ``(t, y)``; ``fy = f(t, y)`` (or None: evaluated here) serves the differences.

        Without an analytic Jacobian this is MATLAB's ``numjac``
        (:func:`odelab.solvers.numjac.numjac`) with ``thresh = threshold`` (the solvers pass
        ``AbsTol``, as MATLAB's do); its increment factors ``fac`` are kept here from one
        Jacobian to the next, and its evaluations count in ``nfevals``."""
        self.npds += 1
        jac = self._jac
        if jac is not None:
            value = jac(t, y) if callable(jac) else jac
            if self.sparse:
                from scipy import sparse

                return sparse.csc_matrix(value, dtype=float)
            return np.asarray(value, dtype=float).reshape(self.n, self.n)
        if fy is None:
            fy = self.f(t, y)
        from odelab.solvers.numjac import numjac

        result = numjac(self.fun, t, y, fy, threshold, self.fac, vectorized=self.vectorized,
                        pattern=self.pattern if self.sparse else None, groups=self._groups)
        self.fac = result.fac
        self.nfevals += result.nfevals
        return result.dfdy

    # --- linear algebra ---------------------------------------------------------------------

    def factor(self, matrix):
        """LU-factor an iteration matrix (counted as one decomposition)."""
        self.ndecomps += 1
        if self.sparse:
            from scipy.sparse.linalg import splu

            return ("sparse", splu(matrix.tocsc()))
        from scipy.linalg import lu_factor

        return ("dense", lu_factor(matrix, check_finite=False))

    def solve(self, lu, rhs: np.ndarray) -> np.ndarray:
        """Solve with a factorisation from :meth:`factor` (counted as one linear solve)."""
        self.nsolves += 1
        kind, fac = lu
        if kind == "sparse":
            return fac.solve(rhs)
        from scipy.linalg import lu_solve

        return lu_solve(fac, rhs, check_finite=False)

    def mass_times(self, v: np.ndarray) -> np.ndarray:
        return v if self.mass is None else self.mass @ v


def rms_or_max(v: np.ndarray, scale: np.ndarray) -> float:
    """MATLAB's error norm: the max norm of ``v / scale``."""
    return float(np.max(np.abs(v) / scale)) if v.size else 0.0


def initial_step(f0, y0, threshold, rtol, power, hmax, htspan, t0, htry, normcontrol=False):
    """MATLAB's first step from ``y'(t0)``: ``1 / (||f0 / wt|| / (0.8 rtol^power))``, capped
    (:func:`odelab.solvers.controller.first_step`)."""
    if htry == htry:  # given
        return given_step(htry, t0, hmax)
    if normcontrol:
        rh = (float(np.linalg.norm(f0)) / max(float(np.linalg.norm(y0)), float(np.max(threshold)))) / (0.8 * rtol**power)
    else:
        rh = float(np.max(np.abs(f0) / np.maximum(np.abs(y0), threshold))) / (0.8 * rtol**power)
    return first_step(rh, htspan, hmax, t0)


class Newton:
    """The simplified Newton iteration's memory across steps: the last observed rate of convergence."""

    __slots__ = ("rate", "havrate")

    def __init__(self):
        self.rate = 0.0
        self.havrate = False


MAX_NEWTON = 4


def newton(work: "Work", lu, residual, z: np.ndarray, scale: float, wt: np.ndarray, rtol: float, memory: Newton,
           minnrm: float | None = None):
    """Solve ``residual(z) = 0`` by simplified Newton with the factorisation ``lu`` of its matrix.

    Each iteration is one evaluation (in ``residual``) and one linear solve:
    ``z += lu \\ residual(z)``. The change in the solution is ``scale * dz``; convergence is
    judged as ode15s judges it (Shampine & Reichelt 1997, Section 2.3): from the observed rate
    ``rho`` the remaining error ``||dy|| rho / (1 - rho)`` must fall below ``rtol / 2`` (``0.05
    rtol`` on the first iteration, with the rate kept from earlier steps), at most
    :data:`MAX_NEWTON` iterations, and the iteration is abandoned as soon as it diverges
    (``||dy||`` not shrinking by 0.9) or cannot converge in the iterations left.

    Returns ``(z, converged)``; ``memory`` carries the rate to the next call. ``minnrm``: the
    change below which the iteration has converged outright (default ``100 eps`` of the
    starting guess's weighted size; ode15s measures it on the step's starting state).
    """
    if minnrm is None:
        minnrm = 100 * EPS * float(np.max(np.abs(z) * abs(scale) / wt)) if z.size else 0.0
    oldnrm = 0.0
    for it in range(1, MAX_NEWTON + 1):
        dz = work.solve(lu, residual(z))
        z = z + dz
        newnrm = abs(scale) * float(np.max(np.abs(dz) / wt))
        verdict = rate_test(it, newnrm, oldnrm, minnrm, memory, rtol, MAX_NEWTON)
        if verdict is not None:
            return z, verdict
        oldnrm = newnrm
    return z, False


def rate_test(it: int, newnrm: float, oldnrm: float, minnrm: float, memory: Newton, rtol: float, max_iter: int):
    """The convergence test of MATLAB's simplified Newton iterations after iteration ``it``
    (Shampine & Reichelt 1997, Section 2.3), with ``newnrm`` the weighted size of its change:
    True (converged), False (diverging, or it cannot converge in the iterations left) or None
    (iterate again). ``memory`` keeps the observed rate for the next call."""
    if not math.isfinite(newnrm):
        return False
    if newnrm <= minnrm:
        return True
    if it == 1:
        if memory.havrate:
            if newnrm * memory.rate / (1 - memory.rate) <= 0.05 * rtol:
                return True
        else:
            memory.rate = 0.0
        return None
    if newnrm > 0.9 * oldnrm:
        return False
    memory.rate = max(0.9 * memory.rate, newnrm / oldnrm)
    memory.havrate = True
    errit = newnrm * memory.rate / (1 - memory.rate)
    if errit <= 0.5 * rtol:
        return True
    if it == max_iter or 0.5 * rtol < errit * memory.rate ** (max_iter - it):
        return False
    return None


def consistent_slope(work: "Work", t: float, y: np.ndarray, f0: np.ndarray, J) -> np.ndarray:
    """``y'(t)`` from ``M y' = f``: ``M^-1 f`` for a nonsingular (or no) mass matrix.

    For a singular ``M`` (an index-1 DAE) the algebraic equations ``u^T f = 0`` (``u`` spanning
    the left null space of ``M``) are differentiated, ``u^T (f_t + J y') = 0``, and solved
    together with ``M y' = f``: the slope of the algebraic states is then consistent, which the
    trapezoidal rule needs because it carries the slope from step to step (it never damps an
    error in it). ``f_t`` is one forward difference (one evaluation).
    """
    if work.mass is None:
        return f0
    M = work.mass.toarray() if hasattr(work.mass, "toarray") else np.asarray(work.mass, dtype=float)
    U, s, _ = np.linalg.svd(M)
    rank = int(np.sum(s > s[0] * work.n * EPS)) if s.size and s[0] > 0 else 0
    if rank == work.n:
        return np.linalg.solve(M, f0)
    null = U[:, rank:]
    tdel = SQRT_EPS * max(abs(t), 1.0)
    ft = (work.f(t + tdel, y) - f0) / tdel
    Jd = J.toarray() if hasattr(J, "toarray") else np.asarray(J)
    A = np.vstack([M, null.T @ Jd])
    b = np.concatenate([f0, -(null.T @ ft)])
    return np.linalg.lstsq(A, b, rcond=None)[0]


class Output:
    """Collect MATLAB's output points from accepted steps and a per-step interpolant, and locate
    events (MATLAB's ``Events``) on that interpolant with :func:`odelab.solvers.events.locate_events`.

    ``events`` is ``(ev, v0)`` from :func:`~odelab.solvers.events.as_event_function` (or None).
    A terminal event cuts the step at the event: the output ends there (``Refine`` points spread
    over the cut step, the event's point appended, as MATLAB outputs it) and :meth:`step`
    returns True; the solver then stops with ``t, y = out.t[-1], out.y[-1]``.
    """

    def __init__(self, tspan: np.ndarray, y0: np.ndarray, refine: int, events=None, nonnegative=None):
        self.nonnegative = nonnegative  # odelab.solvers.output.NonNegative: interpolated values clipped at 0
        self.tspan = tspan
        self.every_step = tspan.size == 2
        self.refine = refine
        self.tdir = 1.0 if tspan[-1] > tspan[0] else -1.0
        self.t = [float(tspan[0])]
        self.y = [y0.copy()]
        self.next = 1
        self.events, self.v = events if events is not None else (None, None)
        self.t0 = float(tspan[0])
        self.y_left = y0.copy()  # the state at the start of the next step (event brackets)
        self.te: list[float] = []
        self.ye: list[np.ndarray] = []
        self.ie: list[int] = []

    def step(self, t: float, tnew: float, ynew: np.ndarray, interp) -> bool:
        """Record the step ``t -> tnew``; ``interp(times)`` returns states (len(times), n).

        Returns True when a terminal event stopped the integration inside the step."""
        if self.nonnegative is not None:
            interp = _clipped(interp, self.nonnegative.idx)
        stop = False
        if self.events is not None:
            from odelab.solvers.events import locate_events

            found_t, found_y, found_i, self.v, stop = locate_events(
                lambda tq: interp(np.array([tq]))[0], self.events, self.v, t, self.y_left, tnew, ynew, self.t0)
            self.y_left = ynew.copy()
            if found_t:
                self.te.extend(found_t)
                self.ye.extend(np.array(v, dtype=float) for v in found_y)
                self.ie.extend(found_i)
                if stop:
                    tnew, ynew = found_t[-1], np.asarray(found_y[-1], dtype=float)
        self._record(t, tnew, ynew, interp)
        if stop and self.t[-1] != tnew:  # MATLAB outputs the terminal event's point
            self.t.append(tnew)
            self.y.append(ynew.copy())
        return stop

    def _record(self, t: float, tnew: float, ynew: np.ndarray, interp) -> None:
        if self.every_step:
            if self.refine > 1:
                times = t + (tnew - t) * np.arange(1, self.refine) / self.refine
                self.t.extend(times.tolist())
                self.y.extend(interp(times))
            self.t.append(tnew)
            self.y.append(ynew.copy())
            return
        start = self.next
        while self.next < self.tspan.size and self.tdir * (tnew - self.tspan[self.next]) >= 0:
            self.next += 1
        if self.next == start:
            return
        times = self.tspan[start:self.next]
        inside = times != tnew
        values = np.empty((times.size, ynew.size))
        values[~inside] = ynew
        if inside.any():
            values[inside] = interp(times[inside])
        self.t.extend(times.tolist())
        self.y.extend(values)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.t), np.vstack(self.y)

    def found(self) -> tuple[list[float], list[np.ndarray], list[int]]:
        """The events located: ``(te, ye, ie)`` in the order found (0-based indices)."""
        return self.te, self.ye, self.ie


def _clipped(interp, idx):
    """``interp`` with its values' listed components clipped at 0 (MATLAB's NonNegative output)."""
    from odelab.solvers.dense import clip_nonnegative

    return lambda times: clip_nonnegative(np.array(interp(times), dtype=float), idx)


class QuadraticSteps:
    """Accepted steps whose interpolant is a quadratic in ``s = (t - t_n)/h``:
    ``y_n + s a1 + s^2 a2`` (ode23t, ode23tb). Serves :class:`Output` step by step and, at the
    end, ``deval``/``sol(t)`` as a :class:`~odelab.solvers.dense.DenseOutput` (coefficients the
    identity on ``K = (a1/h, a2/h)``).
    """

    def __init__(self):
        self.t: list[float] = []
        self.h: list[float] = []
        self.y: list[np.ndarray] = []
        self.K: list[np.ndarray] = []

    def add(self, t: float, h: float, y: np.ndarray, a1: np.ndarray, a2: np.ndarray):
        """Record the step and return its interpolant ``times -> states`` (len(times), n)."""
        self.t.append(t)
        self.h.append(h)
        self.y.append(y)
        self.K.append(np.stack([a1 / h, a2 / h]))

        def interp(times):
            s = (np.asarray(times, dtype=float)[:, None] - t) / h
            return y + s * a1 + (s * s) * a2

        return interp

    def cut(self, tend: float) -> None:
        """End the last step at ``tend`` (a terminal event): the same quadratic on ``[t_n, tend]``."""
        r = (tend - self.t[-1]) / self.h[-1]
        self.h[-1] = tend - self.t[-1]
        self.K[-1] = np.stack([self.K[-1][0], self.K[-1][1] * r])

    def dense(self, y_final: np.ndarray, nonnegative=None):
        if not self.t:
            return None
        from odelab.solvers.dense import DenseOutput

        return DenseOutput(t=np.array(self.t), h=np.array(self.h), y=np.vstack(self.y), K=np.stack(self.K),
                           coefficients=np.eye(2), y_final=y_final.copy(),
                           nonnegative=None if nonnegative is None else nonnegative.idx)


def quadratic_through(rho: float, y: np.ndarray, y_rho: np.ndarray, ynew: np.ndarray):
    """``(a1, a2)`` of the quadratic ``y + s a1 + s^2 a2`` through ``y`` (s = 0), ``y_rho``
    (s = rho) and ``ynew`` (s = 1)."""
    d1 = ynew - y
    a2 = ((y_rho - y) - rho * d1) / (rho * rho - rho)
    return d1 - a2, a2
