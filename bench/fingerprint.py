"""A fingerprint of the solvers: a grid of runs hashed bit for bit, to show a refactoring changed no value.

Every run's ``t``, ``y``, statistics, status, message, events (``te``, ``ye``, ``ie``) and its
interpolant's values and slopes at a few points (``deval``) go into a SHA-256 per run; the
grid's lines are ``group/method/variant hash`` and the last line the hash of them all:

    python bench/fingerprint.py [--out FILE] [--group python|stiff|compiled|...]

The groups: the explicit pairs and ode113 (Refine, vector and backward tspan, NormControl, a
vector AbsTol, MaxStep/InitialStep, events terminal and not, NonNegative, a mass matrix,
OutputFcn, complex y0), the fixed-step methods, the stiff solvers (the same, plus a given
Jacobian, a singular mass (DAE), ode15s's orders and BDF), ode15i, dde23, SciPy's classes, and
the compiled backend (explicit, fixed, ode23s, ode15s, events). Compare two trees with
``PYTHONPATH=<tree>/src python bench/fingerprint.py --out a.txt`` and ``diff``; run it also
under ``OPENBLAS_CORETYPE=Nehalem`` and ``=Haswell``.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
import warnings

import numpy as np

import odelab


def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])


def rigid_events(t, y):
    return np.array([y[0], y[1] - 0.5]), np.array([False, False]), np.array([0.0, 1.0])


def rigid_stop(t, y):
    return np.array([y[0] - 0.9]), np.array([True]), np.array([1.0])


def vdp(t, y, mu=10.0):
    return np.array([y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]])


def vdp_jac(t, y, mu=10.0):
    return np.array([[0.0, 1.0], [-2 * mu * y[0] * y[1] - 1, mu * (1 - y[0] ** 2)]])


def vdp_events(t, y):
    return np.array([y[0], y[1]]), np.array([False, False]), np.array([0.0, -1.0])


def vdp_stop(t, y):
    return np.array([y[0] + 1.5]), np.array([True]), np.array([-1.0])


def decay(t, y):
    return np.array([-y[1] - 0.2 * y[0], y[0] - 0.1 * y[1]])


def robertson_dae(t, y):
    return np.array([-0.04 * y[0] + 1e4 * y[1] * y[2], 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2,
                     y[0] + y[1] + y[2] - 1])


MASS = np.array([[2.0, 0.5], [0.5, 1.0]])
DAE_MASS = np.diag([1.0, 1.0, 0.0])
TIMES: list | None = None  # --times: (seconds, run) of each run, to stderr
BUDGET = 5000  # steps: a run that stalls (NonNegative on van der Pol) stops there, as failed
POINTS = np.linspace(0.05, 0.95, 7)


def _digest(sol, span) -> str:
    h = hashlib.sha256()
    for part in (sol.t, sol.y):
        h.update(np.ascontiguousarray(part).tobytes())
    h.update(repr((sol.stats, sol.status, sol.message)).encode())
    for name in ("te", "ye", "ie"):
        value = getattr(sol, name, None)
        if value is not None:
            h.update(np.ascontiguousarray(np.asarray(value)).tobytes())
    t0, tf = float(span[0]), float(span[-1])
    points = t0 + POINTS * (tf - t0)
    for derivative in (False, True):
        try:
            h.update(np.ascontiguousarray(sol.deval(points, derivative=derivative)).tobytes())
        except Exception as exc:  # no interpolant: its message is part of the fingerprint
            h.update(type(exc).__name__.encode())
    return h.hexdigest()[:16]


def _run(lines, name, call, span):
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            sol = call()
            lines.append(f"{name} {_digest(sol, span)}")
        except Exception as exc:
            lines.append(f"{name} raised {type(exc).__name__}: {exc}")
    if TIMES is not None:
        TIMES.append((time.perf_counter() - start, name))


def explicit(lines):
    calls = []
    out_calls = []

    def output_fcn(t, y, flag):
        out_calls.append((flag, np.asarray(t).tobytes(), np.asarray(y).tobytes()))
        return False

    variants = {
        "default": ([0, 20], {}),
        "refine1": ([0, 20], {"refine": 1}),
        "refine7": ([0, 20], {"Refine": 7}),
        "tspan": (list(np.linspace(0, 20, 33)), {"rtol": 1e-6}),
        "backward": ([20, 0], {}),
        "normcontrol": ([0, 20], {"NormControl": "on", "atol": 1e-8}),
        "atolvec": ([0, 20], {"RelTol": 1e-5, "AbsTol": [1e-6, 1e-7, 1e-8]}),
        "steps": ([0, 20], {"initial_step": 1e-3, "MaxStep": 0.5}),
        "events": ([0, 20], {"events": rigid_events}),
        "terminal": ([0, 20], {"Events": rigid_stop, "rtol": 1e-6}),
        "nonnegative": ([0, 20], {"NonNegative": [3]}),
        "outputfcn": ([0, 20], {"output_fcn": output_fcn, "OutputSel": [1, 3]}),
        "tight": ([0, 60], {"rtol": 1e-10, "atol": 1e-12}),
    }
    for method in ("ode23", "ode45", "ode78", "ode89", "ode113"):
        for variant, (span, options) in variants.items():
            out_calls.clear()
            _run(lines, f"explicit/{method}/{variant}", lambda: odelab.solve(rigid, span, [0, 1, 1], method, **options),
                 span)
            if variant == "outputfcn":
                lines.append(f"explicit/{method}/outputfcn-calls "
                             f"{hashlib.sha256(repr(out_calls).encode()).hexdigest()[:16]}")
        _run(lines, f"explicit/{method}/mass", lambda: odelab.solve(decay, [0, 10], [1, 0], method, mass=MASS), [0, 10])
        _run(lines, f"explicit/{method}/complex",
             lambda: odelab.solve(lambda t, y: 1j * y, [0, 5], [1 + 0j], method), [0, 5])
    del calls


def fixed(lines):
    for method in ("euler", "heun", "midpoint", "ralston", "rk3", "rk4"):
        _run(lines, f"fixed/{method}/h", lambda: odelab.solve(rigid, [0, 10], [0, 1, 1], method, h=0.01), [0, 10])
        span = list(np.linspace(0, 10, 11))
        _run(lines, f"fixed/{method}/tspan", lambda: odelab.solve(rigid, span, [0, 1, 1], method, h=0.3), span)


def stiff(lines):
    variants = {
        "default": ([0, 30], {}),
        "refine3": ([0, 30], {"refine": 3}),
        "tspan": (list(np.linspace(0, 30, 41)), {"rtol": 1e-5}),
        "backward": ([30, 0], {}),
        "jacobian": ([0, 30], {"jacobian": vdp_jac, "rtol": 1e-6, "atol": 1e-8}),
        "events": ([0, 30], {"events": vdp_events}),
        "terminal": ([0, 30], {"Events": vdp_stop}),
        "nonnegative": ([0, 30], {"NonNegative": [1]}),
        "normcontrol": ([0, 30], {"NormControl": "on"}),
        "steps": ([0, 30], {"InitialStep": 1e-4, "max_step": 0.7}),
    }
    for method in ("ode15s", "ode23s", "ode23t", "ode23tb"):
        for variant, (span, options) in variants.items():
            _run(lines, f"stiff/{method}/{variant}", lambda: odelab.solve(vdp, span, [2, 0], method, max_steps=BUDGET, **options), span)
        _run(lines, f"stiff/{method}/mass", lambda: odelab.solve(decay, [0, 10], [1, 0], method, mass=MASS), [0, 10])
        if method != "ode23s":
            span = [0, 4e5]
            _run(lines, f"stiff/{method}/dae", lambda: odelab.solve(
                robertson_dae, span, [1, 0, 0], method, mass=DAE_MASS, rtol=1e-4, atol=[1e-6, 1e-10, 1e-6]), span)
    for order in (1, 2, 5):
        for bdf in ("off", "on"):
            _run(lines, f"stiff/ode15s/maxorder{order}-bdf{bdf}",
                 lambda: odelab.solve(vdp, [0, 30], [2, 0], "ode15s", MaxOrder=order, BDF=bdf), [0, 30])


def residual(lines):
    from odelab.solvers.api import solve_residual  # ode15i: not in trees older than it

    def F(t, y, yp):
        return np.array([yp[0] - y[1], yp[1] - 10.0 * (1 - y[0] ** 2) * y[1] + y[0]])

    for variant, options in {"default": {}, "tight": {"rtol": 1e-6, "atol": 1e-8}, "refine3": {"refine": 3}}.items():
        _run(lines, f"residual/ode15i/{variant}",
             lambda: solve_residual(F, [0, 20], [2, 0], [0, -2], "ode15i", **options), [0, 20])


def scipy(lines):
    for method in ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA"):
        _run(lines, f"scipy/{method}/default", lambda: odelab.solve(vdp, [0, 10], [2, 0], method), [0, 10])


def compiled(lines):
    from odelab.solvers.compiled import CompiledSystem, solve_compiled
    from odelab.systems.jacobian import complex_step_jacobian

    rig = CompiledSystem.from_equations(["y1", "y2", "y3"], ["y2*y3", "-y1*y3", "a*y1*y2"], {"a": -0.51})
    ball = CompiledSystem.from_equations(["h", "v"], ["v", "-g"], {"g": 9.81}).with_events(
        ["h", "v", "h - 2"], [True, False, False], [-1, 0, 1], {"g": 9.81})
    variants = {
        "default": ([0, 60], {}),
        "refine1": ([0, 60], {"refine": 1}),
        "refine7": ([0, 60], {"refine": 7}),
        "tspan": (list(np.linspace(0, 60, 97)), {"rtol": 1e-6}),
        "backward": ([60, 0], {}),
        "normcontrol": ([0, 60], {"norm_control": True, "atol": 1e-8}),
        "atolvec": ([0, 60], {"atol": [1e-8, 1e-9, 1e-10]}),
        "steps": ([0, 60], {"initial_step": 1e-3, "max_step": 0.5}),
    }
    for method in ("ode23", "ode45"):
        for variant, (span, options) in variants.items():
            _run(lines, f"compiled/{method}/{variant}",
                 lambda: solve_compiled(rig, span, [0, 1, 1], method, **options), span)
        for y0, span in (([10.0, 0.0], [0, 5]), ([0.0, 12.0], [0, 5]), ([0.0, 12.0], list(np.linspace(0, 5, 41)))):
            _run(lines, f"compiled/{method}/events{y0[0]:g}-{len(span)}",
                 lambda: solve_compiled(ball, span, y0, method), span)
    for method in ("euler", "heun", "rk4"):
        _run(lines, f"compiled/{method}/h", lambda: solve_compiled(rig, [0, 10], [0, 1, 1], method, h=0.01), [0, 10])
    states, equations, parameters = ["x", "v"], ["v", "mu*(1 - x^2)*v - x"], {"mu": 1000.0}
    vdp_c = CompiledSystem.from_equations(states, equations, parameters)
    jac = complex_step_jacobian(equations, states, parameters)
    rob = CompiledSystem.from_equations(
        ["y1", "y2", "y3"], ["-0.04*y1 + 1e4*y2*y3", "0.04*y1 - 1e4*y2*y3 - 3e7*y2^2", "3e7*y2^2"], {})
    rob_jac = complex_step_jacobian(["-0.04*y1 + 1e4*y2*y3", "0.04*y1 - 1e4*y2*y3 - 3e7*y2^2", "3e7*y2^2"],
                                    ["y1", "y2", "y3"], {})
    rob_span = [0, 0.4, 4, 40, 400, 4e3, 4e4, 4e5, 4e6, 4e8, 4e10]
    for method in ("ode23s", "ode15s"):
        _run(lines, f"compiled/{method}/vdp",
             lambda: solve_compiled(vdp_c, [0, 3000], [2, 0], method, jacobian=jac), [0, 3000])
        _run(lines, f"compiled/{method}/robertson", lambda: solve_compiled(
            rob, rob_span, [1, 0, 0], method, jacobian=rob_jac, rtol=1e-4, atol=[1e-8, 1e-14, 1e-8]), rob_span)
        _run(lines, f"compiled/{method}/vdp-refine2",
             lambda: solve_compiled(vdp_c, [0, 300], [2, 0], method, jacobian=jac, refine=2), [0, 300])


GROUPS = {"explicit": explicit, "fixed": fixed, "stiff": stiff, "residual": residual, "scipy": scipy,
          "compiled": compiled}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="also write the lines to this file")
    parser.add_argument("--group", action="append", choices=list(GROUPS), help="only these groups")
    parser.add_argument("--times", action="store_true", help="the slowest runs' seconds, to stderr")
    args = parser.parse_args()
    global TIMES
    TIMES = [] if args.times else None
    lines: list[str] = []
    for name in args.group or GROUPS:
        GROUPS[name](lines)
    total = hashlib.sha256("\n".join(lines).encode()).hexdigest()[:16]
    text = "\n".join(lines) + f"\n{len(lines)} runs: {total}\n"
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)
    sys.stdout.write(text)
    for seconds, name in sorted(TIMES or [], reverse=True)[:15]:
        sys.stderr.write(f"{seconds:8.2f} s  {name}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
