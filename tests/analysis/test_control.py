"""Control analysis: stepinfo against closed forms, python-control and MATLAB; Bode against G(jw)."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from odelab import StateSpace
from odelab.analysis import control as ctl

PLANT = StateSpace([[0, 1], [-3, -4]], [[0], [1]], [[10, 0]], [[0]], states=["x", "v"], inputs=["f"],
                   outputs=["y"])  # Exercise 2: G = 10 / (s^2 + 4 s + 3)


def plant_step(t):
    return 10 / 3 * (1 - 1.5 * np.exp(-t) + 0.5 * np.exp(-3 * t))


def test_stepinfo_of_exercise2_against_matlab_definitions_in_closed_form():
    s = ctl.stepinfo(PLANT)[("y", "f")]
    yf = 10 / 3
    t10 = brentq(lambda t: plant_step(t) - 0.1 * yf, 0, 5)
    t90 = brentq(lambda t: plant_step(t) - 0.9 * yf, 0, 10)
    ts = brentq(lambda t: yf - plant_step(t) - 0.02 * yf, 0, 20)  # monotone: the error falls through 2 %
    assert s.rise_time == pytest.approx(t90 - t10, rel=1e-6)
    assert s.settling_time == pytest.approx(ts, rel=1e-6)
    assert s.transient_time == pytest.approx(ts, rel=1e-6)  # max |y - yfinal| = yfinal, at t = 0
    assert s.overshoot == 0 and s.undershoot == 0
    assert s.peak == pytest.approx(yf, rel=1e-15) and s.peak_time == math.inf  # approached, never reached
    assert s.steady_state == pytest.approx(yf, rel=1e-15)
    assert s.settling_min == pytest.approx(0.9 * yf, rel=1e-5) and s.settling_max < yf


def test_stepinfo_against_python_control_step_info_on_the_same_grid():
    import control

    for sys in (PLANT, ctl.tf2ss([8, 18, 32], [1, 6, 14, 24]), ctl.tf2ss([-1, 1], [1, 1, 1])):
        t = np.linspace(0, 20, 20001)
        y = ctl.step_response(sys, t, 0)[:, 0]
        ours = ctl.step_metrics(t, y, float(ctl.dcgain(sys)[0, 0]))
        theirs = control.step_info(y, t, yfinal=float(ctl.dcgain(sys)[0, 0]))
        h = t[1]
        # python-control takes the first sample past each level; we interpolate between samples.
        assert abs(ours.rise_time - theirs["RiseTime"]) <= 2 * h
        assert abs(ours.settling_time - theirs["SettlingTime"]) <= 2 * h
        assert ours.overshoot == pytest.approx(theirs["Overshoot"], abs=1e-4)
        assert ours.undershoot == pytest.approx(theirs["Undershoot"], abs=1e-4)
        if math.isfinite(ours.peak_time):  # a monotone response's supremum is only approached
            assert abs(ours.peak_time - theirs["PeakTime"]) <= h and ours.peak >= theirs["Peak"]


def test_stepinfo_matches_matlabs_published_example():
    # MathWorks, "Numeric Values of Time-Domain System Characteristics": H = tf([8 18 32],[1 6 14 24])
    # gives RiseTime 0.2087, SettlingTime 3.4972 (0.5 %: 4.8896), SettlingMin 1.1956, SettlingMax 1.6871,
    # Overshoot 26.5302, Peak 1.6871, PeakTime 0.5987 -- MATLAB's peak is its grid's best sample.
    H = ctl.tf2ss([8, 18, 32], [1, 6, 14, 24])
    s = next(iter(ctl.stepinfo(H).values()))
    assert round(s.rise_time, 4) == 0.2087 and abs(s.settling_time - 3.4972) < 1e-4
    assert round(s.settling_min, 4) == 1.1956 and s.undershoot == 0
    # 0.5 %: MATLAB's 4.8896 comes from its coarser grid; ours is the crossing to ~1e-7.
    assert abs(next(iter(ctl.stepinfo(H, settling_threshold=0.005).values())).settling_time - 4.8896) < 3e-4
    # The exact peak lies above MATLAB's sampled one, by less than 0.01 %:
    assert 1.6871 <= s.peak <= 1.6871 * 1.0001 and 26.5302 <= s.overshoot <= 26.56
    assert abs(s.peak_time - 0.5987) < 0.015
    # ... and is the true maximum: y'(t) = 0 there (impulse response of H crosses zero).
    t = np.linspace(s.peak_time - 1e-3, s.peak_time + 1e-3, 3)
    y = ctl.step_response(H, np.linspace(0, s.peak_time + 1e-3, 2001), 0)[:, 0]
    assert np.max(y) <= s.peak + 1e-12 and t[1] == pytest.approx(s.peak_time)


def test_bode_against_g_of_jw_computed_directly():
    fr = ctl.bode(PLANT, 0.01, 100, 301)
    G = np.array([(PLANT.C @ np.linalg.solve(1j * w * np.eye(2) - PLANT.A, PLANT.B) + PLANT.D)[0, 0] for w in fr.w])
    np.testing.assert_allclose(fr.magnitude_db[0, 0], 20 * np.log10(np.abs(G)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(fr.phase_deg[0, 0], np.degrees(np.unwrap(np.angle(G))), rtol=0, atol=1e-10)
    assert fr.w[0] == 0.01 and fr.w[-1] == pytest.approx(100) and fr.phase_deg[0, 0, -1] < -170


def test_margins_against_the_crossover_in_closed_form():
    m = ctl.margins(PLANT)[("y", "f")]
    wc = brentq(lambda w: abs(10 / ((1j * w) ** 2 + 4j * w + 3)) - 1, 0.1, 10)
    pm = 180 + np.degrees(np.angle(10 / ((1j * wc) ** 2 + 4j * wc + 3)))
    assert m["gain_crossover"] == pytest.approx(wc, rel=1e-9) and m["phase_margin"] == pytest.approx(pm, rel=1e-9)
    assert m["gain_margin"] == math.inf  # a second-order lag never reaches -180 degrees


def test_transfer_functions_poles_zeros_damping():
    G = ctl.ss2tf(PLANT)
    np.testing.assert_allclose(G.num[0][0], [10.0]) and np.testing.assert_allclose(G.den[0][0], [1, 4, 3])
    assert ctl.tf_text(G.num[0][0], G.den[0][0]) == ("10", "s^2 + 4 s + 3")
    assert ctl.poles(PLANT).tolist() == [-3, -1]
    assert [(r["wn"], r["zeta"]) for r in ctl.damp(PLANT)] == [(1.0, 1.0), (3.0, 1.0)]
    assert ctl.dcgain(PLANT).tolist() == [[pytest.approx(10 / 3, rel=1e-15)]]
    H = ctl.tf2ss([1, 3], [1, 3, 2])
    assert H.A.tolist() == [[-3, -2], [1, 0]] and H.C.tolist() == [[1, 3]]  # MATLAB's tf2ss
    assert ctl.zeros(H)[("y1", "u1")].tolist() == [-3]
    under = ctl.tf2ss([6], [1, 2, 6])
    r = ctl.damp(under)
    assert r[0]["wn"] == pytest.approx(math.sqrt(6)) and r[0]["zeta"] == pytest.approx(1 / math.sqrt(6))
    with pytest.raises(ValueError, match="`den` must have a nonzero coefficient"):
        ctl.tf([1], [0, 0])


def test_stepinfo_refuses_a_nonlinear_system():
    from odelab import NonlinearSystem

    nl = NonlinearSystem(lambda t, x, u: -x ** 3 + u, states=["x"], inputs=["u"])
    with pytest.raises(ValueError, match="linearise a nonlinear system first"):
        ctl.stepinfo(nl)
