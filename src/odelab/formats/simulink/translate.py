"""A Simulink :class:`~odelab.formats.simulink.model.Model` -> the sections of an odelab diagram experiment.

Subsystems are flattened (their blocks named ``Sub_Gain``), Inport/Outport, Goto/From, bus
creators and selectors and conversions are followed to the block that computes the signal,
every other block is mapped by :mod:`~odelab.formats.simulink.mapping`, and the blocks whose
output reaches no sink are left out. The sinks (Scope, Display, To Workspace, XY Graph, the
root's Outports) name the experiment's ``[system] outputs``; the solver settings become
``[time]`` and ``[solver]``. Every block gets a :class:`~odelab.formats.base.Note`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from odelab.formats.base import GAP, IGNORED, TRANSLATED, Note
from odelab.formats.simulink import mapping
from odelab.formats.simulink.mexpr import MExprError, V, evaluate, text_of
from odelab.formats.simulink.model import Block, Model, System
from odelab.formats.simulink.scope import Parameters, Scope, identifier

__all__ = ["Flat", "Translation", "translate"]

INHERIT = "inherit"  # a sample time of -1, resolved from the block's input after wiring


@dataclass
class Flat:
    """One odelab block: its name, its table (without input), what feeds it, and where it came from."""

    name: str
    spec: dict
    inputs: list  # Simulink input port numbers of ``owner`` or ("ref", odelab reference)
    owner: Block
    system: System
    refs: list = field(default_factory=list)  # the resolved references, after wiring
    gap: str = ""


class Translation:
    """The state of one model's translation; :func:`translate` drives it."""

    def __init__(self, model: Model, scope: Scope, solver: dict):
        self.model = model
        self.root_scope = scope
        self.params: Parameters = scope.params
        self.notes: list[Note] = []
        self.flats: dict[str, Flat] = {}
        self.taken: set[str] = set()
        self.outs: dict[tuple[int, str], str] = {}  # (id(block), port) -> reference
        self.routes: dict[tuple[int, str], tuple[Block, str]] = {}  # (id(block), port) -> (block, input port)
        self.sources: dict[tuple[int, str], tuple[Block, str]] = {}  # (id(dst block), in port) -> (src block, out port)
        self.parent: dict[int, tuple[Block, System]] = {}  # id(system) -> (its subsystem block, the parent system)
        self.flattened: set[int] = set()  # ids of subsystem blocks whose contents are flattened
        self.gotos: dict[tuple[int, str], Block] = {}
        self.global_gotos: dict[str, Block] = {}
        self.buses: dict[int, Block] = {}
        self.sinks: list[tuple[Block, System]] = []
        self.initials: dict[str, tuple[Block, str]] = {}  # block -> (Simulink block, port) feeding its initial value
        self.consumed: set[str] = set()  # constants read into an initial value: not blocks of their own
        self.missing: dict[str, list[str]] = {}
        self.solver = solver

    def name_for(self, wanted: str) -> str:
        base = identifier(wanted)
        name, n = base, 2
        while name in self.taken:
            name = f"{base}_{n}"
            n += 1
        self.taken.add(name)
        return name

    def note(self, block: Block, outcome: str, detail: str, construct: str = "") -> None:
        what = construct or (block.type if block.type != "Reference" else block.source or "Reference")
        self.notes.append(Note(f"block {block.path}", what, outcome, detail))


