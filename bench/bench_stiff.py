"""Stiff benchmark: odelab's ode15s, ode23s, ode23t and ode23tb against SciPy's
Radau, BDF and LSODA, and GNU Octave's ode15s/ode23s when ``octave-cli`` is installed.

Problems (the issue's): van der Pol with mu = 1000 on [0, 3000] (MATLAB's defaults, rtol 1e-3,
atol 1e-6); Robertson's chemical kinetics on [0, 4e10] (rtol 1e-4, atol [1e-8, 1e-14, 1e-8]:
MATLAB's example's 1e-10 on y2 lets y2 go negative late and the solution blow up); a chain of
100 masses with stiff springs and dampers, pulled at one end (200 states, rtol 1e-4, atol 1e-7);
HIRES on [0, 321.8122] (Hairer & Wanner's test set, rtol 1e-4, atol 1e-7; its function is
``bench_compiled_stiff.hires``).
Every method gets the same Python right-hand side and finite-difference Jacobians (MATLAB's
default), so the counts compare like with like. The error is measured against a Radau solve at
rtol 1e-10: vdp at t = 3000 (a smooth stretch), Robertson at 0.4, 4, ..., 4e10 in units of the
tolerance (|err| / (rtol |ref| + atol)), the chain's last mass over t in [0, 10], HIRES at its end.

Issue 27's target for ode15s's Python path (<= 0.8x SciPy BDF's time) is printed last: the two
run alternately in one process, ``--repeat`` times each, and the ratio is of their best times
(``--ratio-only`` prints just that).

Octave's ode15s (SUNDIALS IDA) is given ``InitialSlope = f(t0, y0)``: its default, zeros, is
handed to IDA as y'(t0), inconsistent for an ODE, and IDA then fails its error test at t = 0
on van der Pol and Robertson. Octave prints its Stats instead of returning them; the script
reads the printed counts (Octave reports no Jacobian or LU counts: "-").

    python bench/bench_stiff.py [--repeat 3] [--problems vdp,robertson,hires,chain] [--ratio-only]
                                [--methods ode15s,ode23t,...] [--octave ode15s,ode23s] [--no-octave]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time

import numpy as np
from bench_compiled_stiff import hires

import odelab

MU = 1000.0
N_MASSES = 100
K, C = 1e4, 1e3  # spring and damper constants of the chain: eigenvalues down to about -4C/m


def vdp(t, y):
    return np.array([y[1], MU * (1 - y[0] ** 2) * y[1] - y[0]])


def rober(t, y):
    return np.array([-0.04 * y[0] + 1e4 * y[1] * y[2], 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2,
                     3e7 * y[1] ** 2])


def chain(t, y):
    x, v = y[:N_MASSES], y[N_MASSES:]
    xl = np.concatenate([[0.0], x[:-1]])  # wall at the left
    xr = np.concatenate([x[1:], [x[-1]]])  # free right end
    vl = np.concatenate([[0.0], v[:-1]])
    vr = np.concatenate([v[1:], [v[-1]]])
    a = K * (xl - 2 * x + xr) + C * (vl - 2 * v + vr)
    a[-1] += 1.0  # a unit force pulls the last mass
    return np.concatenate([v, a])


ROBER_T = np.array([0, 0.4, 4, 40, 400, 4e3, 4e4, 4e5, 4e6, 4e8, 4e10])
PROBLEMS = {
    "vdp": dict(fun=vdp, tspan=[0.0, 3000.0], y0=[2.0, 0.0], rtol=1e-3, atol=1e-6),
    "robertson": dict(fun=rober, tspan=ROBER_T, y0=[1.0, 0.0, 0.0], rtol=1e-4, atol=[1e-8, 1e-14, 1e-8]),
    "chain": dict(fun=chain, tspan=np.linspace(0, 10, 101), y0=np.zeros(2 * N_MASSES), rtol=1e-4, atol=1e-7),
    "hires": dict(fun=hires, tspan=[0.0, 321.8122], y0=[1.0, 0, 0, 0, 0, 0, 0, 0.0057], rtol=1e-4, atol=1e-7),
}
METHODS = ("ode15s", "ode23s", "ode23t", "ode23tb", "Radau", "BDF", "LSODA")


def reference(name):
    p = PROBLEMS[name]
    return odelab.solve(p["fun"], p["tspan"], p["y0"], method="Radau", rtol=1e-10,
                        atol=np.asarray(p["atol"]) * 1e-6)


def error(name, t, y, ref):
    p = PROBLEMS[name]
    if name in ("vdp", "hires"):
        return float(np.max(np.abs(y[-1] - ref.y[-1]) / np.abs(ref.y[-1]))), f"rel. error at t = {p['tspan'][-1]:g}"
    if name == "robertson":
        atol = np.asarray(p["atol"])
        k = min(len(y), len(ref.y))
        return float(np.max(np.abs(y[:k] - ref.y[:k]) / (p["rtol"] * np.abs(ref.y[:k]) + atol))), "err / tol"
    return float(np.max(np.abs(y[:, N_MASSES - 1] - ref.y[:, N_MASSES - 1])) / np.max(np.abs(ref.y[:, N_MASSES - 1]))), \
        "rel. error of the last mass"


def alternate(name, repeat):
    """Best times of ode15s and SciPy's BDF (through odelab.solve), run alternately."""
    p = PROBLEMS[name]
    best = {"ode15s": np.inf, "BDF": np.inf}
    for _ in range(repeat):
        for method in best:
            start = time.perf_counter()
            odelab.solve(p["fun"], p["tspan"], p["y0"], method=method, rtol=p["rtol"], atol=p["atol"])
            best[method] = min(best[method], time.perf_counter() - start)
    return best["ode15s"], best["BDF"]


