"""Error tables: the lab's relative error, undefined where the reference is zero or tiny."""

import numpy as np

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
