"""The landing's law of ``planned`` on an axis whose model declares a mode (issue 33,
:mod:`nurbsmotion.interpolators.planned.mode_law`): its closed loop against a sampling by
scipy's solve_ivp, every pole radius < 1 with the true mode, tau and Kc off the model's
within the band it was designed for, the rigid landing untouched, and a run on the mode
that lands without a limit cycle and takes a load after the landing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from nurbsmotion.interpolators.planned.identify import LAW_ROWS
from nurbsmotion.interpolators.planned.mode_law import (MODE_LAW_ROWS, landing_loop,
                                                        mode_landing_law, sampled_axis)
from nurbsmotion.machine import Disturbance, die_bonder, die_bonder_real
from nurbsmotion.nurbs import make_line
from nurbsmotion.plant import continuous_model

POLE = 0.7  # planned's default tracking_pole


def _mode_model(frequency=90.0, **changes):
    m = die_bonder(**changes)
    return m.with_options(axes=tuple(
        dataclasses.replace(a, resonance_frequency=frequency, resonance_damping=0.02)
        for a in m.axes))


def _ivp_sampled(tau, Kc, Ke, Ts, delay, f, zeta, lam):
    """(Phi, g1, g0) of :func:`sampled_axis` by solve_ivp on the continuous model: the
    drive u[k-1] over the first ``delay`` of the sample, u[k] over the rest."""
    from scipy.integrate import solve_ivp

    A, B = continuous_model(tau, Kc, Ke, f, zeta, lam)
    nx = A.shape[0]

    def run(x0, u1, u0):
        x = np.asarray(x0, float)
        for h, u in ((delay * Ts, u1), ((1 - delay) * Ts, u0)):
            if h > 0:
                x = solve_ivp(lambda t, y: A @ y + B * u, (0, h), x, method="DOP853",
                              rtol=1e-12, atol=1e-12).y[:, -1]
        return x

    Phi = np.column_stack([run(np.eye(nx)[i], 0, 0) for i in range(nx)])
    return Phi, run(np.zeros(nx), 1, 0), run(np.zeros(nx), 0, 1)


def _online_drive(law, th, th_prev, u1, u2, z, end):
    """The landing's drive and error as :func:`online_step` computes them from its rows
    (step 3', without the band), written out independently of :func:`landing_loop`."""
    al, cl, g0w, g0th, g1w, g1th, ah, b0h, ch, b1h, kt, kw, ki = law
    w_last = ((th - th_prev) - g0th * u1 - g1th * u2) / cl
    w = al * w_last + g0w * u1 + g1w * u2
    e = end - (th + ch * w + b1h * u1)
    w = ah * w + b0h * u1
    return kt * e - kw * w + ki * z, e


@pytest.mark.filterwarnings("ignore::nurbsmotion.machine.UnstableModeWarning")
@pytest.mark.parametrize("which", ["90Hz", "real"])
def test_landing_loop_is_the_sampled_law(which):
    """One step of :func:`landing_loop` equals the plant sampled by solve_ivp under the
    law as the online step computes it, from a random state (to 1e-9 relative)."""
    model = _mode_model() if which == "90Hz" else die_bonder_real()
    law = mode_landing_law(model, POLE)
    assert law.shape == (MODE_LAW_ROWS, 2) and np.all(law[0] == 1.0)
    Ts, D = model.sample_period, model.delay / model.sample_period
    rng = np.random.default_rng(3)
    for j, ax in enumerate(model.axes):
        args = (ax.time_constant, ax.electrical_gain, ax.mechanical_gain, Ts, D,
                ax.resonance_frequency * 1.07, 0.02, 0.5)
        Phi, g1, g0 = _ivp_sampled(*args)
        np.testing.assert_allclose(np.column_stack(sampled_axis(*args)),
                                   np.column_stack([Phi, g1, g0]), rtol=1e-9, atol=1e-12)
        s = rng.normal(size=8) * [50, 30, 50, 30, 3, 0.5, 0.5, 20]
        x, th_prev, u1, u2, z = s[:4], s[4], s[5], s[6], s[7]
        u, e = _online_drive(law[1:LAW_ROWS + 1, j], x[1], th_prev, u1, u2, z, 0.0)
        nxt = np.concatenate([Phi @ x + g1 * u1 + g0 * u, [x[1], u, u1, z + e]])
        T = landing_loop(law[1:LAW_ROWS + 1, j], sampled_axis(*args))
        np.testing.assert_allclose(T @ s, nxt, rtol=1e-9, atol=1e-9 * np.max(np.abs(nxt)))


@pytest.mark.filterwarnings("ignore::nurbsmotion.machine.UnstableModeWarning")
@pytest.mark.parametrize("which", ["90Hz", "real"])
def test_landing_law_is_stable_within_the_band(which):
    """Every pole radius of the landing's loop < 1 with the true tau and Kc x0.9 to x1.1
    of the model's and the true mode from 1/1.1 to 1/0.9 of the model's (within 10 % of
    the true one), on a grid finer than the design's corners, the plant sampled by
    solve_ivp, for the landing and for the tracking (the same law without the integral);
    and on the rigid placement's landing (the landing before) with the same
    modes, some radius reaches 0.97 or beyond."""
    from nurbsmotion.interpolators.planned.identify import LAW_ROWS, _landing_law

    model = _mode_model() if which == "90Hz" else die_bonder_real()
    law = mode_landing_law(model, POLE)
    Ts, D = model.sample_period, model.delay / model.sample_period
    worst, worst_rigid, worst_track = 0.0, 0.0, 0.0
    for j, ax in enumerate(model.axes):
        a = np.exp(-Ts / ax.time_constant)
        rigid = np.zeros(LAW_ROWS)
        _landing_law(a, ax.electrical_gain * (1 - a),
                     ax.mechanical_gain * ax.time_constant * (1 - a),
                     ax.mechanical_gain * ax.electrical_gain * (Ts - ax.time_constant * (1 - a)),
                     D, POLE, rigid)
        for ft in (0.9, 1.0, 1.1):
            for fk in (0.9, 1.05, 1.1):
                for ff in np.linspace(1 / 1.1, 1 / 0.9, 5):
                    axis = _ivp_sampled(ax.time_constant * ft, ax.electrical_gain * fk,
                                        ax.mechanical_gain, Ts, D,
                                        ax.resonance_frequency * ff, 0.02, 0.5)
                    r = np.max(np.abs(np.linalg.eigvals(landing_loop(law[1:LAW_ROWS + 1, j],
                                                                     axis))))
                    worst = max(worst, r)
                    track = law[1:LAW_ROWS + 1, j].copy()
                    track[10:13] = law[LAW_ROWS + 1, j], law[LAW_ROWS + 2, j], 0.0
                    worst_track = max(worst_track, np.max(np.abs(np.linalg.eigvals(
                        landing_loop(track, axis, integral=False)))))
                    worst_rigid = max(worst_rigid, np.max(np.abs(np.linalg.eigvals(
                        landing_loop(rigid, axis)))))
    assert worst < 0.95, worst
    assert worst_track < 0.95, worst_track
    assert worst_rigid > 0.97, worst_rigid


def test_no_mode_no_mode_law():
    """A model without a mode gets no mode law (the rigid landing, unchanged)."""
    for m in (die_bonder(), die_bonder(delay=0.5e-3, encoder="counts")):
        assert np.all(mode_landing_law(m, POLE) == 0.0)


LINE = ([0.0, 0.0], [2000.0, 1000.0])


@pytest.mark.filterwarnings("ignore::nurbsmotion.machine.UnstableModeWarning")
@pytest.mark.parametrize("load", [False, True])
def test_a_known_mode_lands_without_a_limit_cycle(load):
    """The true axes with a 100 Hz mode (damping 0.02), the model's at 90 Hz: the run
    settles within 2 pulses, with no limit cycle and no chatter at rest (the landing
    with the rigid placement limit-cycled at ~10 V RMS), also with a 0.5 V load arriving
    0.1 s after the start (the integral takes it)."""
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate
    from nurbsmotion.servo import ServoPlant

    model = _mode_model()
    true = _mode_model(100.0)
    if load:
        true = true.with_options(axes=tuple(
            dataclasses.replace(a, disturbance=(Disturbance(0.1, 0.5),))
            for a in true.axes))
    line = make_line(*LINE)
    interp = make_interpolator("planned", line, model, 2e5)
    plant = ServoPlant(true.tau, true.Kc, true.Ke, model.max_drive, model.sample_period,
                       np.array(LINE[0]), true.effects())
    tr = simulate(interp, model, plant=plant, hold=0.3, settle_window=2.0)
    rest = tr.at_rest(window=300)
    assert tr.metrics().settled
    assert not any(rest.limit_cycle.values())
    assert max(rest.drive_chatter_rms.values()) <= 0.05
    assert np.max(np.abs(tr.position[-300:] - np.array(LINE[1]))) <= 2.0


@pytest.mark.parametrize("case", [314, 448])
def test_a_placement_asking_for_a_negative_gain_is_designed_not_a_crash(case):
    """Regression (issue 33's random real machines, 7 of 1,000): where the rigid placement
    of a model with a declared mode asks for a negative gain, its logarithm was NaN and the
    design crashed in NumPy's eigvals ("Array must not contain infs or NaNs"). The law is
    designed with each gain's sign kept: finite, and stable on every corner of the
    model's uncertainty (the design's own check raises InfeasibleError otherwise)."""
    from nurbsmotion.interpolators.planned import DEFAULT_TRACKING_POLE
    from nurbsmotion.random_machines import random_machine, random_model

    true = random_machine([33, case], int(np.random.default_rng([33, case]).integers(2, 4)),
                          real=True)
    model = random_model(true, [33, case, 1])
    law = mode_landing_law(model, DEFAULT_TRACKING_POLE)
    assert law.shape == (MODE_LAW_ROWS, model.n_axes)
    assert np.isfinite(law).all() and law[0].any()
