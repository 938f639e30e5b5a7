"""One message shape for unknown keys: the valid choices of that very table, did-you-mean
(MATLAB's spellings included), a note for MATLAB and Simulink habits; and syntax errors in the
expression language's own words."""

import pytest

from odelab.exceptions import OdelabError
from odelab.experiment.loader import load_experiment

BASE = '[system]\nstates = ["x"]\ninputs = ["vin"]\n[system.equations]\nx = "vin - x"\n[time]\nstop = 1\n'


def message(tmp_path, text: str) -> str:
    path = tmp_path / "lab.toml"
    path.write_text(text)
    with pytest.raises(OdelabError) as info:
        load_experiment(path)
    return str(info.value)


def test_a_signal_key_lists_the_keys_of_its_type_with_simulinks_percentage_explained(tmp_path):
    text = message(tmp_path, BASE + '[inputs.vin]\ntype = "pulse"\nduty = 50\n')
    assert "unknown key `inputs.vin.duty`" in text
    assert "Known keys in [inputs.vin] (type 'pulse'): type, amplitude, period, width, delay." in text
    assert "percentage of the period" in text and "width = 0.5" in text


def test_a_misspelt_signal_key_gets_did_you_mean(tmp_path):
    text = message(tmp_path, BASE + '[inputs.vin]\ntype = "sine"\nfrequncy = 2\n')
    assert "Did you mean `frequency`?" in text and "amplitude, frequency, phase, bias" in text


def test_the_top_level_list_names_every_table(tmp_path):
    text = message(tmp_path, "sweeps = 1\n" + BASE + '[inputs.vin]\ntype = "step"\n')
    for table in ("case", "problem", "sweep", "study", "events", "expect"):
        assert table in text.split("Known keys in the top level:")[1]
    assert "Did you mean `sweep`?" in text


def test_stats_says_that_statistics_are_always_printed(tmp_path):
    text = message(tmp_path, BASE + '[inputs.vin]\ntype = "step"\n[solver]\nStats = "on"\n')
    assert "step statistics are always printed and stored" in text and "remove `Stats`" in text
    assert "MATLAB's odeset names (RelTol, AbsTol" in text


def test_a_matlab_spelling_with_a_typo_is_matched(tmp_path):
    text = message(tmp_path, BASE + '[inputs.vin]\ntype = "step"\n[solver]\nRelTo = 1e-4\n')
    assert "Did you mean `RelTol`?" in text


def test_a_prime_is_explained_without_pythons_words(tmp_path):
    text = message(tmp_path, '[system]\nstates = ["y"]\n[system.equations]\ny = "y\'"\n[time]\nstop = 1\n')
    assert "a quote or prime (') is not part of the expression language" in text
    assert "string literal" not in text and "detected at line" not in text


def test_validate_quotes_sweep_case_names_that_hold_commas():
    from pathlib import Path

    from typer.testing import CliRunner

    from odelab.cli import app

    path = Path(__file__).resolve().parents[2] / "experiments" / "convergence.toml"
    out = CliRunner().invoke(app, ["validate", str(path)]).output
    assert '"method=euler, h=0.1"; "method=euler, h=0.05"; ' in out
