"""Operating points: :class:`OperatingPoint`, :func:`operating_point` and equilibrium solving."""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from odelab.analysis.linearize._system import _check_system, _f, _names, _point_text
from odelab.analysis.linearize.jacobian import _jacobian_block
from odelab.exceptions import InputError
from odelab.systems.nonlinear import as_vector

#: Default bound on max |f(x̄, ū)| for a point to count as an equilibrium.
EQUILIBRIUM_TOL = 1e-10


class NoEquilibriumError(InputError):
    """No equilibrium f(x̄, ū) = 0 was found for the given input."""


class NotAnEquilibriumWarning(UserWarning):
    """A point given as an operating point does not satisfy f(x̄, ū) = 0."""


# ---------------------------------------------------------------------------------------
# Operating points
# ---------------------------------------------------------------------------------------


def _frozen(a) -> np.ndarray:
    out = np.array(a, dtype=float).reshape(-1)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class OperatingPoint:
    """An operating point (x̄, ū, ȳ) of a system, at time ``t``.

    Attributes
    ----------
    x, u, y
        The state, input and output there, shapes (nx,), (nu,), (ny,); read-only.
    residual
        max |f(t, x̄, ū)|: 0 up to rounding at an equilibrium.
    t
        The time at which f was evaluated (matters only for time-varying systems).
    states, inputs, outputs
        The names of the entries of x, u and y.
    """

    x: np.ndarray
    u: np.ndarray
    y: np.ndarray
    residual: float
    t: float = 0.0
    states: tuple[str, ...] = ()
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()

    def __post_init__(self):
        for name in ("x", "u", "y"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        object.__setattr__(self, "residual", float(self.residual))
        object.__setattr__(self, "t", float(self.t))
        for name in ("states", "inputs", "outputs"):
            object.__setattr__(self, name, tuple(getattr(self, name)))

    def is_equilibrium(self, tol: float = EQUILIBRIUM_TOL) -> bool:
        """Whether ``residual <= tol``."""
        return self.residual <= tol

    def as_dict(self) -> dict:
        """``{"x": {name: value}, "u": {...}, "y": {...}, "residual": r, "t": t}``."""
        return {
            "x": dict(zip(self.states, self.x.tolist())),
            "u": dict(zip(self.inputs, self.u.tolist())),
            "y": dict(zip(self.outputs, self.y.tolist())),
            "residual": self.residual,
            "t": self.t,
        }

    def __repr__(self) -> str:
        def named(names, values):
            return ", ".join(f"{n}={v:.10g}" for n, v in zip(names, values))

        return (
            f"OperatingPoint(x: {named(self.states, self.x)}; u: {named(self.inputs, self.u)}; "
            f"y: {named(self.outputs, self.y)}; residual={self.residual:.3g})"
        )


def operating_point(
    system,
    *,
    u0,
    x_guess=None,
    fixed: Mapping[str, float] | None = None,
    free_inputs: Sequence[str] = (),
    t: float = 0.0,
    tol: float = EQUILIBRIUM_TOL,
) -> OperatingPoint:
    """Find an equilibrium x̄ with f(t, x̄, ū) = 0 for the input ``u0``.

    Parameters
    ----------
    system
        A :class:`~odelab.systems.nonlinear.NonlinearSystem` or
        :class:`~odelab.systems.statespace.StateSpace`.
    u0
        The input ū: a number (one input), a sequence, or a mapping name -> value.
    x_guess
        Where the search starts (default: zeros). A mapping may name only some states; the
        others start at 0. With several equilibria, this chooses which one is found.
    fixed
        States held at given values, e.g. ``{"x": 0.5}``; the others are solved for. With
        more equations than unknowns the result is a least-squares point, accepted only if
        its residual is within ``tol``.
    free_inputs
        Inputs solved for instead of held at ``u0`` (which is then their starting guess):
        with ``fixed={"x": 0.5}, free_inputs=["f"]`` this finds the force f̄ that holds the
        mass at x̄ = 0.5, the lab's question read backwards.
    t
        Time at which f is evaluated.
    tol
        Largest accepted residual max |f(t, x̄, ū)|.

    Returns
    -------
    OperatingPoint

    Raises
    ------
    NoEquilibriumError
        (an :class:`~odelab.exceptions.InputError`) when no point with residual within
        ``tol`` is found; the message gives the best point and residual and what to try.

    Notes
    -----
    Solved with :func:`scipy.optimize.root`, MINPACK's Powell hybrid method (``hybr``)
    first and Levenberg-Marquardt (``lm``) as a fallback, both with the exact Jacobian of
    :func:`jacobians`, then polished by Newton steps so the residual reaches rounding level.
    """
    _check_system(system)
    states, inputs = _names(system, "states"), _names(system, "inputs")
    nx = len(states)
    u = as_vector(np.zeros(len(inputs)) if u0 is None else u0, inputs, "u0", word="input")
    x = np.zeros(nx)
    if x_guess is not None:
        if isinstance(x_guess, Mapping):
            unknown = [k for k in x_guess if k not in states]
            if unknown:
                raise InputError(f"`x_guess` names unknown states {unknown}; the states are {list(states)}.", key="x_guess")
            for k, v in x_guess.items():
                x[states.index(k)] = float(v)
        else:
            x = as_vector(x_guess, states, "x_guess", word="state")
    fixed = dict(fixed or {})
    for k, v in fixed.items():
        if k not in states:
            raise InputError(f"`fixed` names {k!r}, which is not a state; the states are {list(states)}.", key="fixed")
        try:
            x[states.index(k)] = float(v)
        except (TypeError, ValueError):
            raise InputError(f"`fixed[{k!r}]` must be a number; got {v!r}.", key="fixed") from None
    free_inputs = tuple(free_inputs)
    for k in free_inputs:
        if k not in inputs:
            raise InputError(f"`free_inputs` names {k!r}, which is not an input; the inputs are {list(inputs)}.", key="free_inputs")
    if not (isinstance(tol, (int, float)) and tol > 0):
        raise InputError(f"`tol` must be a positive number; got {tol!r}.", key="tol")
    t = float(t)

    ix = np.array([i for i, s in enumerate(states) if s not in fixed], dtype=int)
    iu = np.array([inputs.index(k) for k in free_inputs], dtype=int)
    n_unknown = ix.size + iu.size
    if n_unknown > nx:
        raise InputError(
            f"{n_unknown} unknowns ({', '.join([states[i] for i in ix] + list(free_inputs))}) but only "
            f"{nx} equations f(x̄, ū) = 0: the equilibrium is not unique. Hold more states with "
            "`fixed` or solve for fewer inputs.",
            key="free_inputs" if free_inputs else "fixed",
        )

    def unpack(z):
        xx, uu = x.copy(), u.copy()
        xx[ix] = z[: ix.size]
        uu[iu] = z[ix.size :]
        return xx, uu

    def residual(z):
        xx, uu = unpack(z)
        return _f(system, t, xx, uu)

    def jac(z):
        xx, uu = unpack(z)
        AB = _jacobian_block(system, "dynamics", t, xx, uu, "auto")
        return AB[:, np.concatenate([ix, nx + iu])]

    z = np.concatenate([x[ix], u[iu]])
    r = residual(z)
    if not np.all(np.isfinite(r)):
        bad = [s for s, v in zip(states, r) if not np.isfinite(v)]
        raise InputError(
            f"`dynamics` is not finite at the starting point ({_point_text(states, x)}) for "
            f"{', '.join(bad)}; give an `x_guess` inside the model's domain.",
            key="x_guess",
        )
    best_z, best_r = z, float(np.max(np.abs(r), initial=0.0))
    if best_r > tol and n_unknown > 0:
        best_z, best_r = _solve_equilibrium(residual, jac, z, square=n_unknown == nx, tol=tol)
    elif 0 < best_r and n_unknown > 0:  # a guess already within tol: take it to rounding level
        best_z = _polish(residual, jac, best_z)
        best_r = float(np.max(np.abs(residual(best_z)), initial=0.0))
    xx, uu = unpack(best_z)
    if not best_r <= tol:
        r = residual(best_z)
        worst = states[int(np.nanargmax(np.abs(r)))] if np.any(np.isfinite(r)) else states[0]
        what = f"u0 = [{_point_text(inputs, u)}]" if inputs else "this system"
        raise NoEquilibriumError(
            f"no equilibrium found for {what}: the best point found, [{_point_text(states, xx)}]"
            + (f" with [{_point_text(free_inputs, uu[iu])}]" if iu.size else "")
            + (f" (holding {_point_text(list(fixed), list(fixed.values()))})" if fixed else "")
            + f", leaves max |f(x̄, ū)| = {best_r:.3g} (in d{worst}/dt), above `tol` = {tol:g}. "
            "The system may have no equilibrium for this input (x' = 1 + x^2 has none), or the "
            "search needs help: try another `x_guess`, hold a state with `fixed`, a different "
            "`u0`, or a larger `tol` if the residual is rounding error of large terms.",
            key="u0",
        )
    return OperatingPoint(
        x=xx,
        u=uu,
        y=np.asarray(system.output(t, xx, uu), dtype=float).reshape(-1),
        residual=best_r,
        t=t,
        states=states,
        inputs=inputs,
        outputs=_names(system, "outputs"),
    )


def _solve_equilibrium(residual, jac, z0, *, square: bool, tol: float):
    """Best (z, max|residual|) found by hybr (square systems), lm, and Newton polishing."""
    from scipy.optimize import root

    def norm(z):
        r = residual(z)
        return float(np.max(np.abs(r))) if np.all(np.isfinite(r)) else math.inf

    candidates = [(norm(z0), z0)]
    attempts = (["hybr"] if square else []) + ["lm"]
    for method in attempts:
        start = min(candidates, key=lambda c: c[0])[1]
        options = {"xtol": 1e-14} if method == "hybr" else {"xtol": 1e-15, "ftol": 1e-15}
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore", RuntimeWarning)
                sol = root(residual, start, jac=jac, method=method, options=options)
            z = np.asarray(sol.x, dtype=float)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
            if isinstance(exc, InputError):
                raise
            continue
        z = _polish(residual, jac, z)
        candidates.append((norm(z), z))
        if candidates[-1][0] <= tol:
            break
    r, z = min(candidates, key=lambda c: c[0])
    return z, r


def _polish(residual, jac, z, steps: int = 4):
    """Newton (Gauss-Newton when not square) steps, kept only while they reduce the residual."""
    r = residual(z)
    if not np.all(np.isfinite(r)):
        return z
    size = np.max(np.abs(r), initial=0.0)
    for _ in range(steps):
        if size == 0.0:
            break
        try:
            with np.errstate(all="ignore"):
                dz = np.linalg.lstsq(jac(z), -r, rcond=None)[0]
        except (np.linalg.LinAlgError, ValueError):
            break
        z_new = z + dz
        r_new = residual(z_new)
        new_size = np.max(np.abs(r_new), initial=0.0) if np.all(np.isfinite(r_new)) else math.inf
        if not new_size < size:
            break
        z, r, size = z_new, r_new, new_size
    return z
