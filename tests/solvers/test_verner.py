"""ode78 and ode89: Verner's pairs as data, checked tree by tree, on the one explicit engine."""

from collections import Counter

import numpy as np
import pytest

import odelab
from odelab.exceptions import InputError
from odelab.solvers import engine
from odelab.solvers.dense import basis_values
from odelab.solvers.registry import METHODS
from odelab.solvers.tableau import ButcherTableau, _condition_ok, _order_conditions, _tree_data, rooted_trees
from odelab.solvers.verner import VERNER87, VERNER98

PAIRS = {"ode78": VERNER87, "ode89": VERNER98}


def rigid(t, y):
    return [y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]]


def riccati(t, y):
    """y1' = -2 t y1^2 (nonlinear: no elementary differential vanishes), y2' = cos(t) y2."""
    return np.array([-2 * t * y[0] ** 2, np.cos(t) * y[1]])


def riccati_exact(t):
    return np.array([1 / (1 + t * t), np.exp(np.sin(t))])


def test_rooted_trees_up_to_order_9():
    orders, _, _ = _tree_data(np.zeros((1, 1)))
    assert len(rooted_trees()) == 486
    assert [Counter(orders.tolist())[p] for p in range(1, 10)] == [1, 1, 2, 4, 9, 20, 48, 115, 286]


@pytest.mark.parametrize("name", PAIRS)
def test_every_order_condition_holds_and_the_order_is_exact(name):
    tab = PAIRS[name]
    conditions = _order_conditions(tab.A, tab.b, tab.c, 9)
    # Verner's 17-digit decimals: round-off only, a few ulps of the terms' size
    assert all(_condition_ok(v, r, scale) for p, v, r, scale in conditions if p <= tab.order)
    assert max(abs(v - r) for p, v, r, _ in conditions if p <= tab.order) < 1e-12
    if tab.order < 9:  # ode78's 8th-order solution misses some order-9 condition by far more
        assert max(abs(v - r) for p, v, r, _ in conditions if p == 9) > 1e-7
    # The embedded solution b - E has exactly the order error_order (7 and 8).
    embedded = _order_conditions(tab.A, tab.b - tab.error_weights, tab.c, tab.error_order + 1)
    assert max(abs(v - r) for p, v, r, _ in embedded if p <= tab.error_order) < 1e-12
    assert max(abs(v - r) for p, v, r, _ in embedded if p == tab.error_order + 1) > 1e-7
    np.testing.assert_allclose(tab.A.sum(axis=1), tab.c, atol=1e-13)
    np.testing.assert_allclose(tab.extra_A.sum(axis=1), tab.extra_c, atol=1e-13)
    assert abs(tab.error_weights.sum()) < 1e-15 and not tab.fsal


@pytest.mark.parametrize("name", PAIRS)
def test_the_continuous_extension_meets_its_conditions_power_by_power(name):
    tab = PAIRS[name]
    orders, gammas, phis = _tree_data(tab.full_A, 8)
    # in the powers of s Verner publishes: round-off relative to terms up to 1.4e6 (ode78), the
    # bound the tableau checks itself with (eps times the roundings times the terms' size)
    assert tab._dense_order_problems() == []
    powers = tab.dense_powers
    values = powers.T @ phis.T  # (powers of s, trees)
    required = np.where(np.arange(1, 9)[:, None] == orders[None, :], 1 / gammas[None, :], 0.0)
    magnitudes = np.abs(tab._dense_magnitudes.T) @ _tree_data(np.abs(tab.full_A), 8)[2].T
    assert (np.abs(values - required) <= 1e-12 * magnitudes).all()  # any summation order (BLAS here)
    # in the Chebyshev form odelab evaluates: b(s) . Phi(t) = s^|t| / gamma(t) to round-off
    s = np.linspace(0.1, 1, 10)
    weights = tab.dense @ basis_values(s, tab.dense.shape[1], "chebyshev")  # b_j(s), (stages, 10)
    error = np.abs(phis @ weights - s[None, :] ** orders[:, None] / gammas[:, None]).max()
    assert error < {"ode78": 1e-13, "ode89": 1e-10}[name], error
    np.testing.assert_allclose(tab.dense.sum(axis=1)[:tab.stages], tab.b, atol=1e-11)
    assert tab.dense.shape == (tab.full_c.size, 9) and tab.dense_order == 8 and np.abs(tab.dense).max() < 32
    assert (tab.stages, tab.full_c.size) == {"ode78": (13, 21), "ode89": (16, 21)}[name]


