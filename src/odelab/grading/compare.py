"""What differs between a student's experiment and the reference's: the words of the feedback.

Both cases are compared as loaded (their resolved configuration, defaults filled in, and their
compiled right-hand sides), so that "RelTol = 1e-6" and "rtol = 1e-6" are the same thing, a
rewritten but equal equation (``cos(t)`` and ``1*cos( t )``) is not reported, and a wrong sign
is. A system is also matched "up to renaming": :func:`same_system` finds the permutation of
states (and inputs) under which two right-hand sides agree at a few fixed sample points.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["NameMap", "differences", "same_system", "fmt"]

_SAMPLES = 5
_MAX_PERMUTED = 6  # states (and inputs) beyond which only the given order and names are tried


def fmt(value) -> str:
    """A number as the feedback shows it: 4 significant digits, the same on every machine."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, np.floating, np.integer)):
        value = float(value)
        if math.isnan(value):
            return "NaN"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        if value == int(value) and abs(value) < 1e6:
            return str(int(value))
        return f"{value:.4g}"
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(fmt(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {fmt(v)}" for k, v in value.items()) + "}"
    return str(value)


@dataclass(frozen=True)
class NameMap:
    """The student's names for the reference's states, inputs and outputs."""

    states: dict[str, str]
    inputs: dict[str, str]
    outputs: dict[str, str]

    def of(self, name: str) -> str:
        for table in (self.states, self.outputs, self.inputs):
            if name in table:
                return table[name]
        return name

    @classmethod
    def identity(cls, problem) -> "NameMap":
        return cls({s: s for s in problem.states}, {u: u for u in problem.inputs}, {y: y for y in problem.outputs})


def _rhs(problem):
    """f(t, x, u) of a case's system (None where it has none that can be evaluated safely)."""
    system = problem.system.model
    if system is None:
        fun = problem.system.fun  # an equations system without inputs: f(t, x)
        return None if fun is None or problem.inputs else (lambda t, x, u: np.asarray(fun(t, x), dtype=float))
    from odelab.systems.statespace import StateSpace

    if isinstance(system, StateSpace):
        A, B = system.A, system.B
        return lambda t, x, u: A @ x + (B @ u if u.size else 0.0)
    dynamics = getattr(system, "dynamics", None)
    if dynamics is None:
        return None
    return lambda t, x, u: np.asarray(dynamics(t, x, u), dtype=float)


def _points(problem, n: int, m: int):
    rng = np.random.default_rng(20261201)  # fixed: the same sample points on every run
    t0, t1 = float(problem.tspan[0]), float(problem.tspan[-1])
    return [(float(t0 + (t1 - t0) * rng.random()), rng.uniform(-2.0, 2.0, n), rng.uniform(-1.0, 1.0, m))
            for _ in range(_SAMPLES)]


def _evaluate(f, t, x, u):
    try:
        with np.errstate(all="ignore"):
            value = np.asarray(f(t, x, u), dtype=float).reshape(-1)
    except Exception:  # a domain error at a sample point: no evidence either way
        return None
    return value if np.all(np.isfinite(value)) else None


def _agree(a, b) -> bool:
    scale = max(1.0, float(np.max(np.abs(a))) if a.size else 0.0)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= 1e-9 * scale))


def _orders(names_ref, names_stu):
    """Candidate maps (position in the student's list for each reference position): names first."""
    n = len(names_ref)
    if n != len(names_stu):
        return
    if set(names_ref) == set(names_stu):
        yield tuple(names_stu.index(s) for s in names_ref)
    yield tuple(range(n))
    if n <= _MAX_PERMUTED:
        yield from itertools.permutations(range(n))


