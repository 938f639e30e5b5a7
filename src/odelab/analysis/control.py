"""Control analysis of linear systems: transfer functions, poles, step metrics, Bode plots.

python-control (Fuller, Greene, Murray et al., "The Python Control Systems Library",
IEEE CDC 2021) is the field's library for these computations, so odelab converts its
:class:`~odelab.systems.statespace.StateSpace` at this boundary (:func:`to_control`) and lets
python-control do the transfer-function algebra, poles and zeros, frequency responses and
stability margins. It is imported here only, when first needed.

odelab keeps its own exact responses: :func:`stepinfo` measures MATLAB's ``stepinfo``
quantities on the exact step response (matrix exponential, :func:`~odelab.analysis.lti.
lti_response`'s method, to round-off; see :func:`step_response`) on a fine grid, locating each crossing by linear interpolation
and the peak by a parabola through the three samples around it, rather than on a solver's or
python-control's coarser grid. MATLAB's definitions (Control System Toolbox, ``stepinfo``,
R2021b and later), for a step from yinit = 0 to yfinal = the DC gain:

* RiseTime: from the first time y reaches yinit + 10 % of (yfinal - yinit) to the first time
  it reaches 90 %;
* SettlingTime: the last time |y - yfinal| is at least 2 % of |yfinal - yinit|;
  TransientTime: the same with 2 % of max |y - yfinal| (R2021a's SettlingTime);
* SettlingMin, SettlingMax: min and max of y once it has risen (after the 90 % time);
* Overshoot: 100 (max y - yfinal) / |yfinal - yinit| (%, at least 0), for a rising response;
  Undershoot: 100 (yinit - min y) / |yfinal - yinit| (%, at least 0);
* Peak: max |y|; PeakTime: when it occurs.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from odelab.exceptions import InputError

__all__ = ["StepInfo", "FrequencyResponse", "to_control", "tf", "ss2tf", "tf2ss", "poles", "zeros", "dcgain",
           "damp", "stepinfo", "step_metrics", "bode", "margins", "analyze", "tf_text", "loop_gain",
           "loop_analysis"]


def _ct():
    import control

    return control


def _statespace(system):
    from odelab.systems.statespace import StateSpace

    if isinstance(system, StateSpace):
        return system
    if hasattr(system, "matrices") and hasattr(system, "linear"):  # a compiled diagram
        return system.system if system.linear else None
    if type(system).__module__.startswith("control"):
        ct = _ct()
        s = ct.tf2ss(system) if isinstance(system, ct.TransferFunction) else system
        if isinstance(s, ct.StateSpace):
            return StateSpace(s.A, s.B, s.C, s.D)
    raise InputError(f"`system` must be an odelab StateSpace (or a linear diagram); got {type(system).__name__}: "
                     "linearise a nonlinear system first (odelab.linearize).", key="system")


def to_control(system):
    """An odelab StateSpace (or python-control system) as a python-control ``StateSpace``,
    keeping its state, input and output names."""
    ct = _ct()
    if isinstance(system, (ct.StateSpace, ct.TransferFunction)):
        return system
    ss = _statespace(system)
    return ct.ss(ss.A, ss.B, ss.C, ss.D, states=list(ss.states), inputs=list(ss.inputs), outputs=list(ss.outputs))


def tf(num, den):
    """The transfer function num(s)/den(s), coefficients in descending powers (MATLAB's ``tf``);
    a python-control ``TransferFunction``, so ``feedback``, ``series``, ``*``... work on it."""
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    if not den.size or not np.any(den):
        raise InputError(f"`den` must have a nonzero coefficient; got {den.tolist()}.", key="den")
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        raise InputError("`num` and `den` must be finite coefficients.", key="num")
    return _ct().tf(num, den)


def ss2tf(system):
    """The transfer function(s) of a state-space system: a python-control ``TransferFunction``
    (MIMO: entry [i, j] from input j to output i), minimal (common factors cancelled)."""
    ct = _ct()
    G = ct.minreal(ct.ss2tf(to_control(system)), verbose=False)
    # Round-off in the conversion leaves coefficients like -1.8e-15 s^2 in a numerator whose
    # others are O(10): they would read as a zero at 1e16. Drop those below 1e-12 of the largest.
    num = [[_trim(G.num[i][j]) for j in range(G.ninputs)] for i in range(G.noutputs)]
    return ct.tf(num, [[np.asarray(G.den[i][j], dtype=float) for j in range(G.ninputs)] for i in range(G.noutputs)])


def _trim(c) -> np.ndarray:
    c = np.asarray(c, dtype=float).copy()
    scale = np.max(np.abs(c), initial=0.0)
    c[np.abs(c) <= 1e-12 * scale] = 0.0
    c = np.trim_zeros(c, "f")
    return c if c.size else np.zeros(1)


def tf2ss(num, den=None):
    """An odelab StateSpace of num/den (or of a python-control ``TransferFunction``) in MATLAB's
    ``tf2ss`` controller canonical form (A's first row is -den[1:]/den[0])."""
    from odelab.systems.statespace import StateSpace

    ct = _ct()
    G = num if den is None else tf(num, den)
    s = ct.tf2ss(G)
    return StateSpace(s.A, s.B, s.C, s.D)


def poles(system) -> np.ndarray:
    """The poles (eigenvalues of A), sorted by real part then imaginary part."""
    p = np.asarray(_ct().poles(to_control(system)), dtype=complex)
    return p[np.lexsort((p.imag, p.real))]


def zeros(system) -> dict[tuple[str, str], np.ndarray]:
    """The zeros of each channel (output, input) of the system's transfer function."""
    ss = _statespace(system)
    G = ss2tf(ss)
    out = {}
    for i, y in enumerate(ss.outputs):
        for j, u in enumerate(ss.inputs):
            z = np.asarray(_ct().zeros(G[i, j]), dtype=complex)
            out[(y, u)] = z[np.lexsort((z.imag, z.real))] if z.size else z
    return out


def dcgain(system) -> np.ndarray:
    """The steady-state gain -C A^-1 B + D, (ny, nu) (inf where A is singular on that channel)."""
    ss = _statespace(system)
    with np.errstate(all="ignore"):
        try:
            g = np.asarray(_ct().dcgain(to_control(ss)), dtype=float)
        except (NotImplementedError, np.linalg.LinAlgError):
            # python-control evaluates a singular A's MIMO gain through its zeros, which it has
            # only for square systems (a network's integrator with two outputs): channel by channel
            sys = to_control(ss)
            g = np.array([[np.real(_ct().dcgain(sys[i, j])) for j in range(len(ss.inputs))]
                          for i in range(len(ss.outputs))], dtype=float)
    return g.reshape(len(ss.outputs), len(ss.inputs))


def damp(system) -> list[dict[str, float]]:
    """Each pole with its natural frequency wn = |p| (rad/s) and damping ratio zeta = -Re p / |p|,
    as MATLAB's ``damp``."""
    wn, zeta, p = _ct().damp(to_control(system), doprint=False)
    rows = [{"pole": complex(pk), "wn": float(w), "zeta": float(z)} for w, z, pk in zip(wn, zeta, p)]
    return sorted(rows, key=lambda r: (r["wn"], r["pole"].imag))


# --- step metrics ------------------------------------------------------------------------------


@dataclass(frozen=True)
class StepInfo:
    """MATLAB's ``stepinfo`` fields (times in s, overshoot/undershoot in %)."""

    rise_time: float
    settling_time: float
    transient_time: float
    settling_min: float
    settling_max: float
    overshoot: float
    undershoot: float
    peak: float
    peak_time: float
    steady_state: float

    MATLAB_NAMES = {"rise_time": "RiseTime", "transient_time": "TransientTime", "settling_time": "SettlingTime",
                    "settling_min": "SettlingMin", "settling_max": "SettlingMax", "overshoot": "Overshoot",
                    "undershoot": "Undershoot", "peak": "Peak", "peak_time": "PeakTime",
                    "steady_state": "SteadyStateValue"}

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    def matlab(self) -> dict[str, float]:
        """The fields under MATLAB's names (RiseTime, SettlingTime...)."""
        return {self.MATLAB_NAMES[k]: v for k, v in asdict(self).items()}


def _first_crossing(t, y, level) -> float:
    """The first time y (rising) reaches ``level``, interpolated between samples."""
    idx = np.flatnonzero(y >= level)
    if not idx.size:
        return math.nan
    k = int(idx[0])
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (level - y[k - 1]) * (t[k] - t[k - 1]) / (y[k] - y[k - 1]))


def _last_exit(t, e, level) -> float:
    """The last time e is at least ``level`` (then stays below it), interpolated."""
    idx = np.flatnonzero(e >= level)
    if not idx.size:
        return float(t[0])
    k = int(idx[-1])
    if k == t.size - 1:
        return math.nan  # not settled within the window
    return float(t[k] + (e[k] - level) * (t[k + 1] - t[k]) / (e[k] - e[k + 1]))


def _refined(t, a, k: int) -> tuple[float, float]:
    """Sample ``k`` of ``a`` refined by the parabola through the three around it."""
    if 0 < k < a.size - 1:
        y0, y1, y2 = a[k - 1], a[k], a[k + 1]
        denom = y0 - 2 * y1 + y2
        if denom < 0:
            d = 0.5 * (y0 - y2) / denom  # offset in samples, |d| <= 1/2
            h = t[k + 1] - t[k] if d > 0 else t[k] - t[k - 1]
            return float(y1 - 0.25 * (y0 - y2) * d), float(t[k] + d * h)
    return float(a[k]), float(t[k])


#: peaks within this relative distance of the largest are the same peak (an undamped response's
#: peaks are equal; sampled, any of them can hold the largest sample)
PEAK_TIE = 1e-6


def _peak(t, a) -> tuple[float, float]:
    """The largest value of samples ``a`` (refined by a parabola) and when it is first reached: a
    response whose peaks are all equal (undamped) peaks at its first, not at whichever sample
    happens to be largest."""
    k = int(np.argmax(a))
    value, when = _refined(t, a, k)
    if k < 2:
        return value, when
    head = a[1:k]
    local = np.flatnonzero((head >= a[:k - 1]) & (head > a[2:k + 1]) & (head >= value * (1 - 1e-4))) + 1
    for i in local:  # earlier local maxima, first first
        v, at = _refined(t, a, int(i))
        if v >= value * (1 - PEAK_TIE):
            return value, at
    return value, when


def step_metrics(t, y, yfinal: float, yinit: float = 0.0, *, settling_threshold: float = 0.02,
                 rise_limits: tuple[float, float] = (0.1, 0.9)) -> StepInfo:
    """MATLAB's ``stepinfo`` quantities of step-response samples ``y`` at times ``t`` (see the
    module docstring for the definitions)."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    nan = math.nan
    if not math.isfinite(yfinal):
        return StepInfo(nan, nan, nan, nan, nan, nan, nan, float(np.max(np.abs(y))), nan, yfinal)
    delta = yfinal - yinit
    peak, peak_time = _peak(t, np.abs(y))
    if int(np.argmax(np.abs(y))) == y.size - 1 and abs(yfinal) >= peak:
        # Still approaching |yfinal| at the end of the window: the supremum is |yfinal|, reached
        # only as t -> inf (MATLAB reports the last sample of its own window instead).
        peak, peak_time = abs(float(yfinal)), math.inf
    if delta == 0:
        return StepInfo(nan, nan, nan, nan, nan, nan, nan, peak, peak_time, yfinal)
    s = np.sign(delta)
    r = s * (y - yinit)  # the response as if rising from 0 to |delta|
    lo, hi = rise_limits
    t_lo = _first_crossing(t, r, lo * abs(delta))
    t_hi = _first_crossing(t, r, hi * abs(delta))
    e = np.abs(y - yfinal)
    settling = _last_exit(t, e, settling_threshold * abs(delta))
    transient = _last_exit(t, e, settling_threshold * float(np.max(e)))
    # from the (interpolated) moment the response has risen, where y = yinit + 90 % of delta
    after = np.concatenate([[yinit + hi * delta], y[t > t_hi]]) if math.isfinite(t_hi) else y[-1:]
    rmax, _ = _peak(t, r)
    overshoot = max(0.0, 100.0 * (rmax - abs(delta)) / abs(delta))
    undershoot = max(0.0, 100.0 * -float(np.min(r)) / abs(delta))
    return StepInfo(rise_time=t_hi - t_lo, settling_time=settling, transient_time=transient,
                    settling_min=float(np.min(after)), settling_max=float(np.max(after)), overshoot=overshoot,
                    undershoot=undershoot, peak=peak, peak_time=peak_time, steady_state=float(yfinal))


def _horizon(ss) -> float:
    """A first window: 8 time constants of the slowest stable mode (stepinfo doubles it until
    every channel settles well inside it); 10 s when no mode decays."""
    p = np.linalg.eigvals(ss.A)
    stable = p[p.real < 0]
    return 8.0 / float(np.min(-stable.real)) if stable.size else 10.0


def step_response(ss, t: np.ndarray, j: int) -> np.ndarray:
    """The exact response (N, ny) from rest to a unit step on input ``j`` at evenly spaced times
    ``t`` from 0: one matrix exponential of Van Loan's block [[A h, B h], [0, 0]] gives
    x_{k+1} = expm(A h) x_k + (int_0^h expm(A s) ds) B, exact for a constant input (this is how
    MATLAB's ``step`` steps too); far cheaper on a fine grid than one exponential per time."""
    from scipy.linalg import expm

    n = ss.A.shape[0]
    h = float(t[1] - t[0])
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = ss.A * h
    M[:n, n] = ss.B[:, j] * h
    E = expm(M)
    Phi, gamma = E[:n, :n], E[:n, n]
    X = np.empty((t.size, n))
    x = np.zeros(n)
    for k in range(t.size):
        X[k] = x
        x = Phi @ x + gamma
    return X @ ss.C.T + ss.D[:, j]


def stepinfo(system, *, settling_threshold: float = 0.02, rise_limits: tuple[float, float] = (0.1, 0.9),
             t_final: float | None = None, points: int = 20001) -> dict[tuple[str, str], StepInfo]:
    """MATLAB's ``stepinfo`` for each channel (output, input), measured on the exact unit-step
    response from rest over [0, t_final] (default: long enough for every channel to settle).

    Returns a dict (output name, input name) -> :class:`StepInfo`.
    """
    ss = _statespace(system)
    if ss is None:
        raise InputError("stepinfo needs a linear system; linearise the diagram first.", key="system")
    if not 0 < settling_threshold < 1:
        raise InputError(f"`settling_threshold` must be between 0 and 1; got {settling_threshold!r}.",
                         key="settling_threshold")
    gains = dcgain(ss)
    first = float(t_final) if t_final is not None else _horizon(ss)
    out: dict[tuple[str, str], StepInfo] = {}
    for j, u in enumerate(ss.inputs):
        doublings, horizon, seen = 0, first, None
        while True:
            t = np.linspace(0.0, horizon, points)
            y = step_response(ss, t, j)
            infos = {(name, u): step_metrics(t, y[:, i], float(gains[i, j]), settling_threshold=settling_threshold,
                                             rise_limits=rise_limits) for i, name in enumerate(ss.outputs)}
            seen = seen or infos
            moving = [s for s in infos.values() if math.isfinite(s.steady_state) and s.steady_state != 0]
            unsettled = any(math.isnan(s.settling_time) for s in moving)
            late = any(s.settling_time > 0.8 * horizon for s in moving if math.isfinite(s.settling_time))
            if t_final is not None or not (unsettled or late) or doublings == 8:
                break
            horizon *= 2
            doublings += 1
        if doublings == 8 and unsettled:
            # It never settles (an undamped or marginal mode): SettlingTime is NaN, as MATLAB's, and
            # the rest is measured on the first window, sampled finest (256 times longer adds nothing).
            infos = {k: (s if not math.isnan(s.settling_time) else
                         replace(seen[k], settling_time=math.nan, transient_time=math.nan))
                     for k, s in infos.items()}
        out.update(infos)
    return out


# --- frequency response ------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FrequencyResponse:
    """Bode data: ``w`` (rad/s, (N,)), ``magnitude_db`` and ``phase_deg`` (ny, nu, N) with the
    phase unwrapped along w, and the names of the channels."""

    w: np.ndarray
    magnitude_db: np.ndarray
    phase_deg: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]


def bode(system, w_from: float = 0.01, w_to: float = 100.0, points: int = 200) -> FrequencyResponse:
    """Magnitude (dB) and phase (degrees) of G(jw) on ``points`` log-spaced frequencies in
    [w_from, w_to] rad/s, from python-control's ``frequency_response``."""
    if not (0 < w_from < w_to and math.isfinite(w_to)):
        raise InputError(f"the frequency range must satisfy 0 < from < to; got from = {w_from!r}, to = {w_to!r}.",
                         key="bode")
    ss = _statespace(system)
    w = np.logspace(math.log10(w_from), math.log10(w_to), int(points))
    resp = _ct().frequency_response(to_control(ss), w)
    G = np.asarray(resp.frdata if hasattr(resp, "frdata") else resp.fresp).reshape(len(ss.outputs), len(ss.inputs), w.size)
    with np.errstate(divide="ignore"):
        mag = 20 * np.log10(np.abs(G))
    phase = np.degrees(np.unwrap(np.angle(G), axis=-1))
    return FrequencyResponse(w=w, magnitude_db=mag, phase_deg=phase, outputs=tuple(ss.outputs),
                             inputs=tuple(ss.inputs))


def margins(system) -> dict[tuple[str, str], dict[str, float]]:
    """Gain margin (absolute and dB) at the phase crossover and phase margin (degrees) at the gain
    crossover of each channel, taken as a loop transfer L(s) closed by unit negative feedback
    (MATLAB's ``margin``); inf where the curve never crosses."""
    ct = _ct()
    ss = _statespace(system)
    G = to_control(ss)
    out = {}
    for i, y in enumerate(ss.outputs):
        for j, u in enumerate(ss.inputs):
            with np.errstate(all="ignore"):
                gm, pm, _, wcg, wcp, _ = ct.stability_margins(G[i, j])
            if gm > GAIN_MARGIN_LIMIT:
                # A phase that tends to -180 degrees (relative degree 2) "crosses" it only through
                # round-off, at a frequency where |L| is below 1e-10: MATLAB reports Inf there.
                gm, wcg = math.inf, math.nan
            out[(y, u)] = {"gain_margin": float(gm), "gain_margin_db": float(20 * np.log10(gm)) if gm > 0 else
                           math.nan, "phase_margin": float(pm), "phase_crossover": float(wcg),
                           "gain_crossover": float(wcp)}
    return out


GAIN_MARGIN_LIMIT = 1e10  # 200 dB


def tf_text(num, den, var: str = "s") -> tuple[str, str]:
    """Numerator and denominator as polynomial strings, e.g. ('10', 's^2 + 4 s + 3')."""
    def poly(c):
        c = np.trim_zeros(np.asarray(c, dtype=float), "f")
        if not c.size:
            return "0"
        n = c.size - 1
        terms = []
        for k, a in enumerate(c):
            if a == 0:
                continue
            p = n - k
            mag = abs(a)
            coef = "" if (mag == 1 and p > 0) else f"{mag:.6g}"
            sym = "" if p == 0 else (var if p == 1 else f"{var}^{p}")
            body = (coef + (" " if coef and sym else "") + sym) or "1"
            sign = "-" if a < 0 else "+"
            terms.append((sign, body))
        if not terms:
            return "0"
        text = ("-" if terms[0][0] == "-" else "") + terms[0][1]
        for sign, body in terms[1:]:
            text += f" {sign} {body}"
        return text
    return poly(num), poly(den)


# --- the [analysis] section of experiment files ------------------------------------------------


def analyze(system, *, step_info: bool = False, bode_range: dict | None = None, show_poles: bool = False,
            linearized_at: Any = None, with_margins: bool = True) -> dict[str, Any]:
    """Everything [analysis] asks for, JSON-ready: the transfer functions always, and the poles
    (with wn, zeta, zeros and DC gains), step metrics and Bode data with margins as asked."""
    ss = _statespace(system)
    G = ss2tf(ss)
    out: dict[str, Any] = {"states": list(ss.states), "inputs": list(ss.inputs), "outputs": list(ss.outputs),
                           "A": ss.A.tolist(), "B": ss.B.tolist(), "C": ss.C.tolist(), "D": ss.D.tolist()}
    if linearized_at is not None:
        out["operating_point"] = linearized_at
    gains = dcgain(ss)
    tfs = []
    for i, y in enumerate(ss.outputs):
        for j, u in enumerate(ss.inputs):
            num = np.asarray(G.num[i][j], dtype=float)
            den = np.asarray(G.den[i][j], dtype=float)
            tfs.append({"output": y, "input": u, "num": num.tolist(), "den": den.tolist(),
                        "text": list(tf_text(num, den)), "dc_gain": float(gains[i, j])})
    out["transfer_functions"] = tfs
    if show_poles:
        out["poles"] = [{"re": r["pole"].real, "im": r["pole"].imag, "wn": r["wn"], "zeta": r["zeta"]}
                        for r in damp(ss)]
        out["zeros"] = {f"{y}/{u}": [{"re": z.real, "im": z.imag} for z in zs] for (y, u), zs in zeros(ss).items()}
    if step_info:
        out["step_info"] = [{"output": y, "input": u, **s.matlab()} for (y, u), s in stepinfo(ss).items()]
    if bode_range is not None:
        fr = bode(ss, float(bode_range.get("from", 0.01)), float(bode_range.get("to", 100.0)),
                  int(bode_range.get("points", 200)))
        out["bode"] = {"w": fr.w.tolist(), "channels": [
            {"output": y, "input": u, "magnitude_db": fr.magnitude_db[i, j].tolist(),
             "phase_deg": fr.phase_deg[i, j].tolist()}
            for i, y in enumerate(fr.outputs) for j, u in enumerate(fr.inputs)]}
        if with_margins:
            out["margins"] = [{"output": y, "input": u, **m} for (y, u), m in margins(ss).items()]
    return out


# --- loops ------------------------------------------------------------------------------------


def loop_gain(open_system, x0, u0):
    """L(s) of a loop opened at one signal: ``open_system`` has the extra last input ``loop_in``
    and the output ``loop_out`` (:meth:`odelab.systems.diagram.CompiledDiagram.open_loop`); it is
    linearised exactly at the closed loop's operating point (x0, u0), and L = -loop_out/loop_in,
    so that the closed loop is 1/(1 + L) as MATLAB's ``margin`` assumes."""
    from odelab.analysis.linearize import linearize
    from odelab.systems.statespace import StateSpace

    x0 = np.asarray(x0, dtype=float)
    u0 = np.asarray(u0, dtype=float)
    z0 = float(np.asarray(open_system.output(0.0, x0, np.append(u0, 0.0))).reshape(-1)[0])
    lin = linearize(open_system, x0=x0, u0=np.append(u0, z0), check=False)
    return StateSpace(lin.A, lin.B[:, -1:], -lin.C, -lin.D[:, -1:], states=lin.states, inputs=("loop_in",),
                      outputs=("loop_out",))


def loop_analysis(open_system, x0, u0, at: str, bode_range: dict | None) -> dict[str, Any]:
    """The loop gain L(s) at ``at``: its transfer function, gain and phase margins, Bode data."""
    L = loop_gain(open_system, x0, u0)
    G = ss2tf(L)
    num, den = np.asarray(G.num[0][0], dtype=float), np.asarray(G.den[0][0], dtype=float)
    out: dict[str, Any] = {"at": at, "num": num.tolist(), "den": den.tolist(), "text": list(tf_text(num, den)),
                           **margins(L)[("loop_out", "loop_in")]}
    rng = bode_range or {"from": 0.01, "to": 100.0, "points": 200}
    fr = bode(L, float(rng["from"]), float(rng["to"]), int(rng["points"]))
    out["bode"] = {"w": fr.w.tolist(), "magnitude_db": fr.magnitude_db[0, 0].tolist(),
                   "phase_deg": fr.phase_deg[0, 0].tolist()}
    return out
