"""Numbers that travel: the solvers' results do not depend on the machine's BLAS kernel.

numpy hands ``w @ K`` and ``w.dot(K)`` to BLAS, whose kernels (OpenBLAS picks one per CPU:
Nehalem, Sandybridge, Haswell, Zen, ...) sum in other orders and fuse multiply-adds or not, so
the last bits differ, and a step-size controller turns such a bit into another step now and
then. The engine sums its stages in one fixed order (:mod:`odelab.solvers.ordered`) without
BLAS; these tests check the order itself and run whole integrations under two kernels.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from odelab.solvers.ordered import backwards, combine, matmul, matvec, norm, stage

SIZES = [(m, n) for m in (1, 2, 3, 4, 7, 8, 9, 13, 16, 21) for n in (1, 2, 3, 4, 8, 17, 50)]


def sequential(w, K):
    acc = np.zeros(K.shape[1:])
    for k in range(w.size):
        acc = acc + w[k] * K[k]
    return acc


@pytest.mark.parametrize("m, n", SIZES)
def test_the_one_call_forms_sum_in_index_order_bit_for_bit(m, n):
    rng = np.random.default_rng(m * 100 + n)
    w = rng.standard_normal(m) * 10.0 ** rng.integers(-3, 3, m)
    K = rng.standard_normal((m, n)) * 10.0 ** rng.integers(-3, 3, (m, n))
    expected = sequential(w, K)
    assert np.array_equal(combine(w, K), expected)
    assert np.array_equal(backwards(w) @ K, expected)  # matmul's own loop (no BLAS)
    assert np.array_equal(backwards(w).dot(K[None])[0], expected)  # the engine's form
    # a stage: terms from the last down, then y; the engine's layout puts y below the stages
    y = rng.standard_normal(n)
    rows = np.vstack([K[::-1], y])
    coefficients = np.concatenate([[1.0], w])[::-1]  # [w_(m-1) .. w_0, 1], read backwards
    assert coefficients.strides[0] < 0
    assert np.array_equal(stage(y, w, K), sequential(w[::-1], K[::-1]) + y)
    assert np.array_equal(coefficients.dot(rows[None])[0], stage(y, w, K))
    assert norm(K[:, 0]) == np.sqrt(sequential(K[:, 0], K[:, 0][:, None])[0])


@pytest.mark.parametrize("m, n", SIZES)
def test_the_stiff_solvers_products_sum_in_index_order_bit_for_bit(m, n):
    rng = np.random.default_rng(m * 1000 + n)
    A = rng.standard_normal((n, m)) * 10.0 ** rng.integers(-3, 3, (n, m))
    x = rng.standard_normal(m) * 10.0 ** rng.integers(-3, 3, m)
    assert np.array_equal(matvec(A, x), sequential(x, A.T))
    B = rng.standard_normal((m, 5))
    assert np.array_equal(matmul(A, B), np.array([sequential(row, B) for row in A]))
    assert np.array_equal(matmul(A.T.copy().T, B), matmul(A, B))  # any layout of A


_CASES = r"""
import hashlib, json, sys
import numpy as np
import odelab

def digest(*arrays):
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()

def rigid(t, y):
    return np.array([y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]])