def same_system(ref_problem, stu_problem) -> NameMap | None:
    """The renaming under which the two cases' systems are the same equations, or None.

    States and inputs are permuted (names first, then order, then every permutation up to
    six); the right-hand sides must agree at five fixed sample points (t in the reference's
    span, x in [-2, 2], u in [-1, 1]) to 1e-9 of their scale.
    """
    f, g = _rhs(ref_problem), _rhs(stu_problem)
    if f is None or g is None:
        return None
    n, m = len(ref_problem.states), len(ref_problem.inputs)
    if n != len(stu_problem.states) or m != len(stu_problem.inputs):
        return None
    points = _points(ref_problem, n, m)
    ref_values = [_evaluate(f, t, x, u) for t, x, u in points]
    if any(v is None for v in ref_values):
        return None
    seen = set()
    for ps in _orders(ref_problem.states, stu_problem.states):
        for pu in _orders(ref_problem.inputs, stu_problem.inputs) if m else [()]:
            if (ps, pu) in seen:
                continue
            seen.add((ps, pu))
            ok = True
            for (t, x, u), want in zip(points, ref_values):
                xs = np.empty(n)
                xs[list(ps)] = x
                us = np.empty(m)
                if m:
                    us[list(pu)] = u
                got = _evaluate(g, t, xs, us)
                if got is None or not _agree(want, got[list(ps)]):
                    ok = False
                    break
            if ok:
                states = {s: stu_problem.states[ps[i]] for i, s in enumerate(ref_problem.states)}
                inputs = {s: stu_problem.inputs[pu[i]] for i, s in enumerate(ref_problem.inputs)}
                outputs = _outputs(ref_problem, stu_problem)
                return NameMap(states, inputs, outputs)
    return None


def _outputs(ref_problem, stu_problem) -> dict[str, str]:
    if set(ref_problem.outputs) <= set(stu_problem.outputs):
        return {y: y for y in ref_problem.outputs}
    if len(ref_problem.outputs) == len(stu_problem.outputs):
        return dict(zip(ref_problem.outputs, stu_problem.outputs))
    return {}


def name_map(ref_problem, stu_problem) -> NameMap:
    """The student's names for the reference's: the same names where they exist, else by position."""
    def by(ref, stu):
        if set(ref) <= set(stu):
            return {s: s for s in ref}
        if len(ref) == len(stu):
            return dict(zip(ref, stu))
        return {s: s for s in ref if s in stu}

    return NameMap(by(ref_problem.states, stu_problem.states), by(ref_problem.inputs, stu_problem.inputs),
                   by(ref_problem.outputs, stu_problem.outputs))


# --- differences --------------------------------------------------------------------------------

def _close(a, b) -> bool:
    if isinstance(a, bool) or isinstance(b, bool):
        return a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=0.0) or a == b
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    return a == b


def _flat(prefix: str, value) -> dict[str, object]:
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            out.update(_flat(f"{prefix}.{k}", v))
        return out
    return {prefix: value}


def differences(ref_case, stu_case, names: NameMap) -> list[str]:
    """What the student's case sets differently from the reference's, one phrase each, in a fixed order:
    the solver, the parameters, the equations (or matrices), the initial values, the time span, the
    inputs, the exact solution."""
    ref, stu = ref_case.config, stu_case.config
    out: list[str] = []
    # solver: method, then every key of either, by name
    rs, ss = ref.get("solver", {}), stu.get("solver", {})
    for key in ["method", *sorted((set(rs) | set(ss)) - {"method", "jacobian"})]:
        a, b = rs.get(key), ss.get(key)
        if not _close(a, b):
            if b is None:
                out.append(f"solver.{key} is not set, where the reference has {fmt(a)}")
            elif a is None:
                out.append(f"solver.{key} is {fmt(b)}, which the reference does not set")
            else:
                out.append(f"solver.{key} is {fmt(b)} where the reference has {fmt(a)}")
    # parameters, by name
    rp, sp = ref.get("parameters", {}), stu.get("parameters", {})
    for key in sorted(set(rp) & set(sp)):
        if not _close(rp[key], sp[key]):
            out.append(f"parameters.{key} is {fmt(sp[key])} where the reference has {fmt(rp[key])}")
    out.extend(_system_differences(ref_case, stu_case, names))
    # initial values, in the student's names
    ri, si = ref.get("initial", {}), stu.get("initial", {})
    for s, mine in names.states.items():
        if s in ri and mine in si and not _close(ri[s], si[mine]):
            out.append(f"initial.{mine} is {fmt(si[mine])} where the reference has {fmt(ri[s])}")
    rt, st = ref.get("time", {}), stu.get("time", {})
    for key in ("start", "stop", "points"):
        if not _close(rt.get(key), st.get(key)):
            out.append(f"time.{key} is {fmt(st.get(key))} where the reference has {fmt(rt.get(key))}")
    if not _close(rt.get("output"), st.get("output")):
        out.append("time.output differs from the reference's output times")
    rin, sin = ref.get("inputs", {}) or {}, stu.get("inputs", {}) or {}
    for u, mine in names.inputs.items():
        a, b = rin.get(u), sin.get(mine)
        if a is None or b is None:
            continue
        fa, fb = _flat(f"inputs.{mine}", a), _flat(f"inputs.{mine}", b)
        for key in sorted(set(fa) | set(fb)):
            if not _close(fa.get(key), fb.get(key)):
                shown = fmt(fb.get(key)) if key in fb else "not set"
                out.append(f"{key} is {shown} where the reference has {fmt(fa.get(key)) if key in fa else 'none'}")
    re_, se = ref.get("exact"), stu.get("exact")
    if re_ is not None:
        for q, text in re_.items():
            mine = names.of(q)
            if se is None or mine not in se:
                continue
            if _norm(se[mine]) != _norm(text):
                out.append(f"exact.{mine} is {se[mine]!r} where the reference has {text!r}")
    return out


