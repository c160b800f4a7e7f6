"""The law ``planned`` holds the end with once its plan rests there, on a machine whose
reading is not exact (issue 33: encoder counts, measurement noise): the machine's own
position and speed gains, scaled so that the quantiser cannot sustain a limit cycle, an
integral slower than that loop, and the plant's state from an observer no faster than
that loop (:func:`rest_law`, :func:`observer_gains`,
docs/model.md#planned-on-a-real-machine).

Why not the landing's law placed at ``tracking_pole`` (:func:`.identify._landing_law`):
its gains are set per sample, not by the machine, and its speed comes from one position
increment. On a reading in counts or with noise that speed is off by up to a count (or
six sigma) per sample, and the placed law answered it with a kick (0.06 V per count on
the die bonder's x axis, where its position gain gives 0.02 V per count): a count's edge
crossed at rest set the axis drifting to the next edge, and so on (0.06-0.07 V RMS of
chatter), and on a fast sampled machine (Ts 0.25 ms, tau 3-15 ms) the same law turned
0.29 count of noise into +-6 V. The machine's own gains are the bandwidth its maker chose
for its reading, its delay and (when the machine file is checked) its mode; the
describing function of the quantiser bounds what they may be.

Glossary
--------
P, I, D : the law's gains [V/pulse, V/(pulse*s), V/(pulse/s)] (LinuxCNC ``pid``);
GM : the loop's gain margin (the largest factor on the gains for which every smaller one
keeps the loop stable); Ts : sample period [s]; a, c : the ZOH plant's speed pole and
speed-to-position weight (:func:`.inverse.axis_zoh`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numba import njit

from ...machine import Machine
from ...plant.linear import linear_loop_poles

__all__ = ["rest_law", "rest_gain_margin", "observer_gains", "REST_LAW_ROWS",
           "QUANTISER_GAIN", "INTEGRAL_TIMES", "GAIN_SPREAD"]

REST_LAW_ROWS = 5
"""Rows per axis of the plan's ``rest_law``: 1 where it holds the end (0: the landing's law,
:func:`.identify._landing_law`, unchanged), then ``k_p`` [V/pulse], ``k_d`` [V/(rad/s)]
on the observer's speed, ``k_i`` [V/(pulse*sample)] on the integral of the error beyond
the reading's band, and the observer's pole (:func:`observer_gains`)."""

QUANTISER_GAIN = 4.0 / math.pi
"""The largest describing-function gain of a rounding quantiser of step q (one count):
``N(A) = 4q/(pi*A)*sqrt(1 - (q/(2A))^2)`` for ``q/2 <= A < 3q/2``, 0 below, largest at
``A = q/sqrt(2)``, where it is ``4/pi`` (Gelb & Vander Velde, *Multiple-Input Describing
Functions*, 1968). The reading's noise and the landing's dead zone of the error have
gains within [0, 1]."""

GAIN_SPREAD = 0.10
"""How far the true axis's gain from drive to position (Kc) may be off the model's: the
10 % of issue 33 (as :data:`.mode_law.MODEL_SPREAD`)."""

INTEGRAL_TIMES = 4.0
"""The rest law's integral time over the time constant of its loop's slowest pole, where
the machine's law has no integral: ``I = P/(INTEGRAL_TIMES*T)``, ``T = -Ts/ln(r)`` with r
that pole's radius. An integral a few times slower than the loop it is added to moves
its poles little (the usual PI rule: Astrom & Hagglund, *Advanced PID Control*, 2006:
an integral time of the order of the closed loop's time constant or more); the loop with
it is checked, and the integral halved until it is stable (:func:`rest_law`)."""

_MARGIN_GRID = np.geomspace(1.0 / 64.0, 64.0, 97)
"""Factors on the law's gains at which the loop is checked (then bisected): 1/64 to 64 in
1/8-octave steps."""


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


def _radius(gains, ax, machine, factor: float) -> float:
    scaled = replace(gains, Pgain=gains.Pgain * factor, Igain=gains.Igain * factor,
                     Dgain=gains.Dgain * factor)
    poles = linear_loop_poles(scaled, ax.time_constant, ax.electrical_gain,
                              ax.mechanical_gain, machine.sample_period,
                              machine.speed_measurement == "true", machine.delay,
                              ax.resonance_frequency, ax.resonance_damping,
                              ax.load_fraction, ax.encoder_on)
    return float(np.max(np.abs(poles)))


def rest_gain_margin(gains, ax, machine: Machine) -> float:
    """The largest factor on the law ``gains``'s P, I and D (a
    :class:`~nurbsmotion.control.PidGains`) up to which the linear loop of axis ``ax`` of
    ``machine`` (its delay and declared mode, :func:`nurbsmotion.plant.linear_loop_poles`)
    is stable at every factor from 1/64 on (0 if not there; 64 at most), to 1e-3."""
    stable = 0.0
    for f in _MARGIN_GRID:
        if not _radius(gains, ax, machine, f) < 1.0:
            break
        stable = float(f)
    else:
        return float(_MARGIN_GRID[-1])
    if stable == 0.0:
        return 0.0
    lo, hi = stable, stable * _MARGIN_GRID[1] / _MARGIN_GRID[0]
    while hi - lo > 1e-3 * lo:
        mid = 0.5 * (lo + hi)
        if _radius(gains, ax, machine, mid) < 1.0:
            lo = mid
        else:
            hi = mid
    return lo


def rest_law(machine: Machine, band: float) -> np.ndarray:
    """The plan's ``rest_law`` (shape (:data:`REST_LAW_ROWS`, n_axes)).

    Per axis, where the model's reading is not exact (``band`` > 0, the landing's band of
    :func:`.identify.reading_knowledge`) and its model declares no mode (those keep the
    law designed with the mode, :mod:`.mode_law`):

    - the machine's own P and D gains scaled by ``s = min(1, GM/(QUANTISER_GAIN*(1 +
      GAIN_SPREAD)))``, GM the gain margin of their loop (:func:`rest_gain_margin`, P and
      D alone, stable down to no gain at all). By the describing function a limit cycle
      through the quantiser needs the loop unstable at some gain within the quantiser's
      [0, 4/pi]; scaled so, the loop is stable at every gain up to 4/pi times the law's
      with Kc 10 % above the model's, so it predicts none;
    - an integral: the machine's own I gain, or without one ``P/(INTEGRAL_TIMES*T)``
      (:data:`INTEGRAL_TIMES`), scaled by s and halved until the loop with it is stable
      at the law's gains times 1/1.1, 1 and 4/pi*1.1. It acts on the error beyond the
      band only (step 3' of :func:`.step.online_step`): within a count of the end, where
      the quantiser's gain falls to 0 and a loop with an integral would hunt (it is
      unstable at low gains), the law is P and D;
    - the observer's pole at the radius r of the scaled PD loop's slowest pole (no faster
      than the loop it feeds: what it filters of the reading is what that loop would not
      follow).

    Zeros elsewhere (the landing's law as before; bit-identical).

    Parameters
    ----------
    machine : Machine
        The model machine: its laws (:attr:`Machine.pid_gains`), axes, Ts and delay.
    band : float
        The landing's band [pulse]: what the reading alone can put between the measured
        and the true position.
    """
    out = np.zeros((REST_LAW_ROWS, machine.n_axes))
    if not band > 0.0:
        return out
    Ts = machine.sample_period
    for j, (ax, gains) in enumerate(zip(machine.axes, machine.pid_gains)):
        if ax.resonance_frequency > 0.0:
            continue
        pd = replace(gains, Igain=0.0)
        margin = rest_gain_margin(pd, ax, machine)
        s = min(1.0, margin / (QUANTISER_GAIN * (1.0 + GAIN_SPREAD)))
        if not s > 0.0:
            continue   # no stable scaling of the machine's law: the landing's law
        r = _radius(pd, ax, machine, s)
        if gains.Igain > 0.0:
            integral = gains.Igain
        else:
            slowest = -Ts / math.log(r) if 0.0 < r < 1.0 else Ts
            integral = gains.Pgain / (INTEGRAL_TIMES * slowest)
        law = replace(pd, Igain=integral)
        for _ in range(60):
            if all(_radius(law, ax, machine, s * f) < 1.0
                   for f in (1.0 / (1.0 + GAIN_SPREAD), 1.0,
                             QUANTISER_GAIN * (1.0 + GAIN_SPREAD))):
                break
            law = replace(law, Igain=0.5 * law.Igain)
        else:
            law = pd
        # k_d on the plant's speed [rad/s] (the observer's; the law's D is per pulse/s,
        # Ke pulse/rad)
        out[:, j] = (1.0, s * law.Pgain, s * law.Dgain * ax.mechanical_gain,
                     s * law.Igain * Ts, r)
    return out
