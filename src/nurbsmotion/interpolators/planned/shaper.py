"""A known mode planned through: the plan's drive shaped at the model's two-mass mode
(issue 33; docs/model.md#planned-on-a-real-machine).

Where the model machine declares a mode on an axis (``resonance_frequency`` f > 0,
``resonance_damping`` zeta), the plan's drive of *every* axis is convolved with one
input shaper: a few non-negative taps ``h[n]`` summing to 1, one per sample, whose
z-transform ``H(z) = sum_n h[n] z^-n`` has a double zero at each of the model's sampled
mode poles ``z_m = exp((-zeta*wn + j*wn*sqrt(1 - zeta^2))*Ts)`` (a discrete ZVD shaper,
Singer & Seering 1990 in the sampled form of Murphy & Watanabe 1992). The mode of the
ZOH-sampled plant is excited by the shaped drive ``H(z_true)`` times as much as by the
plan's own: 0 at the model's mode, and, the zero being double, about ``cos(pi*r/2)^2``
(the continuous ZVD's sensitivity) at a true mode ``r`` times the model's.

Why ZVD (the closed forms of the undamped shapers, residual vibration as a share of the
unshaped, at a true mode +-10 % off the model's):

- ZV (2 impulses, half a period): up to 15.6 % at +-10 %; too sensitive.
- ZVD (3 impulses, one period): up to 2.4 % at +-10 % (0 at the model's mode).
- EI at 5 % (3 impulses, one period): 5 % at the model's mode, 2.4 % at +-10 %.

ZVD and EI add the same time (one period) and leave the same at the band's edges; within
the band +-10 % ZVD's worst case is half of EI's, so ZVD. Several modes: their shapers are convolved (one per distinct mode).

Shaping keeps the plan within the drive limit: a shaped drive is a convex combination of
the plan's drives (``h >= 0``, ``sum h = 1``), so ``|u_s| <= max |u|``. The rigid plant
is linear and starts at rest, so the shaped plan is exactly the model's response to the
shaped drive: its positions are the same convex combination of the plan's positions.
A convex combination of positions on a straight piece stays on it, but across a stop
corner it would cut the corner; so the plan is shaped piece by piece between its stops,
each piece's drive shaped on its own and the next piece delayed by the shaper's length
(a dwell of one period at each stop corner: the time the shaper adds there).

The encoder of a two-mass axis reads the motor, ``theta_cm + lambda*delta`` (load:
``theta_cm - (1 - lambda)*delta``), not the rigid plan's ``theta_cm``: the position the
online step steers to (:func:`encoder_offset`) adds the model's twist ``delta`` under the
shaped drive, so its feedback does not fight the spring's quasi-static twist while the
axis accelerates.

Glossary
--------
f : mode frequency [Hz]; wn = 2*pi*f [rad/s]; zeta : its damping ratio; Ts : sample
period [s]; h : shaper taps (one per sample, >= 0, sum 1); z_m : sampled mode pole;
delta : twist theta_motor - theta_load [pulse]; lambda : load fraction.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import replace

import numpy as np
from numba import njit

from ...errors import InfeasibleError, InvalidArgumentError

__all__ = ["SHAPER_KINDS", "shaper_taps", "plan_shaper", "residual_vibration",
           "time_law_shaper", "tool_lead", "shape_plan", "encoder_offset", "twist_at"]

SHAPER_KINDS = ("zv", "zvd")
"""Shapers :func:`shaper_taps` designs: zero vibration at the mode (ZV), and with a zero
derivative in the mode's frequency as well (ZVD, the default: module docstring)."""

MAX_SHAPER_PERIODS = 4.0
"""A shaper longer than this many periods of its mode is not searched for (the discrete
ZVD takes one period and a sample or two)."""


def _mode_pole(frequency: float, damping: float, sample_period: float) -> complex:
    wn = 2.0 * math.pi * frequency
    return cmath.exp(complex(-damping * wn, wn * math.sqrt(1.0 - damping * damping))
                     * sample_period)


