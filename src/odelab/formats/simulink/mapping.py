"""Simulink blocks -> odelab's diagram blocks: one small function per block type, with Simulink's defaults.

Each function receives a :class:`~odelab.formats.simulink.translate.BlockContext` and adds the
odelab block (or blocks) that compute the same signal: ``c.add(spec, inputs)`` with the spec an
experiment file's block table, ``c.out(port, ref)`` where a Simulink output port is found, and
``c.route(port, input)`` for a block that only routes a signal (Goto, a conversion). A parameter
the model leaves unset takes Simulink's documented default (``c.p("Time", "1")``: a Step's time
is 1), from the block's own text, else the model's ``BlockParameterDefaults``, else the default
written here. What cannot be translated is a gap with what to do instead (``c.gap(...)``).

:data:`BY_TYPE` maps a ``BlockType`` to its function, :data:`BY_SOURCE` a library link's
``SourceBlock`` (``simulink/Continuous/PID Controller``) to its function.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["BY_SOURCE", "BY_TYPE", "PHYSICAL_LIBRARIES", "PHYSICAL_TYPES", "SINKS", "mapped_types"]

#: blocks of the physical-modelling libraries (Simscape and its electrical, mechanical, fluid families)
PHYSICAL_TYPES = ("SimscapeBlock", "PMComponent", "PMIOPort", "SimscapeComponentBlock", "SimscapeMultibodyBlock",
                  "PMConnectionPort", "ConnectionPort")
PHYSICAL_LIBRARIES = ("fl_lib", "ee_lib", "elec_lib", "foundation", "powerlib", "sps_lib", "spsPowerguiLib",
                      "nesl_utility", "sm_lib", "sdl_lib", "sh_lib", "ssc_lib", "simscape", "mblibv1", "drive_lib",
                      "electricdrivelib", "spsMeasurementsLib", "physmod")

#: libraries whose blocks check or show a signal without changing the simulation (Model Verification, the
#: Control System Toolbox's Check ... blocks, dashboards): ignored with a note
OBSERVERS = ("slctrlblks", "Model Verification", "simulink/Dashboard", "hmilib", "Check ", "Assertion")

#: blocks that only show or store a signal: each of their inputs becomes an output of the experiment
SINKS = ("Scope", "Display", "ToWorkspace", "XYGraph", "FloatingScope", "ToFile", "Terminator", "Outport")


# --- sources ----------------------------------------------------------------------------------------

def _step(c):
    c.add({"type": "step", "time": c.scalar("Time", "1"), "initial": c.scalar("Before", "0"),
           "final": c.scalar("After", "1")})
    c.held("SampleTime")


def _constant(c):
    value = c.p("Value", "1")
    if value.num.size == 1:
        c.add({"type": "constant", "value": c.item(value)})
        return
    parts = [c.add({"type": "constant", "value": c.item(value, i)}, name=f"{c.name}_{i + 1}", out=None)
             for i in range(value.num.size)]
    c.add({"type": "mux"}, inputs=[("ref", p) for p in parts])


def _ground(c):
    c.add({"type": "constant", "value": 0.0})


def _sine(c):
    if c.text("SineType", "Time based").lower().startswith("sample"):
        c.gap("a sample-based Sine Wave: set Sine type to Time based (frequency in rad/s), or write the samples "
              "as a lookup table", "sine")
        return
    c.add({"type": "sine", "amplitude": c.scalar("Amplitude", "1"), "frequency": c.scalar("Frequency", "1"),
           "phase": c.scalar("Phase", "0"), "bias": c.scalar("Bias", "0")})
    c.held("SampleTime")


def _pulse(c):
    if c.text("PulseType", "Time based").lower().startswith("sample"):
        c.gap("a sample-based Pulse Generator: set Pulse type to Time based (period and delay in seconds)", "pulse")
        return
    width = c.p("PulseWidth", "5")
    c.add({"type": "pulse", "amplitude": c.scalar("Amplitude", "1"), "period": c.scalar("Period", "10"),
           "width": c.item(width) / 100.0 if width.sym is None else f"({c.item(width)}) / 100",
           "delay": c.scalar("PhaseDelay", "0")})


def _ramp(c):
    c.add({"type": "ramp", "slope": c.scalar("slope", "1"), "start": c.scalar("start", "0"),
           "initial": c.scalar("X0", "0")})


def _clock(c):
    c.add({"type": "clock"})


def _digital_clock(c):
    clock = c.add({"type": "clock"}, name=f"{c.name}_t", out=None)
    c.add({"type": "zero-order-hold", "sample_time": c.sample("SampleTime", "1")}, inputs=[("ref", clock)])


def _random(c):
    c.add({"type": "random-number", "mean": c.scalar("Mean", "0"), "variance": c.scalar("Variance", "1"),
           "seed": c.scalar("Seed", "0"), "sample_time": c.sample("SampleTime", "0.1")})


def _uniform(c):
    c.add({"type": "uniform-random-number", "minimum": c.scalar("Minimum", "-1"), "maximum": c.scalar("Maximum", "1"),
           "seed": c.scalar("Seed", "0"), "sample_time": c.sample("SampleTime", "0.1")})


def _white_noise(c):
    c.add({"type": "band-limited-white-noise", "power": c.scalar("Cov", "[0.1]"), "seed": c.scalar("seed", "[23341]"),
           "sample_time": c.sample("Ts", "0.1")})


# --- math ---------------------------------------------------------------------------------------------

def _gain(c):
    gain = c.p("Gain", "1")
    mult = c.text("Multiplication", "Element-wise(K.*u)")
    if gain.num.size > 1 and mult.startswith("Matrix(u*K)"):
        c.add({"type": "gain", "gain": c.matrix_of(gain, transpose=True)}, inputs=[1])
        return
    c.add({"type": "gain", "gain": c.item(gain) if gain.num.size == 1 else
           (c.matrix_of(gain) if mult.startswith("Matrix") else c.list_of(gain))}, inputs=[1])


def _signs(text: str, count: int | None = None) -> str:
    text = text.strip()
    if text.isdigit():
        return "+" * int(text)
    return "".join(ch for ch in text if ch in "+-")


def _sum(c):
    signs = _signs(c.text("Inputs", "|++"))
    if not signs:
        c.gap(f"the Sum's signs {c.text('Inputs', '')!r} are not + and -", "sum")
        return
    if len(signs) == 1 and signs == "+":
        c.add({"type": "sum", "signs": "+"}, inputs=[1])
        c.note("a Sum of one input adds a vector's elements; odelab passes a scalar through (the same for a scalar)")
        return
    c.add({"type": "sum", "signs": signs}, inputs=list(range(1, len(signs) + 1)))


def _product(c):
    text = c.text("Inputs", "2").strip()
    ops = "*" * int(text) if text.isdigit() else "".join(ch for ch in text if ch in "*/")
    if not ops:
        c.gap(f"the Product's inputs {text!r} are not * and /", "product")
        return
    if c.text("Multiplication", "Element-wise(.*)").startswith("Matrix") and len(ops) > 1:
        c.note("a matrix product of scalar signals, as odelab's elementwise product")
    if ops == "*" or ops == "/":
        c.add({"type": "product", "ops": ops}, inputs=[1])
        return
    c.add({"type": "product", "ops": ops}, inputs=list(range(1, len(ops) + 1)))


def _fcn_block(c, expression: str, n: int = 1):
    c.add({"type": "fcn", "expression": expression}, inputs=list(range(1, n + 1)))


_MATH = {"exp": ("exp(u)", 1), "log": ("log(u)", 1), "10^u": ("10^u", 1), "log10": ("log10(u)", 1),
         "magnitude^2": ("u^2", 1), "square": ("u^2", 1), "pow": ("u1^u2", 2), "conj": ("u", 1),
         "reciprocal": ("1/u", 1), "hypot": ("sqrt(u1^2 + u2^2)", 2), "rem": ("rem(u1, u2)", 2),
         "mod": ("mod(u1, u2)", 2), "transpose": ("u", 1), "hermitian": ("u", 1), "sqrt": ("sqrt(u)", 1),
         "signedsqrt": ("sign(u)*sqrt(abs(u))", 1), "rsqrt": ("1/sqrt(u)", 1)}
_TRIG = {f: (f"{f}(u)", 1) for f in ("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh")}
_TRIG.update({"atan2": ("atan2(u1, u2)", 2), "asinh": ("log(u + sqrt(u^2 + 1))", 1),
              "acosh": ("log(u + sqrt(u^2 - 1))", 1), "atanh": ("0.5*log((1 + u)/(1 - u))", 1)})


def _operator(table, default):
    def translate(c):
        op = c.text("Operator", default).strip()
        op = op if op in table else op.lower()  # "rSqrt", "signedSqrt"
        if op not in table:
            c.gap(f"the operator {op!r}: write it as a Fcn block (u(1)...)", "fcn")
            return
        _fcn_block(c, *table[op])
    return translate


def _fcn(c):
    text = c.text("Expr", c.text("Expression", "sin(u(1)*exp(2.3*(-u(2))))"))
    expression = c.fcn_expression(text)
    if expression is None:
        return
    c.add({"type": "fcn", "expression": expression}, inputs=[1])


def _abs(c):
    c.add({"type": "abs"}, inputs=[1])


def _sign(c):
    c.add({"type": "sign"}, inputs=[1])


def _minmax(c):
    n = c.inputs_count("Inputs", "1")
    c.add({"type": "min-max", "function": c.text("Function", "min").strip().lower()}, inputs=list(range(1, n + 1)))


def _bias(c):
    bias = c.p("Bias", "0")
    c.add({"type": "fcn", "expression": f"u + ({c.text_item(bias)})"}, inputs=[1])


def _unary_minus(c):
    c.add({"type": "gain", "gain": -1.0}, inputs=[1])


_RELATIONS = {"==": "==", "~=": "!=", "<": "<", "<=": "<=", ">": ">", ">=": ">="}


def _relational(c):
    op = c.text("Operator", ">=").strip()
    if op not in _RELATIONS:
        c.gap(f"the relational operator {op!r}", "fcn")
        return
    _fcn_block(c, f"u1 {_RELATIONS[op]} u2", 2)


def _compare_constant(c):
    op = c.text("relop", "<=").strip()
    const = c.p("const", "3.0")
    if op not in _RELATIONS:
        c.gap(f"the relational operator {op!r}", "fcn")
        return
    c.add({"type": "fcn", "expression": f"u {_RELATIONS[op]} ({c.text_item(const)})"}, inputs=[1])


def _compare_zero(c):
    op = c.text("relop", ">=").strip()
    c.add({"type": "fcn", "expression": f"u {_RELATIONS.get(op, '>=')} 0"}, inputs=[1])


def _logic(c):
    op = c.text("Operator", "AND").strip().upper()
    n = int(c.text("Inputs", "2")) if c.text("Inputs", "2").strip().isdigit() else 2
    args = [f"(u{i + 1} != 0)" for i in range(n)] if n > 1 else ["(u != 0)"]
    table = {"AND": " * ".join(args), "NAND": f"1 - {' * '.join(args)}", "OR": f"max({', '.join(args)}, 0)",
             "NOR": f"1 - max({', '.join(args)}, 0)", "NOT": "(u == 0)", "XOR": f"mod({' + '.join(args)}, 2)"}
    if op not in table:
        c.gap(f"the logical operator {op!r}", "fcn")
        return
    _fcn_block(c, table[op], n if op != "NOT" else 1)


def _polynomial(c):
    coefs = c.p("coefs", "[+2.081618890e-19, -1.441693666e-14, +4.719686976e-10, -8.536869453e-06, "
                "+1.621573104e-01, -8.087801117e+01]")
    terms = [c.text_item(coefs, i) for i in range(coefs.num.size)]
    n = len(terms) - 1
    c.add({"type": "fcn", "expression": " + ".join(f"({t})*u^{n - i}" for i, t in enumerate(terms))}, inputs=[1])


# --- continuous -----------------------------------------------------------------------------------------

def _integrator(c):
    if c.text("ExternalReset", "none").lower() != "none":
        c.gap("an Integrator with an external reset: write the reset as an [events] table of an ODE file", "integrator")
        return
    external = c.text("InitialConditionSource", "internal").lower() != "internal"
    spec = {"type": "integrator", "initial": 0.0 if external else c.numbers("InitialCondition", "0")}
    if external:  # the initial condition is input 2: a constant there is the initial value (wiring.finish)
        c.initial_from(2)
    if c.text("LimitOutput", "off").lower() == "on":
        upper, lower = c.p("UpperSaturationLimit", "inf"), c.p("LowerSaturationLimit", "-inf")
        if not (upper.sym is None and math.isinf(float(upper.num.reshape(-1)[0]))):
            spec["upper"] = c.item(upper)
        if not (lower.sym is None and math.isinf(float(lower.num.reshape(-1)[0]))):
            spec["lower"] = c.item(lower)
    if c.text("ZeroCross", "on").lower() == "off" and ("upper" in spec or "lower" in spec):
        spec["zero_crossing"] = False
    c.add(spec, inputs=[1])


def _second_order_integrator(c):
    """x'' = u: two integrators, dx/dt (port 2) and x (port 1), with the block's initial conditions."""
    for key in ("ICSourceX", "ICSourceDXDT"):
        if c.text(key, "internal").lower() != "internal":
            c.gap(f"a Second-Order Integrator whose {key} is external: give its initial conditions in the block",
                  "integrator")
            return
    if c.text("LimitX", "off").lower() == "on" or c.text("LimitDXDT", "off").lower() == "on":
        c.gap("a Second-Order Integrator with limits: write it as two integrators with lower/upper", "integrator")
        return
    rate = c.add({"type": "integrator", "initial": c.numbers("ICDXDT", "0")}, inputs=[1], name=f"{c.name}_dxdt", out=2)
    c.add({"type": "integrator", "initial": c.numbers("ICX", "0")}, inputs=[("ref", rate)], out=1)
    c.note(f"two integrators: `{rate}` (dx/dt, its second output) and `{c.name}` (x)")


