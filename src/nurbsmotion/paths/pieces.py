"""Exact path pieces the G-code and DXF readers build: lines and circular arcs.

Arcs are exact rational quadratics (:func:`nurbsmotion.make_arc`). A programmed arc ends
at its programmed end point even when, by rounding in the file, the end point's distance
to the centre differs slightly from the start point's: the arc is built with the start
radius and its last control point (the curve's end) is then moved onto the programmed end
point. The readers check the radius mismatch first (LinuxCNC's rule for G2/G3), so the
move is at most a few micrometres.
"""

from __future__ import annotations

import math
from array import array
from itertools import chain

import numpy as np

from ..errors import InvalidCurveError
from ..nurbs import NurbsCurve, make_arc, point_extent

__all__ = ["with_end_point", "arc_by_center", "arc_sweep", "HELIX_TOLERANCE", "arc_by_bulge", "arc_by_radius", "PieceChain",
           "bezier_elevation", "arc_spans", "arc_angle_deviation", "spiral_segments"]


def with_end_point(curve: NurbsCurve, end) -> NurbsCurve:
    """``curve`` with its last control point (its end point) replaced by ``end``."""
    points = np.array(curve.control_points)
    points[-1] = end
    return NurbsCurve(
        curve.degree, curve.knots, points, curve.weights, name=curve.name, units=curve.units
    )


def arc_by_center(
    start, end, center, *, clockwise: bool, turns: int = 1, name=None, units=None
) -> list[NurbsCurve]:
    """Arc pieces from ``start`` round ``center`` to ``end`` (XY), as G2/G3 program it.

    Parameters
    ----------
    start, end, center : array_like, shape (2,)
        Points [path units]. ``end == start`` means a full circle.
    clockwise : bool
        G2 (True) or G3 (False), seen from +Z.
    turns : int
        Number of turns as LinuxCNC's P word: ``turns - 1`` full circles precede the arc.

    Returns
    -------
    list of NurbsCurve
        ``turns - 1`` full circles, then the arc ending exactly at ``end``.
    """
    s, e, c = (np.asarray(v, dtype=float) for v in (start, end, center))
    radius = float(np.hypot(*(s - c)))
    if radius == 0.0:
        raise InvalidCurveError(f"arc centre {c.tolist()} coincides with its start point")
    a0, sweep = arc_sweep(s, e, c, clockwise)
    pieces = [
        make_arc(c, radius, a0, a0 + math.copysign(2 * math.pi, sweep), name=name, units=units)
        for _ in range(turns - 1)
    ]
    arc = make_arc(c, radius, a0, a0 + sweep, name=name, units=units)
    pieces.append(with_end_point(arc, e))
    return pieces


def arc_sweep(start, end, center, clockwise: bool) -> tuple[float, float]:
    """Start angle and signed sweep [rad] of a G2/G3 arc (one turn) from ``start`` round
    ``center`` to ``end`` (each (x, y)): in (0, 2 pi], negative clockwise; a full turn
    when the end angle equals the start angle or ``end == start``."""
    a0 = math.atan2(start[1] - center[1], start[0] - center[0])
    a1 = math.atan2(end[1] - center[1], end[0] - center[0])
    sweep = (a0 - a1) % (2 * math.pi) if clockwise else (a1 - a0) % (2 * math.pi)
    if sweep == 0.0 or (start[0] == end[0] and start[1] == end[1]):
        sweep = 2 * math.pi
    return a0, -sweep if clockwise else sweep


def arc_by_radius(start, end, radius: float, *, clockwise: bool, name=None, units=None):
    """Arc piece in G2/G3 radius format: ``radius > 0`` at most a half turn, ``< 0`` more.

    Raises
    ------
    InvalidCurveError
        If start and end coincide, or are further apart than the diameter.
    """
    s, e = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    chord = e - s
    d = float(np.hypot(*chord))
    r = abs(float(radius))
    if d == 0.0:
        raise InvalidCurveError("a radius-format arc cannot end where it starts")
    if d > 2 * r * (1 + 1e-9):
        raise InvalidCurveError(
            f"arc radius {r:g} is too small for the chord of length {d:g} from {s.tolist()} "
            f"to {e.tolist()}"
        )
    h = math.sqrt(max(r * r - d * d / 4, 0.0))
    left = np.array([-chord[1], chord[0]]) / d
    side = 1.0 if (not clockwise) == (radius > 0) else -1.0
    center = (s + e) / 2 + side * h * left
    return arc_by_center(s, e, center, clockwise=clockwise, name=name, units=units)[0]


