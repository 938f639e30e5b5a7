"""``build_report``: the stored runs in, a lab report out (one self-contained HTML file and Markdown).

The HTML page embeds its figures (base64 PNG) and its CSS and loads nothing from anywhere:
it opens offline, from a file or an e-mail attachment, and prints with every collapsed
section opened. The Markdown report links the same figures as PNG files in ``figures/``.
Every file is written atomically (temporary file, then rename), and the texts are rendered
before anything is written, so a failing template or an interrupted report leaves the
previous report as it was rather than half a new one.
"""

from __future__ import annotations

import base64
import platform
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Iterable

from odelab import __version__
from odelab.exceptions import InputError
from odelab.fileio import atomic_write

__all__ = ["FORMATS", "Figure", "ReportResult", "build_report"]

FORMATS = ("html", "md")
HTML_NAME = "index.html"
MARKDOWN_NAME = "report.md"
FIGURES_DIR = "figures"
# Per-step tables: the HTML folds them away, so it can hold far more rows than the Markdown.
HTML_STEP_ROWS = 200
MD_STEP_ROWS = 40
# A printed per-step table longer than this keeps its first and last rows and its maxima.
PRINT_STEP_ROWS = 20


@dataclass(eq=False)
class Figure:
    """A drawn figure: a plot's PNG bytes, or a Graphviz drawing's SVG, embedded in the HTML and
    written for the Markdown.

    A plot's bytes are filled in once every figure of the report is known (:class:`_Drawing`),
    so that they can be drawn together, across the cores."""

    name: str
    caption: str
    alt: str
    png: bytes
    svg: bytes | None = None  # a drawing by Graphviz: shown instead of ``png``

    @property
    def data(self) -> bytes:
        return self.svg if self.svg is not None else self.png

    @property
    def path(self) -> str:
        """Where the Markdown report links it, relative to the report folder."""
        return f"{FIGURES_DIR}/{self.name}.{'svg' if self.svg is not None else 'png'}"

    @property
    def data_uri(self) -> str:
        mime = "image/svg+xml" if self.svg is not None else "image/png"
        return f"data:{mime};base64," + base64.b64encode(self.data).decode("ascii")


@dataclass(frozen=True)
class ReportResult:
    """What :func:`build_report` wrote, and what it had to leave out or warn about."""

    paths: tuple[Path, ...]
    warnings: tuple[str, ...]

    @property
    def html(self) -> Path | None:
        return next((p for p in self.paths if p.name == HTML_NAME), None)

    @property
    def markdown(self) -> Path | None:
        return next((p for p in self.paths if p.name == MARKDOWN_NAME), None)


def _formats(formats: Iterable[str]) -> tuple[str, ...]:
    if isinstance(formats, str):
        formats = FORMATS if formats == "both" else (formats,)
    chosen = []
    for f in formats:
        name = "md" if f in ("md", "markdown") else f
        if name not in FORMATS:
            raise InputError(f"`formats` has {f!r}; choose html, md or both.", key="formats")
        if name not in chosen:
            chosen.append(name)
    if not chosen:
        raise InputError("`formats` is empty; choose html, md or both.", key="formats")
    return tuple(chosen)


class _Drawing:
    """The report's figures: named as they are asked for, drawn all at once by :meth:`finish`."""

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = jobs
        self.taken: set[str] = set()
        self.pending: list[tuple[object, Figure]] = []

    def __call__(self, spec) -> Figure | None:
        if spec is None:
            return None
        name, i = spec.name, 2
        while name in self.taken:
            name, i = f"{spec.name}-{i}", i + 1
        self.taken.add(name)
        figure = Figure(name=name, caption=spec.caption, alt=spec.alt, png=b"")
        self.pending.append((spec, figure))
        return figure

    def finish(self) -> None:
        """Every figure asked for, from the cache or drawn (in parallel when there are many)."""
        from odelab.report.drawing import render_pngs

        for (_, figure), png in zip(self.pending, render_pngs([spec for spec, _ in self.pending], jobs=self.jobs)):
            figure.png = png
        self.pending = []


def _drawn(view_dot: str, name: str, taken: set[str], caption: str, alt: str) -> tuple[Figure | None, str]:
    """A Graphviz drawing of DOT text as a report figure (its caption naming what drew it), or None and why not."""
    from odelab.report.graphviz import render_svg

    drawn, note = render_svg(view_dot)
    if drawn is None:
        return None, note
    unique, i = name, 2
    while unique in taken:
        unique, i = f"{name}-{i}", i + 1
    taken.add(unique)
    return Figure(name=unique, caption=f"{caption}; laid out by {drawn.by}.", alt=alt, png=b"", svg=drawn.svg), ""


