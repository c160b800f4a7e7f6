"""The model :func:`nurbsmotion.identify.identify` fits, simulated exactly (private).

One axis, driven by the logged drive ``u[k]`` held over each sample and reaching the plant
``delay`` seconds after the sample instant (the previous drive holds meanwhile). Its
rigid-body motion (the centre of mass, ``p``) is issue 32's plant with Coulomb friction
and stiction::

    tau * dv/dt = -v + G * (u - F * sign(v))        dp/dt = v        G = Ke * Kc

an axis at rest staying at rest while ``|u| <= S``. An optional mode adds the relative
coordinate of a two-mass axis, scaled by the load's share (``x = (1 - r) * (motor -
load)``), driven by the same net drive::

    d2x/dt2 = -(1/tau + 2*zeta*omega) * dx/dt - omega**2 * x + (G / tau) * (u - F*sign(v))

and the encoder reads ``y = p + c * x``: ``c = r / (1 - r)`` with the encoder on the motor
(``r`` the load's share of the inertia), ``c = -1`` on the load.

The friction acts where the plant puts it (docs/model.md#real-machine,
:mod:`nurbsmotion.plant`): on a rigid axis on the whole body, which sticks while
``|u| <= S``; on a two-mass axis on the **motor**, whose speed is ``v + m * x'`` with
``m = r / (1 - r)`` (the coupling with the encoder on the motor; from the load fraction
with it on the load). The motor sticks when that speed reaches zero and stays while the
drive on it, ``u`` less the spring and damper, is within ``S``; meanwhile the load swings
on the held motor and the rigid body follows it (:func:`_two_mass_friction`).

Each sample is integrated in closed form, piece by piece: the rigid part as a first-order
lag to the instant its speed reaches zero (``t = tau * log((v0 - vinf) / -vinf)``), where
it sticks or reverses; the mode as a damped oscillator with a constant input. A two-mass
axis with friction is checked every eighth of the mode's period (of the held motor's,
stuck) and its stops and breakaways found by regula falsi on the closed form, as the
plant does. No ODE solver: the same numbers at any sample period.

Glossary
--------
u : drive [V]; p, y : position [pulse]; v : speed [pulse/s]; tau : time constant [s];
G : Ke*Kc, speed per volt [pulse/s/V]; F : Coulomb friction [V]; S : stiction [V];
omega : mode's angular frequency [rad/s]; zeta : its damping ratio; c : its coupling into
the encoder; r : the load's share of the inertia; m = r/(1 - r); Ts : sample period [s];
d : delay [s].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..plant import oscillator

__all__ = ["simulate_axis"]


@njit(cache=True)
def _mode_step(x, xd, dt, force, omega, half_damping, damped, table):
    """The mode ``x'' + 2a x' + omega^2 x = force`` advanced by ``dt`` (underdamped);
    ``table`` holds ``(dt, exp, cos, sin)`` of the two usual piece lengths."""
    xp = force / (omega * omega)
    y0 = x - xp
    if dt == table[0, 0]:
        e, c, s = table[0, 1], table[0, 2], table[0, 3]
    elif dt == table[1, 0]:
        e, c, s = table[1, 1], table[1, 2], table[1, 3]
    else:
        e = math.exp(-half_damping * dt)
        c = math.cos(damped * dt)
        s = math.sin(damped * dt)
    y = e * (y0 * c + (xd + half_damping * y0) / damped * s)
    v = e * (xd * c - (half_damping * xd + omega * omega * y0) / damped * s)
    return y + xp, v


@njit(cache=True)
def _coefficients(h, tau, a1, a0, cache):
    """``(exp(-h/tau), -expm1(-h/tau), eC, eS)`` of an interval ``h`` [s]; ``cache`` rows
    ``(h, ...)`` hold the few lengths a log repeats (the check steps of the two pieces)."""
    for i in range(cache.shape[0]):
        if cache[i, 0] == h:
            return cache[i, 1], cache[i, 2], cache[i, 3], cache[i, 4]
        if cache[i, 0] < 0.0:
            break
    g = -math.expm1(-h / tau)
    ec, es = oscillator(a1, a0, h)
    for i in range(cache.shape[0]):
        if cache[i, 0] < 0.0:
            cache[i, 0] = h
            cache[i, 1] = 1.0 - g
            cache[i, 2] = g
            cache[i, 3] = ec
            cache[i, 4] = es
            break
    return 1.0 - g, g, ec, es


@njit(cache=True, inline="always")
def _oscillate(x, xd, ec, es, a1, a0, force):
    """The mode ``x'' + a1 x' + a0 x = force`` (constant) advanced by the interval whose
    :func:`nurbsmotion.plant.oscillator` values are ``ec``, ``es``."""
    xp = force / a0
    z0 = x - xp
    m = 0.5 * a1
    return ec * z0 + es * (xd + m * z0) + xp, ec * xd - es * (m * xd + a0 * z0)


MAX_EVENTS = 64
"""Friction events (stops, breakaways) one piece of a sample may hold at most: beyond, the
motor is held for the rest of it (as :data:`nurbsmotion.plant.MAX_EVENTS`)."""


@njit(cache=True, inline="always")
def _illinois(lo, hi, g_lo, g_hi, t, g_t, past, side):
    """One bracket update of the Illinois method (regula falsi that halves the value kept
    at the end that stays twice in a row): the root lies in (lo, hi] with values g_lo,
    g_hi; ``t`` with value ``g_t`` is ``past`` the root or not. Returns the new
    ``(lo, hi, g_lo, g_hi, side)``."""
    if past:
        if side == 1:
            g_lo *= 0.5
        return lo, t, g_lo, g_t, 1
    if side == -1:
        g_hi *= 0.5
    return t, hi, g_t, g_hi, -1


@njit(cache=True, inline="always")
def _held_drive(drive, k, piece, lag, frac, Ts):
    """The drive [V] and its duration [s] over piece 0 or 1 of sample k of a loop whose
    drive arrives ``lag`` whole samples and ``frac`` of a sample late: piece 0 is the
    first ``frac*Ts`` of the sample, where drive[k - lag - 1] still holds, piece 1 the
    rest, under drive[k - lag] (0 before the log's first drive)."""
    if piece == 0:
        j, h = k - lag - 1, frac * Ts
    else:
        j, h = k - lag, (1.0 - frac) * Ts
    return (drive[j] if j >= 0 else 0.0), h


@njit(cache=True)
def _two_mass_friction(drive, Ts, lag, frac, tau, gain, coulomb, S, omega, zeta, coupling,
                       motor_share, speed0, out):
    """:func:`simulate_axis` of a two-mass axis with friction, which acts on the motor (as
    the plant's, docs/model.md#real-machine): sliding, the net drive is ``u - F*sign(w_m)``
    with the motor's speed ``w_m = v + m*x'`` (``m = lam/(1 - lam)``); the instant it
    reaches zero is found by checks every eighth of the mode's period and Illinois regula
    falsi between. There the motor sticks while the drive on it, ``u`` less the spring
    and damper (``lam*tau/G * (omega^2*x + 2*zeta*omega*x')`` [V]), is within ``S``; stuck,
    the load swings on the held motor (``x'' + sa1*x' + sa0*x = 0``, ``sa0 =
    (1 - lam)*omega^2``, ``sa1 = 1/tau + (1 - lam)*2*zeta*omega``) and the rigid body
    follows it (``p = theta_m - m*x``), until that drive leaves ``+-S`` (found the same
    way)."""
    n = drive.shape[0]
    m = motor_share
    lam = m / (1.0 + m)
    a1 = 1.0 / tau + 2.0 * zeta * omega
    a0 = omega * omega
    sa1 = 1.0 / tau + (1.0 - lam) * 2.0 * zeta * omega
    sa0 = (1.0 - lam) * a0
    spring = lam * tau / gain  # [V per pulse/s^2]
    accel = gain / tau
    check_slide = 2.0 * math.pi / omega / 8.0
    check_stuck = 2.0 * math.pi / math.sqrt(sa0) / 8.0
    slide_cache = np.full((6, 5), -1.0)
    stuck_cache = np.full((6, 5), -1.0)
    p = 0.0
    v = speed0
    x = 0.0
    xd = 0.0
    stuck = speed0 == 0.0
    sgn = 1.0 if speed0 > 0.0 else -1.0
    out[0] = 0.0
    for k in range(n - 1):
        for piece in range(2):
            u, h = _held_drive(drive, k, piece, lag, frac, Ts)
            if h <= 0.0:
                continue
            events = 0
            left = h
            # equal check steps over the piece, so that their coefficients repeat
            n_slide = max(int(math.ceil(h / check_slide - 1e-9)), 1)
            n_stuck = max(int(math.ceil(h / check_stuck - 1e-9)), 1)
            step_slide = h / n_slide
            step_stuck = h / n_stuck
            while left > 1e-15 * Ts:
                if stuck:
                    fm = u - spring * (a0 * x + 2.0 * zeta * omega * xd)
                    if abs(fm) > S and events < MAX_EVENTS:
                        stuck = False
                        sgn = 1.0 if fm > 0.0 else -1.0
                        continue
                    theta = p + m * x
                    dt = min(left, step_stuck) if events < MAX_EVENTS else left
                    if dt == step_stuck:
                        _, _, ec, es = _coefficients(dt, tau, sa1, sa0, stuck_cache)
                    else:
                        ec, es = oscillator(sa1, sa0, dt)
                    x1, xd1 = _oscillate(x, xd, ec, es, sa1, sa0, 0.0)
                    fm1 = u - spring * (a0 * x1 + 2.0 * zeta * omega * xd1)
                    if abs(fm1) > S and events < MAX_EVENTS:
                        # the breakaway inside: |fm(t)| - S from <= 0 to > 0
                        lo, hi = 0.0, dt
                        glo, ghi = abs(fm) - S, abs(fm1) - S
                        side = 0
                        for _ in range(80):
                            t = (lo * ghi - hi * glo) / (ghi - glo) if ghi != glo else lo
                            if not (lo < t < hi):
                                t = 0.5 * (lo + hi)
                            ec, es = oscillator(sa1, sa0, t)
                            xt, xdt = _oscillate(x, xd, ec, es, sa1, sa0, 0.0)
                            gt = abs(u - spring * (a0 * xt + 2.0 * zeta * omega * xdt)) - S
                            lo, hi, glo, ghi, side = _illinois(lo, hi, glo, ghi, t, gt,
                                                               gt > 0.0, side)
                            if hi - lo <= 1e-13 * Ts:
                                break
                        dt = hi
                        ec, es = oscillator(sa1, sa0, dt)
                        x1, xd1 = _oscillate(x, xd, ec, es, sa1, sa0, 0.0)
                        events += 1
                    x, xd = x1, xd1
                    p = theta - m * x
                    v = -m * xd
                    left -= dt
                    continue
                net = u - coulomb * sgn
                vinf = gain * net
                force = accel * net
                dt = min(left, step_slide)
                if dt == step_slide:
                    e, g, ec, es = _coefficients(dt, tau, a1, a0, slide_cache)
                else:
                    g = -math.expm1(-dt / tau)
                    e = 1.0 - g
                    ec, es = oscillator(a1, a0, dt)
                v1 = vinf + (v - vinf) * e
                x1, xd1 = _oscillate(x, xd, ec, es, a1, a0, force)
                if (v1 + m * xd1) * sgn <= 0.0:
                    # the motor stops inside: w_m(t) from sgn-signed to 0
                    lo, hi = 0.0, dt
                    wlo, whi = (v + m * xd) * sgn, (v1 + m * xd1) * sgn
                    side = 0
                    for _ in range(80):
                        t = (lo * whi - hi * wlo) / (whi - wlo) if whi != wlo else lo
                        if not (lo < t < hi):
                            t = 0.5 * (lo + hi)
                        et = math.exp(-t / tau)
                        ec, es = oscillator(a1, a0, t)
                        _, xdt = _oscillate(x, xd, ec, es, a1, a0, force)
                        wt = (vinf + (v - vinf) * et + m * xdt) * sgn
                        lo, hi, wlo, whi, side = _illinois(lo, hi, wlo, whi, t, wt, wt <= 0.0,
                                                           side)
                        if hi - lo <= 1e-13 * Ts:
                            break
                    dt = hi
                    g = -math.expm1(-dt / tau)
                    e = 1.0 - g
                    ec, es = oscillator(a1, a0, dt)
                    x1, xd1 = _oscillate(x, xd, ec, es, a1, a0, force)
                    p += vinf * dt + (v - vinf) * tau * g
                    x, xd = x1, xd1
                    v = -m * xd  # the motor at rest
                    stuck = True  # released at once if the drive on it exceeds S
                    events += 1
                else:
                    p += vinf * dt + (v - vinf) * tau * g
                    v = v1
                    x, xd = x1, xd1
                left -= dt
        out[k + 1] = p + coupling * x
    return out


@njit(cache=True)
def simulate_axis(drive, sample_period, delay, tau, gain, coulomb, stiction, omega, zeta,
                  coupling, load_fraction, speed0, out):
    """Encoder positions of the model, relative to the first, into ``out``.

    Parameters
    ----------
    drive : ndarray, shape (n_samples,)
        u[k] [V], held over sample k; zero before the log.
    sample_period, delay : float
        Ts and d [s], d >= 0.
    tau, gain, coulomb, stiction : float
        tau [s], G = Ke*Kc [pulse/s/V], F and S [V] (S < F is read as S = F).
    omega, zeta, coupling : float
        The mode [rad/s] (0 for a rigid axis), its damping ratio and c.
    load_fraction : float
        lam, the load's share of the inertia, where the encoder is on the load
        (``coupling <= 0``); on the motor it is ``c / (1 + c)``. Read only by a two-mass
        axis with friction (:func:`_two_mass_friction`).
    speed0 : float
        Speed at sample 0 [pulse/s]; 0 starts the axis at rest (stuck).
    out : ndarray, shape (n_samples,)
        y[k] - y[0] [pulse], written.
    """
    n = drive.shape[0]
    Ts = sample_period
    lag = int(math.floor(delay / Ts))
    frac = delay / Ts - lag
    if frac > 1.0 - 1e-12:  # rounding of delay / Ts at a whole sample
        lag += 1
        frac = 0.0
    S = max(stiction, coulomb)
    modal = omega > 0.0
    if modal and S > 0.0:
        share = coupling if coupling > 0.0 else load_fraction / (1.0 - load_fraction)
        return _two_mass_friction(drive, Ts, lag, frac, tau, gain, coulomb, S, omega, zeta,
                                  coupling, share, speed0, out)
    half_damping = 0.5 * (1.0 / tau + 2.0 * zeta * omega)
    damped = math.sqrt(max(omega * omega - half_damping * half_damping, 1e-300))
    accel = gain / tau
    table = np.empty((2, 4))
    for i in range(2):
        h = frac * Ts if i == 0 else (1.0 - frac) * Ts
        table[i, 0] = h
        table[i, 1] = math.exp(-half_damping * h)
        table[i, 2] = math.cos(damped * h)
        table[i, 3] = math.sin(damped * h)
    p = 0.0
    v = speed0
    stuck = speed0 == 0.0
    x = 0.0
    xd = 0.0
    out[0] = 0.0
    for k in range(n - 1):
        for piece in range(2):
            u, h = _held_drive(drive, k, piece, lag, frac, Ts)
            if h <= 0.0:
                continue
            left = h
            while left > 0.0:
                if stuck:
                    if abs(u) <= S:
                        if modal:
                            x, xd = _mode_step(x, xd, left, 0.0, omega, half_damping, damped,
                                              table)
                        left = 0.0
                        break
                    stuck = False
                    sgn = 1.0 if u > 0.0 else -1.0
                else:
                    sgn = 1.0 if v > 0.0 else -1.0
                net = u - coulomb * sgn
                vinf = gain * net
                dt = left
                hit = False
                if vinf * sgn < 0.0:  # decelerating towards zero speed
                    tz = tau * math.log((v - vinf) / (-vinf))
                    if tz < dt:
                        dt = tz
                        hit = True
                e = math.exp(-dt / tau)
                p += vinf * dt + (v - vinf) * tau * (-math.expm1(-dt / tau))
                v = vinf + (v - vinf) * e
                if modal:
                    x, xd = _mode_step(x, xd, dt, accel * net, omega, half_damping,
                                      damped, table)
                left -= dt
                if hit:
                    v = 0.0
                    stuck = True  # released at once if |u| > S
            # (loop over pieces)
        out[k + 1] = p + coupling * x
    return out


def simulate(drive: np.ndarray, sample_period: float, params: dict,
             speed0: float = 0.0) -> np.ndarray:
    """:func:`simulate_axis` for a parameter dict (keys of :data:`PARAMETERS`); returns
    the positions, shape (n_samples,) [pulse], from 0."""
    out = np.empty(drive.shape[0])
    omega = 2.0 * math.pi * params.get("resonance_frequency", 0.0)
    return simulate_axis(np.ascontiguousarray(drive, dtype=float), float(sample_period),
                         float(params["delay"]), float(params["time_constant"]),
                         float(params["gain"]), float(params.get("coulomb_friction", 0.0)),
                         float(params.get("stiction", 0.0)), omega,
                         float(params.get("resonance_damping", 0.0)),
                         float(params.get("coupling", 0.0)),
                         float(params.get("load_fraction", 0.5)), float(speed0), out)
