"""Deriving a network's state equations, as Close & Frederick do by hand.

1. The element laws (each element's constitutive relation) and the interconnection laws: at
   every node the through variables sum to zero (forces, torques, currents, flows, heat flows),
   and every element's across variable is the difference of its nodes' (compatibility, the
   loop law); sources and couplings add their own relations.
2. The states, one per independent energy store: a mass's displacement and velocity, an
   inertia's angle and speed, a capacitor's voltage, an inductor's current, a spring's stretch
   where the masses do not fix it, a fluid capacitance's pressure, a thermal capacitance's
   temperature. A store whose variable the others fix (capacitors in parallel, inertias joined
   by a gear, a mass moved by a velocity source, inductors in series) is reduced, with a line
   saying why; the test is the rank of the across (or through) relations, taken with generic
   parameter values.
3. Solving the laws, which are linear in the unknown node across variables, element through
   variables and state derivatives once each nonlinear law is held as an opaque value, gives
   every state derivative and every element variable in terms of the states and the inputs.

Everything is symbolic in the parameters: ``d(mass.v)/dt = (f - b*mass.v - k*mass.x)/m``.
"""

from __future__ import annotations

import difflib
import random
from dataclasses import dataclass, field
from fractions import Fraction

from odelab.expressions.compile import compile_expression
from odelab.expressions.parse import parse_expression
from odelab.systems.network.elements import DOMAINS, Element, NetworkError
from odelab.systems.network.graph import GROUND, Graph, build_graph
from odelab.systems.network.symbolic import require_sympy, to_sympy, to_text

__all__ = ["Derivation", "derive"]


@dataclass
class Derivation:
    """What the derivation found, symbolic in the parameters (SymPy expressions).

    ``laws`` and ``interconnection`` are the lines a student writes by hand; ``states`` are in
    the textbook's order; ``equations`` maps each state to its derivative; ``variables`` maps
    every element variable (``spring.f``) to its expression in the states and inputs.
    """

    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: tuple[str, ...]
    laws: list[tuple[str, str]]  # (element, law text)
    interconnection: list[str]
    state_notes: list[str]  # why each state, and every reduction
    equations: dict  # state -> SymPy rhs
    output_expressions: dict  # output -> SymPy
    variables: dict  # element.variable -> SymPy (states, inputs, parameters, t)
    linear: bool
    matrices: dict | None = None  # A, B, C, D as SymPy matrices when linear
    symbols: dict = field(default_factory=dict)  # name -> SymPy symbol
    elements: dict = field(default_factory=dict)

    def equation_texts(self) -> dict[str, str]:
        """Each state's derivative in the expression language (what odelab compiles)."""
        return {s: to_text(e) for s, e in self.equations.items()}

    def output_texts(self) -> dict[str, str]:
        return {y: to_text(e) for y, e in self.output_expressions.items()}


# -- helpers ------------------------------------------------------------------------------------

def _generic_values(names) -> dict:
    """Generic positive values for a structural rank test (fixed seed: the same answer every run)."""
    rng = random.Random(20261201)
    return {n: Fraction(rng.randint(11, 97), rng.randint(5, 13)) for n in sorted(names)}


class _Parser:
    """Element texts -> SymPy, through odelab's parser; each message names the element and key."""

    def __init__(self, sp, parameters, symbols):
        self.sp = sp
        self.parameters = parameters
        self.symbols = symbols
        self.inputs: list[str] = []  # names of the sources' values that are not parameters, in order

    def parse(self, value, *, element: str, key: str, allowed: dict[str, object], what: str,
              inputs: bool = False, law_of: str | None = None):
        """``allowed``: name -> symbol. With ``inputs``, any other name becomes an input."""
        path = f"elements.{element}.{key}"
        names = dict(allowed)
        for p in self.parameters:
            names.setdefault(p, self.symbols[p])
        parsed = parse_expression(value, key=path, names=names)  # a parameter `e` shadows the constant e
        extra = [n for n in parsed.names if n not in names]
        if extra and law_of is not None:
            listed = ", ".join(f"`{n}`" for n in extra)
            close = difflib.get_close_matches(extra[0], list(allowed), n=1)
            hint = f" Did you mean `{close[0]}`?" if close else ""
            raise NetworkError(f"`{path}` = {value!r} names {listed}, which {'it does' if len(extra) == 1 else 'they do'}"
                               f" not have: {what} and of t.{hint}", key=path)
        if extra and inputs:
            for n in extra:
                if "." in n:
                    raise NetworkError(f"`{path}` is {value!r}: {n!r} is an element variable; a source's value "
                                       "is a number or an expression of inputs, [parameters] and t.", key=path)
                if n not in self.symbols:
                    self.symbols[n] = self.sp.Symbol(n)
                if n not in self.inputs:
                    self.inputs.append(n)
                names[n] = self.symbols[n]
        elif extra:
            # odelab's own message: unknown name, did-you-mean, the names known here
            try:
                compile_expression(parsed, names=list(names), key=path)
            except Exception as exc:
                text = getattr(exc, "message", str(exc))
                raise NetworkError(f"`{path}` = {value!r}: {what}. {text}".rstrip(), key=path) from None
        return to_sympy(parsed, names)


# -- the derivation -----------------------------------------------------------------------------

