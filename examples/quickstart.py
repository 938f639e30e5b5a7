"""The lab's Exercise 1 and MATLAB's rigid-body example with odelab's Python API."""

import numpy as np

import odelab

for stop in (np.pi, 2 * np.pi):
    for solver in (odelab.ode23, odelab.ode45):
        sol = solver(lambda t, y: np.cos(t), [0, stop], 2)
        exact = np.sin(sol.t) + 2
        rel = np.abs(exact - sol.y[:, 0]) / np.abs(exact)
        print(f"{sol.method} on [0, {stop:.4f}]: {sol.t.size:3d} points, max relative error {rel.max():.3e}, {sol.stats}")

rigid = lambda t, y: [y[1] * y[2], -y[0] * y[2], -0.51 * y[0] * y[1]]
sol = odelab.ode45(rigid, [0, 12], [0, 1, 1], RelTol=1e-4, AbsTol=[1e-4, 1e-4, 1e-5])
print(f"rigid body: {sol.t.size} points, {sol.stats}")
