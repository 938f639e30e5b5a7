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


def run_arguments(line: str) -> list[str]:
    """The paths the first set-up line hands to ``odelab run`` (its words up to the next ``&&``)."""
    command = line.split("/odelab run ", 1)[1].split("&&", 1)[0]
    return [word for word in command.split() if not word.startswith("-")]


def test_the_first_line_runs_every_shipped_experiment():
    """`odelab run FOLDER` runs the folder's files, not its subfolders' (a user's `odelab run .` would
    otherwise pick up runs/**/resolved.toml): the first line names every folder of shipped
    experiments, so that it runs each one and its report has them all."""
    from odelab.run.runfiles import expand_paths

    named = run_arguments(setup_lines()[0])
    folders = sorted({p.parent.relative_to(ROOT).as_posix() + "/" for p in (ROOT / "experiments").rglob("*.toml")})
    assert {"experiments/", "experiments/networks/"} <= set(folders)  # the walk finds the subfolders
    assert [f for f in folders if f not in named] == [], f"README.md's first line runs {named}"
    files, problems = expand_paths([ROOT / arg for arg in named])
    assert problems == []
    assert sorted(files) == sorted((ROOT / "experiments").rglob("*.toml"))


def test_the_first_line_check_finds_a_folder_left_out():
    """Not vacuous: the first line as it was (experiments/ alone) leaves the networks out."""
    old = ("python3 -m venv .venv && .venv/bin/pip install -q -e . && .venv/bin/odelab run experiments/ && "
           ".venv/bin/odelab report")
    assert run_arguments(old) == ["experiments/"]
    assert run_arguments(setup_lines()[0]) == ["experiments/", "experiments/networks/"]


def test_readme_lists_every_block_with_its_keys_and_defaults():
    """Issue 21: the README's table of blocks names every registered block, each of its keys,
    and whether a key is required or what its default is."""
    from odelab.systems.diagram.blocks import BLOCKS, REQUIRED

    text = (ROOT / "README.md").read_text()
    table = text.split("## Diagram blocks", 1)[1].split("\n## ", 1)[0]
    rows = {line.split("|")[1].strip().strip("`"): line.split("|")[2] for line in table.splitlines()
            if line.startswith("| `")}
    assert set(rows) == set(BLOCKS), sorted(set(rows) ^ set(BLOCKS))
    for name, cls in BLOCKS.items():
        for key, spec in cls.KEYS.items():
            if spec.default is REQUIRED:
                assert f"`{key}`" in rows[name], f"{name}: required key {key}"
            elif spec.default is None:
                assert f"`{key}` (optional)" in rows[name], f"{name}: optional key {key}"
            else:
                assert f"`{key} = " in rows[name], f"{name}: key {key} with its default"
        if isinstance(getattr(cls.KEYS.get("initial"), "default", None), float):
            assert f"`initial = {cls.KEYS['initial'].default:g}`" in rows[name], name
