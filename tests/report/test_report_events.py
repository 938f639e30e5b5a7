"""The report of the shipped bouncing ball: events drawn on the solution, listed next to their exact times."""

from __future__ import annotations

import math

import pytest
from report_support import parse_html, table_records

T1 = math.sqrt(2 * 10 / 9.81)


def exact_bounce(k):
    return T1 * (1 + 2 * 0.8 * (1 - 0.8**k) / (1 - 0.8))


@pytest.fixture(scope="module")
def ball(lab_report):
    root, errors, _ = parse_html(lab_report.html)
    assert not errors, errors[:10]
    node = root.find("section", id="bouncing_ball")
    assert node is not None
    return node


def test_events_table_lists_every_bounce_next_to_its_exact_time(ball):
    table = ball.find("table", cls="events")
    records = table_records(table)
    assert len(records) == 7
    for k, row in enumerate(records):
        assert row["Event"] == "floor" and row["#"] == str(k + 1)
        assert float(row["Exact t"]) == pytest.approx(exact_bounce(k), abs=1e-9)
        assert abs(float(row["t"]) - exact_bounce(k)) < 1e-9 and float(row["|t - exact|"]) < 1e-12
        assert row["Reset"].startswith("v = ")
    assert "7 events located by ode45" in ball.text()


def test_solution_figure_marks_the_events(ball):
    caption = ball.find("figure", id="fig-bouncing_ball-solution").find("figcaption").text()
    assert "Red triangles mark the located events, dotted vertical lines their exact times" in caption


def test_markdown_lists_the_events(lab_report):
    md = lab_report.md
    part = md[md.index("### Events"):]
    rows = [line for line in part.splitlines() if line.startswith("| ") and "floor" in line][:7]
    assert len(rows) == 7 and rows[0].split("|")[3].strip() == "1.427843123"


@pytest.mark.parametrize("raw, message", [
    ({"a": 1}, "`events` must be a list"),
    ([{"name": "floor", "t": "1"}], "`events[0]` must be a table with a name, a time t and a state"),
    ([{"name": "floor", "t": 1.0, "state": {}, "exact_t": "x"}], "`events[0].exact_t` must be a number"),
])
def test_malformed_events_in_result_json_are_named(raw, message):
    from odelab.report.collect import parse_events

    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_events(raw)
