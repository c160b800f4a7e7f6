"""Contour error against an independent dense search, and the SPEC section 10 figures.

The reference search samples the curve densely in its parameter, keeps every local minimum
of the distance within one sample chord of the best, and refines each by Newton's method
on ``(C(u) - p) . C'(u)`` inside its two sample intervals until the distance changes by
less than 1e-9 pulse — it shares no code with :func:`nurbsmotion.metrics.nearest_parameter`
(no grid in arc length, no k-d tree, no ball query).
"""

import math

import numpy as np
import pytest

from nurbsmotion import metrics
from nurbsmotion.loop import run, to_pulses
from nurbsmotion.machine import die_bonder
from nurbsmotion.metrics import nearest_parameter, overshoot, settle_time
from nurbsmotion.nurbs import (NurbsCurve, make_butterfly, make_circle, make_die_bonder_pi,
                               make_polyline)

CONTOUR_TOL = 1e-6
"""[pulse]: the issue's bound on the contour error's own error."""


def reference_distance(curve, points, samples=100_000):
    u = np.linspace(0.0, 1.0, samples)
    u = np.union1d(u, curve.breakpoints)
    C = curve(u)
    chord = float(np.max(np.linalg.norm(np.diff(C, axis=0), axis=1)))
    out = np.empty(len(points))
    for i, p in enumerate(points):
        d = np.linalg.norm(C - p, axis=1)
        dmin = d.min()
        inner = (d[1:-1] <= d[:-2]) & (d[1:-1] <= d[2:])
        cand = np.flatnonzero(np.concatenate([[d[0] <= d[1]], inner, [d[-1] <= d[-2]]]))
        cand = cand[d[cand] <= dmin + chord]
        best = dmin
        for c in cand:
            lo, hi = u[max(c - 1, 0)], u[min(c + 1, len(u) - 1)]
            best = min(best, _newton_reference(curve, p, lo, hi, u[c]))
        out[i] = best
    return out


def _newton_reference(curve, p, lo, hi, x):
    """Scalar Newton on g(u) = (C(u) - p) . C'(u) in [lo, hi], halving the step until the
    distance does not grow."""
    dist = float(np.linalg.norm(curve(x) - p))
    for _ in range(100):
        c0, c1, c2 = curve.derivatives(x, 2)
        g = float((c0 - p) @ c1)
        h = float(c1 @ c1 + (c0 - p) @ c2)
        step = g / h if h > 0 else math.copysign(0.25 * (hi - lo), g)
        while True:
            y = min(max(x - step, lo), hi)
            dy = float(np.linalg.norm(curve(y) - p))
            if dy <= dist or abs(step) < 1e-18:
                break
            step *= 0.5
        if dist - dy < 1e-9 * 1e-3 and abs(y - x) < 1e-15:
            x, dist = y, min(dist, dy)
            break
        x, dist = y, min(dist, dy)
    return dist


def near_points(curve, rng, n, spread, u=None):
    u = rng.uniform(0, 1, n) if u is None else u
    return curve(u) + rng.normal(scale=spread, size=(len(u), curve.n_axes))


def check_exact(curve, pts):
    _, d = nearest_parameter(curve, pts)
    ref = reference_distance(curve, pts)
    np.testing.assert_allclose(d, ref, rtol=0, atol=CONTOUR_TOL)
    return d, ref


def test_closed_path_just_before_its_end():
    """Regression (issue 12): on a closed path the old search took the grid point at the
    start (the same place as the end) and refined only the first cell, never the last:
    up to half a grid cell too far (8 pulses on the butterfly; thousands of pulses on a
    long closed path)."""
    curve = to_pulses(make_butterfly(), die_bonder())
    rng = np.random.default_rng(1)
    u = np.concatenate([1 - np.geomspace(1e-7, 2e-4, 40), rng.uniform(0, 1, 40)])
    check_exact(curve, near_points(curve, rng, 0, 30.0, u=u))


def test_long_closed_circle_end():
    curve = make_circle(3e7, start_angle=0.3)
    rng = np.random.default_rng(2)
    u = 1 - np.geomspace(1e-8, 1e-4, 30)
    pts = near_points(curve, rng, 0, 50.0, u=u)
    d, _ = check_exact(curve, pts)
    exact = np.abs(np.linalg.norm(pts, axis=1) - 3e7)
    np.testing.assert_allclose(d, exact, rtol=0, atol=1e-6)