def test_the_stored_chebyshev_form_is_the_exact_conversion_of_the_published_powers():
    from odelab.solvers import verner

    np.testing.assert_array_equal(verner.chebyshev_rows(verner._D87_DIGITS, 21), VERNER87.dense)
    robust = {j + 1: row for j, row in enumerate(verner._D98) if any(row)}
    np.testing.assert_array_equal(verner.chebyshev_rows(robust, 21), VERNER98.dense)
    # and it is the same polynomial: at s = 0.3, sum_m a_m s^m (40 digits) against the T_k form
    s = 0.3
    for stage, digits in verner._D87_DIGITS.items():
        direct = sum(float(a) * s ** (m + 1) for m, a in enumerate(digits))
        assert abs(VERNER87.dense[stage - 1] @ basis_values(s, 9, "chebyshev")[:, 0] - direct) < 1e-9


def test_a_mistyped_coefficient_is_rejected_at_construction():
    A = np.array(VERNER98.A)
    A[7, 5] += 1e-9  # one digit wrong in the ninth decimal
    A.setflags(write=False)
    with pytest.raises(ValueError, match="row sums of A"):
        ButcherTableau(name="typo", c=VERNER98.c, A=A, b=VERNER98.b, order=9)
    c = A.sum(axis=1)  # the row sum fixed too: the order conditions still catch it
    with pytest.raises(ValueError, match=r"order-\d condition gives"):
        ButcherTableau(name="typo", c=c, A=A, b=VERNER98.b, order=9)
    dense = np.array(VERNER87.dense)
    dense[7, 3] *= 1 + 1e-9
    with pytest.raises(ValueError, match="continuous extension"):
        ButcherTableau(name="typo", c=VERNER87.c, A=VERNER87.A, b=VERNER87.b, order=8, dense=dense, dense_order=8,
                       extra_c=VERNER87.extra_c, extra_A=VERNER87.extra_A, dense_basis="chebyshev")


@pytest.mark.parametrize("name, order", [("ode78", 8), ("ode89", 9)])
def test_observed_order_on_fixed_steps(name, order):
    tab = PAIRS[name]
    y0 = riccati_exact(0.0)
    errors = []
    for n in (16, 32):  # global error in y1 over [0, 4], before round-off
        grid = np.linspace(0, 4, n + 1)
        t, y, *_ = engine.integrate_fixed(riccati, grid, np.ones(n + 1, bool), y0, tab.A, tab.b, tab.c)
        errors.append(np.abs(y[:, 0] - 1 / (1 + t * t)).max())
    observed = np.log2(errors[0] / errors[1])
    assert order - 0.5 < observed < order + 2, observed


@pytest.mark.parametrize("name", PAIRS)
def test_dense_output_order_on_one_step(name):
    """The interpolant's local error inside one step falls as h^9 (order 8)."""
    tab = PAIRS[name]
    t0 = 1.0
    y0 = riccati_exact(t0)
    errors = []
    for h in (1.0, 0.5, 0.25):
        K = np.zeros((tab.full_c.size, 2))
        for i, ci in enumerate(tab.full_c):
            K[i] = riccati(t0 + ci * h, y0 + h * tab.full_A[i, :i] @ K[:i])
        errors.append(max(np.abs(y0 + h * (K.T @ tab.dense_powers) @ s ** np.arange(1, 9) - riccati_exact(t0 + s * h)).max()
                          for s in (0.2, 0.4, 0.6, 0.8)))
    assert (np.log2(np.array(errors[:-1]) / errors[1:]) > 9).all(), errors


@pytest.mark.parametrize("name", PAIRS)
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_accuracy_in_units_of_the_tolerance(name, rtol):
    ex1 = odelab.solve(lambda t, y: np.cos(t), [0, np.pi], 2.0, method=name, rtol=rtol, atol=rtol * 1e-3)
    assert np.abs(ex1.y[:, 0] - (np.sin(ex1.t) + 2)).max() / 2 < rtol
    times = np.linspace(0, 12, 25)
    body = odelab.solve(rigid, times, [0, 1, 1], method=name, rtol=rtol, atol=rtol * 1e-3)
    ref = odelab.solve(rigid, times, [0, 1, 1], method="DOP853", rtol=1e-13, atol=1e-15)
    assert np.abs(body.y - ref.y).max() < 10 * rtol


