"""Parameter sweeps: expanding an experiment file's ``[sweep]`` table into cases.

```toml
[sweep]
"solver.method" = ["euler", "heun", "rk4"]
"solver.h" = { from = 0.1, to = 0.0125, count = 4, log = true }
mode = "product"          # or "zip": the lists side by side, all of one length
store = "summary"         # one table for the sweep; "all" also stores every case's folder
```

Each swept key is a dotted path into the experiment (``solver.h``, ``parameters.k``,
``initial.x``, ``time.stop``, ``inputs.f.amplitude``); its values are a list or a range
written as MATLAB users think of them (``from``/``to`` with ``count`` as ``linspace``, with
``log = true`` as ``logspace``, or ``step`` as ``from:step:to``). The expansion is pure: it
returns one override table per case, with a readable name ("h=0.05, method=rk4"), that the
loader merges over the base (and over each ``[[case]]``) like any other case.
"""

from __future__ import annotations

import difflib
import itertools
import math
from dataclasses import dataclass
from typing import Any

from odelab.exceptions import ExperimentError

__all__ = ["MAX_SWEEP_CASES", "SWEEP_OPTIONS", "Sweep", "SweepPoint", "expand_sweep", "format_value"]

SWEEP_OPTIONS = ("mode", "store")
MAX_SWEEP_CASES = 100_000
# Sections a swept key may point into, and for the first three which names must already exist.
_SECTIONS = ("solver", "parameters", "initial", "inputs", "time", "reference", "exact", "system")
_RANGE_KEYS = ("from", "to", "count", "step", "log")


@dataclass(frozen=True)
class SweepPoint:
    """One case of a sweep: its name, its swept values (key path -> value) and its override."""

    name: str
    values: dict[str, Any]
    override: dict[str, Any]


@dataclass(frozen=True)
class Sweep:
    """A parsed ``[sweep]``: the swept keys with their values, the mode and the store policy."""

    keys: tuple[str, ...]
    values: tuple[tuple[Any, ...], ...]
    mode: str = "product"
    store: str = "summary"

    def points(self) -> list[SweepPoint]:
        combos = zip(*self.values) if self.mode == "zip" else itertools.product(*self.values)
        labels = _labels(self.keys)
        points = []
        for combo in combos:
            values = dict(zip(self.keys, combo))
            name = ", ".join(f"{labels[k]}={format_value(v)}" for k, v in values.items())
            override: dict[str, Any] = {}
            for key, value in values.items():
                node = override
                *parents, leaf = key.split(".")
                for part in parents:
                    node = node.setdefault(part, {})
                node[leaf] = value
            points.append(SweepPoint(name=name, values=values, override=override))
        return points

    def as_dict(self) -> dict[str, Any]:
        return {"keys": list(self.keys), "values": [list(v) for v in self.values], "mode": self.mode,
                "store": self.store}


def format_value(value: Any) -> str:
    """A swept value as people write it: 0.05, 1e-4, 2.5e-6, ode45, true."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if value != 0 and (abs(value) < 1e-3 or abs(value) >= 1e6):
            mantissa, exponent = f"{value:.6e}".split("e")
            mantissa = mantissa.rstrip("0").rstrip(".")
            return f"{mantissa}e{int(exponent)}"
        return f"{value:.6g}"
    return str(value)


def _labels(keys: tuple[str, ...]) -> dict[str, str]:
    """Each key's label in case names: its last part, or the whole path where two would clash."""
    leaves = [k.rsplit(".", 1)[-1] for k in keys]
    return {k: leaf if leaves.count(leaf) == 1 else k for k, leaf in zip(keys, leaves)}


def _round(value: float) -> float:
    """Range values to 12 significant digits, so logspace gives 1e-4, not 9.999999999999999e-05."""
    return float(f"{value:.12g}")


def _where(key: str) -> str:
    """How a swept key is written in messages and error keys: sweep."solver.h"."""
    return f'sweep."{key}"'


