"""Atomic file writes, shared by the results store and the report."""

from __future__ import annotations

import contextlib
import functools
import os
import re
import tempfile
from pathlib import Path

__all__ = ["atomic_write", "spreadsheet_cell", "umask"]


@functools.cache
def umask() -> int:
    """The process's umask (read once: reading it means setting it)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: Path, data: str | bytes) -> None:
    """Write ``path`` so that readers see the old file or the new one, never a part of one.

    The data goes to a temporary file in the same folder, is flushed to disk, and is renamed
    over the target; on any failure (including Ctrl-C) the temporary file is removed and the
    old file is untouched. The file gets the usual permissions (rw-r--r-- under the common
    umask 022), not the private ones of a temporary file: results and reports are shared. The
    folder is made if it is not there (again if, empty, another process removes it just then: the
    store removes the experiment folders a failed run leaves empty, ``odelab.store.hidden``).
    """
    path = Path(path)
    for attempt in range(100):
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
            break
        except FileNotFoundError:
            if attempt == 99:
                raise
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def spreadsheet_cell(value):
    """A CSV cell a spreadsheet shows as text, never runs as a formula (OWASP's CSV injection advice).

    A text cell starting with ``= + - @``, a tab or a carriage return (``=HYPERLINK(...)``,
    ``-2+3``) gets a leading single quote; numbers, and text that is a plain number (``-3``,
    ``-1e-4``), are left alone: they are data, not formulas.
    """
    if not isinstance(value, str) or not value.startswith(_FORMULA_START):
        return value
    try:
        float(value)
    except ValueError:
        return "'" + value
    return value if value.strip() == value and not value.lower().lstrip("+-").startswith(("nan", "inf")) \
        else "'" + value


_DECIMAL_COMMA = re.compile(r"^[-+]?\d*,\d+(?:[eE][-+]?\d+)?$")


def decimal_comma_line(line: str) -> bool:
    """A CSV line whose numbers are written with decimal commas, as a spreadsheet in a European locale
    saves them (``0,5;1,25`` or ``0,5<tab>1,25``): fields separated by ``;`` or tabs, at least one
    number with a comma for its decimal point and every field a number so written or a whole number."""
    for sep in (";", "\t"):
        if sep in line:
            cells = [c.strip() for c in line.split(sep)]
            return (len(cells) >= 2 and any(_DECIMAL_COMMA.match(c) for c in cells)
                    and all(_DECIMAL_COMMA.match(c) or c.lstrip("+-").isdigit() for c in cells))
    return False


DECIMAL_COMMA_FIX = ("odelab reads numbers with a decimal point. Save the file with '.' as the decimal separator "
                     "(LibreOffice: Save As, Edit filter settings; Excel: File, Options, Advanced, untick 'Use "
                     "system separators' and set the decimal separator to '.'), then save it again as CSV")
