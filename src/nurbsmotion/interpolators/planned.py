"""The ``planned`` interpolator: plan the actual motion, then steer the plant along it.

Offline (:func:`nurbsmotion.motion_plan.plan_motion`): the actual position of every sample,
time-optimal within the drive limit of the model's ZOH plant, on the path (or within the
corner tolerance of it), at rest at both ends and at every stop corner, together with the
feedforward drive u_ff[k] and plant state x_ff[k] = (w_ff, theta_ff) that make the model's
plant follow it exactly.

Online, every sample (:func:`online_step`, plain scalar/array code that numba compiles):

1. the plant's exact sampled model (pole a, and the drive's effect on the next two
   position increments, b1 and beta = c*b0 - a*b1) is identified by recursive least
   squares from the positions measured and the drives applied, starting from the model
   (:func:`_identify`; a linear regression exact for any tau and Kc); the deviation
   from the plan's state is the measured position's, and the speed's through the
   identified plant from the last position increment and drive;
2. a time-scaling governor advances the plan's clock by ``rate`` in (0, 1] samples. The
   *estimated* plant follows the plan at rate r with the drive ``ga*A*r^2 + gv*V*r``
   (A, V: the acceleration and speed parts of the plan's drive), which must stay within
   ``1 - drive_headroom`` of Umax (never below the plan's own use). Over the next
   :data:`RATE_WINDOW` plan samples a backward pass finds the largest rate of each sample
   from which the clock can still be slowed to the next samples' rates with the drive
   that is left (:func:`_window_rate`: slowing the clock slows the plant, and costs
   drive); beyond the window, up to the next stop, one uniform rate bounds it (the
   support function of the plan's drive there, :func:`_demand`). The governor moves the
   rate towards the window's, lowered further after a sample whose drive demand exceeded
   Umax, by at most ``1 - tracking_pole`` and at most what the drive left at the clock
   can change; the clock advances by the mean of the old and the new rate (the plant's
   speed moves between them over the sample). A weaker plant is thus slowed down where it
   must be, just before it accelerates or brakes, not over the whole way to the next stop;
3. the drive is the identified plant's drive from the plan's speed at the clock (times the
   rate it had) to the plan's speed at the next clock (times the new rate), both exact
   between samples (:func:`_plan_speed_at`), plus a state feedback on the deviation whose
   gains put both poles of the *identified* plant's deviation dynamics at
   ``tracking_pole`` (:func:`_pole_gains`) and, once the plan's clock has reached the
   plan's rest on the end, at 0 (deadbeat: what a plant that differs from the model has
   left of the move closes in two samples instead of decaying at the tracking pole),
   clipped to +-Umax: *every drive is within the limit by construction*, whatever the
   true plant. Once the plan moves an axis only towards a stop (a stop corner or the
   end), the drive also leaves the identified plant able to stop before it, braking at
   Umax from the next sample on, and keeps it so until the plan moves the axis on past
   it or the next stop comes (:func:`_stop_guards`, :func:`_short_of_stop`; the plan's
   own braking never needs more, so on the model's plant it changes nothing): a plant
   weaker or stronger than the model does not pass the end point or a stop corner;
4. the loop's law is affine in the setpoint between its clamps,
   ``u = slope*thd + offset`` with slope > 0 (:func:`nurbsmotion.control.pid_affine`,
   from the law's memory and the measured state), so the setpoint that produces exactly
   that drive is ``thd = (u - offset) / slope``; where a clamp or the deadband of the law
   (LinuxCNC ``pid``'s maxerror, deadband, ...) makes the drive differ, the setpoint is
   solved for on the law's own output (:func:`nurbsmotion.control.pid_output`, continuous
   and nondecreasing in the setpoint), and where a clamp makes that drive unreachable,
   moved until the output is within Umax (:func:`_setpoint_for`). Setpoints lead the path
   and need not lie on it; the actual position is what must.

Every sample's status says whether the governor slowed the plan or the drive was clipped
(``LIMITED``). The move is finished (``FINISHED``: the setpoint has arrived) once the
plan's clock reaches the plan's rest on the end; the step goes on steering after that
until the run ends.

Glossary
--------
u : drive [V] (and, for a :class:`Setpoint`, the curve parameter); thd : setpoint [pulse];
tha : measured position [pulse]; w : motor speed [rad/s]; Ts : sample period [s].
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .. import stepping
from .._runtime.memory import release_freed_memory
from ..control import pid_affine, pid_output
from ..errors import InvalidArgumentError
from ..feed import FeedLimit
from ..machine import Machine
from ..motion_plan import DEFAULT_PATH_TOLERANCE, axis_zoh, move_tolerance, plan_motion
from ..nurbs import NurbsCurve
from .base import Interpolator, positive_feed

__all__ = ["PlannedInterpolator", "online_step", "DEFAULT_TRACKING_POLE",
           "DEFAULT_DRIVE_HEADROOM"]

DEFAULT_TRACKING_POLE = 0.7
"""Both poles of the deviation dynamics under the online feedback, placed on the identified
plant: a deviation from the plan decays by this factor per sample (a user parameter:
closer to 0 follows the plan more tightly and leaves less drive to the governor's rate
changes, closer to 1 the reverse)."""

DEFAULT_DRIVE_HEADROOM = 0.1
"""Fraction of Umax the governor keeps free for the feedback when it scales the plan's
clock to the drive the (estimated) plant needs up to the next stop (a user parameter)."""

SUPPORT_DIRECTIONS = 9
"""Directions in which the governor knows the plan's drive demand up to the next stop
exactly (between them it bounds it above, by at most ``1/cos(pi/4/(n-1)) - 1``: 0.5 %)."""

SUPPORT_BLOCK = 8
"""The plan stores the support of its drive (:func:`_support`) at every this-many-th sample
only; each sample's own is the stored one at the next such sample maxed with the few
samples before it (:func:`_support_at`): the same values, an eighth of the memory (a
10-minute move's support held 86 MB)."""

RATE_WINDOW = 16
"""Plan samples ahead over which the governor plans the clock's rate sample by sample
(:func:`_window_rate`); beyond them, up to the next stop, it bounds the rate by one
uniform value, which is safe but slower. A parameter of cost against speed: the drive
left beside the plan changes the rate by about 0.05 (2 m/s on the die-bonder) to over 0.3
per sample, so 16 samples let it fall from 1 to 0.2 before the samples that need it; 32
gave the same runs on the die-bonder's Pi and butterfly at twice the cost per sample."""

RATE_BISECTIONS = 20
"""Bisections of the governor's largest rate (to 1e-6 of a sample per sample)."""

GAIN_RANGE = 4.0
"""The estimated plant may need between 1/4 and 4 times the model's drive (issue 10 asks
for any tau, Kc within x[0.5, 2]: up to 4 times the acceleration drive)."""


@njit(cache=True)
def _gains(est, j, a, b0, c, b1):
    """The estimated plant's drive over the model's for the plan's acceleration part
    (``ga = b0/b0'``) and speed part (``gv = Kc/Kc'``), each within
    [1/GAIN_RANGE, GAIN_RANGE]; ``est`` holds axis j's identified (a', b1', beta')
    (:func:`_identify`), and ``b1 + beta = Ke*Ts*b0`` for every ZOH plant of this form."""
    s_model = b1 + c * b0 - a * b1
    s_est = est[1, j] + est[2, j]
    ga = s_model / s_est if s_est > s_model / GAIN_RANGE else GAIN_RANGE
    ga = min(max(ga, 1.0 / GAIN_RANGE), GAIN_RANGE)
    gv = ga * (1.0 - est[0, j]) / (1.0 - a)
    return ga, min(max(gv, 1.0 / GAIN_RANGE), GAIN_RANGE)


@njit(cache=True)
def _plan_speed_at(drive_speed, drive_accel, phi, j, a, log_a, b0):
    """The plan's speed [rad/s] of axis j at clock ``phi`` [samples]: the model's plant
    from the plan's speed at sample i = floor(phi) under its drive there, over the fraction
    f = phi - i of a sample (ZOH, exact between samples: ``w(i + f) = a^f*w[i]
    + b0*(1 - a^f)/(1 - a)*u[i]``, with ``w[i] = Kc*V[i]``, ``Kc = b0/(1 - a)`` and
    ``u[i] = V[i] + A[i]``, the plan's drive parts; ``log_a = log(a)``)."""
    n = drive_speed.shape[0]
    i = min(int(phi), n - 1)
    f = phi - i if i < n - 1 else 0.0
    w_i = b0 / (1.0 - a) * drive_speed[i, j]
    if f <= 0.0:
        return w_i
    g = -math.expm1(f * log_a)                   # 1 - a^f
    return (1.0 - g) * w_i + b0 * g / (1.0 - a) * (drive_speed[i, j] + drive_accel[i, j])


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
def _identify(est, hist, j, position, a, b0, c, b1, dead_zone=0.0):
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
    Returns :func:`_gains`."""
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
                return _gains(est, j, a, b0, c, b1)
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
    return _gains(est, j, a, b0, c, b1)


@njit(cache=True)
def _position_noise(a):
    """Variance [pulse^2] of the regression's residual when every position is read to one
    pulse (uniform error, variance 1/12) and enters it with weights 1, -(1 + a), a."""
    return (1.0 + (1.0 + a) ** 2 + a * a) / 12.0


@njit(cache=True)
def _demand(support, j, x, y):
    """An upper bound, exact in the directions of :data:`SUPPORT_DIRECTIONS`, of the largest
    ``|x*A[k] + y*V[k]|`` (x, y >= 0) over the plan's samples k from this one to the next
    stop of axis j: the support function of the points (A[k], V[k]) (acceleration and
    speed parts of the plan's drive [V]; ``support`` (n_axes, SUPPORT_DIRECTIONS) from
    :func:`_support_at`) interpolated between the two directions enclosing (x, y) (a
    support function is sublinear, so the interpolation bounds it above)."""
    m = support.shape[1] - 1
    if x <= 0.0 and y <= 0.0:
        return 0.0
    phi = math.atan2(y, x) / (0.5 * math.pi) * m
    k = min(int(phi), m - 1)
    step = 0.5 * math.pi / m
    p0, p1 = k * step, (k + 1) * step
    sd = math.sin(step)
    l0 = (x * math.sin(p1) - y * math.cos(p1)) / sd
    l1 = (y * math.cos(p0) - x * math.sin(p0)) / sd
    return max(l0, 0.0) * support[j, k] + max(l1, 0.0) * support[j, k + 1]


@njit(cache=True)
def _first_root(p, q, c):
    """The smallest positive root of ``p*r^2 + q*r + c = 0``, at most 1 (1 if none)."""
    best = 1.0
    if abs(p) <= 1e-300:
        if q != 0.0 and -c / q > 0.0:
            best = min(best, -c / q)
        return best
    disc = q * q - 4.0 * p * c
    if disc < 0.0:
        return best
    t = -0.5 * (q + math.copysign(math.sqrt(disc), q))
    for r in (t / p, c / t if t != 0.0 else -1.0):
        if r > 0.0:
            best = min(best, r)
    return best


@njit(cache=True)
def _static_rate(p, q, limit):
    """The largest rate r in [0, 1] with ``|p*r^2 + q*r| <= limit`` for every r' in
    [0, r] (the first crossing of +-limit by the parabola through 0)."""
    return min(_first_root(p, q, -limit), _first_root(p, q, limit))


@njit(cache=True)
def _rate_room(f, speed, limit):
    """``(slow, fast)``: how much of ``limit`` [V] is left for slowing the clock down and
    for speeding it up, given the drive ``f`` [V] the sample already needs and the sign of
    the axis' motion ``speed`` (slowing needs a drive against the motion)."""
    s = 1.0 if speed >= 0.0 else -1.0
    return max(limit + s * f, 0.0), max(limit - s * f, 0.0)


@njit(cache=True)
def _window_rate(i0, r_tail, gains, a, drive_speed, drive_accel, headroom, umax):
    """The largest clock rate at plan samples ``i0`` and ``i0 + 1`` (the clock passes
    both within the sample) from which the estimated plant can follow the plan: a
    backward pass over the plan samples ``i0 .. i0 + RATE_WINDOW`` from ``r_tail`` (the
    uniform rate that holds from there to the next stop; the window may cross stops: the
    plan is at rest there, and its rate may change freely). At sample k the rate r may be
    at most the static rate
    (:func:`_static_rate`: ``|ga*A*r^2 + gv*V*r|`` within the limit) and at most the next
    sample's rate plus what the drive left can take off over one plan sample: slowing the
    clock by dr slows axis j by ``w_ff*dr``, which costs ``ga*V/(1 - a)*dr`` [V] (V the
    speed part of the plan's drive, ``w_ff/Kc``), over 1/r loop samples. ``gains`` (2,
    n_axes): ga, gv. Both sample k's and k + 1's drives bound the change (the clock may
    lie anywhere between them while the rate changes)."""
    end = min(i0 + RATE_WINDOW, drive_speed.shape[0])
    r_next = r_tail
    r_after = r_next  # the rate at sample i0 + 1: the clock passes it within the sample
    static_next = 1.0  # sample k + 1's static rate (the window's end: the tail's)
    for k in range(end - 1, i0 - 1, -1):
        static = 1.0
        r_k = 1.0
        for j in range(drive_speed.shape[1]):
            # the clock lies anywhere between k and k + 1 while the rate changes: both
            # samples' drives must leave room for it
            for kk in range(k, min(k + 2, end)):
                A, V = drive_accel[kk, j], drive_speed[kk, j]
                p, q = gains[0, j] * A, gains[1, j] * V
                limit = max((1.0 - headroom) * umax, abs(A + V))
                if kk == k:
                    static = min(static, _static_rate(p, q, limit))
                cost = gains[0, j] * abs(V) / (1.0 - a[j])
                if cost > 0.0:
                    # slowing from r at k to r_next at k + 1 (r - r_next per plan sample,
                    # so (r - r_next)*r per loop sample): s*(p*r^2 + q*r)
                    # - cost*(r - r_next)*r >= -limit, s the sign of the motion; its first
                    # crossing from r = 0
                    s = 1.0 if V >= 0.0 else -1.0
                    r_k = min(r_k, _first_root(s * p - cost, s * q + cost * r_next, limit))
        r_k = min(r_k, static, static_next)
        static_next = static
        if k == i0 + 1:
            r_after = r_k
        r_next = r_k
    return min(r_next, r_after)


@njit(cache=True)
def _stopping_travel(w, a, b0, c, b1, brake):
    """Travel [pulse] of a ZOH plant ``(a, b0, c, b1)`` from speed ``w`` [rad/s] under the
    constant drive ``brake`` [V] until its speed is 0 (0 if ``brake`` does not oppose
    ``w``): with ``w_inf = b0*brake/(1 - a)``, the speed ``w_inf + (w - w_inf)*a^t`` is 0
    at ``a^t = -w_inf/(w - w_inf)``, and the travel to there is the ZOH position update
    summed over t samples, ``c*(w_inf*t + (w - w_inf)*(1 - a^t)/(1 - a)) + b1*brake*t``
    (exact for fractional t: it is the continuous plant's)."""
    w_inf = b0 * brake / (1.0 - a)
    if w == 0.0 or w * brake >= 0.0:
        return 0.0
    ratio = -w_inf / (w - w_inf)           # in (0, 1)
    t = math.log(ratio) / math.log(a)
    return c * (w_inf * t + (w - w_inf) * (1.0 - ratio) / (1.0 - a)) + b1 * brake * t


@njit(cache=True)
def _short_of_stop(u, x, w, stop, s, a, b0, c, b1, umax):
    """The drive nearest ``u`` [V], within +-Umax, after which the ZOH plant ``(a, b0, c,
    b1)`` at position ``x`` [pulse] and speed ``w`` [rad/s], braking at Umax from the
    next sample on, stops before ``stop`` [pulse] (moving in direction ``s``, +-1): the
    travel grows with the drive, so it is ``u`` itself if that stops in time, the full
    brake if nothing does, and else the bisected drive that stops on ``stop``."""
    brake = -s * umax

    def beyond(v):
        w1 = a * w + b0 * v
        return s * (x + c * w + b1 * v + _stopping_travel(w1, a, b0, c, b1, brake) - stop)

    if beyond(u) <= 0.0:
        return u
    if beyond(brake) > 0.0:
        return brake
    good, bad = brake, u
    for _ in range(RATE_BISECTIONS):
        mid = 0.5 * (good + bad)
        if beyond(mid) > 0.0:
            bad = mid
        else:
            good = mid
    return good


@njit(cache=True)
def online_step(phi, rate, excess_prev, est, hist, position, plan_position,
                plan_drive_speed, plan_drive_accel, support, gains, a, b0, c, b1, log_a,
                umax, headroom, rate_gain, rest, guards, guard_offsets, slope, offset,
                out_setpoint, out_drive, dead_zone=0.0):
    """One sample of the planned interpolator (module docstring, steps 1-4).

    Plain loops over floats and float arrays, so that numba compiles it unchanged.

    Parameters
    ----------
    phi : float
        The plan's clock at this sample [samples].
    rate : float
        The clock's rate over the last sample, in (0, 1].
    excess_prev : float
        How far the last sample's drive demand exceeded Umax (relative; 0 if not).
    est : ndarray, shape (12, n_axes)
        In/out: the plant's identified sampled model and its covariance
        (:func:`_identify`).
    hist : ndarray, shape (5, n_axes)
        In/out: the identification's memory (:func:`_identify`); row 0 is the drive
        applied at the last sample, which the caller corrects if the law produced another.
    position : ndarray, shape (n_axes,)
        tha[k], measured [pulse].
    plan_position : ndarray, shape (n, n_axes)
        theta_ff [pulse].
    plan_drive_speed, plan_drive_accel : ndarray, shape (n, n_axes)
        The feedforward drive's speed part w_ff/Kc and acceleration part
        (w_ff[k+1]-w_ff[k])/b0 [V] (u_ff is their sum at rate 1).
    support : ndarray, shape (n_axes, SUPPORT_DIRECTIONS)
        Per axis, the support function of the plan's drive parts from the window's end
        (:data:`RATE_WINDOW` samples after the clock's) up to the next stop
        (:func:`_support_at`; zero when the window reaches the plan's end).
    gains : ndarray, shape (2, n_axes)
        Scratch: the estimated plant's ga and gv (:func:`_gains`).
    a, b0, c, b1 : ndarray, shape (n_axes,)
        The model's ZOH plant (:func:`nurbsmotion.motion_plan.axis_zoh`).
    log_a : ndarray, shape (n_axes,)
        log(a), for the plan's speed between samples (:func:`_plan_speed_at`).
    umax : float
        Umax [V].
    headroom : float
        Fraction of Umax the governor keeps for the feedback.
    rate_gain : float
        Largest change of the rate per sample; ``1 - rate_gain`` is the tracking pole.
    rest : int
        The plan sample from which the plan rests on the end: from there on the
        feedback is deadbeat.
    guards, guard_offsets : ndarray, shapes (n_guards, 4) and (n_axes + 1,)
        Where the plant must be able to stop (:func:`_stop_guards`): while the clock
        lies between two plan samples that a guard both holds, the drive keeps the plant
        able to stop before its position (:func:`_short_of_stop`).
    slope, offset : ndarray, shape (n_axes,)
        The law's affine form at this sample: u[k] = slope*thd[k] + offset [V/pulse, V].
    out_setpoint, out_drive : ndarray, shape (n_axes,)
        Written: thd[k] [pulse] and the drive it produces [V].
    dead_zone : float
        The identification's dead zone [pulse] (:func:`_identify`,
        :func:`reading_knowledge`).

    Returns
    -------
    phi_next, rate, excess : float
        The clock at the next sample, the rate used over this sample, and how far this
        sample's drive demand exceeded Umax.
    """
    n = plan_position.shape[0]
    n_axes = position.shape[0]
    i0 = min(int(phi), n - 1)
    i1 = min(i0 + 1, n - 1)
    f = phi - i0 if i1 > i0 else 0.0
    # 1a. identify the plant's exact sampled model from the measured positions and the
    # drives applied (recursive least squares, see :func:`_identify`)
    r_tail = 1.0
    for j in range(n_axes):
        ga, gv = _identify(est, hist, j, position[j], a[j], b0[j], c[j], b1[j],
                           dead_zone)
        gains[0, j] = ga
        gains[1, j] = gv
        # 2a. the largest uniform rate at which the estimated plant can follow the plan
        # from the window's end to the next stop: |ga*A*r^2 + gv*V*r| <= (1 - headroom)*Umax
        # at every sample there; the plan itself may use the full drive, the headroom
        # applies beyond the model
        limit = max((1.0 - headroom) * umax, _demand(support, j, 1.0, 1.0))
        if _demand(support, j, ga, gv) > limit:
            lo, hi = 0.0, 1.0
            for _ in range(RATE_BISECTIONS):
                mid = 0.5 * (lo + hi)
                if _demand(support, j, ga * mid * mid, gv * mid) > limit:
                    hi = mid
                else:
                    lo = mid
            r_tail = min(r_tail, lo)
    # 2b. sample by sample over the window, slowing down only as late as the drive can
    target = _window_rate(i0, r_tail, gains, a, plan_drive_speed, plan_drive_accel,
                          headroom, umax)
    # 2c. governor: towards that rate, slower after a drive demand beyond Umax, changing
    # no faster than the drive left at the clock can change the plant's speed
    if excess_prev > 0.0:
        target = min(target, rate * (1.0 - rate_gain * excess_prev))
    down, up = rate_gain, rate_gain
    for j in range(n_axes):
        A = plan_drive_accel[i0, j] * (1.0 - f) + plan_drive_accel[i1, j] * f
        V = plan_drive_speed[i0, j] * (1.0 - f) + plan_drive_speed[i1, j] * f
        cost = gains[0, j] * abs(V) / (1.0 - a[j])
        if cost > 0.0:
            limit = max((1.0 - headroom) * umax, abs(A + V))
            slow, fast = _rate_room(gains[0, j] * A * rate * rate + gains[1, j] * V * rate,
                                    V, limit)
            down = min(down, slow / cost)
            up = min(up, fast / cost)
    rate_old = rate
    if target < rate:
        rate = max(target, rate - down, rate_gain)
    else:
        rate = min(target, rate + up)
    # the plant's speed moves from the old rate's to the new one over the sample: the
    # clock advances by their mean
    phi_next = min(phi + 0.5 * (rate_old + rate), n - 1.0)
    excess = 0.0
    for j in range(n_axes):
        # 1b. deviation from the plan's state: position measured; the plant's speed from
        # its last position increment and drive (hist rows 3 and 0, :func:`_identify`)
        # through the identified plant (exact when it is the true one)
        th = plan_position[i0, j] * (1.0 - f) + plan_position[i1, j] * f
        e_th = th - position[j]
        ae, b0e, ce, b1e = _estimated_plant(est, j, b0[j], gains[0, j])
        w_last = (hist[3, j] - b1e * hist[0, j]) / ce
        w_now = ae * w_last + b0e * hist[0, j]
        w_ref = _plan_speed_at(plan_drive_speed, plan_drive_accel, phi, j, a[j], log_a[j],
                               b0[j])
        e_w = w_ref * rate_old - w_now
        # 3. drive: the estimated plant's drive from the plan's speed at the clock (at the
        # rate it had) to its speed at the next clock (at the new rate), plus feedback;
        # clipped
        w_next = _plan_speed_at(plan_drive_speed, plan_drive_accel, phi_next, j, a[j],
                                log_a[j], b0[j])
        uf = (w_next * rate - ae * w_ref * rate_old) / b0e
        kpe, kde = _pole_gains(ae, b0e, ce, b1e, 0.0 if phi >= rest else 1.0 - rate_gain)
        u = uf + kpe * e_th + kde * e_w
        if abs(u) > umax:
            excess = max(excess, abs(u) / umax - 1.0)
            u = umax if u > 0 else -umax
        # 3b. never past a stop: the drive leaves the plant able to stop before the
        # positions the plan guards at both ends of the clock's sample, braking at Umax
        # from the next sample on; the side the plant moves towards last
        lo_g, hi_g = guard_offsets[j], guard_offsets[j + 1]
        hi = max(_guarded(guards, lo_g, hi_g, i0, 1.0),
                 _guarded(guards, lo_g, hi_g, i1, 1.0))
        lo = min(_guarded(guards, lo_g, hi_g, i0, -1.0),
                 _guarded(guards, lo_g, hi_g, i1, -1.0))
        for side in (-1.0, 1.0) if w_now >= 0.0 else (1.0, -1.0):
            target = hi if side > 0.0 else lo
            if math.isfinite(target):
                u = _short_of_stop(u, position[j], w_now, target, side, ae, b0e, ce, b1e,
                                   umax)
        hist[1, j] = hist[0, j]
        hist[0, j] = u
        # 4. the setpoint that produces exactly this drive
        out_drive[j] = u
        out_setpoint[j] = (u - offset[j]) / slope[j]
    return phi_next, rate, excess


class PlannedPlan(NamedTuple):
    """What the online step reads (see :func:`online_step` for each array's meaning)."""

    parameter: np.ndarray        # (n,) curve parameter of each sample's desired position
    path_step: np.ndarray        # (n,) the desired position's step to the next [pulse]
    position: np.ndarray         # (n, n_axes) theta_ff [pulse]
    drive_speed: np.ndarray      # (n, n_axes) [V]
    drive_accel: np.ndarray      # (n, n_axes) [V]
    support: np.ndarray          # (ceil(n / SUPPORT_BLOCK), n_axes, SUPPORT_DIRECTIONS) [V]
    bounds: np.ndarray           # (n_stops + 1,) the stops' first samples, then n
    a: np.ndarray                # (n_axes,) the model's ZOH plant
    b0: np.ndarray
    c: np.ndarray
    b1: np.ndarray
    log_a: np.ndarray            # (n_axes,) log(a): a^f between samples
    headroom: float
    rate_gain: float
    rest: int                    # the first sample of the plan's rest on the end
    guards: np.ndarray           # (n_guards, 4) where the plant must be able to stop
    guard_offsets: np.ndarray    # (n_axes + 1,) each axis' rows of guards
    dead_zone: float = 0.0       # the identification's dead zone [pulse]


class PlannedState(NamedTuple):
    """The online state: the plan's clock [samples], its rate and the last excess
    (shape (1,) each), the estimate and history arrays of :func:`online_step`,
    and per-axis scratch (the law's slope and offset, the drive, the support, the
    estimated plant's gains)."""

    phi: np.ndarray
    rate: np.ndarray
    excess: np.ndarray
    est: np.ndarray
    hist: np.ndarray
    slope: np.ndarray
    offset: np.ndarray
    drive: np.ndarray
    support: np.ndarray
    gains: np.ndarray


class PlannedInterpolator(Interpolator):
    """Plans the actual motion, then steers the plant along it (module docstring).

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        The model the plan and the online step use (tau, Kc, Ke, Umax, Ts); the law is the
        loop's own, read every sample.
    feed : float or FeedLimit
        Commanded feed F [pulse/s], the speed limit along the path (per piece: a
        :class:`nurbsmotion.feed.FeedLimit`).
    corner_tolerance : float
        eps [pulse], >= 0: how far the motion may leave a sharp corner (0: exact stop).
        Where rounding the corners would not arrive sooner, the motion stops at them, and
        :attr:`notes` (so the run's message) says so.
    path_tolerance : float
        [pulse], >= 0: how far from the path a short move (a plan of at most
        :data:`~nurbsmotion.motion_plan.SHORT_MOVE_SAMPLES` samples; with stops, planned
        from stop to stop) may go where that lets it arrive sooner, or as far as the
        speed profile's plan does if
        that is farther (:data:`~nurbsmotion.motion_plan.DEFAULT_PATH_TOLERANCE`: one
        pulse).
    drive_fraction : float
        Fraction of Umax, in (0, 1], the plan's feedforward may use; the rest is left to
        the feedback on a plant that differs from the model.
    tracking_pole : float
        Pole of the online feedback's deviation dynamics, in [0, 1)
        (:data:`DEFAULT_TRACKING_POLE`).
    drive_headroom : float
        Fraction of Umax, in [0, 1), the online governor keeps for the feedback
        (:data:`DEFAULT_DRIVE_HEADROOM`).
    grid_size : int
        Arc-length grid of the offline speed profile.
    max_samples : int
        A plan longer than this many samples is refused.

    Raises
    ------
    InvalidArgumentError
        If the feed is not finite and > 0 (:class:`~nurbsmotion.errors.InvalidFeedError`),
        or an option is out of range.
    InfeasibleError
        If the drive cannot move along the path, or the plan would take more than
        ``max_samples`` samples.
    """

    name = "planned"
    open_loop = False  # its setpoints invert the loop's law: none without a loop

    def __init__(self, curve: NurbsCurve, machine: Machine, feed, *,
                 corner_tolerance: float = 0.0,
                 path_tolerance: float = DEFAULT_PATH_TOLERANCE,
                 drive_fraction: float = 1.0,
                 tracking_pole: float = DEFAULT_TRACKING_POLE,
                 drive_headroom: float = DEFAULT_DRIVE_HEADROOM, grid_size: int = 4000,
                 max_samples: int = 10_000_000):
        machine.check_path(curve.n_axes)
        super().__init__(curve, machine.sample_period)
        feed = feed if isinstance(feed, FeedLimit) else positive_feed(feed)
        for name, value, lo, hi in (("tracking_pole", tracking_pole, 0.0, 1.0),
                                    ("drive_headroom", drive_headroom, 0.0, 1.0)):
            if isinstance(value, bool) or not (isinstance(value, (int, float))
                                               and lo <= value < hi):
                raise InvalidArgumentError(f"{name} must lie in [{lo:g}, {hi:g}), got {value!r}")
        self.feed = feed
        self.machine = machine
        self.tracking_pole = float(tracking_pole)
        self.drive_headroom = float(drive_headroom)
        # The motion's speed and drive are not kept: the plan's drive_speed and
        # drive_accel hold them (u_ff = drive_speed + drive_accel), and a long move's
        # memory is mostly these per-sample arrays.
        p = plan_motion(curve, machine, feed, corner_tolerance=corner_tolerance,
                        path_tolerance=path_tolerance, drive_fraction=drive_fraction,
                        grid_size=grid_size, max_samples=max_samples)
        self.duration = p.duration
        if corner_tolerance > 0 and p.stop_times.size:  # asked to round, but stops
            self.notes = ("the motion stops at the sharp corners: rounding them within the "
                          "corner tolerance would not arrive sooner",)
        a, b0, c, b1 = axis_zoh(machine)
        drive_speed = p.speed / machine.Kc
        drive_accel = np.zeros_like(p.speed)
        np.subtract(p.speed[1:], p.speed[:-1], out=drive_accel[:-1])
        drive_accel /= b0
        rest = p.arrival
        # at the stop corners, not at the middles of blends: a blend's superposed pieces
        # do not brake into its middle, and guarding there kept the model's own plant
        # from its plan (88 instead of 42 pulses from a spiral's path within eps = 50)
        guards, guard_offsets = _stop_guards(
            p.position, p.stop_times, rest, path_tolerance,
            _sample_extremes(p.position, p.speed, p.drive, a, b0, c, b1))
        path_step = _path_steps(p.desired)
        parameter, position, stops, n = p.parameter, p.position, p.stop_indices, p.n_samples
        del p  # its speed, drive and desired positions before the support is built
        self.plan = PlannedPlan(
            parameter=parameter, path_step=path_step, position=position,
            drive_speed=drive_speed, drive_accel=drive_accel,
            support=_support(drive_accel, drive_speed, stops, SUPPORT_BLOCK),
            bounds=np.append(np.asarray(stops, dtype=np.int64), n),
            a=a, b0=b0, c=c, b1=b1, log_a=np.log(a), headroom=self.drive_headroom,
            # the clock's rate changes at most as fast as a deviation decays
            rate_gain=1.0 - self.tracking_pole, rest=rest, guards=guards,
            guard_offsets=guard_offsets, **reading_knowledge(machine, a, b0, c, b1))
        release_freed_memory()  # the plan's temporaries, before a long run's peak

    def nominal_duration(self) -> float:
        return self.duration

    def new_state(self) -> PlannedState:
        n = self.machine.n_axes
        # the clock starts at plan sample 0 with the loop: the step gives sample 0's
        # setpoint too (registered below with first_sample=0)
        return PlannedState(np.zeros(1), np.ones(1), np.zeros(1), _prior_estimate(self.plan),
                            np.zeros((5, n)), np.empty(n), np.empty(n), np.empty(n),
                            np.empty((n, SUPPORT_DIRECTIONS)), np.empty((2, n)))


@njit(cache=True)
def _law_output(law, law_state, j, command, position, velocity):
    """The law's output [V] for a candidate setpoint (:func:`nurbsmotion.control.pid_output`
    compiled once here, not inlined at every call of :func:`_within_limit`)."""
    return pid_output(law, law_state, j, command, position, velocity)[0]


DRIVE_MATCH = 1e-6
"""The law's output for a setpoint counts as the drive asked of it within this fraction
of Umax: the affine form's rounding (its terms reach thousands of volts that cancel, as
``FF2*command/Ts^2`` does) stays far below it, a deadband's or a clamp's effect far above;
beyond it the setpoint is solved for on the law itself (:func:`_setpoint_for`)."""


@njit(cache=True)
def _setpoint_for(law, law_state, j, command, drive, position, velocity):
    """The setpoint of axis ``j`` at which the law, as it computes (clamps, deadband and
    frozen integrator included), outputs ``drive`` [V] (within +-Umax): ``command``, the
    affine form's setpoint, where that is exact (always for PD and PD+). Otherwise the
    law's output, continuous and nondecreasing in the setpoint (every gain >= 0, every
    clamp and the deadband monotone), is bracketed away from ``command`` and bisected;
    where no setpoint gives ``drive`` (a clamp flattens the output short of it), the
    setpoint nearest ``command`` whose drive is within Umax (:func:`_within_limit`).
    Returns ``(setpoint, found)``."""
    umax = law[j]["maxoutput"]
    out = _law_output(law, law_state, j, command, position, velocity)
    if abs(out - drive) <= DRIVE_MATCH * umax:
        if abs(out) <= umax:
            return command, True
        return _within_limit(law, law_state, j, command, position, velocity)
    sign = 1.0 if out < drive else -1.0
    step = abs(command - position) + 1.0
    near, far = command, command + sign * step
    tries = 0
    while sign * (_law_output(law, law_state, j, far, position, velocity) - drive) < 0.0:
        tries += 1
        if tries > 60:
            return _within_limit(law, law_state, j, command, position, velocity)
        near = far
        step *= 2.0
        far = command + sign * step
    for _ in range(60):
        mid = 0.5 * (near + far)
        if sign * (_law_output(law, law_state, j, mid, position, velocity) - drive) < 0.0:
            near = mid
        else:
            far = mid
    return _within_limit(law, law_state, j, near, position, velocity)


@njit(cache=True)
def _within_limit(law, law_state, j, command, position, velocity):
    """The setpoint of axis ``j`` nearest to ``command`` whose drive, as the law computes
    it (clamps included), is within Umax: ``command`` itself when the affine form was
    exact (always for PD and PD+). The law's output rises with the command, so the
    search widens away from the limit it exceeds, then bisects. Returns
    ``(setpoint, found)``."""
    umax = law[j]["maxoutput"]
    out = _law_output(law, law_state, j, command, position, velocity)
    if abs(out) <= umax:
        return command, True
    sign = 1.0 if out > 0 else -1.0
    # widen until the output is no longer beyond the limit it exceeds (it may then lie
    # anywhere below it, even beyond the other limit), then bisect to that limit
    step = abs(command - position) + 1.0
    good = command - sign * step
    tries = 0
    while sign * _law_output(law, law_state, j, good, position, velocity) > umax:
        tries += 1
        if tries > 60:
            return command, False
        step *= 2.0
        good = command - sign * step
    bad = command
    for _ in range(60):
        mid = 0.5 * (good + bad)
        if sign * _law_output(law, law_state, j, mid, position, velocity) <= umax:
            good = mid
        else:
            bad = mid
    if abs(_law_output(law, law_state, j, good, position, velocity)) > umax:
        return command, False  # the law jumps over the whole band: no admissible setpoint
    return good, True


@njit(cache=True)
def planned_step(plan, state, law, law_state, position, velocity, command, bounds):
    """One sample: the law's affine form from its memory and the measured state, then
    :func:`online_step`; the contract of :mod:`nurbsmotion.stepping`."""
    n_axes = command.shape[0]
    for j in range(n_axes):
        slope, offset = pid_affine(law, law_state, j, position[j], velocity[j])
        state.slope[j] = slope
        state.offset[j] = offset
        bounds[j, 0] = np.nan
        bounds[j, 1] = np.nan
    phi = state.phi[0]
    tail = int(phi) + RATE_WINDOW  # the window's end (:func:`_window_rate`)
    if tail < plan.position.shape[0]:
        _support_at(plan, tail, state.support)
    else:
        state.support[:] = 0.0
    phi_next, rate, excess = online_step(
        phi, state.rate[0], state.excess[0], state.est, state.hist, position,
        plan.position, plan.drive_speed, plan.drive_accel, state.support, state.gains,
        plan.a, plan.b0, plan.c, plan.b1, plan.log_a, law[0]["maxoutput"], plan.headroom,
        plan.rate_gain, plan.rest, plan.guards, plan.guard_offsets, state.slope,
        state.offset, command, state.drive, plan.dead_zone)
    state.phi[0] = phi_next
    state.rate[0] = rate
    state.excess[0] = excess
    status = stepping.WORKING
    for j in range(n_axes):
        setpoint, found = _setpoint_for(law, law_state, j, command[j], state.drive[j],
                                        position[j], velocity[j])
        if not found:
            status = stepping.CORNERED
        if setpoint != command[j]:
            # a clamp of the law: the identification and the speed estimate see the drive
            # the plant gets
            umax = law[j]["maxoutput"]
            out = _law_output(law, law_state, j, setpoint, position[j], velocity[j])
            state.hist[0, j] = min(max(out, -umax), umax)
        command[j] = setpoint
    n = plan.parameter.shape[0]
    i0 = min(int(phi), n - 1)
    feed = rate * plan.path_step[i0] / law[0]["period"]  # the plan's path speed at its clock
    if phi >= plan.rest:  # the plan rests on the end: the setpoint has arrived
        return 1.0, 0.0, stepping.FINISHED
    if status == stepping.WORKING and (excess > 0.0 or rate < 1.0):
        status = stepping.LIMITED
    return plan.parameter[i0], feed, status


# from sample 0: the plan's first drive u[0] moves the plant (motion_plan.LEAD)
stepping.register(PlannedPlan, planned_step, first_sample=0)


_DIRECTIONS = np.linspace(0.0, 0.5 * np.pi, SUPPORT_DIRECTIONS)
_COSINES, _SINES = np.cos(_DIRECTIONS), np.sin(_DIRECTIONS)
"""The support's directions (constants of the compiled code)."""


def _support(accel: np.ndarray, speed: np.ndarray, stops: np.ndarray,
             block: int = 1) -> np.ndarray:
    """Per sample k and axis, ``max |cos(p)*accel[k'] + sin(p)*speed[k']|`` over the
    samples k' from k to the next stop (a stop corner or the end), for the
    :data:`SUPPORT_DIRECTIONS` angles p evenly spaced in [0, pi/2], at every ``block``-th
    sample; shape (ceil(n / block), n_axes, SUPPORT_DIRECTIONS) [V]. One compiled
    backward pass per piece between stops (no temporary of the samples' size)."""
    out = np.empty((-(-len(accel) // block),) + accel.shape[1:] + (SUPPORT_DIRECTIONS,))
    bounds = np.concatenate([[0], np.asarray(stops, dtype=np.int64), [len(accel)]])
    _support_into(np.ascontiguousarray(accel), np.ascontiguousarray(speed), bounds,
                  block, out)
    return out


@njit(cache=True, inline="always")
def _raise_to_sample(out, accel, speed, k):
    """``out`` (n_axes, SUPPORT_DIRECTIONS) [V] raised to sample ``k``'s
    ``|cos(p)*accel + sin(p)*speed|`` where that is larger."""
    for j in range(out.shape[0]):
        for d in range(out.shape[1]):
            v = abs(_COSINES[d] * accel[k, j] + _SINES[d] * speed[k, j])
            if v > out[j, d]:
                out[j, d] = v


@njit(cache=True)
def _support_into(accel, speed, bounds, block, out):
    """:func:`_support`'s running maxima, backwards from each stop in ``bounds``."""
    running = np.empty((accel.shape[1], SUPPORT_DIRECTIONS))
    for b in range(bounds.shape[0] - 1):
        lo, hi = bounds[b], bounds[b + 1]
        running[:] = 0.0
        for k in range(hi - 1, lo - 1, -1):
            _raise_to_sample(running, accel, speed, k)
            if k % block == 0:  # element by element: a slice copy compiles a shape check
                for j in range(running.shape[0]):  # with its error message (2 s of a
                    for d in range(running.shape[1]):  # cold start)
                        out[k // block, j, d] = running[j, d]


@njit(cache=True)
def _support_at(plan, i, out):
    """The support of sample ``i`` (:func:`_support` with ``block = 1``) into ``out``
    (n_axes, SUPPORT_DIRECTIONS) [V]: the stored one at the next stored sample before the
    next stop, raised to the samples from ``i`` to there. Returns ``out``."""
    block = SUPPORT_BLOCK
    lo, up = 0, plan.bounds.shape[0] - 1  # the next stop: the first bound > i (the last
    while lo < up:                        # bound, the plan's length, is > i)
        mid = (lo + up) // 2
        if plan.bounds[mid] > i:
            up = mid
        else:
            lo = mid + 1
    end = i if i % block == 0 else min((i // block + 1) * block, plan.bounds[lo])
    stored = end // block if end < plan.bounds[lo] else -1
    for j in range(out.shape[0]):
        for d in range(out.shape[1]):
            out[j, d] = plan.support[stored, j, d] if stored >= 0 else 0.0
    for k in range(i, end):
        _raise_to_sample(out, plan.drive_accel, plan.drive_speed, k)
    return out


def _path_steps(desired: np.ndarray) -> np.ndarray:
    """``|desired[k + 1] - desired[k]|`` [pulse] for every sample k (0 at the last), shape
    (n,), axis by axis (no temporary of the positions' size)."""
    steps = np.zeros(len(desired))
    for j in range(desired.shape[1]):
        d = np.diff(desired[:, j])
        steps[:-1] += np.square(d, out=d)
    return np.sqrt(steps, out=steps)


def _sample_extremes(position: np.ndarray, speed: np.ndarray, drive: np.ndarray, a, b0, c,
                     b1):
    """The highest and lowest position [pulse] the plan passes through over each sample
    (from sample k to k + 1; the last sample's own), each shape (n, n_axes): where its
    speed (n, n_axes) [rad/s] changes sign within the sample, the ZOH plant ``(a, b0, c,
    b1)`` (shape (n_axes,) each) turns between the samples, after the travel to rest under
    that sample's drive (n, n_axes) [V] (:func:`_stopping_travel`; at a stop corner up to
    ``acceleration*Ts^2/8`` beyond both samples)."""
    hi = position.copy()
    np.maximum(hi[:-1], position[1:], out=hi[:-1])
    lo = position.copy()
    np.minimum(lo[:-1], position[1:], out=lo[:-1])
    for k, j in zip(*np.nonzero(speed[:-1] * speed[1:] < 0.0)):
        turn = position[k, j] + _stopping_travel(speed[k, j], a[j], b0[j], c[j], b1[j],
                                                 drive[k, j])
        hi[k, j] = max(hi[k, j], turn)
        lo[k, j] = min(lo[k, j], turn)
    return hi, lo


def _stop_guards(position: np.ndarray, stop_times, rest: int, path_tolerance: float,
                 extremes):
    """Where the plant must be able to stop, braking at Umax (:func:`_short_of_stop`):
    ``(guards, offsets)``. ``guards`` (n_guards, 4): per guard its first plan sample, the
    sample after its last, the position [pulse] and the direction (+1: not above it, -1:
    not below), axis by axis (axis j's rows ``offsets[j]:offsets[j + 1]``, (n_axes + 1,)),
    in the order of their stops; at most two of an axis' guards overlap (a guard ends by
    the stop of the axis' next one, which starts after the stop before it), and their
    first samples do not decrease (:func:`_guarded`).

    A stop is a stop corner (at the fractional samples ``stop_times``) or the plan's rest
    on the end (at sample ``rest``; what the pre-compensation leaves after that, a
    fraction of a pulse either way when the landing could not be made exact, is not a
    move). An axis that the plan ``position`` (n, n_axes) moves into a stop and does not
    move on past it in the next piece is guarded from the sample after the plan was last
    beyond the stop's position (at the earliest the previous stop) up to where the plan
    moves it past the stop after all, or up to the next stop it moves into (the plan's
    last sample if none): the plant is kept able to stop before the plan's farthest
    position in that direction over that stretch, between the samples too (``extremes``,
    :func:`_sample_extremes`). Held while the plan holds or turns the axis, a guard keeps
    a plant that lags the plan from running through the corner after the plan has
    turned. The plan's own braking never needs more than Umax and it comes to rest at
    its stops, so on the model's plant a guard changes nothing. (An axis that goes on
    through a stop is not guarded there: the plan passes the corner's sample moving.)
    A move, into, past or beyond a stop, is one of more than
    :func:`~nurbsmotion.motion_plan.move_tolerance` of ``path_tolerance`` [pulse]."""
    n, n_axes = position.shape
    tol = move_tolerance(path_tolerance)
    hi, lo = extremes
    rows: list = [[] for _ in range(n_axes)]
    corners = [t for t in np.asarray(stop_times, dtype=float) if 0 < t < rest]
    arrive = [min(int(math.floor(t + 1e-9)), n - 1) for t in corners] + [max(rest, 1)]
    stops = [min(int(math.ceil(t - 1e-9)), n - 1) for t in corners] + [max(rest, 1)]
    firsts = [0] + stops[:-1]               # each stop's piece starts at the stop before
    sign = np.zeros((len(stops), n_axes))   # the direction each axis moves into each stop
    for g, (first, k_in) in enumerate(zip(firsts, arrive)):
        for j in range(n_axes):
            off = position[k_in, j] - position[first:k_in, j]
            moved = np.flatnonzero(np.abs(off) > tol)
            if moved.size:
                sign[g, j] = np.sign(off[moved[-1]])
    for g, (first, k_in, k) in enumerate(zip(firsts, arrive, stops)):
        for j in np.flatnonzero(sign[g]):
            s = sign[g, j]
            beyond = np.flatnonzero(s * (position[first:k_in, j] - position[k_in, j]) > tol)
            start = first + (beyond[-1] + 1 if beyond.size else 0)
            later = np.flatnonzero(sign[g + 1:, j])
            hold = stops[g + 1 + later[0]] if later.size else n
            farthest = s * np.max(s * position[start:k + 1, j])
            past = np.flatnonzero(s * (position[k:hold, j] - farthest) > tol)
            if past.size and g + 1 < len(stops) and k + past[0] < stops[g + 1]:
                continue  # the axis goes on through the stop
            end = k + past[0] if past.size else hold
            farthest = (np.max(hi[start:end, j]) if s > 0 else np.min(lo[start:end, j]))
            rows[j].append((start, end, farthest, s))
    offsets = np.cumsum([0] + [len(r) for r in rows]).astype(np.int64)
    guards = np.array([g for r in rows for g in r], dtype=float).reshape(-1, 4)
    return guards, offsets


@njit(cache=True)
def _guarded(guards, lo, hi, i, side):
    """The position [pulse] that the guards in rows ``lo:hi`` of ``guards``
    (:func:`_stop_guards`, one axis') on direction ``side`` (+-1) hold at plan sample
    ``i``: the nearest of those that hold it (+-inf: none). Only the last two that start
    by ``i`` can (bisection on their first samples)."""
    first, up = lo, hi
    while lo < up:   # the first guard that starts after i
        mid = (lo + up) // 2
        if guards[mid, 0] > i:
            up = mid
        else:
            lo = mid + 1
    best = side * math.inf
    for g in range(max(lo - 2, first), lo):
        if guards[g, 3] == side and i < guards[g, 1]:
            best = min(best, guards[g, 2]) if side > 0 else max(best, guards[g, 2])
    return best


def _prior_estimate(plan: PlannedPlan) -> np.ndarray:
    """The identification's start (:func:`_identify`): the model's (a, b1, beta), shape
    (12, n_axes) with the covariance. Prior standard deviations: 1 - a for a (a plant
    whose tau is half or twice the model's has 1 - a about twice or half the model's),
    and GAIN_RANGE times b1 and beta (the drive's effect, proportional to Kc/tau)."""
    a, b0, c, b1 = plan.a, plan.b0, plan.c, plan.b1
    beta = c * b0 - a * b1
    est = np.zeros((12, len(a)))
    est[0], est[1], est[2] = a, b1, beta
    est[3] = (1.0 - a) ** 2
    est[7] = (GAIN_RANGE * b1) ** 2
    est[11] = (GAIN_RANGE * beta) ** 2
    return est


def reading_knowledge(machine: Machine, a, b0, c, b1) -> dict:
    """What the online step takes from the model machine's reading of the position
    (:attr:`Machine.encoder`, :attr:`Machine.measurement_noise`,
    :attr:`Machine.dac_bits`): the identification's ``dead_zone`` [pulse], 0 for an
    exact reading and an exact drive (today's step, bit for bit).

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
    return {"dead_zone": dead_zone}
