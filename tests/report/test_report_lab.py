"""The report of real runs of the lab's experiments: structure, figures, numbers, validity."""

from __future__ import annotations

import base64
import re

import pytest
from report_support import markdown_cells, markdown_tables, parse_html, table_records

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
LAB = ("exercise1", "exercise1_2pi", "rigid_body")


def drawn(data: bytes) -> bool:
    """A PNG of a drawn figure, not a blank or tiny one: a page-wide image (at least 600 px),
    at least 1 % of it ink (not white) in at least 8 colours (lines, text and their edges)."""
    import io

    import numpy as np
    from PIL import Image

    if not data.startswith(PNG_SIGNATURE):
        return False
    pixels = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
    ink = pixels[(pixels != 255).any(axis=-1)]
    return pixels.shape[1] >= 600 and len(ink) >= 0.01 * pixels.shape[0] * pixels.shape[1] and len(
        np.unique(ink, axis=0)) >= 8


@pytest.fixture(scope="module")
def tree(lab_report):
    root, errors, doctype = parse_html(lab_report.html)
    assert not errors, errors[:10]
    return root


def section(tree, name):
    node = tree.find("section", id=name)
    assert node is not None, f"no section for {name}"
    return node


def png_of(img) -> bytes:
    src = img.attrs["src"]
    assert src.startswith("data:image/png;base64,"), src[:40]
    return base64.b64decode(src.split(",", 1)[1], validate=True)


def test_writes_one_html_page_the_markdown_and_its_figures(lab_report):
    out = lab_report.out
    paths = set(lab_report.result.paths)
    assert out / "index.html" in paths and out / "report.md" in paths
    assert lab_report.result.warnings == ()
    linked = re.findall(r"!\[[^\]]*\]\((figures/[^)]+\.png)\)", lab_report.md)
    assert len(linked) >= 2 * len(LAB) + 2  # solution + error per experiment, + the linearisation's two
    for rel in linked:
        data = (out / rel).read_bytes()
        assert drawn(data), rel
        assert out / rel in paths
    assert not list(out.rglob("*.tmp")), "a temporary file was left behind"


def test_html_is_well_formed_with_unique_ids_and_working_links(lab_report, tree):
    _, errors, doctype = parse_html(lab_report.html)
    assert doctype and doctype.lower() == "doctype html"
    assert errors == []
    ids = [n.attrs["id"] for n in tree.iter() if "id" in n.attrs]
    assert len(ids) == len(set(ids)), "duplicate ids"
    for a in tree.find_all("a"):
        href = a.attrs.get("href", "")
        if href.startswith("#"):
            assert href[1:] in ids, f"link to missing #{href[1:]}"
    assert tree.find("html").attrs.get("lang") == "en"
    assert tree.find("meta", charset="utf-8") is not None


def test_no_remote_resources_and_no_external_files(lab_report, tree):
    html = lab_report.html
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", html, re.I)
    assert not re.search(r"url\(\s*['\"]?(https?:)?//", html, re.I)
    assert "@import" not in html and "@font-face" not in html
    assert not tree.find_all("link"), "stylesheets or icons must be inline"
    for node in tree.iter():
        for attr in ("src", "href"):
            value = node.attrs.get(attr)
            if value is not None:
                assert value.startswith(("data:", "#")), f"<{node.tag} {attr}={value[:60]!r}>"
    # the Content-Security-Policy makes any remote load fail in the browser as well
    csp = tree.find("meta", http_equiv="Content-Security-Policy")
    assert csp is not None and "default-src 'none'" in csp.attrs["content"]


SVG = "{http://www.w3.org/2000/svg}"
#: the figures Graphviz draws (report.build._draw_control): a block diagram or a network, as SVG
DRAWING_ID = re.compile(r"fig-.+-(diagram|network)(-\d+)?")


