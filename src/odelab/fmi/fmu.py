"""An FMU as an odelab system, through FMPy (the field's Python FMU library).

:func:`open_fmu` checks and unpacks the archive (:mod:`.archive`), reads its model description
with FMPy and names what odelab needs: the continuous states (the variables the derivatives
belong to), the inputs, the outputs, the parameters and the event indicators. An
:class:`Adapter` gives FMI 2.0 and FMI 3.0 one vocabulary (set and get by name, derivatives,
event indicators, the event iteration), so :mod:`.simulate` steps either with odelab's solvers.
"""

from __future__ import annotations

import atexit
import ctypes
import hashlib
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from odelab.exceptions import InputError
from odelab.fmi.archive import FmuArchive, binary_for, open_archive

__all__ = ["FmuModel", "Adapter", "open_fmu"]

_KEY = "system.file"
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,199}")
_REAL = ("Real", "Float64", "Float32")
_INT = ("Integer", "Int32", "Int64", "Int8", "UInt8", "Int16", "UInt16", "UInt32", "UInt64", "Enumeration")
_BOOL = ("Boolean",)

# unpacked FMUs by (path, sha256): the cases and sweeps of a file share one; removed at exit
_OPENED: dict[tuple[str, str], "FmuModel"] = {}
_FOLDERS: list[Path] = []


@atexit.register
def _remove_folders() -> None:  # pragma: no cover - at interpreter exit
    for folder in _FOLDERS:
        shutil.rmtree(folder, ignore_errors=True)


@dataclass(frozen=True)
class Var:
    name: str
    vr: int
    type: str  # the FMI type's name: Real, Integer, Boolean (FMI 2); Float64, Int32... (FMI 3)
    causality: str
    variability: str
    start: float | None
    initial: str | None
    unit: str | None
    description: str | None


def _kind(type_name: str) -> str | None:
    if type_name in _REAL:
        return "real"
    if type_name in _INT:
        return "integer"
    if type_name in _BOOL:
        return "boolean"
    return None


def _start(v) -> float | None:
    if v.start is None:
        return None
    text = str(v.start).strip()
    if text in ("true", "false"):
        return 1.0 if text == "true" else 0.0
    try:
        return float(text.split()[0])
    except (ValueError, IndexError):
        return None


@dataclass(eq=False)
class FmuModel:
    """A checked, unpacked FMU and what odelab reads from its model description."""

    path: Path
    archive: FmuArchive
    md: object  # fmpy.model_description.ModelDescription
    version: int  # 2 or 3
    interfaces: tuple[str, ...]  # "model-exchange", "co-simulation"
    states: tuple[Var, ...]
    derivatives: tuple[Var, ...]
    inputs: tuple[Var, ...]
    outputs: tuple[Var, ...]
    parameters: dict[str, Var]
    n_indicators: int
    default: dict = field(default_factory=dict)  # startTime, stopTime, tolerance, stepSize
    _classes: dict = field(default_factory=dict, repr=False)

    @property
    def name(self) -> str:
        return self.md.modelName

    def units(self) -> dict[str, str]:
        return {v.name: v.unit for v in (*self.states, *self.inputs, *self.outputs, *self.parameters.values())
                if v.unit}

    def identifier(self, interface: str) -> str:
        part = self.md.modelExchange if interface == "model-exchange" else self.md.coSimulation
        return part.modelIdentifier

    def adapter(self, interface: str) -> "Adapter":
        """A new instance's adapter (the library is loaded once per process and interface)."""
        from fmpy import fmi2, fmi3

        cls = self._classes.get(interface)
        if cls is None:
            identifier = self.identifier(interface)
            binary_for(self.archive, identifier)  # a missing binary: its message, not FMPy's
            me = interface == "model-exchange"
            kind = ((fmi2.FMU2Model if me else fmi2.FMU2Slave) if self.version == 2
                    else (fmi3.FMU3Model if me else fmi3.FMU3Slave))
            kwargs = {"guid": self.md.guid}  # FMPy's name for FMI 3's instantiationToken too
            try:
                cls = kind(unzipDirectory=str(self.archive.folder), modelIdentifier=identifier,
                           instanceName="odelab", **kwargs)
            except Exception as exc:  # the library does not load (wrong architecture, missing symbols)
                raise InputError(f"{self.path.name}: its binary for this machine cannot be loaded ({exc}).",
                                 key=_KEY) from None
            self._classes[interface] = cls
        return Adapter(self, cls, interface)


