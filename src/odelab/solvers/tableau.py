"""Butcher tableaux of the explicit Runge-Kutta methods, held as data.

Every method odelab integrates itself is one of these constants plus a registry entry: the
one stepping engine (:mod:`odelab.solvers.engine`) reads the arrays, it never special-cases
a method. A tableau checks its own invariants (row sums, consistency, the order conditions
up to its order, the error weights and the continuous extension): one built by a user is
checked when it is built; the shipped ones are built with ``check=False`` (the checks cost
about 35 M instructions at import, a tenth of a second of every run's start-up) and checked
by ``tests/solvers/test_tableau.py``, which calls :meth:`ButcherTableau.verify` on every
shipped tableau, so a typo in a coefficient fails the test suite, not a user's results.

The order conditions are checked for every rooted tree up to order 9 (486 trees): Butcher's
elementary weights ``b . Phi(t) = 1/gamma(t)`` (Butcher, *Numerical Methods for ODEs*, 3rd
ed., 2016, Sec. 31), and for a continuous extension ``b(s) . Phi(t) = s^|t| / gamma(t)`` for
every power of ``s`` separately. Verner's high-order pairs (``ode78``, ``ode89``) live in
:mod:`odelab.solvers.verner`.
"""

from __future__ import annotations

from dataclasses import InitVar, dataclass, field
from functools import cached_property
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

def _array(rows) -> np.ndarray:
    out = np.array([[float(x) for x in row] for row in rows]) if np.ndim(rows[0]) else np.array([float(x) for x in rows])
    out.setflags(write=False)
    return out


MAX_CHECKED_ORDER = 9


def rooted_trees(max_order: int = MAX_CHECKED_ORDER) -> list[tuple[int, ...]]:
    """Every rooted tree up to ``max_order`` nodes, each as the sorted indices of its subtrees.

    Tree 0 is the single node; a tree ``(i, j, ...)`` is a root carrying trees i, j, ... of
    this same list (which come before it). The counts per order are 1, 1, 2, 4, 9, 20, 48,
    115, 286 (OEIS A000081).
    """
    trees: list[tuple[int, ...]] = [()]
    orders = [1]
    by_order: dict[int, list[int]] = {1: [0]}
    for p in range(2, max_order + 1):
        # Graft a tree u onto the root of a smaller tree r: r's children plus u, kept sorted
        # (u not before r's last child), so every tree comes out once.
        new = []
        for r, children in enumerate(trees[:]):
            q = orders[r]
            if q >= p:
                continue
            first = children[-1] if children else 0
            new.extend((*children, u) for u in by_order[p - q] if u >= first)
        new.sort()
        by_order[p] = list(range(len(trees), len(trees) + len(new)))
        trees.extend(new)
        orders.extend([p] * len(new))
    return trees


_TREES = rooted_trees()
# How many trees have at most p nodes: 1, 2, 4, 8, 17, 37, 85, 200, 486.
_TREE_COUNTS = {p: n for p, n in zip(range(1, MAX_CHECKED_ORDER + 1), (1, 2, 4, 8, 17, 37, 85, 200, 486))}


def _tree_structure():
    """Order, density and Butcher-product split of every tree (they do not depend on A).

    A tree with children (c_1, ..., c_k) is the tree with children (c_1, ..., c_{k-1}) (its
    ``rest``, earlier in the list) with c_k grafted on the root, so that
    ``Phi(t) = Phi(rest) * (A Phi(c_k))``: one product per tree, and all trees of one order at once.
    """
    index = {children: i for i, children in enumerate(_TREES)}
    orders = np.ones(len(_TREES), dtype=int)
    gammas = np.ones(len(_TREES))
    rest = np.zeros(len(_TREES), dtype=int)
    last = np.zeros(len(_TREES), dtype=int)
    for i, children in enumerate(_TREES):
        if children:
            rest[i], last[i] = index[children[:-1]], children[-1]
            orders[i] = orders[rest[i]] + orders[last[i]]
    g = [1.0] * len(_TREES)
    o = orders.tolist()
    for i, children in enumerate(_TREES):
        if children:  # gamma(t) = |t| prod gamma(children) = |t| gamma(rest) / |rest| gamma(last)
            g[i] = o[i] * g[rest[i]] / o[rest[i]] * g[last[i]]
    gammas[:] = g
    return orders, gammas, rest, last


