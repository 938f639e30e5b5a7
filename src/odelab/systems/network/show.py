"""The derivation as a student writes it: plain text at 80 columns (the CLI) and as sections of
lines (the report). Pure functions of a derived network: nothing is printed here."""

from __future__ import annotations

import textwrap

from odelab.systems.network.elements import DOMAINS
from odelab.systems.network.symbolic import require_sympy, to_text

__all__ = ["derivation_sections", "derivation_text", "compact_lines", "transfer_functions", "matrix_text"]


def matrix_text(rows) -> str:
    """``[0, 1; -k/m, -b/m]`` (MATLAB's rows) from rows of strings or numbers."""
    def cell(v):
        return f"{v:.6g}" if isinstance(v, float) else str(v)
    return "[" + "; ".join(", ".join(cell(v) for v in row) for row in rows) + "]"


def _poly_text(sp, expr, s) -> str:
    """A polynomial in s, highest power first: ``m*s^2 + b*s + k``."""
    poly = sp.Poly(sp.expand(expr), s)
    terms = []
    for (k,), c in sorted(poly.terms(), key=lambda kc: -kc[0][0]):
        c = sp.factor(c)
        power = "" if k == 0 else ("s" if k == 1 else f"s^{k}")
        if k == 0:
            text = to_text(c)
        elif c == 1:
            text = power
        elif c == -1:
            text = "-" + power
        else:
            ct = to_text(c)
            text = f"({ct})*{power}" if c.is_Add else f"{ct}*{power}"
        terms.append(text)
    out = " + ".join(terms) if terms else "0"
    return out.replace("+ -", "- ")


def transfer_functions(derivation, values=None, symbolic: bool = True) -> list[tuple[str, str, str]]:
    """[(output/input, symbolic G(s), numeric G(s))] of a linear network."""
    sp = require_sympy()
    d = derivation
    if not d.linear or not d.inputs or not d.outputs:
        return []
    s = sp.Symbol("s")
    A, B, C, D = (d.matrices[k] for k in "ABCD")
    n = A.shape[0]
    out = []
    if n:
        M = s * sp.eye(n) - A
        adj = M.adjugate()
        det = sp.expand(M.det())
    for j, u in enumerate(d.inputs):
        for i, y in enumerate(d.outputs):
            if n:
                num = sp.expand((C[i, :] * adj * B[:, j])[0, 0] + D[i, j] * det)
                G = sp.cancel(num / det)
            else:
                G = D[i, j]
            nm, dn = sp.fraction(sp.cancel(sp.together(G)))
            # a monic-in-s denominator's leading coefficient moved into the numerator is not
            # textbook form: keep the derived polynomials, cleared of common factors
            sym = f"({_poly_text(sp, nm, s)}) / ({_poly_text(sp, dn, s)})" if symbolic else ""
            numeric = ""
            if values is not None:
                subs = {d.symbols[p]: sp.Float(v, 17) if not float(v).is_integer() else sp.Integer(int(v))
                        for p, v in values.items() if p in d.symbols}
                nn, dd = sp.Poly(sp.expand(nm.subs(subs)), s), sp.Poly(sp.expand(dn.subs(subs)), s)
                lead = dd.LC()
                if lead != 0:  # the numeric form is monic, as MATLAB's tf shows it
                    nn, dd = sp.Poly(nn.as_expr() / lead, s), sp.Poly(dd.as_expr() / lead, s)
                numeric = f"({_numeric_poly(nn)}) / ({_numeric_poly(dd)})"
            out.append((f"{y}/{u}", sym, numeric))
    return out


def _numeric_poly(poly) -> str:
    deg = poly.degree()
    coeffs = [float(c) for c in poly.all_coeffs()]
    terms = []
    for k, c in zip(range(deg, -1, -1), coeffs):
        if c == 0:
            continue
        mag = f"{abs(c):.6g}"
        power = "" if k == 0 else ("s" if k == 1 else f"s^{k}")
        body = mag if k == 0 else (power if mag == "1" else f"{mag} {power}")
        terms.append(("-" if c < 0 else "+", body))
    if not terms:
        return "0"
    text = ("-" if terms[0][0] == "-" else "") + terms[0][1]
    for sign, body in terms[1:]:
        text += f" {sign} {body}"
    return text


