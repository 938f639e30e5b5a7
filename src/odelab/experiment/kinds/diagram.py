"""Building a diagram from an experiment file's [blocks] table (``kind = "diagram"``).

Each entry of [blocks] is a block: its ``type`` is a block type of
:data:`odelab.systems.diagram.BLOCKS` or an input signal type (step, ramp, sine, pulse, table,
expression, constant), which makes it a source built exactly as [inputs] are
(:func:`~odelab.experiment.build.build_signal`). Numbers in every numeric key may be
expressions of [parameters]. Every message names ``blocks.<name>.<key>``.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

import numpy as np

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.build import SIGNAL_KEYS, _matrix, build_signal
from odelab.experiment.cases import Built
from odelab.experiment.fields import constant
from odelab.experiment.userfiles import resolve_user_file

__all__ = ["build_diagram", "block_types"]

_TOML_KIND = {bool: "a boolean", int: "a number", float: "a number", str: "a string", list: "an array",
              dict: "a table"}


def block_types() -> list[str]:
    """Every TOML block type: the signal sources, then the blocks of the registry."""
    from odelab.systems.diagram.blocks import BLOCKS

    return [*SIGNAL_KEYS, *BLOCKS]


def _got(value) -> str:
    text = str(value).lower() if isinstance(value, bool) else repr(value)
    return f"{text} ({_TOML_KIND.get(type(value), type(value).__name__)})"


def _value(kind: str, value, key: str, params: dict[str, float]):
    """A key's value converted by its declared kind (expressions of parameters evaluated)."""
    if kind == "number":
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise ExperimentError(f"`{key}` must be a number or an expression string; got {_got(value)}.", key=key)
        return constant(value, key, params)
    if kind == "numbers":
        if isinstance(value, list):
            return [_value("number", v, f"{key}[{i}]", params) for i, v in enumerate(value)]
        return _value("number", value, key, params)
    if kind == "matrix":
        if isinstance(value, bool) or not isinstance(value, (int, float, str, list)):
            raise ExperimentError(f"`{key}` must be a number, an expression or a matrix [[...]]; got {_got(value)}.",
                                  key=key)
        return _matrix(value, key, params)
    if kind in ("text", "expression"):
        if kind == "expression" and isinstance(value, (int, float)) and not isinstance(value, bool):
            return str(value)
        if not isinstance(value, str):
            raise ExperimentError(f"`{key}` must be a string; got {_got(value)}.", key=key)
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            raise ExperimentError(f"`{key}` must be true or false; got {_got(value)}.", key=key)
        return value
    if kind == "count":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ExperimentError(f"`{key}` must be a whole number; got {_got(value)}.", key=key)
        return value
    if kind == "names":
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ExperimentError(f"`{key}` must be an array of names, e.g. [\"y\"]; got {_got(value)}.", key=key)
        return value
    raise AssertionError(kind)  # pragma: no cover - a Key with an unknown kind


def _source(name: str, spec: dict, path: Path, params: dict[str, float], max_rows: int | None = None):
    from odelab.signals import SIGNALS
    from odelab.systems.diagram.blocks import Source

    kind = spec["type"]
    key = f"blocks.{name}"
    given = {}
    for k, v in spec.items():
        if k == "type":
            continue
        if k in ("input", "inputs"):
            raise ExperimentError(f"`{key}.{k}`: a {kind} block is a source and takes no input; remove `{k}`.",
                                  key=f"{key}.{k}")
        if k not in SIGNAL_KEYS[kind]:
            given[k] = v  # build_signal names the keys that do not apply
        elif SIGNALS[kind].KEYS[k].kind != "number":  # a file name, a method's name, an expression of t, samples
            key_kind = SIGNALS[kind].KEYS[k].kind
            given[k] = _value(key_kind if key_kind in ("expression", "numbers") else "text", v, f"{key}.{k}", params)
        else:
            given[k] = _value("number", v, f"{key}.{k}", params)
    signal, values = build_signal(kind, given, key=key, path=path, params=params, what="block", max_rows=max_rows)
    shown = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in values.items())
    return Source(signal, kind=kind, label=f"{kind}" + (f"\n{shown}" if shown else ""))