def derive(elements: dict[str, Element], outputs: dict[str, str] | None, parameters) -> Derivation:
    """Derive the state equations of a network (``parameters``: the names of the parameters)."""
    d = _Deriver(elements, tuple(parameters))
    d.read()
    d.relations()
    d.across_states()
    d.known_displacements()
    d.through_states()
    d.law_equations()
    d.solve()
    return d.result(outputs)


class _Deriver:
    """One derivation, in the module's three steps; each method is one paragraph of the hand
    derivation (the laws read, the relations reduced, the states chosen, the laws solved)."""

    def __init__(self, elements: dict[str, Element], parameters: tuple[str, ...]):
        sp = self.sp = require_sympy()
        self.elements, self.parameters = elements, parameters
        self.graph = build_graph(elements)
        self.t = sp.Symbol("t")
        self.symbols: dict[str, object] = {p: sp.Symbol(p) for p in parameters}
        self.symbols["t"] = self.t
        self.reader = _Parser(sp, parameters, self.symbols)
        self.generic = _generic_values(parameters)
        self.states: list[str] = []
        self.state_sym: dict[str, object] = {}
        self.notes: list[str] = []
        self.deriv: dict[str, object] = {}  # state -> symbol of its derivative (an unknown) or an expression
        self.el_state: dict[str, object] = {}
        self.input_rate: dict[str, object] = {}  # derivative symbols of inputs, d(u)/dt

    # -- small rules ------------------------------------------------------------------------

    def numeric(self, expr):
        """A generic rational value of an expression of the parameters (for rank tests)."""
        sp = self.sp
        val = expr.subs({self.symbols[p]: sp.Rational(v.numerator, v.denominator) for p, v in self.generic.items()})
        return sp.nsimplify(val) if not val.is_Rational else val

    def across_of(self, a, b):
        return (self.across[a] if a != GROUND else 0) - (self.across[b] if b != GROUND else 0)

    def u(self, name, side=1):
        el = self.elements[name]
        return self.across_of(*(el.nodes if side == 1 else el.nodes2))

    def ratio(self, name):
        el, c = self.elements[name], self.coef[name]
        return 1 / c["r"] if el.TYPE == "rack-pinion" else c.get("n", c.get("K"))

    def new_state(self, label):
        s = self.sp.Symbol(label)
        self.states.append(label)
        self.state_sym[label] = s
        self.symbols[label] = s
        return s

    def disp_of(self, a, b):
        known = self.known_disp
        if (a != GROUND and a not in known) or (b != GROUND and b not in known):
            return None
        return (known.get(a, 0) if a != GROUND else 0) - (known.get(b, 0) if b != GROUND else 0)

    def rate(self, expr):
        """d/dt of an expression of inputs, t and source markers."""
        sp = self.sp
        out = sp.diff(expr, self.t)
        for u_name in self.inputs:
            dsym = self.input_rate.setdefault(u_name, sp.Symbol(f"d({u_name})/dt"))
            out += sp.diff(expr, self.symbols[u_name]) * dsym
        for n, m in self.marker.items():
            if expr.has(m):
                out += sp.diff(expr, m) * sp.Symbol(f"d(source[{n}])/dt")
        return out

    def through_rate(self, name):
        """d/dt of the through variable of a chosen through store."""
        s = self.el_state[name]
        dsym = self.deriv[s.name]
        if name in self.law_expr:
            return self.sp.diff(self.law_expr[name].subs(self.law_var[name], s), s) * dsym
        if DOMAINS[self.elements[name].DOMAIN].integral:
            return self.coef[name]["k"] * dsym
        return dsym

    def final(self, expr):
        expr = expr.subs(self.solution).subs(self.rates).subs(self.source_values)
        return _tidy(self.sp, expr)

    # -- 1. the laws, read by odelab's parser --------------------------------------------------

    def read(self) -> None:
        """Coefficients, source values and laws; then the unknowns: node across variables, port
        through variables, and a marker symbol per source (which sources fix a reduced variable)."""
        sp, t, reader = self.sp, self.t, self.reader
        self.coef: dict[str, dict[str, object]] = {}
        self.law_var: dict[str, object] = {}
        self.law_expr: dict[str, object] = {}
        self.value: dict[str, object] = {}
        for name, el in self.elements.items():
            self.coef[name] = {}
            for key, v in el.values.items():
                if key == "value":
                    self.value[name] = reader.parse(v, element=name, key=key, allowed={"t": t}, what="", inputs=True)
                else:
                    self.coef[name][key] = reader.parse(
                        v, element=name, key=key, allowed={},
                        what=f"a {el.TYPE}'s `{key}` is a number or an expression of [parameters]")
            if el.law is not None:
                var = sp.Symbol(f"{name}.{el.LAW_OF}")
                self.law_var[name] = var
                self.law_expr[name] = reader.parse(
                    el.law, element=name, key=el.LAW, allowed={el.LAW_OF: var, "t": t}, law_of=el.LAW_OF,
                    what=(f"the {el.LAW} of a {el.TYPE} is a law of its {_variable_word(el)} `{el.LAW_OF}` "
                          "(and of [parameters])"))
        self.inputs = tuple(reader.inputs)
        self.across = {node: sp.Symbol(f"{DOMAINS[domain].across}({node})") for domain, node in self.graph.nodes}
        self.flow = {(p.element, p.side): sp.Symbol(f"flow[{p.element}:{p.side}]") for p in self.graph.ports}
        self.marker = {name: sp.Symbol(f"source[{name}]") for name, el in self.elements.items()
                       if el.ROLE in ("across-source", "through-source")}

    def relations(self) -> None:
        """The across relations (sources, couplings) and the through relations (node laws,
        sources, couplings), each solved for as many of its variables as it fixes."""
        sp, u, marker, coef, flow = self.sp, self.u, self.marker, self.coef, self.flow
        across_rel = []  # (element, expression == 0, with source markers)
        for name, el in self.elements.items():
            if el.ROLE == "across-source":
                across_rel.append((name, u(name) - marker[name]))
            elif el.ROLE == "transformer":
                across_rel.append((name, u(name, 2) - u(name) / self.ratio(name)))
            elif el.ROLE == "gyrator":
                across_rel.append((name, u(name) - coef[name]["K"] * u(name, 2)))
        self.node_vars = list(self.across.values())
        self.solved_across = _solve_relations(sp, across_rel, self.node_vars, self.numeric, "across", self.elements)
        through_rel = []
        self.node_law = {}
        for domain, node in self.graph.nodes:
            total = 0
            for p in self.graph.ports:
                if p.a == node:
                    total += flow[(p.element, p.side)]
                if p.b == node:
                    total -= flow[(p.element, p.side)]
            self.node_law[node] = total
            through_rel.append((f"node {node}", total))
        for name, el in self.elements.items():
            if el.ROLE == "through-source":
                through_rel.append((name, flow[(name, 1)] + marker[name]))
            elif el.ROLE == "transformer":
                through_rel.append((name, flow[(name, 2)] + self.ratio(name) * flow[(name, 1)]))
            elif el.ROLE == "gyrator":
                through_rel.append((name, flow[(name, 2)] + coef[name]["K"] * flow[(name, 1)]))
        self.flow_vars = list(flow.values())
        self.solved_through = _solve_relations(sp, through_rel, self.flow_vars, self.numeric, "through",
                                               self.elements)

    # -- 2. the states ---------------------------------------------------------------------------

    def across_states(self) -> None:
        """Across stores (masses, inertias, capacitances): a state per independent across variable."""
        sp, states, notes = self.sp, self.states, self.notes
        self.chosen_across: list[tuple[str, object, object]] = []  # (element, reduced form, state symbol)
        self.dep_across: dict[str, tuple[dict, object]] = {}  # element -> ({element: coefficient}, source part)
        for name, el in self.elements.items():
            if el.ROLE != "across-store":
                continue
            form = self.solved_across(self.u(name))
            combo = _combination(sp, form, [(c[0], c[1]) for c in self.chosen_across], self.node_vars, self.numeric)
            d = DOMAINS[el.DOMAIN]
            if combo is not None:
                coeffs, rest = combo
                self.dep_across[name] = (coeffs, rest)
                notes.append(_reduction_note(sp, name, el, coeffs, rest, self.marker, self.elements, d.across))
                continue
            if d.integral:
                xs = self.new_state(f"{name}.{d.integral}")
            s = self.new_state(f"{name}.{d.across}")
            self.chosen_across.append((name, form, s))
            self.el_state[name] = s
            if d.integral:
                self.deriv[f"{name}.{d.integral}"] = s
                self.el_state[name + ":integral"] = xs
            self.deriv[f"{name}.{d.across}"] = sp.Symbol(f"d({name}.{d.across})/dt")
            what = {"mass": "a mass: its displacement and velocity", "inertia": "an inertia: its angle and speed"}
            notes.append(f"{', '.join(states[-2:] if d.integral else states[-1:])}: "
                         f"{what.get(el.TYPE, 'a ' + el.TYPE + ': its ' + d.across_word)}")

    def known_displacements(self) -> None:
        """Known displacements of mechanical nodes: combinations of the masses' and inertias' states."""
        sp = self.sp
        mech_states = [(n, f, s) for n, f, s in self.chosen_across if DOMAINS[self.elements[n].DOMAIN].integral]
        self.known_disp: dict[str, object] = {}
        for domain, node in self.graph.nodes:
            if not DOMAINS[domain].integral:
                continue
            form = self.solved_across(self.across[node])
            combo = _combination(sp, form, [(n, f) for n, f, _ in mech_states], self.node_vars, self.numeric)
            if combo is not None and combo[1] == 0:
                self.known_disp[node] = sum((c * self.el_state[n + ":integral"] for n, c in combo[0].items()),
                                            sp.Integer(0))

    def through_states(self) -> None:
        """Through stores (springs where the masses leave them free, inductors, inertances)."""
        sp, notes = self.sp, self.notes
        self.chosen_through: list[tuple[str, object, object]] = []
        self.dep_through: dict[str, tuple[dict, object]] = {}
        self.stretch: dict[str, object] = {}  # spring -> its stretch (state, or an expression of states)
        for name, el in self.elements.items():
            if el.ROLE != "through-store":
                continue
            d = DOMAINS[el.DOMAIN]
            if d.integral:
                fixed = self.disp_of(*el.nodes)
                if fixed is not None:
                    self.stretch[name] = sp.expand(fixed)
                    notes.append(f"{name}.{d.integral} = {to_text(self.stretch[name])}: the masses fix the "
                                 f"{_variable_word(el)} of {name}, no state")
                    continue
            form = self.solved_through(self.flow[(name, 1)])
            combo = _combination(sp, form, [(c[0], c[1]) for c in self.chosen_through], self.flow_vars, self.numeric)
            if combo is None:
                var = d.integral if d.integral else d.through
                s = self.new_state(f"{name}.{var}")
                self.chosen_through.append((name, form, s))
                self.el_state[name] = s
                self.deriv[f"{name}.{var}"] = sp.Symbol(f"d({name}.{var})/dt")
                if d.integral:
                    self.stretch[name] = s
                    notes.append(f"{name}.{var}: a {el.TYPE} whose {_variable_word(el)} the masses do not fix")
                else:
                    notes.append(f"{name}.{var}: {'an' if el.TYPE[0] in 'aeiou' else 'a'} {el.TYPE}: "
                                 f"its {d.through_word}")
                continue
            coeffs, rest = combo
            self._check_reducible(name, el, d, coeffs, rest)
            self.dep_through[name] = (coeffs, rest)
            notes.append(_reduction_note(sp, name, el, coeffs, rest, self.marker, self.elements, d.through))

    def _check_reducible(self, name, el, d, coeffs, rest) -> None:
        """A through store fixed by sources alone, or a nonlinear spring fixed by others, has no
        state equation: say why and what to change."""
        if not coeffs:
            sources = [n for n in self.marker if rest.has(self.marker[n])]
            raise NetworkError(
                f"the {d.through_word} of {name!r} ({el.TYPE}) is fixed by the source"
                f"{'s' if len(sources) > 1 else ''} {', '.join(repr(s) for s in sources)}: they are in series "
                f"with nothing else to carry it, so its {el.TYPE} law would need the derivative of the "
                f"source's value and the network has no state there. Put a {_parallel_hint(el)} in parallel "
                f"with {name!r}, or remove {name!r}.", key=f"elements.{name}")
        if d.integral and name in self.law_expr:
            raise NetworkError(
                f"the force of {name!r} is fixed by {', '.join(repr(c) for c in coeffs)} (they are in series "
                f"with nothing else at their common node), and a nonlinear {el.TYPE} law cannot be reduced: "
                f"put a mass or a damper at the node between them.", key=f"elements.{name}")

    # -- 3. the laws as equations in the unknowns, solved ----------------------------------------

    def law_equations(self) -> None:
        """Every element's law (and each node's) as an equation == 0 in the unknowns; nonlinear
        dissipator laws are held as opaque values G with arguments W."""
        self.eqs: list = []
        self.unknowns = list(self.node_vars) + list(self.flow_vars)
        self.G: dict[str, object] = {}  # opaque values of nonlinear dissipator laws
        self.W: dict[str, object] = {}  # their arguments, unknowns
        for name, el in self.elements.items():
            F = self.flow[(name, 1)]
            if el.ROLE == "across-store":
                self._across_store(name, el, F)
            elif el.ROLE == "through-store":
                self._through_store(name, el, F)
            elif el.ROLE == "dissipator":
                self._dissipator(name, el, F)
            else:
                self.eqs.extend(self._source_or_coupling(name, el, F))
        self.eqs.extend(self.node_law.values())

    def _across_store(self, name, el, F) -> None:
        C = self.coef[name][_first(el.PARAMETERS)]
        if name in self.el_state:
            s = self.el_state[name]
            D = self.deriv[s.name]
            self.unknowns.append(D)
            self.eqs.append(self.u(name) - s)
            self.eqs.append(F - C * D)
            return
        coeffs, rest = self.dep_across[name]
        self.eqs.append(F - C * (sum((k * self.deriv[self.el_state[n].name] for n, k in coeffs.items()),
                                     self.sp.Integer(0)) + self.rate(rest)))

    def _through_store(self, name, el, F) -> None:
        sp, c, u, eqs = self.sp, self.coef[name], self.u, self.eqs
        law = self.law_expr.get(name)
        d = DOMAINS[el.DOMAIN]
        if d.integral and name in self.stretch and name not in self.el_state:  # fixed by the masses
            x = self.stretch[name]
            eqs.append(F - (law.subs(self.law_var[name], x) if law is not None else c["k"] * x))
        elif name in self.el_state:
            s = self.el_state[name]
            D = self.deriv[s.name]
            self.unknowns.append(D)
            if d.integral:
                eqs.append(F - (law.subs(self.law_var[name], s) if law is not None else c["k"] * s))
                eqs.append(D - u(name))
            else:
                eqs.append(F - s)
                eqs.append(c[_first(el.PARAMETERS)] * D - u(name))
        else:
            coeffs, rest = self.dep_through[name]
            dF = sum((k * self.through_rate(n) for n, k in coeffs.items()), sp.Integer(0)) + self.rate(rest)
            if d.integral:
                eqs.append(u(name) - dF / c["k"])
                self.stretch[name] = (sum((k * _through_value(sp, n, self.el_state, self.law_expr, self.law_var,
                                                              self.coef, self.elements)
                                           for n, k in coeffs.items()), sp.Integer(0)) + rest) / c["k"]
            else:
                eqs.append(u(name) - c[_first(el.PARAMETERS)] * dF)

    def _dissipator(self, name, el, F) -> None:
        if name in self.law_expr:
            g = self.sp.Symbol(f"law[{name}]")
            w = self.sp.Symbol(f"arg[{name}]")
            self.G[name], self.W[name] = g, w
            self.unknowns.append(w)
            self.eqs.append(w - self.u(name))
            self.eqs.append(F - g)
            return
        c, k = self.coef[name], _first(el.PARAMETERS)
        self.eqs.append(F - (c[k] * self.u(name) if el.TYPE in ("damper", "rotational-damper")
                             else self.u(name) / c[k]))

    def _source_or_coupling(self, name, el, F) -> list:
        u, flow = self.u, self.flow
        if el.ROLE == "across-source":
            return [u(name) - self.marker[name]]
        if el.ROLE == "through-source":
            return [F + self.marker[name]]
        if el.ROLE == "transformer":
            return [u(name, 2) - u(name) / self.ratio(name), flow[(name, 2)] + self.ratio(name) * F]
        if el.ROLE == "gyrator":
            K = self.coef[name]["K"]
            return [u(name) - K * u(name, 2), flow[(name, 2)] + K * F]
        return []

    def solve(self) -> None:
        """Solve the laws; then each nonlinear law's argument must come out as an expression of
        the states and inputs (else it sits in an algebraic loop)."""
        sp, G, W = self.sp, self.G, self.W
        solution = _solve_laws(sp, self.eqs, self.unknowns, self.numeric, self.graph, self.elements)
        pending = dict(G)
        subs_g = {}
        while pending:
            ready = [n for n in pending if not any(solution[W[n]].has(g) for g in pending.values())]
            if not ready:
                names = ", ".join(repr(n) for n in pending)
                raise NetworkError(
                    f"the nonlinear law of {names} sits in an algebraic loop: its "
                    f"{_variable_word(self.elements[next(iter(pending))])} depends on its own through variable, so "
                    "the state equations would need the law inverted. Put an energy store (a mass, a capacitor, a "
                    "fluid capacitance) at the node between them, or write the law as linear.", key="elements")
            for n in ready:
                arg = sp.expand(solution[W[n]].subs(subs_g))
                subs_g[G[n]] = self.law_expr[n].subs(self.law_var[n], arg)
                del pending[n]
        for key in list(solution):
            solution[key] = solution[key].subs(subs_g)
        self.solution = solution
        self.source_values = {m: self.value[n] for n, m in self.marker.items()}
        self.rates = {sp.Symbol(f"d(source[{n}])/dt"): self.rate(self.value[n]) for n in self.marker}

    # -- the results -------------------------------------------------------------------------------

    def result(self, outputs: dict[str, str] | None) -> Derivation:
        sp, symbols = self.sp, self.symbols
        equations = {s: self.final(self.deriv[s]) for s in self.states}
        variables = _element_variables(sp, self.elements, self.across, self.flow, self.u, self.solution,
                                       self.stretch, self.known_disp, self.el_state, self.law_var, self.final,
                                       self.disp_of, self.G, self.W)
        for v in variables:
            symbols.setdefault(v, sp.Symbol(v))
        needs_rate = list(self.input_rate.values())
        for s, e in equations.items():
            bad = [r for r in needs_rate if e.has(r)]
            if bad:  # pragma: no cover - the reductions above keep input rates out of the state equations
                raise NetworkError(f"d({s})/dt needs {bad[0]}, the derivative of an input.", key="elements")
        outs = {y: self._output(y, text, variables, needs_rate) for y, text in (outputs or {}).items()}
        laws = _law_lines(self.elements, self.coef, self.law_expr, self.law_var, self.value, self.stretch,
                          self.el_state, sp)
        inter = _interconnection_lines(self.graph, self.elements, sp)
        linear, matrices = _linear_form(sp, equations, outs, self.states, self.inputs, symbols, self.t)
        return Derivation(states=tuple(self.states), inputs=self.inputs, outputs=tuple(outs),
                          parameters=self.parameters, laws=laws, interconnection=inter, state_notes=self.notes,
                          equations=equations, output_expressions=outs, variables=variables, linear=linear,
                          matrices=matrices, symbols=symbols, elements=self.elements)

    def _output(self, y, text, variables, needs_rate):
        """An output's expression of element variables, inputs and parameters, in the states."""
        sp, symbols = self.sp, self.symbols
        key = f"system.outputs.{y}"
        allowed = {v: sp.Symbol(v) for v in variables}
        allowed.update({p: symbols[p] for p in self.parameters})
        allowed.update({u_: symbols[u_] for u_ in self.inputs})
        allowed["t"] = self.t
        parsed = parse_expression(text, key=key)
        try:
            compile_expression(parsed, names=list(allowed), key=key)
        except Exception as exc:
            text_ = getattr(exc, "message", str(exc))
            raise NetworkError(f"`{key}` = {text!r}: an output is an expression of element variables "
                               f"(`mass.x`, `C1.v`, `L1.i`), inputs and [parameters]. {text_}", key=key) from None
        expr = to_sympy(parsed, allowed).subs({sp.Symbol(v): e for v, e in variables.items()})
        bad = [r for r in needs_rate if expr.has(r)]
        if bad:
            raise NetworkError(f"`{key}` = {text!r} needs {bad[0].name}, the derivative of an input (a store fixed "
                               "by a source carries that source's rate of change); odelab's inputs have no "
                               "derivative: choose another output.", key=key)
        return _tidy(sp, expr)


