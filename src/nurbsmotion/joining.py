"""Degree elevation, Bézier decomposition and joining of NURBS curves into one path.

Paths read from G-code or DXF arrive as pieces (lines, arcs, NURBS blocks) of different
degrees. :func:`join` chains them into one clamped NURBS of the highest degree, the form
every interpolator in nurbsmotion reads.

Method
------
Degree elevation and Bézier decomposition are both *exact changes of basis*: the curve's
homogeneous form ``(w(u) C(u), w(u))`` is a piecewise polynomial that lies in the target
spline space (The NURBS Book, section 5.5: elevating p to p + t raises every knot's
multiplicity by t; section 5.3: inserting knots to multiplicity p gives the Bézier
segments). Instead of the recurrences A5.9 / A5.1 the new control points are obtained by
interpolating the homogeneous form at the Greville abscissae of the target knot vector,
where the collocation problem is uniquely solvable (Schoenberg-Whitney) and well
conditioned for the low degrees of toolpaths. In exact arithmetic this reproduces the
curve; in floating point the elevated curve equals the original to about 1e-15 of the
path size (checked in the tests against evaluation).

Joining
-------
Consecutive pieces must meet: the end of one within ``tolerance`` times the path size
(the largest extent of all control points) of the start of the next, or
:class:`InvalidCurveError` names both pieces and the gap. The shared control point is the
end of the earlier piece. Each junction is a knot of full multiplicity (degree p), so the
path is C0 there and :meth:`NurbsCurve.sharp_corners` reports the junctions with a
tangent jump. Each piece gets a parameter span proportional to its arc length, so
``|C'(u)|`` stays comparable from piece to piece (about the total length), which keeps the
interpolators' first Taylor step sensible across junctions. Weights of each piece are
scaled (a rational curve is unchanged by a common factor on its weights) so that the two
weights meeting at a junction agree.

Glossary
--------
p : degree; t : knot vector; w : weights; u : curve parameter in [0, 1];
H : homogeneous control points ``(w P, w)``.
"""

from __future__ import annotations

from typing import Iterable, Sequence

import numpy as np

from .errors import InvalidCurveError
from .nurbs import NurbsCurve, point_extent

__all__ = ["elevate_degree", "bezier_segments", "join", "join_with_edges", "DEFAULT_JOIN_TOLERANCE"]

DEFAULT_JOIN_TOLERANCE = 1e-9
"""Largest gap between pieces accepted by :func:`join`, relative to the path size."""


def _homogeneous(curve: NurbsCurve):
    w = curve.weights
    H = np.hstack([curve.control_points * w[:, None], w[:, None]])
    from scipy.interpolate import BSpline  # lazily: importing it costs ~0.5 s

    return BSpline(curve.knots, H, curve.degree, extrapolate=False)


def _refit(curve: NurbsCurve, knots: np.ndarray, degree: int) -> NurbsCurve:
    """The curve (or its part over ``[knots[0], knots[-1]]``) in the spline space of
    ``(degree, knots)``, which must contain it."""
    n = len(knots) - degree - 1
    sums = np.concatenate([[0.0], np.cumsum(knots)])
    greville = (sums[degree + 1 : degree + 1 + n] - sums[1 : 1 + n]) / degree
    greville = np.clip(greville, knots[degree], knots[n])  # the mean of equal knots may round
    H = _homogeneous(curve)(greville)
    from scipy.interpolate import make_interp_spline

    fit = make_interp_spline(greville, H, k=degree, t=knots)
    w = fit.c[:, -1]
    return NurbsCurve(
        degree, knots, fit.c[:, :-1] / w[:, None], w, name=curve.name, units=curve.units
    )


def elevate_degree(curve: NurbsCurve, degree: int) -> NurbsCurve:
    """The same curve with its degree raised to ``degree`` (The NURBS Book, section 5.5).

    Parameters
    ----------
    curve : NurbsCurve
        Curve of degree p.
    degree : int
        Target degree ``>= p``. Every distinct knot's multiplicity grows by
        ``degree - p``, so the continuity at every knot is kept.

    Returns
    -------
    NurbsCurve
        Equal to ``curve`` at every parameter (to rounding), with the same name and units.

    Raises
    ------
    InvalidCurveError
        If ``degree`` is lower than the curve's degree.
    """
    p = curve.degree
    if isinstance(degree, bool) or int(degree) != degree or degree < p:
        raise InvalidCurveError(
            f"cannot elevate a degree-{p} curve to degree {degree!r}; the target must be an "
            f"integer >= {p}"
        )
    degree = int(degree)
    if degree == p:
        return curve
    values, counts = np.unique(curve.knots, return_counts=True)
    knots = np.repeat(values, counts + (degree - p))
    return _refit(curve, knots, degree)


def bezier_segments(curve: NurbsCurve) -> list[NurbsCurve]:
    """The curve split at its knots into rational Bézier segments (The NURBS Book, 5.3).

    Returns
    -------
    list of NurbsCurve
        One per non-empty knot span, each of the curve's degree with ``p + 1`` control
        points and knots ``[0]*(p+1) + [1]*(p+1)``; segment k covers
        ``[breakpoints[k], breakpoints[k+1]]`` of the curve, linearly reparametrised.
    """
    p = curve.degree
    bp = curve.breakpoints
    return [_refit(curve, np.repeat([a, b], p + 1), p) for a, b in zip(bp[:-1], bp[1:])]