def _signal_generator(c):
    wave = c.text("WaveForm", "sine").strip().lower()
    amplitude, frequency = c.p("Amplitude", "1"), c.p("Frequency", "1")
    hertz = c.text("Units", "rad/sec").strip().lower().startswith("hertz")
    w = f"2*pi*({c.text_item(frequency)})" if hertz else f"({c.text_item(frequency)})"
    a = c.text_item(amplitude)
    if wave == "sine":
        c.add({"type": "sine", "amplitude": c.item(amplitude), "frequency": c.item(frequency) * 2 * math.pi
               if hertz and frequency.sym is None else (w if frequency.sym is not None else c.item(frequency))})
    elif wave == "square":
        c.add({"type": "expression", "expression": f"({a}) * square({w} * t)"})
    elif wave == "sawtooth":
        c.add({"type": "expression", "expression": f"({a}) * sawtooth({w} * t)"})
    else:
        c.gap(f"a Signal Generator of {wave} waves: use a Random Number block", "random-number")


def _derivative(c):
    c.add({"type": "derivative"}, inputs=[1])
    c.note("the Derivative block is Simulink's: du/dt from the last two points the solver accepted, a first-order "
           "approximation, zero at the first step (see the derivative block in docs/blocks.md)")


def _transfer_fcn(c):
    c.add({"type": "transfer-fcn", "num": c.numbers("Numerator", "[1]", vector=True),
           "den": c.numbers("Denominator", "[1 1]", vector=True)}, inputs=[1])


