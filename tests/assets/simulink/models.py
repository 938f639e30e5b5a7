"""The corpus's models, described once (make_corpus.py writes each in the format its file name says).

Each entry: file name -> (root system, solver settings, model parameters (callbacks), layout). The
constructs are those of real course models: Sum signs "|+-", defaults left unset (a Step's time 1),
workspace variables from a script beside the model and from callbacks, masked subsystems, library
links (PID Controller, Compare To Constant), Goto/From, buses, Mux/Demux, lookup tables, discrete
blocks with inherited sample times, transport delays, random sources, Stop, fixed-step solvers.
"""

from make_corpus import B, L, Sub

VAR = {"Solver": "ode45", "SolverType": "Variable-step"}

MSD = Sub([
    B("Step", "Force"),  # Time left at Simulink's default: 1
    B("Sum", "Sum", {"Inputs": "|+--", "IconShape": "round"}, ports=(3, 1)),
    B("Gain", "1/m", {"Gain": "1/m"}),
    B("Integrator", "Velocity"),
    B("Integrator", "Position"),
    B("Gain", "Damping", {"Gain": "b"}),
    B("Gain", "Spring", {"Gain": "k"}),
    B("Scope", "Scope"),
    B("ToWorkspace", "To Workspace", {"VariableName": "x"}),
], [
    L("Force:1", "Sum:1"), L("Sum:1", "1/m:1"), L("1/m:1", "Velocity:1"),
    L("Velocity:1", ["Position:1", "Damping:1"]), L("Position:1", ["Spring:1", "Scope:1", "To Workspace:1"]),
    L("Damping:1", "Sum:2"), L("Spring:1", "Sum:3"),
])

# The same system as a masked subsystem "Plant" (m, b, k its mask parameters; b from the workspace)
PLANT = Sub([
    B("Inport", "F", {"Port": "1"}),
    B("Sum", "Sum", {"Inputs": "+--"}, ports=(3, 1)),
    B("Gain", "1/m", {"Gain": "1/m"}),
    B("Integrator", "v", {"InitialCondition": "0"}),
    B("Integrator", "x", {"InitialCondition": "0"}),
    B("Gain", "b", {"Gain": "b"}),
    B("Gain", "k", {"Gain": "k"}),
    B("Outport", "x out", {"Port": "1"}),
], [
    L("F:1", "Sum:1"), L("Sum:1", "1/m:1"), L("1/m:1", "v:1"), L("v:1", ["x:1", "b:1"]),
    L("x:1", ["k:1", "x out:1"]), L("b:1", "Sum:2"), L("k:1", "Sum:3"),
], mask=[("m", "mass"), ("b", "b"), ("k", "4")])
MSD_MASKED = Sub([
    B("Step", "Force", {"Time": "1"}),
    B("SubSystem", "Plant", sub=PLANT, ports=(1, 1)),
    B("Outport", "position", {"Port": "1"}),
], [L("Force:1", "Plant:1"), L("Plant:1", "position:1")])

FIRST_ORDER = Sub([
    B("Step", "Step"),
    B("TransferFcn", "Lag", {"Numerator": "[1]", "Denominator": "[tau 1]"}),
    B("Outport", "y", {"Port": "1"}),
], [L("Step:1", "Lag:1"), L("Lag:1", "y:1")])

PID_LOOP = Sub([
    B("Step", "Reference", {"Time": "0"}),
    B("Sum", "Error", {"Inputs": "|+-"}, ports=(2, 1)),
    B("Reference", "PID Controller", {"P": "Kp", "I": "Ki", "D": "Kd", "N": "100"},
      source="simulink/Continuous/PID Controller"),
    B("TransferFcn", "Plant", {"Numerator": "[1]", "Denominator": "[1 3 2]"}),
    B("Scope", "Scope"),
], [L("Reference:1", "Error:1"), L("Error:1", "PID Controller:1"), L("PID Controller:1", "Plant:1"),
    L("Plant:1", ["Error:2", "Scope:1"], name="y")])

SINE_GAIN = Sub([
    B("Sin", "Sine Wave", {"Amplitude": "2", "Frequency": "3", "Bias": "1"}),
    B("Gain", "Half", {"Gain": "0.5"}),
    B("Display", "Display"),
    B("ToWorkspace", "To Workspace", {"VariableName": "y"}),
], [L("Sine Wave:1", "Half:1"), L("Half:1", ["Display:1", "To Workspace:1"])])

