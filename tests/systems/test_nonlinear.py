"""NonlinearSystem: the system protocol, name and shape validation, systems from expressions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odelab.exceptions import InputError
from odelab.systems.nonlinear import NonlinearSystem, as_vector

M, B_DAMP, K1, K3 = 1.0, 4.0, 3.0, 2.0


def spring(t, x, u):
    """Hardening spring m x'' + b x' + k1 x + k3 x^3 = f."""
    return np.array([x[1], (u[0] - B_DAMP * x[1] - K1 * x[0] - K3 * x[0] ** 3) / M])


def spring_system(**kwargs):
    return NonlinearSystem(spring, states=["x", "v"], inputs=["f"], **kwargs)


class TestProtocol:
    def test_sizes_and_names(self):
        sys = spring_system(name="spring")
        assert (sys.nx, sys.nu, sys.ny) == (2, 1, 2)
        assert sys.states == ("x", "v") and sys.inputs == ("f",)
        assert sys.outputs == sys.states  # y = x by default
        assert "spring" in repr(sys)

    def test_dynamics_values(self):
        sys = spring_system()
        dx = sys.dynamics(0.0, np.array([0.5, -1.0]), np.array([2.0]))
        assert dx.shape == (2,)
        assert dx[0] == -1.0
        assert dx[1] == pytest.approx(2.0 + 4.0 - 1.5 - 2.0 * 0.125, abs=1e-15)

    def test_default_output_is_the_state_copy(self):
        sys = spring_system()
        x = np.array([0.5, -1.0])
        y = sys.output(0.0, x, np.array([0.0]))
        np.testing.assert_array_equal(y, x)
        y[0] = 99.0
        assert x[0] == 0.5  # a copy, not a view

    def test_output_function(self):
        sys = NonlinearSystem(spring, lambda t, x, u: [10 * x[0]], states=["x", "v"], inputs=["f"], outputs=["y"])
        assert sys.ny == 1 and sys.outputs == ("y",)
        np.testing.assert_array_equal(sys.output(0.0, np.array([0.25, 3.0]), np.array([0.0])), [2.5])

    def test_no_inputs_accepts_u_none(self):
        sys = NonlinearSystem(lambda t, x, u: -x, states=["x"])
        assert sys.nu == 0
        np.testing.assert_array_equal(sys.dynamics(0.0, np.array([2.0]), None), [-2.0])
        np.testing.assert_array_equal(sys.dynamics(0.0, np.array([2.0]), np.zeros(0)), [-2.0])

    def test_column_vector_is_flattened(self):
        sys = NonlinearSystem(lambda t, x, u: np.array([[x[1]], [-x[0]]]), states=["x", "v"])
        dx = sys.dynamics(0.0, np.array([1.0, 2.0]), None)
        assert dx.shape == (2,)
        np.testing.assert_array_equal(dx, [2.0, -1.0])

    def test_scalar_return_for_one_state(self):
        sys = NonlinearSystem(lambda t, x, u: -2.0 * x[0], states="x")
        assert sys.states == ("x",)
        np.testing.assert_array_equal(sys.dynamics(0.0, np.array([1.5]), None), [-3.0])


class TestValidation:
    def test_wrong_number_of_derivatives(self):
        sys = NonlinearSystem(lambda t, x, u: [x[1], -x[0], 0.0], states=["x", "v"])
        with pytest.raises(InputError) as info:
            sys.dynamics(0.0, np.array([1.0, 0.0]), None)
        assert str(info.value) == "`dynamics` returned 3 values but the system has 2 states (x, v)."
        assert info.value.key == "dynamics"

    def test_wrong_number_of_outputs(self):
        sys = NonlinearSystem(spring, lambda t, x, u: [x[0], x[1]], states=["x", "v"], inputs=["f"], outputs=["y"])
        with pytest.raises(InputError, match=r"`output` returned 2 values but the system has 1 output \(y\)"):
            sys.output(0.0, np.zeros(2), np.zeros(1))

    def test_matrix_return_is_rejected_with_its_shape(self):
        sys = NonlinearSystem(lambda t, x, u: np.zeros((2, 2)), states=["x", "v"])
        with pytest.raises(InputError, match=r"returned 4 values \(shape \(2, 2\)\)"):
            sys.dynamics(0.0, np.zeros(2), None)

    def test_check_catches_bad_shapes_and_non_finite_values(self):
        sys = spring_system()
        sys.check([0.0, 0.0], [1.0])  # fine
        with pytest.raises(InputError, match=r"`x0` has 3 values but the system has 2 states \(x, v\)"):
            sys.check([0.0, 0.0, 0.0], [1.0])
        with pytest.raises(InputError, match=r"`u0` has 2 values but the system has 1 input \(f\)"):
            sys.check([0.0, 0.0], [1.0, 2.0])
        bad = NonlinearSystem(lambda t, x, u: [x[1], math.log(x[0]) if x[0] > 0 else math.nan], states=["x", "v"])
        with pytest.raises(InputError, match="`dynamics` is not finite for v"):
            bad.check([0.0, 0.0])

    @pytest.mark.parametrize(
        "kwargs, match",
        [
            ({"states": []}, "at least one state"),
            ({"states": ["x", ""]}, r"`states\[1\]` must be a non-empty string"),
            ({"states": ["x", "x"]}, "names 'x' twice"),
            ({"states": ["x", 3]}, "non-empty string"),
            ({"states": ["x", "v"], "inputs": ["f", "f"]}, "names 'f' twice"),
            ({"states": ["x", "v"], "inputs": ["v"]}, "'v' is both a state and an input"),
        ],
    )
    def test_bad_names(self, kwargs, match):
        with pytest.raises(InputError, match=match):
            NonlinearSystem(spring, **kwargs)

    def test_outputs_need_an_output_function_and_vice_versa(self):
        with pytest.raises(InputError, match="`outputs` must name the outputs"):
            NonlinearSystem(spring, lambda t, x, u: x, states=["x", "v"], inputs=["f"])
        with pytest.raises(InputError, match="only be the state names"):
            NonlinearSystem(spring, states=["x", "v"], inputs=["f"], outputs=["y"])
        with pytest.raises(InputError, match="`outputs` names 'y' twice"):
            NonlinearSystem(spring, spring, states=["x", "v"], inputs=["f"], outputs=["y", "y"])

    def test_not_callable(self):
        with pytest.raises(InputError, match="`dynamics` must be callable"):
            NonlinearSystem([1, 2], states=["x"])


