"""Public solver functions: :func:`ode23`, :func:`ode45` and :func:`solve`."""

from __future__ import annotations

import math
import os
import traceback

import numpy as np

import warnings
from dataclasses import replace

from odelab.exceptions import InputError, SolverWarning
from odelab.solution import Solution, Stats
from odelab.solvers import engine
from odelab.solvers.controller import min_step
from odelab.solvers.optionset import DEFAULT_ATOL, DEFAULT_RTOL
from odelab.solvers.options import (SolverOptions, as_tspan, as_y0, normalize_options, resolve_options,
                                   resolved_for)
from odelab.solvers.registry import DRIVERS, RESIDUAL_METHOD, Method, get_method, join_names, methods_with
from odelab.solvers.status import Status

__all__ = ["ode23", "ode45", "solve", "odextend"]


def ode23(fun, tspan, y0, *, rtol=DEFAULT_RTOL, atol=DEFAULT_ATOL, max_step=None, initial_step=None, refine=None,
          norm_control=False, **matlab_options) -> Solution:
    """Solve a non-stiff ODE with MATLAB's ``ode23`` (Bogacki-Shampine 3(2)).

    Reproduces MATLAB's ``[t, y] = ode23(fun, tspan, y0, odeset(...))`` step for step: the same
    initial step, step-size control, error norm and output points.

    Parameters
    ----------
    fun : callable
        ``fun(t, y)`` with ``y`` a 1-D float array; returns dy/dt (array-like, or a scalar for
        one state).
    tspan : sequence of float
        ``[t0, tf]`` (output at every step, ``refine`` points per step) or a longer strictly
        increasing or decreasing sequence of output times.
    y0 : float or sequence of float
        Initial state.
    rtol, atol : float, float or sequence of float
        Relative tolerance and absolute tolerance (scalar or one per state); MATLAB's defaults.
    max_step : float, optional
        Largest step; default ``0.1 * |tf - t0|``.
    initial_step : float, optional
        First step to try; default chosen from ``fun(t0, y0)`` as MATLAB does.
    refine : int, optional
        Output points per step with a two-element ``tspan`` (default 1).
    norm_control : bool
        Control the Euclidean norm of the error (MATLAB's ``NormControl``).
    **matlab_options
        MATLAB's option names (``RelTol``, ``AbsTol``, ``MaxStep``, ``InitialStep``,
        ``Refine``, ``NormControl``, ``Events``, ``NonNegative``, ``Mass``, ``MStateDependence``,
        ``OutputFcn``, ``OutputSel``), ``max_steps`` (stop after that many steps) and:

        - ``events``: ``ev(t, y) -> (value, isterminal, direction)`` as MATLAB's events
          function (or SciPy's list of functions with ``terminal``/``direction`` attributes).
        - ``nonnegative``: 0-based indices of components kept >= 0. MATLAB's spelling
          ``NonNegative`` takes MATLAB's 1-based indices, since that is what a MATLAB user types.
        - ``mass``: ``M``, ``M(t)`` or ``M(t, y)`` for ``M y' = f``; ``mstate_dependence``
          "none" (``M(t)``), "weak" or "strong" (``M(t, y)``).
        - ``output_fcn``: ``f(t, y, flag)`` with flags "init", "" and "done"; returning True
          stops. ``output_sel``: 0-based components passed to it (``OutputSel``: 1-based).
        - ``args``: a tuple of extra arguments for ``fun`` (and events, mass).

        ``y0`` may be complex (complex arithmetic, error norm on ``|y|``, as MATLAB).

    Returns
    -------
    Solution
        ``t`` (N,), ``y`` (N, n), ``stats``, ``status`` and ``message``; ``te``, ``ye``, ``ie``
        (events, 0-based indices); ``deval``/``sol(t)`` (the method's interpolant). A failed
        integration returns the solution up to where it stopped with ``status == "failed"``
        and issues an :class:`~odelab.exceptions.SolverWarning` with the message. A terminal
        event or an output function's stop is not a failure.

    Raises
    ------
    InputError
        A ``ValueError`` naming the bad argument, its value and the fix.

    Examples
    --------
    >>> import numpy as np, odelab
    >>> sol = odelab.ode23(lambda t, y: np.cos(t), [0, np.pi], 2.0)
    >>> sol.t.size, sol.stats.nsteps
    (12, 11)
    """
    return _matlab_solver("ode23", fun, tspan, y0, rtol, atol, max_step, initial_step, refine, norm_control,
                          matlab_options)


def ode45(fun, tspan, y0, *, rtol=DEFAULT_RTOL, atol=DEFAULT_ATOL, max_step=None, initial_step=None, refine=None,
          norm_control=False, **matlab_options) -> Solution:
    """Solve a non-stiff ODE with MATLAB's ``ode45`` (Dormand-Prince 5(4)).

    Same arguments and result as :func:`ode23`; ``refine`` defaults to 4, as in MATLAB.

    Examples
    --------
    >>> import odelab
    >>> rigid = lambda t, y: [y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]]
    >>> sol = odelab.ode45(rigid, [0, 12], [0, 1, 1], RelTol=1e-4, AbsTol=[1e-4, 1e-4, 1e-5])
    >>> sol.stats
    Stats(nsteps=21, nfailed=0, nfevals=127)
    """
    return _matlab_solver("ode45", fun, tspan, y0, rtol, atol, max_step, initial_step, refine, norm_control,
                          matlab_options)


