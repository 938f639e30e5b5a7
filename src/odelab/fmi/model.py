"""What an exported FMU holds, taken from one loaded case: its variables and its generated C.

A case carries its system's compiled description (:class:`~odelab.solvers.compiled.CompiledSystem`:
checked equations with their parameters, a state-space model's matrices, a diagram's generated
body) and its input signals. The right-hand side and the outputs are written as numba source by
odelab's own generators, then re-emitted as C by :mod:`odelab.fmi.ccode`. Everything the C
reads at run time is the vector ``p``: the tunable parameters first (FMI parameters, by name),
then the numbers of the signals and blocks (fixed), exactly the layout of the compiled backend.
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field

import numpy as np

from odelab.exceptions import InputError
from odelab.fmi.ccode import c_function, c_number
from odelab.solvers.optionset import DEFAULT_RTOL
from odelab.solvers.registry import METHODS

__all__ = ["ExportModel", "Variable", "model_of_case", "refusal"]

#: The largest system exported (states + outputs + parameters + numbers of the signals).
MAX_VARIABLES = 20_000


@dataclass(frozen=True)
class Variable:
    name: str
    vr: int
    causality: str  # "parameter", "local", "output"
    variability: str  # "fixed", "tunable", "continuous"
    start: float | None = None
    initial: str | None = None  # "exact", "calculated", "approx"
    unit: str | None = None
    description: str | None = None
    derivative: int | None = None  # the 1-based index of the state this is the derivative of


@dataclass(frozen=True)
class ExportModel:
    """Everything the C generator, the XML writer and the build need."""

    name: str
    identifier: str
    description: str
    states: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: tuple[str, ...]
    variables: tuple[Variable, ...]
    p: np.ndarray  # the run-time vector: parameters (by their offset), then signals' and blocks' numbers
    parameter_offset: int  # p[parameter_offset + i] is parameters[i]
    x0: np.ndarray
    c_rhs: str
    c_outputs: str
    c_indicators: str
    n_indicators: int
    time_events: np.ndarray  # where an input jumps (an FMI time event: ME stops there, CS's integrator too)
    start: float
    stop: float
    tolerance: float
    step: float  # the Co-Simulation communication step written as the DefaultExperiment's stepSize
    units: dict[str, str] = field(default_factory=dict)

    @property
    def guid(self) -> str:
        digest = hashlib.sha256((self.c_rhs + self.c_outputs + self.c_indicators + repr(self.p.tolist()) + repr(self.variables))
                                .encode()).hexdigest()
        return "{" + f"{digest[:8]}-{digest[8:12]}-{digest[12:16]}-{digest[16:20]}-{digest[20:32]}" + "}"


def refusal(case) -> str | None:
    """Why this case's system cannot be exported (None if it can)."""
    problem, config = case.problem, case.config
    system = config.get("system", {})
    if "function" in system:
        return ("its system is a Python function, whose code odelab cannot write as C: write it as "
                "[system.equations] to export it")
    if getattr(METHODS.get(problem.method), "delays", False) or "history" in config:
        return "it is a delay equation (lag), whose history an FMU's interface cannot carry"
    if problem.system.events is not None:
        return "its [events] (an FMU's state events with resets) are not exported yet; remove [events] to export"
    if problem.system.diagram is not None:
        return _diagram_refusal(problem.system.diagram)
    if problem.system.fmu is not None:
        return "it is an FMU already"
    if problem.system.compiled is None:
        return "odelab does not generate its right-hand side"
    return problem.system.compiled.why_not()


def _diagram_refusal(diagram) -> str | None:
    """Why a diagram cannot be exported: a discrete or memory block, an algebraic loop, a block
    odelab does not generate, a vector signal (a zero-crossing block goes: its switching
    functions become the FMU's event indicators)."""
    w = diagram.wiring
    if w.torn:
        return f"its algebraic loop {w.loops[0]} is solved by Newton's method, which the generator does not write"
    for name in w.order:
        b = w.blocks[name]
        if b.DISCRETE:
            return f"its block `{name}` ({b.TYPE}) is discrete; discrete blocks are not exported yet"
        if b.STATEFUL_MODE:
            return f"its block `{name}` ({b.TYPE}) switches with memory, which the generator does not write yet"
        if b.SOURCE:
            continue
        if not b.generated:
            return f"its block `{name}` ({b.TYPE}) is evaluated in Python only"
        if any(w.widths[port] != 1 for port in w.sources[name]) or b.nstates > 1 and b.TYPE == "integrator":
            return f"its block `{name}` carries a vector signal, which the generator does not write"
    return None


