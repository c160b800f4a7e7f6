"""Compiled NURBS evaluation kernels (numba ``@njit(cache=True)``).

Span search, B-spline basis functions with their derivatives and rational derivatives, for
one parameter (called from the compiled loop, :mod:`nurbsmotion._loop_kernel`) or a batch
(called by :meth:`nurbsmotion.nurbs.NurbsCurve.derivatives`). Any degree, any axis count.

The first call of each kernel compiles it (about a second or two); the machine code is
cached on disk next to this file (or in ``NUMBA_CACHE_DIR``), so later processes load it.

Glossary
--------
p : degree; n : number of control points; U : knot vector, shape (n + p + 1,);
Pw : homogeneous control points ``[w*P, w]``, shape (n, n_axes + 1); u : parameter;
span : index i with ``U[i] <= u < U[i+1]`` (right-sided) or ``U[i] < u <= U[i+1]``
(left-sided); ders : basis derivatives, ``ders[k, j] = N_{span-p+j, p}^(k)(u)``.

References
----------
Piegl & Tiller, *The NURBS Book*, 2nd ed., Springer 1997: A2.1 (span), A2.3 (basis
functions and derivatives), A4.2 (derivatives of a rational curve).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["find_span", "basis_derivatives", "rational_derivatives_at",
           "rational_derivatives"]


@njit(cache=True)
def find_span(n: int, p: int, U, u: float, left: bool) -> int:
    """Knot span of ``u`` (A2.1, by bisection), among the spans ``p .. n-1``.

    Right-sided (``left=False``): the largest i with ``U[i] <= u``, so that at a knot the
    span starting there is taken (and the last span at ``u = U[n]``). Left-sided: the
    smallest i with ``u <= U[i+1]``, the span ending at a knot (the first span at
    ``u = U[p]``).
    """
    lo = p
    hi = n - 1
    if left:
        while lo < hi:
            mid = (lo + hi) // 2
            if u <= U[mid + 1]:
                hi = mid
            else:
                lo = mid + 1
    else:
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if U[mid] <= u:
                lo = mid
            else:
                hi = mid - 1
    return lo


@njit(cache=True)
def basis_derivatives(span: int, u: float, p: int, n_der: int, U, ders) -> None:
    """Non-zero basis functions and their derivatives up to ``n_der`` (A2.3).

    Writes ``ders[k, j]`` for ``k = 0 .. n_der``, ``j = 0 .. p``; orders above ``p`` are 0.
    ``ders`` must have shape at least ``(n_der + 1, p + 1)``.
    """
    ndu = np.empty((p + 1, p + 1))
    left = np.empty(p + 1)
    right = np.empty(p + 1)
    a = np.empty((2, p + 1))
    ndu[0, 0] = 1.0
    for j in range(1, p + 1):
        left[j] = u - U[span + 1 - j]
        right[j] = U[span + j] - u
        saved = 0.0
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]       # lower triangle: knot differences
            temp = ndu[r, j - 1] / ndu[j, r]
            ndu[r, j] = saved + right[r + 1] * temp      # upper triangle: basis functions
            saved = left[j - r] * temp
        ndu[j, j] = saved
    for j in range(p + 1):
        ders[0, j] = ndu[j, p]
    nd = min(n_der, p)
    for r in range(p + 1):
        s1 = 0
        s2 = 1
        a[0, 0] = 1.0
        for k in range(1, nd + 1):
            d = 0.0
            rk = r - k
            pk = p - k
            if r >= k:
                a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                d = a[s2, 0] * ndu[rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                d += a[s2, j] * ndu[rk + j, pk]
            if r <= pk:
                a[s2, k] = -a[s1, k - 1] / ndu[pk + 1, r]
                d += a[s2, k] * ndu[r, pk]
            ders[k, r] = d
            s1, s2 = s2, s1
    factor = float(p)
    for k in range(1, nd + 1):
        for j in range(p + 1):
            ders[k, j] *= factor
        factor *= p - k
    for k in range(nd + 1, n_der + 1):
        for j in range(p + 1):
            ders[k, j] = 0.0


@njit(cache=True)
def _binomial(k: int, i: int) -> float:
    out = 1.0
    for m in range(1, i + 1):
        out = out * (k - i + m) / m
    return out


@njit(cache=True)
def rational_derivatives_at(U, Pw, p: int, u: float, max_order: int, left: bool, out) -> None:
    """Point and derivatives of a NURBS curve at one parameter (A2.3 + A4.2).

    Parameters
    ----------
    U : ndarray, shape (n + p + 1,)
    Pw : ndarray, shape (n, n_axes + 1)
        Homogeneous control points ``[w*P, w]``.
    p, u, max_order, left
        Degree, parameter, highest order, one-sided rule (see :func:`find_span`).
    out : ndarray, shape (>= max_order + 1, n_axes)
        Written: ``out[k]`` is ``C^(k)(u)``.
    """
    n = Pw.shape[0]
    dim = Pw.shape[1] - 1
    span = find_span(n, p, U, u, left)
    ders = np.empty((max_order + 1, p + 1))
    basis_derivatives(span, u, p, max_order, U, ders)
    hom = np.zeros((max_order + 1, dim + 1))
    for k in range(max_order + 1):
        for j in range(p + 1):
            b = ders[k, j]
            row = span - p + j
            for c in range(dim + 1):
                hom[k, c] += b * Pw[row, c]
    w0 = hom[0, dim]
    for k in range(max_order + 1):
        for c in range(dim):
            v = hom[k, c]
            for i in range(1, k + 1):
                v -= _binomial(k, i) * hom[i, dim] * out[k - i, c]
            out[k, c] = v / w0


@njit(cache=True)
def rational_derivatives(U, Pw, p: int, us, max_order: int, left: bool):
    """:func:`rational_derivatives_at` for a batch ``us`` (shape (m,)).

    Returns
    -------
    ndarray, shape (max_order + 1, m, n_axes)
    """
    m = us.shape[0]
    dim = Pw.shape[1] - 1
    out = np.empty((max_order + 1, m, dim))
    one = np.empty((max_order + 1, dim))
    for i in range(m):
        rational_derivatives_at(U, Pw, p, us[i], max_order, left, one)
        out[:, i, :] = one
    return out
