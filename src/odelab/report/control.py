"""The report's diagram and control-analysis parts: the drawing, linmod, stepinfo, Bode.

From the stored runs only: ``extra["diagram"]`` (DOT text, and A, B, C, D of a linear diagram)
and ``extra["analysis"]`` (transfer functions, poles, step metrics, Bode data, margins). A
linear diagram is compared with every state-space experiment of the report that has the same
A and B (Figure 1 against Exercise 2): matrix by matrix, and case by case on the responses.
The drawing is laid out by Graphviz (:mod:`odelab.report.graphviz`: the system's ``dot`` or the
WebAssembly one) when the report is built.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from odelab.report.plots import SERIES_COLORS, FigureSpec, Line, Panel, RefLine

__all__ = ["ControlView", "control_view"]

EPS = float(np.finfo(float).eps)


@dataclass(eq=False)
class ControlView:
    """What one experiment's diagram and analysis parts show."""

    case: str  # the case the analysis comes from
    dot: str | None = None  # the diagram as DOT text
    diagram_figure: Any = None  # a build.Figure once drawn, or None
    diagram_note: str = ""  # why there is no drawing
    linear: bool | None = None
    matrices: list[tuple[str, list[str], list[tuple[str, list[float]]]]] = field(default_factory=list)
    equivalent: list[dict[str, Any]] = field(default_factory=list)  # same-system experiments
    operating_point: list[tuple[str, float]] = field(default_factory=list)
    transfer_functions: list[dict[str, Any]] = field(default_factory=list)
    poles: list[dict[str, Any]] = field(default_factory=list)
    zeros: list[tuple[str, str]] = field(default_factory=list)
    step_info: list[dict[str, Any]] = field(default_factory=list)
    margins: list[dict[str, Any]] = field(default_factory=list)
    loop: dict[str, Any] | None = None  # the loop gain opened at a block: L(s), margins, Bode data
    bode_figure: Any = None  # a FigureSpec, then a Figure once drawn
    network_dot: str | None = None  # kind = "network": the network as DOT text
    network_figure: Any = None  # a build.Figure once drawn, or None
    network_note: str = ""  # why there is no drawing
    derivation: list[tuple[str, list[str]]] = field(default_factory=list)  # (heading, lines) of the derivation

    @property
    def has_analysis(self) -> bool:
        return bool(self.transfer_functions)


def _matrix_rows(M, rows, cols):
    return (list(cols), [(r, [float(v) for v in row]) for r, row in zip(rows, M)])


def _ss_of(config: dict) -> dict | None:
    system = config.get("system", {})
    if system.get("kind") != "state-space":
        return None
    return {k: system.get(k) for k in ("A", "B", "C", "D", "states", "inputs", "outputs")}


def _same_system(diagram: dict, ss: dict) -> dict | None:
    """How a linear diagram's A, B, C, D compare with a state-space block's: None if A or B differ;
    C and D are compared on the outputs both have."""
    try:
        A1, B1, A2, B2 = (np.asarray(v, dtype=float) for v in (diagram["A"], diagram["B"], ss["A"], ss["B"]))
    except (TypeError, ValueError, KeyError):
        return None
    if A1.shape != A2.shape or B1.shape != B2.shape or not (np.array_equal(A1, A2) and np.array_equal(B1, B2)):
        return None
    shared = [y for y in diagram["outputs"] if y in (ss.get("outputs") or [])]
    if not shared:
        return None
    C1, D1 = np.asarray(diagram["C"], dtype=float), np.asarray(diagram["D"], dtype=float)
    C2, D2 = np.asarray(ss["C"], dtype=float), np.asarray(ss["D"], dtype=float)
    i1 = [diagram["outputs"].index(y) for y in shared]
    i2 = [ss["outputs"].index(y) for y in shared]
    return {"outputs": shared, "C": bool(np.array_equal(C1[i1], C2[i2])), "D": bool(np.array_equal(D1[i1], D2[i2])),
            "inputs": (list(diagram["inputs"]), list(ss.get("inputs") or []))}


def _responses(runs, others, outputs) -> list[dict[str, Any]]:
    """Case by case (same case name, same output times): max |difference| of the shared outputs."""
    by_name = {r.case: r for r in others if r.ok}
    rows = []
    for r in runs:
        o = by_name.get(r.case)
        if o is None or not r.ok or r.t.shape != o.t.shape or not np.array_equal(r.t, o.t):
            continue
        for y in outputs:
            a, b = r.column(y), o.column(y)
            if a is None or b is None:
                continue
            diff = float(np.max(np.abs(a - b))) if a.size else 0.0
            scale = float(np.max(np.abs(b))) if b.size else 0.0
            ulps = diff / (EPS * scale) if scale > 0 else (0.0 if diff == 0 else math.inf)
            rows.append({"case": r.case, "output": y, "points": int(r.t.size), "max_diff": diff, "ulps": ulps})
    return rows


