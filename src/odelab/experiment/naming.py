"""Results-folder names: an experiment's or case's name made a safe folder, and the clashes it forbids.

Here (not in the loader) so that the store, the study and the grader name folders without
importing the loader (pydantic, the schema) and without an import circle.
"""

from __future__ import annotations

import re

from odelab.exceptions import ExperimentError

__all__ = ["NAME_RULE", "check_experiment_names", "folder_key", "slug"]


_SLUG = re.compile(r"[^A-Za-z0-9._-]+")


def slug(name: str) -> str:
    """A folder name for an experiment or case name that cannot leave the results folder."""
    s = _SLUG.sub("-", name.replace("\x00", "")).strip("-.")
    return s[:80] or "unnamed"


NAME_RULE = ("(a results folder's name keeps letters, digits, '.', '_' and '-' of the first 80 characters, anything "
             "else becomes '-', and folder names are compared ignoring case, as on Windows and macOS)")


def folder_key(name: str) -> str:
    """What two names must not share: their results folder, compared as a case-insensitive file system would."""
    return slug(name).casefold()


def check_experiment_names(experiments) -> list[tuple[object, ExperimentError]]:
    """Experiments of one run that would share a results folder: each later one with its error.

    ``experiments`` are loaded experiments (``.name``, ``.source``); the first to claim a
    folder keeps it, so a folder of files still runs all but the colliding ones.
    """
    claimed: dict[str, object] = {}
    clashes = []
    for exp in experiments:
        key = folder_key(exp.name)
        first = claimed.setdefault(key, exp)
        if first is exp:
            continue
        same = first.name == exp.name
        what = f"is also named {exp.name!r} and" if same else f"is named {exp.name!r}, which"
        clashes.append((exp, ExperimentError(
            f"experiment {what} would be stored in the same results folder {slug(exp.name)!r} as {first.name!r} "
            f"from {first.source}, overwriting its cases: give this file its own `name` {NAME_RULE}.",
            source=str(exp.source), key="name")))
    return clashes
