"""What the implicit solvers share: Jacobians, LU factorisations, counters and output.

MATLAB's stiff solvers report, besides steps, failures and function evaluations, the partial
derivatives (Jacobians) formed, the LU decompositions and the linear solves. :class:`Work`
holds those counters and the three operations that produce them:

* :meth:`Work.jacobian` — ``df/dy`` at ``(t, y)``: the user's analytic Jacobian (a matrix or a
  callable), or MATLAB's ``numjac`` (:mod:`odelab.solvers.numjac`: adaptive increments whose
  factors are kept from one Jacobian to the next; one evaluation per column, fewer with a
  ``JPattern`` sparsity pattern by grouping structurally orthogonal columns, one vectorised call
  with ``Vectorized``);
* :meth:`Work.factor` — LU of an iteration matrix ``M - c J`` (:mod:`odelab.solvers.lu`'s
  fixed-order LU up to ``lu.SMALL`` states, the same bits on every machine; dense LAPACK
  above; SuperLU when a
  ``JPattern`` makes the matrix sparse; LAPACK's banded LU of the matrix permuted to a narrow
  band when the Jacobian is an expression system's exact one, whose structure is known from
  its equations (``jacobian.pattern``), and :func:`odelab.solvers.banded.plan_band` finds that
  band narrow enough: the compiled loops make the same choice, see :mod:`odelab.solvers.banded`);
* :meth:`Work.solve` — one solve with that factorisation.

The output points, events and step records are the collector's every driver shares
(:class:`odelab.solvers.output.StepOutput`, fed by :mod:`odelab.solvers.implicit.driver`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from odelab.solvers import lu as _small
from odelab.solvers.controller import first_step, given_step
from odelab.solvers.dense import DenseOutput
from odelab.solvers.ordered import matvec, norm

__all__ = ["Work", "rms_or_max", "initial_step", "jacobian_times", "newton", "rate_test", "Newton",
           "QuadraticSteps", "QuadraticRecords", "quadratic_through"]

EPS = float(np.finfo(float).eps)
SQRT_EPS = math.sqrt(EPS)
_max = np.maximum.reduce  # ndarray.max() without its Python layer (the same reduction)


@functools.cache
def _lapack_lu(dtype):
    """LAPACK's ``getrf`` and ``getrs`` for ``dtype``: what ``scipy.linalg.lu_factor`` and
    ``lu_solve`` call, called directly (the same values bit for bit): their wrappers cost
    10-25 us a call (lu_factor 11.5 us against getrf's 1.1 on a 3-by-3, lu_solve 27 against
    getrs's 2.2), more than the factorisation or the solve on the small systems stiff problems
    mostly are."""
    from scipy.linalg import get_lapack_funcs

    return get_lapack_funcs(("getrf", "getrs"), dtype=dtype)


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
        self.band = None  # an odelab.solvers.banded.Band when the iteration matrices factor banded
        structure = getattr(jacobian, "pattern", None)  # an expression system's exact Jacobian knows it
        if structure is not None and jpattern is None and mass is None:
            from odelab.solvers.banded import MIN_STATES, plan_band

            self.band = plan_band(structure()) if n >= MIN_STATES else None
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
        if self.band is not None:
            return ("banded", self.band.factor(matrix))
        if self.sparse:
            from scipy.sparse.linalg import splu

            return ("sparse", splu(matrix.tocsc()))
        matrix = np.asarray(matrix)
        if matrix.shape[0] <= _small.SMALL:  # the same bits on every machine (odelab.solvers.lu)
            return ("ordered", _small.factor(matrix))
        factors, piv, _info = _lapack_lu(matrix.dtype)[0](matrix)  # info > 0 (singular): Newton fails and says so
        return ("dense", (factors, piv))

    def solve(self, lu, rhs: np.ndarray) -> np.ndarray:
        """Solve with a factorisation from :meth:`factor` (counted as one linear solve)."""
        self.nsolves += 1
        kind, fac = lu
        if kind == "ordered":
            return _small.solve(fac, rhs)
        if kind == "sparse":
            return fac.solve(rhs)
        if kind == "banded":
            return self.band.solve(fac, rhs)
        lu, piv = fac
        x, _info = _lapack_lu(np.result_type(lu, rhs))[1](lu, piv, rhs)
        return x

    def mass_times(self, v: np.ndarray) -> np.ndarray:
        return v if self.mass is None else jacobian_times(self.mass, v)


def jacobian_times(A, v: np.ndarray) -> np.ndarray:
    """``A @ v`` for a Jacobian or mass matrix: a dense one summed in index order without BLAS
    (:func:`odelab.solvers.ordered.matvec`, the compiled loops' order, so the product does not
    depend on the machine's BLAS kernel); a sparse one by SciPy's own loop (row by row)."""
    if hasattr(A, "tocsr"):
        return A @ v
    return matvec(A, v)


def rms_or_max(v: np.ndarray, scale: np.ndarray) -> float:
    """MATLAB's error norm: the max norm of ``v / scale``."""
    return float(np.max(np.abs(v) / scale)) if v.size else 0.0


def initial_step(f0, y0, threshold, rtol, power, hmax, htspan, t0, htry, normcontrol=False):
    """MATLAB's first step from ``y'(t0)``: ``1 / (||f0 / wt|| / (0.8 rtol^power))``, capped
    (:func:`odelab.solvers.controller.first_step`)."""
    if htry == htry:  # given
        return given_step(htry, t0, hmax)
    if normcontrol:
        rh = (norm(f0) / max(norm(y0), float(np.max(threshold)))) / (0.8 * rtol**power)
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
        minnrm = 100 * EPS * float((np.abs(z) * abs(scale) / wt).max()) if z.size else 0.0
    oldnrm = 0.0
    solve, scale = work.solve, abs(scale)
    for it in range(1, MAX_NEWTON + 1):
        dz = solve(lu, residual(z))
        z = z + dz
        newnrm = scale * float(_max(np.abs(dz) / wt))
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


class QuadraticSteps:
    """Accepted steps whose interpolant is a quadratic in ``s = (t - t_n)/h``:
    ``y_n + s a1 + s^2 a2`` (ode23t, ode23tb). Each step's record is ``K = (a1/h, a2/h)``, one row
    of the collector's :class:`~odelab.solvers.output.StepStore` (field :attr:`fields`); at the
    end the store serves ``deval``/``sol(t)`` as a :class:`~odelab.solvers.dense.DenseOutput`
    (coefficients the identity on ``K``).
    """

    def __init__(self, n: int):
        self.fields = (((2, n), float),)
        self.rows = ()
        self._t = self._h = None

    def add(self, t: float, h: float, y: np.ndarray, a1: np.ndarray, a2: np.ndarray):
        """Make the step's record (:attr:`rows`) and return its interpolant ``times -> states``
        (len(times), n)."""
        self._t, self._h = t, h
        self.rows = (np.stack([a1 / h, a2 / h]),)

        def interp(times):
            s = (np.asarray(times, dtype=float)[:, None] - t) / h
            return y + s * a1 + (s * s) * a2

        return interp

    def cut(self, tend: float) -> None:
        """End the last step at ``tend`` (a terminal event): the same quadratic on ``[t_n, tend]``."""
        r = (tend - self._t) / self._h
        K = self.rows[0]
        self.rows = (np.stack([K[0], K[1] * r]),)

    @staticmethod
    def dense(store, y_final: np.ndarray, nonnegative=None):
        """The steps' dense output from the collector's store (its steps' starts, sizes and ``K``)."""
        if not store.count:
            return None

        return DenseOutput(t=store.t[:-1].copy(), h=np.diff(store.t), y=store.y[:-1].copy(), K=store.fields[0].copy(),
                           coefficients=np.eye(2), y_final=y_final.copy(),
                           nonnegative=None if nonnegative is None else nonnegative.idx)


class QuadraticRecords:
    """A :class:`~odelab.solvers.implicit.driver.Stepper` mixin for methods whose steps are
    :class:`QuadraticSteps` (``self.steps``): the records the collector stores, the cut at a
    terminal event and ``deval``."""

    @property
    def fields(self):
        return self.steps.fields

    @property
    def rows(self):
        return self.steps.rows

    def cut(self, t):
        self.steps.cut(t)

    def dense(self, y_final, store):
        return self.steps.dense(store, y_final, self.nn)


def quadratic_through(rho: float, y: np.ndarray, y_rho: np.ndarray, ynew: np.ndarray):
    """``(a1, a2)`` of the quadratic ``y + s a1 + s^2 a2`` through ``y`` (s = 0), ``y_rho``
    (s = rho) and ``ynew`` (s = 1)."""
    d1 = ynew - y
    a2 = ((y_rho - y) - rho * d1) / (rho * rho - rho)
    return d1 - a2, a2
