"""The online step's identification of the plant (:mod:`.step`): recursive least squares of
the exact sampled model from the measured positions and the applied drives (:func:`_identify`,
its dead zone :func:`reading_knowledge`), and the state feedback gains that place the
identified deviation dynamics' poles (:func:`_pole_gains`) and the landing's law
(:func:`_landing_law`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...machine import Machine


GAIN_RANGE = 4.0
"""The estimated plant may need between 1/4 and 4 times the model's drive (issue 10 asks
for any tau, Kc within x[0.5, 2]: up to 4 times the acceleration drive)."""


@njit(cache=True)
def _gains(est, j, a, b0, c, b1, gain_range):
    """The estimated plant's drive over the model's for the plan's acceleration part (``ga =
    b0/b0'``) and speed part (``gv = Kc/Kc'``), each within [1/gain_range, gain_range] (the
    plan's ``gain_range``, :data:`GAIN_RANGE` by default); ``est`` holds axis j's identified
    (a', p1', p2', p3') (:func:`_identify`), and ``p1 + p2 + p3 = b1 + beta = Ke*Ts*b0``
    for every ZOH plant of this form, delayed or not (:func:`_drive_weights`)."""
    s_model = b1 + c * b0 - a * b1
    s_est = est[1, j] + est[2, j] + est[3, j]
    ga = s_model / s_est if s_est > s_model / gain_range else gain_range
    ga = min(max(ga, 1.0 / gain_range), gain_range)
    gv = ga * (1.0 - est[0, j]) / (1.0 - a)
    return ga, min(max(gv, 1.0 / gain_range), gain_range)


@njit(cache=True)
def _estimated_plant(est, j, b0, ga):
    """Axis j's identified ZOH plant ``(a', b0', c', b1')``: a' and b1' as estimated,
    ``b0' = b0/ga`` (:func:`_gains`) and c' from ``beta' = c'*b0' - a'*b1'``."""
    ae, b1e = est[0, j], est[1, j]
    b0e = b0 / ga
    return ae, b0e, (est[2, j] + ae * b1e) / b0e, b1e


@njit(cache=True)
def _estimated_delayed_plant(est, j, a, b0, c, b1, ga, gain_range):
    """Axis j's identified ZOH plant ``(a', b0', c', b1')`` when the drive is delayed
    (:func:`_identify` regresses the delayed plant's drive weights, :func:`_drive_weights`,
    which do not give c' and b1' one by one): the plant of the model's form whose
    ``a = exp(-Ts/tau)`` is a' (its tau within ``gain_range`` of the model's, as
    :func:`_gains` bounds the gains: a' within [a^gain_range, a^(1/gain_range)]) and
    whose steady position gain per sample of drive ``s = (1 - a)*Ke*Kc*Ts`` is the
    model's over ga (:func:`_gains`), with ``b0' = b0/ga``:
    ``c' = Ke*tau*(1 - a') = -s*(1 - a')/(ln(a')*b0')`` and ``b1' = (s - c'*b0')/(1 - a')``
    (on the model's plant: the model's own)."""
    ae = min(max(est[0, j], a ** gain_range), a ** (1.0 / gain_range))
    q = 1.0 - ae
    b0e = b0 / ga
    s = (b1 + c * b0 - a * b1) / ga
    ce = -s * q / (math.log(ae) * b0e)
    return ae, b0e, ce, (s - ce * b0e) / q


@njit(cache=True)
def _pole_gains(a, b0, c, b1, pole):
    """State-feedback gains ``(k_theta, k_w)`` that put both poles of the deviation
    dynamics of the ZOH plant ``x[k+1] = [[a, 0], [c, 1]] x[k] + [b0, b1] u[k]`` at
    ``pole`` (Ackermann's formula in closed form)."""
    det = b0 * (c * b0 + (1.0 - a) * b1)
    k_w = (b0 * c * (a + 1.0 - 2.0 * pole) - b1 * (a - pole) ** 2) / det
    k_theta = b0 * (1.0 - pole) ** 2 / det
    return k_theta, k_w


@njit(cache=True)
def _landing_gains(a, b0, c, b1, pole):
    """The landing's gains ``(k_theta, k_w, k_i)`` [V/pulse, V/(rad/s), V/(pulse*sample)]:
    the drive ``u = k_theta*e - k_w*w + k_i*z`` (e = end - theta [pulse], w [rad/s],
    ``z[k+1] = z[k] + e[k]``) puts all three poles of the ZOH plant
    ``x[k+1] = [[a, 0], [c, 1]] x[k] + [b0, b1] u[k]`` with the integrator at ``pole``.
    Ackermann's formula solved in closed form (the characteristic polynomial of the closed
    loop matched to ``(z - pole)^3``); ``d = c*b0 + (1 - a)*b1`` is the plant's position
    gain per sample of drive at steady speed, > 0 for every plant of the model's form."""
    q = 1.0 - pole
    d = c * b0 + (1.0 - a) * b1
    k_i = q ** 3 / d
    k_theta = q * q * (3.0 * d - b1 * q) / (d * d)
    k_w = -(-a ** 3 * b1 ** 2 + 2 * a ** 2 * b0 * b1 * c + 3 * a ** 2 * b1 ** 2 * pole
            - a * b0 ** 2 * c ** 2 - 6 * a * b0 * b1 * c * pole + 2 * a * b0 * b1 * c
            - 3 * a * b1 ** 2 * pole ** 2 + 3 * b0 ** 2 * c ** 2 * pole
            - 2 * b0 ** 2 * c ** 2 + 3 * b0 * b1 * c * pole ** 2 - b0 * b1 * c
            + b1 ** 2 * pole ** 3) / (b0 * d * d)
    return k_theta, k_w, k_i


HIST_ROWS = 6
"""Rows of the identification's memory per axis (:func:`_identify`)."""

N_PARAMETERS = 5
"""The identification's parameters (a, p1, p2, p3, delta) (:func:`_identify`)."""

EST_ROWS = N_PARAMETERS * (1 + N_PARAMETERS)
"""Rows of the estimate per axis: the parameters, then their covariance row-major."""


@njit(cache=True)
def _zoh_part(a, kc, ke_tau, kekc_ts, h):
    """The ZOH plant over a part ``h`` of the sample (0 < h <= 1): ``(a_h, b0_h, c_h,
    b1_h)`` with ``a_h = a**h``, ``b0_h = Kc*(1 - a_h)``, ``c_h = Ke*tau*(1 - a_h)``,
    ``b1_h = Ke*Kc*(h*Ts - tau*(1 - a_h))``."""
    ah = a ** h
    return ah, kc * (1.0 - ah), ke_tau * (1.0 - ah), kekc_ts * h - ke_tau * kc * (1.0 - ah)


@njit(cache=True)
def _plant_part(a, b0, c, b1, h):
    """The ZOH plant ``(a, b0, c, b1)`` (one sample Ts) over a part ``h`` of the sample
    (0 < h <= 1): :func:`_zoh_part` with the plant's Kc, Ke*tau and Ke*Kc*Ts from ``b0 =
    Kc*(1 - a)``, ``c = Ke*tau*(1 - a)``, ``b1 = Ke*Kc*Ts - c*Kc``."""
    ke_tau = c / (1.0 - a)
    return _zoh_part(a, b0 / (1.0 - a), ke_tau, b1 + ke_tau * b0, h)


@njit(cache=True)
def _delayed_zoh(a, b0, c, b1, delay):
    """The ZOH plant ``(a, b0, c, b1)`` (one sample Ts) with its drive arriving ``delay``
    samples late, 0 <= delay < 1: ``x[k+1] = [[a, 0], [c, 1]] x[k] + g0 u[k] + g1 u[k-1]``
    (u[k-1] holds for the first ``delay`` of the sample, u[k] for the rest). Returns
    ``(g0w, g0th, g1w, g1th)``; with no delay ``(b0, b1, 0, 0)``. The plant's tau, Kc and
    Ke follow from ``a = exp(-Ts/tau)``, ``b0 = Kc*(1 - a)``, ``c = Ke*tau*(1 - a)`` and
    ``b1 = Ke*Kc*Ts - c*Kc`` (:func:`_zoh_part`)."""
    if delay <= 0.0:
        return b0, b1, 0.0, 0.0
    kc = b0 / (1.0 - a)
    ke_tau = c / (1.0 - a)                  # Ke*tau [pulse/(rad/s)]
    kekc_ts = b1 + ke_tau * b0              # Ke*Kc*Ts [pulse/V]
    a_late, b0_late, c_late, b1_late = _zoh_part(a, kc, ke_tau, kekc_ts, 1.0 - delay)
    _, b0_held, _, b1_held = _zoh_part(a, kc, ke_tau, kekc_ts, delay)
    # u[k-1]'s effect at the sample's end: its ZOH over the delay, then the free plant
    return b0_late, b1_late, a_late * b0_held, c_late * b0_held + b1_held


@njit(cache=True)
def _drive_weights(a, b0, c, b1, delay):
    """The weights ``(p1, p2, p3)`` of u[k-1], u[k-2], u[k-3] in the position increment of
    the ZOH plant ``(a, b0, c, b1)`` whose drive arrives ``delay`` samples late
    (0 <= delay < 1, :func:`_delayed_zoh`'s ``g0, g1``): from ``x[k+1] = A x[k] + g0 u[k]
    + g1 u[k-1]``,

        dth[k] = a*dth[k-1] + g0th*u[k-1] + (g1th - a*g0th + c*g0w)*u[k-2]
                 + (c*g1w - a*g1th)*u[k-3];

    without a delay ``(b1, beta, 0)``, ``beta = c*b0 - a*b1``. Their sum is ``c*b0 + (1 -
    a)*b1`` whatever the delay (a constant drive moves the plant alike)."""
    if delay <= 0.0:
        return b1, c * b0 - a * b1, 0.0
    g0w, g0th, g1w, g1th = _delayed_zoh(a, b0, c, b1, delay)
    return g0th, g1th - a * g0th + c * g0w, c * g1w - a * g1th


LAW_ROWS = 13
"""Rows of :func:`_landing_law`'s output."""


@njit(cache=True)
def _landing_law(a, b0, c, b1, delay, pole, out):
    """The landing's law on the ZOH plant ``(a, b0, c, b1)`` whose drive arrives
    ``delay`` samples late (0 <= delay < 1), written to ``out`` (:data:`LAW_ROWS`): the
    delayed plant ``a, c, g0w, g0th, g1w, g1th`` (:func:`_delayed_zoh`: the speed from
    the last position increment and the drives that made it), the plant over the delay
    ``a_h, b0_h, c_h, b1_h`` (:func:`_plant_part`; ``1, 0, 0, 0`` without a delay: the
    state the next drive meets, predicted from the drive in flight) and the gains
    ``k_theta, k_w, k_i`` of :func:`_landing_gains`, applied to that predicted state: from
    it the drive acts for a whole sample, so the undelayed plant's three poles (plant and
    integrator) are placed at ``pole`` and the delay adds a pole at 0 (a predictor: a
    state whose drive in flight brings it to rest on the end gets no drive, where a law
    on the delayed state with all four poles at ``pole`` answered it and overshot the end
    by 34 pulses on the Pi at 0.2 m/s with 0.5 ms of delay)."""
    g0w, g0th, g1w, g1th = _delayed_zoh(a, b0, c, b1, delay)
    out[0], out[1], out[2], out[3], out[4], out[5] = a, c, g0w, g0th, g1w, g1th
    if delay > 0.0:
        out[6], out[7], out[8], out[9] = _plant_part(a, b0, c, b1, delay)
    else:
        out[6], out[7], out[8], out[9] = 1.0, 0.0, 0.0, 0.0
    out[10], out[11], out[12] = _landing_gains(a, b0, c, b1, pole)


@njit(cache=True)
def _identify(est, hist, j, position, a, b0, c, b1, dead_zone=0.0, gain_range=GAIN_RANGE,
              follow=0.0):
    """Update axis j's estimate of its sampled plant from the position measured now.

    Every plant of the model's form (docs/model.md#servo-axis, ZOH) driven by the drive u,
    arriving a known fraction of a sample late, plus a drive d it does not know (a load;
    Coulomb friction while the axis moves one way) obeys, in measured positions and
    applied drives only,

        dth[k] = a*dth[k-1] + p1*u[k-1] + p2*u[k-2] + p3*u[k-3] + delta,
        delta = (p1 + p2 + p3)*d,

    with ``dth[k] = th[k] - th[k-1]`` and the drive weights of :func:`_drive_weights`
    (without a delay p1 = b1, p2 = beta = c*b0 - a*b1, p3 = 0, and the prior's zero
    variance of p3 keeps it 0): an exact linear regression in (a, p1, p2, p3, delta)
    whatever tau, Kc and a constant d are (no speed is differenced, so the nominal plant's
    estimate stays on the model; without delta a load was read as a plant of a quarter of
    the gain, and a law placed on that plant was unstable). A Kalman filter of these four
    with the plant's three constant and delta a random walk (d may change: a load step,
    friction reversing with the motion) whose variance per sample is
    ``follow**2`` times the residual's (:func:`_position_noise`): delta is followed with
    a gain of about ``follow`` per sample. ``est`` rows 0-4 hold (a, p1, p2, p3, delta),
    rows 5-29 their covariance (row-major 5x5); ``hist`` (:data:`HIST_ROWS` rows) u[k-1],
    u[k-2] [V], th[k-1] [pulse], dth[k-1] [pulse], 1 once th[k-1] is known, and u[k-3]
    [V].

    ``dead_zone`` [pulse] (:func:`reading_knowledge`): the largest residual the reading
    alone can make (encoder counts, noise, DAC); a residual within it carries no
    information on the plant and leaves the estimate as it is, and a larger one updates
    it by its part beyond it (the dead-zone RLS of bounded noise: a single count cannot
    throw the estimate). 0 (an exact reading): every residual.
    Returns :func:`_gains` (within ``gain_range``)."""
    n = N_PARAMETERS
    noise = _position_noise(a)
    est[n + n * (n - 1) + n - 1, j] += follow * follow * noise
    if hist[4, j] > 0.0:
        y = position - hist[2, j]
        x = (hist[3, j], hist[0, j], hist[1, j], hist[5, j], 1.0)
        err = y
        for r in range(n):
            err -= est[r, j] * x[r]
        hist[3, j] = y
        hist[2, j] = position
        if dead_zone > 0.0:
            if abs(err) <= dead_zone:
                return _gains(est, j, a, b0, c, b1, gain_range)
            err -= math.copysign(dead_zone, err)
        p0 = p1 = p2 = p3 = p4 = 0.0
        for q in range(n):
            p0 += est[n + q, j] * x[q]
            p1 += est[2 * n + q, j] * x[q]
            p2 += est[3 * n + q, j] * x[q]
            p3 += est[4 * n + q, j] * x[q]
            p4 += est[5 * n + q, j] * x[q]
        p = (p0, p1, p2, p3, p4)
        gain = 1.0 / (noise + x[0] * p0 + x[1] * p1 + x[2] * p2 + x[3] * p3 + x[4] * p4)
        for r in range(n):
            est[r, j] += p[r] * gain * err
            for q in range(n):
                est[n + n * r + q, j] -= p[r] * p[q] * gain
    else:
        hist[3, j] = 0.0   # the loop starts at rest: th[0] = th[1]
        hist[4, j] = 1.0
        hist[2, j] = position
    return _gains(est, j, a, b0, c, b1, gain_range)


@njit(cache=True)
def _position_noise(a):
    """Variance [pulse^2] of the regression's residual when every position is read to one
    pulse (uniform error, variance 1/12) and enters it with weights 1, -(1 + a), a."""
    return (1.0 + (1.0 + a) ** 2 + a * a) / 12.0



def reading_knowledge(machine: Machine, a, b0, c, b1) -> dict:
    """What the online step takes from the model machine's reading of the position
    (:attr:`Machine.encoder`, :attr:`Machine.measurement_noise`,
    :attr:`Machine.dac_bits`): the identification's ``dead_zone`` [pulse], 0 for an
    exact reading and an exact drive, and the landing's ``landing_band`` [pulse], half a
    count plus 3 sigma of the noise, 0 for an exact reading.

    The regression's residual (:func:`_identify`) reads positions with weights 1,
    -(1 + a), a and drives with p1, p2, p3 (:func:`_drive_weights`, with the machine's
    delay); a reading within q/2 of the position (q = one count [pulse]) and with
    Gaussian noise sigma [pulse], and a drive within half a DAC step of the one asked
    for, leave a residual of at most
    ``(q/2 + 3*sigma)*(1 + |1 + a| + |a|) + (|p1| + |p2| + |p3|)*lsb/2`` (3 sigma: the
    noise's bound but for 0.3 % of the samples), the worst axis."""
    q = 1.0 if machine.encoder == "counts" else 0.0
    sigma = float(machine.measurement_noise)
    lsb = (2.0 * machine.max_drive / 2.0 ** machine.dac_bits
           if machine.dac_bits is not None else 0.0)
    a, b0, c, b1 = (np.asarray(v, dtype=float) for v in (a, b0, c, b1))
    delay = machine.delay / machine.sample_period
    weights = np.array([_drive_weights(*v, delay) for v in zip(a, b0, c, b1)])
    reading = (0.5 * q + 3.0 * sigma) * (1.0 + np.abs(1.0 + a) + np.abs(a))
    drive = np.abs(weights).sum(axis=1) * 0.5 * lsb
    dead_zone = float(np.max(reading + drive)) if q or sigma or lsb else 0.0
    # the landing's band (:func:`.step.online_step`, step 3'): how far the reading alone
    # can put the measured position from the true one; an error within it carries no
    # information on where the axis is, and the landing leaves it alone (no hunting on a
    # count's edge, no integrating of the noise)
    return {"dead_zone": dead_zone, "landing_band": 0.5 * q + 3.0 * sigma}
