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
(``r`` the load's share of the inertia), ``c = -1`` on the load. While the rigid body is
stuck, the net drive on it is zero and the mode rings freely. (That the rigid body, not
the motor alone, sticks is the fit's simplification of a two-mass axis with friction on
its motor.)

Each sample is integrated in closed form, piece by piece: the rigid part as a first-order
lag to the instant its speed reaches zero (``t = tau * log((v0 - vinf) / -vinf)``), where
it sticks or reverses; the mode as a damped oscillator with a constant input. No
sub-steps, no ODE solver: the same numbers at any sample period.

Glossary
--------
u : drive [V]; p, y : position [pulse]; v : speed [pulse/s]; tau : time constant [s];
G : Ke*Kc, speed per volt [pulse/s/V]; F : Coulomb friction [V]; S : stiction [V];
omega : mode's angular frequency [rad/s]; zeta : its damping ratio; c : its coupling into
the encoder; Ts : sample period [s]; d : delay [s].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

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
def simulate_axis(drive, sample_period, delay, tau, gain, coulomb, stiction, omega, zeta,
                  coupling, speed0, out):
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
            if piece == 0:
                j = k - lag - 1
                h = frac * Ts
            else:
                j = k - lag
                h = (1.0 - frac) * Ts
            if h <= 0.0:
                continue
            u = drive[j] if j >= 0 else 0.0
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
                         float(params.get("coupling", 0.0)), float(speed0), out)