def shaper_taps(frequency: float, damping: float, sample_period: float,
                kind: str = "zvd") -> np.ndarray:
    """The shortest non-negative taps, one per sample and summing to 1, whose transform
    has a zero (``"zv"``) or a double zero (``"zvd"``) at the sampled mode pole.

    Found by linear programming (scipy's HiGHS) for 2, 3, ... taps: the conditions are
    linear in the taps (``sum h[n] z^-n = 0``, and for ZVD ``sum n h[n] z^-n = 0``, real
    and imaginary parts), and among the feasible taps of the least length the one with the
    least centroid (the least delay) is taken. Where the mode's half damped period is a
    whole number N of samples this is the continuous shaper exactly (ZV: taps at 0 and N;
    ZVD: at 0, N, 2N, amplitudes ``1, 2K, K^2`` over ``(1 + K)^2``,
    ``K = exp(-zeta*pi/sqrt(1 - zeta^2))``).

    Parameters
    ----------
    frequency : float
        The mode's natural frequency f [Hz], > 0.
    damping : float
        Its damping ratio zeta, in [0, 1).
    sample_period : float
        Ts [s], > 0.
    kind : {"zv", "zvd"}

    Returns
    -------
    ndarray, shape (n_taps,)
        h[n], the weight of the drive n samples earlier (>= 0, sum 1).

    Raises
    ------
    InvalidArgumentError
        For a bad argument, or a mode at or above the Nyquist frequency (no sampled drive
        can shape it).
    """
    from scipy.optimize import linprog

    if kind not in SHAPER_KINDS:
        raise InvalidArgumentError(f"kind must be one of {SHAPER_KINDS}, got {kind!r}")
    if not (math.isfinite(frequency) and frequency > 0):
        raise InvalidArgumentError(f"frequency must be finite and > 0 [Hz], got {frequency!r}")
    if not (0.0 <= damping < 1.0):
        raise InvalidArgumentError(f"damping must be in [0, 1), got {damping!r}")
    if not (math.isfinite(sample_period) and sample_period > 0):
        raise InvalidArgumentError(f"sample_period must be > 0 [s], got {sample_period!r}")
    if not frequency * math.sqrt(1.0 - damping ** 2) * sample_period < 0.5:
        raise InvalidArgumentError(
            f"a {frequency:g} Hz mode (damping {damping:g}) is at or beyond the Nyquist "
            f"frequency of Ts = {sample_period:g} s: no sampled drive shapes it")
    z = _mode_pole(frequency, damping, sample_period)
    longest = int(math.ceil(MAX_SHAPER_PERIODS / (frequency * sample_period))) + 2
    for n_taps in range(2, longest + 1):
        n = np.arange(n_taps)
        zn = z ** (-n.astype(float))
        rows = [zn.real, zn.imag]
        if kind == "zvd":
            rows += [(n * zn).real, (n * zn).imag]
        # scaled by the sum of each row's magnitudes: the conditions are met to rounding
        A_eq = np.vstack([np.ones(n_taps)] + [r / max(np.abs(r).sum(), 1e-300) for r in rows])
        b_eq = np.zeros(A_eq.shape[0])
        b_eq[0] = 1.0
        res = linprog(n.astype(float), A_eq=A_eq, b_eq=b_eq, bounds=(0, None),
                      method="highs")
        if res.status == 0:
            h = np.maximum(res.x, 0.0)
            return h / h.sum()
    raise InfeasibleError(  # pragma: no cover (a ZVD exists within one period and 2 taps)
        f"no {kind} shaper of at most {longest} taps for a {frequency:g} Hz mode at "
        f"Ts = {sample_period:g} s")


def residual_vibration(taps: np.ndarray, frequency: float, damping: float,
                       sample_period: float) -> float:
    """The share of a sampled mode's vibration the shaper leaves: ``|H(z_m)|``, the
    residue of the shaped drive's response at the mode pole over the unshaped one's (the
    taps sum to 1).

    Parameters
    ----------
    taps : ndarray, shape (n_taps,)
        h[n] (:func:`shaper_taps`).
    frequency : float
        The (true) mode [Hz].
    damping : float
        Its damping ratio.
    sample_period : float
        Ts [s].

    Returns
    -------
    float
        Dimensionless, >= 0 (0: the mode is not excited after the drive ends).
    """
    z = _mode_pole(frequency, damping, sample_period)
    n = np.arange(len(taps))
    return float(abs(np.sum(np.asarray(taps) * z ** (-n.astype(float)))))


def plan_shaper(machine) -> np.ndarray | None:
    """The shaper of a model machine (module docstring): the ZVD taps of each distinct
    mode of its axes, convolved; None for a machine without a mode (its plan is not
    touched)."""
    modes = sorted({(a.resonance_frequency, a.resonance_damping) for a in machine.axes
                    if a.resonance_frequency > 0})
    if not modes:
        return None
    h = np.ones(1)
    for f, zeta in modes:
        h = np.convolve(h, shaper_taps(f, zeta, machine.sample_period))
    return h


