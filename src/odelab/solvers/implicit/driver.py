"""The one attempt loop of odelab's stiff solvers (ode15s, ode23s, ode23t, ode23tb).

Every stiff solver of the MATLAB ODE Suite advances the same way (Shampine & Reichelt, *The
MATLAB ODE Suite*, SIAM J. Sci. Comput. 18(1), 1997, Section 2-3): at the top of a step the
step size is clamped by MATLAB's rules (:func:`odelab.solvers.controller.clamp_step`); an
attempt either fails in its Newton iteration (the Jacobian is refreshed if it is stale, else
the step is cut), fails its error test (the step is cut by the method's rule), or is
accepted; a failure at ``|h| <= hmin`` stops the run; an accepted step is output (``Refine``
points or ``tspan`` times from the method's interpolant, events located on it, MATLAB's
NonNegative projection) by the collector every driver shares
(:class:`odelab.solvers.output.StepOutput`, with the stiff solvers' rounding
:data:`~odelab.solvers.output.STIFF_RULES`), and the next step size is chosen by the method.
:func:`integrate` is that loop, once; a :class:`Stepper` is one method's own part: its start,
its attempt, its reactions to a failure, what it keeps from an accepted step and how it chooses
the next one.
"""

from __future__ import annotations

import warnings

import numpy as np

from odelab.solvers.controller import clamp_step
from odelab.solvers.dense import clip_nonnegative
from odelab.solvers.implicit.common import Work
from odelab.solvers.output import STIFF_RULES, NonNegative, StepOutput
from odelab.solvers.status import Status

__all__ = ["STEPS", "Stepper", "integrate", "register_step"]


class Stepper:
    """One stiff method's step, driven by :func:`integrate`.

    The base holds what every method shares: the problem's :class:`Work` (function,
    Jacobian source, counters), the tolerances, MATLAB's ``threshold = AbsTol/RelTol``, the
    direction of integration, the current Jacobian ``J`` and whether it was formed at the
    current point (``jcurrent``, cleared by the driver after every accepted step), and the
    NonNegative constraint ``nn`` (or None).
    """

    #: A Newton failure that only refreshes a stale Jacobian still counts as a failed attempt
    #: of the step (no growth after it): ode23t's rule; ode15s and ode23tb do not count it.
    refresh_clears_nofailed = False
    #: The per-step record the collector's :class:`~odelab.solvers.output.StepStore` keeps for
    #: ``deval`` besides each step's end (``(shape, dtype)`` of each field), and its rows for
    #: the last accepted step (:meth:`accept` sets them).
    fields: tuple = ()
    rows: tuple = ()

    @classmethod
    def for_run(cls, work: Work, tspan, rtol: float, atol: np.ndarray, extra: dict, nonnegative=None):
        """The step of one run from its resolved options (``extra``: the stiff solvers' own, see
        :func:`odelab.solvers.implicit.resolve_extras`); a method with options of its own overrides it."""
        return cls(work, tspan, rtol, atol, nonnegative)

    #: Seconds the first compile of the method's compiled twin costs (its loop in
    #: solvers/compiled/loops/, if it has one), measured on a 2-core machine, idle (bench/bench_compiled.py).
    compile_seconds: float | None = None

    @classmethod
    def compiled_arguments(cls, extra: dict) -> tuple:
        """What the compiled twin's loop takes after the arguments every stiff loop takes (its own options)."""
        return ()

    def __init__(self, work: Work, tspan, rtol: float, atol: np.ndarray, nonnegative=None):
        self.work = work
        self.rtol = rtol
        self.atol = atol
        self.threshold = atol / rtol
        self.t0, self.tf = float(tspan[0]), float(tspan[-1])
        self.htspan = abs(float(tspan[1]) - self.t0)
        self.tdir = 1.0 if self.tf > self.t0 else -1.0
        self.nn = None if nonnegative is None else NonNegative(nonnegative, self.threshold, False)
        self.J = None
        self.jcurrent = False

    def refresh_jacobian(self, t: float, y: np.ndarray) -> None:
        """Form ``J`` again at ``(t, y)`` (numjac's ``thresh`` is AbsTol, as in MATLAB)."""
        self.J = self.work.jacobian(t, y, None, self.atol)
        self.jcurrent = True
        self.jacobian_changed()

    def jacobian_changed(self) -> None:
        """The iteration matrix must be formed again (a new ``J``)."""

    # --- the method's own part --------------------------------------------------------------

    def start(self, t: float, y: np.ndarray, f0: np.ndarray, hmax: float, htry: float) -> float:
        """Prepare the first step at ``(t0, y0)`` and return its size ``|h|``."""
        raise NotImplementedError

    def begin_step(self, t: float, y: np.ndarray, absh_before: float, absh: float, done: bool) -> None:
        """The step size was clamped from ``absh_before`` to ``absh`` (``done``: it lands on tf)."""

    def attempt(self, t: float, y: np.ndarray, absh: float, done: bool):
        """Try the step: ``(ynew, err)`` with ``err`` in units of RelTol's norm, or None when
        the Newton iteration did not converge."""
        raise NotImplementedError

    def after_newton_failure(self, absh: float, hmin: float) -> float:
        """The step after a Newton failure with a current Jacobian (MATLAB: 0.3 |h|)."""
        raise NotImplementedError

    def after_error_failure(self, absh: float, hmin: float, err: float, nfails: int, nofailed: bool) -> float:
        """The step after a failed error test (``nfails``: error failures of this step so far)."""
        raise NotImplementedError

    def accept(self, t: float, y: np.ndarray, ynew: np.ndarray):
        """Keep the accepted step; return ``(tnew, ynew, interp)``, ``interp(times)`` the step's
        interpolant as states (len(times), n); the step's record goes in :attr:`rows`."""
        raise NotImplementedError

    def cut(self, t: float) -> None:
        """A terminal event ended the last accepted step at ``t`` (before its record is stored)."""

    def next_step(self, absh: float, err: float, nofailed: bool) -> float:
        """The size of the next step after an accepted one."""
        raise NotImplementedError

    def dense(self, y_final: np.ndarray, store):
        """The solution's dense output for ``deval`` from the steps' records (or None)."""
        return None


