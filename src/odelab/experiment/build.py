"""Build runtime systems and input signals from a validated experiment section."""

from __future__ import annotations

import difflib
import hashlib
import importlib.machinery
import importlib.util
import sys
from pathlib import Path
from collections.abc import Mapping
from typing import Callable

import numpy as np

from odelab.expressions.matlab import is_matrix_string, split_matrix

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.cases import Built
from odelab.experiment.fields import check_keys, check_names, constant, expr
from odelab.experiment.userfiles import check_python_source, resolve_user_file
from odelab.systems.outputs import ExpressionOutputs, LinearOutputs

__all__ = ["build_function_system", "build_ode", "build_state_space", "build_inputs", "build_signal", "load_function",
           "SIGNAL_KEYS"]


def build_ode(model: schema.Experiment, params: dict[str, float]) -> Built:
    """An ODE system from [system.equations] (and [system.outputs]) expressions."""
    ex = expr()
    system = model.system
    if not system.states:
        raise ExperimentError("`system.states` is required: list the state names, e.g. states = [\"x\", \"v\"].",
                              key="system.states")
    states = check_names(system.states, "system.states", "state")
    inputs = check_names(system.inputs, "system.inputs", "input") if system.inputs else ()
    clash = sorted((set(states) | set(inputs)) & set(params))
    if clash:
        raise ExperimentError(f"{clash[0]!r} is both a parameter and a state or input; rename one.",
                              key=f"parameters.{clash[0]}")
    both = sorted(set(states) & set(inputs))
    if both:
        raise ExperimentError(f"{both[0]!r} is both a state and an input; rename one.", key="system.inputs")
    if system.equations is None:
        raise ExperimentError("[system.equations] is required: one right-hand side d(state)/dt per state, e.g. "
                              f"{states[0]} = \"-{states[0]}\" (or give `function = \"file.py:name\"`).",
                              key="system.equations")
    if isinstance(system.outputs, list):
        raise ExperimentError("`system.outputs` of an equations system is a table of expressions, e.g. "
                              "[system.outputs] y = \"10*x\".", key="system.outputs")
    check_keys(system.equations, states, "system.equations", "states", require_all=True)
    from odelab.systems.delay import uses_lag

    delayed = uses_lag(system.equations.values()) or model.history is not None  # dde23: experiment/delays.py
    args = ["t", *states, *inputs]
    keys = [f"system.equations.{s}" for s in states]
    # Each text is compiled once: by NonlinearSystem.from_expressions where the case needs the system object
    # (inputs, [linearize], [analysis]; with its complex-step twin for exact Jacobians), else here.
    as_object = not delayed and (inputs or model.linearize is not None or model.analysis is not None)
    F = None if delayed or as_object else ex.compile_vector([system.equations[s] for s in states], args=args,
                                                             constants=params, keys=keys)
    outputs: tuple[str, ...] = ()
    output_fn = None
    resolved = {"states": list(states), "equations": dict(system.equations)}
    if inputs:
        resolved["inputs"] = list(inputs)
    if system.outputs:
        outputs = tuple(ex.check_identifier(n, key=f"system.outputs.{n}", what="output") for n in system.outputs)
        dup = sorted(set(outputs) & (set(states) | set(inputs) | set(params)))
        if dup:
            raise ExperimentError(f"output {dup[0]!r} has the name of a state, input or parameter; rename it.",
                                  key=f"system.outputs.{dup[0]}")
        if not as_object:
            G = ex.compile_vector(list(system.outputs.values()), args=args, constants=params,
                                  keys=[f"system.outputs.{n}" for n in outputs])
            output_fn = ExpressionOutputs(G, len(outputs))
        resolved["outputs"] = dict(system.outputs)
    if delayed:
        from odelab.experiment.kinds.delays import build_delay

        return build_delay(model, params, states, outputs, output_fn, resolved)

    sys_obj = None
    fun = None  # with inputs, the runner integrates through odelab.simulate, which applies them
    F_complex = None
    if as_object:
        from odelab.systems.nonlinear import NonlinearSystem

        sys_obj = NonlinearSystem.from_expressions(
            {s: system.equations[s] for s in states}, inputs=inputs,
            outputs=dict(system.outputs) if system.outputs else None, parameters=params)
        F, G, F_complex = sys_obj.expression_parts()
        if outputs:
            output_fn = ExpressionOutputs(G, len(outputs))
    from odelab.solvers.compiled import CompiledSystem

    if not inputs:
        from odelab.systems.fields import ExpressionField

        fun = ExpressionField(F)

    # the compiled backend's description (nothing is compiled unless that backend runs);
    # the loader binds the inputs' signals to it
    compiled = CompiledSystem.from_system(states, [system.equations[s] for s in states], params, inputs, keys=keys)

    jacobian = _jacobian(system, states, params, None if inputs else F_complex)
    if system.jacobian is not None:
        resolved["jacobian"] = [list(row) for row in system.jacobian]
    return Built(states=states, inputs=inputs, outputs=outputs, fun=fun, output_fn=output_fn, resolved=resolved,
                 linear=False, model=sys_obj, compiled=compiled, jacobian=jacobian)


