"""Zero-crossing detection for diagrams, as Simulink does it.

A block whose output's formula switches (saturation, dead zone, limited integrator, abs,
sign, switch, relay, min-max) declares *switching functions* of its inputs (and state) and a
*mode* per element (which formula applies). The hybrid driver
(:mod:`~odelab.systems.diagram.hybrid`) holds every mode constant during a piece of the
integration, so the right-hand side is smooth inside each step (no corner stepped over by
error control), and watches the switching functions that can leave the current modes as the
events of the piece: :mod:`odelab.solvers.events` (MATLAB's ``odezero``) locates the first one
on the step's interpolant, the piece ends there, the modes are chosen afresh from the signs of
the switching functions (a value of exactly zero takes the sign it crossed into) and the
integration restarts. A ramp of slope 1 into a saturation at 0.5 thus switches at t = 0.5 to
round-off whatever the tolerances.

The solver ignores an event function that is zero at the start of a piece (MATLAB's ``odezero``
ignores a zero at the initial point), so the driver never relies on one: at the start of the
run and of every piece without a crossing behind it, a switching function exactly zero takes
the sign it moves into (its value just after, along the flow: Simulink's initialisation reads
the direction the same way), and :meth:`Switching.departing` names the functions that leave a
zero at a piece's start in a direction their mode watches, the crossings an event at the
piece's start would have reported (a chattering switch among them).

This module holds the pieces that know about blocks and modes; it keeps no state of its own
(the modes live on the blocks while the driver runs, and are cleared after).
"""

from __future__ import annotations

import numpy as np

__all__ = ["Switching", "MAX_CONSECUTIVE"]

#: consecutive crossings closer together than the event tolerance that end the run (Simulink's
#: "number of consecutive zero crossings" limit, 1000)
MAX_CONSECUTIVE = 1000


