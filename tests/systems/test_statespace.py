"""StateSpace: matrices, shapes and their messages, names, the system protocol."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from odelab.exceptions import InputError
from odelab.systems.statespace import StateSpace

# The lab's mass-spring-damper, m x'' + b x' + k x = F, m = 1, k = 3, b = 4, measured
# through a sensor of gain q = 10: states (x, v), y = q x.
A_LAB = [[0.0, 1.0], [-3.0, -4.0]]
B_LAB = [[0.0], [1.0]]
C_LAB = [[10.0, 0.0]]
D_LAB = [[0.0]]


@pytest.fixture
def plant() -> StateSpace:
    return StateSpace(A_LAB, B_LAB, C_LAB, D_LAB)


class TestLabPlant:
    def test_matrices_and_sizes(self, plant):
        np.testing.assert_array_equal(plant.A, A_LAB)
        np.testing.assert_array_equal(plant.B, B_LAB)
        np.testing.assert_array_equal(plant.C, C_LAB)
        np.testing.assert_array_equal(plant.D, D_LAB)
        assert (plant.nx, plant.nu, plant.ny) == (2, 1, 1)
        assert all(M.dtype == np.float64 and M.ndim == 2 for M in plant.matrices())

    def test_default_names(self, plant):
        assert plant.states == ("x1", "x2")
        assert plant.inputs == ("u1",)
        assert plant.outputs == ("y1",)
        assert plant.operating_point is None

    def test_dynamics_and_output(self, plant):
        x = np.array([0.5, -2.0])
        u = np.array([3.0])
        # x1' = x2, x2' = -3 x1 - 4 x2 + u; y = 10 x1
        np.testing.assert_array_equal(plant.dynamics(0.0, x, u), [-2.0, -1.5 + 8.0 + 3.0])
        np.testing.assert_array_equal(plant.output(0.0, x, u), [5.0])

    def test_matrices_are_read_only_copies(self):
        A = np.array(A_LAB)
        plant = StateSpace(A, B_LAB, C_LAB, D_LAB)
        A[0, 0] = 99.0
        assert plant.A[0, 0] == 0.0
        with pytest.raises(ValueError):
            plant.A[0, 0] = 1.0
        with pytest.raises(AttributeError):
            plant.A = np.eye(2)
        with pytest.raises(AttributeError):
            plant.foo = 1

    def test_short_forms(self, plant):
        # B as a column list, C as a row list, D as a scalar: the same system
        short = StateSpace(A_LAB, [0, 1], [10, 0], 0)
        assert short == plant
        fractions = StateSpace([[0, 1], [-3, Fraction(-4)]], [0, 1], [10, 0], 0)
        assert fractions == plant

    def test_repr_shows_the_matrices_and_round_trips(self, plant):
        text = repr(plant)
        assert "A=[[ 0.,  1.],\n       [-3., -4.]]" in text
        assert "C=[[10.,  0.]]" in text
        assert "states=('x1', 'x2'), inputs=('u1',), outputs=('y1',)" in text
        assert eval(text, {"StateSpace": StateSpace, "np": np}) == plant

    def test_equality_and_allclose(self, plant):
        assert plant == StateSpace(A_LAB, B_LAB, C_LAB, D_LAB, operating_point="ignored")
        assert plant != StateSpace(A_LAB, B_LAB, C_LAB, D_LAB, states=["x", "v"])
        nudged = StateSpace([[0.0, 1.0], [-3.0, -4.0 + 1e-14]], B_LAB, C_LAB, D_LAB, states=["x", "v"])
        assert nudged != plant
        assert nudged.allclose(plant)
        assert not nudged.allclose(plant, rtol=0, atol=1e-16)
        assert not plant.allclose(StateSpace(A_LAB))  # different shapes
        assert plant != "plant"


class TestDefaults:
    def test_only_A(self):
        sys = StateSpace([[-1.0]])
        assert (sys.nx, sys.nu, sys.ny) == (1, 0, 1)
        assert sys.B.shape == (1, 0) and sys.D.shape == (1, 0)
        np.testing.assert_array_equal(sys.C, [[1.0]])
        assert sys.outputs == sys.states == ("x1",)
        np.testing.assert_array_equal(sys.dynamics(0.0, np.array([2.0]), np.zeros(0)), [-2.0])

    def test_C_none_outputs_are_the_states(self):
        sys = StateSpace(A_LAB, B_LAB, states=["x", "v"])
        np.testing.assert_array_equal(sys.C, np.eye(2))
        np.testing.assert_array_equal(sys.D, np.zeros((2, 1)))
        assert sys.outputs == ("x", "v")

    def test_inputs_named_without_B(self):
        sys = StateSpace(A_LAB, inputs=["F"])
        np.testing.assert_array_equal(sys.B, np.zeros((2, 1)))

    def test_scalar_system(self):
        sys = StateSpace(-2, 1, 3, 0.5)
        assert [M.shape for M in sys.matrices()] == [(1, 1)] * 4
        np.testing.assert_array_equal(sys.output(0, np.array([1.0]), np.array([2.0])), [4.0])

    def test_one_state_reads_1d_B_as_a_row_and_1d_C_as_a_column(self):
        sys = StateSpace([[-1.0]], [1.0, 2.0], [3.0, 4.0, 5.0])
        assert sys.B.shape == (1, 2) and sys.C.shape == (3, 1) and sys.D.shape == (3, 2)

    def test_1d_D(self):
        two_inputs = StateSpace(A_LAB, [[0, 0], [1, 2]], [10, 0], [1, 2])
        np.testing.assert_array_equal(two_inputs.D, [[1.0, 2.0]])
        two_outputs = StateSpace(A_LAB, [0, 1], np.eye(2), [1, 2])
        np.testing.assert_array_equal(two_outputs.D, [[1.0], [2.0]])

    def test_feedthrough_only_input_from_D(self):
        sys = StateSpace(A_LAB, C=[10, 0], D=[[2.0]])
        assert sys.nu == 1
        np.testing.assert_array_equal(sys.B, [[0.0], [0.0]])

    def test_names(self):
        sys = StateSpace(A_LAB, B_LAB, C_LAB, D_LAB, states=["x", "v"], inputs="F", outputs=["y"])
        assert sys.states == ("x", "v") and sys.inputs == ("F",) and sys.outputs == ("y",)

    def test_operating_point_is_stored_as_given(self):
        op = {"x": [1.0, 0.0], "u": [3.0]}
        assert StateSpace(A_LAB, B_LAB, C_LAB, D_LAB, operating_point=op).operating_point is op


def message(**kwargs) -> str:
    with pytest.raises(InputError) as info:
        StateSpace(**kwargs)
    return str(info.value)


class TestShapeMessages:
    def test_B_against_the_named_inputs(self):
        assert message(A=A_LAB, B=np.ones((2, 2)), inputs=["F"]) == (
            "`B` is 2x2 but A is 2x2 and there is 1 input: B must be 2x1"
        )

    def test_B_rows(self):
        assert message(A=A_LAB, B=np.ones((3, 2))) == (
            "`B` is 3x2 but A is 2x2 and there are 2 inputs: B must be 2x2"
        )

    def test_C(self):
        assert message(A=A_LAB, B=B_LAB, C=np.ones((1, 3))) == (
            "`C` is 1x3 but A is 2x2 and there is 1 output: C must be 1x2"
        )
        assert message(A=A_LAB, B=B_LAB, C=np.ones((2, 2)), outputs=["y"]) == (
            "`C` is 2x2 but A is 2x2 and there is 1 output: C must be 1x2"
        )

    def test_D(self):
        assert message(A=A_LAB, B=B_LAB, C=C_LAB, D=np.ones((2, 1))) == (
            "`D` is 2x1 but there is 1 output and 1 input: D must be 1x1"
        )
        assert message(A=A_LAB, B=np.ones((2, 2)), C=np.eye(2), D=[1.0, 2.0, 3.0]) == (
            "`D` is a 1-D array of length 3 but there are 2 outputs and 2 inputs: D must be 2x2"
        )
        assert message(A=A_LAB, B=np.ones((2, 2)), C=np.eye(2), D=5.0).startswith(
            "`D` is the scalar 5.0 but there are 2 outputs and 2 inputs: D must be 2x2"
        )

    def test_A(self):
        assert message(A=np.ones((2, 3))) == "`A` is 2x3: A must be square (n x n)."
        assert message(A=[1.0, 2.0]).startswith("`A` is a 1-D array of length 2: A must be square")
        assert message(A=np.zeros((0, 0))).startswith("`A` is 0x0")
        assert message(A=np.ones((2, 2, 2))).startswith("`A` must be at most 2-D")

    def test_1d_B_and_C_of_the_wrong_length(self):
        assert message(A=A_LAB, B=[0, 1, 2]).startswith(
            "`B` is a 1-D array of length 3 but A is 2x2: a 1-D B is read as one column (one input), "
            "so it must have length 2"
        )
        assert message(A=A_LAB, C=[1, 2, 3]).startswith(
            "`C` is a 1-D array of length 3 but A is 2x2: a 1-D C is read as one row (one output)"
        )

    @pytest.mark.parametrize(
        "kwargs, text",
        [
            ({"A": [[0.0, np.nan], [1.0, 0.0]]}, "`A` must have finite entries; got nan at [0, 1]."),
            ({"A": A_LAB, "B": [0.0, np.inf]}, "`B` must have finite entries; got inf at [1]."),
            ({"A": [[1j]]}, "`A` must be real; got complex entries"),
            ({"A": [["a"]]}, "`A` must be a matrix of real numbers"),
            ({"A": [[1.0, 2.0], [3.0]]}, "`A` must be a matrix of real numbers"),
            ({"A": None}, "`A` must be a matrix of real numbers"),
            ({"A": A_LAB, "C": [[None, 1.0]]}, "`C` must be a matrix of real numbers"),
        ],
    )
    def test_entries(self, kwargs, text):
        assert message(**kwargs).startswith(text)


class TestNameMessages:
    def test_wrong_count(self):
        assert message(A=A_LAB, states=["x"]) == "`states` has 1 name but there are 2 states: give 2 names."
        assert message(A=A_LAB, B=B_LAB, C=C_LAB, outputs=["y", "z"]).startswith("`C` is 1x2")

    def test_outputs_without_C(self):
        assert message(A=A_LAB, outputs=["y"]) == (
            "`outputs` has 1 name but C is not given, so the outputs are the 2 states: give C, "
            "or 2 output names."
        )

    def test_duplicates_and_empty(self):
        assert message(A=A_LAB, states=["x", "x"]) == "`states` must be unique; 'x' appears twice."
        assert message(A=A_LAB, B=B_LAB, inputs=[""]).startswith("`inputs` must be non-empty strings")
        assert message(A=A_LAB, B=B_LAB, inputs=[3]).startswith("`inputs` must be non-empty strings")

    def test_input_error_is_a_value_error_with_a_key(self):
        with pytest.raises(ValueError) as info:
            StateSpace(A_LAB, np.ones((3, 1)))
        assert info.value.key == "B"
