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


def _observer_drive(law, m_w, m_th, th, w_hat, th_hat, u1, u2, z, end):
    """The landing's drive, error and observer as :func:`online_step` computes them on a
    reading not exact (step 3' with ``rest_observer``, without the band), written out
    independently of :func:`observer_landing_loop`."""
    al, cl, g0w, g0th, g1w, g1th, ah, b0h, ch, b1h, kt, kw, ki = law
    th_hat = th_hat + cl * w_hat + g0th * u1 + g1th * u2
    w_hat = al * w_hat + g0w * u1 + g1w * u2
    innovation = th - th_hat
    w_hat += m_w * innovation
    th_hat += m_th * innovation
    e = end - (th + ch * w_hat + b1h * u1)
    w = ah * w_hat + b0h * u1
    return kt * e - kw * w + ki * z, e, w_hat, th_hat


def _case_model(case):
    from nurbsmotion.random_machines import random_machine, random_model

    true = random_machine([33, case], int(np.random.default_rng([33, case]).integers(2, 4)),
                          real=True)
    return random_model(true, [33, case, 1])


def _observed_case(case):
    """Item 4's ``case`` model, its reading's landing band [pulse] and the observers
    :func:`mode_rest_observer` gives its axes at the tracking pole ``POLE``."""
    from nurbsmotion.interpolators.planned.identify import reading_knowledge
    from nurbsmotion.interpolators.planned.inverse import axis_zoh
    from nurbsmotion.interpolators.planned.mode_law import mode_rest_observer

    model = _case_model(case)
    band = reading_knowledge(model, *axis_zoh(model))["landing_band"]
    return model, band, mode_rest_observer(model, POLE, band)


@pytest.mark.filterwarnings("ignore::nurbsmotion.machine.UnstableModeWarning")
def test_observer_landing_loop_is_the_sampled_law():
    """One step of :func:`observer_landing_loop` equals the plant sampled by solve_ivp
    under the landing's law with its speed observer as the online step computes it, from
    a random state (to 1e-9 relative); with the observer's poles at 0 (it then reads the
    speed from the last increment) its poles are :func:`landing_loop`'s."""
    from nurbsmotion.interpolators.planned.mode_law import observer_landing_loop
    from nurbsmotion.interpolators.planned.rest_observer import observer_gains

    model = die_bonder_real()
    law = mode_landing_law(model, POLE)
    Ts, D = model.sample_period, model.delay / model.sample_period
    rng = np.random.default_rng(5)
    for j, ax in enumerate(model.axes):
        rows = law[1:LAW_ROWS + 1, j]
        args = (ax.time_constant, ax.electrical_gain, ax.mechanical_gain, Ts, D,
                ax.resonance_frequency * 0.93, 0.02, 0.5)
        Phi, g1, g0 = _ivp_sampled(*args)
        for pole in (0.7, 0.35):
            m_w, m_th = observer_gains(rows[0], rows[1], pole)
            s = rng.normal(size=9) * [50, 30, 50, 30, 0.5, 0.5, 20, 40, 30]
            x, u1, u2, z, w_hat, th_hat = s[:4], s[4], s[5], s[6], s[7], s[8]
            u, e, w_new, th_new = _observer_drive(rows, m_w, m_th, x[1], w_hat, th_hat, u1,
                                                  u2, z, 0.0)
            nxt = np.concatenate([Phi @ x + g1 * u1 + g0 * u, [u, u1, z + e, w_new, th_new]])
            T = observer_landing_loop(rows, (Phi, g1, g0), pole)
            np.testing.assert_allclose(T @ s, nxt, rtol=1e-9,
                                       atol=1e-9 * np.max(np.abs(nxt)))
        deadbeat = np.abs(np.linalg.eigvals(observer_landing_loop(rows, (Phi, g1, g0), 0.0)))
        increment = np.abs(np.linalg.eigvals(landing_loop(rows, (Phi, g1, g0))))
        assert abs(np.max(deadbeat) - np.max(increment)) < 1e-9


