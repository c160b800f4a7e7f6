"""Time-optimal bound (SPEC section 9) and the ``planned`` interpolator (issue 4).

Measured on the die-bonder preset (Ts = 1 ms), default parameters, closed loop; the
docstrings quote the numbers the assertions guard.
"""

from __future__ import annotations

import functools
import math
import os

import numpy as np
import pytest
from scipy.optimize import brentq

import nurbsmotion as nm
from nurbsmotion.errors import InfeasibleError, InvalidCurveError, InvalidFeedError
from nurbsmotion.interpolators import LOOP_METHODS, make_interpolator
from nurbsmotion.interpolators.planned.identify import HIST_ROWS
from nurbsmotion.interpolators.planned import PlannedInterpolator
from nurbsmotion.loop import simulate, to_pulses
from nurbsmotion.metrics import contour_error
from nurbsmotion.interpolators.planned.plan import plan_motion
from nurbsmotion.machine import Axis, die_bonder
from nurbsmotion.nurbs import NurbsCurve
from nurbsmotion.planning import speed_profile, time_optimal_bound
from nurbsmotion.servo import ServoPlant, zoh_matrices

MACHINE = die_bonder()
PI = nm.make_die_bonder_pi()


@pytest.fixture(scope="module")
def butterfly():
    return to_pulses(nm.make_butterfly(), MACHINE)


# ------------------------------------------------------------------ the bound
def line_time(L: float, F: float, M: float, tau: float) -> float:
    """Least time over a straight line of one first-order axis, ``tau*xdd + xd = u*M``
    with ``|u| <= 1``, ``xd <= F``, at rest at both ends: full drive up, full drive down
    (derived from the exact exponential solutions, independently of the planner).

    Up from rest: ``v = M (1 - exp(-t/tau))``; t_up(v) = tau ln(M / (M - v)), distance
    ``M t_up - tau v``. Down to rest from v: t_dn(v) = tau ln((M + v) / M), distance
    ``tau v - M t_dn``.
    """
    t_up = lambda v: tau * math.log(M / (M - v))          # noqa: E731
    t_dn = lambda v: tau * math.log((M + v) / M)          # noqa: E731
    d_up = lambda v: M * t_up(v) - tau * v                 # noqa: E731
    d_dn = lambda v: tau * v - M * t_dn(v)                 # noqa: E731
    if d_up(F) + d_dn(F) <= L:
        return t_up(F) + t_dn(F) + (L - d_up(F) - d_dn(F)) / F
    v = brentq(lambda v: d_up(v) + d_dn(v) - L, 1e-9 * F, F)
    return t_up(v) + t_dn(v)


@pytest.mark.parametrize("L, F", [(50_000.0, 1e6), (2_000.0, 1e6), (300_000.0, 5e6)])
def test_bound_straight_line_matches_closed_form(L, F):
    """X axis alone: the phase-plane bound agrees with the closed form to 0.1 %."""
    line = nm.make_line([0.0, 0.0], [L, 0.0])
    M = MACHINE.max_drive * MACHINE.Kc[0] * MACHINE.Ke[0]
    expected = line_time(L, F, M, MACHINE.tau[0])
    got = time_optimal_bound(line, MACHINE, F, grid_size=20_000)
    assert got == pytest.approx(expected, rel=1e-3)
    assert got >= expected * (1 - 1e-9)  # the discrete profile is admissible: never faster


def test_bound_pi_and_grid_convergence():
    """Pi at 1 m/s: 0.11528 s at 2000 points, 0.11527 s at 20000 (SPEC: about 0.115 s)."""
    coarse = time_optimal_bound(PI, MACHINE, 1e6, grid_size=2000)
    fine = time_optimal_bound(PI, MACHINE, 1e6, grid_size=20_000)
    assert fine == pytest.approx(0.115, rel=0.01)
    assert abs(coarse - fine) <= 2e-3 * fine


@pytest.mark.parametrize("seed", [2, 5])
def test_bound_resolves_a_near_cusp(seed, monkeypatch):
    """A smooth turn of radius below one pulse inside a knot span (a near-cusp) at 2 m/s:
    at the planner's 4,000 grid points the bound equals the Richardson extrapolation of
    uniform grids without the turn refinement (320,000 and 1,280,000 points; first order
    in the spacing) to 0.1 %; the uniform grid of 4,000 points alone is off by over 20 %
    (these seeds step over the turn or land on it)."""
    from nurbsmotion import planning
    from nurbsmotion.paths.random_paths import random_path
    curve = random_path("near_cusps", [77, seed], n_axes=2)
    feed = 2e6
    refined = time_optimal_bound(curve, MACHINE, feed, grid_size=4000)
    monkeypatch.setattr(planning, "MAX_TURN", math.inf)
    uniform, coarse, fine = (time_optimal_bound(curve, MACHINE, feed, grid_size=g)
                             for g in (4000, 320_000, 1_280_000))
    extrapolated = fine - (coarse - fine) / 3.0
    assert refined == pytest.approx(extrapolated, rel=1e-3)
    assert abs(uniform / extrapolated - 1) > 0.2


def test_bound_orders():
    """The bound grows as the feed or the drive falls; an ideal drive gives L/F."""
    t = [time_optimal_bound(PI, MACHINE, F, grid_size=3000) for F in (2e6, 1e6, 5e5)]
    assert t[0] < t[1] < t[2]
    weak = time_optimal_bound(PI, die_bonder(max_drive=5.0), 1e6, grid_size=3000)
    assert weak > t[1]
    assert time_optimal_bound(PI, die_bonder(max_drive=math.inf), 1e6) == \
        pytest.approx(PI.length / 1e6)


# ------------------------------------------------------------------ the sampled bound
def _end_state_of_unit_drives(Ad, Bd, n):
    """Columns: the state [w, theta] at sample n after a unit drive at sample i alone,
    from rest (simulated with the ZOH matrices)."""
    out = np.zeros((2, n))
    for i in range(n):
        x = Bd.copy()
        for _ in range(i + 1, n):
            x = Ad @ x
        out[:, i] = x
    return out


def _linprog_reach(Ad, Bd, n, slack):
    from scipy.optimize import linprog
    E = _end_state_of_unit_drives(Ad, Bd, n)
    res = linprog(-E[1], A_ub=np.vstack([E[0], -E[0]]), b_ub=[slack, slack],
                  bounds=[(-1, 1)] * n, method="highs")
    assert res.status == 0
    return -res.fun


@pytest.mark.parametrize("tau, Kc, Ke, n, slack", [
    (0.31, 2506.17, 1591.5494, 1, 0.0), (0.31, 2506.17, 1591.5494, 7, 0.0),
    (0.135, 3156.23, 1591.5494, 40, 0.0), (0.02, 100.0, 10.0, 25, 3.0),
    (0.31, 2506.17, 1591.5494, 30, 5.0), (5e-4, 50.0, 2.0, 12, 0.5)])
def test_rest_to_rest_reach_matches_linear_programming(tau, Kc, Ke, n, slack):
    """The weighted-median dual of :func:`planning._rest_to_rest_reach` gives the farthest
    move of the ZOH axis in n samples that scipy's HiGHS finds on the primal LP, built
    from the plant's matrices by simulation (to 1e-9)."""
    from nurbsmotion.planning import _rest_to_rest_reach
    Ad, Bd = zoh_matrices(tau, Kc, Ke, 1e-3)
    got = _rest_to_rest_reach(Ad[0, 0], Bd[0], Ad[1, 0], Bd[1], n, slack)
    assert got == pytest.approx(_linprog_reach(Ad, Bd, n, slack), rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("L", [40.0, 5_000.0, 120_000.0])
def test_sampled_stop_bound_of_a_line(L):
    """One axis, one piece: the least n for which HiGHS finds a drive sequence that ends on the end (window 0) with a motor speed the next drive
    can hold there for a sample (``|w| <= b1*Umax/c``); not below the continuous bound
    without a feed limit less that sample's worth of motion, and within two samples of
    it."""
    from nurbsmotion.planning import sampled_stop_bound
    from scipy.optimize import linprog
    Ts = MACHINE.sample_period
    Ad, Bd = zoh_matrices(MACHINE.tau[0], MACHINE.Kc[0], MACHINE.Ke[0], Ts)
    slack = Bd[1] / Ad[1, 0]
    n = 1
    while True:
        E = _end_state_of_unit_drives(Ad, Bd, n)
        res = linprog(np.zeros(n), A_ub=np.vstack([E[0], -E[0]]), b_ub=[slack, slack],
                      A_eq=E[1:], b_eq=[L / MACHINE.max_drive], bounds=[(-1, 1)] * n,
                      method="highs")
        if res.status == 0:
            break
        n += 1
    line = nm.make_line([0.0, 0.0], [L, 0.0])
    got = sampled_stop_bound(line, MACHINE, settle_window=0.0)
    assert got == pytest.approx(n * Ts)
    M = MACHINE.max_drive * MACHINE.Kc[0] * MACHINE.Ke[0]
    continuous = line_time(L, M * (1 - 1e-9), M, MACHINE.tau[0])
    assert continuous - Ts <= n * Ts <= continuous + 2 * Ts
    # a settle window lets the last piece end a pulse short
    assert sampled_stop_bound(line, MACHINE) <= got


def test_sampled_stop_bound_is_below_every_run():
    """On the Pi: ``planned``'s and ``paper``'s move-and-settle are
    never below the sampled bound, which is itself below the continuous one at 1 m/s
    (whose pieces it rounds up to samples but whose path and feed it ignores); a window
    that is not a finite number >= 0 is refused."""
    from nurbsmotion.metrics import settle_time
    from nurbsmotion.planning import sampled_stop_bound
    curve = to_pulses(PI, MACHINE)
    bound = sampled_stop_bound(curve, MACHINE)
    assert bound < time_optimal_bound(curve, MACHINE, 1e6)
    for method in ("planned", "paper"):
        tr = simulate(make_interpolator(method, curve, MACHINE, 1e6), MACHINE,
                      settle_time=0.05)
        assert settle_time(tr.t, tr.position, curve(1.0)) >= bound
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="settle_window"):
            sampled_stop_bound(curve, MACHINE, settle_window=bad)


def test_sampled_bound_of_an_out_and_back_move_is_the_time_to_turn_and_return():
    """Out along x by L and back to the start (a closed path; it printed 0, issue 37):
    its turn is no sample-instant rest (x reverses, and may within a sample), so the
    bound is the full-drive time out to L less the window, where x turns, plus back to
    within the window of the end, from scipy's root of the closed form
    ``V (t - tau (1 - exp(-t / tau)))``, in whole samples; and no run within the drive
    limit settles sooner."""
    from scipy.optimize import brentq
    from nurbsmotion.planning import rest_corners, sampled_stop_bound
    L, window = 20_000.0, 1.0
    path = nm.make_polyline([[0.0, 0.0], [L, 0.0], [0.0, 0.0]])
    assert path.sharp_corners().size == 1 and rest_corners(path).size == 0
    tau = MACHINE.tau[0]
    V = MACHINE.max_drive * MACHINE.Kc[0] * MACHINE.Ke[0]

    def reach(d):
        return brentq(lambda t: V * (t - tau * (1 - math.exp(-t / tau))) - d, 0.0, 10.0,
                      xtol=1e-15)

    Ts = MACHINE.sample_period
    expected = math.ceil((reach(L - window) + reach(L - 2 * window)) / Ts - 1e-9) * Ts
    bound = sampled_stop_bound(path, MACHINE, settle_window=window)
    assert bound == pytest.approx(expected, abs=1e-12)
    for method in ("planned", "paper"):
        tr = simulate(make_interpolator(method, path, MACHINE, 5e5), MACHINE,
                      settle_time=0.05)
        metrics = tr.metrics()
        if metrics.total_saturated_samples == 0:
            assert metrics.settle_time_s >= bound, method


def test_profile_rests_at_corners_and_ends():
    prof = speed_profile(PI, MACHINE, 1e6, grid_size=3000)
    assert len(prof.pieces) == 3
    for s, u, V in prof.pieces:
        assert V[0] == 0.0 and V[-1] == 0.0
        assert np.all(V <= 1e6 * (1 + 1e-12)) and np.all(np.diff(s) > 0)


# ------------------------------------------------------------------ planned (issue 10)
def _planned(curve, feed, plant=None, **options):
    it = PlannedInterpolator(curve, MACHINE, feed, **options)
    return it, simulate(it, MACHINE, plant=plant, settle_time=0.1)


@functools.lru_cache(maxsize=None)
def _planned_pi(feed):
    return _planned(PI, feed)


def settle_time(trace, window=1.0):
    """First time after which the actual position stays within ``window`` of the end."""
    d = np.max(np.abs(trace.position - trace.curve(1.0)), axis=1)
    out = np.nonzero(d > window)[0]
    assert out.size == 0 or out[-1] < len(d) - 1, "never settles"
    return float(trace.t[out[-1] + 1]) if out.size else 0.0


