"""NurbsCurve evaluation, derivatives, factories and validation against independent oracles.

Oracles: scipy's ``BSpline`` (used directly) and ``BSpline.design_matrix`` for the
non-rational and rational basis, the closed-form circle for ``make_arc``/``make_circle``,
fourth-order finite differences for derivatives, and the NURBS properties of
Piegl & Tiller, The NURBS Book, section 4.2 (partition of unity, end-point interpolation,
affine invariance, C^(p-m) continuity at a knot of multiplicity m).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.interpolate import BSpline
from scipy.stats import special_ortho_group

from conftest import (
    EXACT,
    FD,
    RANDOM_SWEEPS,
    TIGHT,
    clamped_knots,
    curves,
    random_clamped_knots,
    random_points,
    span_interiors,
)
from nurbsmotion import (
    InvalidCurveError,
    NurbsCurve,
    make_arc,
    make_circle,
    make_line,
    make_polyline,
)
from nurbsmotion.errors import NurbsmotionError


def random_curve(rng: np.random.Generator, degree: int, n_axes: int, rational: bool = True):
    knots = random_clamped_knots(rng, degree)
    n = len(knots) - degree - 1
    P = random_points(rng, n, n_axes)
    w = rng.uniform(0.2, 5.0, size=n) if rational else None
    return NurbsCurve(degree, knots, P, w)


def max_norm(values: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(values, axis=-1)))


# ---------------------------------------------------------------------- scipy oracle
@pytest.mark.parametrize("sweep", range(RANDOM_SWEEPS))
@pytest.mark.parametrize("n_axes", [1, 2, 3, 4])
@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_unit_weights_equal_scipy_bspline(degree, n_axes, sweep):
    rng = np.random.default_rng([degree, n_axes, sweep])
    knots = random_clamped_knots(rng, degree)
    n = len(knots) - degree - 1
    P = random_points(rng, n, n_axes)
    curve = NurbsCurve(degree, knots, P)
    oracle = BSpline(knots, P, degree)
    u = np.concatenate([rng.uniform(0.0, 1.0, 50), [0.0, 1.0]])
    # The rational formula subtracts w^(i) C^(k-i) terms whose w^(i) vanish only to
    # rounding, so the error of order k scales with the derivatives of orders <= k.
    scale = 1.0
    for order in range(4):
        expected = oracle(u, nu=order)
        scale = max(scale, max_norm(expected))
        np.testing.assert_allclose(curve(u, order), expected, rtol=0, atol=EXACT * scale)


@given(curves())
def test_rational_basis_equals_weighted_design_matrix(curve):
    # Control points = identity: each coordinate of C(u) is one rational basis function.
    n = curve.n_control_points
    basis_curve = NurbsCurve(curve.degree, curve.knots, np.eye(n), curve.weights)
    u = np.linspace(0.0, 1.0, 41)
    R = basis_curve(u)
    N = BSpline.design_matrix(u, curve.knots, curve.degree).toarray()
    expected = N * curve.weights / (N @ curve.weights)[:, None]
    np.testing.assert_allclose(R, expected, rtol=0, atol=EXACT)
    assert np.all(R >= -EXACT)
    np.testing.assert_allclose(R.sum(axis=1), 1.0, rtol=0, atol=EXACT)


# ---------------------------------------------------------------------- NURBS properties
@given(curves())
def test_end_points_are_end_control_points(curve):
    P = curve.control_points
    scale = max_norm(P)
    np.testing.assert_allclose(curve(0.0), P[0], rtol=0, atol=EXACT * scale)
    np.testing.assert_allclose(curve(1.0), P[-1], rtol=0, atol=EXACT * scale)


@given(curves(), st.integers(0, 2**32 - 1))
def test_affine_invariance(curve, seed):
    rng = np.random.default_rng(seed)
    d = curve.n_axes
    R = special_ortho_group.rvs(d, random_state=rng) if d > 1 else np.array([[-1.0]])
    shift = rng.uniform(-100.0, 100.0, d)
    moved = NurbsCurve(
        curve.degree, curve.knots, curve.control_points @ R.T + shift, curve.weights
    )
    u = np.concatenate([rng.uniform(0.0, 1.0, 30), curve.breakpoints])
    expected = curve(u) @ R.T + shift
    scale = max_norm(moved.control_points)
    np.testing.assert_allclose(moved(u), expected, rtol=0, atol=EXACT * 10 * scale)
    # Derivatives transform by the linear part only.
    np.testing.assert_allclose(
        moved(u, 1), curve(u, 1) @ R.T, rtol=0, atol=TIGHT * max_norm(curve(u, 1))
    )


@given(curves())
def test_knot_multiplicity_counts_equal_knots_for_numbers_and_arrays(curve):
    # the reference: a count of equal entries of the knot vector, one value at a time
    u = np.concatenate([curve.breakpoints, [0.5 * (curve.breakpoints[0] + curve.breakpoints[1])]])
    expected = [int(np.count_nonzero(curve.knots == x)) for x in u]
    assert [curve.knot_multiplicity(x) for x in u] == expected
    assert isinstance(curve.knot_multiplicity(float(u[0])), int)
    np.testing.assert_array_equal(curve.knot_multiplicity(u), expected)


@given(curves())
def test_derivatives_continuous_across_knots_up_to_order_p_minus_m(curve):
    p = curve.degree
    for knot in curve.breakpoints[1:-1]:
        m = curve.knot_multiplicity(knot)
        top = min(p - m, 3)  # derivatives() stops at order 3 (jerk)
        left = curve.derivatives(knot, top, side="left")
        right = curve.derivatives(knot, top, side="right")
        for k in range(top + 1):
            scale = max(1.0, max_norm(curve(span_interiors(curve), k)))
            np.testing.assert_allclose(left[k], right[k], rtol=0, atol=TIGHT * scale)


# ---------------------------------------------------------------------- exact circle
SWEEPS_DEG = [30.0, 89.0, 90.0, 135.0, 180.0, 270.0, 360.0]


@pytest.mark.parametrize("direction", [1.0, -1.0], ids=["ccw", "cw"])
@pytest.mark.parametrize("sweep_deg", SWEEPS_DEG)
def test_arc_is_exact_circle(sweep_deg, direction):
    center = np.array([3.0, -2.0])
    radius = 7.5
    start = math.radians(20.0)
    sweep = direction * math.radians(sweep_deg)
    arc = make_arc(center, radius, start, start + sweep)

    u = np.linspace(0.0, 1.0, 1001)
    offset = arc(u) - center
    np.testing.assert_allclose(np.linalg.norm(offset, axis=1), radius, rtol=EXACT, atol=0)
    np.testing.assert_allclose(arc.curvature(u), 1.0 / radius, rtol=EXACT, atol=0)

    # Points advance monotonically in the sweep direction, from start to start + sweep.
    angle = start + np.unwrap(np.arctan2(offset[:, 1], offset[:, 0]) - start)
    assert np.all(direction * np.diff(angle) > 0)
    for u_end, a in [(0.0, start), (1.0, start + sweep)]:
        expected = center + radius * np.array([math.cos(a), math.sin(a)])
        np.testing.assert_allclose(arc(u_end), expected, rtol=0, atol=EXACT * radius)
    # The tangent turns the same way: cross(C - c, C') has the sign of the sweep.
    d1 = arc(u, 1)
    assert np.all(direction * (offset[:, 0] * d1[:, 1] - offset[:, 1] * d1[:, 0]) > 0)

    assert arc.length == pytest.approx(radius * abs(sweep), rel=TIGHT)
    # Half the arc length is reached at half the sweep.
    mid = arc(arc.parameter_at(arc.length / 2))
    a = start + sweep / 2
    np.testing.assert_allclose(
        mid, center + radius * np.array([math.cos(a), math.sin(a)]), rtol=0, atol=TIGHT * radius
    )
    assert arc.sharp_corners().size == 0


@pytest.mark.parametrize("clockwise", [False, True])
def test_circle_is_exact(clockwise):
    radius, center, start = 0.25, np.array([-1.0, 4.0]), 1.0
    circle = make_circle(radius, center, start, clockwise=clockwise)
    u = np.linspace(0.0, 1.0, 2001)
    offset = circle(u) - center
    np.testing.assert_allclose(np.linalg.norm(offset, axis=1), radius, rtol=EXACT, atol=0)
    np.testing.assert_allclose(circle.curvature(u), 1.0 / radius, rtol=EXACT, atol=0)
    first = center + radius * np.array([math.cos(start), math.sin(start)])
    np.testing.assert_allclose(circle(0.0), first, rtol=0, atol=EXACT * radius)
    np.testing.assert_allclose(circle(1.0), first, rtol=0, atol=EXACT * radius)
    # A quarter of the parameter after the start, a quarter turn in the chosen direction
    # (the four quadrant pieces are symmetric, so u = 1/4 is exactly at 90 degrees).
    a = start + (-1 if clockwise else 1) * math.pi / 2
    np.testing.assert_allclose(
        circle(0.25), center + radius * np.array([math.cos(a), math.sin(a)]),
        rtol=0, atol=EXACT * radius,
    )
    assert circle.length == pytest.approx(2 * math.pi * radius, rel=TIGHT)
    assert circle.sharp_corners().size == 0
    assert circle.n_control_points == 9


# ---------------------------------------------------------------------- derivatives
def central_difference(f, u, h):
    """Fourth-order central difference of ``f`` at ``u``."""
    return (-f(u + 2 * h) + 8 * f(u + h) - 8 * f(u - h) + f(u - 2 * h)) / (12 * h)


def one_sided_difference(f0, f, u, h):
    """Fourth-order one-sided difference: forward for ``h > 0``, backward for ``h < 0``.
    ``f0`` is the one-sided value at ``u`` itself."""
    return (-25 * f0 + 48 * f(u + h) - 36 * f(u + 2 * h) + 16 * f(u + 3 * h)
            - 3 * f(u + 4 * h)) / (12 * h)


@pytest.mark.parametrize("sweep", range(RANDOM_SWEEPS))
@pytest.mark.parametrize("n_axes", [1, 2, 3])
@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_derivatives_match_finite_differences(degree, n_axes, sweep):
    rng = np.random.default_rng([100, degree, n_axes, sweep])
    curve = random_curve(rng, degree, n_axes)
    bp = curve.breakpoints
    u = span_interiors(curve, (0.3, 0.5, 0.7))
    h = 1e-3 * np.repeat(np.diff(bp), 3)[:, None]
    for order in (1, 2, 3):
        exact = curve(u, order)
        fd = central_difference(lambda x: curve(x[:, 0], order - 1), u[:, None], h)
        scale = max(1.0, max_norm(exact))
        np.testing.assert_allclose(exact, fd, rtol=0, atol=FD * scale)


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_one_sided_derivatives_at_full_multiplicity_knot(degree):
    rng = np.random.default_rng([200, degree])
    knots = clamped_knots(degree, [0.4], [degree])
    n = len(knots) - degree - 1
    curve = NurbsCurve(degree, knots, rng.uniform(-10, 10, (n, 2)), rng.uniform(0.2, 5, n))
    corner = 0.4
    assert curve.turning_angle(corner) > 1e-3  # a genuine corner: the two sides differ
    h = 1e-4
    for order in (1, 2, 3):
        for side, step in (("right", h), ("left", -h)):
            exact = curve(corner, order, side)
            f0 = curve(corner, order - 1, side)
            fd = one_sided_difference(f0, lambda x: curve(x, order - 1), corner, step)
            scale = max(1.0, np.linalg.norm(exact))
            np.testing.assert_allclose(exact, fd, rtol=0, atol=FD * scale)
    # Default is the right side (SPEC section 5: the span the motion moves into).
    np.testing.assert_array_equal(curve(corner, 1), curve(corner, 1, "right"))


def test_derivative_of_degree_one_rational_segment_is_exact():
    # C(u) = (w1 u) / ((1 - u) + w1 u) * (1, 0) for P0 = 0, P1 = (1, 0), weights (1, w1):
    # C' = w1 / D^2, C'' = -2 w1 (w1 - 1) / D^3, C''' = 6 w1 (w1 - 1)^2 / D^4.
    w1 = 3.0
    curve = NurbsCurve(1, [0, 0, 1, 1], [[0.0, 0.0], [1.0, 0.0]], [1.0, w1])
    u = np.linspace(0.0, 1.0, 11)
    D = 1 - u + w1 * u
    expected = [w1 * u / D, w1 / D**2, -2 * w1 * (w1 - 1) / D**3, 6 * w1 * (w1 - 1) ** 2 / D**4]
    d = curve.derivatives(u, 3)
    for k in range(4):
        np.testing.assert_allclose(d[k][:, 0], expected[k], rtol=EXACT, atol=EXACT)
        np.testing.assert_array_equal(d[k][:, 1], 0.0)


# ---------------------------------------------------------------------- knot normalisation
def test_knot_domain_is_normalised_and_kept():
    rng = np.random.default_rng(7)
    knots01 = clamped_knots(3, [0.2, 0.6], [1, 2])
    knots27 = 2.0 + 5.0 * knots01
    P = rng.uniform(-5, 5, (len(knots01) - 4, 3))
    w = rng.uniform(0.2, 5, len(P))
    on_27 = NurbsCurve(3, knots27, P, w)
    on_01 = NurbsCurve(3, knots01, P, w)
    assert on_27.domain == (2.0, 7.0)
    assert on_01.domain == (0.0, 1.0)
    np.testing.assert_allclose(on_27.knots, knots01, rtol=0, atol=EXACT)
    assert on_27 == on_01  # these knots map to [0, 1] without rounding
    u = np.linspace(0, 1, 101)
    for order in range(4):
        np.testing.assert_allclose(
            on_27(u, order), on_01(u, order), rtol=0,
            atol=EXACT * max(1.0, max_norm(on_01(u, order))),
        )


# ---------------------------------------------------------------------- shapes
@pytest.mark.parametrize("n_axes", [1, 2, 4])
def test_output_shapes_are_never_squeezed(n_axes):
    curve = random_curve(np.random.default_rng(n_axes), 3, n_axes)
    assert curve(0.5).shape == (n_axes,)
    assert curve(0.5, 2).shape == (n_axes,)
    assert curve(np.array([0.5])).shape == (1, n_axes)
    assert curve(np.linspace(0, 1, 7)).shape == (7, n_axes)
    assert curve(np.linspace(0, 1, 7), 3).shape == (7, n_axes)
    assert curve.derivatives(np.linspace(0, 1, 7), 2).shape == (3, 7, n_axes)
    assert curve.derivatives(0.3, 3).shape == (4, n_axes)
    assert curve.derivatives(0.3, 0).shape == (1, n_axes)


def test_curve_does_not_mutate_or_share_inputs():
    knots = clamped_knots(2, [0.5], [1])
    P = np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 1.0], [4.0, 0.0]])
    w = np.array([1.0, 2.0, 0.5, 1.0])
    curve = NurbsCurve(2, knots, P, w)
    before = curve(0.3)
    P[1] = 100.0
    w[1] = 50.0
    knots[3] = 0.1
    np.testing.assert_array_equal(curve(0.3), before)
    for arr in (curve.knots, curve.control_points, curve.weights):
        with pytest.raises(ValueError):
            arr[0] = 1.0


# ---------------------------------------------------------------------- validation
SQUARE = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
CUBIC_KNOTS = [0, 0, 0, 0, 1, 1, 1, 1]


def test_invalid_curve_error_is_a_value_error():
    assert issubclass(InvalidCurveError, ValueError)
    assert issubclass(InvalidCurveError, NurbsmotionError)


@pytest.mark.parametrize(
    "args, message",
    [
        pytest.param((3, [0, 0, 0, 0, 1, 1, 1], SQUARE),
                     r"knot vector has 7 entries, expected 8 = n \+ p \+ 1", id="knot-count"),
        pytest.param((2, [0, 0, 0, 0.6, 0.4, 1, 1, 1], SQUARE + [[2.0, 2.0]]),
                     r"non-decreasing.*knot 4 = 0\.4 < knot 3 = 0\.6", id="decreasing"),
        pytest.param((2, [0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1], SQUARE + [[2, 2], [3, 3]]),
                     r"interior knot 0\.5 has multiplicity 3, more than the degree 2",
                     id="interior-multiplicity"),
        pytest.param((3, [0, 0, 0, 0.5, 1, 1, 1, 1], SQUARE), r"not clamped",
                     id="unclamped-start"),
        pytest.param((3, [0, 0, 0, 0, 0.5, 1, 1, 1], SQUARE), r"not clamped",
                     id="unclamped-end"),
        pytest.param((3, [0, 0, 0, 0, np.nan, 1, 1, 1, 1], SQUARE + [[2, 2]]),
                     r"knot 4 is not finite", id="knot-nan"),
        pytest.param((3, [1, 1, 1, 1, 1, 1, 1, 1], SQUARE), r"empty domain",
                     id="empty-domain"),
        pytest.param((3, CUBIC_KNOTS, SQUARE, [1, 1, -0.5, 1]),
                     r"weight 2 is -0\.5; weights must be > 0", id="weight-negative"),
        pytest.param((3, CUBIC_KNOTS, SQUARE, [1, 0, 1, 1]),
                     r"weight 1 is 0; weights must be > 0", id="weight-zero"),
        pytest.param((3, CUBIC_KNOTS, SQUARE, [1, np.nan, 1, 1]),
                     r"weight 1 is not finite: nan", id="weight-nan"),
        pytest.param((3, CUBIC_KNOTS, SQUARE, [1, 1, 1, np.inf]),
                     r"weight 3 is not finite: inf", id="weight-inf"),
        pytest.param((3, CUBIC_KNOTS, [[0, 0], [1, np.inf], [1, 1], [0, 1]]),
                     r"control point 1 is not finite", id="control-point-inf"),
        pytest.param((3, CUBIC_KNOTS, [[0, 0], [1, 0], [np.nan, 1], [0, 1]]),
                     r"control point 2 is not finite", id="control-point-nan"),
        pytest.param((3, CUBIC_KNOTS, [0.0, 1.0, 2.0, 3.0]),
                     r"control_points must have shape \(n, n_axes\), got shape \(4,\)",
                     id="control-points-1d"),
        pytest.param((3, CUBIC_KNOTS, SQUARE, [1, 1, 1]),
                     r"weights has 3 entries, expected 4", id="weights-length"),
        pytest.param((3, CUBIC_KNOTS, SQUARE, [[1, 1, 1, 1]]),
                     r"weights must have shape \(n,\)", id="weights-2d"),
        pytest.param((0, [0, 0, 0, 0, 1], SQUARE), r"degree must be an integer >= 1, got 0",
                     id="degree-zero"),
        pytest.param((-2, CUBIC_KNOTS, SQUARE), r"degree must be an integer >= 1, got -2",
                     id="degree-negative"),
        pytest.param((2.5, CUBIC_KNOTS, SQUARE), r"degree must be an integer >= 1, got 2\.5",
                     id="degree-fractional"),
        pytest.param(("3", CUBIC_KNOTS, SQUARE), r"degree must be an integer >= 1, got '3'",
                     id="degree-string"),
        pytest.param((3, [0, 0, 0, 0, 1, 1, 1], SQUARE[:3]),
                     r"degree-3 curve needs at least p \+ 1 = 4 control points, got 3",
                     id="too-few-points"),
        pytest.param((3, CUBIC_KNOTS, [[2.0, 1.0]] * 4),
                     r"all 4 control points coincide at \[2\.0, 1\.0\] \(zero length\)",
                     id="zero-length"),
        pytest.param((3, [0, 0, 0, 0, 0, 1, 1, 1, 1], SQUARE + [[2.0, 2.0]]),
                     r"knot 0 has multiplicity 5, more than p \+ 1 = 4",
                     id="end-multiplicity-start"),
        pytest.param((2, [0, 0, 0, 1, 1, 1, 1], SQUARE),
                     r"knot 1 has multiplicity 4, more than p \+ 1 = 3",
                     id="end-multiplicity-end"),
    ],
)
def test_invalid_curve_is_rejected_with_message(args, message):
    with pytest.raises(InvalidCurveError, match=message):
        NurbsCurve(*args)


def test_end_knot_multiplicity_above_p_plus_1_is_rejected_regression():
    # Regression: knots (0,0,0,0,1,1,1) for p = 2 were accepted; the basis function of P0
    # was then identically zero and the curve started at P1, not at its first control
    # point (so the setpoint would jump at the start of a move).
    with pytest.raises(InvalidCurveError, match="knot 0 has multiplicity 4"):
        NurbsCurve(2, [0, 0, 0, 0, 1, 1, 1], [[0, 0], [1, 0], [2, 1], [3, 0]])


def test_knot_span_below_double_resolution_is_refused_naming_it(tmp_path, capsys):
    # Regression (issue 37): a span of 1e-300 passed; its derivatives overflowed (NumPy
    # warnings) and `bound` never finished its arc-length table. The limit is the spacing
    # of doubles at the normalised domain's end: one just above it is accepted and its
    # derivatives are finite.
    points = [[0, 0], [5, 0], [5, 5], [10, 5], [10, 10]]
    with pytest.raises(InvalidCurveError, match=r"knot span \[0, 1e-300\] \(knots 2 and 3\)"):
        NurbsCurve(2, [0, 0, 0, 1e-300, 1e-300, 1, 1, 1], points)
    eps = np.finfo(float).eps
    with pytest.raises(InvalidCurveError, match="shorter than a double can resolve"):
        NurbsCurve(2, [0, 0, 0, 0.25 * eps, 0.5, 1, 1, 1], points)
    ok = NurbsCurve(2, [0, 0, 0, 2 * eps, 0.5, 1, 1, 1], points)
    assert np.all(np.isfinite(ok(np.linspace(0, 1, 101), 3)))
    # read from a file: the same refusal, one line naming the file, no warning
    from nurbsmotion.cli import main

    path = tmp_path / "tiny_span.json"
    path.write_text('{"units": "mm", "degree": 2, "knots": [0, 0, 0, 1e-300, 1e-300, 1, 1, 1],'
                    ' "control_points": [[0, 0], [5, 0], [5, 5], [10, 5], [10, 10]]}')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["bound", str(path), "--feed", "50mm/s"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tiny_span.json" in err and "knot span [0, 1e-300]" in err


@pytest.mark.parametrize("degree", [3.0, True, "3", np.float64(3.0)])
def test_non_integer_degree_is_refused(degree):
    # Issue 14: degree=3.0 was accepted; a degree is an integer, never a float or a bool.
    with pytest.raises(InvalidCurveError, match="degree must be an integer"):
        NurbsCurve(degree, CUBIC_KNOTS, SQUARE)


@pytest.mark.parametrize(
    "call, message",
    [
        pytest.param(lambda: make_arc((0, 0), 1.0, 0.5, 0.5), r"arc sweep must be in \(0, 2 pi\]",
                     id="arc-zero-sweep"),
        pytest.param(lambda: make_arc((0, 0), 1.0, 0.0, 7.0), r"got 7\.0 rad",
                     id="arc-sweep-too-large"),
        pytest.param(lambda: make_arc((0, 0), -1.0, 0.0, 1.0),
                     r"arc radius must be finite and > 0, got -1\.0", id="arc-negative-radius"),
        pytest.param(lambda: make_arc((0, 0), 0.0, 0.0, 1.0),
                     r"arc radius must be finite and > 0, got 0\.0", id="arc-zero-radius"),
        pytest.param(lambda: make_arc((0, 0, 0), 1.0, 0.0, 1.0),
                     r"arc center must have 2 coordinates", id="arc-center-3d"),
        pytest.param(lambda: make_circle(-2.0), r"got -2\.0", id="circle-negative-radius"),
        pytest.param(lambda: make_polyline([[0, 0], [1, 1], [1, 1], [2, 0]]),
                     r"polyline points 1 and 2 coincide at \[1\.0, 1\.0\]",
                     id="polyline-repeated"),
        pytest.param(lambda: make_polyline([[0, 0]]), r"at least 2 points, got 1",
                     id="polyline-one-point"),
        pytest.param(lambda: make_polyline([[0, 0], [np.nan, 1]]), r"must be finite",
                     id="polyline-nan"),
        pytest.param(lambda: make_line((1, 2), (1, 2)), r"coincide", id="line-zero-length"),
    ],
)
def test_invalid_factory_input_is_rejected_with_message(call, message):
    with pytest.raises(InvalidCurveError, match=message):
        call()


@pytest.mark.parametrize(
    "u, message",
    [
        (1.5, r"must lie in \[0, 1\], got 1\.5$"),
        (-0.25, r"must lie in \[0, 1\], got -0\.25$"),
        ([0.2, 1.0 + 1e-9], r"got 1\.000000001$"),
        (np.nan, r"must be finite, got \[nan\]"),
        ([0.1, np.inf], r"must be finite, got \[inf\]"),
    ],
)
def test_parameter_outside_domain_raises_value_error_naming_it(u, message):
    # Regression: under numpy 2 the message read "got np.float64(1.5)".
    curve = make_line((0.0, 0.0), (1.0, 1.0))
    with pytest.raises(ValueError, match=message):
        curve(u)


def test_bad_order_or_side_raise_value_error():
    curve = make_line((0.0,), (1.0,))
    with pytest.raises(ValueError, match=r"derivative order must be an integer 0\.\.3, got 4"):
        curve(0.5, 4)
    with pytest.raises(ValueError, match=r"side must be 'right' or 'left', got 'up'"):
        curve(0.5, 1, side="up")


# ---------------------------------------------------------------------- factories
def test_polyline_knots_follow_chord_length_and_vertices_are_corners():
    points = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0], [6.0, 8.0]])
    line = make_polyline(points)
    np.testing.assert_allclose(line.knots, [0, 0, 3 / 12, 7 / 12, 1, 1], rtol=0, atol=EXACT)
    np.testing.assert_allclose(line(line.breakpoints), points, rtol=0, atol=EXACT)
    assert line.length == pytest.approx(12.0, rel=TIGHT)
    np.testing.assert_allclose(line.sharp_corners(), [3 / 12, 7 / 12], rtol=0, atol=EXACT)
    # Turning angles from the segment directions (1,0) -> (0,1) -> (3,4)/5.
    np.testing.assert_allclose(
        line.turning_angle(line.sharp_corners()), [math.pi / 2, math.acos(4 / 5)],
        rtol=0, atol=TIGHT,
    )


def test_line_has_constant_speed_and_no_corner():
    line = make_line((1.0, 2.0, 3.0), (4.0, 6.0, 3.0), name="move", units="mm")
    u = np.linspace(0, 1, 11)
    np.testing.assert_allclose(line(u, 1), np.tile([3.0, 4.0, 0.0], (11, 1)), atol=EXACT)
    np.testing.assert_array_equal(line(u, 2), 0.0)
    assert line.length == pytest.approx(5.0, rel=TIGHT)
    assert (line.name, line.units) == ("move", "mm")
    # Collinear polyline vertices are knots of full multiplicity but not corners.
    straight = make_polyline([[0.0, 0.0], [1.0, 1.0], [3.0, 3.0]])
    assert straight.sharp_corners().size == 0


# ---------------------------------------------------------------------- packaging
def test_import_does_not_import_matplotlib():
    src = Path(__file__).resolve().parents[1] / "src"
    env = dict(os.environ, PYTHONPATH=str(src))
    code = "import sys, nurbsmotion; print('matplotlib' in sys.modules)"
    result = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == "False"


# ---------------------------------------------------------------- isolated zero speed
@pytest.mark.parametrize(
    "degree, knots, points, where, right, left",
    [
        # a control point repeated at the start: C'(0) = 0, C''(0) points at (1, 1)
        (2, [0, 0, 0, 1, 1, 1], [[0, 0], [0, 0], [1, 1]], 0.0, [1, 1], None),
        # repeated at the end: C'(1) = 0; the last span runs straight from (1.5, 0.5)
        (2, [0, 0, 0, 0.5, 1, 1, 1], [[0, 0], [1, 0], [2, 1], [2, 1]], 1.0, None, [1, 1]),
        # repeated inside a cubic: C'(1/2) = 0 with the same direction on both sides
        (3, [0, 0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1, 1],
         [[0, 0], [1, 0], [2, 0], [3, 0], [4, 0], [5, 0], [6, 0]], None, None, None),
    ],
)
def test_zero_speed_points_keep_the_exact_curve(degree, knots, points, where, right, left):
    """A curve with C'(u) = 0 at isolated points is accepted as given (its geometry is
    the control polygon's, unchanged) and its limit tangent is the direction of motion."""
    c = NurbsCurve(degree, knots, points)
    np.testing.assert_array_equal(c.control_points, np.asarray(points, float))
    if where is not None:
        np.testing.assert_allclose(c.zero_speed_points, [where], atol=1e-12)
        if right is not None:
            np.testing.assert_allclose(c.limit_tangent(where, "right"), np.array(right) / np.linalg.norm(right), atol=1e-12)
            np.testing.assert_allclose(c.tangent(where), np.array(right) / np.linalg.norm(right), atol=1e-12)
        if left is not None:
            np.testing.assert_allclose(c.limit_tangent(where, "left"), np.array(left) / np.linalg.norm(left), atol=1e-12)
    assert c.sharp_corners().size == 0
    # arc length against an independent quadrature of |C'| (scipy quad on a fine split)
    from scipy.integrate import quad
    ref = sum(quad(lambda u: float(np.linalg.norm(c(u, 1))), a, b, epsabs=1e-14, epsrel=1e-13)[0]
              for a, b in zip(np.linspace(0, 1, 41)[:-1], np.linspace(0, 1, 41)[1:]))
    assert c.length == pytest.approx(ref, rel=1e-10)
    s = np.linspace(0, c.length, 11)
    np.testing.assert_allclose(c.arc_length(c.parameter_at(s)), s, atol=1e-12 * c.length)


