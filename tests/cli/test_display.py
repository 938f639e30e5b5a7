"""The terminal's summary table: laid out without Rich's Table when it fits, the same characters and styles."""

import io

import numpy as np

import pytest
from rich.console import Console
from rich.table import Table
from rich.text import Text

from odelab.cli.display import print_grid

COLUMNS = [("case", "left"), ("method", "left"), ("points", "right"), ("quantity", "left"),
           ("pointwise max |f - y| / |f|", "left"), ("status", "left")]
ROWS = [["ode23", "ode45 (compiled)", "12", "y", "2.1e-03 at t = 3.14 (|f| = 1.0e-08)", Text("ok", style="green")],
        ["", "", "", "é中文", "", ""],  # a double-width name: widths are terminal cells, not characters
        ["a long case name", "x", "123456", "[red]v[/]", "", Text("FAILED", style="bold red")]]


def _styled_chars(width: int, draw) -> list[tuple[str, object]]:
    """Every character the console writes, with the style it is written in (segment boundaries ignored)."""
    console = Console(file=io.StringIO(), width=width, highlight=False, emoji=False, force_terminal=True,
                      color_system="truecolor", record=True)
    draw(console)
    return [(ch, seg.style) for seg in console._record_buffer for ch in seg.text]


def _rich_table(console):
    table = Table(show_edge=False, pad_edge=False, header_style="bold", box=None)
    for name, justify in COLUMNS:
        table.add_column(name, justify=justify, no_wrap=not name.startswith("pointwise"))
    for row in ROWS:
        table.add_row(*(c if isinstance(c, Text) else Text(c) for c in row))
    console.print(table)


@pytest.mark.parametrize("width", [200, 80])
def test_the_grid_writes_what_richs_table_writes(width):
    ours = _styled_chars(width, lambda c: print_grid(c, COLUMNS, ROWS, wrap=("pointwise max |f - y| / |f|",)))
    rich = _styled_chars(width, _rich_table)
    assert "".join(ch for ch, _ in ours) == "".join(ch for ch, _ in rich)
    bold = [i for i, (ch, style) in enumerate(ours) if style is not None and style.bold and ch != " "]
    assert bold == [i for i, (ch, style) in enumerate(rich) if style is not None and style.bold and ch != " "]
    for (ch, a), (_, b) in zip(ours, rich):  # the same colour on every non-blank character and cell padding
        if ch != " " or (b is not None and b.color is not None):
            assert (a.color if a else None) == (b.color if b else None)


def test_the_grid_lines_at_a_wide_console():
    console = Console(file=io.StringIO(), width=200, highlight=False, emoji=False)
    print_grid(console, COLUMNS, ROWS)
    lines = console.file.getvalue().splitlines()
    assert lines[0] == ("case              method            points  quantity   pointwise max |f - y| / |f|          "
                        "status")
    assert lines[2] == " " * 44 + "é中文" + " " * 49  # 5 cells for 3 characters, padded to the column's 9
    assert lines[3].startswith("a long case name  x                 123456  [red]v[/]")  # a cell is never markup


@pytest.mark.parametrize("width", [200, 80, 64])
def test_a_console_without_colours_gets_the_styled_grids_characters(width):
    """A pipe or a file (no colour system, nothing recorded): the grid goes out as plain lines, character for
    character what the styled grid (a recording console takes that path) writes."""
    def out(**kwargs) -> str:
        console = Console(file=io.StringIO(), width=width, highlight=False, emoji=False, **kwargs)
        assert console.color_system is None
        print_grid(console, COLUMNS, ROWS, wrap=("pointwise max |f - y| / |f|",))
        return console.file.getvalue()

    plain = out()
    assert plain == out(record=True) and plain.count("\n") >= len(ROWS) + 1
    assert "FAILED" in plain and "\x1b" not in plain


def test_a_narrow_console_keeps_names_whole_and_moves_free_text_below():
    console = Console(file=io.StringIO(), width=64, highlight=False, emoji=False)
    print_grid(console, COLUMNS, ROWS, wrap=("pointwise max |f - y| / |f|",))
    text = console.file.getvalue()
    assert max(len(line) for line in text.splitlines()) <= 64
    assert "…" not in text
    assert "ode45 (compiled)" in text and "a long case name" in text  # Rich alone cut these to "ode45…"
    assert "pointwise max |f - y| / |f|:\n  ode23 ode45 (compiled) y: 2.1e-03 at t = 3.14" in text


def test_the_lab_tables_fit_80_columns_with_every_case_and_method_whole():
    from pathlib import Path

    from odelab.cli.display import print_experiment
    from odelab.experiment.loader import load_experiment
    from odelab.run.runner import run_case

    exp = load_experiment(Path(__file__).resolve().parents[2] / "experiments" / "exercise2.toml")
    results = [run_case(c) for c in exp.cases]
    console = Console(file=io.StringIO(), width=80, highlight=False, emoji=False)
    print_experiment(console, exp, results)
    lines = console.file.getvalue().splitlines()
    assert max(len(line) for line in lines) <= 80 and not any("…" in line for line in lines)
    table = lines[:next(i for i, line in enumerate(lines) if line.startswith("pointwise max"))]
    rows = [line.split() for line in table if line.startswith(("step-", "sine-", "ramp-"))]
    assert any(line.split()[:3] == ["case", "method", "pts"] for line in table)  # numeric titles give way
    assert [r[:2] for r in rows] == [[c.name, c.problem.method] for c in exp.cases]
    assert "marked * (of peak)" in " ".join(lines)


def test_a_quantitys_extent_is_taken_a_block_at_a_time(monkeypatch):
    from odelab.cli import display

    column = np.array([np.nan, 3.0, -np.inf, 7.5, np.nan, -2.25, np.inf, 1.0])
    whole = display._extent(column)
    assert whole == ["1", "-2.25", "7.5"]  # the final value, and min and max of the finite values
    monkeypatch.setattr(display, "_EXTENT_BLOCK", 3)  # blocks of 3: [nan 3 -inf] [7.5 nan -2.25] [inf 1]
    assert display._extent(column) == whole
    assert display._extent(np.array([np.nan, np.inf, np.nan, np.nan])) == ["nan", "nan", "nan"]
