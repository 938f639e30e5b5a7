"""Wiring a diagram: resolving references, widths, the evaluation order and algebraic loops.

A reference names a block (``"position"``) or one output port of a block with several
(``"plant.y"``, ``"split.2"``). A block's output depends on its inputs at the same instant
only if it has direct feedthrough (a gain, a sum; not an integrator, nor a state-space block
with D = 0), so the evaluation order is a topological order of the feedthrough edges,
computed once. A cycle of feedthrough edges is an algebraic loop: the diagram cannot be
evaluated in any order, and it is refused with the loop printed in signal-flow order.
"""

from __future__ import annotations

import difflib
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

from odelab.exceptions import InputError
from odelab.systems.diagram.base import Block, BlockError

__all__ = ["DiagramError", "Wiring", "find_loop", "located", "resolve", "wire"]


class DiagramError(InputError):
    """A diagram is wired wrongly; ``key`` is the path ``blocks.<name>.<key>``."""


@dataclass(frozen=True, eq=False)
class Wiring:
    """A checked diagram: blocks, what feeds each input, port widths and the evaluation order."""

    blocks: dict[str, Block]
    sources: dict[str, tuple[tuple[str, int], ...]]  # block -> (block, port) feeding each input
    outputs: dict[str, tuple[str, int]]  # output name -> (block, port)
    widths: dict[tuple[str, int], int]
    order: tuple[str, ...]  # every block, in an order where feedthrough inputs come first
    torn: tuple[str, ...] = ()  # blocks whose outputs are the unknowns of algebraic loops (solved)
    loops: tuple[str, ...] = ()  # each loop as text, "a -> b -> a"


def located(exc: BlockError, name: str) -> DiagramError:
    """A block's error with its key written as the full path ``blocks.<name>.<key>``."""
    full = f"blocks.{name}.{exc.key}" if exc.key else f"blocks.{name}"
    message = exc.message
    if exc.key and f"`{exc.key}`" in message:
        message = message.replace(f"`{exc.key}`", f"`{full}`", 1)
    else:
        message = f"`{full}`: {message}"
    return DiagramError(message, key=full)


def _is_name(name) -> bool:
    return isinstance(name, str) and name.isascii() and name.isidentifier()


def resolve(ref: str, blocks: Mapping[str, Block], key: str) -> tuple[str, int]:
    """(block, port index) for a reference ``"name"`` or ``"name.port"``."""
    if not isinstance(ref, str):
        raise DiagramError(f"`{key}` must name a block; got {ref!r}.", key=key)
    name, dot, port = ref.partition(".")
    if name not in blocks:
        close = difflib.get_close_matches(name, list(blocks), n=1)
        hint = f" Did you mean `{close[0]}{dot}{port}`?" if close else ""
        raise DiagramError(f"`{key}`: {ref!r} is not a block of the diagram.{hint}", key=key)
    ports = blocks[name].ports()
    if not dot:
        if len(ports) == 1:
            return name, 0
        raise DiagramError(f"`{key}`: block {name!r} has {len(ports)} outputs; name one: "
                           f"{', '.join(name + '.' + p for p in ports)}.", key=key)
    if port not in ports:
        close = difflib.get_close_matches(port, list(ports), n=1)
        hint = f" Did you mean `{name}.{close[0]}`?" if close else ""
        listed = ", ".join(name + "." + p for p in ports if p) or name
        raise DiagramError(f"`{key}`: block {name!r} has no output {port!r} (its outputs: {listed}).{hint}",
                           key=key)
    return name, ports.index(port)


def _input_key(name: str, block: Block, i: int) -> str:
    return f"blocks.{name}.input" if len(block.inputs) == 1 else f"blocks.{name}.inputs[{i}]"


def find_loop(edges: dict[str, list[str]], nodes: list[str], declared: list[str]) -> list[str]:
    """One cycle among ``nodes`` (each has a successor among them), in signal-flow order,
    starting from the block declared first."""
    inside = set(nodes)
    position = {n: i for i, n in enumerate(declared)}
    start = min(nodes, key=position.__getitem__)
    path, seen = [start], {start: 0}
    node = start
    while True:
        node = min((n for n in edges[node] if n in inside), key=position.__getitem__)
        if node in seen:
            cycle = path[seen[node]:]
            first = min(cycle, key=position.__getitem__)
            i = cycle.index(first)
            return cycle[i:] + cycle[:i]
        seen[node] = len(path)
        path.append(node)


LOOP_POLICIES = ("warning", "none", "error", "solve")


def _topological(declared, edges):
    indegree = {n: 0 for n in declared}
    for src in declared:
        for dst in edges[src]:
            indegree[dst] += 1
    ready = deque(n for n in declared if indegree[n] == 0)
    order: list[str] = []
    while ready:
        node = ready.popleft()
        order.append(node)
        for nxt in edges[node]:
            indegree[nxt] -= 1
            if indegree[nxt] == 0:
                ready.append(nxt)
    return order


def _on_cycles(declared, edges, order):
    """The blocks on cycles (in declaration order): drop those whose feedthrough successors are
    all ordered, by a worklist over the reversed edges (linear in the diagram's size)."""
    done = set(order)
    left = {n for n in declared if n not in done}
    succ_left = {n: sum(1 for m in edges[n] if m in left) for n in left}
    preds: dict[str, list[str]] = {n: [] for n in left}
    for n in left:
        for m in edges[n]:
            if m in left:
                preds[m].append(n)
    drop = deque(n for n in left if succ_left[n] == 0)
    while drop:
        n = drop.popleft()
        left.discard(n)
        for p in preds[n]:
            if p in left:
                succ_left[p] -= 1
                if succ_left[p] == 0:
                    drop.append(p)
    return [n for n in declared if n in left]


