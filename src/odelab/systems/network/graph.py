"""The graph of a network: nodes per domain, the ground, and the checks made before deriving.

Every element joins one node pair (a coupling joins two, one per side). A node belongs to one
domain; ``ground`` is the reference of every domain. The checks here are the topological ones
(an element joining two domains, a node with no path to ground); the algebraic ones (two
sources fixing the same variable, a storage element fixed by a source) are made by the
derivation, which has the equations.
"""

from __future__ import annotations

from dataclasses import dataclass

from odelab.systems.network.elements import DOMAINS, Element, NetworkError

__all__ = ["GROUND", "Graph", "Port", "build_graph"]

GROUND = "ground"


@dataclass(frozen=True)
class Port:
    """One node pair of an element: its domain and nodes (side 1, or side 2 of a coupling)."""

    element: str
    side: int  # 1 or 2
    domain: str
    a: str
    b: str


@dataclass(frozen=True)
class Graph:
    elements: dict  # name -> Element, in the file's order
    ports: tuple[Port, ...]
    nodes: tuple[tuple[str, str], ...]  # (domain, node) of every node but ground, first seen first

    def ports_of(self, name: str) -> tuple[Port, ...]:
        return tuple(p for p in self.ports if p.element == name)


def build_graph(elements: dict[str, Element]) -> Graph:
    """Ports and nodes of the elements, checked: one domain per node, every node reaches ground."""
    ports: list[Port] = []
    domain_of: dict[str, tuple[str, str]] = {}  # node -> (domain, first element on it)
    nodes: list[tuple[str, str]] = []
    for name, el in elements.items():
        sides = [(1, el.DOMAIN, el.nodes)]
        if el.DOMAIN2 is not None:
            sides.append((2, el.DOMAIN2, el.nodes2))
        for side, domain, (a, b) in sides:
            for node in (a, b):
                if node == GROUND:
                    continue
                if node not in domain_of:
                    domain_of[node] = (domain, name)
                    nodes.append((domain, node))
                elif domain_of[node][0] != domain:
                    other_domain, other = domain_of[node]
                    key = "nodes2" if side == 2 else "nodes"
                    raise NetworkError(
                        f"node {node!r} joins two domains: {other!r} puts it in the {other_domain} domain, "
                        f"{name!r} ({el.TYPE}) in the {domain} domain. A node belongs to one domain: give "
                        f"{name!r} a node of its own, and join domains only through a coupling (dc-motor: "
                        f"electrical to rotational; rack-pinion: rotational to translational).",
                        key=f"elements.{name}.{key}")
            ports.append(Port(name, side, domain, a, b))
    _check_grounded(ports, nodes)
    return Graph(elements=dict(elements), ports=tuple(ports), nodes=tuple(nodes))


def _check_grounded(ports: list[Port], nodes: list[tuple[str, str]]) -> None:
    """Every node has a path to ground through the elements of its domain."""
    parent: dict[str, str] = {}

    def find(n):
        while parent.setdefault(n, n) != n:
            parent[n] = parent[parent[n]]
            n = parent[n]
        return n

    for p in ports:
        # each domain has its own ground
        a = f"{p.domain}:{p.a}"
        b = f"{p.domain}:{p.b}"
        parent[find(a)] = find(b)
    floating: dict[str, list[str]] = {}
    for domain, node in nodes:
        root = find(f"{domain}:{node}")
        if root != find(f"{domain}:{GROUND}"):
            floating.setdefault(root, []).append(node)
    if floating:
        group = next(iter(floating.values()))
        names = sorted({p.element for p in ports if p.a in group or p.b in group})
        listed = ", ".join(repr(n) for n in group)
        which = "node " + listed if len(group) == 1 else "nodes " + listed
        raise NetworkError(
            f"{which} float: no element joins {'it' if len(group) == 1 else 'them'} to ground "
            f"(elements {', '.join(repr(n) for n in names)}), so {'its' if len(group) == 1 else 'their'} "
            f"{DOMAINS[_domain(nodes, group[0])].across_word} is not defined. Connect one of these nodes to "
            "\"ground\" (e.g. nodes = [\"" + group[0] + "\", \"ground\"]), or fix a misspelt node name.",
            key="elements")


def _domain(nodes, node):
    return next(d for d, n in nodes if n == node)
