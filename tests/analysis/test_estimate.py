"""The global error estimate against the true errors: closed forms (DETEST's A1-A4 and more) and the Bari
test set's Robertson and E5, over methods and tolerances; and the verdict's two rules."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import odelab
from odelab.analysis.errors import summarize
from odelab.analysis.estimate import DISAGREE_UNITS, compare_solves, digits_of

from ..solvers.implicit.test_ode15s_ode23s import rober
from ..solvers.implicit.test_stiff_references import E5_REF, ROBER_1E11, e5

CLOSED = {  # name: (f, tspan, y0, exact(t) -> (len(t), n)); A1-A4 are DETEST's (Hull et al. 1972)
    "A1": (lambda t, y: -y, [0, 20], [1.0], lambda t: np.exp(-t)[:, None]),
    "A2": (lambda t, y: -0.5 * y**3, [0, 20], [1.0], lambda t: (1 / np.sqrt(t + 1))[:, None]),
    "A3": (lambda t, y: y * np.cos(t), [0, 20], [1.0], lambda t: np.exp(np.sin(t))[:, None]),
    "A4": (lambda t, y: y / 4 * (1 - y / 20), [0, 20], [1.0], lambda t: (20 / (1 + 19 * np.exp(-t / 4)))[:, None]),
    "exercise1": (lambda t, y: np.cos(t) + 0 * y, [0, 2 * np.pi], [2.0], lambda t: (np.sin(t) + 2)[:, None]),
    "oscillator": (lambda t, y: np.array([y[1], -y[0]]), [0, 10], [1.0, 0.0],
                   lambda t: np.column_stack([np.cos(t), -np.sin(t)])),
    "rational": (lambda t, y: -2 * t * y**2, [0, 10], [1.0], lambda t: (1 / (1 + t**2))[:, None]),
}
METHODS = ["ode23", "ode45", "ode113", "ode78", "ode89", "ode15s", "ode23s", "ode23t", "ode23tb"]
SECOND_ORDER = ("ode23s", "ode23t", "ode23tb")
# Bari test set problems with their reference at the end of the span, at the tolerances its runs use
# (E5 at its own AbsTol 1.7e-24: the silent wrong answers)
BARI = [("rober", rober, [0, 1e11], [1, 0, 0], ROBER_1E11, ["ode15s", "ode23s", "ode23t", "ode23tb"],
         [(1e-4, 1e-10), (1e-6, 1e-12), (1e-8, 1e-14)]),
        ("E5", e5, [0, 1e13], [1.76e-3, 0, 0, 0], E5_REF, ["ode15s", "ode23tb"],
         [(1e-4, 1.7e-24), (1e-6, 1.7e-24), (1e-8, 1.7e-24)])]


def _estimate(f, tspan, y0, method, rtol, atol):
    a = odelab.solve(f, tspan, y0, method=method, rtol=rtol, atol=atol)
    if not a.success:
        return a, None, None
    b = odelab.solve(f, np.unique(a.t), y0, method=method, rtol=rtol / 10, atol=atol / 10)
    if not b.success or b.t.size != a.t.size:
        return a, b, None
    names = [f"y{i}" for i in range(a.y.shape[1])]
    est = compare_solves(a.t, dict(zip(names, a.y.T)), dict(zip(names, b.y.T)), factor=10, rtol=rtol,
                         atol={n: atol for n in names})
    return a, b, est


def _triples():
    """(problem, method, rtol, quantity, estimated error, true error, estimated digits, true digits, verdict)."""
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, (f, tspan, y0, exact) in CLOSED.items():
            for method in METHODS:
                for rtol in (1e-3, 1e-5, 1e-7):
                    if method in SECOND_ORDER and rtol < 1e-6:  # thousands of steps: CI's time
                        continue
                    a, _, est = _estimate(f, tspan, y0, method, rtol, 1e-3 * rtol)
                    ex = exact(a.t)
                    for i, q in enumerate(est.quantities):
                        true = summarize(q, a.t, a.y[:, i], ex[:, i])
                        e = est.quantities[q]
                        out.append((name, method, rtol, q, e.max_abs, true.max_abs, e.digits,
                                    digits_of(true.headline), est.verdict))
        for name, f, tspan, y0, ref, methods, tolerances in BARI:
            for method in methods:
                for rtol, atol in tolerances:
                    if method in SECOND_ORDER and rtol < 1e-7 or method == "ode23s" and rtol < 1e-5:
                        continue
                    a, b, est = _estimate(f, tspan, y0, method, rtol, atol)
                    if est is None:
                        continue  # a failed solve says so (status failed): nothing is claimed
                    for i, q in enumerate(est.quantities):
                        # the end point, digits of the test set's mixed error |y - ref| / (|ref| + AbsTol/RelTol)
                        scale = abs(ref[i]) + atol / rtol
                        e_end = abs(a.y[-1, i] - b.y[-1, i]) * 10 / 9
                        t_end = abs(a.y[-1, i] - ref[i])
                        claimed = 0.0 if est.quantities[q].flagged else digits_of(e_end / scale)
                        out.append((name, method, rtol, q, e_end, t_end, claimed, digits_of(t_end / scale),
                                    est.verdict))
    return out


@pytest.fixture(scope="module")
def triples():
    return _triples()


def test_the_estimate_is_within_10x_of_the_true_error_in_90_percent_of_the_triples(triples):
    # Measured: 227 of 236 (96.2 %), 191 of the 192 closed-form ones; the misses are E5 at AbsTol 1.7e-24
    # (every one flagged unreliable) and ode89 on exercise 1 at RelTol 1e-3, 16x over (its true error,
    # 1.5e-13, is at round-off). The most the estimate claims beyond the true digits: 0.53.
    within = []
    for name, method, rtol, q, est, true, *_ in triples:
        ratio = 1.0 if est == true else (math.inf if true == 0 else est / true)
        within.append(0.1 <= ratio <= 10)
    assert len(triples) > 230
    assert sum(within) / len(within) >= 0.90, sum(within) / len(within)
    closed = [w for w, t in zip(within, triples) if t[0] in CLOSED]
    assert sum(closed) / len(closed) >= 0.98


def test_the_estimate_never_claims_two_digits_more_than_the_truth(triples):
    over = [t for t in triples if (t[6] or 0) - (t[7] or 0) >= 2]
    assert not over, over[:5]


def test_e5_at_its_own_tolerances_is_flagged_and_correct_runs_are_not(triples):
    verdicts = {(t[0], t[1], t[2]): t[8] for t in triples}
    assert all(v == "unreliable" for (name, _, _), v in verdicts.items() if name == "E5")
    assert sum(1 for (name, _, _) in verdicts if name == "E5") >= 5
    closed = [v for (name, _, _), v in verdicts.items() if name in CLOSED]
    assert closed.count("ok") == len(closed)
    assert all(v == "ok" for (name, _, _), v in verdicts.items() if name == "rober")


def test_robertson_with_ode23t_at_a_loose_abstol_is_flagged():
    # RelTol 1e-4, AbsTol 1e-6: y1 runs off to -5.7e6 with status success (the silent wrong answer)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a, _, est = _estimate(rober, [0, 1e11], [1, 0, 0], "ode23t", 1e-4, 1e-6)
    assert a.success and est.unreliable
    assert est.quantities["y0"].units > DISAGREE_UNITS and est.quantities["y0"].flagged
    assert any(r.startswith("y0: the run and a solve at tolerances 10 times tighter disagree by") for r in est.reasons)


def test_a_phase_error_is_not_a_wrong_value():
    # van der Pol mu = 1000 at MATLAB's defaults: the relaxation jumps of a solve at 10x tighter tolerances
    # come up to 2.3 s earlier or later (1.35 RelTol t), so pointwise the two differ by the jump's height
    # (3.4 in x, 0 digits, as the true error is); a shift in time of 10 RelTol |t - t0| explains every
    # such difference, and the result is not flagged.
    vdp = lambda t, y: [y[1], 1000 * (1 - y[0] ** 2) * y[1] - y[0]]  # noqa: E731
    a, _, est = _estimate(vdp, [0, 3000], [2, 0], "ode15s", 1e-3, 1e-6)
    assert est.quantities["y0"].max_abs > 3 and est.quantities["y0"].digits == 0
    assert est.verdict == "ok" and any("phase error" in n for n in est.notes)


def test_fewer_than_one_digit_is_flagged():
    t = np.linspace(0, 1, 11)
    run = {"x": np.ones(11)}
    tight = {"x": np.ones(11) + np.where(t > 0.5, 0.5, 0.0)}
    est = compare_solves(t, run, tight, factor=10, rtol=1e-3, atol={"x": 0.01})  # 43 units: 0.3 digits
    assert est.unreliable and "fewer than 1 correct digit" in est.reasons[0]
    same = compare_solves(t, run, {"x": np.ones(11) * (1 + 1e-6)}, factor=10, rtol=1e-3, atol={"x": 1e-6})
    assert same.verdict == "ok" and same.quantities["x"].digits == pytest.approx(6 - math.log10(10 / 9), abs=0.01)
