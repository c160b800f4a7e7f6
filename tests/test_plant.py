"""The machine as it is (issue 32): the plant stage against independent references.

- two-mass axis with Coulomb friction and stiction, delay and load steps: against
  ``scipy.integrate.solve_ivp`` on the physical two-mass equations (motor and load, spring
  and damper), with events at the motor's stops and breakaways;
- delay: against ``scipy.signal.cont2discrete`` of the physical model over the two
  intervals of a sample (the delayed input as an augmented discrete state);
- counts, noise and the DAC by hand; machine keys validated and round-tripped; the ideal
  machine unchanged.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import cont2discrete

from nurbsmotion.errors import InvalidMachineError, PathFileError
from nurbsmotion.machine import (Axis, Disturbance, Machine, die_bonder, die_bonder_real,
                                 load_machine)
from nurbsmotion.plant import make_stage, measure, noise_draw, stage_response

SWEEP = int(os.environ.get("NURBSMOTION_PLANT_DRAWS", "6"))
"""Random drive sequences per reference check (raise it for a longer sweep)."""

Ts = 1e-3


def _effects(*, delay=0.0, dac_bits=None, encoder="exact", noise=0.0, seed=0, **axis):
    a = {"coulomb_friction": 0.0, "stiction": 0.0, "disturbance": [],
         "resonance_frequency": 0.0, "resonance_damping": 0.0, "load_fraction": 0.5,
         "encoder_on": "motor"}
    a.update(axis)
    return {"encoder": encoder, "measurement_noise": noise, "seed": seed, "delay": delay,
            "dac_bits": dac_bits, "axes": [a]}


class TwoMass:
    """The physical equations, written from the masses (not from the stage's modal
    form): state [w_motor, theta_motor, w_load, theta_load], speeds [rad/s], positions
    [pulse], forces in the axis's normalised units (viscous damping 1 in all)."""

    def __init__(self, tau, Kc, Ke, f=0.0, zeta=0.0, lam=0.5, coulomb=0.0, stiction=0.0):
        self.tau, self.Kc, self.Ke = tau, Kc, Ke
        self.rigid = f == 0.0
        self.fc, self.fs = coulomb, max(stiction, coulomb)
        if self.rigid:
            return
        wn = 2 * math.pi * f
        mu = lam * (1 - lam) * tau
        self.k = wn * wn * mu
        self.c = mu * (2 * zeta * wn - 1 / tau)
        self.Jm, self.Jl = (1 - lam) * tau, lam * tau
        self.bm, self.bl = 1 - lam, lam

    def linear(self):
        """(A, B) of the sliding model without friction."""
        Ke = self.Ke
        if self.rigid:
            return np.array([[-1 / self.tau, 0], [Ke, 0]]), np.array([[self.Kc / self.tau], [0]])
        k, c, Jm, Jl = self.k, self.c, self.Jm, self.Jl
        A = np.array([[-(self.bm + c) / Jm, -k / (Ke * Jm), c / Jm, k / (Ke * Jm)],
                      [Ke, 0, 0, 0],
                      [c / Jl, k / (Ke * Jl), -(self.bl + c) / Jl, -k / (Ke * Jl)],
                      [0, 0, Ke, 0]])
        return A, np.array([[self.Kc / Jm], [0], [0], [0]])

    def tool(self, x):
        return x[1] if self.rigid else x[3]

    def net(self, x, v):
        """The drive on the motor but for friction [V]."""
        if self.rigid:
            return v
        return v - (self.k * (x[1] - x[3]) / self.Ke + self.c * (x[0] - x[2])) / self.Kc

    def rhs(self, v, s, stuck):
        A, B = self.linear()

        def f(t, x):
            dx = A @ x + B[:, 0] * (v - self.fc * s)
            if stuck:
                dx = A @ x
                dx[0] = dx[1] = 0.0
            return dx
        return f

    def advance(self, x, v, h, state):
        """``x`` after ``h`` [s] under drive ``v`` [V]; ``state[0]``: the motor's
        direction (+1, -1) or 0 stuck, updated. Events: stops and breakaways."""
        t = 0.0
        tol = dict(method="DOP853", rtol=1e-13, atol=1e-12)
        friction = self.fs > 0
        while h - t > 1e-16:
            s = state[0]
            if friction and s == 0:
                if abs(self.net(x, v)) > self.fs:
                    state[0] = math.copysign(1.0, self.net(x, v))
                    continue

                def brk(tt, y):
                    return abs(self.net(y, v)) - self.fs
                brk.terminal, brk.direction = True, 1
                sol = solve_ivp(self.rhs(v, 0, True), (t, h), x, events=brk, **tol)
            else:
                def stop(tt, y):
                    return s * y[0]
                stop.terminal, stop.direction = True, -1
                sol = solve_ivp(self.rhs(v, s if friction else 0.0, False), (t, h), x,
                                events=stop if friction else None, **tol)
            x = sol.y[:, -1].copy()
            t = sol.t[-1]
            if sol.status == 1:  # an event
                if s == 0:
                    state[0] = math.copysign(1.0, self.net(x, v))
                else:
                    x[0] = 0.0
                    net = self.net(x, v)
                    state[0] = 0.0 if abs(net) <= self.fs else math.copysign(1.0, net)
        return x


