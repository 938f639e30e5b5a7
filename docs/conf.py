"""Sphinx configuration of odelab's documentation site.

Pages are Markdown (MyST). Two pages are generated while the site builds, from the code
itself, so they cannot drift: the key reference (``reference/keys``, from the experiment
schema through :mod:`odelab.experiment.keyref`) and the command-line reference
(``reference/cli``, from the Typer commands). Build with warnings as errors:
``python -m sphinx -W -b html docs docs/_build/html`` (``tests/test_docs.py`` does).
"""

from __future__ import annotations

import odelab

project = "odelab"
author = "the odelab developers"
copyright = "2026, the odelab developers"
release = odelab.__version__

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "REPORT-STYLE.md"]
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
                   if "_build" not in p.parts and p.name != "REPORT-STYLE.md")
    extra = [p for p in pages if p not in named and p != "index" and not p.startswith("crosswalk/matlab-habits")]
    if not extra:
        return ""
    return "```{toctree}\n:caption: More\n:maxdepth: 1\n\n" + "\n".join(extra) + "\n```\n"


def _generated(app, docname, source):
    if docname == "index":
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
    app.connect("source-read", _generated)
    app.connect("autodoc-process-docstring", _plain_bars)
