"""The compiled NURBS kernels against the scipy reference route (The NURBS Book A2.1,
A2.3, A4.2 against ``BSpline`` in homogeneous coordinates)."""

import numpy as np
import pytest

import nurbsmotion as nm
from random_curves import N_CASES, random_curve

RTOL = 1e-12
"""Compiled versus reference: relative to the largest value of each derivative order."""


def assert_agree(curve, u, side):
    got = curve.derivatives(u, 3, side)
    ref = curve._derivatives_reference(u, 3, side)
    assert got.shape == ref.shape
    for k in range(4):
        scale = max(np.max(np.abs(ref[k])), 1e-300)
        np.testing.assert_allclose(got[k], ref[k], rtol=RTOL, atol=RTOL * scale,
                                   err_msg=f"order {k}, side {side}")


def parameters(curve, m=401):
    """A grid plus every breakpoint, where the one-sided rule matters."""
    return np.unique(np.concatenate([np.linspace(0.0, 1.0, m), curve.breakpoints]))


@pytest.mark.parametrize("side", ["right", "left"])
@pytest.mark.parametrize("name", ["die-bonder-pi", "butterfly"])
def test_benchmarks_agree_with_the_reference(name, side):
    curve = nm.builtin_path(name)
    assert_agree(curve, parameters(curve, 2001), side)


@pytest.mark.parametrize("side", ["right", "left"])
def test_random_curves_agree_with_the_reference(side):
    rng = np.random.default_rng(11)
    for _ in range(N_CASES):
        curve = random_curve(rng)
        assert_agree(curve, parameters(curve), side)


def test_one_sided_derivatives_at_a_corner():
    """The Pi's corner at u = 1/3: from the left it moves up (+y), from the right along x."""
    pi = nm.make_die_bonder_pi()
    left = pi(1 / 3, 1, "left")
    right = pi(1 / 3, 1, "right")
    assert left[0] == pytest.approx(0.0, abs=1e-6) and left[1] > 0
    assert right[0] > 0
    np.testing.assert_allclose(pi(1 / 3, 0, "left"), pi(1 / 3, 0, "right"), atol=1e-9)


def test_shapes_follow_the_parameter():
    c = nm.make_circle(2.0)
    assert c.derivatives(0.5, 2).shape == (3, 2)
    assert c.derivatives(np.zeros((3, 4)), 1).shape == (2, 3, 4, 2)
    assert c(np.array([]), 1).shape == (0, 2)


def test_derivatives_above_the_degree_are_zero_for_a_polyline():
    line = nm.make_polyline([[0.0, 0.0], [1.0, 2.0], [3.0, 2.0]])
    d = line.derivatives(np.linspace(0, 1, 7), 3)
    assert np.all(d[2] == 0.0) and np.all(d[3] == 0.0)


def loop_path_agrees(curve, us, order):
    """The compiled loop's path (the power form, Horner) against the reference route,
    right-sided, orders 0 .. ``order``, relative to the largest value of each order."""
    from nurbsmotion.interpolators.base import (path_data, path_derivatives, path_point,
                                                path_scratch)

    path = path_data(curve, 2)
    ref = curve._derivatives_reference(us, order, "right")
    got = np.empty_like(ref)
    d = path_scratch(path)
    point = np.empty(curve.n_axes)
    for i, u in enumerate(us):
        got[:, i] = path_derivatives(path, float(u), order, d)[: order + 1]
        path_point(path, float(u), point)
        np.testing.assert_array_equal(point, got[0, i])  # one route for points
    for k in range(order + 1):
        scale = max(np.max(np.abs(ref[k])), 1e-300)
        np.testing.assert_allclose(got[k], ref[k], rtol=RTOL, atol=RTOL * scale,
                                   err_msg=f"order {k}")


def test_the_loops_power_form_agrees_with_the_reference():
    """Knots, corners, tiny spans (1e-6 of the domain) and degree 5 included."""
    rng = np.random.default_rng(3)
    curves = [nm.builtin_path("butterfly"), nm.make_die_bonder_pi()]
    curves += [random_curve(rng) for _ in range(N_CASES)]
    tiny = np.concatenate([np.zeros(6), [0.4, 0.4 + 1e-6, 0.7], np.ones(6)])
    curves.append(nm.NurbsCurve(5, tiny, np.cumsum(rng.normal(size=(9, 3)), axis=0),
                                rng.uniform(0.3, 4.0, 9)))
    for curve in curves:
        loop_path_agrees(curve, parameters(curve), 2)


def test_importing_the_package_compiles_nothing_and_loads_no_plotting():
    """numba loads with the first evaluation, matplotlib only with the first figure."""
    import subprocess
    import sys

    code = ("import sys, nurbsmotion; "
            "print('matplotlib' in sys.modules, 'numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "False"]