def _first(params) -> str:
    return next(iter(params))


def _variable_word(el) -> str:
    words = {"x": "stretch", "v": "relative velocity", "theta": "twist", "w": "relative speed", "p": "pressure drop"}
    if el.TYPE == "resistor":
        return "voltage"
    return words.get(el.LAW_OF or DOMAINS[el.DOMAIN].across, "variable")


def _parallel_hint(el) -> str:
    return {"electrical": "resistor", "fluid": "fluid resistance", "translational": "damper",
            "rotational": "rotational damper"}.get(el.DOMAIN, "resistance")


def _tidy(sp, expr):
    """A readable canonical form: one fraction over a common denominator where that is shorter."""
    expr = sp.expand(expr)
    together = sp.cancel(sp.together(expr))
    if sp.count_ops(together) <= sp.count_ops(expr):
        expr = together
    return expr


def _through_value(sp, name, el_state, law_expr, law_var, coef, elements):
    s = el_state[name]
    if name in law_expr:
        return law_expr[name].subs(law_var[name], s)
    if DOMAINS[elements[name].DOMAIN].integral:
        return coef[name]["k"] * s
    return s


def _solve_relations(sp, relations, variables, numeric, kind, elements):
    """Solve linear relations for as many variables as they fix; return a function reducing any
    linear form to the free variables. Dependent relations mean two sources fix one variable."""
    if not relations:
        return lambda expr: sp.expand(expr)
    exprs = [r for _, r in relations]
    M, _ = sp.linear_eq_to_matrix(exprs, variables)
    Mg = M.applyfunc(numeric)
    rank = 0
    kept = []
    for i in range(len(exprs)):
        trial = Mg.extract(kept + [i], list(range(Mg.shape[1])))
        if trial.rank() > rank:
            kept.append(i)
            rank += 1
            continue
        # relation i follows from the ones kept: which of them
        rows = Mg.extract(kept, list(range(Mg.shape[1])))
        coeffs = sp.Matrix(rows.T).gauss_jordan_solve(Mg.row(i).T)[0] if kept else None
        involved = [relations[kept[j]][0] for j in range(len(kept)) if coeffs is not None and coeffs[j] != 0]
        names = [n for n in [*involved, relations[i][0]] if not n.startswith("node ")]
        kinds = sorted({elements[n].TYPE for n in names if n in elements})
        if kind == "across":
            raise NetworkError(
                f"{' and '.join(repr(n) for n in names)} fix the same variable: "
                f"{'they are in parallel' if len(kinds) == 1 and kinds[0].endswith('source') else 'they form a loop'}"
                f" ({', '.join(kinds)}), so the across variable between their nodes is given twice. Keep one source, "
                "or put a resistance (a resistor, a damper) in series with one of them.",
                key=f"elements.{relations[i][0]}")
        raise NetworkError(
            f"{' and '.join(repr(n) for n in names)} fix the same variable: "
            f"they are in series ({', '.join(kinds)}), so the through variable they share is given twice. Keep "
            "one source, or put an element in parallel with one of them.", key=f"elements.{relations[i][0]}")
    # pivot variables by the generic matrix's reduced row echelon form
    _, pivots = Mg.rref()
    pivot_vars = [variables[j] for j in pivots]
    sol = sp.solve(exprs, pivot_vars, dict=True)
    sol = sol[0] if sol else {}

    def reduce(expr):
        return sp.expand(sp.sympify(expr).subs(sol))

    return reduce