PENDULUM = Sub([
    B("Integrator", "omega"),
    B("Integrator", "theta", {"InitialCondition": "theta0"}),
    B("Trigonometry", "sin", {"Operator": "sin"}),
    B("Gain", "g/L", {"Gain": "g/L"}),
    B("Gain", "friction", {"Gain": "c"}),
    B("Sum", "Sum", {"Inputs": "--"}, ports=(2, 1)),
    B("Scope", "Scope", {"NumInputPorts": "2"}, ports=(2, 0)),
], [L("Sum:1", "omega:1"), L("omega:1", ["theta:1", "friction:1", "Scope:2"], name="omega"),
    L("theta:1", ["sin:1", "Scope:1"], name="theta"), L("sin:1", "g/L:1"), L("g/L:1", "Sum:1"),
    L("friction:1", "Sum:2")])

LIMITS = Sub([
    B("Step", "Step", {"Time": "0", "After": "2"}),
    B("Saturate", "Saturation", {"UpperLimit": "1"}),  # LowerLimit left at -0.5
    B("Integrator", "Limited", {"LimitOutput": "on", "UpperSaturationLimit": "1.5"}),
    B("DeadZone", "Dead Zone"),  # -0.5 .. 0.5
    B("Scope", "Scope", ports=(2, 0)),
], [L("Step:1", "Saturation:1"), L("Saturation:1", "Limited:1"), L("Limited:1", ["Dead Zone:1", "Scope:1"]),
    L("Dead Zone:1", "Scope:2")])

STATE_SPACE = Sub([
    B("Constant", "One"),  # Value left at 1
    B("StateSpace", "Plant", {"A": "[0 1; -2 -3]", "B": "[0; 1]", "C": "eye(2)", "D": "[0; 0]", "X0": "[1; 0]"}),
    B("Demux", "Split", {"Outputs": "2"}),
    B("Scope", "Scope", ports=(2, 0)),
], [L("One:1", "Plant:1"), L("Plant:1", "Split:1"), L("Split:1", "Scope:1", name="x1"),
    L("Split:2", "Scope:2", name="x2")])

DISCRETE = Sub([
    B("Step", "Step", {"Time": "0"}),
    B("ZeroOrderHold", "ZOH", {"SampleTime": "Ts"}),
    B("DiscreteTransferFcn", "Filter", {"Numerator": "[0.1]", "Denominator": "[1 -0.9]", "SampleTime": "Ts"}),
    B("UnitDelay", "Delay"),  # SampleTime left at -1: inherited from the filter
    B("Scope", "Scope", ports=(2, 0)),
], [L("Step:1", "ZOH:1"), L("ZOH:1", "Filter:1"), L("Filter:1", ["Delay:1", "Scope:1"], name="f"),
    L("Delay:1", "Scope:2", name="d")])

INNER = Sub([B("Inport", "in", {"Port": "1"}), B("Gain", "Double", {"Gain": "2"}), B("Outport", "out", {"Port": "1"})],
            [L("in:1", "Double:1"), L("Double:1", "out:1")])
ROUTING = Sub([
    B("Clock", "Clock"),
    B("Goto", "Goto", {"GotoTag": "time"}),
    B("From", "From", {"GotoTag": "time"}),
    B("Constant", "Three", {"Value": "3"}),
    B("BusCreator", "Bus Creator", {"Inputs": "2"}, ports=(2, 1)),
    B("BusSelector", "Bus Selector", {"OutputSignals": "b,a"}, ports=(1, 2)),
    B("SubSystem", "Doubler", sub=INNER, ports=(1, 1)),
    B("Mux", "Mux", {"Inputs": "2"}, ports=(2, 1)),
    B("Demux", "Demux", {"Outputs": "2"}, ports=(1, 2)),
    B("Product", "Times", {"Inputs": "**"}, ports=(2, 1)),
    B("Outport", "p", {"Port": "1"}),
], [L("Clock:1", "Goto:1"), L("From:1", "Bus Creator:1", name="a"), L("Three:1", "Bus Creator:2", name="b"),
    L("Bus Creator:1", "Bus Selector:1"), L("Bus Selector:1", "Doubler:1"), L("Bus Selector:2", "Mux:2"),
    L("Doubler:1", "Mux:1"), L("Mux:1", "Demux:1"), L("Demux:1", "Times:1"), L("Demux:2", "Times:2"),
    L("Times:1", "p:1")])

FCN_MATH = Sub([
    B("Clock", "Clock"),
    B("Fcn", "f", {"Expr": "u(1)^2 + k*sin(u(1))"}),
    B("Math", "exp", {"Operator": "exp"}),
    B("Sqrt", "sqrt"),
    B("Abs", "abs"),
    B("Constant", "minus two", {"Value": "-2"}),
    B("Product", "ratio", {"Inputs": "*/"}, ports=(2, 1)),
    B("MinMax", "max", {"Function": "max", "Inputs": "2"}, ports=(2, 1)),
    B("Scope", "Scope", ports=(4, 0)),
], [L("Clock:1", ["f:1", "exp:1", "sqrt:1", "ratio:1"]), L("f:1", "Scope:1", name="f"),
    L("exp:1", ["ratio:2", "Scope:2"], name="e"), L("sqrt:1", "max:1"), L("minus two:1", "abs:1"),
    L("abs:1", "max:2"), L("max:1", "Scope:3", name="m"), L("ratio:1", "Scope:4", name="r")])

