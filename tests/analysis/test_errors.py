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
