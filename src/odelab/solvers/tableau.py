"""Butcher tableaux of the explicit Runge-Kutta methods, held as data.

Every method odelab integrates itself is one of these constants plus a registry entry: the
one stepping engine (:mod:`odelab.solvers.engine`) reads the arrays, it never special-cases
a method. A tableau checks its own invariants when it is built (row sums, consistency,
the order conditions up to its order, the error weights and the continuous extension), so
a typo in a coefficient fails at import, not in a user's results.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction as Fr

import numpy as np

__all__ = [
    "ButcherTableau",
    "BS23",
    "DP54",
    "EULER",
    "HEUN",
    "MIDPOINT",
    "RALSTON",
    "KUTTA3",
    "RK4",
]

_TOL = 1e-14


def _array(rows) -> np.ndarray:
    out = np.array([[float(x) for x in row] for row in rows]) if np.ndim(rows[0]) else np.array([float(x) for x in rows])
    out.setflags(write=False)
    return out


def _order_conditions(A: np.ndarray, b: np.ndarray, c: np.ndarray) -> list[tuple[int, float, float]]:
    """(order, value, required) for the Runge-Kutta order conditions up to order 5.

    One condition per rooted tree (Butcher, *Numerical Methods for ODEs*, 3rd ed., 2016,
    Table 315(I)): 1, 1, 2, 4 and 9 conditions for orders 1 to 5.
    """
    Ac = A @ c
    c2, c3 = c**2, c**3
    rows = [
        (1, b.sum(), 1.0),
        (2, b @ c, 1 / 2),
        (3, b @ c2, 1 / 3),
        (3, b @ Ac, 1 / 6),
        (4, b @ c3, 1 / 4),
        (4, b @ (c * Ac), 1 / 8),
        (4, b @ (A @ c2), 1 / 12),
        (4, b @ (A @ Ac), 1 / 24),
        (5, b @ c**4, 1 / 5),
        (5, b @ (c2 * Ac), 1 / 10),
        (5, b @ (c * (A @ c2)), 1 / 15),
        (5, b @ (c * (A @ Ac)), 1 / 30),
        (5, b @ (Ac**2), 1 / 20),
        (5, b @ (A @ c3), 1 / 20),
        (5, b @ (A @ (c * Ac)), 1 / 40),
        (5, b @ (A @ (A @ c2)), 1 / 60),
        (5, b @ (A @ (A @ Ac)), 1 / 120),
    ]
    return rows


@dataclass(frozen=True, eq=False)
class ButcherTableau:
    """An explicit Runge-Kutta method as data.

    Parameters
    ----------
    name
        Short name, e.g. ``"Bogacki-Shampine 3(2)"``.
    c, A, b
        Nodes (s,), strictly lower-triangular stage matrix (s, s), weights (s,) of the
        propagated solution.
    order
        Order of the propagated solution.
    error_weights
        ``E`` such that the local error estimate is ``h * sum_j E_j k_j`` (the difference of
        the two embedded solutions); ``None`` for a fixed-step method.
    error_order
        Order of the embedded (lower) solution; the controller's exponent is 1/(error_order + 1).
    dense
        Continuous extension, shape (s, q): the interpolant at ``s`` in [0, 1] is
        ``y + h * sum_j k_j * sum_m dense[j, m] * s**(m+1)``; ``None`` if the method has none.
    dense_order
        Order of the continuous extension.
    fsal
        First Same As Last: the last stage is ``f(t + h, y_new)`` and serves as the next
        step's first stage.
    reference
        Where the coefficients come from.
    """

    name: str
    c: np.ndarray
    A: np.ndarray
    b: np.ndarray
    order: int
    error_weights: np.ndarray | None = None
    error_order: int | None = None
    dense: np.ndarray | None = None
    dense_order: int | None = None
    fsal: bool = False
    reference: str = ""
    stages: int = field(init=False)

    def __post_init__(self) -> None:
        s = self.c.size
        object.__setattr__(self, "stages", s)
        problems = []
        if self.A.shape != (s, s) or self.b.shape != (s,):
            problems.append(f"shapes c {self.c.shape}, A {self.A.shape}, b {self.b.shape} disagree")
        elif np.any(np.triu(self.A) != 0):
            problems.append("A is not strictly lower triangular (the method would be implicit)")
        else:
            row_sums = self.A.sum(axis=1)
            if not np.allclose(row_sums, self.c, rtol=0, atol=_TOL):
                problems.append(f"row sums of A {row_sums} differ from the nodes c {self.c}")
            if not 1 <= self.order <= 5:
                problems.append(f"order {self.order} is outside the checked range 1..5")
            for p, value, required in _order_conditions(self.A, self.b, self.c):
                if p <= self.order and abs(value - required) > _TOL:
                    problems.append(f"order-{p} condition gives {value!r}, needs {required!r}")
        if self.error_weights is not None:
            if self.error_weights.shape != (s,):
                problems.append("error_weights must have one entry per stage")
            elif abs(self.error_weights.sum()) > _TOL:
                problems.append("error weights must sum to 0 (both embedded solutions are consistent)")
            if self.error_order is None or self.error_order >= self.order:
                problems.append("an embedded pair needs error_order < order")
        if self.fsal and (self.c[-1] != 1.0 or not np.array_equal(self.A[-1], self.b)):
            problems.append("FSAL needs c[-1] == 1 and the last row of A equal to b")
        if self.dense is not None:
            if self.dense.shape[0] != s:
                problems.append("dense must have one row per stage")
            elif not np.allclose(self.dense.sum(axis=1), self.b, rtol=0, atol=_TOL):
                problems.append("the continuous extension at s = 1 must equal the step's solution b")
        if problems:
            raise ValueError(f"invalid Butcher tableau {self.name!r}: " + "; ".join(problems))


def _tableau(name, c, A, b, order, **kw) -> ButcherTableau:
    for key in ("error_weights", "dense"):
        if kw.get(key) is not None:
            kw[key] = _array(kw[key])
    return ButcherTableau(name=name, c=_array(c), A=_array(A), b=_array(b), order=order, **kw)


# --- embedded pairs used by ode23 / ode45 ------------------------------------------------

BS23 = _tableau(
    "Bogacki-Shampine 3(2)",
    c=[0, Fr(1, 2), Fr(3, 4), 1],
    A=[
        [0, 0, 0, 0],
        [Fr(1, 2), 0, 0, 0],
        [0, Fr(3, 4), 0, 0],
        [Fr(2, 9), Fr(1, 3), Fr(4, 9), 0],
    ],
    b=[Fr(2, 9), Fr(1, 3), Fr(4, 9), 0],
    order=3,
    error_weights=[Fr(-5, 72), Fr(1, 12), Fr(1, 9), Fr(-1, 8)],
    error_order=2,
    # Cubic Hermite-type extension used by MATLAB's ntrp23 (coefficients of s, s^2, s^3).
    dense=[
        [1, Fr(-4, 3), Fr(5, 9)],
        [0, 1, Fr(-2, 3)],
        [0, Fr(4, 3), Fr(-8, 9)],
        [0, -1, 1],
    ],
    dense_order=3,
    fsal=True,
    reference="P. Bogacki, L. F. Shampine, A 3(2) pair of Runge-Kutta formulas, "
    "Appl. Math. Lett. 2(4), 1989; L. F. Shampine, M. W. Reichelt, The MATLAB ODE Suite, "
    "SIAM J. Sci. Comput. 18(1), 1997.",
)

DP54 = _tableau(
    "Dormand-Prince 5(4)",
    c=[0, Fr(1, 5), Fr(3, 10), Fr(4, 5), Fr(8, 9), 1, 1],
    A=[
        [0, 0, 0, 0, 0, 0, 0],
        [Fr(1, 5), 0, 0, 0, 0, 0, 0],
        [Fr(3, 40), Fr(9, 40), 0, 0, 0, 0, 0],
        [Fr(44, 45), Fr(-56, 15), Fr(32, 9), 0, 0, 0, 0],
        [Fr(19372, 6561), Fr(-25360, 2187), Fr(64448, 6561), Fr(-212, 729), 0, 0, 0],
        [Fr(9017, 3168), Fr(-355, 33), Fr(46732, 5247), Fr(49, 176), Fr(-5103, 18656), 0, 0],
        [Fr(35, 384), 0, Fr(500, 1113), Fr(125, 192), Fr(-2187, 6784), Fr(11, 84), 0],
    ],
    b=[Fr(35, 384), 0, Fr(500, 1113), Fr(125, 192), Fr(-2187, 6784), Fr(11, 84), 0],
    order=5,
    error_weights=[
        Fr(71, 57600), 0, Fr(-71, 16695), Fr(71, 1920), Fr(-17253, 339200), Fr(22, 525), Fr(-1, 40)
    ],
    error_order=4,
    # Quartic extension used by MATLAB's ntrp45 (coefficients of s, s^2, s^3, s^4).
    dense=[
        [1, Fr(-183, 64), Fr(37, 12), Fr(-145, 128)],
        [0, 0, 0, 0],
        [0, Fr(1500, 371), Fr(-1000, 159), Fr(1000, 371)],
        [0, Fr(-125, 32), Fr(125, 12), Fr(-375, 64)],
        [0, Fr(9477, 3392), Fr(-729, 106), Fr(25515, 6784)],
        [0, Fr(-11, 7), Fr(11, 3), Fr(-55, 28)],
        [0, Fr(3, 2), -4, Fr(5, 2)],
    ],
    dense_order=4,
    fsal=True,
    reference="J. R. Dormand, P. J. Prince, A family of embedded Runge-Kutta formulae, "
    "J. Comp. Appl. Math. 6(1), 1980; Shampine & Reichelt 1997 (continuous extension).",
)

# --- classical fixed-step methods --------------------------------------------------------
# References: E. Hairer, S. P. Norsett, G. Wanner, Solving Ordinary Differential Equations I,
# 2nd ed., Springer 1993, Sec. II.1; A. Ralston, Math. Comp. 16(80), 1962 (Ralston's method).

EULER = _tableau("Euler", c=[0], A=[[0]], b=[1], order=1, reference="Euler 1768; Hairer et al. II.1")

HEUN = _tableau(
    "Heun (improved Euler)",
    c=[0, 1],
    A=[[0, 0], [1, 0]],
    b=[Fr(1, 2), Fr(1, 2)],
    order=2,
    reference="K. Heun 1900; Hairer et al. II.1",
)

MIDPOINT = _tableau(
    "Explicit midpoint",
    c=[0, Fr(1, 2)],
    A=[[0, 0], [Fr(1, 2), 0]],
    b=[0, 1],
    order=2,
    reference="C. Runge 1895; Hairer et al. II.1",
)

RALSTON = _tableau(
    "Ralston",
    c=[0, Fr(2, 3)],
    A=[[0, 0], [Fr(2, 3), 0]],
    b=[Fr(1, 4), Fr(3, 4)],
    order=2,
    reference="A. Ralston, Runge-Kutta methods with minimum error bounds, Math. Comp. 16(80), 1962",
)

KUTTA3 = _tableau(
    "Kutta's third-order method",
    c=[0, Fr(1, 2), 1],
    A=[[0, 0, 0], [Fr(1, 2), 0, 0], [-1, 2, 0]],
    b=[Fr(1, 6), Fr(2, 3), Fr(1, 6)],
    order=3,
    reference="W. Kutta 1901; Hairer et al. II.1, Table 1.1",
)

RK4 = _tableau(
    "Classical Runge-Kutta",
    c=[0, Fr(1, 2), Fr(1, 2), 1],
    A=[[0, 0, 0, 0], [Fr(1, 2), 0, 0, 0], [0, Fr(1, 2), 0, 0], [0, 0, 1, 0]],
    b=[Fr(1, 6), Fr(1, 3), Fr(1, 3), Fr(1, 6)],
    order=4,
    reference="W. Kutta 1901; Hairer et al. II.1",
)