class BlockContext:
    """What a mapping function sees: one Simulink block, its scope, and the translation to add blocks to."""

    def __init__(self, tr: Translation, block: Block, system: System, scope: Scope, prefix: str):
        self.tr = tr
        self.block = block
        self.system = system
        self.scope = scope
        self.name = tr.name_for(f"{prefix}{block.name}")
        self.added: list[str] = []
        self.extra: list[str] = []
        self.gapped = ""

    # -- parameters ----------------------------------------------------------------------------
    def text(self, key: str, default: str) -> str:
        params = self.block.params
        if key in params:
            return params[key]
        return self.tr.model.defaults.get(self.block.type, {}).get(key, default)

    def p(self, key: str, default: str) -> V:
        text = self.text(key, default)
        missing: set[str] = set()
        try:
            value = evaluate(text, lambda n: self.scope.lookup(n, self.name), missing)
        except MExprError as exc:
            self.gap(f"its {key} {text!r} is not a value this importer reads ({exc}); write the number", "")
            return V(np.array([[math.nan]]))
        for name in missing:
            self.tr.missing.setdefault(name, [])
            if self.block.path not in self.tr.missing[name]:
                self.tr.missing[name].append(self.block.path)
        if value.sym is not None and value.scalar and not missing and _as_written(text, value, self.scope):
            value.sym[0, 0] = " ".join(text.split())  # "1/m" as the student wrote it (the same number)
        return value

    @staticmethod
    def item(value: V, i: int = 0):
        idx = np.unravel_index(i, value.num.shape, order="F")
        return value.item(idx)

    @staticmethod
    def text_item(value: V, i: int = 0) -> str:
        idx = np.unravel_index(i, value.num.shape, order="F")
        return str(value.texts()[idx])

    def scalar(self, key: str, default: str):
        value = self.p(key, default)
        if value.num.size != 1:
            self.gap(f"its {key} is a {value.num.shape[0]}x{value.num.shape[1]} value; odelab's block takes one "
                     "number here", "")
            return 0.0
        return self.item(value)

    def list_of(self, value: V) -> list:
        return [self.item(value, i) for i in range(value.num.size)]

    def numbers(self, key: str, default: str, vector: bool = False):
        value = self.p(key, default)
        if value.num.size == 1 and not vector:
            return self.item(value)
        if value.num.size > 1 and min(value.num.shape) > 1:
            self.gap(f"its {key} is a matrix; a list of numbers is needed", "")
        return self.list_of(value)

    def matrix_of(self, value: V, transpose: bool = False) -> list:
        num = value.num.T if transpose else value.num
        texts = None if value.sym is None else (value.sym.T if transpose else value.sym)
        return [[V(num, texts).item((i, j)) for j in range(num.shape[1])] for i in range(num.shape[0])]

    def matrix(self, key: str, default: str) -> list:
        return self.matrix_of(self.p(key, default))

    def sample(self, key: str, default: str):
        value = self.p(key, default)
        flat = [self.item(value, i) for i in range(value.num.size)]
        if value.sym is None and value.num.size >= 1 and float(value.num.reshape(-1)[0]) == -1.0:
            return INHERIT
        if value.sym is None and value.num.size >= 1 and float(value.num.reshape(-1)[0]) == 0.0:
            self.gap(f"its {key} is 0 (continuous): odelab's block is discrete; give it a sample time", "")
            return 1.0
        if value.sym is None and value.num.size >= 1 and math.isinf(float(value.num.reshape(-1)[0])):
            self.gap(f"its {key} is inf (constant): give it a sample time", "")
            return 1.0
        return flat[0] if len(flat) == 1 else flat[:2]

    def zero_crossing(self) -> dict:
        return {"zero_crossing": False} if self.text("ZeroCross", "on").lower() == "off" else {}

    def fcn_expression(self, text: str) -> str | None:
        """A Fcn block's expression in odelab's language: ``u(1)`` and ``u[1]`` as ``u1``, MATLAB's operators as
        odelab's, workspace names as parameters."""
        text = re.sub(r"\bu\s*[\(\[]\s*(\d+)\s*[\)\]]", r"u\1", text)
        missing: set[str] = set()

        def lookup(n):
            if re.fullmatch(r"u\d*", n):
                return V(np.array([[1.0]]), np.array([[n]], dtype=object))
            return self.scope.lookup(n, self.name)

        try:
            value = evaluate(text, lookup, missing)
        except MExprError as exc:
            self.gap(f"its expression {text!r} is not one this importer reads ({exc}); write it as an odelab fcn", "")
            return None
        for name in missing:
            self.tr.missing.setdefault(name, []).append(self.block.path)
        return text_of(value)

    # -- what the block becomes ----------------------------------------------------------------------
    def add(self, spec: dict, inputs=None, name: str | None = None, out: int | None = 1) -> str:
        if name is None:
            name = self.name
        elif name != self.name:
            name = self.tr.name_for(name)
        self.tr.flats[name] = Flat(name, dict(spec), list(inputs or []), self.block, self.system)
        self.added.append(name)
        if out is not None:
            self.out(out, name)
        return name

    def out(self, port: int, ref: str) -> None:
        self.tr.outs[(id(self.block), str(port))] = ref

    def route(self, out_port: int, in_port: int) -> None:
        self.tr.routes[(id(self.block), str(out_port))] = (self.block, str(in_port))

    def held(self, key: str) -> None:
        """A source with a nonzero sample time: its value sampled and held (a zero-order hold after it)."""
        value = self.p(key, "0")
        if value.sym is None and value.num.size and float(value.num.reshape(-1)[0]) in (0.0, -1.0):
            return
        flat = self.tr.flats.pop(self.name)
        inner = self.tr.name_for(f"{self.name}_continuous")
        flat.name = inner
        self.tr.flats[inner] = flat
        self.added.append(inner)
        self.add({"type": "zero-order-hold", "sample_time": self.sample(key, "0")}, inputs=[("ref", inner)])
        self.note("its sample time: the source is sampled and held by a zero-order hold")

    def note(self, detail: str) -> None:
        self.extra.append(detail)

    def inputs_count(self, key: str, default: str) -> int:
        return input_count(self.tr, self.block, key, default)

    def initial_from(self, port: int) -> None:
        """The block's initial condition is what feeds its input ``port`` (a constant), read after wiring."""
        self.tr.initials[self.name] = (self.block, str(port))

    def gap(self, detail: str, kind: str) -> None:
        if not self.gapped:
            self.gapped = detail