def _reference(model, drive, delay, disturbance=()):
    """Tool position at every sample instant under ``drive`` (V per sample), by
    :class:`TwoMass` over every interval of constant drive."""
    n_whole = int(math.floor(delay / Ts + 1e-12))
    split = delay - n_whole * Ts
    split = 0.0 if split < 1e-12 else split
    x = np.zeros(2 if model.rigid else 4)
    state = [0.0 if model.fs > 0 else 1.0]
    applied = lambda k: drive[k] if k >= 0 else 0.0  # noqa: E731
    out = [model.tool(x)]
    for k in range(len(drive)):
        cuts = sorted({0.0, split, Ts} | {at - k * Ts for at, _ in disturbance
                                          if 0 < at - k * Ts < Ts})
        for a, b in zip(cuts[:-1], cuts[1:]):
            if b - a <= 0:
                continue
            u = applied(k - n_whole - 1) if a < split else applied(k - n_whole)
            load = sum(d for at, d in disturbance if at <= k * Ts + a + 1e-15)
            x = model.advance(x, u + load, b - a, state)
        out.append(model.tool(x))
    return np.array(out)


AXES = [  # tau, Kc, Ke as the die-bonder's, and two made up
    (0.135, 3156.23, 1591.5494), (0.31, 2506.17, 1591.5494), (0.02, 300.0, 500.0)]


@pytest.mark.parametrize("case", range(SWEEP))
def test_two_mass_friction_matches_solve_ivp(case):
    rng = np.random.default_rng(1000 + case)
    tau, Kc, Ke = AXES[case % len(AXES)]
    f = float(rng.uniform(40, 300))
    lam = float(rng.uniform(0.2, 0.8))
    zeta = max(float(rng.uniform(0.01, 0.2)), 1.5 / (4 * math.pi * f * tau))
    coulomb = float(rng.uniform(0.1, 0.4))
    stiction = coulomb + float(rng.uniform(0.0, 0.2))
    delay = float(rng.choice([0.0, 0.3e-3, 1.6e-3]))
    n = 25
    # drives about the friction level, with rests, so that the motor stops and sticks
    drive = rng.choice([0.0, 1.0], n) * rng.normal(0, 0.8, n)
    disturbance = [(float(rng.uniform(0.004, 0.02)), float(rng.normal(0, 0.3)))]
    effects = _effects(delay=delay, coulomb_friction=coulomb, stiction=stiction,
                       resonance_frequency=f, resonance_damping=zeta, load_fraction=lam,
                       disturbance=[{"at": a, "drive": d} for a, d in disturbance])
    stage = make_stage(effects, [tau], [Kc], [Ke], 10.0, Ts)
    _, tool = stage_response(stage, drive[:, None])
    ref = _reference(TwoMass(tau, Kc, Ke, f, zeta, lam, coulomb, stiction), drive, delay,
                     disturbance)
    np.testing.assert_allclose(tool[:, 0], ref, rtol=0, atol=1e-6)


