"""The package's shape, read from its source (ast over every module): no import circles, short functions.

An import inside a function counts as an edge: it is a circle all the same, only one that
bites later (at the first call instead of at import). ``if TYPE_CHECKING:`` imports do not
run and do not count.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "odelab"

# Circles that other rooms are cutting this round, by the modules they may span (name prefixes),
# with who and why. A circle with a module outside every entry fails; an entry that no longer
# matches a circle fails too (delete it).
KNOWN_CIRCLES: dict[tuple[str, ...], str] = {}


def _within(circle, prefixes) -> bool:
    return all(m.startswith(prefixes) for m in circle)


MAX_FUNCTION_LINES = 150
# Functions over MAX_FUNCTION_LINES that other rooms own and have not yet cut (name: reason).
LONG_FUNCTIONS: dict[str, str] = {}


def _modules() -> dict[str, Path]:
    out = {}
    for path in SRC.rglob("*.py"):
        parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST):
    """Every Import/ImportFrom node, at any depth, except under ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _is_type_checking(node):
            stack.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def import_graph(modules: dict[str, Path] | None = None) -> dict[str, set[str]]:
    """Module -> the odelab modules it imports (``from a import b`` is the module a.b when b is one)."""
    modules = modules or _modules()
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for mod, path in modules.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                graph[mod].update(a.name for a in node.names if a.name in modules)
                continue
            base = node.module or ""
            if node.level:
                up = package.split(".")
                up = up[:len(up) - (node.level - 1)]
                base = ".".join(up) + (f".{node.module}" if node.module else "")
            for alias in node.names:
                if f"{base}.{alias.name}" in modules:
                    graph[mod].add(f"{base}.{alias.name}")
                elif base in modules:
                    graph[mod].add(base)
        graph[mod].discard(mod)
    return graph


def circles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(frozenset(component))
    return found


def test_the_circle_finder_finds_a_circle_through_an_import_inside_a_function(tmp_path):
    pkg = tmp_path / "odelab" / "experiment"
    pkg.mkdir(parents=True)
    (tmp_path / "odelab" / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "loader.py").write_text("from odelab.experiment import study\n")
    (pkg / "study.py").write_text("def f():\n    from odelab.experiment.loader import slug\n")
    (pkg / "store.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                  "    from odelab.experiment import loader\n")
    (pkg / "naming.py").write_text("from . import store\n")
    modules = {}
    for path in (tmp_path / "odelab").rglob("*.py"):
        parts = list(path.relative_to(tmp_path).with_suffix("").parts)
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph = import_graph(modules)
    assert graph["odelab.experiment.naming"] == {"odelab.experiment.store"}  # a relative import
    assert circles(graph) == [frozenset({"odelab.experiment.loader", "odelab.experiment.study"})]


def test_no_import_circles():
    found = circles(import_graph())
    new = [sorted(c) for c in found if not any(_within(c, known) for known in KNOWN_CIRCLES)]
    assert not new, f"import circles in src/odelab (imports inside functions included): {new}"
    stale = [why for known, why in KNOWN_CIRCLES.items() if not any(_within(c, known) for c in found)]
    assert not stale, f"these circles are cut: remove them from KNOWN_CIRCLES: {stale}"


def _long_functions() -> dict[str, int]:
    out = {}
    for mod, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    out[f"{mod}.{node.name}"] = lines
    return out


def test_no_function_over_150_lines():
    long = _long_functions()
    new = {name: n for name, n in long.items() if name not in LONG_FUNCTIONS}
    assert not new, f"functions over {MAX_FUNCTION_LINES} lines (split them): {new}"
    stale = sorted(set(LONG_FUNCTIONS) - set(long))
    assert not stale, f"these functions are short now: remove them from LONG_FUNCTIONS: {stale}"
