"""Borderless terminal tables (Rich) laid out to fit the console: shared by ``odelab run``'s sections."""

from __future__ import annotations

import re

from rich.cells import cell_len
from rich.console import Console
from rich.text import Text

__all__ = ["fits", "print_grid"]


def fits(console: Console, columns, rows) -> bool:
    """Whether the table's cells, each on one line, fit the console's width as they are."""
    widths = [cell_len(name) for name, _ in columns]
    for row in rows:
        for i, cell in enumerate(row):
            widths[i] = max(widths[i], cell_len(cell.plain if isinstance(cell, Text) else str(cell)))
    return sum(widths) + 2 * (len(widths) - 1) <= console.width


def print_grid(console: Console, columns, rows, *, wrap=()) -> None:
    """A borderless table (Rich's ``Table(box=None, pad_edge=False, show_edge=False)``, bold header).

    Cells are plain strings (never markup) or :class:`rich.text.Text`. When every cell is one
    line and the table fits the console's width, the lines are laid out here, exactly as Rich
    lays them out (each column as wide as its widest cell, two spaces between columns, the last
    one padded too) and printed as one Text: a tenth of the cost of Rich's table layout, which
    a batch of small files pays once per file; to a console that shows no styles and records
    none (a pipe, a file), as plain lines, the same characters without a style span per cell.
    Otherwise (Rich would shrink or wrap columns) the same cells go through Rich's Table.
    """
    header = [name for name, _ in columns]
    plains = [[c.plain if isinstance(c, Text) else c for c in row] for row in rows]
    widths = [cell_len(name) for name in header]
    one_line = all("\n" not in name for name in header)
    for row in plains:
        for i, plain in enumerate(row):
            one_line = one_line and "\n" not in plain
            widths[i] = max(widths[i], cell_len(plain))
    fits_as_is = one_line and sum(widths) + 2 * (len(widths) - 1) <= console.width
    if fits_as_is and console.color_system is None and not console.record:
        # A console that shows no styles (a pipe, a file, NO_COLOR) and keeps none for export: the
        # same lines as plain text, without building and rendering a style span per cell.
        def line(texts) -> str:
            return "  ".join(_padded(text, width, justify) for text, width, (_, justify) in zip(texts, widths, columns))

        console.print(Text("\n".join([line(header), *map(line, plains)])), soft_wrap=True)
        return
    cells = [[c if isinstance(c, Text) else Text(c) for c in row] for row in rows]
    if fits_as_is:
        text = Text()
        for i, ((name, justify), width) in enumerate(zip(columns, widths)):
            pad = " " * (width - cell_len(name))
            text.append((pad + name if justify == "right" else name + pad) + ("  " if i < len(widths) - 1 else ""),
                        style="bold")
        for row in cells:
            text.append("\n")
            for i, ((_, justify), width, cell) in enumerate(zip(columns, widths, row)):
                pad = " " * (width - cell_len(cell.plain))  # in the cell's style, as Rich pads it
                if justify == "right":
                    text.append(pad, style=cell.style)
                text.append_text(cell)
                if justify != "right":
                    text.append(pad, style=cell.style)
                if i < len(widths) - 1:
                    text.append("  ")
        console.print(text, soft_wrap=True)  # it fits: no wrapping to compute
        return
    from rich.table import Table

    # Too wide for the terminal. Text columns (left-aligned: case, method, quantity, status) keep
    # their cells whole, so an ode45 row never reads "ode…"; numeric columns give way instead:
    # their headers break at spaces or shorten ("fevals" to "fev"), their cells wrap at spaces
    # ("2.728e-05 of peak" on two lines). The free-text columns in ``wrap`` wrap too, or, if even
    # that leaves no room, follow the table as lines of their own.
    def words(text: str) -> int:
        return max((cell_len(w) for w in _camel(text).split()), default=1)

    def layout(short: bool):
        titles = [_SHORT.get(name, name) if short else name for name, _ in columns]
        widths = []
        for i, (name, justify) in enumerate(columns):
            plain = [row[i].plain for row in cells if i < len(row)]
            whole = max((cell_len(p) for p in plain), default=1)
            cell = whole if justify != "right" else max((words(p) for p in plain), default=1)
            widths.append(max(cell, words(titles[i]) if justify == "right" else cell_len(titles[i])))
        return titles, widths

    keep = [i for i, (name, _) in enumerate(columns) if name not in wrap]
    for short in (False, True):
        titles, widths = layout(short)
        fixed = sum(widths[i] for i in keep) + 2 * (len(keep) - 1)
        if fixed + 14 * (len(columns) - len(keep)) <= console.width:
            break
    if fixed > console.width and len(keep) > 2:  # even squeezed it does not fit: split it, never cut a number
        for part in _parts(columns, keep, widths, console.width):
            print_grid(console, [columns[i] for i in part], [[row[i] for i in part] for row in rows], wrap=wrap)
        return
    below = [i for i in range(len(columns)) if i not in keep] if fixed + 14 * (len(columns) - len(keep)) > console.width \
        else []
    shown = [i for i in range(len(columns)) if i not in below]
    table = Table(show_edge=False, pad_edge=False, header_style="bold", box=None)
    for i in shown:
        name, justify = columns[i]
        if name in wrap:
            table.add_column(Text(titles[i]), justify=justify, overflow="fold", min_width=12)
        elif justify == "right":
            table.add_column(Text(_break_header(titles[i], widths[i])), justify=justify, min_width=widths[i],
                             max_width=max(widths[i], max((cell_len(r[i].plain) for r in cells if i < len(r)),
                                                          default=1)))
        else:
            table.add_column(Text(titles[i]), justify=justify, no_wrap=True, min_width=widths[i])
    for row in cells:
        table.add_row(*(row[i] for i in shown if i < len(row)))
    console.print(table)
    labels = [i for i in keep if columns[i][1] == "left" and i < min(below, default=0)]
    for i in below:
        current: list[str] = [""] * len(labels)
        lines = []
        for row in cells:
            current = [row[j].plain or current[k] for k, j in enumerate(labels)]
            if i < len(row) and row[i].plain.strip():
                lines.append(f"{' '.join(c for c in current if c)}: {row[i].plain}")
        if lines:
            console.print(Text(f"{columns[i][0]}:", style="bold"))
            for line in lines:
                console.print(Text("  " + line))