def print_ratios(problems, repeat):
    print(f"\node15s / SciPy BDF, alternating, best of {repeat} each (issue 27: <= 0.8):")
    for name in problems:
        a, b = alternate(name, repeat)
        print(f"  {name:10s} ode15s {a * 1e3:8.1f} ms  BDF {b * 1e3:8.1f} ms  ratio {a / b:.2f}")


def run_odelab(name, method, repeat):
    p = PROBLEMS[name]
    best, sol = np.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        sol = odelab.solve(p["fun"], p["tspan"], p["y0"], method=method, rtol=p["rtol"], atol=p["atol"])
        best = min(best, time.perf_counter() - start)
    return sol, best


OCTAVE = r"""
mu = 1000; n = %(n)d; K = %(K)g; C = %(C)g;
function d = chainf(t, y, n, K, C)
  x = y(1:n); v = y(n+1:end);
  xl = [0; x(1:end-1)]; xr = [x(2:end); x(end)]; vl = [0; v(1:end-1)]; vr = [v(2:end); v(end)];
  a = K*(xl - 2*x + xr) + C*(vl - 2*v + vr); a(end) += 1;
  d = [v; a];
end
probs = {
  {'vdp', @(t,y) [y(2); mu*(1-y(1)^2)*y(2)-y(1)], [0 3000], [2;0], 1e-3, 1e-6},
  {'robertson', @(t,y) [-0.04*y(1)+1e4*y(2)*y(3); 0.04*y(1)-1e4*y(2)*y(3)-3e7*y(2)^2; 3e7*y(2)^2], ...
    [0 0.4 4 40 400 4e3 4e4 4e5 4e6 4e8 4e10], [1;0;0], 1e-4, [1e-8 1e-14 1e-8]},
  {'chain', @(t,y) chainf(t, y, n, K, C), linspace(0,10,101), zeros(2*n,1), 1e-4, 1e-7}};
want = {%(want)s};
for i = 1:numel(probs)
  p = probs{i};
  if ~any(strcmp(p{1}, want)), continue; end
  for s = {%(solvers)s}
    try
      opts = odeset('RelTol', p{5}, 'AbsTol', p{6}, 'Stats', 'on');
      if strcmp(s{1}, 'ode15s')
        %% Octave's ode15s hands InitialSlope (default zeros) to IDA as y'(t0): for an ODE it must be
        %% f(t0, y0), or IDA fails its error test at t = 0 ("error test failed repeatedly").
        opts = odeset(opts, 'InitialSlope', p{2}(p{3}(1), p{4}));
      end
      tic; txt = evalc('[t, y] = feval(s{1}, p{2}, p{3}, p{4}, opts);'); el = toc;
      %% Stats are printed, not returned: steps, failed attempts, evaluations, in that order
      nums = str2double(regexp(txt, '\d+', 'match'));
      st = struct('nsteps', nums(1), 'nfailed', nums(2), 'nfevals', nums(3), 'npds', -1, 'ndecomps', -1);
      if strcmp(p{1}, 'chain'), out = y(:, n); elseif strcmp(p{1}, 'vdp'), out = y(end, :); else, out = y; end
      printf('RESULT %%s %%s ok %%d %%d %%d %%d %%d %%.6g %%s\n', p{1}, s{1}, st.nsteps, st.nfailed, st.nfevals, ...
             st.npds, st.ndecomps, el, mat2str(out, 12));
    catch err
      printf('RESULT %%s %%s failed 0 0 0 0 0 0 %%s\n', p{1}, s{1}, strrep(err.message, char(10), ' '));
    end
  end
end
"""