def _table_file(values: dict, key: str, path: Path, max_rows: int | None):
    """A lookup table's ``file``: (breakpoints, values) from a CSV of two columns."""
    from odelab import signals as sg

    csv = resolve_user_file(values["file"], f"{key}.file", path)
    if not csv.is_file():
        raise ExperimentError(f"`{key}.file`: {values['file']!r} does not exist (looked for {csv}).",
                              key=f"{key}.file")
    for other in ("breakpoints", "table"):
        if other in values:
            raise ExperimentError(f"`{key}.{other}`: give either `file` or `breakpoints` and `table`, not both.",
                                  key=f"{key}.{other}")
    try:
        table = sg.Table.from_csv(csv, max_rows=max_rows)
    except InputError as exc:
        text = exc.message[:1].lower() + exc.message[1:]
        text = text.replace("(t, u)", "(breakpoint, value)").replace("t, u", "breakpoint, value")
        raise ExperimentError(f"`{key}.file` {values['file']!r}: {text}", key=f"{key}.file") from None
    return np.array(table.t), np.array(table.values)


def _aliased(cls, spec: dict, key: str) -> dict:
    """The block's keys under their own names: MATLAB's spellings (a PID's ``Kp``) taken as the key they name."""
    if not cls.ALIASES:
        return spec
    out: dict[str, Any] = {}
    for k, v in spec.items():
        own = cls.ALIASES.get(k, k)
        if own in out:
            raise ExperimentError(f"`{key}` gives `{own}` twice (as `{own}` and as MATLAB's `{k}`); keep one.",
                                  key=f"{key}.{k}")
        out[own] = v
    return out


def _unknown_keys(cls, key: str, unknown: list[str]) -> ExperimentError:
    """Every key of a block that does not apply, in one message, each with its nearest key."""
    names = ["input", "inputs", *cls.KEYS, *cls.ALIASES]
    known = ", ".join(["input" if cls.INPUTS[1] == 1 else "inputs", *cls.KEYS]) if not cls.SOURCE \
        else ", ".join(cls.KEYS) or "no other keys"
    if cls.ALIASES:
        known += " (" + ", ".join(f"{a} for {k}" for a, k in cls.ALIASES.items()) + ", as MATLAB writes them)"
    def nearest(k: str) -> str | None:
        close = difflib.get_close_matches(k, names, n=1) or difflib.get_close_matches(
            k.lower(), [n.lower() for n in names], n=1)
        return next((n for n in names if n.lower() == close[0].lower()), None) if close else None

    if len(unknown) == 1:  # one key: the fix after the list
        close = nearest(unknown[0])
        hint = f" Did you mean `{close}`?" if close else ""
        return ExperimentError(f"`{key}.{unknown[0]}` does not apply to a {cls.TYPE} block; a {cls.TYPE} takes "
                               f"{known}.{hint}", key=f"{key}.{unknown[0]}")
    parts = [f"`{key}.{k}`" + (f" (did you mean `{nearest(k)}`?)" if nearest(k) else "") for k in unknown]
    listed = " and ".join(parts) if len(parts) == 2 else ", ".join(parts[:-1]) + " and " + parts[-1]
    return ExperimentError(f"{listed} do not apply to a {cls.TYPE} block; a {cls.TYPE} takes {known}.",
                           key=f"{key}.{unknown[0]}")


