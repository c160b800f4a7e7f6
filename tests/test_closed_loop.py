"""The one closed loop: independent recomputation of its rows, resumption, plain-Python
execution, no mutation of its inputs, explicit status and verdict."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.loop import closed_loop
from nurbsmotion.control import pid_state
from nurbsmotion.interpolators import (PaperInterpolator, PlannedInterpolator, Status,
                                       TaylorInterpolator)
from nurbsmotion.loop import run, settle_hold_samples, simulate
from nurbsmotion.machine import Axis, Machine, die_bonder
from nurbsmotion.servo import ServoPlant
from random_curves import N_CASES, random_curve


def random_machine(rng, n_axes):
    x = (0.31, 2506.17, 1591.5494, 0.0136, 0.03)
    y = (0.135, 3156.23, 1591.5494, 0.00577, 0.028)
    axes = tuple(Axis(f"a{j}", *(v * rng.uniform(0.8, 1.25) for v in (x, y)[j % 2]))
                 for j in range(n_axes))
    return Machine(axes, max_drive=float(rng.choice([10.0, 3.0, math.inf])),
                   sample_period=float(rng.choice([1e-3, 5e-4])),
                   controller=str(rng.choice(["pd+", "pd"])),
                   speed_measurement=str(rng.choice(["encoder", "true"])))


def replay_rows(trace, plant):
    """The loop recomputed from the trace's setpoints alone, sample by sample, with the
    paper's PD / PD+ (eq. 3.3) written here and the plant's own response: the positions,
    drives and clipping every row must have."""
    m = trace.machine
    Ts, Ke = m.sample_period, m.Ke
    thd = trace.position_command
    n = len(thd)
    w = np.zeros(m.n_axes)
    th = trace.curve(0.0).copy()     # at rest on the path's start before sample 0
    th_prev = th.copy()
    thd_prev, wd_prev = th.copy(), np.zeros(m.n_axes)
    drive = np.empty_like(thd)
    pos = np.empty_like(thd)
    ff = 1.0 if m.controller == "pd+" else 0.0
    for k in range(n):
        wa = (th - th_prev) / (Ke * Ts) if m.speed_measurement == "encoder" else w
        wd = (thd[k] - thd_prev) / (Ke * Ts)
        u = (m.Kp * (thd[k] - th) + m.Kd * (wd - wa)
             + ff * (wd / m.Kc + m.tau * (wd - wd_prev) / Ts / m.Kc))
        drive[k], pos[k] = u, th
        applied = np.clip(u, -m.max_drive, m.max_drive)
        sp, ps = plant.response(applied[None], position=th)
        # response() starts at rest: add the free motion of the current speed
        free_w, free_th = plant.Ad[:, 0, 0] * w, plant.Ad[:, 1, 0] * w
        th_prev = th
        w, th = sp[1] + free_w, ps[1] + free_th
        thd_prev, wd_prev = thd[k], wd
    return pos, drive


def test_random_curves_and_machines_follow_the_law_and_the_plant():
    rng = np.random.default_rng(5)
    for _ in range(N_CASES):
        curve = random_curve(rng, scale=3000.0)
        m = random_machine(rng, curve.n_axes)
        feed = float(rng.uniform(5e4, 1e6))
        order = int(rng.integers(1, 3))
        plant = ServoPlant.of_machine(m, time_constant_scale=1.2, electrical_gain_scale=0.8)
        for interp in (PaperInterpolator(curve, m, feed, order=order),
                       TaylorInterpolator(curve, m.sample_period, feed, order=order)):
            tr = simulate(interp, m, plant=plant, settle_time=0.01, settle_limit=0.5)
            pos, drive = replay_rows(tr, plant)
            scale = max(np.max(np.abs(tr.position)), 1.0)
            np.testing.assert_allclose(tr.position, pos, rtol=1e-9, atol=1e-9 * scale)
            np.testing.assert_allclose(tr.drive, drive, rtol=1e-7,
                                       atol=1e-9 * max(np.max(np.abs(drive)), 1.0))
            np.testing.assert_array_equal(
                tr.drive_applied, np.clip(tr.drive, -m.max_drive, m.max_drive))
            assert np.all(np.diff(tr.u) >= 0) and tr.u[-1] == 1.0


def test_planned_moves_the_plant_from_sample_0_and_the_loop_follows_the_law():
    """``planned`` gives sample 0's setpoint too (stepping.first_sample): it leads the
    start, so the drive u[0] moves the plant over the first sample, and the rows are the
    law's and the plant's, recomputed from the setpoints alone; ``paper``'s sample 0 is
    the start and its u[0] is 0."""
    curve = nm.make_die_bonder_pi()
    m = die_bonder()
    plant = ServoPlant.of_machine(m, time_constant_scale=1.2, electrical_gain_scale=0.8)
    tr = simulate(PlannedInterpolator(curve, m, 1e6), m, plant=plant, settle_time=0.01)
    assert np.max(np.abs(tr.drive[0])) > 0.1 * m.max_drive
    assert np.max(np.abs(tr.position[1] - curve(0.0))) > 0
    pos, drive = replay_rows(tr, plant)
    np.testing.assert_allclose(tr.position, pos, rtol=1e-9, atol=1e-9 * 6e4)
    np.testing.assert_allclose(tr.drive, drive, rtol=1e-7, atol=1e-9 * m.max_drive)
    paper = simulate(PaperInterpolator(curve, m, 1e6), m, settle_time=0.01)
    np.testing.assert_array_equal(paper.position_command[0], curve(0.0))
    np.testing.assert_array_equal(paper.drive[0], 0.0)


def test_growing_the_rows_resumes_the_run_where_it_stopped():
    """The same run from one row of capacity (resumed ~10 times) and from a large one."""
    m = die_bonder(max_drive=0.3)
    interp = PaperInterpolator(nm.make_die_bonder_pi(), m, 1e6)
    start = interp.curve(0.0)
    settling = closed_loop.Settling(interp.plan.path.end, 1.0, 50, 30, 10**4, 10**6)
    runs = [closed_loop.run(interp.plan, interp.new_state(), m.law(), pid_state(start),
                            ServoPlant.of_machine(m), True, start, settling, True, capacity)
            for capacity in (1, 10**5)]
    (code_a, a, _), (code_b, b, _) = runs
    assert code_a == code_b == closed_loop.DONE
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)


def test_the_loop_runs_as_plain_python():
    """NUMBA_DISABLE_JIT=1 runs the very same functions uncompiled: the same trace."""
    code = ("import json, nurbsmotion as nm; from nurbsmotion.loop import run; "
            "from nurbsmotion.machine import die_bonder; "
            "tr = run(nm.make_line([0.0, 0.0], [3000.0, 4000.0]), die_bonder(), 2e5, '{}', "
            "settle_time=0.0); "
            "print(json.dumps([tr.position.tolist(), tr.drive.tolist(), tr.status.tolist()]))")
    for name in ("paper", "planned"):
        env = dict(os.environ, NUMBA_DISABLE_JIT="1")
        out = subprocess.run([sys.executable, "-c", code.format(name)], env=env,
                             capture_output=True, text=True, check=True, timeout=300)
        position, drive, status = json.loads(out.stdout)
        tr = run(nm.make_line([0.0, 0.0], [3000.0, 4000.0]), die_bonder(), 2e5, name,
                 settle_time=0.0)
        np.testing.assert_allclose(position, tr.position, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(drive, tr.drive, rtol=1e-9, atol=1e-9)
        assert status == tr.status.tolist()


def test_simulate_changes_nothing_it_is_given():
    m = die_bonder()
    pi = nm.make_die_bonder_pi()
    interp = PlannedInterpolator(pi, m, 1e6)
    plant = ServoPlant.of_machine(m, time_constant_scale=1.2, electrical_gain_scale=0.8)
    plan = [np.copy(x) if isinstance(x, np.ndarray) else x for x in interp.plan]
    a = simulate(interp, m, plant=plant)
    b = simulate(interp, m, plant=plant)
    np.testing.assert_array_equal(a.drive, b.drive)
    for before, after in zip(plan, interp.plan):
        if isinstance(before, np.ndarray):
            np.testing.assert_array_equal(before, after)
    assert plant.position is None  # the plant value object holds no motion state


def test_status_limited_and_verdict_are_reported():
    m = die_bonder()
    pi = nm.make_die_bonder_pi()
    planned = run(pi, m, 1e6, "planned")
    assert planned.success and planned.status[planned.finished_index] == Status.FINISHED
    # a true plant with a 30 % weaker drive: the governor slows the plan (limited steps)
    weak = run(pi, m, 1e6, "planned", plant=ServoPlant.of_machine(m, electrical_gain_scale=0.7))
    limited = weak.status == Status.LIMITED
    assert limited.any() and f"{int(limited.sum())} steps limited" in weak.message
    assert np.all(np.abs(weak.drive) <= m.max_drive)
    paper = run(pi, m, 1e6, "paper")
    assert not paper.success and "samples with a drive beyond Umax" in paper.message
    # the paper's limited samples are those where eq. 3.10 cut the feed
    lim = paper.status == Status.LIMITED
    np.testing.assert_array_less(paper.feed[lim], 1e6)
    taylor = run(pi, m, 2e5, "taylor2")
    assert set(np.unique(taylor.status)) <= {Status.WORKING, Status.FINISHED}


def test_the_run_goes_on_until_the_motion_has_settled():
    """At 2 m/s constant feed the drive is still saturated well after the setpoint stops;
    the trace covers it until the position has stayed within the window."""
    m = die_bonder()
    tr = run(nm.make_die_bonder_pi(), m, 2e6, "taylor2")
    hold = settle_hold_samples(m)
    assert tr.settled_index is not None and len(tr.t) - tr.settled_index >= hold
    tail = tr.position[tr.settled_index:] - [60000.0, 0.0]
    assert np.max(np.linalg.norm(tail, axis=1)) <= 1.0
    over = np.max(np.abs(tr.drive), axis=1) > m.max_drive
    assert not over[tr.settled_index:].any()
    assert over[tr.finished_index + 50:].any()  # saturation beyond the old 50 ms tail


def test_a_motion_that_cannot_settle_says_so():
    m = die_bonder()
    # a true plant with a 30 % weaker drive: settles, but later; with a 1 ms limit it cannot
    plant = ServoPlant.of_machine(m, electrical_gain_scale=0.7)
    tr = run(nm.make_die_bonder_pi(), m, 1e6, "paper", plant=plant, settle_limit=0.001)
    assert not tr.success and tr.settled_index is None
    assert "did not settle within 1 pulse of the end in 0.001 s" in tr.message


def test_sample_limit_is_a_clear_error():
    m = die_bonder()
    with pytest.raises(nm.InfeasibleError, match="end was not reached within 100 samples"):
        simulate(TaylorInterpolator(nm.make_die_bonder_pi(), m.sample_period, 2e5), m,
                 max_samples=100)


def test_every_interpolator_runs_with_every_law():
    """PD, PD+ and a LinuxCNC pid with an integrator and a deadband, on a 3-axis path."""
    from nurbsmotion.control import PidGains

    rng = np.random.default_rng(3)
    pid_axes = tuple(Axis(f"a{j}", 0.31, 2506.17, 1591.5494,
                          pid=PidGains(Pgain=0.0136, Igain=0.02, Dgain=0.03 / 1591.5494,
                                       FF1=1 / (2506.17 * 1591.5494),
                                       FF2=0.31 / (2506.17 * 1591.5494), deadband=0.05))
                     for j in range(3))
    machines = [Machine(tuple(Axis(f"a{j}", 0.31, 2506.17, 1591.5494, 0.0136, 0.03)
                              for j in range(3)), max_drive=10.0, sample_period=1e-3,
                        controller=c) for c in ("pd", "pd+")]
    machines.append(Machine(pid_axes, max_drive=10.0, sample_period=1e-3, controller="pid"))
    path = nm.NurbsCurve(3, [0, 0, 0, 0, 1, 1, 1, 1],
                         np.cumsum(rng.normal(0, 3000, (4, 3)), axis=0))
    for m in machines:
        for name in ("taylor1", "taylor2", "paper", "planned"):
            tr = run(path, m, 3e5, name)
            assert tr.u[-1] == 1.0 and np.all(np.isfinite(tr.drive))
            assert tr.settled_index is not None, (m.controller, name, tr.message)


def test_every_interpolator_keeps_a_per_piece_feed_limit():
    """The programmed feed of each piece (G-code F) is a speed limit along it for every
    interpolator: on the Pi's transfer piece at 0.1 m/s and 0.5 m/s elsewhere, the setpoint
    (for ``planned``, whose setpoints lead the path: the actual position) never moves
    faster than the piece's limit (first-order steps of paper and taylor1 are exact on
    these straight-ish spans to a few per cent: 2 % allowance)."""
    from nurbsmotion.feed import FeedLimit

    m = die_bonder()
    pi = nm.make_die_bonder_pi()
    limit = FeedLimit([0.0, 1 / 3, 2 / 3, 1.0], [5e5, 1e5, 5e5])
    for name in ("taylor1", "paper", "planned"):
        tr = run(pi, m, limit, name)
        k = np.arange(1, tr.finished_index)
        moving = tr.position if name == "planned" else tr.position_command
        speed = np.linalg.norm(np.diff(moving, axis=0), axis=1)[k - 1] / 1e-3
        cap = np.maximum(limit(tr.u[k - 1]), limit(tr.u[k]))  # a step may cross a corner
        assert np.all(speed <= cap * 1.02 + 1.0), name
        middle = (tr.u[k - 1] > 0.4) & (tr.u[k - 1] < 0.6)
        assert np.max(speed[middle]) <= 1e5 * 1.02, name