out = {}
rng = np.random.default_rng(7)
w, K = rng.standard_normal(7), rng.standard_normal((7, 3))
out["blas"] = digest(w.dot(K), w @ rng.standard_normal((7, 40)))  # a plain gemv: kernel-dependent
runs = {
    # the lab's Exercise 1 with ode45 and its rigid body (MATLAB's RelTol/AbsTol)
    "exercise1 ode45": odelab.ode45(lambda t, y: np.cos(t), [0, np.pi], 2),
    "rigid ode45 lab": odelab.ode45(rigid, [0, 12], [0, 1, 1], RelTol=1e-4, AbsTol=[1e-4, 1e-4, 1e-5]),
    "rigid ode89": odelab.ode89(rigid, [0, 120], [0, 1, 1], rtol=1e-10, atol=1e-12),
    "rigid ode78 tspan": odelab.ode78(rigid, np.linspace(0, 60, 37), [0, 1, 1], rtol=1e-9, atol=1e-12),
    "vdp ode23": odelab.ode23(lambda t, y: [y[1], 5 * (1 - y[0] ** 2) * y[1] - y[0]], [0, 40], [2, 0]),
    "bounce ode45 events": odelab.ode45(lambda t, y: [y[1], -9.81], [0, 5], [10, 0],
                                        events=lambda t, y: ([y[0]], [1], [-1])),
    "rk4": odelab.solve(rigid, [0, 12], [0, 1, 1], method="rk4", h=0.01),
    "norm control": odelab.ode45(rigid, [0, 30], [0, 1, 1], NormControl="on", rtol=1e-7),
}
# the stiff solvers (van der Pol mu = 1000, Robertson, HIRES's eight states, a damped oscillator's
# mass matrix): BLAS-free sums and, up to odelab.solvers.lu.SMALL states, an LU of their own
def vdp(t, y):
    return [y[1], 1000 * (1 - y[0] ** 2) * y[1] - y[0]]

def rober(t, y):
    return [-0.04 * y[0] + 1e4 * y[1] * y[2], 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2, 3e7 * y[1] ** 2]

for method in ("ode15s", "ode23s", "ode23t", "ode23tb"):
    runs[method + " vdp"] = odelab.solve(vdp, [0, 3000], [2, 0], method=method)
    runs[method + " robertson"] = odelab.solve(rober, [0, 0.4, 4, 40, 400, 4e3, 4e4, 4e5, 4e6, 4e8, 4e10],
                                               [1, 0, 0], method=method, rtol=1e-4, atol=[1e-8, 1e-14, 1e-8])
def hires(t, y):  # Hairer & Wanner's HIRES
    return [-1.71 * y[0] + 0.43 * y[1] + 8.32 * y[2] + 0.0007, 1.71 * y[0] - 8.75 * y[1],
            -10.03 * y[2] + 0.43 * y[3] + 0.035 * y[4], 8.32 * y[1] + 1.71 * y[2] - 1.12 * y[3],
            -1.745 * y[4] + 0.43 * y[5] + 0.43 * y[6], -280 * y[5] * y[7] + 0.69 * y[3] + 1.71 * y[4] - 0.43 * y[5]
            + 0.69 * y[6], 280 * y[5] * y[7] - 1.81 * y[6], -280 * y[5] * y[7] + 1.81 * y[6]]

for method in ("ode15s", "ode23s"):
    runs[method + " hires"] = odelab.solve(hires, [0.0, 321.8122], [1.0, 0, 0, 0, 0, 0, 0, 0.0057], method=method,
                                           rtol=1e-4, atol=1e-7)
runs["ode15s mass"] = odelab.solve(lambda t, y: [y[1], -4 * y[0] - 0.5 * y[1]], np.linspace(0, 10, 41), [1, 0],
                                   method="ode15s", mass=[[1, 0], [0, 2]], rtol=1e-6)
for name, sol in runs.items():
    s = sol.stats
    out[name] = [digest(sol.t, sol.y, sol.te, sol.ye), s.nsteps, s.nfailed, s.nfevals]
json.dump(out, sys.stdout)
"""


def _run_under(kernel):
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel, "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", _CASES], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_explicit_and_small_stiff_runs_give_the_same_bits_under_two_blas_kernels():
    nehalem, haswell = _run_under("Nehalem"), _run_under("Haswell")
    if nehalem.pop("blas") == haswell.pop("blas"):
        pytest.skip("this numpy's BLAS gives the same bits under both kernels (not OpenBLAS, or a CPU "
                    "without AVX2): nothing to tell apart")
    assert sum(name.split()[0] in ("ode15s", "ode23s", "ode23t", "ode23tb") for name in nehalem) == 11
    # the kernels differ on a plain product, and the integrations agree bit for bit anyway:
    # times, states, events and counts
    assert nehalem == haswell