def _jacobian(system, states: tuple[str, ...], params: dict[str, float], compiled=None):
    """The exact df/dx for the stiff solvers: the file's `jacobian`, else complex step on the equations
    (``compiled``: their complex-step compilation over t and the states, where one was made)."""
    from odelab.systems.jacobian import complex_step_jacobian, expression_jacobian

    n = len(states)
    if system.jacobian is None:
        return complex_step_jacobian([system.equations[s] for s in states], states, params,
                                     keys=[f"system.equations.{s}" for s in states], compiled=compiled)
    rows = system.jacobian
    if len(rows) != n or any(len(row) != n for row in rows):
        shape = f"rows of {', '.join(str(len(r)) for r in rows)} entries"
        raise ExperimentError(f"`system.jacobian` must be a {n}-by-{n} matrix, one row per equation: row i holds "
                              f"the derivatives of d(state i)/dt with respect to {', '.join(states)}; got {shape}.",
                              key="system.jacobian")
    return expression_jacobian(rows, states, params)


def _matrix(value, key: str, params: dict[str, float]) -> np.ndarray | None:
    if value is None:
        return None
    if is_matrix_string(value):  # MATLAB's "[0 1; -k/m -b/m]": rows at ;, elements at spaces or commas
        try:
            value = split_matrix(value)
        except ValueError as exc:
            raise ExperimentError(f"`{key}` is {value!r}: {exc}.", key=key) from None
    if not isinstance(value, list):
        return np.array([[constant(value, key, params)]])
    if all(not isinstance(v, list) for v in value):
        return np.array([constant(v, f"{key}[{j}]", params) for j, v in enumerate(value)])
    if not all(isinstance(v, list) for v in value):
        raise ExperimentError(f"`{key}` mixes rows and numbers; write a matrix as [[a, b], [c, d]].", key=key)
    widths = {len(row) for row in value}
    if len(widths) != 1:
        raise ExperimentError(f"`{key}` has rows of different lengths ({', '.join(str(len(r)) for r in value)}); "
                              "every row needs the same number of entries.", key=key)
    return np.array([[constant(v, f"{key}[{i}][{j}]", params) for j, v in enumerate(row)]
                     for i, row in enumerate(value)])