_ORDERS, _GAMMAS, _REST, _LAST = _tree_structure()


def _products(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``M @ v`` as elementwise products summed by numpy's own reduction (no BLAS call).

    The self-checks below run at import: their values must not depend on which BLAS kernel the
    machine picks (another summation order, fused multiply-adds), so they never call BLAS.
    """
    return (M * v).sum(axis=-1)


def _tree_data(A: np.ndarray, max_order: int = MAX_CHECKED_ORDER) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Order |t|, density gamma(t) and stage vector Phi(t) of each tree up to ``max_order``.

    The condition of tree t for weights b is ``b . Phi(t) = 1/gamma(t)``; Phi of a root
    carrying subtrees u is the product over u of ``A Phi(u)``. Returns arrays (N,), (N,), (N, s).
    Called with ``|A|`` it gives the sum of the absolute values of the terms of each Phi(t), the
    scale of its round-off.
    """
    count = _TREE_COUNTS[max_order]
    phis = np.ones((count, A.shape[0]))
    a_phis = np.empty_like(phis)
    a_phis[0] = A.sum(axis=1)
    for p in range(2, max_order + 1):
        level = slice(_TREE_COUNTS[p - 1], _TREE_COUNTS[p])
        phis[level] = phis[_REST[level]] * a_phis[_LAST[level]]
        a_phis[level] = _products(phis[level][:, None, :], A[None, :, :])
    return _ORDERS[:count], _GAMMAS[:count], phis


_EPS = float(np.finfo(float).eps)


def _roundings(orders, stages: int):
    """How many roundings (each at most eps/2 relative to its terms' size) a condition of a tree
    of each order accumulates: |t| - 1 products with A and one with b, each a sum of at most
    ``stages`` products. The bounds below allow twice that (eps per rounding), and the
    coefficients' own rounding to doubles (eps/2 each, at most |t| + 1 factors a term) fits in
    the same allowance."""
    return np.asarray(orders) * (stages + 1)


def _conditions(A: np.ndarray, weights: np.ndarray, magnitudes: np.ndarray, max_order: int, extra: int = 0):
    """The tree conditions of each row of ``weights`` (m, s): ``w . Phi(t)`` for every rooted
    tree t up to ``max_order``, ``Phi`` built from ``A``, with the round-off coefficients given as
    doubles can leave in it: eps times the number of roundings (``extra`` more for a sum over
    the columns of a continuous extension) times ``sum |w_j| |Phi|_j``, the terms' size
    (``magnitudes`` the rows' ``|w|``, ``|Phi|`` built from ``|A|``).

    Returns ``(orders (T,), gammas (T,), values (m, T), tolerances (m, T))``; what a value
    must equal depends on the weights (``1/gamma`` for a solution's, see the callers).
    """
    orders, gammas, phis = _tree_data(A, max_order)
    phi_sizes = _tree_data(np.abs(A), max_order)[2]
    values = _products(weights[:, None, :], phis[None, :, :])
    scales = _products(magnitudes[:, None, :], phi_sizes[None, :, :])
    tolerances = (_roundings(orders, A.shape[0])[None, :] + extra) * _EPS * scales
    return orders, gammas, values, tolerances


def _order_conditions(A: np.ndarray, b: np.ndarray, c: np.ndarray,
                      max_order: int = MAX_CHECKED_ORDER) -> list[tuple[int, float, float, float]]:
    """(order, value, required, tolerance) for the Runge-Kutta order conditions up to ``max_order``.

    One condition per rooted tree: ``b . Phi(t) = 1/gamma(t)``, with ``Phi`` built from ``A``
    (the row sums of ``A``, checked separately, are ``c``); ``tolerance`` as :func:`_conditions`.
    """
    orders, gammas, values, tolerances = _conditions(A, np.asarray(b)[None], np.abs(b)[None], max_order)
    return list(zip(orders.tolist(), values[0].tolist(), (1.0 / gammas).tolist(), tolerances[0].tolist()))


def _condition_ok(value, required, tolerance):
    """A condition holds when its value is within ``tolerance`` (round-off of the coefficients'
    own size, never a fixed absolute bound) of what it requires. Scalars or arrays (all of them)."""
    return bool(np.all(np.abs(np.asarray(value) - required) <= np.asarray(tolerance)))


def _sum_ok(values, required, magnitudes, terms):
    """Sums of ``terms`` doubles (row sums, the weights at s = 1) equal ``required`` to their round-off."""
    return _condition_ok(values, required, terms * _EPS * np.asarray(magnitudes))


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
    dense_basis
        ``"monomial"``: column m of ``dense`` multiplies ``s**(m+1)``; ``"chebyshev"``: column k
        multiplies ``T_k(2s - 1)`` (k = 0..q), a well-conditioned form for large coefficients.
    extra_c, extra_A
        A non-FSAL pair's interpolation stages (m of them): stage ``s+1+j`` is
        ``f(t + extra_c[j] h, y + h sum_k extra_A[j, k] K_k)`` over the s stages, the stage
        ``f(t + h, y_new)`` (index s) and the extra stages before it; ``extra_A`` has shape
        (m, s + 1 + m). ``dense`` then has s + 1 + m rows.
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
    extra_c: np.ndarray | None = None
    extra_A: np.ndarray | None = None
    dense_basis: str = "monomial"
    stages: int = field(init=False)
    check: InitVar[bool] = True  # verify() now (False: the shipped constants, which the tests verify)

    def __post_init__(self, check: bool) -> None:
        object.__setattr__(self, "stages", self.c.size)
        if check:
            self.verify()

    def verify(self) -> None:
        """Check the invariants: shapes, row sums, the order conditions (exactly the stated
        order), the embedded pair's and the continuous extension's; ``ValueError`` naming the first
        failures."""
        s = self.stages
        problems = []
        if self.A.shape != (s, s) or self.b.shape != (s,):
            problems.append(f"shapes c {self.c.shape}, A {self.A.shape}, b {self.b.shape} disagree")
        elif np.any(np.triu(self.A) != 0):
            problems.append("A is not strictly lower triangular (the method would be implicit)")
        else:
            row_sums = self.A.sum(axis=1)
            if not _sum_ok(row_sums, self.c, np.abs(self.A).sum(axis=1), s):
                problems.append(f"row sums of A {row_sums} differ from the nodes c {self.c}")
            if not 1 <= self.order <= MAX_CHECKED_ORDER:
                problems.append(f"order {self.order} is outside the checked range 1..{MAX_CHECKED_ORDER}")
            checked = min(self.order + 1, MAX_CHECKED_ORDER)
            orders, gammas, values, tolerances = _conditions(self.A, self.b[None], np.abs(self.b)[None], checked)
            values, required, tolerances = values[0], 1.0 / gammas, tolerances[0]
            ok = np.abs(values - required) <= tolerances
            failed = np.flatnonzero(~ok & (orders <= self.order))
            if failed.size:
                k = failed[0]
                problems.append(f"order-{orders[k]} condition gives {values[k]!r}, needs {required[k]!r}")
            if self.order < MAX_CHECKED_ORDER and ok[orders == self.order + 1].all():
                # The order is exactly what it says: some condition of the next order fails.
                problems.append(f"the method meets every order-{self.order + 1} condition: its order is "
                                f"higher than {self.order}")
        if self.error_weights is not None:
            if self.error_weights.shape != (s,):
                problems.append("error_weights must have one entry per stage")
            elif not _sum_ok(self.error_weights.sum(), 0.0, np.abs(self.error_weights).sum(), s):
                problems.append("error weights must sum to 0 (both embedded solutions are consistent)")
            if self.error_order is None or self.error_order >= self.order:
                problems.append("an embedded pair needs error_order < order")
            elif not problems and self.error_order >= 1:
                # The embedded solution b - E has the order the controller's exponent assumes.
                conditions = _order_conditions(self.A, self.b - self.error_weights, self.c, self.error_order)
                failed = [p for p, value, required, tol in conditions if abs(value - required) > tol]
                if failed:
                    problems.append(f"the embedded solution b - error_weights fails an order-{failed[0]} condition: "
                                    f"its order is below {self.error_order}")
        if self.fsal and (self.c[-1] != 1.0 or not np.array_equal(self.A[-1], self.b)):
            problems.append("FSAL needs c[-1] == 1 and the last row of A equal to b")
        if (self.extra_c is None) != (self.extra_A is None):
            problems.append("extra_c and extra_A go together")
        elif self.extra_c is not None:
            m = self.extra_c.size
            if self.fsal:
                problems.append("interpolation stages (extra_c, extra_A) belong to a non-FSAL pair")
            elif self.extra_A.shape != (m, s + 1 + m) or np.any(np.triu(self.extra_A[:, s + 1:]) != 0):
                problems.append(f"extra_A must be ({m}, {s + 1 + m}) and explicit (stage j uses the ones before it)")
            elif not _sum_ok(self.extra_A.sum(axis=1), self.extra_c, np.abs(self.extra_A).sum(axis=1), s + 1 + m):
                problems.append(f"row sums of extra_A {self.extra_A.sum(axis=1)} differ from extra_c {self.extra_c}")
        if self.dense_basis not in ("monomial", "chebyshev"):
            problems.append(f"dense_basis is {self.dense_basis!r}: 'monomial' or 'chebyshev'")
        if self.dense is not None and not problems:
            rows = self.full_c.size
            b_full = np.concatenate([self.b, np.zeros(rows - s)])
            if self.dense.shape[0] != rows:
                problems.append(f"dense must have one row per stage of the extended step ({rows})")
            # (judged against the round-off of the published powers-of-s coefficients, whatever the form)
            elif not _sum_ok(self.dense.sum(axis=1), b_full, self._dense_magnitudes.sum(axis=1),
                             2 * self.dense.shape[1]):
                problems.append("the continuous extension at s = 1 must equal the step's solution b")
            elif self.dense_order is not None:
                problems.extend(self._dense_order_problems())
        if problems:
            raise ValueError(f"invalid Butcher tableau {self.name!r}: " + "; ".join(problems))

    @property
    def full_c(self) -> np.ndarray:
        """Nodes of every stage the continuous extension uses (with ``f(t+h, y_new)`` and the extra stages)."""
        if self.fsal or self.dense is None:
            return self.c
        extra = self.extra_c if self.extra_c is not None else np.empty(0)
        return np.concatenate([self.c, [1.0], extra])

    @property
    def full_A(self) -> np.ndarray:
        """Stage matrix of the extended step (rows: the s stages, ``f(t+h, y_new)``, the extra stages)."""
        if self.fsal or self.dense is None:
            return self.A
        s, rows = self.stages, self.full_c.size
        full = np.zeros((rows, rows))
        full[:s, :s] = self.A
        full[s, :s] = self.b
        if self.extra_A is not None:
            full[s + 1:, :] = self.extra_A
        return full

    @cached_property
    def increment_form(self) -> dict[str, np.ndarray]:
        """The arrays acting on ``K_0`` and the increments ``K_j - K_0`` instead of the stages.

        Since the rows of ``A`` sum to ``c`` and ``b`` to 1, ``y + h sum_j a_ij K_j`` equals
        ``y + h (c_i K_0 + sum_j a_ij (K_j - K_0))``: column 0 of ``A`` becomes ``c``, entry 0 of
        ``b`` becomes 1, of the error weights 0, and row 0 of the continuous extension the
        powers' sums (1, 0, ...). Same method; in floating point the large coefficients of
        Verner's pairs multiply increments of size O(h) instead of whole stages. Keys ``A``,
        ``b``, ``error_weights``, ``dense``, ``extra_A`` (those the tableau has).
        """
        out = {}
        A = np.array(self.A)
        A[:, 0] = self.c
        A[0, 0] = 0.0
        out["A"] = A
        b = np.array(self.b)
        b[0] = 1.0
        out["b"] = b
        if self.error_weights is not None:
            E = np.array(self.error_weights)
            E[0] = 0.0
            out["error_weights"] = E
        if self.dense is not None:
            D = np.array(self.dense)
            D[0] = 0.0
            if self.dense_basis == "chebyshev":
                D[0, :2] = 0.5  # s = (T_0 + T_1(2s - 1)) / 2
            else:
                D[0, 0] = 1.0
            out["dense"] = D
        if self.extra_A is not None:
            X = np.array(self.extra_A)
            X[:, 0] = self.extra_c
            out["extra_A"] = X
        for arr in out.values():
            arr.setflags(write=False)
        return out

    @cached_property
    def _to_powers(self) -> np.ndarray | None:
        """Row k: the coefficients of s^0 .. s^(q-1) in the basis function k of ``dense``'s columns
        (None for the monomial form)."""
        if self.dense_basis == "monomial":
            return None
        q = self.dense.shape[1]
        # row k: T_k(2s - 1) in powers s^0 .. s^(q-1), by T_(k+1) = 2 (2s - 1) T_k - T_(k-1)
        to_powers = np.zeros((q, q))
        to_powers[0, 0] = 1.0
        if q > 1:
            to_powers[1, :2] = (-1.0, 2.0)
        for k in range(1, q - 1):
            shifted = np.zeros(q)
            shifted[1:] = to_powers[k, :-1]
            to_powers[k + 1] = 2.0 * (2.0 * shifted - to_powers[k]) - to_powers[k - 1]
        return to_powers  # integers, exact in doubles

    @cached_property
    def dense_powers(self) -> np.ndarray:
        """The continuous extension as coefficients of s, s^2, ... (converted from Chebyshev form)."""
        if self.dense_basis == "monomial":
            return self.dense
        # the s^0 column vanishes (checked below)
        return _products(self.dense[:, None, :], self._to_powers.T[None, :, :])[:, 1:]

    @cached_property
    def _dense_magnitudes(self) -> np.ndarray:
        """The size of the terms of each ``dense_powers`` coefficient (``|dense|`` itself for the
        monomial form): the scale of the conversion's round-off."""
        if self.dense_basis == "monomial":
            return np.abs(self.dense)
        return _products(np.abs(self.dense)[:, None, :], np.abs(self._to_powers.T)[None, :, :])[:, 1:]

    def _dense_order_problems(self) -> list[str]:
        """The continuous extension's conditions, one per tree and power of s, each to the
        round-off its terms can leave (the conversion to powers of s included)."""
        q = self.dense.shape[1]
        orders, gammas, values, tolerances = _conditions(self.full_A, self.dense_powers.T, self._dense_magnitudes.T,
                                                         self.dense_order, extra=q)
        if self.dense_basis == "chebyshev":
            at_zero = _products(self.dense, (-1.0) ** np.arange(q))
            if not _sum_ok(at_zero, 0.0, np.abs(self.dense).sum(axis=1), q):
                return ["the continuous extension must vanish at s = 0"]
        powers = np.arange(1, self.dense_powers.shape[1] + 1)
        # the power s^m of the extension carries the trees of order m, the others vanish
        required = np.where(powers[:, None] == orders[None, :], 1.0 / gammas[None, :], 0.0)  # (q, trees)
        bad = np.abs(values - required) > tolerances
        if bad.any():
            m, k = np.argwhere(bad)[0]
            return [f"the continuous extension fails an order-{orders[k]} condition (power s^{m + 1}): "
                    f"its order is below {self.dense_order}"]
        return []


def _tableau(name, c, A, b, order, **kw) -> ButcherTableau:
    for key in ("error_weights", "dense", "extra_c", "extra_A"):
        if kw.get(key) is not None:
            kw[key] = _array(kw[key])
    return ButcherTableau(name=name, c=_array(c), A=_array(A), b=_array(b), order=order, check=False, **kw)


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
