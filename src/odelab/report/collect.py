"""Reading the results store for a report: validated runs, grouped by experiment, in lab order.

A run that cannot be read (a corrupted or foreign ``result.json``, a broken trajectory) is
skipped with a warning that names the folder and the reason; it never stops the report. The
records are read and checked by :mod:`odelab.store.records`; the report never reads an
experiment file (the case order is stored with each case).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from odelab.store.records import QuantityErrors, StoredRun, parse_events, parse_record

__all__ = ["ExperimentRuns", "QuantityErrors", "StoredRun", "collect_runs", "parse_events", "parse_record"]


# Source files are read (as bytes, to hash) only to notice a file edited since its runs.
_MAX_SOURCE_BYTES = 50_000_000


@dataclass(eq=False)
class ExperimentRuns:
    """The stored cases of one experiment, in the order of the experiment file."""

    name: str
    runs: list[StoredRun]
    notes: list[str] = field(default_factory=list)  # provenance remarks for the section

    @property
    def title(self) -> str:
        first = self.runs[0]
        title = first.config.get("title") if isinstance(first.config.get("title"), str) else None
        return title or first.title or self.name

    @property
    def description(self) -> str:
        value = self.runs[0].config.get("description")
        return value if isinstance(value, str) else ""

    @property
    def source(self) -> str:
        return self.runs[0].source

    @property
    def file_hashes(self) -> list[str]:
        return sorted({r.file_sha256 for r in self.runs if r.file_sha256})

    @property
    def report(self) -> dict:
        """The experiment file's [report] table as stored (``order``, ``note``, ``quote``), or {}."""
        value = self.runs[0].config.get("report")
        return value if isinstance(value, dict) else {}

    @property
    def linearisation(self) -> bool:
        return any(isinstance(r.extra.get("linearization"), dict) for r in self.runs)


def _read(folder: Path) -> StoredRun:
    from odelab.store.results import read_run

    return parse_record(read_run(folder))


def _source_digest(source: str) -> str | None:
    """The experiment file's current SHA-256 (None if it is gone or unreadable): its bytes only, never parsed."""
    if not source:
        return None
    path = Path(source)
    try:
        if not path.is_file() or path.stat().st_size > _MAX_SOURCE_BYTES:
            return None
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _order_cases(group: ExperimentRuns) -> None:
    """The cases in their experiment's order (stored with each case), then by time and name."""
    last = 1 + max((r.case_index for r in group.runs if r.case_index is not None), default=0)
    group.runs.sort(key=lambda r: (r.case_index if r.case_index is not None else last, r.created, r.case))
    digest = _source_digest(group.source)
    hashes = group.file_hashes
    if len(hashes) > 1:
        group.notes.append(f"the cases of this experiment come from {len(hashes)} different versions of "
                           f"{group.source or 'its file'} (sha256 {', '.join(h[:12] for h in hashes)}); "
                           "run the experiment again to bring them in line")
    elif digest is not None and hashes and digest != hashes[0]:
        group.notes.append(f"{group.source} has changed since these runs (sha256 {hashes[0][:12]} then, "
                           f"{digest[:12]} now); run it again to report the current file")


def experiment_sort_key(group: ExperimentRuns) -> tuple:
    """Experiments with a [report] ``order`` first (lowest first), then linearisation studies, then the rest
    alphabetically."""
    order = group.report.get("order")
    if isinstance(order, int) and not isinstance(order, bool):
        return (0, order, group.name)
    if group.linearisation:
        return (1, 0, group.name)
    return (2, 0, group.name)


def collect_runs(runs: Path, experiments: list[str] | None = None) -> tuple[list[ExperimentRuns], list[str]]:
    """Read every stored case under ``runs``; returns the experiments in lab order and the warnings."""
    from odelab.store.results import list_runs

    warnings: list[str] = []
    groups: dict[str, ExperimentRuns] = {}
    for folder in list_runs(runs):
        try:
            run = _read(folder)
        except json.JSONDecodeError as exc:
            warnings.append(f"skipped {folder}: result.json is not valid JSON ({exc.msg}, line {exc.lineno})")
            continue
        except (OSError, ValueError, IndexError, KeyError, TypeError) as exc:
            # read_run's ValueError for a foreign file, OSError for a missing trajectory, and the
            # parse errors of a truncated or hand-edited trajectory.csv
            reason = str(exc) or type(exc).__name__
            warnings.append(f"skipped {folder}: {reason}")
            continue
        if experiments and run.experiment not in experiments:
            continue
        groups.setdefault(run.experiment, ExperimentRuns(run.experiment, [])).runs.append(run)
    for name in experiments or []:
        if name not in groups:
            warnings.append(f"no stored runs of experiment {name!r} in {runs}; run it with `odelab run` first")
    ordered = sorted(groups.values(), key=experiment_sort_key)
    for group in ordered:
        _order_cases(group)
    return ordered, warnings