def end_overshoot(trace):
    t = trace.curve.derivatives(1.0, 1, "left")[1]
    t = t / np.linalg.norm(t)
    return float(max(0.0, np.max((trace.position - trace.curve(1.0)) @ t)))


def _check_run(it, trace):
    """Finite, monotone parameter, every drive within Umax, at rest on the end point."""
    assert np.all(np.isfinite(trace.position_command))
    assert np.all(np.diff(trace.u) >= 0.0)
    assert trace.u[trace.finished_index] == 1.0
    assert np.all(np.abs(trace.drive) <= trace.machine.max_drive * (1 + 1e-12))
    np.testing.assert_allclose(trace.position[-1], it.curve(1.0), atol=1.0)


def test_plan_is_the_model_plants_response_to_its_drive():
    """Independent check: the model's plant (ServoPlant, matrix exponential) driven by the
    plan's drive from rest follows the plan's speed and position; the drive stays within
    Umax, and the plan ends at rest on the end point."""
    plan = plan_motion(PI, MACHINE, 1e6)
    plant = ServoPlant.of_machine(MACHINE, PI(0.0))
    speed, position = plant.response(plan.drive[:-1])
    np.testing.assert_allclose(position, plan.position, atol=1e-6)
    np.testing.assert_allclose(speed, plan.speed, atol=1e-6, rtol=1e-9)
    assert np.max(np.abs(plan.drive)) <= MACHINE.max_drive
    np.testing.assert_allclose(plan.position[-1], PI(1.0), atol=1e-6)
    np.testing.assert_allclose(plan.speed[-1], 0.0, atol=1e-9)
    assert np.max(contour_error(PI, plan.position)) <= 5.0


@pytest.mark.parametrize("seed, feed", [(42, 8.3e4), (141, 9.9e5), (7, 3e6)])
def test_plan_lands_on_the_end_when_the_desired_motion_does(seed, feed):
    """A short, fast move, where the pre-compensation leaves a pulse or two: the plan is
    at rest exactly on the end from the sample the desired motion arrives there, and it
    is still the model plant's response to its drive (ServoPlant) within Umax."""
    from nurbsmotion.paths.random_paths import random_path
    curve = random_path("short_moves", [10, seed], n_axes=2)
    plan = plan_motion(curve, MACHINE, feed)
    arrive = int(np.flatnonzero(np.any(plan.desired != plan.desired[-1], axis=1))[-1]) + 1
    np.testing.assert_array_equal(plan.position[arrive:],
                                  np.broadcast_to(curve(1.0), plan.position[arrive:].shape))
    plant = ServoPlant.of_machine(MACHINE, curve(0.0))
    speed, position = plant.response(plan.drive[:-1])
    np.testing.assert_allclose(position, plan.position, atol=1e-6)
    np.testing.assert_allclose(speed, plan.speed, atol=1e-6, rtol=1e-9)
    assert np.max(np.abs(plan.drive)) <= MACHINE.max_drive


def test_plan_lands_before_the_desired_motion_creeps_in(monkeypatch):
    """The Pi at 0.2 m/s: the desired motion's last samples creep to the end (the
    averaging halves its last braking); the plan lands exactly on the end up to
    INVERSE_REACH + 1 samples sooner, on the path (within a quarter pulse), within Umax,
    and still the model plant's response to its drive (ServoPlant)."""
    from nurbsmotion.interpolators.planned import inverse, landing
    from nurbsmotion.interpolators.planned import plan as mp

    arrivals = []
    land = landing._land_on_end

    def spy(y, *args):
        arrivals.append(landing._arrival(y))
        return land(y, *args)

    monkeypatch.setattr(mp, "_land_on_end", spy)
    plan = plan_motion(PI, MACHINE, 2e5)
    assert arrivals[-1] - inverse.INVERSE_REACH - 1 <= plan.arrival < arrivals[-1]
    np.testing.assert_array_equal(plan.position[plan.arrival:],
                                  np.broadcast_to(PI(1.0), plan.position[plan.arrival:].shape))
    assert np.max(contour_error(PI, plan.position)) <= inverse.PRECOMPENSATION_TOLERANCE
    assert np.max(np.abs(plan.drive)) <= MACHINE.max_drive
    speed, position = ServoPlant.of_machine(MACHINE, PI(0.0)).response(plan.drive[:-1])
    np.testing.assert_allclose(position, plan.position, atol=1e-6)
    np.testing.assert_allclose(speed, plan.speed, atol=1e-6, rtol=1e-9)


def _feed_cases():
    """(name, curve [pulse], feed [pulse/s]): the issue-37 line (10 mm at 10 mm/s, read
    from JSON in mm), the same line faster, the Pi where its feed binds, a free-form
    curve and a short move (step 6) at feeds that bind."""
    from nurbsmotion.paths.random_paths import random_path
    return [("line 10 mm/s", None, 1e4), ("line 30 mm/s", None, 3e4),
            ("pi 0.2 m/s", PI, 2e5),
            ("free form", random_path("free_form", [77, 3], n_axes=2, length=3000.0), 2e4),
            ("short move", random_path("short_moves", [77, 5], n_axes=2), 6e4)]


@pytest.mark.parametrize("case", range(5))
def test_the_tool_keeps_the_feed(case, tmp_path):
    """Issue 37 item 2: the feed is a limit on the tool's motion. Closed loop on the
    nominal plant (which follows the plan), the tool's speed between samples,
    ``|theta[k+1] - theta[k]|/Ts``, stays within the feed plus the sampled system's
    allowance, ``(FEED_SLACK + 2*e)/Ts`` with e the plan's largest distance from its
    desired motion (the desired motion moves at most F*Ts a sample; the landing and a
    short move's nearest path points at most FEED_SLACK more). Before, the landing took
    the line's last 47 pulses in 2 samples: 26 mm/s at 10 mm/s, 0.998 x the bound. On a
    line the speed along the path is x's exactly; no run settles below the bound."""
    from nurbsmotion.interpolators.planned.landing import FEED_SLACK
    from nurbsmotion.paths.files import load_path
    name, curve, feed = _feed_cases()[case]
    if curve is None:
        file = tmp_path / "line.json"
        file.write_text('{"units": "mm", "degree": 1, "knots": [0,0,1,1], '
                        '"control_points": [[0,0],[10,0]]}')
        curve = to_pulses(load_path(file), MACHINE)
    Ts = MACHINE.sample_period
    it = PlannedInterpolator(curve, MACHINE, feed)
    trace = simulate(it, MACHINE, settle_time=0.02)
    _check_run(it, trace)
    plan = plan_motion(curve, MACHINE, feed)   # the interpolator's (it keeps no y)
    np.testing.assert_allclose(trace.position[:len(plan.position)], plan.position, atol=1e-3)
    e = float(np.max(np.linalg.norm(plan.position - plan.desired, axis=1)))
    speed = np.linalg.norm(np.diff(trace.position, axis=0), axis=1) / Ts
    assert np.max(speed) <= feed + (FEED_SLACK + 2 * e) / Ts, (name, np.max(speed) / feed)
    if name.startswith("line"):
        assert e <= 0.25
        assert np.max(np.diff(trace.position[:, 0])) / Ts <= feed * 1.05
    assert settle_time(trace) >= time_optimal_bound(curve, MACHINE, feed) * (1 - 1e-3)


def _continuous_positions(plan, machine, start, per_sample=8):
    """The continuous plant under the plan's held drives (RK45, scipy; SPEC section 3:
    tau*w' = -w + Kc*u, theta' = Ke*w), ``per_sample`` points in every sample interval."""
    from scipy.integrate import solve_ivp
    Ts, n_axes = machine.sample_period, len(start)
    x = np.ravel(np.column_stack([np.zeros(n_axes), start]))
    out = []
    for u in plan.drive[:-1]:
        def rhs(t, x, u=u):
            w = x[0::2]
            return np.ravel(np.column_stack([(-w + machine.Kc * u) / machine.tau,
                                             machine.Ke * w]))
        sol = solve_ivp(rhs, (0.0, Ts), x, t_eval=np.linspace(0.0, Ts, per_sample + 1),
                        rtol=1e-10, atol=1e-9)
        out.append(sol.y[1::2, :-1].T)
        x = sol.y[:, -1]
    return np.vstack(out)


def _without_and_with_step_6(monkeypatch, curve, machine, feed):
    """The plans of ``curve`` without step 6 (steps 1-5 alone) and with it."""
    from nurbsmotion.interpolators.planned import shorten as step6
    with monkeypatch.context() as patch:
        patch.setattr(step6, "_shorten", lambda *args: None)
        before = plan_motion(curve, machine, feed)
    return before, plan_motion(curve, machine, feed)


def _three_axes():
    """The die-bonder with a third axis z, a copy of x."""
    x = MACHINE.axes[0]
    return MACHINE.with_options(axes=MACHINE.axes + (
        Axis("z", x.time_constant, x.electrical_gain, x.mechanical_gain, x.position_gain,
             x.speed_gain),))


@pytest.mark.parametrize("seed, feed, n_axes",
                         [(0, 1e6, 2), (30, 1e6, 2), (50, 2e5, 2), (78, 1e6, 2), (7, 1e6, 3)])
def test_short_move_rests_as_soon_as_the_drive_allows(seed, feed, n_axes, monkeypatch):
    """Random short moves (bound 4-12 ms, mostly near the Nyquist frequency): step 6
    frees the timing along the path and solves the drives at once, so the plan rests on
    the end sooner than steps 1-5 alone, within Umax, still the model plant's response
    to its drive (ServoPlant), and within the path tolerance (or as near the path as the
    plan it replaces) not only at the samples but all along the continuous motion
    (RK45, 8 points a sample; exact distances, metrics.contour_error), its nearest path
    point moving forward no faster than the feed; run on the nominal plant it settles
    when its plan rests and passes the end by under 1 um. With 3 axes the program bounds
    the distance by a polygon around the path, and by a cut where a point is off the
    path between its normals."""
    from nurbsmotion.interpolators.planned import shorten as step6
    from nurbsmotion.metrics import nearest_parameter, settle_time
    from nurbsmotion.paths.random_paths import random_path
    curve = random_path("short_moves", [10, seed], n_axes=n_axes)
    machine = MACHINE if n_axes == 2 else _three_axes()
    before, plan = _without_and_with_step_6(monkeypatch, curve, machine, feed)
    assert plan.arrival < before.arrival
    end = curve(1.0)
    np.testing.assert_array_equal(plan.position[plan.arrival:],
                                  np.broadcast_to(end, plan.position[plan.arrival:].shape))
    assert np.max(np.abs(plan.drive)) <= machine.max_drive
    speed, position = ServoPlant.of_machine(machine, curve(0.0)).response(plan.drive[:-1])
    np.testing.assert_allclose(position, plan.position, atol=1e-6)
    np.testing.assert_allclose(speed, plan.speed, atol=1e-6, rtol=1e-9)
    allowed = max(step6.DEFAULT_PATH_TOLERANCE, float(np.max(contour_error(curve,
                                                                         before.position))))
    assert np.max(contour_error(curve, plan.position)) <= allowed * (1 + 1e-6)
    # between the points it holds (at least every half sample) the motion stays within
    # a tenth of the tolerance of it
    moving = _continuous_positions(plan, machine, curve(0.0))
    assert np.max(contour_error(curve, moving)) <= 1.1 * allowed
    u, _ = nearest_parameter(curve, plan.position)
    assert np.all(np.diff(plan.parameter) >= 0)
    progress = np.diff(curve.arc_length(u))
    assert np.max(progress) <= feed * machine.sample_period + 2 * allowed
    tr = simulate(PlannedInterpolator(curve, machine, feed), machine, settle_time=0.02)
    assert settle_time(tr.t, tr.position, end) <= plan.arrival * machine.sample_period + 1e-12
    assert tr.metrics().end_overshoot <= 1.0