def _combination(sp, form, chosen, variables, numeric):
    """``form`` (a linear form in ``variables`` plus a source part) as a combination of the chosen
    forms: ({element: coefficient}, source part), or None if it is independent of them."""
    free = sorted((v for v in form.free_symbols if v in set(variables)), key=lambda v: v.name)
    if not free:
        return ({}, form)
    cols = sorted({v for _, f in chosen for v in f.free_symbols if v in set(variables)} | set(free),
                  key=lambda v: v.name)

    def vec(f):
        return [sp.expand(f).coeff(v) for v in cols]

    base = [vec(f) for _, f in chosen]
    target = vec(form)
    if not base:
        return None
    Bg = sp.Matrix(base).applyfunc(numeric)
    Tg = sp.Matrix([target]).applyfunc(numeric)
    if sp.Matrix.vstack(Bg, Tg).rank() > Bg.rank():
        return None
    cs = sp.symbols(f"c0:{len(base)}")
    eq = [sum((cs[i] * base[i][j] for i in range(len(base))), sp.Integer(0)) - target[j] for j in range(len(cols))]
    sol = sp.solve(eq, cs, dict=True)
    sol = sol[0] if sol else {}
    coeffs = {}
    rest = sp.expand(form)
    for i, (name, f) in enumerate(chosen):
        c = sp.simplify(sol.get(cs[i], 0).subs({c_: 0 for c_ in cs}))
        if c != 0:
            coeffs[name] = c
            rest -= c * f
    rest = sp.simplify(sp.expand(rest))
    return coeffs, rest