def test_a_cusp_is_a_sharp_corner():
    """A genuine reversal (tangent turns by pi at a point of zero speed) is a corner."""
    c = NurbsCurve(2, [0, 0, 0, 1, 1, 1], [[0.0, 0.0], [1.0, 0.0], [0.0, 0.0001]])
    c2 = NurbsCurve(3, [0, 0, 0, 0, 1, 1, 1, 1], [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0], [1.0, 0.0]])
    assert c.sharp_corners().size == 0 and c.zero_speed_points.size == 0  # no zero speed
    # the symmetric cubic with crossing control legs has a cusp at u = 1/2
    assert c2.zero_speed_points.size == 1 and c2.zero_speed_points[0] == pytest.approx(0.5, abs=1e-9)
    np.testing.assert_allclose(c2.sharp_corners(), [0.5], atol=1e-9)
    assert c2.turning_angle(c2.sharp_corners())[0] == pytest.approx(np.pi, abs=1e-6)


def test_only_a_zero_length_curve_is_refused():
    with pytest.raises(InvalidCurveError, match="zero length"):
        NurbsCurve(2, [0, 0, 0, 1, 1, 1], [[1.0, 2.0]] * 3)


def test_bounding_box_is_exact_against_a_dense_sample():
    """The box from span ends and each axis's turning points holds every point of a
    dense sample and each extreme that a bounded scalar minimiser (scipy) finds from the
    sample's best point; its corners are points of the curve (made by evaluating it), so
    it is no larger than the curve. Circles, the benchmark paths and random rational
    curves."""
    from scipy.optimize import minimize_scalar
    from random_curves import random_curve

    from nurbsmotion.nurbs import builtin_path, make_circle, make_die_bonder_pi

    rng = np.random.default_rng(5)
    curves = [make_circle(3.0), builtin_path("butterfly"), make_die_bonder_pi()]
    curves += [random_curve(rng) for _ in range(8)]
    for curve in curves:
        box = curve.bounding_box()
        pts = curve(np.linspace(0.0, 1.0, 200_001))
        size = float(np.max(np.ptp(pts, axis=0)))
        assert np.all(pts >= box[0] - 1e-12 * size) and np.all(pts <= box[1] + 1e-12 * size)
        u = np.linspace(0.0, 1.0, 200_001)
        for j in range(curve.n_axes):
            for row, sign in ((0, 1.0), (1, -1.0)):
                i = int(np.argmin(sign * pts[:, j]))
                lo, hi = u[max(i - 1, 0)], u[min(i + 1, len(u) - 1)]
                best = minimize_scalar(lambda x: sign * curve(x)[j], bounds=(lo, hi),
                                       method="bounded", options={"xatol": 1e-14})
                assert sign * box[row, j] <= min(sign * pts[i, j], best.fun) + 1e-12 * size
    np.testing.assert_allclose(make_circle(3.0).bounding_box(), [[-3, -3], [3, 3]],
                               rtol=0, atol=1e-12)


