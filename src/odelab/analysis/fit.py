"""Weighted nonlinear least squares with honest uncertainties.

:func:`fit_least_squares` minimises ``sum r_i(p)^2`` of weighted residuals
``r_i = (model_i(p) - data_i) / sigma_i`` by SciPy's trust-region reflective method (Branch,
Coleman & Li, SIAM J. Sci. Comput. 21(1), 1999) within the bounds, with the exact Jacobian the
caller supplies (odelab's: forward sensitivities, :mod:`odelab.analysis.sensitivity`).

The uncertainties are the classical linearised ones, as NIST's StRD certifies them and as
MATLAB's ``nlparci`` and R's ``nls`` report them (Bates & Watts, *Nonlinear Regression
Analysis and Its Applications*, 1988, ch. 2):

* covariance ``C = s^2 (J^T J)^-1`` with ``s^2 = RSS / (n - p)`` the residual variance, or
  ``C = (J^T J)^-1`` when the measurement noise ``sigma`` is known (the residuals are then
  already in units of sigma);
* standard errors ``sqrt(diag C)``, 95 % intervals ``estimate +- t_{0.975, n-p} * se``
  (Student's t quantile), the correlation matrix ``C_ij / (se_i se_j)``;
* identifiability: the Fisher matrix of the *relative* parameter changes,
  ``F = (J D)^T (J D)`` with ``D = diag(|p|)``, is near-singular when the data cannot
  separate some parameters. Its condition number and the singular vector of its smallest
  singular value name the combination (``a`` and ``b`` entering only as ``a*b``: the
  direction ``da/a = -db/b``).

Pure: arrays in, a frozen :class:`FitResult` out; nothing prints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Callable, Sequence

import numpy as np

__all__ = ["FitResult", "FitEvaluationError", "fit_least_squares", "uncertainties", "autocorrelation",
           "combination_text", "IDENTIFIABILITY_LIMIT"]

IDENTIFIABILITY_LIMIT = 1e10
"""Condition number of the scaled Fisher matrix above which the fit warns: the worst-determined
combination of relative parameter changes is then known 1e5 times less well than the best."""


class FitEvaluationError(Exception):
    """The model could not be evaluated at a trial parameter vector (the solver failed, say)."""


@dataclass(frozen=True)
class FitResult:
    """Estimates, their uncertainties and how the fit went."""

    names: tuple[str, ...]
    estimates: np.ndarray
    standard_errors: np.ndarray  # inf where the data do not determine the parameter
    lower95: np.ndarray
    upper95: np.ndarray
    correlation: np.ndarray
    rss: float  # weighted residual sum of squares
    n: int  # residuals (measurements)
    dof: int  # n - p
    residual_variance: float  # s^2 (1 when sigma is known)
    sigma_known: bool
    t_quantile: float
    solves: int  # model evaluations (each one solve of states and sensitivities)
    iterations: int  # accepted trust-region steps
    status: str  # "converged" or "failed"
    message: str
    condition: float  # of the scaled Fisher matrix
    identifiability: str | None  # the warning, naming the combination, or None
    null_direction: np.ndarray | None
    residuals: np.ndarray  # weighted residuals at the estimates
    jacobian: np.ndarray = field(repr=False)
    initial: np.ndarray = field(default_factory=lambda: np.empty(0))
    at_bound: tuple[str, ...] = ()
    failed_trials: int = 0  # trial points where the model could not be evaluated (rejected, infinite cost)

    @property
    def converged(self) -> bool:
        return self.status == "converged"


def uncertainties(J: np.ndarray, r: np.ndarray, p: np.ndarray, names: Sequence[str], *, sigma_known: bool,
                  limit: float = IDENTIFIABILITY_LIMIT) -> dict:
    """Covariance-based uncertainties and the identifiability diagnosis at the estimates ``p``."""
    from scipy.special import stdtrit  # Student's t quantile (scipy.stats costs seconds to import)

    J = np.asarray(J, dtype=float)
    r = np.asarray(r, dtype=float)
    p = np.asarray(p, dtype=float)
    n, m = J.shape
    dof = n - m
    rss = float(r @ r)
    s2 = 1.0 if sigma_known else (rss / dof if dof > 0 else math.nan)
    scale = np.where(p != 0, np.abs(p), 1.0)
    Js = J * scale  # the Jacobian in relative changes dp/|p|
    _, sv, Vt = np.linalg.svd(Js, full_matrices=False)
    smax = sv[0] if sv.size else 0.0
    smin = sv[-1] if sv.size else 0.0
    condition = math.inf if smin <= smax * 1e-150 else float((smax / smin) ** 2)
    # covariance in relative terms from the SVD: V S^-2 V^T (inf where a singular value is zero)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(sv > smax * 1e-150, 1.0 / sv ** 2, math.inf)
        cov_rel = (Vt.T * inv) @ Vt if np.all(np.isfinite(inv)) else None
    if cov_rel is not None:
        cov = s2 * cov_rel * np.outer(scale, scale)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            corr = cov / np.outer(se, se)
        corr = np.clip(np.where(np.isfinite(corr), corr, 0.0), -1.0, 1.0)
        np.fill_diagonal(corr, 1.0)
    else:
        se = np.full(m, math.inf)
        corr = np.full((m, m), math.nan)
        np.fill_diagonal(corr, 1.0)
    null = None
    warning = None
    if m >= 1 and condition > limit:
        null = Vt[-1].copy()
        involved = np.abs(null) >= 0.1 * np.abs(null).max()
        null /= np.sign(null[np.argmax(involved)]) or 1.0  # the first parameter involved moves up
        warning = combination_text(names, null, condition)
        # the data do not determine these: their linearised standard errors (1e12 and the like) mean nothing
        se = np.where(involved, math.inf, se)
    tq = float(stdtrit(dof, 0.975)) if dof > 0 else math.nan
    return {"standard_errors": se, "correlation": corr, "rss": rss, "dof": dof, "n": n, "residual_variance": s2,
            "t_quantile": tq, "lower95": p - tq * se, "upper95": p + tq * se, "condition": condition,
            "identifiability": warning, "null_direction": null}


def _power(name: str, exponent: float) -> str:
    frac = Fraction(exponent).limit_denominator(4)
    if abs(float(frac) - exponent) > 0.05 * max(1.0, abs(exponent)):
        return f"{name}^{exponent:.3g}"
    if frac == 1:
        return name
    if frac.denominator == 1:
        return f"{name}^{frac.numerator}"
    return f"{name}^({frac.numerator}/{frac.denominator})"


def combination_text(names: Sequence[str], direction: np.ndarray, condition: float) -> str:
    """Say which combination of the parameters the data cannot separate, from the null direction.

    Along ``direction`` (in relative changes dp_k/p_k) the fit does not change: with two
    parameters a and b and direction (c_a, c_b), the data depend only on a^(c_b) * b^(-c_a),
    written with a's exponent 1 ("a and b enter only as a*b" for (1, -1)).
    """
    v = np.asarray(direction, dtype=float)
    big = [i for i in range(v.size) if abs(v[i]) >= 0.1 * np.abs(v).max()]
    cond = "infinite" if math.isinf(condition) else f"{condition:.2g}"
    terms = " ".join(f"{'+' if v[i] >= 0 else '-'} {abs(v[i]):.2f} d{names[i]}/{names[i]}" for i in big).lstrip("+ ")
    how = (f"(the Fisher matrix of relative parameter changes has condition number {cond}; changing the parameters "
           f"by {terms} leaves the model's fit to the data unchanged)")
    if len(big) == 1:
        return (f"not identifiable: the data do not determine {names[big[0]]} (it has almost no effect on the fitted "
                f"quantities) {how}. Fix it to a known value (remove it from [fit]) or measure what it affects.")
    if len(big) == 2:
        i, j = big
        exponent = -v[i] / v[j]  # the invariant is names[i] * names[j]^exponent
        if exponent >= 0:
            combo = f"{names[i]}*{_power(names[j], exponent)}"
        else:
            combo = f"{names[i]}/{_power(names[j], -exponent)}"
        return (f"not identifiable: the data cannot separate {names[i]} and {names[j]}; they enter only as {combo} "
                f"{how}. Fix one of them (remove it from [fit]) or fit {combo} as one parameter.")
    listed = ", ".join(names[i] for i in big)
    return (f"not identifiable: the data determine only combinations of {listed} {how}. Fix some of them (remove "
            "them from [fit]) or add measurements that separate them.")


def autocorrelation(r: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Sample autocorrelation of residuals at lags 0..max_lag (Box & Jenkins' estimator)."""
    r = np.asarray(r, dtype=float)
    r = r - r.mean() if r.size else r
    n = r.size
    if max_lag is None:
        max_lag = min(20, max(n // 4, 1))
    max_lag = min(max_lag, n - 1)
    denom = float(r @ r)
    if n < 2 or denom == 0:
        return np.ones(1)
    return np.array([float(r[: n - k] @ r[k:]) / denom for k in range(max_lag + 1)])


def fit_least_squares(evaluate: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], p0, *,
                      names: Sequence[str], lower=None, upper=None, sigma_known: bool = False,
                      max_solves: int = 500, xtol: float = 1e-12, ftol: float = 1e-12, gtol: float = 1e-12,
                      limit: float = IDENTIFIABILITY_LIMIT) -> FitResult:
    """Fit by trust-region reflective least squares; ``evaluate(p) -> (r, J)``, weighted residuals and Jacobian.

    ``evaluate`` may raise :class:`FitEvaluationError` when the model cannot be computed at a
    trial point (the solver blew up, met NaN, ran out of steps). Such a trial point, or one whose
    residuals or Jacobian are not finite, is a step of infinite cost: the trust-region method
    rejects it and shrinks its region to a quarter of the step (Branch, Coleman & Li's rule for
    an unacceptable step; SciPy's ``trf`` does this for non-finite residuals), so the fit goes on
    from the last good point; ``FitResult.failed_trials`` counts them. Only an initial point
    that cannot be evaluated fails the fit, with that reason. Never raises for a fit that does
    not converge: the result's status says so.
    """
    from scipy.optimize import least_squares

    names = tuple(names)
    p0 = np.asarray(p0, dtype=float)
    m = p0.size
    lo = np.full(m, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    hi = np.full(m, np.inf) if upper is None else np.asarray(upper, dtype=float)
    cache: dict[bytes, tuple[np.ndarray, np.ndarray | None, str | None]] = {}
    state = {"solves": 0, "last": p0.copy(), "last_rss": math.nan, "failed": 0, "size": None}

    def get(p):
        """(r, J, why): J is None and r infinite where the model cannot be evaluated (``why``)."""
        key = np.asarray(p, dtype=float).tobytes()
        if key not in cache:
            if len(cache) > 8:
                cache.clear()
            if state["solves"] >= max_solves:
                raise _Budget()
            state["solves"] += 1
            why = None
            try:
                r, J = evaluate(np.array(p, dtype=float))
                r = np.asarray(r, dtype=float)
                J = np.asarray(J, dtype=float)
                if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
                    why = f"the model's values or sensitivities are not finite at {_point(names, p)}"
            except FitEvaluationError as exc:
                why = str(exc)
            if why is not None:
                state["failed"] += 1
                size = state["size"] if state["size"] is not None else 1
                cache[key] = (np.full(size, np.inf), None, why)
            else:
                state["size"] = r.size
                cache[key] = (r, J, None)
                rss = float(r @ r)
                if not rss > state["last_rss"]:  # the best point evaluated so far
                    state["last"], state["last_rss"] = np.array(p, dtype=float), rss
        return cache[key]

    def jacobian(p):
        r, J, why = get(p)
        if J is None:  # trf asks for the Jacobian only at accepted points, which were evaluated
            raise FitEvaluationError(why)
        return J

    def failed(why: str) -> FitResult:
        p = state["last"]
        entry = cache.get(p.tobytes())
        if entry is not None and entry[1] is not None:
            r, J = entry[0], entry[1]
        else:
            r, J = np.full(1, math.nan), np.full((1, m), math.nan)
        nan = np.full(m, math.nan)
        return FitResult(names, p, nan, nan, nan, np.full((m, m), math.nan), float(np.nansum(r ** 2)), r.size,
                         r.size - m, math.nan, sigma_known, math.nan, state["solves"], 0, "failed",
                         f"{why.rstrip('.')}. The last iterate was {_point(names, p)}.", math.nan, None, None, r, J,
                         p0, failed_trials=state["failed"])

    try:
        _, J0, why0 = get(p0)
        if J0 is None:
            state["failed"] = 0  # the start is not a trial point
            return failed(f"the model could not be evaluated at the initial point: {why0}")
        res = least_squares(lambda p: get(p)[0], p0, jac=jacobian, bounds=(lo, hi), method="trf",
                            x_scale="jac", xtol=xtol, ftol=ftol, gtol=gtol, max_nfev=max_solves)
    except _Budget:
        return failed(f"the fit did not converge within {max_solves} model solves (raise max_solves, or start closer)")
    except FitEvaluationError as exc:
        return failed(f"the model could not be evaluated: {exc}")
    if res.status == 0:
        state["last"] = np.asarray(res.x, dtype=float)
        return failed(f"the fit did not converge within {max_solves} model solves (raise max_solves, or start closer)")
    if res.status < 0:
        state["last"] = np.asarray(res.x, dtype=float)
        return failed(f"the fit stopped: {res.message}")
    p = np.asarray(res.x, dtype=float)
    r, J, why = get(p)
    if J is None:
        return failed(f"the model could not be evaluated at the fit's last point: {why}")
    info = uncertainties(J, r, p, names, sigma_known=sigma_known, limit=limit)
    at_bound = tuple(names[i] for i in range(m) if res.active_mask[i] != 0)
    message = {1: "the gradient is below its tolerance", 2: "the parameters changed less than their tolerance",
               3: "the sum of squares changed less than its tolerance",
               4: "both the parameters and the sum of squares stopped changing"}.get(res.status, res.message)
    return FitResult(names, p, info["standard_errors"], info["lower95"], info["upper95"], info["correlation"],
                     info["rss"], info["n"], info["dof"], info["residual_variance"], sigma_known, info["t_quantile"],
                     state["solves"], max(int(res.njev or 1) - 1, 0), "converged", f"converged: {message}",
                     info["condition"], info["identifiability"], info["null_direction"], r, J, p0, at_bound,
                     failed_trials=state["failed"])


class _Budget(Exception):
    pass


def _point(names, p) -> str:
    return ", ".join(f"{n} = {float(v):.10g}" for n, v in zip(names, p))
