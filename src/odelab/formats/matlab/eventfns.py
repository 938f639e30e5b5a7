"""odeset's Events function as ``[events.NAME]`` tables, and a restart loop as their ``reset``.

``[value, isterminal, direction] = events(t, y)`` is read on symbols: each element of ``value``
becomes an event whose ``when`` is that expression, ``isterminal`` its ``terminal`` and
``direction`` (-1, 0, 1) its ``direction`` (falling, both, rising). A loop that calls the solver
again from the state at a terminal event (MATLAB's ``ballode``) gives those events a ``reset``
(the state the next call starts from) and ``max_events`` (the loop's number of calls).
"""

from __future__ import annotations

from pathlib import Path

from odelab.formats.base import IGNORED
from odelab.formats.matlab.system import definition_site, read_function
from odelab.formats.matlab.values import Arr, FuncValue, Str, Struct, TooBig, Unsupported

__all__ = ["build_events"]

_DIRECTIONS = {-1.0: "falling", 0.0: "both", 1.0: "rising"}


def _event_names(fv: FuncValue, count: int) -> list[str]:
    from odelab.formats.matlab.exprtext import identifier

    base = fv.name if fv.name else "event"
    base = "event" if base.lower() in ("events", "event", "ev", "evt", "eventfun", "eventfcn", "events_fcn",
                                       "eventsfcn", "myevent", "myevents") else base
    base = identifier(base, set())
    return [base] if count == 1 else [f"{base}_{k + 1}" for k in range(count)]


def _constant_list(value, count: int) -> list[float] | None:
    if not isinstance(value, Arr):
        return None
    numbers = value.numbers()
    if numbers is None:
        return None
    flat = [float(v) for v in numbers.T.reshape(-1)]
    if len(flat) == 1:
        return flat * count
    return flat if len(flat) == count else None


def build_events(b, namer, names: list[str]) -> None:
    call = b.call
    options = call.options
    events_fn = options.fields.get("Events") if isinstance(options, Struct) else None
    if events_fn is None:
        if call.reset is not None:
            b.gap(("events",), "the restart loop has no Events function to restart at")
        return
    if isinstance(events_fn, Str) and call.flag and events_fn.text.lower() == "on":
        fv, flag = call.fun, "events"
    elif isinstance(events_fn, FuncValue):
        fv, flag = events_fn, None
    else:
        b.gap(("events",), "odeset's Events is not a function handle (@events)")
        return
    reading = read_function(b.interp, fv, call.states, call.extras, 3, flag=flag)
    if reading.gap is not None:
        b.gap(("events",), f"the events function {fv.name or fv.text} cannot be translated: {reading.gap.reason}",
              reading.gap.line, reading.gap.file)
        return
    value = reading.outputs[0] if reading.outputs else None
    if not isinstance(value, Arr) or value.size == 0:
        b.gap(("events",), "the events function returns no value")
        return
    count = value.size
    terminal = _constant_list(reading.outputs[1] if len(reading.outputs) > 1 else None, count)
    direction = _constant_list(reading.outputs[2] if len(reading.outputs) > 2 else None, count)
    if terminal is None or direction is None:
        b.gap(("events",), "the events function's isterminal and direction must be constants (one per event)")
        return
    table: dict = {}

    file, line, fname = definition_site(b.interp, fv)
    where = Path(file).name if file else b.file
    for k, name in enumerate(_event_names(fv, count)):
        try:
            when = namer.text(value.item(k))
        except (Unsupported, TooBig) as exc:
            b.gap(("events", name, "when"), f"the event's value cannot be written: {exc}")
            continue
        entry = {"when": when, "direction": _DIRECTIONS.get(direction[k], "both"), "terminal": terminal[k] != 0}
        table[name] = entry
        b.comment(("events", name), f"the events function {fname} ({where} line {line})"
                                    + (f", value {k + 1}" if count > 1 else ""))
    _reset(b, namer, names, table)
    b.spec.tables["events"] = table


def _reset(b, namer, names: list[str], table: dict) -> None:
    call = b.call
    if call.reset is None:
        return
    terminal = [name for name, entry in table.items() if isinstance(entry, dict) and entry["terminal"]]
    if not terminal:
        b.gap(("events",), "the restart loop restarts at an event that is not terminal")
        return
    try:
        reset = {names[i]: namer.text(item) for i, item in sorted(call.reset.items())}
    except (Unsupported, TooBig) as exc:
        b.gap(("events",), f"the restart loop's new initial state cannot be written: {exc}")
        return
    if not reset:
        reset = {names[0]: names[0]}
    for name in terminal:
        table[name]["reset"] = dict(reset)
        b.comment(("events", name, "reset"), f"the restart loop (line {call.restart_line}): y0 of the next call")
    if call.max_events:
        table["max_events"] = call.max_events
        b.comment(("events", "max_events"), f"the restart loop's {call.max_events} calls (line {call.restart_line})")
    else:
        b.comment(("events",), "the restart loop (a while loop) has no fixed count: odelab's max_events (100) bounds "
                               "it")
    for option in call.restart_notes:
        b.interp.note(call.restart_line, f"odeset(options, '{option}', ...)", IGNORED,
                      f"the loop's {option} for the next call: odelab restarts at each event as MATLAB's first call "
                      "starts", call.file)
