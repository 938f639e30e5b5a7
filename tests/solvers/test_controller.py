"""MATLAB's step-size rules (solvers/controller.py), the same in Python and compiled."""

import math

import numpy as np
import pytest

from odelab.solvers import controller as ctl

RULES = [
    ("min_step", (0.0,)), ("min_step", (1.0,)), ("min_step", (-3.5e7,)),
    ("given_step", (1e-20, 1.0, 0.5)), ("given_step", (2.0, 1.0, 0.5)), ("given_step", (0.01, 1.0, 0.5)),
    ("first_step", (0.0, 2.0, 0.5, 0.0)), ("first_step", (40.0, 2.0, 0.5, 0.0)), ("first_step", (1e300, 2.0, 0.5, 1.0)),
    ("clamp_step", (0.0, 1.0, 0.95, 10.0)), ("clamp_step", (0.0, 1.0, 0.5, 10.0)), ("clamp_step", (0.0, 1.0, 0.5, 0.1)),
    ("clamp_step", (1.0, 0.0, 0.5, 10.0)), ("clamp_step", (1e8, 2e8, 1e-20, 1e9)),
    ("shrink", (0.1, 1e-15, 2e-3, 1e-3, 0.2, 0.1, 0.8, True)), ("shrink", (0.1, 1e-15, 1e9, 1e-3, 0.2, 0.1, 0.8, True)),
    ("shrink", (0.1, 1e-15, 2e-3, 1e-3, 0.2, 0.1, 0.8, False)), ("shrink", (1e-15, 1e-14, 2e-3, 1e-3, 0.2, 0.1, 0.8, False)),
    ("grow", (0.1, 1e-4, 1e-3, 0.2, 1.25, 5.0)), ("grow", (0.1, 0.0, 1e-3, 0.2, 1.25, 5.0)),
    ("grow", (0.1, 1e-12, 1e-3, 1 / 3, 1.2, 10.0)),
]


def test_the_rules_are_matlabs():
    assert ctl.min_step(1.0) == 16 * np.spacing(1.0)
    # within 10 % of tf the step is stretched to land on it, else it is kept within [hmin, hmax]
    assert ctl.clamp_step(0.0, 1.0, 0.95, 10.0) == (ctl.min_step(0.0), 1.0, True)
    assert ctl.clamp_step(0.0, 1.0, 0.5, 0.1) == (ctl.min_step(0.0), 0.1, False)
    assert ctl.clamp_step(1e8, 2e8, 1e-20, 1e9)[1] == ctl.min_step(1e8)
    # the first failure scales by 0.8 (rtol/err)^p, at least by `least`; later ones halve
    assert ctl.shrink(0.1, 0.0, 2e-3, 1e-3, 0.2, 0.1, 0.8, True) == 0.1 * (0.8 * 0.5 ** 0.2)
    assert ctl.shrink(0.1, 0.0, 1e9, 1e-3, 0.2, 0.1, 0.8, True) == 0.1 * 0.1
    assert ctl.shrink(0.1, 0.0, 2e-3, 1e-3, 0.2, 0.1, 0.8, False) == 0.05
    # growth is at most five-fold (ode45), 1.25 (err/rtol)^p below that
    assert ctl.grow(0.1, 0.0, 1e-3, 0.2, 1.25, 5.0) == 0.5
    assert ctl.grow(0.1, 1e-4, 1e-3, 0.2, 1.25, 5.0) == 0.1 / (1.25 * 0.1 ** 0.2)
    assert ctl.first_step(40.0, 2.0, 0.5, 0.0) == 1 / 40.0
    assert ctl.shrink_after_newton(1.0, 0.0) == 0.3


def test_the_compiled_kernels_compile_the_same_rules():
    pytest.importorskip("numba")
    from odelab.solvers.compiled.cache import load_kernels

    kernels = load_kernels()
    for name, args in RULES:
        python, compiled = getattr(ctl, name)(*args), getattr(kernels, name)(*args)
        assert python == compiled, (name, args)
    assert math.ulp(0.0) * 16 == kernels.min_step(0.0)