def derivation_sections(net, values=None, symbolic_tf: bool = True) -> list[tuple[str, list[str]]]:
    """[(heading, lines)]: elements, interconnection, states, state equations, outputs, A..D, G(s)."""
    d = net.derive()
    sections = []
    width = max(len(n) for n in d.elements)
    laws = []
    for name, law in d.laws:
        el = d.elements[name]
        laws.append(f"{name.ljust(width)}  {el.describe()}:  {law}")
    sections.append(("Element laws", laws))
    nodes = [line for line in d.interconnection if line.startswith("node ")]
    compat = [line for line in d.interconnection if not line.startswith("node ")]
    domains = sorted({el.DOMAIN for el in d.elements.values()} | {el.DOMAIN2 for el in d.elements.values()
                                                                  if el.DOMAIN2})
    words = "; ".join(DOMAINS[dn].node_law for dn in domains)
    inter = [f"at each node, {words}:", *(f"  {line}" for line in nodes),
             "compatibility (each element's across variable from its nodes'):", *(f"  {line}" for line in compat)]
    sections.append(("Interconnection laws", inter))
    stores = [n for n, el in d.elements.items() if el.ROLE in ("across-store", "through-store")]
    head = (f"{', '.join(d.states) or 'none'} ({len(d.states)} state{'s' if len(d.states) != 1 else ''}; "
            f"energy stores: {', '.join(stores) or 'none'})")
    sections.append(("States", [head, *d.state_notes]))
    eq = d.equation_texts()
    sections.append(("State equations", [f"d({s})/dt = {eq[s]}" for s in d.states]))
    if d.outputs:
        sections.append(("Outputs", [f"{y} = {t}" for y, t in d.output_texts().items()]))
    if d.linear:
        lines = [f"x' = A x + B u, y = C x + D u;  x = ({', '.join(d.states)}), u = ({', '.join(d.inputs)}), "
                 f"y = ({', '.join(d.outputs)})"]
        numeric = net.matrices(values) if values is not None else None
        for k in "ABCD":
            m = d.matrices[k]
            if 0 in m.shape:
                continue
            sym = matrix_text([[to_text(m[i, j]) for j in range(m.shape[1])] for i in range(m.shape[0])])
            text = f"{k} = {sym}"
            if numeric is not None:
                num = matrix_text(numeric[k].tolist())
                if num != sym:
                    text += f" = {num}"
            lines.append(text)
        sections.append(("Linear: state-space matrices", lines))
        tfs = transfer_functions(d, values, symbolic=symbolic_tf)
        if tfs:
            tf_lines = []
            for label, sym, num in tfs:
                tf_lines.append(f"G_{label}(s) = {sym}" + (f" = {num}" if num and num != sym else ""))
            sections.append(("Transfer functions", tf_lines))
    elif any(e.has(d.symbols["t"]) for e in [*d.equations.values(), *d.output_expressions.values()]):
        sections.append(("Time-varying", ["a source's value is a function of t: odelab integrates the equations "
                                          "as written above; give the source's value as an input (an [inputs] "
                                          "table: sine, ramp, table...) to get A, B, C, D"]))
    elif _affine(d):
        sections.append(("Affine", ["the state equations are linear but for constant terms (a source of constant "
                                    "value): odelab integrates them as written above; give the constant as an "
                                    "input (an [inputs] table of type \"constant\") to get A, B, C, D"]))
    else:
        sections.append(("Nonlinear", ["the state equations are nonlinear: odelab integrates them as written "
                                       "above; [linearize] gives the linear model about an operating point"]))
    return sections


def _affine(d) -> bool:
    """x' = A x + B u + c with c != 0: every equation and output of degree at most 1."""
    sp = require_sympy()
    names = [d.symbols[n] for n in (*d.states, *d.inputs)] + [d.symbols["t"]]
    try:
        return all(sp.Poly(e, *names).total_degree() <= 1
                   for e in [*d.equations.values(), *d.output_expressions.values()])
    except sp.PolynomialError:
        return False


def derivation_text(net, values=None, width: int = 80) -> str:
    """The derivation as text wrapped at ``width`` columns."""
    out = []
    for heading, lines in derivation_sections(net, values):
        out.append(heading)
        for line in lines:
            indent = "  " + " " * (len(line) - len(line.lstrip()))
            out.extend(textwrap.wrap(line.strip(), width=width, initial_indent=indent,
                                     subsequent_indent=indent + "    ", break_on_hyphens=False,
                                     break_long_words=False) or [""])
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def compact_lines(net) -> list[str]:
    """Three or four lines for ``odelab run``: the states and the state equations."""
    d = net.derive()
    eq = d.equation_texts()
    lines = [f"network: {len(d.elements)} elements -> {len(d.states)} states ({', '.join(d.states)})"
             + (" (linear)" if d.linear else " (nonlinear)")]
    lines += [f"  {note}" for note in d.state_notes if " adds no state" in note]
    lines += [f"  d({s})/dt = {eq[s]}" for s in d.states]
    lines.append("  (the whole derivation: odelab network FILE.toml)")
    return lines
