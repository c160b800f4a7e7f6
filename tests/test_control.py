"""The control law as data (LinuxCNC ``pid``) against independent references.

- the unsaturated closed loop (law and exact ZOH plant) against ``scipy.signal.dlsim`` of
  a state-space model written here from the equations, on random gains and setpoints;
- the clamps, deadband and anti-windup against a sequence worked by hand;
- the paper's PD / PD+ as presets; machine files with ``[axes.pid]``; unstable loops.
"""

import math

import numpy as np
import pytest
from scipy import signal

import nurbsmotion as nm
from nurbsmotion import InvalidMachineError, PathFileError
from nurbsmotion.control import (PidGains, loop_poles, pid_affine, pid_commit, pid_law,
                                 pid_output, pid_state)
from nurbsmotion.interpolators import make_interpolator
from nurbsmotion.loop import run, simulate
from nurbsmotion.machine import Axis, Machine, die_bonder, load_machine
from nurbsmotion.servo import ServoPlant, plant_step, zoh_matrices

from conftest import TIGHT


def reference_loop(gains, tau, Kc, Ke, Ts, feedback_deriv):
    """One axis's closed loop as a discrete state-space system, from the equations.

    State ``[w, theta, e_prev, errorI, r_prev, cmdD_prev]``, inputs ``[r, 1]`` (the
    command and the constant that carries the bias), outputs ``[theta, u]``, where at
    sample k (the law first, then the plant over Ts):

        e = r - theta;  errorI' = errorI + e*Ts;  cmdD = (r - r_prev)/Ts
        cmdDD = (cmdD - cmdD_prev)/Ts;  errorD = (e - e_prev)/Ts  or  cmdD - Ke*w
        u = bias + P*e + I*errorI' + D*errorD + FF0*r + FF1*cmdD + FF2*cmdDD
    """
    g = gains
    # the plant's exact ZOH, written independently of nurbsmotion.servo
    a = -1.0 / tau
    Ad = np.array([[math.exp(a * Ts), 0.0], [Ke * (math.exp(a * Ts) - 1.0) / a, 1.0]])
    Bd = Kc / tau * np.array([(math.exp(a * Ts) - 1.0) / a,
                              Ke * ((math.exp(a * Ts) - 1.0) / a - Ts) / a])
    # u = Ku @ x + Du @ [r, 1]
    Ku = np.zeros(6)
    Du = np.zeros(2)
    # e = r - theta
    Ku[1] += -g.Pgain - g.Igain * Ts
    Du[0] += g.Pgain + g.Igain * Ts
    Ku[3] += g.Igain
    Du[1] += g.bias
    Du[0] += g.FF0
    # cmdD = (r - r_prev)/Ts
    Du[0] += g.FF1 / Ts + g.FF2 / Ts**2
    Ku[4] += -g.FF1 / Ts - g.FF2 / Ts**2
    Ku[5] += -g.FF2 / Ts
    if feedback_deriv:       # errorD = cmdD - Ke*w
        Du[0] += g.Dgain / Ts
        Ku[4] += -g.Dgain / Ts
        Ku[0] += -g.Dgain * Ke
    else:                    # errorD = (r - theta - e_prev)/Ts
        Du[0] += g.Dgain / Ts
        Ku[1] += -g.Dgain / Ts
        Ku[2] += -g.Dgain / Ts
    A = np.zeros((6, 6))
    B = np.zeros((6, 2))
    A[0, :2], A[1, :2] = Ad[0], Ad[1]
    A[0] += Bd[0] * Ku
    A[1] += Bd[1] * Ku
    B[0] += Bd[0] * Du
    B[1] += Bd[1] * Du
    A[2, 1], B[2, 0] = -1.0, 1.0                       # e_prev' = r - theta
    A[3, 3], A[3, 1], B[3, 0] = 1.0, -Ts, Ts           # errorI' = errorI + e*Ts
    B[4, 0] = 1.0                                       # r_prev' = r
    A[5, 4], B[5, 0] = -1.0 / Ts, 1.0 / Ts              # cmdD_prev' = (r - r_prev)/Ts
    C = np.zeros((2, 6))
    C[0, 1] = 1.0
    C[1] = Ku
    D = np.zeros((2, 2))
    D[1] = Du
    return (A, B, C, D, Ts)