def _zero_pole(c):
    zeros, poles, gain = c.p("Zeros", "[1]"), c.p("Poles", "[0 -1]"), c.p("Gain", "[1]")
    if zeros.sym is not None or poles.sym is not None or gain.sym is not None:
        c.gap("a Zero-Pole block of parameters: write it as a Transfer Fcn of the same parameters", "transfer-fcn")
        return

    num = float(gain.num.reshape(-1)[0]) * np.real(np.poly(zeros.num.reshape(-1)))
    den = np.real(np.poly(poles.num.reshape(-1)))
    c.add({"type": "transfer-fcn", "num": [float(x) for x in np.atleast_1d(num)],
           "den": [float(x) for x in np.atleast_1d(den)]}, inputs=[1])


def _state_space(c):
    A, B, C, D = (c.p(k, "1") for k in ("A", "B", "C", "D"))
    spec = {"type": "state-space", "A": c.matrix_of(A), "B": c.matrix_of(B), "C": c.matrix_of(C),
            "D": c.matrix_of(D), "initial": c.numbers("X0", "0")}
    p = C.num.shape[0]
    x0 = c.p("X0", "0")
    if x0.num.size == 1 and A.num.shape[0] > 1:
        spec["initial"] = [c.item(x0)] * A.num.shape[0]
    if p == 1:
        c.add(spec, inputs=[1])
        return
    inner = c.add(spec, inputs=[1], name=f"{c.name}_ss", out=None)
    c.add({"type": "mux"}, inputs=[("ref", f"{inner}.y{i + 1}") for i in range(p)])


