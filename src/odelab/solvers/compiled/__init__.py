"""The compiled backend: expression systems and MATLAB's stepping loop compiled together.

An experiment's equations (or a state-space model's A and B) are a closed, checked language,
and its input signals are data of a few known kinds (:mod:`.inputs`), so odelab can generate
one Python module holding the right-hand side, run by the stepping loops of
:mod:`odelab.solvers.engine` rewritten for numba (the field's standard JIT for numeric Python). The module is cached on disk by a hash of its text (:mod:`.cache`): the first run of a
system compiles it (a few seconds), later runs load it in a fraction of a second.

The loop takes exactly the steps of the Python engine and gives the same values to round-off
(``tests/solvers/test_compiled.py`` checks every shipped experiment): the same initial step,
error norm, controller, ``Refine`` and ``tspan`` output rules, vector tolerances, NormControl,
``max_steps`` and the fixed-step methods, with the same status codes and messages.

numba is imported only when this backend runs. :data:`BACKENDS` are the choices of
``[solver] backend`` and ``odelab run --backend``; ``"auto"`` (the runner's rule) keeps short
runs on the Python path, which has no compile cost, and moves long ones here.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from odelab.exceptions import InputError
from odelab.solution import Solution, Stats

__all__ = ["BACKENDS", "AUTO_STEPS", "COMPILE_SECONDS", "CompiledSystem", "expected_compile_seconds", "unavailable",
           "solve_compiled"]

BACKENDS = ("auto", "python", "compiled")

#: Solver options that call back into Python (or are not in the compiled loop yet).
PYTHON_ONLY_OPTIONS = ("events", "nonnegative", "mass", "output_fcn", "args")

#: ``backend = "auto"`` considers the compiled path once a run needs more than this many steps
#: (about 0.3 s on the Python path), and takes it if the compile costs less than the rest.
AUTO_STEPS = 10_000

#: Seconds a compile costs, measured on a 2-core machine (bench/bench_compiled.py), idle: the
#: shared adaptive loop (once per machine), the events loop, one system's rhs, and loading a
#: cached build (numba's import and the cache index).
COMPILE_SECONDS = {"adaptive": 2.5, "events": 4.0, "rhs": 0.6, "load": 0.5}


@dataclass(frozen=True, eq=False)
class CompiledSystem:
    """What the compiled backend needs to build a system's right-hand side.

    Build it with :meth:`from_equations` (``d(state)/dt`` expressions with parameters) or
    :meth:`linear` (``x' = A x``). Parameter values are passed at run time, not compiled in,
    so a sweep over parameters reuses one build.
    """

    kind: str  # "equations" or "linear"
    states: tuple[str, ...]
    parameters: tuple[str, ...] = ()
    values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    equations: tuple = ()  # (text, TOML key) per state
    inputs: tuple[str, ...] = ()  # input names (equations) or one per column of B (linear)
    signals: tuple = ()  # one odelab.signals signal per input, bound by with_signals()
    events: tuple = ()  # (text, TOML key) of each [events] `when`, bound by with_events()
    event_parameters: tuple[str, ...] = ()
    event_values: np.ndarray = field(default_factory=lambda: np.zeros(0))  # of the event parameters
    terminal: np.ndarray = field(default_factory=lambda: np.zeros(0))  # 1.0 / 0.0 per event
    direction: np.ndarray = field(default_factory=lambda: np.zeros(0))  # 1, -1, 0 per event

    @classmethod
    def from_equations(cls, states: Sequence[str], equations: Sequence, parameters: Mapping[str, float] | None = None,
                       keys: Sequence[str | None] | None = None) -> "CompiledSystem":
        """An equations system: ``equations[i]`` (text or ParsedExpression) is d(states[i])/dt.

        The texts are parsed and checked when the module is generated (only if this backend
        runs); names other than ``t``, the states and the parameters are refused then.
        """
        keys = tuple(keys) if keys is not None else (None,) * len(equations)
        parameters = dict(parameters or {})
        return cls(kind="equations", states=tuple(states), parameters=tuple(parameters),
                   values=np.array([float(v) for v in parameters.values()], dtype=float),
                   equations=tuple(zip(equations, keys)))

    def _parsed(self) -> list:
        from odelab.expressions import parse_expression

        parsed = [parse_expression(text, key=key) for text, key in self.equations]
        known = {"t", *self.states, *self.parameters, *self.inputs}
        for p in parsed:
            unknown = sorted(set(p.names) - known)
            if unknown:
                raise InputError(f"`{p.key or p.text}` uses `{unknown[0]}`, which is not a state, "
                                 f"{'an input, ' if self.inputs else ''}a parameter or t.", key=p.key)
        return parsed

    @classmethod
    def from_system(cls, states: Sequence[str], equations: Sequence, parameters: Mapping[str, float] | None = None,
                    inputs: Sequence[str] = (), keys: Sequence[str | None] | None = None) -> "CompiledSystem":
        """An equations system whose expressions may also use the ``inputs`` (bind their signals
        with :meth:`with_signals` before solving)."""
        system = cls.from_equations(states, equations, parameters, keys)
        return replace(system, inputs=tuple(inputs))

    @classmethod
    def linear(cls, A, states: Sequence[str], B=None, inputs: Sequence[str] = ()) -> "CompiledSystem":
        """``x' = A x``, or ``x' = A x + B u`` with one input per column of ``B``."""
        A = np.asarray(A, dtype=float)
        values = [np.ascontiguousarray(A).ravel()]
        if B is not None and np.shape(B)[1]:
            values.append(np.ascontiguousarray(np.asarray(B, dtype=float)).ravel())
            inputs = tuple(inputs) or tuple(f"u{k}" for k in range(np.shape(B)[1]))
        else:
            inputs = ()
        return cls(kind="linear", states=tuple(states), values=np.concatenate(values), inputs=tuple(inputs))

    def with_signals(self, signals: Sequence) -> "CompiledSystem":
        """The system with its inputs driven by ``signals`` (:mod:`odelab.signals`, one per input)."""
        if len(signals) != len(self.inputs):
            raise InputError(f"the system has {len(self.inputs)} inputs but {len(signals)} signals were given.",
                             key="signals")
        return replace(self, signals=tuple(signals))

    def with_events(self, whens: Sequence, terminal, direction, parameters: Mapping[str, float] | None = None,
                    keys: Sequence[str | None] | None = None) -> "CompiledSystem":
        """The system with [events]: zeros of the ``whens`` (expressions of t, the states and the
        ``parameters``), located by the compiled loop as :mod:`odelab.solvers.events` does."""
        keys = tuple(keys) if keys is not None else (None,) * len(whens)
        parameters = dict(parameters or {})
        return replace(self, events=tuple(zip(whens, keys)), event_parameters=tuple(parameters),
                       event_values=np.array([float(v) for v in parameters.values()], dtype=float),
                       terminal=np.array([1.0 if f else 0.0 for f in terminal], dtype=float),
                       direction=np.array(direction, dtype=float).reshape(len(whens)))

    def why_not(self) -> str | None:
        """Why this system cannot run compiled (an input the compiled engine cannot generate), or None."""
        from odelab.solvers.compiled.inputs import why_not

        if len(self.signals) != len(self.inputs):
            return "its inputs have no signals"
        for name, signal in zip(self.inputs, self.signals):
            reason = why_not(signal)
            if reason:
                return f"input `{name}`: {reason}"
        return None

    def parameter_vector(self, lo: float = -np.inf, hi: float = np.inf) -> np.ndarray:
        """The run-time data ``_p`` of the generated rhs: with inputs, the bounds of the inputs'
        time (a piece of :func:`~odelab.systems.simulate.simulate`), the parameters and the
        signals' numbers; without, the parameters (or A)."""
        if not self.inputs:
            return np.ascontiguousarray(np.concatenate([self.values, self.event_values]), dtype=float)
        data: list[float] = []
        self._inputs_lines(data)
        return np.concatenate([[float(lo), float(hi)], self.values, np.asarray(data, dtype=float)])

    def _inputs_lines(self, data: list[float]) -> list[str]:
        from odelab.solvers.compiled.inputs import inputs_source

        return inputs_source(self.signals, data, 2 + self.values.size)

    def source(self) -> str:
        """The generated module's text (right-hand side and loops)."""
        from odelab.solvers.compiled import cache, codegen
        from odelab.solvers.compiled.inputs import INPUT_PRELUDE

        reason = self.why_not() if self.inputs else None
        if reason:
            raise InputError(f"the compiled backend cannot run this system: {reason}.", key="backend")
        lines = self._inputs_lines([]) if self.inputs else []
        if self.kind == "linear":
            rhs = codegen.linear_source(len(self.inputs), lines)
        else:
            rhs = codegen.equations_source(self.states, self.parameters, self._parsed(), self.inputs, lines)
        if self.events:
            if self.inputs:
                raise InputError("[events] work with systems without inputs.", key="events")
            from odelab.expressions import parse_expression

            whens = [parse_expression(text, key=key) for text, key in self.events]
            known = {"t", *self.states, *self.event_parameters}
            for w in whens:
                unknown = sorted(set(w.names) - known)
                if unknown:
                    raise InputError(f"`{w.key or w.text}` uses `{unknown[0]}`, which is not a state, a parameter "
                                     "or t.", key=w.key)
            rhs += "\n\n" + codegen.events_source(self.states, self.event_parameters, whens, self.values.size)
        return cache.module_text(codegen.PRELUDE + (INPUT_PRELUDE if self.inputs else ""), rhs)

    def module(self):
        """The module holding the compiled ``rhs`` (compiled or loaded from the cache on first use)."""
        from odelab.solvers.compiled import cache

        return cache.load_module(self.source())


def expected_compile_seconds(system: CompiledSystem, loop: str = "adaptive") -> float:
    """What running ``system`` on the compiled ``loop`` ("adaptive" or "events") would cost
    before its first step: nothing to compile if both are cached, else their compile times
    (:data:`COMPILE_SECONDS`). ``backend = "auto"`` weighs it against the Python run."""
    from odelab.solvers.compiled import cache

    try:
        seconds = COMPILE_SECONDS["load"]
        if not cache.is_built(cache.kernels_text(), "odelab_kernels", "_adaptive_events" if loop == "events"
                              else "_adaptive"):
            seconds += COMPILE_SECONDS[loop]
        if not cache.is_built(system.source()):
            seconds += COMPILE_SECONDS["rhs"]
        return seconds
    except ImportError:  # pragma: no cover - numba missing: why_not_compiled says so first
        return float("inf")


@functools.cache
def unavailable() -> str | None:
    """Why the compiled backend cannot run here (numba missing), or None if it can.

    Looked up once per process: the search of sys.path for numba was a fifth of running a
    small case, paid by every case of a batch."""
    try:
        import importlib.util

        if importlib.util.find_spec("numba") is None:
            return "numba is not installed (pip install numba)"
    except (ImportError, ValueError):  # pragma: no cover
        return "numba cannot be imported"
    return None


def solve_compiled(system: CompiledSystem, tspan, y0, method: str = "ode45", *,
                   input_bounds: tuple[float, float] = (-np.inf, np.inf), **options) -> Solution:
    """Solve ``system`` with an odelab method (ode23, ode45, fixed-step) on the compiled path.

    Same arguments, options and result as :func:`odelab.solvers.api.solve` with the
    system's right-hand side; SciPy's methods are not available here. A failed integration
    returns the partial solution and issues a SolverWarning, as :func:`~odelab.solve` does.
    A system with inputs reads them at t clipped to ``input_bounds`` (one piece of
    :func:`odelab.systems.simulate.simulate`, which restarts at the inputs' breakpoints).
    """
    from odelab.solvers import api

    sol = _solve_compiled(system, tspan, y0, method, options, input_bounds)
    api._warn_if_failed(sol, 3)
    return sol


def _solve_compiled(system: CompiledSystem, tspan, y0, method: str, options: dict,
                    input_bounds: tuple[float, float] = (-np.inf, np.inf)) -> Solution:
    from odelab.solvers import api
    from odelab.solvers.options import as_tspan, as_y0, normalize_options, resolve_options
    from odelab.solvers.registry import get_method

    m = get_method(method)
    if m.kind not in ("adaptive", "fixed"):
        raise InputError(f"the compiled backend runs odelab's explicit Runge-Kutta methods (ode23, ode45, "
                         f"fixed-step); {m.name} is {'SciPy' + chr(39) + 's' if m.kind == 'scipy' else 'not one'}: use backend "
                         "\"python\".", key="backend")
    if m.kind == "adaptive" and not m.tableau.fsal:
        raise InputError(f"the compiled backend runs FSAL pairs (ode23, ode45) and fixed-step methods; {m.name} is "
                         "Verner's non-FSAL pair, which runs on the Python path: use backend \"python\" (or "
                         "\"auto\").", key="backend")
    reason = unavailable()
    if reason:
        raise InputError(f"the compiled backend needs numba: {reason}.", key="backend")
    tspan_arr = as_tspan(tspan)
    y0_arr = as_y0(y0)
    n = y0_arr.size
    if n != len(system.states):
        raise InputError(f"`y0` has {n} values but the system has {len(system.states)} states.", key="y0")
    if np.iscomplexobj(y0_arr):
        raise InputError("the compiled backend integrates real states; `y0` is complex: use backend \"python\".",
                         key="y0")
    opts = resolve_options(m, normalize_options(options, m), tspan_arr, n)
    python_only = [name for name in PYTHON_ONLY_OPTIONS if getattr(opts, name, None) not in (None, ())]
    if python_only:
        raise InputError(f"the compiled backend does not run `{python_only[0]}` (it calls Python); use backend "
                         "\"python\".", key=python_only[0])
    from odelab.solvers.compiled.cache import load_kernels

    kernels = load_kernels()
    rhs = system.module().rhs
    p = system.parameter_vector(*input_bounds)
    tab = m.tableau
    t0 = float(tspan_arr[0])
    f0 = np.empty(n)
    y0_arr = np.array(y0_arr, dtype=float, order="C")  # writable and contiguous, as the signatures say
    rhs(t0, y0_arr.copy(), p, f0)
    if not np.all(np.isfinite(f0)):
        return api._failed_at_start(m, tspan_arr, y0_arr, opts, f"the derivative at t = {t0:g} is not finite "
                                    f"({api._fmt_vec(f0)}): check the right-hand side at the initial state")
    if system.events and m.kind != "adaptive":
        raise InputError(f"[events] are located by ode23 and ode45 (MATLAB's Events); the method is {m.name}.",
                         key="method")
    if m.kind == "fixed":
        grid, keep = api.fixed_grid(tspan_arr, opts.h)
        ys, nsteps, nfevals, status, t_stop = kernels.loop("fixed")(rhs, _c(grid), y0_arr, p, _c(tab.A), _c(tab.b), _c(tab.c))
        done = nsteps + 1
        mask = keep[:done].copy()
        mask[done - 1] = True
        t, y = grid[:done][mask], ys[:done][mask]
        message = api._status_message(status, m, t_stop, opts.h, y, y0_arr, opts, None, tspan_arr)
        return Solution(t=t, y=y, stats=Stats(nsteps=nsteps, nfailed=0, nfevals=nfevals),
                        status="success" if status == 0 else "failed", message=message, method=m.name)

    refine = opts.refine
    if tspan_arr.size == 2 and refine > 1:
        fractions = np.arange(1, refine) / refine
        weights = np.ascontiguousarray(
            (tab.dense @ np.cumprod(np.broadcast_to(fractions, (tab.dense.shape[1], refine - 1)), axis=0)).T)
    else:
        weights = np.zeros((0, tab.c.size))
    threshold = np.broadcast_to(np.atleast_1d(np.asarray(opts.atol / opts.rtol, dtype=float)), (n,)).copy()
    htry = float(opts.initial_step)
    capacity = tspan_arr.size if tspan_arr.size > 2 else 1 + refine * 64
    args = (rhs, _c(tspan_arr), y0_arr, f0, p, _c(tab.A), _c(tab.c), _c(tab.error_weights), _c(tab.dense), _c(weights),
            float(m.power), float(m.shrink_min), float(opts.rtol), threshold, float(opts.max_step), htry, int(refine),
            bool(opts.norm_control), int(opts.max_steps), int(capacity))
    found = {}
    if system.events:
        events = system.module().events
        v0 = np.empty(len(system.events))
        events(t0, y0_arr.copy(), p, v0)
        (t_out, y_out, count, nsteps, nfailed, nfevals, status, t_stop, h_stop, te, ye, ie) = kernels.loop("events")(
            *args, events, v0, _c(system.terminal), _c(system.direction))
        found = {"te": te, "ye": ye, "ie": ie}
    else:
        (t_out, y_out, count, nsteps, nfailed, nfevals, status, t_stop, h_stop) = kernels.loop("adaptive")(*args)
    t = t_out[:count]
    y = y_out[:count]
    if count < t_out.size // 2:  # do not keep a mostly empty buffer alive
        t, y = t.copy(), y.copy()
    message = api._status_message(status, m, t_stop, h_stop, y, y0_arr, opts, None, tspan_arr,
                                  list(found.get("te", ())), list(found.get("ie", ())))
    return Solution(t=t, y=y, stats=Stats(nsteps=nsteps, nfailed=nfailed, nfevals=nfevals + 1),
                    status="failed" if status in api._FAILURES else "success", message=message, method=m.name,
                    warnings=opts.warnings, **found)



def _c(a) -> np.ndarray:
    """A writable, C-contiguous float64 copy: the loops' signatures are exact."""
    return np.array(a, dtype=float, order="C")
