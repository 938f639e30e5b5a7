"""[fit]: estimating parameters of an experiment from its [data], with exact sensitivities.

```toml
[fit]
parameters = { k = { initial = 2, lower = 0, upper = 10 }, b = { initial = 1, lower = 0 } }
quantities = ["x"]               # default: every quantity [data] maps
# validate = "second_run.csv"    # a second data set to check the fitted model against
# method = "ode78"; rtol = 1e-10 # the solver of states and sensitivities (defaults shown)
```

Loading checks the section (:func:`parse_fit`): every fitted parameter exists in
[parameters], is a number (not computed from others), is used by the model, its bounds hold
its initial value; the system is one odelab can differentiate (equations or a state-space
model) or an FMU (``kind = "fmu"``: its runs differenced, :mod:`odelab.fmi.fitting`); there are more measurements than parameters. Nothing is solved then.

:func:`fit_experiment` then builds, per case with [data], the model as complex-capable
functions of the fitted parameters (the equations, outputs, A/B/C/D matrices, [initial] and
[inputs] expressions compiled in the expression language's complex-step variant, parameters
computed from fitted ones recomputed), integrates states and forward sensitivities
(:mod:`odelab.analysis.sensitivity`) at the [fit] tolerances, and fits all cases jointly
(:func:`odelab.analysis.fit.fit_least_squares`). The experiment is then rebuilt with the
estimates, so its cases run (and are compared with the data) at the fitted values, each
carrying the fit's summary.

Tolerances: the sensitivities are integrated with the states under one error norm at
``rtol`` (default 1e-10) and ``atol = rtol * max |measured|`` per case, so the model's and the
Jacobian's relative errors (about rtol) stay orders of magnitude below any real data's noise
(1e-2 to 1e-5 of the signal). Errors in the model values reach the estimates divided by the
Jacobian's smallest singular value: Misra1a's estimates agree with NIST's to 1e-8, Lanczos3's six correlated ones (scaled
Fisher condition 7e8) to 5e-7, 3e-6 of their standard errors (docs/fitting.md). After a fit,
``solver_effect`` says how far tolerances a hundred times tighter would move the estimates.
"""

from __future__ import annotations

import copy
import difflib
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.solvers.registry import get_method

__all__ = ["FitSpec", "FitCase", "parse_fit", "fit_experiment", "fit_summary"]

MAX_SOLVES = 10_000
"""A fit's budget of model solves is at most this (the default is 500)."""

MAX_PARAMETERS = 100
"""Parameters fitted at once (the sensitivities of n states to m parameters are n*m more equations)."""

_SUPPORTED = "systems of [system.equations], kind = \"state-space\" or kind = \"fmu\" (by differences)"


@dataclass(frozen=True, eq=False)
class FitCase:
    """One case's share of the fit: its parametric model, measured quantities and weights."""

    name: str
    model: Any  # an analysis.sensitivity.ParametricModel, or an fmi.fitting.FmuFitModel
    observe: Callable | None  # g(t, X, P) -> (nq, k, m); None for an FMU (its model differences itself)
    quantities: tuple[str, ...]
    t: np.ndarray
    measured: np.ndarray  # (k, nq)
    weights: np.ndarray  # (nq,): 1 / sigma, or 1
    t0: float
    tf: float
    atol: float


@dataclass(frozen=True, eq=False)
class FitSpec:
    """A checked [fit] section and what running it needs."""

    names: tuple[str, ...]
    initial: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    quantities: tuple[str, ...]
    cases: tuple[FitCase, ...]
    sigma_known: bool
    method: str
    rtol: float
    max_solves: int
    max_steps: int
    validate: str | None  # [fit] validate, relative to the experiment file
    rebuild: dict  # what rebuilding the experiment with the estimates needs
    data_specs: tuple  # each fitted case's schema.Data, for a validation data set


# --- checking [fit] at load time -----------------------------------------------------------------


