"""After every block is mapped: what feeds each odelab block, the outputs, and what reaches no sink.

Each odelab block's Simulink inputs are followed (through subsystems, Goto/From, buses) to the
block that computes them; an input nobody drives reads 0, as in Simulink. A sample time of -1
(inherited) is taken from the block upstream. Each sink's input becomes an output of the
experiment, named by the signal's name, a To Workspace block's variable or an Outport's name (a
mux into a Scope gives one output per signal). Blocks whose output reaches no sink are left out.
"""

from __future__ import annotations

from odelab.formats.base import GAP, IGNORED, TRANSLATED, Note
from odelab.formats.simulink.scope import identifier
from odelab.formats.simulink.translate import INHERIT, Flat, Translation, _follow, _gap_block

__all__ = ["finish"]


def _constant_zero(tr: Translation, wanted: str, owner, system, why: str) -> str:
    name = tr.name_for(wanted)
    tr.flats[name] = Flat(name, {"type": "constant", "value": 0.0}, [], owner, system)
    tr.notes.append(Note(f"block {owner.path}", owner.type, TRANSLATED, why))
    return name


def _ref(tr: Translation, block, port: str, user: str) -> str:
    """The odelab reference that feeds input ``port`` of Simulink ``block``."""
    src = tr.sources.get((id(block), port))
    found = _follow(tr, *src) if src is not None else None
    if found is None:
        key = (id(block), f"unconnected{port}")
        if key not in tr.outs:
            tr.outs[key] = _constant_zero(tr, f"{user}_in{port}", block, tr.block_system[id(block)],
                                          f"its input {port} is not connected: it reads 0, as in Simulink "
                                          f"(a constant block `{user}_in{port}`)")
        return tr.outs[key]
    src_block, src_port = found
    key = (id(src_block), src_port)
    if key in tr.outs:
        return tr.outs[key]
    if src_block.type == "Inport":  # an Inport of the model: no external input is loaded, it reads 0
        tr.outs[key] = _constant_zero(tr, src_block.name, src_block, tr.block_system[id(src_block)],
                                      "an Inport of the model: without external input data it reads 0; replace it "
                                      "by a source block for another input")
        return tr.outs[key]
    return _gap_block(tr, src_block, tr.block_system[id(src_block)], "")


def _inherit(tr: Translation, flat: Flat) -> None:
    """A sample time of -1: the first upstream block's that has one, else the fixed step."""
    ref = flat.refs[0] if flat.refs else None
    for _ in range(1000):
        if ref is None:
            break
        up = tr.flats.get(ref.split(".")[0])
        if up is None:
            break
        ts = up.spec.get("sample_time")
        if ts is not None and ts != INHERIT:
            flat.spec["sample_time"] = ts
            return
        ref = up.refs[0] if up.refs else None
    step = tr.fixed_step
    if step is not None:
        flat.spec["sample_time"] = step
        return
    flat.gap = ("its sample time is inherited (-1) and nothing upstream has one; give the block its sample time "
                "(in seconds)")
    tr.notes.append(Note(f"block {flat.owner.path}", flat.owner.type, GAP, flat.gap))


def _signal_name(tr: Translation, sink, port: str, ref: str) -> str:
    named = tr.line_names.get((id(sink), port))
    if named:
        return named
    src = tr.sources.get((id(sink), port))
    if src is not None and src[1].isdigit() and src[0].port_names.get(int(src[1])):
        return src[0].port_names[int(src[1])]
    return ref.replace(".", "_")


def _sink_ports(tr: Translation, sink) -> list[str]:
    ports = sorted({p for (b, p) in tr.sources if b == id(sink) and p.isdigit()}, key=int)
    return ports


def width(tr: Translation, ref: str, depth: int = 0) -> int:
    """A signal's width as far as the blocks' parameters tell (1 when they do not): an integrator's or a unit
    delay's list of initial values, a mux's inputs, a gain's or a sum's inputs (bounded depth, no recursion
    limit reached)."""
    flat = tr.flats.get(ref)
    if flat is None or flat.gap or depth > 200 or "." in ref:
        return 1
    spec, kind = flat.spec, flat.spec.get("type")
    if kind in ("integrator", "unit-delay", "transport-delay") and isinstance(spec.get("initial"), list):
        return len(spec["initial"])
    if kind == "mux":
        return sum(width(tr, r, depth + 1) for r in flat.refs)
    if kind in ("gain", "sum", "product", "saturation", "dead-zone", "abs", "sign", "zero-order-hold") and flat.refs:
        if kind == "gain" and isinstance(spec.get("gain"), list) and spec["gain"] and isinstance(spec["gain"][0], list):
            return len(spec["gain"])
        return max(width(tr, r, depth + 1) for r in flat.refs)
    return 1


