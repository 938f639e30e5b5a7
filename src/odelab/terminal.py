"""Showing user text on a terminal: control characters made visible, Rich markup escaped.

Titles, case and quantity names, file paths and the messages that quote them come from files
anyone can write. Printed raw, an ESC sequence in a title can clear the screen, set the window
title or write the clipboard (OSC 52); a carriage return can overwrite a line; a bidi override
can reorder what is read; and Rich would read ``[red]`` or ``:x:`` in them as markup. Every
user string the CLI prints goes through :func:`shown` (the CLI's consoles also have emoji codes
turned off). Nothing here prints.
"""

from __future__ import annotations

import re

__all__ = ["visible", "shown"]

# C0 controls, DEL, C1 controls (CSI 0x9b and OSC 0x9d act like ESC [ and ESC ]), and the
# invisible formatting characters that reorder or split lines (bidi overrides, isolates,
# marks, the Unicode line and paragraph separators).
_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]")
_CONTROL_KEEPING_LINES = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def _escape_char(match: re.Match) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def visible(text: str, *, lines: bool = False) -> str:
    """``text`` with every control character written as an escape (``\\x1b``, ``\\x00``, ``\\u202e``).

    ``lines=True`` keeps newlines and tabs (for odelab's own multi-line messages that quote
    user text); otherwise they are shown as ``\\n`` and ``\\t`` too, so a name is one line.
    """
    pattern = _CONTROL_KEEPING_LINES if lines else _CONTROL
    return pattern.sub(_escape_char, str(text))


def shown(text: str, *, lines: bool = False) -> str:
    """:func:`visible`, then Rich markup escaped: safe to put inside a Rich markup string."""
    from rich.markup import escape

    return escape(visible(text, lines=lines))
