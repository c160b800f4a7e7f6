"""An independent simulator of issue 32's real machine, for the identification tests.

Written from the physics with :func:`scipy.integrate.solve_ivp` (events at the stops),
not from the project's loop or from :mod:`nurbsmotion.identify.model`: one axis, the
drive held over each sample and reaching the plant ``delay`` seconds later, Coulomb
friction and stiction on the motor, and optionally a second mass (the load) on a spring
and damper at ``resonance_frequency`` with ``resonance_damping``, the viscous damping split
in proportion to the inertia so that the centre of mass moves exactly as the rigid axis
(tau, Kc, Ke). Positions in pulses, drive in V; the encoder reads the motor or the load,
in whole counts (``floor``) and with Gaussian noise.

Two-mass equations (total inertia 1, ``r`` the load's share, ``G = Ke*Kc``)::

    (1-r) am = -(1-r) vm / tau + G/tau (u - F sign(vm)) - k (pm - pl) - c (vm - vl)
        r al =     -r vl / tau                          + k (pm - pl) + c (vm - vl)

with ``k = omega^2 r (1-r)`` and ``c = 2 zeta omega r (1-r)``. A motor at rest stays at
rest (vm = 0) while the drive on it, ``u`` less the spring and damper
(``(k (pm - pl) + c (vm - vl)) tau / G`` [V]), is within ``S`` (docs/model.md#real-machine);
the load then rings on the held motor, and the instant that drive leaves ``+-S`` is an
event.

Sticking is Karnopp's rule: a motor at rest stays at rest while the drive on it is within
``+-S``; beyond it, it slips the way that drive pushes, against the Coulomb friction ``F``,
until its speed is zero again. A motor released from rest starts at ``vm = 0``, which is
itself a zero of the stop event: when the spring's drive falls through ``F`` so fast that
the motor stops again within the integrator's first step (seed 100 of
benchmarks/identify_eval.py: ``S`` 0.3 % above ``F``, the load swinging at 4e4 pulse/s,
the slip over in about 1e-5 s), scipy's root search returns the start itself and nothing
advances; the old loop repeated that step for ever. The stop is then searched again on
``vm / (t - t0)``, which has the same sign as ``vm`` after the start but not its zero at
the start (it tends to the motor's acceleration there): the true re-stop. A log that never
met that case is simulated exactly as before. ``max_events`` caps the stops and
breakaways within one sample period: a chatter beyond it raises
:class:`ReferenceChatterError` (naming the sample, the time and the count) instead of
hanging.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["simulate_log", "random_axis", "ReferenceChatterError"]

MAX_EVENTS = 1000
"""Default cap on the stops and breakaways within one sample period. The modes simulated
here are at most 250 Hz (a sample of 1 ms is a quarter of their period), and a stick-slip
cycle takes a fair part of the mode's period (the spring must swing the drive on the
motor from one side of the friction band to the other), so a real log has a handful per
sample; a thousand is only reached by a chatter that the simulator cannot resolve."""


class ReferenceChatterError(RuntimeError):
    """The reference simulator met more stops and breakaways within one sample period
    than ``max_events`` (a Zeno-like chatter it cannot resolve)."""


def _rhs(axis, u, sgn, stuck):
    tau, G, F = axis["time_constant"], axis["gain"], axis.get("coulomb_friction", 0.0)
    f_hz = axis.get("resonance_frequency", 0.0)
    if not f_hz:
        def rigid(t, s):
            if stuck:
                return [0.0, 0.0]
            return [s[1], (-s[1] + G * (u - F * sgn)) / tau]
        return rigid
    r = axis.get("load_fraction", 0.5)
    om = 2 * math.pi * f_hz
    k = om * om * r * (1 - r)
    c = 2 * axis["resonance_damping"] * om * r * (1 - r)

    def two_mass(t, s):
        pm, vm, pl, vl = s
        spring = k * (pm - pl) + c * (vm - vl)
        al = (-r * vl / tau + spring) / r
        if stuck:
            return [0.0, 0.0, vl, al]
        am = (-(1 - r) * vm / tau + G / tau * (u - F * sgn) - spring) / (1 - r)
        return [vm, am, vl, al]
    return two_mass


def _held_drive(axis, state, u):
    """The drive on a motor held at rest [V]: ``u`` less the spring and damper (the
    plant's, docs/model.md#real-machine: the motor breaks away when it exceeds ``S``)."""
    if len(state) == 2:
        return u
    r = axis.get("load_fraction", 0.5)
    om = 2 * math.pi * axis["resonance_frequency"]
    k = om * om * r * (1 - r)
    c = 2 * axis["resonance_damping"] * om * r * (1 - r)
    pm, vm, pl, vl = state
    return u - (k * (pm - pl) + c * (vm - vl)) * axis["time_constant"] / axis["gain"]


def _motor_accel(axis, state, u, sgn):
    return _rhs(axis, u, sgn, False)(0.0, state)[1]


def _count_event(count: int, sample: int, t: float, sample_period: float,
                 max_events: int, u: float) -> tuple[int, int]:
    """The stops and breakaways so far within the sample period of the event at ``t``
    [s], and that sample's index; :class:`ReferenceChatterError` beyond ``max_events``
    (``u`` [V] the drive, for the message)."""
    k = int(t // sample_period)
    count = count + 1 if k == sample else 1
    if count > max_events:
        raise ReferenceChatterError(
            f"{count} stops and breakaways within sample {k} (t = {float(t)!r} s, drive "
            f"{float(u)!r} V), more than max_events = {max_events}")
    return count, k


def simulate_log(axis: dict, drive: np.ndarray, sample_period: float, delay: float = 0.0,
                 encoder: str = "exact", noise: float = 0.0, seed: int = 0,
                 rtol: float = 1e-10, initial_state=None,
                 max_events: int = MAX_EVENTS) -> np.ndarray:
    """The encoder readings of one axis under a drive sequence, from rest at 0 (or from
    ``initial_state``).

    Parameters
    ----------
    axis : dict
        ``time_constant`` [s], ``gain`` (Ke*Kc) [pulse/s/V], optionally
        ``coulomb_friction``, ``stiction`` [V], ``resonance_frequency`` [Hz],
        ``resonance_damping``, ``load_fraction``, ``encoder_on`` ("motor" or "load").
    drive : ndarray, shape (n_samples,)
        u[k] [V], held over sample k from k*Ts + delay.
    encoder : {"exact", "counts"}
    noise : float
        Standard deviation of the Gaussian reading noise [pulse].
    initial_state : array_like, shape (2,) or (4,), optional
        ``(pm, vm)`` or ``(pm, vm, pl, vl)`` at t = 0 [pulse, pulse/s] (default at rest at
        0); a motor with ``vm = 0`` starts stuck (Karnopp's rule then decides).
    max_events : int
        Cap on the stops and breakaways within one sample period.

    Raises
    ------
    ReferenceChatterError
        More than ``max_events`` stops and breakaways within one sample period.

    Returns
    -------
    ndarray, shape (n_samples,)
        The reading at each sample instant [pulse].
    """
    Ts = sample_period
    n = len(drive)
    S = max(axis.get("stiction", 0.0), axis.get("coulomb_friction", 0.0))
    two = bool(axis.get("resonance_frequency", 0.0))
    state = np.zeros(4 if two else 2)
    if initial_state is not None:
        state = np.array(initial_state, dtype=float)
        if state.shape != (4 if two else 2,):
            raise ValueError(f"initial_state has shape {state.shape}, expected "
                             f"({4 if two else 2},)")
    stuck = state[1] == 0.0
    sgn = float(np.sign(state[1]))
    read = np.full(n, np.nan)
    events, event_sample = 0, -1  # stops and breakaways within the sample event_sample
    out = 2 if two and axis.get("encoder_on", "motor") == "load" else 0
    drive = np.asarray(drive, dtype=float)
    # Intervals of constant drive at the plant: the drive changes at j*Ts + delay.
    change = [0] + [j for j in range(1, n) if drive[j] != drive[j - 1]]
    starts = [0.0] + [j * Ts + delay for j in change]
    values = [0.0] + [drive[j] for j in change]
    t_end = (n - 1) * Ts
    samples = np.arange(n) * Ts

    def record(sol_fn, a, b, closed):
        lo = int(math.ceil(a / Ts - 1e-9))
        hi = int(math.floor(b / Ts + 1e-9)) if closed else int(math.ceil(b / Ts - 1e-9)) - 1
        hi = min(hi, n - 1)
        if hi >= lo:
            ts = samples[lo:hi + 1]
            read[lo:hi + 1] = sol_fn(ts)

    for i, a in enumerate(starts):
        if a >= t_end:
            break
        b = min(starts[i + 1], t_end) if i + 1 < len(starts) else t_end
        if b - a <= 1e-12 * Ts:
            continue
        u = values[i]
        t = a
        while True:
            if stuck:
                choices = [s for s in (1.0, -1.0)
                           if _motor_accel(axis, state, u, s) * s > 0]
                if (S > 0 and abs(_held_drive(axis, state, u)) <= S) or not choices:
                    if not two:
                        held = state[0]
                        record(lambda ts: np.full(len(ts), held), t, b, b >= t_end)
                        break

                    def breakaway(tt, s):
                        return S - abs(_held_drive(axis, s, u))
                    breakaway.terminal = True
                    breakaway.direction = -1
                    sol = solve_ivp(_rhs(axis, u, 0.0, True), (t, b), state, rtol=rtol,
                                    atol=1e-9, method="DOP853",
                                    events=breakaway if S > 0 else None, dense_output=True)
                    if sol.status != 1:
                        record(lambda ts: sol.sol(ts)[out], t, b, b >= t_end)
                        state = sol.y[:, -1]
                        break
                    # the spring and damper broke the held motor away inside
                    te = sol.t_events[0][0]
                    events, event_sample = _count_event(events, event_sample, te, Ts,
                                                        max_events, u)
                    record(lambda ts: sol.sol(ts)[out], t, te, False)
                    state = sol.y_events[0][0].copy()
                    state[1] = 0.0
                    t = te
                    choices = [math.copysign(1.0, _held_drive(axis, state, u))]
                stuck, sgn = False, choices[0]

            def stop(tt, s):
                return s[1]
            stop.terminal = True
            stop.direction = -sgn
            sol = solve_ivp(_rhs(axis, u, sgn, False), (t, b), state, rtol=rtol, atol=1e-9,
                            method="DOP853", events=stop if S > 0 else None,
                            dense_output=True)
            if sol.status == 1 and sol.t_events[0][0] <= t and state[1] == 0.0:
                # released from rest, and the root search returned the start (the
                # module's docstring): the first zero of vm after the start instead
                a0 = _motor_accel(axis, state, u, sgn)

                def stop_after(tt, s, t0=t, a0=a0):
                    return s[1] / (tt - t0) if tt > t0 else a0
                stop_after.terminal = True
                stop_after.direction = -sgn
                sol = solve_ivp(_rhs(axis, u, sgn, False), (t, b), state, rtol=rtol,
                                atol=1e-9, method="DOP853", events=stop_after,
                                dense_output=True)
            if sol.status == 1:  # the motor stopped inside
                tz = sol.t_events[0][0]
                events, event_sample = _count_event(events, event_sample, tz, Ts,
                                                    max_events, u)
                record(lambda ts: sol.sol(ts)[out], t, tz, False)
                state = sol.y_events[0][0].copy()
                state[1] = 0.0
                stuck = S > 0  # released at once if |u| > S
                t = tz
                if b - t <= 1e-13 * Ts:
                    record(lambda ts: np.full(len(ts), state[out]), t, b, b >= t_end)
                    break
            else:
                record(lambda ts: sol.sol(ts)[out], t, b, b >= t_end)
                state = sol.y[:, -1].copy()
                break
    if encoder == "counts":
        read = np.floor(read)
    if noise:
        read = read + np.random.default_rng(seed).normal(0.0, noise, n)
    return read


def random_axis(rng: np.random.Generator, mode: bool | None = None) -> dict:
    """A random axis in the range of servo machines like the die-bonder's (tau 0.05-0.5 s,
    Ke*Kc over a factor 5, friction 0-6 % of 10 V, modes 40-250 Hz)."""
    axis = {"time_constant": float(rng.uniform(0.05, 0.5)),
            "gain": float(1591.5494 * rng.uniform(1000.0, 5000.0)),
            "coulomb_friction": float(rng.uniform(0.05, 0.6))}
    axis["stiction"] = axis["coulomb_friction"] * float(rng.uniform(1.0, 1.6))
    if mode if mode is not None else rng.random() < 0.5:
        axis["resonance_frequency"] = float(rng.uniform(40.0, 250.0))
        axis["resonance_damping"] = float(rng.uniform(0.01, 0.1))
        axis["load_fraction"] = float(rng.uniform(0.2, 0.7))
        axis["encoder_on"] = "motor" if rng.random() < 0.7 else "load"
    return axis