def _norm(text) -> str:
    return "".join(str(text).split())


def _system_differences(ref_case, stu_case, names: NameMap) -> list[str]:
    """Equations that differ (numerically, at fixed sample points), or matrix entries of a state-space model."""
    rp, sp = ref_case.problem, stu_case.problem
    rsys, ssys = ref_case.config.get("system", {}), stu_case.config.get("system", {})
    out: list[str] = []
    if "A" in rsys and "A" in ssys:
        order_s = [sp.states.index(names.states[s]) if names.states.get(s) in sp.states else None for s in rp.states]
        if None in order_s or len(rp.states) != len(sp.states):
            out.append(f"system.states are {fmt(list(sp.states))} where the reference has {fmt(list(rp.states))}")
            return out
        for M in ("A", "B", "C", "D"):
            a, b = np.asarray(rsys[M], dtype=float), np.asarray(ssys[M], dtype=float)
            if M in ("A", "C"):
                b = b[:, order_s] if b.ndim == 2 and b.shape[1] == len(order_s) else b
            if M in ("A", "B"):
                b = b[order_s, :] if b.ndim == 2 and b.shape[0] == len(order_s) else b
            if a.shape != b.shape:
                out.append(f"system.{M} is {b.shape[0]}-by-{b.shape[1] if b.ndim > 1 else 1} where the reference's "
                           f"is {a.shape[0]}-by-{a.shape[1] if a.ndim > 1 else 1}")
                continue
            bad = np.argwhere(~np.isclose(a, b, rtol=1e-12, atol=0.0))
            for i, j in bad[:3]:
                out.append(f"system.{M}[{i}][{j}] is {fmt(b[i, j])} where the reference has {fmt(a[i, j])}")
        return out
    f, g = _rhs(rp), _rhs(sp)
    req, seq = rsys.get("equations") or {}, ssys.get("equations") or {}
    if f is None or g is None or len(rp.states) != len(sp.states) or len(rp.inputs) != len(sp.inputs):
        if list(rp.states) != list(sp.states):
            out.append(f"system.states are {fmt(list(sp.states))} where the reference has {fmt(list(rp.states))}")
        return out
    order_s = [sp.states.index(names.states[s]) if names.states.get(s) in sp.states else i
               for i, s in enumerate(rp.states)]
    order_u = [sp.inputs.index(names.inputs[u]) if names.inputs.get(u) in sp.inputs else i
               for i, u in enumerate(rp.inputs)]
    wrong = set()
    for t, x, u in _points(rp, len(rp.states), len(rp.inputs)):
        xs, us = np.empty(len(x)), np.empty(len(u))
        xs[order_s] = x
        if len(u):
            us[order_u] = u
        want, got = _evaluate(f, t, x, u), _evaluate(g, t, xs, us)
        if want is None or got is None:
            continue
        got = got[order_s]
        scale = max(1.0, float(np.max(np.abs(want))))
        wrong.update(i for i in range(len(want)) if abs(want[i] - got[i]) > 1e-9 * scale)
    for i in sorted(wrong):
        s, mine = rp.states[i], sp.states[order_s[i]]
        if s in req and mine in seq:
            out.append(f"the equation of {mine} is {seq[mine]!r} where the reference has {req[s]!r}")
        else:
            out.append(f"the equation of {mine} gives other values than the reference's equation of {s}")
    return out