def _matlab_solver(name, fun, tspan, y0, rtol, atol, max_step, initial_step, refine, norm_control, extra):
    options = dict(extra)
    # Explicit keywords count only when they differ from the defaults, so MATLAB's names in
    # **extra can be used alone without a clash.
    for key, value, default in (
        ("rtol", rtol, DEFAULT_RTOL),
        ("atol", atol, DEFAULT_ATOL),
        ("max_step", max_step, None),
        ("initial_step", initial_step, None),
        ("refine", refine, None),
        ("norm_control", norm_control, False),
    ):
        if value is not None and not (np.isscalar(value) and np.isscalar(default) and value == default
                                      and type(value) is type(default)):
            options[key] = value
    sol = _solve(fun, tspan, y0, name, options)
    _warn_if_failed(sol, 4)
    _warn_if_implausible(sol, 4)
    return sol


def solve(fun, tspan, y0, method: str = "ode45", *, resolved: SolverOptions | None = None, **options) -> Solution:
    """Solve an initial value problem with any method odelab knows, by name.

    Parameters
    ----------
    fun, tspan, y0
        As for :func:`ode45`.
    method : str
        ``"ode23"``, ``"ode45"``, ``"ode78"``, ``"ode89"`` and the rest of MATLAB's suite
        (``odelab.ode15s`` and co.); ``"euler"``, ``"heun"``, ``"midpoint"``,
        ``"ralston"``, ``"rk3"``, ``"rk4"`` (fixed step ``h``); ``"RK23"``, ``"RK45"``,
        ``"DOP853"``, ``"Radau"``, ``"BDF"``, ``"LSODA"`` (SciPy). See ``odelab.METHODS``.
    **options
        ``rtol``, ``atol``, ``max_step``, ``initial_step``, ``refine``, ``norm_control``,
        ``max_steps`` (adaptive methods), ``h`` (fixed-step methods), ``args`` (all methods);
        ``events``, ``nonnegative``, ``mass``, ``mstate_dependence``, ``output_fcn``,
        ``output_sel`` (ode23/ode45/ode78/ode89/ode113; ``events`` also ode15s/ode23s/ode23t/ode23tb,
        ``nonnegative`` also ode15s/ode23t/ode23tb without a mass matrix, as MATLAB's);
        MATLAB's names too. See :func:`ode45`.
    resolved : SolverOptions, optional
        Options already normalised and resolved (a loaded case's, ``Problem.solver_options``), instead of
        ``**options``: used as they are when resolved for this method, span and number of states, else
        resolved again from the options they were given for this span.

    Returns
    -------
    Solution
        A failed integration returns the partial solution and issues a
        :class:`~odelab.exceptions.SolverWarning` with its message.
    """
    if resolved is not None:
        check_resolved(resolved, options)
    sol = _solve(fun, tspan, y0, method, options if resolved is None else resolved)
    _warn_if_failed(sol, 3)
    _warn_if_implausible(sol, 3)
    return sol


def odextend(sol, fun, tfinal: float, y0=None, **options):
    """Continue a solution to ``tfinal`` (MATLAB's ``solext = odextend(sol, odefun, tfinal)``).

    The integration restarts at ``sol.t[-1]`` from ``sol.y[-1]`` (or ``y0``) with the same method
    and options (override any with ``**options``; ``fun=None`` keeps the original function) and
    the result is joined to ``sol``: times, states, events, statistics and dense output.
    """
    setup = getattr(sol, "setup", None)
    if setup is None:
        raise InputError(
            "odextend needs a solution returned by ode23, ode45, ode78, ode89 or odelab.solve with one of them.", key="sol"
        )
    if fun is None:
        fun = setup["fun"]
    merged = {**setup["options"], **options}
    start = sol.y[-1] if y0 is None else y0
    more = solve(fun, [float(sol.t[-1]), float(tfinal)], start, method=sol.method, **merged)
    interpolant = None
    if sol.interpolant is not None and more.interpolant is not None:
        interpolant = sol.interpolant.extended(more.interpolant)
    n = sol.y.shape[1]
    ye = np.concatenate([sol.ye.reshape(-1, n), more.ye.reshape(-1, n)])
    return Solution(
        t=np.concatenate([sol.t, more.t[1:]]),
        y=np.concatenate([sol.y, more.y[1:]]),
        stats=Stats(nsteps=sol.stats.nsteps + more.stats.nsteps,
                    nfailed=sol.stats.nfailed + more.stats.nfailed,
                    nfevals=sol.stats.nfevals + more.stats.nfevals),
        status=more.status,
        reason=more.reason,
        message=more.message,
        method=sol.method,
        warnings=sol.warnings + more.warnings,
        te=np.concatenate([sol.te, more.te]),
        ye=ye,
        ie=np.concatenate([sol.ie, more.ie]),
        interpolant=interpolant,
        setup={"fun": fun, "options": merged},
    )


