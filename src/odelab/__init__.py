"""odelab: MATLAB-faithful ode23/ode45, state-space systems, linearisation and lab reports.

The public API is imported lazily (PEP 562), so ``import odelab`` and ``odelab --help`` stay
fast and import neither numpy nor scipy until a solver is used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

# public name -> module that defines it
_LAZY = {
    "ode23": "odelab.solvers.api",
    "ode45": "odelab.solvers.api",
    "solve": "odelab.solvers.api",
    "dde23": "odelab.solvers.dde23",
    "deval": "odelab.solution",
    "odextend": "odelab.solvers.api",
    "OdelabWarning": "odelab.exceptions",
    "SolverWarning": "odelab.exceptions",
    "ode113": "odelab.solvers.adams",
    **{name: "odelab.solvers.suite" for name in ("ode78", "ode89")},
    **{name: f"odelab.solvers.implicit.{name}" for name in ("ode15s", "ode15i", "ode23s", "ode23t", "ode23tb")},
    "decic": "odelab.solvers.implicit.decic",
    "METHODS": "odelab.solvers.registry",
    "Solution": "odelab.solution",
    "Stats": "odelab.solution",
    "OdelabError": "odelab.exceptions",
    "InputError": "odelab.exceptions",
    "ExpressionError": "odelab.exceptions",
    "ExperimentError": "odelab.exceptions",
    "StateSpace": "odelab.systems.statespace",
    "NonlinearSystem": "odelab.systems.nonlinear",
    "simulate": "odelab.systems.simulate",
    "Response": "odelab.systems.simulate",
    "linearize": "odelab.analysis.linearize",
    "operating_point": "odelab.analysis.linearize",
    "tf": "odelab.analysis.control",
    "ss2tf": "odelab.analysis.control",
    "tf2ss": "odelab.analysis.control",
    "stepinfo": "odelab.analysis.control",
    "bode": "odelab.analysis.control",
    "margins": "odelab.analysis.control",
    "poles": "odelab.analysis.control",
    "zeros": "odelab.analysis.control",
    "dcgain": "odelab.analysis.control",
    "damp": "odelab.analysis.control",
    "load_experiment": "odelab.experiment.loader",
    "run_experiment": "odelab.run.runner",
}

# public name -> a whole module (``from odelab import diagram as dg``)
_MODULES = {"diagram": "odelab.systems.diagram"}

__all__ = ["__version__", *_LAZY, *_MODULES]


def __getattr__(name: str):
    if name in _MODULES:
        module = importlib.import_module(_MODULES[name])
        globals()[name] = module
        return module
    try:
        module = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'odelab' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(__all__)


if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from odelab.analysis.control import bode, damp, dcgain, margins, poles, ss2tf, stepinfo, tf, tf2ss, zeros
    from odelab.analysis.linearize import linearize, operating_point
    from odelab.exceptions import (ExperimentError, ExpressionError, InputError, OdelabError, OdelabWarning,
                                   SolverWarning)
    from odelab.experiment.loader import load_experiment
    from odelab.run.runner import run_experiment
    from odelab.solution import Solution, Stats, deval
    from odelab.solvers.adams import ode113
    from odelab.solvers.api import ode23, ode45, odextend, solve
    from odelab.solvers.dde23 import dde23
    from odelab.solvers.registry import METHODS
    from odelab.solvers.implicit.decic import decic
    from odelab.solvers.implicit.ode15i import ode15i
    from odelab.solvers.implicit.ode15s import ode15s
    from odelab.solvers.implicit.ode23s import ode23s
    from odelab.solvers.implicit.ode23t import ode23t
    from odelab.solvers.implicit.ode23tb import ode23tb
    from odelab.solvers.suite import ode78, ode89
    from odelab.systems.nonlinear import NonlinearSystem
    from odelab.systems.simulate import Response, simulate
    from odelab.systems.statespace import StateSpace