@pytest.mark.parametrize("case", range(SWEEP))
def test_rigid_friction_matches_solve_ivp(case):
    rng = np.random.default_rng(2000 + case)
    tau, Kc, Ke = AXES[case % len(AXES)]
    coulomb, stiction = 0.3, 0.4
    n = 30
    drive = rng.choice([0.0, 1.0], n) * rng.normal(0, 0.8, n)
    drive += np.where(rng.random(n) < 0.3, 0.35, 0.0)  # between Coulomb and stiction
    effects = _effects(coulomb_friction=coulomb, stiction=stiction)
    stage = make_stage(effects, [tau], [Kc], [Ke], 10.0, Ts)
    _, tool = stage_response(stage, drive[:, None])
    ref = _reference(TwoMass(tau, Kc, Ke, coulomb=coulomb, stiction=stiction), drive, 0.0)
    np.testing.assert_allclose(tool[:, 0], ref, rtol=0, atol=1e-6)


def test_stiction_holds_a_drive_below_it():
    """A motor at rest under 0.39 V with 0.4 V stiction does not move at all."""
    stage = make_stage(_effects(coulomb_friction=0.3, stiction=0.4), [0.135], [3156.23],
                       [1591.5494], 10.0, Ts)
    x, tool = stage_response(stage, np.full((50, 1), 0.39), position=[7.0])
    assert np.all(tool == 7.0)
    _, tool = stage_response(stage, np.full((50, 1), 0.41), position=[7.0])
    assert tool[-1, 0] > 7.0


@pytest.mark.parametrize("two_mass", [False, True])
@pytest.mark.parametrize("delay", [0.25e-3, 0.5e-3, 1e-3, 2.7e-3])
def test_delay_matches_cont2discrete(delay, two_mass):
    """The delayed input as an augmented discrete state: x[k+1] = P2 (P1 x[k] +
    G1 u[k-n-1]) + G2 u[k-n], (P, G) from cont2discrete over h1 and Ts - h1."""
    tau, Kc, Ke = 0.135, 3156.23, 1591.5494
    model = TwoMass(tau, Kc, Ke, 100.0 if two_mass else 0.0, 0.05, 0.4)
    A, B = model.linear()
    nx = A.shape[0]
    C, D = np.eye(nx), np.zeros((nx, 1))
    n_whole = int(math.floor(delay / Ts + 1e-12))
    split = delay - n_whole * Ts
    split = 0.0 if split < 1e-12 * Ts else split
    P2, G2, *_ = cont2discrete((A, B, C, D), Ts - split, method="zoh")
    P1, G1, *_ = (cont2discrete((A, B, C, D), split, method="zoh") if split
                  else (np.eye(nx), np.zeros((nx, 1))))
    rng = np.random.default_rng(7)
    drive = rng.normal(0, 1.0, 60)
    u = lambda k: drive[k] if k >= 0 else 0.0  # noqa: E731
    x = np.zeros(nx)
    ref = [0.0]
    for k in range(len(drive)):
        x = P2 @ (P1 @ x + G1[:, 0] * u(k - n_whole - 1)) + G2[:, 0] * u(k - n_whole)
        ref.append(model.tool(x))
    effects = _effects(delay=delay, resonance_frequency=100.0 if two_mass else 0.0,
                       resonance_damping=0.05, load_fraction=0.4)
    _, tool = stage_response(make_stage(effects, [tau], [Kc], [Ke], 10.0, Ts),
                             drive[:, None])
    ref = np.array(ref)
    scale = np.max(np.abs(ref))
    np.testing.assert_allclose(tool[:, 0], ref, rtol=0, atol=1e-9 * scale)


def _read(stage, *args):
    return measure(stage.noise, stage.seed, stage.counts, *args)


