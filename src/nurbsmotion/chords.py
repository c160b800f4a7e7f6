"""Runs of short chords joined into smooth curves within a path tolerance (CAM programs).

CAM systems write a smooth curve as thousands of short G1 chords (0.01 mm is ordinary).
Taken literally, every joint of two chords is a corner, and a planner that respects the
drive limits must nearly stop at each: a few per cent of the feed. LinuxCNC follows such
programs with ``G64 P<tol>``, blending within ``tol`` of the programmed chords.
:func:`join_chords` does it as a geometry operation: every run of chords whose joints turn
by small angles is replaced by one smooth cubic B-spline within the tolerance of the
chords; real corners stay corners, and every other piece (arcs, splines, long lines) is
kept as it is.

Which joints are chord joints
-----------------------------
Two consecutive line pieces of lengths a and b, turning by theta at their joint. The
circular arc tangent to both at a distance ``l = min(a, b) / 2`` from the joint (at the
shorter one's midpoint) passes ``l tan(theta / 4)`` from the joint: where that is within the
tolerance e, a smooth curve through that joint is within e of the chords, so the joint is a
chord joint (for chords of length L that a CAM system wrote within e of a curve of radius
R, theta = L / R and ``l tan(theta / 4)`` is about ``L^2 / (8 R)``, the chord's own sag).
A turn of a right angle or more is always a corner, whatever the chords' lengths; so is a
joint where the programmed feed changes. A run is a maximal sequence of at least two line
pieces joined by chord joints.

Fit
---
A cubic least-squares B-spline in the chords' arc length s of points on the chords (each
chord's start and at least three more, a quarter of the median chord apart), with knots at
every :data:`START_SPAN_CHORDS`-th vertex: its banded normal equations solved by Cholesky
(as ``scipy.interpolate.make_lsq_spline(method="norm-eq")`` solves them), in time linear in
the number of points (the bound below is computed from the result, whatever the solve's
rounding). Its end control points are then set to the run's end points, so the path stays
continuous with its neighbours. Its distance from the chords is bounded by that of the point
of equal arc length: ``e(s) = C(s) - P(s)``, with P the chords at s. Between two
consecutive points (the knots are among them) P is linear, so ``|e|`` is at most its
larger end value plus ``delta^2 / 8`` times the larger ``|C''|`` at the two ends (``C''``
is linear on a knot span). Where that bound exceeds the tolerance, the knot spans there are
halved (a knot at their middle vertex) and the spline fitted again. Where a span of one
chord still exceeds it, the run is split at that chord's start, which becomes a corner, and
each part fitted again (a part of one chord stays a chord). The bound holds both ways:
every point of the curve is within e of a chord point, and every chord point within e of
the curve.

Glossary
--------
e : tolerance [path units]; s : arc length along a run's chords [path units];
P(s) : the chords at s; C(s) : the fitted spline; theta : turn at a joint [rad].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InvalidArgumentError
from .feed import FeedLimit
from .joining import join_with_edges
from .nurbs import NurbsCurve, point_extent

__all__ = ["ChordJoin", "join_chords", "polyline_corners", "START_SPAN_CHORDS", "MAX_TURN",
           "CHECKS_PER_CHORD"]

MAX_TURN = 0.5 * np.pi
"""A joint turning by this much or more [rad] is a corner, however short its chords."""

START_SPAN_CHORDS = 32
"""Chords per knot span of a run's first fit; spans are halved where the fit leaves the
chords by more than the tolerance, so this sets how much of the chords' rounding noise the
spline may average away where the tolerance allows, not how close it stays."""

CHECKS_PER_CHORD = 256
"""Most points a chord is sampled at for the fit and its check (a long chord among short
ones): beyond it the points are farther apart, which only makes the bound looser."""

_MAX_REFINEMENTS = 40
"""Rounds of halving a run's knot spans in vertices (each halves every span where the fit
leaves the chords: 2^40 chords, never the limit)."""


@dataclass(frozen=True)
class ChordJoin:
    """A path with its chord runs joined (:func:`join_chords`).

    Attributes
    ----------
    curve : NurbsCurve
        The path [its units]; the input itself where nothing was joined.
    feed : FeedLimit or None
        The programmed feed along the new curve's parameter [path units / s].
    tolerance : float
        The tolerance the runs were fitted within [path units].
    chords_joined : int
        Chords replaced by smooth curves.
    runs : int
        Smooth curves they became.
    max_deviation : float
        The largest bound of the distance between a fitted curve and its chords
        [path units], at most ``tolerance``; 0 where nothing was joined.
    """

    curve: NurbsCurve
    feed: FeedLimit | None
    tolerance: float
    chords_joined: int = 0
    runs: int = 0
    max_deviation: float = 0.0

    def describe(self, unit: str | None = None, per_unit: float = 1.0) -> str:
        """One sentence for a console: ``"99,999 chords joined into 1 smooth curve within
        0.001 mm"``; the tolerance is shown in ``unit`` (``per_unit`` of them per path
        unit) where given."""
        tol = (f"{self.tolerance * per_unit:.4g} {unit}" if unit
               else f"{self.tolerance:.4g} {self.curve.units or 'path units'}")
        if not self.chords_joined:
            return f"no chords joined (tolerance {tol})"
        return (f"{self.chords_joined:,} chords joined into {self.runs:,} smooth "
                f"curve{'s' if self.runs != 1 else ''} within {tol}")


def join_chords(curve: NurbsCurve, tolerance: float, feed: FeedLimit | None = None) -> ChordJoin:
    """``curve`` with each run of short chords replaced by a smooth cubic B-spline within
    ``tolerance`` of them (see the module docstring).

    Parameters
    ----------
    curve : NurbsCurve
        A path whose pieces (between knots of full multiplicity) may be straight lines
        [path units], e.g. a G-code program or a polyline joined into one curve.
    tolerance : float
        Largest distance of a fitted curve from the chords it replaces [path units],
        ``>= 0``; 0 joins nothing.
    feed : FeedLimit, optional
        The programmed feed along ``curve`` [path units / s]: a joint where it changes
        is kept as a corner, and the result carries it along the new curve.

    Returns
    -------
    ChordJoin

    Raises
    ------
    InvalidArgumentError
        If ``tolerance`` is negative or not finite.
    """
    e = float(tolerance)
    if not (np.isfinite(e) and e >= 0):
        raise InvalidArgumentError(f"the chord tolerance must be finite and >= 0, got {tolerance!r}")
    bounds, first = _pieces(curve)            # piece k: u in bounds[k:k+2], points first[k:k+2]
    P = curve.control_points
    if e == 0 or bounds.size < 3:
        return ChordJoin(curve, feed, e)
    line = _is_line(P, first)
    speed = _piece_speeds(feed, bounds)
    ends = P[first]
    d = np.diff(ends, axis=0)
    length = np.linalg.norm(d, axis=1)
    joint = _chord_joints(d, length, line, speed, e)
    runs = _runs(joint)
    if not runs:
        return ChordJoin(curve, feed, e)
    segments, parts, joined, fitted, worst = [], [], 0, 0, 0.0
    start = 0                                  # first piece not yet in a segment
    for k0, k1 in runs:                        # pieces k0 .. k1 - 1 form the run
        for a, b, spline, dev in _fit_run(ends[k0:k1 + 1], e, k0):
            if spline is None:
                continue                       # chords kept: left in the block around them
            if a > start:
                segments.append(_sub_curve(curve, bounds, first, start, a))
                parts.append((start, a))
            segments.append(spline)
            parts.append((a, b))
            joined += b - a
            fitted += 1
            worst = max(worst, dev)
            start = b
    if not fitted:
        return ChordJoin(curve, feed, e)
    if start < bounds.size - 1:
        segments.append(_sub_curve(curve, bounds, first, start, bounds.size - 1))
        parts.append((start, bounds.size - 1))
    new, edges = join_with_edges(segments, name=curve.name, units=curve.units)
    new_feed = None if feed is None else _mapped_feed(feed, bounds, parts, edges)
    return ChordJoin(new, new_feed, e, joined, fitted, worst)


def polyline_corners(points: np.ndarray, tolerance: float, factor: float = 1.0, *,
                     whole: bool = True, angle_tolerance: float = 1e-6) -> tuple[int, bool]:
    """The sharp corners a degree-1 path through ``points`` keeps once its chord runs are
    joined within ``tolerance`` (:func:`join_chords`), counted from its vertices alone,
    before any curve is built: what a run's planner sees of a large polyline file
    (:func:`nurbsmotion.study.run_input.load_run_contour`).

    Where no joint is a chord joint, :func:`join_chords` returns the path as it is and the
    count is exact: the joints whose turn exceeds ``angle_tolerance``, computed as
    :meth:`NurbsCurve.sharp_corners` computes them on the path scaled by ``factor`` (the
    path the planner reads, in pulses). Otherwise (or with ``whole`` false: the first
    vertices of a longer path) it is a lower bound: the joints between two pieces that
    stay chords (neither is in a run: the joint and its neighbours are no chord joints;
    every such test needs only the two pieces of its joint, so a prefix decides them as
    the whole path does), turning by more than twice ``angle_tolerance`` (the joined
    path's corners are computed from its elevated pieces' tangents, which rounding moves
    by far less than that).

    Parameters
    ----------
    points : ndarray, shape (n_points, n_axes)
        The vertices in order [path units].
    tolerance : float
        The chord join's tolerance [path units], >= 0 (0: nothing is joined).
    factor : float
        Pulses per path unit: the planner's path is ``points * factor``.
    whole : bool
        Whether ``points`` are all the path's vertices (else its first ones).
    angle_tolerance : float
        Smallest turn counted as a corner [rad] (:meth:`NurbsCurve.sharp_corners`).

    Returns
    -------
    corners : int
    exact : bool
        Whether ``corners`` is the path's count (else at least that many).
    """
    P = np.asarray(points, dtype=float)
    if P.shape[0] < 3:
        return 0, whole
    d = np.diff(P, axis=0)
    length = np.linalg.norm(d, axis=1)
    # the line test of _is_line: a prefix's extent is at most the whole path's, so a
    # piece that is no line here is none there either (and its joints no chord joints)
    size = point_extent(P) or 1.0
    if tolerance > 0:
        joint = _chord_joints(d, length, length > 1e-12 * size, np.ones(d.shape[0]),
                              tolerance)
    else:
        joint = np.zeros(d.shape[0] - 1, dtype=bool)
    scaled = P if factor == 1.0 else P * factor     # Scale.path: the same product
    u = np.diff(scaled, axis=0)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    angle = np.arccos(np.clip(np.sum(u[:-1] * u[1:], axis=1), -1.0, 1.0))
    if whole and not joint.any():
        return int(np.count_nonzero(angle > angle_tolerance)), True
    # vertex v (joint v - 1 here) keeps its turn where joints v - 1, v, v + 1 are no chord
    # joints; the last vertex of a prefix has an unknown next piece
    chord = np.concatenate([[False], joint, [False]])
    kept = ~(chord[:-2] | chord[1:-1] | chord[2:])
    if not whole:
        kept[-1] = False
    return int(np.count_nonzero(kept & (angle > 2.0 * angle_tolerance))), False


def _pieces(curve: NurbsCurve):
    """The curve's pieces between its C0 joints (interior knots of multiplicity p):
    their parameter bounds, shape (n_pieces + 1,), and the index of the control point at
    each bound (the curve passes through it there)."""
    t, p = curve.knots, curve.degree
    values, counts = np.unique(t, return_counts=True)
    joints = values[1:-1][counts[1:-1] >= p]
    bounds = np.concatenate([[0.0], joints, [1.0]])
    first = np.searchsorted(t, joints, side="left") - 1
    first = np.concatenate([[0], first, [curve.n_control_points - 1]]).astype(np.intp)
    return bounds, first


def _is_line(P: np.ndarray, first: np.ndarray) -> np.ndarray:
    """Whether each piece is a straight line traversed forward: all its control points on
    the segment between its end points (to 1e-12 of the path's size), in order, so that
    the curve (within their convex hull, variation diminishing) runs along it."""
    size = point_extent(P) or 1.0
    A, B = P[first[:-1]], P[first[1:]]
    d = B - A
    L = np.linalg.norm(d, axis=1)
    line = L > 1e-12 * size
    if np.all(np.diff(first) == 1):            # degree 1: every piece is its chord
        return line
    piece = np.repeat(np.arange(first.size - 1), np.diff(first))   # of points first[k] ..
    idx = np.arange(first[0], first[-1])
    u = np.where(line, L, 1.0)
    tangent = d / u[:, None]
    rel = P[idx] - A[piece]
    along = np.einsum("ij,ij->i", rel, tangent[piece])
    off = np.linalg.norm(rel - along[:, None] * tangent[piece], axis=1)
    ok = off <= 1e-12 * size
    # in order: along rises (weakly) through each piece's points and its end
    nxt = np.concatenate([along[1:], [0.0]])
    last = np.zeros(idx.size, dtype=bool)
    last[np.cumsum(np.diff(first)) - 1] = True
    nxt[last] = L[piece[last]]
    ok &= nxt >= along - 1e-12 * size
    bad = np.zeros(first.size - 1, dtype=bool)
    np.logical_or.at(bad, piece, ~ok)
    return line & ~bad


def _piece_speeds(feed: FeedLimit | None, bounds: np.ndarray) -> np.ndarray:
    """The lowest programmed feed on each piece (all equal without a feed)."""
    n = bounds.size - 1
    if feed is None:
        return np.ones(n)
    bp, v = feed.breakpoints, feed.speeds
    lo = np.clip(np.searchsorted(bp, bounds[:-1], side="right") - 1, 0, v.size - 1)
    hi = np.clip(np.searchsorted(bp, bounds[1:], side="left") - 1, 0, v.size - 1)
    out = v[lo].copy()
    for k in np.flatnonzero(hi > lo):           # a feed change inside a piece
        out[k] = v[lo[k]:hi[k] + 1].min()
    return out


def _chord_joints(d, length, line, speed, e) -> np.ndarray:
    """For each joint of pieces k and k + 1, whether it is a chord joint (module
    docstring)."""
    a, b = length[:-1], length[1:]
    safe = np.maximum(a * b, np.finfo(float).tiny)
    cos = np.clip(np.einsum("ij,ij->i", d[:-1], d[1:]) / safe, -1.0, 1.0)
    theta = np.arccos(cos)
    sag = 0.5 * np.minimum(a, b) * np.tan(0.25 * theta)
    return (line[:-1] & line[1:] & (speed[:-1] == speed[1:]) & (theta < MAX_TURN)
            & (sag <= e))


def _runs(joint: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs of pieces ``k0 .. k1 - 1`` linked by chord joints, as (k0, k1)."""
    j = np.concatenate([[False], joint, [False]]).astype(np.int8)
    edge = np.diff(j)
    starts, stops = np.flatnonzero(edge == 1), np.flatnonzero(edge == -1)
    return [(int(a), int(b) + 1) for a, b in zip(starts, stops)]


def _fit_run(V: np.ndarray, e: float, offset: int):
    """Fit the chords through vertices ``V`` (shape (m + 1, n_axes)); yield (first piece,
    end piece, NurbsCurve or None for chords kept, deviation bound), splitting at the
    worst vertex where one spline cannot stay within ``e``."""
    stack = [(0, V.shape[0] - 1)]
    out = []
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            out.append((offset + i, offset + j, None, 0.0))
            continue
        spline, dev, worst = _fit(V[i:j + 1], e)
        if spline is not None:
            out.append((offset + i, offset + j, spline, dev))
            continue
        k = i + int(np.clip(worst, 1, j - i - 1))
        stack.append((k, j))
        stack.append((i, k))
    out.sort(key=lambda r: r[0])
    return out


def _fit(V: np.ndarray, e: float):
    """One cubic spline within ``e`` of the chords through ``V``: (NurbsCurve, its
    deviation bound, None), or (None, None, the vertex where it fails) when no spline
    with knots at the vertices does (module docstring)."""
    from scipy.linalg import LinAlgError

    c = np.linalg.norm(np.diff(V, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(c)])
    L, m = s[-1], c.size
    # points of each chord: its start and at least 3 more, no farther apart than a quarter
    # of the median chord (up to CHECKS_PER_CHORD: fewer only loosen the bound)
    q = np.clip(np.ceil(4.0 * c / np.median(c)), 4, CHECKS_PER_CHORD).astype(np.intp)
    owner = np.repeat(np.arange(m), q)
    frac = (np.arange(owner.size) - np.repeat(np.cumsum(q) - q, q)) / q[owner]
    x = np.append(s[owner] + frac * c[owner], L)          # rising: vertices included
    D = _polyline(s, V, x)
    delta = np.diff(x)
    vertex = np.arange(0, m + 1, START_SPAN_CHORDS)
    inner = np.unique(np.append(vertex, m))[1:-1]         # knots at these vertices
    worst = m // 2
    for _ in range(_MAX_REFINEMENTS):
        t = np.concatenate([[0.0] * 4, s[inner], [L] * 4])
        # the knot span of each point: its chord's start vertex (a knot) or the last before
        first = np.searchsorted(inner, np.append(owner, m - 1), side="right")  # [coef]
        N = _cubic_basis(t, x, first + 3)
        try:
            coef = _least_squares(N, first, D, t.size - 4)
        except (ValueError, LinAlgError):
            break
        coef[0], coef[-1] = V[0], V[-1]                   # the run's ends, exactly
        err = np.linalg.norm(_combine(N, first, coef) - D, axis=1)
        curv = np.linalg.norm(_second_derivative(t, coef, x), axis=1)
        if not (np.all(np.isfinite(err)) and np.all(np.isfinite(curv))):
            break
        bound = np.maximum(err[:-1], err[1:]) + delta ** 2 / 8.0 * np.maximum(curv[:-1],
                                                                             curv[1:])
        over = bound > e
        if not np.any(over):
            return (NurbsCurve(3, t / L, coef, np.ones(coef.shape[0])),
                    float(np.max(bound)), None)
        worst = int(owner[int(np.argmax(bound))])           # its chord's start vertex
        knots = np.concatenate([[0], inner, [m]])             # as vertex indices
        span = np.unique(np.searchsorted(knots, owner[over], side="right") - 1)
        span = span[knots[span + 1] - knots[span] > 1]       # spans of one chord: no knot
        if span.size == 0:
            break
        inner = np.union1d(inner, (knots[span] + knots[span + 1]) // 2)
    return None, None, worst


def _cubic_basis(t: np.ndarray, x: np.ndarray, span: np.ndarray) -> np.ndarray:
    """The four cubic B-splines nonzero at each ``x``, shape (len(x), 4): column r is
    that of coefficient ``span - 3 + r``, where ``t[span] <= x <= t[span + 1]`` (The NURBS
    Book A2.2, vectorised over the points)."""
    N = np.zeros((x.size, 4))
    N[:, 0] = 1.0
    left = np.empty((x.size, 4))
    right = np.empty((x.size, 4))
    for j in range(1, 4):
        left[:, j] = x - t[span + 1 - j]
        right[:, j] = t[span + j] - x
        saved = np.zeros(x.size)
        for r in range(j):
            temp = N[:, r] / (right[:, r + 1] + left[:, j - r])
            N[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        N[:, j] = saved
    return N


def _least_squares(N: np.ndarray, first: np.ndarray, D: np.ndarray, n: int) -> np.ndarray:
    """The coefficients, shape (n, n_axes), of the cubic spline nearest ``D`` (shape
    (len(N), n_axes)) in the least-squares sense, point i's basis ``N[i]`` belonging to
    coefficients ``first[i] .. first[i] + 3``: the banded normal equations (bandwidth 3),
    solved by Cholesky (``scipy.linalg.solveh_banded``), as ``scipy.interpolate.
    make_lsq_spline(method="norm-eq")`` solves them, in O(len(N)).

    Raises ``LinAlgError`` where they are singular (a span without points)."""
    from scipy.linalg import solveh_banded

    ab = np.zeros((4, n))                 # upper form: ab[3 - d, i + d] = A[i, i + d]
    for d in range(4):
        for r in range(4 - d):
            ab[3 - d] += np.bincount(first + r + d, weights=N[:, r] * N[:, r + d],
                                     minlength=n)
    rhs = np.zeros((n, D.shape[1]))
    for r in range(4):
        for j in range(D.shape[1]):
            rhs[:, j] += np.bincount(first + r, weights=N[:, r] * D[:, j], minlength=n)
    return solveh_banded(ab, rhs, check_finite=False)


def _combine(N: np.ndarray, first: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """The spline at the points whose basis ``N`` belongs to coefficients ``first ..
    first + 3`` (:func:`_least_squares`), shape (len(N), n_axes)."""
    out = N[:, :1] * coef[first]
    for r in range(1, 4):
        out += N[:, r:r + 1] * coef[first + r]
    return out


def _second_derivative(t: np.ndarray, coef: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The second derivative of the cubic spline (knots ``t``, distinct inside,
    coefficients ``coef``) at ``x``, shape (len(x), n_axes): a spline of degree 1 on the
    same knots (The NURBS Book, Eq. 3.8 twice), the straight line between its values at
    the knots, which are its coefficients."""
    c1 = 3.0 * np.diff(coef, axis=0) / (t[4:-1] - t[1:-4])[:, None]
    c2 = 2.0 * np.diff(c1, axis=0) / (t[4:-2] - t[2:-4])[:, None]
    at = t[3:-3]                                    # its knots: 0, inner ones, L
    return np.column_stack([np.interp(x, at, c2[:, j]) for j in range(c2.shape[1])])


def _polyline(s: np.ndarray, V: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The chords through ``V`` at arc lengths ``x``, shape (len(x), n_axes)."""
    return np.column_stack([np.interp(x, s, V[:, j]) for j in range(V.shape[1])])


def _sub_curve(curve: NurbsCurve, bounds, first, k0: int, k1: int) -> NurbsCurve:
    """Pieces ``k0 .. k1 - 1`` of ``curve`` as a curve of their own (same degree, its
    parameter a linear map of the original's)."""
    p, t = curve.degree, curve.knots
    a, b = int(first[k0]), int(first[k1])
    knots = np.array(t[a:b + p + 2])
    knots[0], knots[-1] = bounds[k0], bounds[k1]
    return NurbsCurve(p, knots, curve.control_points[a:b + 1], curve.weights[a:b + 1],
                      units=curve.units)


def _mapped_feed(feed: FeedLimit, bounds, parts, edges) -> FeedLimit:
    """``feed`` along the joined curve: each part's old parameter range maps linearly onto
    its new one (exact for kept pieces; a fitted run has one feed, joints where it changes
    being corners)."""
    old = np.array([bounds[parts[0][0]]] + [bounds[b] for _, b in parts])
    bp = np.interp(feed.breakpoints, old, edges)
    bp[0], bp[-1] = 0.0, 1.0
    keep = np.concatenate([[True], np.diff(bp) > 0])
    v = feed.speeds[keep[1:]]
    bp = bp[keep]
    same = np.concatenate([[False], v[1:] == v[:-1]])      # merge equal neighbours
    return FeedLimit(np.concatenate([bp[:-1][~same], [1.0]]), v[~same])
