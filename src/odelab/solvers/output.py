"""What an adaptive driver does with each accepted step, written once: output, dense storage, events.

MATLAB's solvers share their output rules (Shampine & Reichelt, *The MATLAB ODE Suite*, SIAM
J. Sci. Comput. 18(1), 1997, Sec. 4 and ``ode45.m``): a two-element ``tspan`` gives ``Refine``
points per step (the step's end and ``refine - 1`` interior points at ``s = j/refine`` on its
continuous extension), a longer one output exactly at its entries; after each step the event
functions are located on the step's extension (:func:`odelab.solvers.events.locate_events`)
and a terminal event cuts the step; ``OutputFcn`` sees each step's new rows and may stop the
run; ``NonNegative`` components count a negative value as error and are clipped when accepted.
A driver keeps only its own step and interpolant and feeds this module's collector.

How a driver uses it (the explicit engine, ode113, the stiff solvers' ``implicit/driver.py``)::

    out = StepOutput(tspan, y0, refine, fields=[((s, n), dtype)], events=events, v0=v0,
                     output_fcn=output_fcn, refine_after=None)
    ...                                   # for each accepted step from (t, y) to (tnew, ynew):
    cut = out.locate(value_at, t, y, tnew, ynew)   # None, or (te, ye) of a terminal event
    if cut is not None: tnew, ynew = cut           # the step now ends at the event
    out.store.add(tnew, ynew, K)          # the step's record (one row per field), grown in place
    if out.per_step and out.emit(t, tnew, ynew, cut is not None, values, interior):
        ...                               # the output function asked to stop: Status.OUTPUT_STOP
    ...
    t_out, y_out = out.finish()           # the output arrays; out.store holds the step records

* ``value_at(tq)`` is the step's extension at one time (``(n,)``), for events;
* ``values(times, rows)`` writes the extension at the vector-``tspan`` entries inside the step
  (a list of m floats) into ``rows`` (m, n); the collector then puts ``ynew`` itself on an
  entry equal to ``tnew`` (a driver may leave that row unwritten);
* ``interior(times)`` at the step's ``refine - 1`` interior Refine times (``(refine-1, n)``).

A driver that interpolates the interior Refine points of all steps at once after the loop
(the explicit engine: a stacked product, cheaper than one per step) passes ``refine_after``:
``refine_after(store, fractions) -> (t_out, y_out)``; then ``interior`` is called only for an
output function. :class:`NonNegative` holds the constraint's test and clip, and
:class:`DriverResult` is what every driver returns.

Two choices of rounding differ between the drivers and are the collector's ``rules``
(:class:`OutputRules`): the explicit engine and ode113 write MATLAB's (``ode45.m``,
``ode15s.m``: ``tref = t + (tnew-t)*S`` with ``S = (1:Refine-1)/Refine``, and a terminal event
output after its step's ``tspan`` entries whenever entries remain), the stiff solvers
:data:`STIFF_RULES`, which their results were written with (each choice keeps its drivers'
results to the bit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["DriverResult", "NonNegative", "OutputRules", "MATLAB_RULES", "STIFF_RULES", "StepOutput", "StepStore"]

#: Steps the step arrays hold at first; they grow by a quarter (at least this many) when full.
FIRST_CAPACITY = 64


def grow_rows(arr: np.ndarray, rows: int) -> None:
    """Resize ``arr`` to ``rows`` rows in place.

    A realloc: the first rows keep their values, and the operating system remaps a long run's
    arrays instead of copying them (so growing one never holds two copies). No view of these
    arrays is taken before their last resize.
    """
    arr.resize((rows,) + arr.shape[1:], refcheck=False)


@dataclass(frozen=True, eq=False)
class DriverResult:
    """What an adaptive driver returns.

    ``t, y`` the output; ``nsteps, nfailed, nfevals`` the statistics (``fun(t0)`` is the
    caller's); ``status`` a :class:`~odelab.solvers.status.Status`; ``t_stop`` where the run
    stopped and ``h_stop`` the last step size tried; ``exception`` what ``fun`` (or the events
    or output function) raised, or None; ``found = (te, ye, ie)`` the located events (lists);
    ``steps`` the driver's dense output (the explicit engine's step arrays, ode113's
    :class:`~odelab.solvers.adams.AdamsDenseOutput`), or None. It unpacks in that order.
    """

    t: np.ndarray
    y: np.ndarray
    nsteps: int
    nfailed: int
    nfevals: int
    status: int
    t_stop: float
    h_stop: float
    exception: BaseException | None
    found: tuple
    steps: Any

    def __iter__(self):
        # the drivers returned this tuple before; callers still unpack it (no copy: astuple would deep-copy)
        return iter(tuple(getattr(self, name) for name in _FIELDS))


_FIELDS = tuple(DriverResult.__dataclass_fields__)


class NonNegative:
    """MATLAB's ``NonNegative``: which components, the test of a step and the clip after it.

    Shampine, Thompson, Kierzenka & Byrne, *Non-negative solutions of ODEs* (Appl. Math.
    Comput. 170, 2005): a step whose solution has a negative constrained component fails when
    that part, measured as the error is, exceeds the tolerance; an accepted step is clipped at
    zero (its interpolant keeps the unclipped stages).
    """

    __slots__ = ("idx", "threshold")

    def __init__(self, idx: np.ndarray, threshold, norm_control: bool):
        self.idx = idx
        self.threshold = threshold if norm_control else threshold[idx]

    def negative(self, y: np.ndarray) -> bool:
        """Whether a constrained component of ``y`` is negative."""
        return bool((y[self.idx] < 0).any())

    def excess(self, y: np.ndarray) -> np.ndarray:
        """The constrained components' negative parts, ``max(0, -y_i)`` (for a norm)."""
        return np.maximum(0.0, -y[self.idx])

    def error(self, y: np.ndarray) -> float:
        """The max-norm error of the negative parts, ``max_i max(0, -y_i) / (atol_i/rtol)``."""
        return float((np.maximum(0.0, -y[self.idx]) / self.threshold).max())

    def clip(self, y: np.ndarray) -> bool:
        """Clip ``y``'s constrained components at zero in place; whether any was negative."""
        idx = self.idx
        if (y[idx] < 0).any():
            y[idx] = np.maximum(y[idx], 0.0)
            return True
        return False