def test_self_intersecting_and_self_passing_paths():
    rng = np.random.default_rng(3)
    # A figure eight (crosses itself) and a hairpin whose legs are 2 pulses apart.
    eight = NurbsCurve(3, [0, 0, 0, 0, .2, .4, .6, .8, 1, 1, 1, 1],
                       [[0, 0], [1e4, 1e4], [2e4, 0], [1e4, -1e4], [0, 1e4], [-1e3, 5e3],
                        [0, 0], [0, -10]])
    hairpin = make_polyline([[0, 0], [1e4, 0], [1e4, 2], [0, 2]])
    for curve, spread in ((eight, 20.0), (hairpin, 1.5)):
        check_exact(curve, near_points(curve, rng, 150, spread))


def test_tight_curl_far_and_near():
    """A smooth turn of radius below one pulse inside a span (near-cusp)."""
    curve = NurbsCurve(3, [0, 0, 0, 0, 0.5, 1, 1, 1, 1],
                       [[0, 0], [5e3, 0], [1e4, 0.3], [5e3, 0.6], [0, 0.6]])
    rng = np.random.default_rng(4)
    pts = np.concatenate([near_points(curve, rng, 100, 3.0),
                          curve([0.5]) + rng.normal(scale=2.0, size=(50, 2))])
    check_exact(curve, pts)


def test_chunks_give_the_same_result(monkeypatch):
    curve = make_die_bonder_pi()
    pts = near_points(curve, np.random.default_rng(5), 300, 200.0)
    whole = nearest_parameter(curve, pts)
    monkeypatch.setattr(metrics, "_CHUNK", 7)
    parts = nearest_parameter(curve, pts)
    np.testing.assert_array_equal(whole[1], parts[1])


def test_settle_time_definition():
    t = np.arange(8) * 1e-3
    pos = np.array([[5.0], [3.0], [0.5], [2.0], [0.9], [-0.2], [0.0], [0.1]])
    assert settle_time(t, pos, np.array([0.0]), 1.0) == pytest.approx(4e-3)
    assert settle_time(t, pos, np.array([0.0]), 0.05) == math.inf
    assert settle_time(t, pos, np.array([0.0]), 10.0) == 0.0
    with pytest.raises(ValueError, match="settle window"):
        settle_time(t, pos, np.array([0.0]), 0.0)


def test_overshoot_definition():
    pos = np.array([[0.0, -5], [0.5, -1], [0.3, 2.5], [0.0, 0.1]])
    assert overshoot(pos, np.zeros(2), np.array([0.0, 3.0])) == pytest.approx(2.5)
    assert overshoot(pos, np.zeros(2), np.array([0.0, -1.0])) == pytest.approx(5.0)
    assert overshoot(pos[:2], np.zeros(2), np.array([0.0, 1.0])) == 0.0


def test_overshoot_is_at_most_the_distance_off_the_path():
    """A sample beyond the point's plane but on the path (where the path bends back past
    it) has not passed it: ``off_path`` bounds each sample's excursion."""
    pos = np.array([[0.0, -5], [0.5, -1], [0.3, 2.5], [0.0, 0.1]])
    up = np.array([0.0, 1.0])
    assert overshoot(pos, np.zeros(2), up, np.array([9.0, 9.0, 0.0, 9.0])) \
        == pytest.approx(0.1)
    assert overshoot(pos, np.zeros(2), up, np.array([9.0, 9.0, 1.5, np.inf])) \
        == pytest.approx(1.5)
    assert overshoot(pos, np.zeros(2), up, np.full(4, np.inf)) == pytest.approx(2.5)


def _metrics_of(curve, position, u, finished):
    """The running figures for made-up rows: actual ``position`` (n, 2) [pulse] and
    setpoint parameter ``u`` (n,), the setpoint at the end from sample ``finished``."""
    from nurbsmotion.loop.closed_loop import new_rows

    n = len(u)
    rows = new_rows(n, 2, False)
    for r in rows[:9]:
        r[...] = 0.0
    rows.u[:], rows.position[:], rows.command[:] = u, position, position
    m = metrics.RunningMetrics(curve, die_bonder(), 1.0)
    m.add(0, rows, finished, True)
    return m


def _end_overshoot_of(curve, position, u, finished):
    return _metrics_of(curve, position, u, finished).end_overshoot


