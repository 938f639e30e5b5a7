"""Writing an FMU: modelDescription.xml, the C sources, the binary built with the machine's C
compiler, and the zip.

The FMI plumbing is odelab's own small runtime (``c/odelab_fmi2.c``) compiled against the
Modelica Association's FMI 2.0 headers, which FMPy ships (``fmpy/c-code``): the standard's own
declarations, so a wrong signature is a compile error, not a crash in a host. Each FMU ships
its sources (``sources/``, with ``buildDescription.xml``) for other platforms.
"""

from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path

from odelab.exceptions import InputError
from odelab.fmi.model import ExportModel, c_model

__all__ = ["Exported", "build_fmu", "find_compiler", "model_description", "platform_folder"]

_C = Path(__file__).with_name("c")
_HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
            3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}
COMPILE_SECONDS = 120


@dataclass(frozen=True)
class Exported:
    """What :func:`build_fmu` wrote: the FMU, its model's name, the compiler and the seconds it took."""

    path: Path
    model: ExportModel
    compiler: str
    generate_seconds: float
    compile_seconds: float
    fmi: int = 2


def platform_folder(fmi: int = 2) -> str:
    """The binaries/ folder for this machine: FMI 2's linux64, darwin64, win64 (32-bit: linux32...);
    FMI 3's x86_64-linux, aarch64-darwin..."""
    bits = "64" if sys.maxsize > 2 ** 32 else "32"
    if fmi == 3:
        machine = platform.machine().lower()
        arch = {"amd64": "x86_64", "arm64": "aarch64"}.get(machine, machine)
        system = {"Linux": "linux", "Darwin": "darwin", "Windows": "windows"}.get(platform.system(), "linux")
        return f"{arch}-{system}"
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(platform.system(), "linux")
    return system + bits


def find_compiler() -> str:
    """The C compiler: $CC, else cc, gcc or clang on the PATH; a message saying how to get one."""
    wanted = [os.environ["CC"]] if os.environ.get("CC") else []
    for name in (*wanted, "cc", "gcc", "clang"):
        found = shutil.which(name)
        if found:
            return found
    raise InputError("no C compiler found (looked for cc, gcc and clang on the PATH): an FMU's binary is compiled "
                     "C. Install gcc (Debian/Ubuntu: `apt-get install gcc`; Fedora: `dnf install gcc`; macOS: "
                     "`xcode-select --install`) or set CC to a compiler.")


def _headers() -> Path:
    try:
        import fmpy
    except ImportError:
        raise InputError("exporting an FMU needs the FMI 2.0 headers that FMPy ships: install odelab's FMI extra "
                         "(`pip install odelab[fmi]`, or `pip install fmpy`).") from None
    folder = Path(fmpy.__file__).parent / "c-code"
    if not all((folder / h).is_file() for names in _HEADERS.values() for h in names):
        raise InputError(f"FMPy's FMI headers are missing from {folder}; reinstall fmpy.")
    return folder


def _number(value: float) -> str:
    return repr(float(value))


def _tool() -> str:
    try:
        from importlib.metadata import version

        return f"odelab {version('odelab')}"
    except Exception:  # pragma: no cover - not installed as a distribution
        return "odelab"