class TestAsVector:
    def test_forms(self):
        np.testing.assert_array_equal(as_vector(2, ["f"], "u0"), [2.0])
        np.testing.assert_array_equal(as_vector([1, 2], ["x", "v"], "x0"), [1.0, 2.0])
        np.testing.assert_array_equal(as_vector({"v": 2, "x": 1}, ["x", "v"], "x0"), [1.0, 2.0])
        assert as_vector([], [], "u0").shape == (0,)

    def test_errors(self):
        with pytest.raises(InputError, match=r"`x0` has 1 value but the system has 2 states \(x, v\)"):
            as_vector(1.0, ["x", "v"], "x0", word="state")
        with pytest.raises(InputError, match=r"missing \['v'\]"):
            as_vector({"x": 1}, ["x", "v"], "x0", word="state")
        with pytest.raises(InputError, match=r"unknown \['w'\]"):
            as_vector({"x": 1, "v": 0, "w": 2}, ["x", "v"], "x0", word="state")
        with pytest.raises(InputError, match="must be finite"):
            as_vector([1.0, math.inf], ["x", "v"], "x0")
        with pytest.raises(InputError, match="must be numbers"):
            as_vector(["a", "b"], ["x", "v"], "x0")


class TestFromExpressions:
    PARAMS = {"m": M, "b": B_DAMP, "k1": K1, "k3": K3}

    def make(self, **kwargs):
        return NonlinearSystem.from_expressions(
            {"x": "v", "v": "(f - b*v - k1*x - k3*x^3) / m"}, inputs=["f"], parameters=self.PARAMS, **kwargs
        )

    def test_matches_the_python_function(self):
        sys = self.make()
        assert sys.states == ("x", "v") and sys.inputs == ("f",) and sys.outputs == ("x", "v")
        rng = np.random.default_rng(1)
        for _ in range(20):
            x, u, t = rng.normal(size=2), rng.normal(size=1), rng.uniform(0, 5)
            np.testing.assert_allclose(sys.dynamics(t, x, u), spring(t, x, u), rtol=1e-14, atol=1e-14)
        assert sys.equations == {"x": "v", "v": "(f - b*v - k1*x - k3*x^3) / m"}
        assert sys.parameters == self.PARAMS

    def test_outputs_and_time(self):
        sys = NonlinearSystem.from_expressions(
            {"x": "v", "v": "-k*x + sin(t)"}, outputs={"y": "10*x", "e": "x - v"}, parameters={"k": 3}
        )
        assert sys.outputs == ("y", "e") and sys.nu == 0
        np.testing.assert_allclose(sys.output(0.0, np.array([0.5, 0.25]), np.zeros(0)), [5.0, 0.25])
        np.testing.assert_allclose(sys.dynamics(1.0, np.array([0.5, 0.25]), None), [0.25, -1.5 + math.sin(1.0)])

    def test_complex_step_variant_is_kept(self):
        sys = self.make()
        assert sys.complex_step_dynamics is not None
        x = np.array([0.5 + 1e-20j, 0.0])
        f = np.asarray(sys.complex_step_dynamics(0.0, x, np.array([0.0])))
        # d(x')/dx = -(k1 + 3 k3 x^2) / m, exactly
        assert f.imag[1] / 1e-20 == pytest.approx(-(K1 + 3 * K3 * 0.25) / M, rel=1e-15)

    def test_errors_are_located(self):
        with pytest.raises(InputError) as info:
            NonlinearSystem.from_expressions({"x": "v", "v": "-k*x +"}, parameters={"k": 1.0}, source="lab.toml")
        assert info.value.key == "system.equations.v"
        assert info.value.source == "lab.toml"
        with pytest.raises(InputError) as info:
            NonlinearSystem.from_expressions({"x": "-x"}, outputs={"y": "2*nope"})
        assert info.value.key == "system.outputs.y"

    def test_bad_definitions(self):
        with pytest.raises(InputError, match="must map each state name"):
            NonlinearSystem.from_expressions({})
        with pytest.raises(InputError, match="parameter 'x' has the name of a state") as info:
            NonlinearSystem.from_expressions({"x": "-k*x"}, parameters={"x": 1.0})
        assert info.value.key == "system.parameters.x"
        with pytest.raises(InputError, match="must be a number"):
            NonlinearSystem.from_expressions({"x": "-k*x"}, parameters={"k": "fast"})
        with pytest.raises(InputError, match="cannot be named `t`"):
            NonlinearSystem.from_expressions({"t": "1"})
