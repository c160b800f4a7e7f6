"""The closed loop, the paper's interpolator and the metrics (SPEC sections 4, 6, 7, 9)."""

import math

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.interpolators import PaperInterpolator, TaylorInterpolator
from nurbsmotion.loop import interpolate
from nurbsmotion.loop import run, simulate
from nurbsmotion.machine import die_bonder
from nurbsmotion.metrics import contour_error

CIRCLE = nm.make_circle(10_000.0)


def steady_following_error(trace, start=0.3, margin=5):
    k0 = int(start / trace.machine.sample_period)
    f = trace.position_command - trace.position
    return np.max(np.abs(f[k0: trace.finished_index - margin]), axis=0)


def test_pd_plus_follows_ten_times_better_than_pd_on_the_circle():
    """Circle R = 10,000 at 5e4 pulse/s, nothing saturates: ours 0.012 (PD+) vs 1.70 (PD)
    pulse on X over the steady part."""
    errors = {}
    for controller in ("pd+", "pd"):
        m = die_bonder(controller=controller)
        tr = run(CIRCLE, m, 5e4, "taylor2")
        assert tr.metrics().total_saturated_samples == 0
        errors[controller] = steady_following_error(tr)
    assert errors["pd"][0] == pytest.approx(1.70, rel=0.02)
    assert errors["pd+"][0] < 0.05
    assert np.all(errors["pd"] >= 10 * errors["pd+"])


def test_paper_with_unlimited_drive_is_the_constant_feed_interpolator():
    m = die_bonder(max_drive=math.inf)
    for order in (1, 2):
        tr = simulate(PaperInterpolator(CIRCLE, m, 2e5, order=order), m)
        ref = interpolate(TaylorInterpolator(CIRCLE, m.sample_period, 2e5, order=order))
        n = len(ref.u)
        np.testing.assert_array_equal(tr.u[:n], ref.u)
        np.testing.assert_array_equal(tr.position_command[:n], ref.position)
        assert tr.finished_index == ref.finished_index


def test_paper_avoids_the_start_saturation_on_the_circle():
    """At 2e5 pulse/s constant feed saturates Y at the start; eq. 3.1 with the paper's
    bound keeps every sample within Umax. With eq. 3.2 (the paper's own first-order step)
    the first sample still exceeds Umax by 0.4 %, because |C'(u)| of the rational circle
    grows away from the quarter points and the first-order step overshoots the estimate."""
    m = die_bonder()
    const = run(CIRCLE, m, 2e5, "taylor1").metrics()
    assert const.saturated_samples["y"] >= 1
    second = simulate(PaperInterpolator(CIRCLE, m, 2e5, order=2), m)
    assert np.all(np.abs(second.drive) <= m.max_drive * (1 + 1e-9))
    first = simulate(PaperInterpolator(CIRCLE, m, 2e5, order=1), m)
    ratio = np.abs(first.drive).max(axis=0) / m.max_drive
    assert ratio[1] == pytest.approx(1.004, abs=5e-4)
    assert np.flatnonzero(np.abs(first.drive[:, 1]) > m.max_drive).tolist() == [1]


def test_paper_still_saturates_at_the_abrupt_stop_of_a_fast_circle():
    m = die_bonder()
    tr = simulate(PaperInterpolator(CIRCLE, m, 3e5, order=2), m)
    sat = np.flatnonzero(np.any(np.abs(tr.drive) > m.max_drive * (1 + 1e-6), axis=1))
    assert sat.tolist() == [tr.finished_index + 1]


def test_paper_on_pi_at_1m_s_reports_its_corner_and_end_saturation():
    """SPEC section 7: the faithful algorithm still saturates at the corners and the end."""
    m = die_bonder()
    pi = nm.make_die_bonder_pi()
    tr = run(pi, m, 1e6, "paper")
    met = tr.metrics()
    assert met.saturated_samples["x"] > 0
    sat_u = tr.u[np.any(np.abs(tr.drive) > m.max_drive * (1 + 1e-6), axis=1)]
    near_corner = np.any(np.abs(sat_u[:, None] - np.array([1 / 3, 2 / 3])) < 0.05, axis=1)
    assert near_corner.any() and (sat_u == 1.0).any()
    const = run(pi, m, 1e6, "taylor1").metrics()
    assert const.max_drive_ratio["x"] > 5  # SPEC section 8: a factor of five or more
    assert met.max_drive_ratio["x"] < const.max_drive_ratio["x"]
    assert met.max_contour_error < const.max_contour_error


def test_trace_rows_follow_the_discrete_law():
    """Recompute u[k] from the trace's own thd and tha with eq. 3.3, independently."""
    m = die_bonder()
    tr = run(nm.make_die_bonder_pi(), m, 5e5, "paper")
    Ts, Ke = m.sample_period, m.Ke
    thd = np.vstack([tr.position_command[:1], tr.position_command])
    tha = np.vstack([tr.position[:1], tr.position])
    wd = np.diff(thd, axis=0) / (Ke * Ts)
    wa = np.diff(tha, axis=0) / (Ke * Ts)
    ad = np.diff(np.vstack([np.zeros((1, 2)), wd]), axis=0) / Ts
    u = m.Kp * (thd[1:] - tha[1:]) + m.Kd * (wd - wa) + wd / m.Kc + m.tau * ad / m.Kc
    np.testing.assert_allclose(tr.drive, u, rtol=1e-9, atol=1e-9 * m.max_drive)
    np.testing.assert_array_equal(tr.drive_applied, np.clip(tr.drive, -10, 10))


