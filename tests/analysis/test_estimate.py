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
    # the jumps lie up to 2.3 s apart (above), within the 100 RelTol |t - t0| searched (up to 300 s)
    assert 0.1 < est.quantities["y0"].phase_shift < 5


def test_the_phase_note_quotes_the_shift_found_not_the_window_searched():
    # two ramps 0 -> 1 over 0.1, the tighter solve's 0.3 later (t on a 0.001 grid, RelTol 1e-3, AbsTol 1e-6). Where
    # the run is at 1 and the tighter solve still at 0, the two curves pass within the band 1000 AbsTol = 0.001 of
    # each other's value after shifting the run back to 5.0001 or the tighter solve on to 5.3999: the
    # shorter of the two is largest at t = 5.2, 0.1999 (worked by hand); the window searched there is
    # 100 RelTol t = 0.52. The note said "at most 0.54" before (the window at the last suspect point, t = 5.399).
    t = np.round(np.linspace(0, 10, 10001), 12)
    run = {"x": np.clip((t - 5) / 0.1, 0, 1)}
    tight = {"x": np.clip((t - 5.3) / 0.1, 0, 1)}
    est = compare_solves(t, run, tight, factor=10, rtol=1e-3, atol={"x": 1e-6})
    q = est.quantities["x"]
    assert est.verdict == "ok" and q.digits == 0 and not q.flagged
    assert q.phase_shift == pytest.approx(0.1999, abs=1e-9) and q.t_phase_shift == pytest.approx(5.2, abs=1e-12)
    assert "and a shift in time of at most 0.2 explains them (at t = 5.2): a phase error" in est.notes[0]
    assert est.as_dict()["quantities"]["x"]["phase_shift"] == q.phase_shift


def test_fewer_than_one_digit_is_flagged():
    t = np.linspace(0, 1, 11)
    run = {"x": np.ones(11)}
    tight = {"x": np.ones(11) + np.where(t > 0.5, 0.5, 0.0)}
    est = compare_solves(t, run, tight, factor=10, rtol=1e-3, atol={"x": 0.01})  # 43 units: 0.3 digits
    assert est.unreliable and "fewer than 1 correct digit" in est.reasons[0]
    same = compare_solves(t, run, {"x": np.ones(11) * (1 + 1e-6)}, factor=10, rtol=1e-3, atol={"x": 1e-6})
    assert same.verdict == "ok" and same.quantities["x"].digits == pytest.approx(6 - math.log10(10 / 9), abs=0.01)


def _shift_distance(t, values, tight, i, width):
    """The phase check's distance at one point, as odelab computed it point by point until 2026-12 (the
    reference for the vectorised :func:`odelab.analysis.estimate._shift_distances`, bit for bit)."""
    if not (np.isfinite(values[i]) and width > 0):
        return float(abs(values[i] - tight[i])) if np.isfinite(values[i]) else math.inf
    rt, rtight = (t, tight) if t[-1] >= t[0] else (t[::-1], tight[::-1])
    a, b = t[i] - width, t[i] + width
    j0, j1 = np.searchsorted(rt, a, side="left"), np.searchsorted(rt, b, side="right")
    pool = np.concatenate([rtight[j0:j1], np.interp([a, b], rt, rtight)])
    pool = pool[np.isfinite(pool)]
    if pool.size == 0:
        return math.inf
    v = float(values[i])
    return max(float(pool.min()) - v, v - float(pool.max()), 0.0)


def _curves(rng, n, backward, holes):
    t = np.unique(rng.uniform(0, 100, n))
    t = t[::-1].copy() if backward else t
    run = np.sin(0.5 * t) + rng.normal(0, 1e-2, t.size)
    tight = np.sin(0.5 * (t + rng.uniform(0, 3)))
    if holes:
        k = rng.integers(0, t.size, size=max(1, t.size // 50))
        tight[k] = rng.choice([np.nan, np.inf, -np.inf], size=k.size)
    return t, run, tight


@pytest.mark.parametrize("n", [2, 3, 63, 64, 65, 129, 3000])
@pytest.mark.parametrize("backward", [False, True])
@pytest.mark.parametrize("holes", [False, True])
def test_the_phase_check_over_all_points_at_once_is_the_point_by_point_one_bit_for_bit(n, backward, holes):
    from odelab.analysis.estimate import _shift_distances

    rng = np.random.default_rng(n + 2 * backward + 4 * holes)
    t, run, tight = _curves(rng, n, backward, holes)
    width = rng.uniform(0, 30, t.size) * (rng.random(t.size) < 0.9)  # some windows empty (width 0)
    points = np.arange(t.size)
    fast = _shift_distances(t, run, tight, points, width)
    slow = np.array([_shift_distance(t, run, tight, i, width[i]) for i in points])
    assert fast.tobytes() == slow.tobytes()


@pytest.mark.parametrize("n", [2, 65, 3000])
@pytest.mark.parametrize("backward", [False, True])
@pytest.mark.parametrize("holes", [False, True])
def test_the_shift_each_point_needs_is_the_segment_by_segment_one(n, backward, holes):
    # vectorised (binary lifting over blocks of the curve's extrema) against one point at a time over every
    # segment (the fallback for a curve with values that are not finite: there the two are the same function)
    from odelab.analysis.estimate import _shift_needed, _shifts_needed

    rng = np.random.default_rng(10 + n + 2 * backward + 4 * holes)
    t, run, tight = _curves(rng, n, backward, holes)
    band = 10 ** rng.uniform(-4, -1, t.size)
    fast = _shifts_needed(t, run, tight, np.arange(t.size), band)
    slow = np.array([_shift_needed(t, run, tight, i, abs(t[-1] - t[0]), band[i]) for i in range(t.size)])
    assert np.array_equal(np.isinf(fast), np.isinf(slow))
    finite = np.isfinite(slow)
    assert np.all(np.abs(fast[finite] - slow[finite]) <= 1e-12 * abs(t[-1] - t[0]))
    if n > 64:
        assert np.count_nonzero(slow[finite] > 0) > t.size // 4  # most points need a shift: the test is not vacuous


def test_range_extrema_and_the_first_point_beyond_against_a_scan():
    from odelab.analysis.estimate import _BLOCK, _RangeExtrema

    rng = np.random.default_rng(7)
    x = rng.normal(size=70 * _BLOCK + 17)
    x[rng.integers(0, x.size, 9)] = np.nan
    table = _RangeExtrema(x)
    j0 = rng.integers(0, x.size, 500)
    j1 = np.minimum(x.size, j0 + rng.integers(0, 3 * _BLOCK, 500) * rng.choice([1, 1, 20], 500))  # up to 60 blocks
    least, most = table.extrema(j0, j1)
    for a, b, lo, hi in zip(j0, j1, least, most):
        finite = x[a:b][np.isfinite(x[a:b])]
        assert (lo, hi) == ((finite.min(), finite.max()) if finite.size else (np.inf, -np.inf))
    edge = rng.normal(size=500) - 2.5  # rare values: often none for a while, sometimes none at all
    for down in (True, False):
        for forward in (True, False):
            found = table.first_beyond(j0, edge if down else -edge, down, forward)
            for s, e, k in zip(j0, edge if down else -edge, found):
                idx = range(s + 1, x.size) if forward else range(s - 1, -1, -1)
                want = next((i for i in idx if (x[i] <= e if down else x[i] >= e)), -1)
                assert k == want
