"""The landing's speed on a reading that is not exact (issue 33: encoder counts,
measurement noise): an observer of the plant's state on the frozen identified plant, its
poles at the slowest pole of the machine's own loop (:func:`rest_observer`,
:func:`observer_gains`, docs/model.md#planned-on-a-real-machine).

The landing's law (:func:`.identify._landing_law`) took the plant's speed from the last
position increment and the drives that made it. On a reading in counts or with noise that
increment is off by up to a count (or six sigma), so the speed by a count per sample, and
the law answered it with a kick of its whole speed gain: 0.06 V per count on the die
bonder's x axis (where its position gain gives 0.02 V per count); a count's edge crossed at
rest set the axis drifting to the next edge, and so on (0.06-0.07 V RMS of chatter, item
1), and on a fast sampled random machine (Ts 0.25 ms, tau 3-15 ms) 0.29 count of noise
became +-6 V. The observer advances its last estimate by the drives applied and corrects
it by a fraction of the reading's innovation, so a count flipped by the noise moves the
speed by ``m_w`` per count, not by ``1/c``.

Its poles (:func:`.step.online_step`): at the radius of the slowest pole of the machine's
own closed loop on the model (its law, plant and delay,
:func:`nurbsmotion.plant.linear_loop_poles`: the bandwidth the machine's maker gave the
loop for this reading), but no slower than the landing's own poles (``tracking_pole``):
an observer slower than the law it feeds let the die bonder's nearly integrating x axis
swing +-3.5 pulses after the landing began on a noisy speed, and on random machines whose
own loop is slow (a PID's integral, 0.99 and more) the landing ran away (1.4e5 pulses).

The landing's own poles on such a reading (:func:`reading_pole`): ``tracking_pole`` (0.7
a sample) unless the reading's own change between two samples would then move the drive
by more than the governor's headroom, as on an axis sampled fast against its own loop
(item 4's case 130: Ts 0.1 ms, 111 V a pulse at 0.7, Umax 19.3 V; a count flipped by the
noise swung the drive between the limits); there the fastest slower poles for which it
does not.

Glossary
--------
a, c : the ZOH plant's speed pole and speed-to-position weight (:func:`.inverse.axis_zoh`);
m_w, m_theta : the observer's gains on the innovation [(rad/s)/pulse, 1];
a_h, c_h : the plant over the delay (:func:`.identify._plant_part`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...machine import Machine
from ...plant.linear import linear_loop_poles
from .identify import _landing_gains, _plant_part

__all__ = ["rest_observer", "observer_gains", "reading_gain", "reading_pole",
           "REST_OBSERVER_ROWS", "QUANTISER_GAIN", "POLE_BISECTIONS"]

REST_OBSERVER_ROWS = 2
"""Rows per axis of the plan's ``rest_observer``: 1 where the landing's speed comes from
the observer (0: from the last increment, as before), then the observer's pole."""

POLE_BISECTIONS = 30
"""Bisections of the landing's pole on a reading not exact (:func:`reading_pole`): to
3e-10 of a pole on (``landing_pole``, 1)."""

QUANTISER_GAIN = 4.0 / math.pi
"""The largest describing-function gain of a rounding quantiser of step q (one count):
``N(A) = 4q/(pi*A)*sqrt(1 - (q/(2A))^2)`` for ``q/2 <= A < 3q/2``, 0 below, largest at
``A = q/sqrt(2)``, where it is ``4/pi`` (Gelb & Vander Velde, *Multiple-Input Describing
Functions*, 1968). A limit cycle through the encoder's counts needs the loop unstable at
some gain the quantiser can have (tests/test_planned_real.py checks the landing's loop
with the observer from 1/1.1 to 4/pi*1.1, Kc 10 % off either way)."""


@njit(cache=True)
def observer_gains(a, c, pole):
    """The gains ``(m_w, m_theta)`` [(rad/s)/pulse, 1] of the observer of the ZOH plant
    ``x[k+1] = [[a, 0], [c, 1]] x[k] + (drives)``, ``x = (w, theta)``, from its position
    reading, in filtered form (``x[k|k] = x[k|k-1] + m*(y[k] - theta[k|k-1])``), whose
    estimation error decays with both poles at ``pole``: the predictor gain ``L`` that
    puts the eigenvalues of ``A - L*C`` (C = [0, 1]) at ``pole`` (``L_theta = a + 1 -
    2*pole``, ``L_w = (pole - a)^2/c``: the characteristic polynomial matched to
    ``(z - pole)^2``), and ``m = A^-1 L``."""
    l_th = a + 1.0 - 2.0 * pole
    l_w = (pole - a) ** 2 / c
    return l_w / a, l_th - c * l_w / a