def _reduction_note(sp, name, el, coeffs, rest, marker, elements, var) -> str:
    """One line naming the reduced store and why (``C1 and C2 are in parallel: ...``)."""
    sources = [n for n in marker if rest.has(marker[n])]
    others = list(coeffs)
    what = DOMAINS[el.DOMAIN].across_word if el.ROLE == "across-store" else DOMAINS[el.DOMAIN].through_word
    if others and not sources:
        exprs = to_text(sum((c * sp.Symbol(f"{o}.{var}") for o, c in coeffs.items()), sp.Integer(0)))
        couplings = _couplings_between(elements, [name, *others])
        if couplings and any(c != 1 for c in coeffs.values()):
            why = "joined by " + ", ".join(couplings)
        else:
            why = "in parallel" if el.ROLE == "across-store" else "in series"
        return (f"{name} and {', '.join(others)} are {why}: {name}.{var} = {exprs}, so {name} adds no state "
                f"(its {what} follows from {', '.join(f'{o}.{var}' for o in others)})")
    if sources and not others:
        return (f"{name}'s {what} is fixed by the source {', '.join(sources)}: {name} adds no state (it follows "
                f"{', '.join(sources)}'s value)")
    return (f"{name}'s {what} follows from {', '.join(others)} and the source {', '.join(sources)}: "
            f"{name} adds no state")