LOOKUP = Sub([
    B("Clock", "Clock"),
    B("Lookup_n-D", "Table", {"NumberOfTableDimensions": "1", "BreakpointsForDimension1": "[0 1 2 3]",
                              "Table": "[0 1 4 9]"}),
    B("Integrator", "Area"),
    B("Scope", "Scope", ports=(2, 0)),
], [L("Clock:1", "Table:1"), L("Table:1", ["Area:1", "Scope:1"], name="g"), L("Area:1", "Scope:2", name="area")])

DELAY = Sub([
    B("Step", "Step", {"Time": "0"}),
    B("TransportDelay", "Delay", {"DelayTime": "0.5"}),
    B("Integrator", "Ramp"),
    B("Outport", "y", {"Port": "1"}),
], [L("Step:1", "Delay:1"), L("Delay:1", "Ramp:1"), L("Ramp:1", "y:1")])

STOP_RANDOM = Sub([
    B("Clock", "Clock"),
    B("Reference", "Late", {"relop": ">=", "const": "2.5"}, source="simulink/Logic and Bit\nOperations/Compare\nTo Constant"),
    B("Stop", "Stop"),
    B("RandomNumber", "Noise", {"Seed": "7", "SampleTime": "0.5", "Variance": "4"}),
    B("UniformRandomNumber", "Dither", {"Minimum": "0", "Maximum": "10", "SampleTime": "0.25"}),
    B("Integrator", "Ramp"),
    B("Constant", "One"),
    B("Scope", "Scope", ports=(3, 0)),
], [L("Clock:1", "Late:1"), L("Late:1", "Stop:1"), L("Noise:1", "Scope:1", name="noise"),
    L("Dither:1", "Scope:2", name="dither"), L("One:1", "Ramp:1"), L("Ramp:1", "Scope:3", name="ramp")])

INNER_MASK = Sub([B("Inport", "u", {"Port": "1"}), B("Gain", "times k", {"Gain": "k"}), B("Outport", "y", {"Port": "1"})],
                 [L("u:1", "times k:1"), L("times k:1", "y:1")], mask=[("k", "3")])
OUTER_MASK = Sub([
    B("Inport", "u", {"Port": "1"}),
    B("SubSystem", "Inner", sub=INNER_MASK, ports=(1, 1)),
    B("Gain", "times k", {"Gain": "k"}),
    B("Outport", "inner", {"Port": "1"}),
    B("Outport", "outer", {"Port": "2"}),
], [L("u:1", ["Inner:1", "times k:1"]), L("Inner:1", "inner:1"), L("times k:1", "outer:1")], mask=[("k", "2")])
MASKS = Sub([
    B("Ramp", "Ramp", source="simulink/Sources/Ramp"),  # slope 1 from 0 (its defaults)
    B("SubSystem", "Outer", sub=OUTER_MASK, ports=(1, 2)),
    B("Gain", "times k", {"Gain": "k"}),
    B("Outport", "k3", {"Port": "1"}), B("Outport", "k2", {"Port": "2"}), B("Outport", "k5", {"Port": "3"}),
], [L("Ramp:1", ["Outer:1", "times k:1"]), L("Outer:1", "k3:1"), L("Outer:2", "k2:1"), L("times k:1", "k5:1")])

PULSE_DERIVATIVE = Sub([
    B("DiscretePulseGenerator", "Pulse", {"Amplitude": "3", "Period": "2", "PulseWidth": "50"}),
    B("Integrator", "Charge"),
    B("Sin", "Sine"),
    B("Derivative", "d/dt"),
    B("Scope", "Scope", ports=(2, 0)),
], [L("Pulse:1", "Charge:1"), L("Charge:1", "Scope:1", name="q"), L("Sine:1", "d/dt:1"),
    L("d/dt:1", "Scope:2", name="dsin")])

FIXED = Sub([
    B("Step", "Step", {"Time": "0"}),
    B("Sum", "Sum", {"Inputs": "+-"}, ports=(2, 1)),
    B("Integrator", "x"),
    B("Gain", "a", {"Gain": "2"}),
    B("Outport", "x out", {"Port": "1"}),
], [L("Step:1", "Sum:1"), L("Sum:1", "x:1"), L("x:1", ["a:1", "x out:1"]), L("a:1", "Sum:2")])

