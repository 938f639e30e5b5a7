"""Opening an FMU someone handed you: the zip and its modelDescription.xml checked before any
of it is used, then unpacked by odelab (not by a library) into a private folder.

Each check is one message (an :class:`~odelab.exceptions.InputError` naming ``system.file``):
not a zip, too large, a zip bomb (members that inflate far beyond their compressed size, or
too many), a member outside the archive (``../``, an absolute path, a link), no
modelDescription.xml or an oversized one, XML with a DOCTYPE or entities (the billion laughs),
absurd counts of variables or event indicators, and a binary missing for this platform.
"""

from __future__ import annotations

import os
import platform
import stat
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from odelab.exceptions import InputError

__all__ = ["FmuArchive", "open_archive", "LIMITS"]

#: Bounds checked before anything is unpacked.
LIMITS = {
    "file_bytes": 200 * 2 ** 20,  # the .fmu itself
    "members": 5_000,
    "unpacked_bytes": 500 * 2 ** 20,  # all members together, as the zip declares them
    "ratio": 200,  # a member inflating more than this many times its compressed size is a bomb
    "description_bytes": 20 * 2 ** 20,  # modelDescription.xml
    "variables": 100_000,
    "event_indicators": 10_000,
}

_KEY = "system.file"


@dataclass(frozen=True)
class FmuArchive:
    """An unpacked, checked FMU: its folder (removed with the object's owner), its model
    description (FMPy's reading) and the binary's path for this platform."""

    path: Path
    folder: Path
    fmi_version: str
    description: object  # fmpy.model_description.ModelDescription
    binaries: tuple[str, ...]


def _fail(path: Path, why: str):
    raise InputError(f"{path.name}: {why}", key=_KEY)


def _check_members(path: Path, z: zipfile.ZipFile) -> list[zipfile.ZipInfo]:
    infos = z.infolist()
    if len(infos) > LIMITS["members"]:
        _fail(path, f"the archive holds {len(infos):,} files; an FMU of odelab's has at most "
                    f"{LIMITS['members']:,} (a zip bomb?).")
    total = 0
    for info in infos:
        name = info.filename
        parts = PurePosixPath(name.replace("\\", "/")).parts
        if name.startswith(("/", "\\")) or ".." in parts or (parts and ":" in parts[0]):
            _fail(path, f"the member {name!r} points outside the archive; refusing to unpack it.")
        mode = info.external_attr >> 16
        if stat.S_ISLNK(mode):
            _fail(path, f"the member {name!r} is a symbolic link; refusing to unpack it.")
        total += info.file_size
        if info.file_size > LIMITS["ratio"] * max(info.compress_size, 1) and info.file_size > 2 ** 20:
            _fail(path, f"the member {name!r} inflates {info.file_size / max(info.compress_size, 1):,.0f} times "
                        f"(to {info.file_size:,} bytes): a zip bomb; refusing to unpack it.")
    if total > LIMITS["unpacked_bytes"]:
        _fail(path, f"the archive unpacks to {total:,} bytes, over odelab's limit of {LIMITS['unpacked_bytes']:,} "
                    "(a zip bomb?).")
    return infos


def _read_description(path: Path, data: bytes) -> ET.Element:
    head = data[:4096].lower()
    if b"<!doctype" in data.lower() or b"<!entity" in head:
        _fail(path, "its modelDescription.xml declares a DOCTYPE or entities, which an FMU's model description "
                    "never needs (and which can expand without bound); refusing to read it.")
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        _fail(path, f"its modelDescription.xml is not well-formed XML ({exc}).")
    if root.tag != "fmiModelDescription":
        _fail(path, f"its modelDescription.xml's root is <{root.tag}>, not <fmiModelDescription>.")
    count = sum(1 for e in root.iter() if e.tag in ("ScalarVariable", "Float64", "Float32", "Int32", "Int64",
                                                      "Boolean", "String", "Int8", "UInt8", "Int16", "UInt16",
                                                      "UInt32", "UInt64", "Enumeration", "Binary", "Clock"))
    if count > LIMITS["variables"]:
        _fail(path, f"its model description declares {count:,} variables; odelab loads at most "
                    f"{LIMITS['variables']:,}.")
    indicators = root.get("numberOfEventIndicators", "0")
    try:
        n = int(indicators)
    except ValueError:
        _fail(path, f"its numberOfEventIndicators is {indicators[:40]!r}, not a whole number.")
    if not 0 <= n <= LIMITS["event_indicators"]:
        _fail(path, f"it declares {n:,} event indicators; odelab takes between 0 and "
                    f"{LIMITS['event_indicators']:,}.")
    return root