def run_octave(problems, methods):
    exe = shutil.which("octave-cli")
    if exe is None:
        return {}
    with tempfile.TemporaryDirectory() as tmp:
        script = f"{tmp}/stiff_bench.m"
        with open(script, "w") as fh:
            fh.write(OCTAVE % {"n": N_MASSES, "K": K, "C": C, "want": ", ".join(f"'{p}'" for p in problems),
                                "solvers": ", ".join(f"'{m}'" for m in methods)})
        done = subprocess.run([exe, "-q", "--no-gui", script], capture_output=True, text=True, timeout=3000)
    out = {}
    for line in done.stdout.splitlines():
        if line.startswith("RESULT "):
            _, prob, method, status, *counts, elapsed, rest = line.split(" ", 10)
            out[(prob, method)] = (status, [int(c) for c in counts], float(elapsed), rest)
    return out


def _octave_matrix(text):
    rows = text.strip().strip("[]").split(";")
    return np.array([[float(v) for v in row.split()] for row in rows])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-octave", action="store_true")
    ap.add_argument("--problems", default=",".join(PROBLEMS), help="comma-separated: vdp,robertson,chain,hires")
    ap.add_argument("--ratio-only", action="store_true", help="only ode15s's time over BDF's, alternating")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma-separated odelab/SciPy methods")
    ap.add_argument("--octave", default="ode15s,ode23s", help="comma-separated Octave solvers")
    args = ap.parse_args()
    if args.ratio_only:
        print_ratios(args.problems.split(","), args.repeat)
        return
    rows = []
    refs = {}
    for name in args.problems.split(","):
        ref = refs[name] = reference(name)
        for method in args.methods.split(","):
            sol, best = run_odelab(name, method, args.repeat)
            err, what = error(name, sol.t, sol.y, ref)
            s = sol.stats
            rows.append((name, method, sol.status, s.nsteps, s.nfailed, s.nfevals, s.npds, s.ndecomps,
                         f"{err:.2g} ({what})", f"{best:.3f}"))
            if method == "BDF":
                from scipy.integrate import solve_ivp

                p = PROBLEMS[name]
                r = solve_ivp(p["fun"], (p["tspan"][0], p["tspan"][-1]), p["y0"], method="BDF", rtol=p["rtol"],
                              atol=p["atol"])
                rows[-1] = rows[-1][:6] + (r.njev, r.nlu) + rows[-1][8:]
            elif method in ("Radau", "LSODA"):
                from scipy.integrate import solve_ivp

                p = PROBLEMS[name]
                r = solve_ivp(p["fun"], (p["tspan"][0], p["tspan"][-1]), p["y0"], method=method, rtol=p["rtol"],
                              atol=p["atol"])
                rows[-1] = rows[-1][:6] + (r.njev, r.nlu) + rows[-1][8:]
    octave = {} if args.no_octave else run_octave(args.problems.split(","), args.octave.split(","))
    for (prob, method), (status, counts, elapsed, rest) in octave.items():
        if prob not in args.problems.split(","):
            continue
        if status != "ok":
            rows.append((prob, f"Octave {method}", "failed", "-", "-", "-", "-", "-", rest[:70], "-"))
            continue
        y = _octave_matrix(rest)
        ref = refs[prob]
        if prob == "vdp":
            err, what = error(prob, None, y.reshape(1, -1), ref)
        elif prob == "robertson":
            err, what = error(prob, None, y, ref)
        else:
            full = np.zeros((y.size, 2 * N_MASSES))
            full[:, N_MASSES - 1] = y.ravel()
            err, what = error(prob, None, full, ref)
        nsteps, nfailed, nfevals, npds, ndecomps = (c if c >= 0 else None for c in counts)
        rows.append((prob, f"Octave {method}", "success", nsteps, nfailed, nfevals, npds, ndecomps,
                     f"{err:.2g} ({what})", f"{elapsed:.3f}"))
    head = ("problem", "method", "status", "steps", "failed", "fevals", "Jacobians", "LU", "error", "time (s)")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for row in rows:
        print("| " + " | ".join("-" if v is None else (f"{v:,}" if isinstance(v, int) else str(v)) for v in row) + " |")
    if "ode15s" in args.methods.split(",") and "BDF" in args.methods.split(","):
        print_ratios(args.problems.split(","), args.repeat)


if __name__ == "__main__":
    main()