SWITCHING = Sub([
    B("Clock", "Clock"),
    B("Relay", "Relay", {"OnSwitchValue": "2", "OffSwitchValue": "1", "OnOutputValue": "5", "OffOutputValue": "-1"}),
    B("Constant", "High", {"Value": "10"}),
    B("Constant", "Low", {"Value": "-10"}),
    B("Switch", "Switch", {"Threshold": "3"}),
    B("Scope", "Scope", ports=(2, 0)),
], [L("Clock:1", ["Relay:1", "Switch:2"]), L("High:1", "Switch:1"), L("Low:1", "Switch:3"),
    L("Relay:1", "Scope:1", name="relay"), L("Switch:1", "Scope:2", name="switch")])

CHART = Sub([B("Inport", "u", {"Port": "1"}), B("Outport", "y", {"Port": "1"})], [L("u:1", "y:1")])
WITH_GAPS = Sub([
    B("Step", "Step"),
    B("Gain", "Unknown gain", {"Gain": "K_missing"}),
    B("SubSystem", "Chart", {"SFBlockType": "Chart"}, sub=CHART, ports=(1, 1)),
    B("Scope", "Scope", ports=(2, 0)),
], [L("Step:1", ["Unknown gain:1", "Chart:1"]), L("Unknown gain:1", "Scope:1"), L("Chart:1", "Scope:2")])

PHYSICAL = Sub([
    B("SimscapeBlock", "Resistor", {"SourceFile": "foundation.electrical.elements.resistor"}),
    B("Reference", "Solver Configuration", source="nesl_utility/Solver\nConfiguration"),
], [])

MODELS = {
    "msd/msd.mdl": (MSD, {**VAR, "StopTime": "10", "RelTol": "1e-6", "AbsTol": "1e-8"}, None, None),
    "msd_masked.slx": (MSD_MASKED, {**VAR, "StopTime": "10", "RelTol": "1e-6", "AbsTol": "1e-8"},
                       {"PreLoadFcn": "mass = 2; b = 0.8;"}, None),
    "first_order.slx": (FIRST_ORDER, {}, {"PreLoadFcn": "tau = 0.5;"}, "blockdiagram"),
    "pid_loop.mdl": (PID_LOOP, {**VAR, "StopTime": "8", "RelTol": "1e-5", "AbsTol": "1e-7"},
                     {"InitFcn": "Kp = 4; Ki = 2; Kd = 0.5;"}, "package"),
    "sine_gain.slx": (SINE_GAIN, {"Solver": "VariableStepDiscrete", "StopTime": "5"}, None, None),
    "pendulum.mdl": (PENDULUM, {**VAR, "StopTime": "10", "RelTol": "1e-8", "AbsTol": "1e-10", "MaxStep": "0.1"},
                     {"InitFcn": "g = 9.81; L = 0.5; c = 0.2; theta0 = 1;"}, None),
    "limits.slx": (LIMITS, {**VAR, "StopTime": "4", "RelTol": "1e-6", "AbsTol": "1e-9"}, None, None),
    "state_space.mdl": (STATE_SPACE, {**VAR, "StopTime": "5", "RelTol": "1e-8", "AbsTol": "1e-10"}, None, None),
    "discrete.slx": (DISCRETE, {**VAR, "StopTime": "3"}, {"PreLoadFcn": "Ts = 0.1;"}, None),
    "routing.slx": (ROUTING, {**VAR, "StopTime": "2"}, None, "blockdiagram"),
    "fcn_math.mdl": (FCN_MATH, {**VAR, "StopTime": "3"}, {"PreLoadFcn": "k = 0.5;"}, None),
    "lookup.mdl": (LOOKUP, {**VAR, "StopTime": "4", "RelTol": "1e-8", "AbsTol": "1e-10"}, None, "package"),
    "delay.slx": (DELAY, {**VAR, "StopTime": "3", "RelTol": "1e-6", "AbsTol": "1e-8"}, None, None),
    "stop_random.mdl": (STOP_RANDOM, {**VAR, "StopTime": "10", "MaxStep": "0.1"}, None, None),
    "masks.slx": (MASKS, {**VAR, "StopTime": "2"}, {"PreLoadFcn": "k = 5;"}, None),
    "pulse_derivative.mdl": (PULSE_DERIVATIVE, {**VAR, "StopTime": "6", "RelTol": "1e-8", "AbsTol": "1e-10"},
                             None, "package"),
    "fixed_step.slx": (FIXED, {"Solver": "ode4", "SolverType": "Fixed-step", "FixedStep": "0.01", "StopTime": "3"},
                       None, "blockdiagram"),
    "switching.mdl": (SWITCHING, {**VAR, "StopTime": "5", "RelTol": "1e-6", "AbsTol": "1e-9"}, None, None),
    "with_gaps.slx": (WITH_GAPS, VAR, None, None),
    "physical.slx": (PHYSICAL, VAR, None, None),
}