def _warn_if_failed(sol: Solution, stacklevel: int) -> None:
    if sol.status == "failed":
        warnings.warn(sol.message, SolverWarning, stacklevel=stacklevel)


def _solve(fun, tspan, y0, method: str, options: dict | SolverOptions) -> Solution:
    sol = _solve_method(fun, tspan, y0, method, options)
    if get_method(method).stiff and sol.status == "success":  # a stiff run's result checked (plausibility.py)

        from odelab.solvers.plausibility import implausible

        note = implausible(sol.t, sol.y, np.asarray(sol.y[0]), _atol_of(sol, options), sol.method)
        if note is not None:
            sol = replace(sol, warnings=tuple(sol.warnings) + (note,))
    return sol


def _atol_of(sol: Solution, options: dict | SolverOptions):
    if isinstance(options, SolverOptions):
        return np.asarray(options.atol, dtype=float).ravel()
    atol = normalize_options(options, get_method(sol.method)).get("atol", DEFAULT_ATOL)
    return np.asarray(atol, dtype=float).ravel()


def check_resolved(resolved, options: dict) -> None:
    """``resolved=`` is a SolverOptions and comes alone (odelab.solve's and solve_compiled's rule)."""
    if options:
        raise InputError(f"give the options either resolved or as keywords, not both; got `resolved` and "
                         f"{', '.join(f'`{k}`' for k in options)}.", key="resolved")
    if not isinstance(resolved, SolverOptions):
        raise InputError(f"`resolved` must be a SolverOptions (odelab.solvers.options.resolve_options); got "
                         f"{resolved!r}.", key="resolved")


def _given(options: dict | SolverOptions, m: Method) -> dict:
    """The options as given, in odelab's names, checked against ``m``: normalised once (resolved ones were)."""
    if isinstance(options, SolverOptions):
        return dict(options.given) if get_method(options.method) is m else normalize_options(options.given, m)
    return normalize_options(options, m)


def _warn_if_implausible(sol: Solution, stacklevel: int) -> None:
    from odelab.solvers.plausibility import PREFIX

    for note in sol.warnings:
        if note.startswith(PREFIX):
            warnings.warn(note, SolverWarning, stacklevel=stacklevel)


def _solve_method(fun, tspan, y0, method: str, options: dict) -> Solution:
    m = get_method(method)
    if not callable(fun):
        raise InputError(f"`fun` must be a callable fun(t, y); got {fun!r}.", key="fun")
    delayed = getattr(fun, "lags", None) is not None and hasattr(fun, "ddefun")
    if delayed and not m.delays:
        names = " or ".join(f'method = "{n}"' for n in methods_with(lambda x: x.delays, delays=True))
        raise InputError(f"this system has delayed states (lag(...)): {m.name} solves ordinary equations only; "
                         f"use {names} (MATLAB's solver for delay equations).", key="method")
    if hasattr(fun, "residual") and hasattr(fun, "partials") and hasattr(fun, "start"):
        return _solve_implicit_system(fun, tspan, y0, m, options)
    return DRIVERS[m.kind].run(fun, tspan, y0, m, options)  # the driver of the method's kind


# --- the drivers (registry.DRIVERS): run(fun, tspan, y0, method, options) -> Solution ---------------------------

def drive_residual(fun, tspan, y0, m: Method, options: dict) -> Solution:
    """Methods of kind ``"residual"`` (ode15i) take F(t, y, y'), through :func:`solve_residual`, not f(t, y)."""
    raise InputError(f"{m.name} solves fully implicit systems F(t, y, y') = 0 from y0 and a consistent slope "
                     f"yp0: call odelab.{m.name}(F, tspan, y0, yp0) (odelab.decic makes them consistent); "
                     "for y' = f(t, y) use ode15s.", key="method")


def _prepared(fun, tspan, y0, m: Method, options: dict):
    """The arrays, the options resolved once and ``fun`` with MATLAB's extra arguments bound:
    ``(fun, user_fun, tspan, y0, given, opts)``."""
    tspan_arr = as_tspan(tspan)
    y0_arr = as_y0(y0, allow_complex=True)
    if np.iscomplexobj(y0_arr) and not m.complex_y0:
        raise InputError(f"a complex `y0` is integrated by {'/'.join(methods_with(lambda x: x.complex_y0))} "
                         f"(as MATLAB's); {m.name} takes real y0: split it into real and imaginary parts.", key="y0")
    given = _given(options, m)  # the keyword API's options normalised once; a loaded case's carried as resolved
    opts = resolved_for(m, options, tspan_arr, y0_arr.size) if isinstance(options, SolverOptions) else \
        resolve_options(m, given, tspan_arr, y0_arr.size)
    user_fun = fun
    if opts.args:
        args = opts.args

        def fun(t, y, _f=user_fun):
            return _f(t, y, *args)

    return fun, user_fun, tspan_arr, y0_arr, given, opts