def build_state_space(model: schema.Experiment, params: dict[str, float]) -> Built:
    """A linear state-space system x' = Ax + Bu, y = Cx + Du (a Simulink State-Space block)."""
    from odelab.systems.statespace import StateSpace

    system = model.system
    if system.equations is not None or system.function is not None:
        raise ExperimentError("a state-space system is given by matrices A, B, C, D, not by `equations` or "
                              "`function`; remove those or set kind = \"ode\".", key="system.kind")
    if system.A is None:
        raise ExperimentError("`system.A` is required for kind = \"state-space\", e.g. A = [[0, 1], [-3, -4]].",
                              key="system.A")
    if system.outputs is not None and not isinstance(system.outputs, list):
        raise ExperimentError("`system.outputs` of a state-space system is a list of output names (the rows "
                              "of C), e.g. outputs = [\"y\"].", key="system.outputs")
    mats = {name: _matrix(getattr(system, name), f"system.{name}", params) for name in "ABCD"}
    states = check_names(system.states, "system.states", "state") if system.states else None
    inputs = check_names(system.inputs, "system.inputs", "input") if system.inputs else None
    outputs = check_names(system.outputs, "system.outputs", "output") if system.outputs else None
    try:
        ss = StateSpace(mats["A"], mats["B"], mats["C"], mats["D"], states=states, inputs=inputs, outputs=outputs)
    except InputError as exc:
        text = exc.message
        for name in ("A", "B", "C", "D"):
            text = text.replace(f"`{name}`", f"`system.{name}`")
        for name in ("states", "inputs", "outputs"):
            text = text.replace(f"`{name}`", f"`system.{name}`")
        key = exc.key if exc.key is None or exc.key.startswith("system.") else f"system.{exc.key}"
        raise ExperimentError(text, key=key) from None
    resolved = {
        "kind": "state-space",
        "states": list(ss.states),
        "inputs": list(ss.inputs),
        "outputs": list(ss.outputs),
        "A": ss.A.tolist(),
        "B": ss.B.tolist(),
        "C": ss.C.tolist(),
        "D": ss.D.tolist(),
    }
    A = ss.A
    output_fn = LinearOutputs(ss.C, ss.D)

    from odelab.solvers.compiled import CompiledSystem

    fun = None
    compiled = CompiledSystem.linear(A, ss.states, ss.B, ss.inputs)
    if ss.nu == 0:
        from odelab.systems.fields import LinearField

        fun = LinearField(A)

    if system.jacobian is not None:
        raise ExperimentError("`system.jacobian` is for [system.equations]; a state-space system's Jacobian is "
                              "its A matrix, which the stiff solvers use already: remove `jacobian`.",
                              key="system.jacobian")
    return Built(states=ss.states, inputs=ss.inputs, outputs=ss.outputs, fun=fun, output_fn=output_fn,
                 resolved=resolved, linear=True, model=ss, compiled=compiled, jacobian=A)


class _SignalKeys(Mapping):
    """type -> {key: default} of every registered signal type (:data:`odelab.signals.SIGNALS`),
    read from the registry at each use, so a type registered later is known too."""

    def __getitem__(self, kind: str) -> dict:
        from odelab.signals import SIGNALS

        return {k: spec.default for k, spec in SIGNALS[kind].KEYS.items()}

    def __iter__(self):
        from odelab.signals import SIGNALS

        return iter(tuple(SIGNALS))

    def __len__(self) -> int:
        from odelab.signals import SIGNALS

        return len(SIGNALS)


# Keys each signal type takes, with their defaults (the rest are errors, not silently ignored).
SIGNAL_KEYS: Mapping[str, dict] = _SignalKeys()


def signal_type_list(last: str = ", ") -> str:
    """The registered signal types for a message: "step, ramp, ..., constant" (``last`` before the final one)."""
    names = list(SIGNAL_KEYS)
    return ", ".join(names[:-1]) + last + names[-1] if len(names) > 1 else "".join(names)


