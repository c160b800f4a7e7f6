"""A known mode (issue 33): the die-bonder-real preset's loop with its mode, the warning
for a loop its mode destabilises, and the input shaper of ``planned``, against
independent references.

- the loop's poles with the mode and the half-sample delay: the physical two-mass
  equations sampled by ``scipy.signal.cont2discrete`` over the two halves of a sample,
  the PD+ law by hand (not :func:`nurbsmotion.plant.linear_loop_poles`);
- the shaper: the closed-form ZV / ZVD of Singer & Seering (amplitudes, times, and their
  residual vibration off the mode, ``|cos(pi*r/2)|`` and ``cos(pi*r/2)^2`` undamped);
- the shaped plan: the rigid model's response to its drive by ``cont2discrete`` /
  ``dlsim``, and its drive within the plan's (a convex combination);
- the model's twist under a held drive against ``solve_ivp``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import cont2discrete, dlsim

from nurbsmotion.machine import (UnstableModeWarning, die_bonder, die_bonder_real,
                                 load_machine, mode_safe_gains)
from nurbsmotion.interpolators.planned.shaper import (encoder_offset, plan_shaper,
                                                      residual_vibration, shape_plan,
                                                      shaper_taps)

Ts = 1e-3


def _physical(tau, Kc, Ke, f, zeta, lam):
    """The two-mass axis from its physical parts (docs/model.md#real-machine): motor and
    load inertias (1 - lam)*tau and lam*tau, viscous shares 1 - lam and lam, a spring and
    a damper on the twist; state [w_m, th_m, w_l, th_l] (rad/s, pulse), input the drive."""
    wn = 2 * math.pi * f
    mu = lam * (1 - lam) * tau
    k, c = wn * wn * mu, mu * (2 * zeta * wn - 1 / tau)
    Jm, Jl = (1 - lam) * tau, lam * tau

    A = np.zeros((4, 4))
    A[0] = np.array([-((1 - lam) + c), -k / Ke, c, k / Ke]) / Jm
    A[2] = np.array([c, k / Ke, -(lam + c), -k / Ke]) / Jl
    A[1, 0] = A[3, 2] = Ke
    B = np.array([[Kc / Jm], [0.0], [0.0], [0.0]])
    return A, B


def _mode_radius(axis, Kp, Kd, delay_half_sample=True):
    """Largest pole radius of the PD+ loop on the motor's reading, encoder differencing,
    the drive half a sample late: x[k+1] = P x + P G u[k-1] + G u[k] with (P, G) over
    Ts/2, u[k] = -Kp*th[k] - Kd/Ke*(th[k] - th[k-1])/Ts."""
    A, B = _physical(axis.time_constant, axis.electrical_gain, axis.mechanical_gain,
                     axis.resonance_frequency, axis.resonance_damping, axis.load_fraction)
    P, G, *_ = cont2discrete((A, B, np.eye(4), np.zeros((4, 1))), Ts / 2, method="zoh")
    G = G[:, 0]
    Ke = axis.mechanical_gain
    law = np.zeros(6)  # z = [x (4), th[k-1], u[k-1]]
    law[1] = -Kp - Kd / (Ke * Ts)
    law[4] = Kd / (Ke * Ts)
    T = np.zeros((6, 6))
    T[:4, :4] = P @ P
    T[:4] += np.outer(G, law)
    T[:4, 5] += P @ G
    T[4, 1] = 1.0
    T[5] = law
    return float(np.max(np.abs(np.linalg.eigvals(T))))


def test_preset_loop_with_its_mode_is_stable_with_margin():
    real = die_bonder_real()
    assert real.delay == Ts / 2
    own = [max(abs(p)) for p in real.mode_loop_poles()]
    for axis, r in zip(real.axes, own):
        ref = _mode_radius(axis, axis.position_gain, axis.speed_gain)
        assert ref == pytest.approx(r, rel=1e-9)
        assert ref < 0.95
        # the same loop at the paper's gains: unstable (issue 33: 1.09 x, 1.28 y)
    paper = die_bonder()
    for axis, a0, want in zip(real.axes, paper.axes, (1.0924, 1.2773)):
        assert _mode_radius(axis, a0.position_gain, a0.speed_gain) == pytest.approx(
            want, abs=1e-4)


def test_preset_gains_place_the_rigid_loop_at_a_quarter_of_the_mode():
    for axis in die_bonder_real().axes:
        Kp, Kd = axis.position_gain, axis.speed_gain
        tau, Kc, Ke = axis.time_constant, axis.electrical_gain, axis.mechanical_gain
        s = np.roots([tau, 1 + Kc * Kd, Kc * Ke * Kp])
        assert abs(s[0]) == pytest.approx(2 * math.pi * axis.resonance_frequency / 4)
        assert -s[0].real / abs(s[0]) == pytest.approx(1 / math.sqrt(2))
        assert (Kp, Kd) == mode_safe_gains(tau, Kc, Ke, axis.resonance_frequency)
    assert load_machine("examples/die_bonder_real.toml") == die_bonder_real()


def test_a_loop_its_mode_destabilises_is_warned_about_by_axis_and_radius():
    from dataclasses import replace

    base = die_bonder()
    with pytest.warns(UnstableModeWarning) as caught:
        base.with_options(axes=tuple(replace(a, resonance_frequency=100.0,
                                             resonance_damping=0.02) for a in base.axes))
    text = " ".join(str(w.message) for w in caught)
    assert "axis 'y'" in text and "100 Hz" in text and "pole radius" in text
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        die_bonder_real()
        die_bonder()


@pytest.mark.parametrize("zeta", [0.0, 0.02, 0.1])
@pytest.mark.parametrize("half", [3, 5])
def test_shaper_is_the_closed_form_where_half_a_period_is_whole_samples(zeta, half):
    wd = math.pi / (half * Ts)
    f = wd / math.sqrt(1 - zeta ** 2) / (2 * math.pi)
    K = math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))
    zv = shaper_taps(f, zeta, Ts, "zv")
    want = np.zeros(half + 1)
    want[[0, half]] = np.array([1, K]) / (1 + K)
    np.testing.assert_allclose(zv, want, atol=1e-9)
    zvd = shaper_taps(f, zeta, Ts)
    want = np.zeros(2 * half + 1)
    want[[0, half, 2 * half]] = np.array([1, 2 * K, K * K]) / (1 + K) ** 2
    np.testing.assert_allclose(zvd, want, atol=1e-9)
    # residual vibration off the mode: Singer & Seering's sum over the impulses of the
    # continuous mode at the true frequency (the same damping)
    for r in (0.8, 0.9, 1.0, 1.1, 1.2):
        w = 2 * math.pi * f * r
        s = complex(zeta * w, w * math.sqrt(1 - zeta ** 2))
        for h in (zv, zvd):
            t = np.flatnonzero(h) * Ts
            ref = abs(np.sum(h[h > 0] * np.exp(s * t)))
            assert residual_vibration(h, f * r, zeta, Ts) == pytest.approx(ref, abs=1e-12)
        if zeta == 0.0:
            assert residual_vibration(zv, f * r, 0.0, Ts) == pytest.approx(
                abs(math.cos(math.pi * r / 2)), abs=1e-12)
            assert residual_vibration(zvd, f * r, 0.0, Ts) == pytest.approx(
                math.cos(math.pi * r / 2) ** 2, abs=1e-12)


def test_zvd_at_a_mode_off_by_a_tenth():
    """The sampled ZVD at 90 Hz (half a period 5.6 samples): non-negative, sum 1, zero at
    its mode, and at +-10 % about the continuous ZVD's cos(pi*r/2)^2 (2.5 %)."""
    h = shaper_taps(90.0, 0.02, Ts)
    assert np.all(h >= 0) and h.sum() == pytest.approx(1.0, abs=1e-15)
    assert residual_vibration(h, 90.0, 0.02, Ts) < 1e-9
    for r in (0.9, 1.1):
        assert residual_vibration(h, 90.0 * r, 0.02, Ts) < 0.035
    assert residual_vibration(shaper_taps(90.0, 0.02, Ts, "zv"), 99.0, 0.02, Ts) > 0.1


def test_no_mode_no_shaper_the_plan_untouched():
    from nurbsmotion.interpolators.planned.plan import plan_motion
    from nurbsmotion.loop import to_pulses
    import nurbsmotion as nm

    m = die_bonder()
    assert plan_shaper(m) is None and encoder_offset(np.zeros((3, 2)), m) is None
    path = to_pulses(nm.builtin_path("die-bonder-pi"), m)
    p = plan_motion(path, m, 1e6)
    assert shape_plan(p, m, path) is p


def test_shaped_plan_is_the_rigid_response_of_its_drive_within_the_limit():
    from nurbsmotion.interpolators.planned.plan import plan_motion
    from nurbsmotion.loop import to_pulses
    from nurbsmotion.metrics import contour_error
    import nurbsmotion as nm

    real = die_bonder_real()
    path = to_pulses(nm.builtin_path("die-bonder-pi"), real)
    p = plan_motion(path, real, 5e5)
    s = shape_plan(p, real, path)
    h = plan_shaper(real)
    assert s is not p and s.arrival == p.arrival + (len(h) - 1) * (p.stop_times.size + 1)
    # a convex combination: within the plan's largest drive, so within Umax
    assert np.all(np.max(np.abs(s.drive), axis=0) <= np.max(np.abs(p.drive), axis=0)
                  * (1 + 1e-6))
    assert np.max(np.abs(s.drive)) <= real.max_drive
    for j, a in enumerate(real.axes):
        A = np.array([[-1 / a.time_constant, 0.0], [a.mechanical_gain, 0.0]])
        B = np.array([[a.electrical_gain / a.time_constant], [0.0]])
        sysd = cont2discrete((A, B, np.eye(2), np.zeros((2, 1))), Ts, method="zoh")
        _, out, _ = dlsim(sysd, s.drive[:, j], x0=[0.0, s.position[0, j]])
        np.testing.assert_allclose(out[:-1, 1], s.position[:-1, j], atol=1e-6 * 6e4)
    # each piece shaped on its own: a shaped position is a convex combination of the
    # piece's positions within the shaper's length T, so it is within the sagitta of the
    # path over the distance covered in T, (v*T)^2*kappa/8, of the path
    u = np.linspace(0, 1, 20001)
    d1, d2 = path(u, 1), path(u, 2)
    kappa = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(
        np.linalg.norm(d1, axis=1), 1e-300) ** 3
    reach = np.max(np.linalg.norm(np.diff(p.position, axis=0), axis=1)) * (len(h) - 1)
    sagitta = reach ** 2 * float(np.max(kappa)) / 8
    assert 1.0 < float(np.max(contour_error(path, s.position))) < sagitta
    # the model's mode (100 Hz, known) is not excited: no twist left at rest
    twist = encoder_offset(s.drive, real)
    assert np.max(np.abs(twist[-1])) < 1e-3 * np.max(np.abs(twist))


def test_encoder_offset_matches_solve_ivp():
    real = die_bonder_real()
    rng = np.random.default_rng(3)
    u = rng.uniform(-3, 3, size=(40, 2))
    got = encoder_offset(u, real)
    for j, a in enumerate(real.axes):
        wn = 2 * math.pi * a.resonance_frequency
        g = a.mechanical_gain * a.electrical_gain / ((1 - a.load_fraction) * a.time_constant)
        x = np.zeros(2)
        ref = [0.0]
        for k in range(len(u) - 1):
            v = u[k, j]
            sol = solve_ivp(lambda t, y: [y[1], -wn * wn * y[0]
                                          - 2 * a.resonance_damping * wn * y[1] + g * v],
                            (0, Ts), x, rtol=1e-11, atol=1e-9)
            x = sol.y[:, -1]
            ref.append(x[0])
        np.testing.assert_allclose(got[:, j], a.load_fraction * np.array(ref), atol=1e-6,
                                   rtol=1e-7)