def _parts(columns, keep: list[int], widths: list[int], width: int) -> list[list[int]]:
    """The columns in groups that each fit ``width``: every group repeats the leading label columns (the
    left-aligned ones before the first number: case, method; #, event), the others follow in order."""
    labels = []
    for i in keep:
        if columns[i][1] == "left" or not labels and i == keep[0]:
            labels.append(i)
        else:
            break
    labels = labels[:2]
    rest = [i for i in range(len(columns)) if i not in labels]
    base = sum(widths[i] for i in labels) + 2 * len(labels)
    parts, current, used = [], [], base
    for i in rest:
        if current and used + widths[i] > width:
            parts.append(labels + current)
            current, used = [], base
        current.append(i)
        used += widths[i] + 2
    if current:
        parts.append(labels + current)
    return parts


def _padded(text: str, width: int, justify: str) -> str:
    """``text`` padded with spaces to ``width`` terminal cells, on the left if ``justify`` is "right"."""
    spaces = " " * (width - cell_len(text))
    return spaces + text if justify == "right" else text + spaces


# Numeric columns' titles when a table must fit a narrow terminal.
_SHORT = {"points": "pts", "failed": "fail", "fevals": "fev", "evaluations": "evals", "quantity": "qty"}


def _camel(name: str) -> str:
    """MATLAB's CamelCase titles with a space where a line may break (SettlingTime: Settling Time)."""
    return re.sub(r"(?<=[a-z])(?=[A-Z])", " ", name)


def _break_header(name: str, width: int) -> str:
    """A column title broken at spaces (and CamelCase joints) into lines of at most ``width`` characters."""
    lines: list[str] = []
    for word in (_camel(name) if cell_len(name) > width else name).split():
        if lines and cell_len(lines[-1]) + 1 + cell_len(word) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return "\n".join(lines)