def _draw_control(view, stem: str, draw: _Drawing) -> list[Figure]:
    """The diagram and network (by Graphviz) and the Bode plot of a section, drawn."""
    if view is None:
        return []
    drawn = []
    if view.dot is not None:
        view.diagram_figure, view.diagram_note = _drawn(
            view.dot, f"{stem}-diagram", draw.taken, "The block diagram as written in the experiment file",
            "Block diagram of the experiment.")
        drawn.append(view.diagram_figure)
    if view.network_dot is not None:
        view.network_figure, view.network_note = _drawn(
            view.network_dot, f"{stem}-network", draw.taken, "The network as written in the experiment file: nodes "
            "as circles, each element between its two nodes (the arrow points at its first node, the + side), "
            "couplings as boxes", "Drawing of the network's elements and nodes.")
        drawn.append(view.network_figure)
    view.bode_figure = draw(view.bode_figure)
    drawn.append(view.bode_figure)
    return [f for f in drawn if f is not None]


def generated_at() -> datetime:
    """The time the report's header states (local, with its zone): the one clock a build reads,
    so that tests of two builds can hold it fixed."""
    return datetime.now().astimezone()


def build_report(
    runs: Path,
    out: Path,
    *,
    formats: Iterable[str] = FORMATS,
    experiments: list[str] | None = None,
    template_dir: Path | None = None,
    jobs: int | None = None,
) -> ReportResult:
    """Write the lab report of the runs stored in ``runs`` into the folder ``out``.

    Parameters
    ----------
    runs
        The results folder written by ``odelab run`` (``runs/<experiment>/<case>/``).
    out
        The report folder: ``index.html`` (self-contained) and ``report.md`` with its PNG
        figures in ``figures/``. Created if missing; the report's own files are replaced.
    formats
        ``"html"``, ``"md"``, both (the default; also spelt ``"both"``).
    experiments
        Report only these experiments (by name); all stored ones when None.
    template_dir
        A folder of the course's own templates (``report.html.j2``, ``report.md.j2``,
        ``report.css``); the package's are used for any it does not hold.
    jobs
        Figures drawn at once, in a pool of processes (default: the cores this process may
        use; 1 draws them here). Figures found in the figure cache are not drawn.

    Returns
    -------
    ReportResult
        The files written and the warnings: runs that could not be read (skipped),
        experiments asked for but not stored, studies that could not be shown. The report
        shows them too, in its header.

    Raises
    ------
    InputError
        If ``runs`` is not a folder, a format is unknown, or a template is missing or broken.
    """
    from odelab.analysis.errors import HEADLINE_RULE
    from odelab.report.collect import collect_runs
    from odelab.report.content import build_sections
    from odelab.report.render import environments, render_template

    runs, out = Path(runs), Path(out)
    chosen = _formats(formats)
    if not runs.is_dir():
        raise InputError(f"`runs` {str(runs)!r} is not a folder; run experiments first (`odelab run "
                         f"experiments/ --runs {runs}`) or give the results folder.", key="runs")
    _check_out(out)  # before any figure is drawn
    html_env, md_env = environments(template_dir)

    from odelab.report.studies import asked_for, collect_studies, study_sections

    records, study_warnings = collect_studies(runs, experiments)
    # stored as a sweep, or as a study's records (named by its file, stored per target)
    swept = {r["experiment"] for r in records} | {asked_for(r, experiments) for r in records if experiments}
    groups, warnings = collect_runs(runs, experiments)
    warnings = [w for w in warnings if not any(f"experiment {name!r}" in w for name in swept)]
    warnings.extend(study_warnings)
    if not groups and not records and not experiments:
        warnings.append(f"{runs} holds no stored runs; run experiments with `odelab run` first")
    if experiments and not groups and not records:  # never overwrite a report with an empty one
        raise InputError(f"`experiments`: no stored runs of {', '.join(map(repr, experiments))} in {runs}; run "
                         f"them first (`odelab run FILE --runs {runs}`), or check the names. The report in {out} "
                         "was left as it was.", key="experiments")
    sections, more = build_sections(groups)
    warnings.extend(more)
    studies, more = study_sections(records, {"summary", "header", "problems", "contents", "failed", "provenance",
                                             "settings", *(s.anchor for s in sections)})
    warnings.extend(more)

    draw = _Drawing(jobs)
    figures: list[Figure] = []
    for section in sections:
        section.solution_figure = draw(section.solution_figure)
        section.solution_parts = [draw(spec) for spec in section.solution_parts]
        section.error_figure = draw(section.error_figure)
        section.error_parts = [draw(spec) for spec in section.error_parts]
        for view in section.linearisations:
            view.figures = [draw(spec) for spec in view.figures]
        if section.stiffness is not None:
            section.stiffness.figure = draw(section.stiffness.figure)
            if section.stiffness.figure is not None:
                figures.append(section.stiffness.figure)
        figures.extend(_draw_control(section.control, section.anchor, draw))
        if section.fit is not None:
            section.fit.figures = [draw(spec) for spec in section.fit.figures]
            figures.extend(f for f in section.fit.figures if f is not None)
        figures.extend(f for f in (section.solution_figure, *section.solution_parts, section.error_figure,
                                   *section.error_parts) if f is not None)
        figures.extend(f for view in section.linearisations for f in view.figures)
    for study in studies:
        study.figures = [draw(spec) for spec in study.figures]
        figures.extend(f for f in study.figures if f is not None)
    draw.finish()

    cases = [case for section in sections for case in section.cases]
    context = {
        "report": {
            "title": "odelab lab report",
            "generated": generated_at().strftime("%Y-%m-%d %H:%M %Z"),
            "odelab_version": __version__,
            "python_version": platform.python_version(),
            "runs": str(runs),
            "experiments": len(sections),
            "cases": len(cases),
            "failed": [(section, case) for section in sections for case in section.cases if not case.ok and not case.expected],
            "warnings": list(warnings),
            "html_step_rows": HTML_STEP_ROWS,
            "md_step_rows": MD_STEP_ROWS,
            "print_rows": PRINT_STEP_ROWS,
            "headline_rule": HEADLINE_RULE,
            "estimated": any(case.run.estimate for case in cases),  # the Est. error column has a number
            "unreliable": any(case.unreliable for case in cases),  # a status says ok?
        },
        "sections": sections,
        "studies": studies,
    }
    texts = {}
    if "html" in chosen:
        texts[HTML_NAME] = render_template(html_env, "report.html.j2", context)
    if "md" in chosen:
        texts[MARKDOWN_NAME] = render_template(md_env, "report.md.j2", context)

    written: list[Path] = []
    files = [(out / figure.path, figure.data) for figure in figures] if "md" in chosen else []
    files += [(out / name, text) for name, text in texts.items()]  # the figures first, so the Markdown
    for path, data in files:                                          # never links a file not yet there
        try:
            atomic_write(path, data)
        except OSError as exc:  # a full disk, a read-only folder, a file where a folder should be
            raise InputError(f"`out`: cannot write {path}: {exc.strerror or exc}; free some space or give "
                             "another folder with --out (each report file is replaced whole or not at all).",
                             key="out") from None
        written.append(path)
    if "md" in chosen:
        _remove_stale_figures(out, {figure.path for figure in figures})
    from odelab.cachedir import take_notes

    warnings.extend(take_notes())  # a cache folder not used, cached figures or templates made again
    return ReportResult(paths=tuple(written), warnings=tuple(warnings))


def _remove_stale_figures(out: Path, current: set[str]) -> None:
    """Figures of an earlier report that this one no longer shows: removed, so figures/ matches report.md."""
    folder = out / FIGURES_DIR
    if not folder.is_dir():
        return
    for path in [*folder.glob("*.png"), *folder.glob("*.svg")]:
        if f"{FIGURES_DIR}/{path.name}" not in current and path.is_file() and not path.is_symlink():
            try:
                path.unlink()
            except OSError:  # a read-only leftover does no harm: the report does not link it
                pass


def _check_out(out: Path) -> None:
    """The report folder: a folder, or a path where one can be made (a clear message, not a traceback)."""
    for part in (out, *out.parents):
        if part.exists() or part.is_symlink():
            if not part.is_dir():
                what = "is" if part == out else f"is inside {str(part)!r}, which is"
                raise InputError(f"`out` {str(out)!r} {what} a file, not a folder; give a folder for the report "
                                 "(it is created if missing), e.g. --out report.", key="out")
            return