def test_increments_keep_the_round_off_of_large_coefficients_down():
    """Two-body orbit, e = 0.6, two periods: back at the start. Summing Verner's 8(7) coefficients
    (up to 120) against whole stages left a floor near 3e-11; on increments the error follows rtol."""
    e = 0.6

    def kepler(t, y):
        r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
        return [y[2], y[3], -y[0] / r3, -y[1] / r3]

    y0 = [1 - e, 0, 0, np.sqrt((1 + e) / (1 - e))]
    for name in PAIRS:
        sol = odelab.solve(kepler, [0, 4 * np.pi], y0, method=name, rtol=1e-12, atol=1e-15)
        assert np.abs(sol.y[-1] - y0).max() < 1e-11
    inc = VERNER87.increment_form
    assert inc["A"][5, 0] == VERNER87.c[5] and inc["b"][0] == 1 and inc["error_weights"][0] == 0
    np.testing.assert_array_equal(inc["dense"][0], [0.5, 0.5, 0, 0, 0, 0, 0, 0, 0])  # s in Chebyshev form


def test_fewer_evaluations_than_ode45_at_tight_tolerances():
    tol = dict(rtol=1e-10, atol=1e-12)
    work = {m: odelab.solve(rigid, [0, 12], [0, 1, 1], method=m, **tol).stats.nfevals for m in ("ode45", "ode78", "ode89")}
    assert work["ode78"] < 0.5 * work["ode45"] and work["ode89"] < 0.5 * work["ode45"], work


