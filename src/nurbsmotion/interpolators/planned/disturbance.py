"""The online step's disturbance observer (:mod:`.step`, the tracking; opt-in,
``PlannedPlan.disturbance_observer``): the axis' speed, position and the drive d it gets
besides the one asked for, estimated by a deadbeat current estimator on the model's plant
(:func:`observer_gains`, :func:`_observe`), d fed forward per direction of the plan's
motion so that Coulomb friction's sign is fed forward before the axis reverses
(:func:`_for_direction`), and the deviation d made before it was estimated kept apart
and rejected deadbeat (:func:`_made`, :func:`_rejected`).
docs/model.md#planned-on-a-real-machine says why this design, and gives the lower bound of
a load step's deviation.

Glossary
--------
d : the input-equivalent disturbance [V] (a load, Coulomb friction while the axis moves one
way), added to the drive u [V]; nu : the reading's innovation [pulse]; sigma : the
direction of the plan's motion of an axis (-1, 0 at rest, +1).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

DOB_ROWS = 14
"""Rows of the observer's state per axis: 0 the estimate d [V] in force; 1 whether any
reading has moved the observer off the model's prediction (0: never, so d is exactly 0
and the step is the one without an observer); 2 the direction of the plan's motion d is
the estimate of (-1, 0, +1); 3-5 the last estimate in each direction (-1, 0, +1) [V]; 6-8
whether each was observed; 9 and 10 the plant's speed [rad/s] and position [pulse]
estimated at this sample (:func:`_observe`); 11 and 12 the deviation the disturbance
made before it was estimated, as the tracking sees it (at the state the next drive meets:
position [pulse], speed [rad/s], plan minus plant), which the tracking rejects at
:data:`REJECTION_POLE` (:func:`_made`, :func:`_rejected`); 13 1 once the observer has
started (on the first reading, the axis at rest)."""

REJECTION_POLE = 0.0
"""The pole at which the tracking rejects the deviation a disturbance made before the
observer had it (rows 11-12 of :data:`DOB_ROWS`): 0, deadbeat, two samples. That
deviation is the observer's own record (its corrections times the model's response), not
a reading, so no count or noise is in it; from the state a drive step delta made in one
sample, the deadbeat drives of the model's form are -2*delta and +delta whatever the
plant (a near-integrating axis: A ~ [[1, 0], [c, 1]], B ~ (b0, c*b0/2)), so it asks
about twice the disturbance's step. The plan's own deviation keeps ``tracking_pole``."""

ROUNDING_FLOOR = 1e-6
"""The observer's least dead zone [pulse]: a residual of a position increment within it
is the double's rounding of the plant's and the model's arithmetic (positions of up to
1e8 pulses round to 1e-8), not a drive; on the die bonder 1e-6 pulse is 3e-8 V of
disturbance. An exact reading of the model's own plant thus leaves the estimate at
exactly 0 and the run bit for bit the one without an observer."""

REST_SPEED = 0.01
"""The plan rests an axis (sigma = 0) where its speed would move it less than this
[pulse] over a sample: a hundredth of a pulse. The plan's waver about a rest (the
inverse's leakage onto an axis held still, through the sampled plant's zero near -1:
below 1e-3 pulse per sample on the die bonder's Pi and butterfly) is no motion, and a
move from rest passes it within its first sample (a drive of 0.01/b1 V, 1.6 mV on the
die bonder's x axis, does)."""


def observer_gains(a, b0, c, b1, pole: float = 0.0) -> np.ndarray:
    """The gains ``(L_w, L_th, L_d)`` of :func:`_observe` per axis, shape (3, n_axes)
    [rad/s/pulse, 1, V/pulse]: the current estimator of the model's plant with a constant
    unknown drive d, ``x = (w, th, d)``, ``x[k+1] = F x[k] + G u`` with ``F = [[a, 0,
    b0], [c, 1, b1], [0, 0, 1]]`` and the position read, ``x+ = x- + L*(th - th-)``, whose
    error ``(I - L*C)*F`` has all three poles at ``pole`` (Ackermann's formula for the
    dual, ``L = (F - pole*I)^3 O^-1 e3`` with ``O = [C F; C F^2; C F^3]``). At ``pole`` 0
    (the default, the rigid axes' opt-in observer) deadbeat: any error of the model's
    form, a step of d included, is gone three samples after it arose, and ``L_th`` is 1
    (the position estimated is the one read); an axis with a mode takes the pole its
    design allows (:func:`.mode_law.mode_disturbance_observer`). The drive's known delay
    is an input, not in F: the gains are the undelayed plant's."""
    out = []
    for v in zip(*(np.atleast_1d(np.asarray(x, dtype=float)) for x in (a, b0, c, b1))):
        aj, b0j, cj, b1j = v
        F = np.array([[aj, 0.0, b0j], [cj, 1.0, b1j], [0.0, 0.0, 1.0]])
        C = np.array([0.0, 1.0, 0.0])
        O = np.vstack([C @ F, C @ F @ F, C @ F @ F @ F])
        out.append(np.linalg.matrix_power(F - pole * np.eye(3), 3)
                   @ np.linalg.solve(O, np.array([0.0, 0.0, 1.0])))
    # C order, as every other plan array (one compiled signature for the loop)
    return np.ascontiguousarray(np.array(out, dtype=float).T.reshape(3, -1))


@njit(cache=True)
def _observe(dob, j, position, increment, hist, a, b0, c, b1, g0w, g0th, g1w, g1th, gain,
             dead_zone):
    """Update axis j's estimate of its speed, position and the drive d it gets besides u
    (rows 9, 10, 0) from the position measured now, before the identification takes it
    (:func:`.identify._identify`, whose memory ``hist`` it reads: u[k-1], u[k-2]; the
    loop starts at rest, so on the first reading the estimate is that reading at rest).
    Returns the correction's innovation [pulse] (0: none).

    Prediction on the model's plant, the drives through its known delay (``g0w, g0th,
    g1w, g1th``, :func:`.identify._delayed_zoh`) and d on the plant itself (``b0, b1``),
    then the reading's innovation beyond the reading's ``dead_zone`` [pulse] (at least
    :data:`ROUNDING_FLOOR`) corrects all three with the ``gain`` (L_w, L_th, L_d)
    (:func:`observer_gains`: deadbeat on a rigid axis); ``increment`` [pulse], the
    reading's last increment (on an axis with a mode less the model's twist's,
    :mod:`.shaper`). An innovation the reading alone can make leaves the prediction as it
    is: one count cannot throw the estimate (the dead-zone update of
    bounded noise, as the identification's); on the model's own plant read exactly every
    innovation is the double's rounding, so nothing moves. d is corrected only while the
    axis moves (its increment beyond the dead zone): a still axis is held by friction with
    whatever drive it has, up to the stiction, and d read there wound up like an integral
    (stick-slip of a resting axis). Returns 0 then too (no deviation is recorded)."""
    if dob[13, j] == 0.0:
        dob[13, j] = 1.0
        dob[9, j] = 0.0
        dob[10, j] = position
        return 0.0
    w, th, d = dob[9, j], dob[10, j], dob[0, j]
    u1, u2 = hist[0, j], hist[1, j]
    th_p = th + c * w + g0th * u1 + g1th * u2 + b1 * d
    w_p = a * w + g0w * u1 + g1w * u2 + b0 * d
    nu = position - th_p
    zone = max(dead_zone, ROUNDING_FLOOR)
    if abs(nu) <= zone:
        nu = 0.0
    else:
        nu -= math.copysign(zone, nu)
        dob[1, j] = 1.0
    dob[9, j] = w_p + gain[0, j] * nu
    dob[10, j] = th_p + gain[1, j] * nu
    if abs(increment) <= zone:
        # at rest, stopping or reversing friction is no constant drive (it holds the axis
        # with whatever the drive is, up to the stiction): the state follows the reading,
        # d stays the one the axis slid with
        return 0.0
    dob[0, j] = d + gain[2, j] * nu
    return nu


@njit(cache=True)
def _made(dob, j, nu, gain, a_h, b0_h, c_h, b1_h):
    """Add to axis j's record of the deviation the disturbance made (rows 11-12, plan
    minus plant) what the observer's correction by the innovation ``nu`` [pulse] found
    (``gain``, :func:`observer_gains`), carried over the model's delay to the state the
    next drive meets (the model's plant over the delay ``a_h, b0_h, c_h, b1_h``; 1, 0, 0,
    0 without one: the estimate is fed forward from the next drive on)."""
    dw, dth, dd = gain[0, j] * nu, gain[1, j] * nu, gain[2, j] * nu
    dob[11, j] -= dth + c_h * dw + b1_h * dd
    dob[12, j] -= a_h * dw + b0_h * dd


@njit(cache=True)
def _rejected(dob, j, a, b0, c, b1, k_th, k_w):
    """Axis j's drive [V] that rejects the deviation the disturbance made (rows 11-12,
    plan minus plant, gains ``k_th``, ``k_w`` at :data:`REJECTION_POLE`), and that record
    advanced over the sample under it on the model's plant (a, b0, c, b1)."""
    e_th, e_w = dob[11, j], dob[12, j]
    v = k_th * e_th + k_w * e_w
    dob[11, j] = e_th + c * e_w - b1 * v
    dob[12, j] = a * e_w - b0 * v
    return v


@njit(cache=True)
def _direction(w, ke_ts):
    """sigma of a plan speed ``w`` [rad/s], ``ke_ts`` = Ke*Ts [pulse/(rad/s)]
    (:data:`REST_SPEED`)."""
    if abs(w) * ke_ts < REST_SPEED:
        return 0.0
    return 1.0 if w > 0.0 else -1.0


@njit(cache=True)
def _for_direction(dob, j, sigma):
    """The estimate for the plan's direction ``sigma`` at the next clock (the motion this
    sample's drive is for): the estimate in force is kept as the last of the direction it
    was observed in, and where the plan moves the axis another way, that direction's last
    estimate, if it has one, takes its place (Coulomb friction flips with the motion, a
    load does not; at rest friction holds the axis and a load still acts: each direction
    has its own; a direction the plan moved the axis in before any increment moved the
    estimate had none: 0). Returns the estimate [V]."""
    k = int(dob[2, j]) + 1
    if dob[1, j] == 0.0:
        dob[6 + int(sigma) + 1, j] = 1.0
        dob[2, j] = sigma
        return 0.0
    dob[3 + k, j] = dob[0, j]
    dob[6 + k, j] = 1.0
    if sigma != dob[2, j]:
        k = int(sigma) + 1
        if dob[6 + k, j] != 0.0:
            dob[0, j] = dob[3 + k, j]
        elif dob[2, j] != 0.0:
            # a direction not seen yet: the part of the estimate that opposed the motion
            # is taken for Coulomb friction f >= 0 (it flips with the motion, and is
            # none at rest), the rest for a load (d = load - f*sigma)
            s = dob[2, j]
            f = max(0.0, -s * dob[0, j])
            dob[0, j] = dob[0, j] + f * s - f * sigma
        dob[2, j] = sigma
    return dob[0, j]


@njit(cache=True)
def _hold(dob, j, error, dth, k_i, zone):
    """Where the plan rests axis j and the axis is held short of the plan (``error`` =
    plan - measured [pulse] beyond ``zone`` [pulse], its last increment ``dth`` within it):
    friction holds it, with a drive the observer cannot take from a still axis. The
    estimate then integrates the error, ``d -= k_i*error`` [V] per sample (``k_i``
    [V/(pulse*sample)], the landing's integral gain at the tracking's pole,
    :func:`.identify._landing_gains`), until the axis breaks away; once it slides, the
    increments take over (:func:`_observe`)."""
    if abs(dth) > zone or abs(error) <= zone:
        return
    dob[0, j] -= k_i * (error - math.copysign(zone, error))
    dob[1, j] = 1.0