def nurbsmotion_loop(gains, tau, Kc, Ke, Ts, feedback_deriv, r, start):
    """The same loop through nurbsmotion's per-sample functions (as the kernel runs them)."""
    law = pid_law([gains], math.inf, Ts, feedback_deriv)
    st = pid_state(np.array([start]))
    Ad, Bd = zoh_matrices(tau, Kc, Ke, Ts)
    Ad, Bd = Ad[None], Bd[None]
    w, th = 0.0, start
    out = np.empty((len(r), 2))
    for k, rk in enumerate(r):
        u, e, ei, cd = pid_output(law, st, 0, rk, th, Ke * w)
        pid_commit(law, st, 0, rk, u, e, ei, cd)
        out[k] = th, u
        w, th = plant_step(Ad, Bd, 0, w, th, u)
    return out


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("feedback_deriv", [False, True])
def test_unsaturated_loop_matches_dlsim(seed, feedback_deriv):
    rng = np.random.default_rng(seed)
    while True:  # random gains until the reference loop is stable
        tau, Kc, Ke, Ts = (rng.uniform(0.05, 0.5), rng.uniform(500, 4000),
                           rng.uniform(500, 3000), float(rng.choice([1e-3, 5e-4, 2e-3])))
        kp, kd = 0.0136 * rng.uniform(0.5, 2), 0.03 * rng.uniform(0.5, 2)
        gains = PidGains(Pgain=kp, Igain=kp * rng.uniform(0, 5), Dgain=kd / Ke,
                         bias=rng.uniform(-0.2, 0.2), FF0=rng.uniform(0, 1e-4),
                         FF1=rng.uniform(0, 2) / (Kc * Ke),
                         FF2=rng.uniform(0, 2) * tau / (Kc * Ke))
        sys = reference_loop(gains, tau, Kc, Ke, Ts, feedback_deriv)
        if np.max(np.abs(np.linalg.eigvals(sys[0]))) < 0.999:
            break
    n = 400
    r = np.cumsum(rng.normal(0, 50, n)) + 1000.0
    start = 1000.0
    x0 = np.array([0.0, start, 0.0, 0.0, start, 0.0])
    _, y, _ = signal.dlsim(sys, np.column_stack([r, np.ones(n)]), x0=x0)
    ours = nurbsmotion_loop(gains, tau, Kc, Ke, Ts, feedback_deriv, r, start)
    for col in range(2):
        scale = np.max(np.abs(y[:, col]))
        np.testing.assert_allclose(ours[:, col], y[:, col], rtol=TIGHT, atol=TIGHT * scale)


