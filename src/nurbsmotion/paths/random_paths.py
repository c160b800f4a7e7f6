"""Seeded random paths in families, for studies and test sweeps.

``random_path(family, seed, n_axes=2, length=2e4)`` draws one path [pulse] of a family from
``numpy.random.default_rng(seed)``: the same seed gives the same path on every machine.
Each family stresses one thing an interpolator or a figure can get wrong:

``free_form``
    Cubic to quintic, 4-12 control points on a random walk, weights 0.5-2.
``nearly_straight``
    Cubic through control points on a line, off it by at most 1e-3 of the length.
``curls``
    A planar spiral of 1-4 turns whose radius shrinks to 0.2-2 % of the length: tight
    curls where the curvature limits the feed.
``sharp_corners``
    Degree 1-3, 2-5 sharp corners (interior knots of full multiplicity) turning by
    30-170 degrees.
``near_corners``
    A polyline whose 2-6 vertices turn by 0.05-2 degrees: sharp corners (V = 0 there)
    that look straight.
``near_cusps``
    A cubic span that turns back with a smooth turn of radius below one pulse (0.05-0.8
    pulse) inside the span, not at a knot.
``tiny_spans``
    Free-form with one knot span 1e-6 of the domain wide.
``duplicated_points``
    Cubic free-form with one control point repeated: twice (a valid curve with a short
    control leg of zero length) or three times, where the curve stops (C'(u) = 0) at an
    isolated point. Such a curve is accepted (its zero-speed points are known), but in
    the die-bonder study no interpolator passes the stop (``InfeasibleError``: a speed
    limit of 0 there) and the arc-length tables of some never converge (stopped by the
    study's ``case_time_limit``): the family keeps recording both.
``hairpins``
    Out and back along parallel legs 2-40 pulses apart, with a smooth U-turn.
``closed``
    A closed free-form loop (end = start) around a star-shaped polygon.
``spirals``
    An Archimedean spiral of 1.5-5 turns out from its centre (radius growing evenly with
    the angle, from 0.5-5 % of the length): a curvature that falls steadily, so the
    speed limit of the drive rises along the whole path.
``short_moves``
    A free-form move of 0.3-3 % of ``length``: on the die-bonder with the default length
    a move whose time-optimal bound is below 50 ms.

Paths of 3 axes are the planar ones rotated into a random plane, with a random z ramp
(but for ``near_cusps`` and ``hairpins``, whose tight turn a ramp would open up, and
``closed``, whose points leave the plane and come back); the free-form families draw
3-axis control points directly. ``length`` is the typical extent [pulse].
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..errors import InvalidArgumentError
from ..nurbs import NurbsCurve, make_polyline

__all__ = ["FAMILIES", "random_path"]


def _clamped(degree: int, interior) -> np.ndarray:
    return np.concatenate([np.zeros(degree + 1), np.asarray(interior, dtype=float),
                           np.ones(degree + 1)])


def _uniform_knots(degree: int, n_points: int) -> np.ndarray:
    return _clamped(degree, np.linspace(0, 1, n_points - degree + 1)[1:-1])


def _free_form(rng, length, n_axes):
    p = int(rng.integers(3, 6))
    n = int(rng.integers(max(4, p + 1), 13))
    steps = rng.normal(size=(n - 1, n_axes))
    points = np.concatenate([np.zeros((1, n_axes)), np.cumsum(steps, axis=0)])
    points *= length / max(np.ptp(points, axis=0).max(), 1e-12)
    return NurbsCurve(p, _uniform_knots(p, n), points, rng.uniform(0.5, 2.0, n))


def _nearly_straight(rng, length, n_axes):
    n = int(rng.integers(4, 9))
    direction = _unit(rng, n_axes)
    along = np.linspace(0, length, n)[:, None] * direction
    points = along + rng.uniform(-1e-3, 1e-3, (n, n_axes)) * length
    return NurbsCurve(3, _uniform_knots(3, n), points)


def _curls(rng, length, n_axes):
    turns = rng.uniform(1.0, 4.0)
    r_end = rng.uniform(0.002, 0.02) * length
    n = int(math.ceil(turns * 8)) + 1
    angle = np.linspace(0, 2 * math.pi * turns, n)
    radius = np.geomspace(0.5 * length, r_end, n)
    points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    return NurbsCurve(3, _uniform_knots(3, n), _embed(rng, points, n_axes, length))


def _sharp_corners(rng, length, n_axes):
    p = int(rng.integers(1, 4))
    n_corners = int(rng.integers(2, 6))
    vertices = _turning_polyline(rng, n_corners, np.radians(rng.uniform(30, 170, n_corners)),
                                 length)
    # Each leg a Bezier piece of degree p; corners are knots of full multiplicity p.
    points = [vertices[0]]
    for a, b in zip(vertices[:-1], vertices[1:]):
        points.extend(a + (b - a) * np.arange(1, p + 1)[:, None] / p)
    interior = np.repeat(np.arange(1, n_corners + 1) / (n_corners + 1), p)
    return NurbsCurve(p, _clamped(p, interior), _embed(rng, np.array(points), n_axes, length))


def _near_corners(rng, length, n_axes):
    n_corners = int(rng.integers(2, 7))
    turns = np.radians(rng.uniform(0.05, 2.0, n_corners)) * rng.choice([-1, 1], n_corners)
    vertices = _turning_polyline(rng, n_corners, turns, length)
    return make_polyline(_embed(rng, vertices, n_axes, length))


def _near_cusps(rng, length, n_axes):
    r = rng.uniform(0.05, 0.8)
    half = 0.5 * length
    # A single cubic span [0, a] ... [a, b] turning back: the U-turn of the middle span
    # has its smallest radius of curvature about r (checked in the tests), inside it.
    points = np.array([[0.0, 0.0], [half, 0.0], [length, 0.0], [length, 2 * r],
                       [half, 2 * r], [0.0, 2 * r]])
    return NurbsCurve(3, _clamped(3, [1 / 3, 2 / 3]),
                      _embed(rng, points, n_axes, length, ramp=False))


def _tiny_spans(rng, length, n_axes):
    curve = _free_form(rng, length, n_axes)
    u0 = rng.uniform(0.1, 0.9)
    knots = np.sort(np.concatenate([curve.knots, [u0, u0 + 1e-6]]))
    p = curve.degree
    n = len(knots) - p - 1
    steps = rng.normal(size=(n - 1, n_axes))
    points = np.concatenate([np.zeros((1, n_axes)), np.cumsum(steps, axis=0)])
    points *= length / max(np.ptp(points, axis=0).max(), 1e-12)
    return NurbsCurve(p, knots, points)


def _duplicated_points(rng, length, n_axes):
    p = 3
    copies = int(rng.choice([2, p]))
    n = int(rng.integers(6, 11))
    steps = rng.normal(size=(n - copies, n_axes))
    points = np.concatenate([np.zeros((1, n_axes)), np.cumsum(steps, axis=0)])
    i = int(rng.integers(1, len(points) - 1))
    points = np.insert(points, [i] * (copies - 1), points[i], axis=0)
    points *= length / max(np.ptp(points, axis=0).max(), 1e-12)
    return NurbsCurve(p, _uniform_knots(p, n), points)


def _hairpins(rng, length, n_axes):
    gap = rng.uniform(2.0, 40.0)
    leg = length * rng.uniform(0.3, 1.0)
    points = np.array([[0.0, 0.0], [0.5 * leg, 0.0], [leg, 0.0], [leg + gap, 0.0],
                       [leg + gap, gap], [leg, gap], [0.5 * leg, gap], [0.0, gap]])
    return NurbsCurve(3, _uniform_knots(3, len(points)),
                      _embed(rng, points, n_axes, length, ramp=False))


def _closed(rng, length, n_axes):
    n = int(rng.integers(5, 10))
    angle = np.sort(rng.uniform(0, 2 * math.pi, n))
    radius = 0.5 * length * rng.uniform(0.4, 1.0, n)
    ring = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    points = _embed(rng, np.concatenate([ring, ring[:1]]), n_axes, length, ramp=False)
    if n_axes == 3:  # out of its plane, and back to the start
        points[:-1, 2] += rng.uniform(-0.1, 0.1, n) * length
        points[-1] = points[0]
    return NurbsCurve(3, _uniform_knots(3, len(points)), points)


def _spirals(rng, length, n_axes):
    turns = rng.uniform(1.5, 5.0)
    n = int(math.ceil(turns * 8)) + 1
    angle = np.linspace(0, 2 * math.pi * turns, n) + rng.uniform(0, 2 * math.pi)
    radius = np.linspace(rng.uniform(0.005, 0.05), 0.5, n) * length
    points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    return NurbsCurve(3, _uniform_knots(3, n), _embed(rng, points - points[0], n_axes,
                                                      length))


def _short_moves(rng, length, n_axes):
    return _free_form(rng, length * rng.uniform(0.003, 0.03), n_axes)


def _unit(rng, n_axes) -> np.ndarray:
    v = rng.normal(size=n_axes)
    return v / np.linalg.norm(v)


def _turning_polyline(rng, n_corners: int, turns: np.ndarray, length: float) -> np.ndarray:
    """Planar vertices of ``n_corners + 1`` legs, turning by ``turns`` [rad] at each."""
    heading = np.concatenate([[rng.uniform(0, 2 * math.pi)],
                              rng.choice([-1, 1], n_corners) * np.abs(turns)])
    heading = np.cumsum(heading)
    legs = rng.uniform(0.5, 1.5, n_corners + 1) * length / (n_corners + 1)
    steps = legs[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    return np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])


def _embed(rng, planar: np.ndarray, n_axes: int, length: float,
           ramp: bool = True) -> np.ndarray:
    """Planar points in ``n_axes`` axes: as they are in 2, rotated into a random plane
    in 3, with a random z ramp that makes the path truly spatial (``ramp=False`` where a
    ramp would open up a tight turn)."""
    if n_axes == 2:
        return planar
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    spatial = np.column_stack([planar, np.zeros(len(planar))]) @ q.T
    if ramp:
        spatial[:, 2] += np.linspace(0, rng.uniform(0.05, 0.3) * length, len(planar))
    return spatial


FAMILIES: dict[str, Callable] = {
    "free_form": _free_form,
    "nearly_straight": _nearly_straight,
    "curls": _curls,
    "sharp_corners": _sharp_corners,
    "near_corners": _near_corners,
    "near_cusps": _near_cusps,
    "tiny_spans": _tiny_spans,
    "duplicated_points": _duplicated_points,
    "hairpins": _hairpins,
    "closed": _closed,
    "short_moves": _short_moves,
    "spirals": _spirals,
}
"""Random-path families by name (see the module docstring)."""


def random_path(family: str, seed, n_axes: int = 2, length: float = 2e4) -> NurbsCurve:
    """A seeded random path of one family [pulse].

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    seed : int or numpy.random.SeedSequence
        The same seed gives the same path.
    n_axes : int
        2 or 3.
    length : float
        Typical extent of the path [pulse], > 0.

    Raises
    ------
    KeyError
        For an unknown family.
    ValueError
        For ``n_axes`` other than 2 or 3, or a bad ``length``.
    InvalidCurveError
        When the drawn curve is not a valid path (``duplicated_points`` today).
    """
    if family not in FAMILIES:
        raise KeyError(f"no random-path family {family!r}; choose from {sorted(FAMILIES)}")
    if n_axes not in (2, 3):
        raise InvalidArgumentError(f"random paths have 2 or 3 axes, got {n_axes!r}")
    if not (math.isfinite(length) and length > 0):
        raise InvalidArgumentError(f"random path length must be finite and > 0 pulse, got {length!r}")
    rng = np.random.default_rng(seed)
    curve = FAMILIES[family](rng, float(length), n_axes)
    return NurbsCurve(curve.degree, curve.knots, curve.control_points, curve.weights,
                      name=f"random:{family}:{n_axes}", units="pulse")