@pytest.mark.parametrize("seed, n_axes, feed", [(240, 3, 109660.3), (229, 2, 2630500.5)])
def test_a_plan_ringing_about_the_end_is_replaced_by_one_at_rest(monkeypatch, seed,
                                                                 n_axes, feed):
    """Short moves whose landing (step 5) fails: the plan of steps 1-5 rings about the end
    after its arrival by more than the path tolerance (0.6 mm at 0.11 m/s on 3 axes: 2.6
    pulses at the Nyquist frequency, within a pulse 4 samples after it; 2.6 m/s on 2
    axes: 5.3 pulses, within a pulse 6 samples after). Step 6 finds no earlier arrival,
    so it plans one at rest exactly on the end at the first sample from the arrival on
    that has one (the arrival itself; a sample later), before the ringing has died down:
    within Umax, the model plant's response to its drive, and a run on the nominal
    plant settles when the plan rests, sooner than the ringing plan's."""
    from nurbsmotion.interpolators.planned import shorten as step6
    from nurbsmotion.metrics import settle_time
    from nurbsmotion.paths.random_paths import random_path
    curve = random_path("short_moves", [10, seed], n_axes=n_axes)
    machine, end = (_three_axes() if n_axes == 3 else MACHINE), curve(1.0)
    ringing, plan = _without_and_with_step_6(monkeypatch, curve, machine, feed)
    after = np.linalg.norm(ringing.position[ringing.arrival:] - end, axis=1)
    assert np.max(after) > step6.DEFAULT_PATH_TOLERANCE
    settled = ringing.arrival + np.flatnonzero(after > step6.DEFAULT_PATH_TOLERANCE)[-1] + 1
    assert plan.arrival < settled
    np.testing.assert_array_equal(plan.position[plan.arrival:],
                                  np.broadcast_to(end, plan.position[plan.arrival:].shape))
    assert np.max(np.abs(plan.drive)) <= machine.max_drive
    speed, position = ServoPlant.of_machine(machine, curve(0.0)).response(plan.drive[:-1])
    np.testing.assert_allclose(position, plan.position, atol=1e-6)
    settled = []
    for shorten in (lambda *args: None, step6._shorten):
        with monkeypatch.context() as patch:
            patch.setattr(step6, "_shorten", shorten)
            tr = simulate(PlannedInterpolator(curve, machine, feed), machine,
                          settle_time=0.02)
        settled.append(settle_time(tr.t, tr.position, end))
    assert settled[1] <= plan.arrival * machine.sample_period + 1e-12
    assert settled[1] < settled[0]


def test_a_short_move_with_stops_is_planned_from_stop_to_stop(monkeypatch):
    """A zigzag whose both axes move from the start (2 stop corners, 1 m/s, bound about
    30 ms): step 6 plans it piece by piece, so it arrives sooner than steps 1-5 alone
    (whose averaging costs a sample at every stop) and rests exactly on every corner at
    a sample instant; within Umax, the model plant's response to its drive, within the
    path tolerance all along the continuous motion (RK45), never past a corner along
    the path's tangent into it; run on the nominal plant it settles when its plan rests
    and passes no stop by 1 um."""
    from nurbsmotion.interpolators.planned import shorten as step6
    from nurbsmotion.metrics import settle_time
    corners = np.array([[0.0, 0.0], [6000.0, 4000.0], [12000.0, 0.0], [18000.0, 4000.0]])
    curve = nm.make_polyline(corners)
    feed = 1e6
    before, plan = _without_and_with_step_6(monkeypatch, curve, MACHINE, feed)
    assert plan.arrival < before.arrival
    np.testing.assert_array_equal(plan.corner_times, np.round(plan.corner_times))
    at = plan.corner_times.astype(int)
    np.testing.assert_allclose(plan.position[at], corners[1:3], atol=1e-6)
    np.testing.assert_allclose(plan.speed[at], 0.0, atol=1e-6)
    assert np.max(np.abs(plan.drive)) <= MACHINE.max_drive
    speed, position = ServoPlant.of_machine(MACHINE, curve(0.0)).response(plan.drive[:-1])
    np.testing.assert_allclose(position, plan.position, atol=1e-6)
    moving = _continuous_positions(plan, MACHINE, curve(0.0))
    assert np.max(contour_error(curve, moving)) <= 1.1 * step6.DEFAULT_PATH_TOLERANCE
    # each piece's motion, up to its stop (a corner, the end), does not pass it
    bounds = [0, *at, len(plan.position) - 1]
    for j in range(len(corners) - 1):
        into = (corners[j + 1] - corners[j]) / np.linalg.norm(corners[j + 1] - corners[j])
        piece = moving[8 * bounds[j]:8 * bounds[j + 1]]
        assert np.max((piece - corners[j + 1]) @ into) <= step6.PRECOMPENSATION_TOLERANCE
    tr = simulate(PlannedInterpolator(curve, MACHINE, feed), MACHINE, settle_time=0.02)
    assert settle_time(tr.t, tr.position, curve(1.0)) <= (
        plan.arrival * MACHINE.sample_period + 1e-12)
    met = tr.metrics()
    assert met.corner_overshoot <= 1.0 and met.end_overshoot <= 1.0


def test_a_path_whose_axis_first_moves_after_a_stop_keeps_its_averaged_plan():
    """The Pi's x first moves at its first corner: planned from stop to stop, its first
    drive would be at the limit before the online step has seen x move (plants tau x0.8,
    Kc x1.2 went 71 um off the arch), so the plan keeps steps 1-5's timing there (its
    corners between samples, x's drive starting while y still brakes)."""
    plan = plan_motion(PI, MACHINE, 1e6)
    assert np.all(plan.corner_times != np.round(plan.corner_times))
    k = int(plan.corner_times[0])
    assert abs(plan.drive[k, 0]) < 0.5 * MACHINE.max_drive  # x starts gently


def test_a_short_closed_move_goes_all_the_way_round(monkeypatch):
    """A short full circle (start = end, 2 mm across, 0.5 m/s): step 6 may not skip the
    path because its end point is its start. The plan's path points (its parameters)
    run from the start round to the end, no farther apart than the feed allows in a
    sample, and every sample is as near its point as the tolerance (or the plan of
    steps 1-5) is."""
    from nurbsmotion.interpolators.planned import shorten as step6
    circle = nm.make_arc(np.zeros(2), 1000.0, 0.0, 2 * math.pi)
    feed = 5e5
    before, plan = _without_and_with_step_6(monkeypatch, circle, MACHINE, feed)
    assert plan.arrival < before.arrival
    s = circle.arc_length(plan.parameter)
    assert s[0] == 0.0 and s[-1] == pytest.approx(circle.length)
    assert np.all(np.diff(s) >= 0)
    assert np.max(np.diff(s)) <= feed * MACHINE.sample_period * (1 + 1e-6)
    off = np.linalg.norm(plan.position - circle(plan.parameter), axis=1)
    allowed = max(step6.DEFAULT_PATH_TOLERANCE,
                  float(np.max(contour_error(circle, before.position))))
    assert np.max(off) <= allowed * (1 + 1e-6)


def test_path_tolerance_trades_accuracy_for_time():
    """A wider path tolerance lets a short move arrive no later, a zero one keeps it as
    near the path as the plan of steps 1-5; each stays within its tolerance."""
    from nurbsmotion.paths.random_paths import random_path
    curve = random_path("short_moves", [10, 78], n_axes=2)
    arrivals, contours = [], []
    for tolerance in (0.0, 1.0, 5.0):
        plan = plan_motion(curve, MACHINE, 1e6, path_tolerance=tolerance)
        arrivals.append(plan.arrival)
        contours.append(float(np.max(contour_error(curve, plan.position))))
    assert arrivals[0] >= arrivals[1] >= arrivals[2]
    assert contours[1] <= 1.0 * (1 + 1e-6) and contours[2] <= 5.0 * (1 + 1e-6)


@pytest.mark.parametrize("feed, settle_ratio", [(2e5, 1.03), (1e6, 1.10)])
def test_planned_pi_nominal(feed, settle_ratio):
    """Pi, nominal plant: no saturated sample, contour error <= 5 um, end overshoot
    <= 1 um (issue 10 item 2); move-and-settle within 3 % of the bound at 0.2 m/s and
    (issue target 5 %, measured 7.6 %) 10 % at 1 m/s."""
    it, trace = _planned_pi(feed)
    _check_run(it, trace)
    assert np.max(contour_error(PI, trace.position)) <= 5.0
    assert end_overshoot(trace) <= 1.0
    # the run finishes when the plan rests on the end, where the plant settles (not
    # after the pre-compensation's samples at rest that follow)
    assert abs(trace.cycle_time - settle_time(trace)) <= MACHINE.sample_period * (1 + 1e-9)
    assert settle_time(trace) <= settle_ratio * time_optimal_bound(PI, MACHINE, feed)


def test_planned_follows_its_plan_on_the_nominal_plant():
    """On the model's own plant the online identification stays on the model (it regresses
    measured positions, no differenced speed), so the actual position is the plan's."""
    it, trace = _planned_pi(2e5)
    n = len(it.plan.position)
    np.testing.assert_allclose(trace.position[:n], it.plan.position, atol=1e-3)


def _scipy_zoh(j, tau_scale, kc_scale):
    """Axis j of the die-bonder with tau and Kc scaled: its ZOH coefficients
    ``(a, b0, c, b1)`` from scipy's matrix exponential of
    ``[w, theta, u]' = [[-1/tau, 0, kc/tau], [ke, 0, 0], [0, 0, 0]] [w, theta, u]``."""
    from scipy.linalg import expm

    tau, kc, ke = (MACHINE.tau[j] * tau_scale, MACHINE.Kc[j] * kc_scale, MACHINE.Ke[j])
    E = expm(np.array([[-1 / tau, 0, kc / tau], [ke, 0, 0], [0, 0, 0]])
             * MACHINE.sample_period)
    return E[0, 0], E[0, 2], E[1, 0], E[1, 2]


@pytest.mark.parametrize("tau_scale, kc_scale, w0", [(1.0, 1.0, 600.0), (1.2, 0.8, -400.0),
                                                    (0.5, 2.0, 1200.0)])
def test_stopping_travel_and_the_drive_that_stops_on_the_end(tau_scale, kc_scale, w0):
    """The travel of a plant braking at Umax from speed w0 [rad/s] until it stops equals
    RK45's on the continuous plant (tau*w' = -w + Kc*u, theta' = Ke*w, stopped by an
    event at w = 0). Of the drives for the next sample, the online step keeps the one
    after which braking at Umax stops exactly on an end that coasting through the sample
    would pass (60 % of the way from braking at once to coasting), the full brake for an
    end nothing stops before, and any drive that already stops short of it."""
    from scipy.integrate import solve_ivp

    from nurbsmotion.interpolators.planned.guards import _short_of_stop, _stopping_travel

    j, umax = 1, MACHINE.max_drive
    a, b0, c, b1 = _scipy_zoh(j, tau_scale, kc_scale)
    tau, kc, ke = MACHINE.tau[j] * tau_scale, MACHINE.Kc[j] * kc_scale, MACHINE.Ke[j]
    s = math.copysign(1.0, w0)
    brake = -s * umax

    def travel(w):
        stop = lambda t, y: y[0]  # noqa: E731
        stop.terminal = True
        sol = solve_ivp(lambda t, y: [(-y[0] + kc * brake) / tau, ke * y[0]], (0.0, 10.0),
                        [w, 0.0], events=stop, rtol=1e-11, atol=1e-12)
        return sol.y_events[0][0][1]

    assert _stopping_travel(w0, a, b0, c, b1, brake) == pytest.approx(travel(w0), rel=1e-7)
    assert _stopping_travel(w0, a, b0, c, b1, -brake) == 0.0

    def after(u):  # one sample of drive u, then the brake
        return c * w0 + b1 * u + travel(a * w0 + b0 * u)

    end = after(brake) + 0.6 * (after(0.0) - after(brake))
    u = _short_of_stop(0.0, 0.0, w0, end, s, a, b0, c, b1, umax)
    assert s * brake < s * u < 0.0
    assert after(u) == pytest.approx(end, rel=1e-6)
    assert _short_of_stop(0.0, 0.0, w0, 0.5 * after(brake), s, a, b0, c, b1, umax) == brake
    assert _short_of_stop(0.0, 0.0, w0, 2.0 * after(0.0), s, a, b0, c, b1, umax) == 0.0


def _identified(it, position, drive, *options):
    """The online identification's estimate after feeding it ``position`` (n, 2) [pulse]
    read under ``drive`` (n, 2) [V] sample by sample, as the loop does."""
    from nurbsmotion.interpolators.planned.identify import _identify
    from nurbsmotion.interpolators.planned.interpolator import _prior_estimate

    est = _prior_estimate(it.plan, MACHINE.max_drive)
    hist = np.zeros((HIST_ROWS, 2))
    for k in range(1, len(drive)):
        for j in range(2):
            _identify(est, hist, j, position[k, j], it.plan.a[j], it.plan.b0[j],
                      it.plan.c[j], it.plan.b1[j], *options)
            hist[1, j], hist[0, j] = hist[0, j], drive[k, j]
    return est


@pytest.mark.parametrize("tau_scale, kc_scale", [(0.6, 1.7), (1.9, 0.55)])
def test_identification_finds_the_true_sampled_plant(tau_scale, kc_scale):
    """The recursive least squares of the online step, fed the positions of a plant
    whose tau and Kc differ from the model (ServoPlant, matrix exponential) under a
    random drive, converges to that plant's ZOH coefficients (scipy's expm)."""

    it = PlannedInterpolator(PI, MACHINE, 1e6)
    plant = ServoPlant.of_machine(MACHINE, PI(0.0), time_constant_scale=tau_scale,
                                  electrical_gain_scale=kc_scale)
    drive = np.random.default_rng(3).uniform(-10, 10, (600, 2))
    drive[0] = 0.0  # as in the loop: u[0] = 0, the plant still at rest at sample 1
    _, position = plant.response(drive)
    est = _identified(it, position, drive)
    for j in range(2):
        a, b0, c, b1 = _scipy_zoh(j, tau_scale, kc_scale)
        # 1 - a sets the speed part of the drive: within 2 % of it
        assert abs(est[0, j] - a) <= 0.02 * (1 - a)
        np.testing.assert_allclose(est[1:3, j], [b1, c * b0 - a * b1], rtol=1e-3)