def test_counts_by_hand():
    stage = make_stage(_effects(encoder="counts"), [0.1], [100.0], [100.0], 10.0, Ts)
    assert _read(stage, 3.2, 0.5, 0, 0) == 2.5      # 0.5 + floor(2.7)
    assert _read(stage, 0.5, 0.5, 0, 0) == 0.5
    assert _read(stage, 0.49, 0.5, 0, 0) == -0.5    # floor, not toward zero
    assert _read(stage, -3.0, 0.0, 0, 0) == -3.0
    exact = make_stage(_effects(), [0.1], [100.0], [100.0], 10.0, Ts)
    assert _read(exact, 3.2, 0.5, 0, 0) == 3.2


def test_noise_by_hand_and_reproducible():
    stage = make_stage(_effects(noise=2.0, seed=11), [0.1], [100.0], [100.0], 10.0, Ts)
    got = [_read(stage, 10.0, 0.0, k, 1) for k in range(5)]
    assert got == [10.0 + 2.0 * noise_draw(11, k, 1) for k in range(5)]
    assert got == [_read(stage, 10.0, 0.0, k, 1) for k in range(5)]  # same seed
    draws = np.array([noise_draw(3, k, 0) for k in range(20000)])
    assert abs(draws.mean()) < 0.03 and abs(draws.std() - 1.0) < 0.03
    assert noise_draw(3, 5, 0) != noise_draw(4, 5, 0) != noise_draw(3, 5, 1)


def test_dac_by_hand():
    """16 bits over +-10 V: q = 20/65536 V; the rigid axis then equals the ideal ZOH
    plant driven by the rounded drive."""
    from nurbsmotion.servo import ServoPlant

    q = 20.0 / 65536
    drive = np.array([1.23456, -0.0001, 9.9999999, -10.0, 0.00016, 0.0])
    levels = np.clip(np.floor(drive / q + 0.5), -32768, 32767)
    assert levels[2] == 32767 and levels[3] == -32768 and levels[4] == 1
    stage = make_stage(_effects(dac_bits=16), [0.135], [3156.23], [1591.5494], 10.0, Ts)
    _, tool = stage_response(stage, drive[:, None])
    _, ideal = ServoPlant([0.135], [3156.23], [1591.5494], 10.0, Ts).response(
        (levels * q)[:, None], position=[0.0])
    np.testing.assert_allclose(tool[:, 0], ideal[:, 0], rtol=1e-12, atol=1e-9)


def test_machine_keys_round_trip_and_example(tmp_path):
    m = die_bonder_real()
    assert m.has_effects and not die_bonder().has_effects
    assert Machine.from_dict(m.to_dict()) == m
    assert load_machine("examples/die_bonder_real.toml") == m
    assert "encoder" not in die_bonder().to_dict()  # an ideal machine's file is unchanged
    withstep = m.with_options(axes=(m.axes[0], Axis(
        **{**m.axes[1].__dict__, "disturbance": (Disturbance(0.2, 0.5),)})))
    assert Machine.from_dict(withstep.to_dict()) == withstep
    import tomli_w
    try:
        import tomllib
    except ImportError:  # Python < 3.11
        import tomli as tomllib
    f = tmp_path / "m.toml"
    f.write_text(tomli_w.dumps(withstep.to_dict()))
    assert tomllib.loads(f.read_text())["axes"][1]["disturbance"] == [{"at": 0.2,
                                                                       "drive": 0.5}]
    assert load_machine(f) == withstep


@pytest.mark.parametrize("changes, words", [
    (dict(encoder="count"), "encoder"), (dict(measurement_noise=-1.0), "measurement_noise"),
    (dict(seed=True), "seed"), (dict(delay=-1e-3), "delay"), (dict(delay=2.0), "delay"),
    (dict(dac_bits=1), "dac_bits"), (dict(dac_bits=16.0), "dac_bits"),
    (dict(dac_bits=16, max_drive=math.inf), "dac_bits"),
    (dict(delay=0.6e-3), "poles"),
])
def test_machine_keys_refused(changes, words):
    with pytest.raises(InvalidMachineError, match=words):
        die_bonder(**changes)


