"""What the linearisation needs of a system: the protocol check, names, f(t, x, u)."""

from __future__ import annotations

import numpy as np

from odelab.exceptions import InputError


def _is_statespace(system) -> bool:
    try:
        from odelab.systems.statespace import StateSpace
    except ImportError:  # pragma: no cover - statespace is part of odelab
        return False
    return isinstance(system, StateSpace)


def _check_system(system) -> None:
    missing = [a for a in ("states", "inputs", "outputs", "dynamics", "output") if not hasattr(system, a)]
    if missing:
        raise InputError(
            f"`system` must be a NonlinearSystem or StateSpace (with states, inputs, outputs, "
            f"dynamics(t, x, u) and output(t, x, u)); {type(system).__name__} lacks {', '.join(missing)}.",
            key="system",
        )


def _names(system, what: str) -> tuple[str, ...]:
    return tuple(getattr(system, what))


def _f(system, t, x, u) -> np.ndarray:
    return np.asarray(system.dynamics(t, x, u), dtype=float).reshape(-1)


def _point_text(names, values) -> str:
    return ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, values)) or "none"
