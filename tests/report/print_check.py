"""Reading a printed report back: what each page of a PDF holds, from poppler's ``pdftotext
-bbox-layout`` (every text line with its box) and ``pdftoppm`` (the page as pixels, for what
pdftotext cannot see: how far down figures reach).

Used by tests/report/test_report_print.py and by hand (``python tests/report/print_check.py
report.pdf index.html``, which prints each page's findings)."""

from __future__ import annotations

import html as html_lib
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

XHTML = "{http://www.w3.org/1999/xhtml}"
#: Below this fraction of its height a page counts as more than half blank.
HALF = 0.5


def tools_missing() -> list[str]:
    return [t for t in ("pdftotext", "pdftoppm") if shutil.which(t) is None]


@dataclass
class Page:
    number: int  # 1-based
    height: float  # points
    lines: list[tuple[float, float, str]] = field(default_factory=list)  # (yMin, yMax, text), top to bottom
    ink_bottom: float = 0.0  # fraction of the page's height down to which anything is drawn

    @property
    def text(self) -> str:
        return "\n".join(t for _, _, t in self.lines)


def read_pages(pdf: Path) -> list[Page]:
    """Every page's text lines (top to bottom) and how far down its ink reaches."""
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "bbox.html"
        subprocess.run(["pdftotext", "-bbox-layout", str(pdf), str(out)], check=True, capture_output=True)
        root = ET.fromstring(out.read_text(encoding="utf-8").replace("<!DOCTYPE html>", ""))
        pages = []
        for k, page in enumerate(root.iter(XHTML + "page"), start=1):
            p = Page(k, float(page.get("height")))
            for line in page.iter(XHTML + "line"):
                words = [w.text or "" for w in line.iter(XHTML + "word")]
                p.lines.append((float(line.get("yMin")), float(line.get("yMax")), " ".join(words)))
            p.lines.sort()
            pages.append(p)
        subprocess.run(["pdftoppm", "-r", "24", "-gray", str(pdf), str(Path(folder) / "p")], check=True,
                       capture_output=True)
        from PIL import Image
        import numpy as np

        for p, image in zip(pages, sorted(Path(folder).glob("p-*.pgm"))):
            a = np.asarray(Image.open(image), dtype=float)
            rows = np.flatnonzero((a < 235).any(axis=1))
            p.ink_bottom = float(rows[-1] + 1) / a.shape[0] if rows.size else 0.0
    return pages


def headings(html_text: str) -> tuple[list[str], list[str]]:
    """The texts of the report's chapter (h2) and section (h3) headings, as printed on one line."""
    def clean(fragment: str) -> str:
        return " ".join(html_lib.unescape(re.sub(r"<[^>]+>", " ", fragment)).split())

    h2 = [clean(m) for m in re.findall(r"<h2[^>]*>(.*?)</h2>", html_text, re.S)]
    h3 = [clean(m) for m in re.findall(r"<h3[^>]*>(.*?)</h3>", html_text, re.S)]
    return h2, h3


def _starts(line: str, heads: list[str]) -> bool:
    norm = " ".join(line.split())
    return any(h and (norm == h or (len(norm) >= 12 and h.startswith(norm))) for h in heads)


def orphaned_headings(pages: list[Page], html_text: str, lines_after: int = 3) -> list[str]:
    """Headings left at the bottom of a page: at most ``lines_after`` lines of text follow them
    there and nothing drawn (their figure or table starts on the next page). A chapter that
    ends there (the next page starts with an h2) is not counted."""
    h2, h3 = headings(html_text)
    out = []
    for p, nxt in zip(pages, pages[1:]):
        if not p.lines or (nxt.lines and _starts(nxt.lines[0][2], h2)):
            continue
        last = max((i for i, (_, _, t) in enumerate(p.lines) if _starts(t, h2 + h3)), default=None)
        if last is None or len(p.lines) - 1 - last > lines_after:
            continue
        after = p.lines[last:]
        gaps = [b[0] - a[1] for a, b in zip(after, after[1:])]
        drawn = p.ink_bottom * p.height > p.lines[-1][1] + 15 or any(g > 30 for g in gaps)  # a figure follows
        if not drawn:
            out.append(f"page {p.number}: {p.lines[last][2]!r} is followed by {len(p.lines) - 1 - last} line(s) "
                       "and its content starts on the next page")
    return out


def half_blank(pages: list[Page], html_text: str) -> list[str]:
    """Pages whose content ends above half their height, unless a chapter (h2) starts the next page."""
    h2, _ = headings(html_text)
    out = []
    for p, nxt in zip(pages, pages[1:]):
        if p.ink_bottom < HALF and not (nxt.lines and _starts(nxt.lines[0][2], h2)):
            out.append(f"page {p.number}: ink ends at {p.ink_bottom:.0%} of the page")
    return out


def split_words(pages: list[Page]) -> list[str]:
    """Lines that end in a word cut at a hyphen inside an experiment's name (``work-`` / ``precision``)."""
    out = []
    for p in pages:
        for (_, _, a), (_, _, b) in zip(p.lines, p.lines[1:]):
            if re.search(r"[A-Za-z_]-$", a) and re.match(r"[a-z_]+[a-z0-9_]*\b", b) and "_" in (a + b).split()[-1]:
                out.append(f"page {p.number}: {a!r} / {b!r}")
    return out


def main(argv: list[str]) -> int:  # pragma: no cover - a tool for a person
    pdf, page_html = Path(argv[0]), Path(argv[1]).read_text(encoding="utf-8")
    pages = read_pages(pdf)
    print(f"{len(pages)} pages")
    for p in pages:
        print(f"  page {p.number}: ink to {p.ink_bottom:.0%}; last line {p.lines[-1][2][:70] if p.lines else ''!r}")
    for line in orphaned_headings(pages, page_html) + half_blank(pages, page_html) + split_words(pages):
        print(line)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(sys.argv[1:]))
