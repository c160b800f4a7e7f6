"""Open-loop interpolators (SPEC section 5) and the feedrate fluctuation (section 9)."""

import math

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.errors import InvalidFeedError
from nurbsmotion.interpolators import TaylorInterpolator, UniformInterpolator, make_open_loop
from nurbsmotion.loop import interpolate

CIRCLE = nm.make_circle(10_000.0)


def fluctuation(curve, feed, order):
    return interpolate(TaylorInterpolator(curve, 1e-3, feed, order)).feed_fluctuation()


def test_second_order_fluctuates_less_on_the_circle():
    """Radius 10,000 at F = 1e6/s, Ts = 1 ms: 1st order 1.98 % max, 2nd order 0.17 %."""
    max1, rms1 = fluctuation(CIRCLE, 1e6, 1)
    max2, rms2 = fluctuation(CIRCLE, 1e6, 2)
    assert max1 == pytest.approx(0.0198, abs=5e-4)
    assert max2 < 0.002 and rms2 < rms1 / 5


def test_second_order_fluctuates_less_on_the_butterfly():
    """Butterfly (mm) at 100 mm/s: RMS 2.46 % vs 1.78 %. The maximum (77 % vs 75 %) sits at
    the near-cusps, whose radius of curvature (0.023 mm) is below the 0.1 mm step, so no
    chord can match the arc there."""
    b = nm.make_butterfly()
    max1, rms1 = fluctuation(b, 100.0, 1)
    max2, rms2 = fluctuation(b, 100.0, 2)
    assert rms2 < 0.8 * rms1
    assert max2 < max1
    assert 1 / np.max(b.curvature(np.linspace(0.25, 0.26, 20001))) < 0.1


@pytest.mark.parametrize("method", ["uniform", "taylor1", "taylor2"])
def test_lands_exactly_on_the_end_and_holds_it(method):
    pi = nm.make_die_bonder_pi()
    interp = make_open_loop(method, pi, 1e-3, 5e5)
    series = interpolate(interp)
    assert series.u[-1] == 1.0 and np.all(np.diff(series.u) > 0)
    np.testing.assert_array_equal(series.position[-1], [60000.0, 0.0])
    np.testing.assert_array_equal(series.position[0], [0.0, 0.0])
    assert series.finished_index == len(series.u) - 1


def test_steps_across_sharp_corners_keep_the_arc_length_step():
    """On a polyline |C'| is constant per span, so 1st order is exact: every full step
    travels V*Ts along the path, also the steps that cross a corner."""
    path = nm.make_polyline([[0, 0], [100, 0], [100, 37], [0, 80]])
    series = interpolate(TaylorInterpolator(path, 1e-3, 2_000.0, order=1))
    s = path.arc_length(series.u)
    np.testing.assert_allclose(np.diff(s)[:-1], 2.0, rtol=1e-9)
    assert np.diff(s)[-1] <= 2.0


def test_uniform_steps_the_parameter_evenly():
    pi = nm.make_die_bonder_pi()
    interp = UniformInterpolator.for_feed(pi, 1e-3, 5e5)
    series = interpolate(interp)
    np.testing.assert_allclose(np.diff(series.u)[:-1], interp.parameter_step, rtol=1e-12)
    assert interp.parameter_step == pytest.approx(5e5 * 1e-3 / pi.length)


def test_feed_function_is_followed_with_the_acceleration_term():
    """A feed rising linearly in u: over each step the mean speed should be the mean of V
    at its two ends; the tangential-acceleration term (2nd order) gets it, the 1st-order
    step lags by A*Ts/2."""
    line = nm.make_line([0.0, 0.0], [1000.0, 0.0])

    def feed(u):
        return 1_000.0 + 50_000.0 * u

    worst = {}
    for order in (1, 2):
        series = interpolate(TaylorInterpolator(line, 1e-3, feed, order))
        speed = np.diff(series.position[:, 0])[:-1] / 1e-3
        target = 0.5 * (feed(series.u[:-2]) + feed(series.u[1:-1]))
        worst[order] = np.max(np.abs(speed - target) / target)
    assert worst[2] < worst[1] / 10


@pytest.mark.parametrize("feed", [0.0, -5.0, math.nan, math.inf])
def test_bad_feed_is_a_clear_error(feed):
    with pytest.raises(InvalidFeedError, match="feed must be finite and > 0"):
        TaylorInterpolator(CIRCLE, 1e-3, feed)


def test_feed_function_that_stops_is_an_error_not_a_hang():
    with pytest.raises(InvalidFeedError, match=r"feed function returned 0.0 at u = 0.5"):
        TaylorInterpolator(CIRCLE, 1e-3, lambda u: 1e5 if u < 0.5 else 0.0)


def test_piecewise_feed_keeps_each_interval_s_speed():
    """A feed of 2,000 on the first half of a polyline's parameter and 500 on the rest:
    1st-order steps on straight spans travel exactly V*Ts."""
    from nurbsmotion.feed import FeedLimit

    path = nm.make_polyline([[0, 0], [100, 0], [100, 100]])
    feed = FeedLimit([0.0, 0.5, 1.0], [2000.0, 500.0])
    series = interpolate(TaylorInterpolator(path, 1e-3, feed, order=1))
    steps = np.diff(path.arc_length(series.u))
    first = series.u[:-1] < 0.5
    np.testing.assert_allclose(steps[first][:-1], 2.0, rtol=1e-9)
    np.testing.assert_allclose(steps[~first][:-1], 0.5, rtol=1e-9)
    with pytest.raises(nm.NurbsmotionError, match="breakpoints"):
        TaylorInterpolator(path, 1e-3, FeedLimit([0.0, 1.0], [1.0, 2.0]))


def test_bad_sample_period_and_method():
    with pytest.raises(ValueError, match="sample_period must be finite and > 0, got -0.001"):
        TaylorInterpolator(CIRCLE, -1e-3, 1e5)
    with pytest.raises(ValueError, match="unknown interpolation method 'spline'"):
        make_open_loop("spline", CIRCLE, 1e-3, 1e5)
