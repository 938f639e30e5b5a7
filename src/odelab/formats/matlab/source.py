"""A ``.m`` file's bytes checked and decoded before anything parses them.

MATLAB files are small text files in UTF-8 or (older ones, written on Windows) Latin-1/CP-1252;
a binary file, a UTF-16 file or one over :data:`MAX_M_BYTES` is refused with one message, as is
a file that is not MATLAB at all (an Objective-C or Mathematica ``.m``).
"""

from __future__ import annotations

import codecs
from pathlib import Path

from odelab.exceptions import ExperimentError

__all__ = ["MAX_M_BYTES", "read_source", "decode"]

MAX_M_BYTES = 1_000_000
"""A MATLAB file odelab reads is at most 1 MB (the course's are a few kB)."""

_FOREIGN = ((b"@interface", "Objective-C"), (b"@implementation", "Objective-C"), (b"#import <", "Objective-C"),
            (b"BeginPackage[", "Mathematica"), (b"(* ", "Mathematica"))


def _too_big(size: int | None) -> str:
    shown = f"{size:,}" if size is not None else f"more than {MAX_M_BYTES:,}"
    return (f"is {shown} bytes; odelab reads MATLAB files of up to {MAX_M_BYTES:,} bytes (1 MB), and ODE code is a "
            "few kilobytes. Give the driver script and the files it calls.")


def read_source(path: Path) -> bytes:
    """The file's bytes, within the size budget (a folder, a device or a missing file is one message)."""
    from odelab.formats.toml import read_bytes

    return read_bytes(path, limit=MAX_M_BYTES, too_big=_too_big)


def decode(raw: bytes, src: str) -> str:
    """The text of a MATLAB file: UTF-8 (with or without a byte-order mark), else Windows-1252."""
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise ExperimentError("is UTF-16 text; save it as UTF-8 (MATLAB's editor: Save As, Encoding UTF-8).",
                              source=src)
    if raw.startswith(codecs.BOM_UTF8):
        raw = raw[len(codecs.BOM_UTF8):]
    if b"\x00" in raw:
        raise ExperimentError("is a binary file, not MATLAB source text (.m); give the MATLAB file itself.",
                              source=src)
    controls = sum(1 for byte in raw[:4096] if byte < 32 and byte not in (9, 10, 12, 13))
    if controls > 8:
        raise ExperimentError("is a binary file, not MATLAB source text (.m); give the MATLAB file itself.",
                              source=src)
    head = raw[:2000]
    for marker, language in _FOREIGN:
        if marker in head and b"function" not in head[:head.find(marker)]:
            raise ExperimentError(f"is {language} source, not MATLAB (both use the .m suffix).", source=src)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("cp1252", errors="replace")
    if not text.strip():
        raise ExperimentError("is empty; give a MATLAB script or function file.", source=src)
    return text
