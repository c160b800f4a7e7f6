"""Arc length, its inverse, and sharp corners of a NURBS curve.

:class:`CurveGeometry` is built once per curve (``curve.geometry``, cached) and serves
``s(u)``, ``u(s)``, the total length and the list of sharp corners.

Arc length is integrated with 10-point Gauss-Legendre quadrature on an adaptive partition
of every knot span, split also where C' = 0 (a piece is split until the rule and the rule
on its two halves agree to 1e-13 of the total length and C' does not reverse inside it), so ``s(u)`` is accurate to
well below 1e-9 relative. The inverse ``u(s)`` is found by compiled safeguarded Newton
iteration inside the bracketing piece, to rounding.

Glossary
--------
u : curve parameter in [0, 1]; s : arc length from the start [path units];
L : total length [path units].
"""

from __future__ import annotations

import math
from collections import OrderedDict
from typing import Any

import numpy as np
from numba import njit

from ._kernels import horner, horner1, rational_horner
from .errors import InvalidArgumentError

__all__ = ["CurveGeometry", "distances_to", "sharp_corners"]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(10)
_CACHE_MIN_SIZE, _CACHE_ENTRIES = 1000, 16


def _speed(curve, u: np.ndarray) -> np.ndarray:
    return np.linalg.norm(curve(u, 1), axis=-1)


