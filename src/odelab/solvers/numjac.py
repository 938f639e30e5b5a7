"""MATLAB's ``numjac``: a finite-difference Jacobian with adaptive increments.

Written from Shampine & Reichelt, *The MATLAB ODE Suite*, SIAM J. Sci. Comput. 18(1), 1997,
Section 3.3, and Salane, *Adaptive routines for forming Jacobians numerically*, Sandia report
SAND86-1319 (1986), on which it rests.

Column ``j`` of ``df/dy`` at ``(t, y)`` is the forward difference ``(f(t, y + del_j e_j) -
f(t, y)) / del_j`` with the increment ``del_j = fac_j * max(|y_j|, thresh_j)`` (MATLAB's solvers
take ``thresh = AbsTol``), signed as ``f_j(t, y)`` so the perturbed point moves the way the
solution does. The factors ``fac`` start at ``sqrt(eps)`` and are **carried from one call to
the next** (the caller keeps them): after each Jacobian every column's largest difference
``Difmax`` (in the row ``Rowmax`` where it occurs) is compared with the size of ``f`` there,
``Fscale = max(|f(y + del)|, |f(y)|)`` in that row:

* ``Difmax <= eps^0.875 Fscale``: the difference may be nothing but round-off; the column is
  recomputed at once with the larger factor ``sqrt(fac_j)`` (one more evaluation) and kept if
  it is more significant (``fac' ||new||_inf >= ||old||_inf``), and ``fac_j`` is set from that
  new difference by the two rules below;
* ``Difmax <= eps^0.75 Fscale``: too few significant digits: ``fac_j`` grows 10x for next time;
* ``Difmax > eps^0.25 Fscale``: the increment is large enough for truncation error to show:
  ``fac_j`` shrinks 10x;

within ``[eps^0.78, 0.1]``. An increment that vanishes in floating point (``y_j + del_j ==
y_j``) is grown by 100x until it does not (at the cap ``0.1`` the increment is ``thresh_j``).

With ``vectorized`` the ``n`` perturbed points go to ``f`` as the columns of one ``(n, n)``
array, in one call; with a sparsity ``pattern`` (MATLAB's ``JPattern``) structurally orthogonal
columns are perturbed together (``groups``, e.g. from :func:`column_groups`), one evaluation per
group, and the result is a SciPy sparse matrix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["numjac", "NumjacResult", "column_groups", "FAC_MIN", "FAC_MAX", "FAC_START"]

EPS = float(np.finfo(float).eps)
ROUNDOFF = EPS ** 0.875  # br: a difference this small may be round-off alone
SMALL = EPS ** 0.75  # bl: a difference this small has too few digits
LARGE = EPS ** 0.25  # bu: a difference this large shows truncation error
FAC_MIN = EPS ** 0.78
FAC_MAX = 0.1
FAC_START = math.sqrt(EPS)


@dataclass
class NumjacResult:
    """``dfdy``: the Jacobian (an ndarray, or a SciPy CSC matrix with a pattern); ``fac``: the
    increment factors for the next call; ``nfevals``: evaluations of ``f`` (columns of a
    vectorized call count one each, as MATLAB counts them); ``nfcalls``: calls of ``f``."""

    dfdy: object
    fac: np.ndarray
    nfevals: int
    nfcalls: int


def column_groups(pattern) -> list[np.ndarray]:
    """Structurally orthogonal groups of columns of a sparsity pattern (greedy, column by
    column: Curtis, Powell & Reid 1974). Columns in one group share no row, so one evaluation
    of ``f`` differences them all."""
    from scipy import sparse

    csc = sparse.csc_matrix(pattern, dtype=bool)
    n = csc.shape[1]
    groups: list[list[int]] = []
    used_rows: list[set[int]] = []
    for j in range(n):
        rows = set(csc.indices[csc.indptr[j]:csc.indptr[j + 1]].tolist())
        for g, taken in zip(groups, used_rows):
            if not rows & taken:
                g.append(j)
                taken |= rows
                break
        else:
            groups.append([j])
            used_rows.append(set(rows))
    return [np.array(g, dtype=int) for g in groups]


def numjac(fun, t: float, y, fty, thresh, fac=None, *, vectorized: bool = False, pattern=None,
           groups=None) -> NumjacResult:
    """``df/dy`` at ``(t, y)`` by MATLAB's ``numjac``.

    Parameters
    ----------
    fun : callable
        ``fun(t, y)`` -> ``f`` (length ``n``); with ``vectorized``, ``fun(t, Y)`` for an
        ``(n, m)`` array returns ``(n, m)`` (one column per column of ``Y``).
    fty : array_like
        ``f(t, y)``, already evaluated.
    thresh : float or array_like
        The threshold of significance per component (positive): increments are relative to
        ``max(|y|, thresh)``. MATLAB's solvers pass ``AbsTol``.
    fac : array_like, optional
        The factors returned by the previous call (``None``: ``sqrt(eps)`` for all).
    pattern : array_like or sparse, optional
        The sparsity pattern of ``df/dy`` (nonzero where ``f_i`` depends on ``y_j``).
    groups : list of int arrays, optional
        Column groups of ``pattern`` (computed when not given; pass them to avoid recomputing).
    """
    y = np.asarray(y, dtype=float).reshape(-1)
    n = y.size
    fty = np.asarray(fty, dtype=float).reshape(n)
    thresh = np.broadcast_to(np.asarray(thresh, dtype=float), (n,))
    fac = np.full(n, FAC_START) if fac is None else np.array(fac, dtype=float).reshape(n)

    def f1(yv):
        return np.asarray(fun(t, yv), dtype=float).reshape(n)

    yscale, delta, positive = _increments(y, fty, thresh, fac)
    if pattern is None:
        diffs = _dense_differences(fun, f1, t, y, fty, delta, vectorized)
    else:
        diffs = _grouped_differences(fun, f1, t, y, fty, delta, vectorized, pattern, groups)
    retries = _adapt_factors(f1, y, fty, yscale, positive, fac, diffs)
    return NumjacResult(diffs.jacobian(), fac, diffs.nfevals + retries, diffs.nfcalls + retries)


def _increments(y, fty, thresh, fac):
    """``(yscale, delta, positive)``: the increments ``fac * max(|y|, thresh)`` signed as ``f``,
    grown (``fac`` in place) where they vanish in ``y + del``."""
    yscale = np.maximum(np.abs(y), thresh)
    delta = (y + fac * yscale) - y
    for j in np.nonzero(delta == 0)[0]:
        while True:
            if fac[j] < FAC_MAX:
                fac[j] = min(100.0 * fac[j], FAC_MAX)
                delta[j] = (y[j] + fac[j] * yscale[j]) - y[j]
                if delta[j] != 0:
                    break
            else:
                delta[j] = thresh[j]
                break
    positive = fty >= 0
    delta = np.where(positive, np.abs(delta), -np.abs(delta))  # the way the solution moves
    return yscale, delta, positive


@dataclass
class _Differences:
    """The columns' differences and, per column, the row of the largest (``rowmax``), its size
    (``difmax``) and ``|f(y + del)|`` there (``absFdel_rm``). Dense: ``J``; grouped by a
    pattern: the CSC ``values`` with ``rows`` and ``idx`` (indptr)."""

    rowmax: np.ndarray
    difmax: np.ndarray
    absFdel_rm: np.ndarray
    nfevals: int
    nfcalls: int
    J: np.ndarray | None = None
    values: np.ndarray | None = None
    rows: np.ndarray | None = None
    idx: np.ndarray | None = None

    def column(self, j):
        """Column ``j``'s stored entries (a view: writing to it changes the Jacobian)."""
        return self.J[:, j] if self.rows is None else self.values[self.idx[j]:self.idx[j + 1]]

    def jacobian(self):
        if self.rows is None:
            return self.J
        from scipy import sparse

        n = self.rowmax.size
        return sparse.csc_matrix((self.values, self.rows, self.idx), shape=(n, n))


