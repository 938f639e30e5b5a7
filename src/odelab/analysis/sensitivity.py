"""Forward sensitivities ``S = dx/dp`` of an ODE's solution to its parameters.

For ``x' = f(t, x, p)``, ``x(t0) = x0(p)``, the sensitivities obey the variational equations

    S' = J_x(t, x, p) S + J_p(t, x, p),    S(t0) = dx0/dp,

integrated together with the states (the "forward" or "staggered-direct-free" method, as
CVODES's simultaneous corrector: Hindmarsh et al., ACM TOMS 31(3), 2005). Column k of the
right-hand side is the directional derivative of ``f`` along ``(S_k, e_k)``, which one
complex-step evaluation gives exactly (Squire & Trapp, SIAM Review 40(1), 1998):

    J_x S_k + J_p e_k = Im f(t, x + i h S_k, p + i h e_k) / h,    h = 1e-200,

with no subtraction and so no truncation error: all m columns (and ``f`` itself, the real
part) come from one vectorised call of the complex-step compilation of the equations.
The augmented system ``(x, S)`` is integrated by one solver with one error norm over states
and sensitivities, so the sensitivities are as accurate as the solver's tolerances make them
(full error control).

Everything here is arrays in, arrays out: the experiment layer (``experiment/fit.py``) builds
the complex-capable functions from an experiment file.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

from odelab.exceptions import SolverWarning
from odelab.solvers.registry import SENSITIVITY_METHOD

__all__ = ["ParametricModel", "SensitivitySolution", "solve_sensitivities", "observe", "STEP"]

STEP = 1e-200
"""The complex step: any tiny h works, as nothing is subtracted."""


@dataclass(frozen=True)
class ParametricModel:
    """``x' = rhs(t, X, P)``, ``x(t0) = initial(P)``, with complex, broadcasting arguments.

    ``rhs(t, X, P, piece)`` takes a real time, states ``X`` of shape ``(n, m)`` and parameters
    ``P`` of shape ``(np, m)`` (m evaluation points at once, complex) and returns ``(n, m)``;
    ``piece = (lo, hi)`` is the window of times the inputs are read in, so that at a
    breakpoint they keep the value of the piece being integrated (as :func:`odelab.simulate`
    reads them). ``initial(P)`` takes ``(np, m)`` and returns ``(n, m)``. ``breakpoints`` are
    times where the right-hand side jumps (input steps): the integration restarts there.
    """

    states: tuple[str, ...]
    parameters: tuple[str, ...]
    rhs: Callable
    initial: Callable
    breakpoints: tuple[float, ...] = ()


@dataclass(frozen=True)
class SensitivitySolution:
    """States ``x`` (k, n) and sensitivities ``S`` (k, n, m) at the requested times ``t`` (k,)."""

    t: np.ndarray
    x: np.ndarray
    S: np.ndarray
    nsteps: int
    nfevals: int
    status: str = "success"
    message: str = ""


def _directions(p: np.ndarray) -> np.ndarray:
    """``p + i h e_k`` for every k: shape (np, np), column k perturbs parameter k."""
    m = p.size
    return p[:, None] + 1j * STEP * np.eye(m)


def initial_sensitivities(model: ParametricModel, p) -> tuple[np.ndarray, np.ndarray]:
    """``x0(p)`` (n,) and ``dx0/dp`` (n, m) by complex step."""
    p = np.asarray(p, dtype=float)
    out = np.asarray(model.initial(_directions(p)), dtype=complex)
    out = np.broadcast_to(out, (len(model.states), p.size))
    return out.real[:, 0].copy(), out.imag / STEP


def augmented_rhs(model: ParametricModel, p, piece: tuple[float, float] = (-math.inf, math.inf)) -> Callable:
    """The right-hand side of ``(x, vec(S))``: the states and the variational equations."""
    p = np.asarray(p, dtype=float)
    n, m = len(model.states), p.size
    P = _directions(p)

    def fun(t, z):
        x = z[:n]
        S = z[n:].reshape(n, m)
        F = np.asarray(model.rhs(t, x[:, None] + 1j * STEP * S, P, piece), dtype=complex)
        F = np.broadcast_to(F, (n, m))
        out = np.empty(n + n * m)
        out[:n] = F.real[:, 0]
        out[n:] = (F.imag / STEP).ravel()
        return out

    return fun


def solve_sensitivities(model: ParametricModel, p, times, *, t0: float, tf: float, method: str = SENSITIVITY_METHOD,
                        rtol: float = 1e-10, atol: float = 1e-12, max_steps: int | None = None
                        ) -> SensitivitySolution:
    """Integrate the states and their sensitivities from ``t0`` to ``tf``; return them at ``times``.

    ``times`` must lie in ``[t0, tf]`` (never extrapolated) and increase; the values there
    come from the solver's own output at a vector tspan (its interpolant, as MATLAB's
    ``deval``). The span is cut at the model's breakpoints and the solver restarted there.
    """
    from odelab.solvers.api import solve

    p = np.asarray(p, dtype=float)
    times = np.asarray(times, dtype=float)
    n, m = len(model.states), p.size
    if times.size and (times[0] < min(t0, tf) or times[-1] > max(t0, tf)):
        raise ValueError(f"sensitivities are asked for at t = {times[0]:g}..{times[-1]:g}, outside the span "
                         f"[{t0:g}, {tf:g}]; they are never extrapolated")
    x0, S0 = initial_sensitivities(model, p)
    cuts = sorted(c for c in set(model.breakpoints) if t0 < c < tf)
    edges = [t0, *cuts, tf]
    z = np.concatenate([x0, S0.ravel()])
    X = np.full((times.size, n), np.nan)
    SS = np.full((times.size, n, m), np.nan)
    nsteps = nfevals = 0
    options = {"rtol": rtol, "atol": atol}
    if max_steps:
        options["max_steps"] = max_steps
    for i in range(len(edges) - 1):
        a, b = edges[i], edges[i + 1]
        last = i == len(edges) - 2
        # a time on a breakpoint is read from the piece after it (the inputs' value from there on)
        inside = (times >= a) & ((times <= b) if last else (times < b))
        grid = np.unique(np.concatenate([[a], times[inside], [b]]))
        # the inputs on this piece's side of its breakpoints (never the next piece's value at b)
        fun = augmented_rhs(model, p, (a if i > 0 else -math.inf, float(np.nextafter(b, -math.inf)) if not last
                                       else math.inf))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SolverWarning)
            sol = solve(fun, grid if grid.size > 2 else np.array([a, b]), z, method=method, **options)
        nsteps += sol.stats.nsteps
        nfevals += sol.stats.nfevals
        if sol.status != "success":
            return SensitivitySolution(times, X, SS, nsteps, nfevals, "failed", sol.message)
        rows = np.searchsorted(sol.t, times[inside])
        if grid.size == 2 and times[inside].size:  # times only at the piece's ends: natural output
            rows = np.array([0 if tt == a else sol.t.size - 1 for tt in times[inside]])
        Z = sol.y[rows]
        X[inside] = Z[:, :n]
        SS[inside] = Z[:, n:].reshape(-1, n, m)
        z = sol.y[-1]
    return SensitivitySolution(times, X, SS, nsteps, nfevals, "success", "")


def observe(g: Callable, t: np.ndarray, x: np.ndarray, S: np.ndarray, p) -> tuple[np.ndarray, np.ndarray]:
    """Quantities ``y = g(t, X, P)`` and their sensitivities ``dy/dp = g_x S + g_p`` at the times t.

    ``g(t, X, P)`` takes t (k, 1), X (n, k, m) and P (np, 1, m) (complex, broadcasting) and
    returns (nq, k, m). Returns y (k, nq) and dy/dp (k, nq, m).
    """
    p = np.asarray(p, dtype=float)
    m = p.size
    X = x.T[:, :, None] + 1j * STEP * np.moveaxis(S, 0, 1)  # (n, k, m)
    P = _directions(p)[:, None, :]  # (np, 1, m)
    out = np.asarray(g(np.asarray(t, dtype=float)[:, None], X, P), dtype=complex)
    out = np.broadcast_to(out, (out.shape[0], t.size, m))
    return out.real[:, :, 0].T.copy(), np.moveaxis(out.imag / STEP, 0, 1)

