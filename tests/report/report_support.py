"""Helpers of the report tests: building a report, a strict HTML tree, Markdown tables.

The HTML tree uses the standard library's ``html.parser`` only, and is strict on purpose: the report closes every element it opens, so an end tag that does not
match the open element, a missing end tag, an end tag for a void element or ``<div/>`` is an
error here even where browsers would recover.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]  # the repository

VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}


@dataclass(eq=False)
class Node:
    tag: str
    attrs: dict
    parent: "Node | None" = None
    children: list = field(default_factory=list)  # Node or str

    def iter(self):
        for child in self.children:
            if isinstance(child, Node):
                yield child
                yield from child.iter()

    def find_all(self, tag: str | None = None, *, cls: str | None = None, **attrs) -> list["Node"]:
        out = []
        for node in self.iter():
            if tag and node.tag != tag:
                continue
            if cls and cls not in node.attrs.get("class", "").split():
                continue
            if any(node.attrs.get(k.replace("_", "-")) != v for k, v in attrs.items()):
                continue
            out.append(node)
        return out

    def find(self, tag: str | None = None, *, cls: str | None = None, **attrs) -> "Node | None":
        found = self.find_all(tag, cls=cls, **attrs)
        return found[0] if found else None

    def text(self) -> str:
        parts = []
        for child in self.children:
            parts.append(child.text() if isinstance(child, Node) else child)
        return " ".join("".join(parts).split())


class _Builder(HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.root = Node("#document", {})
        self.stack = [self.root]
        self.errors: list[str] = []
        self.doctype = None

    def handle_decl(self, decl):
        self.doctype = decl

    def handle_starttag(self, tag, attrs):
        node = Node(tag, {k: (v if v is not None else "") for k, v in attrs}, self.stack[-1])
        self.stack[-1].children.append(node)
        if tag not in VOID:
            self.stack.append(node)

    def handle_startendtag(self, tag, attrs):
        if tag not in VOID:
            self.errors.append(f"self-closing non-void element <{tag}/> at line {self.getpos()[0]}")
        self.handle_starttag(tag, attrs)
        if tag not in VOID:
            self.stack.pop()

    def handle_endtag(self, tag):
        line = self.getpos()[0]
        if tag in VOID:
            self.errors.append(f"end tag for void element </{tag}> at line {line}")
            return
        if len(self.stack) == 1:
            self.errors.append(f"stray end tag </{tag}> at line {line}")
            return
        if self.stack[-1].tag != tag:
            self.errors.append(f"</{tag}> closes <{self.stack[-1].tag}> at line {line}")
            if any(n.tag == tag for n in self.stack[1:]):
                while self.stack[-1].tag != tag:
                    self.stack.pop()
            else:
                return
        self.stack.pop()

    def handle_data(self, data):
        self.stack[-1].children.append(data)


def parse_html(text: str) -> tuple[Node, list[str], str | None]:
    """The tree, the well-formedness errors, and the doctype."""
    builder = _Builder()
    builder.feed(text)
    builder.close()
    errors = list(builder.errors)
    errors.extend(f"<{n.tag}> is never closed" for n in builder.stack[1:])
    return builder.root, errors, builder.doctype


def table_records(table: Node) -> list[dict[str, str]]:
    """Rows of a table that have a cell for every header, as {header: cell text}."""
    headers = [th.text() for th in table.find("thead").find_all("th")]
    records = []
    for tr in table.find("tbody").find_all("tr"):
        cells = [c.text() for c in tr.children if isinstance(c, Node) and c.tag in ("td", "th")]
        if len(cells) == len(headers):
            records.append(dict(zip(headers, cells)))
    return records


_UNESCAPED_PIPE = re.compile(r"(?<!\\)\|")


def markdown_tables(text: str) -> list[list[str]]:
    """Blocks of consecutive lines starting with '|' (outside fenced code)."""
    tables, current, fenced = [], [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        if not fenced and line.startswith("|"):
            current.append(line)
        else:
            if current:
                tables.append(current)
            current = []
    if current:
        tables.append(current)
    return tables


def markdown_cells(line: str) -> list[str]:
    return [c.strip() for c in _UNESCAPED_PIPE.split(line)[1:-1]]


@dataclass
class Report:
    out: Path
    result: object  # odelab.report.ReportResult
    html: str
    md: str


def build(runs: Path, out: Path, **kwargs) -> Report:
    """build_report, then the texts it wrote ("" for a format not asked for)."""
    from odelab.report import build_report

    result = build_report(runs, out, **kwargs)
    html = (out / "index.html").read_text(encoding="utf-8") if (out / "index.html").exists() else ""
    md = (out / "report.md").read_text(encoding="utf-8") if (out / "report.md").exists() else ""
    return Report(out, result, html, md)