def _pid(c):
    domain = c.text("TimeDomain", "Continuous-time").lower()
    form = c.text("Form", "Parallel").lower()
    kind = c.text("Controller", "PID").upper()
    for key in ("InitialConditionForIntegrator", "InitialConditionForFilter"):
        ic = c.p(key, "0")
        if ic.sym is not None or float(ic.num.reshape(-1)[0]) != 0.0:
            c.gap(f"a PID Controller with a nonzero {key}: odelab's pid starts from zero states", "pid")
            return
    gains = {k: c.item(c.p(k, d)) for k, d in (("P", "1"), ("I", "1"), ("D", "0"), ("N", "100"))}
    if "I" not in kind:
        gains["I"] = 0.0
    if "D" not in kind:
        gains["D"] = 0.0
    if "P" not in kind:
        gains["P"] = 0.0 if form == "parallel" else gains["P"]
    if form == "ideal":  # P (1 + I/s + D N s/(s + N)) in the parallel form
        p = gains["P"]
        for k in ("I", "D"):
            gains[k] = f"({p}) * ({gains[k]})" if isinstance(p, str) or isinstance(gains[k], str) else p * gains[k]
    if c.text("LimitOutput", "off").lower() == "on" or c.text("AntiWindupMode", "none").lower() != "none":
        c.gap("a PID Controller with output saturation or anti-windup: add a saturation block after a plain pid", "pid")
        return
    if domain.startswith("discrete"):
        for key in ("IntegratorMethod", "FilterMethod"):
            if c.text(key, "Forward Euler").lower() != "forward euler":
                c.gap(f"a discrete PID Controller whose {key} is {c.text(key, '')!r}: odelab's discrete-pid is "
                      "Forward Euler (Simulink's default)", "discrete-pid")
                return
        c.add({"type": "discrete-pid", **gains, "sample_time": c.sample("SampleTime", "1")}, inputs=[1])
        return
    c.add({"type": "pid", **gains}, inputs=[1])