@pytest.mark.parametrize("load", [0.5, -2.0])
def test_identification_is_not_thrown_by_an_unknown_constant_drive(load):
    """A constant drive the model does not know (a load of ``load`` V on every axis from
    sample 60 on) under the same random drive: the regression in increments still
    converges to the true plant's ZOH coefficients (scipy's expm) and its unknown drive
    delta = (b1 + beta)*load; without delta the regression read such a load as a plant
    of another gain."""
    from nurbsmotion.interpolators.planned import DEFAULT_TRACKING_POLE, GAIN_RANGE

    it = PlannedInterpolator(PI, MACHINE, 1e6)
    plant = ServoPlant.of_machine(MACHINE, PI(0.0), time_constant_scale=0.7,
                                  electrical_gain_scale=1.4)
    drive = np.random.default_rng(4).uniform(-8, 8, (600, 2))
    drive[0] = 0.0
    applied = drive.copy()
    applied[60:] += load
    _, position = plant.response(applied)
    est = _identified(it, position, drive, 0.0, GAIN_RANGE, 1.0 - DEFAULT_TRACKING_POLE)
    for j in range(2):
        a, b0, c, b1 = _scipy_zoh(j, 0.7, 1.4)
        # delta follows a random walk (the filter keeps adapting to it): the plant within
        # 15 % of 1 - a (the speed part of the drive) and 1 % of b1, beta, the load's
        # delta within 10 %
        assert abs(est[0, j] - a) <= 0.15 * (1 - a)
        np.testing.assert_allclose(est[1:3, j], [b1, c * b0 - a * b1], rtol=1e-2)
        np.testing.assert_allclose(est[4, j], (b1 + c * b0 - a * b1) * load, rtol=0.1)


@pytest.mark.parametrize("tau_scale, kc_scale, delay", [(1.0, 1.0, 0.5), (0.7, 1.4, 0.3)])
def test_identification_with_a_known_delay_finds_the_delayed_plant(tau_scale, kc_scale,
                                                                   delay):
    """A plant whose drive arrives ``delay`` samples late (RK45 on the continuous plant,
    the drive held over each sample and shifted by the delay) under a random drive: its
    position increments are exactly linear in dth[k-1], u[k-1], u[k-2], u[k-3] (numpy's
    least squares on them leaves a residual of the integration's error only), with the
    weights :func:`_drive_weights` gives on scipy's ZOH of the plant; and the online
    step's filter, told the delay, converges to those weights (a, then p1, p2, p3)."""
    from scipy.integrate import solve_ivp

    from nurbsmotion.interpolators.planned.identify import _drive_weights, _identify
    from nurbsmotion.interpolators.planned.interpolator import _prior_estimate

    j, n = 1, 400
    ts = MACHINE.sample_period
    tau, kc, ke = MACHINE.tau[j] * tau_scale, MACHINE.Kc[j] * kc_scale, MACHINE.Ke[j]
    drive = np.random.default_rng(5).uniform(-8, 8, n)
    drive[0] = 0.0
    y = np.zeros(2)                       # (w [rad/s], theta [pulse]), at rest
    position = np.zeros(n + 1)
    for k in range(n):
        for t0, t1, u in ((0.0, delay, drive[k - 1] if k else 0.0), (delay, 1.0, drive[k])):
            y = solve_ivp(lambda t, x: [(-x[0] + kc * u) / tau, ke * x[0]],
                          (t0 * ts, t1 * ts), y, rtol=1e-12, atol=1e-12,
                          method="RK45").y[:, -1]
        position[k + 1] = y[1]
    a, b0, c, b1 = _scipy_zoh(j, tau_scale, kc_scale)
    weights = _drive_weights(a, b0, c, b1, delay)
    dth = np.diff(position)   # dth[k] = th[k + 1] - th[k], over sample k: u[k], u[k-1]...
    k = np.arange(3, n)
    X = np.column_stack([dth[k - 1], drive[k], drive[k - 1], drive[k - 2]])
    fit, *_ = np.linalg.lstsq(X, dth[k], rcond=None)
    np.testing.assert_allclose(fit, [a, *weights], rtol=1e-6)
    assert abs(sum(weights) - (c * b0 + (1 - a) * b1)) <= 1e-12 * abs(c * b0 + (1 - a) * b1)

    it = PlannedInterpolator(PI, MACHINE, 1e6)
    plan = it.plan._replace(delay=delay)
    est = _prior_estimate(plan, MACHINE.max_drive)
    hist = np.zeros((HIST_ROWS, 2))
    for k in range(1, n + 1):
        _identify(est, hist, j, position[k], plan.a[j], plan.b0[j], plan.c[j], plan.b1[j])
        hist[5, j], hist[1, j], hist[0, j] = hist[1, j], hist[0, j], drive[k] if k < n else 0.0
    assert abs(est[0, j] - a) <= 0.02 * (1 - a)
    np.testing.assert_allclose(est[1:4, j], weights, rtol=0,
                               atol=1e-3 * np.max(np.abs(weights)))


@pytest.mark.parametrize("tau_scale, kc_scale", [(0.5, 2.0), (2.0, 0.5), (1.2, 0.8)])
def test_planned_never_saturates_a_mismatched_plant(tau_scale, kc_scale):
    """The true plant's tau and Kc off by up to x2 either way (the planner sees the
    model): every drive within Umax, and the plant still comes to rest on the end point."""
    it, _ = _planned_pi(1e6)
    plant = ServoPlant.of_machine(MACHINE, PI(0.0), time_constant_scale=tau_scale,
                                  electrical_gain_scale=kc_scale)
    trace = simulate(it, MACHINE, plant=plant, settle_time=0.2)
    _check_run(it, trace)


@pytest.mark.parametrize("tau_scale, kc_scale", [(1.0, 0.8), (1.2, 0.8), (1.2, 1.0)])
def test_a_weaker_plant_is_slowed_only_where_it_must_be(butterfly, tau_scale, kc_scale):
    """Issue 10 item 4 on the butterfly at 0.1 m/s (the planner sees the model; the plant
    needs up to 1.5x its drive): the governor slows the clock only around the samples the
    weaker plant cannot follow at full rate, so the move settles within 2 % of the
    nominal bound (a uniform slow-down up to the end took 7-17 % longer), within 25 um
    of the path and never beyond Umax."""
    it = PlannedInterpolator(butterfly, MACHINE, 1e5)
    plant = ServoPlant.of_machine(MACHINE, butterfly(0.0), time_constant_scale=tau_scale,
                                  electrical_gain_scale=kc_scale)
    trace = simulate(it, MACHINE, plant=plant, settle_time=0.1)
    assert trace.metrics().total_saturated_samples == 0
    assert settle_time(trace) <= 1.02 * time_optimal_bound(butterfly, MACHINE, 1e5)
    assert np.max(contour_error(butterfly, trace.position)) <= 25.0


@pytest.mark.parametrize("tau_scale, kc_scale", [(1.0, 0.8), (1.2, 0.8), (1.2, 1.0)])
def test_a_weaker_plant_lands_on_the_pi_within_its_margin(tau_scale, kc_scale):
    """Issue 10 item 4 on the Pi at 1 m/s, the plants that cannot follow the plan at full
    rate (they arrived 5-16 um short or long and crept in at the tracking pole, 1.11-1.17x
    the bound): the landing on the plant identified during the move lands them within
    1.25x the nominal bound (1.17-1.22x; within 1.15x with deadbeat poles, which
    limit-cycled or never settled with an unknown load, friction or mode:
    benchmarks/real_planned_item1.md), within 25 um of the path and never beyond Umax."""
    it, _ = _planned_pi(1e6)
    plant = ServoPlant.of_machine(MACHINE, PI(0.0), time_constant_scale=tau_scale,
                                  electrical_gain_scale=kc_scale)
    trace = simulate(it, MACHINE, plant=plant, settle_time=0.1)
    _check_run(it, trace)
    assert settle_time(trace) <= 1.25 * time_optimal_bound(PI, MACHINE, 1e6)
    assert np.max(contour_error(PI, trace.position)) <= 25.0


@pytest.mark.parametrize("tau_scale, kc_scale", [(1.0, 0.8), (1.2, 1.2), (2.0, 2.0)])
def test_a_plant_unlike_the_model_stops_short_of_the_place_position(tau_scale, kc_scale):
    """On the Pi at 1 m/s, plants that passed the place position (downwards, -y) by 4.6,
    0.3 and 1.0 um before the plan's clock got there: the drive keeps each able to stop
    before the end, so none passes it (computed here from the positions of the place
    move; the run's end_overshoot says the same), within 1.15x the bound."""
    it = _planned_pi(1e6)[0]
    plant = ServoPlant.of_machine(MACHINE, PI(0.0), time_constant_scale=tau_scale,
                                  electrical_gain_scale=kc_scale)
    trace = simulate(it, MACHINE, plant=plant, settle_time=0.1)
    _check_run(it, trace)
    place = trace.position[:, 0] > PI(1.0)[0] - 1.0   # on the place line, x = 60000
    passed = max(0.0, -float(np.min(trace.position[place, 1] - PI(1.0)[1])))
    # the guard brakes the plant it has identified, not the true one: 2x2 passes by
    # 1.4e-3 pulse (a thousandth of the encoder's resolution)
    assert passed <= 1e-2
    assert trace.metrics().end_overshoot <= 1e-2
    assert settle_time(trace) <= 1.15 * time_optimal_bound(PI, MACHINE, 1e6)


@pytest.mark.parametrize("feed", [5e5, 2e6])
@pytest.mark.parametrize("tau_scale, kc_scale", [(1.0, 0.8), (1.2, 0.8)])
def test_a_plant_unlike_the_model_stops_short_of_a_stop_corner(feed, tau_scale, kc_scale):
    """A move out along x to a stop corner, down y to a second one, and back along x:
    weaker plants ran 3.5-5.7 pulses down through the second corner (only the end was
    guarded). Each axis that the plan holds or turns at a stop is kept able to stop
    before it until the plan moves it on: x never passes 20000 pulses, nor y 0, by more
    than the plan itself (its turning points between samples, RK45) and the identified
    plant's error: on the averaged plans of steps 1-5 a hundredth of a pulse; planned
    from stop to stop (step 6), the plan brakes at the limit into each corner, and at
    2 m/s the plant whose tau is 20 % longer, identified from a few samples, stops 1.3
    pulses late: at most 1.5 pulses, here and in the run's corner_overshoot."""
    from nurbsmotion.nurbs import make_polyline
    curve = make_polyline([[0.0, 0.0], [20000.0, 5000.0], [20000.0, 0.0], [0.0, 0.0]])
    it = PlannedInterpolator(curve, MACHINE, feed)
    plant = ServoPlant.of_machine(MACHINE, curve(0.0), time_constant_scale=tau_scale,
                                  electrical_gain_scale=kc_scale)
    trace = simulate(it, MACHINE, plant=plant, settle_time=0.05)
    _check_run(it, trace)
    # the plan's own extremes, between the samples as well (RK45 on its drives)
    plan = _continuous_positions(plan_motion(curve, MACHINE, feed), MACHINE, curve(0.0))
    assert np.max(trace.position[:, 0]) <= max(20000.0, plan[:, 0].max()) + 1.5
    assert np.min(trace.position[:, 1]) >= min(0.0, plan[:, 1].min()) - 1.5
    assert trace.metrics().corner_overshoot <= 1.5


def test_a_blended_run_on_the_model_plant_follows_its_plan():
    """A serpentine (300-pulse legs) at 2 m/s with a 0.5 mm corner tolerance: its plan
    rounds every corner, and on the model's plant the run is the plan to a thousandth of
    a pulse. The middles of blends are not stops: guarded like stop corners, they kept
    the plant 2.15 pulses off its plan here (and a spiral 46 pulses beyond eps)."""
    from nurbsmotion.nurbs import make_polyline
    curve = make_polyline([[0.0, 0.0], [20000.0, 0.0], [20000.0, 300.0], [0.0, 300.0],
                           [0.0, 600.0], [20000.0, 600.0]])
    it = PlannedInterpolator(curve, MACHINE, 2e6, corner_tolerance=500.0)
    assert it.plan.bounds.size == 1          # no stop corners: blended
    trace = simulate(it, MACHINE, settle_time=0.01)
    n = min(len(trace.position), len(it.plan.position))
    np.testing.assert_allclose(trace.position[:n], it.plan.position[:n], rtol=0, atol=1e-3)
    assert trace.metrics().max_contour_error <= 500.0 + 5.0


