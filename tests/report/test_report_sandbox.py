"""Report templates are sandboxed: a course's --template folder cannot run code (issue 15, class 8)."""

from __future__ import annotations

import numpy as np
import pytest

from odelab.exceptions import InputError
from odelab.report import build_report
from odelab.report.render import environments, render_template

PAYLOADS = [
    "{{ cycler.__init__.__globals__.os.popen('touch {victim}').read() }}",
    "{{ joiner.__init__.__globals__['os'].system('touch {victim}') }}",
    "{{ namespace.__init__.__globals__ }}",
    "{{ ''.__class__.__mro__[1].__subclasses__() }}",
    "{{ lipsum.__globals__['os'].popen('touch {victim}') }}",
    "{{ path.write_text('owned') }}",                      # a Path reached through the context
    "{{ array.tofile('{victim}') }}",                      # a numpy array's method
    "{{ '{{0.__class__}}'.format(path) }}",                # str.format reaching attributes
    "{% set _ = report.warnings.append('x') %}",           # changing the report's data
]


@pytest.mark.parametrize("payload", PAYLOADS)
def test_a_template_cannot_run_code_or_write_files(tmp_path, payload):
    course = tmp_path / "course"
    course.mkdir()
    victim = tmp_path / "victim.txt"
    (course / "report.md.j2").write_text(payload.replace("{victim}", str(victim)))
    _, md = environments(course)
    context = {"report": {"warnings": []}, "sections": [], "path": victim, "array": np.zeros(3)}
    with pytest.raises(InputError, match=r"^template report\.md\.j2.*(unsafe|not safely callable|has no attribute|"
                                         r"cannot modify|access to attribute)"):
        render_template(md, "report.md.j2", context)
    assert not victim.exists()
    assert context["report"]["warnings"] == []


def test_what_a_template_may_do(tmp_path):
    course = tmp_path / "course"
    course.mkdir()
    (course / "report.md.j2").write_text(
        "{% set ns = namespace(n=0) %}{% for x in items %}{% set ns.n = ns.n + x %}{{ loop.cycle('a', 'b') }}"
        "{% endfor %}{{ ns.n }} {{ 'x'.upper() }} {{ d.get('k') }} {{ range(3)|list }} {{ 3.14159|num }}\n")
    _, md = environments(course)
    out = render_template(md, "report.md.j2", {"items": [1, 2, 3], "d": {"k": "v"}})
    assert out == "aba6 X v [0, 1, 2] 3.14159\n"  # the report's own filters work too


def test_the_lab_runs_cannot_be_written_through_a_course_template(lab_runs, tmp_path):
    course = tmp_path / "course"
    course.mkdir()
    (course / "report.md.j2").write_text(
        "{% for s in sections %}{% for c in s.cases %}{{ c.run.folder.joinpath('result.json').write_text('{}') }}"
        "{% endfor %}{% endfor %}\n")
    before = (lab_runs / "exercise1" / "ode23" / "result.json").read_bytes()
    with pytest.raises(InputError, match="not safely callable"):
        build_report(lab_runs, tmp_path / "out", formats="md", template_dir=course, experiments=["exercise1"])
    assert (lab_runs / "exercise1" / "ode23" / "result.json").read_bytes() == before