#: Each stiff solver's step class by its method's name (the registry's), registered by its own module with
#: :func:`register_step`; :func:`odelab.solvers.implicit.solve_implicit` looks the class up here.
STEPS: dict[str, type[Stepper]] = {}


def register_step(name: str):
    """Register the decorated :class:`Stepper` subclass as the step of the method ``name``."""
    def add(cls: type[Stepper]) -> type[Stepper]:
        if name in STEPS and STEPS[name] is not cls:
            raise ValueError(f"a step class for {name!r} is registered already ({STEPS[name].__name__})")
        STEPS[name] = cls
        return cls

    return add


class _Interpolant:
    """The last accepted step's interpolant as the collector calls it (NonNegative: clipped)."""

    __slots__ = ("interp", "tnew", "idx")

    def __init__(self, nn):
        self.idx = None if nn is None else nn.idx
        self.interp = self.tnew = None

    def set(self, tnew: float, interp) -> None:
        self.tnew = tnew
        if self.idx is None:
            self.interp = interp
        else:
            idx = self.idx
            self.interp = lambda times: clip_nonnegative(np.array(interp(times), dtype=float), idx)

    def value_at(self, tq: float) -> np.ndarray:
        return self.interp(np.array([tq]))[0]

    def values(self, times, rows) -> None:
        times = np.array(times)
        inside = times != self.tnew  # the collector writes ynew on an entry equal to tnew
        if inside.any():
            rows[inside] = self.interp(times[inside])

    def interior(self, times) -> np.ndarray:
        return self.interp(times)


