"""The ``planned`` interpolator: plan the actual motion, then steer the plant along it.

Offline (:func:`nurbsmotion.motion_plan.plan_motion`): the actual position of every sample,
time-optimal within the drive limit of the model's ZOH plant, on the path (or within the
corner tolerance of it), at rest at both ends and at every stop corner, together with the
feedforward drive u_ff[k] and plant state x_ff[k] = (w_ff, theta_ff) that make the model's
plant follow it exactly.

Online, every sample (:func:`online_step`, plain scalar/array code that numba compiles):

1. the plant's drive law ``u = p1*dw/dt + p2*w`` (p1 = tau/Kc, p2 = 1/Kc for the model) is
   estimated by recursive least squares from the drives applied and the speeds measured,
   starting from the model; the deviation from the plan's state is measured (position)
   and propagated through the model from the feedback's last drive (speed);
2. a time-scaling governor advances the plan's clock by ``rate`` in (0, 1] samples: the
   largest rate at which the *estimated* plant can follow the plan's drive (speed part
   times the rate, acceleration part times its square) up to the next stop within
   ``1 - drive_headroom`` of Umax (never below the plan's own use), lowered further after
   a sample whose drive demand exceeded Umax; it changes by at most ``1 - tracking_pole``
   per sample. A weaker plant is thus slowed down before it has to brake, so it can still
   stop at the next corner;
3. the drive is the estimated plant's feedforward of the plan at that clock plus a state
   feedback on the deviation whose gains put both poles of the model's deviation dynamics
   at ``tracking_pole``, clipped to +-Umax: *every drive is within the limit by
   construction*, whatever the true plant;
4. the loop's law is affine in the setpoint between its clamps,
   ``u = slope*thd + offset`` with slope > 0 (:func:`nurbsmotion.control.pid_affine`,
   from the law's memory and the measured state), so the setpoint that produces exactly
   that drive is ``thd = (u - offset) / slope``; where a clamp of the law (LinuxCNC
   ``pid``'s maxerror, deadband, ...) makes the drive differ, the setpoint is moved until
   the law's own output (:func:`nurbsmotion.control.pid_output`) is within Umax. Setpoints
   lead the path and need not lie on it; the actual position is what must.

Every sample's status says whether the governor slowed the plan or the drive was clipped
(``LIMITED``); the step goes on steering after the plan's end until the run ends.

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
from ..control import pid_affine, pid_output
from ..errors import InfeasibleError
from ..feed import FeedLimit
from ..machine import Machine
from ..motion_plan import MotionPlan, axis_zoh, plan_motion
from ..nurbs import NurbsCurve
from .base import Interpolator, positive_feed

__all__ = ["PlannedInterpolator", "online_step", "DEFAULT_TRACKING_POLE",
           "DEFAULT_DRIVE_HEADROOM"]

DEFAULT_TRACKING_POLE = 0.7
"""Both poles of the model's deviation dynamics under the online feedback: a deviation from
the plan decays by this factor per sample on the model's plant (a user parameter: closer to
0 follows a mismatched plant more tightly and tolerates less mismatch, closer to 1 the
reverse)."""

DEFAULT_DRIVE_HEADROOM = 0.1
"""Fraction of Umax the governor keeps free for the feedback when it scales the plan's
clock to the drive the (estimated) plant needs up to the next stop (a user parameter)."""

ESTIMATE_NOISE = 0.01
"""Standard deviation of the drive-model residual the online estimate expects, as a
fraction of Umax (the encoder's averaged speeds fit the plant's law to about Ts/tau)."""

GAIN_RANGE = 4.0
"""The estimated plant may need between 1/4 and 4 times the model's drive (issue 10 asks
for any tau, Kc within x[0.5, 2]: up to 4 times the acceleration drive)."""


@njit(cache=True)
def online_step(phi, rate, excess_prev, dev, est, hist, position, speed_measured,
                measured_is_true, plan_position, plan_drive_speed, plan_drive_accel,
                peak_speed, peak_accel, prior, a, b0, c, b1, kp, kd, umax, headroom, ts,
                rate_gain, slope, offset, out_setpoint, out_drive):
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
    dev : ndarray, shape (2, n_axes)
        In/out: the last position deviation [pulse] and drive deviation u_ff - u [V].
    est : ndarray, shape (5, n_axes)
        In/out: the plant's estimated law ``u = p1*dw/dt + p2*w`` (p1 = tau/Kc [V s^2/rad],
        p2 = 1/Kc [V s/rad]) and the covariance (P11, P12, P22) of the estimate.
    hist : ndarray, shape (4, n_axes)
        In/out: u[k-1], u[k-2] [V], the speed of the last sample and the one before
        [rad/s] (row 3 is 1 once two speeds are known).
    position : ndarray, shape (n_axes,)
        tha[k], measured [pulse].
    speed_measured : ndarray, shape (n_axes,)
        The loop's measured speed [rad/s]: encoder differencing (tha[k]-tha[k-1])/(Ke*Ts),
        or the true speed when ``measured_is_true``.
    measured_is_true : bool
    plan_position : ndarray, shape (n, n_axes)
        theta_ff [pulse].
    plan_drive_speed, plan_drive_accel : ndarray, shape (n, n_axes)
        The feedforward drive's speed part w_ff/Kc and acceleration part
        (w_ff[k+1]-w_ff[k])/b0 [V] (u_ff is their sum at rate 1).
    peak_speed, peak_accel : ndarray, shape (n, n_axes)
        The largest |speed part| and |acceleration part| from each sample to the next stop.
    prior : ndarray, shape (2, n_axes)
        The model's p1 = tau/Kc and p2 = 1/Kc.
    a, b0, c, b1 : ndarray, shape (n_axes,)
        The model's ZOH plant (:func:`nurbsmotion.motion_plan.axis_zoh`).
    kp, kd : ndarray, shape (n_axes,)
        Feedback gains on the position [V/pulse] and speed [V/(rad/s)] deviation.
    umax : float
        Umax [V].
    headroom : float
        Fraction of Umax the governor keeps for the feedback.
    ts : float
        Ts [s].
    rate_gain : float
        Largest change of the rate per sample.
    slope, offset : ndarray, shape (n_axes,)
        The law's affine form at this sample: u[k] = slope*thd[k] + offset [V/pulse, V].
    out_setpoint, out_drive : ndarray, shape (n_axes,)
        Written: thd[k] [pulse] and the drive it produces [V].

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
    noise = (ESTIMATE_NOISE * umax) ** 2
    # 1a. estimate the plant's law from the last drives and speeds (recursive least squares)
    r_max = 1.0
    for j in range(n_axes):
        v_now = speed_measured[j]
        if hist[3, j] > 0.0:
            if measured_is_true:
                ubar = hist[0, j]
            else:
                ubar = 0.5 * (hist[0, j] + hist[1, j])
            x1 = (v_now - hist[2, j]) / ts
            x2 = 0.5 * (v_now + hist[2, j])
            px1 = est[2, j] * x1 + est[3, j] * x2
            px2 = est[3, j] * x1 + est[4, j] * x2
            gain = 1.0 / (noise + x1 * px1 + x2 * px2)
            err = ubar - est[0, j] * x1 - est[1, j] * x2
            est[0, j] += px1 * gain * err
            est[1, j] += px2 * gain * err
            est[2, j] -= px1 * px1 * gain
            est[3, j] -= px1 * px2 * gain
            est[4, j] -= px2 * px2 * gain
        hist[2, j] = v_now
        hist[3, j] = 1.0
        # 2a. the clock's largest rate at which the estimated plant can still follow the
        # plan to the next stop: ga*A*r^2 + gv*V*r <= (1 - headroom)*Umax
        ga = min(max(est[0, j] / prior[0, j], 1.0 / GAIN_RANGE), GAIN_RANGE)
        gv = min(max(est[1, j] / prior[1, j], 1.0 / GAIN_RANGE), GAIN_RANGE)
        A = ga * peak_accel[i0, j]
        V = gv * peak_speed[i0, j]
        # the plan itself may use the full drive; the headroom applies beyond the model
        limit = max((1.0 - headroom) * umax, peak_accel[i0, j] + peak_speed[i0, j])
        if A + V > limit:
            if A > 0.0:
                r = (-V + (V * V + 4.0 * A * limit) ** 0.5) / (2.0 * A)
            else:
                r = limit / V
            # within the estimate's own accuracy of the plan's rate, keep it
            r_max = min(r_max, 1.0 if r > 1.0 - ESTIMATE_NOISE else r)
    # 2b. governor: towards the largest rate, slower after a drive demand beyond Umax
    target = r_max
    if excess_prev > 0.0:
        target = min(target, rate * (1.0 - rate_gain * excess_prev))
    if target < rate:
        rate = max(target, rate - rate_gain, rate_gain)
    else:
        rate = min(target, rate + rate_gain)
    excess = 0.0
    worst = 0.0
    for j in range(n_axes):
        # 1b. deviation from the plan's state: position measured; speed from the position
        # deviation's last increment and the last drive's deviation (exact on the model)
        th = plan_position[i0, j] * (1.0 - f) + plan_position[i1, j] * f
        e_th = th - position[j]
        worst = max(worst, abs(e_th))
        e_w_prev = (e_th - dev[0, j] - b1[j] * dev[1, j]) / c[j]
        e_w = a[j] * e_w_prev + b0[j] * dev[1, j]
        # 3. drive: feedforward of the estimated plant at the clock plus feedback, clipped
        ga = min(max(est[0, j] / prior[0, j], 1.0 / GAIN_RANGE), GAIN_RANGE)
        gv = min(max(est[1, j] / prior[1, j], 1.0 / GAIN_RANGE), GAIN_RANGE)
        uf = ((plan_drive_speed[i0, j] * (1.0 - f) + plan_drive_speed[i1, j] * f) * rate * gv
              + (plan_drive_accel[i0, j] * (1.0 - f) + plan_drive_accel[i1, j] * f)
              * rate * rate * ga)
        u = uf + kp[j] * e_th + kd[j] * e_w
        if abs(u) > umax:
            excess = max(excess, abs(u) / umax - 1.0)
            u = umax if u > 0 else -umax
        dev[0, j] = e_th
        dev[1, j] = uf - u  # the feedback's part: what moves the plant off the plan
        hist[1, j] = hist[0, j]
        hist[0, j] = u
        # 4. the setpoint that produces exactly this drive
        out_drive[j] = u
        out_setpoint[j] = (u - offset[j]) / slope[j]
    return min(phi + rate, n - 1.0), rate, excess


class PlannedPlan(NamedTuple):
    """What the online step reads (see :func:`online_step` for each array's meaning)."""

    parameter: np.ndarray        # (n,) curve parameter of each sample's desired position
    desired: np.ndarray          # (n, n_axes) desired position [pulse]
    position: np.ndarray         # (n, n_axes) theta_ff [pulse]
    drive_speed: np.ndarray      # (n, n_axes) [V]
    drive_accel: np.ndarray      # (n, n_axes) [V]
    peak_speed: np.ndarray       # (n, n_axes) [V]
    peak_accel: np.ndarray       # (n, n_axes) [V]
    prior: np.ndarray            # (2, n_axes) tau/Kc, 1/Kc of the model
    a: np.ndarray                # (n_axes,) the model's ZOH plant
    b0: np.ndarray
    c: np.ndarray
    b1: np.ndarray
    kp: np.ndarray               # (n_axes,) feedback gains [V/pulse]
    kd: np.ndarray               # (n_axes,) [V/(rad/s)]
    mechanical_gain: np.ndarray  # (n_axes,) Ke [pulse/rad]
    measured_is_true: bool
    headroom: float
    rate_gain: float


class PlannedState(NamedTuple):
    """The online state: the plan's clock [samples], its rate and the last excess
    (shape (1,) each), the deviation, estimate and history arrays of :func:`online_step`,
    and per-axis scratch (the law's slope and offset, the measured speed, the drive)."""

    phi: np.ndarray
    rate: np.ndarray
    excess: np.ndarray
    dev: np.ndarray
    est: np.ndarray
    hist: np.ndarray
    slope: np.ndarray
    offset: np.ndarray
    speed: np.ndarray
    drive: np.ndarray


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
    InfeasibleError
        If the feed is not finite and > 0, the drive cannot move along the path, or the
        plan would take more than ``max_samples`` samples.
    """

    name = "planned"

    def __init__(self, curve: NurbsCurve, machine: Machine, feed, *,
                 corner_tolerance: float = 0.0, drive_fraction: float = 1.0,
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
                raise InfeasibleError(f"{name} must lie in [{lo:g}, {hi:g}), got {value!r}")
        self.feed = feed
        self.machine = machine
        self.tracking_pole = float(tracking_pole)
        self.drive_headroom = float(drive_headroom)
        self.motion: MotionPlan = plan_motion(curve, machine, feed,
                                              corner_tolerance=corner_tolerance,
                                              drive_fraction=drive_fraction,
                                              grid_size=grid_size, max_samples=max_samples)
        a, b0, c, b1 = axis_zoh(machine)
        p = self.motion
        drive_speed = p.speed / machine.Kc
        drive_accel = np.zeros_like(p.speed)
        drive_accel[:-1] = (p.speed[1:] - p.speed[:-1]) / b0
        kp, kd = _feedback_gains(a, b0, c, b1, self.tracking_pole)
        self.plan = PlannedPlan(
            parameter=p.parameter, desired=p.desired, position=p.position,
            drive_speed=drive_speed, drive_accel=drive_accel,
            peak_speed=_peak_to_next_stop(np.abs(drive_speed), p.stop_indices),
            peak_accel=_peak_to_next_stop(np.abs(drive_accel), p.stop_indices),
            prior=np.array([machine.tau / machine.Kc, 1.0 / machine.Kc]), a=a, b0=b0, c=c,
            b1=b1, kp=kp, kd=kd, mechanical_gain=np.array(machine.Ke, dtype=float),
            measured_is_true=machine.speed_measurement != "encoder",
            headroom=self.drive_headroom,
            # the clock's rate changes at most as fast as a deviation decays
            rate_gain=1.0 - self.tracking_pole)

    def nominal_duration(self) -> float:
        return self.motion.duration

    def new_state(self) -> PlannedState:
        n = self.machine.n_axes
        prior = self.plan.prior
        est = np.empty((5, n))
        est[:2] = prior
        # Prior covariance: the plant may need 1/GAIN_RANGE .. GAIN_RANGE x the model's
        # drive, read as one standard deviation of the model's own value.
        est[2] = prior[0] ** 2
        est[3] = 0.0
        est[4] = prior[1] ** 2
        return PlannedState(np.ones(1), np.ones(1), np.zeros(1), np.zeros((2, n)), est,
                            np.zeros((4, n)), np.empty(n), np.empty(n), np.empty(n),
                            np.empty(n))


@njit(cache=True)
def _within_limit(law, law_state, j, command, position, velocity):
    """The setpoint of axis ``j`` nearest to ``command`` whose drive, as the law computes
    it (clamps included), is within Umax: ``command`` itself when the affine form was
    exact (always for PD and PD+). The law's output rises with the command, so the
    search widens away from the limit it exceeds, then bisects. Returns
    ``(setpoint, found)``."""
    umax = law[j]["maxoutput"]
    out = pid_output(law, law_state, j, command, position, velocity)[0]
    if abs(out) <= umax:
        return command, True
    sign = 1.0 if out > 0 else -1.0
    step = abs(command - position) + 1.0
    good = command - sign * step
    tries = 0
    while abs(pid_output(law, law_state, j, good, position, velocity)[0]) > umax:
        tries += 1
        if tries > 60:
            return command, False
        step *= 2.0
        good = command - sign * step
    bad = command
    for _ in range(60):
        mid = 0.5 * (good + bad)
        if abs(pid_output(law, law_state, j, mid, position, velocity)[0]) <= umax:
            good = mid
        else:
            bad = mid
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
        state.speed[j] = velocity[j] / plan.mechanical_gain[j]
        bounds[j, 0] = np.nan
        bounds[j, 1] = np.nan
    phi = state.phi[0]
    phi_next, rate, excess = online_step(
        phi, state.rate[0], state.excess[0], state.dev, state.est, state.hist, position,
        state.speed, plan.measured_is_true, plan.position, plan.drive_speed,
        plan.drive_accel, plan.peak_speed, plan.peak_accel, plan.prior, plan.a, plan.b0,
        plan.c, plan.b1, plan.kp, plan.kd, law[0]["maxoutput"], plan.headroom,
        law[0]["period"], plan.rate_gain, state.slope, state.offset, command, state.drive)
    state.phi[0] = phi_next
    state.rate[0] = rate
    state.excess[0] = excess
    status = stepping.WORKING
    for j in range(n_axes):
        setpoint, found = _within_limit(law, law_state, j, command[j], position[j],
                                        velocity[j])
        if not found:
            status = stepping.CORNERED
        command[j] = setpoint
    n = plan.parameter.shape[0]
    i0 = min(int(phi), n - 1)
    i1 = min(i0 + 1, n - 1)
    dist2 = 0.0
    for j in range(n_axes):
        dist2 += (plan.desired[i1, j] - plan.desired[i0, j]) ** 2
    feed = rate * math.sqrt(dist2) / law[0]["period"]  # the plan's path speed at its clock
    if phi >= n - 1:
        return 1.0, 0.0, stepping.FINISHED
    if status == stepping.WORKING and (excess > 0.0 or rate < 1.0):
        status = stepping.LIMITED
    return plan.parameter[i0], feed, status


stepping.register(PlannedPlan, planned_step)


def _peak_to_next_stop(values: np.ndarray, stops: np.ndarray) -> np.ndarray:
    """Per sample and axis, the largest of ``values`` from that sample to the next stop
    (a stop corner or the end), shape of ``values``."""
    out = np.empty_like(values)
    bounds = np.concatenate([[0], np.asarray(stops, dtype=int), [len(values)]])
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        if hi > lo:
            seg = values[lo:hi][::-1]
            out[lo:hi] = np.maximum.accumulate(seg, axis=0)[::-1]
    return out


def _feedback_gains(a, b0, c, b1, pole):
    """State-feedback gains (on the position and speed deviation) that put both poles of
    the model's deviation dynamics at ``pole`` (Ackermann's formula), shape (2, n_axes)."""
    out = np.empty((2, len(a)))
    for j in range(len(a)):
        A = np.array([[a[j], 0.0], [c[j], 1.0]])
        B = np.array([b0[j], b1[j]])
        ctrb = np.column_stack([B, A @ B])
        phiA = A @ A - 2 * pole * A + pole * pole * np.eye(2)
        K = np.linalg.solve(ctrb, phiA)[1]          # last row of C^-1 phi(A): [Kw, Ktheta]
        out[0, j], out[1, j] = K[1], K[0]
    return out
