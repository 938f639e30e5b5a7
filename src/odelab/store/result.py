"""The result of running one case: what the results store writes and the report reads."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.analysis.errors import ErrorSummary
from odelab.experiment.cases import Case
from odelab.solution import Stats

__all__ = ["CaseResult", "Integration"]


@dataclass(eq=False)
class Integration:
    """What one solve of a case gave, whichever driver ran it (a solve, a simulation through its inputs'
    discontinuities, a hybrid diagram, a run with [events]); :class:`CaseResult` is built from it."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray | None
    stats: Stats
    status: str
    message: str
    warnings: tuple | list = ()
    events: list = field(default_factory=list)  # located events: name, t, state, ...
    marks: np.ndarray | None = None  # per output row: 1-based number of its event, 0 for none
    backend: str = "python"  # the engine that ran: "python" or "compiled"


@dataclass(eq=False)
class CaseResult:
    """Everything one run of a case produced; what the results store writes and the report reads."""

    case: Case
    status: str
    message: str
    stats: Stats
    elapsed: float
    t: np.ndarray
    x: np.ndarray
    u: np.ndarray | None = None
    y: np.ndarray | None = None
    reference: dict[str, np.ndarray] = field(default_factory=dict)  # name -> reference values at t
    reference_kind: str = "none"
    errors: dict[str, ErrorSummary] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)  # e.g. the linearisation study
    events: list[dict[str, Any]] = field(default_factory=list)  # located events: name, t, state, ...
    event_marks: np.ndarray | None = None  # per output row: 1-based number of its event, 0 for none
    backend: str = "python"  # the engine that ran: "python" or "compiled"
    estimate: dict[str, Any] | None = None  # the global error estimate (odelab.run.estimate), if one was made
    spool: Any = None  # a long run's rows on disk (odelab.store.spool.Spool): t and x are maps of its files

    @property
    def unreliable(self) -> bool:
        """The run succeeded but its error estimate says not to trust it (shown ``ok?``)."""
        return self.status == "success" and bool(self.estimate) and self.estimate.get("verdict") == "unreliable"

    @property
    def expected_stop(self) -> bool:
        """The case failed the way its file says it should (``expect = "max-steps"`` or ``"failure"``).

        Such a case is stored as failed (its status is the solver's) but does not make the run fail:
        it is reported as "stopped, as expected".
        """
        expect = self.case.config.get("expect")
        if self.status == "success" or expect not in ("max-steps", "failure"):
            return False
        return expect == "failure" or "after max_steps = " in self.message

    @property
    def unexpected_failure(self) -> bool:
        """A failed case that its file did not declare: what makes ``odelab run`` exit 1."""
        return self.status != "success" and not self.expected_stop

    @property
    def method(self) -> str:
        return self.case.problem.method

    def record_input_jumps(self) -> None:
        """``extra["input_jumps"]``: where the case's input signals jump, with their values just
        before and at each (:func:`odelab.signals.input_jumps`), so that the report draws a step
        as a step whatever rows the solver output."""
        p = self.case.problem
        if self.u is None or not p.system.signals:
            return
        from odelab.signals import input_jumps

        jumps = input_jumps(p.system.signals, float(p.tspan[0]), float(p.tspan[-1]))
        if jumps is not None:
            self.extra["input_jumps"] = jumps

    def series(self) -> dict[str, np.ndarray]:
        """Every named column at the output times: states, inputs, outputs."""
        p = self.case.problem
        out = {name: self.x[:, i] for i, name in enumerate(p.states)}
        if self.u is not None:
            out.update({name: self.u[:, i] for i, name in enumerate(p.inputs)})
        if self.y is not None:
            out.update({name: self.y[:, i] for i, name in enumerate(p.outputs)})
        return out