@pytest.mark.filterwarnings("ignore::nurbsmotion.machine.UnstableModeWarning")
def test_a_fast_moded_axis_on_counts_lands_through_an_observer():
    """Regression (issue 33's random real machines, case 12: Ts 0.1 ms, 1 count and 0.47
    counts of noise, a 199 Hz mode the model puts at 181 Hz): the law designed with the
    mode took its speed from the last increment and answered one count with 4.5 V, and
    its drive swung between +-8.4 V at rest. Now its landing's speed comes from an
    observer designed into the loop: stable (every pole radius < 1) with tau, Kc and the
    mode off the model's as designed, on a grid finer than the design's corners, with the
    reading's gain from 1/1.1 to 4/pi*1.1 (a quantiser's describing function: no limit
    cycle through the counts), and a count moves its drive by under half as much (0.43 x);
    die-bonder-real (Ts 1 ms), where every observer slows the landing beyond its law
    without one, keeps that law (no observer)."""
    from nurbsmotion.interpolators.planned.identify import reading_knowledge
    from nurbsmotion.interpolators.planned.inverse import axis_zoh
    from nurbsmotion.interpolators.planned.mode_law import (mode_rest_observer,
                                                            observer_landing_loop)
    from nurbsmotion.interpolators.planned.rest_observer import QUANTISER_GAIN

    model, band, observer = _observed_case(12)
    assert band > 0.0
    j = 1
    assert model.axes[0].resonance_frequency == 0.0 and observer[0, 0] == 0.0
    assert observer[0, j] == 1.0 and 0.0 < observer[1, j] <= POLE
    law = mode_landing_law(model, POLE, band)[1:LAW_ROWS + 1, j]
    plain = mode_landing_law(model, POLE)[1:LAW_ROWS + 1, j]
    ax = model.axes[j]
    Ts, D = model.sample_period, model.delay / model.sample_period
    worst = 0.0
    for ft in (0.9, 1.0, 1.1):
        for fk in (0.9, 1.05, 1.1):
            for ff in np.linspace(1 / 1.1, 1 / 0.9, 4):
                axis = sampled_axis(ax.time_constant * ft, ax.electrical_gain * fk,
                                    ax.mechanical_gain, Ts, D, ax.resonance_frequency * ff,
                                    ax.resonance_damping, ax.load_fraction)
                for gain in (1 / 1.1, 1.0, QUANTISER_GAIN, QUANTISER_GAIN * 1.1):
                    T = observer_landing_loop(law, axis, observer[1, j], ax.encoder_on, gain)
                    worst = max(worst, np.max(np.abs(np.linalg.eigvals(T))))
    pos = 3 if ax.encoder_on == "load" else 1
    # the drive's weight on this sample's reading [V/pulse]: with and without the observer
    axis = sampled_axis(ax.time_constant, ax.electrical_gain, ax.mechanical_gain, Ts, D,
                        ax.resonance_frequency, ax.resonance_damping, ax.load_fraction)
    kicks = (observer_landing_loop(law, axis, observer[1, j], ax.encoder_on)[4 + 0, pos],
             landing_loop(plain, axis, ax.encoder_on)[4 + 1, pos])
    assert worst < 1.0, worst
    assert abs(kicks[0]) < 0.5 * abs(kicks[1]), kicks
    real = die_bonder_real()
    band = reading_knowledge(real, *axis_zoh(real))["landing_band"]
    assert band > 0.0
    assert np.all(mode_rest_observer(real, POLE, band) == 0.0)
    np.testing.assert_array_equal(mode_landing_law(real, POLE, band),
                                  mode_landing_law(real, POLE))


def _share_radius(rows, axis, observer_pole, encoder_on, share):
    """The observed landing's largest pole radius with ``share`` of the drive reaching the
    plant (its drive weights scaled; the law and its observer still predict the whole),
    its integral held (k_i 0, its state dropped)."""
    from nurbsmotion.interpolators.planned.mode_law import observer_landing_loop

    Phi, g1, g0 = axis
    held = np.array(rows, dtype=float)
    held[12] = 0.0
    T = observer_landing_loop(held, (Phi, share * g1, share * g0), observer_pole, encoder_on)
    iz = Phi.shape[0] + 2
    T = np.delete(np.delete(T, iz, axis=0), iz, axis=1)
    return float(np.max(np.abs(np.linalg.eigvals(T))))


