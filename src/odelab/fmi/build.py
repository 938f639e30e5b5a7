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
_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
COMPILE_SECONDS = 120


@dataclass(frozen=True)
class Exported:
    """What :func:`build_fmu` wrote: the FMU, its model's name, the compiler and the seconds it took."""

    path: Path
    model: ExportModel
    compiler: str
    generate_seconds: float
    compile_seconds: float


def platform_folder() -> str:
    """FMI 2's binaries/ folder for this machine: linux64, darwin64, win64 (32-bit: linux32...)."""
    bits = "64" if sys.maxsize > 2 ** 32 else "32"
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
    if not all((folder / h).is_file() for h in _HEADERS):
        raise InputError(f"FMPy's FMI headers are missing from {folder}; reinstall fmpy.")
    return folder


def _number(value: float) -> str:
    return repr(float(value))


def model_description(m: ExportModel) -> bytes:
    """modelDescription.xml (FMI 2.0) of ``m``: both interfaces, units, the DefaultExperiment."""
    try:
        from importlib.metadata import version

        tool = f"odelab {version('odelab')}"
    except Exception:  # pragma: no cover - not installed as a distribution
        tool = "odelab"
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
    units = sorted({v.unit for v in m.variables if v.unit})
    if units:
        defs = ET.SubElement(root, "UnitDefinitions")
        for unit in units:
            ET.SubElement(defs, "Unit", {"name": unit})
    ET.SubElement(root, "DefaultExperiment", {"startTime": _number(m.start), "stopTime": _number(m.stop),
                                              "tolerance": _number(m.tolerance), "stepSize": _number(m.step)})
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


def _build_description(m: ExportModel) -> bytes:
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "2.0"})
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


def build_fmu(m: ExportModel, output: Path, generate_seconds: float = 0.0) -> Exported:
    """Write ``m`` as the FMU ``output``: sources, binary for this machine, modelDescription.xml.

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
        sources = {"model.c": c_model(m).encode()}
        for name in ("odelab_fmi2.c", "odelab_model.h"):
            sources[name] = (_C / name).read_bytes()
        for name in _HEADERS:
            sources[name] = (headers / name).read_bytes()
        for name, data in sources.items():
            (work / name).write_bytes(data)
        binary = work / f"{m.identifier}.so"
        _compile(compiler, work, binary)
        compile_seconds = time.perf_counter() - start
        partial = work / "model.fmu"
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", model_description(m))
            suffix = {"darwin": ".dylib", "win": ".dll"}.get(platform_folder()[:-2], ".so")
            z.write(binary, f"binaries/{platform_folder()}/{m.identifier}{suffix}")
            for name, data in sources.items():
                z.writestr(f"sources/{name}", data)
            z.writestr("sources/buildDescription.xml", _build_description(m))
        os.replace(partial, output)
    return Exported(output, m, compiler, generate_seconds, compile_seconds)