def _gauss(curve, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Integral of |C'(u)| over [a, b] (elementwise arrays) by 10-point Gauss-Legendre.

    The weighted sum runs over the nodes left to right, not through a BLAS product (which
    may order or fuse it otherwise, depending on the CPU). The compiled inverse
    (:func:`_gauss_from`) sums the same way but evaluates |C'| by the span's power form,
    so the two agree to rounding (1e-14 relative), not bit for bit."""
    half = 0.5 * (b - a)
    mid = 0.5 * (b + a)
    nodes = mid[:, None] + half[:, None] * _GL_X[None, :]
    speed = _speed(curve, nodes.ravel()).reshape(nodes.shape)
    total = np.zeros(len(half))
    for i, w in enumerate(_GL_W):
        total += speed[:, i] * w
    return half * total


def _reverses(curve, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether C' turns by more than 90 degrees between neighbouring samples (the ends and
    the Gauss nodes) of [a, b]: the sign of a cusp, where C' = 0 and |C'| has a kink.

    A kink between the last Gauss node and an end of a piece is invisible to both the
    whole and the halved rule, which then agree on a wrong value (a 1-axis path that
    reverses, or a 2-axis cusp); such pieces are split until the kink's share is below
    rounding. A reversal narrower than the node spacing can still be missed (a known gap:
    splitting at the real roots of each component of C' per span would close it)."""
    half = 0.5 * (b - a)
    mid = 0.5 * (b + a)
    nodes = mid[:, None] + half[:, None] * _GL_X[None, :]
    d1 = np.concatenate(
        [curve(a, 1)[:, None], curve(nodes, 1), curve(b, 1, "left")[:, None]], axis=1
    )
    return np.any(np.sum(d1[:, 1:] * d1[:, :-1], axis=-1) < 0, axis=1)


@njit(cache=True)
def _speed_at(coef, t):
    """``(|C'|, d|C'|/du)`` at ``t`` from its span's start (``coef``: the span's power form
    of ``[w*C, w]``, :attr:`NurbsCurve.power_form`)."""
    dim = coef.shape[1] - 1
    w, w1, w2 = horner(coef, dim, t)
    d2 = 0.0
    dd = 0.0
    for a in range(dim):
        _, x1, x2 = rational_horner(coef, a, t, w, w1, w2)
        d2 += x1 * x1
        dd += x1 * x2
    speed = math.sqrt(d2)
    return speed, (dd / speed if speed > 0 else 0.0)


@njit(cache=True)
def _speed_only(coef, t):
    """``|C'|`` at ``t`` from its span's start (the first derivative only)."""
    dim = coef.shape[1] - 1
    w, w1 = horner1(coef, dim, t)
    d2 = 0.0
    for a in range(dim):
        A, A1 = horner1(coef, a, t)
        x1 = (A1 - w1 * (A / w)) / w
        d2 += x1 * x1
    return math.sqrt(d2)


@njit(cache=True)
def _gauss_from(coef, span_start, a, b, nodes, weights):
    """Arc length of [a, b] inside the span starting at ``span_start`` by the
    Gauss-Legendre rule ``nodes, weights``, summed node by node as :func:`_gauss` does
    (|C'| from the power form: equal to it to rounding)."""
    half = 0.5 * (b - a)
    mid = 0.5 * (b + a)
    total = 0.0
    for i in range(nodes.shape[0]):
        total += _speed_only(coef, mid + half * nodes[i] - span_start) * weights[i]
    return half * total


@njit(cache=True)
def _inverse_arc_length(table_u, table_s, piece_span, spans, coefficients, nodes, weights,
                      tol, arc, out):
    """``u(s)`` for the arc lengths ``arc`` [path units] in ``[0, L]`` (any order; fastest
    when neighbours are close, as along a motion), into ``out``.

    Safeguarded Newton (bisection where a step leaves the bracket) on
    ``s_j + G(u_j, u) - s`` inside the table's piece j holding s (G: the table's Gauss
    rule, :func:`_gauss_from`), from the previous arc length's parameter extrapolated to
    second order where it lies in the same piece, else the table's linear guess; once
    ``|f| <= tol`` one more Newton step takes the root to rounding, so the result hardly
    depends on the guess."""
    n_pieces = table_u.shape[0] - 1
    prev_piece = -1
    u_prev = 0.0
    s_prev = 0.0
    du = 0.0
    ddu = 0.0
    for q in range(arc.shape[0]):
        sv = arc[q]
        lo_i = 0
        hi_i = n_pieces + 1
        while lo_i < hi_i:                      # searchsorted(table_s, sv, "right")
            mid_i = (lo_i + hi_i) // 2
            if table_s[mid_i] <= sv:
                lo_i = mid_i + 1
            else:
                hi_i = mid_i
        j = min(max(lo_i - 1, 0), n_pieces - 1)
        start = table_u[j]
        lo = start
        hi = table_u[j + 1]
        s_lo = table_s[j]
        frac = (sv - s_lo) / max(table_s[j + 1] - s_lo, 1e-300)
        u = lo + frac * (hi - lo)
        if j == prev_piece:
            d = sv - s_prev
            guess = u_prev + d * (du + 0.5 * d * ddu)
            if lo < guess < hi:
                u = guess
        k = piece_span[j]
        coef = coefficients[k]
        base = spans[k]
        speed = 0.0
        dspeed = 0.0
        for _ in range(60):
            f = s_lo + _gauss_from(coef, base, start, u, nodes, weights) - sv
            speed, dspeed = _speed_at(coef, u - base)
            if f < 0:
                lo = u
            if f > 0:
                hi = u
            step = u - f / speed if speed > 0 else np.nan
            bisect = not (lo < step < hi)
            if abs(f) <= tol:
                if not bisect:
                    u = step
                break
            u = 0.5 * (lo + hi) if bisect else step
        out[q] = u
        prev_piece = j
        u_prev = u
        s_prev = sv
        if speed > 0:
            du = 1.0 / speed
            ddu = -dspeed / (speed * speed * speed)
        else:
            prev_piece = -1


class CurveGeometry:
    """Arc-length table and corner list of one curve.

    Parameters
    ----------
    curve : NurbsCurve
        The curve (not copied; curves are immutable).
    rtol : float
        Relative tolerance of each piece's quadrature against the total length.
    """

    def __init__(self, curve, rtol: float = 1e-13):
        self.curve = curve
        # Planners invert the same arc-length grids again and again (one per replanning
        # pass): remember the last few large inversions.
        self._inverse_cache: OrderedDict[tuple, np.ndarray] = OrderedDict()
        self._piece_span: np.ndarray | None = None  # knot span of each table piece
        if curve.degree == 1 and np.all(curve.weights == curve.weights[0]):
            # A polyline: |C'| is constant on every span, so each span's length is its
            # chord, exactly; no quadrature table to refine (a 10^6-point polyline is
            # measured at once).
            chords = np.linalg.norm(np.diff(curve.control_points, axis=0), axis=1)
            self._u = curve.knots[1:-1].copy()
            self._s = np.concatenate([[0.0], np.cumsum(chords)])
            self.length = float(self._s[-1])
            return
        # |C'| has a kink where C' = 0 (a cusp, a reversal): split there too, so that no
        # quadrature piece straddles one, however narrow the reversal
        bp = np.union1d(curve.breakpoints, curve.zero_speed_points)
        a = np.repeat(bp[:-1], 4) + np.tile(np.arange(4) / 4, len(bp) - 1) * np.repeat(
            np.diff(bp), 4
        )
        b = np.append(a[1:], 1.0)
        whole = _gauss(curve, a, b)  # the first round's whole pieces, computed once
        total = float(np.sum(whole))
        done_a, done_b, done_i = [], [], []
        for round_ in range(40):
            m = 0.5 * (a + b)
            if round_:
                whole = _gauss(curve, a, b)
            halves = _gauss(curve, a, m) + _gauss(curve, m, b)
            ok = np.abs(whole - halves) <= rtol * total
            # a piece must not straddle a reversal of C' (|C'| has a kink there), unless
            # it is itself shorter than the tolerance: near a zero-speed point of higher
            # order C' is rounding noise whose direction "reverses" at every split
            check = ok & (halves > rtol * total)
            ok[check] = ~_reverses(curve, a[check], b[check])
            done_a.append(a[ok])
            done_b.append(b[ok])
            done_i.append(halves[ok])
            a, b = np.concatenate([a[~ok], m[~ok]]), np.concatenate([m[~ok], b[~ok]])
            if a.size == 0:
                break
        else:  # pragma: no cover - only for pathological curves
            done_a.append(a)
            done_b.append(b)
            done_i.append(_gauss(curve, a, b))
        a = np.concatenate(done_a)
        order = np.argsort(a)
        self._u = np.append(a[order], 1.0)
        self._s = np.concatenate([[0.0], np.cumsum(np.concatenate(done_i)[order])])
        self.length = float(self._s[-1])

    @property
    def n_pieces(self) -> int:
        """Number of quadrature pieces of the arc-length table."""
        return len(self._u) - 1

    def arc_length(self, u: Any) -> np.ndarray:
        """Arc length from the start to ``u`` [path units], shape of ``u``."""
        uu = self.curve._check_parameter(u)
        flat = uu.ravel()
        j = np.clip(np.searchsorted(self._u, flat, side="right") - 1, 0, len(self._u) - 2)
        s = self._s[j] + _gauss(self.curve, self._u[j], flat)
        return s.reshape(uu.shape) if uu.ndim else float(s[0])

    def parameter_at(self, s: Any, tol: float = 1e-13, *, cache: bool = True) -> np.ndarray:
        """Parameter ``u`` at arc length ``s`` in ``[0, length]``, shape of ``s``.

        Compiled safeguarded Newton in the table's piece (:func:`_inverse_arc_length`):
        refined to rounding once the residual is within ``tol`` of the length. Inversions
        of 1,000 or more arc lengths are remembered (the last 16) unless ``cache`` is false
        (a motion's every sample, inverted once).

        Raises
        ------
        InvalidArgumentError
            If ``s`` is not finite or lies outside ``[0, length]``.
        """
        ss = np.asarray(s, dtype=float)
        if not np.all(np.isfinite(ss)):
            raise InvalidArgumentError("arc length must be finite")
        key = None
        if cache and ss.size >= _CACHE_MIN_SIZE:
            key = (ss.shape, ss.tobytes(), tol)
            if key in self._inverse_cache:
                self._inverse_cache.move_to_end(key)
                return self._inverse_cache[key].copy()
        u = self._parameter_at(ss, tol)
        if key is not None:
            self._inverse_cache[key] = u.copy()
            if len(self._inverse_cache) > _CACHE_ENTRIES:
                self._inverse_cache.popitem(last=False)
        return u

    def _parameter_at(self, ss: np.ndarray, tol: float):
        L = self.length
        if np.any((ss < 0) | (ss > L * (1 + 1e-12))):
            bad = ss[(ss < 0) | (ss > L * (1 + 1e-12))].flat[0]
            raise InvalidArgumentError(f"arc length {float(bad)!r} lies outside [0, {L!r}]")
        flat = np.ascontiguousarray(np.minimum(ss.ravel(), L))
        if self._piece_span is None:
            spans = self.curve.power_form[0]
            self._piece_span = np.clip(np.searchsorted(spans, self._u[:-1], side="right")
                                       - 1, 0, len(spans) - 2)
        u = np.empty_like(flat)
        _inverse_arc_length(self._u, self._s, self._piece_span, *self.curve.power_form,
                            _GL_X, _GL_W, tol * L, flat, u)
        return u.reshape(ss.shape) if ss.ndim else float(u[0])

    def uniform_parameters(self, n: int) -> np.ndarray:
        """``u`` at ``n`` points equally spaced in arc length from 0 to L, shape (n,).

        Cached (as every large inversion is): the contour error of every run on this curve
        seeds its nearest point search from the same grid.
        """
        return self.parameter_at(np.linspace(0.0, self.length, n))

    def sharp_corners(self, angle_tolerance: float = 1e-6) -> np.ndarray:
        """Interior parameters where the left and right (limit) tangents differ by more
        than ``angle_tolerance`` [rad]: knots of full multiplicity, and interior points
        where C' = 0 (:attr:`NurbsCurve.zero_speed_points`) with a tangent reversal (a
        cusp). Elsewhere the curve is C1 with C' != 0, so it has no corner."""
        return self.curve.sharp_corners(angle_tolerance)


def sharp_corners(curve, angle_tolerance: float) -> np.ndarray:
    """Interior parameters of ``curve`` where the left and right (limit) tangents differ
    by more than ``angle_tolerance`` [rad], shape (n_corners,) (see
    :meth:`CurveGeometry.sharp_corners`). Needs no arc-length table: the size check of a
    run counts a million-span path's corners before any is built."""
    if curve.degree == 1:
        # A polyline turns only at its vertices, from one segment's direction to the next
        # (with any weights a segment is straight; none has zero length, the curve
        # refuses that): a million vertices in one vectorised pass.
        d = np.diff(curve.control_points, axis=0)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        angle = np.arccos(np.clip(np.sum(d[:-1] * d[1:], axis=1), -1.0, 1.0))
        return curve.knots[2:-2][angle > angle_tolerance]
    values, counts = np.unique(curve.knots, return_counts=True)  # values = breakpoints
    full = values[1:-1][counts[1:-1] >= curve.degree]
    zero = [u for u in curve.zero_speed_points if 0.0 < u < 1.0]
    candidates = np.union1d(full, np.asarray(zero, dtype=float))
    if candidates.size:
        angle = curve.turning_angle(candidates)
        candidates = candidates[angle > angle_tolerance]
    return candidates


def distances_to(points: np.ndarray, point: np.ndarray) -> np.ndarray:
    """``|points[k] - point|`` for every row, shape (n,) [the points' unit].

    Summed axis by axis, so that no temporary is larger than one column: a long run's
    trace is most of the process's memory.

    Parameters
    ----------
    points : ndarray, shape (n, n_axes)
    point : ndarray, shape (n_axes,)
    """
    d2 = np.zeros(points.shape[0])
    for j in range(points.shape[1]):
        d2 += (points[:, j] - point[j]) ** 2
    return np.sqrt(d2, out=d2)
