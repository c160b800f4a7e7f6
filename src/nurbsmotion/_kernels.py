"""Compiled NURBS evaluation kernels (numba ``@njit(cache=True)``).

Span search, B-spline basis functions with their derivatives and rational derivatives for
a batch of parameters (:meth:`nurbsmotion.nurbs.NurbsCurve.derivatives`), and each span's
power form (:func:`power_basis`: the Taylor coefficients at its start, which the compiled
loop evaluates by Horner's rule, :mod:`nurbsmotion.interpolators.base`). Any degree, any
axis count.

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

__all__ = ["find_span", "workspace", "basis_table", "basis_derivatives",
           "rational_derivatives_into", "rational_derivatives",
           "power_basis", "horner", "horner1", "rational_horner"]


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


def workspace(p: int, max_order: int, dim: int) -> tuple:
    """Scratch arrays for :func:`basis_derivatives` and :func:`rational_derivatives_into`,
    allocated once per batch rather than per parameter."""
    return (np.empty((max_order + 1, p + 1)), np.empty((p + 1, p + 1)), np.empty(p + 1),
            np.empty(p + 1), np.empty((2, p + 1)), np.empty((max_order + 1, dim + 1)))


@njit(cache=True)
def basis_table(span: int, u: float, p: int, U, ndu, left, right) -> None:
    """The table ``ndu`` of A2.2 / A2.3: the non-zero basis functions ``N_{span-p+j,p}(u)``
    in ``ndu[j, p]`` (upper triangle: the lower degrees) and the knot differences the
    derivatives need (lower triangle); ``left`` and ``right`` (p+1,) are scratch."""
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


@njit(cache=True)
def basis_derivatives(span: int, u: float, p: int, n_der: int, U, ders, ndu, left, right,
                      a) -> None:
    """Non-zero basis functions and their derivatives up to ``n_der`` (A2.3).

    Writes ``ders[k, j]`` for ``k = 0 .. n_der``, ``j = 0 .. p``; orders above ``p`` are 0.
    ``ders`` must have shape at least ``(n_der + 1, p + 1)``; ``ndu`` (p+1, p+1), ``left``
    and ``right`` (p+1,) and ``a`` (2, p+1) are scratch (see :func:`workspace`).
    """
    basis_table(span, u, p, U, ndu, left, right)
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


_BINOMIAL = np.array([[1.0, 0.0, 0.0, 0.0],
                      [1.0, 1.0, 0.0, 0.0],
                      [1.0, 2.0, 1.0, 0.0],
                      [1.0, 3.0, 3.0, 1.0]])
"""Binomial coefficients C(k, i) for the orders A4.2 needs (up to 3, the jerk)."""


@njit(cache=True)
def rational_derivatives_into(U, Pw, p: int, us, max_order: int, left: bool, out,
                              work) -> None:
    """Points and derivatives of a NURBS curve at the parameters ``us`` (A2.3 + A4.2).

    Parameters
    ----------
    U : ndarray, shape (n + p + 1,)
    Pw : ndarray, shape (n, n_axes + 1)
        Homogeneous control points ``[w*P, w]``.
    p, max_order, left
        Degree, highest order (at most 3), one-sided rule (see :func:`find_span`).
    us : ndarray, shape (m,)
        Parameters.
    out : ndarray, shape (>= max_order + 1, m, n_axes)
        Written: ``out[k, i]`` is ``C^(k)(us[i])``.
    work : tuple
        Scratch from :func:`workspace` for at least this degree, order and axis count.
    """
    ders, ndu, wl, wr, a, hom = work
    n = Pw.shape[0]
    dim = Pw.shape[1] - 1
    for i in range(us.shape[0]):
        u = us[i]
        span = find_span(n, p, U, u, left)
        basis_derivatives(span, u, p, max_order, U, ders, ndu, wl, wr, a)
        for k in range(max_order + 1):
            for c in range(dim + 1):
                acc = 0.0
                for j in range(p + 1):
                    acc += ders[k, j] * Pw[span - p + j, c]
                hom[k, c] = acc          # k-th derivative of [w*C, w]
        w0 = hom[0, dim]
        for k in range(max_order + 1):
            for c in range(dim):
                v = hom[k, c]
                for m in range(1, k + 1):
                    v -= _BINOMIAL[k, m] * hom[m, dim] * out[k - m, i, c]
                out[k, i, c] = v / w0


def rational_derivatives(U, Pw, p: int, us, max_order: int, left: bool) -> np.ndarray:
    """:func:`rational_derivatives_into` into a new array, shape (max_order + 1, m, n_axes)."""
    out = np.empty((max_order + 1, us.shape[0], Pw.shape[1] - 1))
    rational_derivatives_into(U, Pw, p, us, max_order, left, out,
                              workspace(p, max_order, Pw.shape[1] - 1))
    return out


def power_basis(U, Pw, p: int, starts) -> np.ndarray:
    """The homogeneous curve ``[w*C, w]`` as a polynomial on each span, in powers of the
    distance to the span's start (the Taylor coefficients there, A2.3, right-sided).

    Parameters
    ----------
    U, Pw, p
        Knots, homogeneous control points and degree (see the module glossary).
    starts : ndarray, shape (m,)
        The distinct knots that start the spans (each ``U[p] <= s < U[n]``).

    Returns
    -------
    ndarray, shape (m, p + 1, n_axes + 1)
        ``c[i, k]`` with ``[w*C, w](u) = sum_k c[i, k] * (u - starts[i])**k`` on
        ``[starts[i], starts[i+1])``.
    """
    out = np.zeros((starts.shape[0], p + 1, Pw.shape[1]))
    _power_basis_into(U, Pw, p, starts, out, *workspace(p, p, Pw.shape[1] - 1)[:5])
    return out


@njit(cache=True)
def _power_basis_into(U, Pw, p, starts, out, ders, ndu, wl, wr, a):
    n = Pw.shape[0]
    for i in range(starts.shape[0]):
        span = find_span(n, p, U, starts[i], np.bool_(False))  # not a literal: one signature
        basis_derivatives(span, starts[i], p, p, U, ders, ndu, wl, wr, a)
        factorial = 1.0
        for k in range(p + 1):
            if k > 0:
                factorial *= k
            for c in range(Pw.shape[1]):
                acc = 0.0
                for j in range(p + 1):
                    acc += ders[k, j] * Pw[span - p + j, c]
                out[i, k, c] = acc / factorial


@njit(cache=True, inline="always")
def horner(coef, j, t):
    """Coordinate ``j`` of a power-form polynomial (:func:`power_basis`, one span's
    ``coef``, shape (p + 1, n_axes + 1)) and its first two derivatives at ``t`` (the
    distance to the span's start): ``(P, P', P'')``."""
    p = coef.shape[0] - 1
    b0 = coef[p, j]
    b1 = 0.0
    b2 = 0.0
    for k in range(p - 1, -1, -1):
        b2 = b2 * t + b1
        b1 = b1 * t + b0
        b0 = b0 * t + coef[k, j]
    return b0, b1, 2.0 * b2


@njit(cache=True, inline="always")
def horner1(coef, j, t):
    """:func:`horner` without the second derivative: ``(P, P')``."""
    p = coef.shape[0] - 1
    b0 = coef[p, j]
    b1 = 0.0
    for k in range(p - 1, -1, -1):
        b1 = b1 * t + b0
        b0 = b0 * t + coef[k, j]
    return b0, b1


@njit(cache=True, inline="always")
def rational_horner(coef, j, t, w, w1, w2):
    """Coordinate ``j`` of ``C = A/w`` and its first two derivatives at ``t`` from a span's
    power form (:func:`horner`), given the weight and its derivatives ``w, w1, w2`` there
    (the quotient rule of A4.2): ``(C, C', C'')``."""
    A, A1, A2 = horner(coef, j, t)
    x = A / w
    x1 = (A1 - w1 * x) / w
    return x, x1, (A2 - 2.0 * w1 * x1 - w2 * x) / w