def _range(spec: dict, key: str) -> list[float]:
    where = _where(key)
    unknown = [k for k in spec if k not in _RANGE_KEYS]
    if unknown:
        close = difflib.get_close_matches(unknown[0], _RANGE_KEYS, n=1)
        hint = f" Did you mean `{close[0]}`?" if close else ""
        raise ExperimentError(f"`{where}` has unknown key `{unknown[0]}`.{hint} A range is "
                              "{ from = 1, to = 10, count = 10 } (add log = true for logspace) or "
                              "{ from = 1, to = 10, step = 0.5 }.", key=where)
    for name in ("from", "to"):
        value = spec.get(name)
        if value is None:
            raise ExperimentError(f"`{where}` is a range without `{name}`: write {{ from = 1, to = 10, count = 10 }}.",
                                  key=where)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ExperimentError(f"`{where}.{name}` must be a finite number; got {value!r}.",
                                  key=where)
    start, stop = float(spec["from"]), float(spec["to"])
    log = spec.get("log", False)
    if not isinstance(log, bool):
        raise ExperimentError(f"`{where}.log` must be true or false; got {log!r}.", key=where)
    count, step = spec.get("count"), spec.get("step")
    if (count is None) == (step is None):
        raise ExperimentError(f"`{where}` needs exactly one of `count` (how many values, as linspace) or `step` "
                              "(as MATLAB's from:step:to).", key=where)
    if log and (start <= 0 or stop <= 0):
        raise ExperimentError(f"`{where}` has log = true, so `from` and `to` must be positive; got from = "
                              f"{format_value(start)}, to = {format_value(stop)}.", key=where)
    if count is not None:
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ExperimentError(f"`{where}.count` must be a whole number of at least 1; got {count!r}.",
                                  key=where)
        if count > MAX_SWEEP_CASES:
            raise ExperimentError(f"`{where}.count` is {count}; a sweep is limited to {MAX_SWEEP_CASES} cases.",
                                  key=where)
        if count == 1:
            return [_round(start)]
        if log:
            a, b = math.log10(start), math.log10(stop)
            return [_round(10 ** (a + (b - a) * i / (count - 1))) for i in range(count)]
        # a + (b - a) f overflows when b - a does (from = -1e308, to = 1e308): a (1 - f) + b f does not
        return [_round(start + (stop - start) * i / (count - 1)) if math.isfinite(stop - start)
                else _round(start * (1 - i / (count - 1)) + stop * (i / (count - 1))) for i in range(count)]
    if log:
        raise ExperimentError(f"`{where}`: `log = true` goes with `count`, not `step`.", key=where)
    if isinstance(step, bool) or not isinstance(step, (int, float)) or not math.isfinite(step) or step == 0:
        raise ExperimentError(f"`{where}.step` must be a non-zero number; got {step!r}.", key=where)
    q = (stop - start) / step if math.isfinite(stop - start) else math.copysign(math.inf, (stop - start) * step)
    if q > 0 and (not math.isfinite(q) or q + 1 > MAX_SWEEP_CASES):  # a subnormal step, or a span past the largest float
        raise ExperimentError(f"`{where}` goes from {format_value(start)} to {format_value(stop)} with step "
                              f"{format_value(step)}: {'more than ' if not math.isfinite(q) else ''}"
                              f"{min(q, 1e308) + 1:.3g} values; a sweep is limited to {MAX_SWEEP_CASES} cases "
                              "(take a larger step).", key=where)
    n = math.floor(q + 1e-9) if q >= 0 else -1
    if n < 0:
        raise ExperimentError(f"`{where}` goes from {format_value(start)} to {format_value(stop)} with step "
                              f"{format_value(step)}: no values (MATLAB's {format_value(start)}:{format_value(step)}:"
                              f"{format_value(stop)} is empty).", key=where)
    if n + 1 > MAX_SWEEP_CASES:
        raise ExperimentError(f"`{where}` gives {n + 1} values; a sweep is limited to {MAX_SWEEP_CASES} cases.",
                              key=where)
    values = [start + i * step for i in range(n + 1)]
    if all(isinstance(v, int) for v in (spec["from"], spec["to"], step)):
        return [int(v) for v in values]
    return [_round(v) for v in values]


