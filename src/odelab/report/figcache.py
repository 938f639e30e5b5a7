"""A cache of rendered report figures, keyed by what is drawn.

A figure's key is the SHA-256 of everything that decides its pixels: the figure spec (panel
titles, labels, scales and every plotted array, byte for byte, which come from the stored
runs), the source of :mod:`odelab.report.plots` and the matplotlib version. Rebuilding a report
whose runs have not changed since the last build copies each PNG from the cache instead of
drawing it; a re-run case changes its arrays, hence its key, and only its figures are drawn.

The PNGs are kept under the user's cache folder (``$ODELAB_CACHE_DIR``, else
``$XDG_CACHE_HOME/odelab``, else ``~/.cache/odelab``) in ``figures/``, and can be deleted at any time.
The cache is untrusted (:mod:`odelab.cachedir`): each PNG is sealed with its SHA-256, and one
that does not match its seal (truncated, or not written by odelab) is drawn again, never
embedded.
"""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

import numpy as np

__all__ = ["figure_key", "load", "store"]

_PLOTS = Path(__file__).with_name("plots.py")
_STAMP: list[bytes] = []


def _stamp() -> bytes:
    if not _STAMP:
        from importlib import metadata

        try:
            mpl = metadata.version("matplotlib")
        except metadata.PackageNotFoundError:  # pragma: no cover
            mpl = "?"
        _STAMP.append(hashlib.sha256(_PLOTS.read_bytes()).digest() + mpl.encode())
    return _STAMP[0]


def _feed(h, obj) -> None:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        h.update(type(obj).__name__.encode())
        for f in dataclasses.fields(obj):
            h.update(f.name.encode())
            _feed(h, getattr(obj, f.name))
    elif isinstance(obj, np.ndarray):
        h.update(f"array{obj.dtype.str}{obj.shape}".encode())
        h.update(np.ascontiguousarray(obj).tobytes())
    elif isinstance(obj, (list, tuple)):
        h.update(f"seq{len(obj)}(".encode())
        for item in obj:
            _feed(h, item)
        h.update(b")")
    elif isinstance(obj, dict):
        h.update(f"map{len(obj)}(".encode())
        for key in sorted(obj, key=repr):
            _feed(h, key)
            _feed(h, obj[key])
        h.update(b")")
    else:
        h.update(f"{type(obj).__name__}:{obj!r};".encode())


def figure_key(spec) -> str:
    """The cache key of a figure spec (see the module docstring). ``name`` is not part of it."""
    h = hashlib.sha256(_stamp())
    _feed(h, dataclasses.replace(spec, name=""))
    return h.hexdigest()


def _folder() -> Path | None:
    from odelab.cachedir import cache_folder

    return cache_folder("figures")


def load(key: str) -> bytes | None:
    """The cached PNG for ``key`` if it is whole (it matches its seal), or None."""
    from odelab.cachedir import read_entry

    return read_entry(_folder(), f"{key}.png", "figure")


def store(key: str, png: bytes) -> None:
    """Keep ``png`` under ``key``, sealed (atomically; a cache that cannot be written is skipped)."""
    from odelab.cachedir import write_entry

    write_entry(_folder(), f"{key}.png", png)