def test_the_pruned_box_and_zero_speed_points_equal_the_search_of_every_span():
    """Regression (issue 37: ``contours`` and ``interpolate`` took minutes on a
    million-span spline): the bounding box looks for turning points only in spans whose
    control points pass outside the box of the breakpoints (convex hull), the zero-speed
    search only in spans where no axis's hodograph keeps one sign; both give exactly what
    the search of every span gives, on random (rational) curves, a long wave and curves
    that stop at a repeated control point."""
    from random_curves import random_curve

    rng = np.random.default_rng(37)
    x = np.arange(2000) * 0.01
    wave = NurbsCurve(3, np.r_[[0.0] * 3, np.arange(1998.0), [1997.0] * 3],
                      np.column_stack([x, 2.0 * np.sin(x / 0.3)]))
    stops = NurbsCurve(3, [0, 0, 0, 0, 1, 2, 3, 4, 4, 4, 4],
                       [[0, 0], [1, 0], [2, 1], [2, 1], [2, 1], [3, 0], [4, 2]])
    curves = [wave, stops] + [random_curve(rng) for _ in range(12)]
    for curve in curves:
        if curve.degree == 1:
            continue
        _, _, turns = curve._axis_turns()
        pts = curve(np.concatenate([curve.breakpoints, turns[~np.isnan(turns)]]))
        np.testing.assert_array_equal(curve.bounding_box(),
                                      [pts.min(axis=0), pts.max(axis=0)])
        every = NurbsCurve(curve.degree, curve.knots, curve.control_points, curve.weights)
        every._spans_that_may_stop = lambda: np.arange(len(every.breakpoints) - 1)
        np.testing.assert_array_equal(curve.zero_speed_points, every.zero_speed_points)
    assert stops.zero_speed_points.size == 1 and wave._spans_that_may_stop().size == 0