_PLAIN = re.compile(r"^[A-Za-z0-9_.\s+\-*/^()]+$")


def _as_written(text: str, value: V, scope: Scope) -> bool:
    """Whether a scalar parameter's text reads the same in odelab's language: plain arithmetic of numbers and of
    parameters that keep their names (no elementwise dots, no renamed mask parameter)."""
    if not _PLAIN.match(text) or re.search(r"\.[*/^]", text):
        return False
    for name in set(re.findall(r"(?<![\w.])([A-Za-z_]\w*(?:\.\w+)*)", text)):
        if name in ("pi",):
            continue
        found = scope.lookup(name)
        if found is None or found.sym is None or not found.scalar or str(found.sym[0, 0]) != name:
            return False
    return True


def _follow(tr: Translation, block: Block, port: str, seen: int = 0):
    """The (block, port) that computes what ``block``'s output ``port`` carries: through subsystems' Outports and
    Inports, Goto/From, selectors and routing blocks (iterative; a loop of routing blocks alone is refused)."""
    for _ in range(100_000):
        key = (id(block), port)
        if key in tr.outs:
            return block, port
        if key in tr.routes:
            blk, inp = tr.routes[key]
            src = tr.sources.get((id(blk), inp))
            if src is None:
                return None
            block, port = src
            continue
        if id(block) in tr.flattened:
            inner = next((b for b in block.system.blocks if b.type == "Outport" and b.params.get("Port", "1") == port),
                         None)
            if inner is None:
                return None
            src = tr.sources.get((id(inner), "1"))
            if src is None:
                return None
            block, port = src
            continue
        if block.type == "Inport":
            owner = _owner(tr, block)
            if owner is None:
                return block, port  # a root Inport: a source of its own
            sub, _ = owner
            src = tr.sources.get((id(sub), block.params.get("Port", "1")))
            if src is None:
                return None
            block, port = src
            continue
        if block.type == "From":
            goto = _goto(tr, block)
            if goto is None:
                return None
            src = tr.sources.get((id(goto), "1"))
            if src is None:
                return None
            block, port = src
            continue
        if block.type == "BusSelector":
            found = _select(tr, block, int(port))
            if found is None:
                return None
            block, port = found
            continue
        return block, port
    return None


def _owner(tr: Translation, block: Block):
    return tr.parent.get(id(tr.block_system[id(block)]))


def _gap_block(tr: Translation, block: Block, system: System, prefix: str) -> str:
    """A block that could not be translated: a place in [blocks] (written as a gap) that its users still name."""
    name = tr.name_for(prefix + block.name)
    tr.flats[name] = Flat(name, {}, [], block, system, gap="not translated")
    for port in range(1, 9):
        tr.outs.setdefault((id(block), str(port)), name)
    return name


def _goto(tr: Translation, block: Block):
    tag = block.params.get("GotoTag", "A")
    system = tr.block_system.get(id(block))
    while system is not None:
        found = tr.gotos.get((id(system), tag))
        if found is not None:
            return found
        up = tr.parent.get(id(system))
        system = up[1] if up else None
    return tr.global_gotos.get(tag)


def input_count(tr: Translation, block: Block, key: str, default: str) -> int:
    """How many inputs a block has: its ``Ports`` (``[2, 1]``), else its parameter ``key`` (a count, or a list
    of names or signs), the model's default for its type, or ``default``."""
    ports = block.params.get("Ports", "").strip("[] ")
    first = ports.split(",")[0].strip() if ports else ""
    if first.isdigit():
        return int(first)
    text = block.params.get(key, tr.model.defaults.get(block.type, {}).get(key, default)).strip()
    if text.isdigit():
        return int(text)
    return max(1, len([p for p in text.strip("[]").split(",") if p.strip()]))


