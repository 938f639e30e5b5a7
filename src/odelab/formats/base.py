"""What every file-format reader returns: a :class:`Document`, the plain dict an experiment file holds.

A reader turns a file's bytes into the dict that :mod:`tomllib` gives for an experiment file;
everything after it (validation, cases, runs, the store, the report) is the same whatever the
file's format. An importer (a MATLAB script, a Simulink model) also returns the experiment file
it wrote (``text``: TOML, commented with where each part came from) and its :class:`Note`\\ s:
what it translated, what it ignored and what it could not translate (the gaps). The dict of an
imported document is the TOML reader's reading of ``text``, so running the source and running
the written file give the same bits.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["Document", "ImportOptions", "Note", "TRANSLATED", "IGNORED", "GAP"]

TRANSLATED, IGNORED, GAP = "translated", "ignored", "gap"


@dataclass(frozen=True)
class Note:
    """One row of an import's table: where in the source, what was found, and what became of it."""

    where: str  # "line 12", "block msd/Gain1", "model"
    construct: str  # what was found: "plot(t, y)", "Gain", "odeset('RelTol', ...)"
    outcome: str  # TRANSLATED, IGNORED or GAP
    detail: str  # what it became, or (a gap) what to write instead
    file: str = ""  # the source file, when not the one imported (a workspace script)

    def __post_init__(self) -> None:
        if self.outcome not in (TRANSLATED, IGNORED, GAP):
            raise ValueError(f"a note's outcome is {TRANSLATED!r}, {IGNORED!r} or {GAP!r}; got {self.outcome!r}")


@dataclass(frozen=True)
class ImportOptions:
    """What an importer may be told besides the file: ``odelab run/import``'s ``--workspace``, ``--set``
    and ``--call``."""

    workspace: tuple[Path, ...] = ()  # MATLAB scripts that assign the model's workspace variables
    sets: tuple[tuple[str, str], ...] = ()  # NAME=VALUE overrides of workspace variables and parameters
    call: str | None = None  # the solver call a student types at MATLAB's prompt, for a function file
    output: Path | None = None  # where `odelab import` writes the experiment file: its file names are relative to it


@dataclass(frozen=True)
class Document:
    """A file read: the experiment's plain dict and what produced it."""

    path: Path
    data: dict
    raw: bytes  # the file's bytes: their SHA-256 identifies the experiment's version in the store
    format: str = "toml"  # the reader's name
    text: str | None = None  # an importer's experiment file (TOML); None for a TOML file
    notes: tuple[Note, ...] = field(default=(), compare=False)

    @property
    def gaps(self) -> tuple[Note, ...]:
        """What could not be translated: an experiment file with gaps is written, but does not run."""
        return tuple(n for n in self.notes if n.outcome == GAP)

    @property
    def imported(self) -> bool:
        return self.text is not None

    def gaps_message(self, shown: int = 5) -> str:
        """Why an imported file with gaps does not run: the first gaps, each with its place and the fix."""
        gaps = self.gaps
        parts = [f"{g.file + ': ' if g.file else ''}{g.where}: {g.construct}: {g.detail}" for g in gaps[:shown]]
        more = f"; and {len(gaps) - shown} more" if len(gaps) > shown else ""
        return (f"could not be translated completely ({len(gaps)} gap{'s' if len(gaps) != 1 else ''}): "
                + "; ".join(parts) + more + f". `odelab import {self.path.name}` writes the experiment file with "
                "the gaps marked and prints the whole table; fill them in there and run that file.")
