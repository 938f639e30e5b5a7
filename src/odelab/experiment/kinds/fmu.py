"""Building a system from an FMU (``[system] kind = "fmu"``, ``file = "Model.fmu"``).

The FMU is read through FMPy (:mod:`odelab.fmi.fmu`): its continuous states are the case's
states, its real, integer and boolean outputs the stored outputs, its parameters are set from
[parameters], and the inputs named in [inputs] are driven by their signals (the others keep
their start values). Loading an FMU runs its native code, so it is refused unless the run
allows it (``odelab run --allow-native``, :func:`odelab.fmi.allow_native`).
"""

from __future__ import annotations

import difflib
from dataclasses import replace
from pathlib import Path

import numpy as np

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.cases import Built
from odelab.experiment.limits import Limits, check_count

__all__ = ["build_fmu"]

_NOT_FOR_FMU = ("states", "equations", "function", "inputs", "outputs", "A", "B", "C", "D", "jacobian",
                "algebraic_loops")


def _check_names(given, known: dict, key: str, what: str, path: Path) -> None:
    for name in given:
        if name not in known:
            close = difflib.get_close_matches(name, list(known), n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            listed = ", ".join(list(known)[:20]) or "none"
            raise ExperimentError(f"`{key}.{name}`: {path.name} has no {what} {name!r} (its {what}s: {listed})."
                                  f"{hint}", key=f"{key}.{name}")


def build_fmu(model: schema.Experiment, params: dict[str, float], path: Path, limits: Limits) -> Built:
    """The Built system of an FMU case (checked names; the FMU opened once per file content)."""
    from odelab.experiment.userfiles import resolve_user_file
    from odelab.fmi import NATIVE_REFUSAL
    from odelab.fmi.fmu import open_fmu
    from odelab.fmi.native import native_allowed
    from odelab.fmi.simulate import FmuRun

    system = model.system
    for name in _NOT_FOR_FMU:
        if getattr(system, name) is not None:
            raise ExperimentError(f"`system.{name}` does not apply to kind = \"fmu\": the FMU declares its states, "
                                  "inputs and outputs; remove it.", key=f"system.{name}")
    if system.file is None:
        raise ExperimentError("kind = \"fmu\" needs `file`, the FMU to simulate, e.g. file = \"BouncingBall.fmu\".",
                              key="system.file")
    file = resolve_user_file(system.file, "system.file", path)
    if not native_allowed():
        raise ExperimentError(NATIVE_REFUSAL.format(name=Path(system.file).name), key="system.file")
    try:
        fmu = open_fmu(file)
    except InputError as exc:
        raise ExperimentError(exc.message, key="system.file") from None
    interface = system.interface or fmu.interfaces[0]
    if interface not in fmu.interfaces:
        raise ExperimentError(f"`system.interface` is {interface!r}, but {file.name} offers only "
                              f"{' and '.join(fmu.interfaces)}.", key="system.interface")
    try:
        fmu.adapter(interface)  # its binary for this machine, loaded now: a missing one is the file's error
    except InputError as exc:
        raise ExperimentError(exc.message, key="system.file") from None
    if not limits.allows("states", len(fmu.states)):
        check_count("states", len(fmu.states), "system.file", "states", limits)
    _check_names(params, fmu.parameters, "parameters", "parameter", file)
    inputs = {v.name: v for v in fmu.inputs}
    _check_names(model.inputs or {}, inputs, "inputs", "input", file)
    used = tuple(name for name in inputs if name in (model.inputs or {}))
    values = {fmu.parameters[name]: value for name, value in params.items()}
    states = tuple(v.name for v in fmu.states)
    outputs = tuple(v.name for v in fmu.outputs)
    clash = sorted(set(states + outputs) & set(params))
    if clash:
        raise ExperimentError(f"{clash[0]!r} is both a parameter and a state or output of {file.name}.",
                              key=f"parameters.{clash[0]}")
    x0 = np.array([v.start if v.start is not None else 0.0 for v in fmu.states], dtype=float)
    run_inputs = tuple(inputs[name] for name in used)
    run = FmuRun(model=_with_inputs(fmu, run_inputs), interface=interface, values=values)
    resolved = {"kind": "fmu", "file": system.file, "interface": interface, "fmi_version": f"{fmu.version}.0",
                "model": fmu.name, "states": list(states)}
    if used:
        resolved["inputs"] = list(used)
    if outputs:
        resolved["outputs"] = list(outputs)
    return Built(states=states, inputs=used, outputs=outputs, fun=None, output_fn=run.output_fn if outputs else None,
                 resolved=resolved, x0=x0, fmu=run)


def _with_inputs(fmu, inputs):
    """The FMU's model with only the inputs the case drives (the others keep their start values)."""
    return replace(fmu, inputs=tuple(inputs), _classes=fmu._classes)
