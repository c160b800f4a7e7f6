"""The compiled closed loop against the readable reference loop (``compiled=False``):
the same trace to 1e-12 relative on the benchmarks and on random curves of any degree and
axis count."""

import copy
import math

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.interpolators import (PaperInterpolator, PlannedInterpolator,
                                       TaylorInterpolator, make_interpolator)
from nurbsmotion.loop import _compiled_feed, simulate, to_pulses
from nurbsmotion.machine import Axis, Machine, die_bonder
from nurbsmotion.servo import ServoPlant
from random_curves import N_CASES, random_curve

RTOL = 1e-12
"""Compiled versus reference: relative to the largest value of each recorded quantity."""

FIELDS = ("u", "position_command", "position", "speed_command", "speed", "drive",
          "drive_applied", "feed")


def assert_same_trace(a, b):
    assert len(a.t) == len(b.t) and a.finished_index == b.finished_index
    np.testing.assert_array_equal(a.t, b.t)
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape, name
        scale = max(np.max(np.abs(y)), 1e-300)
        np.testing.assert_allclose(x, y, rtol=RTOL, atol=RTOL * scale, err_msg=name)
    if b.speed_bounds is None:
        assert a.speed_bounds is None
    else:
        np.testing.assert_array_equal(np.isnan(a.speed_bounds), np.isnan(b.speed_bounds))
        scale = np.nanmax(np.abs(b.speed_bounds))
        np.testing.assert_allclose(a.speed_bounds, b.speed_bounds, rtol=RTOL,
                                   atol=RTOL * scale)


def both_loops(make, machine, **options):
    return (simulate(make(), machine, **options),
            simulate(make(), machine, compiled=False, **options))


@pytest.mark.parametrize("method", ["taylor1", "taylor2", "paper"])
@pytest.mark.parametrize("name, feeds", [("die-bonder-pi", (2e5, 5e5, 1e6)),
                                         ("butterfly", (5e4, 2e5))])
def test_benchmarks_run_the_same_in_both_loops(name, feeds, method):
    m = die_bonder()
    path = to_pulses(nm.builtin_path(name), m)
    for feed in feeds:
        assert_same_trace(*both_loops(lambda: make_interpolator(method, path, m, feed), m))


def random_machine(rng, n_axes):
    x = (0.31, 2506.17, 1591.5494, 0.0136, 0.03)
    y = (0.135, 3156.23, 1591.5494, 0.00577, 0.028)
    axes = tuple(Axis(f"a{j}", *(v * rng.uniform(0.8, 1.25) for v in (x, y)[j % 2]))
                 for j in range(n_axes))
    return Machine(axes, max_drive=float(rng.choice([10.0, 3.0, math.inf])),
                   sample_period=float(rng.choice([1e-3, 5e-4])),
                   controller=str(rng.choice(["pd+", "pd"])),
                   speed_measurement=str(rng.choice(["encoder", "true"])))


def test_random_curves_and_machines_run_the_same_in_both_loops():
    rng = np.random.default_rng(5)
    for _ in range(N_CASES):
        curve = random_curve(rng, scale=3000.0)
        m = random_machine(rng, curve.n_axes)
        feed = float(rng.uniform(5e4, 1e6))
        order = int(rng.integers(1, 3))
        start = curve(0.0)
        for make in (lambda: PaperInterpolator(curve, m, feed, order=order),
                     lambda: TaylorInterpolator(curve, m.sample_period, feed, order=order)):
            # A plant that differs from the model, as a user may pass one.
            plants = [ServoPlant.of_machine(m, start, time_constant_scale=1.2,
                                            electrical_gain_scale=0.8) for _ in range(2)]
            a = simulate(make(), m, plant=plants[0], settle_time=0.01)
            b = simulate(make(), m, plant=plants[1], settle_time=0.01, compiled=False)
            assert_same_trace(a, b)
            np.testing.assert_allclose(plants[0].position, plants[1].position, rtol=RTOL)


def test_growing_the_rows_resumes_the_run():
    """A paper run far slower than its commanded feed outgrows the first guess of rows."""
    m = die_bonder(max_drive=0.3)
    path = nm.make_die_bonder_pi()
    a, b = both_loops(lambda: PaperInterpolator(path, m, 1e6), m)
    assert len(a.t) > 2 * 1.2 * path.length / 1e6 / m.sample_period
    assert_same_trace(a, b)


