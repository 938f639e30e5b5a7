"""A Simulink model as plain data: its systems, blocks, lines, solver settings and callbacks.

:func:`load_model` takes a file's bytes (an ``.slx`` zip in either layout, a classic ``.mdl`` or
a text-package ``.mdl``) and returns a :class:`Model` whatever the format: blocks with their
parameters as text (library links' ``InstanceData`` merged), their masks' parameters, their
subsystems (``<System Ref="system_5"/>`` parts resolved), and lines resolved to the blocks they
join. The nesting of subsystems is bounded (:data:`MAX_SUBSYSTEM_DEPTH`) while it is read, with
an explicit stack.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from odelab.formats.simulink.container import ContainerError, parse_xml, read_package, split_text_package
from odelab.formats.simulink.tree import Node, TreeError, parse_mdl

__all__ = ["MAX_BLOCKS", "MAX_SUBSYSTEM_DEPTH", "Block", "Line", "Model", "ModelError", "System", "load_model"]

MAX_SUBSYSTEM_DEPTH = 100
"""Subsystems nest at most 100 deep (course models nest 1 to 5)."""
MAX_BLOCKS = 50_000
"""A model has at most 50,000 blocks (a large course model has a few hundred)."""


class ModelError(ValueError):
    """The file is not a model this reader can read (one sentence; the caller names the file)."""


@dataclass(eq=False)
class Block:
    type: str  # BlockType ("Gain", "SubSystem", "Reference"...)
    name: str
    sid: str
    params: dict[str, str]
    path: str = ""  # "msd/Plant/Gain": the block's path in the model
    mask: list[tuple[str, str]] = field(default_factory=list)  # a mask's parameters (name, value text) in order
    masked: bool = False
    system: "System | None" = None
    port_names: dict[int, str] = field(default_factory=dict)  # output port -> its signal's name
    line: int | None = None  # where it is in a .mdl

    @property
    def source(self) -> str:
        """A library link's source block (``simulink/Continuous/PID Controller``), newlines as spaces."""
        return " ".join(self.params.get("SourceBlock", "").split())


@dataclass(eq=False)
class Line:
    src: tuple[Block, str]  # (block, output port "1", "2"...)
    dsts: list[tuple[Block, str]]  # (block, input port "1"... or "trigger", "enable", "lconn1")
    name: str = ""


@dataclass(eq=False)
class System:
    blocks: list[Block] = field(default_factory=list)
    lines: list[Line] = field(default_factory=list)
    depth: int = 0


@dataclass(eq=False)
class Model:
    name: str
    format: str  # "slx", "slx (blockdiagram.xml)", "mdl", "mdl (text package)"
    params: dict[str, str]  # the model's own parameters (PreLoadFcn, InitFcn, ...)
    solver: dict[str, str]  # Simulink.SolverCC's parameters (StartTime, StopTime, Solver, RelTol...)
    defaults: dict[str, dict[str, str]]  # BlockParameterDefaults: BlockType -> parameter -> text
    root: System
    nblocks: int = 0
    scripts: dict[str, str] = field(default_factory=dict)  # MATLAB Function blocks' code, by chart name


def _is_zip(raw: bytes) -> bool:
    return raw[:4] == b"PK\x03\x04" or raw[:4] == b"PK\x05\x06"


def _decode(raw: bytes) -> str:
    if b"\x00" in raw[:4096]:
        raise ModelError("it is a binary file, neither an .slx (a zip) nor an .mdl (text)")
    for encoding in ("utf-8-sig", "latin-1"):  # older .mdl files are in the platform's 8-bit encoding
        try:
            return raw.decode(encoding)
        except UnicodeDecodeError:
            continue
    raise ModelError("its text cannot be decoded")  # pragma: no cover - latin-1 decodes everything


def load_model(raw: bytes, name: str = "model") -> Model:
    """The model in a file's bytes (raises :class:`ModelError` or ContainerError with one sentence); ``name`` is the
    model's when the file does not say it (a newer .slx names its model by its file)."""
    if _is_zip(raw):
        parts = read_package(raw)
        return _from_parts(parts, "slx", name)
    text = _decode(raw)
    stub, parts = split_text_package(text)
    if parts:
        return _from_parts(parts, "mdl (text package)", name)
    try:
        root = parse_mdl(stub, MAX_SUBSYSTEM_DEPTH)
    except TreeError as exc:
        where = f"line {exc.line}: " if exc.line else ""
        raise ContainerError(f"{where}{exc}", depth=exc.depth) from None
    top = root.find("Model") or root.find("Library")
    if top is None:
        raise ModelError("it has no `Model {` section: it is not a Simulink model (a .mdl starts with `Model {`)")
    if top.tag == "Library":
        raise ModelError("it is a Simulink library, not a model: import the model that uses its blocks")
    model = _build(top, "mdl", lambda ref: None, name)
    flow = root.find("Stateflow")
    if flow is not None:
        from odelab.formats.simulink.mfunction import charts

        model.scripts = charts([flow])
    return model


