"""The TOML reader: an experiment file's bytes read and parsed safely (size, encoding, nesting depth).

Every limit here is checked before the work it protects: the size before the file is read
(so ``odelab run /dev/zero`` stops at once), the encoding before parsing, and the nesting
depth before anything recursive (the TOML parser itself, the case merge, the schema) walks
the data. Each failure is one :class:`~odelab.exceptions.ExperimentError` saying what to do.
"""

from __future__ import annotations

import codecs
import stat
import tomllib
from pathlib import Path

from odelab.exceptions import ExperimentError
from odelab.formats.base import Document

__all__ = ["MAX_FILE_BYTES", "MAX_NESTING", "read", "read_toml", "read_bytes", "parse_toml", "nesting_depth"]

MAX_FILE_BYTES = 1_000_000
"""Experiment files are at most 1 MB (the lab's are about 1 kB)."""

MAX_NESTING = 16
"""Tables and arrays nest at most 16 deep (the deepest key odelab knows, system.blocks.x.params, is 4)."""

_UTF16_BOMS = (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)
_UTF32_BOMS = (codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)


def read(path: Path, options=None) -> Document:
    """The :mod:`odelab.formats` reader of ``.toml`` files (``options`` are for importers: unused)."""
    data, raw = read_toml(path)
    return Document(path=Path(path), data=data, raw=raw)


def read_toml(path: Path) -> tuple[dict, bytes]:
    """Read and parse a TOML file, turning every failure into an ExperimentError."""
    raw = read_bytes(path, limit=MAX_FILE_BYTES, too_big=_too_big)
    return parse_toml(raw, str(path)), raw


def read_bytes(path: Path, *, limit: int, too_big) -> bytes:
    """A regular file's bytes, at most ``limit`` of them: a folder, a device, a pipe, a missing or
    unreadable file and a file over the limit are each one ExperimentError (``too_big(size)`` says
    the last; the size is None when the file grew while it was read). Shared by every reader."""
    path = Path(path)
    src = str(path)
    try:
        info = path.stat()
    except FileNotFoundError:
        raise ExperimentError("no such file; check the path.", source=src) from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise ExperimentError(f"cannot be read: {getattr(exc, 'strerror', None) or exc}.", source=src) from None
    if stat.S_ISDIR(info.st_mode):
        raise ExperimentError("is a folder, not an experiment file; `odelab run` takes folders and runs the "
                              "*.toml files in them.", source=src)
    if not stat.S_ISREG(info.st_mode):
        raise ExperimentError("is not a regular file (a device, a pipe or a socket); give an experiment file.",
                              source=src)
    if info.st_size > limit:
        raise ExperimentError(too_big(info.st_size), source=src)
    try:
        with open(path, "rb") as fh:
            raw = fh.read(limit + 1)  # the file may have grown since stat
    except OSError as exc:
        raise ExperimentError(f"cannot be read: {exc.strerror}.", source=src) from None
    if len(raw) > limit:
        raise ExperimentError(too_big(None), source=src)
    return raw


def _too_big(size: int | None) -> str:
    shown = f"{size:,}" if size is not None else f"more than {MAX_FILE_BYTES:,}"
    return (f"is {shown} bytes; experiment files are limited to {MAX_FILE_BYTES:,} bytes (1 MB). Put long "
            "input data in a CSV table (`type = \"table\"`) instead.")


def parse_toml(raw: bytes, src: str) -> dict:
    """Decode (UTF-8, with or without a byte-order mark) and parse TOML, checking the nesting depth."""
    if raw.startswith(_UTF32_BOMS) or raw.startswith(_UTF16_BOMS):
        kind = "UTF-32" if raw.startswith(_UTF32_BOMS) else "UTF-16"
        raise ExperimentError(f"is {kind} text; TOML files must be UTF-8: save it as UTF-8 (in Notepad: "
                              "Save as, Encoding: UTF-8).", source=src)
    if raw.startswith(codecs.BOM_UTF8):  # Windows Notepad writes one; TOML does not allow it, we accept it
        raw = raw[len(codecs.BOM_UTF8):]
    if not raw.strip():
        raise ExperimentError("is empty; an experiment needs at least [system], [initial] and [time] "
                              "(`odelab new FILE` writes a starter).", source=src)
    if b"\x00" in raw:
        if _looks_utf16(raw):
            raise ExperimentError("is UTF-16 text (without a byte-order mark); TOML files must be UTF-8: save it "
                                  "as UTF-8.", source=src)
        raise ExperimentError("is a binary file, not a TOML text file.", source=src)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ExperimentError(f"is not UTF-8 text (byte {exc.start}); save it as UTF-8.", source=src) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        from odelab.formats.toml_habits import toml_error_message  # MATLAB habits get what to write instead

        raise ExperimentError(toml_error_message(text, exc), source=src) from None
    except RecursionError:  # tomllib recurses once per level of [ and {: hundreds of levels overflow it
        raise _too_deep(None, src) from None
    depth = nesting_depth(data)
    if depth > MAX_NESTING:  # dotted keys and [a.b.c...] headers nest without brackets
        raise _too_deep(depth, src)
    return data


def _too_deep(depth: int | None, src: str) -> ExperimentError:
    shown = f"{depth}" if depth is not None else "hundreds of"
    return ExperimentError(f"nests tables or arrays {shown} levels deep; experiment files are limited to "
                           f"{MAX_NESTING} levels (odelab's own keys need at most 4).", source=src)


def _looks_utf16(raw: bytes) -> bool:
    """ASCII text saved as UTF-16 has a NUL in every other byte."""
    head = raw[:200]
    return len(head) >= 4 and (head[1::2].count(0) > 0.8 * len(head[1::2]) or
                               head[0::2].count(0) > 0.8 * len(head[0::2]))


def nesting_depth(data) -> int:
    """How deeply tables and arrays nest in parsed data (iterative: no recursion to overflow)."""
    deepest = 0
    stack = [(data, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, dict):
            children = node.values()
        elif isinstance(node, list):
            children = node
        else:
            continue
        depth += 1
        deepest = max(deepest, depth)
        if depth > MAX_NESTING:
            return depth
        stack.extend((child, depth) for child in children)
    return deepest