def _block(name: str, spec: dict, params: dict[str, float], path: Path | None = None, max_rows: int | None = None):
    from odelab.systems.diagram.blocks import BLOCKS, BlockError, Fcn
    from odelab.systems.diagram.graph import located
    from odelab.systems.diagram.tables import LookupTable

    cls = BLOCKS[spec["type"]]
    key = f"blocks.{name}"
    values: dict[str, Any] = {}
    texts = {}
    spec = _aliased(cls, spec, key)
    unknown = [k for k in spec if k not in ("type", "input", "inputs") and k not in cls.KEYS]
    if unknown:
        raise _unknown_keys(cls, key, unknown)
    for k, v in spec.items():
        if k == "type":
            continue
        if k == "input":
            values[k] = _value("text", v, f"{key}.input", params)
        elif k == "inputs":
            values[k] = _value("names", v, f"{key}.inputs", params)
        else:
            values[k] = _value(cls.KEYS[k].kind, v, f"{key}.{k}", params)
            texts[k] = v
    if isinstance(values.get("gain"), np.ndarray) and values["gain"].size == 1:
        values["gain"] = float(values["gain"].reshape(()))
    extra = {}
    if cls is LookupTable and values.get("file") is not None and path is not None:
        extra["data"] = _table_file(values, key, path, max_rows)
    try:
        block = cls(parameters=params, **values) if cls is Fcn else cls(**values, **extra)
    except BlockError as exc:
        raise located(exc, name) from None
    block.texts = texts
    return block


def _declared_size(kind, spec: dict) -> tuple[str, int] | None:
    """A size a block's parameters declare before anything is built: a demux's ``outputs`` (its
    ports), a transfer function's order (its states; its realisation's A is order x order)."""
    if kind == "demux":
        n = spec.get("outputs")
        return ("outputs", n) if isinstance(n, int) and not isinstance(n, bool) else None
    if kind == "transfer-fcn" and isinstance(spec.get("den"), list):
        return "den", len(spec["den"]) - 1
    return None