def _bode_figure(stem: str, case: str, bode: dict, margins: list[dict], loop: dict | None) -> FigureSpec | None:
    try:
        w = np.asarray(bode["w"], dtype=float)
        channels = bode["channels"]
    except (KeyError, TypeError, ValueError):
        return None
    mag, phase = [], []
    for k, ch in enumerate(channels):
        color = SERIES_COLORS[k % len(SERIES_COLORS)]
        label = f"{ch['input']} → {ch['output']}"
        mag.append(Line(w, np.asarray(ch["magnitude_db"], dtype=float), label, color))
        phase.append(Line(w, np.asarray(ch["phase_deg"], dtype=float), label, color))
    if loop and isinstance(loop.get("bode"), dict):
        lw = np.asarray(loop["bode"]["w"], dtype=float)
        label = f"loop gain L (opened at {loop['at']})"
        mag.append(Line(lw, np.asarray(loop["bode"]["magnitude_db"], dtype=float), label, "#000000", "--"))
        phase.append(Line(lw, np.asarray(loop["bode"]["phase_deg"], dtype=float), label, "#000000", "--"))
        margins = [loop]
    crossings = tuple(RefLine(m["gain_crossover"], f"gain crossover {m['gain_crossover']:.3g} rad/s", axis="x",
                              color="#666666", linestyle=":")
                      for m in margins[:1] if m.get("gain_crossover") is not None
                      and math.isfinite(m["gain_crossover"]))
    panels = (Panel("Magnitude", "frequency ω (rad/s)", "|G(jω)| (dB)", tuple(mag), xscale="log",
                    reflines=(RefLine(0.0, "0 dB", color="#999999", linestyle="-"),) + crossings, legend=False),
              Panel("Phase", "frequency ω (rad/s)", "phase of G(jω) (degrees)", tuple(phase), xscale="log",
                    reflines=(RefLine(-180.0, "-180°", color="#999999", linestyle="-"),) + crossings, legend=False))
    return FigureSpec(name=f"{stem}-bode", caption=f"Bode plot of the linear model ({case}): magnitude in dB "
                      "and phase in degrees over frequency in rad/s.",
                      alt=f"Bode magnitude and phase plots of {len(channels)} channel(s).", panels=panels,
                      columns=2, panel_height=2.6, legend=True)  # one legend above both, off the curves


def control_view(stem: str, runs, groups) -> ControlView | None:
    """The diagram and analysis parts of one experiment (None if it has neither)."""
    diagram_run = next((r for r in runs if isinstance(r.extra.get("diagram"), dict)), None)
    analysis_run = next((r for r in runs if isinstance(r.extra.get("analysis"), dict)), None)
    network_run = next((r for r in runs if isinstance(r.extra.get("network"), dict)), None)
    if diagram_run is None and analysis_run is None and network_run is None:
        return None
    view = ControlView(case=(analysis_run or diagram_run or network_run).case)
    if network_run is not None:
        n = network_run.extra["network"]
        view.network_dot = n.get("dot") if isinstance(n.get("dot"), str) else None
        view.derivation = [(str(h), [str(line) for line in lines]) for h, lines in n.get("sections", [])]
    if diagram_run is not None:
        d = diagram_run.extra["diagram"]
        view.dot = d.get("dot") if isinstance(d.get("dot"), str) else None
        view.linear = bool(d.get("linear"))
        if view.linear and all(k in d for k in ("A", "B", "C", "D", "states", "inputs", "outputs")):
            view.matrices = [(name, *_matrix_rows(d[name], rows, cols)) for name, rows, cols in (
                ("A", d["states"], d["states"]), ("B", d["states"], d["inputs"]),
                ("C", d["outputs"], d["states"]), ("D", d["outputs"], d["inputs"]))]
            for g in groups:
                if g.runs is runs:
                    continue
                ss = next((_ss_of(r.config) for r in g.runs if _ss_of(r.config)), None)
                same = _same_system(d, ss) if ss else None
                if same is not None:
                    rows = _responses(runs, g.runs, same["outputs"])
                    same.update({"experiment": g.name, "title": g.title, "responses": rows,
                                 "identical": bool(rows) and all(r["max_diff"] == 0 for r in rows)})
                    view.equivalent.append(same)
    if analysis_run is not None:
        a = analysis_run.extra["analysis"]
        op = a.get("operating_point")
        if isinstance(op, dict):
            view.operating_point = [*((k, v) for k, v in op.get("x", {}).items()),
                                    *((k, v) for k, v in op.get("u", {}).items())]
        view.transfer_functions = list(a.get("transfer_functions", []))
        view.poles = list(a.get("poles", []))
        view.zeros = [(ch, ", ".join(_complex_text(z) for z in zs) or "none")
                      for ch, zs in (a.get("zeros") or {}).items()]
        view.step_info = list(a.get("step_info", []))
        view.margins = list(a.get("margins", []))
        view.loop = a.get("loop") if isinstance(a.get("loop"), dict) else None
        if "bode" in a:
            view.bode_figure = _bode_figure(stem, analysis_run.case, a["bode"], view.margins, view.loop)
    return view


def _complex_text(z: dict) -> str:
    re_, im = float(z.get("re", 0.0)), float(z.get("im", 0.0))
    return f"{re_:.4g}" if im == 0 else f"{re_:.4g} {'+' if im > 0 else '−'} {abs(im):.4g}j"