def _couplings_between(elements, names) -> list[str]:
    """The couplings (gears, levers...) on the way between the nodes of the named elements."""
    nodes = {n for name in names for n in elements[name].nodes if n != GROUND}
    found: list[str] = []
    grown = True
    while grown:
        grown = False
        for cname, el in elements.items():
            if el.ROLE not in ("transformer", "gyrator") or cname in found:
                continue
            sides = [set(el.nodes) - {GROUND}, set(el.nodes2) - {GROUND}]
            if all(side & nodes for side in sides):
                found.append(cname)
    if not found:  # a chain: grow the node set through couplings touching it
        for cname, el in elements.items():
            if el.ROLE == "transformer" and (set(el.nodes) | set(el.nodes2)) & nodes:
                found.append(cname)
    return found


def _solve_laws(sp, eqs, unknowns, numeric, graph, elements):
    """Solve the linear laws for every unknown (a singular system: say where the network is not
    determined)."""
    M, rhs = sp.linear_eq_to_matrix([sp.expand(e) for e in eqs], unknowns)
    if M.shape[0] != M.shape[1] or M.applyfunc(numeric).rank() < M.shape[1]:
        Mg = M.applyfunc(numeric)
        undetermined = []
        null = Mg.nullspace()
        for vec in null:
            for j, val in enumerate(vec):
                if val != 0:
                    undetermined.append(unknowns[j].name)
        where = ", ".join(dict.fromkeys(undetermined)) or "some variables"
        raise NetworkError(
            "the network's laws do not determine " + where + ": an element or a node has nothing that fixes its "
            "variable (two springs in series with no mass or damper between them, a node with only a source, a "
            "coupling whose side carries nothing). Combine the elements, or add a mass, damper or resistance at "
            "that node.", key="elements")
    sol = sp.linsolve((M, rhs), unknowns)
    values = next(iter(sol))
    return {u: sp.expand(v) for u, v in zip(unknowns, values)}