def test_corner_overshoot_where_the_path_bends_back_beyond_the_corner():
    """In along +x to a sharp corner at (100, 0), out along +y, then the outgoing piece
    (a quadratic) bends to +x: half way to the end it is 50 pulses beyond the corner's
    plane x = 100. A machine exactly on the path has not passed the corner (its samples
    up to 32 pulses beyond that plane were counted as passing it); one that goes 3 pulses
    beyond the corner itself has passed it by 3."""
    bend = NurbsCurve(2, [0, 0, 0, 0.5, 0.5, 1, 1, 1],
                      [[0, 0], [50, 0], [100, 0], [100, 100], [300, 100]])
    u = np.array([0.0, 0.25, 0.5, 0.6, 0.7, 0.75, 0.75])
    on_path = bend(u)
    assert _metrics_of(bend, on_path, u, 7).corner_overshoot == pytest.approx(0.0, abs=1e-9)
    ahead = on_path.copy()
    ahead[2] = [103.0, 0.0]  # the position runs ahead of its setpoint past the corner
    u[2] = 0.45
    assert _metrics_of(bend, ahead, u, 7).corner_overshoot == pytest.approx(3.0)


def test_end_overshoot_before_the_setpoint_arrives():
    """A machine that runs ahead of its setpoint passes the end (by 3 pulses, along the
    final direction +x) before the setpoint gets there: counted. A hook, whose path
    bends back past the end's plane: a sample beyond that plane but nearest to the hook's
    middle has not passed the end; one beyond the end itself has."""
    line = NurbsCurve(1, [0, 0, 1, 1], [[0.0, 0.0], [100.0, 0.0]])
    u = np.array([0.0, 0.3, 0.6, 0.8, 0.9, 0.95, 1.0])
    x = np.array([0.0, 40.0, 80.0, 103.0, 101.0, 100.0, 100.0])
    assert _end_overshoot_of(line, np.column_stack([x, 0 * x]), u, 6) == pytest.approx(3.0)
    # the hook: up from (0, 0) to (0, 100), then right and down to end at (50, 50),
    # arriving downwards (-y): the path's top is 50 pulses beyond the end's plane
    hook = NurbsCurve(1, [0, 0, 1 / 3, 2 / 3, 1, 1],
                      [[0.0, 0.0], [0.0, 100.0], [50.0, 100.0], [50.0, 50.0]])
    u = np.array([0.0, 0.4, 0.6, 0.8, 0.95, 1.0, 1.0])
    pos = np.array([[0, 0], [0, 100], [25, 102], [50, 80], [50.5, 60], [50, 48],
                    [50, 50.0]])
    assert _end_overshoot_of(hook, pos, u, 5) == pytest.approx(2.0)


def test_end_overshoot_of_a_closed_path():
    """The butterfly is closed: past its end the path goes on from its start, so a plant
    that passes the end stays near the path; it has passed the end all the same (the
    figure is the excursion along the arrival direction after the setpoint arrived,
    computed here from the trace)."""
    machine = die_bonder()
    curve = to_pulses(make_butterfly(), machine)
    trace = run(curve, machine, 2e5, "paper", settle_time=0.05)
    t = curve.limit_tangent(np.array([1.0]), "left")[0]
    after = (trace.position[trace.finished_index:] - curve(1.0)) @ t
    assert after.max() > 10.0
    assert trace.metrics().end_overshoot == pytest.approx(after.max())


def test_run_figures_against_the_trace():
    machine = die_bonder()
    trace = run(make_die_bonder_pi(), machine, 1e6, "taylor1", settle_time=0.3)
    m = trace.metrics()
    end = trace.curve(1.0)
    dist = np.linalg.norm(trace.position - end, axis=1)
    assert m.settled and dist[-1] <= 1.0
    k = int(round(m.settle_time_s / machine.sample_period))
    assert np.all(dist[k:] <= 1.0) and dist[k - 1] > 1.0
    # The place move arrives downwards (-y): overshoot is how far below the end it went.
    after = trace.position[trace.finished_index:, 1]
    assert m.end_overshoot == pytest.approx(max(0.0, end[1] - after.min()))
    # The two corners of the Pi: lift (+y) turns to transfer (+x), transfer to place.
    assert m.corner_overshoot > 0
    _, d = nearest_parameter(trace.curve, trace.position)
    assert m.max_contour_error == d.max()


def test_search_order_and_three_axes():
    """The search starts each point from the previous point's cell: the distances must not
    depend on the order of the points; and a 3-axis path (a helix) is searched as exactly."""
    t = np.linspace(0, 1, 13)
    helix = NurbsCurve(3, np.concatenate([[0, 0, 0], np.linspace(0, 1, 11), [1, 1, 1]]),
                       np.column_stack([1e4 * np.cos(6 * t), 1e4 * np.sin(6 * t), 3e3 * t]))
    rng = np.random.default_rng(6)
    pts = near_points(helix, rng, 120, 40.0)
    d, _ = check_exact(helix, pts)
    _, backwards = nearest_parameter(helix, pts[::-1])
    np.testing.assert_array_equal(backwards[::-1], d)