def _from_parts(parts: dict[str, bytes], fmt: str, name: str) -> Model:
    main = parts.get("simulink/blockdiagram.xml")
    if main is None:
        raise ModelError("it has no simulink/blockdiagram.xml: it is a zip, but not a Simulink model")
    info = parse_xml(main, "simulink/blockdiagram.xml", MAX_SUBSYSTEM_DEPTH)
    top = info if info.tag in ("Model", "Library") else (info.find("Model") or info.find("Library"))
    if top is None:
        raise ModelError("its blockdiagram.xml has no <Model>: it is not a Simulink model")
    if top.tag == "Library":
        raise ModelError("it is a Simulink library, not a model: import the model that uses its blocks")
    root_ref = top.find("System")
    layout = "systems/system_*.xml" if root_ref is not None and root_ref.get("Ref") else "blockdiagram.xml"
    for part, data in parts.items():  # the configuration sets (the newer layout keeps them apart)
        if re.match(r"simulink/configset\d*\.xml$", part):
            top.children.append(parse_xml(data, part, MAX_SUBSYSTEM_DEPTH))
    defaults = parts.get("simulink/bddefaults.xml")
    if defaults is not None:
        top.children.append(parse_xml(defaults, "simulink/bddefaults.xml", MAX_SUBSYSTEM_DEPTH))

    def system_part(ref: str) -> Node | None:
        data = parts.get(f"simulink/systems/{ref.lower()}.xml")
        return None if data is None else parse_xml(data, f"simulink/systems/{ref}.xml", MAX_SUBSYSTEM_DEPTH)

    model = _build(top, f"{fmt} ({layout})", system_part, name)
    flows = [parse_xml(data, part, MAX_SUBSYSTEM_DEPTH) for part, data in parts.items()
             if part.startswith("simulink/stateflow/") and "/_rels/" not in part]
    if flows:
        from odelab.formats.simulink.mfunction import charts

        model.scripts = charts(flows)
    return model


def _solver(top: Node) -> dict[str, str]:
    """The solver settings: the model's own (old .mdl files) overlaid by the first Simulink.SolverCC's."""
    keys = ("Solver", "SolverName", "SolverType", "StartTime", "StopTime", "RelTol", "AbsTol", "MaxStep", "MinStep",
            "InitialStep", "FixedStep", "Refine", "MaxOrder", "ZeroCrossControl", "AlgebraicLoopMsg")
    out = {k: top.params[k] for k in keys if k in top.params}
    for node in top.walk(skip=("System", "BlockParameterDefaults", "Stateflow")):
        if node.tag in ("Simulink.SolverCC", "Simulink.DebuggingCC"):
            out.update({k: v for k, v in node.params.items() if k in keys})
            if node.tag == "Simulink.SolverCC":
                break
    if "Solver" not in out and "SolverName" in out:
        out["Solver"] = out["SolverName"]
    return out


def _defaults(top: Node) -> dict[str, dict[str, str]]:
    out: dict[str, dict[str, str]] = {}
    for node in top.walk(skip=("System",)):
        if node.tag == "BlockParameterDefaults":
            for block in node.all("Block"):
                kind = block.get("BlockType")
                if kind:
                    out.setdefault(kind, {}).update({k: v for k, v in block.params.items() if k != "BlockType"})
    return out


def _mask(node: Node) -> tuple[bool, list[tuple[str, str]]]:
    """A block's mask parameters, whichever way the release wrote them."""
    params = node.params
    masked = params.get("Mask", "off") == "on" or any(c.tag in ("Mask", "MaskObject") for c in node.children)
    if "MaskVariables" in params:  # "m=@1;k=@2;" with "2|3"
        names = [v.split("=")[0].strip() for v in params["MaskVariables"].split(";") if "=" in v]
        values = params.get("MaskValueString", params.get("MaskValues", "")).split("|")
        return True, [(n, values[i] if i < len(values) else "") for i, n in enumerate(names)]
    out = []
    for child in node.children:
        if child.tag not in ("Mask", "MaskObject"):
            continue
        for sub in child.walk():
            if sub is child:
                continue
            if sub.tag in ("MaskParameter", "Object", "Simulink.MaskParameter") and "Name" in sub.params and (
                    "Value" in sub.params or sub.tag != "Object"):
                out.append((sub.params["Name"], sub.params.get("Value", "")))
    return masked, out


