"""`odelab import` on Simulink models: exit 0 (all translated), 1 (written with gaps), 2 (refused), the table,
and the written file equal to what `odelab run` runs."""

from pathlib import Path

from typer.testing import CliRunner

from odelab.cli import app
from odelab.formats import read

CORPUS = Path(__file__).resolve().parents[2] / "assets" / "simulink"


def test_import_exit_codes_table_and_written_file(tmp_path):
    runner = CliRunner()
    ok = runner.invoke(app, ["import", str(CORPUS / "msd" / "msd.mdl"), "-o", str(tmp_path)])
    assert ok.exit_code == 0, ok.output
    assert (tmp_path / "msd.toml").read_text() == read(CORPUS / "msd" / "msd.mdl").text
    assert "b_1_m" in ok.output and "its name made an identifier" in ok.output
    gaps = runner.invoke(app, ["import", str(CORPUS / "with_gaps.slx"), "-o", str(tmp_path)])
    assert gaps.exit_code == 1 and "K_missing" in gaps.output and (tmp_path / "with_gaps.toml").exists()
    pinned = runner.invoke(app, ["import", str(CORPUS / "with_gaps.slx"), "-o", str(tmp_path / "p"), "--set",
                                 "K_missing=2"])
    assert pinned.exit_code == 1 and "K_missing = 2.0" in (tmp_path / "p" / "with_gaps.toml").read_text()
    refused = runner.invoke(app, ["import", str(CORPUS / "physical.slx"), "-o", str(tmp_path)])
    assert refused.exit_code == 2 and "physical components" in refused.output
    assert not (tmp_path / "physical.toml").exists()