def _transport_delay(c):
    c.add({"type": "transport-delay", "delay": c.scalar("DelayTime", "1"), "initial": c.numbers("InitialOutput", "0")},
          inputs=[1])


# --- discontinuities --------------------------------------------------------------------------------

def _saturation(c):
    c.add({"type": "saturation", "upper": c.scalar("UpperLimit", "0.5"), "lower": c.scalar("LowerLimit", "-0.5"),
           **c.zero_crossing()}, inputs=[1])


def _dead_zone(c):
    c.add({"type": "dead-zone", "lower": c.scalar("LowerValue", "-0.5"), "upper": c.scalar("UpperValue", "0.5"),
           **c.zero_crossing()}, inputs=[1])


def _switch(c):
    criteria = c.text("Criteria", "u2 >= Threshold").replace("Threshold", "threshold").strip()
    if criteria not in ("u2 >= threshold", "u2 > threshold", "u2 ~= 0"):
        c.gap(f"the Switch criterion {criteria!r}", "switch")
        return
    c.add({"type": "switch", "threshold": c.scalar("Threshold", "0"), "criteria": criteria, **c.zero_crossing()},
          inputs=[1, 2, 3])


def _relay(c):
    c.add({"type": "relay", "on_point": c.scalar("OnSwitchValue", "eps"), "off_point": c.scalar("OffSwitchValue", "eps"),
           "on_value": c.scalar("OnOutputValue", "1"), "off_value": c.scalar("OffOutputValue", "0"),
           **c.zero_crossing()}, inputs=[1])


