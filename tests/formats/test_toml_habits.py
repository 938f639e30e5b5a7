"""MATLAB habits that run: a state-space system written with MATLAB matrix strings and a range of output times."""

from pathlib import Path

import numpy as np

from odelab.run.runner import run_experiment

EXERCISE2_MATLAB = '''
title = "Exercise 2, written as in MATLAB"
[parameters]
m = 1
k = 3
b = 4
q = 10
[system]
kind = "state-space"
states = ["x", "v"]
inputs = ["f"]
outputs = ["y"]
A = "[0 1; -k/m -b/m]"
B = "[0; 1/m]"
C = "[q 0]"
D = "[0]"
[initial]
x = 0
v = 0
[time]
stop = 15
output = "0:0.1:15"
[inputs.f]
type = "step"
time = 0
'''


def test_matlab_matrix_strings_and_range_run_like_toml_rows(tmp_path: Path):
    matlab = tmp_path / "matlab.toml"
    matlab.write_text(EXERCISE2_MATLAB)
    rows = tmp_path / "rows.toml"
    rows.write_text(EXERCISE2_MATLAB.replace('A = "[0 1; -k/m -b/m]"', 'A = [[0, 1], ["-k/m", "-b/m"]]')
                    .replace('B = "[0; 1/m]"', 'B = [[0], ["1/m"]]').replace('C = "[q 0]"', 'C = [["q", 0]]')
                    .replace('D = "[0]"', "D = [[0]]")
                    .replace('output = "0:0.1:15"', "output = [" + ", ".join(f"{0.1 * i:.1f}" for i in range(151))
                             + "]"))
    (a,), (b,) = run_experiment(matlab), run_experiment(rows)
    assert a.t.size == 151 and a.t[-1] == 15.0
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a.case.problem.system.model.A, [[0, 1], [-3, -4]])
    np.testing.assert_allclose(a.y, b.y, rtol=1e-9, atol=1e-12)
    # the step response of the lab's plant settles at q/k = 10/3, within the tolerance
    assert abs(a.y[-1, 0] - 10 / 3) < 1e-3
    assert a.errors["y"].max_abs < 1e-3
