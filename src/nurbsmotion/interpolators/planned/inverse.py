"""Step 3 of the plan (:mod:`.plan`): the drive sequence whose response is the desired
motion, by the zero-phase-error inverse of the exact ZOH plant (:func:`axis_zoh`) and rounds
of pre-compensation (:func:`_precompensate`, :func:`_drive_sequence`), with the constants
that fix where the desired motion starts (:data:`LEAD`) and rests (:data:`END_REST`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ...machine import Machine
from ...servo import zoh_coefficients


PRECOMPENSATION_TOLERANCE = 0.25
"""The pre-compensation of step 3 runs until the realised position is within this many
pulses of the desired one on every axis (a quarter of the encoder's resolution: a
position error the loop cannot even see is left alone)."""

PRECOMPENSATION_ROUNDS = 200
"""At most this many rounds of the pre-compensation. Each round multiplies the position
error of a motion component of frequency f by about ``sin(pi*f*Ts)^2``: the motion's
slow part converges in a few rounds, the part near the Nyquist frequency (the sharpest
turns of a curved path at speed, which the sampled plant's zero near -1 barely passes)
in tens to hundreds; what is left is reported by the plan's position."""

LEAD = 0
"""Sample at which the desired motion leaves the start: the plan's drive u[LEAD] is the
first that moves the plant (the loop applies it: ``planned`` registers its step from
sample 0, :func:`nurbsmotion.stepping.first_sample`); the averaged profile's first moving
sample is y[LEAD + 1] (step 3 holds the commanded positions at the start through sample
LEAD + 1 and meets y[LEAD + 1] with the commanded position of sample LEAD + 2). An
interpolator whose sample 0 is the start would lead by 1 (one dead sample)."""

END_REST = 10
"""Samples at rest on the end appended to the desired motion before step 3 (a parameter of
the pre-compensation, like its rounds). It holds the last two commanded positions on
the end (at rest: u = 0, w = 0), and what it cannot correct collects next to them; these
samples put that place where the motion is already at rest, so that the approach to the
end is met (on the die-bonder, with 3 such samples the last one before them missed the
end by up to 1.4 pulses, an overshoot; with 10, by under 0.03)."""

INVERSE_REACH = 3
"""Samples over which a desired position shapes the drive of step 3 (the zero-phase
inverse reads the commanded positions one sample either side of the speed it gives, and
the drive is the speed's difference): step 4 eases the drive limit over the distance the
motion covers in this many samples plus the one of the averaging, and step 5 lands up to
this many samples plus one before the desired motion arrives, changing at most as many
drives."""


def axis_zoh(machine: Machine):
    """Per-axis coefficients ``(a, b0, c, b1)`` of the exact ZOH plant, each shape (n_axes,)
    (:func:`nurbsmotion.servo.zoh_coefficients`)."""
    return zoh_coefficients(machine.tau, machine.Kc, machine.Ke, machine.sample_period)


@njit(cache=True)
def _realise_into(y_cmd, alpha, beta, a, b0, w, theta, u):
    """Speed ``w``, position ``theta`` and drive ``u`` (written, each shape (n, n_axes))
    of the model's plant under the zero-phase-error inverse of the commanded positions
    ``y_cmd`` (shape (n, n_axes), at rest at both ends), in one pass per axis: with
    ``d[k] = y[k+1] - y[k]``, ``w[k] = (beta*d[k-1] + alpha*d[k]) / (alpha + beta)^2``,
    ``u[k] = (w[k+1] - a*w[k]) / b0`` (0 at the last sample, as w) and
    ``theta[k+1] = y[0] + sum_{i<=k} (alpha*w[i] + beta*w[i+1])``."""
    n = y_cmd.shape[0]
    for j in range(y_cmd.shape[1]):
        gain = (alpha[j] + beta[j]) * (alpha[j] + beta[j])
        d_prev = 0.0
        for k in range(n - 1):
            d = y_cmd[k + 1, j] - y_cmd[k, j]
            w[k, j] = (beta[j] * d_prev + alpha[j] * d) / gain
            d_prev = d
        w[n - 1, j] = 0.0
        theta[0, j] = y_cmd[0, j]
        total = 0.0
        for k in range(n - 1):
            u[k, j] = (w[k + 1, j] - a[j] * w[k, j]) / b0[j]
            total += alpha[j] * w[k, j] + beta[j] * w[k + 1, j]
            theta[k + 1, j] = y_cmd[0, j] + total
        u[n - 1, j] = 0.0


class _InversePlant(NamedTuple):
    """The model plant as the zero-phase-error inverse reads it (:func:`_realise_into`),
    each shape (n_axes,): ``alpha = c - a*beta`` and ``beta = b1/b0`` [pulse/(rad/s)] weigh
    the speeds of two samples in a position increment, ``a`` and ``b0`` give the drive
    [V] from two speeds (:func:`axis_zoh`)."""

    alpha: np.ndarray
    beta: np.ndarray
    a: np.ndarray
    b0: np.ndarray


@njit(cache=True, fastmath={"nnan", "ninf", "nsz"})  # max in any order: exact
def _precompensate(y, plant, rounds, limit, slack, y_cmd, sets, peaks):
    """:func:`_drive_sequence`'s rounds, compiled: ``y_cmd`` (in: ``y``, C-contiguous, shape (n,
    n_axes)) is corrected by the realised position's error each round, through the ``plant``
    (an :class:`_InversePlant`). ``sets``, two ``(w, theta, u)`` (each shape (n, n_axes)),
    receive two rounds. Returned are a set (0 or 1) and whether it is accepted: the set
    holding the round with the smallest error whose drive stays within ``limit``, accepted
    if that error is within ``slack`` [pulse] of the smallest error of any round (-1 and not
    accepted if no round is within the limit). The two sets take turns, so no round is
    copied, and they are separate arrays, so the caller keeps the one it returns without the
    other. ``peaks`` (n,) receives the largest |drive| of every sample [V] in the round with
    the smallest error when that round's drive exceeds ``limit`` (where the drive limit must
    be eased; the round is not accepted then)."""
    n, n_axes = y.shape
    yf, cf = y.reshape(-1), y_cmd.reshape(-1)
    best_error = math.inf
    least_error = math.inf
    best = -1
    cur = 0
    for _ in range(rounds + 1):
        if cur == 0:
            w, theta, u = sets[0]
        else:
            w, theta, u = sets[1]
        _realise_into(y_cmd, plant.alpha, plant.beta, plant.a, plant.b0, w, theta, u)
        tf, uf = theta.reshape(-1), u.reshape(-1)
        worst = 0.0
        peak = 0.0
        for i in range(yf.shape[0]):  # flat: no branch, vectorised
            worst = max(worst, abs(yf[i] - tf[i]))
            peak = max(peak, abs(uf[i]))
        if worst < least_error:
            least_error = worst
        if worst == least_error and peak > limit:  # the round nearest y, beyond the limit
            for k in range(n):
                top = 0.0
                for j in range(n_axes):
                    top = max(top, abs(u[k, j]))
                peaks[k] = top
        improved = worst < best_error and peak <= limit
        if improved:
            best_error = worst
            best = cur
        if worst <= PRECOMPENSATION_TOLERANCE:
            break
        for i in range((LEAD + 2) * n_axes, max((LEAD + 2) * n_axes, (n - 2) * n_axes)):
            cf[i] += yf[i] - tf[i]
        for k in range(min(LEAD + 2, n)):  # w = 0 through sample LEAD: at rest till then
            for j in range(n_axes):
                y_cmd[k, j] = y[0, j]
        for k in range(max(0, n - 2), n):  # at rest on the end
            for j in range(n_axes):
                y_cmd[k, j] = y[n - 1, j]
        if improved:  # keep it: the next round goes to the other set
            cur = 1 - cur
    return best, best >= 0 and best_error <= least_error + slack


def _drive_sequence(y: np.ndarray, machine: Machine, rounds: int,
                    limit: float = math.inf, slack: float = math.inf):
    """Step 3: the drive sequence whose response follows ``y`` (see module docstring):
    ``(w, theta, u)``, each shape (n, n_axes), or None, and the largest |drive| of every
    sample [V], shape (n,), in the round nearest ``y``.

    Rounds of pre-compensation until the realised position is within
    :data:`PRECOMPENSATION_TOLERANCE` of ``y`` or ``rounds`` are done. Returned is the
    round with the smallest position error among those whose drive stays within ``limit``
    [V], if that error is within ``slack`` [pulse] of the smallest error of any round
    (the rest of the error is motion the drive cannot make); None otherwise (the peaks
    say where the limit is exceeded)."""
    a, b0, c, b1 = axis_zoh(machine)
    beta = b1 / b0
    alpha = c - a * beta
    y = np.ascontiguousarray(y, dtype=float)
    sets = [tuple(np.empty_like(y) for _ in range(3)) for _ in range(2)]
    peaks = np.empty(len(y))
    kept, accepted = _precompensate(y, _InversePlant(alpha, beta, a, b0), rounds,
                                    float(limit), float(slack), y.copy(),
                                    (sets[0], sets[1]), peaks)
    return (sets[kept] if accepted else None), peaks