@njit(cache=True)
def reading_gain(a, b0, c, b1, delay, pole, observer_pole):
    """How much the landing's drive moves [V/pulse] for a change of the reading alone, at
    once (the sample it is read): the law of :func:`.identify._landing_law` with its
    three poles at ``pole`` on the ZOH plant ``(a, b0, c, b1)`` whose drive arrives
    ``delay`` samples late, fed by this module's observer with both poles at
    ``min(observer_pole, pole)`` (:func:`observer_gains`, as :func:`.step.online_step`
    starts it). A reading dy moves the observer's speed by ``m_w*dy`` and the predicted
    position ``y + c_h*w`` (``a_h, c_h``: the plant over the delay,
    :func:`.identify._plant_part`) by ``(1 + c_h*m_w)*dy``; the drive
    ``k_theta*e - k_w*a_h*w + ...`` by ``-(k_theta*(1 + c_h*m_w) + k_w*a_h*m_w)*dy``
    (the band's dead zone on e left out: an upper bound of its position part).
    Returns ``(gain, k_w)``, the latter to tell the law's speed gain's sign."""
    k_theta, k_w, _ = _landing_gains(a, b0, c, b1, pole)
    if delay > 0.0:
        a_h, _, c_h, _ = _plant_part(a, b0, c, b1, delay)
    else:
        a_h, c_h = 1.0, 0.0
    m_w = observer_gains(a, c, min(observer_pole, pole))[0]
    return abs(k_theta * (1.0 + c_h * m_w) + k_w * a_h * m_w), k_w


@njit(cache=True)
def reading_pole(a, b0, c, b1, delay, pole, observer_pole, step, room):
    """The landing's pole on a reading not exact (:func:`.step.online_step`, step 3'):
    ``pole`` (the plan's ``landing_pole``) where a change of the reading by ``step``
    [pulse] (what the reading alone can move between two samples: a count and the
    noise's 3 sigma each side, twice the landing's band) moves the drive by at most
    ``room`` [V] (the share of Umax the governor keeps for the feedback, the plan's
    ``headroom``) (:func:`reading_gain`); else the fastest slower pole for which it does,
    by :data:`POLE_BISECTIONS` bisections on (pole, 1), no slower than where the law's speed gain
    k_w would turn negative (a law that pushes the axis along its own speed, which
    friction the model does not know turns into stick-slip): there the reading still
    moves the drive by more than ``room``. The gains fall with the pole, about as
    (1 - pole)^2 (:func:`.identify._landing_gains`): on an axis sampled fast against its
    own loop (Ts 0.1 ms, a law at ``pole`` 0.7 asking 111 V a pulse of an axis whose Umax
    is 19.3 V) a count flipped by the noise otherwise swings the drive between the limits
    while the axis stays within a pulse or two. On the plant's own bandwidth (the die
    bonder read in 1-um counts: 0.025 V a pulse at 0.7, 10 V of Umax) ``pole`` itself,
    bit for bit."""
    if reading_gain(a, b0, c, b1, delay, pole, observer_pole)[0] * step <= room:
        return pole
    lo, hi = pole, 1.0
    for _ in range(POLE_BISECTIONS):
        mid = 0.5 * (lo + hi)
        gain, k_w = reading_gain(a, b0, c, b1, delay, mid, observer_pole)
        if k_w < 0.0 or gain * step <= room:
            hi = mid
        else:
            lo = mid
    if reading_gain(a, b0, c, b1, delay, hi, observer_pole)[1] < 0.0:
        return lo    # k_w >= 0 at lo: the slowest pole the speed gain's sign allows
    return hi


def rest_observer(machine: Machine, band: float) -> np.ndarray:
    """The plan's ``rest_observer`` (shape (:data:`REST_OBSERVER_ROWS`, n_axes)): per axis
    where the model's reading is not exact (``band`` > 0, the landing's band of
    :func:`.identify.reading_knowledge`) and its model declares no mode (those keep the
    law designed with the mode, :mod:`.mode_law`), 1 and the largest pole radius of the
    machine's own linear loop on the model (its law, plant and delay; the step takes the
    faster of it and the landing's pole); zeros elsewhere
    (the landing as before: an exact reading's runs are bit-identical).

    Parameters
    ----------
    machine : Machine
        The model machine: its laws (:attr:`Machine.pid_gains`), axes, Ts and delay.
    band : float
        The landing's band [pulse]: what the reading alone can put between the measured
        and the true position.
    """
    out = np.zeros((REST_OBSERVER_ROWS, machine.n_axes))
    if not band > 0.0:
        return out
    for j, (ax, gains) in enumerate(zip(machine.axes, machine.pid_gains)):
        if ax.resonance_frequency > 0.0:
            continue
        poles = linear_loop_poles(gains, ax.time_constant, ax.electrical_gain,
                                  ax.mechanical_gain, machine.sample_period,
                                  machine.speed_measurement == "true", machine.delay)
        out[:, j] = (1.0, float(np.max(np.abs(poles))))
    return out