def wire(blocks: Mapping[str, Block], outputs: Mapping[str, str], algebraic_loops: str = "error") -> Wiring:
    """Check a diagram's wiring and compute its widths and evaluation order.

    ``algebraic_loops``: ``"error"`` refuses a cycle of direct-feedthrough blocks; ``"warning"``
    (Simulink's default), ``"none"`` or ``"solve"`` tear each loop at one block (the first of
    it declared), whose output becomes an unknown the compiled diagram solves for by Newton's
    method at every evaluation (:class:`~odelab.systems.diagram.compile.CompiledDiagram`).

    Raises
    ------
    DiagramError
        Unknown references (with did-you-mean), unconnected blocks, width mismatches, and
        algebraic loops ("algebraic loop: net -> accel -> net; ...").
    """
    blocks = dict(blocks)
    if not blocks:
        raise DiagramError("the diagram has no blocks: add a [blocks] table, e.g. "
                           "force = { type = \"step\" }.", key="blocks")
    for name in blocks:
        if not _is_name(name):
            raise DiagramError(f"block name {name!r} is not usable: block names are ASCII identifiers (letters, "
                               "digits, _), and a dot addresses a port (plant.y).", key=f"blocks.{name}")
    sources = {name: tuple(resolve(ref, blocks, _input_key(name, b, i)) for i, ref in enumerate(b.inputs))
               for name, b in blocks.items()}
    out_ports = {}
    for out, ref in outputs.items():
        out_ports[out] = resolve(ref, blocks, f"system.outputs.{out}")

    used = {src for feeds in sources.values() for src, _ in feeds} | {src for src, _ in out_ports.values()}
    for name in blocks:
        if name not in used and blocks[name].ports():  # a block without outputs (stop) is a sink
            raise DiagramError(f"block {name!r} is not connected: no block takes its output and it is not one of "
                               "`system.outputs`; connect it (input = \"" + name + "\") or remove it.",
                               key=f"blocks.{name}")

    # Feedthrough edges: src -> dst when dst's output depends on src's at the same instant.
    declared = list(blocks)
    edges: dict[str, list[str]] = {n: [] for n in blocks}
    for name, feeds in sources.items():
        if blocks[name].feedthrough:
            for src in dict.fromkeys(s for s, _ in feeds):
                edges[src].append(name)
    order = _topological(declared, edges)
    torn: list[str] = []
    loops: list[str] = []
    while len(order) < len(blocks):
        left = _on_cycles(declared, edges, order)
        loop = find_loop(edges, left, declared)
        if len(loop) <= 12:
            text = " -> ".join([*loop, loop[0]])
        else:  # a few blocks and the count: a loop through 10,000 blocks is not a message
            text = " -> ".join([*loop[:6], "...", *loop[-2:], loop[0]]) + f" ({len(loop):,} blocks in the loop)"
        if algebraic_loops == "error":
            raise DiagramError(f"algebraic loop: {text}; break it with an integrator (or another block with state "
                               "and no direct feedthrough: a strictly proper transfer-fcn, a state-space block with "
                               "D = 0), or let odelab solve it as Simulink does: remove [system] algebraic_loops = "
                               "\"error\".", key=f"blocks.{loop[0]}")
        cut = loop[0]
        torn.append(cut)
        loops.append(text)
        for src in declared:  # the torn block's output is an unknown: its inputs no longer order it
            edges[src] = [d for d in edges[src] if d != cut]
        order = _topological(declared, edges)

    widths: dict[tuple[str, int], int] = {}
    for name, b in blocks.items():
        fixed = None if b.feedthrough else b.fixed_widths()
        if b.SOURCE:
            fixed = [1]
        if fixed is not None:
            widths.update({(name, i): w for i, w in enumerate(fixed)})

    def setup(name):
        b = blocks[name]
        try:
            got = b.setup([widths[s] for s in sources[name]])
        except BlockError as exc:
            raise located(exc, name) from None
        except InputError as exc:  # the expression of a fcn block
            raise _rekey(exc, name) from None
        return got

    for name in torn:  # the unknowns of a loop are scalars (checked below)
        widths.update({(name, i): 1 for i in range(len(blocks[name].ports()))})
    for name in order:
        if blocks[name].feedthrough and name not in torn:
            widths.update({(name, i): w for i, w in enumerate(setup(name))})
    for name in torn:
        got = setup(name)
        if any(w != 1 for w in got):
            raise DiagramError(f"the algebraic loop through `{name}` carries a vector signal; odelab solves loops of "
                               "scalar signals: split the vector with a demux, or break the loop with a block with "
                               "state.", key=f"blocks.{name}")
    for name in order:
        if not blocks[name].feedthrough and not blocks[name].SOURCE:
            setup(name)
    for out, port in out_ports.items():
        if widths[port] != 1:
            raise DiagramError(f"`system.outputs.{out}` is a signal of width {widths[port]}; an output is one "
                               "number: split the vector with a demux block and name one element.",
                               key=f"system.outputs.{out}")
    return Wiring(blocks=blocks, sources=sources, outputs=out_ports, widths=widths, order=tuple(order),
                  torn=tuple(torn), loops=tuple(loops))


def _rekey(exc: InputError, name: str) -> InputError:
    if not (exc.key or "").startswith("blocks."):
        exc.key = f"blocks.{name}.{exc.key or 'expression'}"
        if getattr(exc, "message", None):
            exc.message = exc.message.replace("`expression`", f"`blocks.{name}.expression`")
    return exc
