"""The online step's disturbance observer (:mod:`.step`, the tracking): the drive the axis
gets besides the one asked for, estimated from every position increment on the identified
plant (:func:`_observe`), kept per direction of the plan's motion so that Coulomb
friction's sign is fed forward before the axis moves or reverses (:func:`_for_direction`).
docs/model.md#planned-on-a-real-machine says why this design.

Glossary
--------
d : the input-equivalent disturbance [V] (a load, Coulomb friction while the axis moves one
way), added to the drive u [V]; dth : position increment over a sample [pulse]; sigma : the
direction of the plan's motion of an axis (-1, 0 at rest, +1).
"""

from __future__ import annotations

import math

from numba import njit

DOB_ROWS = 9
"""Rows of the observer's state per axis: 0 the estimate d [V] in force; 1 whether any
increment has moved it (0: never, so it is exactly 0 and the step is the one without an
observer); 2 the direction of the plan's motion it is the estimate of (-1, 0, +1); 3-5 the
last estimate in each direction (-1, 0, +1) [V]; 6-8 whether each was observed."""

ROUNDING_FLOOR = 1e-6
"""The observer's least dead zone [pulse]: a residual of a position increment within it
is the double's rounding of the plant's and the model's arithmetic (positions of up to
1e8 pulses round to 1e-8), not a drive; on the die bonder 1e-6 pulse is 3e-8 V of
disturbance. An exact reading of the model's own plant thus leaves the estimate at
exactly 0 and the run bit for bit the one without an observer."""

DOB_GAIN = 1.0

REST_SPEED = 0.01
"""The plan rests an axis (sigma = 0) where its speed would move it less than this
[pulse] over a sample: a hundredth of a pulse. The plan's waver about a rest (the
inverse's leakage onto an axis held still, through the sampled plant's zero near -1:
below 1e-3 pulse per sample on the die bonder's Pi and butterfly) is no motion, and a
move from rest passes it within its first sample (a drive of 0.01/b1 V, 1.6 mV on the
die bonder's x axis, does)."""


@njit(cache=True)
def _observe(dob, j, position, hist, a, p1, p2, p3, dead_zone):
    """Update axis j's disturbance estimate from the position measured now, before the
    identification takes it (:func:`.identify._identify`, whose memory ``hist`` and
    estimate ``est`` it reads: th[k-1], dth[k-1], u[k-1], u[k-2], u[k-3] and the identified
    (a, p1, p2, p3)).

    The increment of every plant of the model's form obeys ``dth[k] = a*dth[k-1] +
    p1*(u[k-1] + d) + p2*(u[k-2] + d) + p3*(u[k-3] + d)`` for a drive d constant over the
    last three samples (:func:`.identify._identify`); its residual with the estimate in
    force, beyond the reading's ``dead_zone`` [pulse] (at least :data:`ROUNDING_FLOOR`),
    is the disturbance's change times ``S = p1 + p2 + p3`` (the identified S, within
    ``gain_range`` of the model's ``s_model``), and the estimate takes all of it: the
    observer's pole is at 0 (deadbeat: the increment equation holds exactly with the new
    estimate). A residual the reading alone can make leaves it as it is: one count cannot
    throw it (the dead-zone update of bounded noise, as the identification's)."""
    if hist[4, j] == 0.0:
        return
    dth = position - hist[2, j]
    zone = max(dead_zone, ROUNDING_FLOOR)
    if dth * hist[3, j] <= 0.0 or abs(dth) <= zone:
        return   # at rest, stopping or reversing: friction is no constant drive there
    d = dob[0, j]
    r = (position - hist[2, j] - a * hist[3, j] - p1 * (hist[0, j] + d)
         - p2 * (hist[1, j] + d) - p3 * (hist[5, j] + d))
    if abs(r) <= zone:
        return
    r -= math.copysign(zone, r)
    dob[0, j] = d + DOB_GAIN * r / (p1 + p2 + p3)
    dob[1, j] = 1.0


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