def _rate_limiter(c):
    c.add({"type": "rate-limiter", "rising": c.scalar("RisingSlewLimit", "1"),
           "falling": c.scalar("FallingSlewLimit", "-1"), "initial": c.scalar("InitialCondition", "0")}, inputs=[1])


_INTERP = {"linear": "linear", "linear point-slope": "linear", "linear lagrange": "linear", "flat": "flat",
           "nearest": "nearest", "cubic spline": "cubic-spline", "above": None, "below": "flat"}
_EXTRAP = {"linear": "linear", "clip": "clip", "cubic spline": "linear"}


def _lookup_nd(c):
    dims = c.text("NumberOfTableDimensions", "1").strip()
    interp = _INTERP.get(c.text("InterpMethod", "Linear point-slope").strip().lower())
    extrap = _EXTRAP.get(c.text("ExtrapMethod", "Linear").strip().lower())
    if interp is None or extrap is None:
        c.gap(f"the lookup method {c.text('InterpMethod', '')!r} / {c.text('ExtrapMethod', '')!r}", "lookup-table")
        return
    if dims == "1":
        c.add({"type": "lookup-table", "breakpoints": c.numbers("BreakpointsForDimension1", "[-5:5]", vector=True),
               "table": c.numbers("Table", "tanh([-5:5])", vector=True), "interpolation": interp,
               "extrapolation": extrap}, inputs=[1])
    elif dims == "2":
        if interp == "cubic-spline":
            c.gap("a 2-D cubic-spline lookup: odelab's 2-D table is linear, flat or nearest", "lookup-table")
            return
        c.add({"type": "lookup-table", "breakpoints1": c.numbers("BreakpointsForDimension1", "[1:3]", vector=True),
               "breakpoints2": c.numbers("BreakpointsForDimension2", "[1:3]", vector=True),
               "table": c.matrix("Table", "[4 5 6;16 19 20;10 18 23]"), "interpolation": interp,
               "extrapolation": extrap}, inputs=[1, 2])
    else:
        c.gap(f"a {dims}-D lookup table: odelab's lookup-table has 1 or 2 dimensions", "lookup-table")


def _lookup_old(c):
    method = c.text("LookUpMeth", "Interpolation-Extrapolation").lower()
    extrap = "linear" if method == "interpolation-extrapolation" else "clip"
    interp = "flat" if method.startswith("use input below") else "nearest" if "nearest" in method else "linear"
    c.add({"type": "lookup-table", "breakpoints": c.numbers("InputValues", "[-5:5]", vector=True),
           "table": c.numbers("Table", c.text("OutputValues", "tanh([-5:5])"), vector=True),
           "interpolation": interp, "extrapolation": extrap}, inputs=[1])


