"""Every sentence of the report true of its data (issue 37): each lead-in and caption that makes
a claim is checked where the claim holds *and* on the files where it must not appear.

"Printed" text is what the print stylesheet shows: the text of the page less every element of
class ``no-print`` (the screen-only parts), with the ``print-only`` ones."""

from __future__ import annotations

import re

from report_support import Node, parse_html


def printed(node: Node) -> str:
    parts = []
    for child in node.children:
        if isinstance(child, Node):
            if "no-print" in child.attrs.get("class", "").split():
                continue
            parts.append(printed(child))
        else:
            parts.append(child)
    return " ".join(" ".join(parts).split())


def sections(html: str) -> dict[str, Node]:
    root, problems, _ = parse_html(html)
    return {s.attrs["id"]: s for s in root.find_all("section", cls="experiment")}


def test_the_linear_model_lead_in_only_where_an_analysis_follows(lab_report):
    for anchor, section in sections(lab_report.html).items():
        text = section.text()
        if "the analysis below uses its linear model" in text:
            assert "Control analysis" in text, anchor
    by = sections(lab_report.html)
    for anchor in ("speed_control", "thermostat"):  # nonlinear diagrams with no [analysis]
        text = by[anchor].text()
        assert "Control analysis" not in text and "analysis below" not in text, anchor
        assert "The diagram has nonlinear blocks, so it has no A, B, C, D of its own" in text
    assert "the analysis below uses its linear model" in by["feedback_pi"].text()
    md = lab_report.md
    for part in md.split("\n## ")[1:]:
        if "the analysis below uses its linear model" in part:
            assert "### Control analysis" in part


def test_the_print_never_points_at_the_screen_only_appendix(lab_report):
    root, _, _ = parse_html(lab_report.html)
    text = printed(root.find("body"))
    for m in re.finditer(r"[^.]*\bappendix\b[^.]*\.", text, re.IGNORECASE):
        assert "not printed" in m.group(0) or "screen version" in m.group(0), m.group(0)
    assert "Appendix: resolved settings" not in text  # the contents' entry is screen-only too
    assert "resolved.toml" in text


def step_tables(section: Node) -> dict[str, Node]:
    return {d.find("summary").text(): d for d in section.find_all("details", cls="steps")}


def test_printed_step_tables_keep_the_rows_of_the_maxima(lab_report):
    by = sections(lab_report.html)
    promised = 0
    for anchor, section in by.items():
        note = section.find("p", cls="print-only")
        long_tables = [d for d in section.find_all("details", cls="steps")
                       if int(re.search(r"each of the (\d+) output", d.find("summary").text()).group(1)) > 20]
        says = any("rows of the largest" in p.text() for p in section.find_all("p", cls="table-note"))
        assert says == bool(long_tables), anchor  # the promise only where a table is cut
        for d in long_tables:
            promised += 1
            body = d.find("tbody")
            rows = [tr for tr in body.find_all("tr") if len(tr.find_all("td")) == 5]
            values = [[td.text() for td in tr.find_all("td")] for tr in rows]
            abs_err = [float(v[3]) for v in values]
            rel = [float(v[4]) for v in values if v[4] != "undefined"]
            kept = [v for tr, v in zip(rows, values) if "no-print" not in tr.attrs.get("class", "")]
            # the largest errors of the screen table are among the printed rows
            assert max(abs_err) in [float(v[3]) for v in kept], (anchor, d.find("summary").text())
            if rel:
                assert max(rel) in [float(v[4]) for v in kept if v[4] != "undefined"], anchor
    assert promised >= 5
    # the saturating PI case of the issue: both maxima of u printed, at their times
    saturating = step_tables(by["feedback_pi"])["step-3-saturating (ode45): u at each of the 518 output points"]
    printed_rows = printed(saturating)
    assert re.search(r"0\.7534\d* -0\.53\d+ -0\.53\d+ 7\.4\d\de-07", printed_rows)
    assert re.search(r"1\.046\d* -0\.0166\d+ -0\.0166\d+ \S+ 2\.026e-05", printed_rows)


def test_one_panel_captions_name_what_they_show(lab_report):
    html = lab_report.html
    assert "as MATLAB's documentation plots" not in html and "as MATLAB&#39;s documentation plots" not in html
    by = sections(html)
    captions = {a: " ".join(f.text() for f in s.find_all("figcaption")) for a, s in by.items()}
    assert "Every state against t in one panel" in captions["rigid_body"]  # y1, y2, y3: all its states
    assert "Every state against t" not in captions["speed_control"]
    assert "speed and sampled_error against t in one panel" in captions["speed_control"]
    assert "T and heater against t in one panel" in captions["thermostat"]
    for anchor in ("speed_control", "thermostat", "bouncing_ball"):  # hundreds of points: no markers drawn
        assert "hollow markers at the output points" not in captions[anchor].split("Bottom:")[0], anchor


def test_notes_are_not_warnings_and_say_no_bare_zero(lab_report):
    by = sections(lab_report.html)
    pi = by["feedback_pi"]
    notes = pi.find(cls="notes")
    assert notes is not None and "warn" not in notes.attrs["class"].split()
    text = notes.text()
    assert "small-step: actuator (saturation) never changed mode (no zero crossing)" in text
    assert "zero crossings located: actuator (saturation) 1" in text
    assert not re.search(r"zero crossings located:[^;.]* 0\b", lab_report.html + lab_report.md)


def test_a_curve_a_log_axis_cannot_draw_is_named_in_the_caption(lab_report):
    root, _, _ = parse_html(lab_report.html)
    captions = {f.attrs.get("id"): f.find("figcaption").text() for f in root.find_all("figure")}
    exercise1 = captions["fig-work-precision_exercise1-work-precision"]
    assert "Not drawn: ode89 (its error is 0 at every point), which a log axis cannot show" in exercise1
    for name, caption in captions.items():  # the others draw every curve: no such sentence
        if name != "fig-work-precision_exercise1-work-precision" and "Not drawn" in caption:
            assert "work-precision" in name or "convergence" in name, name


def test_the_error_estimate_is_described_as_it_is_made(lab_report):
    text = parse_html(lab_report.html)[0].find(id="summary").text()
    assert "a fixed-step method: h / 2" in text and "RelTol and AbsTol / 10, scaled by 10/9" in text
    # no shipped case is flagged: the ok? sentence would describe nothing
    assert ">ok?<" not in lab_report.html and "ok?: the two solves" not in text
    assert "**ok?**" not in lab_report.md
