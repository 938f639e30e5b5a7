"""Error tables: the lab's relative error, undefined where the reference is zero or tiny."""

import numpy as np
import pytest

from odelab.analysis.errors import RELATIVE_FLOOR, error_columns, summarize


def test_relative_error_is_the_labs_definition():
    ref = np.array([2.0, 3.0, -4.0])
    val = np.array([2.1, 2.7, -4.0])
    abs_err, rel_err = error_columns(val, ref)
    np.testing.assert_allclose(abs_err, [0.1, 0.3, 0.0], atol=1e-15)
    np.testing.assert_allclose(rel_err, [0.05, 0.1, 0.0], atol=1e-15)


def test_zero_and_tiny_reference_is_undefined_not_inf():
    ref = np.array([0.0, 1e-12, 1.0])
    val = np.array([1e-6, 1e-6, 1.001])
    _, rel_err = error_columns(val, ref)
    assert np.isnan(rel_err[0]) and np.isnan(rel_err[1])
    assert abs(rel_err[2] - 1e-3) < 1e-12
    s = summarize("y", np.array([0.0, 1.0, 2.0]), val, ref)
    assert s.undefined == 2 and s.max_rel is not None and abs(s.max_rel - 1e-3) < 1e-12 and s.t_max_rel == 2.0
    assert abs(s.max_abs - 1e-3) < 1e-12 and s.t_max_abs == 2.0
    assert RELATIVE_FLOOR == np.sqrt(np.finfo(float).eps)


def test_all_undefined():
    s = summarize("y", np.array([0.0, 1.0]), np.array([1.0, 1.0]), np.zeros(2))
    assert s.max_rel is None and s.undefined == 2 and s.max_abs == 1.0


# --- the headline rule --------------------------------------------------------------------------

from odelab.analysis.errors import HEADLINE_RULE, NEAR_ZERO, headline_basis  # noqa: E402


def test_headline_is_the_labs_pointwise_maximum_where_f_stays_away_from_zero():
    # Exercise 1: f = sin t + 2 stays in [1, 3] on [0, 2 pi]
    t = np.linspace(0, 2 * np.pi, 17)
    f = np.sin(t) + 2
    y = f * (1 + 1e-4 * np.cos(t))  # a relative error of up to 1e-4
    s = summarize("y", t, y, f)
    assert s.basis == "pointwise" and s.headline == s.max_rel
    assert abs(s.max_rel - 1e-4) < 1e-12
    assert s.scale == 3.0 and s.peak_rel == s.max_abs / 3.0


def test_headline_is_relative_to_the_peak_where_f_nears_zero():
    # y(t) = sin t through a zero crossing: a 1e-6 absolute error at t = 1e-4 is 1 % pointwise
    t = np.array([0.0, 1e-4, 0.5, 1.0, 1.5])
    f = np.sin(t)
    y = f + np.array([0.0, 1e-6, 2e-6, -3e-6, 1e-6])
    s = summarize("y", t, y, f)
    assert s.basis == "peak"
    assert s.max_rel == pytest.approx(1e-6 / np.sin(1e-4), rel=1e-9) and s.t_max_rel == 1e-4
    assert s.ref_at_max_rel == pytest.approx(np.sin(1e-4), rel=1e-12)
    assert s.headline == pytest.approx(3e-6 / np.sin(1.5), rel=1e-9)  # max |f - y| / max |f|
    assert s.headline < s.max_rel / 1000
    d = s.as_dict()
    assert d["rel_basis"] == "peak" and d["rel_error"] == s.headline and d["max_rel"] == s.max_rel


def test_the_near_zero_threshold_is_ten_percent_of_the_peak():
    assert NEAR_ZERO == 0.1
    assert headline_basis(np.array([1.0, 0.1, -1.0])) == "pointwise"  # |f| >= 0.1 max |f| everywhere
    assert headline_basis(np.array([1.0, 0.0999, 1.0])) == "peak"
    assert headline_basis(np.zeros(3)) == "peak"
    assert "10%" in HEADLINE_RULE and "max |f - y| / max |f|" in HEADLINE_RULE


def _summary_of_whole_columns(name, t, values, reference):
    """summarize() as it was, over the whole columns at once (the reference for the blockwise one)."""
    from odelab.analysis.errors import ErrorSummary, headline_basis

    reference = np.asarray(reference, dtype=float)
    abs_err, rel_err = error_columns(values, reference)
    i = int(np.nanargmax(abs_err)) if np.any(np.isfinite(abs_err)) else 0
    undefined = int(np.count_nonzero(np.isnan(rel_err)))
    finite_ref = np.abs(reference[np.isfinite(reference)])
    scale = float(finite_ref.max()) if finite_ref.size else float("nan")
    basis = headline_basis(reference)
    if undefined == rel_err.size:
        return ErrorSummary(name, float(abs_err[i]), float(t[i]), None, None, undefined, scale, None, basis)
    j = int(np.nanargmax(rel_err))
    return ErrorSummary(name, float(abs_err[i]), float(t[i]), float(rel_err[j]), float(t[j]), undefined, scale,
                        float(abs(reference[j])), basis)


@pytest.mark.filterwarnings("ignore:invalid value encountered in subtract:RuntimeWarning")  # inf - inf, as ever
@pytest.mark.parametrize("seed", range(40))
def test_summarize_a_block_at_a_time_is_the_whole_columns_summary(seed):
    # ties (values on a coarse grid), zeros, NaN and inf in either column, runs of NaN longer than a block
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    reference = np.round(rng.normal(size=n) * rng.choice([1e-9, 1, 1e6]), int(rng.integers(0, 3)))
    values = reference + np.round(rng.normal(size=n), 1) * rng.choice([0, 1e-3, 1])
    for column in (reference, values):
        if rng.random() < 0.5:
            k = rng.integers(0, n, size=int(rng.integers(1, max(2, n // 3))))
            column[k] = rng.choice([np.nan, np.inf, -np.inf, 0.0], size=k.size)
    if rng.random() < 0.2:
        values[: n // 2] = np.nan
    t = np.linspace(0, 1, n)
    want = _summary_of_whole_columns("y", t, values, reference)
    for block in (1, 3, 7, 64, n):
        got = summarize("y", t, values, reference, block=block)
        assert repr(got) == repr(want), block