class Switching:
    """The switching blocks of a compiled diagram and their modes.

    ``located`` are the blocks whose crossings are located (zero-crossing detection on); the
    ``stepped`` ones (a relay with ``zero_crossing = false``) change mode at the end of the
    step in which their switching function changed sign, as Simulink's blocks do without
    detection; every other switching block (detection off) reads its mode off its inputs.
    """

    def __init__(self, diagram, enabled: bool = True):
        self.diagram = diagram
        blocks = diagram.wiring.blocks
        self.blocks = [n for n in diagram.wiring.order if blocks[n].ZC]
        self.located = [n for n in self.blocks if enabled and blocks[n].zero_crossing]
        self.stepped = [n for n in self.blocks if n not in self.located and blocks[n].STATEFUL_MODE]
        self.held = self.located + self.stepped
        self.counts = {n: 0 for n in self.located + self.stepped}
        self.times: dict[str, list[float]] = {n: [] for n in self.counts}
        self._sizes: dict[str, int] = {}

    def __bool__(self) -> bool:
        return bool(self.held)

    # -- evaluation --------------------------------------------------------------------------------

    def _inputs(self, vals, name):
        w = self.diagram.wiring
        return [vals[p] for p in w.sources[name]]

    def _state(self, x, name):
        sl = self.diagram.slices.get(name)
        return None if sl is None else x[sl]

    def _extra(self, t, x, u, name) -> dict:
        """What a block needs besides its state and inputs: a rate limiter its input's slope."""
        if getattr(self.diagram.wiring.blocks[name], "NEEDS_SLOPE", False):
            return {"slope": self.diagram.input_slope(name, t, x, u)}
        return {}

    def raw(self, t, x, u, names) -> dict[str, np.ndarray]:
        """Each named block's switching functions at one point, with the modes as they are."""
        vals = self.diagram._ports(t, x, u, False)
        blocks = self.diagram.wiring.blocks
        return {n: blocks[n].zc_values(self._state(x, n), self._inputs(vals, n), **self._extra(t, x, u, n))
                for n in names}

    def sync(self, t, x, u, fired=()) -> np.ndarray:
        """The state with every rate limiter that tracks its input (or has just caught it) put
        exactly on its input, at an instant where the inputs are continuous (a located switch,
        the end of a piece before its jumps): no integration error is carried on."""
        blocks = self.diagram.wiring.blocks
        names = [n for n in self.held if hasattr(blocks[n], "caught")]
        if not names:
            return x
        x = np.array(x, dtype=float)
        for n in names:
            vals = self.diagram._ports(t, x, u, False)
            ins, sl = self._inputs(vals, n), self.diagram.slices[n]
            if blocks[n].caught(x[sl], ins, n in fired):
                x[sl] = np.asarray(ins[0], dtype=float).reshape(-1)[:1]
        return x

    def release(self) -> None:
        """Forget the held modes (blocks read them off their inputs again)."""
        for n in self.blocks:
            self.diagram.wiring.blocks[n].mode = None

    def ahead(self, t, x, u_of, dt: float, names=None) -> dict[str, np.ndarray]:
        """The switching functions just after ``t`` along the flow with the modes as they are:
        at ``(t + dt, x + dt f(t, x))``, ``u_of(t)`` the sources' values. Their signs say which
        way a function exactly zero at ``t`` moves."""
        names = self.held if names is None else names
        u = u_of(t)
        f = np.asarray(self.diagram._dynamics(t, x, u), dtype=float).reshape(-1)
        return self.raw(t + dt, np.asarray(x, dtype=float) + dt * f, u_of(t + dt), names)

    def departing(self, t, x, u_of, dt: float):
        """The located blocks whose switching function is exactly zero at ``t`` and leaves it,
        along the flow with the modes held, in a direction its mode watches: the crossings an
        event at ``t`` would report, which the solver does not (a zero at its initial point is
        not an event). Returns ``(names, after)``, ``after`` the values just after ``t`` (for
        :meth:`choose`), or ``([], None)``."""
        blocks = self.diagram.wiring.blocks
        now = self.raw(t, x, u_of(t), self.located)
        if not any(np.any(np.asarray(v) == 0) for v in now.values()):
            return [], None
        after = self.ahead(t, x, u_of, dt, self.located)
        hit = []
        for n in self.located:
            d = np.asarray(blocks[n].zc_directions(blocks[n].mode), dtype=float).reshape(-1)
            v, a = np.asarray(now[n], dtype=float).reshape(-1), np.asarray(after[n], dtype=float).reshape(-1)
            if v.shape != d.shape or a.shape != d.shape:
                continue
            fire = (v == 0) & ~np.isnan(d) & (np.sign(a) != 0) & (np.nan_to_num(d) * a >= 0)
            if np.any(fire):
                hit.append(n)
        return hit, (after if hit else None)

    def choose(self, t, x, u, before: dict[str, np.ndarray] | None = None, after=None) -> np.ndarray:
        """Set the modes the state ``x`` at ``t`` selects and return the state with the blocks'
        resets applied (an integrator put exactly at its limit, a relay's new output).

        A switching function exactly zero takes the sign opposite to its value ``before`` (the
        side it came from); without history, the sign of its value ``after`` (just after ``t``
        along the flow: a dict, or a function of ``x`` called with the modes read off the
        inputs, see :meth:`ahead`), so that the mode chosen at a zero is the one the run goes
        on in; or 0 (each block's own convention) when it stays zero. A relay keeps its own rule
        (on once u >= on_point). Blocks are visited in evaluation order, each seeing the modes
        already chosen upstream; blocks with state (whose outputs feed back) are revisited until
        nothing changes.
        """
        blocks = self.diagram.wiring.blocks
        x = np.array(x, dtype=float)
        for n in self.held:
            if not blocks[n].STATEFUL_MODE:
                blocks[n].mode = None
        if callable(after):
            after = after(x)
        for _ in range(len(self.held) + 2):
            moved = False
            for n in self.held:
                b = blocks[n]
                vals = self.diagram._ports(t, x, u, False)
                ins, xs = self._inputs(vals, n), self._state(x, n)
                held = b.mode
                if not b.STATEFUL_MODE:
                    b.mode = None
                extra = self._extra(t, x, u, n)
                raw = np.asarray(b.zc_values(xs, ins, **extra), dtype=float)
                signs = np.sign(raw)
                if before is not None and n in before and before[n].shape == raw.shape:
                    zero = signs == 0
                    signs[zero] = -np.sign(before[n][zero])
                if after is not None and not b.STATEFUL_MODE and n in after and np.shape(after[n]) == raw.shape:
                    zero = signs == 0
                    signs[zero] = np.sign(np.asarray(after[n], dtype=float)[zero])
                b.mode = held
                b.mode = np.asarray(b.zc_mode(signs, xs, ins, **extra))
                sl = self.diagram.slices.get(n)
                if sl is not None:
                    new = np.asarray(b.zc_reset(x[sl], b.mode), dtype=float).reshape(-1)
                    if not np.array_equal(new, x[sl]):
                        x[sl] = new
                        moved = True
            if not moved:
                break
        return x

    # -- the events of a piece ---------------------------------------------------------------------

    def event_function(self, signal_values):
        """MATLAB's events function for the located blocks at the modes now held:
        ``ev(t, x) -> (value, isterminal, direction)``; a function that cannot leave its mode is
        a constant 1 (never crosses). ``signal_values(t)`` are the sources' values."""
        blocks = self.diagram.wiring.blocks
        names = self.located
        dirs, watched, owners = [], [], []
        for n in names:
            d = np.asarray(blocks[n].zc_directions(blocks[n].mode), dtype=float).reshape(-1)
            watched.append(~np.isnan(d))
            dirs.append(np.nan_to_num(d, nan=0.0))
            owners.extend([n] * d.size)
        direction = np.concatenate(dirs) if dirs else np.zeros(0)
        mask = np.concatenate(watched) if watched else np.zeros(0, dtype=bool)
        terminal = np.ones(direction.size, dtype=bool)
        self.owners = owners

        def ev(t, x):
            raw = self.raw(t, x, signal_values(t), names)
            value = np.concatenate([raw[n] for n in names]) if names else np.zeros(0)
            return np.where(mask, value, 1.0), terminal, direction

        return ev

    def stepped_check(self, signal_values):
        """For blocks without location (a relay with detection off): ``changed(t, x)`` says
        whether a watched switching function has crossed in its direction since the last call."""
        blocks = self.diagram.wiring.blocks
        names = self.stepped
        last: dict[str, np.ndarray] = {}

        def changed(t, x) -> bool:
            raw = self.raw(t, x, signal_values(t), names)
            hit = False
            for n in names:
                d = np.asarray(blocks[n].zc_directions(blocks[n].mode), dtype=float)
                v = raw[n]
                if n in last:
                    a, b = last[n], v
                    crossed = (np.sign(a) != np.sign(b)) & (np.isnan(d) == False) & (np.nan_to_num(d) * (b - a) >= 0)  # noqa: E712
                    hit = hit or bool(np.any(crossed))
                last[n] = v
            return hit

        return changed

    def record(self, t: float, names) -> None:
        for n in dict.fromkeys(names):
            if n in self.counts:
                self.counts[n] += 1
                self.times[n].append(float(t))

    def summary(self) -> str:
        """"saturation sat: 1, relay r: 12" style text of the crossings per block."""
        blocks = self.diagram.wiring.blocks
        return ", ".join(f"{n} ({blocks[n].TYPE}) {c}" for n, c in self.counts.items())
