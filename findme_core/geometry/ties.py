"""Near-ties decided the same on every machine.

The last bits of a BLAS result (``@``, ``np.dot``, ``np.tensordot``, ``np.linalg.*``) depend on
the kernel OpenBLAS picks for the CPU (``OPENBLAS_CORETYPE`` Haswell, SkylakeX, Sandybridge,
...), and those of numpy's ``exp``, ``log``, ``arctan2`` on its SIMD dispatch
(``NPY_DISABLE_CPU_FEATURES``). Where two candidates are equal in exact arithmetic (two paths of
one score, a symmetric room), ``argmax``, ``argsort`` or ``a > b`` then pick by that noise, and
one machine's answer is not another's. The helpers here decide such choices by a tolerance and
a deterministic key instead:

* ``argmax`` / ``argmin``: the lowest index among the values within the tolerance of the best
  (of all values, or along an axis);
* ``order``: best first, values within the tolerance of their neighbour in that order kept in
  index order (a stable sort on values with their last bits ignored);
* ``beats``: ``a > b`` by more than the tolerance (a candidate replaces the incumbent only
  when really better, so ties go to the first one considered);
* ``dot`` / ``matvec``: products that feed such a decision, as an elementwise multiply and a
  plain numpy sum (numpy's own summation, the same on every CPU), not through BLAS.

The tolerance of a comparison between ``a`` and ``b`` is ``atol + rtol * max(|a|, |b|)``; the
defaults (``RTOL``, ``ATOL``) lie far above the last-bit noise of a double and far below any
difference that means something; a caller whose values carry more rounding (sums of large
terms) passes its own. ``order`` takes a per-value ``atol`` (an array) for values of unequal
rounding. NaN never wins a comparison; an all-NaN input gives 0.
"""

from __future__ import annotations

import math

import numpy as np

#: Relative and absolute tolerance of a tie: ~4500 ulps of the larger value, 100 times the
#: differences seen between OpenBLAS kernels on the dev split's scores (~1e-14), and 100 times
#: below the smallest real difference seen between two candidates (~1e-10).
RTOL = 1e-12
ATOL = 1e-12
#: Relative tolerance of a tie between float32 values (~16 ulps of a float32): scores the
#: code computes in float32 for speed (``manhattan``).
RTOL32 = 1e-6


def _vals(values) -> np.ndarray:
    v = np.asarray(values, float).ravel()
    if v.size == 0:
        raise ValueError("no values to choose from")
    return v


def argmax(values, rtol: float = RTOL, atol: float = ATOL, axis: int | None = None):
    """Index of the largest of ``values``, the lowest index among those within
    ``atol + rtol * |max|`` of it. NaN is never chosen (0 if all are NaN).

    Args:
        axis: None: over the flattened values (an int); else along that axis (an int array,
            like ``np.argmax(values, axis)``).
    """
    if axis is None:   # the same test on a flat array, with Python floats (no array ops)
        v = _vals(values)
        best = float(np.fmax.reduce(v))   # NaN ignored; all NaN: NaN, and 0 is returned
        if best != best:
            return 0
        tol = 0.0 if math.isinf(best) else atol + rtol * abs(best)
        return int(np.argmax(v >= best - tol))
    v = np.asarray(values, float)
    if v.shape[axis] == 0:
        raise ValueError("no values to choose from")
    with np.errstate(invalid="ignore"):
        best = np.nanmax(np.where(np.isnan(v), -np.inf, v), axis=axis, keepdims=True)
        tol = np.where(np.isinf(best), 0.0, atol + rtol * np.abs(best))
        near = v >= best - tol
    return np.argmax(near, axis=axis)


def argmin(values, rtol: float = RTOL, atol: float = ATOL, axis: int | None = None):
    """Index of the smallest of ``values``, the lowest index among those within the
    tolerance of it (``argmax`` of the negated values; ``axis`` as there)."""
    return argmax(-np.asarray(values, float), rtol, atol, axis)


def order(values, descending: bool = True, rtol: float = RTOL, atol=ATOL) -> np.ndarray:
    """(N,) indices of the 1-D ``values`` sorted best first (largest first when
    ``descending``), ties in index order: consecutive sorted values within the tolerance of
    each other form a group, whose members keep their index order. NaN goes last.

    Args:
        atol: absolute tolerance, one for all or (N,) per value (two neighbours tie within
            the larger of theirs, plus ``rtol`` times the larger magnitude)."""
    v = np.asarray(values, float)
    if v.ndim != 1:
        raise ValueError(f"order takes a 1-D array, got shape {v.shape}")
    if v.size < 2:
        return np.arange(v.size)
    key = -v if descending else v
    key = np.where(np.isnan(key), np.inf, key)
    idx = np.argsort(key, kind="stable")
    s = key[idx]
    at = np.broadcast_to(np.asarray(atol, float), v.shape)[idx]
    with np.errstate(invalid="ignore"):
        tol = np.maximum(at[:-1], at[1:]) + rtol * np.maximum(np.abs(s[:-1]), np.abs(s[1:]))
        gap = np.diff(s) > tol
    gap |= np.isinf(s[1:]) & ~np.isinf(s[:-1])
    if gap.all():   # no ties: the sorted order
        return idx
    group = np.concatenate([[0], np.cumsum(gap)])
    return idx[np.lexsort((idx, group))]


def beats(a, b, rtol: float = RTOL, atol: float = ATOL):
    """``a > b`` by more than ``atol + rtol * max(|a|, |b|)`` (False where either is NaN);
    elementwise for arrays."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    with np.errstate(invalid="ignore"):
        out = a - b > atol + rtol * np.maximum(np.abs(a), np.abs(b))
    return bool(out) if out.ndim == 0 else out


def dot(a, b, axis: int = -1) -> np.ndarray:
    """Sum of ``a * b`` (broadcast) over ``axis``: a product without BLAS, the same bits on
    every CPU (an elementwise multiply, then numpy's pairwise summation)."""
    return np.sum(np.multiply(a, b), axis=axis)


def matvec(m, v) -> np.ndarray:
    """``m @ v`` for (..., K) rows ``m`` and a (K,) vector ``v`` (or (..., K) vectors),
    without BLAS (``dot`` over the last axis)."""
    return dot(m, v, axis=-1)


def matmul(a, b) -> np.ndarray:
    """``a @ b`` for (..., N, K) and (..., K, M) without BLAS: (..., N, M). For the small
    matrices (rotations, 3x3 and 4x4 systems) whose result feeds a discrete choice."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.sum(a[..., :, :, None] * b[..., None, :, :], axis=-2)