def _check_path(key: str, base: dict, case_overrides: list[dict]) -> None:
    """A swept key must name something the experiment has (or a solver option)."""
    parts = key.split(".")
    where = _where(key)
    if len(parts) < 2 or not all(parts):
        raise ExperimentError(f"`{where}`: {key!r} is not a dotted path such as \"solver.h\" or \"parameters.k\": "
                              "write the section and the key.", key=where)
    section = parts[0]
    if section not in _SECTIONS:
        close = difflib.get_close_matches(section, _SECTIONS, n=1)
        hint = f" Did you mean \"{close[0]}.{'.'.join(parts[1:])}\"?" if close else ""
        raise ExperimentError(f"`{where}` points into [{section}], which is not a section a sweep can "
                              f"change.{hint} Sweepable sections: {', '.join(_SECTIONS)}.", key=where)
    if section == "solver":
        from odelab.experiment.schema import SOLVER_KEYS
        from odelab.solvers.optionset import canonical as option_name

        leaf = parts[1]
        canonical = option_name(leaf) or leaf
        if len(parts) != 2 or (leaf != "method" and canonical not in SOLVER_KEYS):
            close = difflib.get_close_matches(leaf, SOLVER_KEYS, n=1)
            hint = f" Did you mean \"solver.{close[0]}\"?" if close else ""
            raise ExperimentError(f"`{where}`: {leaf!r} is not a solver option.{hint} Solver options: "
                                  f"{', '.join(SOLVER_KEYS)}.", key=where)
        return
    if section in ("parameters", "initial", "inputs"):
        known: set[str] = set()
        for table in (base, *case_overrides):
            value = table.get(section)
            if isinstance(value, dict):
                known |= set(value)
        if parts[1] not in known:
            close = difflib.get_close_matches(parts[1], sorted(known), n=1)
            hint = f" Did you mean \"{section}.{close[0]}\"?" if close else ""
            what = {"parameters": "parameter", "initial": "initial state", "inputs": "input"}[section]
            raise ExperimentError(f"`{where}`: the experiment has no {what} {parts[1]!r}.{hint} "
                                  f"Declare it in [{section}] first (known: {', '.join(sorted(known)) or 'none'}).",
                                  key=where)


def _flatten(table: dict, prefix: str = ""):
    """Swept keys as dotted paths, whether written quoted ("solver.h") or as TOML tables."""
    for key, value in table.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict) and value and not any(k in _RANGE_KEYS for k in value):
            yield from _flatten(value, path + ".")
        else:
            yield path, value