def test_loop_starts_at_rest_and_holds_the_end():
    m = die_bonder()
    tr = run(nm.make_die_bonder_pi(), m, 2e5, "taylor2", settle_time=0.3)
    np.testing.assert_array_equal(tr.position[0], [0, 0])
    np.testing.assert_array_equal(tr.drive[0], [0, 0])
    assert tr.u[tr.finished_index] == 1.0 and np.all(tr.u[tr.finished_index:] == 1.0)
    assert np.all(np.diff(tr.u) >= 0)
    assert tr.cycle_time == pytest.approx(tr.finished_index * 1e-3)
    assert np.max(np.abs(tr.position[-1] - [60000, 0])) < 0.5


def test_true_speed_measurement_is_offered():
    """With the true motor speed in the Kd term, the speed error compares an instantaneous
    speed with the backward-difference command: 0.178 pulse on X instead of 0.012."""
    m = die_bonder(speed_measurement="true")
    tr = run(CIRCLE, m, 5e4, "taylor2")
    assert steady_following_error(tr)[0] == pytest.approx(0.178, rel=0.02)


def test_contour_error_against_the_exact_circle_distance():
    rng = np.random.default_rng(3)
    angle = rng.uniform(0, 2 * np.pi, 500)
    radius = 10_000 + rng.uniform(-300, 300, 500)
    pts = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    np.testing.assert_allclose(contour_error(CIRCLE, pts), np.abs(radius - 10_000), atol=1e-3)


def test_contour_error_at_a_sharp_corner():
    """Points beyond the Pi's corner at (0, 20000): the nearest curve point is the corner."""
    pi = nm.make_die_bonder_pi()
    pts = np.array([[-30.0, 20_040.0], [-100.0, 20_000.0], [0.0, 10_000.0]])
    d = contour_error(pi, pts)
    assert d[0] == pytest.approx(50.0, abs=0.01)
    assert d[1] == pytest.approx(100.0, abs=0.01)
    assert d[2] == pytest.approx(0.0, abs=0.01)


def test_replay_of_a_parameter_sequence_equals_the_original_run():
    m = die_bonder()
    pi = nm.make_die_bonder_pi()
    ref = simulate(TaylorInterpolator(pi, 1e-3, 5e5, 2), m)
    from nurbsmotion.interpolators import ReplayInterpolator

    replay = simulate(ReplayInterpolator(pi, 1e-3, ref.u[: ref.finished_index + 1]), m)
    np.testing.assert_array_equal(replay.position_command, ref.position_command)
    np.testing.assert_array_equal(replay.drive, ref.drive)
    with pytest.raises(ValueError, match="parameters decrease at sample 2"):
        ReplayInterpolator(pi, 1e-3, [0.0, 0.5, 0.4, 1.0])
    with pytest.raises(ValueError, match="must start at 0 and end at 1"):
        ReplayInterpolator(pi, 1e-3, [0.0, 0.5])


def test_a_ten_minute_move_runs_without_a_sample_limit():
    """600,000 samples: the default safety limit scales with the commanded move."""
    m = die_bonder()
    curve = nm.make_butterfly().scaled(1000.0, units="pulse")
    tr = run(curve, m, curve.length / 600.0, "paper", settle_time=0.0)
    assert tr.finished_index == pytest.approx(600_000, abs=10)
    assert tr.u[-1] == 1.0


def test_a_diverging_loop_is_a_failed_run_that_says_so():
    """Without a drive limit, a plant 300x stronger than the model makes the PD+ loop
    unstable: the positions overflow. simulate() returns the trace with success False
    and a message that says the loop diverged (not only that it did not settle)."""
    from nurbsmotion.servo import ServoPlant

    machine = die_bonder().with_options(max_drive=math.inf)
    curve = nm.make_die_bonder_pi()
    plant = ServoPlant.of_machine(machine, curve(0.0), electrical_gain_scale=300.0)
    trace = simulate(TaylorInterpolator(curve, machine.sample_period, 2e5, 1), machine,
                     plant=plant, settle_time=0.05, settle_limit=0.5)
    assert not np.all(np.isfinite(trace.position))
    assert not trace.success
    assert trace.message.startswith("the closed loop diverged")


def test_planned_has_no_open_loop_setpoints():
    """``interpolate`` runs an interpolator without a servo loop; ``planned``'s setpoints
    invert the loop's law, which has no gains there: a typed error that names it and says
    how to run it, not a division by zero inside the compiled step."""
    from nurbsmotion.errors import InvalidArgumentError
    from nurbsmotion.interpolators import PlannedInterpolator
    from nurbsmotion.loop import interpolate
    m = die_bonder()
    it = PlannedInterpolator(nm.make_die_bonder_pi(), m, 1e6)
    with pytest.raises(InvalidArgumentError, match="planned.*simulate"):
        interpolate(it)