def _diagram_lines(diagram, offset: int) -> tuple[list[str], list[str], list[str], list[float]]:
    """The rhs body, the outputs' and the event indicators' lines of a diagram (numba style, as
    :func:`odelab.systems.diagram.codegen.diagram_source` writes them), its numbers from ``_p[offset]``.
    The switching functions of its saturations and dead zones (input minus each limit) are the
    event indicators."""
    from odelab.systems.diagram.codegen import Writer

    w = diagram.wiring
    data: list[float] = []
    g = Writer(diagram, data, offset)
    port: dict[tuple[str, int], str] = {(name, 0): f"_u{i}" for i, name in enumerate(diagram.inputs)}
    crossings: list[str] = []
    for name in w.order:
        b = w.blocks[name]
        if b.SOURCE:
            continue
        ins = [port[p] for p in w.sources[name]] if b.feedthrough else []
        for i, v in enumerate(b.generate_outputs(g, name, ins)):
            port[(name, i)] = v
        if b.ZC and b.TYPE in ("saturation", "dead-zone"):
            crossings += [f"({ins[0]} - {g.number(b.hi)})", f"({ins[0]} - {g.number(b.lo)})"]
    shared = list(g.lines)
    for name in diagram.slices:
        b = w.blocks[name]
        b.generate_derivative(g, name, [port[p] for p in w.sources[name]])
    outputs = shared + [f"    _out[{k}] = {port[p]}" for k, p in enumerate(w.outputs.values())]
    indicators = shared + [f"    _out[{k}] = {text}" for k, text in enumerate(crossings)] if crossings else []
    return g.lines, outputs, indicators, data


def _identifier(name: str) -> str:
    ident = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not ident or not (ident[0].isalpha()):
        ident = "m_" + ident
    return ident[:60]


def _linear_lines(problem, compiled, data_offset: int) -> tuple[list[str], list[str], list[float]]:
    """Straight-line numba-style source of x' = A x + B u and y = C x + D u, numbers as p entries."""
    ss = problem.system.model
    A, B = np.asarray(ss.A, float), np.asarray(ss.B, float)
    C, D = np.asarray(ss.C, float), np.asarray(ss.D, float)
    data: list[float] = []
    nu = len(problem.inputs)

    def number(value: float) -> str:
        data.append(float(value))
        return f"_p[{data_offset + len(data) - 1}]"

    def rows(M, N) -> list[str]:
        out = []
        for i in range(M.shape[0]):
            text = "0.0"
            for j in range(M.shape[1]):
                text = f"({text} + ({number(M[i, j])} * _y[{j}]))"
            for j in range(nu if N is not None and N.size else 0):
                text = f"({text} + ({number(N[i, j])} * _u{j}))"
            out.append(f"    _out[{i}] = {text}")
        return out

    return rows(A, B), rows(C, D) if C.size else [], data


def _equation_lines(problem, compiled, offset: int) -> list[str]:
    """The outputs of an equations system (or a derived network), from their checked expressions."""
    from odelab.expressions import parse_expression
    from odelab.expressions.parse import python_name
    from odelab.solvers.compiled.codegen import expression_source

    texts = problem.output_texts
    known = {"t", *compiled.states, *compiled.parameters, *compiled.inputs}
    lines = [f"    {python_name(name)} = _u{i}" for i, name in enumerate(compiled.inputs)]
    lines += [f"    {python_name(name)} = _y[{i}]" for i, name in enumerate(compiled.states)]
    lines += [f"    {name} = _p[{offset + i}]" for i, name in enumerate(compiled.parameters)]
    for i, name in enumerate(problem.outputs):
        parsed = parse_expression(texts[name], key=f"system.outputs.{name}", names=known)
        unknown = sorted(set(parsed.names) - known)
        if unknown:
            raise InputError(f"`system.outputs.{name}` uses `{unknown[0]}`, which the FMU does not have.",
                             key=f"system.outputs.{name}")
        lines.append(f"    _out[{i}] = {expression_source(parsed)}")
    return lines


