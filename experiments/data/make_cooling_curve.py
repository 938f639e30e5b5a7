"""Write cooling_curve.csv: a cup of coffee cooling by Newton's law, measured with a thermometer.

T' = -k (T - T_room) with k = 0.045 1/min, T_room = 21 C, T(0) = 88 C, read every 2 minutes
for an hour with Gaussian noise of standard deviation 0.4 C (the thermometer's), from a fixed
seed. The curve is the closed form T_room + (T0 - T_room) exp(-k t), so
experiments/cooling_fit.toml estimates k and T0 from data no solver produced. Run it again to
get the same file:

    python experiments/data/make_cooling_curve.py
"""

from pathlib import Path

import numpy as np

K, T_ROOM, T0 = 0.045, 21.0, 88.0  # the true values [fit] should find (k and T0)
NOISE = 0.4  # C
SEED = 1701


def main() -> None:
    t = np.arange(0, 61, 2, dtype=float)
    rng = np.random.default_rng(SEED)
    T = T_ROOM + (T0 - T_ROOM) * np.exp(-K * t) + rng.normal(0.0, NOISE, t.size)
    out = Path(__file__).with_name("cooling_curve.csv")
    lines = [f"# written by {Path(__file__).name}: k = {K:g} 1/min, T_room = {T_ROOM:g} C, T0 = {T0:g} C, noise sd "
             f"{NOISE:g} C, seed {SEED}", "minutes,temperature"]
    lines += [f"{ti:g},{Ti:.2f}" for ti, Ti in zip(t, T)]
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