@pytest.mark.parametrize("tau", [1e-5, 1e-3, 0.0123, 0.31, 100.0])
@pytest.mark.parametrize("Ts", [1e-4, 1e-3, 2.5e-3])
def test_closed_form_zoh_is_the_matrix_exponential(tau, Ts):
    """SPEC section 3: [Ad Bd] = expm([[A, b], [0, 0]]*Ts), here from scipy's expm."""
    from scipy.linalg import expm

    Kc, Ke = 2506.17, 1591.5494
    M = np.zeros((3, 3))
    M[0, 0], M[1, 0], M[0, 2] = -1.0 / tau, Ke, Kc / tau
    E = expm(M * Ts)
    Ad, Bd = zoh_matrices(tau, Kc, Ke, Ts)
    np.testing.assert_allclose(Ad, E[:2, :2], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(Bd, E[:2, 2], rtol=1e-13)


def test_loop_poles_match_the_state_space_eigenvalues():
    """The stability check's poles are those of the reference model's autonomous loop."""
    m = die_bonder()
    for feedback_deriv in (False, True):
        g = PidGains(Pgain=0.0136, Igain=0.05, Dgain=0.03 / 1591.5494, FF1=1e-7)
        A, *_ = reference_loop(g, 0.31, 2506.17, 1591.5494, 1e-3, feedback_deriv)
        ref = np.linalg.eigvals(A)
        Ad, Bd = zoh_matrices(0.31, 2506.17, 1591.5494, 1e-3)
        ours = loop_poles(g, Ad, Bd, 1e-3, 1591.5494, feedback_deriv)
        # the reference adds the command's own states (poles at 0) and, with feedback_deriv,
        # e_prev (a pole at 0): every pole of ours is one of its poles
        for p in ours:
            assert np.min(np.abs(ref - p)) < 1e-9
        assert np.max(np.abs(ref)) == pytest.approx(np.max(np.abs(ours)), rel=1e-12)
    assert m.loop_pole_radius < 1


def test_clamps_deadband_and_anti_windup_by_hand():
    """Ts = 0.1 s, Pgain 1, Igain 10, maxoutput 2, maxerror 3, deadband 0.5, maxerrorI 0.5,
    the feedback held at 0 and the command 4, 4, 4, -1 (worked by hand):

    k=0: e = min(4, 3) - 0.5 = 2.5; errorI = 0.25; out = 2.5 + 2.5 = 5.0 > 2: limit +1
    k=1: e = 2.5, e*limit > 0: errorI frozen at 0.25; out = 2.5 + 2.5 = 5.0 (limit +1)
    k=2: the same: errorI stays 0.25
    k=3: e = -1 + 0.5 = -0.5, e*limit < 0: errorI = 0.25 - 0.05 = 0.2;
         out = -0.5 + 2.0 = 1.5 (inside: limit 0)
    then command 10 twice from limit 0: errorI 0.2 + 0.25 = 0.45, then clamped at 0.5.
    """
    g = PidGains(Pgain=1.0, Igain=10.0, maxerror=3.0, deadband=0.5, maxerrorI=0.5)
    law = pid_law([g], 2.0, 0.1, False)
    st = pid_state(np.array([0.0]))
    got = []
    for cmd in (4.0, 4.0, 4.0, -1.0, 10.0, 10.0):
        out, e, ei, cd = pid_output(law, st, 0, cmd, 0.0, 0.0)
        pid_commit(law, st, 0, cmd, out, e, ei, cd)
        got.append((out, ei, st[0]["limit_state"]))
    expected = [(5.0, 0.25, 1.0), (5.0, 0.25, 1.0), (5.0, 0.25, 1.0), (1.5, 0.2, 0.0),
                (2.5 + 4.5, 0.45, 1.0), (2.5 + 4.5, 0.45, 1.0)]
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_derivative_clamps_by_hand():
    """Dgain 1, FF1 1, FF2 1, Ts 0.5; maxerrorD 1, maxcmdD 2, maxcmdDD 3; command 0 -> 5:
    errorD = (5 - 0)/0.5 = 10 -> 1; cmdD = 10 -> 2; cmdDD = (2 - 0)/0.5 = 4 -> 3."""
    g = PidGains(Dgain=1.0, FF1=1.0, FF2=1.0, maxerrorD=1.0, maxcmdD=2.0, maxcmdDD=3.0)
    law = pid_law([g], math.inf, 0.5, False)
    st = pid_state(np.array([0.0]))
    out, e, ei, cd = pid_output(law, st, 0, 5.0, 0.0, 0.0)
    assert (out, cd) == (1.0 + 2.0 + 3.0, 2.0)


def test_affine_form_and_the_speed_bound_of_eq_3_6():
    """Between the clamps the output is slope*command + offset; for PD+ that slope is the
    paper's Ksig/(Ke*Ts) (section 3.2), and the command at either bound drives exactly
    +-Umax."""
    rng = np.random.default_rng(2)
    for controller in ("pd+", "pd"):
        m = die_bonder(controller=controller)
        law = m.law()
        Ts, Ke = m.sample_period, m.Ke
        ff = 1.0 if controller == "pd+" else 0.0
        ksig = m.Kp * Ke * Ts + m.Kd + ff * (1 / m.Kc + m.tau / (m.Kc * Ts))
        for _ in range(20):
            st = pid_state(rng.normal(0, 1e3, 2))
            st["prev_error"] = rng.normal(0, 10, 2)
            st["cmd_d"] = rng.normal(0, 1e4, 2)
            fb = rng.normal(0, 1e3, 2)
            for j in range(2):
                slope, offset = pid_affine(law, st, j, fb[j], 0.0)
                assert slope * Ke[j] * Ts == pytest.approx(ksig[j], rel=1e-12)
                for c in rng.normal(0, 1e3, 3):
                    out = pid_output(law, st, j, c, fb[j], 0.0)[0]
                    assert out == pytest.approx(slope * c + offset, rel=1e-9, abs=1e-9)
                for umax in (10.0, -10.0):
                    c = (umax - offset) / slope
                    assert pid_output(law, st, j, c, fb[j], 0.0)[0] == pytest.approx(umax,
                                                                                      rel=1e-9)


def pid_preset_machine(m: Machine) -> Machine:
    axes = tuple(Axis(a.name, a.time_constant, a.electrical_gain, a.mechanical_gain, pid=g)
                 for a, g in zip(m.axes, m.pid_gains))
    return m.with_options(axes=axes, controller="pid")


@pytest.mark.parametrize("interpolator", ["paper", "taylor2"])
def test_pd_plus_and_its_pid_preset_give_the_same_trace(interpolator):
    m = die_bonder()
    pid = pid_preset_machine(m)
    pi = nm.make_die_bonder_pi()
    a, b = run(pi, m, 1e6, interpolator), run(pi, pid, 1e6, interpolator)
    assert len(a.t) == len(b.t)
    for name in ("position_command", "position", "drive"):
        x, y = getattr(a, name), getattr(b, name)
        np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-9 * np.max(np.abs(x)))