def drawing_problems(data: bytes) -> list[str]:
    """What is wrong with a Graphviz drawing: not an SVG, or not a drawing of blocks joined by
    signals (fewer than 3 nodes or 2 edges, a node with neither a shape nor a text, fewer labels
    than half the nodes)."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        return [f"not XML: {exc}"]
    if root.tag != SVG + "svg":
        return [f"root is {root.tag}"]
    groups = [(g.get("class"), g) for g in root.iter(SVG + "g")]
    nodes = [g for cls, g in groups if cls == "node"]
    edges = [g for cls, g in groups if cls == "edge"]
    problems = []
    if len(nodes) < 3 or len(edges) < 2:
        problems.append(f"{len(nodes)} nodes and {len(edges)} edges")
    for g in nodes:
        title = g.findtext(SVG + "title")
        drawn_parts = [e for e in g if e.tag in {SVG + t for t in ("polygon", "ellipse", "path", "polyline", "text")}]
        if not title or not drawn_parts:  # a block's box, a junction's dot, or a named output's text
            problems.append(f"node {title!r} is not drawn")
    labels = [t.text for t in root.iter(SVG + "text") if (t.text or "").strip()]
    if len(labels) < len(nodes) // 2:
        problems.append(f"{len(labels)} labels for {len(nodes)} nodes")
    return problems


def test_every_figure_is_an_embedded_non_trivial_png(tree):
    """A plot is a drawn PNG; a block diagram or network drawing is an SVG by Graphviz with its
    nodes, edges and labels (issue 37: crisp in print); nothing else is SVG."""
    images = tree.find_all("img")
    assert len(images) >= 2 * len(LAB) + 2
    drawings = []
    for img in images:
        figure_id = img.parent.attrs.get("id", "")
        if DRAWING_ID.fullmatch(figure_id):
            src = img.attrs["src"]
            assert src.startswith("data:image/svg+xml;base64,"), (figure_id, src[:40])
            assert drawing_problems(base64.b64decode(src.split(",", 1)[1], validate=True)) == [], figure_id
            assert "laid out by" in img.parent.find("figcaption").text()
            drawings.append(figure_id)
        else:
            assert drawn(png_of(img)), figure_id
        assert img.attrs.get("alt")
        assert img.parent.tag == "figure" and img.parent.find("figcaption").text()
    # the shipped experiments with a [blocks] diagram, and the networks (the README's first line runs them too)
    assert sorted(drawings) == [f"fig-{name}-diagram" for name in ("feedback_pi", "figure1")] + [
        f"fig-network_{name}-network" for name in ("dc_motor", "msd", "nonlinear_spring", "quarter_car", "rlc",
                                                   "tanks", "thermal")] + [
        f"fig-{name}-diagram" for name in ("speed_control", "thermostat")]


def test_the_readme_report_has_every_network_with_its_section_figures_and_drawing(shipped_report):
    """The README's first line runs experiments/networks/ too: each network has its section, its
    solution figure and its network drawing (an SVG by Graphviz) in the report it writes."""
    from conftest import readme_folders

    root, errors, _ = parse_html(shipped_report.html)
    assert not errors, errors[:10]
    networks = sorted(p.stem for folder in readme_folders() for p in folder.glob("network_*.toml"))
    assert networks == ["network_dc_motor", "network_msd", "network_nonlinear_spring", "network_quarter_car",
                        "network_rlc", "network_tanks", "network_thermal"]
    sections = [s.attrs["id"] for s in root.find_all("section", cls="experiment")]
    assert sorted(name for name in sections if name.startswith("network_")) == networks
    for name in networks:
        node = section(root, name)
        assert node.find("h2").text().endswith(("by its elements", "by their elements", name)), name
        figures = {f.attrs["id"] for f in node.find_all("figure")}
        assert {f"fig-{name}-solution", f"fig-{name}-network"} <= figures, (name, figures)
        img = node.find("figure", id=f"fig-{name}-network").find("img")
        assert drawing_problems(base64.b64decode(img.attrs["src"].split(",", 1)[1], validate=True)) == [], name
    assert shipped_report.result.warnings == ()


def test_the_drawing_check_finds_a_drawing_without_its_blocks():
    """Not vacuous: an empty SVG, a PNG, one node with no edge, and a node drawn as nothing are refused."""
    empty = b'<svg xmlns="http://www.w3.org/2000/svg" width="10pt" height="10pt"><g class="graph"></g></svg>'
    assert drawing_problems(empty) != []
    assert drawing_problems(PNG_SIGNATURE + b"\0" * 20) != []
    one = (b'<svg xmlns="http://www.w3.org/2000/svg"><g class="node"><title>b:a</title>'
           b'<polygon points="0,0 1,1"/><text>a</text></g></svg>')
    assert drawing_problems(one) == ["1 nodes and 0 edges"]
    hollow = one.replace(b'<polygon points="0,0 1,1"/><text>a</text>', b"")
    assert "node 'b:a' is not drawn" in drawing_problems(hollow)


def test_sections_follow_the_lab_order(tree):
    order = [s.attrs["id"] for s in tree.find_all("section", cls="experiment")]
    present = [name for name in ("exercise1", "exercise1_2pi", "rigid_body", "exercise2") if name in order]
    assert order[:len(present)] == present
    # a linearisation study comes before the remaining experiments, which are alphabetical
    rest = order[len(present):]
    lin = [name for name in rest if name in ("linearisation", "linearization", "network_nonlinear_spring",
                                             "nonlinear_spring")]
    assert rest[:len(lin)] == lin and "nonlinear_spring" in lin
    others = rest[len(lin):]
    assert others == sorted(others) and "msd_inputs" in others


def test_every_experiment_section_has_its_parts(tree):
    for name in (*LAB, "msd_inputs", "nonlinear_spring"):
        node = section(tree, name)
        assert node.find("h2").text()
        assert node.find("table", cls="errors") is not None
        figures = {f.attrs["id"] for f in node.find_all("figure")}
        assert f"fig-{name}-solution" in figures
        # the error is drawn beside, under or below the solution, in the same figure
        assert f"fig-{name}-relative-error" not in figures
        caption = node.find("figure", id=f"fig-{name}-solution").find("figcaption").text()
        assert "Error against t on a log scale" in caption
        steps = node.find_all("details", cls="steps")
        assert steps, f"{name}: no per-step tables"
        for d in steps:
            assert d.find("summary").text()
            assert len(d.find("tbody").find_all("tr")) >= 2


def test_summary_table_lists_every_case_with_its_numbers(tree):
    summary = tree.find("section", id="summary")
    rows = summary.find("table").find("tbody").find_all("tr", cls="group-start")
    listed = {(r.attrs["data-experiment"], r.attrs["data-case"]) for r in rows}
    for case in [("exercise1", "ode23"), ("exercise1", "ode45"), ("exercise1_2pi", "ode23"),
                 ("exercise1_2pi", "ode45"), ("rigid_body", "ode45"), ("msd_inputs", "step"),
                 ("msd_inputs", "step-ode23"), ("msd_inputs", "sine"), ("msd_inputs", "ramp"),
                 ("nonlinear_spring", "ode45")]:
        assert case in listed

    def cells(experiment, case):
        row = summary.find("tr", data_experiment=experiment, data_case=case)
        return [c.text() for c in row.children if not isinstance(c, str)]

    def tail(experiment, case):  # points, steps, failed, fevals, quantity, max abs, max rel (then est. error)
        return cells(experiment, case)[-8:-1]

    assert tail("exercise1", "ode23") == ["12", "11", "0", "34", "y", "2.136e-04", "1.068e-04"]
    assert cells("exercise1", "ode23")[-1] == "—"  # a reference: the true error, no estimate
    assert tail("exercise1_2pi", "ode23")[-1] == "6.907e-04"
    assert tail("rigid_body", "ode45")[:4] == ["85", "21", "0", "127"]
    assert tail("exercise1", "ode23")[0] == "12"
    status = summary.find("tr", data_experiment="rigid_body", data_case="ode45").find("span", cls="status")
    assert status.text() == "ok"


def _grid_widths(table) -> list[int]:
    """The number of columns each row of a table's body fills, counting the cells that reach down into it
    from rows above (rowspan) and each cell's colspan."""
    reaching: dict[int, int] = {}  # column -> rows it is still occupied for
    widths = []
    for tr in table.find("tbody").find_all("tr"):
        column, filled = 0, 0
        cells = [c for c in tr.children if not isinstance(c, str) and c.tag in ("td", "th")]
        for cell in cells:
            while reaching.get(column, 0) > 0:
                column += 1
            span, down = int(cell.attrs.get("colspan", 1)), int(cell.attrs.get("rowspan", 1))
            for c in range(column, column + span):
                reaching[c] = down
            column += span
        filled = sum(1 for v in reaching.values() if v > 0)
        widths.append(filled)
        reaching = {c: v - 1 for c, v in reaching.items() if v > 1}
    return widths


