"""The online step's identification of the plant (:mod:`.step`): recursive least squares of
the exact sampled model from the measured positions and the applied drives (:func:`_identify`,
its dead zone :func:`reading_knowledge`), and the state feedback gains that place the
identified deviation dynamics' poles (:func:`_pole_gains`).
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
    (a', b1', beta') (:func:`_identify`), and ``b1 + beta = Ke*Ts*b0`` for every ZOH plant
    of this form."""
    s_model = b1 + c * b0 - a * b1
    s_est = est[1, j] + est[2, j]
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
def _pole_gains(a, b0, c, b1, pole):
    """State-feedback gains ``(k_theta, k_w)`` that put both poles of the deviation
    dynamics of the ZOH plant ``x[k+1] = [[a, 0], [c, 1]] x[k] + [b0, b1] u[k]`` at
    ``pole`` (Ackermann's formula in closed form)."""
    det = b0 * (c * b0 + (1.0 - a) * b1)
    k_w = (b0 * c * (a + 1.0 - 2.0 * pole) - b1 * (a - pole) ** 2) / det
    k_theta = b0 * (1.0 - pole) ** 2 / det
    return k_theta, k_w


@njit(cache=True)
def _identify(est, hist, j, position, a, b0, c, b1, dead_zone=0.0, gain_range=GAIN_RANGE):
    """Update axis j's estimate of its sampled plant from the position measured now.

    Every plant of the model's form (docs/model.md#servo-axis, ZOH) obeys, in measured positions
    and applied drives only,

        dth[k] = a*dth[k-1] + b1*u[k-1] + beta*u[k-2],   beta = c*b0 - a*b1,

    with ``dth[k] = th[k] - th[k-1]``: an exact linear regression in (a, b1, beta) whatever
    tau and Kc are (no speed is differenced, so the nominal plant's estimate stays on the
    model). Recursive least squares from the model's values, with the residual of an
    encoder read to one pulse (:func:`_position_noise`). ``est`` rows 0-2 hold
    (a, b1, beta), rows 3-11 their covariance (row-major 3x3); ``hist`` rows u[k-1],
    u[k-2] [V], th[k-1] [pulse], dth[k-1] [pulse] and 1 once th[k-1] is known.

    ``dead_zone`` [pulse] (:func:`identification_dead_zone`): the largest residual the
    reading alone can make (encoder counts, noise, DAC); a residual within it carries no
    information on the plant and leaves the estimate and its covariance as they are, and
    a larger one updates them by its part beyond it (the dead-zone RLS of bounded noise:
    a single count cannot throw the estimate). 0 (an exact reading): every residual.
    Returns :func:`_gains` (within ``gain_range``)."""
    if hist[4, j] > 0.0:
        y = position - hist[2, j]
        x0, x1, x2 = hist[3, j], hist[0, j], hist[1, j]
        p0 = est[3, j] * x0 + est[4, j] * x1 + est[5, j] * x2
        p1 = est[6, j] * x0 + est[7, j] * x1 + est[8, j] * x2
        p2 = est[9, j] * x0 + est[10, j] * x1 + est[11, j] * x2
        err = y - est[0, j] * x0 - est[1, j] * x1 - est[2, j] * x2
        if dead_zone > 0.0:
            if abs(err) <= dead_zone:
                hist[3, j] = y
                hist[2, j] = position
                return _gains(est, j, a, b0, c, b1, gain_range)
            err -= math.copysign(dead_zone, err)
        gain = 1.0 / (_position_noise(a) + x0 * p0 + x1 * p1 + x2 * p2)
        est[0, j] += p0 * gain * err
        est[1, j] += p1 * gain * err
        est[2, j] += p2 * gain * err
        est[3, j] -= p0 * p0 * gain
        est[4, j] -= p0 * p1 * gain
        est[5, j] -= p0 * p2 * gain
        est[6, j] -= p1 * p0 * gain
        est[7, j] -= p1 * p1 * gain
        est[8, j] -= p1 * p2 * gain
        est[9, j] -= p2 * p0 * gain
        est[10, j] -= p2 * p1 * gain
        est[11, j] -= p2 * p2 * gain
        hist[3, j] = y
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
    -(1 + a), a and drives with b1, beta; a reading within q/2 of the position (q = one
    count [pulse]) and with Gaussian noise sigma [pulse], and a drive within half a DAC
    step of the one asked for, leave a residual of at most
    ``(q/2 + 3*sigma)*(1 + |1 + a| + |a|) + (|b1| + |beta|)*lsb/2`` (3 sigma: the noise's
    bound but for 0.3 % of the samples), the worst axis."""
    q = 1.0 if machine.encoder == "counts" else 0.0
    sigma = float(machine.measurement_noise)
    lsb = (2.0 * machine.max_drive / 2.0 ** machine.dac_bits
           if machine.dac_bits is not None else 0.0)
    a, b0, c, b1 = (np.asarray(v, dtype=float) for v in (a, b0, c, b1))
    beta = c * b0 - a * b1
    reading = (0.5 * q + 3.0 * sigma) * (1.0 + np.abs(1.0 + a) + np.abs(a))
    drive = (np.abs(b1) + np.abs(beta)) * 0.5 * lsb
    dead_zone = float(np.max(reading + drive)) if q or sigma or lsb else 0.0
    # the landing's band (:func:`.step.online_step`, step 3'): how far the reading alone
    # can put the measured position from the true one; an error within it carries no
    # information on where the axis is, and the landing leaves it alone (no hunting on a
    # count's edge, no integrating of the noise)
    return {"dead_zone": dead_zone, "landing_band": 0.5 * q + 3.0 * sigma}