def _bus_elements(tr: Translation, creator: Block) -> list[tuple[str, tuple[Block, str]]]:
    out = []
    count = input_count(tr, creator, "Inputs", "2")
    for i in range(1, count + 1):
        src = tr.sources.get((id(creator), str(i)))
        if src is None:
            continue
        name = tr.line_names.get((id(creator), str(i))) or src[0].port_names.get(int(src[1]) if src[1].isdigit()
                                                                               else 0) or f"signal{i}"
        out.append((name, src))
    return out


def _select(tr: Translation, selector: Block, k: int):
    wanted = [w.strip() for w in selector.params.get("OutputSignals", "signal1,signal2").split(",")]
    if k > len(wanted):
        return None
    path = wanted[k - 1].split(".")
    src = tr.sources.get((id(selector), "1"))
    while src is not None and path:
        creator = _follow(tr, *src)
        if creator is None or creator[0].type != "BusCreator":
            return None
        elements = dict(_bus_elements(tr, creator[0]))
        src = elements.get(path.pop(0))
    return src


def translate(model: Model, scope: Scope) -> Translation:
    """Flatten and map every block (:func:`~odelab.formats.simulink.wiring.finish` then wires them)."""
    tr = Translation(model, scope, model.solver)
    tr.systems = []
    tr.line_names = {}
    tr.block_system = {}
    tr.fixed_step = None
    _walk(tr, model.root, scope)
    return tr


def _walk(tr: Translation, root: System, scope: Scope) -> None:
    stack = [(root, scope, "")]
    while stack:
        system, sc, prefix = stack.pop()
        tr.systems.append(system)
        for block in system.blocks:
            tr.block_system[id(block)] = system
        for line in system.lines:
            for dst, dport in line.dsts:
                tr.sources[(id(dst), dport)] = line.src
                if line.name:
                    tr.line_names[(id(dst), dport)] = line.name
        for block in system.blocks:
            if block.type == "Goto":
                tag = block.params.get("GotoTag", "A")
                tr.gotos[(id(system), tag)] = block
                if block.params.get("TagVisibility", "local").lower() in ("global", "scoped"):
                    tr.global_gotos.setdefault(tag, block)
        for block in system.blocks:
            pushed = _subsystem(tr, block, system, sc, prefix)
            if pushed is _HANDLED:
                continue
            if pushed is not None:
                stack.append(pushed)
                continue
            _map_block(tr, block, system, sc, prefix)


_HANDLED = object()  # a subsystem turned into a gap: nothing more to map


def _matlab_function(tr: Translation, block: Block, system: System, scope: Scope, prefix: str) -> bool:
    """A MATLAB Function block of straight-line scalar code: one fcn block per output (True), else False."""
    from odelab.formats.simulink.mfunction import function_outputs

    model_path = block.path.split("/", 1)[1] if "/" in block.path else block.name
    script = tr.model.scripts.get(model_path) or tr.model.scripts.get(block.name)
    if script is None:
        return False
    exprs, why = function_outputs(script, lambda n: scope.lookup(n, block.path))
    if why:
        tr.note(block, GAP, f"a MATLAB Function block whose code is not translated ({why}): write it as fcn blocks",
                construct="MATLAB Function")
        _gap_block(tr, block, system, prefix)
        return True
    inner = [b for b in block.system.blocks if b.type == "Inport"] if block.system else []
    n_in = max(len(inner), 1)
    c = BlockContext(tr, block, system, scope, prefix)
    for k, expression in enumerate(exprs):
        name = c.name if k == 0 else f"{c.name}_{k + 1}"
        c.add({"type": "fcn", "expression": expression}, inputs=list(range(1, n_in + 1)), name=name, out=k + 1)
    tr.note(block, TRANSLATED, "its MATLAB code, straight-line arithmetic, as " + ", ".join(
        f"`{n}` = {e}" for n, e in zip(c.added, exprs)), construct="MATLAB Function")
    return True
_SUBSYSTEM_GAPS = (("TriggerPort", "a triggered subsystem"), ("EnablePort", "an enabled subsystem"),
                   ("ActionPort", "an If/Switch Case action subsystem"), ("ForIterator", "a For Iterator subsystem"),
                   ("WhileIterator", "a While Iterator subsystem"), ("ResetPort", "a resettable subsystem"))