def time_law_shaper(machine) -> np.ndarray | None:
    """The taps the plan shapes its *time law* with (:func:`plan_shaper`: the ZVD of
    every distinct mode of the model machine's axes, convolved), or None for a machine
    without a mode (its plan is the rigid one, bit for bit).

    The plan's arc length s(t) of each piece between stops is replaced by
    ``sum_n h[n]*s(t - n*Ts)`` before it is sampled (:func:`.blend._piece_motions`):
    the desired motion is ``C(s_shaped(t))``, on the path (a convex combination of arc
    lengths is an arc length, where shaping the axes cuts curves), at rest on each stop
    ``len(h) - 1`` samples later, its path speed a convex combination of the profile's
    (within the feed). On a straight piece the axes' positions are affine in s, so the
    sampled desired motion *is* the rigid plan's shaped by h and, the inverse of step 3
    being linear and time-invariant, so is its drive: ``u_s[k] = sum_n h[n]*u[k - n]``,
    within the drive limit (a convex combination) and exciting a sampled mode pole z
    ``|H(z)|`` times as much as the unshaped drive (:func:`residual_vibration`; 0 at the
    model's mode, about 3 % at a true mode 10 % off). On a curve the drive's centripetal
    part is not a convex combination: step 4 of the plan checks the limit and eases the
    profile where the sampled drive exceeds it, as for any plan.

    A mode at or beyond the Nyquist frequency (``f*sqrt(1 - zeta^2)*Ts >= 1/2``) is not
    shaped: no sampled drive can (:func:`shaper_taps`); its axis is planned as if it had
    none (and its twist still taken off the reading, :func:`encoder_offset`)."""
    Ts = machine.sample_period
    modes = sorted({(a.resonance_frequency, a.resonance_damping) for a in machine.axes
                    if a.resonance_frequency > 0
                    and a.resonance_frequency * math.sqrt(1.0 - a.resonance_damping ** 2)
                    * Ts < 0.5})
    if not modes:
        return None
    h = np.ones(1)
    for f, zeta in modes:
        h = np.convolve(h, shaper_taps(f, zeta, Ts))
    return h


def tool_lead(desired: np.ndarray, machine, shaper: np.ndarray,
              stops: np.ndarray = np.zeros(0)) -> np.ndarray:
    """How far [pulse] each moded axis's rigid motion (its centre of mass) must lead the
    desired *tool* motion, across the path, for the tool on the load to stay on it where
    its acceleration is sustained (the centripetal part on a curve), shape (n, n_axes).

    The tool is ``theta_cm - (1 - lambda)*delta`` (docs/model.md#real-machine), so
    ``tool = theta_cm*((2*zeta*wn*tau - 1)*s + tau*wn^2)/(tau*(s^2 + 2*zeta*wn*s +
    wn^2))``; well below the mode its inverse is ``theta_cm = y + y'/(tau*wn^2) +
    y''/wn^2 + ...``: the tool lags the rigid motion by its acceleration over wn^2 (on
    the Pi's transfer arc at 1 m/s, 58 um on y, across the path) and by its speed over
    tau*wn^2 (the load's viscous share pulled through the spring; across the path where
    the axes' tau differ). Only the part across the path is led (the part along it
    delays the tool on the path, not off it, and its steps at the shaped acceleration's
    transitions ask for jumps no drive makes): the lead is projected on the normal
    plane of the motion's direction (central differences; none where the motion rests
    or its differences straddle a stop corner), then shaped by ``shaper`` centred on its
    centroid, so that its drive is a shaped drive too (``|H(z_m)|`` of the unshaped at
    a sampled mode pole z_m). The exact zero-phase inverse through the mode is not
    taken.

    Parameters
    ----------
    desired : ndarray, shape (n, n_axes)
        y[k], the desired tool positions [pulse], at rest at both ends.
    machine : Machine
        The model machine (its axes' tau, and mode f; 0 on axes without a mode).
    shaper : ndarray, shape (n_taps,)
        :func:`time_law_shaper`'s taps.
    stops : ndarray, shape (n_stops,)
        The (fractional) samples of the stop corners.

    Returns
    -------
    ndarray, shape (n, n_axes)
        [pulse]; 0 where the motion rests.
    """
    Ts = machine.sample_period
    y = np.asarray(desired, dtype=float)
    n = len(y)
    lead = np.zeros_like(y)
    if n < 3:
        return lead
    v = np.zeros_like(y)
    acc = np.zeros_like(y)
    v[1:-1] = (y[2:] - y[:-2]) / (2.0 * Ts)
    acc[1:-1] = (y[2:] - 2.0 * y[1:-1] + y[:-2]) / (Ts * Ts)
    raw = np.zeros_like(y)
    for j, ax in enumerate(machine.axes):
        if ax.resonance_frequency > 0:
            wn2 = (2.0 * math.pi * ax.resonance_frequency) ** 2
            raw[:, j] = acc[:, j] / wn2 + v[:, j] / (ax.time_constant * wn2)
    speed = np.linalg.norm(v, axis=1)
    k = np.arange(n)
    moving = speed > 0
    for t in np.asarray(stops, dtype=float):
        moving &= ~((k - 1 < t) & (t < k + 1))
    tangent = np.zeros_like(y)
    tangent[moving] = v[moving] / speed[moving, None]
    raw -= np.sum(raw * tangent, axis=1)[:, None] * tangent
    raw[~moving] = 0.0
    taps = np.asarray(shaper, dtype=float)
    centre = int(round(float(np.sum(np.arange(len(taps)) * taps))))
    for j in range(y.shape[1]):
        if np.any(raw[:, j]):
            lead[:, j] = np.convolve(raw[:, j], taps)[centre:centre + n]
    return lead