def test_every_row_of_every_table_fills_its_columns(tree, lab_report):
    # a rowspan that counts fewer rows than the table has (the summary's experiment cell over cases with
    # an error estimate and no reference: stiff's and bouncing_ball's second quantity moved one column
    # left, under Experiment, until 2026-12) shifts every cell of the rows below it
    tables = tree.find_all("table")
    assert len(tables) > 50
    for table in tables:
        if table.find("thead") is None or table.find("tbody") is None:
            continue
        header = sum(int(th.attrs.get("colspan", 1)) for th in table.find("thead").find_all("th"))
        widths = _grid_widths(table)
        wrong = [i for i, w in enumerate(widths) if w != header]
        assert not wrong, f"{table.attrs.get('class')}: rows {wrong[:5]} fill {[widths[i] for i in wrong[:5]]} of {header}"


def test_the_experiment_cell_spans_the_rows_of_its_cases_with_estimates_only(tree):
    # stiff.toml has no reference: its stiff cases list x and v with their estimates, two rows each
    rows = tree.find("section", id="summary").find("tbody").find_all("tr")
    first = next(i for i, r in enumerate(rows) if r.attrs.get("data-experiment") == "stiff")
    after = next(i for i, r in enumerate(rows) if i > first and r.attrs.get("data-experiment") not in (None, "stiff"))
    cell = rows[first].find("td", cls="experiment-cell")
    assert int(cell.attrs["rowspan"]) == after - first == 1 + 2 * 5  # ode45 stopped (no estimate), five stiff solvers


