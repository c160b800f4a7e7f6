"""Degree elevation, Bézier decomposition and joining, checked against evaluation."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from nurbsmotion import NurbsCurve, builtin_path, make_arc, make_circle, make_line
from nurbsmotion.errors import InvalidCurveError
from nurbsmotion.joining import bezier_segments, elevate_degree, join

N_RANDOM = int(os.environ.get("NURBSMOTION_N_RANDOM", "20"))
U = np.linspace(0.0, 1.0, 1001)


def random_curve(rng, p=None, n_axes=2):
    p = int(rng.integers(1, 5)) if p is None else p
    n = int(rng.integers(p + 1, p + 8))
    interior = np.sort(rng.choice(np.linspace(0.05, 0.95, 7), n - p - 1))  # repeated knots too
    interior = interior[: n - p - 1]
    knots = np.concatenate([[0.0] * (p + 1), interior, [1.0] * (p + 1)])
    _, counts = np.unique(knots[p + 1 : -p - 1], return_counts=True)
    if counts.size and counts.max() > p:  # keep the interior multiplicity legal
        knots = np.concatenate([[0.0] * (p + 1), np.linspace(0, 1, n - p + 1)[1:-1], [1.0] * (p + 1)])
    points = np.cumsum(rng.normal(size=(n, n_axes)) + 0.5, axis=0) * 100.0
    return NurbsCurve(p, knots, points, rng.uniform(0.3, 4.0, n))


def size(curve):
    return float(np.max(np.ptp(curve.control_points, axis=0)))


def test_elevation_equals_original_random_sweep():
    rng = np.random.default_rng(5)
    for _ in range(N_RANDOM):
        c = random_curve(rng)
        for extra in (1, 2, 3):
            e = elevate_degree(c, c.degree + extra)
            assert e.degree == c.degree + extra
            assert np.max(np.abs(e(U) - c(U))) <= 1e-12 * size(c)
            # derivatives equal too (one-sided on the right, as the curve's own)
            d_ref = c(U[:-1], 1)
            assert np.max(np.abs(e(U[:-1], 1) - d_ref)) <= 1e-9 * np.max(np.abs(d_ref))
            # every distinct knot's multiplicity grew by exactly `extra`
            for k in c.breakpoints:
                assert e.knot_multiplicity(k) == c.knot_multiplicity(k) + extra


@pytest.mark.parametrize("name", ["die-bonder-pi", "butterfly"])
def test_elevation_of_benchmarks_keeps_corners_and_length(name):
    c = builtin_path(name)
    e = elevate_degree(c, 5)
    assert np.max(np.abs(e(U) - c(U))) <= 1e-12 * size(c)
    np.testing.assert_allclose(e.sharp_corners(), c.sharp_corners(), atol=1e-15)
    assert e.length == pytest.approx(c.length, rel=1e-12)


def test_elevation_of_exact_circle_keeps_radius():
    e = elevate_degree(make_circle(radius=3.0), 4)
    r = np.linalg.norm(e(U), axis=1)
    assert np.max(np.abs(r - 3.0)) <= 1e-13 * 3.0
    np.testing.assert_allclose(e.curvature(U[1:-1]), 1 / 3.0, rtol=1e-10)


def test_elevation_refuses_lower_degree():
    with pytest.raises(InvalidCurveError, match="cannot elevate a degree-3 curve to degree 2"):
        elevate_degree(builtin_path("die-bonder-pi"), 2)


def test_bezier_segments_reproduce_spans():
    rng = np.random.default_rng(11)
    for _ in range(N_RANDOM):
        c = random_curve(rng)
        segs = bezier_segments(c)
        bp = c.breakpoints
        assert len(segs) == len(bp) - 1
        v = np.linspace(0, 1, 101)
        for s, a, b in zip(segs, bp[:-1], bp[1:]):
            assert s.n_control_points == c.degree + 1
            assert np.max(np.abs(s(v) - c(a + (b - a) * v))) <= 1e-12 * size(c)


def test_join_tangent_arc_and_line_is_smooth_and_proportional():
    arc = make_arc([0.0, 0.0], 10.0, 0.0, math.pi / 2)  # ends at (0, 10) heading -x
    line = make_line([0.0, 10.0], [-20.0, 10.0])
    j = join([arc, line], name="hook")
    L_arc, L_line = 5 * math.pi, 20.0
    assert j.degree == 2 and j.name == "hook"
    assert j.length == pytest.approx(L_arc + L_line, rel=1e-12)
    u_junction = L_arc / (L_arc + L_line)
    assert j.breakpoints[1] == pytest.approx(u_junction, rel=1e-13)
    u_junction = j.breakpoints[1]
    assert j.knot_multiplicity(u_junction) == 2  # full multiplicity: C0 in the representation
    assert j.sharp_corners().size == 0  # but tangent-continuous, so no corner
    # each piece is a linear reparametrisation onto its arc-length share of [0, 1]
    v = np.linspace(0, 1, 201)
    np.testing.assert_allclose(j(u_junction * v), arc(v), atol=1e-12 * 20)
    np.testing.assert_allclose(j(u_junction + (1 - u_junction) * v), line(v), atol=1e-12 * 20)
    # comparable parametrisation speed on both sides: the mean of |C'| over each piece is
    # the total length; the line's is constant, the rational arc's varies a little
    total = L_arc + L_line
    line_speed = np.linalg.norm(j(u_junction + (1 - u_junction) * v, 1), axis=1)
    np.testing.assert_allclose(line_speed, total, rtol=1e-12)
    arc_speed = np.linalg.norm(j(u_junction * v[:-1], 1), axis=1)
    assert 0.8 * total < arc_speed.min() < arc_speed.max() < 1.25 * total


def test_join_reports_corner_at_right_angle():
    pieces = [make_line([0, 0], [3, 0]), make_line([3, 0], [3, 4]), make_arc([1, 4], 2.0, 0.0, math.pi / 2)]
    j = join(pieces)
    lengths = np.array([3.0, 4.0, math.pi])
    np.testing.assert_allclose(j.sharp_corners(), [3 / lengths.sum()], rtol=1e-12)
    # the line-to-arc junction at (3, 4) is tangent (both heading +y): not a corner
    assert j.turning_angle(7 / lengths.sum()) < 1e-9


def test_join_rescales_weights_of_rational_pieces():
    arc = make_arc([0, 0], 1.0, 0.0, math.pi)
    heavy = NurbsCurve(arc.degree, arc.knots, arc.control_points[::-1] * [1, -1], arc.weights[::-1] * 7.0)
    j = join([arc, heavy])
    half = arc.length / (2 * arc.length)
    v = np.linspace(0, 1, 101)
    np.testing.assert_allclose(j(half + half * v), heavy(v), atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(j(U), axis=1), 1.0, atol=1e-13)


def test_join_mixed_degrees_elevates_to_highest():
    pi = builtin_path("die-bonder-pi")
    tail = make_line(pi.control_points[-1], pi.control_points[-1] + [-60000.0, 0.0])
    j = join([pi, tail])
    assert j.degree == 3
    assert j.length == pytest.approx(pi.length + 60000.0, rel=1e-12)
    assert len(j.sharp_corners()) == 3


def test_join_gap_names_pieces_and_gap():
    a = make_line([0, 0], [1, 0], name="line 12")
    b = make_line([1, 0.001], [2, 0], name="line 13")
    with pytest.raises(InvalidCurveError, match=r"piece 0 \(line 12\) ends at \[1\.0, 0\.0\] but piece 1 \(line 13\) starts at \[1\.0, 0\.001\]: a gap of 0\.001"):
        join([a, b])
    j = join([a, b], tolerance=1e-3)  # relative to the path size 2: 0.002 > 0.001
    np.testing.assert_array_equal(j(j.breakpoints[1]), [1.0, 0.0])  # the earlier piece's end is kept


def test_join_rejects_incompatible_pieces():
    with pytest.raises(InvalidCurveError, match="empty"):
        join([])
    with pytest.raises(InvalidCurveError, match="different units"):
        join([make_line([0, 0], [1, 0], units="mm"), make_line([1, 0], [2, 0], units="inch")])
    with pytest.raises(InvalidCurveError, match="different numbers of axes"):
        join([make_line([0, 0], [1, 0]), make_line([1, 0, 0], [2, 0, 0])])


def test_join_single_piece_is_identity():
    c = builtin_path("butterfly")
    j = join([c], name="b")
    assert j == c and j.name == "b" and j.units == "mm"
