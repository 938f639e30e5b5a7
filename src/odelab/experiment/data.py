"""[data]: measured data read from a CSV file, the reference of a case and what [fit] fits.

```toml
[data]
file = "step_response.csv"       # relative to the experiment file, inside its folder
time = "t"                       # the time column (default "t")
columns = { x = "position" }     # model quantity = CSV column (default: same names)
sigma = { x = 0.01 }             # optional: measurement noise per quantity
```

Reading is safe and every failure names the file, the column and the row: a file that is
missing, too large, not UTF-8 text, has no header row of column names, a cell that is not a
number, a NaN, or times that do not increase. A file that does not look like a table (no
header of names separated by commas, semicolons or tabs) is refused without quoting any of
its content, so pointing ``file`` at something else never echoes it. The path is resolved
relative to the experiment file and must stay inside its folder (a file given on the command
line, ``odelab run --validate-with``, may be anywhere: its user chose it).
"""

from __future__ import annotations

import csv
import difflib
import math
import re
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.fileio import DECIMAL_COMMA_FIX, decimal_comma_line

__all__ = ["MeasuredData", "read_data", "read_data_file", "MAX_DATA_BYTES", "MAX_DATA_ROWS", "check_span"]

MAX_DATA_BYTES = 50_000_000
"""A data file is at most 50 MB (a million rows of a few columns)."""

MAX_DATA_ROWS = 1_000_000
"""At most a million measured rows: each is one residual per quantity of the fit."""

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_ .()\[\]/%-]{0,63}$")


@dataclass(frozen=True, eq=False)
class MeasuredData:
    """Measured quantities at increasing times."""

    file: str  # as written in the experiment file (or on the command line)
    path: Path
    time: str  # the time column's name
    t: np.ndarray
    values: dict[str, np.ndarray]  # model quantity -> measured values at t
    columns: dict[str, str]  # model quantity -> CSV column
    sigma: dict[str, float]  # model quantity -> noise, where given

    def as_dict(self) -> dict:
        return {"file": self.file, "time": self.time, "columns": dict(self.columns), "rows": int(self.t.size),
                **({"sigma": dict(self.sigma)} if self.sigma else {})}


def _split(line: str) -> tuple[list[str], str | None]:
    for sep in (",", ";", "\t"):
        if sep in line:
            return [cell.strip() for cell in next(csv.reader([line], delimiter=sep))], sep
    return line.split(), None


_READ: dict[tuple, tuple[list[str], np.ndarray]] = {}  # the cases of a file (a sweep's) share their data file


def read_data_file(path: Path, shown: str, key: str) -> tuple[list[str], np.ndarray]:
    """The header and the numbers (rows x columns) of a CSV file with one header row.

    ``shown`` is the file's name as the user wrote it; ``key`` the TOML key that named it. A
    file read before, unchanged since (same size and modification time), is not read again.
    """
    where = f"`{key}` {shown!r}"
    try:
        info = path.stat()
    except FileNotFoundError:
        raise ExperimentError(f"{where}: no such file (looked for {path}); check the name, which is relative to the "
                              "experiment file's folder.", key=key) from None
    except (OSError, ValueError) as exc:
        raise ExperimentError(f"{where} cannot be read: {getattr(exc, 'strerror', None) or exc}.", key=key) from None
    if stat.S_ISDIR(info.st_mode):
        raise ExperimentError(f"{where} is a folder; give a CSV file.", key=key)
    if not stat.S_ISREG(info.st_mode):
        raise ExperimentError(f"{where} is not a regular file (a device, a pipe or a socket); give a CSV file.",
                              key=key)
    if info.st_size > MAX_DATA_BYTES:
        raise ExperimentError(f"{where} is {info.st_size:,} bytes; data files are limited to {MAX_DATA_BYTES:,} bytes "
                              f"({MAX_DATA_ROWS:,} rows): thin the recording (every k-th row) first.", key=key)
    memo = (str(path), info.st_size, info.st_mtime_ns, MAX_DATA_BYTES, MAX_DATA_ROWS)
    if memo in _READ:
        header, table = _READ[memo]
        return list(header), table
    header, table = _parse(path, where, key)
    if len(_READ) >= 8:
        _READ.clear()
    table.flags.writeable = False
    _READ[memo] = (list(header), table)
    return header, table


