"""PieceChain: pieces kept as arrays and joined in bulk equal the pieces joined one by one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nurbsmotion import NurbsCurve, make_line
from nurbsmotion.joining import join_with_edges
from nurbsmotion.paths.pieces import HELIX_TOLERANCE, PieceChain, arc_by_center, bezier_elevation


def _embed(curve: NurbsCurve, base, cols) -> NurbsCurve:
    P = np.repeat(np.asarray(base, float)[None, :], curve.n_control_points, axis=0)
    P[:, list(cols)] = curve.control_points
    return NurbsCurve(curve.degree, curve.knots, P, curve.weights)


def _one_by_one():
    """A 3-axis path of lines, arcs in two planes (one of 3 turns) and a rational cubic,
    as the chain receives it and as separate NurbsCurve pieces."""
    chain = PieceChain([0.0, 0.0, 1.0])
    pieces = []
    chain.add_line([2.0, 0.0, 1.0])
    pieces.append(make_line([0.0, 0.0, 1.0], [2.0, 0.0, 1.0]))
    # XY arc, clockwise, 3/4 turn round (2, 1); then the same circle once more in full
    for end, turns in (([1.0, 1.0], 1), ([1.0, 1.0], 1)):
        start = chain.last
        arcs = arc_by_center(start[:2], end, [2.0, 1.0], clockwise=True, turns=turns)
        for arc in arcs:
            a0 = math.atan2(start[1] - 1.0, start[0] - 2.0)
            sweep = -2.0 * float(np.sum(np.arccos(arc.weights[1::2])))
            chain.add_arc([*arc.control_points[-1], 1.0], (0, 1), (2.0, 1.0), 1.0, a0, sweep)
            pieces.append(_embed(arc, [0.0, 0.0, 1.0], (0, 1)))
            start = chain.last
    # XZ arc (columns 2, 0: Z is the first plane axis, as G18 has it), counter-clockwise
    start = chain.last  # (1, 1, 1)
    arc = arc_by_center([1.0, 1.0], [1.0, 3.0], [1.0, 2.0], clockwise=False)[0]  # (z, x)
    chain.add_arc([3.0, 1.0, 1.0], (2, 0), (1.0, 2.0), 1.0, math.atan2(-1.0, 0.0), math.pi)
    pieces.append(_embed(arc, start, (2, 0)))
    cubic = NurbsCurve(3, [0, 0, 0, 0, 0.5, 1, 1, 1, 1],
                       [[3.0, 1.0, 1.0], [4.0, 2.0, 1.5], [3.0, 3.0, 2.0], [2.0, 2.5, 1.0], [2.0, 4.0, 0.0]],
                       [2.0, 1.0, 3.0, 1.0, 0.5])
    chain.add_curve(cubic)
    pieces.append(cubic)
    chain.add_line([0.0, 4.0, 0.0])
    pieces.append(make_line([2.0, 4.0, 0.0], [0.0, 4.0, 0.0]))
    return chain, pieces


def test_bulk_join_equals_joining_piece_by_piece():
    chain, pieces = _one_by_one()
    curve, edges = chain.build(name="p", units="mm")
    reference, ref_edges = join_with_edges(pieces)
    assert curve.degree == reference.degree == 3
    np.testing.assert_allclose(edges, ref_edges, rtol=0, atol=1e-12)
    u = np.linspace(0.0, 1.0, 2001)
    np.testing.assert_allclose(curve(u), reference(u), rtol=0, atol=1e-12)
    np.testing.assert_allclose(curve.knots, reference.knots, rtol=0, atol=1e-12)


def test_lines_only_make_a_polyline_and_arcs_stay_quadratic():
    chain = PieceChain([0.0, 0.0])
    for end in ([1.0, 0.0], [1.0, 2.0], [-1.0, 2.0]):
        chain.add_line(end)
    curve, edges = chain.build()
    assert curve.degree == 1
    np.testing.assert_array_equal(curve.control_points, [[0, 0], [1, 0], [1, 2], [-1, 2]])
    np.testing.assert_allclose(edges, [0, 0.2, 0.6, 1.0])
    chain.add_arc([-1.0, 0.0], (0, 1), (-1.0, 1.0), 1.0, math.pi / 2, math.pi)
    curve, _ = chain.build()
    assert curve.degree == 2
    mid = curve(np.array([0.95]))[0]
    assert math.hypot(mid[0] + 1.0, mid[1] - 1.0) == pytest.approx(1.0, abs=1e-14)


def test_spiral_stays_within_the_helix_tolerance():
    chain = PieceChain([1.0, 0.0, 0.0])
    # one and a half turns, radius 1 -> 1.001, Z 0 -> -2: a helix that is also a spiral
    sweep = 3 * math.pi
    chain.add_spiral([-1.001, 0.0, -2.0], (0, 1), (0.0, 0.0), 1.0, 1.001, 0.0, sweep, 1.0)
    curve, _ = chain.build()
    u = np.linspace(0.0, 1.0, 20001)
    P = curve(u)
    angle = np.unwrap(np.arctan2(P[:, 1], P[:, 0]))
    t = angle / sweep
    radius = 1.0 + 0.001 * t
    assert np.max(np.abs(np.hypot(P[:, 0], P[:, 1]) - radius)) < HELIX_TOLERANCE * 1.001
    assert np.max(np.abs(P[:, 2] - (-2.0 * t))) < 1e-9
    np.testing.assert_array_equal(curve.control_points[-1], [-1.001, 0.0, -2.0])


def test_bezier_elevation_rows_sum_to_one():
    for q, p in ((1, 2), (2, 3), (2, 5), (3, 4)):
        E = bezier_elevation(q, p)
        np.testing.assert_allclose(E.sum(axis=1), 1.0)
        assert E[0, 0] == E[-1, -1] == 1.0