def test_a_pid_law_with_an_integrator_runs_every_interpolator():
    m = die_bonder()
    axes = tuple(Axis(a.name, a.time_constant, a.electrical_gain, a.mechanical_gain,
                      pid=PidGains(Pgain=g.Pgain, Igain=2 * g.Pgain, Dgain=g.Dgain,
                                   FF1=g.FF1, FF2=g.FF2, maxerrorI=50.0))
                 for a, g in zip(m.axes, m.pid_gains))
    pid = m.with_options(axes=axes, controller="pid")
    pi = nm.make_die_bonder_pi()
    for name in ("taylor2", "paper", "planned"):
        tr = run(pi, pid, 5e5, name)
        assert tr.u[tr.finished_index] == 1.0
        assert np.max(np.abs(tr.position[-1] - [60000.0, 0.0])) <= 1.0


PID_TOML = """name = "hal"
controller = "pid"
max_drive = 10
sample_period = 0.001
[[axes]]
name = "x"
time_constant = 0.31
electrical_gain = 2506.17
mechanical_gain = 1591.5494
[axes.pid]
Pgain = 0.0136
Dgain = 1.885e-05
FF1 = 2.507e-07
FF2 = 7.773e-08
{extra}
"""


def test_machine_file_with_linuxcnc_pid_names(tmp_path):
    f = tmp_path / "hal.toml"
    f.write_text(PID_TOML.format(extra="Igain = 0.01\nmaxerrorI = 100"))
    m = load_machine(f)
    assert m.controller == "pid"
    assert m.axes[0].pid == PidGains(Pgain=0.0136, Dgain=1.885e-05, FF1=2.507e-07,
                                     FF2=7.773e-08, Igain=0.01, maxerrorI=100.0)
    assert load_machine(f) == Machine.from_dict(m.to_dict())


@pytest.mark.parametrize("extra, message", [
    ("Kp = 1", r"axis 'x' pid: unknown key\(s\) \['Kp'\]"),
    ("Igain = -1", "pid Igain must be >= 0, got -1.0"),
    ("Pgain = nan", "pid Pgain must be finite, got nan"),
    ('bias = "0.1"', "pid bias must be a number, got '0.1'"),
    ("FF0 = true", "pid FF0 must be a number, got True"),
])
def test_bad_pid_tables_name_axis_key_and_value(tmp_path, extra, message):
    f = tmp_path / "bad.toml"
    text = PID_TOML.format(extra=extra).replace("Pgain = 0.0136\n", "") \
        if extra.startswith("Pgain") else PID_TOML.format(extra=extra)
    f.write_text(text)
    with pytest.raises(PathFileError, match=message):
        load_machine(f)


def test_an_unstable_machine_is_refused_with_its_poles():
    # 20 times the position gain puts the X loop's poles outside the unit circle
    x, y = die_bonder().axes
    axes = (Axis("x", 0.31, 2506.17, 1591.5494, 0.0136 * 20, 0.03), y)
    with pytest.raises(InvalidMachineError,
                       match=r"axis 'x': the closed loop is unstable at Ts = 0.001 s: "
                             r"poles .*largest \|p\| = 1\.[0-9]+, must be < 1"):
        Machine(axes, max_drive=10.0, sample_period=1e-3)
    # the same gains at a far slower sample rate: refused too
    with pytest.raises(InvalidMachineError, match="unstable at Ts = 1e\\+06 s"):
        die_bonder(sample_period=1e6)


