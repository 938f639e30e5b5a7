"""Whether this run may load native code (an FMU's binary): off unless the user said so."""

from __future__ import annotations

from contextlib import contextmanager
from contextvars import ContextVar

__all__ = ["allow_native", "native_allowed"]

_ALLOWED: ContextVar[bool] = ContextVar("odelab_allow_native", default=False)
_PROCESS = [False]  # set by the CLI for the whole run: forked pool workers inherit it


def native_allowed() -> bool:
    """True inside :func:`allow_native` (or after ``allow_native(process=True)``)."""
    return _ALLOWED.get() or _PROCESS[0]


@contextmanager
def allow_native(allowed: bool = True):
    """Within this block, experiment files may load FMUs (``odelab run --allow-native``)."""
    token = _ALLOWED.set(bool(allowed))
    try:
        yield
    finally:
        _ALLOWED.reset(token)