def test_error_tables_hold_the_stored_maxima(tree):
    records = {r["Case"]: r for r in table_records(section(tree, "exercise1").find("table", cls="errors"))}
    # Exercise 1's f = sin t + 2 stays in [1, 3]: the headline is the lab's pointwise maximum
    assert records["ode23"]["Rel error"] == records["ode23"]["Max |f - y| / |f|"] == "1.068e-04"
    assert records["ode23"]["Points"] == "12"
    assert records["ode45"]["Rel error"] == "1.187e-07"
    assert records["ode23"]["|f| there"] == "—"
    # the rigid body's y1 crosses zero: the headline is relative to its peak (about 1), and the
    # pointwise maximum is shown with the small |f| it divided by
    rigid = table_records(section(tree, "rigid_body").find("table", cls="errors"))[0]
    assert (rigid["Steps"], rigid["Failed"], rigid["F-evals"]) == ("21", "0", "127")
    assert rigid["Quantity"] == "y1" and rigid["Max |f - y| / |f|"] == "1.728e-02 (1 undefined)"
    assert rigid["Rel error"] == "4.181e-04 of peak"  # max |f - y| = 4.181e-04, max |y1| = 1.000
    assert rigid["|f| there"] == "7.607e-03"


def test_exercise1_note_quotes_the_stored_numbers(lab_report, tree):
    expected = "1.068e-04 on [0, pi] with 12 points; 6.907e-04 on [0, 2 pi] with 17 points"
    note = section(tree, "exercise1").find("div", cls="lab-note")
    assert note is not None and expected in note.text()
    assert "6.907e-4 is ode23 on [0, 2 pi]" in note.text()
    assert expected in lab_report.md


def test_rigid_body_plots_every_state_with_the_step_statistics(tree):
    figure = section(tree, "rigid_body").find("figure", id="fig-rigid_body-solution")
    caption = figure.find("figcaption").text()
    assert "21 successful steps, 0 failed attempts, 127 function evaluations" in caption
    assert "markers at the output points" in caption