def _subsystem(tr: Translation, block: Block, system: System, scope: Scope, prefix: str):
    """A SubSystem to flatten: (its system, its scope, its prefix) to walk; None when it is not one."""
    if block.type != "SubSystem" or block.system is None:
        return None
    kind = block.params.get("SFBlockType", "") or block.params.get("MaskType", "")
    if kind == "MATLAB Function" and _matlab_function(tr, block, system, scope, prefix):
        return _HANDLED
    if kind in ("Chart", "MATLAB Function", "Stateflow", "State Transition Table", "Truth Table"):
        _gap_block(tr, block, system, prefix)
        tr.note(block, GAP, f"a {kind} block (Stateflow / MATLAB code) is not a diagram: write its logic as fcn blocks "
                "or an ODE file's [events]", construct=kind)
        return _HANDLED
    for inner in block.system.blocks:
        for port_type, what in _SUBSYSTEM_GAPS:
            if inner.type == port_type:
                tr.note(block, GAP, f"{what}: odelab's diagrams run every block at every instant; write the "
                        "condition into the blocks (a switch, a product by the enable signal)", construct="SubSystem")
                _gap_block(tr, block, system, prefix)
                return _HANDLED
    tr.flattened.add(id(block))
    tr.parent[id(block.system)] = (block, system)
    bindings = {}
    for name, text in block.mask:
        missing: set[str] = set()
        try:
            value = evaluate(text, lambda n: scope.lookup(n, block.path), missing) if text.strip() else None
        except MExprError as exc:
            tr.note(block, GAP, f"its mask parameter {name} = {text!r} is not a value this importer reads ({exc})",
                    construct="mask")
            continue
        for m in missing:
            tr.missing.setdefault(m, []).append(block.path)
        if value is not None:
            bindings[name] = (value, f"mask parameter of {block.path}: {name} = {text}")
    inner_scope = Scope(scope, bindings, where=identifier(block.name)) if block.mask else scope
    what = "masked subsystem" if block.masked else "subsystem"
    tr.note(block, TRANSLATED, f"{what} flattened: its blocks are named {identifier(prefix + block.name)}_<block>"
            + (f"; its mask parameters {', '.join(n for n, _ in block.mask)} are [parameters]" if block.mask else ""),
            construct="SubSystem")
    return block.system, inner_scope, f"{prefix}{block.name}_"


_VIRTUAL = {"Inport": "routed to what feeds the subsystem's input", "Outport": "routed to its subsystem's output",
            "Goto": "routed to its From blocks", "From": "routed from its Goto block",
            "BusSelector": "routed from the bus creator's signals", "Terminator": "ends a signal: nothing to compute"}


def _map_block(tr: Translation, block: Block, system: System, scope: Scope, prefix: str) -> None:
    kind = block.type
    if kind in _VIRTUAL or kind in mapping.SINKS or kind == "XYScope" or block.source == "simulink/Sinks/XY Graph":
        if kind in mapping.SINKS or kind == "XYScope" or block.source == "simulink/Sinks/XY Graph":
            tr.sinks.append((block, system))
        if kind in _VIRTUAL and not (kind == "Outport" and id(system) not in tr.parent):
            tr.note(block, TRANSLATED, _VIRTUAL[kind])
        return
    if kind in ("Assertion", "CheckStaticLowerBound", "CheckStaticUpperBound") or (
            kind == "Reference" and any(o in block.source for o in mapping.OBSERVERS)):
        tr.note(block, IGNORED, "checks or shows a signal without changing the simulation")
        return
    if kind == "BusCreator":
        tr.buses[id(block)] = block
        c = BlockContext(tr, block, system, scope, prefix)
        c.add({"type": "mux"}, inputs=list(range(1, input_count(tr, block, "Inputs", "2") + 1)))
        tr.note(block, TRANSLATED, f"a bus: its selectors take its signals by name; as a signal it is a mux `{c.name}`")
        return
    func = mapping.BY_TYPE.get(kind) if kind != "Reference" else mapping.BY_SOURCE.get(block.source)
    if func is None:
        _gap_block(tr, block, system, prefix)
        what = f"the library block {block.source!r}" if kind == "Reference" else f"a {kind} block"
        tr.note(block, GAP, f"{what} has no odelab block: write its equation as a fcn block, or see "
                "docs/crosswalk/simulink.md")
        return
    c = BlockContext(tr, block, system, scope, prefix)
    func(c)
    if c.gapped:
        for name in c.added:
            tr.flats[name].gap = c.gapped
        if not c.added:
            tr.flats[c.name] = Flat(c.name, {}, [], block, system, gap=c.gapped)
            tr.outs.setdefault((id(block), "1"), c.name)
        tr.note(block, GAP, c.gapped)
        return
    shown = ", ".join(f"`{n}` ({tr.flats[n].spec.get('type')})" for n in c.added) or "routed"
    renamed = "" if c.name == block.name else f" (its name made an identifier: {c.name})"
    tr.note(block, TRANSLATED, f"{shown}{renamed}" + "".join(f"; {e}" for e in c.extra))