class StepStore:
    """Every accepted step's record in arrays grown in place (what dense output and deval read).

    ``t`` (N+1,) and ``y`` (N+1, n) hold ``t0, y0`` and each step's end; ``fields[j]`` (N, ...)
    the driver's per-step data (stages, differences, ...), one row a step. :meth:`trim` cuts
    them to the N steps taken (in place: no copy of a long run's arrays).
    """

    __slots__ = ("t", "y", "fields", "count", "capacity", "add", "_first", "_second", "_third", "_fourth")

    def __init__(self, t0: float, y0: np.ndarray, fields=()):
        capacity = FIRST_CAPACITY
        self.t = np.empty(capacity + 1)
        self.y = np.empty((capacity + 1, y0.size), dtype=y0.dtype)
        self.t[0] = t0
        self.y[0] = y0
        self.fields = [np.empty((capacity,) + tuple(shape), dtype=dtype) for shape, dtype in fields]
        self.count = 0
        self.capacity = capacity
        #: ``add(t_end, y_end, *rows)``: record one step, its end, its end state and one row of
        #: each field (a method chosen by the number of fields: a driver calls it every step)
        self.add = (self._add0, self._add1, self._add2, self._addn, self._add4)[len(self.fields)] \
            if len(self.fields) <= 4 else self._addn
        self._first, self._second, self._third, self._fourth = (self.fields + [None] * 4)[:4]

    def _add0(self, t_end: float, y_end: np.ndarray) -> None:
        k = self.count
        if k == self.capacity:
            self._grow()
        self.count = k = k + 1
        self.t[k] = t_end
        self.y[k] = y_end

    def _add1(self, t_end: float, y_end: np.ndarray, row) -> None:
        k = self.count
        if k == self.capacity:
            self._grow()
        self._first[k] = row
        self.count = k = k + 1
        self.t[k] = t_end
        self.y[k] = y_end

    def _add2(self, t_end: float, y_end: np.ndarray, row, second) -> None:
        k = self.count
        if k == self.capacity:
            self._grow()
        self._first[k] = row
        self._second[k] = second
        self.count = k = k + 1
        self.t[k] = t_end
        self.y[k] = y_end

    def _add4(self, t_end: float, y_end: np.ndarray, first, second, third, fourth) -> None:
        k = self.count
        if k == self.capacity:
            self._grow()
        self._first[k] = first
        self._second[k] = second
        self._third[k] = third
        self._fourth[k] = fourth
        self.count = k = k + 1
        self.t[k] = t_end
        self.y[k] = y_end

    def _addn(self, t_end: float, y_end: np.ndarray, *rows) -> None:
        k = self.count
        if k == self.capacity:
            self._grow()
        for arr, row in zip(self.fields, rows):
            arr[k] = row
        self.count = k = k + 1
        self.t[k] = t_end
        self.y[k] = y_end

    def _grow(self) -> None:
        self.capacity += max(self.count >> 2, FIRST_CAPACITY)
        grow_rows(self.t, self.capacity + 1)
        grow_rows(self.y, self.capacity + 1)
        for arr in self.fields:
            grow_rows(arr, self.capacity)

    def trim(self) -> None:
        k = self.count
        grow_rows(self.t, k + 1)
        if self.y is not None:
            grow_rows(self.y, k + 1)
        for arr in self.fields:
            grow_rows(arr, k)
        self.capacity = k


