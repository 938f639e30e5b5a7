"""One shape for every Simulink file: a tree of :class:`Node`\\ s (a section, its parameters, its sections).

A classic ``.mdl`` is text sections (``Block { BlockType Gain  Gain "k" }``); an ``.slx`` and the
text-package ``.mdl`` are XML (``<Block BlockType="Gain"><P Name="Gain">k</P></Block>``). Both
become the same nodes here (:func:`parse_mdl` for the text, :func:`from_xml` for an XML element),
so the model is read from one shape (:mod:`odelab.formats.simulink.model`). Both readers are
iterative with explicit budgets: the nesting depth and the number of nodes are checked as each
section opens, never by Python's recursion limit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["MAX_DEPTH", "MAX_NODES", "Node", "TreeError", "from_xml", "parse_mdl"]

MAX_DEPTH = 400
"""Sections nest at most 400 deep (a model's subsystems are bounded more tightly in model.py)."""
MAX_NODES = 1_000_000
"""At most a million sections and elements in one model (a large course model has about 5,000)."""


class TreeError(ValueError):
    """A file that is not a Simulink model this reader knows; ``line`` where it went wrong (text files)."""

    def __init__(self, message: str, line: int | None = None, depth: bool = False):
        super().__init__(message)
        self.line = line
        self.depth = depth


@dataclass(eq=False)
class Node:
    """A section: its tag (``Block``, ``System``, ``Line``, ``Simulink.SolverCC``...), its parameters in order
    (name -> text) and its sections."""

    tag: str
    params: dict[str, str] = field(default_factory=dict)
    children: list["Node"] = field(default_factory=list)
    line: int | None = None  # where it starts, in a text file

    def get(self, name: str, default: str | None = None) -> str | None:
        return self.params.get(name, default)

    def find(self, tag: str) -> "Node | None":
        for child in self.children:
            if child.tag == tag:
                return child
        return None

    def all(self, tag: str) -> list["Node"]:
        return [c for c in self.children if c.tag == tag]

    def walk(self, skip: tuple[str, ...] = ()):
        """Every node below (and including) this one, depth first, without entering ``skip`` tags."""
        stack = [self]
        while stack:
            node = stack.pop()
            yield node
            stack.extend(reversed([c for c in node.children if c.tag not in skip]))


# --- the classic .mdl text ---------------------------------------------------------------------------

_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", '"': '"', "\\": "\\", "'": "'", "0": "\0"}


def _unquote(text: str, line: int) -> str:
    """A run of double-quoted strings (``"a" "b"`` continues a value) with C-like escapes."""
    out: list[str] = []
    i, n = 0, len(text)
    while i < n:
        if text[i] in " \t":
            i += 1
            continue
        if text[i] != '"':
            raise TreeError(f"text after a quoted value: {text[i:i + 20]!r}", line)
        i += 1
        while True:
            if i >= n:
                raise TreeError("a quoted value is not closed on its line", line)
            ch = text[i]
            if ch == "\\" and i + 1 < n:
                out.append(_ESCAPES.get(text[i + 1], text[i + 1]))
                i += 2
            elif ch == '"':
                i += 1
                break
            else:
                out.append(ch)
                i += 1
    return "".join(out)


def parse_mdl(text: str, max_systems: int = MAX_DEPTH) -> Node:
    """The sections of a classic ``.mdl`` (``Model {...}``, ``Library {...}``, ``Stateflow {...}``) under one root.

    A value is a double-quoted string (continued by further quoted strings on the next lines) or the
    rest of the line (``Ports [1, 1]``, ``BlockType Gain``). Raises :class:`TreeError` with the line.
    """
    root = Node("")
    stack = [root]
    count = 0
    systems = 0  # Systems open: a subsystem's nesting
    last: tuple[Node, str] | None = None  # the parameter a continuation line extends
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith('"') and last is not None:  # a quoted value continued
            node, key = last
            node.params[key] += _unquote(line, number)
            continue
        last = None
        if line == "}":
            if len(stack) == 1:
                raise TreeError("a `}` closes no section", number)
            systems -= stack.pop().tag == "System"
            continue
        if line.endswith("{"):
            tag = line[:-1].strip()
            if not tag or len(tag.split()) != 1 or '"' in tag:
                raise TreeError(f"a section name {tag!r} is not a word", number)
            count += 1
            if count > MAX_NODES:
                raise TreeError(f"the model has more than {MAX_NODES:,} sections", number)
            if tag == "System":
                systems += 1
                if systems > max_systems:
                    raise TreeError(f"its subsystems nest more than {max_systems} deep", number, depth=True)
            if len(stack) > MAX_DEPTH:
                raise TreeError(f"sections nest more than {MAX_DEPTH} deep", number, depth=True)
            node = Node(tag, line=number)
            stack[-1].children.append(node)
            stack.append(node)
            continue
        fields = line.split(None, 1)
        key, rest = fields[0], (fields[1].strip() if len(fields) > 1 else "")
        if len(stack) == 1:
            if key.startswith("__MWOPC_"):  # the package of a text-package .mdl begins: its parts are XML
                break
            raise TreeError(f"{line[:40]!r} is outside any section (a classic .mdl starts with `Model {{`)", number)
        value = _unquote(rest, number) if rest.startswith('"') else rest
        stack[-1].params[key] = value
        last = (stack[-1], key) if rest.startswith('"') else None
    else:
        if len(stack) > 1:
            raise TreeError(f"the section `{stack[-1].tag}` opened on line {stack[-1].line} is not closed")
    return root


# --- XML --------------------------------------------------------------------------------------------

def from_xml(element) -> Node:
    """An XML element (ElementTree) as a node: its attributes and ``<P Name="x">text</P>`` children (and
    leaf children such as a mask parameter's ``<Value>``) are parameters, other children are sections;
    an ``<Object ClassName="Simulink.SolverCC">`` is the section ``Simulink.SolverCC``, as in a ``.mdl``."""
    def convert(el) -> Node:
        tag = el.get("ClassName") or el.tag if el.tag == "Object" else el.tag
        node = Node(tag, params={k: v for k, v in el.attrib.items()})
        if tag != el.tag:
            node.params.setdefault("$ObjectTag", el.tag)
        return node

    top = convert(element)
    stack = [(element, top)]
    count = 0
    while stack:
        el, node = stack.pop()
        for child in el:
            count += 1
            if count > MAX_NODES:
                raise TreeError(f"the model has more than {MAX_NODES:,} XML elements")
            if not isinstance(child.tag, str):  # a comment or a processing instruction
                continue
            if child.tag == "P" and child.get("Name") is not None and len(child) == 0:
                node.params[child.get("Name")] = child.text or ""
            elif len(child) == 0 and not child.attrib and node.tag not in ("System", "Model", "Library"):
                node.params[child.tag] = child.text or ""
            else:
                sub = convert(child)
                if child.text and child.text.strip() and len(child) == 0:
                    sub.params.setdefault("$text", child.text)
                node.children.append(sub)
                stack.append((child, sub))
    return top
