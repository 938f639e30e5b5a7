"""Algebraic loops solved by Newton's method, and lookup tables against numpy/scipy interpolation."""

import numpy as np
import pytest
from scipy.interpolate import CubicSpline, RegularGridInterpolator

from odelab import diagram as dg
from odelab.signals import Ramp, Step, Table, interpolate_1d, interpolate_2d
from odelab.systems.diagram.compile import AlgebraicLoopError
from odelab.systems.diagram.tables import LookupTable

EPS = np.finfo(float).eps
BP = np.array([0.0, 0.5, 1.2, 2.0, 3.0])
TB = np.array([1.0, -0.5, 2.0, 0.3, 0.8])


@pytest.mark.parametrize("a", [3.0, 0.25, -0.5])
def test_the_loop_y_equals_u_minus_a_y_is_u_over_one_plus_a(a):
    d = dg.Diagram({"u": Step(time=0, final=2.0), "y": dg.Sum(signs="+-", inputs=["u", "ay"]),
                    "ay": dg.Gain(gain=a, input="y"), "q": dg.Integrator(input="y")}, {"y": "y", "q": "q"})
    c = d.compile()
    assert c.wiring.loops == ("y -> ay -> y",) and len(c.notes) == 1 and "y -> ay -> y" in c.notes[0]
    assert c.linear and abs(c.system.D[0, 0] - 1 / (1 + a)) <= 4 * EPS  # the linear model, exactly
    r = c.simulate([0, 1])
    np.testing.assert_allclose(r.y[:, 0], 2 / (1 + a), rtol=8 * EPS)
    np.testing.assert_allclose(r.y[:, 1], 2 * r.t / (1 + a), rtol=1e-12, atol=1e-14)
    with pytest.raises(dg.DiagramError, match="algebraic loop: y -> ay -> y"):
        d.compile(algebraic_loops="error")
    assert d.compile(algebraic_loops="none").notes == []


def test_a_nonlinear_loop_is_solved_and_fails_clearly_where_its_solution_ends():
    # z = t + z^2: z = (1 - sqrt(1 - 4t))/2 for t <= 1/4, no real solution after
    d = dg.Diagram({"c": dg.Clock(), "f": dg.Fcn(expression="u^2", input="z"),
                    "z": dg.Sum(signs="++", inputs=["c", "f"]), "q": dg.Integrator(input="z")}, {"z": "z", "q": "q"})
    c = d.compile()
    t = np.array([0.0, 0.1, 0.2, 0.24])
    got = [c.output(ti, [0.0], [ti])[0] for ti in t]
    np.testing.assert_allclose(got, (1 - np.sqrt(1 - 4 * t)) / 2, rtol=1e-12)
    with pytest.warns(Warning):
        r = c.simulate([0, 1])
    assert r.status == "failed" and "algebraic loop f -> z -> f" in r.message and "no solution" in r.message
    assert 0.2 <= r.t[-1] <= 0.25 and r.t.size > 2  # the partial results up to the failure
    with pytest.raises(AlgebraicLoopError, match="singular"):
        dg.Diagram({"u": Step(), "y": dg.Sum(signs="++", inputs=["u", "y"]), "q": dg.Integrator(input="y")},
                   {"q": "q"}).compile().system  # y = u + y: no solution for u != 0