class _FitSection(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    fit: schema.Fit


def _error(message: str, key: str) -> ExperimentError:
    return ExperimentError(message, key=key)


def parse_fit(raw: Any, cases, models, original: dict, *, path: Path, file_hash: str, name: str, limits,
              sweep=None, load=None) -> FitSpec:
    """Check [fit] against the loaded cases (``models``: their validated schema models).

    ``load(path, data, file_hash, name, limits)`` is the loader's function that turns a file's
    tables into an experiment: the fit rebuilds the experiment with its estimates through it
    (passed in, so that this module does not import the loader, which imports it).
    """
    from odelab.experiment.schema_errors import schema_error

    if not isinstance(raw, dict):
        raise _error("[fit] must be a table: [fit] with parameters = { k = { initial = 2, lower = 0 } }.", "fit")
    try:  # validated as the file's [fit], so that messages name the keys as the file spells them
        spec = _FitSection.model_validate({"fit": raw}).fit
    except ValidationError as exc:
        raise schema_error(exc, source=str(path), case=None, data={"fit": raw}) from None
    if sweep is not None:
        raise _error("[fit] and [sweep] cannot be combined yet: fit first, then sweep with the estimates in "
                     "[parameters].", "fit")
    if spec.parameters is None:
        raise _error("`fit.parameters` is required: name the parameters to estimate, e.g. parameters = { k = "
                     "{ initial = 2, lower = 0 } }.", "fit.parameters")
    if not spec.parameters:
        raise _error("`fit.parameters` is empty: name the parameters to estimate, e.g. parameters = { k = "
                     "{ initial = 2, lower = 0 } }.", "fit.parameters")
    base_params = original.get("parameters") or {}
    if not isinstance(base_params, dict):
        base_params = {}
    names = tuple(spec.parameters)
    fitted_cases = [(c, m) for c, m in zip(cases, models) if c.problem.data is not None]
    if not fitted_cases:
        raise _error("[fit] estimates parameters from measurements, but no case has [data]: add a [data] table "
                     "with the CSV file of the measurements.", "fit")
    # every fitted parameter: exists, is a number, not overridden by a case
    known = list(base_params)
    initial, lower, upper = [], [], []
    values = cases[0].problem.parameters
    for pname in names:
        key = f"fit.parameters.{pname}"
        if pname not in base_params:
            close = difflib.get_close_matches(pname, known, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            listed = f" (the file's parameters: {', '.join(known)})" if known else " (the file has no [parameters])"
            raise _error(f"`{key}`: {pname!r} is not a parameter of the experiment{listed}.{hint} A fitted "
                         "parameter needs a value in [parameters], which the fit starts from unless `initial` "
                         "says otherwise.", key)
        text = base_params[pname]
        if isinstance(text, str):
            from odelab.expressions import parse_expression

            used = sorted(set(parse_expression(text, key=f"parameters.{pname}", names=known).names) & set(known))
            if used:
                raise _error(f"`{key}`: parameters.{pname} = {text!r} is computed from {', '.join(used)}; a fitted "
                             f"parameter must be a number of its own: fit {' or '.join(used)} instead, or give "
                             f"{pname} a number.", key)
        for c, m in zip(cases, models):
            if c.problem.parameters.get(pname) != values.get(pname):
                raise _error(f"case {c.name!r} sets parameters.{pname}, which [fit] estimates: one fit estimates one "
                             "value for all cases; remove it from the case.", f"case.parameters.{pname}")
        entry = spec.parameters[pname]
        p0 = values[pname]
        if entry.initial is not None:
            from odelab.experiment.fields import constant

            p0 = constant(entry.initial, f"{key}.initial", {k: v for k, v in values.items() if k not in names})
        lo = -math.inf if entry.lower is None else float(entry.lower)
        hi = math.inf if entry.upper is None else float(entry.upper)
        if not lo < hi:
            raise _error(f"`{key}`: lower = {lo:g} must be below upper = {hi:g}.", f"{key}.lower")
        if not lo <= p0 <= hi:
            where = "initial" if entry.initial is not None else f"value in [parameters] ({p0:g}), the fit's start,"
            raise _error(f"`{key}`: the {where} {p0:g} is outside the bounds [{lo:g}, {hi:g}]; start the fit inside "
                         "them (change `initial`, or widen `lower`/`upper`).", f"{key}.initial")
        initial.append(float(p0))
        lower.append(lo)
        upper.append(hi)
    # quantities
    mapped = []
    for c, _ in fitted_cases:
        mapped.extend(q for q in c.problem.data.values if q not in mapped)
    quantities = tuple(spec.quantities) if spec.quantities is not None else tuple(mapped)
    if not quantities:
        raise _error("`fit.quantities` is empty: list the measured quantities to fit, e.g. [\"x\"].",
                     "fit.quantities")
    for i, q in enumerate(quantities):
        if q not in mapped:
            close = difflib.get_close_matches(q, mapped, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise _error(f"`fit.quantities[{i}]` is {q!r}, which no case's [data] measures (measured: "
                         f"{', '.join(mapped)}).{hint}", f"fit.quantities[{i}]")
    # sigma: for every fitted quantity of every case, or for none
    given = [(c.name, q, q in c.problem.data.sigma) for c, _ in fitted_cases for q in quantities
             if q in c.problem.data.values]
    if any(g for *_, g in given) and not all(g for *_, g in given):
        missing = next(f"{q} in case {n!r}" for n, q, g in given if not g)
        raise _error(f"`data.sigma` is given for some fitted quantities but not for {missing}: give the measurement "
                     "noise of every fitted quantity (the fit then weighs each by 1/sigma and uses it for the "
                     "uncertainties), or of none (the noise is then estimated from the residuals).", "data.sigma")
    sigma_known = bool(given) and all(g for *_, g in given)
    n_meas = sum(c.problem.data.t.size * sum(q in c.problem.data.values for q in quantities) for c, _ in fitted_cases)
    if n_meas <= len(names):
        raise _error(f"[fit] estimates {len(names)} parameters from {n_meas} measurements; it needs more measurements "
                     "than parameters (and many more for useful uncertainties).", "fit.parameters")
    try:
        method = _fit_method(spec.method)
    except InputError as exc:
        raise exc.located(key="fit.method")
    if not (0 < spec.rtol < 1e-2):
        raise _error(f"`fit.rtol` must be between 0 and 0.01; got {spec.rtol!r} (the default 1e-10 keeps the "
                     "sensitivities' error far below the data's noise).", "fit.rtol")
    if spec.atol is not None and not spec.atol > 0:
        raise _error(f"`fit.atol` must be positive; got {spec.atol!r}.", "fit.atol")
    if not 1 <= spec.max_solves <= MAX_SOLVES:
        raise _error(f"`fit.max_solves` must be between 1 and {MAX_SOLVES:,}; got {spec.max_solves} (a fit that needs "
                     "more is better restarted from a closer `initial`).", "fit.max_solves")
    if len(names) > MAX_PARAMETERS:
        raise _error(f"[fit] estimates {len(names)} parameters; at most {MAX_PARAMETERS} can be fitted at once (each adds "
                     "one sensitivity per state to the integration).", "fit.parameters")
    fit_cases = []
    used_anywhere: set[str] = set()
    for c, m in fitted_cases:
        fc, used = _fit_case(c, m, names, quantities, spec, path)
        fit_cases.append(fc)
        used_anywhere |= used
    for pname in names:
        if pname not in used_anywhere:
            raise _error(f"`fit.parameters.{pname}`: {pname!r} is not used by the model of any case with [data] (not "
                         "in its equations, outputs, matrices, [initial] or [inputs], nor in a parameter they use), so "
                         "the data cannot say anything about it: remove it from [fit].", f"fit.parameters.{pname}")
    if spec.validate_ is not None:
        from odelab.experiment.data import resolve_data_path

        file = resolve_data_path(spec.validate_, "fit.validate", path)
        if not file.is_file():
            raise _error(f"`fit.validate` {spec.validate_!r}: no such file (looked for {file}).", "fit.validate")
    return FitSpec(names=names, initial=np.array(initial), lower=np.array(lower), upper=np.array(upper),
                   quantities=quantities, cases=tuple(fit_cases), sigma_known=sigma_known, method=method,
                   rtol=float(spec.rtol), max_solves=int(spec.max_solves), max_steps=int(limits.steps or 0),
                   validate=spec.validate_,
                   rebuild={"path": path, "original": original, "file_hash": file_hash, "name": name,
                            "limits": limits, "load": load},
                   data_specs=tuple(m.data for _, m in fitted_cases))


def _fit_method(name: str) -> str:
    method = get_method(name, key="fit.method")
    if not method.adaptive or method.stiff or method.delays:  # sensitivities: an adaptive explicit method
        raise ExperimentError(f"`fit.method` is {name!r}; states and sensitivities are integrated by an adaptive "
                              "explicit method: ode78 (the default), ode89, ode45, ode113 or DOP853.", key="fit.method")
    return method.name


# --- the parametric model of one case ---------------------------------------------------------------


def _matrix_texts(value) -> list | None:
    from odelab.expressions.matlab import is_matrix_string, split_matrix

    if value is None:
        return None
    if is_matrix_string(value):
        value = split_matrix(value)
    if not isinstance(value, list):
        return [value]
    if all(not isinstance(v, list) for v in value):
        return list(value)
    return [v for row in value for v in row]


def _fit_case(case, model: schema.Experiment, names: tuple[str, ...], quantities, spec: schema.Fit, path: Path):
    """Compile a case's model as complex-step functions of the fitted parameters ``names``."""
    from odelab.analysis.sensitivity import ParametricModel
    from odelab.expressions import compile_vector

    p = case.problem
    system = model.system
    if system.kind == "fmu":
        return _fmu_fit_case(case, model, names, quantities, spec)
    if system.kind not in ("ode", "state-space") or system.function is not None:
        raise _error(f"[fit] differentiates the model exactly, which needs {_SUPPORTED}; case {case.name!r} is a "
                     f"{'`function`' if system.function is not None else system.kind} system.", "fit")
    if p.system.events is not None or p.linearize is not None:
        raise _error(f"[fit] cannot fit case {case.name!r}, which has [events] or [linearize].", "fit")
    dependent, derived, depends, fixed, parameter_values = _dependent_parameters(
        dict(model.parameters), dict(p.parameters), names)
    states, inputs, outputs = p.states, p.inputs, p.outputs
    n = len(states)
    used: set[str] = set()

    def compile_texts(texts, keys, args):
        from odelab.expressions import parse_expression

        for text in texts:
            if isinstance(text, str):
                used.update(parse_expression(text, names=[*args, *fixed]).names)
        return compile_vector(texts, args=args, constants=fixed, keys=keys, complex_step=True)

    # the inputs: real signals, or expressions of t and the parameters
    signal_fns = []
    for j, iname in enumerate(inputs):
        sig_spec = (model.inputs or {}).get(iname)
        if sig_spec is not None and sig_spec.type == "expression":
            text = sig_spec.expression
            ce = compile_texts([text], [f"inputs.{iname}.expression"], ["t", *dependent])
            signal_fns.append(("expression", ce))
        else:
            signal_fns.append(("signal", p.system.signals[j]))

    def input_values(t, pvals, piece):
        out = []
        for kind, fn in signal_fns:
            if kind == "expression":
                out.append(fn(np.asarray(t, dtype=float), *pvals)[0])
            else:
                tt = np.asarray(t, dtype=float)
                if piece is not None:
                    tt = np.clip(tt, piece[0], piece[1])
                out.append(np.asarray(fn(tt.ravel()), dtype=float).reshape(tt.shape))
        return out

    # initial state
    init_texts = [model.initial.get(s, float(p.x0[i])) for i, s in enumerate(states)]
    X0 = compile_texts(init_texts, [f"initial.{s}" for s in states], list(dependent))

    def initial(P):
        out = np.asarray(X0(*parameter_values(P)), dtype=complex)
        return np.broadcast_to(out, (n, P.shape[1]))

    if system.kind == "ode":
        args = ["t", *states, *inputs, *dependent]
        F = compile_texts([system.equations[s] for s in states], [f"system.equations.{s}" for s in states], args)
        G = None
        if outputs:
            G = compile_texts(list(system.outputs.values()), [f"system.outputs.{o}" for o in outputs], args)

        def rhs(t, X, P, piece=None):
            pv = parameter_values(P)
            return F(np.float64(t), *X, *input_values(t, pv, piece), *pv)

        def evaluate_outputs(t, X, P, pv, U):
            return G(t, *X, *U, *pv)
    else:
        ss = p.system.model
        mats = {}
        for mname in "ABCD":
            M = getattr(ss, mname)
            texts = _matrix_texts(getattr(system, mname))
            if texts is None or len(texts) != M.size or M.size == 0:
                mats[mname] = (None, M)
            else:
                keys = [f"system.{mname}"] * len(texts)
                mats[mname] = (compile_texts(texts, keys, list(dependent)), M)

        def matrix(mname, pv, nd):
            fn, M = mats[mname]
            if fn is None:
                return M.reshape(*M.shape, *([1] * nd))
            out = np.asarray(fn(*pv), dtype=complex)
            return out.reshape(*M.shape, *out.shape[1:]) if out.ndim > 1 else out.reshape(*M.shape, *([1] * nd))

        def _times(Mx, V):  # sum_j M[i, j] V[j] with trailing broadcast dimensions
            return np.sum(Mx * V[None], axis=1)

        def rhs(t, X, P, piece=None):
            pv = parameter_values(P)
            dx = _times(matrix("A", pv, 1), X)
            if inputs:
                U = np.array(np.broadcast_arrays(*input_values(t, pv, piece), X[0]))[:-1]
                dx = dx + _times(matrix("B", pv, 1), U)
            return dx

        def evaluate_outputs(t, X, P, pv, U):
            y = _times(matrix("C", pv, 2), X)
            if inputs and mats["D"][1].size:
                Uarr = np.array(np.broadcast_arrays(*U, X[0]))[:-1]
                y = y + _times(matrix("D", pv, 2), Uarr)
            return y

    def observe(t, X, P):
        pv = parameter_values(P)
        rows = []
        U = input_values(t, pv, None) if inputs else []
        Y = evaluate_outputs(t, X, P, pv, U) if outputs and any(q in outputs for q in case_quantities) else None
        for q in case_quantities:
            if q in states:
                rows.append(X[states.index(q)])
            else:
                rows.append(Y[outputs.index(q)])
        return np.array(np.broadcast_arrays(*rows))

    case_quantities, measured, weights, atol = _measured(p, quantities, spec)
    # parameters reach the model directly, or through parameters computed from them
    reach = set()
    for pname in names:
        if pname in used or any(pname in _closure(d, depends) and d in used for d in derived):
            reach.add(pname)
    breakpoints = []
    t0, tf = float(p.tspan[0]), float(p.tspan[-1])
    for s in p.system.signals:
        breakpoints.extend(float(b) for b in s.breakpoints(t0, tf))
    model_obj = ParametricModel(states=tuple(states), parameters=names, rhs=rhs, initial=initial,
                                breakpoints=tuple(sorted(set(breakpoints))))
    return FitCase(case.name, model_obj, observe, case_quantities, p.data.t, measured, weights, t0, tf, atol), reach


def _measured(p, quantities, spec: schema.Fit):
    """A case's measured quantities, their values (k, nq), weights (1 / sigma) and the absolute tolerance."""
    data = p.data
    case_quantities = tuple(q for q in quantities if q in data.values)
    measured = np.column_stack([data.values[q] for q in case_quantities])
    weights = np.array([1.0 / data.sigma[q] if q in data.sigma else 1.0 for q in case_quantities])
    scale = float(np.max(np.abs(measured))) or 1.0
    atol = float(spec.atol) if spec.atol is not None else float(spec.rtol) * scale
    return case_quantities, measured, weights, atol


def _fmu_fit_case(case, model: schema.Experiment, names: tuple[str, ...], quantities, spec: schema.Fit):
    """An FMU case's share of the fit: its runs at trial parameters, differenced (odelab.fmi.fitting)."""
    from odelab.fmi.fitting import FmuFitModel

    p = case.problem
    if p.system.events is not None or p.linearize is not None:
        raise _error(f"[fit] cannot fit case {case.name!r}, which has [events] or [linearize].", "fit")
    dependent, derived, depends, _fixed, parameter_values = _dependent_parameters(
        dict(model.parameters), dict(p.parameters), names)
    fmu_parameters = p.system.fmu.model.parameters
    variables = {n: fmu_parameters[n] for n in dependent if n in fmu_parameters}
    reach = {n for n in names if n in variables or any(n in _closure(d, depends) and d in variables for d in derived)}
    case_quantities, measured, weights, atol = _measured(p, quantities, spec)
    lower = np.array([-math.inf if e.lower is None else float(e.lower) for e in spec.parameters.values()])
    upper = np.array([math.inf if e.upper is None else float(e.upper) for e in spec.parameters.values()])
    fit_model = FmuFitModel(run=p.system.fmu, x0=np.asarray(p.x0, dtype=float), dependent=tuple(dependent),
                            parameter_values=parameter_values, variables=variables, states=tuple(p.states),
                            outputs=tuple(p.outputs), quantities=case_quantities, lower=lower, upper=upper)
    t0, tf = float(p.tspan[0]), float(p.tspan[-1])
    return FitCase(case.name, fit_model, None, case_quantities, p.data.t, measured, weights, t0, tf, atol), reach


def _dependent_parameters(raw_params: dict, values: dict, names: tuple[str, ...]):
    """The parameters that depend on the fitted ``names`` and how to compute them from a row of values.

    Parameters computed from fitted ones are recomputed from them, in their order of
    dependence. Returns (dependent: the fitted then the derived names, derived, depends: each
    computed parameter's parameters, fixed: the others' values, parameter_values(P)).
    """
    from odelab.expressions import compile_expression

    # parameters computed from fitted ones are recomputed from them: in their order of dependence
    depends: dict[str, set[str]] = {}
    compiled_params: dict[str, Any] = {}
    for pname, text in raw_params.items():
        if isinstance(text, str) and pname not in names:
            ce = compile_expression(text, names=list(raw_params), key=f"parameters.{pname}", complex_step=True)
            compiled_params[pname] = ce
            depends[pname] = set(ce.names) & set(raw_params)
    dependent = list(names)
    changed = True
    while changed:
        changed = False
        for pname, deps in depends.items():
            if pname not in dependent and deps & set(dependent):
                dependent.append(pname)
                changed = True
    derived = [n for n in dependent if n not in names]
    order: list[str] = []
    while len(order) < len(derived):  # the loader has refused cycles already
        for pname in derived:
            if pname not in order and not (depends[pname] & (set(derived) - set(order))):
                order.append(pname)
    fixed = {k: float(v) for k, v in values.items() if k not in dependent}

    def parameter_values(P) -> list:
        """Values of the dependent parameters (fitted, then derived) for parameter rows P."""
        env: dict[str, Any] = dict(fixed)
        env.update({n: P[i] for i, n in enumerate(names)})
        for pname in order:
            ce = compiled_params[pname]
            env[pname] = ce(**{k: env[k] for k in ce.names if k in env})
        return [env[n] for n in dependent]

    return dependent, derived, depends, fixed, parameter_values


def _closure(pname: str, depends: dict[str, set[str]]) -> set[str]:
    """Every parameter ``pname`` is computed from, directly or not."""
    seen: set[str] = set()
    stack = [pname]
    while stack:
        for d in depends.get(stack.pop(), ()):
            if d not in seen:
                seen.add(d)
                stack.append(d)
    return seen


# --- running the fit ------------------------------------------------------------------------------


def _solve_case(fc: FitCase, p: np.ndarray, spec: FitSpec, times=None):
    from odelab.analysis.sensitivity import observe, solve_sensitivities

    times = fc.t if times is None else times
    if fc.observe is None:  # an FMU: its runs, differenced
        return fc.model.solve(p, times, t0=fc.t0, tf=fc.tf, method=spec.method, rtol=spec.rtol, atol=fc.atol,
                              max_steps=spec.max_steps or None)
    sol = solve_sensitivities(fc.model, p, times, t0=fc.t0, tf=fc.tf, method=spec.method, rtol=spec.rtol,
                              atol=fc.atol, max_steps=spec.max_steps or None)
    if sol.status != "success":
        return None, None, sol
    y, dy = observe(fc.observe, times, sol.x, sol.S, p)
    return y, dy, sol


def residuals_and_jacobian(spec: FitSpec, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted residuals (model - data) / sigma of every fitted case, and their exact Jacobian."""
    from odelab.analysis.fit import FitEvaluationError

    rs, Js = [], []
    for fc in spec.cases:
        with np.errstate(over="ignore", invalid="ignore"):  # a trial point's blow-up is the solver's status
            y, dy, sol = _solve_case(fc, p, spec)
        if y is None:
            point = ", ".join(f"{n} = {v:.6g}" for n, v in zip(spec.names, p))
            raise FitEvaluationError(f"case {fc.name!r} could not be solved at {point}: {sol.message}")
        rs.append(((y - fc.measured) * fc.weights).ravel())
        Js.append((dy * fc.weights[None, :, None]).reshape(-1, p.size))
    return np.concatenate(rs), np.vstack(Js)


def fit_experiment(exp, *, validate_with: str | None = None):
    """Fit ``exp``'s [fit] and return the experiment rebuilt with the estimates (its cases carry the summary).

    Never raises for a fit that does not converge: the summary's status is then "failed" with
    the last iterate and why, and the cases run at that iterate.
    """
    from odelab.analysis.fit import fit_least_squares

    spec: FitSpec = exp.fit
    result = fit_least_squares(lambda p: residuals_and_jacobian(spec, p), spec.initial, names=spec.names,
                               lower=spec.lower, upper=spec.upper, sigma_known=spec.sigma_known,
                               max_solves=spec.max_solves)
    summary = fit_summary(result, spec)
    if result.converged:
        summary["solver_effect"] = _solver_effect(spec, result)
    validations = []
    for file, anywhere in ((spec.validate, False), (validate_with, True)):
        if file is not None:
            validations.append(validate_fit(spec, result.estimates, file, anywhere=anywhere))
    for v in validations:  # beside the fit's own residuals, for comparison
        fitted = summary["residuals"].get(v["case"], {})
        v["fit_rms"] = {q: fitted[q]["rms"] for q in v.get("rms", {}) if q in fitted}
    if validations:
        summary["validation"] = validations
    rb = spec.rebuild
    data = copy.deepcopy(rb["original"])
    params = dict(data.get("parameters") or {})
    for pname, value in zip(spec.names, result.estimates):
        params[pname] = float(value)
    data["parameters"] = params
    rebuilt = rb["load"](rb["path"], data, rb["file_hash"], rb["name"], rb["limits"])
    cases = tuple(replace(c, problem=replace(c.problem, fit=summary)) for c in rebuilt.cases)
    return replace(rebuilt, cases=cases, fit=spec)


def _solver_effect(spec: FitSpec, result) -> float | None:
    """How far the solver's error moves the estimates, in units of their standard errors.

    The residuals at the estimates are computed again at 1/100 of the tolerances; the
    Gauss-Newton step that difference implies, ``J^+ (r_tight - r)``, is the shift of the
    estimates due to the solver's error at the fit's tolerances (to first order). Returns the
    largest |shift| / standard error (None if it cannot be computed).
    """
    from odelab.analysis.fit import FitEvaluationError

    se = np.asarray(result.standard_errors, dtype=float)
    if not np.all(np.isfinite(se)) or not np.all(se > 0):
        return None
    tight = replace(spec, rtol=spec.rtol / 100, cases=tuple(replace(c, atol=c.atol / 100) for c in spec.cases))
    try:
        r_tight, _ = residuals_and_jacobian(tight, np.asarray(result.estimates, dtype=float))
    except FitEvaluationError:
        return None
    shift = np.linalg.lstsq(result.jacobian, r_tight - result.residuals, rcond=None)[0]
    return _finite(float(np.max(np.abs(shift) / se)))


def _finite(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def fit_summary(result, spec: FitSpec) -> dict:
    """The fit as plain, JSON-safe data: what the terminal, --json, result.json and the report show."""
    from odelab.analysis.fit import autocorrelation
    from odelab.experiment.data import MAX_STORED_ROWS

    params = {}
    for i, pname in enumerate(result.names):
        params[pname] = {
            "estimate": _finite(float(result.estimates[i])),
            "standard_error": _finite(float(result.standard_errors[i])),
            "ci95": [_finite(float(result.lower95[i])), _finite(float(result.upper95[i]))],
            "initial": float(spec.initial[i]),
            "lower": _finite(float(spec.lower[i])),
            "upper": _finite(float(spec.upper[i])),
            "at_bound": pname in result.at_bound,
        }
    corr = [[_finite(float(v)) for v in row] for row in np.asarray(result.correlation)]
    per_case = {}
    offset = 0
    r = np.asarray(result.residuals, dtype=float)
    for fc in spec.cases:
        k, nq = fc.measured.shape
        block = r[offset:offset + k * nq].reshape(k, nq) if r.size >= offset + k * nq else None
        offset += k * nq
        if block is None:
            continue
        keep = np.unique(np.linspace(0, k - 1, min(k, MAX_STORED_ROWS)).round().astype(int))
        per_case[fc.name] = {q: {"rms": float(np.sqrt(np.mean((block[:, j] / fc.weights[j]) ** 2))), "rows": int(k),
                                 "autocorrelation": autocorrelation(block[:, j]).tolist(),
                                 # model - data at the fit's tolerances, at the (thinned) measured times
                                 "t": fc.t[keep].tolist(), "residuals": (block[keep, j] / fc.weights[j]).tolist()}
                             for j, q in enumerate(fc.quantities)}
    s2 = _finite(float(result.residual_variance))
    return {
        "status": result.status,
        "message": result.message,
        "parameters": params,
        "names": list(result.names),
        "correlation": corr,
        "rss": _finite(float(result.rss)),
        "n": int(result.n),
        "dof": int(result.dof),
        "residual_variance": s2,
        "residual_std": _finite(math.sqrt(s2)) if s2 is not None and s2 >= 0 else None,
        "sigma_known": bool(result.sigma_known),
        "t_quantile": _finite(float(result.t_quantile)),
        "solves": int(result.solves) * len(spec.cases),
        # "sensitivities": exact, with the states; "differences": an FMU's runs differenced (fmu_runs of them)
        "jacobian": "differences" if any(fc.observe is None for fc in spec.cases) else "sensitivities",
        "fmu_runs": sum(fc.model.runs[0] for fc in spec.cases if fc.observe is None) or None,
        "evaluations": int(result.solves),
        "iterations": int(result.iterations),
        # trial points where a case could not be solved: rejected steps of infinite cost
        "failed_trials": int(getattr(result, "failed_trials", 0)),
        "condition": _finite(float(result.condition)),
        "identifiability": result.identifiability,
        "cases": [fc.name for fc in spec.cases],
        "quantities": list(spec.quantities),
        "method": spec.method,
        "rtol": spec.rtol,
        "residuals": per_case,
    }


def validate_fit(spec: FitSpec, p: np.ndarray, file: str, *, anywhere: bool) -> dict:
    """The fitted model against a second data set (read like the first case's [data])."""
    from odelab.experiment.data import check_span, read_data

    fc = spec.cases[0]
    data_spec = spec.data_specs[0]
    quantities = tuple(fc.quantities)
    data = read_data(data_spec, spec.rebuild["path"], quantities, key="data", file_override=file,
                     anywhere=anywhere)
    check_span(data, np.array([fc.t0, fc.tf]))
    sub = replace(fc, t=data.t)
    y, _, sol = _solve_case(sub, p, spec, times=data.t)
    if y is None:
        return {"file": file, "case": fc.name, "status": "failed", "message": sol.message}
    out = {"file": file, "case": fc.name, "status": "success", "rows": int(data.t.size), "rms": {}}
    for j, q in enumerate(quantities):
        if q in data.values:
            out["rms"][q] = float(np.sqrt(np.mean((y[:, j] - data.values[q]) ** 2)))
    return out