def _lookup_2d(c):
    c.add({"type": "lookup-table", "breakpoints1": c.numbers("RowIndex", "[1:3]", vector=True),
           "breakpoints2": c.numbers("ColumnIndex", "[1:3]", vector=True),
           "table": c.matrix("Table", c.text("OutputValues", "[4 5 6;16 19 20;10 18 23]")),
           "interpolation": "linear", "extrapolation": "linear"}, inputs=[1, 2])


# --- discrete ---------------------------------------------------------------------------------------------

def _zoh(c):
    c.add({"type": "zero-order-hold", "sample_time": c.sample("SampleTime", "1")}, inputs=[1])


def _unit_delay(c):
    c.add({"type": "unit-delay", "initial": c.numbers("InitialCondition", c.text("X0", "0")),
           "sample_time": c.sample("SampleTime", "-1")}, inputs=[1])


def _memory(c):
    c.gap("a Memory block (the input at the previous solver step): use a unit-delay with a sample time", "unit-delay")


def _discrete_tf(c):
    c.add({"type": "discrete-transfer-fcn", "num": c.numbers("Numerator", "[1]", vector=True),
           "den": c.numbers("Denominator", "[1 0.5]", vector=True), "sample_time": c.sample("SampleTime", "1")},
          inputs=[1])


def _discrete_filter(c):
    num, den = c.numbers("Numerator", "[1]", vector=True), c.numbers("Denominator", "[1 2]", vector=True)
    num, den = (v if isinstance(v, list) else [v] for v in (num, den))
    n = max(len(num), len(den))  # ascending powers of 1/z: pad both to one length, as descending powers of z
    c.add({"type": "discrete-transfer-fcn", "num": num + [0.0] * (n - len(num)), "den": den + [0.0] * (n - len(den)),
           "sample_time": c.sample("SampleTime", "1")}, inputs=[1])


def _discrete_ss(c):
    A, B, C, D = (c.p(k, "1") for k in ("A", "B", "C", "D"))
    spec = {"type": "discrete-state-space", "A": c.matrix_of(A), "B": c.matrix_of(B), "C": c.matrix_of(C),
            "D": c.matrix_of(D), "initial": c.numbers("InitialCondition", c.text("X0", "0")),
            "sample_time": c.sample("SampleTime", "1")}
    if not isinstance(spec["initial"], list) and A.num.shape[0] > 1:
        spec["initial"] = [spec["initial"]] * A.num.shape[0]
    p = C.num.shape[0]
    if p == 1:
        c.add(spec, inputs=[1])
        return
    inner = c.add(spec, inputs=[1], name=f"{c.name}_ss", out=None)
    c.add({"type": "mux"}, inputs=[("ref", f"{inner}.y{i + 1}") for i in range(p)])


def _discrete_integrator(c):
    method = c.text("IntegratorMethod", "Integration: Forward Euler").lower()
    ic = c.p("InitialCondition", "0")
    if "forward euler" not in method or ic.sym is not None or float(ic.num.reshape(-1)[0]) != 0.0 \
            or c.text("ExternalReset", "none").lower() != "none" or c.text("LimitOutput", "off").lower() == "on":
        c.gap("a Discrete-Time Integrator other than Forward Euler from 0 without limits or reset: write it as a "
              "discrete-transfer-fcn", "discrete-transfer-fcn")
        return
    gain = c.p("gainval", "1.0")
    ts = c.sample("SampleTime", "1")
    step = ts[0] if isinstance(ts, list) else ts
    k = f"({c.text_item(gain)}) * ({step})" if gain.sym is not None or isinstance(step, str) else \
        float(gain.num.reshape(-1)[0]) * step
    c.add({"type": "discrete-transfer-fcn", "num": [k], "den": [1.0, -1.0], "sample_time": ts}, inputs=[1])


