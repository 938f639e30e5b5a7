"""Sums of stages in a fixed order, so that results do not depend on the machine's BLAS.

``numpy.dot`` and ``@`` hand a product such as ``w @ K`` ((m,) by (m, n)) to BLAS (``gemv``),
whose kernels differ by CPU: OpenBLAS's Haswell and Zen kernels fuse multiply-adds and sum in
blocks of four, its Nehalem and Sandybridge kernels do not, and each gives other last bits. A
step-size controller turns such a bit into another accepted step now and then, so MATLAB
parity, exact step counts and the compiled backend's equality with the Python one would hold on
one machine only. Every combination of stages in the explicit engine, its interpolants and
``deval`` is therefore written in one order, the one ``solvers/compiled/loops/kernels.py.txt``
spells out as loops:

* a *combination* ``sum_k w[k] K[k]`` starts at 0 and adds the terms for k = 0, 1, ... (each
  product rounded, then added: no fused multiply-add);
* a *stage* ``y + sum_k a[k] K[k]`` sums its terms for k = m-1 down to 0, then adds ``y``.

Two ways to compute them, the same bits:

* :func:`combine` and :func:`stage`: a loop of numpy ufuncs over the terms (vectorised over
  any leading axes), for everything outside the stepping loop;
* :func:`matvec` and :func:`matmul`: the products of the stiff solvers (a Jacobian times a
  slope, the backward differences' rescaling and predictor, an interpolant), in the same order
  (for m = 0, 1, ...): numpy's matmul with the vector read backwards, numpy's dot with the
  left matrix's rows read backwards (its own loops, one call each);
* :func:`backwards`: a copy of a coefficient vector read through a negative stride. BLAS takes
  positive strides only, so numpy computes a product with such an operand in its own loop,
  ``op = 0; op += a[k] * b[k]`` in index order: ``backwards(w) @ K`` (numpy's ``matmul``) and
  ``backwards(w).dot(K[None])[0]`` (``numpy.dot`` with a 3-D operand, which never goes to
  ``gemv``; half the call's cost) are :func:`combine` in one call. The engine's hot path
  uses the second (a test checks both against :func:`combine` bit for bit for many sizes, so
  a numpy that changed this would be caught).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["backwards", "combine", "matmul", "matvec", "norm", "stage"]


def backwards(w) -> np.ndarray:
    """``w`` (1-D) as a view with a negative stride: ``backwards(w) @ K`` sums in index order without BLAS."""
    w = np.asarray(w)
    out = np.empty_like(w)[::-1]
    out[...] = w
    return out


def combine(w, K) -> np.ndarray:
    """``sum_k w[..., k] * K[..., k, :]`` for k = 0, 1, ..., starting at 0: shape ``(..., n)``.

    ``w`` (..., m) and ``K`` (..., m, n) broadcast over their leading axes.
    """
    w = np.asarray(w)
    K = np.asarray(K)
    shape = np.broadcast_shapes(w.shape[:-1], K.shape[:-2]) + K.shape[-1:]
    acc = np.zeros(shape, dtype=np.result_type(w, K))
    for k in range(w.shape[-1]):
        acc += w[..., k, None] * K[..., k, :]
    return acc


def stage(y, a, K) -> np.ndarray:
    """A Runge-Kutta stage ``y + sum_k a[k] K[k]``: the terms summed for k = m-1 down to 0, then ``y``.

    ``a`` (..., m), ``K`` (..., m, n) (at least m rows: the first m are used), ``y`` (..., n).
    """
    a = np.asarray(a)
    K = np.asarray(K)
    m = a.shape[-1]
    shape = np.broadcast_shapes(a.shape[:-1], K.shape[:-2]) + K.shape[-1:]
    acc = np.zeros(shape, dtype=np.result_type(a, K, y))
    for k in range(m - 1, -1, -1):
        acc += a[..., k, None] * K[..., k, :]
    return acc + y


def norm(v) -> float:
    """The Euclidean norm ``sqrt(sum_k |v_k|^2)``, the squares summed for k = 0, 1, ... (no BLAS;
    ``numpy.linalg.norm`` calls BLAS's dot). Real or complex ``v``."""
    v = np.asarray(v).ravel()
    if np.iscomplexobj(v):
        return math.sqrt(float(backwards(v.real) @ v.real) + float(backwards(v.imag) @ v.imag))
    return math.sqrt(float(backwards(v) @ v))


def matvec(A, x) -> np.ndarray:
    """``A @ x`` for a dense A (p, m), each entry ``sum_j A[i, j] x[j]`` for j = 0, 1, ...
    starting at 0 (numpy's matmul with ``x`` read backwards runs its own loop: one call)."""
    return np.asarray(A) @ backwards(np.asarray(x))


def matmul(A, B) -> np.ndarray:
    """``A @ B`` for dense A (p, m) and B (m, q), each entry ``sum_k A[i, k] B[k, j]`` for
    k = 0, 1, ... starting at 0: ``numpy.dot`` of a copy of A whose rows run backwards in memory
    (a negative stride, which BLAS does not take) with B as a 3-D operand, so every entry is
    numpy's own sequential dot (as :func:`backwards`' engine form; matmul would copy A back to a
    contiguous array and call BLAS), in one call."""
    A = np.asarray(A)
    rows = np.empty_like(A)[:, ::-1]
    rows[...] = A
    return rows.dot(np.asarray(B)[None])[:, 0]
