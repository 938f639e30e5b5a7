"""Write step_response.csv: the lab's mass-spring-damper (experiments/exercise2.toml's system) measured.

m x'' + b x' + k x = f with m = 1, k = 3, b = 4 and a unit step force at t = 0, "measured" every
0.1 s for 10 s with Gaussian noise of standard deviation 0.005 m on the position, from a fixed
seed. The response is the exact one (the matrix exponential of the state-space model, from
SciPy, not odelab's solvers), so experiments/msd_fit.toml estimates b and k from data that no
part of odelab produced. Run it again to get the same file:

    python experiments/data/make_step_response.py
"""

from pathlib import Path

import numpy as np
from scipy.linalg import expm

M, K, B = 1.0, 3.0, 4.0  # the true values [fit] should find
NOISE = 0.005  # m
SEED = 20261201


def step_response(t: np.ndarray) -> np.ndarray:
    """x(t) of x' = A x + B u, x(0) = 0, u = 1: [x; 1]' = [[A, B], [0, 0]] [x; 1], by expm."""
    A = np.array([[0.0, 1.0], [-K / M, -B / M]])
    Bu = np.array([0.0, 1.0 / M])
    Z = np.zeros((3, 3))
    Z[:2, :2], Z[:2, 2] = A, Bu
    return np.array([(expm(Z * ti) @ np.array([0.0, 0.0, 1.0]))[0] for ti in t])


def main() -> None:
    t = np.round(np.arange(0, 101) * 0.1, 10)
    rng = np.random.default_rng(SEED)
    x = step_response(t) + rng.normal(0.0, NOISE, t.size)
    out = Path(__file__).with_name("step_response.csv")
    lines = [f"# written by {Path(__file__).name}: m = {M:g}, k = {K:g}, b = {B:g}, noise sd {NOISE:g} m, seed {SEED}",
             "t,position"]
    lines += [f"{ti:.1f},{xi:.6f}" for ti, xi in zip(t, x)]
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