def test_cases_that_differ_by_input_get_a_panel_each(tree):
    node = section(tree, "msd_inputs")
    caption = node.find("figure", id="fig-msd_inputs-solution").find("figcaption").text()
    assert caption.startswith("One column per input: rows show y, x, v, f against t; cases that differ only "
                              "in their solver share a panel")
    records = {r["Case"]: r for r in table_records(node.find("table", cls="errors"))}
    assert list(records) == ["step", "step-ode23", "sine", "ramp"]  # the file's order, not alphabetical
    assert records["sine"]["Input"] == "f = sin(0.2 t)"
    assert records["ramp"]["Input"] == "f = t"
    assert records["step-ode23"]["Method"] == "ode23"
    # with outputs, the plots and per-step tables show the output y
    steps = [d.find("summary").text() for d in node.find_all("details", cls="steps")]
    assert len(steps) == 4 and all(": y at each of" in s for s in steps)


def test_set_ups_group_cases_that_differ_only_in_their_solver(lab_runs):
    from odelab.report.collect import collect_runs
    from odelab.report.content import setups

    groups, warnings = collect_runs(lab_runs, ["msd_inputs"])
    assert warnings == []
    found = setups(groups[0].runs)
    assert [g.label for g in found] == ["step: f steps 0 → 1 at t = 0", "sine: f = sin(0.2 t)", "ramp: f = t"]
    assert [[r.case for r in g.runs] for g in found] == [["step", "step-ode23"], ["sine"], ["ramp"]]
    # within a set-up the methods differ, so each line has its method's report-wide colour
    from odelab.report.plots import METHOD_COLORS

    assert found[0].colors == {"step": METHOD_COLORS["ode45"], "step-ode23": METHOD_COLORS["ode23"]}


def test_per_step_table_in_html_has_every_point(tree):
    details = section(tree, "exercise1").find_all("details", cls="steps")
    ode23 = next(d for d in details if d.find("summary").text().startswith("ode23"))
    rows = [[c.text() for c in tr.children if not isinstance(c, str)] for tr in ode23.find("tbody").find_all("tr")]
    assert len(rows) == 12
    assert rows[0][:3] == ["0", "2", "2"]
    assert rows[-1][4] == "1.068e-04"  # the maximum, at t = pi


def test_markdown_caps_long_tables_and_says_how_many_rows_are_left_out(lab_report):
    md = lab_report.md
    head = "**ode45: y1 at each of the 85 output points**"
    assert head in md
    block = md.split(head, 1)[1].split("\n\n", 2)[1]
    lines = [line for line in block.splitlines() if line.startswith("|")]
    rows = [line for line in lines[2:] if not line.startswith("| … |")]
    gaps = [int(re.search(r"(\d+) rows? left out", line).group(1)) for line in lines[2:] if line.startswith("| … |")]
    # the first and last 20 rows and the rows of the maxima (rigid_body's y1: in the middle), the rest counted
    assert rows[0].startswith("| 0 |") and rows[-1].startswith("| 12 |") and 40 <= len(rows) <= 42
    assert len(rows) + sum(gaps) == 85 and 1 <= len(gaps) <= 3
    # a short table is complete
    short = md.split("**ode23: y at each of the 12 output points**", 1)[1].split("\n\n", 2)[1]
    assert len([line for line in short.splitlines() if line.startswith("|")]) == 2 + 12


def test_markdown_tables_are_rectangular(lab_report):
    tables = markdown_tables(lab_report.md)
    assert len(tables) >= 10
    for table in tables:
        widths = {len(markdown_cells(line)) for line in table}
        assert len(widths) == 1, table[:3]
        assert re.fullmatch(r"\|(\s*:?-+:?\s*\|)+", table[1].replace(" ", "")), table[1]


def test_markdown_has_the_sections_in_order(lab_report):
    md = lab_report.md
    positions = [md.index(f"({name})\n") for name in LAB]
    assert positions == sorted(positions)
    assert md.index("## Summary") < positions[0]
    assert "## Resolved settings" in md and "```toml" in md