def test_a_polylines_corners_are_its_vertices_where_the_left_and_right_tangents_turn():
    """The corners of a degree-1 curve come from its segments' directions (a million in
    one pass, issue 37): the same vertices as the curve's own left and right tangents
    give, on random polylines with weights, collinear runs and reversals, at several
    tolerances."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        n = int(rng.integers(3, 60))
        P = np.cumsum(rng.normal(size=(n, 2)), axis=0)
        for i in np.flatnonzero(rng.random(n - 2) < 0.3) + 1:  # vertices on straight runs
            P[i] = 0.5 * (P[i - 1] + P[i + 1])
        if rng.random() < 0.3 and n > 3:  # a reversal
            P[2] = P[1] - 0.5 * (P[2] - P[1])
        knots = np.r_[0.0, np.sort(rng.random(n - 2)), 1.0]
        knots = np.r_[0.0, knots, 1.0]
        w = rng.uniform(0.5, 2.0, n) if rng.random() < 0.5 else None
        curve = NurbsCurve(1, knots, P, w)
        inner = curve.knots[2:-2]
        angle = curve.turning_angle(inner)
        for tol in (1e-6, 0.1, 1.0):
            np.testing.assert_array_equal(curve.sharp_corners(tol), inner[angle > tol])


def test_sharp_corners_need_no_arc_length_table():
    """The planner's size check counts a path's corners before any arc length (issue 37):
    the corners are not computed through the arc-length table."""
    curve = NurbsCurve(2, [0, 0, 0, 1, 1, 2, 2, 2], [[0, 0], [1, 0], [1, 0], [1, 1], [2, 2]],
                       [1, 2, 1, 1, 1])
    assert curve.sharp_corners().size == 1 and curve._geometry is None
    assert curve.geometry.sharp_corners().tolist() == curve.sharp_corners().tolist()


def test_a_control_point_repeated_degree_times_is_one_corner():
    """A cubic whose control point is repeated three times stops at one knot, a corner
    turning from the incoming leg to the outgoing one. C' has a root of high order
    there, which a polynomial root finder places only to about eps^(1/3) (5e-9 in the
    parameter, where the machine sweep's case 101 listed the same corner twice)."""
    knots = [0, 0, 0, 0, 1 / 7, 2 / 7, 3 / 7, 4 / 7, 5 / 7, 6 / 7, 1, 1, 1, 1]
    P = [[0, 0], [-5098.6, -9730.2], [-8243.2, -5466.7], [-8243.2, -5466.7],
         [-8243.2, -5466.7], [-8111.3, -6024.7], [-10590.3, -2049.7], [-11282.3, -1157.9],
         [-9333.0, 10269.8], [-8331.6, 9516.4]]
    c = NurbsCurve(3, knots, P)
    knot = c.breakpoints[2]  # the span where P2 = P3 = P4 act alone: C(2/7) = P3
    np.testing.assert_allclose(c(knot), P[3], atol=1e-9)
    np.testing.assert_array_equal(c.zero_speed_points, [knot])
    np.testing.assert_array_equal(c.sharp_corners(), [knot])
    legs = np.array([np.subtract(P[3], P[1]), np.subtract(P[5], P[3])])
    expected = np.arccos(np.dot(legs[0], legs[1]) / np.prod(np.linalg.norm(legs, axis=1)))
    assert c.turning_angle(knot) == pytest.approx(expected, abs=1e-6)
