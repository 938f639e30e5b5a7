"""Running cases: references and error tables in units of the tolerance."""

from pathlib import Path


from odelab.experiment.loader import load_experiment
from odelab.run.runner import run_case, run_experiment

ROOT = Path(__file__).resolve().parents[2]


def test_exercise1_numbers():
    results = run_experiment(ROOT / "experiments" / "exercise1.toml")
    by_case = {r.case.name: r for r in results}
    assert f"{by_case['ode23'].errors['y'].max_rel:.3e}" == "1.068e-04"
    assert by_case["ode45"].stats.nfevals == 61 and by_case["ode45"].t.size == 41
    assert by_case["ode23"].reference_kind == "exact"


def test_rigid_body_against_a_high_accuracy_reference():
    (result,) = run_experiment(ROOT / "experiments" / "rigid_body.toml")
    assert result.reference_kind == "high-accuracy"
    assert (result.stats.nsteps, result.stats.nfailed, result.stats.nfevals) == (21, 0, 127)
    # Global errors of a run at rtol 1e-4 stay within a few tens of tolerance units.
    for name in ("y1", "y2", "y3"):
        assert result.errors[name].max_abs < 30 * 1e-4
    # The reference itself is far more accurate: comparing two tight solves agrees to ~1e-10.
    assert abs(result.reference["y3"][-1] - result.x[-1, 2]) < 1e-3


def test_max_steps_guard_is_applied(tmp_path):
    path = tmp_path / "vdp.toml"
    path.write_text('[parameters]\nmu = 1000\n[system]\nstates = ["x", "v"]\n[system.equations]\nx = "v"\n'
                    'v = "mu*(1 - x^2)*v - x"\n[initial]\nx = 2\nv = 0\n[time]\nstop = 3000\n')
    result = run_case(load_experiment(path).cases[0], max_steps=300)
    assert result.status == "failed" and result.stats.nsteps == 300
    assert "stiff" in result.message and "use method 'ode15s'" in result.message


def test_stiff_solvers_and_their_options_in_experiment_files(tmp_path):
    path = tmp_path / "vdp.toml"
    path.write_text('[parameters]\nmu = 1000\n[system]\nstates = ["x", "v"]\n[system.equations]\nx = "v"\n'
                    'v = "mu*(1 - x^2)*v - x"\n[initial]\nx = 2\nv = 0\n[time]\nstop = 100\n'
                    '[solver]\nmethod = "ode15s"\nMaxOrder = 2\nBDF = "on"\n[reference]\nmethod = "high-accuracy"\nsolver = "Radau"\nrtol = 1e-8\natol = 1e-10\n')
    result = run_case(load_experiment(path).cases[0])
    assert result.status == "success" and result.stats.nsteps < 600
    assert result.stats.as_dict()["npds"] == result.stats.npds >= 1
    assert result.errors["x"].max_abs < 0.05  # phase error of a relaxation oscillation at rtol 1e-3


def test_singular_mass_is_a_dae_for_ode15s(tmp_path):
    path = tmp_path / "dae.toml"
    path.write_text('[system]\nstates = ["a", "b", "c"]\n[system.equations]\na = "-0.04*a + 1e4*b*c"\n'
                    'b = "0.04*a - 1e4*b*c - 3e7*b^2"\nc = "a + b + c - 1"\n[initial]\na = 1\nb = 0\nc = 0\n'
                    '[time]\nstop = 40\n[solver]\nmethod = "ode15s"\nrtol = 1e-4\natol = [1e-8, 1e-14, 1e-8]\n'
                    'mass = [[1, 0, 0], [0, 1, 0], [0, 0, 0]]\n')
    result = run_case(load_experiment(path).cases[0])
    assert result.status == "success"
    # y(40) of Robertson (Radau at rtol 1e-13), within a few units of the tolerance
    assert abs(result.x[-1, 0] - 7.158270687194e-01) < 5 * (1e-4 * 0.716 + 1e-8)
    assert abs(result.x[-1].sum() - 1) < 1e-12  # the algebraic equation holds
    # the first evaluation and one per Newton iteration: the exact Jacobian, no finite differences (and
    # no y'' probe for the first step of a DAE)
    assert result.stats.nfevals == 1 + result.stats.nsolves