@pytest.mark.parametrize("axis, words", [
    (dict(coulomb_friction=-0.1), "coulomb_friction"), (dict(stiction=float("nan")), "stiction"),
    (dict(stiction=11.0), "stiction"), (dict(resonance_frequency=-5.0), "resonance_frequency"),
    (dict(resonance_frequency=100.0, resonance_damping=1.0), "resonance_damping"),
    (dict(resonance_frequency=100.0, resonance_damping=0.001), "resonance_damping"),
    (dict(load_fraction=1.0), "load_fraction"), (dict(encoder_on="tool"), "encoder_on"),
    (dict(disturbance=[{"at": -1.0, "drive": 0.5}]), "disturbance at"),
    (dict(disturbance=[{"at": 0.1}]), "disturbance"),
])
def test_axis_keys_refused(axis, words):
    base = die_bonder()
    with pytest.raises(InvalidMachineError, match=words):
        Machine((Axis(**{**base.axes[0].__dict__, **axis}),), 10.0, 1e-3)


def test_unknown_axis_key_in_file_is_named(tmp_path):
    d = die_bonder_real().to_dict()
    d["axes"][0]["stiction_v"] = 0.1
    with pytest.raises(PathFileError, match="stiction_v"):
        Machine.from_dict(d)


def test_delay_limit_of_the_die_bonder():
    """docs/model.md: the die-bonder's PD+ gains are stable up to about 0.57 Ts of delay."""
    die_bonder(delay=0.56e-3)
    with pytest.raises(InvalidMachineError, match="delay = 0.00058"):
        die_bonder(delay=0.58e-3)


def test_ideal_run_unchanged_and_real_run_measured():
    from nurbsmotion.loop import run
    from nurbsmotion.nurbs import make_line

    line = make_line([0.0, 0.0], [2000.0, 1000.0])
    ideal = run(line, die_bonder(), 2e5, "paper")
    same = run(line, die_bonder(encoder="exact", delay=0.0), 2e5, "paper")
    assert ideal.position_measured is None and ideal.hold_samples == 0
    np.testing.assert_array_equal(ideal.position, same.position)
    np.testing.assert_array_equal(ideal.drive, same.drive)
    real = run(line, die_bonder(encoder="counts", dac_bits=16), 2e5, "paper")
    assert real.hold_samples == 300
    meas = real.position_measured
    assert np.all(meas == np.floor(meas))  # whole counts from a start at 0
    np.testing.assert_array_less(np.abs(meas - np.floor(real.position)), 1e-9)
    rest = real.at_rest()
    assert set(rest.limit_cycle) == {"x", "y"} and not any(rest.limit_cycle.values())
    assert rest.peak_speed["x"] > 0 and rest.window_s == pytest.approx(0.3)


def test_campaign_plant_groups_take_effect_keys():
    from nurbsmotion.study.case import _true_machine
    from nurbsmotion.study.spec import _plant

    group = _plant({"name": "d", "delay": 3e-4, "encoder": "counts",
                    "coulomb_friction": 0.3, "stiction": 0.4}, 0)
    true = _true_machine(die_bonder(), group)
    assert true.delay == 3e-4 and true.encoder == "counts"
    assert all(a.coulomb_friction == 0.3 and a.stiction == 0.4 for a in true.axes)
    assert _true_machine(die_bonder(), _plant({"name": "n"}, 0)) == die_bonder()
    with pytest.raises(ValueError, match="stiction_v"):
        _plant({"name": "x", "stiction_v": 0.4}, 0)
    with pytest.raises(InvalidMachineError, match="poles"):
        _true_machine(die_bonder(), _plant({"name": "d", "delay": 8e-4}, 0))


@pytest.mark.parametrize("seed", range(4))
def test_random_real_machines_keep_their_axes(seed):
    from nurbsmotion.random_machines import random_machine

    real, ideal = random_machine(seed, real=True), random_machine(seed)
    assert real.has_effects and not ideal.has_effects
    assert [(a.time_constant, a.position_gain) for a in real.axes] == \
        [(a.time_constant, a.position_gain) for a in ideal.axes]
    assert real.delay <= 0.6 * real.sample_period and real.encoder == "counts"
    assert Machine.from_dict(real.to_dict()) == real
