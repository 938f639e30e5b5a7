"""``odelab import``'s table: for each file, what was translated, what was ignored and what to write instead.

One line per file (where its experiment file was written and the counts), then one row per
note: the place (file and line, or block path), what was found, and what it became or what to
write instead. The columns wrap to fit 80 columns.
"""

from __future__ import annotations

from odelab.formats.base import GAP, IGNORED, TRANSLATED
from odelab.terminal import shown

__all__ = ["print_import", "import_counts"]

_MARK = {TRANSLATED: "[green]ok[/]", IGNORED: "[dim]--[/]", GAP: "[bold red]GAP[/]"}


def import_counts(notes) -> dict[str, int]:
    counts = {TRANSLATED: 0, IGNORED: 0, GAP: 0}
    for note in notes:
        counts[note.outcome] += 1
    return counts


def print_import(console, source: str, written: str, notes) -> None:
    """The file's line and its table (``console`` is the CLI's Rich console)."""
    from rich import box
    from rich.table import Table

    counts = import_counts(notes)
    gaps = counts[GAP]
    state = (f"[bold red]{gaps} gap{'s' if gaps != 1 else ''}[/]: fill {'them' if gaps != 1 else 'it'} in before "
             "it runs" if gaps else "[green]everything translated[/]")
    console.print(f"{shown(source)} -> {shown(written)}: {counts[TRANSLATED]} translated, {counts[IGNORED]} ignored, "
                  f"{state}")
    if not notes:
        return
    table = Table(box=box.SIMPLE, show_edge=False, pad_edge=False, expand=False, width=min(console.width, 100))
    table.add_column("", no_wrap=True)
    table.add_column("where", no_wrap=True, max_width=18)
    table.add_column("found", max_width=26, overflow="fold")
    table.add_column("became / write instead", ratio=1, overflow="fold")
    for note in notes:
        where = f"{note.file}:{note.where.removeprefix('line ')}" if note.file else note.where
        table.add_row(_MARK[note.outcome], shown(where), shown(note.construct), shown(note.detail))
    console.print(table)