def integrate(stepper: Stepper, tspan, y0, f0, hmax, htry, refine, max_steps, events=None):
    """Run ``stepper`` over ``tspan``; returns the engine's tuple
    ``(t, y, nsteps, nfailed, status, t_stop, h_stop, exc)``.

    ``events``: ``(ev, v0)`` (MATLAB's Events) located on each accepted step's interpolant; the
    events found and the dense output are left in ``stepper.work`` (``found``, ``dense``)."""
    work, rtol, nn = stepper.work, stepper.rtol, stepper.nn
    tf = stepper.tf
    ev, v0 = events if events is not None else (None, None)
    out = StepOutput(tspan, y0, refine, stepper.fields, ev, v0, rules=STIFF_RULES)
    add, per_step, step = out.store.add, out.per_step, _Interpolant(nn)
    nsteps = nfailed = 0
    status, exception = Status.SUCCESS, None
    t, y = stepper.t0, y0.copy()
    absh = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # singular iteration matrices show as failed Newton iterations
        try:
            absh = stepper.start(t, y, f0, hmax, htry)
            while True:
                absh_before = absh
                hmin, absh, done = clamp_step(t, tf, absh, hmax)
                stepper.begin_step(t, y, absh_before, absh, done)
                nofailed, nfails = True, 0
                while True:  # attempts at this step
                    trial = stepper.attempt(t, y, absh, done)
                    if trial is None:  # the Newton iteration did not converge
                        nfailed += 1
                        nofailed = nofailed and not stepper.refresh_clears_nofailed
                        if not stepper.jcurrent:
                            stepper.refresh_jacobian(t, y)
                            continue
                        if absh <= hmin:
                            status = Status.STEP_UNDERFLOW
                            break
                        absh = stepper.after_newton_failure(absh, hmin)
                        done, nofailed = False, False
                        continue
                    ynew, err = trial
                    if nn is not None and err <= rtol and nn.negative(ynew):
                        # MATLAB's NonNegative test (Shampine, Thompson, Kierzenka & Byrne 2005): the
                        # negative part becomes the error when larger than the tolerance, so the
                        # method's own failure rule shrinks the step (ode15s's with its order drop)
                        err_nn = nn.error(ynew)
                        if err_nn > rtol:
                            err = err_nn
                    if err > rtol:
                        nfailed += 1
                        nfails += 1
                        if absh <= hmin:
                            status = Status.STEP_UNDERFLOW
                            break
                        absh = stepper.after_error_failure(absh, hmin, err, nfails, nofailed)
                        done, nofailed = False, False
                        continue
                    if err != err:
                        status = Status.NONFINITE
                    break
                if status != Status.SUCCESS:
                    break

                nsteps += 1
                if nn is not None and nn.negative(ynew):  # project onto y_i >= 0 (a copy: ode15s compares)
                    ynew = ynew.copy()
                    nn.clip(ynew)
                tnew, ynew, interp = stepper.accept(t, y, ynew)
                step.set(tnew, interp)
                stop = False
                if ev is not None:
                    cut = out.locate(step.value_at, t, y, tnew, ynew)
                    if cut is not None:  # a terminal event: the step (and its record) ends there
                        tnew, ynew, stop = cut[0], np.asarray(cut[1], dtype=float), True
                        stepper.cut(tnew)
                add(tnew, ynew, *stepper.rows)
                if per_step:
                    out.emit(t, tnew, ynew, stop, step.values, step.interior)
                if stop:
                    t, y = tnew, ynew
                    status = Status.TERMINAL_EVENT
                    break
                t, y = tnew, ynew
                stepper.jcurrent = False
                if done:
                    break
                if max_steps and nsteps >= max_steps:
                    status = Status.MAX_STEPS
                    break
                absh = stepper.next_step(absh, err, nofailed)
        except Exception as exc:  # the user's right-hand side (or Jacobian) failed
            status, exception = Status.FUN_RAISED, exc
    t_out, y_out = out.finish()
    work.found = out.found
    work.dense = stepper.dense(y, out.store)
    return t_out, y_out, nsteps, nfailed, status, t, absh, exception
