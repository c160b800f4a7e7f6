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

import numpy as np

from ..errors import InvalidCurveError
from ..nurbs import NurbsCurve, make_arc

__all__ = ["with_end_point", "arc_by_center", "arc_by_bulge", "arc_by_radius"]


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
    a0 = math.atan2(s[1] - c[1], s[0] - c[0])
    a1 = math.atan2(e[1] - c[1], e[0] - c[0])
    sweep = (a0 - a1) % (2 * math.pi) if clockwise else (a1 - a0) % (2 * math.pi)
    if sweep == 0.0 or np.array_equal(s, e):
        sweep = 2 * math.pi
    sign = -1.0 if clockwise else 1.0
    pieces = [
        make_arc(c, radius, a0, a0 + sign * 2 * math.pi, name=name, units=units)
        for _ in range(turns - 1)
    ]
    arc = make_arc(c, radius, a0, a0 + sign * sweep, name=name, units=units)
    pieces.append(with_end_point(arc, e))
    return pieces


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