def _parse(path: Path, where: str, key: str) -> tuple[list[str], np.ndarray]:
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_DATA_BYTES + 1)
    except OSError as exc:
        raise ExperimentError(f"{where} cannot be read: {exc.strerror}.", key=key) from None
    if len(raw) > MAX_DATA_BYTES:
        raise ExperimentError(f"{where} is more than {MAX_DATA_BYTES:,} bytes; data files are limited to that.",
                              key=key)
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in raw:
        raise ExperimentError(f"{where} is UTF-16 or binary, not a text table; save it as CSV UTF-8 (in Excel: "
                              "Save as, CSV UTF-8).", key=key)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ExperimentError(f"{where} is not UTF-8 text (byte {exc.start}); save it as CSV UTF-8.",
                              key=key) from None
    header: list[str] | None = None
    width = 0
    rows: list[list[float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        cells, sep = _split(stripped)
        if header is None:
            # a table's first line names its columns; anything else is not quoted back
            if len(cells) < 2 or not all(_NAME.match(c) for c in cells) or _all_numbers(cells):
                raise ExperimentError(
                    f"{where} does not look like a data table: its first line (line {number}) should be a header of "
                    "column names separated by commas (t,position), and it is not. Give a CSV file whose first "
                    "line names the columns.", key=key)
            header, width = cells, len(cells)
            continue
        if decimal_comma_line(stripped):
            raise ExperimentError(f"{where}, line {number} writes its numbers with decimal commas ({stripped[:40]!r}): "
                                  f"{DECIMAL_COMMA_FIX}.", key=key)
        if len(cells) != width:
            raise ExperimentError(f"{where}, line {number}: {len(cells)} values, but the header names {width} "
                                  "columns; every row needs one value per column.", key=key)
        values = []
        for column, cell in zip(header, cells):
            try:
                v = float(cell)
            except ValueError:
                shown_cell = f" ({cell!r})" if len(cell) <= 20 and cell.isprintable() else ""
                raise ExperimentError(f"{where}, line {number}, column {column!r}: not a number{shown_cell}; every "
                                      "value below the header must be a number.", key=key) from None
            if not math.isfinite(v):
                raise ExperimentError(f"{where}, line {number}, column {column!r}: {cell.strip()[:10]!r} is not a "
                                      "finite number; remove the row (or fill in the value): a fit cannot use a "
                                      "missing measurement.", key=key)
            values.append(v)
        rows.append(values)
        if len(rows) > MAX_DATA_ROWS:
            raise ExperimentError(f"{where} has more than {MAX_DATA_ROWS:,} rows; thin the recording first.", key=key)
    if header is None:
        raise ExperimentError(f"{where} is empty; give a CSV file with a header row and at least one row of "
                              "numbers.", key=key)
    if not rows:
        raise ExperimentError(f"{where} has a header but no rows of numbers.", key=key)
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise ExperimentError(f"{where}: the header names the column {dupes[0]!r} twice.", key=key)
    return header, np.array(rows, dtype=float)


def _all_numbers(cells: list[str]) -> bool:
    try:
        [float(c) for c in cells]
    except ValueError:
        return False
    return True


def resolve_data_path(name: str, key: str, experiment_path: Path, *, anywhere: bool = False) -> Path:
    """``name`` relative to the experiment file's folder, refusing paths that leave it (unless ``anywhere``)."""
    from odelab.experiment.userfiles import resolve_user_file

    if not isinstance(name, str) or not name.strip():
        raise ExperimentError(f"`{key}` must name a CSV file, e.g. file = \"measured.csv\".", key=key)
    if anywhere:
        return Path(name).expanduser().resolve()
    path = resolve_user_file(name, key, experiment_path)
    folder = Path(experiment_path).parent.resolve()
    if Path(name).is_absolute() or not path.is_relative_to(folder):
        raise ExperimentError(f"`{key}` is {name!r}, which is outside the experiment file's folder ({folder}); "
                              "put the data next to the experiment (or in a folder below it) and name it relative "
                              "to the experiment file.", key=key)
    return path


def read_data(spec, experiment_path: Path, quantities: tuple[str, ...], *, key: str = "data",
              file_override: str | None = None, anywhere: bool = False) -> MeasuredData:
    """Read ``[data]`` (a schema.Data) for a case whose states and outputs are ``quantities``."""
    name = file_override if file_override is not None else spec.file
    file_key = f"{key}.file"
    if file_override is not None:
        file_key = "--validate-with" if anywhere else "fit.validate"
    path = resolve_data_path(name, file_key, experiment_path, anywhere=anywhere)
    header, table = read_data_file(path, name, file_key)
    time = spec.time
    if time not in header:
        close = difflib.get_close_matches(time, header, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ExperimentError(f"`{key}.time` is {time!r}, which is not a column of {name!r} (its columns: "
                              f"{', '.join(header)}).{hint}", key=f"{key}.time")
    t = table[:, header.index(time)]
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0)) + 1
        raise ExperimentError(f"`{key}.file` {name!r}: the time column {time!r} must increase strictly; data row "
                              f"{i + 1} (t = {t[i]:g}) follows t = {t[i - 1]:g}. Sort the rows by time and remove "
                              "repeated times.", key=file_key)
    if spec.columns is not None:
        columns = dict(spec.columns)
        if not columns:
            raise ExperimentError(f"`{key}.columns` is empty; map at least one quantity to a column, e.g. "
                                  f"columns = {{ {quantities[0]} = \"position\" }}.", key=f"{key}.columns")
    else:  # default: every column named like a state or output
        columns = {h: h for h in header if h != time and h in quantities}
        if not columns:
            raise ExperimentError(f"`{key}.file` {name!r} has no column named like a state or output "
                                  f"({', '.join(quantities)}); its columns are {', '.join(header)}. Map them with "
                                  f"`{key}.columns`, e.g. columns = {{ {quantities[0]} = \"{header[-1]}\" }}.",
                                  key=f"{key}.columns")
    values = {}
    for quantity, column in columns.items():
        if quantity not in quantities:
            close = difflib.get_close_matches(quantity, quantities, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ExperimentError(f"`{key}.columns.{quantity}`: {quantity!r} is not a state or output of the model "
                                  f"({', '.join(quantities)}).{hint}", key=f"{key}.columns.{quantity}")
        if not isinstance(column, str) or column not in header:
            close = difflib.get_close_matches(str(column), header, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ExperimentError(f"`{key}.columns.{quantity}` is {column!r}, which is not a column of {name!r} (its "
                                  f"columns: {', '.join(header)}).{hint}", key=f"{key}.columns.{quantity}")
        values[quantity] = table[:, header.index(column)]
    sigma = {}
    for quantity, value in (spec.sigma or {}).items():
        if quantity not in columns:
            raise ExperimentError(f"`{key}.sigma.{quantity}`: {quantity!r} is not one of the measured quantities "
                                  f"({', '.join(columns)}).", key=f"{key}.sigma.{quantity}")
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ExperimentError(f"`{key}.sigma.{quantity}` must be a positive number (the measurement's standard "
                                  f"deviation, in the quantity's units); got {value!r}.", key=f"{key}.sigma.{quantity}")
        sigma[quantity] = float(value)
    t.flags.writeable = False
    return MeasuredData(name, path, time, t, values, columns, sigma)


def check_span(data: MeasuredData, tspan: np.ndarray, key: str = "data") -> None:
    """Measured times must lie inside the simulated span: the model is never extrapolated."""
    t0, tf = float(tspan[0]), float(tspan[-1])
    if tf < t0:
        raise ExperimentError(f"[{key}] needs a forward time span (time.stop > time.start); it runs from {t0:g} to "
                              f"{tf:g}.", key="time.stop")
    if data.t[0] < t0 or data.t[-1] > tf:
        bad = data.t[0] if data.t[0] < t0 else data.t[-1]
        raise ExperimentError(f"`{key}.file` {data.file!r} has measurements from t = {data.t[0]:g} to "
                              f"{data.t[-1]:g}, outside the simulated span [{t0:g}, {tf:g}] (t = {bad:g}); the model "
                              f"is never extrapolated: set time.start <= {data.t[0]:g} and time.stop >= "
                              f"{data.t[-1]:g}.", key=f"{key}.file")


MAX_STORED_ROWS = 20_000
"""Measured rows kept in result.json for the report's plots (evenly thinned beyond that)."""


def model_at_times(problem, times: np.ndarray, integrate, result=None) -> tuple[dict[str, np.ndarray], str | None]:
    """The case's states and outputs at ``times`` inside its span, from the solver itself.

    An adaptive method is run again over the vector tspan ``[t0, times..., tf]``: MATLAB's
    solvers take the same steps whatever the output times and fill those in from the step's
    interpolant (ntrp45 and co.), so these are the case's own solution's values there, as
    ``deval`` gives them. A fixed-step method has no interpolant: its values are read off the
    case's own output points by linear interpolation (between points, never beyond them).
    Returns the values and, if the solve failed, why.
    """
    from odelab.solvers.registry import get_method

    t0, tf = float(problem.tspan[0]), float(problem.tspan[-1])
    if not get_method(problem.method).adaptive and result is not None:  # a fixed step: its own grid
        series = result.series()
        return {name: np.interp(times, result.t, series[name]) for name in (*problem.states, *problem.outputs)}, None
    grid = np.unique(np.concatenate([[t0], times, [tf]]))
    ran = integrate(problem, grid, problem.method, dict(problem.options))  # an experiment.result.Integration
    rt, rx, ru = ran.t, ran.x, ran.u
    if ran.status != "success" or rt.size != grid.size:
        return {}, ran.message
    rows = np.searchsorted(rt, times)
    out = {name: rx[rows, i] for i, name in enumerate(problem.states)}
    if problem.system.output_fn is not None:
        if ru is None and problem.system.input_fn is not None:
            ru = problem.system.input_fn(rt)
        ry = problem.system.output_fn(rt, rx, ru)
        out.update({name: ry[rows, i] for i, name in enumerate(problem.outputs)})
    return out, None


def data_reference(result, integrate) -> None:
    """Errors of a case against its measurements (``[data]``), at the measured times."""
    from odelab.analysis.errors import summarize

    p = result.case.problem
    data: MeasuredData = p.data
    result.reference_kind = "data"
    if result.status != "success":
        return
    model, failed = model_at_times(p, data.t, integrate, result)
    if failed is not None:
        result.warnings.append(f"the model at the measured times could not be computed: {failed}")
        return
    keep = np.unique(np.linspace(0, data.t.size - 1, min(data.t.size, MAX_STORED_ROWS)).round().astype(int))
    record = {"file": data.file, "t": data.t[keep].tolist(), "measured": {}, "model": {}, "rows": int(data.t.size)}
    for name, measured in data.values.items():
        result.errors[name] = summarize(name, data.t, model[name], measured)
        record["measured"][name] = measured[keep].tolist()
        record["model"][name] = model[name][keep].tolist()
        residual = model[name] - measured
        record.setdefault("rms", {})[name] = float(np.sqrt(np.mean(residual ** 2)))
    result.extra["data"] = record