def build_diagram(model: schema.Experiment, params: dict[str, float], path: Path, t0: float, *,
                  max_rows: int | None = None, limits=None) -> Built:
    """A system from [blocks]: linear diagrams become StateSpace systems, others NonlinearSystem.

    ``limits`` (the run's budgets) bounds the states and ports the blocks declare, checked
    before the blocks are built (a demux of 10^12 outputs, 10,000 integrators)."""
    from odelab.experiment.limits import DEFAULT_LIMITS, check_count

    limits = limits or DEFAULT_LIMITS
    from odelab.systems.diagram.compile import CompiledDiagram
    from odelab.systems.diagram.graph import wire

    system = model.system
    for field_name in ("equations", "function", "inputs", "A", "B", "C", "D"):
        if getattr(system, field_name) is not None:
            raise ExperimentError(f"`system.{field_name}` does not apply to kind = \"diagram\": a diagram is its "
                                  "[blocks]; remove it (sources are blocks too).", key=f"system.{field_name}")
    if model.inputs:
        raise ExperimentError("[inputs] does not apply to kind = \"diagram\": write each source as a block, e.g. "
                              "force = { type = \"step\", time = 0 } under [blocks].", key="inputs")
    if not model.blocks:
        raise ExperimentError("kind = \"diagram\" needs a [blocks] table: one block per line, e.g. "
                              "force = { type = \"step\" }, gain = { type = \"gain\", gain = 2, input = \"force\" }.",
                              key="blocks")
    if system.outputs is not None and not isinstance(system.outputs, dict):
        raise ExperimentError("`system.outputs` of a diagram maps output names to blocks, e.g. "
                              "outputs = { y = \"sensor\" }.", key="system.outputs")
    outputs = dict(system.outputs or {})
    for out, ref in outputs.items():
        # names are identifiers, as everywhere else: "a\nb,c" would be stored, then break the
        # trajectory table's header and be skipped by the report
        if not (isinstance(out, str) and out.isascii() and out.isidentifier()):
            raise ExperimentError(f"`system.outputs`: {out!r} is not a valid output name; use ASCII letters, digits "
                                  "and `_`, starting with a letter (e.g. `y`, `omega`).", key="system.outputs")
        if not isinstance(ref, str):
            raise ExperimentError(f"`system.outputs.{out}` must name a block (or block.port); got {_got(ref)}.",
                                  key=f"system.outputs.{out}")
    types = block_types()
    blocks = {}
    for name, spec in model.blocks.items():
        key = f"blocks.{name}"
        kind = spec.get("type")
        if kind is None:
            raise ExperimentError(f"`{key}.type` is required: one of {', '.join(types)}.", key=f"{key}.type")
        if kind not in types:
            close = difflib.get_close_matches(str(kind), types, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ExperimentError(f"`{key}.type` is {_got(kind)}; block types are {', '.join(types)}.{hint}",
                                  key=f"{key}.type")
        size = _declared_size(kind, spec)
        if size is not None:
            what = "ports" if size[0] == "outputs" else "states (the transfer function's order)"
            check_count("states", size[1], f"{key}.{size[0]}", "", limits, asked=f"declares {size[1]:,} {what}")
        try:
            blocks[name] = (_source(name, spec, path, params, max_rows) if kind in SIGNAL_KEYS
                            else _block(name, spec, params, path, max_rows))
        except InputError as exc:
            raise exc.located(key=key) from None
    nstates = sum(b.nstates for b in blocks.values())
    check_count("states", nstates, "blocks", "", limits,
                asked=f"hold {nstates:,} states in {sum(1 for b in blocks.values() if b.nstates):,} blocks")
    loops = system.algebraic_loops or "warning"
    compiled = CompiledDiagram(wire(blocks, outputs, "solve" if loops == "solve" else loops), states=system.states,
                               t0=t0, zero_crossing=model.solver.zero_crossing,
                               loop_note=loops != "none")  # DiagramError: keyed
    discrete = [n for n, b in blocks.items() if b.DISCRETE]
    for section in ("analysis", "linearize"):
        if discrete and getattr(model, section, None) is not None:
            raise ExperimentError(f"[{section}] linearises a continuous-time model, and block `{discrete[0]}` "
                                  f"({blocks[discrete[0]].TYPE}) is discrete: the linear model of a sampled-data "
                                  "diagram is a discrete-time system, which odelab does not build. Remove "
                                  f"[{section}], or linearise the continuous plant on its own.", key=section)
    limiters = [n for n, b in blocks.items() if getattr(b, "NEEDS_SLOPE", False)]
    for section in ("analysis", "linearize"):
        if limiters and getattr(model, section, None) is not None:
            raise ExperimentError(f"[{section}] linearises the diagram about an operating point, and block "
                                  f"`{limiters[0]}` ({blocks[limiters[0]].TYPE}) has no linear model of its own "
                                  "(where it follows its input it is a gain of 1, as Simulink's linmod takes it). "
                                  f"For the analysis, replace it by a gain of 1 (`type = \"gain\", gain = 1`), or "
                                  f"remove [{section}].", key=section)
    from odelab.systems.diagram.delay import TransportDelay

    if any(isinstance(b, TransportDelay) for b in blocks.values()):  # delay equations, run by dde23
        from odelab.experiment.kinds.delays import build_delay_diagram

        return build_delay_diagram(model, compiled, outputs, t0)
    sys_obj = compiled.system
    resolved = {"kind": "diagram", "outputs": outputs}
    if system.states is not None:
        resolved["states"] = list(system.states)
    output_fn = compiled.output_many if compiled.outputs else None
    fun = None
    if not compiled.inputs:
        fun = compiled.dynamics  # a bound method: pickles with the diagram
    # the compiled backend runs a diagram of linear blocks as its state-space model, any other
    # block by block from generated code (nothing is compiled unless that backend runs)
    from odelab.solvers.compiled import CompiledSystem

    if compiled.linear:
        fast = CompiledSystem.linear(sys_obj.A, compiled.states, sys_obj.B, compiled.inputs)
    else:
        from odelab.systems.diagram.codegen import diagram_source, why_not

        reason = why_not(compiled)
        data: list[float] = []
        body = [] if reason else diagram_source(compiled, data, 2 if compiled.inputs else 0)
        fast = CompiledSystem.generated(compiled.states, compiled.inputs, body, data, unsupported=reason)
    return Built(states=compiled.states, inputs=compiled.inputs, outputs=compiled.outputs, fun=fun,
                 output_fn=output_fn, resolved=resolved, linear=compiled.linear, model=sys_obj,
                 x0=compiled.x0, signals=compiled.signals, diagram=compiled, compiled=fast)