@pytest.mark.parametrize("name, s, extra", [("ode78", 13, 7), ("ode89", 16, 4)])
def test_evaluation_counts_and_refine(name, s, extra):
    plain = odelab.solve(rigid, [0, 12], [0, 1, 1], method=name)
    st = plain.stats
    # s - 1 stages per attempt, f(t+h, y_new) per accepted step, the first f(t0, y0)
    assert st.nfevals == 1 + (s - 1) * (st.nsteps + st.nfailed) + st.nsteps
    assert plain.t.size == st.nsteps + 1  # MATLAB's default Refine for ode78/ode89 is 1
    fine = odelab.solve(rigid, [0, 12], [0, 1, 1], method=name, refine=4)
    assert fine.t.size == 4 * st.nsteps + 1 and np.array_equal(fine.y[::4], plain.y)
    # Refine interpolates every step: its extra stages are evaluated (and counted) once per step.
    assert fine.stats.nfevals == st.nfevals + extra * st.nsteps
    # the same extension, to round-off (evaluated in Chebyshev form: the powers of s would lose 1e-10)
    np.testing.assert_allclose(odelab.deval(plain, fine.t), fine.y, rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", PAIRS)
def test_deval_and_output_times_use_the_extension(name):
    sol = odelab.solve(riccati, [0, 3], riccati_exact(0.0), method=name, rtol=1e-9, atol=1e-12)
    tq = np.linspace(0, 3, 301)
    exact = np.array([riccati_exact(t) for t in tq])
    assert np.abs(sol.deval(tq) - exact).max() < 1e-8
    assert sol.interpolant.completion.nfevals > 0  # the steps were completed for deval, not before
    at_times = odelab.solve(riccati, tq, riccati_exact(0.0), method=name, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(at_times.y, sol.deval(tq), rtol=0, atol=1e-9)
    # Output times inside a step make the engine evaluate that step's extra stages (and count them):
    # all steps here but the first, which MATLAB's initial-step rule ends on the first output time.
    st = at_times.stats
    stages, extra = PAIRS[name].stages, PAIRS[name].extra_c.size
    assert st.nfevals == 1 + (stages - 1) * (st.nsteps + st.nfailed) + st.nsteps + extra * (st.nsteps - 1)
    assert at_times.t[1] == tq[1] == at_times.interpolant.t[1]


@pytest.mark.parametrize("name", PAIRS)
def test_events_are_located_on_the_extension(name):
    def crossing(t, y):
        return y[0], True, -1

    # free fall is a quadratic: the 8th-order extension has it exactly, and so the event time
    fall = odelab.solve(lambda t, y: [y[1], -9.81], [0, 5], [10, 0], method=name, events=crossing)
    assert abs(fall.te[0] - np.sqrt(20 / 9.81)) < 1e-13 and fall.stats.nsteps == 9
    sol = odelab.solve(lambda t, y: [y[1], -y[0]], [0, 10], [1, 0], method=name, rtol=1e-10, atol=1e-12,
                       events=crossing)
    assert sol.ie.tolist() == [0] and abs(sol.te[0] - np.pi / 2) < 1e-10
    assert sol.t[-1] == sol.te[0] and sol.status == "success"
    # the shortened last step interpolates the same curve
    mid = (sol.t[-2] + sol.t[-1]) / 2
    assert abs(sol.deval(mid)[0] - np.cos(mid)) < 1e-10


def test_registry_rows_and_backend():
    for name, order, label in (("ode78", 8, "8(7)"), ("ode89", 9, "9(8)")):
        m = METHODS[name]
        assert (m.kind, m.order, m.order_label, m.refine) == ("adaptive", order, label, 1)
        assert m.power == 1 / (order) and m.tableau is PAIRS[name] and m.kind_label == "non-stiff"
        sol = getattr(odelab, name)(lambda t, y: -y, [0, 1], 1.0)
        assert sol.warnings == () and sol.method == name
    from odelab.solvers.compiled.capability import why_not_compiled

    assert "Verner's non-FSAL pair" in why_not_compiled(METHODS["ode78"], object())
    from odelab.solvers.compiled import solve_compiled

    with pytest.raises(InputError, match=r"ode89 is Verner's non-FSAL pair, which runs on the Python path: use "
                                         r"backend \"python\""):
        solve_compiled(None, [0, 1], [1.0], method="ode89")


def test_odextend_nonnegative_and_mass_through_the_same_driver():
    first = odelab.ode89(lambda t, y: -y, [0, 1], 1.0, RelTol=1e-10, AbsTol=1e-12)
    whole = odelab.odextend(first, None, 2.0)  # completes both parts' interpolation stages
    assert abs(whole.y[-1, 0] - np.exp(-2)) < 1e-11 and abs(whole.deval(1.5)[0] - np.exp(-1.5)) < 1e-11
    # y' = -sqrt(y) reaches 0 at t = 2 and must stay there (MATLAB's NonNegative)
    sink = odelab.ode78(lambda t, y: [-np.sqrt(max(y[0], 0.0))], [0, 3], [1.0], NonNegative=[1], RelTol=1e-8)
    assert sink.success and sink.y[:, 0].min() == 0.0 and abs(sink.y[-1, 0]) == 0.0
    heavy = odelab.ode78(lambda t, y: [-y[0]], [0, 1], [1.0], Mass=[[2.0]], RelTol=1e-10, AbsTol=1e-12)
    assert abs(heavy.y[-1, 0] - np.exp(-0.5)) < 1e-11


def _rebuild(tab, **changes):
    fields = dict(name=tab.name, c=tab.c, A=tab.A, b=tab.b, order=tab.order, error_weights=tab.error_weights,
                  error_order=tab.error_order, dense=tab.dense, dense_order=tab.dense_order, fsal=False,
                  extra_c=tab.extra_c, extra_A=tab.extra_A, dense_basis=tab.dense_basis)
    fields.update(changes)
    return ButcherTableau(**fields)


@pytest.mark.parametrize("name", PAIRS)
def test_the_self_check_catches_a_coefficient_wrong_in_its_twelfth_digit(name):
    """The import-time check's tolerance is the coefficients' own round-off (eps times the
    terms' size), not a fixed bound: a correct tableau passes under every BLAS kernel (it calls
    no BLAS), and a coefficient off by one part in 1e11 (the row sums kept, so that only the
    order conditions can see it) still fails."""
    tab = PAIRS[name]
    assert _rebuild(tab).order == tab.order  # the published data passes
    big = np.unravel_index(np.argmax(np.abs(tab.A)), tab.A.shape)
    A = np.array(tab.A)
    delta = A[big] * 1e-11
    A[big] += delta
    A[big[0], 0] -= delta  # same row sum: the nodes c still match
    with pytest.raises(ValueError, match=r"order-\d condition"):
        _rebuild(tab, A=A)
    b = np.array(tab.b)
    j = int(np.argmax(np.abs(b)))
    b[j] += b[j] * 1e-11
    b[0] -= b[j] * 1e-11 / (1 + 1e-11)
    with pytest.raises(ValueError, match=r"order-\d condition"):
        _rebuild(tab, b=b, error_weights=tab.error_weights + (b - tab.b))
    dense = np.array(tab.dense)
    k = np.unravel_index(np.argmax(np.abs(dense[:, 2:])), dense[:, 2:].shape)
    k = (k[0], k[1] + 2)
    dense[k] += dense[k] * 1e-11
    with pytest.raises(ValueError, match="continuous extension"):
        _rebuild(tab, dense=dense)
