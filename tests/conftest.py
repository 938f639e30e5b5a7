"""Session-wide test settings."""

import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def compiled_cache(tmp_path_factory):
    """One cache of compiled modules (odelab.solvers.compiled) for the whole test session.

    Each system is compiled once per session, never read from a developer's own cache, and
    subprocesses started by tests (``odelab run`` in a child process) share it.
    """
    folder = tmp_path_factory.getbasetemp() / "odelab-cache"
    previous = os.environ.get("ODELAB_CACHE_DIR")
    os.environ["ODELAB_CACHE_DIR"] = str(folder)
    yield folder
    if previous is None:
        os.environ.pop("ODELAB_CACHE_DIR", None)
    else:
        os.environ["ODELAB_CACHE_DIR"] = previous
