"""Arc length, its inverse, and sharp corners of a NURBS curve.

:class:`CurveGeometry` is built once per curve (``curve.geometry``, cached) and serves
``s(u)``, ``u(s)``, the total length and the list of sharp corners.

Arc length is integrated with 10-point Gauss-Legendre quadrature on an adaptive partition
of every knot span, split also where C' = 0 (a piece is split until the rule and the rule
on its two halves agree to 1e-13 of the total length and C' does not reverse inside it), so ``s(u)`` is accurate to
well below 1e-9 relative. The inverse ``u(s)`` is found by safeguarded Newton iteration
inside the bracketing piece.

Glossary
--------
u : curve parameter in [0, 1]; s : arc length from the start [path units];
L : total length [path units].
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np

__all__ = ["CurveGeometry", "distances_to"]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(10)
_CACHE_MIN_SIZE, _CACHE_ENTRIES = 1000, 16


def _speed(curve, u: np.ndarray) -> np.ndarray:
    return np.linalg.norm(curve(u, 1), axis=-1)


def _gauss(curve, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Integral of |C'(u)| over [a, b] (elementwise arrays) by 10-point Gauss-Legendre.

    The weighted sum runs over the nodes left to right, not through a BLAS product (which
    may order or fuse it otherwise, depending on the CPU), so that the compiled loop
    (``_arc_length`` of :mod:`nurbsmotion.interpolators.planned`) reproduces ``s(u)``."""
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
        self._corners: dict[float, np.ndarray] = {}
        # Planners invert the same arc-length grids again and again (one per replanning
        # pass): remember the last few large inversions.
        self._inverse_cache: OrderedDict[tuple, np.ndarray] = OrderedDict()
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
        total = float(np.sum(_gauss(curve, a, b)))
        done_a, done_b, done_i = [], [], []
        for _ in range(40):
            m = 0.5 * (a + b)
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
    def table(self) -> tuple[np.ndarray, np.ndarray]:
        """The arc-length table: the pieces' ends ``u``, shape (m + 1,), each piece inside
        one knot span, and ``s(u)`` there [path units], shape (m + 1,) (read, not copied:
        do not change them)."""
        return self._u, self._s

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

    def parameter_at(self, s: Any, tol: float = 1e-13) -> np.ndarray:
        """Parameter ``u`` at arc length ``s`` in ``[0, length]``, shape of ``s``.

        Raises
        ------
        ValueError
            If ``s`` is not finite or lies outside ``[0, length]``.
        """
        ss = np.asarray(s, dtype=float)
        if not np.all(np.isfinite(ss)):
            raise ValueError("arc length must be finite")
        key = None
        if ss.size >= _CACHE_MIN_SIZE:
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
            raise ValueError(f"arc length {float(bad)!r} lies outside [0, {L!r}]")
        flat = np.minimum(ss.ravel(), L)
        j = np.clip(np.searchsorted(self._s, flat, side="right") - 1, 0, len(self._s) - 2)
        lo, hi = self._u[j].copy(), self._u[j + 1].copy()
        s_lo = self._s[j]
        frac = (flat - s_lo) / np.maximum(self._s[j + 1] - s_lo, 1e-300)
        u = lo + frac * (hi - lo)
        active = np.arange(flat.size)  # Newton on the points not yet converged only
        for _ in range(60):
            ua, la, ha = u[active], lo[active], hi[active]
            f = s_lo[active] + _gauss(self.curve, self._u[j[active]], ua) - flat[active]
            done = np.abs(f) <= tol * L
            la = np.where(f < 0, ua, la)
            ha = np.where(f > 0, ua, ha)
            step = ua - f / _speed(self.curve, ua)
            bisect = (step <= la) | (step >= ha) | ~np.isfinite(step)
            u[active] = np.where(done, ua, np.where(bisect, 0.5 * (la + ha), step))
            lo[active], hi[active] = la, ha
            active = active[~done]
            if active.size == 0:
                break
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
        if angle_tolerance not in self._corners:
            c = self.curve
            values, counts = np.unique(c.knots, return_counts=True)  # values = breakpoints
            full = values[1:-1][counts[1:-1] >= c.degree]
            zero = [u for u in c.zero_speed_points if 0.0 < u < 1.0]
            candidates = np.union1d(full, np.asarray(zero, dtype=float))
            if candidates.size:
                angle = c.turning_angle(candidates)
                candidates = candidates[angle > angle_tolerance]
            self._corners[angle_tolerance] = candidates
        return self._corners[angle_tolerance].copy()


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