def _started(fun, tspan_arr, y0_arr, m: Method, opts: SolverOptions):
    """The first derivative, checked: ``(rhs, f0, None)``, or ``(None, None, failed)`` with the
    solution of a run that could not start."""
    t0 = float(tspan_arr[0])
    try:
        f0_raw = fun(t0, y0_arr.copy())
    except Exception as exc:
        return None, None, _failed_at_start(m, tspan_arr, y0_arr, opts, f"the right-hand side raised "
                                            f"{_describe(exc)} at t = {t0:g} (the first call)", Status.FUN_RAISED)
    rhs, f0 = _checked_rhs(fun, f0_raw, y0_arr)
    if not np.all(np.isfinite(f0)):
        return None, None, _failed_at_start(m, tspan_arr, y0_arr, opts, f"the derivative at t = {t0:g} is not "
                                            f"finite ({_fmt_vec(f0)}): check the right-hand side at the initial state")
    return rhs, f0, None


def drive_scipy(fun, tspan, y0, m: Method, options: dict) -> Solution:
    """SciPy's solver classes, stepped (:mod:`odelab.solvers.scipy_adapter`)."""
    from odelab.solvers.scipy_adapter import solve_scipy

    fun, _, tspan_arr, y0_arr, _, opts = _prepared(fun, tspan, y0, m, options)
    return solve_scipy(fun, tspan_arr, y0_arr, m, opts)


def drive_adaptive(fun, tspan, y0, m: Method, options: dict, multistep=None) -> Solution:
    """odelab's explicit pairs (the engine); ``multistep``: a multistep method's integrator instead, which the
    driver of that kind passes (:func:`odelab.solvers.adams.drive_multistep`), with the same preparation and
    output."""
    fun, user_fun, tspan_arr, y0_arr, given, opts = _prepared(fun, tspan, y0, m, options)
    rhs, f0, failed = _started(fun, tspan_arr, y0_arr, m, opts)
    if failed is not None:
        return failed
    return _solve_adaptive(rhs, tspan_arr, y0_arr, f0, m, opts, {"fun": user_fun, "options": given}, multistep)


def drive_implicit(fun, tspan, y0, m: Method, options: dict) -> Solution:
    """odelab's stiff solvers (:mod:`odelab.solvers.implicit`: a step class each, registered by name)."""
    fun, _, tspan_arr, y0_arr, _, opts = _prepared(fun, tspan, y0, m, options)
    rhs, f0, failed = _started(fun, tspan_arr, y0_arr, m, opts)
    if failed is not None:
        return failed
    return _solve_implicit(rhs, tspan_arr, y0_arr, f0, m, opts)


def drive_fixed(fun, tspan, y0, m: Method, options: dict) -> Solution:
    """odelab's explicit Runge-Kutta methods on a fixed step ``h``."""
    fun, _, tspan_arr, y0_arr, _, opts = _prepared(fun, tspan, y0, m, options)
    rhs, _, failed = _started(fun, tspan_arr, y0_arr, m, opts)
    if failed is not None:
        return failed
    return _solve_fixed(rhs, tspan_arr, y0_arr, m, opts)


