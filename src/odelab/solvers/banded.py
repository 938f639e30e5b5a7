"""Banded LU for the stiff solvers' iteration matrices, when the Jacobian's structure allows it.

The Jacobian of an expression system has a structure known from its equations: ``df_i/dy_j``
can be nonzero only where equation ``i`` names state ``j`` (:func:`structural_pattern`). A
symmetric permutation of the states (reverse Cuthill-McKee, Cuthill & McKee 1969, as
``scipy.sparse.csgraph.reverse_cuthill_mckee`` computes it on ``pattern | pattern^T``) gathers
such a matrix near its diagonal; an iteration matrix ``I - c J`` permuted so is then factored
by LAPACK's banded LU with partial pivoting (``dgbtrf``, solved by ``dgbtrs``), whose cost
grows as ``n kl (kl + ku)`` instead of dense LU's ``n^3 / 3``: a chain of 100 masses (200
states) has ``kl = ku = 3`` after the permutation (101 and 100 before), and its LU takes
~5 us instead of ~290 us (one OpenBLAS thread).

:func:`plan_band` decides from the pattern alone, so the Python path
(:class:`odelab.solvers.implicit.common.Work`) and the compiled loops
(``solvers/compiled/loops/stiff.py.txt``) make the same choice and call the same LAPACK
routines on the same numbers: their steps stay equal to the bit. A system smaller than
:data:`MIN_STATES`, or whose band after the permutation is wider than :data:`MAX_BAND_FRACTION`
of its size, stays dense (dense LU is as fast there, measured in numba against
``cython_lapack``: banded is 1.3-1.7x faster at 16-24 states with a band of half the size, 1x
at 48 states with a band of 41), so small problems (Robertson, HIRES, van der Pol, every
MATLAB comparison) factor exactly as before.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Band", "MIN_STATES", "MAX_BAND_FRACTION", "plan_band", "structural_pattern"]

#: Systems with fewer states factor dense (the banded LU saves little there).
MIN_STATES = 16

#: The band (``kl + ku + 1`` after the permutation) may cover at most this fraction of the states.
MAX_BAND_FRACTION = 0.5


def structural_pattern(names: Sequence[Collection[str]], states: Sequence[str]) -> np.ndarray:
    """The (n, n) boolean pattern of ``df/dy``: entry (i, j) where equation i names state j
    (``names[i]``: the free names of equation i)."""
    index = {name: j for j, name in enumerate(states)}
    pattern = np.zeros((len(names), len(states)), dtype=bool)
    for i, free in enumerate(names):
        for name in free:
            j = index.get(name)
            if j is not None:
                pattern[i, j] = True
    return pattern


@dataclass(frozen=True, eq=False)
class Band:
    """A banded LU plan: position ``k`` of the permuted system holds state ``perm[k]``; the
    permuted matrix has ``kl`` sub- and ``ku`` superdiagonals (LAPACK's band storage then has
    ``ldab = 2 kl + ku + 1`` rows, the first ``kl`` for the fill-in of pivoting)."""

    perm: np.ndarray
    kl: int
    ku: int

    @property
    def n(self) -> int:
        return int(self.perm.size)

    @property
    def ldab(self) -> int:
        return 2 * self.kl + self.ku + 1

    def _indices(self):
        """(destination in the flat column-major band storage, source in the flat row-major
        matrix) of every entry inside the band, cached."""
        cached = self.__dict__.get("_idx")
        if cached is None:
            n, kl, ku, perm = self.n, self.kl, self.ku, self.perm
            jj, ii = [], []
            for j in range(n):
                rows = np.arange(max(0, j - ku), min(n, j + kl + 1))
                ii.append(rows)
                jj.append(np.full(rows.size, j))
            i, j = np.concatenate(ii), np.concatenate(jj)
            cached = (kl + ku + i - j) + j * self.ldab, perm[i] * n + perm[j]
            object.__setattr__(self, "_idx", cached)
        return cached

    def pack(self, matrix: np.ndarray) -> np.ndarray:
        """The permuted ``matrix`` in LAPACK's band storage, an (ldab, n) Fortran-ordered array."""
        dest, src = self._indices()
        ab = np.zeros(self.ldab * self.n)
        ab[dest] = np.asarray(matrix, dtype=float).reshape(-1)[src]
        return ab.reshape(self.n, self.ldab).T

    def factor(self, matrix: np.ndarray):
        """``dgbtrf`` of the permuted ``matrix``: (lu, piv)."""
        from scipy.linalg.lapack import dgbtrf

        lu, piv, info = dgbtrf(self.pack(matrix), self.kl, self.ku, overwrite_ab=1)
        if info < 0:  # pragma: no cover - an argument error is a bug here
            raise ValueError(f"dgbtrf: argument {-info} is invalid")
        return lu, piv  # info > 0 (an exactly zero pivot) gives inf/NaN solutions, as lu_factor's

    def solve(self, factors, rhs: np.ndarray) -> np.ndarray:
        """``matrix \\ rhs`` from :meth:`factor`'s factors (``dgbtrs`` on the permuted ``rhs``)."""
        from scipy.linalg.lapack import dgbtrs

        lu, piv = factors
        x, info = dgbtrs(lu, self.kl, self.ku, np.asarray(rhs, dtype=float)[self.perm], piv)
        if info < 0:  # pragma: no cover
            raise ValueError(f"dgbtrs: argument {-info} is invalid")
        out = np.empty_like(x)
        out[self.perm] = x
        return out


def plan_band(pattern) -> Band | None:
    """The banded plan for iteration matrices ``I - c J`` with ``J``'s structural ``pattern``
    ((n, n) booleans), or None when dense LU is the better choice (see the module's notes)."""
    pattern = np.asarray(pattern, dtype=bool)
    n = pattern.shape[0]
    if n < MIN_STATES:
        return None
    from scipy import sparse
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    with_diagonal = pattern | np.eye(n, dtype=bool)  # I - c J has its diagonal
    perm = np.asarray(reverse_cuthill_mckee(sparse.csr_matrix(with_diagonal | pattern.T), symmetric_mode=True),
                      dtype=np.int64)
    inverse = np.empty(n, dtype=np.int64)
    inverse[perm] = np.arange(n)
    rows, cols = np.nonzero(with_diagonal)
    offsets = inverse[rows] - inverse[cols]
    kl, ku = int(max(0, offsets.max())), int(max(0, -offsets.min()))
    if kl + ku + 1 > MAX_BAND_FRACTION * n:
        return None
    return Band(perm=perm, kl=kl, ku=ku)
