"""Benchmark: exporting Exercise 2 as an FMU, and the cost of a step of the exported Model
Exchange FMU under FMPy against odelab's own run of the same case.

1. Export: ``odelab.fmi.export`` of experiments/exercise2.toml (its first case): generating the
   C from the checked trees, then the C compiler and the zip; best of ``--repeat``.
2. A step: the same fixed-step method on both sides, one derivative per step, so the ratio is
   the cost of the right-hand side and of the loop around it:
   - FMPy simulating the exported FMU's Model Exchange interface with its fixed-step ``Euler``
     solver (a Python loop calling the FMU's C through ctypes),
   - odelab's own run of the case with ``euler`` at the same step (the Python engine),
   - odelab stepping the same FMU as ``kind = "fmu"`` with ``euler`` (odelab's engine, the FMU's
     derivatives through FMPy),
   each timed as wall time over steps, best of ``--repeat``; printed as microseconds a step
   and the ratio to odelab's own run.

    python bench/bench_fmi.py [--repeat 3] [--steps 20000]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def best(repeat: int, fn) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--steps", type=int, default=20_000)
    args = parser.parse_args()

    import fmpy

    from odelab import fmi
    from odelab.experiment.loader import load_experiment
    from odelab.run.runner import _integrate

    experiment = load_experiment(ROOT / "experiments" / "exercise2.toml")
    case = experiment.cases[0]
    with tempfile.TemporaryDirectory() as folder:
        fmu = Path(folder) / "exercise2.fmu"
        exports = []

        def export():
            exports.append(fmi.export(experiment, fmu))

        total = best(args.repeat, export)
        compile_s = min(e.compile_seconds for e in exports)
        generate_s = min(e.generate_seconds for e in exports)
        print(f"export exercise2 (generate + compile + zip): {total * 1e3:.0f} ms "
              f"(generate {generate_s * 1e3:.1f} ms, compile {compile_s * 1e3:.0f} ms)")

        stop = float(case.problem.tspan[-1])
        h = stop / args.steps

        def fmpy_run():
            fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", solver="Euler", step_size=h, stop_time=stop,
                              output_interval=h, output=["x", "v"])

        def odelab_run():
            _integrate(case.problem, case.problem.tspan, "euler", {"h": h}, "python")

        toml = Path(folder) / "fmu.toml"
        toml.write_text(f'[system]\nkind = "fmu"\nfile = "exercise2.fmu"\n[time]\nstop = {stop}\n'
                        f'[solver]\nmethod = "euler"\nh = {h}\n')
        with fmi.allow_native():
            fmu_case = load_experiment(toml).cases[0]

        def odelab_fmu_run():
            _integrate(fmu_case.problem, fmu_case.problem.tspan, "euler", {"h": h}, "python")

        own = best(args.repeat, odelab_run) / args.steps
        under_fmpy = best(args.repeat, fmpy_run) / args.steps
        under_odelab = best(args.repeat, odelab_fmu_run) / args.steps
        print(f"a step ({args.steps} Euler steps of {h:g} s, one derivative each):")
        print(f"  odelab's own run of the case      {own * 1e6:8.2f} us   1.00x")
        print(f"  the FMU under FMPy (ModelExchange) {under_fmpy * 1e6:7.2f} us   {under_fmpy / own:.2f}x")
        print(f"  the FMU as kind = \"fmu\" in odelab  {under_odelab * 1e6:6.2f} us   {under_odelab / own:.2f}x")


if __name__ == "__main__":
    main()