def solve_residual(fun, tspan, y0, yp0, method: str = RESIDUAL_METHOD, **options) -> Solution:
    """Solve a fully implicit system ``F(t, y, y') = 0`` from consistent ``y0, yp0`` (``odelab.ode15i``).

    The entry point of the methods of kind ``"residual"`` (:data:`odelab.solvers.registry.DRIVERS`);
    ``fun(t, y, yp)`` returns the residual, ``options`` as :func:`odelab.ode15i` documents them."""
    m = get_method(method)
    if not m.residual:
        raise InputError(f"{m.name} solves y' = f(t, y); a fully implicit F(t, y, y') = 0 is solved by "
                         f"{join_names(methods_with(lambda x: True, residual=True), 'or')}.", key="method")
    if not callable(fun):
        raise InputError(f"`fun` must be a callable F(t, y, yp) returning the residual; got {fun!r}.", key="fun")
    tspan_arr = as_tspan(tspan)
    y0_arr = as_y0(y0)
    try:
        yp0_arr = as_y0(yp0)
    except InputError as exc:
        raise InputError(str(exc).replace("`y0`", "`yp0`"), key="yp0") from None
    n = y0_arr.size
    if yp0_arr.size != n:
        raise InputError(f"`yp0` has {yp0_arr.size} entries but `y0` has {n}: give one initial slope per state.",
                         key="yp0")
    given = normalize_options(options, m)
    if given.get("events") is not None and not callable(given["events"]):
        raise InputError(f"`events` of {m.name} is one function events(t, y, yp) returning (value, isterminal, "
                         f"direction), as MATLAB's; got {given['events']!r}.", key="events")
    opts = resolve_options(m, given, tspan_arr, n)
    args = opts.args
    if args:
        def fun(t, y, yp, _f=fun):
            return _f(t, y, yp, *args)

    t0 = float(tspan_arr[0])
    try:
        raw = fun(t0, y0_arr.copy(), yp0_arr.copy())
    except Exception as exc:
        return _failed_at_start(m, tspan_arr, y0_arr, opts, f"the residual raised {_describe(exc)} at t = {t0:g} "
                                "(the first call)", Status.FUN_RAISED)
    try:
        f0 = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"`fun` must return numbers (one residual per state); it returned {raw!r}.",
                         key="fun") from None
    if f0.size != n:
        raise InputError(f"`fun` returned {f0.size} residual{'s' if f0.size != 1 else ''} but the state has {n}: "
                         "return one residual per state (as many equations as unknowns).", key="fun")
    f0 = f0.reshape(n)
    if not np.all(np.isfinite(f0)):
        return _failed_at_start(m, tspan_arr, y0_arr, opts, f"the residual at t = {t0:g} is not finite "
                                f"({_fmt_vec(f0)}): check F at the initial state and slope")
    from odelab.solvers.implicit import step_class
    from odelab.solvers.implicit.residual import ResidualWork, index_problem

    atol = np.broadcast_to(np.asarray(opts.atol, dtype=float), (n,))
    work = ResidualWork(fun, n, jacobian=opts.extra["jacobian"], atol=atol)
    dfdy, dfdyp = work.partials(t0, y0_arr, yp0_arr, f0)
    why = index_problem(dfdy, dfdyp)
    if why is not None:
        raise InputError(f"{m.name} solves ODEs and DAEs of index 1, as MATLAB's; at t = {t0:g} {why}. Write the "
                         "hidden constraints out (differentiate the algebraic equations until the system is of "
                         "index 1).", key="fun")
    (t, y, nsteps, nfailed, status, t_stop, h_stop, exc), stepper, found = step_class(m.name).run(
        work, tspan_arr, y0_arr, yp0_arr, f0, opts.rtol, atol, opts.max_step, opts.initial_step, opts.refine,
        opts.max_steps, opts.extra["max_order"], opts.events, args, dfdy, dfdyp)
    stats = Stats(nsteps=nsteps, nfailed=nfailed, nfevals=work.nfevals + 1, npds=work.npds,
                  ndecomps=work.ndecomps, nsolves=work.nsolves)
    te, ye, ie = found
    message = _status_message(status, m, t_stop, h_stop, y, y0_arr, opts, exc, tspan_arr, te, ie)
    if status == Status.STEP_UNDERFLOW:
        if stepper.singular_at is not None:
            message += (f" The iteration matrix dF/dy + (alpha/h) dF/dy' was singular at t = {stepper.singular_at:.6g}:"
                        f" {m.name} solves ODEs and DAEs of index 1; a DAE of index 2 or higher, or one whose "
                        "algebraic equations do not determine its algebraic variables there, cannot be solved.")
        else:
            message = message.replace("the problem is stiff (try method 'ode15s', or 'ode23s' at crude tolerances), ",
                                      "the DAE is not of index 1 there, ")
    notes = tuple(opts.warnings)
    if status == Status.SUCCESS:  # a stiff run's result checked, as the other stiff solvers' (plausibility.py)
        from odelab.solvers.plausibility import implausible

        note = implausible(t, y, y0_arr, atol, m.name)
        if note is not None:
            notes += (note,)
    return Solution(t=t, y=y, stats=stats, status=Status(status).label, reason=Status(status), message=message,
                    method=m.name, warnings=notes, interpolant=work.dense,
                    te=np.array(te, dtype=float), ye=np.array(ye, dtype=float).reshape(len(ye), n),
                    ie=np.array(ie, dtype=int))


def _solve_implicit_system(system, tspan, y0, m: Method, options: dict) -> Solution:
    """An :class:`odelab.systems.implicit.ImplicitSystem` (``F(t, x, x') = 0`` from expressions): ode15i from
    its consistent start (decic again when ``y0`` is not the one it carries: a restart after a reset), with
    its exact partial derivatives; events of ``(t, y)``, as an experiment file's."""
    if not m.residual:
        names = join_names(methods_with(lambda x: True, residual=True), "or")
        raise InputError(f"this system is fully implicit (der() in its residuals), solved by {names}, from y and y' "
                         f"together; {m.name} solves y' = f(t, y).", key="method")
    from odelab.solvers.implicit.decic import DecicError

    given = _given(options, m)
    tspan_arr = as_tspan(tspan)
    y0_arr = as_y0(y0)
    try:
        y_start, yp_start = system.start(float(tspan_arr[0]), y0_arr, given.get("rtol", DEFAULT_RTOL), given.get("atol", DEFAULT_ATOL))
    except DecicError as exc:
        opts = resolve_options(m, given, tspan_arr, y0_arr.size)
        return _failed_at_start(m, tspan_arr, y0_arr, opts, f"no consistent initial slope at t = {tspan_arr[0]:g}: "
                                f"{exc.message}", Status.FUN_RAISED)
    events = given.pop("events", None)
    if events is not None:
        def given_events(t, y, yp, *args, _events=events):
            return _events(t, y, *args)

        given["events"] = given_events
    given.setdefault("jacobian", system.partials)
    return solve_residual(system.residual, tspan_arr, y_start, yp_start, m.name, **given)