def _dense_differences(fun, f1, t, y, fty, delta, vectorized) -> _Differences:
    """One forward difference per column (or one vectorised call)."""
    n = y.size
    cols = np.arange(n)
    if vectorized:
        Fdel = np.asarray(fun(t, y[:, None] + np.diag(delta)), dtype=float).reshape(n, n)
        nfcalls = 1
    else:
        Fdel = np.empty((n, n))
        for j in range(n):
            yd = y.copy()
            yd[j] += delta[j]
            Fdel[:, j] = f1(yd)
        nfcalls = n
    Fdiff = Fdel - fty[:, None]
    absdiff = np.abs(Fdiff)
    rowmax = np.argmax(absdiff, axis=0) if n else np.zeros(0, dtype=int)
    return _Differences(rowmax, absdiff[rowmax, cols], np.abs(Fdel[rowmax, cols]), n, nfcalls, J=Fdiff / delta)


def _grouped_differences(fun, f1, t, y, fty, delta, vectorized, pattern, groups) -> _Differences:
    """Structurally orthogonal columns of ``pattern`` perturbed together: one difference a group."""
    from scipy import sparse

    n = y.size
    cols = np.arange(n)
    S = sparse.csc_matrix(pattern, dtype=bool)
    S.eliminate_zeros()
    if groups is None:
        groups = column_groups(S)
    ng = len(groups)
    g = np.empty(n, dtype=int)
    for i, members in enumerate(groups):
        g[members] = i
    Ydel = np.repeat(y[:, None], ng, axis=1)
    Ydel[cols, g] += delta
    if vectorized:
        Fdel = np.asarray(fun(t, Ydel), dtype=float).reshape(n, ng)
        nfcalls = 1
    else:
        Fdel = np.empty((n, ng))
        for i in range(ng):
            Fdel[:, i] = f1(Ydel[:, i])
        nfcalls = ng
    rows = S.indices.astype(int)
    counts = np.diff(S.indptr)
    colidx = np.repeat(cols, counts)
    values = (Fdel[rows, g[colidx]] - fty[rows]) / delta[colidx]
    absdiff = np.abs(values * delta[colidx])
    rowmax = np.zeros(n, dtype=int)
    difmax = np.zeros(n)
    for j in np.nonzero(counts)[0]:
        lo, hi = S.indptr[j], S.indptr[j + 1]
        m = lo + int(np.argmax(absdiff[lo:hi]))
        rowmax[j] = rows[m]
        difmax[j] = absdiff[m]
    return _Differences(rowmax, difmax, np.abs(Fdel[rowmax, g]), ng, nfcalls, values=values, rows=rows,
                        idx=S.indptr)


