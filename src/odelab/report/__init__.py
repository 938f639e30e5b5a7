"""Lab reports from stored runs: one self-contained HTML page and a Markdown report.

>>> from pathlib import Path
>>> from odelab.report import build_report
>>> result = build_report(Path("runs"), Path("report"))      # doctest: +SKIP
>>> result.paths, result.warnings                             # doctest: +SKIP

The package reads the results store (:mod:`odelab.store.results`), lays out each
experiment's content (:mod:`~odelab.report.content`), draws the figures with matplotlib's Agg
backend (:mod:`~odelab.report.plots`) and renders Jinja2 templates kept as files in
``odelab/report/templates`` (:mod:`~odelab.report.render`).
"""

from odelab.report.build import FORMATS, ReportResult, build_report

__all__ = ["FORMATS", "ReportResult", "build_report"]
