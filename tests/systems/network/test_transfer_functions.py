"""Transfer functions derived from networks against the textbook's closed forms, compared with
python-control: the same frequency response (to round-off in units of its magnitude) and the
same order (the derivation keeps no superfluous state)."""

import numpy as np
import pytest

pytest.importorskip("sympy")
control = pytest.importorskip("control")

from odelab.network import (  # noqa: E402
    Capacitor, CurrentSource, Damper, DCMotor, ForceSource, Gear, Inductor, Inertia, Lever, Mass, Network,
    Resistor, RotationalDamper, Spring, VelocitySource, VoltageSource,
)

W = np.logspace(-2, 3, 41)  # rad/s


def derived(net, output, inp):
    sys = net.compile()
    assert type(sys).__name__ == "StateSpace"
    i, j = sys.outputs.index(output), sys.inputs.index(inp)
    return control.ss(sys.A, sys.B[:, [j]], sys.C[[i], :], sys.D[[i], [j]])


def assert_same_response(ss, tf, order):
    assert ss.nstates == order
    a = np.squeeze(ss(1j * W))
    b = np.squeeze(tf(1j * W))
    # round-off of the two evaluations, relative to the response's magnitude at each frequency
    assert np.max(np.abs(a - b) / np.abs(b)) < 1e-9
    # the same poles once both are minimal (a state an output does not see cancels)
    p1 = control.minreal(control.ss2tf(ss), verbose=False).poles()
    p2 = control.minreal(tf, verbose=False).poles()
    np.testing.assert_allclose(np.sort_complex(p1), np.sort_complex(p2), rtol=1e-7, atol=1e-7)


def test_series_rlc_capacitor_voltage():
    R, L, C = 2.0, 0.5, 0.1
    net = Network({"V": VoltageSource(nodes=["a", "ground"], value="u"), "R1": Resistor(nodes=["a", "b"], R="R"),
                   "L1": Inductor(nodes=["b", "c"], L="L"), "C1": Capacitor(nodes=["c", "ground"], C="C")},
                  outputs={"vC": "C1.v", "i": "L1.i"}, parameters={"R": R, "L": L, "C": C})
    assert net.states == ("C1.v", "L1.i")
    s = control.tf("s")
    assert_same_response(derived(net, "vC", "u"), 1 / (L * C * s**2 + R * C * s + 1), 2)
    assert_same_response(derived(net, "i", "u"), C * s / (L * C * s**2 + R * C * s + 1), 2)


def test_parallel_rlc_driven_by_a_current_source():
    R, L, C = 5.0, 0.2, 0.01
    net = Network([CurrentSource("I", nodes=["a", "ground"], value="i_in"), Resistor("R1", nodes=["a", "ground"], R=R),
                   Inductor("L1", nodes=["a", "ground"], L=L), Capacitor("C1", nodes=["a", "ground"], C=C)],
                  outputs={"v": "C1.v", "iL": "L1.i"})
    s = control.tf("s")
    Z = L * s / (L * C * s**2 + (L / R) * s + 1)  # 1/(C s + 1/R + 1/(L s))
    assert_same_response(derived(net, "v", "i_in"), Z, 2)
    assert_same_response(derived(net, "iL", "i_in"), Z / (L * s), 2)


def test_quarter_car_body_displacement_from_the_road():
    ms, mu, ks, bs, kt = 250.0, 35.0, 16000.0, 1000.0, 160000.0
    net = Network({"body": Mass(node="s", m="ms"), "suspension": Spring(nodes=["s", "u"], k="ks"),
                   "shock": Damper(nodes=["s", "u"], b="bs"), "wheel": Mass(node="u", m="mu"),
                   "tyre": Spring(nodes=["u", "r"], k="kt"), "road": VelocitySource(nodes=["r", "ground"], value="vr")},
                  outputs={"body": "body.x"}, parameters=dict(ms=ms, mu=mu, ks=ks, bs=bs, kt=kt))
    s = control.tf("s")
    # X_s/X_r = kt (bs s + ks) / [ms mu s^4 + (ms + mu) bs s^3 + (ms (ks + kt) + mu ks) s^2 + bs kt s + ks kt],
    # and the road is given by its velocity: X_r = V_r / s
    den = ms * mu * s**4 + (ms + mu) * bs * s**3 + (ms * (ks + kt) + mu * ks) * s**2 + bs * kt * s + ks * kt
    assert_same_response(derived(net, "body", "vr"), kt * (bs * s + ks) / den / s, 5)


