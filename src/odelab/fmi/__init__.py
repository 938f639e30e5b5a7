"""FMI: odelab models out as FMUs any simulation tool loads, and FMUs in as odelab systems.

Export (:func:`export`): a case whose equations odelab owns (equations, a state-space model, a
derived network, a diagram without discrete or Python blocks) becomes an FMU with both Model Exchange and Co-Simulation interfaces, its C
generated from odelab's checked expression trees (:mod:`.ccode`, :mod:`.model`) and compiled
with the machine's C compiler (:mod:`.export`).

Import (:func:`load`, ``[system] kind = "fmu"``): an FMU simulated through FMPy, its Model
Exchange interface stepped by odelab's solvers (:mod:`.fmu`, :mod:`.simulate`). Loading an FMU
runs its native code, so it is refused unless the user allowed it (:func:`allow_native`).
"""

from __future__ import annotations

import time
from pathlib import Path

from odelab.exceptions import InputError

__all__ = ["export", "load", "allow_native", "native_allowed"]


def _pick_case(experiment, case: str | None):
    cases = getattr(experiment, "cases", None)
    if cases is None:  # a Case already
        return experiment
    if case is None:
        return cases[0]
    for c in cases:
        if c.name == case:
            return c
    names = ", ".join(c.name for c in cases)
    raise InputError(f"{experiment.name} has no case {case!r}; its cases: {names}.", key="case")


def export(experiment, output, *, case: str | None = None, fmi: int = 2, name: str | None = None):
    """Export one case of a loaded experiment as an FMU (FMI 2.0 or 3.0, Model Exchange and Co-Simulation).

    Parameters
    ----------
    experiment
        A :class:`~odelab.experiment.cases.LoadedExperiment` (``load_experiment(path)``) or one
        of its cases.
    output
        The ``.fmu`` file to write (its folder must exist).
    case
        The case's name; by default the first case.
    fmi
        The FMI version: 2 (FMI 2.0, which every tool of the field loads) or 3 (FMI 3.0).
    name
        The FMU's model name (default: the experiment's name).

    Returns
    -------
    odelab.fmi.build.Exported
        The path written, the model, the compiler and the seconds generating and compiling took.
    """
    from odelab.fmi.build import build_fmu
    from odelab.fmi.model import model_of_case

    if fmi not in (2, 3):
        raise InputError(f"`fmi` must be 2 or 3; got {fmi!r}.")
    chosen = _pick_case(experiment, case)
    start = time.perf_counter()
    model = model_of_case(chosen, name=name)
    return build_fmu(model, Path(output), generate_seconds=time.perf_counter() - start, fmi=fmi)


def load(path, *, allow_native: bool = False, **kwargs):
    """An FMU as an odelab :class:`~odelab.fmi.fmu.FMU` (through FMPy); ``allow_native`` must be
    True: loading an FMU runs its native code."""
    from odelab.fmi.fmu import open_fmu

    if not allow_native:
        raise InputError(NATIVE_REFUSAL.format(name=Path(path).name), key="system.file")
    return open_fmu(Path(path), **kwargs)


NATIVE_REFUSAL = ("{name} is an FMU: simulating it runs the machine code inside it, with your permissions, "
                  "as any program you start. Run it only if you trust where it came from, and then say so: "
                  "`odelab run --allow-native` (Python: allow_native=True).")

from odelab.fmi.native import allow_native, native_allowed  # noqa: E402