def _platform() -> tuple[str, str]:
    """This machine's binaries/ folder in FMI 2 and in FMI 3, and the library suffix."""
    machine = platform.machine().lower()
    arch3 = {"x86_64": "x86_64", "amd64": "x86_64", "aarch64": "aarch64", "arm64": "aarch64"}.get(machine, machine)
    system = {"Linux": ("linux", "linux"), "Darwin": ("darwin", "darwin"), "Windows": ("win", "windows")}.get(
        platform.system(), ("linux", "linux"))
    bits = "64" if sys.maxsize > 2 ** 32 else "32"
    return system[0] + bits, f"{arch3}-{system[1]}"


def open_archive(path: Path, folder: Path | None = None) -> FmuArchive:
    """Check and unpack the FMU ``path`` into ``folder`` (default: a new temporary folder)."""
    path = Path(path)
    if not path.is_file():
        _fail(path, f"no such file (looked for {path}).")
    size = path.stat().st_size
    if size > LIMITS["file_bytes"]:
        _fail(path, f"the file has {size:,} bytes; odelab loads FMUs of at most {LIMITS['file_bytes']:,}.")
    try:
        z = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        _fail(path, f"not an FMU: an FMU is a zip archive, and this one cannot be read as one ({exc}).")
    with z:
        infos = _check_members(path, z)
        names = {i.filename for i in infos}
        if "modelDescription.xml" not in names:
            _fail(path, "not an FMU: it has no modelDescription.xml at its top level.")
        md = z.getinfo("modelDescription.xml")
        if md.file_size > LIMITS["description_bytes"]:
            _fail(path, f"its modelDescription.xml has {md.file_size:,} bytes; odelab reads at most "
                        f"{LIMITS['description_bytes']:,}.")
        root = _read_description(path, z.read(md))
        version = root.get("fmiVersion", "")
        folder = Path(tempfile.mkdtemp(prefix="odelab-fmu-")) if folder is None else folder
        for info in infos:
            target = folder / info.filename
            if info.is_dir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            with z.open(info) as src, open(target, "wb") as dst:
                remaining = info.file_size + 1
                while True:
                    chunk = src.read(1 << 20)
                    if not chunk:
                        break
                    remaining -= len(chunk)
                    if remaining < 0:  # the member inflates beyond the size it declares
                        _fail(path, f"the member {info.filename!r} inflates beyond its declared size (a zip bomb).")
                    dst.write(chunk)
            os.chmod(target, 0o700 if info.filename.startswith("binaries/") else 0o600)
    binaries = tuple(sorted({PurePosixPath(n).parts[1] for n in names
                             if n.startswith("binaries/") and len(PurePosixPath(n).parts) > 2}))
    return FmuArchive(path=path, folder=folder, fmi_version=version, description=root, binaries=binaries)


def binary_for(archive: FmuArchive, identifier: str) -> Path:
    """The FMU's shared library for this machine, or the message saying which platforms it has."""
    v2, v3 = _platform()
    platform_folder = v3 if archive.fmi_version.startswith("3") else v2
    suffix = {"darwin": ".dylib", "windows": ".dll", "win": ".dll"}.get(platform_folder.split("-")[-1].rstrip("3264"),
                                                                       ".so")
    library = archive.folder / "binaries" / platform_folder / f"{identifier}{suffix}"
    if not library.is_file():
        has = ", ".join(archive.binaries) or "none (a source-only FMU)"
        _fail(archive.path, f"it has no binary for this machine (binaries/{platform_folder}/{identifier}{suffix}); "
                            f"its binaries: {has}. Build it for this platform from its sources, or ask its "
                            "supplier for one.")
    return library