def test_dc_motor_with_gear_and_load():
    Ra, La, K, Jm, bm, n, JL, bL = 1.0, 0.5, 0.05, 1e-4, 1e-5, 10.0, 0.01, 1e-3
    net = Network({"V": VoltageSource(nodes=["a", "ground"], value="v_in"), "Ra": Resistor(nodes=["a", "b"], R=Ra),
                   "La": Inductor(nodes=["b", "c"], L=La),
                   "motor": DCMotor(nodes=["c", "ground"], nodes2=["m", "ground"], K=K),
                   "rotor": Inertia(node="m", J=Jm), "bearing": RotationalDamper(nodes=["m", "ground"], b=bm),
                   "gear": Gear(nodes=["m", "ground"], nodes2=["l", "ground"], n=n),
                   "load": Inertia(node="l", J=JL), "friction": RotationalDamper(nodes=["l", "ground"], b=bL)},
                  outputs={"w": "load.w"})
    d = net.derive()
    assert d.states == ("rotor.theta", "rotor.w", "La.i")  # the load's inertia is reduced through the gear
    assert any(note.startswith("load and rotor are joined by gear: load.w = ") for note in d.state_notes)
    s = control.tf("s")
    Jeq, beq = Jm + JL / n**2, bm + bL / n**2  # the load reflected to the motor's side
    G = (K / n) / ((La * s + Ra) * (Jeq * s + beq) + K**2)
    ss = derived(net, "w", "v_in")
    # the rotor's angle is a state the speed does not see: a pole at 0 that the output cancels
    assert_same_response(ss, G, 3)


def test_a_lever_reflects_the_spring_by_its_ratio_squared():
    m, b, k, n = 2.0, 3.0, 50.0, 4.0
    net = Network({"mass": Mass(node="a", m=m), "damper": Damper(nodes=["a", "ground"], b=b),
                   "push": ForceSource(nodes=["a", "ground"], value="F"),
                   "lever": Lever(nodes=["a", "ground"], nodes2=["c", "ground"], n=n),
                   "spring": Spring(nodes=["c", "ground"], k=k)},
                  outputs={"xa": "mass.x", "xc": "spring.x"})
    s = control.tf("s")
    G = 1 / (m * s**2 + b * s + k / n**2)
    assert_same_response(derived(net, "xa", "F"), G, 2)
    assert_same_response(derived(net, "xc", "F"), G / n, 2)


def test_a_spring_in_series_with_a_damper_has_its_stretch_as_a_state():
    m, k, b = 1.5, 40.0, 6.0
    net = Network({"mass": Mass(node="a", m=m), "push": ForceSource(nodes=["a", "ground"], value="F"),
                   "spring": Spring(nodes=["a", "c"], k=k), "damper": Damper(nodes=["c", "ground"], b=b)},
                  outputs={"x": "mass.x", "f": "damper.f"})
    assert net.states == ("mass.x", "mass.v", "spring.x")  # node c is massless
    s = control.tf("s")
    G = (b * s + k) / (m * b * s**3 + m * k * s**2 + k * b * s)  # 1/(m s^2 + k b s/(b s + k))
    assert_same_response(derived(net, "x", "F"), G, 3)
    assert_same_response(derived(net, "f", "F"), k * b * s / (b * s + k) * G, 3)