def shape_plan(plan, machine, curve):
    """The plan (:class:`.plan.MotionPlan`) with its drive shaped at the model's modes,
    piece by piece between its stops (module docstring); the plan itself where the model
    has no mode.

    The desired motion is split at each stop corner into pieces that each rest on their
    corners (at a stop between two samples, the sample's step is split at the corner
    point), each piece's motion is convolved with the shaper and delayed by the shaper's
    length times the pieces before it, and the drive is step 3's inverse of that sum
    (:func:`.inverse._drive_sequence`): the inverse is linear and time-invariant, so its
    drive is each piece's drive shaped, and the rigid plant's response is exactly the plan.

    Parameters
    ----------
    plan : MotionPlan
        The rigid model's plan, at rest at its start.
    machine : Machine
        The model machine.
    curve : NurbsCurve
        The path [pulse] (its sharp corners are the stops' points).

    Returns
    -------
    MotionPlan
        Each stop corner and the arrival later by the shaper's length times the stops
        before them (one more for the arrival); the plan itself where the shaped drive
        would leave the plan's drive limit (no shaped motion is within it).
    """
    h = plan_shaper(machine)
    if h is None:
        return plan
    from .inverse import PRECOMPENSATION_ROUNDS, PRECOMPENSATION_TOLERANCE, _drive_sequence

    L = len(h) - 1  # the samples a piece's shaped motion lasts longer
    y = plan.desired
    n = len(y)
    stops = plan.stop_times
    cuts = sorted({int(k) for k in plan.stop_indices if 0 < k < n})
    corner_u = curve.sharp_corners()
    points = []
    for k in cuts:  # the corner within the sample's step to the stop's first sample
        lo, hi = plan.parameter[max(k - 1, 0)], plan.parameter[min(k, n - 1)]
        near = corner_u[(corner_u >= lo - 1e-12) & (corner_u <= hi + 1e-12)]
        u_c = near[0] if near.size else plan.parameter[min(k, n - 1)]
        points.append(np.asarray(curve(np.array([u_c])))[0])
    n_pieces = len(cuts) + 1
    m = n + L * n_pieces

    def shaped(inc, at):  # increments starting at sample ``at`` of the output, shaped
        out = np.zeros((m,) + inc.shape[1:])
        for t, weight in enumerate(h):
            if weight:
                out[at + t:at + t + len(inc)] += weight * inc
        return out

    edges = [0] + cuts + [n]
    inc = np.diff(y, axis=0, prepend=y[:1])
    pinc = np.diff(plan.parameter, prepend=plan.parameter[:1])
    y_inc = np.zeros((m, y.shape[1]))
    p_inc = np.zeros(m)
    for i in range(n_pieces):
        lo, hi = edges[i], edges[i + 1]
        seg = inc[lo:hi].copy()
        pseg = pinc[lo:hi].copy()
        if i > 0:      # the piece starts on its corner: its first step from there
            seg[0] = y[lo] - points[i - 1]
        if i < n_pieces - 1:  # and ends on the next, one step after its last sample
            seg = np.vstack([seg, points[i] - y[hi - 1]])
            pseg = np.append(pseg, 0.0)
        y_inc += shaped(seg, lo + i * L)
        p_inc += shaped(pseg, lo + i * L)
    desired = y[0] + np.cumsum(y_inc, axis=0)
    desired[-1] = y[-1]
    parameter = np.minimum(plan.parameter[0] + np.cumsum(p_inc), 1.0)
    limit = plan.drive_fraction * machine.max_drive
    plant, _ = _drive_sequence(desired, machine, PRECOMPENSATION_ROUNDS, limit * (1 + 1e-9),
                               PRECOMPENSATION_TOLERANCE)
    if plant is None:
        return plan
    w, theta, u = plant
    theta[-1] = desired[-1]
    w[-1] = 0.0
    shift = (np.searchsorted(np.asarray(cuts, dtype=float), plan.corner_times,
                             side="left") + 1) * float(L) if stops.size else 0.0
    arrival = plan.arrival + n_pieces * L if plan.arrival > 0 else 0
    return replace(plan, position=theta, speed=w, drive=u, parameter=parameter,
                   desired=desired, corner_times=plan.corner_times + shift,
                   arrival=min(arrival, m - 1))


