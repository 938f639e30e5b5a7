"""Sphinx configuration of odelab's documentation site.

Pages are Markdown (MyST). Two pages are generated while the site builds, from the code
itself, so they cannot drift: the key reference (``reference/keys``, from the experiment
schema through :mod:`odelab.experiment.keyref`) and the command-line reference
(``reference/cli``, from the Typer commands). Build with warnings as errors:
``python -m sphinx -W -b html docs docs/_build/html`` (``tests/test_docs.py`` does).
"""

from __future__ import annotations

from pathlib import Path

import odelab

project = "odelab"
author = "the odelab developers"
copyright = "2026, the odelab developers"
release = odelab.__version__

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_generated", "REPORT-STYLE.md"]
myst_enable_extensions = ["deflist"]
myst_heading_anchors = 3
# Links from a page to files of the repository (experiments/..., bench/...) are not pages.
# A toctree glob (tutorials/*) picks up pages added later; it may match none today.
suppress_warnings = ["myst.xref_missing", "myst.header", "toc.empty_glob"]
autodoc_default_options = {"members": False}
autodoc_typehints = "none"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
html_theme = "pydata_sphinx_theme"
html_title = f"odelab {release}"
html_theme_options = {"navigation_with_keys": False, "show_prev_next": True}
html_static_path: list[str] = []


def _cli_reference() -> str:
    """Every command of ``odelab`` with its help text, arguments and options, from the Typer app."""
    import click
    import typer

    from odelab.cli import app

    group = typer.main.get_command(app)
    ctx = click.Context(group, info_name="odelab")
    lines = ["# Command-line reference", "",
             "Generated from the `odelab` commands themselves (`odelab COMMAND --help` prints the same).", ""]
    for name in group.list_commands(ctx):
        cmd = group.get_command(ctx, name)
        sub = click.Context(cmd, info_name=name, parent=ctx)
        lines += [f"## `odelab {name}`", "", (cmd.help or "").strip(), "", "```text",
                  cmd.get_usage(sub).replace("Usage: ", "usage: "), "```", ""]
        rows = []
        for param in cmd.get_params(sub):
            record = param.get_help_record(sub)
            if record is None:
                shown = param.human_readable_name
                rows.append((shown, getattr(param, "help", "") or ""))
            else:
                rows.append(record)
        if rows:
            lines += ["| argument or option | meaning |", "|---|---|"]
            for opt, text in rows:
                opt = opt.replace("|", "\\|")
                text = " ".join(text.split()).replace("|", "\\|")
                lines.append(f"| `{opt}` | {text} |")
            lines.append("")
    return "\n".join(lines)


def _more_pages(index: str) -> str:
    """A toctree of the pages that the index's toctrees do not name (pages added by later work)."""
    import re
    from pathlib import Path

    here = Path(__file__).parent
    named = set(re.findall(r"^([\w./-]+)$", index, flags=re.M))
    pages = sorted(str(p.relative_to(here).with_suffix("")) for p in here.rglob("*.md")
                   if "_build" not in p.parts and "_generated" not in p.parts and p.name != "REPORT-STYLE.md")
    extra = [p for p in pages if p not in named and p != "index" and not p.startswith("crosswalk/matlab-habits")]
    if not extra:
        return ""
    return "```{toctree}\n:caption: More\n:maxdepth: 1\n\n" + "\n".join(extra) + "\n```\n"


GALLERY = Path(__file__).parent / "_generated" / "gallery"


def _build_gallery(app) -> None:
    """Run every shipped experiment and draw its report's figures, for the gallery page.

    The figures are the report's own (``odelab report``), copied into ``_generated/gallery``
    (ignored by git) so that the page can show them; a shipped file that fails stops the build.
    """
    import shutil
    import subprocess
    import sys
    import tempfile

    root = Path(__file__).parent.parent
    shutil.rmtree(GALLERY, ignore_errors=True)
    GALLERY.mkdir(parents=True)
    with tempfile.TemporaryDirectory() as tmp:
        runs, report = Path(tmp) / "runs", Path(tmp) / "report"
        odelab = [sys.executable, "-m", "odelab.cli"]
        folders = sorted({str(p.parent) for p in (root / "experiments").rglob("*.toml")})  # networks/ too
        run = subprocess.run([*odelab, "run", *folders, "--runs", str(runs), "--json"],
                             capture_output=True, text=True, timeout=1200)
        if run.returncode != 0:
            raise RuntimeError(f"the gallery's `odelab run experiments/` exited {run.returncode}: {run.stderr[-2000:]}")
        made = subprocess.run([*odelab, "report", "--runs", str(runs), "--out", str(report), "--format", "md"],
                              capture_output=True, text=True, timeout=1200)
        if made.returncode != 0:
            raise RuntimeError(f"the gallery's `odelab report` exited {made.returncode}: {made.stderr[-2000:]}")
        for png in sorted((report / "figures").glob("*.png")):
            shutil.copy(png, GALLERY / png.name)
        (GALLERY / "runs.json").write_text(run.stdout)


def _gallery_page() -> str:
    import json

    root = Path(__file__).parent.parent
    doc = json.loads((GALLERY / "runs.json").read_text())
    figures = sorted(p.name for p in GALLERY.glob("*.png"))
    lines = ["# Gallery", "",
             "Every experiment file shipped in `experiments/`, run while this page was built, with the figures "
             "`odelab report` draws for it. Each file is ready to copy: `odelab run experiments/NAME.toml`.", ""]
    files: dict[str, list[dict]] = {}
    for exp in doc["experiments"]:
        files.setdefault(exp["file"], []).append(exp)
    for file, exps in files.items():
        path = Path(file)
        title = exps[0]["title"] or path.stem
        shown = path.resolve().relative_to(root) if path.resolve().is_relative_to(root) else path
        lines += [f"## {title}", "", f"`{shown}`: "
                  + ", ".join(f"{len(e['cases'])} case{'s' if len(e['cases']) != 1 else ''} ({e['name']})"
                              for e in exps) + ".", ""]
        for e in exps:
            stem = e["name"].replace("_", "-").lower()
            for name in figures:
                if name.startswith(f"{e['name']}-") or name.startswith(f"{stem}-"):
                    lines += [f"![{e['name']}: {name[:-4]}](_generated/gallery/{name})", ""]
        rel = path.resolve().relative_to(root) if path.resolve().is_relative_to(root) else path
        lines += ["```{literalinclude} " + f"../{rel}", ":language: toml", "```", ""]
    return "\n".join(lines)


def _generated(app, docname, source):
    if docname == "gallery":
        source[0] = _gallery_page()
    elif docname == "index":
        source[0] = source[0].replace("<!-- odelab:more-pages", _more_pages(source[0]) + "<!-- odelab:more-pages")
    elif docname == "reference/keys":
        from odelab.experiment.keyref import markdown

        source[0] = markdown()
    elif docname == "reference/cli":
        source[0] = _cli_reference()


def _plain_bars(app, what, name, obj, options, lines):
    """Docstrings write |x| for an absolute value, which reST would read as a substitution."""
    lines[:] = [line.replace("|", "\\|") for line in lines]


def setup(app):
    app.connect("builder-inited", _build_gallery)
    app.connect("source-read", _generated)
    app.connect("autodoc-process-docstring", _plain_bars)