@pytest.mark.filterwarnings("ignore::nurbsmotion.machine.UnstableModeWarning")
def test_an_observer_that_friction_destabilises_is_not_taken():
    """Regression (issue 33's random real machines, case 183: Ts 2 ms, a 46 Hz mode on z
    with 0.47 V of Coulomb friction and 0.72 V of stiction the model does not know): the
    landing's observer at 0.7 was taken on z (its loop stable on every corner with the
    whole drive and at the reading's gains) and its drive alternated +-0.77 V every sample
    at rest. With a share of the drive reaching the plant, as friction passes (the
    observer still predicting the whole), that loop has a pole beyond -1: at 10 % of the
    drive, its integral held, the plant sampled by solve_ivp at the model's own axis. Now
    the design asks stability at every share of :data:`DRIVE_SHARES` too (the integral
    held: its slow conditional instability at small shares is the law's own), and z keeps
    the law without an observer; an observer taken (case 12's y) is stable from 0.5 % to
    100 % of the drive, finer than the design's shares, on solve_ivp's plant."""
    from nurbsmotion.interpolators.planned.mode_law import _landing_design

    model, band, observer = _observed_case(183)
    Ts, D = model.sample_period, model.delay / model.sample_period
    j = 2
    ax = model.axes[j]
    assert ax.resonance_frequency > 0.0 and observer[0, j] == 0.0
    sampled = (ax.time_constant, ax.electrical_gain, ax.mechanical_gain, Ts, D,
               ax.resonance_frequency, ax.resonance_damping, ax.load_fraction)
    axis = _ivp_sampled(*sampled)
    rows, radius = _landing_design(*sampled, ax.encoder_on, POLE, POLE)
    assert radius < 1.0 and _share_radius(rows, axis, POLE, ax.encoder_on, 1.0) < 1.0
    assert _share_radius(rows, axis, POLE, ax.encoder_on, 0.1) > 1.05
    # an observer taken (case 12's y, at 0.35) is stable from 0.5 % to 100 % of the drive
    model, band, observer = _observed_case(12)
    Ts, D = model.sample_period, model.delay / model.sample_period
    k = 1
    a = model.axes[k]
    assert a.resonance_frequency > 0.0 and observer[0, k] == 1.0
    law = mode_landing_law(model, POLE, band)[1:LAW_ROWS + 1, k]
    for ft, fk, ff in ((1.0, 1.0, 1.0), (0.9, 1.1, 1 / 1.1), (1.1, 0.9, 1 / 0.9)):
        axis = _ivp_sampled(a.time_constant * ft, a.electrical_gain * fk, a.mechanical_gain,
                            Ts, D, a.resonance_frequency * ff, a.resonance_damping,
                            a.load_fraction)
        for share in np.geomspace(0.005, 1.0, 40):
            assert _share_radius(law, axis, observer[1, k], a.encoder_on, share) < 1.0


def _observed_tracking_drive(law, plant, gains, y, th_prev, u1, u2, w_hat, th_hat, d):
    """The tracking's drive with the disturbance observer as :func:`online_step` computes
    it on an axis with a mode about the plan (steps 1a' and 3; no dead zone), written out
    independently of :func:`tracking_observer_loop`: the observer's update, then the
    tracking's speed from the last increment with the estimate in the drives, its
    prediction over the delay, and the estimate fed forward."""
    al, cl, g0w, g0th, g1w, g1th, ah, b0h, ch, b1h = law[:10]
    kt, kw = law[10], law[11]   # the tracking's gains
    a, b0, c, b1 = plant
    l_w, l_th, l_d = gains
    th_p = th_hat + c * w_hat + g0th * u1 + g1th * u2 + b1 * d
    w_p = a * w_hat + g0w * u1 + g1w * u2 + b0 * d
    nu = y - th_p
    w_hat, th_hat, d = w_p + l_w * nu, th_p + l_th * nu, d + l_d * nu
    v1, v2 = u1 + d, u2 + d
    w = al * ((y - th_prev) - g0th * v1 - g1th * v2) / cl + g0w * v1 + g1w * v2
    e_th = -(y + ch * w + b1h * v1)
    e_w = -(ah * w + b0h * v1)
    return kt * e_th + kw * e_w - d, w_hat, th_hat, d