def encoder_offset(drive: np.ndarray, machine) -> np.ndarray | None:
    """What the encoder of each two-mass axis of the model reads beyond the rigid
    motion under ``drive``: ``lambda*delta`` on the motor, ``-(1 - lambda)*delta`` on the
    load, delta the model's twist from rest (docs/model.md#real-machine: ``delta'' +
    2*zeta*wn*delta' + wn^2*delta = Ke*Kc/((1 - lambda)*tau)*v``), sampled exactly under
    the held drive; None where no axis has a mode.

    Parameters
    ----------
    drive : ndarray, shape (n, n_axes)
        The held drive of each sample [V].
    machine : Machine
        The model machine.

    Returns
    -------
    ndarray, shape (n, n_axes), or None
        [pulse]; 0 on rigid axes.
    """
    if not any(a.resonance_frequency > 0 for a in machine.axes):
        return None  # before the imports: scipy.signal alone costs a rigid run ~0.3 s
    from scipy.linalg import expm
    from scipy.signal import lfilter

    Ts = machine.sample_period
    out = np.zeros_like(drive, dtype=float)
    for j, ax in enumerate(machine.axes):
        if not ax.resonance_frequency > 0:
            continue
        wn = 2.0 * math.pi * ax.resonance_frequency
        lam = ax.load_fraction
        gain = ax.mechanical_gain * ax.electrical_gain / ((1.0 - lam) * ax.time_constant)
        # [delta, delta'] under a held drive: the ZOH pair of the oscillator
        M = np.zeros((3, 3))
        M[0, 1] = 1.0
        M[1, 0], M[1, 1], M[1, 2] = -wn * wn, -2.0 * ax.resonance_damping * wn, gain
        E = expm(M * Ts)
        Phi, Gam = E[:2, :2], E[:2, 2]
        # delta[k] as a second-order recursion: the transfer Gam' (zI - Phi)^-1 row 0
        tr, det = np.trace(Phi), np.linalg.det(Phi)
        num = [0.0, Gam[0], Gam[1] * Phi[0, 1] - Gam[0] * Phi[1, 1]]
        delta = lfilter(num, [1.0, -tr, det], drive[:, j])
        out[:, j] = lam * delta if ax.encoder_on == "motor" else -(1.0 - lam) * delta
    return out


@njit(cache=True)
def twist_at(twist, phi, j):
    """The encoder's reading of the model's twist (:func:`encoder_offset`, shape (n,
    n_axes) [pulse]) of axis ``j`` at plan clock ``phi`` [samples], linear between
    samples, held before the first and after the last."""
    n = twist.shape[0]
    if phi <= 0.0:
        return twist[0, j]
    i0 = min(int(phi), n - 1)
    i1 = min(i0 + 1, n - 1)
    f = phi - i0 if i1 > i0 else 0.0
    return twist[i0, j] * (1.0 - f) + twist[i1, j] * f