class Adapter:
    """One FMU instance in FMI 2 or FMI 3, with one vocabulary."""

    def __init__(self, model: FmuModel, fmu, interface: str):
        self.model, self.fmu, self.interface = model, fmu, interface
        self.v3 = model.version == 3
        self.nx, self.nz = len(model.states), model.n_indicators
        self._x = np.zeros(max(self.nx, 1))
        self._dx = np.zeros(max(self.nx, 1))
        self._z = np.zeros(max(self.nz, 1))
        pointer = ctypes.POINTER(ctypes.c_double)
        self._px, self._pdx, self._pz = (a.ctypes.data_as(pointer) for a in (self._x, self._dx, self._z))

    # -- life cycle -------------------------------------------------------------------------
    def start(self, t0: float, tolerance: float | None, stop: float | None, values: dict[str, float]):
        """Instantiate, set ``values`` (parameters, start values, inputs by name), initialise."""
        fmu = self.fmu
        fmu.instantiate(loggingOn=False)
        if not self.v3:
            fmu.setupExperiment(tolerance=tolerance, startTime=t0, stopTime=stop)
        self.set(values)
        if self.v3:
            fmu.enterInitializationMode(tolerance=tolerance, startTime=t0, stopTime=stop)
        else:
            fmu.enterInitializationMode()
        fmu.exitInitializationMode()

    def close(self) -> None:
        try:
            self.fmu.terminate()
        except Exception:  # an instance in its error state cannot terminate; free it all the same
            pass
        # the instance only: FMPy's freeInstance also unloads the library, which the next case reuses
        (self.fmu.fmi3FreeInstance if self.v3 else self.fmu.fmi2FreeInstance)(self.fmu.component)
        self.fmu.component = None

    # -- variables ----------------------------------------------------------------------------
    def _call(self, verb: str, type_name: str):
        """FMPy's getter or setter (``verb`` "get"/"set") for a variable type."""
        if self.v3:
            name = "Int64" if type_name == "Enumeration" else type_name
        else:
            name = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean"}[type_name]
        return getattr(self.fmu, verb + name)

    def set(self, values: dict) -> None:
        """Set variables: :class:`Var` -> value (a number; integers rounded, booleans nonzero)."""
        groups: dict[str, tuple[list[int], list]] = {}
        for var, value in values.items():
            vrs, vals = groups.setdefault(var.type, ([], []))
            vrs.append(var.vr)
            vals.append(value)
        for type_name, (vrs, vals) in groups.items():
            kind = _kind(type_name)
            vals = [float(v) if kind == "real" else bool(v) if kind == "boolean" else int(round(v)) for v in vals]
            self._call("set", type_name)(vrs, vals)

    def get(self, variables) -> np.ndarray:
        """The values of ``variables`` (:class:`Var`) as floats."""
        out = np.empty(len(variables))
        for type_name in {v.type for v in variables}:
            idx = [i for i, v in enumerate(variables) if v.type == type_name]
            got = self._call("get", type_name)([variables[i].vr for i in idx])
            out[idx] = np.asarray(got, dtype=float)
        return out

    # -- Model Exchange ----------------------------------------------------------------------
    def set_time_state(self, t: float, x) -> None:
        self.fmu.setTime(float(t))
        if self.nx:
            self._x[: self.nx] = x
            self.fmu.setContinuousStates(self._px, self.nx)

    def states(self) -> np.ndarray:
        if not self.nx:
            return np.zeros(0)
        self.fmu.getContinuousStates(self._px, self.nx)
        return self._x[: self.nx].copy()

    def derivatives(self) -> np.ndarray:
        if self.v3:
            self.fmu.getContinuousStateDerivatives(self._pdx, self.nx)
        else:
            self.fmu.getDerivatives(self._pdx, self.nx)
        return self._dx[: self.nx].copy()

    def indicators(self) -> np.ndarray:
        self.fmu.getEventIndicators(self._pz, self.nz)
        return self._z[: self.nz].copy()

    def event_iteration(self) -> tuple[bool, bool, float | None]:
        """Update the discrete states until they settle: (terminate, states changed, next time event)."""
        changed = False
        for _ in range(10_000):
            if self.v3:
                need, terminate, _, values, defined, next_time = self.fmu.updateDiscreteStates()
            else:
                need, terminate, _, values, defined, next_time = self.fmu.newDiscreteStates()
            changed = changed or bool(values)
            if terminate or not need:
                return bool(terminate), changed, float(next_time) if defined else None
        raise InputError(f"{self.model.path.name}: its event iteration did not settle in 10,000 rounds.", key=_KEY)

    def enter_event_mode(self) -> None:
        self.fmu.enterEventMode()

    def enter_continuous_mode(self) -> None:
        self.fmu.enterContinuousTimeMode()

    def completed_step(self) -> tuple[bool, bool]:
        """(enter event mode, terminate) after an accepted step."""
        result = self.fmu.completedIntegratorStep()
        return bool(result[0]), bool(result[1])

    # -- Co-Simulation -----------------------------------------------------------------------
    def do_step(self, t: float, h: float) -> float | None:
        """One communication step; None if it completed, else the time the FMU stopped at (it asked to
        terminate: FMI 3's terminateSimulation, FMI 2's fmi2Discard with fmi2Terminated), as FMPy reads it."""
        if self.v3:
            _, terminate, _, last = self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            return float(last) if terminate else None
        from fmpy.fmi1 import FMICallException

        try:
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        except FMICallException as exc:
            if exc.status != 2 or not self.fmu.getBooleanStatus(3):  # fmi2Discard and fmi2Terminated
                raise
            return float(self.fmu.getRealStatus(2))  # fmi2LastSuccessfulTime
        return None


