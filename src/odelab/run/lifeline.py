"""Worker processes that never outlive the run that started them.

A pool worker (or a Dask worker of a local cluster) whose parent is killed (``kill -9``, the
out-of-memory killer, a grader's timeout) is reparented and would otherwise keep running, and
keep its memory, until its case ends, or forever if it waits for work. So every worker odelab
starts calls :func:`exit_with_parent` first thing:

- on Linux, ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` asks the kernel to kill it the moment its
  parent dies, even while it runs compiled code that holds the GIL;
- elsewhere (or if ``prctl`` is refused), a daemon thread polls ``getppid()`` every
  :data:`POLL_SECONDS` and exits when the parent changes.

Two caveats of the parent-death signal. It is tied to the *thread* that forked the worker, not
the process: the workers are forked from the thread that runs the cases (the caller's), which
outlives them. And a parent that dies before the call is not seen: so the worker checks
``getppid()`` against the parent's pid, recorded before forking, right after the call.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

__all__ = ["POLL_SECONDS", "exit_with_parent", "tied_command"]

#: How often the portable watchdog looks at its parent's pid (where prctl is not available).
POLL_SECONDS = 0.25

_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _parent_death_signal(sig: int) -> bool:
    """Linux: have the kernel send ``sig`` to this process when its parent (thread) dies."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):  # pragma: no cover - no libc symbol, or a seccomp policy
        return False


def _watch(parent: int) -> None:  # pragma: no cover - the fallback where prctl is missing

    while True:
        if os.getppid() != parent:
            os._exit(1)
        time.sleep(POLL_SECONDS)


def exit_with_parent(parent: int, *, watchdog: bool = False) -> None:
    """In a worker: exit (at once, without cleanup) when process ``parent`` dies.

    ``parent`` is the pid of the process that started this one, recorded *before* it did (a
    parent that has already died is then noticed too). ``watchdog`` forces the polling thread
    even where the parent-death signal is available.
    """
    armed = _parent_death_signal(signal.SIGKILL)
    if os.getppid() != parent:  # died before the signal was armed: we were already reparented
        os._exit(1)
    if watchdog or not armed:
        threading.Thread(target=_watch, args=(parent,), name="odelab-parent-watch", daemon=True).start()


def tied_command(argv: list[str], parent: int | None = None) -> list[str]:
    """The command line that runs ``argv`` as a process that dies with ``parent`` (default: this process).

    For a program that is not odelab's (``dask scheduler``, ``dask worker``): the command first
    runs this module, which arms the parent-death signal (:func:`exit_with_parent`) and then
    replaces itself with ``argv`` (the signal survives ``exec``). Start it from the thread that
    outlives it (see the module docstring). Where the signal is not available, this module
    stays as the program's parent instead and kills it when ``parent`` dies.
    """
    return [sys.executable, "-m", "odelab.run.lifeline", str(os.getpid() if parent is None else parent),
            "--", *argv]


def _run_tied(parent: int, argv: list[str]) -> int:  # pragma: no cover - runs in the child process
    armed = _parent_death_signal(signal.SIGKILL)
    if os.getppid() != parent:
        return 1
    if armed:
        os.execvp(argv[0], argv)

    child = subprocess.Popen(argv)
    while child.poll() is None:
        if os.getppid() != parent:
            child.kill()
            break
        time.sleep(POLL_SECONDS)
    return child.wait()


if __name__ == "__main__":  # pragma: no cover - see tied_command
    if len(sys.argv) < 4 or sys.argv[2] != "--":
        sys.exit("usage: python -m odelab.run.lifeline PARENT_PID -- PROGRAM [ARG...]")
    sys.exit(_run_tied(int(sys.argv[1]), sys.argv[3:]))