@dataclass(frozen=True)
class OutputRules:
    """Where drivers' output rules differ in rounding only (each keeps its drivers' results).

    ``refine_fractions``: True, a step's Refine times are ``t + (tnew - t) * (j / refine)``
    (MATLAB's ``t + (tnew-t)*S``); False, ``t + ((tnew - t) * j) / refine`` (the last bit may
    differ). ``terminal_repeats``: True, a terminal event's point is output after its step's
    ``tspan`` entries whenever entries remain, even when the event falls exactly on the entry
    just output (MATLAB's ``RequestedPoints`` loop outputs that time twice); False, only when it
    is not already the last output time.
    """

    refine_fractions: bool = True
    terminal_repeats: bool = True


#: MATLAB's rules (the explicit engine, ode113).
MATLAB_RULES = OutputRules()
#: The stiff solvers' (ode15s, ode23s, ode23t, ode23tb; and the compiled stiff kernels' ``_record``).
STIFF_RULES = OutputRules(refine_fractions=False, terminal_repeats=False)


class StepOutput:
    """The output, the step records and the events of one integration, fed step by step.

    Parameters
    ----------
    tspan, y0, refine
        MATLAB's output specification: two entries give ``refine`` rows per step, more give
        rows at those times only.
    fields
        ``(shape, dtype)`` of each per-step record the driver stores (:class:`StepStore`).
    events, v0
        ``events(t, y) -> (value, isterminal, direction)`` and its value at ``t0``, or None.
    output_fcn
        ``output_fcn(t_new, y_new) -> bool`` called with each step's new output rows; True stops.
    refine_after
        ``refine_after(store, fractions) -> (t_out, y_out)``: the driver computes the Refine
        output from the step records after the loop (then :meth:`emit` is needed only with an
        output function, :attr:`per_step`); None: the rows are interpolated step by step.
    rules
        :class:`OutputRules`: MATLAB's by default, :data:`STIFF_RULES` for the stiff solvers.
    """

    def __init__(self, tspan: np.ndarray, y0: np.ndarray, refine: int, fields=(), events=None, v0=None,
                 output_fcn=None, refine_after=None, rules: OutputRules = MATLAB_RULES):
        self.tspan = tspan
        self.t0 = t0 = float(tspan[0])
        self.tdir = 1.0 if float(tspan[-1]) > t0 else -1.0
        self.refine_mode = tspan.size == 2
        self.refine = refine
        self.fractions = np.arange(1, refine) / refine if self.refine_mode and refine > 1 else None
        # the stiff solvers' Refine times: t + ((t_end - t) * j) / refine
        self.multiples = None if rules.refine_fractions else np.arange(1, refine)
        self.terminal_repeats = rules.terminal_repeats
        self.store = StepStore(t0, y0, fields)
        self.events = events
        self.v = v0
        self.te: list[float] = []
        self.ye: list[np.ndarray] = []
        self.ie: list[int] = []
        self.output_fcn = output_fcn
        self.refine_after = refine_after
        # Rows to produce step by step: vector tspan, an output function, or Refine > 1 without
        # a driver that interpolates after the loop (refine 1: the output is the step records).
        self.per_step = (not self.refine_mode or output_fcn is not None
                         or (self.fractions is not None and refine_after is None))
        self.times = tspan.tolist()
        self.nxt = 1  # the next tspan entry to output, and its time
        self.t_next = self.times[1] if tspan.size > 1 else self.tdir * math.inf
        n = y0.size
        if not self.refine_mode:  # at most one row per entry, plus a terminal event's point
            self.t_out = [t0]
            self.y_out = np.empty((tspan.size + 1, n), dtype=y0.dtype)
            self.y_out[0] = y0
            self.nout = 1
        elif self.fractions is not None and refine_after is None:
            self.t_rows, self.y_rows = [t0], [y0.reshape(1, n).copy()]  # blocks, stacked once at the end

    @property
    def found(self) -> tuple:
        """``(te, ye, ie)``: the events located so far."""
        return self.te, self.ye, self.ie

    def locate(self, value_at, t: float, y: np.ndarray, tnew: float, ynew: np.ndarray):
        """Locate the events of the step ``(t, tnew]`` on ``value_at``; ``(te, ye)`` of a terminal
        event that cuts the step there, or None."""
        from odelab.solvers.events import locate_events

        found_t, found_y, found_i, self.v, stop = locate_events(value_at, self.events, self.v, t, y, tnew, ynew,
                                                                self.t0)
        if not found_t:
            return None
        self.te.extend(found_t)
        self.ye.extend(found_y)
        self.ie.extend(found_i)
        return (found_t[-1], found_y[-1]) if stop else None

    def interpolates(self, tnew: float) -> bool:
        """Whether the step ending at ``tnew`` has output inside it (Refine > 1, or a tspan entry)."""
        if self.refine_mode:
            return self.fractions is not None
        return self.tdir * (tnew - self.t_next) > 0

    def emit(self, t: float, t_end: float, y_end: np.ndarray, stop: bool, values, interior) -> bool:
        """The step's output rows (and the output function's call); True if it asks to stop."""
        if not self.refine_mode:
            if not stop and self.tdir * (t_end - self.t_next) < 0:
                return False  # no tspan entry in this step
            return self._at_tspan(t_end, y_end, stop, values)
        if self.fractions is not None:
            if self.multiples is None:
                t_new = np.append(t + (t_end - t) * self.fractions, t_end)
            else:
                t_new = np.append(t + (t_end - t) * self.multiples / self.refine, t_end)
            y_new = np.vstack([interior(t_new[:-1]), y_end])
            if self.refine_after is None:
                self.t_rows.extend(t_new.tolist())
                self.y_rows.append(y_new)
        else:
            t_new, y_new = np.array([t_end]), y_end.reshape(1, -1).copy()
        return self.output_fcn is not None and bool(self.output_fcn(t_new, y_new))

    def _at_tspan(self, t_end: float, y_end: np.ndarray, stop: bool, values) -> bool:
        times, tdir, nxt, before = self.times, self.tdir, self.nxt, self.nout
        wanted = []
        while nxt < len(times) and tdir * (t_end - times[nxt]) >= 0:
            wanted.append(times[nxt])
            nxt += 1
        self.nxt = nxt
        self.t_next = times[nxt] if nxt < len(times) else tdir * math.inf
        if wanted:
            rows = self.y_out[before:before + len(wanted)]
            values(wanted, rows)
            for j, tn in enumerate(wanted):
                if tn == t_end:
                    rows[j] = y_end
            self.t_out.extend(wanted)
            self.nout += len(wanted)
        if stop and (nxt < len(times) if self.terminal_repeats else self.t_out[-1] != t_end):
            # MATLAB outputs the terminal event's point too
            self.t_out.append(t_end)
            self.y_out[self.nout] = y_end
            self.nout += 1
        if self.output_fcn is None or self.nout == before:
            return False
        return bool(self.output_fcn(np.array(self.t_out[before:]), self.y_out[before:self.nout].copy()))

    def finish(self):
        """Trim the step records and return the output ``(t_out, y_out)``."""
        store = self.store
        store.trim()
        if not self.refine_mode:
            grow_rows(self.y_out, self.nout)
            return np.array(self.t_out), self.y_out
        if self.fractions is None:
            return store.t, store.y
        if self.refine_after is not None:
            if not store.count:
                return store.t, store.y
            return self.refine_after(store, self.fractions)
        return np.array(self.t_rows), np.vstack(self.y_rows)