def _checked_rhs(fun, raw, y0: np.ndarray):
    """Check the first derivative's shape; wrap ``fun`` only if its results need reshaping."""
    n = y0.size
    is_complex = np.iscomplexobj(y0)
    if np.iscomplexobj(raw) and not is_complex:
        raise InputError(f"`fun` returned complex values {raw!r} for a real y0: give a complex y0 to integrate "
                         "a complex ODE (as in MATLAB).", key="fun")
    dtype = complex if is_complex else float
    try:
        f0 = np.asarray(raw, dtype=dtype)
    except (TypeError, ValueError):
        raise InputError(f"`fun` must return numbers (one per state); it returned {raw!r}.", key="fun") from None
    if f0.shape in ((n,),) or (n == 1 and f0.ndim == 0):
        if is_complex and not np.iscomplexobj(raw):
            def rhs(t, y):
                return np.asarray(fun(t, y), dtype=complex).reshape(n)

            return rhs, f0.reshape(n)
        return fun, f0.reshape(n)
    if f0.size == n and f0.ndim == 2 and 1 in f0.shape:  # a MATLAB-style column or row vector
        def rhs(t, y):
            return np.asarray(fun(t, y), dtype=dtype).reshape(n)

        return rhs, f0.reshape(n)
    raise InputError(
        f"`fun` returned {f0.size} value{'s' if f0.size != 1 else ''} (shape {f0.shape}) but the state has "
        f"{n}: return one derivative per entry of y0.",
        key="fun",
    )


def _solve_adaptive(fun, tspan, y0, f0, m: Method, opts: SolverOptions, setup: dict, multistep) -> Solution:
    tab = m.tableau
    t0 = float(tspan[0])
    extra_fevals = 0
    if opts.mass is not None:
        # As MATLAB's ode45: fold M into the derivative, then evaluate f0 again (counted).
        from odelab.solvers.mass import with_mass

        fun, _ = with_mass(fun, opts.mass, opts.mstate_dependence, opts.args, t0, y0)
        f0 = np.asarray(fun(t0, y0.copy()), dtype=y0.dtype)
        extra_fevals += 1
    nonnegative = opts.nonnegative
    if nonnegative is not None:
        fun, f0 = _nonnegative_start(fun, t0, y0, nonnegative)
        extra_fevals += 1
    events = v0 = None
    if opts.events is not None:
        from odelab.solvers.events import as_event_function

        events, v0 = as_event_function(opts.events, opts.args, t0, y0)
    output = None
    if opts.output_fcn is not None:
        output = _output_function(opts, tspan, y0)
    threshold = opts.atol / opts.rtol
    if multistep is not None:  # a multistep method's own integrator and interpolant (Adams PECE)
        (t, y, nsteps, nfailed, nfevals, status, t_stop, h_stop, exc, found, interpolant) = multistep(
            fun, tspan, y0, f0, opts.rtol, threshold, opts.max_step, opts.initial_step, opts.refine,
            opts.norm_control, opts.max_steps, events, v0, nonnegative, output)
        steps = None
    else:
        (t, y, nsteps, nfailed, nfevals, status, t_stop, h_stop, exc, found, steps) = engine.integrate_adaptive(
            fun, tspan, y0, f0, *_stepping_arrays(tab), m.power, m.shrink_min,
            opts.rtol, threshold, opts.max_step, opts.initial_step, opts.refine, opts.norm_control, opts.max_steps,
            events, v0, nonnegative, output, *_non_fsal(tab),
        )
        interpolant = None
    if opts.output_fcn is not None:
        sel = slice(None) if opts.output_sel is None else opts.output_sel
        opts.output_fcn(np.empty(0), np.empty((0, y0[sel].size), dtype=y0.dtype), "done")
    stats = Stats(nsteps=nsteps, nfailed=nfailed, nfevals=nfevals + 1 + extra_fevals)
    te, ye, ie = found
    message = _status_message(status, m, t_stop, h_stop, y, y0, opts, exc, tspan, te, ie, fun=fun)
    if steps is not None:
        from odelab.solvers.dense import DenseOutput, StageCompletion

        completion = None
        if len(steps) == 5:  # a non-FSAL pair: steps whose interpolation stages are still to be evaluated
            *steps, complete = steps
            completion = StageCompletion(fun, tab.increment_form["extra_A"], tab.extra_c, tab.stages, complete)
        interpolant = DenseOutput(*steps, coefficients=_stepping_arrays(tab)[3], y_final=y[-1].copy(),
                                  nonnegative=nonnegative, completion=completion, basis=tab.dense_basis)
    return Solution(
        t=t, y=y, stats=stats, status=Status(status).label, reason=Status(status), message=message,
        method=m.name, warnings=opts.warnings,
        te=np.array(te, dtype=float), ye=np.array(ye, dtype=y0.dtype).reshape(len(ye), y0.size),
        ie=np.array(ie, dtype=int), interpolant=interpolant, setup=setup,
    )


