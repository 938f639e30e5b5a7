"""Every block type against a closed form, through the Python API (odelab.diagram)."""

import numpy as np
import pytest

from odelab import diagram as dg
from odelab.signals import Constant, Sine, Step

T = np.linspace(0, 3, 31)
TIGHT = {"rtol": 1e-10, "atol": 1e-12}


def run(blocks, outputs, **kw):
    c = dg.Diagram(blocks, outputs, **{k: v for k, v in kw.items() if k == "states"}).compile()
    r = c.simulate(T, method="ode45", **TIGHT)
    assert r.status == "success", r.message
    return c, r


def test_gain_sum_integrator_step_ramp_and_feedthrough():
    c, r = run({"u": Step(time=0, final=2.0), "c": Constant(1.0),
                "s": dg.Sum(signs="+-", inputs=["u", "c"]),          # 2 - 1 = 1
                "g": dg.Gain(gain=3.0, input="s"),                   # 3
                "i": dg.Integrator(input="g", initial=0.5)},         # 0.5 + 3 t
               {"y": "i", "g": "g"})
    assert c.linear and type(c.system).__name__ == "StateSpace"
    np.testing.assert_allclose(r.y[:, 0], 0.5 + 3 * T, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(r.y[:, 1], 3.0)
    A, B, C, D = c.matrices()
    assert A.tolist() == [[0.0]] and B.tolist() == [[3.0, -3.0]] and D.tolist() == [[0, 0], [3.0, -3.0]]


def test_matrix_gain_mux_demux():
    c, r = run({"t": dg.Clock(), "one": Constant(1.0), "m": dg.Mux(inputs=["t", "one"]),
                "k": dg.Gain(gain=[[1.0, 2.0], [3.0, 4.0]], input="m"), "d": dg.Demux(outputs=2, input="k"),
                "i": dg.Integrator(input="d.2", initial=0.0)},
               {"a": "d.1", "b": "d.2", "x": "i"})
    np.testing.assert_allclose(r.y[:, 0], T + 2, atol=1e-13)
    np.testing.assert_allclose(r.y[:, 1], 3 * T + 4, atol=1e-13)
    np.testing.assert_allclose(r.y[:, 2], 1.5 * T**2 + 4 * T, atol=1e-11)  # exact LTI of a ramp input


def test_product_and_fcn_against_their_integrals():
    # x' = t * t -> t^3/3;  z' = sin(t) -> 1 - cos(t);  w' = t / 2 via ops "*/"
    c, r = run({"t": dg.Clock(), "two": Constant(2.0), "p": dg.Product(inputs=["t", "t"]),
                "q": dg.Product(ops="*/", inputs=["t", "two"]),
                "f": dg.Fcn(expression="sin(u)", input="t"), "x": dg.Integrator(input="p"),
                "z": dg.Integrator(input="f"), "w": dg.Integrator(input="q")},
               {"x": "x", "z": "z", "w": "w"})
    assert not c.linear
    np.testing.assert_allclose(r.y[:, 0], T**3 / 3, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(r.y[:, 1], 1 - np.cos(T), rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(r.y[:, 2], T**2 / 4, rtol=1e-9, atol=1e-11)


def test_fcn_of_several_inputs_uses_u1_u2_and_parameters():
    f = dg.Fcn(expression="a*u1 - u2", inputs=["x", "y"], parameters={"a": 3.0})
    c = dg.Diagram({"x": Constant(2.0), "y": Constant(1.0), "f": f, "i": dg.Integrator(input="f")},
                   {"f": "f", "i": "i"}).compile()
    assert c.output(0.0, [0.0], [2.0, 1.0]).tolist() == [5.0, 0.0]


def test_saturation_and_dead_zone_against_their_definitions():
    c = dg.Diagram({"u": Sine(amplitude=2.0, frequency=1.0), "s": dg.Saturation(lower=-1, upper=0.5, input="u"),
                    "d": dg.DeadZone(lower=-0.5, upper=1.0, input="u"), "i": dg.Integrator(input="s")},
                   {"s": "s", "d": "d", "i": "i"}).compile()
    u = 2 * np.sin(T)
    y = c.output_many(T, np.zeros((T.size, 1)), u[:, None])[:, :2]
    np.testing.assert_array_equal(y[:, 0], np.clip(u, -1, 0.5))
    np.testing.assert_array_equal(y[:, 1], np.where(u > 1, u - 1, np.where(u < -0.5, u + 0.5, 0.0)))
    # Defaults as Simulink's: [-0.5, 0.5].
    assert (dg.Saturation(input="u").lo, dg.Saturation(input="u").hi) == (-0.5, 0.5)


def test_saturating_integrator_holds_at_its_limits():
    # x' = 1 from 0 with upper = 1: x = min(t, 1); then x' = -1 (step at 2) down to lower = 0.5.
    c, r = run({"u": Step(time=2.0, initial=1.0, final=-1.0),
                "x": dg.Integrator(input="u", initial=0.0, lower=0.5 - 0.5, upper=1.0)},
               {"x": "x"})
    expect = np.where(T < 2, np.minimum(T, 1.0), np.maximum(1.0 - (T - 2), 0.0))
    np.testing.assert_allclose(r.y[:, 0], expect, atol=1e-6)
    assert not c.linear  # a limited integrator is nonlinear


def test_transfer_fcn_step_responses_and_matlab_tf2ss_form():
    # (s+3)/(s^2+3s+2): step -> 1.5 - 2 e^-t + 0.5 e^-2t;  (s+2)/(s+1): 2 - e^-t (direct feedthrough)
    c, r = run({"u": Step(time=0), "g": dg.TransferFcn(num=[1, 3], den=[1, 3, 2], input="u"),
                "h": dg.TransferFcn(num=[1, 2], den=[1, 1], input="u")},
               {"g": "g", "h": "h"})
    np.testing.assert_allclose(r.y[:, 0], 1.5 - 2 * np.exp(-T) + 0.5 * np.exp(-2 * T), atol=1e-14)
    np.testing.assert_allclose(r.y[1:, 1], 2 - np.exp(-T[1:]), atol=1e-14)
    g = c.wiring.blocks["g"]
    assert g.A.tolist() == [[-3.0, -2.0], [1.0, 0.0]] and g.C.tolist() == [[1.0, 3.0]]  # MATLAB's tf2ss
    assert not g.feedthrough and c.wiring.blocks["h"].feedthrough


def test_state_space_block_outputs_by_name_and_initial_state():
    # x' = -x + u, y = x, z = 2x + u, x(0) = 1, u = 1: x = 1 for all t, z = 3.
    c, r = run({"u": Step(time=0), "p": dg.StateSpace(A=-1, B=1, C=[[1], [2]], D=[[0], [1]], initial=[1.0],
                                                          outputs=["y", "z"], input="u"),
                "i": dg.Integrator(input="p.z")},
               {"y": "p.y", "z": "p.z", "i": "i"})
    assert c.states == ("p.x1", "i")
    np.testing.assert_allclose(r.y[:, :2], np.column_stack([np.ones_like(T), 3 * np.ones_like(T)]), atol=1e-14)
    np.testing.assert_allclose(r.y[:, 2], 3 * T, atol=1e-12)


def test_every_source_is_the_signal_it_wraps():
    sig = Sine(amplitude=2.0, frequency=3.0, phase=0.1)
    c = dg.Diagram({"s": sig, "i": dg.Integrator(input="s")}, {"s": "s", "i": "i"}).compile()
    assert c.signals == (sig,) and c.inputs == ("s",)
    np.testing.assert_array_equal(c.output_many(T, np.zeros((T.size, 1)), sig(T)[:, None])[:, 0], sig(T))


def test_block_key_errors_name_the_key():
    with pytest.raises(dg.BlockError, match=r"`signs` is '\+-' \(2 signs\) but there are 3 inputs"):
        dg.Sum(signs="+-", inputs=["a", "b", "c"])
    with pytest.raises(dg.BlockError, match="`gian` does not apply to a gain block; it takes input, inputs, gain"):
        dg.Gain(gian=2, input="a")
    with pytest.raises(dg.BlockError, match="a gain block takes 1 input; got 2"):
        dg.Gain(gain=2, inputs=["a", "b"])
    with pytest.raises(dg.BlockError, match=r"improper \(num has degree 2, den degree 1\)"):
        dg.TransferFcn(num=[1, 0, 0], den=[1, 1], input="a")
    with pytest.raises(dg.BlockError, match=r"`initial` \(2\.0\) is outside the limits \[0, 1\]"):
        dg.Integrator(input="a", initial=2.0, lower=0, upper=1)
