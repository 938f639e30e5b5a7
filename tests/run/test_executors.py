"""Serial, process-pool and Dask runs give identical results, in case order."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab.cli import app
from odelab.run.executors import CaseError, run_cases
from odelab.experiment.loader import load_experiment

SWEEP = """
title = "Exercise 1 swept"
[system]
states = ["y"]
[system.equations]
y = "cos(t)"
[initial]
y = 2
[time]
stop = "pi"
[exact]
y = "sin(t) + 2"
[solver]
method = "ode45"
[sweep]
"solver.method" = ["ode23", "ode45", "rk4"]
"solver.rtol" = [1e-3, 1e-5]
"""


def _plain(results):
    out = []
    for r in results:
        assert not isinstance(r, CaseError)
        out.append((r.case.name, r.status, r.stats, r.t.tobytes(), r.x.tobytes(),
                    {n: e.as_dict() for n, e in r.errors.items()}, r.warnings))
    return out


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    path = tmp_path_factory.mktemp("sweep") / "sweep.toml"
    # rk4 takes h, not rtol: zip the methods with what each needs
    path.write_text(SWEEP.replace('"solver.rtol" = [1e-3, 1e-5]', "").replace(
        '"solver.method" = ["ode23", "ode45", "rk4"]',
        'mode = "zip"\n"solver.method" = ["ode23", "ode45", "ode23", "ode45"]\n"solver.rtol" = [1e-3, 1e-3, 1e-5, 1e-6]'))
    return load_experiment(path)


def test_pool_matches_serial_in_order(experiment):
    seen = []
    serial = list(run_cases(experiment.cases, executor="serial"))
    pooled = list(run_cases(experiment.cases, executor="process", jobs=2, on_done=lambda d, f: seen.append((d, f))))
    assert [r.case.index for r in pooled] == [0, 1, 2, 3]
    assert _plain(pooled) == _plain(serial)
    assert seen == [(1, 0), (2, 0), (3, 0), (4, 0)]


def test_dask_local_cluster_matches_serial(experiment):
    distributed = pytest.importorskip("distributed")
    serial = list(run_cases(experiment.cases, executor="serial"))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        dask = list(run_cases(experiment.cases, executor="dask", scheduler=cluster.scheduler_address))
    assert _plain(dask) == _plain(serial)


def test_cli_jobs_and_serial_store_the_same_sweep(tmp_path):
    (tmp_path / "sweep.toml").write_text(SWEEP.replace('"solver.method" = ["ode23", "ode45", "rk4"]',
                                                       '"solver.method" = ["ode23", "ode45"]'))
    runner = CliRunner()
    records = []
    for args in (["--executor", "serial"], ["--jobs", "2"]):
        runs = tmp_path / args[-1]
        result = runner.invoke(app, ["run", str(tmp_path / "sweep.toml"), "--runs", str(runs), *args])
        assert result.exit_code == 0, result.output
        record = json.loads((runs / "sweep" / "sweep.json").read_text())
        for row in record["rows"]:
            row.pop("elapsed_s")
        record.pop("created")
        records.append(record)
        assert not (runs / "sweep" / "rtol=0.001, method=ode23").exists()  # store = "summary"
        csv = (runs / "sweep" / "sweep.csv").read_text().splitlines()
        assert csv[0].startswith("case,solver.method,solver.rtol,method,status,nsteps,nfailed,nfevals,elapsed_s,y_max")
        assert len(csv) == 5 and csv[1].startswith('"method=ode23, rtol=0.001",ode23,0.001,ode23,success,11,0,34,')
    assert records[0] == records[1]
    assert [r["case"] for r in records[0]["rows"]] == ["method=ode23, rtol=0.001", "method=ode23, rtol=1e-5",
                                                       "method=ode45, rtol=0.001", "method=ode45, rtol=1e-5"]
    assert f"{records[0]['rows'][0]['max_rel']['y']:.3e}" == "1.068e-04"  # the lab sheet's ode23 number


def test_bad_executor_and_scheduler_without_dask(tmp_path):
    (tmp_path / "sweep.toml").write_text(SWEEP)
    runner = CliRunner()
    result = runner.invoke(app, ["run", str(tmp_path / "sweep.toml"), "--executor", "cluster"])
    assert result.exit_code == 2 and "`--executor` is 'cluster'; it must be one of serial, process, dask." in result.output
    result = runner.invoke(app, ["run", str(tmp_path / "sweep.toml"), "--scheduler", "tcp://x:1"])
    assert result.exit_code == 2 and "add `--executor dask`" in result.output


def test_pools_hand_out_each_experiments_cases_longest_first():
    from pathlib import Path

    from odelab.run.executors import case_cost, schedule
    from odelab.experiment.loader import load_experiments

    root = Path(__file__).resolve().parents[2] / "experiments"
    exps = load_experiments(root / "convergence.toml")
    cases = [c for e in exps for c in e.cases]
    order = schedule(cases)
    assert sorted(order) == list(range(60)) and set(order[:30]) == set(range(30))  # experiments keep their order
    first = [cases[i] for i in order[:30]]
    assert first[0].name == "method=rk4, h=0.003125" and first[-1].name == "method=euler, h=0.1"
    # a fixed-step case costs steps x stages: rk4 over [0, pi] at h = 0.003125
    assert case_cost(first[0]) == pytest.approx(4 * np.pi / 0.003125)
    assert [case_cost(c) for c in first] == sorted((case_cost(c) for c in first), reverse=True)
    # adaptive cases: tighter tolerances first
    wp = load_experiments(root / "work-precision.toml")[0].cases
    by_rtol = {}
    for i in schedule(list(wp)):
        by_rtol.setdefault(wp[i].problem.method, []).append(wp[i].problem.options["rtol"])
    assert all(r == sorted(r) for r in by_rtol.values())


SLOW_SWEEP = """
title = "van der Pol, mu = 1000, ode45 over longer and longer spans"
[parameters]
mu = 1000
[system]
states = ["x", "v"]
[system.equations]
x = "v"
v = "mu*(1 - x^2)*v - x"
[initial]
x = 2
v = 0
[solver]
method = "ode45"
max_steps = 5000000
[reference]
method = "none"
[sweep]
"time.stop" = [0.5, 3000, 1, 2]
store = "summary"
"""


def test_ctrl_c_in_a_pool_keeps_the_sweeps_finished_cases(tmp_path, monkeypatch):
    """The long case (stop = 3000, minutes on Python) runs first; Ctrl-C once the three short ones are in."""
    import concurrent.futures

    (tmp_path / "vdp.toml").write_text(SLOW_SWEEP)
    original = concurrent.futures.wait

    def wait(pending, return_when):
        if len(pending) == 1:  # only the long case is left: the user presses Ctrl-C
            raise KeyboardInterrupt
        return original(pending, return_when=return_when)

    monkeypatch.setattr(concurrent.futures, "wait", wait)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "vdp.toml"), "--runs", str(tmp_path / "runs"),
                                      "--jobs", "2", "--backend", "python"])
    assert result.exit_code == 130, result.output
    assert "interrupted: 3 of 4 cases finished and stored; the case that was running was not stored." in result.output
    record = json.loads((tmp_path / "runs" / "vdp" / "sweep.json").read_text())
    assert record["complete"] is False and record["cases_total"] == 4
    # stop = 1 and 2 finished after stop = 3000 had started (longest first): stored too, in case order
    assert [r["case"] for r in record["rows"]] == ["stop=0.5", "stop=1", "stop=2"]
    assert all(r["status"] == "success" for r in record["rows"])


def test_default_jobs_keep_small_runs_in_one_process(experiment, monkeypatch):
    """Forking a pool for four sub-millisecond cases costs more than it saves; --jobs 2 still pools."""
    from odelab.run import executors

    costs = [executors.case_cost(c) for c in experiment.cases]
    assert 0 < sum(costs) < executors.POOL_WORTHWHILE  # about evaluations: a few hundred each
    assert executors.small_work(experiment.cases)
    started = []
    real_pool = executors._run_pool
    monkeypatch.setattr(executors, "_run_pool", lambda *a: started.append(a[1]) or real_pool(*a))
    monkeypatch.setattr(executors, "default_jobs", lambda: 2)
    assert _plain(run_cases(experiment.cases, executor="process")) == _plain(run_cases(experiment.cases,
                                                                                     executor="serial"))
    assert started == []
    list(run_cases(experiment.cases, executor="process", jobs=2))
    assert started == [2]
    # the same cases at a fine fixed step are worth a pool
    fine = [c for c in experiment.cases]
    monkeypatch.setattr(executors, "case_cost", lambda case: executors.POOL_WORTHWHILE / 2)
    assert not executors.small_work(fine)
