"""User strings on the terminal: control characters visible, Rich markup and emoji codes inert (issue 15, class 6)."""

from pathlib import Path

import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.terminal import shown, visible

ROOT = Path(__file__).resolve().parents[1]
EXERCISE1 = (ROOT / "experiments" / "exercise1.toml").read_text(encoding="utf-8")


@pytest.mark.parametrize("raw, expected", [
    ("\x1b[2J\x1b[H", "\\x1b[2J\\x1b[H"),                         # clear the screen
    ("\x1b]0;owned\x07", "\\x1b]0;owned\\x07"),                     # set the window title
    ("\x1b]52;c;ZWNobyBoaQ==\x07", "\\x1b]52;c;ZWNobyBoaQ==\\x07"),  # write the clipboard (OSC 52)
    ("\x9b31m\x9d0;t\x9c", "\\x9b31m\\x9d0;t\\x9c"),                 # C1: CSI, OSC, ST
    ("a\x00b\x7fc\rd", "a\\x00b\\x7fc\\x0dd"),                      # NUL, DEL, carriage return
    ("left\u202etxt.exe", "left\\u202etxt.exe"),                  # a bidi override
    ("two\nlines\tand a tab", "two\\x0alines\\x09and a tab"),
    ("plain ümlaut café 日本", "plain ümlaut café 日本"),
])
def test_visible(raw, expected):
    assert visible(raw) == expected


def test_visible_keeps_line_breaks_only_when_asked():
    assert visible("a\nb\tc\x1b", lines=True) == "a\nb\tc\\x1b"


def test_shown_escapes_markup():
    assert shown("[red]x[/] \x1b") == "\\[red]x\\[/] \\x1b"


def hostile_file(tmp_path):
    text = EXERCISE1.replace('title = "Exercise 1', 'title = "\\u001b[2J\\u001b]52;c;aGk=\\u0007 :x: [red]T[/red] Exercise 1', 1)
    text = text.replace('name = "ode23"', 'name = "ode23 \\u009b31m\\u0000 :x:"', 1)
    path = tmp_path / "hostile.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_run_shows_control_characters_and_markup_as_text(tmp_path):
    result = CliRunner().invoke(app, ["run", str(hostile_file(tmp_path)), "--runs", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    out = result.output
    for raw in ("\x1b", "\x9b", "\x00", "\x07", "❌"):
        assert raw not in out
    assert "\\x1b[2J\\x1b]52;c;aGk=\\x07 :x: [red]T[/red] Exercise 1" in out
    assert "ode23 \\x9b31m\\x00 :x:" in out


def test_error_messages_quoting_user_text_are_shown_safely(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(EXERCISE1.replace('method = "ode23"', 'method = "ode23\\u001b]0;x\\u0007 :x:"', 1))
    result = CliRunner().invoke(app, ["run", str(path), "--no-store"])
    assert result.exit_code == 2
    assert "\x1b" not in result.output and "❌" not in result.output
    assert ":x:" in result.output


def test_every_table_of_a_run_shows_hostile_names_safely(tmp_path):
    """The events table and --table's per-point tables too: titles, case, quantity and event names."""
    text = (ROOT / "experiments" / "bouncing_ball.toml").read_text(encoding="utf-8")
    text = text.replace('title = "A bouncing ball"', 'title = "\\u001b[2J ball"', 1)
    text = text.replace("[events.floor]", '[events."fl\\u001b]52;c;aGk=\\u0007oor"]', 1)
    text += '\n[[case]]\nname = "\\u009b31m:x:"\n'
    path = tmp_path / "ball.toml"
    path.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(app, ["run", str(path), "--table", "--no-store"])
    assert result.exit_code == 0, result.output
    for raw in ("\x1b", "\x9b", "\x07", "❌"):
        assert raw not in result.output
    assert "\\x9b31m:x:: 7 events" in result.output
    assert "fl\\x1b]52;c;aGk=\\x07oor" in result.output and "\\x1b[2J ball" in result.output
