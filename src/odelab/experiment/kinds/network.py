"""Building a system from an experiment file's [elements] table (``kind = "network"``).

The network is derived once per file (:mod:`odelab.systems.network`, symbolic in the
parameters) and compiled for each case's parameter values into the system odelab already
runs: a state-space model when the network is linear, otherwise a system of equations in the
expression language, exactly as ``kind = "state-space"`` and ``kind = "ode"`` build theirs.
So every solver, [inputs], [events], [linearize], [analysis], sweeps, studies, the compiled
backend and the report work on a network unchanged.
"""

from __future__ import annotations

import json

import numpy as np

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.cases import Built
from odelab.expressions.compile import compile_vector
from odelab.systems.fields import ExpressionField, LinearField
from odelab.systems.outputs import ExpressionOutputs, LinearOutputs

__all__ = ["build_network", "network_of"]

# derivations by (elements, outputs, parameter names): the cases and sweeps of a file share one
_DERIVED: dict[str, object] = {}
_DERIVED_MAX = 64


def network_of(model: schema.Experiment, params: dict[str, float]):
    """The :class:`~odelab.systems.network.Network` of a validated model, derived (keyed errors)."""
    from odelab.systems.network import Network, NetworkError

    system = model.system
    for field_name in ("states", "equations", "function", "inputs", "A", "B", "C", "D", "jacobian"):
        if getattr(system, field_name) is not None:
            raise ExperimentError(f"`system.{field_name}` does not apply to kind = \"network\": odelab derives the "
                                  "states, inputs and equations from [elements]; remove it.",
                                  key=f"system.{field_name}")
    if not model.elements:
        raise ExperimentError("kind = \"network\" needs an [elements] table: one element per line, e.g. "
                              "mass = { type = \"mass\", node = \"p\", m = 1 }.", key="elements")
    if system.outputs is not None and not isinstance(system.outputs, dict):
        raise ExperimentError("`system.outputs` of a network maps output names to expressions of element "
                              "variables, e.g. outputs = { y = \"q*mass.x\" }.", key="system.outputs")
    outputs = {}
    for name, text in (system.outputs or {}).items():
        if not isinstance(text, (str, int, float)) or isinstance(text, bool):
            raise ExperimentError(f"`system.outputs.{name}` must be an expression string.",
                                  key=f"system.outputs.{name}")
        outputs[name] = text
    memo = json.dumps([model.elements, outputs, sorted(params)], sort_keys=True, default=str)
    try:
        net = _DERIVED.get(memo)
        if net is None:
            net = Network.from_tables(model.elements, outputs=outputs, parameters=params)
            net.derive()
            if len(_DERIVED) < _DERIVED_MAX:
                _DERIVED[memo] = net
    except NetworkError as exc:
        raise ExperimentError(exc.message, key=exc.key or "elements") from None
    clash = sorted(set(net.derive().outputs) & (set(net.states) | set(net.inputs) | set(params)))
    if clash:
        raise ExperimentError(f"output {clash[0]!r} has the name of a state, input or parameter; rename it.",
                              key=f"system.outputs.{clash[0]}")
    return net


def build_network(model: schema.Experiment, params: dict[str, float]) -> Built:
    """A system from [elements]: linear networks become StateSpace systems, others equations."""
    from odelab.solvers.compiled import CompiledSystem

    net = network_of(model, params)
    d = net.derive()
    states, inputs, outputs = d.states, d.inputs, d.outputs
    resolved = {"kind": "network", "states": list(states), "equations": d.equation_texts()}
    if inputs:
        resolved["inputs"] = list(inputs)
    if outputs:
        resolved["outputs"] = d.output_texts()
    try:
        if d.linear:
            ss = net.compile(params)
            A, B, C, D = ss.A, ss.B, ss.C, ss.D
            resolved.update({"A": A.tolist(), "B": B.tolist(), "C": C.tolist(), "D": D.tolist()})
            output_fn = LinearOutputs(C, D)

            fun = LinearField(A) if not inputs else None
            return Built(states=states, inputs=inputs, outputs=outputs, fun=fun,
                         output_fn=output_fn if outputs else None, resolved=resolved, linear=True, model=ss,
                         compiled=CompiledSystem.linear(A, states, B, inputs), jacobian=A, network=net,
                         x0=np.zeros(len(states)))
        from odelab.systems.jacobian import complex_step_jacobian

        texts = d.equation_texts()
        eqs = [texts[s] for s in states]
        keys = [f"elements (d({s})/dt)" for s in states]
        # each equation text compiled once (and once for complex step): the case's fun, its outputs and
        # its Jacobian are the NonlinearSystem's functions; the compiled backend's source is made on use
        sys_obj = net.compile(params)
        F, G, F_complex = sys_obj.expression_parts()
        fun = ExpressionField(F) if not inputs else None
        output_fn = ExpressionOutputs(G, len(outputs)) if outputs else None
        compiled = CompiledSystem.from_system(states, eqs, params, inputs, keys=keys)
        jacobian = complex_step_jacobian(eqs, states, params, keys=keys,
                                         compiled=None if inputs else F_complex)  # same arguments: t, the states
    except InputError as exc:  # pragma: no cover - the derivation's own expressions compile
        raise ExperimentError(f"the derived network does not compile: {exc.message}", key="elements") from None
    return Built(states=states, inputs=inputs, outputs=outputs, fun=fun, output_fn=output_fn, resolved=resolved,
                 linear=False, model=sys_obj, compiled=compiled, jacobian=jacobian, network=net,
                 x0=np.zeros(len(states)))  # [initial] gives some states by name; the others start at 0


def network_record(p) -> dict:
    """What the report needs of a network: its drawing (DOT) and its derivation's sections."""
    from odelab.systems.network.draw import network_dot
    from odelab.systems.network.show import derivation_sections

    net = p.system.network
    key = tuple(sorted(p.parameters.items()))
    cache = net.__dict__.setdefault("_sections", {})  # the cases of a file share their network
    if key not in cache:
        cache[key] = derivation_sections(net, p.parameters)
    sections = cache[key]
    return {"dot": network_dot(net.elements), "linear": bool(net.derive().linear),
            "sections": [[heading, list(lines)] for heading, lines in sections]}