def arc_by_bulge(start, end, bulge: float, *, name=None, units=None) -> NurbsCurve:
    """Arc piece of a DXF polyline segment: ``bulge = tan(sweep / 4)``, > 0 counter-clockwise.

    The centre lies at distance ``(d / 2) / tan(sweep / 2)`` to the left of the chord of
    length d (to the right for a negative sweep or one beyond a half turn).
    """
    s, e = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    chord = e - s
    d = float(np.hypot(*chord))
    if d == 0.0:
        raise InvalidCurveError(f"polyline segment from {s.tolist()} to itself")
    sweep = 4.0 * math.atan(bulge)
    left = np.array([-chord[1], chord[0]]) / d
    center = (s + e) / 2 + left * (d / 2) / math.tan(sweep / 2)
    return arc_by_center(s, e, center, clockwise=bulge < 0, name=name, units=units)[0]


# ---------------------------------------------------------------------- bulk joining
HELIX_TOLERANCE = 1e-9
"""Largest distance of a helix's (or spiral's) cubic approximation from the true curve,
relative to its radius."""
_HELIX_STEP = (384.0 * HELIX_TOLERANCE) ** 0.25
"""Angle [rad] of one cubic Hermite piece of a helix: it deviates at most r h^4 / 384."""


def arc_angle_deviation(phi: np.ndarray) -> np.ndarray:
    """Largest ``|theta(u) - phi u|`` [rad] on a rational quadratic circular arc of angle
    ``phi`` (in (0, pi]; weights 1, cos(phi / 2), 1), whose angle runs as
    ``tan((theta - phi / 2) / 2) = (2 u - 1) tan(phi / 4)`` (the stereographic
    parametrisation); about ``phi**3 / 249``."""
    phi = np.asarray(phi, dtype=float)
    t = np.tan(phi / 4)
    s = np.minimum(1.0, np.sqrt(np.maximum(4 * t / phi - 1, 0.0)) / t)  # where the derivative is 0
    return 2 * np.arctan(s * t) - s * phi / 2


