"""The independent solve_ivp simulator of the identification tests
(tests/identify_reference.py) against closed forms: Karnopp's stick rule on a rigid axis
whose stiction is barely above its Coulomb friction, and a motor that the spring releases
and that sticks again within the integrator's first step (seed 100 of
benchmarks/identify_eval.py, where the simulator once looped for ever).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

import identify_reference
from identify_reference import ReferenceChatterError, simulate_log

KE = 1591.5494
TS = 1e-3
NEAR = {"time_constant": 0.2, "gain": 3000.0 * KE, "coulomb_friction": 0.45,
        "stiction": 0.45 * 1.003}
"""A rigid axis whose stiction is 0.3 % above its Coulomb friction (seed 100's ratio)."""


def _rigid_closed_form(axis, t, u1, t1):
    """Position [pulse] of a rigid axis from rest under drive ``u1`` > S from t = 0 to
    ``t1``, then 0: it slides against F, stops where its speed is zero and stays (|0| <= S).

    dv/dt = (-v + G (u - F sgn v)) / tau, solved in closed form on each piece.
    """
    tau, G, F = axis["time_constant"], axis["gain"], axis["coulomb_friction"]
    a = G * (u1 - F)  # the speed it tends to [pulse/s]
    e1 = 1 - math.exp(-t1 / tau)
    v1, p1 = a * e1, a * (t1 - tau * e1)
    stop = tau * math.log1p(v1 / (G * F))  # from t1 on, v = (v1 + GF) e^-s/tau - GF
    p_stop = p1 + tau * (v1 + G * F) * (1 - math.exp(-stop / tau)) - G * F * stop
    p = np.empty_like(t)
    on = t <= t1
    p[on] = a * (t[on] - tau * (1 - np.exp(-t[on] / tau)))
    s = np.minimum(t[~on] - t1, stop)
    p[~on] = p1 + tau * (v1 + G * F) * (1 - np.exp(-s / tau)) - G * F * s
    return p, t1 + stop, p_stop


def test_karnopp_stick_rule_with_stiction_just_above_coulomb():
    """Between F and S the axis does not move at all; above S it slides against F (closed
    form), stops, and stays stopped under a zero drive."""
    F, S = NEAR["coulomb_friction"], NEAR["stiction"]
    u = np.full(50, 0.5 * (F + S))
    assert np.array_equal(simulate_log(NEAR, u, TS), np.zeros(50))

    u = np.zeros(400)
    u[:30] = 2.0
    y = simulate_log(NEAR, u, TS, rtol=1e-11)
    t = np.arange(400) * TS
    ref, t_stop, p_stop = _rigid_closed_form(NEAR, t, 2.0, 30 * TS)
    assert t_stop < 200 * TS  # the stop and the rest after it are in the log
    np.testing.assert_allclose(y, ref, rtol=1e-9, atol=1e-6)
    assert np.all(y[t > t_stop + TS] == y[-1])
    assert y[-1] == pytest.approx(p_stop, rel=1e-9)


# Seed 100 of benchmarks/identify_eval.py: a two-mass axis with stiction 0.3 % above its
# Coulomb friction, and the state where the simulator looped: the motor at rest, the load
# swinging back at 4e4 pulse/s, the drive on the held motor just above S and falling.
SEED_100 = {"time_constant": 0.1370989788113906, "gain": 3012163.456385701,
            "coulomb_friction": 0.4508684608948689, "stiction": 0.4522815071265162,
            "resonance_frequency": 156.07869026742335,
            "resonance_damping": 0.03650287281059615,
            "load_fraction": 0.33276776579283307}
SEED_100_STATE = (15.243210438541267, 0.0, 64.96888713302839, -40345.95519969747)


def _held_motor_closed_form(axis, state, n, ts):
    """The load ringing on a motor held at ``state[0]`` (a damped oscillator in
    x = pl - pm, solved by the matrix exponential) at t = k ts, k < n [pulse], and the
    drive on the held motor [V] under a zero drive (identify_reference's module
    docstring)."""
    tau, G = axis["time_constant"], axis["gain"]
    r = axis["load_fraction"]
    om = 2 * math.pi * axis["resonance_frequency"]
    k = om * om * r * (1 - r)
    c = 2 * axis["resonance_damping"] * om * r * (1 - r)
    # r x'' = -r x'/tau - k x - c x'
    A = np.array([[0.0, 1.0], [-k / r, -(1 / tau + c / r)]])
    step = expm(A * ts)
    xs = np.empty((n, 2))
    xs[0] = state[2] - state[0], state[3]
    for j in range(1, n):
        xs[j] = step @ xs[j - 1]
    load = state[0] + xs[:, 0]
    held = (k * xs[:, 0] + c * xs[:, 1]) * tau / G  # u - (k (pm-pl) + c (vm-vl)) tau/G
    return load, held


@pytest.mark.parametrize("encoder_on", ["motor", "load"])
def test_a_motor_that_sticks_again_within_the_first_step(encoder_on, monkeypatch):
    """Seed 100's state: the spring's drive on the held motor is above S, so the motor
    slips, but that drive falls through F within about 1e-5 s and the motor sticks again
    (Karnopp). The simulator once took the release's own zero speed for the stop and
    repeated it for ever; now the motor stays put (its slip is of order a t^2, 1e-5
    pulse) and the load rings on it as the closed-form oscillator of a held motor, until
    that drive reaches -S."""
    calls = {"restarts": 0}
    solve = identify_reference.solve_ivp

    def counted(*args, **kwargs):
        event = kwargs.get("events")
        if getattr(event, "__name__", "") == "stop_after":
            calls["restarts"] += 1
        return solve(*args, **kwargs)

    monkeypatch.setattr(identify_reference, "solve_ivp", counted)
    ts = 1e-5  # a fine sampling: the held phase lasts about 2 ms
    n = 300
    axis = dict(SEED_100, encoder_on=encoder_on)
    y = simulate_log(axis, np.zeros(n), ts, initial_state=SEED_100_STATE, rtol=1e-10)
    assert calls["restarts"] >= 1  # the case the fix is for was met
    load, held = _held_motor_closed_form(SEED_100, SEED_100_STATE, n, ts)
    assert held[0] > SEED_100["stiction"]  # released at once ...
    assert held[3] < SEED_100["coulomb_friction"]  # ... and pushed back within 3e-5 s
    # held until the drive on the motor leaves +-S again (the next breakaway)
    out = np.flatnonzero(np.abs(held) > SEED_100["stiction"])
    end = out[out > 10][0]
    assert end > 100  # a long held phase to compare
    expected = np.full(end, SEED_100_STATE[0]) if encoder_on == "motor" else load[:end]
    np.testing.assert_allclose(y[:end], expected, rtol=0, atol=1e-3)
    if encoder_on == "motor":
        assert np.ptp(y[:end]) < 1e-4  # the slip is of order 1e-5 pulse


def test_an_event_cap_raises_instead_of_hanging():
    """More stops and breakaways within one sample period than ``max_events``: a typed
    error naming the count, the sample and the time, not a loop."""
    u = np.zeros(200)
    u[:30] = 2.0  # the axis stops 108.4 ms in (the closed form's test)
    simulate_log(NEAR, u, TS, max_events=1)  # one stop in a sample: allowed
    with pytest.raises(ReferenceChatterError, match=r"1 stops and breakaways within "
                       r"sample 108 \(t = 0\.108.* max_events = 0"):
        simulate_log(NEAR, u, TS, max_events=0)