def _element_variables(sp, elements, across, flow, u, solution, stretch, known_disp, el_state, law_var, final,
                       disp_of, G, W):
    """Every element variable (``spring.f``) as an expression of the states and inputs."""
    out = {}
    for name, el in elements.items():
        sides = [(1, el.DOMAIN, el.nodes)]
        if el.DOMAIN2:
            sides.append((2, el.DOMAIN2, el.nodes2))
        for side, domain, nodes in sides:
            d = DOMAINS[domain]
            suffix = "2" if side == 2 and el.DOMAIN2 == el.DOMAIN else ""
            F = flow[(name, side)]
            sign = -1 if (el.ROLE == "through-source" or el.ROLE == "across-source" or side == 2) else 1
            out[f"{name}.{d.across}{suffix}"] = final(u(name, side))
            out[f"{name}.{d.through}{suffix}"] = final(sign * F)
            if d.integral:
                if name in el_state and el.ROLE == "across-store":
                    out[f"{name}.{d.integral}"] = el_state[name + ":integral"]
                elif name in stretch:
                    out[f"{name}.{d.integral}"] = final(stretch[name])
                else:
                    x = disp_of(*nodes)
                    if x is not None:
                        out[f"{name}.{d.integral}{suffix}"] = final(x)
    return out


def _law_lines(elements, coef, law_expr, law_var, value, stretch, el_state, sp):
    S = sp.Symbol

    def mul(c, name):
        if name.startswith("d("):  # a derivative: its coefficient in front, whole
            return name if c == 1 else f"{_factor(c)}*{name}"
        return to_text(c * S(name))

    lines = []
    for name, el in elements.items():
        d = DOMAINS[el.DOMAIN]
        c = coef[name]
        v, f = f"{name}.{d.across}", f"{name}.{d.through}"
        if el.ROLE == "across-store":
            text = f"{f} = {mul(c[_first(el.PARAMETERS)], f'd({v})/dt')}"
            if d.integral:
                text += f",  d({name}.{d.integral})/dt = {v}"
        elif el.ROLE == "through-store":
            if d.integral:
                x = f"{name}.{d.integral}"
                law = to_text(law_expr[name].subs(law_var[name], S(x))) if name in law_expr else mul(c["k"], x)
                text = f"{f} = {law},  d({x})/dt = {v}"
            else:
                text = f"{mul(c[_first(el.PARAMETERS)], f'd({f})/dt')} = {v}"
        elif el.ROLE == "dissipator":
            if name in law_expr:
                text = f"{f} = {to_text(law_expr[name].subs(law_var[name], S(v)))}"
            else:
                k = c[_first(el.PARAMETERS)]
                text = f"{f} = {mul(k, v)}" if el.TYPE in ("damper", "rotational-damper") else f"{f} = {mul(1 / k, v)}"
        elif el.ROLE == "across-source":
            text = f"{v} = {to_text(value[name])}"
        elif el.ROLE == "through-source":
            text = f"{f} = {to_text(value[name])}"
        else:
            d2 = DOMAINS[el.DOMAIN2]
            s2 = "2" if el.DOMAIN2 == el.DOMAIN else ""
            v2, f2 = f"{name}.{d2.across}{s2}", f"{name}.{d2.through}{s2}"
            if el.ROLE == "gyrator":
                text = f"{f2} = {mul(c['K'], f)},  {v} = {mul(c['K'], v2)}"
            elif el.TYPE == "rack-pinion":
                text = f"{v2} = {mul(c['r'], v)},  {f2} = {mul(1 / c['r'], f)}"
            else:
                text = f"{v2} = {mul(1 / c['n'], v)},  {f2} = {mul(c['n'], f)}"
        lines.append((name, text))
    return lines