@pytest.mark.filterwarnings("ignore::nurbsmotion.machine.UnstableModeWarning")
def test_tracking_observer_loop_is_the_sampled_step_and_stable():
    """The tracking's disturbance observer designed with the mode
    (:func:`mode_disturbance_observer`, die-bonder-real): one step of
    :func:`tracking_observer_loop` equals the plant sampled by solve_ivp under the drive
    written out from the step's equations (to 1e-9 relative), its gains place the
    observer's three poles at the designed pole, and every pole radius of the loop < 1 on
    a grid finer than the design's corners (tau, Kc x0.9-1.1, the mode 1/1.1-1/0.9 of the
    model's), the plant sampled by solve_ivp; a constant drive the model does not know is
    then removed: the loop's steady deviation under it is 0."""
    from nurbsmotion.interpolators.planned.disturbance import observer_gains
    from nurbsmotion.interpolators.planned.mode_law import (DOB_ROW, _rigid_law,
                                                            mode_disturbance_observer,
                                                            tracking_observer_loop)

    model = die_bonder_real()
    law = mode_landing_law(model, POLE)
    designs = mode_disturbance_observer(model, POLE)
    Ts, D = model.sample_period, model.delay / model.sample_period
    rng = np.random.default_rng(5)
    worst = 0.0
    for j, ax in enumerate(model.axes):
        rho, gains, _ = designs[j]
        assert law[DOB_ROW, j] == 1.0
        np.testing.assert_allclose(law[DOB_ROW + 1:DOB_ROW + 4, j], gains, rtol=1e-12)
        plant, _ = _rigid_law(ax.time_constant, ax.electrical_gain, ax.mechanical_gain, Ts,
                              D, POLE)
        a, b0, c, b1 = plant
        F = np.array([[a, 0.0, b0], [c, 1.0, b1], [0.0, 0.0, 1.0]])
        L = observer_gains(a, b0, c, b1, rho)[:, 0]
        poles = np.linalg.eigvals((np.eye(3) - np.outer(L, [0.0, 1.0, 0.0])) @ F)
        np.testing.assert_allclose(poles, rho, atol=2e-4)
        track = law[1:LAW_ROWS + 1, j].copy()
        track[10:12] = law[LAW_ROWS + 1, j], law[LAW_ROWS + 2, j]
        for ft in (0.9, 1.0, 1.1):
            for fk in (0.9, 1.05, 1.1):
                for ff in np.linspace(1 / 1.1, 1 / 0.9, 4):
                    args = (ax.time_constant * ft, ax.electrical_gain * fk,
                            ax.mechanical_gain, Ts, D, ax.resonance_frequency * ff, 0.02, 0.5)
                    Phi, g1, g0 = _ivp_sampled(*args)
                    T = tracking_observer_loop(track, plant, gains, (Phi, g1, g0))
                    worst = max(worst, np.max(np.abs(np.linalg.eigvals(T))))
        # one step against the step's equations written out, the plant by solve_ivp
        s = rng.normal(size=10) * [50, 30, 50, 30, 30, 0.5, 0.5, 40, 30, 0.3]
        x, th_prev, u1, u2, w_hat, th_hat, d = s[:4], s[4], s[5], s[6], s[7], s[8], s[9]
        u, w_n, th_n, d_n = _observed_tracking_drive(track, plant, gains, x[1], th_prev,
                                                     u1, u2, w_hat, th_hat, d)
        nxt = np.concatenate([Phi @ x + g1 * u1 + g0 * u, [x[1], u, u1, w_n, th_n, d_n]])
        T = tracking_observer_loop(track, plant, gains, (Phi, g1, g0))
        np.testing.assert_allclose(T @ s, nxt, rtol=1e-9, atol=1e-9 * np.max(np.abs(nxt)))
        # a constant unknown drive f on the plant: the steady state of the loop
        # x = T x + [g0 + g1; 0...]*f has the plant's reading at 0 (the tracking's
        # target) and the estimate at f
        n = T.shape[0]
        forcing = np.zeros(n)
        forcing[:4] = (g0 + g1) * 0.3
        steady = np.linalg.solve(np.eye(n) - T, forcing)
        assert abs(steady[1]) < 1e-9 * 0.3 / law[LAW_ROWS + 1, j], (j, steady[1])
        assert abs(steady[-1] - 0.3) < 1e-9, (j, steady[-1])   # d estimated, -d fed
    assert worst < 0.95, worst


@pytest.mark.filterwarnings("ignore::nurbsmotion.machine.UnstableModeWarning")
def test_the_twist_is_taken_off_the_reading_at_the_delayed_clock():
    """Regression (issue 33 item 2): the model's twist (``PlannedPlan.twist``) was taken off
    the reading at the plan's clock, though the drive reaches the plant the model's
    ``delay`` late, so the reading's plant is that much behind the clock: on
    die-bonder-real's own plant, without friction and read exactly (its 0.5 ms delay, its
    100 Hz mode), the Pi at 1 m/s left 229 um of contour (21.6 um at the delayed clock;
    13.5 um with no delay at all, where the two readings are the same). The delayed clock
    is taken with ``disturbance_observer`` (opt-in; without it the default's figure
    stays). The bound: half the way from the fixed to the old figure."""
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate, to_pulses
    from nurbsmotion.nurbs import make_die_bonder_pi
    from nurbsmotion.servo import ServoPlant

    model = die_bonder_real().with_options(encoder="exact", dac_bits=None)
    true = model.with_options(axes=tuple(
        dataclasses.replace(a, coulomb_friction=0.0, stiction=0.0) for a in model.axes))
    path = to_pulses(make_die_bonder_pi(), model)
    for observer in (False, True):
        interp = make_interpolator("planned", path, model, 1e6,
                                   disturbance_observer=observer)
        plant = ServoPlant.of_machine(true, path.end_points[0])
        tr = simulate(interp, model, plant=plant, hold=0.3, settle_window=2.0)
        if observer:
            assert tr.metrics().max_contour_error < 0.5 * (21.6 + 229.0)
        else:
            assert tr.metrics().max_contour_error > 0.5 * (21.6 + 229.0)