@pytest.mark.parametrize("interpolation", ["linear", "flat", "nearest", "cubic-spline"])
@pytest.mark.parametrize("extrapolation", ["clip", "linear"])
def test_1d_interpolation_against_numpy_and_scipy(interpolation, extrapolation):
    q = np.linspace(-1, 4, 2001)
    got = interpolate_1d(q, BP, TB, interpolation, extrapolation)
    inside = (q >= BP[0]) & (q <= BP[-1])
    if interpolation == "linear":
        ref = np.interp(q, BP, TB)
    elif interpolation == "cubic-spline":
        ref = CubicSpline(BP, TB)(q)  # not-a-knot, MATLAB's spline
    elif interpolation == "flat":
        ref = TB[np.clip(np.searchsorted(BP, q, side="right") - 1, 0, BP.size - 1)]
    else:
        ref = TB[np.clip(np.searchsorted(0.5 * (BP[1:] + BP[:-1]), q, side="right"), 0, BP.size - 1)]
    np.testing.assert_allclose(got[inside], ref[inside], rtol=0, atol=8 * EPS)
    lo, hi = q < BP[0], q > BP[-1]
    if extrapolation == "clip":
        assert np.all(got[lo] == TB[0]) and np.all(got[hi] == TB[-1])
    elif interpolation == "cubic-spline":
        cs = CubicSpline(BP, TB)
        np.testing.assert_allclose(got[hi], TB[-1] + cs(BP[-1], 1) * (q[hi] - BP[-1]), rtol=1e-14, atol=1e-14)
    else:
        np.testing.assert_allclose(got[hi], TB[-1] + (TB[-1] - TB[-2]) / (BP[-1] - BP[-2]) * (q[hi] - BP[-1]),
                                   rtol=1e-14)


@pytest.mark.parametrize("interpolation, exact", [
    ("linear", 3.92), ("flat", 3.85), ("nearest", 3.92),
    ("cubic-spline", float(CubicSpline(BP, TB).integrate(0, 3)) + TB[0] + TB[-1])])
def test_a_ramp_through_a_lookup_table_integrates_to_the_tables_integral(interpolation, exact):
    # the table's corners and jumps are located: the integral is exact to round-off on each piece
    d = dg.Diagram({"r": Ramp(slope=1.0, start=-1.0, initial=-1.0),
                    "lt": LookupTable(breakpoints=BP.tolist(), table=TB.tolist(), interpolation=interpolation, input="r"),
                    "i": dg.Integrator(input="lt")}, {"y": "lt", "i": "i"}).compile(t0=-1.0)
    r = d.simulate([-1, 4], rtol=1e-3)
    assert abs(r.y[-1, 1] - exact) <= 64 * EPS * 4
    assert len(r.crossings["lt"]) == (4 if interpolation == "nearest" else 5)


def test_2d_lookup_against_scipy_and_key_checks():
    b1, b2 = np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 3.0, 4.0])
    T = np.arange(12.0).reshape(3, 4) ** 1.5
    pts = np.random.default_rng(1).uniform([0, 0], [2, 4], (200, 2))
    for method in ("linear", "nearest"):
        ref = RegularGridInterpolator((b1, b2), T, method=method)(pts)
        np.testing.assert_allclose(interpolate_2d(pts[:, 0], pts[:, 1], b1, b2, T, method), ref, rtol=0,
                                   atol=64 * EPS * T.max())
    lt = LookupTable(breakpoints1=b1.tolist(), breakpoints2=b2.tolist(), table=T.tolist(), inputs=["a", "b"])
    assert lt.dims == 2 and not lt.zero_crossing
    with pytest.raises(dg.BlockError, match="interpolation"):
        LookupTable(breakpoints=[0, 1], table=[0, 1], interpolation="cubic", input="u")
    with pytest.raises(dg.BlockError, match="strictly increase"):
        LookupTable(breakpoints=[0, 1, 1], table=[0, 1, 2], input="u")
    with pytest.raises(dg.BlockError, match="one finite value per breakpoint"):
        LookupTable(breakpoints=[0, 1, 2], table=[0, 1], input="u")


def test_the_table_signal_takes_the_same_interpolation_and_extrapolation():
    t, v = [0.0, 1.0, 2.0], [0.0, 1.0, 0.0]
    held = Table(t, v, interpolation="flat")
    assert held(np.array([0.0, 0.5, 1.0, 1.5, 2.0, 3.0])).tolist() == [0, 0, 1, 1, 0, 0]
    assert held.breakpoints(-1, 5).tolist() == [1.0, 2.0] and held.exact_terms() is None
    line = Table(t, v, extrapolation="linear")
    assert line(np.array([-1.0, 3.0])).tolist() == [-1.0, -1.0] and line.breakpoints(-5, 5).tolist() == [1.0]
    # the exact form of a linearly extrapolated table continues its end segments
    form = line.exact_terms()
    assert form is not None
    with pytest.raises(Exception, match="interpolation"):
        Table(t, v, interpolation="spline")