def _outputs(tr: Translation) -> dict[str, str]:
    outputs: dict[str, str] = {}

    def add(name: str, ref: str):
        n_wide = width(tr, ref)
        if n_wide > 1:  # a vector into a sink: one output per element, through a demux
            parts = tr.name_for(f"{ref.replace('.', '_')}_elements")
            owner = tr.flats[ref].owner
            tr.flats[parts] = Flat(parts, {"type": "demux", "outputs": n_wide}, [], owner, tr.flats[ref].system,
                                   refs=[ref])
            return ", ".join(add1(f"{name}_{i + 1}", f"{parts}.{i + 1}") for i in range(n_wide))
        return add1(name, ref)

    def add1(name: str, ref: str):
        base = identifier(name)
        out, n = base, 2
        while out in outputs and outputs[out] != ref:
            out = f"{base}_{n}"
            n += 1
        outputs[out] = ref
        return out

    named = {"Outport": 0, "ToWorkspace": 0}  # the sinks that name their signal first, then scopes and displays
    for sink, system in sorted(tr.sinks, key=lambda s: named.get(s[0].type, 1)):
        kind = sink.type
        if kind == "Terminator":
            continue
        if kind == "Outport" and id(system) in tr.parent:
            continue
        made = []
        for port in _sink_ports(tr, sink):
            ref = _ref(tr, sink, port, identifier(sink.name))
            if kind == "Outport":
                made.append(add(sink.name, ref))
                continue
            if kind == "ToWorkspace":
                made.append(add(sink.params.get("VariableName", "simout"), ref))
                continue
            flat = tr.flats.get(ref)
            if flat is not None and flat.spec.get("type") == "mux" and not flat.gap:  # one output per signal
                for i, inner in enumerate(flat.refs or []):
                    made.append(add(_mux_name(tr, flat, i, inner), inner))
                continue
            shown = next((o for o, r in outputs.items() if r == ref), None)  # already an output: not twice
            made.append(shown or add(_signal_name(tr, sink, port, ref), ref))
        made = list(dict.fromkeys(made))
        what = {"Outport": "the model's output", "ToWorkspace": "its variable", "ToFile": "its signal (the file "
                "is not written)"}.get(kind, "its signals")
        outcome = TRANSLATED if made else IGNORED
        detail = (f"{what} as output{'s' if len(made) != 1 else ''} {', '.join(made)}" if made
                  else "nothing is connected to it")
        tr.notes.append(Note(f"block {sink.path}", sink.type if sink.type != "Reference" else sink.source, outcome,
                             detail))
    return outputs


def _mux_name(tr: Translation, flat: Flat, i: int, inner: str) -> str:
    owner = flat.owner
    named = tr.line_names.get((id(owner), str(i + 1)))
    if named:
        return named
    src = tr.sources.get((id(owner), str(i + 1)))
    if src is not None and src[1].isdigit() and src[0].port_names.get(int(src[1])):
        return src[0].port_names[int(src[1])]
    return inner.replace(".", "_")


def _prune(tr: Translation, outputs: dict[str, str]) -> None:
    """Leave out the blocks whose output reaches no output (Simulink computes them; nothing shows them)."""
    while True:
        used = {r.split(".")[0] for r in outputs.values()}
        for flat in tr.flats.values():
            used.update(r.split(".")[0] for r in flat.refs)
        dead = [n for n, f in tr.flats.items() if n not in used and not f.gap and f.spec.get("type") != "stop"]
        if not dead:
            return
        for name in dead:
            flat = tr.flats.pop(name)
            path = f"block {flat.owner.path}"
            if name in tr.consumed:  # read into an initial value
                continue
            if not any(f.owner is flat.owner for f in tr.flats.values()):
                tr.notes[:] = [n for n in tr.notes if not (n.where == path and n.outcome == TRANSLATED)]
                tr.notes.append(Note(path, flat.owner.type, IGNORED, "its output reaches no Scope, Outport, Display "
                                     "or To Workspace block: left out"))


def _initials(tr: Translation) -> None:
    """An integrator whose initial condition is an input: the constant (or a mux of constants) feeding it."""
    for name, (block, port) in tr.initials.items():
        flat = tr.flats.get(name)
        if flat is None or flat.gap:
            continue
        ref = _ref(tr, block, port, name)
        source = tr.flats.get(ref)
        parts = [source] if source is not None and source.spec.get("type") == "constant" else (
            [tr.flats.get(r) for r in source.refs] if source is not None and source.spec.get("type") == "mux" else [])
        if not parts or any(p is None or p.spec.get("type") != "constant" for p in parts):
            flat.gap = ("its initial condition is an input fed by a computed signal: give the block its Initial "
                        "condition (a number or a parameter)")
            tr.notes.append(Note(f"block {block.path}", block.type, GAP, flat.gap))
            continue
        values = [p.spec["value"] for p in parts]
        flat.spec["initial"] = values[0] if len(values) == 1 else values
        tr.consumed.update(p.name for p in parts)
        if source.spec.get("type") == "mux":
            tr.consumed.add(source.name)
        tr.notes.append(Note(f"block {block.path}", block.type, TRANSLATED, f"its initial condition (input {port}) "
                             f"is the constant {' and '.join(p.name for p in parts)}: `initial` of `{name}`"))


def finish(tr: Translation) -> None:
    """Wire every block, inherit sample times, name the outputs, prune."""
    for flat in list(tr.flats.values()):
        if flat.gap:
            continue
        flat.refs = [item[1] if isinstance(item, tuple) else _ref(tr, flat.owner, str(item), flat.name)
                     for item in flat.inputs]
    _initials(tr)
    for flat in list(tr.flats.values()):
        if flat.spec.get("sample_time") == INHERIT and not flat.gap:
            _inherit(tr, flat)
    tr.outputs = _outputs(tr)
    _prune(tr, tr.outputs)