def model_of_case(case, output_texts: dict[str, str] | None = None, name: str | None = None) -> ExportModel:
    """The :class:`ExportModel` of one loaded case (a :class:`~odelab.experiment.cases.Case`)."""
    from odelab.solvers.compiled.inputs import inputs_source

    problem = case.problem
    reason = refusal(case)
    if reason:
        raise InputError(f"case {case.name!r} of {case.experiment} cannot be exported as an FMU: {reason}.",
                         key="system")
    compiled = problem.system.compiled
    if compiled is None and problem.system.diagram is not None:
        from odelab.solvers.compiled import CompiledSystem

        compiled = CompiledSystem.generated(problem.states, problem.system.diagram.inputs, (), ())  # its inputs' count
    n = len(problem.states)
    if n == 0:
        raise InputError("a system without states cannot be exported.", key="system.states")
    has_inputs = bool(compiled.inputs)
    first = 2 if has_inputs else 0
    config = case.config
    system = config.get("system", {})
    indicator_body: list[str] = []
    if problem.system.diagram is not None:
        parameters = ()
        has_inputs = bool(problem.system.diagram.inputs)
        first = 2 if has_inputs else 0
        rhs_lines, out_lines, indicator_lines, numbers = _diagram_lines(problem.system.diagram, first)
        data = []
        input_lines = inputs_source(problem.system.signals, data, first + len(numbers)) if has_inputs else []
        p = np.array([-math.inf, math.inf][:first] + numbers + data, dtype=float)
        rhs_body = input_lines + rhs_lines
        out_body = input_lines + out_lines
        indicator_body = input_lines + indicator_lines if indicator_lines else []
    elif compiled.kind == "linear":
        parameters: tuple[str, ...] = ()
        data: list[float] = []
        input_lines = inputs_source(compiled.signals, data, first) if has_inputs else []
        rhs_lines, out_lines, numbers = _linear_lines(problem, compiled, first + len(data))
        p = np.array([-math.inf, math.inf][:first] + data + numbers, dtype=float)
        rhs_body = input_lines + rhs_lines
        out_body = input_lines + out_lines
    else:
        parameters = tuple(compiled.parameters)
        p = compiled.parameter_vector(-math.inf, math.inf) if has_inputs else compiled.values.copy()
        data = []
        input_lines = inputs_source(compiled.signals, data, first + len(parameters)) if has_inputs else []
        module = compiled.source()
        outputs = dict(system.get("outputs") or {}) if isinstance(system.get("outputs"), dict) else {}
        outputs.update(output_texts or {})
        problem_view = _OutputView(problem.outputs, outputs)
        out_body = input_lines + _equation_lines(problem_view, compiled, first)
        rhs_body = None
    if len(p) + 2 * n + len(problem.outputs) > MAX_VARIABLES:
        raise InputError(f"the system has {len(p) + 2 * n:,} variables and numbers; an exported FMU holds at most "
                         f"{MAX_VARIABLES:,}.", key="system")
    size = {"y": n, "p": max(len(p), 1), "out": n}
    head = "def rhs(t, _y, _p, _out):\n"
    if rhs_body is not None:
        c_rhs = c_function(head + "\n".join(rhs_body) + "\n", "rhs", "model_rhs", size, "the right-hand side")
    else:
        c_rhs = c_function(module, "rhs", "model_rhs", size, "the right-hand side")
    ny = len(problem.outputs)
    c_out = c_function("def outputs(t, _y, _p, _out):\n" + "\n".join(out_body or ["    pass"]) + "\n", "outputs",
                       "model_outputs", {**size, "out": max(ny, 1)}, "the outputs") if ny else \
        "static void model_outputs(double t, const double *y, const double *p, double *out)\n" \
        "{\n    (void)t; (void)y; (void)p; (void)out;\n}\n"
    nz = sum(1 for line in indicator_body if line.lstrip().startswith("_out["))
    c_ind = c_function("def indicators(t, _y, _p, _out):\n" + "\n".join(indicator_body) + "\n", "indicators",
                       "model_indicators", {**size, "out": max(nz, 1)}, "the event indicators") if nz else \
        "static void model_indicators(double t, const double *y, const double *p, double *out)\n" \
        "{\n    (void)t; (void)y; (void)p; (void)out;\n}\n"
    breaks: list[float] = []
    t0, tf = float(problem.tspan[0]), float(problem.tspan[-1])
    for signal in problem.system.signals:
        breaks.extend(float(b) for b in signal.breakpoints(t0, tf))
    units = dict(config.get("units") or {})
    variables = _variables(problem, parameters, p, first, units)
    rtol = float(problem.options.get("rtol", config.get("solver", {}).get("rtol", DEFAULT_RTOL)) or DEFAULT_RTOL)
    step = float(problem.options.get("h") or (tf - t0) / 500.0)
    title = config.get("title") or case.experiment
    description = " ".join(filter(None, [title, config.get("description")]))
    model_name = name or case.experiment
    return ExportModel(name=model_name, identifier=_identifier(model_name), description=description,
                       states=tuple(problem.states), outputs=tuple(problem.outputs), parameters=parameters,
                       variables=variables, p=np.asarray(p, dtype=float), parameter_offset=first,
                       x0=np.asarray(problem.x0, dtype=float), c_rhs=c_rhs, c_outputs=c_out,
                       c_indicators=c_ind, n_indicators=nz,
                       time_events=np.unique(np.array(breaks, dtype=float)), start=t0, stop=tf, tolerance=rtol,
                       step=step, units={k: str(v) for k, v in units.items()})