_ENDPOINT = re.compile(r"^(?P<sid>[^#]+)#(?P<kind>[A-Za-z]+)(?::(?P<n>\d+))?$")


def _endpoint(text: str, port: str | None, by_sid, by_name) -> tuple[Block, str] | None:
    """A line's end: ``"5#out:1"`` / ``"5#in:2"`` / ``"5#trigger"`` (SIDs) or a block's name and its port."""
    if port is None:
        m = _ENDPOINT.match(text.strip())
        if not m:
            return None
        block = by_sid.get(m.group("sid"))
        kind, n = m.group("kind").lower(), m.group("n")
        port = n if kind in ("out", "in") else kind + (n or "")
        return None if block is None else (block, port)
    block = by_name.get(text)
    return None if block is None else (block, port.strip().lower())


def _lines(node: Node, by_sid, by_name) -> list[Line]:
    out = []
    for line in node.all("Line"):
        p = line.params
        if "Src" in p:
            src = _endpoint(p["Src"], None, by_sid, by_name)
        else:
            src = _endpoint(p.get("SrcBlock", ""), p.get("SrcPort", "1"), by_sid, by_name)
        dsts = []
        stack = [line]
        while stack:
            item = stack.pop()
            q = item.params
            if "Dst" in q:
                end = _endpoint(q["Dst"], None, by_sid, by_name)
            elif "DstBlock" in q:
                end = _endpoint(q["DstBlock"], q.get("DstPort", "1"), by_sid, by_name)
            else:
                end = None
            if end is not None:
                dsts.append(end)
            stack.extend(reversed(item.all("Branch")))
        if src is not None and dsts:
            out.append(Line(src, dsts, p.get("Name", "")))
    return out


def _build(top: Node, fmt: str, system_part, fallback: str) -> Model:
    name = top.get("Name") or fallback
    root_node = top.find("System")
    if root_node is None:
        raise ModelError("its model has no System (no blocks at all)")
    root = System()
    count = 0
    seen_refs: set[str] = set()
    stack: list[tuple[Node, System, str, int]] = [(root_node, root, name, 0)]
    while stack:
        node, system, path, depth = stack.pop()
        ref = node.get("Ref")
        if ref is not None:
            if ref in seen_refs:
                raise ModelError(f"its system {ref!r} is used by two subsystems (or by itself): the file is damaged")
            seen_refs.add(ref)
            part = system_part(ref)
            if part is None:
                raise ModelError(f"the system part {ref!r} of subsystem {path!r} is missing from the file")
            node = part
        system.depth = depth
        by_sid, by_name = {}, {}
        for bnode in node.all("Block"):
            count += 1
            if count > MAX_BLOCKS:
                raise ModelError(f"it has more than {MAX_BLOCKS:,} blocks")
            params = dict(bnode.params)
            for inst in bnode.all("InstanceData"):
                params.update(inst.params)
            bname = " ".join(params.get("Name", "").split()) or f"block{count}"
            block = Block(type=params.get("BlockType", ""), name=bname, sid=params.get("SID", ""), params=params,
                          path=f"{path}/{bname}", line=bnode.line)
            block.masked, block.mask = _mask(bnode)
            for port in bnode.all("Port"):
                pnum, pname = port.get("PortNumber", "1"), port.get("Name")
                if pname and pnum.isdigit():
                    block.port_names[int(pnum)] = pname
            system.blocks.append(block)
            by_name.setdefault(params.get("Name", ""), block)
            if block.sid:
                by_sid[block.sid] = block
            inner = bnode.find("System")
            if inner is not None:
                if depth + 1 > MAX_SUBSYSTEM_DEPTH:
                    raise ContainerError(f"its subsystems nest more than {MAX_SUBSYSTEM_DEPTH} deep", depth=True)
                block.system = System()
                stack.append((inner, block.system, block.path, depth + 1))
        system.lines = _lines(node, by_sid, by_name)
    return Model(name=name, format=fmt, params=dict(top.params), solver=_solver(top), defaults=_defaults(top),
                 root=root, nblocks=count)
