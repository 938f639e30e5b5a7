"""LU factorisation with partial pivoting in one fixed order, for the stiff solvers' small systems.

LAPACK's ``getrf``/``getrs`` (what ``scipy.linalg.lu_factor``/``lu_solve`` call) run on
OpenBLAS's kernels, which are chosen per CPU and round differently: with the OpenBLAS in SciPy's
wheel a 2 x 2 solve already differs in its last bit between the SkylakeX kernel and the
Nehalem/Haswell ones, and a 3 x 3 factorisation too, so a stiff solver's iterates, and now and
then its step count, depended on the machine (ode23s on van der Pol mu = 1000: 744 steps under
SkylakeX, 745 under Nehalem and Haswell). Systems of up to :data:`SMALL` states are therefore
factored here, by LAPACK's unblocked algorithm (``dgetf2``) written out in plain arithmetic:

* column j: the pivot is the first entry of largest magnitude on or below the diagonal
  (``idamax``'s rule; ``|re| + |im|`` for complex entries, as ``izamax``), its row swapped
  into place; the column below the diagonal is multiplied by the pivot's reciprocal (divided by
  the pivot where that is below the smallest normal number, as ``dgetf2``); then every entry
  of the trailing block gets ``a_ik - l_i u_k`` (the product rounded, then the difference: no
  fused multiply-add);
* a solve applies the row swaps in order, then ``x[i] -= x[j] L[i, j]`` for j = 0, 1, ...
  (unit lower triangle), then from the last row up ``x[j] /= U[j, j]`` and
  ``x[i] -= x[j] U[i, j]``.

Every operation is a single IEEE rounding in an order that does not depend on the machine, so
the factors and solutions are the same bits everywhere; the compiled loops
(``_factor`` in ``solvers/compiled/loops/stiff.py.txt``) do the same arithmetic in the same
order. Python floats are used for the arithmetic: on these sizes they cost less than numpy
calls (2 x 2: 1.3 us a factorisation, 1.1 us a solve; 8 x 8: 13 and 5 us; 12 x 12: 33 and 9 us,
against about 0.4 us for LAPACK's getrf or getrs called directly), which a stiff step's
evaluations of the right-hand side mostly outweigh. Larger systems keep LAPACK (dense or
banded), whose last bits remain the machine's (docs/portability.md).
"""

from __future__ import annotations

import numpy as np

__all__ = ["SMALL", "factor", "solve"]

#: Systems of up to this many states are factored here; larger ones by LAPACK.
SMALL = 12
_SFMIN = float(np.finfo(float).tiny)


def _ieee_divide(a, d):
    """``a / 0`` as IEEE arithmetic gives it (inf or nan, as LAPACK's solve with a zero pivot),
    where Python's division raises."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return (np.complex128(a) if isinstance(a, complex) or isinstance(d, complex) else np.float64(a)) / d


def _magnitude(complex_entries: bool):
    return (lambda z: abs(z.real) + abs(z.imag)) if complex_entries else abs


def factor(matrix: np.ndarray):
    """The LU factors of a square ``matrix`` (real or complex): ``(rows, pivots)``, ``rows`` the
    combined unit-lower and upper factors as a list of row lists, ``pivots[j]`` the row swapped
    with row j at step j. A zero pivot is kept (the solve then gives inf or nan, as LAPACK's
    ``info > 0`` leaves it to the caller: Newton fails and says so)."""
    matrix = np.asarray(matrix)
    rows = matrix.tolist()
    n = len(rows)
    size = _magnitude(np.iscomplexobj(matrix))
    pivots = [0] * n
    for j in range(n):
        p, biggest = j, size(rows[j][j])
        for i in range(j + 1, n):
            m = size(rows[i][j])
            if m > biggest:  # idamax: the first largest (a NaN never wins)
                p, biggest = i, m
        pivots[j] = p
        if p != j:
            rows[j], rows[p] = rows[p], rows[j]
        top = rows[j]
        d = top[j]
        if d == 0:
            continue
        reciprocal = 1.0 / d if abs(d) >= _SFMIN else None
        for i in range(j + 1, n):
            row = rows[i]
            li = row[j] * reciprocal if reciprocal is not None else row[j] / d
            row[j] = li
            if li != 0:
                for k in range(j + 1, n):
                    row[k] -= li * top[k]
    return rows, pivots


def solve(factors, rhs: np.ndarray) -> np.ndarray:
    """``matrix \\ rhs`` (a vector) with the factors of :func:`factor`."""
    rows, pivots = factors
    x = np.asarray(rhs).tolist()
    n = len(x)
    for j in range(n):
        p = pivots[j]
        if p != j:
            x[j], x[p] = x[p], x[j]
    for j in range(n - 1):
        xj = x[j]
        if xj != 0:
            for i in range(j + 1, n):
                x[i] -= xj * rows[i][j]
    for j in range(n - 1, -1, -1):
        d = rows[j][j]
        xj = x[j] = x[j] / d if d != 0 else _ieee_divide(x[j], d)
        if xj != 0:
            for i in range(j):
                x[i] -= xj * rows[i][j]
    return np.array(x)