def test_header_has_version_date_hashes_and_settings(lab_report, tree):
    from odelab import __version__

    header = tree.find("header", id="header")
    assert f"odelab {__version__}" in header.text()
    assert re.search(r"Generated \d{4}-\d\d-\d\d \d\d:\d\d", header.text())
    provenance = header.find("details", id="provenance")
    digest = __import__("hashlib").sha256((__import__("pathlib").Path(
        section(tree, "exercise1").find("code").text())).read_bytes()).hexdigest()
    assert digest[:12] in provenance.text()
    settings = tree.find("section", id="settings").find_all("details", cls="settings")
    first = next(d for d in settings if d.find("summary").text() == "exercise1 (2 cases)")
    assert first.find("p", cls="settings-case").text() == "ode23" and 'method = "ode23"' in first.find("pre").text()
    # the other case shows only what differs, arrays written inline
    pres = [p.text() for p in first.find_all("pre")]
    assert len(pres) == 2 and pres[1].strip() == 'solver.method = "ode45"'
    exercise2 = next(d for d in settings if d.find("summary").text() == "exercise2 (7 cases)").find_all("pre")
    assert "A = [[0.0, 1.0], [-3.0, -4.0]]" in exercise2[0].text()
    assert exercise2[3].text().startswith('inputs.f.type = "sine" inputs.f.amplitude = 1')
    assert provenance.find("a", href="#settings") is not None


def test_linearisation_section(tree, study):
    node = section(tree, "nonlinear_spring")
    assert "Linearisation" in [h.text() for h in node.find_all("h3")]
    figures = {f.attrs["id"] for f in node.find_all("figure")}
    assert "fig-nonlinear_spring-linearisation" in figures  # responses per amplitude and the error against it
    op = node.find("table", cls="operating-point")
    assert ["state", "x", "0"] in [[c.text() for c in tr.children if not isinstance(c, str)]
                                    for tr in op.find("tbody").find_all("tr")]
    a = next(t for t in node.find_all("table", cls="matrix") if t.find("caption").text() == "A")
    rows = [[c.text() for c in tr.children if not isinstance(c, str)] for tr in a.find("tbody").find_all("tr")]
    assert rows == [["x", "0", "1"], ["v", "-3", "-4"]]
    amplitudes = table_records(node.find("table", cls="amplitudes"))
    assert [r["Amplitude"] for r in amplitudes] == ["0.1", "0.3", "1", "3", "10"]
    within = [r["Within threshold"] for r in amplitudes]
    assert within[0] == "yes" and within[-1] == "no"
    summary = node.find("p", cls="lin-summary").text()
    assert f"up to an input amplitude of {study['max_amplitude_within']:g}" in summary
    assert "within 5% of the nonlinear response of y" in summary


def shipped(name: str):
    from report_support import ROOT

    if not (ROOT / "experiments" / f"{name}.toml").exists():
        pytest.skip(f"experiments/{name}.toml is not shipped")


def test_shipped_exercise2_shares_a_panel_per_input(tree):
    shipped("exercise2")
    node = section(tree, "exercise2")
    caption = node.find("figure", id="fig-exercise2-solution").find("figcaption").text()
    assert caption.startswith("One column per input: rows show y, x, v, f against t; cases that differ only "
                              "in their solver share a panel")
    records = table_records(node.find("table", cls="errors"))
    assert len(records) >= 3 and all(r["Status"] == "ok" for r in records)
    assert any(r["Input"] == "f = sin(0.2 t)" for r in records)


def test_shipped_linearisation_study_is_rendered(tree):
    shipped("linearisation")
    node = section(tree, "linearisation")
    summaries = [p.text() for p in node.find_all("p", cls="lin-summary")]
    assert summaries and all("of the nonlinear response" in s for s in summaries)
    assert node.find_all("table", cls="amplitudes") and node.find_all("table", cls="operating-point")
    ids = {f.attrs["id"] for f in node.find_all("figure")}
    assert sum(i.endswith("-linearisation") for i in ids) == 2  # one per operating point
    assert "linearised model" in node.find("p", cls="source").text()
