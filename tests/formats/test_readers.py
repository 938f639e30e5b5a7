"""formats/: a reader per suffix, one Document shape, and an imported file with gaps refused by the loader."""

import sys
import types

import pytest

from odelab import formats
from odelab.exceptions import ExperimentError
from odelab.experiment.loader import load_experiment
from odelab.formats.base import GAP, IGNORED, Document, Note
from odelab.formats.toml import parse_toml

DECAY = '[system]\nstates = ["x"]\n[system.equations]\nx = "-x"\n[initial]\nx = 1\n[time]\nstop = 1\n'


def test_toml_is_read_by_suffix_and_unknown_suffixes_as_toml(tmp_path):
    for name in ("decay.toml", "decay.txt"):
        path = tmp_path / name
        path.write_text(DECAY)
        doc = formats.read(path)
        assert doc.format == "toml" and not doc.imported and doc.data["system"]["states"] == ["x"]
        assert doc.raw == DECAY.encode()
    assert formats.is_experiment_file(tmp_path / "a.toml") and not formats.is_experiment_file(tmp_path / "a.txt")


@pytest.fixture
def fake_importer():
    """A toy importer: every file imports as DECAY, with a gap when the file says `gap`."""
    module = types.ModuleType("odelab_test_fake_importer")

    def read(path, options):
        raw = path.read_bytes()
        notes = (Note("line 1", "plot(t, y)", IGNORED, "plotting: the report draws every state"),)
        if b"gap" in raw:
            notes += (Note("line 2", "while x > 0", GAP, "a loop with a data-dependent bound: write an [events] table"),)
        return Document(path=path, data=parse_toml(DECAY.encode(), str(path)), raw=raw, format="fake", text=DECAY,
                        notes=notes)

    module.read = read
    sys.modules[module.__name__] = module
    formats.READERS[".fake"] = (module.__name__, "a fake file")
    yield
    del formats.READERS[".fake"], sys.modules[module.__name__]


def test_an_imported_file_runs_and_one_with_gaps_is_refused_with_its_table(fake_importer, tmp_path):
    good = tmp_path / "good.fake"
    good.write_text("plot(t, y)")
    (case,) = load_experiment(good).cases
    assert case.problem.states == ("x",) or list(case.problem.states) == ["x"]
    bad = tmp_path / "bad.fake"
    bad.write_text("plot(t, y)\ngap")
    with pytest.raises(ExperimentError) as info:
        load_experiment(bad)
    text = str(info.value)
    assert "could not be translated completely (1 gap): line 2: while x > 0: a loop with a data-dependent bound" in text
    assert "`odelab import bad.fake`" in text and str(bad) in text