def build_inputs(model: schema.Experiment, inputs: tuple[str, ...], path: Path, tspan: np.ndarray, *,
                 max_rows: int | None = None):
    """One signal per declared input, from [inputs.<name>] tables (tables of at most ``max_rows`` rows)."""
    specs = model.inputs or {}
    for name in specs:
        if name not in inputs:
            close = difflib.get_close_matches(name, inputs, n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            raise ExperimentError(f"`inputs.{name}`: {name!r} is not an input of the system "
                                  f"({', '.join(inputs)}).{hint}", key=f"inputs.{name}")
    out = []
    resolved = {}
    for name in inputs:
        spec = specs.get(name)
        if spec is None:
            raise ExperimentError(f"input {name!r} has no signal: add [inputs.{name}] with a `type` "
                                  f"({signal_type_list()}).", key=f"inputs.{name}")
        given = {k: v for k, v in spec.model_dump().items() if v is not None and k != "type"}
        signal, values = build_signal(spec.type, given, key=f"inputs.{name}", path=path, params=model_params(model),
                                      what="input", max_rows=max_rows)
        out.append(signal)
        resolved[name] = {"type": spec.type, **values}

    from odelab.systems.fields import SignalColumns

    signals = tuple(out)
    return signals, SignalColumns(signals), resolved


def build_signal(kind: str, given: dict, *, key: str, path: Path, params: dict[str, float], what: str = "input",
                 max_rows: int | None = None):
    """One :mod:`odelab.signals` signal of type ``kind`` from its keys (numbers already evaluated).

    Shared by [inputs] and the source blocks of diagrams. ``key`` is the table's key path
    (``inputs.f``, ``blocks.force``) and ``what`` the noun for messages. Returns the signal and
    its resolved keys (defaults filled in).
    """
    from odelab.signals import SIGNALS, SignalContext

    cls = SIGNALS[kind]
    allowed = SIGNAL_KEYS[kind]
    for k in given:
        if k not in allowed:
            raise ExperimentError(f"`{key}.{k}` does not apply to a {kind} {what}; a {kind} takes "
                                  f"{', '.join(allowed)}.", key=f"{key}.{k}")
    values = {**allowed, **given}
    for k in allowed:
        if values[k] is None:
            raise ExperimentError(f"`{key}.{k}` is required for a {kind} {what}.", key=f"{key}.{k}")
    for k, value in values.items():
        if isinstance(value, float) and not np.isfinite(value):
            raise ExperimentError(f"`{key}.{k}` must be finite; got {value!r}.", key=f"{key}.{k}")
    ctx = SignalContext(key=key, what=what, params=params, max_rows=max_rows,
                        resolve_file=lambda name, k: resolve_user_file(name, k, path))
    try:
        signal = cls.from_toml(values, ctx)
    except ExperimentError:
        raise
    except InputError as exc:  # the signal names the key; an experiment file's error all the same
        raise ExperimentError(exc.message, source=exc.source, key=exc.key or key) from None
    return signal, {k: v for k, v in values.items() if v is not None}


def model_params(model: schema.Experiment) -> dict[str, float]:
    return expr().evaluate_parameters(model.parameters) if model.parameters else {}


# --- Python-function systems (the lab's `function ydot = eq1(t, y)`) -----------------------


def build_function_system(model: schema.Experiment, path: Path) -> Built:
    system = model.system
    if system.equations is not None:
        raise ExperimentError("[system] has both `function` and [system.equations]; keep one.",
                              key="system.function")
    if system.inputs:
        raise ExperimentError("a `function` system cannot declare `inputs`: compute u(t) inside the function, "
                              "or write the equations as expressions.", key="system.inputs")
    if system.outputs:
        raise ExperimentError("`system.outputs` is not supported with `function`; compute outputs with "
                              "expressions of an equations system.", key="system.outputs")
    states = check_names(system.states, "system.states", "state") if system.states else tuple(model.initial)
    if not states:
        raise ExperimentError("`system.states` is required: list the state names, e.g. states = [\"y\"].",
                              key="system.states")
    fun = load_function(system.function, path)
    return Built(states=states, inputs=(), outputs=(), fun=fun, output_fn=None,
                 resolved={"states": list(states), "function": system.function})


def load_function(spec: str, experiment_path: Path) -> Callable:
    """Import ``"file.py:name"`` (relative to the experiment file) and return the callable.

    This runs the user's own Python code, as MATLAB runs a function file; expressions never do.
    """
    key = "system.function"
    if ":" not in spec:
        raise ExperimentError(f"`{key}` is {spec!r}; write it as \"file.py:function_name\".", key=key)
    file_part, _, name = spec.rpartition(":")
    file = resolve_user_file(file_part, key, experiment_path)
    check_python_source(file_part, key)
    if not file.is_file():
        raise ExperimentError(f"`{key}`: the file {file_part!r} does not exist (looked for {file}).", key=key)
    if not name.isidentifier():
        raise ExperimentError(f"`{key}`: {name!r} is not a valid Python function name.", key=key)
    module_name = "odelab_user_" + hashlib.sha256(str(file).encode()).hexdigest()[:12]
    module = sys.modules.get(module_name)
    if module is None:
        # the source loader, whatever the file holds: never an extension module's loader
        spec_obj = importlib.util.spec_from_file_location(
            module_name, file, loader=importlib.machinery.SourceFileLoader(module_name, str(file)))
        if spec_obj is None or spec_obj.loader is None:
            raise ExperimentError(f"`{key}`: {file_part!r} cannot be imported as Python.", key=key)
        module = importlib.util.module_from_spec(spec_obj)
        try:
            spec_obj.loader.exec_module(module)
        except Exception as exc:
            raise ExperimentError(f"`{key}`: importing {file_part!r} raised {type(exc).__name__}: {exc}.",
                                  key=key) from None
        sys.modules[module_name] = module
    fn = getattr(module, name, None)
    if fn is None:
        names = [n for n in vars(module) if callable(vars(module)[n]) and not n.startswith("_")]
        close = difflib.get_close_matches(name, names, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ExperimentError(f"`{key}`: {file_part!r} has no function {name!r}.{hint}", key=key)
    if not callable(fn):
        raise ExperimentError(f"`{key}`: {name!r} in {file_part!r} is not callable.", key=key)
    return fn