def test_pid_controller_needs_pid_parameters():
    with pytest.raises(InvalidMachineError, match="needs the axis's pid parameters"):
        die_bonder(controller="pid")
    x = Axis("x", 0.31, 2506.17, 1591.5494, pid=PidGains(Pgain=0.0136))
    with pytest.raises(InvalidMachineError, match="pid parameters need controller = 'pid'"):
        Machine((x,), max_drive=10.0, sample_period=1e-3)


def test_true_speed_is_the_feedback_deriv_form_of_the_same_law():
    """The paper's PD+ with the true motor speed equals errorD = cmdD - Ke*w."""
    m = die_bonder(speed_measurement="true")
    assert np.all(m.law()["feedback_deriv"] == 1.0)
    tr = run(nm.make_circle(10_000.0), m, 5e4, "taylor2")
    Ts, Ke = m.sample_period, m.Ke
    thd = np.vstack([tr.position_command[:1], tr.position_command])
    wd = np.diff(thd, axis=0) / (Ke * Ts)
    ad = np.diff(np.vstack([np.zeros((1, 2)), wd]), axis=0) / Ts
    u = (m.Kp * (tr.position_command - tr.position) + m.Kd * (wd - tr.speed)
         + wd / m.Kc + m.tau * ad / m.Kc)
    np.testing.assert_allclose(tr.drive, u, rtol=1e-9, atol=1e-9 * m.max_drive)


def test_plant_value_object_and_mismatch_scales():
    m = die_bonder()
    p = ServoPlant.of_machine(m, time_constant_scale=[1.2, 0.8], electrical_gain_scale=0.9)
    np.testing.assert_allclose(p.time_constant, m.tau * [1.2, 0.8])
    np.testing.assert_allclose(p.electrical_gain, m.Kc * 0.9)
    with pytest.raises(AttributeError):
        p.max_drive = 3.0
    with pytest.raises(InvalidMachineError, match="time_constant must be finite and > 0"):
        ServoPlant.of_machine(m, time_constant_scale=-1.0)


def test_the_linuxcnc_pid_example_machine_runs():
    from pathlib import Path

    m = load_machine(Path(__file__).parents[1] / "examples" / "linuxcnc_pid.toml")
    assert m.controller == "pid" and m.axes[0].pid.Igain == 0.02
    tr = run(nm.make_die_bonder_pi(), m, 5e5, "planned")
    assert tr.success, tr.message


def test_planned_follows_its_plan_through_a_deadband_and_the_clamps():
    """A pid with a 0.5-pulse deadband, an integrator and its clamp (the die-bonder's PD+
    preset otherwise), the Pi at 1 m/s on the model's plant. The law is not affine in the
    setpoint once the deadband or a clamp acts; the affine form's setpoint gave another
    drive, the plant left the plan and the governor slowed it (on random machines up to
    24 um of contour error and 21 um past a stop corner). The setpoint is now solved for
    on the law itself: the run follows the plan (the model plant's response to the
    plan's drive) to 1e-3 pulse, where the affine form's setpoint left it by 28 pulses."""
    m = die_bonder()
    axes = tuple(Axis(a.name, a.time_constant, a.electrical_gain, a.mechanical_gain,
                      pid=PidGains(Pgain=g.Pgain, Igain=2 * g.Pgain, Dgain=g.Dgain,
                                   FF1=g.FF1, FF2=g.FF2, deadband=0.5, maxerrorI=50.0))
                 for a, g in zip(m.axes, m.pid_gains))
    pid = m.with_options(axes=axes, controller="pid")
    interp = make_interpolator("planned", nm.make_die_bonder_pi(), pid, 1e6)
    tr = simulate(interp, pid)
    plan = interp.plan
    n = plan.rest + 1
    assert np.max(np.abs(tr.position[:n] - plan.position[:n])) <= 1e-3
    assert tr.metrics().max_contour_error <= 0.1
    assert tr.metrics().corner_overshoot <= 0.05 and tr.metrics().end_overshoot <= 0.05