def expand_sweep(spec: Any, base: dict, case_overrides: list[dict] | None = None, *, limits=None,
                 copies: int = 1) -> Sweep:
    """Parse and check a ``[sweep]`` table (``spec``) against the experiment it sweeps.

    Raises
    ------
    ExperimentError
        For a key that names nothing sweepable, an empty or malformed list or range, zip lists
        of different lengths, a sweep of more than :data:`MAX_SWEEP_CASES` cases.
    """
    if not isinstance(spec, dict):
        raise ExperimentError("`sweep` must be a table: write [sweep] with lines such as "
                              "\"solver.h\" = [0.1, 0.05].", key="sweep")
    mode = spec.get("mode", "product")
    if mode not in ("product", "zip"):
        raise ExperimentError(f"`sweep.mode` is {mode!r}; it must be \"product\" (every combination) or \"zip\" "
                              "(the lists side by side).", key="sweep.mode")
    store = spec.get("store", "summary")
    if store not in ("summary", "all"):
        raise ExperimentError(f"`sweep.store` is {store!r}; it must be \"summary\" (one table for the sweep) or "
                              "\"all\" (also every case's results folder).", key="sweep.store")
    keys: list[str] = []
    values: list[tuple] = []
    for key, value in _flatten({k: v for k, v in spec.items() if k not in SWEEP_OPTIONS}):
        _check_path(key, base, case_overrides or [])
        where = f'sweep."{key}"'
        if isinstance(value, dict):
            items = _range(value, key)
        elif isinstance(value, list):
            items = value
            if not items:
                raise ExperimentError(f"`{where}` is an empty list: give at least one value.", key=where)
            bad = [v for v in items if isinstance(v, (dict, list))]
            if bad:
                raise ExperimentError(f"`{where}` must list single values (numbers, strings or booleans); got "
                                      f"{bad[0]!r}.", key=where)
            if isinstance(items[0], (int, float)) and not isinstance(items[0], bool):
                bad = [v for v in items if isinstance(v, float) and not math.isfinite(v)]
                if bad:
                    raise ExperimentError(f"`{where}` holds {bad[0]!r}: swept values must be finite.",
                                          key=where)
        else:
            raise ExperimentError(f"`{where}` must be a list of values or a range such as "
                                  f"{{ from = 1, to = 10, count = 10 }}; got {value!r}.", key=where)
        if key in keys:
            raise ExperimentError(f"`{where}` is set twice; keep one.", key=where)
        keys.append(key)
        values.append(tuple(items))
    if not keys:
        raise ExperimentError("`sweep` sweeps nothing: add a line such as \"solver.h\" = [0.1, 0.05].", key="sweep")
    if mode == "zip":
        lengths = {k: len(v) for k, v in zip(keys, values)}
        if len(set(lengths.values())) > 1:
            detail = ", ".join(f"{k} has {n}" for k, n in lengths.items())
            raise ExperimentError(f"`sweep.mode` is \"zip\", so every list needs the same length; {detail}. "
                                  "Make them equal, or use mode = \"product\".", key="sweep.mode")
        total = len(values[0])
    else:
        total = math.prod(len(v) for v in values)
    # the budgets before anything is expanded or compared: counting is cheap, a case is not
    cases = max(1, len(case_overrides or []))
    if total * cases > MAX_SWEEP_CASES:
        raise ExperimentError(f"`sweep` expands to {total * cases} cases; the limit is {MAX_SWEEP_CASES}. Sweep fewer "
                              "values or split the experiment.", key="sweep")
    if limits is not None:
        from odelab.experiment.limits import check_count

        parts = [f"{total:,} sweep values"] + ([f"{cases:,} [[case]] tables"] if cases > 1 else []) + (
            [f"{copies:,} [[problem]] tables"] if copies > 1 else [])
        count = total * cases * copies
        check_count("cases", count, "sweep", "", limits,
                    asked=f"makes {count:,} cases ({' times '.join(parts)})" if len(parts) > 1 else
                    f"makes {count:,} cases")
    # each value (each zip entry) once: a dict of what has been seen, linear in the sweep's size
    if mode == "zip":
        seen: dict[tuple, int] = {}
        for i, combo in enumerate(zip(*values)):
            shown = tuple(format_value(v) for v in combo)
            if shown in seen:
                raise ExperimentError(f"`sweep` (mode = \"zip\") has entries {seen[shown] + 1} and {i + 1} "
                                      f"equal ({', '.join(shown)}): each case once.", key="sweep")
            seen[shown] = i
    else:
        for key, items in zip(keys, values):
            seen_values: dict[str, int] = {}
            for i, v in enumerate(items):
                shown = format_value(v)
                if shown in seen_values:
                    raise ExperimentError(f"`{_where(key)}` lists {shown} twice: each value once (values "
                                          f"{seen_values[shown] + 1} and {i + 1} are equal).", key=_where(key))
                seen_values[shown] = i
    return Sweep(keys=tuple(keys), values=tuple(values), mode=mode, store=store)