def _adapt_factors(f1, y, fty, yscale, positive, fac, diffs: _Differences) -> int:
    """Adjust ``fac`` (in place) for the next call, retrying the columns that may be round-off
    alone with ``sqrt(fac)``; returns the evaluations the retries took."""
    rowmax, difmax, rows, idx = diffs.rowmax, diffs.difmax, diffs.rows, diffs.idx
    cols = np.arange(y.size)
    retries = 0
    absFty = np.abs(fty)
    absFty_rm = absFty[rowmax]
    check = ((diffs.absFdel_rm != 0) & (absFty_rm != 0)) | (difmax == 0)
    if not check.any():
        return retries
    Fscale = np.maximum(diffs.absFdel_rm, absFty_rm)
    tiny = difmax <= ROUNDOFF * Fscale
    for k in np.nonzero(check & tiny)[0]:
        tmpfac = min(math.sqrt(fac[k]), FAC_MAX)
        d = (y[k] + tmpfac * yscale[k]) - y[k]
        if tmpfac == fac[k] or d == 0:
            continue
        d = abs(d) if positive[k] else -abs(d)
        yd = y.copy()
        yd[k] += d
        fdel = f1(yd)
        retries += 1
        fdiff = fdel - fty
        tmp = fdiff / d
        if rows is not None:
            tmp_rows = rows[idx[k]:idx[k + 1]]
            tmp = tmp[tmp_rows]
            fdiff_k = fdiff[tmp_rows]
        else:
            tmp_rows = cols
            fdiff_k = fdiff
        if fdiff_k.size == 0:
            continue
        m = int(np.argmax(np.abs(fdiff_k)))
        rowm, difm = int(tmp_rows[m]), float(abs(fdiff_k[m]))
        old = diffs.column(k)
        if tmpfac * float(np.max(np.abs(tmp))) >= (float(np.max(np.abs(old))) if old.size else 0.0):
            old[:] = tmp  # the new difference is more significant: keep it
            fscale = max(abs(fdel[rowm]), absFty[rowm])
            if difm <= SMALL * fscale:
                fac[k] = min(10.0 * tmpfac, FAC_MAX)
            elif difm > LARGE * fscale:
                fac[k] = max(0.1 * tmpfac, FAC_MIN)
            else:
                fac[k] = tmpfac
    grow = check & ~tiny & (difmax <= SMALL * Fscale)
    fac[grow] = np.minimum(10.0 * fac[grow], FAC_MAX)
    shrink = check & (difmax > LARGE * Fscale)
    fac[shrink] = np.maximum(0.1 * fac[shrink], FAC_MIN)
    return retries