def _factor(expr) -> str:
    text = to_text(expr)
    return text if expr.is_Atom else f"({text})"


def _interconnection_lines(graph: Graph, elements, sp) -> list[str]:
    lines = []
    for domain, node in graph.nodes:
        d = DOMAINS[domain]
        left, right = [], []
        for p in graph.ports:
            el = elements[p.element]
            suffix = "2" if p.side == 2 and el.DOMAIN2 == el.DOMAIN else ""
            var = f"{p.element}.{d.through}{suffix}"
            gives = el.ROLE in ("through-source", "across-source") or p.side == 2
            if p.a == node:
                (right if gives else left).append(var)
            if p.b == node:
                (left if gives else right).append(var)
        lines.append(f"node {node}: {' + '.join(left) or '0'} = {' + '.join(right) or '0'}")
    pairs: dict[tuple[str, str, str], list[str]] = {}  # elements between the same nodes share one line
    for name, el in elements.items():
        sides = [(1, el.DOMAIN, el.nodes)]
        if el.DOMAIN2:
            sides.append((2, el.DOMAIN2, el.nodes2))
        for side, domain, (a, b) in sides:
            d = DOMAINS[domain]
            suffix = "2" if side == 2 and el.DOMAIN2 == el.DOMAIN else ""
            pairs.setdefault((domain, a, b), []).append(f"{name}.{d.across}{suffix}")
    for (domain, a, b), names in pairs.items():
        d = DOMAINS[domain]
        terms = [f"{d.across}({n})" for n in (a, b) if n != GROUND]
        rhs = terms[0] if b == GROUND else (f"-{terms[0]}" if a == GROUND else f"{terms[0]} - {terms[1]}")
        lines.append(f"{' = '.join(names)} = {rhs}")
    return lines


def _linear_form(sp, equations, outputs, states, inputs, symbols, t):
    """(True, {A, B, C, D}) when x' and y are linear in the states and inputs, else (False, None)."""
    X = [symbols[s] for s in states]
    U = [symbols[u] for u in inputs]
    f = sp.Matrix([equations[s] for s in states]) if states else sp.zeros(0, 1)
    g = sp.Matrix([outputs[y] for y in outputs]) if outputs else sp.zeros(0, 1)
    mats = {}
    for name, vec, wrt in (("A", f, X), ("B", f, U), ("C", g, X), ("D", g, U)):
        mats[name] = vec.jacobian(wrt) if vec.shape[0] and wrt else sp.zeros(vec.shape[0], len(wrt))
    allvars = set(X) | set(U) | {t}
    for m in mats.values():
        if any(e.free_symbols & allvars for e in m) or any(e.atoms(sp.Function) for e in m):
            return False, None
    for vec, A_, B_ in ((f, mats["A"], mats["B"]), (g, mats["C"], mats["D"])):
        if vec.shape[0] == 0:
            continue
        rest = vec - (A_ * sp.Matrix(X) if X else sp.zeros(vec.shape[0], 1)) \
            - (B_ * sp.Matrix(U) if U else sp.zeros(vec.shape[0], 1))
        if any(sp.cancel(sp.expand(e)) != 0 for e in rest):
            return False, None
    return True, {k: m.applyfunc(lambda e: _tidy(sp, e)) for k, m in mats.items()}
