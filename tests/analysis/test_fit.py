"""The least-squares fit's uncertainties: coverage of the 95 % intervals, identifiability, failures."""

import numpy as np
import pytest

from odelab.analysis.fit import FitEvaluationError, autocorrelation, combination_text, fit_least_squares

TRUE = np.array([2.0, 0.8])  # y = A exp(-k t)
T = np.linspace(0, 4, 20)


def decay(p):
    A, k = p
    e = np.exp(-k * T)
    return A * e, np.column_stack([e, -A * T * e])


@pytest.mark.parametrize("sigma_known", [False, True])
def test_95_percent_intervals_cover_the_truth_in_90_to_99_percent_of_200_draws(sigma_known):
    sigma = 0.05
    rng = np.random.default_rng(12345)
    covered = np.zeros(2)
    draws = 200
    for _ in range(draws):
        data = decay(TRUE)[0] + rng.normal(0, sigma, T.size)
        w = 1 / sigma if sigma_known else 1.0

        def evaluate(p, data=data, w=w):
            y, J = decay(p)
            return (y - data) * w, J * w

        fit = fit_least_squares(evaluate, [1.0, 1.0], names=("A", "k"), lower=[0, 0], sigma_known=sigma_known)
        assert fit.converged
        covered += (fit.lower95 <= TRUE) & (TRUE <= fit.upper95)
    fraction = covered / draws
    assert np.all((0.90 <= fraction) & (fraction <= 0.99)), fraction


def test_standard_errors_from_the_residual_variance():
    rng = np.random.default_rng(7)
    data = decay(TRUE)[0] + rng.normal(0, 0.05, T.size)

    def evaluate(p):
        y, J = decay(p)
        return y - data, J

    fit = fit_least_squares(evaluate, [1.0, 1.0], names=("A", "k"))
    r, J = evaluate(fit.estimates)
    s2 = r @ r / (T.size - 2)
    cov = s2 * np.linalg.inv(J.T @ J)
    np.testing.assert_allclose(fit.standard_errors, np.sqrt(np.diag(cov)), rtol=1e-9)
    np.testing.assert_allclose(fit.correlation[0, 1], cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]), rtol=1e-9)
    assert fit.dof == 18 and fit.rss == pytest.approx(r @ r)


def test_product_of_parameters_is_named():
    # y = exp(-a b t): the data determine a*b only
    data = np.exp(-1.5 * T)

    def evaluate(p):
        a, b = p
        e = np.exp(-a * b * T)
        return e - data + 1e-3 * np.sin(7 * T), np.column_stack([-b * T * e, -a * T * e])

    fit = fit_least_squares(evaluate, [1.0, 2.0], names=("a", "b"))
    assert fit.identifiability is not None and "a*b" in fit.identifiability
    assert "cannot separate a and b" in fit.identifiability
    assert np.all(np.isinf(fit.standard_errors)) or np.all(fit.standard_errors > 1e3 * np.abs(fit.estimates))


@pytest.mark.parametrize("direction, combo", [((1, -1), "a*b"), ((1, 1), "a/b"), ((1, -0.5), "a*b^2"),
                                               ((0.5, 1), "a/b^(1/2)")])
def test_combination_text(direction, combo):
    text = combination_text(("a", "b"), np.array(direction) / np.linalg.norm(direction), 1e20)
    assert f"enter only as {combo} " in text


def test_one_parameter_without_effect():
    text = combination_text(("a", "b"), np.array([0.0, 1.0]), float("inf"))
    assert "do not determine b" in text and "infinite" in text


def test_a_fit_that_does_not_converge_reports_its_last_iterate_and_why():
    data = decay(TRUE)[0]

    def evaluate(p):
        y, J = decay(p)
        return y - data, J

    fit = fit_least_squares(evaluate, [50.0, 9.0], names=("A", "k"), max_solves=3)
    assert fit.status == "failed"
    assert "did not converge within 3 model solves" in fit.message and "last iterate was A = " in fit.message

    def broken(p):
        if p[1] > 1.5:
            raise FitEvaluationError("the solver failed at t = 1")
        return evaluate(p)

    fit = fit_least_squares(broken, [1.0, 1.0], names=("A", "k"), lower=[0, 0], upper=[10, 2])
    assert fit.status in ("converged", "failed")
    fit = fit_least_squares(broken, [1.0, 1.6], names=("A", "k"))
    assert fit.status == "failed" and fit.failed_trials == 0
    assert "could not be evaluated at the initial point: the solver failed at t = 1" in fit.message


@pytest.mark.parametrize("how", ["raises", "nan", "inf jacobian"])
def test_a_trial_point_that_cannot_be_evaluated_is_a_rejected_step(how):
    # The model fails at the first trial point (a blow-up, NaN, max steps): the trust region
    # shrinks and the fit goes on from the start, to the same estimates as a fit that never failed.
    data = decay(TRUE)[0]

    def evaluate(p):
        y, J = decay(p)
        return y - data, J

    clean = fit_least_squares(evaluate, [1.0, 1.0], names=("A", "k"))
    seen = []

    def flaky(p):
        seen.append(tuple(p))
        if len(seen) == 2:  # the first trial point
            if how == "raises":
                raise FitEvaluationError("the solver failed at t = 3")
            r, J = evaluate(p)
            return (np.full_like(r, np.nan), J) if how == "nan" else (r, J * np.inf)
        return evaluate(p)

    fit = fit_least_squares(flaky, [1.0, 1.0], names=("A", "k"))
    assert fit.converged and fit.failed_trials == 1
    np.testing.assert_allclose(fit.estimates, TRUE, rtol=1e-9)
    np.testing.assert_allclose(fit.estimates, clean.estimates, rtol=1e-9)
    assert fit.solves > clean.solves


def test_autocorrelation():
    rng = np.random.default_rng(3)
    white = autocorrelation(rng.normal(size=400))
    assert white[0] == 1.0 and np.all(np.abs(white[1:]) < 3 / np.sqrt(400))
    trend = autocorrelation(np.sin(np.linspace(0, 3, 400)))
    assert trend[1] > 0.95