def _unit(v) -> str | None:
    unit = getattr(v, "unit", None)
    declared = getattr(v, "declaredType", None)
    return unit or (getattr(declared, "unit", None) if declared is not None else None)


def _variables(md) -> dict[int, Var]:
    out = {}
    for v in md.modelVariables:
        kind = _kind(v.type)
        if kind is None:
            continue
        out[id(v)] = Var(v.name, int(v.valueReference), v.type, v.causality or "local", v.variability or "continuous",
                         _start(v), v.initial, _unit(v), v.description)
    return out


def _read(path: Path, archive: FmuArchive) -> FmuModel:
    from fmpy import read_model_description

    try:
        md = read_model_description(str(archive.folder), validate=False)
    except Exception as exc:
        raise InputError(f"{path.name}: FMPy cannot read its model description ({str(exc)[:300]}).",
                         key=_KEY) from None
    version = 3 if str(md.fmiVersion).startswith("3") else 2 if str(md.fmiVersion).startswith("2") else 0
    if not version:
        raise InputError(f"{path.name}: it is an FMI {md.fmiVersion} FMU; odelab loads FMI 2.0 and 3.0.", key=_KEY)
    interfaces = tuple(name for name, part in (("model-exchange", md.modelExchange), ("co-simulation", md.coSimulation))
                       if part is not None)
    if not interfaces:
        only = " (only Scheduled Execution, which odelab does not run)" if getattr(md, "scheduledExecution", None) \
            else ""
        raise InputError(f"{path.name}: it offers neither Model Exchange nor Co-Simulation{only}.", key=_KEY)
    for part in (md.modelExchange, md.coSimulation):
        identifier = getattr(part, "modelIdentifier", None) if part is not None else ""
        if part is not None and not (isinstance(identifier, str) and _IDENTIFIER.fullmatch(identifier)):
            raise InputError(f"{path.name}: its modelIdentifier {str(identifier)[:80]!r} is not a C identifier, as the "
                             "standard asks (it names the binary to load); refusing to load it.", key=_KEY)
    arrays = [v.name for v in md.modelVariables if getattr(v, "dimensions", None)]
    if arrays:
        raise InputError(f"{path.name}: its variable {arrays[0]!r} is an array (FMI 3 dimensions); odelab loads FMUs "
                         "of scalar variables only, so far.", key=_KEY)
    table = _variables(md)
    derivatives, states = [], []
    for unknown in md.derivatives:
        der = unknown.variable
        state = der.derivative
        if id(der) not in table or state is None or id(state) not in table:
            raise InputError(f"{path.name}: its derivative {der.name!r} is not a real variable of a state.", key=_KEY)
        derivatives.append(table[id(der)])
        states.append(table[id(state)])
    state_names = {s.name for s in states}
    inputs = tuple(table[id(v)] for v in md.modelVariables if id(v) in table and v.causality == "input")
    outputs = tuple(table[id(v)] for v in md.modelVariables
                    if id(v) in table and v.causality == "output" and v.name not in state_names)
    parameters = {table[id(v)].name: table[id(v)] for v in md.modelVariables
                  if id(v) in table and v.causality == "parameter" and v.variability in ("fixed", "tunable")}
    default = {}
    if md.defaultExperiment is not None:
        for key in ("startTime", "stopTime", "tolerance", "stepSize"):
            value = getattr(md.defaultExperiment, key, None)
            if value is not None:
                default[key] = float(value)
    nz = int(md.numberOfEventIndicators or 0)
    return FmuModel(path=path, archive=archive, md=md, version=version, interfaces=interfaces, states=tuple(states),
                    derivatives=tuple(derivatives), inputs=inputs, outputs=outputs, parameters=parameters,
                    n_indicators=nz, default=default)


def open_fmu(path: Path) -> FmuModel:
    """The checked, unpacked FMU at ``path`` (one per file content and process)."""
    path = Path(path)
    try:
        digest = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() and \
            path.stat().st_size <= 200 * 2 ** 20 else ""
    except OSError:
        digest = ""
    key = (str(path.resolve()), digest)
    model = _OPENED.get(key)
    if model is None:
        try:
            import fmpy  # noqa: F401
        except ImportError:
            raise InputError("loading an FMU needs FMPy: install odelab's FMI extra (`pip install odelab[fmi]`, "
                             "or `pip install fmpy`).", key=_KEY) from None
        archive = open_archive(path)
        _FOLDERS.append(archive.folder)
        model = _read(path, archive)
        _OPENED[key] = model
    return model