def test_both_loops_report_the_same_sample_limit():
    m = die_bonder()
    path = nm.make_die_bonder_pi()
    messages = []
    for compiled in (True, False):
        with pytest.raises(nm.InfeasibleError) as err:
            simulate(TaylorInterpolator(path, m.sample_period, 2e5), m, max_samples=100,
                     compiled=compiled)
        messages.append(str(err.value))
    assert messages[0] == messages[1]


def test_a_feed_function_runs_in_the_reference_loop():
    m = die_bonder()
    path = nm.make_die_bonder_pi()
    tr = simulate(TaylorInterpolator(path, m.sample_period, lambda u: 2e5 + 1e5 * u), m)
    assert tr.u[tr.finished_index] == 1.0


def same_planned_runs(interp, machine, plant=None, **options):
    """Both loops on one planned interpolator (each with its own copy of ``plant``): the
    traces, the plants' final states and the stepper's state after the run agree."""
    plants = [None, None] if plant is None else [copy.deepcopy(plant) for _ in range(2)]
    runs = []
    for compiled, pl in zip((True, False), plants):
        trace = simulate(interp, machine, plant=pl, compiled=compiled, **options)
        runs.append((trace, interp.u, interp._phi, interp._s, interp.slowdowns, pl))
    (a, *state_a, pa), (b, *state_b, pb) = runs
    assert_same_trace(a, b)
    assert state_a == state_b
    if pa is not None:
        np.testing.assert_allclose(pa.position, pb.position, rtol=RTOL)
    return a, b


def saturated(trace):
    return int(np.sum(np.max(np.abs(trace.drive), axis=1) > trace.machine.max_drive))


@pytest.mark.parametrize("name, feeds", [("die-bonder-pi", (2e5, 5e5, 1e6, 2e6)),
                                         ("butterfly", (5e4, 1e5, 2e5))])
def test_planned_runs_the_same_in_both_loops(name, feeds):
    """The benchmarks, with the model's plant and with tau 20 % larger and Kc 20 % smaller
    (where the safety layer shortens and lengthens steps most)."""
    m = die_bonder()
    path = to_pulses(nm.builtin_path(name), m)
    start = path(0.0)
    for feed in feeds:
        interp = PlannedInterpolator(path, m, feed)
        for plant in (None, ServoPlant.of_machine(m, start, time_constant_scale=1.2,
                                                  electrical_gain_scale=0.8)):
            a, b = same_planned_runs(interp, m, plant)
            assert saturated(a) == saturated(b)


def test_planned_on_random_curves_and_machines_runs_the_same_in_both_loops():
    rng = np.random.default_rng(11)
    ran = 0
    for _ in range(max(N_CASES // 2, 1)):
        curve = random_curve(rng, scale=3000.0)
        m = random_machine(rng, curve.n_axes)
        feed = float(rng.uniform(5e4, 1e6))
        try:
            interp = PlannedInterpolator(curve, m, feed, grid_size=1000, check_iterations=3)
        except nm.InfeasibleError:
            continue
        plant = ServoPlant.of_machine(m, curve(0.0), time_constant_scale=1.2,
                                      electrical_gain_scale=0.8)
        same_planned_runs(interp, m, plant, settle_time=0.01)
        ran += 1
    assert ran >= max(N_CASES // 4, 1)


def test_planned_without_safety_layer_runs_the_same_in_both_loops():
    """No speed bounds are recorded then, as in the reference."""
    m = die_bonder()
    interp = PlannedInterpolator(nm.make_die_bonder_pi(), m, 1e6, safety_layer=False)
    a, b = same_planned_runs(interp, m)
    assert a.speed_bounds is None


def test_planned_subclasses_run_in_the_reference_loop():
    """A subclass may override the step, so only the exact class is compiled."""
    class Slower(PlannedInterpolator):
        pass

    m = die_bonder()
    path = nm.make_die_bonder_pi()
    assert _compiled_feed(PlannedInterpolator(path, m, 5e5, check_iterations=0)) is not None
    assert _compiled_feed(Slower(path, m, 5e5, check_iterations=0)) is None
