"""The README's two set-up lines are the project's promises: keep .ci/run in step with them."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def setup_lines() -> list[str]:
    text = (ROOT / "README.md").read_text()
    block = text.split("```sh\n", 1)[1].split("```", 1)[0]
    return [line for line in block.splitlines() if line.strip()]


def test_readme_starts_with_exactly_two_setup_lines():
    text = (ROOT / "README.md").read_text()
    assert text.index("```sh") < 20  # right under the title
    assert len(setup_lines()) == 2


def test_ci_runs_the_readme_test_line_verbatim():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert setup_lines()[1] in ci