def spiral_segments(sweep: np.ndarray, radius0: np.ndarray, radius1: np.ndarray,
                    rise: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How :meth:`PieceChain.build` splits helices and spirals into cubic segments.

    A *rational* segment is a rational quadratic arc (at most a quarter turn) whose radius
    and other coordinates move linearly in its parameter: exact on the circle, off the
    true spiral only radially and along the other axes, by at most ``drift *
    arc_angle_deviation(angle)`` with ``drift = hypot(radius1 - radius0, rise) / |sweep|``
    [length / rad]. A *Hermite* segment (angle at most ``(384 HELIX_TOLERANCE)^(1/4)``)
    is exact along the other axes and off the circle by at most ``r h^4 / 384``. Each
    piece takes the kind that needs fewer segments within :data:`HELIX_TOLERANCE` of its
    smaller radius: rational for the spirals of rounded arc centres (a tiny drift), Hermite
    for steep helices.

    Parameters
    ----------
    sweep : ndarray, shape (n,)
        Signed sweep of each piece [rad].
    radius0, radius1 : ndarray, shape (n,)
        Start and end radius [length].
    rise : ndarray, shape (n,)
        Distance the other coordinates travel [length].

    Returns
    -------
    count : ndarray of int64, shape (n,)
        Segments of each piece.
    rational : ndarray of bool, shape (n,)
        Whether the piece is built of rational segments.
    """
    sweep = np.abs(np.asarray(sweep, dtype=float))
    hermite = np.maximum(1, np.ceil(sweep / _HELIX_STEP)).astype(np.int64)
    allowed = HELIX_TOLERANCE * np.minimum(radius0, radius1)  # [length]
    drift = np.hypot(np.asarray(radius1) - radius0, rise) / np.where(sweep > 0, sweep, 1.0)  # [length / rad]
    with np.errstate(divide="ignore"):
        step = np.cbrt(249.0 * allowed / drift)  # the angle where drift * phi^3 / 249 = allowed
    count = np.maximum(arc_spans(sweep), np.ceil(sweep / np.minimum(step, np.pi / 2) - 1e-12))
    count = np.minimum(count, hermite + 1).astype(np.int64)  # beyond the Hermite count: Hermite
    for _ in range(64):  # the estimate is within a segment or two; make sure
        short = (count <= hermite) & (drift * arc_angle_deviation(sweep / count) > allowed)
        if not np.any(short):
            break
        count[short] += 1
    rational = count <= hermite
    return np.where(rational, count, hermite), rational


def bezier_elevation(q: int, p: int) -> np.ndarray:
    """Matrix ``E`` (shape (p + 1, q + 1)) that raises a Bézier segment of degree q to
    degree p: new homogeneous points ``E @ H`` (The NURBS Book, eq. 5.36)."""
    E = np.zeros((p + 1, q + 1))
    t = p - q
    for i in range(p + 1):
        for j in range(max(0, i - t), min(q, i) + 1):
            E[i, j] = math.comb(q, j) * math.comb(t, i - j) / math.comb(p, i)
    return E


def arc_spans(sweep: np.ndarray) -> np.ndarray:
    """Number of rational quadratic segments of arcs of the given sweeps [rad]: one per
    started quarter turn, as :func:`nurbsmotion.make_arc` splits them."""
    return np.maximum(1, np.ceil(np.abs(sweep) / (math.pi / 2) - 1e-12)).astype(np.int64)


class PieceChain:
    """The pieces of one path in order, kept as flat arrays until :meth:`build` joins them.

    A CAM program of a million moves is a million pieces; one :class:`NurbsCurve` per
    piece would cost minutes and gigabytes. Here a line costs its end point and an arc
    seven numbers; :meth:`build` makes the joined curve in a few array operations. The
    result is the curve :func:`nurbsmotion.joining.join_with_edges` makes of the same
    pieces: degree = the highest piece degree, each piece a span of the parameter
    proportional to its arc length, a knot of multiplicity p at every junction, the shared
    control point the end of the earlier piece, weights of each piece scaled by a common
    factor so that they agree at the junction. Lines and arcs are raised to the path's
    degree by the Bézier degree-elevation formula (exact; :func:`bezier_elevation`).

    Parameters
    ----------
    start : sequence of float, length n_axes
        Where the first piece starts [path units].
    """

    _ARC_FIELDS = 7  # first column, second column, centre (2), radius, start angle, sweep
    _SPIRAL_FIELDS = 8  # the same with the start and the end radius

    def __init__(self, start):
        self.start = [float(x) for x in start]
        self.n_axes = len(self.start)
        self.last = list(self.start)  # end of the last piece
        self.kind = array("b")  # 0 line, 1 arc, 2 curve
        self.ends = array("d")  # n_axes per piece
        self.lengths = array("d")
        self.arcs = array("d")  # _ARC_FIELDS per arc
        self.spirals = array("d")  # _SPIRAL_FIELDS per helix or spiral
        self.curves: list[NurbsCurve] = []

    def __len__(self) -> int:
        return len(self.kind)

    def add_line(self, end) -> float:
        """A straight piece to ``end`` (shape (n_axes,)); returns its length."""
        length = math.dist(self.last, end)
        self.kind.append(0)
        self.ends.extend(end)
        self.lengths.append(length)
        self.last = list(end)
        return length

    def add_lines(self, ends: np.ndarray) -> None:
        """Straight pieces through the rows of ``ends`` (shape (n_pieces, n_axes)) in
        order, as :meth:`add_line` adds each."""
        ends = np.ascontiguousarray(ends, dtype=float)
        if ends.ndim != 2 or ends.shape[1] != self.n_axes:
            raise InvalidCurveError(
                f"line ends of shape {ends.shape} cannot join a path of {self.n_axes} axes")
        if not len(ends):
            return
        points = ends.tolist()
        self.kind.frombytes(bytes(len(points)))  # kind 0: line
        self.ends.frombytes(ends.tobytes())
        self.lengths.extend(map(math.dist, chain([self.last], points), points))
        self.last = points[-1]

    def add_arc(self, end, cols: tuple, center, radius: float, start_angle: float, sweep: float) -> float:
        """A circular arc in the coordinates ``cols`` (two column indices) round
        ``center`` from ``start_angle`` through ``sweep`` [rad] (negative: clockwise); the
        other coordinates stay at the start. The arc ends exactly at ``end`` (see
        :func:`with_end_point`). Returns its length ``radius * |sweep|``."""
        length = radius * abs(sweep)
        self.kind.append(1)
        self.ends.extend(end)
        self.lengths.append(length)
        self.arcs.extend((cols[0], cols[1], center[0], center[1], radius, start_angle, sweep))
        self.last = list(end)
        return length

    def add_spiral(self, end, cols: tuple, center, radius0: float, radius1: float,
                   start_angle: float, sweep: float, length: float) -> float:
        """A helix or spiral: the angle runs ``start_angle -> start_angle + sweep`` [rad]
        round ``center`` in the coordinates ``cols``, the radius ``radius0 -> radius1`` and
        every other coordinate from the start to ``end`` linearly in the angle. Built of
        cubic segments within :data:`HELIX_TOLERANCE` of the smaller radius, ending exactly
        at ``end``: rational arcs with a linear radial and axial drift, or Hermite pieces,
        whichever needs fewer (:func:`spiral_segments`).
        ``length`` is the caller's arc length of it (its parameter share); returned."""
        self.kind.append(3)
        self.ends.extend(end)
        self.lengths.append(length)
        self.spirals.extend((cols[0], cols[1], center[0], center[1], radius0, radius1, start_angle, sweep))
        self.last = list(end)
        return length

    def add_curve(self, curve: NurbsCurve, length: float | None = None) -> float:
        """Any NURBS piece (starting at the end of the last one); returns its length."""
        if curve.n_axes != self.n_axes:
            raise InvalidCurveError(f"a piece with {curve.n_axes} axes cannot join a path of {self.n_axes}")
        length = curve.length if length is None else float(length)
        self.kind.append(2)
        end = curve.control_points[-1].tolist()
        self.ends.extend(end)
        self.lengths.append(length)
        self.curves.append(curve)
        self.last = end
        return length

    def build(self, *, name: str | None = None, units: str | None = None,
              tolerance: float = 1e-9) -> tuple[NurbsCurve, np.ndarray]:
        """The joined path and the parameter where each piece starts.

        Returns
        -------
        curve : NurbsCurve
        edges : ndarray, shape (n_pieces + 1,)
            ``edges[k]`` .. ``edges[k + 1]`` is piece k; ``edges[0] = 0``, ``edges[-1] = 1``.

        Raises
        ------
        InvalidCurveError
            If there is no piece, a curve piece does not start where the previous one
            ends (within ``tolerance`` times the path size), or the joined curve is invalid.
        """
        n, d = len(self.kind), self.n_axes
        if n == 0:
            raise InvalidCurveError("cannot join an empty list of pieces")
        kind = np.frombuffer(self.kind, dtype=np.int8)
        ends = np.frombuffer(self.ends, dtype=float).reshape(n, d)
        starts = np.vstack([np.array(self.start)[None, :], ends[:-1]])
        lengths = np.frombuffer(self.lengths, dtype=float)
        arcs = np.frombuffer(self.arcs, dtype=float).reshape(-1, self._ARC_FIELDS)
        spirals = np.frombuffer(self.spirals, dtype=float).reshape(-1, self._SPIRAL_FIELDS)
        lines, arc_idx, curve_idx, spiral_idx = (np.flatnonzero(kind == k) for k in (0, 1, 2, 3))
        p = max([1] + ([2] if len(arcs) else []) + ([3] if len(spirals) else [])
                + [c.degree for c in self.curves])

        size = point_extent(np.vstack([starts[:1], ends]))
        for k, c in zip(curve_idx, self.curves):
            gap = float(np.linalg.norm(c.control_points[0] - starts[k]))
            if gap > tolerance * size:
                raise InvalidCurveError(
                    f"piece {k} ({c.name}) starts at {c.control_points[0].tolist()} but the path "
                    f"is at {starts[k].tolist()}: a gap of {gap:.6g}, more than the tolerance "
                    f"{tolerance:g} x path size {size:.6g}")
        curves = [_raise_degree(c, p) for c in self.curves]

        total = float(np.sum(lengths))
        if not total > 0:
            raise InvalidCurveError("degenerate path: its pieces have zero length")
        edges = np.concatenate([[0.0], np.cumsum(lengths) / total])
        edges[-1] = 1.0
        a, b = edges[:-1], edges[1:]

        m_arc = arc_spans(arcs[:, 6])
        m_spiral, rational = spiral_segments(
            spirals[:, 7], spirals[:, 4], spirals[:, 5],
            _other_distance(starts[spiral_idx], ends[spiral_idx], spirals[:, :2]))
        count = np.empty(n, dtype=np.int64)  # new control points (= knots) per piece
        count[lines] = p
        count[arc_idx] = p * m_arc
        count[spiral_idx] = p * m_spiral
        count[curve_idx] = [c.n_control_points - 1 for c in curves]
        offset = np.concatenate([[1], 1 + np.cumsum(count)[:-1]])  # row of each piece's first new point
        N = 1 + int(np.sum(count))
        P = np.empty((N, d))
        W = np.empty(N)
        K = np.empty(N + p + 1)
        K[: p + 1], K[-1] = 0.0, 1.0

        # Weights: a common factor per piece so that neighbours agree at the junction (lines
        # and arcs end with weight 1; a curve piece may not).
        scale = np.empty(n)
        w_run, k_prev = (curves[0].weights[0] if len(curve_idx) and curve_idx[0] == 0 else 1.0), 0
        for k, c in zip(curve_idx, curves):
            scale[k_prev:k] = w_run
            scale[k] = w_run / c.weights[0]
            w_run, k_prev = c.weights[-1] * scale[k], k + 1
        scale[k_prev:] = w_run
        if kind[0] == 2:  # a curve piece first: kept exactly, weights and all
            P[0], W[0] = curves[0].control_points[0], curves[0].weights[0]
        else:
            P[0], W[0] = starts[0], scale[0]

        if len(lines):
            t = np.arange(1, p + 1) / p
            S, E = starts[lines], ends[lines]
            rows = offset[lines][:, None] + np.arange(p)
            P[rows] = S[:, None, :] + (E - S)[:, None, :] * t[None, :, None]
            P[rows[:, -1]] = E  # exactly the programmed end
            W[rows] = scale[lines][:, None]
            K[p + rows] = b[lines][:, None]
        if len(arc_idx):
            self._arc_rows(arcs, m_arc, arc_idx, starts, ends, a, b, scale, offset, p, P, W, K)
        for kind in (False, True):  # Hermite, rational
            sel = rational == kind
            if np.any(sel):
                self._spiral_rows(spirals[sel], m_spiral[sel], spiral_idx[sel], kind, starts, ends, a, b,
                                  scale, offset, p, P, W, K)
        for k, c in zip(curve_idx, curves):
            r0, cnt = offset[k], c.n_control_points - 1
            P[r0: r0 + cnt] = c.control_points[1:]
            W[r0: r0 + cnt] = c.weights[1:] * scale[k]
            interior = c.knots[p + 1: c.n_control_points]
            K[p + r0: p + r0 + len(interior)] = a[k] + (b[k] - a[k]) * interior
            K[p + r0 + len(interior): p + r0 + cnt] = b[k]
        curve = NurbsCurve(p, K, P, W, name=name, units=units)
        return curve, edges

    def _spiral_rows(self, spirals, m, idx, rational, starts, ends, a, b, scale, offset, p, P, W, K) -> None:
        """Fill the rows of helix or spiral pieces (:func:`spiral_segments`): cubic Hermite
        segments, or rational quadratic arcs with a radius and other coordinates linear in
        the parameter, raised to cubics."""
        _, owner, within = _segments(m)
        ci, cj = spirals[owner, 0].astype(np.int64), spirals[owner, 1].astype(np.int64)
        cx, cy, r0, r1, a0, sweep = (spirals[owner, f] for f in range(2, 8))
        S, E = starts[idx][owner], ends[idx][owner]
        seg = np.arange(len(owner))
        t0, t1 = within / m[owner], (within + 1) / m[owner]
        if rational:
            # (w C, w) of an arc whose unit vector is the rational quadratic e(u) (weights 1,
            # w, 1) times a point linear in u, V(u) = c + rho(u) e + L(u): the product of the
            # Bernstein bases of degrees 2 and 1 gives a cubic (The NURBS Book, eq. 5.36).
            ang0, ang1 = a0 + sweep * t0, a0 + sweep * t1
            w = np.cos((ang1 - ang0) / 2)
            units = [(np.cos(ang0), np.sin(ang0)),
                     (np.cos((ang0 + ang1) / 2) / w, np.sin((ang0 + ang1) / 2) / w),
                     (np.cos(ang1), np.sin(ang1))]

            def point(i: int, t: np.ndarray) -> np.ndarray:  # V at the arc's point i and parameter end t
                X = S + t[:, None] * (E - S)
                rad = r0 + (r1 - r0) * t
                X[seg, ci], X[seg, cj] = cx + rad * units[i][0], cy + rad * units[i][1]
                return X

            Wq = np.stack([np.ones_like(w), (1 + 2 * w) / 3, (1 + 2 * w) / 3, np.ones_like(w)], axis=1)
            w2 = 2 * w[:, None]
            Q = np.stack([point(0, t0), (point(0, t1) + w2 * point(1, t0)) / (1 + w2),
                          (w2 * point(1, t1) + point(2, t0)) / (1 + w2), point(2, t1)],
                         axis=1)  # (segments, 4, d)
            self._place(Q, Wq, m, idx, starts, ends, a, b, scale, offset, p, P, W, K)
            return
        ends_of = []  # point and d/dangle at the start (t0) and the end (t1) of each segment
        for t in (t0, t1):
            ang, rad = a0 + sweep * t, r0 + (r1 - r0) * t
            c, s = np.cos(ang), np.sin(ang)
            dr = (r1 - r0) / sweep
            X = S + t[:, None] * (E - S)
            D = (E - S) / sweep[:, None]  # d/dangle of the coordinates that move linearly
            X[seg, ci], X[seg, cj] = cx + rad * c, cy + rad * s
            D[seg, ci], D[seg, cj] = dr * c - rad * s, dr * s + rad * c
            ends_of.append((X, D))
        (X0, D0), (X1, D1) = ends_of
        step = (sweep / m[owner])[:, None]
        Q = np.stack([X0, X0 + D0 * step / 3, X1 - D1 * step / 3, X1], axis=1)  # (segments, 4, d)
        self._place(Q, np.ones(Q.shape[:2]), m, idx, starts, ends, a, b, scale, offset, p, P, W, K)

    def _arc_rows(self, arcs, m, idx, starts, ends, a, b, scale, offset, p, P, W, K) -> None:
        """Fill the rows of every arc piece: its rational quadratic segments, as
        :func:`nurbsmotion.make_arc` makes them."""
        _, owner, within = _segments(m)
        ci, cj = arcs[owner, 0].astype(np.int64), arcs[owner, 1].astype(np.int64)
        cx, cy, r = arcs[owner, 2], arcs[owner, 3], arcs[owner, 4]
        step = arcs[owner, 6] / m[owner]
        a0 = arcs[owner, 5] + within * step
        w_mid = np.cos(step / 2)
        seg = np.arange(len(owner))
        Q = np.repeat(starts[idx][owner][:, None, :], 3, axis=1)  # (segments, 3, d)
        for j, (angle, radius) in enumerate(((a0, r), (a0 + step / 2, r / w_mid), (a0 + step, r))):
            Q[seg, j, ci] = cx + radius * np.cos(angle)
            Q[seg, j, cj] = cy + radius * np.sin(angle)
        Wq = np.ones((len(owner), 3))
        Wq[:, 1] = w_mid
        self._place(Q, Wq, m, idx, starts, ends, a, b, scale, offset, p, P, W, K)

    @staticmethod
    def _place(Q, Wq, m, idx, starts, ends, a, b, scale, offset, p, P, W, K) -> None:
        """Put the Bézier segments ``Q`` (shape (segments, q + 1, d), weights ``Wq``) of
        the pieces ``idx`` (``m[k]`` segments each) into the rows of P, W and K, raised to
        degree p; each piece starts at the previous end and ends exactly at its own."""
        first, owner, within = _segments(m)
        Q[first, 0] = starts[idx]
        Q[first + m - 1, -1] = ends[idx]
        q = Q.shape[1] - 1
        if p > q:
            H = np.einsum("ij,sjk->sik", bezier_elevation(q, p),
                          np.concatenate([Q * Wq[..., None], Wq[..., None]], axis=2))
            Wq = H[..., -1]
            Q = H[..., :-1] / Wq[..., None]
            Q[first + m - 1, -1] = ends[idx]
        rows = offset[idx][owner][:, None] + within[:, None] * p + np.arange(p)
        P[rows] = Q[:, 1:]
        W[rows] = Wq[:, 1:] * scale[idx][owner][:, None]
        knot = a[idx][owner] + (b - a)[idx][owner] * (within + 1) / m[owner]
        knot[first + m - 1] = b[idx]
        K[p + rows] = knot[:, None]


def _other_distance(starts: np.ndarray, ends: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Distance from ``starts`` to ``ends`` (shape (n, n_axes)) over every coordinate but
    the two in ``cols`` (shape (n, 2), column indices) of each row."""
    delta = ends - starts
    rows = np.arange(len(delta))
    for k in range(2):
        delta[rows, cols[:, k].astype(np.int64)] = 0.0
    return np.sqrt(np.sum(delta * delta, axis=1))


def _segments(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For pieces of ``m[k]`` segments: the first segment of each piece, the piece of each
    segment and each segment's index within its piece."""
    first = np.cumsum(m) - m
    owner = np.repeat(np.arange(len(m)), m)
    return first, owner, np.arange(int(np.sum(m))) - first[owner]


def _raise_degree(curve: NurbsCurve, p: int) -> NurbsCurve:
    """``curve`` at degree p: by the Bézier formula when every interior knot has full
    multiplicity (lines, arcs, helices), else by :func:`nurbsmotion.joining.elevate_degree`."""
    q = curve.degree
    if q == p:
        return curve
    interior = curve.knots[q + 1: -q - 1]
    if len(interior) == 0 or (len(interior) % q == 0 and np.all(
            interior.reshape(-1, q) == interior.reshape(-1, q)[:, :1])):
        spans = (curve.n_control_points - 1) // q
        w = curve.weights
        H = np.hstack([curve.control_points * w[:, None], w[:, None]])
        idx = np.arange(spans)[:, None] * q + np.arange(q + 1)
        Hs = np.einsum("ij,sjk->sik", bezier_elevation(q, p), H[idx])
        H2 = np.vstack([Hs[0, :1], Hs[:, 1:].reshape(-1, H.shape[1])])
        breaks = np.concatenate([[0.0], interior[::q], [1.0]]) if len(interior) else np.array([0.0, 1.0])
        knots = np.concatenate([[0.0] * (p + 1), np.repeat(breaks[1:-1], p), [1.0] * (p + 1)])
        pts = H2[:, :-1] / H2[:, -1:]
        pts[0], pts[-1] = curve.control_points[0], curve.control_points[-1]
        return NurbsCurve(p, knots, pts, H2[:, -1], name=curve.name, units=curve.units)
    from ..joining import elevate_degree

    return elevate_degree(curve, p)
