"""Observed order fits and work-precision curves on synthetic errors with known answers."""

import math

import numpy as np

from odelab.analysis.studies import convergence_order, quadrature_order, quadrature_rule, work_precision


def test_exact_power_law_gives_the_order():
    h = 0.1 / 2.0 ** np.arange(6)
    fit = convergence_order(h, 3.0 * h ** 4, nominal=4, label="rk4")
    assert abs(fit.order - 4) < 1e-12 and abs(10 ** fit.intercept - 3.0) < 1e-10
    assert fit.excluded == ("",) * 6 and fit.warnings == () and abs(fit.deviation) < 1e-12
    np.testing.assert_allclose(fit.fitted(h), 3.0 * h ** 4, rtol=1e-10)


def test_round_off_points_are_left_out_visibly():
    h = 0.1 / 2.0 ** np.arange(7)
    err = 2.0 * h ** 4
    err[-2:] = [1e-9, 2e-9]  # the error stops falling (3e-9, 1e-9), then grows: round-off
    fit = convergence_order(h, err, nominal=4, label="rk4")
    assert fit.excluded[-2:] == ("round-off", "round-off") and fit.used[:5] == (True,) * 5
    assert abs(fit.order - 4) < 1e-9
    assert "rk4: 2 points left out of the fit: h=0.003125 (round-off), h=0.0015625 (round-off)" in fit.warnings


def test_round_off_floor_from_the_number_of_steps():
    h = np.array([0.1, 0.05, 0.025, 0.0125])
    err = h ** 8  # 1.5e-15 at the finest: below eps * N * scale
    fit = convergence_order(h, err, steps=np.pi / h, scale=3.0)
    assert fit.excluded == ("", "", "", "round-off")


def test_steps_too_large_are_left_out():
    h = 0.2 / 2.0 ** np.arange(6)
    err = h ** 2 * (1 + 5 * h)  # pre-asymptotic at the coarse end: local slopes 2.5, 2.2, ...
    fit = convergence_order(h, err, nominal=2, label="heun")
    assert fit.excluded[0] == "steps too large" and not fit.excluded[-1]
    assert abs(fit.order - 2) < 0.1
    plain = np.polyfit(np.log(h), np.log(err), 1)[0]
    assert abs(plain - 2) > abs(fit.order - 2)


def test_failed_points_and_too_few_points():
    fit = convergence_order([0.1, 0.05], [math.nan, 1e-3], nominal=1, label="euler")
    assert math.isnan(fit.order) and fit.excluded == ("no error measured", "")
    assert fit.warnings[0] == "euler: fewer than two usable points; no order fitted"


def test_nominal_mismatch_warns():
    h = np.array([0.1, 0.05, 0.025])
    fit = convergence_order(h, h ** 4, nominal=3, label="rk3")
    assert fit.warnings == ("rk3: observed order 4.00 is not the nominal 3",)


def test_quadrature_orders_and_rules_of_the_fixed_step_methods():
    from odelab.solvers.registry import get_method

    expected = {"euler": (1, "the left rectangle rule"), "heun": (2, "the trapezoidal rule"),
                "midpoint": (2, "the midpoint rule"), "rk3": (4, "Simpson's rule"), "rk4": (4, "Simpson's rule")}
    for name, (order, rule) in expected.items():
        tab = get_method(name).tableau
        assert (quadrature_order(tab.b, tab.c), quadrature_rule(tab.b, tab.c)) == (order, rule), name
    tab = get_method("ode45").tableau  # Dormand-Prince's b: a quadrature of order 5, no name
    assert quadrature_order(tab.b, tab.c) == 5 and quadrature_rule(tab.b, tab.c) == "its quadrature rule"


def test_an_order_explained_by_the_quadrature_rule_says_why():
    h = np.array([0.1, 0.05, 0.025])
    fit = convergence_order(h, h ** 4, nominal=3, label="rk3", quadrature=(4, "Simpson's rule"))
    assert fit.note == "Simpson's rule, order 4: dy/dt does not depend on y"
    assert fit.warnings[0].startswith("rk3: observed order 4.00, not the nominal 3, because dy/dt does not depend")
    other = convergence_order(h, h ** 2, nominal=3, label="rk3", quadrature=(4, "Simpson's rule"))
    assert other.note == "" and other.warnings == ("rk3: observed order 2.00 is not the nominal 3",)


def test_work_precision_sorts_and_fits_cost_per_digit():
    tol = [1e-6, 1e-3, 1e-4, 1e-5]  # tightest first on purpose
    err = [1e-7, 1e-4, 1e-5, 1e-6]
    curve = work_precision("ode45", tol, err, [1000.0, 100.0, 100 * 10 ** 0.2, 100 * 10 ** 0.4],
                           [0.4, 0.1, 0.2, 0.3])
    assert curve.tolerance == (1e-3, 1e-4, 1e-5, 1e-6) and curve.seconds == (0.1, 0.2, 0.3, 0.4)
    assert curve.error == (1e-4, 1e-5, 1e-6, 1e-7) and curve.nfevals[0] == 100.0
    # log10 fevals 2, 2.2, 2.4, 3 over 4..7 digits: least-squares slope 1.6 / 5 = 0.32 per digit
    assert abs(curve.slope - 0.32) < 1e-12