# --- routing and sinks ----------------------------------------------------------------------------------

def _mux(c):
    c.add({"type": "mux"}, inputs=list(range(1, c.inputs_count("Inputs", "2") + 1)))


def _demux(c):
    text = c.text("Outputs", "2").strip()
    if not text.isdigit():
        c.gap(f"a Demux into parts {text!r}: odelab's demux splits a vector into its elements", "demux")
        return
    n = int(text)
    name = c.add({"type": "demux", "outputs": n}, inputs=[1], out=None)
    for i in range(n):
        c.out(i + 1, f"{name}.{i + 1}")


def _stop(c):
    c.add({"type": "stop"}, inputs=[1], out=None)


def _pass(c):
    c.route(1, 1)


def _manual_switch(c):
    c.route(1, 1 if c.text("sw", "1").strip() == "1" else 2)
    c.note(f"a Manual Switch in position {c.text('sw', '1')}: that input passes through")


BY_TYPE = {
    "Step": _step, "Constant": _constant, "Ground": _ground, "Sin": _sine, "SineWave": _sine,
    "DiscretePulseGenerator": _pulse, "Ramp": _ramp, "Clock": _clock, "DigitalClock": _digital_clock,
    "RandomNumber": _random, "UniformRandomNumber": _uniform,
    "Gain": _gain, "Sum": _sum, "Product": _product, "Math": _operator(_MATH, "exp"),
    "Trigonometry": _operator(_TRIG, "sin"), "Sqrt": _operator(_MATH, "sqrt"), "Fcn": _fcn, "Abs": _abs,
    "Signum": _sign, "MinMax": _minmax, "Bias": _bias, "UnaryMinus": _unary_minus,
    "RelationalOperator": _relational, "Logic": _logic, "Polyval": _polynomial,
    "Integrator": _integrator, "SecondOrderIntegrator": _second_order_integrator, "Derivative": _derivative,
    "SignalGenerator": _signal_generator, "TransferFcn": _transfer_fcn, "ZeroPole": _zero_pole,
    "StateSpace": _state_space, "TransportDelay": _transport_delay,
    "Saturate": _saturation, "DeadZone": _dead_zone, "Switch": _switch, "Relay": _relay, "RateLimiter": _rate_limiter,
    "Lookup_n-D": _lookup_nd, "Lookup": _lookup_old, "Lookup2D": _lookup_2d,
    "ZeroOrderHold": _zoh, "UnitDelay": _unit_delay, "Memory": _memory, "DiscreteTransferFcn": _discrete_tf,
    "DiscreteFilter": _discrete_filter, "DiscreteStateSpace": _discrete_ss, "DiscreteIntegrator": _discrete_integrator,
    "Mux": _mux, "Demux": _demux, "Stop": _stop,
    "DataTypeConversion": _pass, "SignalConversion": _pass, "Reshape": _pass, "SignalSpecification": _pass,
    "ManualSwitch": _manual_switch, "RateTransition": _pass,
}

#: library links (BlockType Reference), by their SourceBlock with its newlines as spaces
BY_SOURCE = {
    "simulink/Continuous/PID Controller": _pid, "simulink/Discrete/Discrete PID Controller": _pid,
    "simulink/Sources/Ramp": _ramp, "simulink/Sources/Band-Limited White Noise.": _white_noise,
    "simulink/Sources/Band-Limited White Noise": _white_noise,
    "simulink/Logic and Bit Operations/Compare To Constant": _compare_constant,
    "simulink/Logic and Bit Operations/Compare To Zero": _compare_zero,
    "simulink/Math Operations/Polynomial": _polynomial,
    "simulink/Sinks/XY Graph": None,  # a sink: handled with the others
}


def mapped_types() -> list[str]:
    """Every Simulink block the importer translates (types and library links), for the crosswalk's test."""
    return sorted({*BY_TYPE, *(k for k, v in BY_SOURCE.items() if v is not None)})
