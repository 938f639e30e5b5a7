"""A sweep's files: ``runs/<experiment>/sweep.json`` (its format, written and checked here) and ``sweep.csv``.

The sweep's rows and its study's result come from :mod:`odelab.experiment.study`; this module
writes them atomically and is the one place that knows the format's name and version.
"""

from __future__ import annotations

import csv
import io
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from odelab.experiment.study import run_study, sweep_rows

__all__ = ["SWEEP_FORMAT", "sweep_record", "sweep_csv", "write_sweep", "METRICS", "STEP_INFO"]

#: sweep.csv's columns of each quantity's response (experiment.study's metrics) and of each channel's stepinfo
METRICS = ("final", "min", "max", "t_max", "overshoot_percent")
STEP_INFO = ("RiseTime", "SettlingTime", "Overshoot", "Undershoot", "Peak", "PeakTime", "SteadyStateValue")


SWEEP_FORMAT = "odelab-sweep/1"


def sweep_record(exp, results) -> dict[str, Any]:
    """What ``sweep.json`` holds: the sweep, its rows, the study's result and provenance."""
    from odelab.store.results import versions

    rows = sweep_rows(results)
    first = results[0].case
    record = {
        "format": SWEEP_FORMAT,
        "experiment": exp.name,
        "title": exp.title,
        "source": str(exp.source),
        "file_sha256": exp.file_hash,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": dict(versions()),
        "sweep": exp.sweep.as_dict(),
        "complete": len(results) == len(exp.cases),  # False: interrupted, these are the cases that finished
        "cases_total": len(exp.cases),
        "states": list(first.problem.states),
        "outputs": list(first.problem.outputs),
        "reference": results[0].reference_kind,
        "description": first.config.get("description", ""),
        "rows": rows,
        "study": run_study(exp.study, rows) if exp.study is not None else None,
    }
    return record


def sweep_csv(record: dict[str, Any]) -> str:
    """The sweep as one table a spreadsheet opens: a row per case."""
    from odelab.fileio import spreadsheet_cell

    rows = record["rows"]
    keys = record["sweep"]["keys"]
    quantities = sorted({q for r in rows for q in r["max_abs"]})
    header = ["case", *keys, "method", "status", "nsteps", "nfailed", "nfevals", "elapsed_s"]
    # each quantity's response (final, min, max...) where it has no reference (with one, its errors are
    # the point: a convergence study's), and each channel's stepinfo; then the errors
    measured = list(dict.fromkeys(q for r in rows for q in (r.get("metrics") or {}) if q not in quantities))
    header += [f"{q}_{what}" for q in measured for what in METRICS]
    channels = list(dict.fromkeys((s["output"], s["input"]) for r in rows for s in (r.get("step_info") or [])))
    header += [f"{y}/{u}_{what}" for y, u in channels for what in STEP_INFO]
    header += [f"{q}_{what}" for q in quantities for what in ("max_abs", "end_abs", "max_rel")]
    # the global error estimate's columns, when some case has one (odelab.run.estimate)
    estimated = sorted({q for r in rows for q in (r.get("est_abs") or {})})
    if estimated:
        header += ["estimate", *(f"{q}_{what}" for q in estimated for what in ("est_abs", "est_digits"))]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow([spreadsheet_cell(h) for h in header])
    for r in rows:
        cells = [r["case"], *(r["swept"].get(k) for k in keys), r["method"], r["status"], r["nsteps"], r["nfailed"],
                 r["nfevals"], r["elapsed_s"]]
        for q in measured:
            cells += [((r.get("metrics") or {}).get(q) or {}).get(what) for what in METRICS]
        info = {(s["output"], s["input"]): s for s in (r.get("step_info") or [])}
        for channel in channels:
            cells += [(info.get(channel) or {}).get(what) for what in STEP_INFO]
        for q in quantities:
            cells += [r["max_abs"].get(q), r["end_abs"].get(q), r["max_rel"].get(q)]
        if estimated:
            cells.append(r.get("estimate"))
            for q in estimated:
                cells += [(r.get("est_abs") or {}).get(q), (r.get("est_digits") or {}).get(q)]
        writer.writerow(["" if c is None else repr(c) if isinstance(c, float) else spreadsheet_cell(c)
                         for c in cells])
    return buf.getvalue()


def write_sweep(exp, results, runs) -> Path:
    """Store ``runs/<experiment>/sweep.json`` and ``sweep.csv`` atomically; returns the folder."""
    import json

    from odelab.experiment.naming import slug
    from odelab.fileio import atomic_write
    from odelab.store.hidden import remove_if_empty
    from odelab.store.results import json_safe

    folder = Path(runs) / slug(exp.name)
    record = json_safe(sweep_record(exp, results))
    try:  # atomic_write makes the folder (again, if another run removes it as empty meanwhile)
        atomic_write(folder / "sweep.csv", sweep_csv(record))
        atomic_write(folder / "sweep.json", json.dumps(record, indent=1, allow_nan=False) + "\n")
    except BaseException:
        remove_if_empty(folder)  # nothing stored: no empty experiment folder left behind
        raise
    return folder