def model_description(m: ExportModel, fmi: int = 2) -> bytes:
    """modelDescription.xml of ``m`` (FMI 2.0, or 3.0): both interfaces, units, the DefaultExperiment."""
    if fmi == 3:
        return model_description3(m)
    tool = _tool()
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": m.name, "guid": m.guid, "description": m.description,
        "generationTool": tool, "variableNamingConvention": "flat",
        "numberOfEventIndicators": str(m.n_indicators)})
    common = {"modelIdentifier": m.identifier, "needsExecutionTool": "false",
              "canNotUseMemoryManagementFunctions": "true", "canGetAndSetFMUstate": "false",
              "canSerializeFMUstate": "false", "providesDirectionalDerivative": "false"}
    me = ET.SubElement(root, "ModelExchange", {**common, "completedIntegratorStepNotNeeded": "true"})
    ET.SubElement(ET.SubElement(me, "SourceFiles"), "File", {"name": "model.c"})
    cs = ET.SubElement(root, "CoSimulation", {**common, "canHandleVariableCommunicationStepSize": "true"})
    ET.SubElement(ET.SubElement(cs, "SourceFiles"), "File", {"name": "model.c"})
    _units_and_experiment(root, m)
    variables = ET.SubElement(root, "ModelVariables")
    for v in m.variables:
        attrs = {"name": v.name, "valueReference": str(v.vr), "causality": v.causality, "variability": v.variability}
        if v.description:
            attrs["description"] = v.description
        if v.initial:
            attrs["initial"] = v.initial
        sv = ET.SubElement(variables, "ScalarVariable", attrs)
        real = {}
        if v.start is not None:
            real["start"] = _number(v.start)
        if v.unit:
            real["unit"] = v.unit
        if v.derivative is not None:
            real["derivative"] = str(v.derivative)
        ET.SubElement(sv, "Real", real)
    index = {v.vr: i + 1 for i, v in enumerate(m.variables)}
    structure = ET.SubElement(root, "ModelStructure")
    outputs = [v for v in m.variables if v.causality == "output"]
    derivatives = [v for v in m.variables if v.derivative is not None]
    if outputs:
        block = ET.SubElement(structure, "Outputs")
        for v in outputs:
            ET.SubElement(block, "Unknown", {"index": str(index[v.vr])})
    if derivatives:
        block = ET.SubElement(structure, "Derivatives")
        for v in derivatives:
            ET.SubElement(block, "Unknown", {"index": str(index[v.vr])})
    unknowns = sorted((index[v.vr] for v in [*outputs, *derivatives]))
    if unknowns:
        block = ET.SubElement(structure, "InitialUnknowns")
        for i in unknowns:
            ET.SubElement(block, "Unknown", {"index": str(i)})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def _units_and_experiment(root, m: ExportModel) -> None:
    """The UnitDefinitions (every unit a variable names) and the DefaultExperiment, alike in FMI 2.0 and 3.0."""
    units = sorted({v.unit for v in m.variables if v.unit})
    if units:
        defs = ET.SubElement(root, "UnitDefinitions")
        for unit in units:
            ET.SubElement(defs, "Unit", {"name": unit})
    ET.SubElement(root, "DefaultExperiment", {"startTime": _number(m.start), "stopTime": _number(m.stop),
                                              "tolerance": _number(m.tolerance), "stepSize": _number(m.step)})


