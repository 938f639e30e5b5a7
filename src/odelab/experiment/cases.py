"""The types loading produces: a compiled problem, a case, an experiment, a built system.

They sit below the loader, the builders and the runner so that each of those imports them and
none imports another for its types.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping

import numpy as np

if TYPE_CHECKING:  # the types only: none of these is imported at run time
    from odelab.experiment.data import MeasuredData
    from odelab.experiment.events import EventSet
    from odelab.experiment.schema import Linearize
    from odelab.solvers.options import SolverOptions
    from odelab.systems.system import System
    from odelab.fmi.simulate import FmuRun
    from odelab.solvers.compiled import CompiledSystem
    from odelab.systems.diagram.compile import CompiledDiagram
    from odelab.systems.network import Network
    from odelab.systems.nonlinear import NonlinearSystem
    from odelab.systems.statespace import StateSpace

__all__ = ["Built", "Case", "LoadedExperiment", "Problem"]


@dataclass(frozen=True, eq=False)
class Problem:
    """A case compiled for running: its system and how to run it, nothing the runner must parse."""

    system: System  # what the case computes: fun, outputs, inputs, Jacobian, events, closed form, model...
    tspan: np.ndarray  # MATLAB tspan given to the solver
    x0: np.ndarray
    method: str
    # the [solver] options resolved once at load (odelab.solvers.options.SolverOptions: checked, MATLAB's
    # defaults filled in, for tspan and the states, the exact Jacobian included), carried to the driver as they
    # are; a change is ``solver_options.updated(...)`` (a step budget checked alone, anything else resolved again)
    solver_options: SolverOptions
    reference: str = "none"  # "exact", "lti", "high-accuracy" or "none"
    reference_solver: tuple[str, float, float] = ("auto", 1e-12, 1e-14)
    linearize: Linearize | None = None  # the [linearize] section, if any
    parameters: dict[str, float] = field(default_factory=dict)
    backend: str = "auto"  # [solver] backend: "auto", "python" or "compiled"
    analysis: dict | None = None  # the resolved [analysis] section: {"step_info", "bode", "poles", "input"}
    data: MeasuredData | None = None  # [data]: the case's reference
    fit: dict | None = None  # the summary of the experiment's [fit], once it has been fitted
    initial_given: tuple[str, ...] = ()  # the states the file's [initial] gives (the rest took their defaults)
    notes: tuple[str, ...] = ()  # what loading did that the run's notes say (values converted from their units)

    @property
    def options(self) -> Mapping[str, Any]:
        """The options as the file gives them, in odelab's names (state names made indices): the resolved
        options' ``given``, the one copy (a solve of another span starts from them)."""
        return self.solver_options.given

    # the names, read from the system (the one place they are held)
    @property
    def states(self) -> tuple[str, ...]:
        return self.system.states

    @property
    def inputs(self) -> tuple[str, ...]:
        return self.system.inputs

    @property
    def outputs(self) -> tuple[str, ...]:
        return self.system.outputs


@dataclass(frozen=True, eq=False)
class Case:
    """One case of an experiment, merged over the base and resolved."""

    experiment: str
    name: str
    title: str
    source: Path
    file_hash: str
    config: dict[str, Any]  # the merged configuration, defaults filled in (resolved.toml)
    problem: Problem
    index: int = 0  # position in the experiment (results are stored in this order)
    swept: dict[str, Any] = field(default_factory=dict)  # [sweep] key path -> this case's value


@dataclass(frozen=True, eq=False)
class LoadedExperiment:
    name: str
    title: str
    source: Path
    file_hash: str
    cases: tuple[Case, ...]
    sweep: Any = None  # an odelab.experiment.sweep.Sweep, for a file with [sweep]
    study: Any = None  # an odelab.experiment.study.StudySpec, for a file with [study]
    fit: Any = None  # an odelab.experiment.fit.FitSpec, for a file with [fit]


@dataclass(frozen=True, eq=False)
class Built:
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    fun: Callable
    output_fn: Callable | None
    resolved: dict
    linear: bool = False
    model: StateSpace | NonlinearSystem | None = None
    x0: np.ndarray | None = None  # initial state set by the system itself (a diagram's blocks)
    signals: tuple = ()  # input signals set by the system itself (a diagram's sources)
    diagram: CompiledDiagram | None = None  # for drawings and reports
    compiled: CompiledSystem | None = None  # for the compiled backend (expression systems without inputs)
    jacobian: Callable | np.ndarray | None = None  # exact df/dx for the stiff solvers: J(t, x) or a constant matrix
    network: Network | None = None  # the derived network of a kind = "network" system
    fmu: FmuRun | None = None  # kind = "fmu"