class _OutputView:
    def __init__(self, outputs, texts):
        self.outputs = outputs
        self.output_texts = texts


def _variables(problem, parameters, p, first: int, units: dict) -> tuple[Variable, ...]:
    """States (value references 0..n-1), their derivatives (n..2n-1), outputs, then parameters."""
    n = len(problem.states)
    out: list[Variable] = []
    for i, s in enumerate(problem.states):
        out.append(Variable(s, i, "local", "continuous", float(problem.x0[i]), "exact", units.get(s),
                            f"state {s}"))
    for i, s in enumerate(problem.states):
        unit = None
        if units.get(s) and units.get("t"):
            unit = f"{units[s]}/{units['t']}"
        out.append(Variable(f"der({s})", n + i, "local", "continuous", None, None, unit, f"d({s})/dt",
                            derivative=i + 1))
    base = 2 * n
    for i, y in enumerate(problem.outputs):
        out.append(Variable(y, base + i, "output", "continuous", None, None, units.get(y), f"output {y}"))
    base += len(problem.outputs)
    for i, name in enumerate(parameters):
        out.append(Variable(name, base + i, "parameter", "tunable", float(p[first + i]), "exact", units.get(name),
                            f"parameter {name}"))
    return tuple(out)


def c_model(m: ExportModel, fmi: int = 2) -> str:
    """``model.c``: the generated part of the FMU's C sources (the runtime is ``odelab_fmi2.c`` or
    ``odelab_fmi3.c``, each on ``odelab_core.c``)."""
    def array(name: str, values) -> str:
        values = list(values) or [0.0]
        body = ",\n    ".join(", ".join(c_number(v) for v in values[i:i + 4]) for i in range(0, len(values), 4))
        return f"static const double {name}[] = {{\n    {body}\n}};\n"

    lines = [
        "/* Generated by odelab from its checked expression trees: every name and number below was",
        "   written by odelab's generator, none pasted from the experiment file. */",
        "#include \"odelab_model.h\"",
        "",
        f"#define MODEL_IDENTIFIER_STRING \"{m.identifier}\"",
        f"#define MODEL_GUID \"{m.guid}\"",
        f"#define NX {len(m.states)}",
        f"#define NY {len(m.outputs)}",
        f"#define NPAR {len(m.parameters)}",
        f"#define NP {max(len(m.p), 1)}",
        f"#define PAR_OFFSET {m.parameter_offset}",
        f"#define NTE {len(m.time_events)}",
        f"#define NZ {m.n_indicators}",
        f"#define DEFAULT_TOLERANCE {c_number(m.tolerance)}",
        f"#define DEFAULT_START {c_number(m.start)}",
        f"#define DEFAULT_STOP {c_number(m.stop)}",
        "",
        array("P_START", m.p),
        array("X_START", m.x0),
        array("TIME_EVENTS", m.time_events),
        m.c_rhs,
        m.c_outputs,
        m.c_indicators,
        f"#include \"odelab_fmi{fmi}.c\"",
        "",
    ]
    return "\n".join(lines)