def _label(curves: Sequence[NurbsCurve], i: int) -> str:
    name = curves[i].name
    return f"piece {i} ({name})" if name else f"piece {i}"


def join(
    curves: Iterable[NurbsCurve],
    *,
    tolerance: float = DEFAULT_JOIN_TOLERANCE,
    name: str | None = None,
    units: str | None = None,
) -> NurbsCurve:
    """Chain curves whose ends meet into one clamped NURBS (see the module docstring).

    Parameters
    ----------
    curves : iterable of NurbsCurve
        Pieces in path order, all with the same number of axes and compatible units
        (``None`` is compatible with anything).
    tolerance : float
        Largest accepted gap between the end of a piece and the start of the next,
        relative to the path size (the largest extent of all control points over any axis).
    name : str, optional
        Name of the joined path.
    units : str, optional
        Units of the joined path; by default the pieces' common units.

    Returns
    -------
    NurbsCurve
        Degree = the highest degree of the pieces; piece k occupies
        ``[s_k / L, s_(k+1) / L]`` of the parameter, with ``s_k`` the arc length before it
        and ``L`` the total length; junctions are knots of multiplicity = degree.

    Raises
    ------
    InvalidCurveError
        If there are no pieces, axes or units differ, or two consecutive pieces do not
        meet (naming both pieces, their end points and the gap).
    """
    return join_with_edges(curves, tolerance=tolerance, name=name, units=units)[0]


def join_with_edges(
    curves: Iterable[NurbsCurve],
    *,
    tolerance: float = DEFAULT_JOIN_TOLERANCE,
    name: str | None = None,
    units: str | None = None,
    lengths: Sequence[float] | None = None,
) -> tuple[NurbsCurve, np.ndarray]:
    """:func:`join`, also returning where each piece starts.

    Returns
    -------
    curve : NurbsCurve
        As :func:`join`.
    edges : ndarray, shape (n_pieces + 1,)
        Parameter of the joined curve where piece k starts (``edges[k]``) and ends
        (``edges[k + 1]``); ``edges[0] = 0``, ``edges[-1] = 1``.

    Other Parameters
    ----------------
    lengths : sequence of float, optional
        The pieces' arc lengths where the caller knows them exactly (lines, arcs);
        ``None`` entries (or no sequence) are computed.
    """
    pieces = list(curves)
    if not pieces:
        raise InvalidCurveError("cannot join an empty list of curves")
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise InvalidCurveError(f"join tolerance must be finite and >= 0, got {tolerance!r}")
    axes = {c.n_axes for c in pieces}
    if len(axes) > 1:
        i = next(i for i, c in enumerate(pieces) if c.n_axes != pieces[0].n_axes)
        raise InvalidCurveError(
            f"cannot join curves with different numbers of axes: {_label(pieces, 0)} has "
            f"{pieces[0].n_axes}, {_label(pieces, i)} has {pieces[i].n_axes}"
        )
    piece_units = {c.units for c in pieces} - {None}
    if len(piece_units) > 1:
        raise InvalidCurveError(f"cannot join curves in different units: {sorted(piece_units)}")
    unit = units if units is not None else (piece_units.pop() if piece_units else None)

    all_points = np.vstack([c.control_points for c in pieces])
    size = point_extent(all_points)
    for i in range(len(pieces) - 1):
        end, start = pieces[i].control_points[-1], pieces[i + 1].control_points[0]
        gap = float(np.linalg.norm(end - start))
        if gap > tolerance * size:
            raise InvalidCurveError(
                f"{_label(pieces, i)} ends at {end.tolist()} but {_label(pieces, i + 1)} "
                f"starts at {start.tolist()}: a gap of {gap:.6g}, more than the tolerance "
                f"{tolerance:g} x path size {size:.6g}"
            )
    if len(pieces) == 1:
        c = pieces[0]
        curve = NurbsCurve(c.degree, c.knots, c.control_points, c.weights, name=name, units=unit)
        return curve, np.array([0.0, 1.0])

    p = max(c.degree for c in pieces)
    pieces = [elevate_degree(c, p) for c in pieces]
    known = list(lengths) if lengths is not None else [None] * len(pieces)
    lengths = np.array([c.length if k is None else float(k) for c, k in zip(pieces, known)])
    edges = np.concatenate([[0.0], np.cumsum(lengths) / np.sum(lengths)])
    edges[-1] = 1.0
    knots = [np.zeros(p + 1)]
    points = [pieces[0].control_points]
    weights = [pieces[0].weights]
    for k, c in enumerate(pieces):
        a, b = edges[k], edges[k + 1]
        knots.append(a + (b - a) * c.knots[p + 1 : -p - 1])
        if k > 0:
            scale = weights[-1][-1] / c.weights[0]
            points.append(c.control_points[1:])
            weights.append(c.weights[1:] * scale)
        if k < len(pieces) - 1:
            knots.append(np.full(p, b))
    knots.append(np.ones(p + 1))
    curve = NurbsCurve(
        p,
        np.concatenate(knots),
        np.vstack(points),
        np.concatenate(weights),
        name=name,
        units=unit,
    )
    return curve, edges