def model_description3(m: ExportModel) -> bytes:
    """modelDescription.xml (FMI 3.0): the same variables as FMI 2.0's, then the event indicators
    (FMI 3.0 names them as variables) and time, the independent variable; ``derivative`` by value
    reference."""
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": m.name, "instantiationToken": m.guid, "description": m.description,
        "generationTool": _tool(), "variableNamingConvention": "flat"})
    common = {"modelIdentifier": m.identifier, "needsExecutionTool": "false", "canGetAndSetFMUState": "false",
              "canSerializeFMUState": "false", "providesDirectionalDerivatives": "false",
              "providesAdjointDerivatives": "false"}
    ET.SubElement(root, "ModelExchange", {**common, "needsCompletedIntegratorStep": "false"})
    ET.SubElement(root, "CoSimulation", {**common, "canHandleVariableCommunicationStepSize": "true"})
    _units_and_experiment(root, m)
    variables = ET.SubElement(root, "ModelVariables")
    end = max((v.vr for v in m.variables), default=-1) + 1
    ET.SubElement(variables, "Float64", {"name": "time", "valueReference": str(end + m.n_indicators),
                                         "causality": "independent", "variability": "continuous"})
    for v in m.variables:
        attrs = {"name": v.name, "valueReference": str(v.vr), "causality": v.causality, "variability": v.variability}
        if v.description:
            attrs["description"] = v.description
        if v.initial:
            attrs["initial"] = v.initial
        if v.start is not None:
            attrs["start"] = _number(v.start)
        if v.unit:
            attrs["unit"] = v.unit
        if v.derivative is not None:
            attrs["derivative"] = str(v.derivative - 1)  # the state's value reference
        ET.SubElement(variables, "Float64", attrs)
    for k in range(m.n_indicators):
        ET.SubElement(variables, "Float64", {"name": f"event indicator {k + 1}", "valueReference": str(end + k),
                                             "causality": "local", "variability": "continuous"})
    structure = ET.SubElement(root, "ModelStructure")
    outputs = [v for v in m.variables if v.causality == "output"]
    derivatives = [v for v in m.variables if v.derivative is not None]
    for v in outputs:
        ET.SubElement(structure, "Output", {"valueReference": str(v.vr)})
    for v in derivatives:
        ET.SubElement(structure, "ContinuousStateDerivative", {"valueReference": str(v.vr)})
    for v in sorted([*outputs, *derivatives], key=lambda v: v.vr):
        ET.SubElement(structure, "InitialUnknown", {"valueReference": str(v.vr)})
    for k in range(m.n_indicators):
        ET.SubElement(structure, "EventIndicator", {"valueReference": str(end + k)})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def _build_description(m: ExportModel, fmi: int = 2) -> bytes:
    root = ET.Element("fmiBuildDescription", {"fmiVersion": f"{fmi}.0"})
    config = ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": m.identifier})
    files = ET.SubElement(config, "SourceFileSet", {"language": "C99"})
    ET.SubElement(files, "SourceFile", {"name": "model.c"})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def _compile(compiler: str, folder: Path, binary: Path) -> None:
    command = [compiler, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o", str(binary),
               str(folder / "model.c"), "-lm"]
    try:
        done = subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=COMPILE_SECONDS,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise InputError(f"the C compiler ({compiler}) did not finish within {COMPILE_SECONDS} s.") from None
    except OSError as exc:
        raise InputError(f"the C compiler ({compiler}) could not be started: {exc}.") from None
    if done.returncode != 0:
        raise InputError(f"the C compiler ({compiler}) failed on the generated model (a bug of odelab's "
                         f"generator; please report it): {done.stderr.strip()[:2000]}")


def build_fmu(m: ExportModel, output: Path, generate_seconds: float = 0.0, fmi: int = 2) -> Exported:
    """Write ``m`` as the FMU ``output`` (FMI ``fmi``.0): sources, binary for this machine, modelDescription.xml.

    Work files go to a temporary folder beside ``output`` (removed afterwards), and the FMU is
    written under a temporary name and renamed: nothing is left half-written."""
    output = Path(output).absolute()
    if output.suffix.lower() != ".fmu":
        raise InputError(f"the FMU's file name must end in .fmu; got {output.name!r}.", key="output")
    if not output.parent.is_dir():
        raise InputError(f"the folder {str(output.parent)!r} does not exist.", key="output")
    compiler = find_compiler()
    headers = _headers()
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=output.parent, prefix=".odelab-fmu-") as work:
        work = Path(work)
        sources = {"model.c": c_model(m, fmi).encode()}
        for name in (f"odelab_fmi{fmi}.c", "odelab_core.c", "odelab_model.h"):
            sources[name] = (_C / name).read_bytes()
        for name in _HEADERS[fmi]:
            sources[name] = (headers / name).read_bytes()
        for name, data in sources.items():
            (work / name).write_bytes(data)
        binary = work / f"{m.identifier}.so"
        _compile(compiler, work, binary)
        compile_seconds = time.perf_counter() - start
        partial = work / "model.fmu"
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", model_description(m, fmi))
            suffix = {"Darwin": ".dylib", "Windows": ".dll"}.get(platform.system(), ".so")
            z.write(binary, f"binaries/{platform_folder(fmi)}/{m.identifier}{suffix}")
            for name, data in sources.items():
                z.writestr(f"sources/{name}", data)
            z.writestr("sources/buildDescription.xml", _build_description(m, fmi))
        os.replace(partial, output)
    return Exported(output, m, compiler, generate_seconds, compile_seconds, fmi)