def _stepping_arrays(tab) -> tuple:
    """The engine's ``A, c, E, dense``: a non-FSAL pair's in increment form (K_0, K_j - K_0)."""
    if tab.fsal:
        return tab.A, tab.c, tab.error_weights, tab.dense
    inc = tab.increment_form
    return inc["A"], tab.c, inc["error_weights"], inc["dense"]


def _non_fsal(tab) -> tuple:
    """The engine's ``b`` and ``extra`` arguments (increment form): none for an FSAL pair."""
    if tab.fsal:
        return ()
    inc = tab.increment_form
    return (inc["b"], None if tab.extra_c is None else (inc["extra_A"], tab.extra_c), tab.dense_basis)


def _nonnegative_start(fun, t0: float, y0: np.ndarray, nonnegative: np.ndarray):
    """Check y0 against ``NonNegative`` and wrap ``fun`` (MATLAB's ``odenonnegative``); returns the
    wrapped function and f0 evaluated again with it (one more evaluation, as MATLAB counts)."""
    if np.iscomplexobj(y0):
        raise InputError("`nonnegative` applies to real states; y0 is complex.", key="nonnegative")
    if np.any(y0[nonnegative] < 0):
        bad = int(nonnegative[np.argmax(y0[nonnegative] < 0)])
        raise InputError(f"`nonnegative` asks state {bad} to stay >= 0 but y0[{bad}] = {y0[bad]:g} "
                         "(MATLAB: 'NonNegative' violated at t0).", key="nonnegative")
    fun = _nonnegative_rhs(fun, nonnegative)
    return fun, fun(t0, y0.copy())


def _nonnegative_rhs(fun, idx: np.ndarray):
    """MATLAB's ``odenonnegative``: at or below zero, a non-negative component may not decrease."""
    def rhs(t, y):
        yp = np.array(fun(t, y), dtype=float)
        at_zero = idx[y[idx] <= 0]
        if at_zero.size:
            yp[at_zero] = np.maximum(yp[at_zero], 0.0)
        return yp

    return rhs


def _output_function(opts: SolverOptions, tspan: np.ndarray, y0: np.ndarray):
    """MATLAB's OutputFcn protocol: ``'init'`` now, ``''`` after each step (True stops), ``'done'`` at the end."""
    from odelab.solvers.events import CallbackError

    user = opts.output_fcn
    sel = slice(None) if opts.output_sel is None else opts.output_sel
    try:
        user(tspan[[0, -1]].copy(), y0[sel].copy(), "init")
    except Exception as exc:
        raise InputError(f"the output function raised {_describe(exc)} on its 'init' call.",
                         key="output_fcn") from None

    def out(t_new, y_new):
        try:
            return bool(user(t_new, y_new[:, sel], ""))
        except Exception as exc:
            raise CallbackError("output function", float(t_new[-1]), exc) from exc

    return out


def _solve_implicit(fun, tspan, y0, f0, m: Method, opts: SolverOptions) -> Solution:
    from odelab.solvers.implicit import solve_implicit

    events = None
    if opts.events is not None:
        from odelab.solvers.events import as_event_function

        events = as_event_function(opts.events, opts.args, float(tspan[0]), y0)
    extra_fevals = 0
    if opts.nonnegative is not None:  # (a mass matrix with it is refused by implicit.resolve_extras, as MATLAB)
        fun, f0 = _nonnegative_start(fun, float(tspan[0]), y0, opts.nonnegative)
        extra_fevals = 1
    (t, y, nsteps, nfailed, status, t_stop, h_stop, exc), work = solve_implicit(fun, tspan, y0, f0, m, opts, events)
    stats = Stats(nsteps=nsteps, nfailed=nfailed, nfevals=work.nfevals + 1 + extra_fevals, npds=work.npds,
                  ndecomps=work.ndecomps, nsolves=work.nsolves)
    te, ye, ie = work.found
    message = _status_message(status, m, t_stop, h_stop, y, y0, opts, exc, tspan, te, ie)
    return Solution(t=t, y=y, stats=stats, status=Status(status).label, reason=Status(status), message=message,
                    method=m.name, warnings=opts.warnings, interpolant=work.dense,
                    te=np.array(te, dtype=float), ye=np.array(ye, dtype=float).reshape(len(ye), y0.size),
                    ie=np.array(ie, dtype=int))


