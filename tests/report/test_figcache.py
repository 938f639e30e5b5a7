"""The figure cache: a rebuild with unchanged runs draws nothing and writes the same files."""

import shutil

import numpy as np
import pytest

from odelab.report import drawing, figcache, plots
from odelab.report.plots import FigureSpec, Line, Panel
from report_support import build


def spec(y, name="a", title="x(t)"):
    t = np.linspace(0, 1, 5)
    return FigureSpec(name=name, caption="c", alt="a",
                      panels=(Panel(title=title, xlabel="t", ylabel="x", lines=(Line(t, y, "ode45", "#000"),)),))


def test_the_key_follows_every_plotted_value_and_label_but_not_the_file_name():
    y = np.arange(5.0)
    key = figcache.figure_key(spec(y))
    assert figcache.figure_key(spec(y.copy(), name="b")) == key
    y2 = y.copy()
    y2[3] = np.nextafter(y2[3], 9)  # one bit of one value
    assert figcache.figure_key(spec(y2)) != key
    assert figcache.figure_key(spec(y, title="v(t)")) != key


def test_a_rebuild_of_unchanged_runs_draws_nothing(lab_runs, tmp_path, monkeypatch):
    # the header states when the report was built: one clock for both builds, so that two
    # builds a minute apart still compare (nothing else in a report depends on the time)
    from datetime import datetime, timezone

    import odelab.report.build as report_build

    monkeypatch.setattr(report_build, "generated_at", lambda: datetime(2026, 1, 2, 3, 4, tzinfo=timezone.utc))
    first = build(lab_runs, tmp_path / "one", formats=["md"])
    drawn = []
    monkeypatch.setattr(drawing, "POOL_MIN", 10**6)  # drawn here, where the list below can see it
    monkeypatch.setattr(plots, "_draw_png", lambda s: drawn.append(s.name) or b"")
    second = build(lab_runs, tmp_path / "two", formats=["md"])
    assert drawn == []
    names = sorted(p.name for p in (tmp_path / "one" / "figures").iterdir())
    assert len(names) >= 10 and names == sorted(p.name for p in (tmp_path / "two" / "figures").iterdir())
    for name in names:
        assert (tmp_path / "one" / "figures" / name).read_bytes() == (tmp_path / "two" / "figures" / name).read_bytes()
    assert second.md == first.md and "2026-01-02 03:04 UTC" in first.md


def test_a_changed_run_redraws_only_its_figures(lab_runs, tmp_path, monkeypatch):
    runs = tmp_path / "runs"
    shutil.copytree(lab_runs, runs)
    build(runs, tmp_path / "one", formats=["md"])
    csv = runs / "exercise1" / "ode23" / "trajectory.csv"
    lines = csv.read_text().splitlines()
    cells = lines[3].split(",")
    cells[1] = repr(float(cells[1]) + 1e-3)  # y at one output point
    csv.write_text("\n".join([*lines[:3], ",".join(cells), *lines[4:]]) + "\n")
    drawn = []
    monkeypatch.setattr(drawing, "POOL_MIN", 10**6)
    real = plots._draw_png
    monkeypatch.setattr(plots, "_draw_png", lambda s: drawn.append(s.name) or real(s))
    build(runs, tmp_path / "two", formats=["md"])
    assert drawn and all(name.startswith("exercise1-") for name in drawn)