def test_two_capacitors_in_parallel_are_one_state():
    R, C1, C2 = 100.0, 1e-3, 4e-3
    net = Network({"I": CurrentSource(nodes=["a", "ground"], value="i_in"), "R1": Resistor(nodes=["a", "ground"], R=R),
                   "C1": Capacitor(nodes=["a", "ground"], C=C1), "C2": Capacitor(nodes=["a", "ground"], C=C2)},
                  outputs={"v": "C2.v", "i2": "C2.i"})
    d = net.derive()
    assert d.states == ("C1.v",)
    assert "C2 and C1 are in parallel: C2.v = C1.v, so C2 adds no state" in " ".join(d.state_notes)
    s = control.tf("s")
    assert_same_response(derived(net, "v", "i_in"), R / (R * (C1 + C2) * s + 1), 1)
    assert_same_response(derived(net, "i2", "i_in"), C2 * R * s / (R * (C1 + C2) * s + 1), 1)


def test_two_inductors_in_series_are_one_state():
    L1, L2, R = 1.0, 3.0, 2.0
    net = Network({"V": VoltageSource(node="a", value="u"), "L1": Inductor(nodes=["a", "b"], L=L1),
                   "L2": Inductor(nodes=["b", "c"], L=L2), "R1": Resistor(nodes=["c", "ground"], R=R)},
                  outputs={"i": "L2.i", "vL2": "L2.v"})
    d = net.derive()
    assert d.states == ("L1.i",)
    assert "L2 and L1 are in series: L2.i = L1.i, so L2 adds no state" in " ".join(d.state_notes)
    s = control.tf("s")
    assert_same_response(derived(net, "i", "u"), 1 / ((L1 + L2) * s + R), 1)
    assert_same_response(derived(net, "vL2", "u"), L2 * s / ((L1 + L2) * s + R), 1)


def test_a_rack_and_pinion_reflects_the_mass_by_its_radius_squared():
    from odelab.network import RackPinion, TorqueSource

    J, r, m, b = 0.01, 0.05, 2.0, 3.0
    net = Network({"T": TorqueSource(node="w", value="tau"), "pinion": Inertia(node="w", J=J),
                   "rack": RackPinion(nodes=["w", "ground"], nodes2=["x", "ground"], r=r),
                   "cart": Mass(node="x", m=m), "drag": Damper(nodes=["x", "ground"], b=b)},
                  outputs={"v": "cart.v"})
    assert net.states == ("pinion.theta", "pinion.w")  # the cart moves with the pinion: v = r w
    s = control.tf("s")
    # (J + m r^2) dw/dt = tau - b r^2 w, and v = r w
    assert_same_response(derived(net, "v", "tau"), r / ((J + m * r**2) * s + b * r**2), 2)


def test_fluid_and_thermal_analogues_of_the_rlc_and_rc_circuits():
    from odelab.network import (FluidCapacitance, FluidInertance, FluidResistance, PressureSource,
                                TemperatureSource, ThermalCapacitance, ThermalResistance)

    I, R, C = 2.0, 3.0, 0.5
    pipe = Network({"pump": PressureSource(node="a", value="p_in"), "line": FluidInertance(nodes=["a", "b"], I=I),
                    "valve": FluidResistance(nodes=["b", "c"], R=R), "tank": FluidCapacitance(node="c", C=C)},
                   outputs={"p": "tank.p"})
    assert pipe.states == ("tank.p", "line.q")
    s = control.tf("s")
    assert_same_response(derived(pipe, "p", "p_in"), 1 / (I * C * s**2 + R * C * s + 1), 2)
    Rt, Ct = 0.2, 400.0
    room = Network({"outside": TemperatureSource(node="o", value="T_out"),
                    "wall": ThermalResistance(nodes=["o", "r"], R=Rt), "air": ThermalCapacitance(node="r", C=Ct)},
                   outputs={"T": "air.T", "q": "wall.q"})
    assert_same_response(derived(room, "T", "T_out"), 1 / (Rt * Ct * s + 1), 1)
    assert_same_response(derived(room, "q", "T_out"), Ct * s / (Rt * Ct * s + 1), 1)