def test_the_guard_lookup_finds_every_guard_that_holds_a_sample():
    """The online step looks a sample's guards up by bisection among the last two that
    start by it (:func:`_guarded`); on a zigzag of 12 stop corners (every axis turned at
    every other stop, guards overlapping) it finds, at every plan sample and on both
    sides, the nearest position of all the guards that hold that sample, counted one by
    one."""
    from nurbsmotion.interpolators.planned.guards import _guarded
    from nurbsmotion.nurbs import make_polyline
    zigzag = [[4000.0 * (k % 2) + 100.0 * k, 3000.0 * ((k // 2) % 2)] for k in range(13)]
    it = PlannedInterpolator(make_polyline(zigzag), MACHINE, 1e6)
    guards, offsets = it.plan.guards, it.plan.guard_offsets
    assert len(guards) >= 12
    for j in range(2):
        rows = guards[offsets[j]:offsets[j + 1]]
        for i in range(len(it.plan.position)):
            for side in (1.0, -1.0):
                held = [g[2] for g in rows if g[0] <= i < g[1] and g[3] == side]
                want = (min(held) if side > 0 else max(held)) if held else side * math.inf
                assert _guarded(guards, offsets[j], offsets[j + 1], i, side) == want


@pytest.mark.parametrize("tau_scale, kc_scale", [(0.5, 1.0), (1.2, 0.8), (2.0, 0.5)])
@pytest.mark.parametrize("pole", [0.7, 0.0])
def test_feedback_gains_place_the_identified_plants_poles(tau_scale, kc_scale, pole):
    """The online feedback's gains for a plant's ZOH coefficients (scipy's expm of the
    continuous plant) put both eigenvalues of A - B K (numpy) at the tracking pole, and
    at 0 once the plan rests on the end (deadbeat: (A - B K)^2 = 0)."""
    from nurbsmotion.interpolators.planned.identify import _pole_gains

    for j in range(2):
        a, b0, c, b1 = _scipy_zoh(j, tau_scale, kc_scale)
        k_theta, k_w = _pole_gains(a, b0, c, b1, pole)
        closed = np.array([[a, 0.0], [c, 1.0]]) - np.outer([b0, b1], [k_w, k_theta])
        np.testing.assert_allclose(np.linalg.eigvals(closed), [pole, pole], atol=1e-6)
        if pole == 0.0:
            np.testing.assert_allclose(closed @ closed, 0.0, atol=1e-9)


def test_corner_tolerance_rounds_within_eps_and_is_faster():
    """eps = 0.5 mm at 1 m/s: contour error to the sharp path <= eps + 5 um, sooner at
    rest on the end than the exact stop."""
    eps = 500.0
    it, trace = _planned(PI, 1e6, corner_tolerance=eps)
    _check_run(it, trace)
    assert np.max(contour_error(PI, trace.position)) <= eps + 5.0
    assert settle_time(trace) < settle_time(_planned_pi(1e6)[1])


@pytest.mark.parametrize("eps", [300.0, 1000.0])
def test_a_blend_whose_drives_add_is_eased_on_both_pieces(eps):
    """A V whose legs run mostly along y: at the corner the first leg brakes y at its
    drive limit while the second accelerates y the same way, so the blend's y drive is
    the sum of two drives at the limit. Easing only the later piece (the sample's
    parameter) could not bring the sum down, and ran away: 1.93 x the stop-at-corner
    bound at eps = 1 mm (now 0.875 x), and on a 0.2 m DXF polyline at Ts = 0.1 ms a
    profile of 2,287 s after 10 minutes of planning, refused as "the feed is too low".
    Both pieces are now eased over the whole blend: within eps + 5 um of the sharp path,
    never slower than stopping at the corner, no drive beyond Umax."""
    V = nm.make_polyline([[0.0, 0.0], [1000.0, 3000.0], [2000.0, 0.0]])
    it, trace = _planned(V, 1e6, corner_tolerance=eps)
    _check_run(it, trace)
    assert np.max(contour_error(V, trace.position)) <= eps + 5.0
    assert settle_time(trace) <= settle_time(_planned(V, 1e6)[1])


def test_a_piece_shorter_than_its_two_blends_stays_within_eps():
    """A polyline whose first piece (0.53 mm) is shorter than the blends at both its ends
    (eps = 0.5 mm): the third piece used to start before the first had stopped, three
    motions superposed while each blend was checked against its own two pieces only (714
    um from the sharp path, and 13 s of drive easing, one piece of three unseen). Each
    blend now measures the superposition of every piece that moves: within eps + 5 um,
    never slower than stopping at the corners, no drive beyond Umax (found by a random
    polyline sweep: 1 of 150 beyond eps before, 0 of 560 after)."""
    P = nm.make_polyline([[0, 0], [-270, -459], [1760, -2528], [715, -3240], [-241, -3237],
                          [-410, -686]])
    eps = 500.0
    it, trace = _planned(P, 1e6, corner_tolerance=eps)
    _check_run(it, trace)
    assert np.max(contour_error(P, trace.position)) <= eps + 5.0
    assert settle_time(trace) <= settle_time(_planned(P, 1e6)[1])


def test_segments_far_shorter_than_eps_blend_like_the_arc_they_draw():
    """A quarter circle of radius 20 mm drawn as 100 chords of 0.31 mm (as CAM writes
    it), eps = 50 um: blends of two segments at a time cannot go faster than a fraction
    of the feed (0.227 s, 6 x the arc's 0.038 s, and 12 s of planning), and the tree
    before that refused the move after its drive easing ran away. Segments now start
    while earlier ones still move, as long as the measured deviation allows: within eps
    + 5 um of the chords, under twice the exact arc's time (0.057 s), and far sooner
    than stopping at every corner (0.354 s)."""
    R, eps = 20000.0, 50.0
    angle = np.linspace(0.0, 0.5 * np.pi, 101)
    chords = nm.make_polyline(np.column_stack([R * np.cos(angle), R * np.sin(angle)]))
    it, trace = _planned(chords, 1e6, corner_tolerance=eps)
    _check_run(it, trace)
    assert np.max(contour_error(chords, trace.position)) <= eps + 5.0
    arc = nm.make_arc([0.0, 0.0], R, 0.0, 0.5 * np.pi)
    assert settle_time(trace) <= 2.0 * settle_time(_planned(arc, 1e6)[1])


def _corpus_case(name: str, axes: str, seed: list):
    """The first contour of a corpus file [pulse] and the file sweep's random machine of
    that ``seed`` with 0.1 um pulses (``benchmarks/file_sweep.py``)."""
    from pathlib import Path

    from nurbsmotion.paths.files import load_contours
    from nurbsmotion.random_machines import random_machine

    corpus = Path(__file__).resolve().parent / "data" / "corpus"
    contour = load_contours(corpus / name, axes=axes)[0]
    machine = random_machine(seed, len(axes)).with_options(pulse_length_um=0.1)
    return contour, to_pulses(contour.curve, machine), machine


def test_a_profile_at_the_drive_limit_over_a_long_stretch_is_not_refused():
    """A 0.31 m DXF spline (ezdxf's corpus) on a random 3-axis pid machine (0.1 um
    pulses, Ts = 0.1 ms, 110 mm/s; found by the file sweep): the speed profile runs at
    the drive limit for most of its 224,000 samples, and the sampled drive exceeded it
    by 1e-7 to 1e-9 here and there; each round eased a window and the excess turned up in
    another, so after 12 rounds the move was refused ("needs 1 x Umax"). Where local
    easing stalls on the finest grid, the whole path is eased by the excess as well: the
    plan is found, no drive beyond Umax in the run (4 of 440 file-sweep runs were refused
    so)."""
    from nurbsmotion.loop import run

    _, path, machine = _corpus_case("bjnortier_splineA.dxf", "xyz", [14, 0, 3, 3])
    trace = run(path, machine, 1097860.0, "planned",
                interpolator_options={"corner_tolerance": 5000.0})
    assert trace.success, trace.message
    assert trace.metrics().total_saturated_samples == 0


@pytest.mark.filterwarnings("ignore::nurbsmotion.paths.gcode.GcodeWarning")
def test_corners_are_rounded_only_where_that_arrives_sooner():
    """LinuxCNC's tp_arc-with-spiral.ngc (its own F words) on a random 3-axis pid machine
    (0.1 um pulses, Ts = 0.1 ms; found by the file sweep) at eps = 0.5 mm: the blends
    superpose up to five pieces, whose drives add to 3 x Umax, and easing that sum
    slowed the move to 1.45 x the stop-at-corner bound. The plan now stops at the
    corners where that arrives no later, and says so (its corner_tolerance is 0)."""
    from nurbsmotion import units

    contour, path, machine = _corpus_case("tp_arc-with-spiral.ngc", "xyz", [39, 0, 3, 5])
    feed = units.feed_in_pulses(contour.feed, contour.curve, machine)
    stopping = plan_motion(path, machine, feed)
    plan = plan_motion(path, machine, feed, corner_tolerance=5000.0)
    assert plan.arrival <= stopping.arrival
    assert plan.corner_tolerance == 0.0 and plan.stop_indices.size == 4


def test_easing_the_whole_path_costs_no_more_than_the_excess():
    """The same spline on another random machine (Ts = 0.25 ms, 280 mm/s): on the
    finest grid a curvature peak needed 1.06 x Umax, and easing the whole path by the
    excess to the power of the round (as local windows are) made the move 1.47 x the
    time-optimal bound. The whole path is eased by the excess itself, only where local
    easing stalls on the finest grid: within 1 % of the bound."""
    _, path, machine = _corpus_case("bjnortier_splineA.dxf", "xyz", [14, 0, 3, 1])
    feed = 2798914.0
    plan = plan_motion(path, machine, feed)
    assert plan.arrival * machine.sample_period <= 1.01 * time_optimal_bound(path, machine,
                                                                             feed)


@pytest.mark.filterwarnings("ignore::nurbsmotion.paths.gcode.GcodeWarning")
def test_a_stalled_excess_on_the_finest_grid_is_not_run_away_from():
    """A gear wheel of arcs and lines (LinuxCNC's G6_Ruota_dentata_1=2.ngc, 4.5 m) on a
    random pid machine at Ts = 0.1 ms: the easing stalled at 3.07 x Umax on the finest
    grid, and easing the whole path by the excess to the power of the round asked for
    a 3,408 s move (refused: more than 10,000,000 samples). Planned now, within 5 % of
    the time-optimal bound (39.3 s; the plan 40.8 s), no drive beyond Umax."""
    _, path, machine = _corpus_case("G6_Ruota_dentata_1=2.ngc", "xy", [8, 0, 2, 4])
    plan = plan_motion(path, machine, 940405.0)
    assert plan.arrival * machine.sample_period <= 1.05 * time_optimal_bound(
        path, machine, 940405.0)
    assert np.max(np.abs(plan.drive)) <= machine.max_drive * (1 + 1e-9)


def test_a_refused_blend_falls_back_to_stopping_and_says_so(monkeypatch):
    """Where the blended plan is refused, the plan that stops at the corners is made
    (its corner_tolerance is 0); where that is refused too, the blended plan's reason
    is raised."""
    import nurbsmotion.interpolators.planned.plan as mp

    real = mp._plan_motion

    def blends_refused(curve, machine, feed, corner_tolerance, **options):
        if corner_tolerance > 0:
            raise InfeasibleError("blends refused")
        return real(curve, machine, feed, corner_tolerance, **options)

    monkeypatch.setattr(mp, "_plan_motion", blends_refused)
    plan = plan_motion(PI, MACHINE, 1e6, corner_tolerance=500.0)
    assert plan.corner_tolerance == 0.0 and plan.stop_indices.size == 2
    # the run says so (summary.json's "message"); rounded corners say nothing
    it, trace = _planned(PI, 1e6, corner_tolerance=500.0)
    assert "stops at the sharp corners" in trace.message and trace.success
    monkeypatch.setattr(mp, "_plan_motion", real)
    assert "stops at" not in _planned(PI, 1e6, corner_tolerance=500.0)[1].message

    def all_refused(curve, machine, feed, corner_tolerance, **options):
        raise InfeasibleError("blends refused" if corner_tolerance else "stops refused")

    monkeypatch.setattr(mp, "_plan_motion", all_refused)
    with pytest.raises(InfeasibleError, match="blends refused"):
        plan_motion(PI, MACHINE, 1e6, corner_tolerance=500.0)


def test_planned_is_registered():
    assert "planned" in LOOP_METHODS
    assert isinstance(make_interpolator("planned", PI, MACHINE, 1e6), PlannedInterpolator)


# ------------------------------------------------------------------ random sweep
def random_curve(rng: np.random.Generator) -> NurbsCurve:
    """Degree 2-5, random weights, 1-4 spans with random sharp corners, ~10-80 mm."""
    while True:
        p = int(rng.integers(2, 6))
        n_breaks = int(rng.integers(0, 4))
        breaks = np.sort(rng.uniform(0.1, 0.9, n_breaks))
        if n_breaks and np.min(np.diff(np.r_[0.0, breaks, 1.0])) < 0.05:
            continue
        corner = rng.random(n_breaks) < 0.6
        interior = np.concatenate([[b] * (p if c else 1) for b, c in zip(breaks, corner)]) \
            if n_breaks else np.array([])
        knots = np.r_[[0.0] * (p + 1), interior, [1.0] * (p + 1)]
        n = len(knots) - p - 1
        steps = rng.normal(size=(n, 2)) * rng.uniform(2_000, 12_000)
        points = np.cumsum(steps, axis=0)
        weights = rng.uniform(0.5, 2.0, n)
        try:
            return NurbsCurve(p, knots, points, weights, name="random", units="pulse")
        except InvalidCurveError:
            continue


SWEEP = int(os.environ.get("NURBSMOTION_SWEEP", "3"))


@pytest.mark.parametrize("seed", range(SWEEP))
def test_planned_random_sweep(seed):
    """Seeded random NURBS at random feeds: no saturation, monotone parameter, at rest on
    the end (NURBSMOTION_SWEEP=N raises the count)."""
    rng = np.random.default_rng(1000 + seed)
    curve = random_curve(rng)
    feed = float(rng.uniform(5e4, 1.5e6))
    swapped = rng.random() < 0.5  # also a preset with the axes swapped
    machine = die_bonder()
    if swapped:
        machine = machine.with_options(axes=machine.axes[::-1])
    it = PlannedInterpolator(curve, machine, feed)
    trace = simulate(it, machine, settle_time=0.1)
    assert trace.metrics().total_saturated_samples == 0, (seed, curve, feed, swapped)
    _check_run(it, trace)


# ------------------------------------------------------------------ infeasible requests
@pytest.mark.parametrize("feed", [0.0, -1.0, math.nan, math.inf])
def test_bad_feed_is_an_invalid_argument(feed):
    with pytest.raises(InvalidFeedError, match="feed"):
        PlannedInterpolator(PI, MACHINE, feed)
    with pytest.raises(InvalidFeedError, match="feed"):
        time_optimal_bound(PI, MACHINE, feed)


def test_drive_too_weak_for_the_feed_is_refused():
    """At 1e-12 V the drive moves, slowly: a feed 1e11 times its top speed is refused by
    run's checks as what it is (issue 37; it was 'cannot move along the path', the speed
    limit taken relative to the unreachable feed), a plan is refused for its samples, and
    the bound is the drive-limited time, at least the length over the top speed."""
    from nurbsmotion.errors import InvalidFeedError
    from nurbsmotion.loop import check_run_arguments
    from nurbsmotion.planning import top_speed

    weak = die_bonder(max_drive=1e-12)
    with pytest.raises(InvalidFeedError, match="times the fastest"):
        check_run_arguments(PI, weak, 1e6)
    with pytest.raises(InfeasibleError, match="samples"):
        PlannedInterpolator(PI, weak, 1e6)
    assert time_optimal_bound(PI, weak, 1e6) >= PI.length / top_speed(weak)


def test_plan_too_long_is_infeasible_not_a_hang():
    with pytest.raises(InfeasibleError, match="more than 100 samples"):
        PlannedInterpolator(PI, die_bonder(max_drive=0.01), 1e6, max_samples=100)


@pytest.mark.parametrize("option, value", [("drive_fraction", 0.0), ("drive_fraction", 1.5),
                                           ("corner_tolerance", -1.0),
                                           ("path_tolerance", -1.0),
                                           ("path_tolerance", math.nan),
                                           ("tracking_pole", 1.0), ("drive_headroom", 1.0)])
def test_bad_options(option, value):
    with pytest.raises(ValueError, match=option):
        PlannedInterpolator(PI, MACHINE, 1e6, **{option: value})


@pytest.mark.parametrize("degree", [2, 3])
def test_a_repeated_control_point_is_a_stop_not_a_refusal(degree):
    """C' = 0 where a control point repeats (issue 11 item 3): the curvature in arc
    length is unbounded there, so the drive-limited motion comes to rest at that point
    (as at a sharp corner) instead of the plan being refused; planned never saturates."""
    rng = np.random.default_rng(degree)
    P = np.cumsum(rng.uniform(2000, 6000, size=(6, 2)), axis=0)
    P = np.insert(P, 3, [P[3]] * (degree - 1), axis=0)  # p copies: C' = 0 at a knot
    n, p = len(P), degree
    knots = np.concatenate([[0.0] * (p + 1), np.linspace(0, 1, n - p + 1)[1:-1],
                            [1.0] * (p + 1)])
    curve = NurbsCurve(p, knots, P)
    (u0,) = curve.zero_speed_points[:1]
    m = die_bonder()
    profile = speed_profile(curve, m, 5e5)
    s0 = float(curve.arc_length(u0))
    assert min(abs(p[0][0] - s0) for p in profile.pieces) < 1e-6 * curve.length
    assert math.isfinite(time_optimal_bound(curve, m, 5e5))
    trace = simulate(make_interpolator("planned", curve, m, 5e5), m)
    assert trace.success and trace.metrics().total_saturated_samples == 0


def test_a_piece_start_does_not_stall_the_forward_pass():
    """Sweep case 54 (tiny knot spans): at a piece's start (b = 0) the implicit step of the
    forward pass found no range at the next point and fell back to b = 0, twice in a row,
    so the profile took an infinite time on some grids. Every grid now gives about the
    same finite time, positive speeds inside the piece and zero saturation in the loop."""
    from nurbsmotion.paths.random_paths import random_path

    curve = random_path("tiny_spans", [10, 54], n_axes=2)
    m = die_bonder()
    durations = []
    for grid in (2000, 4000, 4010, 20000):
        profile = speed_profile(curve, m, 172144.72284469937, grid_size=grid)
        durations.append(profile.duration)
        for s, u, v in profile.pieces:
            assert np.all(v[1:-1] > 0)
    assert max(durations) < 1.01 * min(durations)
    trace = simulate(make_interpolator("planned", curve, m, 172144.72284469937), m)
    assert trace.metrics().total_saturated_samples == 0


def _slow_machine():
    """Two axes whose steady speed Umax*Kc*Ke is 1e6 pulse/s (1 m/s), 5 ms time constant."""
    axis = dict(time_constant=0.005, electrical_gain=100.0, mechanical_gain=1000.0,
                position_gain=5e-4, speed_gain=0.0)
    return die_bonder().with_options(axes=(Axis("x", **axis), Axis("y", **axis)),
                                     max_drive=10.0)


@pytest.mark.parametrize("radius, feed", [(2e5, 2e6), (2e4, 0.98e6)])
def test_a_speed_the_drive_cannot_hold_falls_along_the_path(radius, feed):
    """A quarter circle from heading +y to heading -x. At twice the axes' steady speed M
    (radius 0.2 m, 2 m/s), x must slow to about M/|x'| as the path turns toward it; at
    0.98 M on a 20 mm radius, the curvature's drive at the feed is more than x can give
    without braking. The passes once held a speed they could not keep (a falling step was
    clamped as if on a drive-bound MVC): the profile's x drive rose above Umax, the first
    case's bound came out 0.263 s instead of 0.290 s, and the planner eased in vain and
    refused both paths. Every interval's acceleration is now admissible at one of its
    ends, and the planned run neither saturates nor is refused."""
    m = _slow_machine()
    arc = nm.make_arc([0.0, 0.0], radius, 0.0, math.pi / 2)
    M = m.max_drive * m.Kc * m.Ke
    profile = speed_profile(arc, m, feed, grid_size=4000)
    (s, u, V), = profile.pieces
    d1, d2 = arc(u, 1), arc(u, 2)
    speed = np.linalg.norm(d1, axis=1)[:, None]
    q1 = d1 / speed
    q2 = (d2 - np.sum(q1 * d2, axis=1)[:, None] * q1) / speed**2
    a = (V[1:] ** 2 - V[:-1] ** 2) / (2 * np.diff(s))
    drive = [np.max(np.abs(m.tau * (q2[k] * V[k, None] ** 2 + q1[k] * a[:, None])
                           + q1[k] * V[k, None]) / M, axis=1)
             for k in (slice(0, -1), slice(1, None))]
    assert np.all(np.minimum(*drive) <= 1 + 1e-6)
    trace = simulate(make_interpolator("planned", arc, m, feed), m)
    assert trace.success and trace.metrics().total_saturated_samples == 0


@pytest.mark.parametrize("length", [2e6, 3e4])
def test_the_profile_converges_from_above_where_the_axis_settles_within_a_grid_step(length):
    """A straight move at a feed above the axis's steady speed M (tau 5 ms, M = 1 m/s).
    Under |tau x'' + x'| <= M its time-optimal motion is bang-bang with one switch at t1:
    L/M = t1 - tau ln(2 - exp(-t1/tau)), T = t1 + tau ln(2 - exp(-t1/tau)) (solved by
    brentq). Its speed relaxes toward M over M tau = 5,000 pulses, less than one grid
    step of a coarse grid (2e6 / 60 = 33,000 pulses). The explicit rise once jumped
    above M and then stalled: 3.48 T at 60 points, and 0.9965 T at 200 (faster than the
    optimum: not a bound). The rise is now implicit there: every grid gives at least T,
    less as the grid is refined."""
    from scipy.optimize import brentq

    m = _slow_machine()
    tau, M = 0.005, m.max_drive * m.Kc[0] * m.Ke[0]
    line = nm.make_line([0.0, 0.0], [length, 0.0])
    t1 = brentq(lambda t: t - tau * math.log(2 - math.exp(-t / tau)) - length / M, 1e-9, 10)
    T = t1 + tau * math.log(2 - math.exp(-t1 / tau))
    durations = np.array([speed_profile(line, m, 3 * M, grid_size=g).duration
                          for g in (60, 200, 1000, 4000, 20000)])
    assert np.all(durations >= T * (1 - 1e-12))
    assert np.all(np.diff(durations) < 0)
    assert durations[0] < 1.05 * T and durations[3] < 1.001 * T


@pytest.mark.parametrize("seed", range(12))
def test_planned_on_random_machines(seed):
    """Machines nobody tuned for (:mod:`nurbsmotion.random_machines`: every law, Ts
    0.1-2 ms, tau 2-100 ms, feeds up to 3x an axis's steady speed), on the model's plant:
    never refused, never saturated, at rest on the end, following its own plan (the
    model plant's response to the plan's drive) within a pulse while it moves.
    ``benchmarks/machine_sweep.py`` runs 600 such cases."""
    from nurbsmotion.paths.random_paths import FAMILIES, random_path
    from nurbsmotion.random_machines import random_machine

    rng = np.random.default_rng([5, seed])
    n_axes = int(rng.integers(2, 4))
    m = random_machine([5, seed], n_axes)
    curve = random_path(sorted(FAMILIES)[seed % len(FAMILIES)], [5, seed], n_axes=n_axes)
    feed = float(np.exp(rng.uniform(np.log(0.02), np.log(3.0)))) * np.min(m.max_axis_speed)
    interp = PlannedInterpolator(curve, m, feed)
    tr = simulate(interp, m)
    assert tr.success, tr.message
    assert tr.metrics().total_saturated_samples == 0
    n = min(interp.plan.rest + 1, len(tr.position))
    assert np.max(np.abs(tr.position[:n] - interp.plan.position[:n])) <= 1.0


def test_landing_stays_near_a_tight_curl_the_samples_step_across():
    """A 2 mm curl at 2 m/s, Ts = 2 ms (a random machine's; 40 samples for the move):
    consecutive samples lie far apart along the curl. The landing judged a changed
    position by its distance to the polyline through the desired samples, which cuts
    the curl: it accepted positions 46 um off the path (the exact distance,
    :func:`nurbsmotion.metrics.contour_error`), and step 6, no farther from the path
    than the plan it replaced, kept them. With the distance to the curve itself the
    plan stays within 3 um."""
    from nurbsmotion.paths.random_paths import random_path

    axes = (Axis("x", 0.03013, 289.77, 1606.3, 4.2458e-4, 0.014266),
            Axis("y", 0.019733, 279.38, 1430.06, 6.4964e-5, 0.0))
    m = die_bonder().with_options(axes=axes, max_drive=11.4363, sample_period=0.002)
    curve = random_path("curls", [77, 177], n_axes=2)
    plan = plan_motion(curve, m, 2.0157e6)
    assert np.max(contour_error(curve, plan.position)) <= 3.0


@pytest.mark.parametrize("seed", range(4))
def test_warm_started_programs_match_scipy_linprog(seed):
    """Step 6's programs (issue 35): HiGHS warm-started from the last basis, as the rounds
    re-linearise the path (same shape, new numbers), reaches the optimum scipy's
    ``linprog`` finds cold, round after round; an infeasible program gives None."""
    from scipy import sparse
    from scipy.optimize import linprog
    from nurbsmotion.interpolators.planned.shorten import _WarmProgram

    rng = np.random.default_rng(seed)
    n, m_ub, m_eq = 40, 60, 8
    A_eq = sparse.csr_matrix(rng.normal(size=(m_eq, n)))
    bounds = np.column_stack([np.full(n, -1.0), np.full(n, 1.0)])
    bounds[-1] = (0.0, np.inf)                       # an unbounded column, as E
    program = _WarmProgram()
    A = rng.normal(size=(m_ub, n))
    for _ in range(5):
        A += 0.05 * rng.normal(size=A.shape)         # the next round's numbers
        A_ub = sparse.csr_matrix(np.hstack([A[:, :-1], -np.ones((m_ub, 1))]))
        b_ub = rng.uniform(0.5, 1.5, m_ub)
        cost = np.r_[rng.normal(size=n - 1) * 0.01, 1.0]
        x = program.solve(cost, A_ub, b_ub, A_eq, bounds)
        ref = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=np.zeros(m_eq),
                      bounds=bounds, method="highs")
        assert ref.status == 0 and x is not None
        assert cost @ x == pytest.approx(ref.fun, rel=1e-7, abs=1e-9)
        assert np.all(A_ub @ x <= b_ub + 1e-7) and np.allclose(A_eq @ x, 0.0, atol=1e-7)
    # x[0] >= 2 within |x| <= 1: no program
    infeasible = sparse.csr_matrix(np.eye(1, n) * -1.0)
    assert program.solve(cost, infeasible, np.array([-2.0]), A_eq, bounds) is None


@pytest.mark.parametrize("seed", range(4))
def test_programs_that_grow_are_warm_started_to_scipys_optimum(seed):
    """Step 6's programs (issue 35) add rows and columns as a round holds more points: the
    rows and columns named as in the last program keep their basis status, the new ones
    start basic (rows) or at a bound (columns); HiGHS still reaches the optimum scipy's
    ``linprog`` finds cold, and the same after rows are dropped again."""
    from scipy import sparse
    from scipy.optimize import linprog
    from nurbsmotion.interpolators.planned.shorten import _WarmProgram

    rng = np.random.default_rng(seed)
    n, m_ub, m_eq = 40, 90, 8
    A_all = rng.normal(size=(m_ub, n + 21))           # rows of every point, 20 extra columns
    A_eq_all = rng.normal(size=(m_eq, n + 21))
    A_eq_all[:, -1] = 0.0
    program = _WarmProgram()
    for rows, extra in ((np.arange(0, 90, 3), 0), (np.arange(0, 90, 2), 8),
                        (np.arange(90), 20), (np.arange(0, 90, 5), 4)):
        cols = np.r_[np.arange(n - 1), n - 1 + 1 + np.arange(extra), n - 1 + 21]
        # the last column (E) last, as step 6 orders them; its key is the same throughout
        A = A_all[np.ix_(rows, cols)] + 0.02 * rng.normal(size=(len(rows), len(cols)))
        A[:, -1] = -1.0
        A_ub, A_eq = sparse.csr_matrix(A), sparse.csr_matrix(A_eq_all[:, cols])
        b_ub = rng.uniform(0.5, 1.5, len(rows))
        bounds = np.column_stack([np.full(len(cols), -1.0), np.full(len(cols), 1.0)])
        bounds[-1] = (0.0, np.inf)
        cost = np.r_[rng.normal(size=len(cols) - 1) * 0.01, 1.0]
        row_keys = np.r_[rows, 1000 + np.arange(m_eq)]
        x = program.solve(cost, A_ub, b_ub, A_eq, bounds, row_keys, cols)
        ref = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=np.zeros(m_eq),
                      bounds=bounds, method="highs")
        assert ref.status == 0 and x is not None
        assert cost @ x == pytest.approx(ref.fun, rel=1e-7, abs=1e-9)
        assert np.all(A_ub @ x <= b_ub + 1e-7) and np.allclose(A_eq @ x, 0.0, atol=1e-7)


def test_a_program_stops_where_its_work_budget_runs_out():
    """Step 6's work budget (issue 35) is counted in simplex pivots times the program's
    rows: a program given less than it needs returns no motion and marks the budget
    exhausted; given enough, it reaches scipy's ``linprog`` optimum and spends exactly
    its pivots times its rows (HiGHS' own count), so the plan is the same on any machine
    and at any load."""
    from scipy import sparse
    from scipy.optimize import linprog
    from nurbsmotion.interpolators.planned.shorten import _WarmProgram, _Work

    rng = np.random.default_rng(3)
    n, m_ub, m_eq = 40, 60, 8
    A_eq = sparse.csr_matrix(rng.normal(size=(m_eq, n)))
    A_ub = sparse.csr_matrix(np.hstack([rng.normal(size=(m_ub, n - 1)), -np.ones((m_ub, 1))]))
    b_ub = rng.uniform(0.5, 1.5, m_ub)
    bounds = np.column_stack([np.full(n, -1.0), np.full(n, 1.0)])
    bounds[-1] = (0.0, np.inf)
    cost = np.r_[rng.normal(size=n - 1) * 0.01, 1.0]
    rows = m_ub + m_eq
    ample = _Work(1e9)
    x = _WarmProgram(ample).solve(cost, A_ub, b_ub, A_eq, bounds)
    ref = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=np.zeros(m_eq),
                  bounds=bounds, method="highs")
    assert x is not None and not ample.exhausted
    assert cost @ x == pytest.approx(ref.fun, rel=1e-7, abs=1e-9)
    pivots = (1e9 - ample.left) / rows
    assert pivots >= 1 and pivots == int(pivots)
    short = _Work((pivots - 1) * rows)
    assert _WarmProgram(short).solve(cost, A_ub, b_ub, A_eq, bounds) is None
    assert short.exhausted


def test_a_short_move_keeps_the_earliest_arrival_found_within_its_work_budget():
    """Step 6's search (issue 35) under a work budget (``shorten_work``): with none the
    search is complete; with one too small for any program the plan of steps 1-5 stays,
    and with one that runs out on the way the plan arrives no sooner than without it but
    no later than steps 1-5 alone; either way the plan says so and the interpolator's
    notes (the run's message) too. A bad budget is refused by name."""
    from nurbsmotion.errors import InvalidArgumentError
    from nurbsmotion.paths.random_paths import random_path

    curve = random_path("short_moves", [10, 7], n_axes=3)
    machine, feed = _three_axes(), 1e6
    full = plan_motion(curve, machine, feed, shorten_work=math.inf)
    assert full.shorten_status == "complete"
    assert plan_motion(curve, machine, feed).arrival == full.arrival
    none = plan_motion(curve, machine, feed, shorten_work=1e-3)
    assert none.shorten_status == "work budget"
    assert none.arrival > full.arrival
    for work in (3e3, 3e4):
        plan = plan_motion(curve, machine, feed, shorten_work=work)
        assert full.arrival <= plan.arrival <= none.arrival
        if plan.shorten_status == "complete":
            assert plan.arrival == full.arrival
        assert np.max(np.abs(plan.drive)) <= machine.max_drive
        np.testing.assert_array_equal(plan.position[plan.arrival:], np.broadcast_to(
            curve(1.0), plan.position[plan.arrival:].shape))
    interp = PlannedInterpolator(curve, machine, feed, shorten_work=1e-3)
    assert interp.shorten_status == "work budget"
    assert any("work budget" in note for note in interp.notes)
    assert not PlannedInterpolator(curve, machine, feed).notes
    for bad in (0, -1.0, True, "1e5", math.nan):
        with pytest.raises(InvalidArgumentError, match="shorten_work"):
            plan_motion(curve, machine, feed, shorten_work=bad)


def test_the_narrow_trust_region_starts_its_programs_cold(monkeypatch):
    """Step 6 (issue 35): an arrival sample's narrow trust region, tried where the wide one
    finds no motion, starts from no basis: warm-started from the wide region's last one,
    a first program the narrow region makes infeasible took HiGHS 5 s of CPU on
    planner_sweep case 71 (0.13 s cold). Each region's rounds share one program."""
    from nurbsmotion.interpolators.planned import shorten as step6
    from nurbsmotion.paths.random_paths import random_path

    calls = []
    original = step6._shorten_at

    def recorded(*args):
        program = args[13]
        calls.append((args[4], args[11], program, program.basis is None))
        return original(*args)

    monkeypatch.setattr(step6, "_shorten_at", recorded)
    curve = random_path("short_moves", [10, 0], n_axes=2)
    plan_motion(curve, MACHINE, 1e6)
    narrow = [c for c in calls if not c[1]]
    wide = [c[2] for c in calls if c[1]]
    assert narrow and all(cold for *_, cold in narrow)
    assert not any(program is other for _, _, program, _ in narrow for other in wide)


@pytest.mark.parametrize("seed", range(3))
def test_an_axis_reach_is_scipy_linprogs_farthest_rest_to_rest_move(seed):
    """Step 6 (issue 35) skips an arrival sample N where an axis cannot move as far as
    the piece needs: its reach (:func:`_axis_reach`, the dual of the rest-to-rest
    program in closed form) is the farthest displacement scipy's ``linprog`` finds over
    drives within the limit that leave the plant, simulated sample by sample, at rest
    at N."""
    from scipy.optimize import linprog
    from nurbsmotion.interpolators.planned.inverse import LEAD
    from nurbsmotion.interpolators.planned.shorten import _axis_reach, _partial_zoh

    from types import SimpleNamespace

    rng = np.random.default_rng(seed)
    # the plant alone (no loop to keep stable): tau and Kc scaled at random
    plant = SimpleNamespace(tau=MACHINE.tau * rng.uniform(0.3, 3.0, 2),
                            Kc=MACHINE.Kc * rng.uniform(0.5, 2.0, 2), Ke=MACHINE.Ke,
                            sample_period=MACHINE.sample_period)
    zoh = _partial_zoh(plant, 4)
    a, b0, c, b1 = (x[-1] for x in zoh)
    limit = MACHINE.max_drive * rng.uniform(0.5, 1.0)
    for N in (LEAD + 1, LEAD + 2, 7, 30, 128):
        reach = _axis_reach(zoh, N, limit)
        for j in range(2):
            # speed and position at N of a unit drive held over sample k, simulated
            G = np.zeros((2, N - LEAD))
            for k in range(LEAD, N):
                w = theta = 0.0
                for i in range(k, N):
                    u = 1.0 if i == k else 0.0
                    w, theta = a[j] * w + b0[j] * u, theta + c[j] * w + b1[j] * u
                G[:, k - LEAD] = w, theta
            ref = linprog(-G[1], A_eq=G[:1], b_eq=[0.0], bounds=(-limit, limit),
                          method="highs")
            assert ref.status == 0
            assert reach[j] == pytest.approx(-ref.fun, rel=1e-9)


def test_a_stacked_program_is_the_one_written_block_by_block():
    """Step 6's constraint matrix (issue 35), built from its entries in one step
    (:func:`_stacked_program`), holds the same numbers at the same places as the blocks
    ``[A_n - E; -A_n - E; A_t - S; -A_t - S; A_t; -A_t; D A_t; -D A_t; A_t[0]; -A_t[-1];
    A_eq]`` stacked with ``scipy.sparse`` (zero entries aside, which HiGHS drops)."""
    from scipy import sparse
    from nurbsmotion.interpolators.planned.shorten import _stacked_program

    rng = np.random.default_rng(5)
    m, r, n_fixed, n_eq = 9, 4, 30, 12
    col_step = n_fixed + np.arange(m)
    col_E = n_fixed + m
    n_var = col_E + 1

    def entries(n_rows, zeros):
        # three position columns a row; consecutive rows may share them (one sample)
        rows = np.repeat(np.arange(n_rows), 3)
        first = np.repeat(rng.integers(0, n_fixed - 3, n_rows // zeros + 1), zeros)[:n_rows]
        cols = (first[:, None] + np.arange(3)).ravel()
        vals = rng.normal(size=rows.size)
        vals[rng.random(rows.size) < 0.2] = 0.0
        return rows, cols, vals

    t_entries, n_entries = entries(m, 2), entries(m * r, 1)
    eq = (rng.normal(size=40), (rng.integers(0, n_eq, 40), rng.integers(0, n_fixed, 40)))
    eq[1][0][0] = n_eq - 1
    A = _stacked_program(m, m * r, n_var, col_E, col_step, n_entries, t_entries, eq, n_eq)

    def csr(e, n_rows):
        return sparse.csr_matrix((e[2], (e[0], e[1])), shape=(n_rows, n_var))

    A_t, A_n = csr(t_entries, m), csr(n_entries, m * r)
    E = csr((np.arange(m * r), np.full(m * r, col_E), np.ones(m * r)), m * r)
    S = csr((np.arange(m), col_step, np.ones(m)), m)
    D = sparse.diags([np.ones(m - 1), -np.ones(m - 1)], [0, 1], shape=(m - 1, m))
    A_eq = sparse.csr_matrix(eq, shape=(n_eq, n_var))
    ref = sparse.vstack([A_n - E, -A_n - E, A_t - S, -A_t - S, A_t, -A_t, D @ A_t,
                         -(D @ A_t), A_t[:1], -A_t[-1:], A_eq]).tocsc()
    ref.eliminate_zeros()
    ref.sort_indices()
    assert A.shape == ref.shape and A.has_sorted_indices
    np.testing.assert_array_equal(A.indptr, ref.indptr)
    np.testing.assert_array_equal(A.indices, ref.indices)
    np.testing.assert_array_equal(A.data, ref.data)


def test_a_single_count_does_not_throw_the_identification():
    """Issue 33 item 1: an encoder edge under a resting axis (the count toggling 0, 1, 0,
    ... with no drive) leaves the estimate and its covariance as they were when the
    reading is in counts (its residual is within the dead zone of the reading), and
    moves it without one; an exact reading has no dead zone (today's step)."""
    from nurbsmotion.interpolators.planned.identify import _identify, reading_knowledge
    from nurbsmotion.interpolators.planned.interpolator import _prior_estimate

    it = PlannedInterpolator(PI, MACHINE, 1e6)
    p = it.plan
    assert reading_knowledge(MACHINE, p.a, p.b0, p.c, p.b1) == {"dead_zone": 0.0,
                                                               "landing_band": 0.0}
    dz = reading_knowledge(MACHINE.with_options(encoder="counts"), p.a, p.b0, p.c,
                           p.b1)["dead_zone"]
    # a count's residual: 1 + |1 + a| at most (positions weighted 1, -(1 + a), a)
    assert 1.0 + abs(1.0 + p.a[0]) <= 2.0 * dz
    for zone, moved in ((dz, False), (0.0, True)):
        est = _prior_estimate(p, MACHINE.max_drive)
        prior = est.copy()
        hist = np.zeros((HIST_ROWS, 2))
        for k in range(40):
            _identify(est, hist, 0, float(k % 2), p.a[0], p.b0[0], p.c[0], p.b1[0], zone)
        assert (not np.array_equal(est[:, 0], prior[:, 0])) == moved


def test_identification_on_counts_stays_near_the_true_plant():
    """Positions read in whole counts of a plant with tau x1.3, Kc x0.8 under a random
    drive: with the dead zone the estimated drive ratio ga (:func:`_gains`) ends within
    10 % of the true one (scipy's expm) and never reaches the clip GAIN_RANGE."""
    from nurbsmotion.interpolators.planned.identify import (GAIN_RANGE, _identify,
                                                            reading_knowledge)
    from nurbsmotion.interpolators.planned.interpolator import _prior_estimate

    it = PlannedInterpolator(PI, MACHINE, 1e6)
    p = it.plan
    dz = reading_knowledge(MACHINE.with_options(encoder="counts"), p.a, p.b0, p.c,
                           p.b1)["dead_zone"]
    plant = ServoPlant.of_machine(MACHINE, PI(0.0), time_constant_scale=1.3,
                                  electrical_gain_scale=0.8)
    drive = np.random.default_rng(5).uniform(-10, 10, (400, 2))
    drive[0] = 0.0
    _, position = plant.response(drive)
    counts = np.floor(position - position[0]) + position[0]
    est = _prior_estimate(p, MACHINE.max_drive)
    hist = np.zeros((HIST_ROWS, 2))
    for k in range(1, 400):
        for j in range(2):
            ga, _ = _identify(est, hist, j, counts[k, j], p.a[j], p.b0[j], p.c[j],
                              p.b1[j], dz)
            assert 1.0 / GAIN_RANGE < ga < GAIN_RANGE
            hist[1, j], hist[0, j] = hist[0, j], drive[k, j]
    for j in range(2):
        a, b0, c, b1 = _scipy_zoh(j, 1.3, 0.8)
        s_model = p.b1[j] + p.c[j] * p.b0[j] - p.a[j] * p.b1[j]
        ga_true = s_model / (b1 + c * b0 - a * b1)
        assert abs(est[1, j] + est[2, j] - (b1 + c * b0 - a * b1)) <= 0.1 * abs(
            b1 + c * b0 - a * b1), (j, ga_true)


def test_a_path_of_too_many_corners_is_refused_before_its_arc_length(monkeypatch):
    """Regression (issue 37, work refused late): a zigzag of 100,001 points has 99,999
    sharp corners, whose pieces need at least 51 grid points each, more than
    MAX_GRID_POINTS: refused from the corners alone, before the arc length (seconds on a
    million points) is computed."""
    from nurbsmotion.planning import MAX_GRID_POINTS

    n = 100_001
    points = np.column_stack([np.arange(n) * 10.0, (np.arange(n) % 2) * 10.0])
    knots = np.concatenate([[0.0], np.arange(n, dtype=float), [n - 1.0]])
    zigzag = NurbsCurve(1, knots, points)
    assert 51 * (n - 1) > MAX_GRID_POINTS

    def no_arc_length(*args, **kwargs):
        raise AssertionError("arc length computed before the corner check")

    monkeypatch.setattr(NurbsCurve, "arc_length", no_arc_length)
    monkeypatch.setattr(NurbsCurve, "length", property(no_arc_length))
    with pytest.raises(InfeasibleError, match="99999 sharp corners"):
        speed_profile(zigzag, MACHINE, 1e5)


def test_the_profile_size_is_checked_from_the_corners_before_the_run(tmp_path, monkeypatch, capsys):
    """Regression (issue 37, work refused late): a zigzag path file of 100,001 points is
    refused by `bound` and `run` in one line naming its corners and the limit, from
    check_profile_size (knots and corners), before the settle window's check and the arc
    length (each a second or more on a million points)."""
    import json

    from nurbsmotion import metrics
    from nurbsmotion.cli import main
    from nurbsmotion.errors import WorkLimitError
    from nurbsmotion.planning import MAX_GRID_POINTS, PIECE_GRID_POINTS, check_profile_size

    n = 100_001
    points = np.column_stack([np.arange(n) * 0.01, (np.arange(n) % 2) * 0.01])
    knots = [0] + list(range(n)) + [n - 1]
    file = tmp_path / "zigzag.json"
    file.write_text(json.dumps({"units": "mm", "degree": 1, "knots": knots,
                                "control_points": points.tolist()}))
    assert PIECE_GRID_POINTS * (n - 1) > MAX_GRID_POINTS

    def no_arc_length(*args, **kwargs):
        raise AssertionError("arc length or settle window computed before the size check")

    monkeypatch.setattr(NurbsCurve, "arc_length", no_arc_length)
    monkeypatch.setattr(NurbsCurve, "length", property(no_arc_length))
    monkeypatch.setattr(metrics, "check_settle_window", no_arc_length)
    zigzag = NurbsCurve(1, knots, points)
    with pytest.raises(WorkLimitError, match="99,999 sharp corners; its 100,000 corner-free "
                                             "pieces need at least 5,100,000 grid points"):
        check_profile_size(zigzag)
    from nurbsmotion.paths import files

    # parsed (the text's corner count off): check_profile_size's exact count; from the
    # text (the file is over SIZE_SCAN_BYTES): at least those of its first vertices
    for scan, count in ((len(file.read_text()), "99,999 sharp corners"),
                        (files.SIZE_SCAN_BYTES, "at least 98,039 sharp corners (in its first "
                                                "98,042 points)")):
        monkeypatch.setattr(files, "SIZE_SCAN_BYTES", scan)
        for command in (["bound", str(file), "--feed", "100mm/s"],
                        ["run", str(file), "--feed", "100mm/s", "--out", str(tmp_path / "o")]):
            assert main(command) == 2
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and count in err[0], err
            assert "planning.MAX_GRID_POINTS" in err[0]
    assert not (tmp_path / "o").exists()


def test_a_spline_of_too_many_spans_is_refused_before_its_bounding_box(tmp_path, monkeypatch,
                                                                        capsys):
    """Regression (issue 37): a cubic path file of 900,000 spans (more than
    MAX_GRID_POINTS / (2 * 3)) was refused only after the exact bounding box of the chord
    join (a minute): the box is computed only for --path-tolerance, and the span count
    refuses it first."""
    import json

    from nurbsmotion.cli import main

    n = 900_003
    x = np.round(np.arange(n) * 0.01, 4)
    knots = [0, 0, 0] + list(range(n - 2)) + [n - 3] * 3
    file = tmp_path / "wave.json"
    file.write_text(json.dumps({"units": "mm", "degree": 3, "knots": knots, "control_points":
                                np.column_stack([x, np.round(np.sin(x), 4)]).tolist()}))

    def no_box(*args, **kwargs):
        raise AssertionError("bounding box computed")

    monkeypatch.setattr(NurbsCurve, "bounding_box", no_box)
    assert main(["bound", str(file), "--feed", "100mm/s"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "900,000 knot spans of degree 3" in err[0], err
    assert "5,400,001 points, more than the limit of 5,000,000" in err[0]


def _step6_calls(monkeypatch, curve, feed):
    """Every call of step 6's :func:`_shorten_at` in ``plan_motion(curve, MACHINE, feed)``:
    its arguments, whether the wide region's trust was widened by the feed, its result."""
    from nurbsmotion.interpolators.planned import shorten as step6

    calls = []
    original = step6._shorten_at

    def recorded(*args):
        found = original(*args)
        calls.append((args, bool(args[14] and args[14][0]), found))
        return found

    monkeypatch.setattr(step6, "_shorten_at", recorded)
    plan_motion(curve, MACHINE, feed)
    return calls


def _programs(monkeypatch, args):
    """:func:`_shorten_at` called again on ``args`` with a program of its own: its result
    and every linear program it solved (cost, matrix, right-hand side, bounds)."""
    from nurbsmotion.interpolators.planned import shorten as step6

    programs = []
    solve = step6._WarmProgram.solve_stacked

    def recorded(self, cost, A, b_ub, bounds, *keys):
        programs.append((cost.copy(), A.toarray(), b_ub.copy(), bounds.copy()))
        return solve(self, cost, A, b_ub, bounds, *keys)

    monkeypatch.setattr(step6._WarmProgram, "solve_stacked", recorded)
    found = step6._shorten_at(*args[:13], step6._WarmProgram(), [False], *args[15:])
    monkeypatch.setattr(step6._WarmProgram, "solve_stacked", solve)
    return found, programs


def test_an_unwidened_wide_region_is_not_solved_again_narrow(monkeypatch):
    """Step 6 (issue 35): where the feed never widened the wide trust region beyond the
    chord's (``widened``), the narrow region's programs are the wide region's, number for
    number, so it finds no motion either; the search does not solve them again."""
    from nurbsmotion.paths.random_paths import random_path

    calls = _step6_calls(monkeypatch, random_path("nearly_straight", [10, 1], n_axes=2), 3e5)
    unwidened = [(args, k) for k, (args, widened, found) in enumerate(calls)
                 if args[11] and not widened and found is None]
    assert unwidened
    for args, k in unwidened:
        assert k + 1 == len(calls) or calls[k + 1][0][4] != args[4]   # no narrow try
        wide, wide_programs = _programs(monkeypatch, args)
        narrow, narrow_programs = _programs(monkeypatch, args[:11] + (False,) + args[12:])
        assert wide is None and narrow is None and len(narrow_programs) == len(wide_programs)
        for a, b in zip(wide_programs, narrow_programs):
            assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_a_try_below_the_duration_ends_where_E_exceeds_the_tolerance(monkeypatch):
    """Step 6 (issue 35, SHORTEN_BELOW_ROUNDS): a try at an arrival sample before the
    piece's continuous duration (``below``) stops after a program whose largest normal
    offset E exceeds the path tolerance; its second program, solved all the same without
    the rule, finds no motion either."""
    from nurbsmotion.interpolators.planned.shorten import SHORTEN_BELOW_ROUNDS
    from nurbsmotion.paths.random_paths import random_path

    calls = _step6_calls(monkeypatch, random_path("sharp_corners", [10, 0], n_axes=2), 3e5)
    below = [args for args, _, found in calls if args[15]]
    assert below and all(found is None for args, _, found in calls if args[15])
    spared = 0
    for args in below:
        found, programs = _programs(monkeypatch, args)
        without, all_programs = _programs(monkeypatch, args[:15] + (False,))
        assert found is None and without is None
        assert len(programs) == 1 <= len(all_programs) <= SHORTEN_BELOW_ROUNDS
        spared += len(all_programs) - len(programs)
    assert spared > 0
