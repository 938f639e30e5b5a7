"""Jinja2 environments for the report: HTML with autoescape on, Markdown with its own escaping.

Templates are files: the package's ``templates/`` folder, or a course's own folder given as
``template_dir``, whose files take precedence name by name (a course can replace only
``report.css`` and keep the rest).

In the Markdown environment every ``{{ value }}`` goes through :func:`md_escape` unless it is
already :class:`MarkdownText` (the output of the ``md_*`` filters), so a user's title or case
name can never break a table (``|``), open a link, start emphasis or inject raw HTML. Inside
the template's own raw HTML (``<details><summary>``) Markdown escapes do not apply: values
there go through ``md_html``, which escapes them as HTML.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from odelab.exceptions import InputError
from odelab.terminal import visible

__all__ = ["MarkdownText", "TEMPLATE_NAMES", "environments", "md_code", "md_escape", "md_fence", "md_html",
           "md_raw", "render_template", "sci"]

# The templates a report is made of; a course's template_dir may hold any of them.
TEMPLATE_NAMES = ("report.html.j2", "report.md.j2", "report.css")


class MarkdownText(str):
    """A string that is already Markdown: the Markdown environment writes it unescaped."""


# CommonMark lets a backslash escape any ASCII punctuation; these are the characters that
# can start or end markup inside a line (tables, emphasis, code, raw HTML, entities).
_MD_SPECIAL = re.compile(r"([\\`*<>|#&~])")
# A bracket only makes a link as "](" or "][" (or "]:" defining one at the start of a line);
# "[0, pi]" stays readable in the source.
_MD_LINK_BRACKET = re.compile(r"\](?=[(\[])")
_MD_LINK_DEFINITION = re.compile(r"^(\s*\[[^\]]*)\](?=:)")
# An underscore inside a word is literal in GitHub Markdown (exercise1_2pi); at a word edge
# it can open or close emphasis.
_MD_EDGE_UNDERSCORE = re.compile(r"(?<![A-Za-z0-9])_|_(?![A-Za-z0-9])")


def md_escape(value: Any) -> MarkdownText:
    """``value`` as literal text in Markdown, on one line (safe inside a table cell)."""
    if isinstance(value, MarkdownText):
        return value
    text = visible(" ".join(str(value).split()))  # newlines would end a table row; ESC would reach a terminal
    text = _MD_SPECIAL.sub(r"\\\1", text)
    text = _MD_LINK_BRACKET.sub(r"\\]", text)
    text = _MD_LINK_DEFINITION.sub(r"\1\\]", text)
    text = _MD_EDGE_UNDERSCORE.sub(r"\\_", text)
    return MarkdownText(text)


def md_fence(text: str, info: str = "") -> MarkdownText:
    """A fenced code block that ``text`` cannot close early (its fence outruns any backtick run)."""
    text = visible(text, lines=True)  # report.md is read with cat and less too
    longest = max((len(m) for m in re.findall(r"`+", text)), default=0)
    fence = "`" * max(3, longest + 1)
    body = text if text.endswith("\n") else text + "\n"
    return MarkdownText(f"{fence}{info}\n{body}{fence}")


def md_code(value: Any) -> MarkdownText:
    """``value`` as an inline code span (backslashes are literal there, so it is fenced, not escaped)."""
    text = visible(" ".join(str(value).split()))
    longest = max((len(m) for m in re.findall(r"`+", text)), default=0)
    fence = "`" * (longest + 1)
    pad = " " if text.startswith("`") or text.endswith("`") else ""
    return MarkdownText(f"{fence}{pad}{text}{pad}{fence}")


def md_html(value: Any) -> MarkdownText:
    """``value`` for the raw HTML inside Markdown (a ``<summary>``): HTML-escaped, since Markdown's
    backslash escapes do not apply in an HTML block."""
    from markupsafe import escape

    return MarkdownText(str(escape(" ".join(str(value).split()))))


def md_inline(value: Any) -> MarkdownText:
    """:func:`md_escape` for a piece of a sentence: a space at either end is kept (``**bold**`` then " text")."""
    text = str(value)
    lead = " " if text[:1].isspace() else ""
    trail = " " if text[-1:].isspace() and text.strip() else ""
    return MarkdownText(lead + md_escape(text) + trail)


def md_raw(value: Any) -> MarkdownText:
    """Mark template output (a macro's, a ``{% set %}`` block's) as Markdown already escaped."""
    return MarkdownText(str(value))


def _md_finalize(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, MarkdownText):
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return str(value)
    return md_escape(value)


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def sci(value: Any, missing: str = "—") -> str:
    """Four significant digits in scientific notation, as the lab quotes errors: 1.068e-04."""
    if _missing(value):
        return missing
    return f"{float(value):.3e}"


def num(value: Any, digits: int = 6, missing: str = "—") -> str:
    """A value with ``digits`` significant digits (plain or scientific, whichever is shorter)."""
    if _missing(value):
        return missing
    return f"{float(value):.{digits}g}"


def count(value: Any, missing: str = "—") -> str:
    """A count; ``missing`` where the method does not report it (SciPy's implicit nfailed)."""
    return missing if value is None else str(value)


def short_hash(value: str | None) -> str:
    return (value or "")[:12] or "—"


def percent(value: Any) -> str:
    if _missing(value):
        return "—"
    return f"{100 * float(value):g}%"


_FILTERS = {"sci": sci, "num": num, "count": count, "short_hash": short_hash, "percent": percent}


def _loader(template_dir: Path | None):
    from jinja2 import ChoiceLoader, FileSystemLoader, PackageLoader

    loaders = []
    if template_dir is not None:
        template_dir = Path(template_dir)
        if not template_dir.is_dir():
            raise InputError(f"`template_dir` {str(template_dir)!r} is not a folder; give a folder holding "
                             f"any of {', '.join(TEMPLATE_NAMES)}.", key="template_dir")
        loaders.append(FileSystemLoader(str(template_dir)))
    loaders.append(PackageLoader("odelab.report", "templates"))
    return ChoiceLoader(loaders)


def _sandbox_class():
    """Jinja's immutable sandbox, narrowed to what a report template needs to call.

    A template is a file a course hands around, so it is treated as untrusted: Jinja's sandbox
    already refuses ``_``-attributes (``''.__class__.__mro__``, ``cycler.__init__.__globals__``)
    and changes to lists and dicts; on top of that a template may call only its own macros,
    Jinja's harmless globals (range, dict, namespace, cycler, joiner, lipsum), methods of
    strings, numbers and containers, and methods of the report's own view objects. So no
    ``Path.write_text`` or ``ndarray.tofile`` through the stored runs in the context.
    """
    from jinja2.runtime import Macro
    from jinja2.sandbox import ImmutableSandboxedEnvironment, safe_range
    from jinja2.utils import Cycler, Joiner, Namespace, generate_lorem_ipsum

    plain = (str, int, float, bool, list, tuple, dict, set, frozenset)
    harmless = {safe_range, range, dict, Namespace, Cycler, Joiner, generate_lorem_ipsum}

    class ReportSandbox(ImmutableSandboxedEnvironment):
        def is_safe_callable(self, obj) -> bool:
            if not super().is_safe_callable(obj):
                return False
            if isinstance(obj, Macro) or any(obj is h for h in harmless):
                return True
            owner = getattr(obj, "__self__", None)
            if owner is None or isinstance(owner, type):
                return False
            if type(owner) in plain or isinstance(owner, (Cycler, Joiner, Namespace)):
                return True
            if type(owner).__module__ == "jinja2.runtime":  # loop.cycle(), super(), caller()
                return True
            return type(owner).__module__.startswith("odelab.report.")

    return ReportSandbox


def environments(template_dir: Path | None = None):
    """The HTML environment (autoescape on) and the Markdown environment (Markdown escaping).

    Both are sandboxed (see :func:`_sandbox_class`): the package's templates and a course's
    ``--template`` folder are rendered the same way, and neither can run code.
    """
    from jinja2 import StrictUndefined

    sandbox = _sandbox_class()
    loader = _loader(template_dir)
    common = {"loader": loader, "undefined": StrictUndefined, "trim_blocks": True, "lstrip_blocks": True,
              "keep_trailing_newline": True}
    html = sandbox(autoescape=True, bytecode_cache=_bytecode_cache("html"), **common)
    md = sandbox(autoescape=False, finalize=_md_finalize, bytecode_cache=_bytecode_cache("md"), **common)
    for env in (html, md):
        env.filters.update(_FILTERS)
    md.filters["md"] = md_escape
    md.filters["md_fence"] = md_fence
    md.filters["md_code"] = md_code
    md.filters["md_raw"] = md_raw
    md.filters["md_inline"] = md_inline
    md.filters["md_html"] = md_html
    return html, md


def render_template(env, name: str, context: dict[str, Any]) -> str:
    """Render template ``name``; a broken template (often a course's own) is an InputError naming it."""
    from jinja2 import TemplateError, TemplateNotFound

    try:
        return env.get_template(name).render(**context)
    except TemplateNotFound as exc:
        raise InputError(f"template {exc.name!r} was not found in the template folder or the package.",
                         key="template_dir") from None
    except TemplateError as exc:
        where = f" (line {exc.lineno})" if getattr(exc, "lineno", None) else ""
        filename = getattr(exc, "filename", None) or name
        raise InputError(f"template {filename}{where}: {exc.message or exc}", key="template_dir") from None


def _bytecode_cache(kind: str):
    """Compiled templates kept in the user's cache folder: compiling the report's templates took
    0.1 s of every build. One folder per environment (HTML and Markdown compile the same text
    differently) and per version of this file (where the environments are set up); Jinja
    checks each template's source against its entry, so an edited template is compiled again.

    The entries are marshalled code, run when loaded: the cache is untrusted
    (:mod:`odelab.cachedir`). Its folder is checked, each entry is sealed with its SHA-256 and
    loaded only if it matches; a damaged or foreign entry is compiled again. Without a usable
    folder, no cache (the templates are compiled each time)."""
    import hashlib

    from jinja2 import BytecodeCache

    from odelab import cachedir

    class SealedCache(BytecodeCache):
        def __init__(self, folder: Path):
            self.folder = folder

        def load_bytecode(self, bucket) -> None:
            data = cachedir.read_entry(self.folder, f"__jinja2_{bucket.key}.cache", "report template")
            if data is None:
                return
            try:
                bucket.bytecode_from_string(data)
            except Exception:  # noqa: BLE001 - sealed but unreadable (another Python): compile it
                bucket.reset()

        def dump_bytecode(self, bucket) -> None:
            cachedir.write_entry(self.folder, f"__jinja2_{bucket.key}.cache", bucket.bytecode_to_string())

    stamp = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:16]
    folder = cachedir.cache_folder(f"templates/{kind}-{stamp}")
    return None if folder is None else SealedCache(folder)

