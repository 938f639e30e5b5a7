"""MATLAB habits in the expression language: matrix strings, ranges, and the hints (expressions/matlab.py)."""

import numpy as np
import pytest

from odelab.expressions.matlab import colon_range, range_parts, split_matrix


@pytest.mark.parametrize("text, rows", [
    ("[0 1; -k/m -b/m]", [["0", "1"], ["-k/m", "-b/m"]]),
    ("[0, 1; -3, -4]", [["0", "1"], ["-3", "-4"]]),
    ("[a - b c]", [["a - b", "c"]]),         # a binary minus with spaces both sides
    ("[a -b]", [["a", "-b"]]),               # MATLAB: a space, then a sign: a new element
    ("[a-b]", [["a-b"]]),
    ("[2 * k  sin(w * t)]", [["2 * k", "sin(w * t)"]]),
    ("[q 0]", [["q", "0"]]),
    ("[0; 1/m]", [["0"], ["1/m"]]),
    ("[1 2\n 3 4]", [["1", "2"], ["3", "4"]]),  # rows on lines, as in an m-file
])
def test_matlab_matrix_strings_split_as_matlab_does(text, rows):
    assert split_matrix(text) == rows


def test_a_ragged_matrix_names_the_row():
    with pytest.raises(ValueError, match="row 2 has 1 elements but row 1 has 2"):
        split_matrix("[0 1; 3]")


def test_ranges_expand_as_matlab_colon():
    assert range_parts("0:0.1:15") == ("0", "0.1", "15")
    assert range_parts("[0:0.1:15]") == ("0", "0.1", "15")
    assert range_parts("0:5") == ("0", "1", "5")
    assert range_parts("2*pi") is None and range_parts("a:b:c:d") is None
    t = colon_range(0.0, 0.1, 15.0)
    assert t.size == 151 and t[0] == 0.0 and t[-1] == 15.0  # snapped: 150*0.1 is 15.000000000000002
    np.testing.assert_allclose(np.diff(t), 0.1, rtol=1e-12)
    assert colon_range(0.0, 0.3, 1.0).tolist() == pytest.approx([0.0, 0.3, 0.6, 0.9])  # stops short, as MATLAB
    assert colon_range(10.0, -2.5, 0.0).tolist() == [10.0, 7.5, 5.0, 2.5, 0.0]
    assert colon_range(0.0, 1.0, -1.0).size == 0