def fixed_grid(tspan: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Step points for a fixed step ``h`` and which of them are output.

    Each interval between consecutive ``tspan`` entries is covered by steps of exactly ``h``
    from its start (``a + k*h``, no accumulated round-off), the last one shortened to land on
    the interval's end; a remainder below 1e-9 h is absorbed rather than taken as a tiny step.
    With a two-element ``tspan`` every step point is output, otherwise only ``tspan``.
    """
    pieces = []
    keep = []
    every = tspan.size == 2
    for a, b in zip(tspan[:-1], tspan[1:]):
        span = abs(b - a)
        nsteps = max(1, math.ceil(span / h - 1e-9))
        pts = a + np.sign(b - a) * h * np.arange(nsteps + 1, dtype=float)
        pts[-1] = b
        pieces.append(pts[:-1])
        mask = np.full(nsteps, every)
        mask[0] = True
        keep.append(mask)
    grid = np.concatenate([*pieces, tspan[-1:]])
    return grid, np.concatenate([*keep, [True]])


def _solve_fixed(fun, tspan, y0, m: Method, opts: SolverOptions) -> Solution:
    grid, keep = fixed_grid(tspan, opts.h)
    tab = m.tableau
    t, y, nsteps, nfevals, status, t_stop, exc = engine.integrate_fixed(fun, grid, keep, y0, tab.A, tab.b, tab.c)
    message = _status_message(status, m, t_stop, opts.h, y, y0, opts, exc, tspan)
    return Solution(t=t, y=y, stats=Stats(nsteps=nsteps, nfailed=0, nfevals=nfevals),
                    status=Status(status).label, reason=Status(status), message=message,
                    method=m.name)


def _failed_at_start(m: Method, tspan, y0, opts: SolverOptions, why: str, reason=Status.NONFINITE) -> Solution:
    return Solution(t=tspan[:1].copy(), y=y0.reshape(1, -1), stats=Stats(0, 0, 1), status="failed",
                    reason=reason,
                    message=f"{m.name} could not start: {why}.", method=m.name, warnings=opts.warnings)


def _describe(exc: BaseException) -> str:
    text = str(exc)
    where = _user_line(exc)
    return (f"{type(exc).__name__}: {text}" if text else type(exc).__name__) + (f" ({where})" if where else "")


def _user_line(exc: BaseException) -> str:
    """Where in the user's own code the exception was raised: 'eq1.py, line 3' (a NameError needs it)."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    for frame in reversed(traceback.extract_tb(exc.__traceback__)):
        name = frame.filename
        if name.startswith("<") or os.path.abspath(name).startswith(package) or "-packages" in name:
            continue
        return f"{os.path.basename(name)}, line {frame.lineno}"
    return ""


def _fmt_vec(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v[:6]) + (", ..." if v.size > 6 else "") + "]"


def _status_message(status, m: Method, t_stop, h_stop, y, y0, opts: SolverOptions, exc, tspan, te=(), ie=(),
                    fun=None) -> str:
    tf = float(tspan[-1])
    if status == Status.SUCCESS:
        return f"{m.name} reached t = {tf:g}."
    if status == Status.TERMINAL_EVENT:
        return f"{m.name} stopped at t = {te[-1]:.10g}: terminal event {ie[-1]} occurred."
    if status == Status.OUTPUT_STOP:
        return f"{m.name} stopped at t = {t_stop:.10g}: the output function asked to stop."
    where = f"at t = {t_stop:.10g}"
    if status == Status.STEP_UNDERFLOW:
        hmin = min_step(t_stop)
        grown = float(np.max(np.abs(y[-1]))) > 1e6 * max(1.0, float(np.max(np.abs(y0))))
        cause = (
            "the solution may be unbounded near there (it grew from "
            f"{float(np.max(np.abs(y0))):g} to {float(np.max(np.abs(y[-1]))):.3g}): a finite-time blow-up"
            if grown
            else "the solution may have a singularity there, or the problem is stiff (try method 'ode15s', "
            "or 'ode23s' at crude tolerances), or the tolerances are tighter than double precision allows (loosen rtol/atol)"
        )
        return (
            f"{m.name} failed {where}: the step size fell below {hmin:.2g}, the smallest allowed, "
            f"without meeting the tolerances (MATLAB: 'Unable to meet integration tolerances'); {cause}."
        )
    if status == Status.NONFINITE:
        return (
            f"{m.name} failed {where}: the derivative became NaN or infinite in the next step "
            f"(step size {h_stop:.3g}). Check the right-hand side for a division by zero, a log or sqrt "
            "of a negative number, or a blow-up near there; the solution up to that point is kept."
        )
    if status == Status.MAX_STEPS:
        head = f"{m.name} stopped {where} of {tf:g} after max_steps = {opts.max_steps} steps: "
        if m.stiff:
            return head + "raise max_steps, or loosen rtol/atol."
        from odelab.solvers.stiffness import diagnose_step_limit, step_limit_advice

        tab = m.tableau
        diagnosis = (diagnose_step_limit(fun, float(t_stop), y[-1], float(h_stop), tab.A, tab.b,
                                         scale=float(np.max(np.abs(y))))
                     if fun is not None and tab is not None and len(y) else None)
        return head + step_limit_advice(m.name, diagnosis, opts.max_steps, float(tspan[0]), float(t_stop), tf)
    from odelab.solvers.events import CallbackError

    if isinstance(exc, CallbackError):
        return f"{m.name} failed at t = {exc.t:.10g}: the {exc.what} raised {_describe(exc.original)}."
    return f"{m.name} failed {where}: the right-hand side raised {_describe(exc)}."
