"""Tableau invariants: every method's coefficients satisfy the conditions its order claims."""

import numpy as np
import pytest

from odelab.solvers import tableau as tb
from odelab.solvers.tableau import ButcherTableau, _order_conditions

ALL = [tb.BS23, tb.DP54, tb.EULER, tb.HEUN, tb.MIDPOINT, tb.RALSTON, tb.KUTTA3, tb.RK4]


@pytest.mark.parametrize("tab", ALL, ids=lambda t: t.name)
def test_order_conditions_hold_up_to_the_order_and_fail_above(tab):
    conditions = _order_conditions(tab.A, tab.b, tab.c)
    for p, value, required, _ in conditions:
        if p <= tab.order:
            assert value == pytest.approx(required, abs=1e-15)
    # The claimed order is the exact order: some condition of order p+1 fails.
    above = [abs(v - r) for p, v, r, _ in conditions if p == tab.order + 1]
    if above:
        assert max(above) > 1e-4


@pytest.mark.parametrize("tab", ALL, ids=lambda t: t.name)
def test_row_sums_and_explicitness(tab):
    np.testing.assert_allclose(tab.A.sum(axis=1), tab.c, atol=1e-15)
    assert np.all(np.triu(tab.A) == 0)
    assert not tab.A.flags.writeable and not tab.b.flags.writeable


@pytest.mark.parametrize("tab", [tb.BS23, tb.DP54], ids=lambda t: t.name)
def test_embedded_pair(tab):
    assert tab.fsal and tab.c[-1] == 1 and np.array_equal(tab.A[-1], tab.b)
    # The embedded solution b - E has exactly the lower order error_order.
    b_hat = tab.b - tab.error_weights
    conditions = _order_conditions(tab.A, b_hat, tab.c)
    for p, value, required, _ in conditions:
        if p <= tab.error_order:
            assert value == pytest.approx(required, abs=1e-15)
    assert max(abs(v - r) for p, v, r, _ in conditions if p == tab.error_order + 1) > 1e-4
    # The continuous extension reproduces the step's solution at s = 1 and y at s = 0.
    np.testing.assert_allclose(tab.dense.sum(axis=1), tab.b, atol=1e-15)


def test_matlab_error_weights_are_the_published_ones():
    assert tb.BS23.error_weights.tolist() == [-5 / 72, 1 / 12, 1 / 9, -1 / 8]
    assert tb.DP54.error_weights[0] == 71 / 57600 and tb.DP54.error_weights[-1] == -1 / 40


def test_a_broken_tableau_is_rejected_at_construction():
    with pytest.raises(ValueError, match="order-2 condition"):
        ButcherTableau(
            name="bad heun",
            c=np.array([0.0, 1.0]),
            A=np.array([[0.0, 0.0], [1.0, 0.0]]),
            b=np.array([0.4, 0.6]),
            order=2,
        )
    with pytest.raises(ValueError, match="row sums"):
        ButcherTableau(name="bad c", c=np.array([0.0, 0.5]), A=np.array([[0.0, 0.0], [1.0, 0.0]]),
                       b=np.array([0.5, 0.5]), order=2)
    with pytest.raises(ValueError, match="implicit"):
        ButcherTableau(name="implicit", c=np.array([0.5]), A=np.array([[0.5]]), b=np.array([1.0]), order=1)


def _shipped_tableaux():
    """Every ButcherTableau held by a module of odelab.solvers (built with check=False at import)."""
    import importlib
    import pkgutil

    import odelab.solvers

    found = {}
    for info in pkgutil.walk_packages(odelab.solvers.__path__, "odelab.solvers."):
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if isinstance(value, ButcherTableau):
                found[value.name] = value
    return found


def test_every_shipped_tableau_passes_its_checks():
    """The shipped constants skip the checks at import; here every one of them is verified."""
    found = _shipped_tableaux()
    assert {t.name for t in ALL} <= set(found) and len(found) >= len(ALL) + 2  # with Verner's 8(7), 9(8)
    for tab in found.values():
        tab.verify()  # raises ValueError naming the failed condition


def test_verify_catches_a_typo_in_a_shipped_tableau():
    """check=False only defers the checks: the same coefficients with one digit wrong fail verify()."""
    A = tb.DP54.A.copy()
    A[3, 1] += 1e-6
    c = A.sum(axis=1)
    typo = ButcherTableau(name="DP54 typo", c=c, A=A, b=tb.DP54.b, order=5, check=False)
    with pytest.raises(ValueError, match=r"order-\d condition gives"):
        typo.verify()


def test_a_tableau_built_unchecked_is_checked_only_when_asked():
    """check=False defers verify(); the default checks at construction (a user's tableau)."""
    bad = dict(name="bad heun", c=np.array([0.0, 1.0]), A=np.array([[0.0, 0.0], [1.0, 0.0]]), b=np.array([0.4, 0.6]),
               order=2)
    deferred = ButcherTableau(**bad, check=False)
    with pytest.raises(ValueError, match="order-2 condition"):
        deferred.verify()
    with pytest.raises(ValueError, match="order-2 condition"):
        ButcherTableau(**bad)
