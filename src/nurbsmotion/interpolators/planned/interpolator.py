"""The ``planned`` interpolator's value objects: the plan the online step reads
(:class:`PlannedPlan`), its state (:class:`PlannedState`), and :class:`PlannedInterpolator`,
which builds both from the offline plan (:func:`.plan.plan_motion`) and registers the step
(:func:`.step.planned_step`) with the loop.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ... import stepping
from ..._runtime.memory import release_freed_memory
from ...errors import InvalidArgumentError
from ...feed import FeedLimit
from ...machine import Machine
from ...nurbs import NurbsCurve
from ..base import Interpolator, positive_feed
from .disturbance import DOB_ROWS, observer_gains
from .governor import RATE_BISECTIONS, RATE_WINDOW, SUPPORT_BLOCK, SUPPORT_DIRECTIONS, _support
from .guards import _sample_extremes, _stop_guards
from .identify import (EST_ROWS, GAIN_RANGE, HIST_ROWS, N_PARAMETERS, _drive_weights,
                       reading_knowledge)
from .inverse import axis_zoh
from .mode_law import MODE_LAW_ROWS, mode_landing_law, mode_rest_observer
from .plan import plan_motion
from .rest_observer import REST_OBSERVER_ROWS, rest_observer
from .shaper import encoder_offset, shape_plan
from ...limits import DEFAULT_PATH_TOLERANCE
from .shorten import DEFAULT_SHORTEN_WORK
from .step import DRIVE_MATCH, LANDING_ROWS, planned_step

__all__ = ["PlannedInterpolator", "PlannedPlan", "PlannedState", "DEFAULT_TRACKING_POLE",
           "DEFAULT_DRIVE_HEADROOM", "machine_knowledge"]


DEFAULT_TRACKING_POLE = 0.7
"""Both poles of the deviation dynamics under the online feedback, placed on the identified
plant: a deviation from the plan decays by this factor per sample (a user parameter:
closer to 0 follows the plan more tightly and leaves less drive to the governor's rate
changes, closer to 1 the reverse)."""

DEFAULT_DRIVE_HEADROOM = 0.1
"""Fraction of Umax the governor keeps free for the feedback when it scales the plan's
clock to the drive the (estimated) plant needs up to the next stop (a user parameter)."""


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
    # the landing's band [pulse] (reading_knowledge) and its closed loop's poles
    landing_band: float = 0.0
    landing_pole: float = 0.0
    delay: float = 0.0           # the model's delay [samples], < 1 (the landing's law)
    # the online step's tuning, each documented at the constant that is its default (data,
    # not compiled in: ``plan._replace(rate_window=32)`` needs no new compilation); the
    # support's SUPPORT_BLOCK and SUPPORT_DIRECTIONS fix array shapes and stay constants
    rate_window: int = RATE_WINDOW          # plan samples the governor rates one by one
    rate_bisections: int = RATE_BISECTIONS  # bisections of a largest rate or drive
    gain_range: float = GAIN_RANGE          # the estimated plant's drive, model's x[1/g, g]
    drive_match: float = DRIVE_MATCH        # the law's output matches a drive (x Umax)
    # (MODE_LAW_ROWS, n_axes): per axis whose model declares a mode, 1 and the landing's
    # law designed with it (.mode_law.mode_landing_law); zeros: the rigid landing
    mode_law: np.ndarray = np.zeros((MODE_LAW_ROWS, 0))
    # (n, n_axes) [pulse]: what the encoder reads of the model's twist under the plan's
    # drive (.shaper.encoder_offset), taken off the reading on a moded axis; (0, 0): none
    twist: np.ndarray = np.zeros((0, 0))
    # (REST_OBSERVER_ROWS, n_axes): per rigid axis whose model's reading is not exact, 1 and
    # the pole of the landing's speed observer (.rest_observer.rest_observer); zeros: none
    rest_observer: np.ndarray = np.zeros((REST_OBSERVER_ROWS, 0))
    # feed the disturbance observer's estimate forward in the tracking (.disturbance;
    # opt-in, work in progress: docs/model.md#planned-on-a-real-machine)
    disturbance_observer: bool = False
    # (3, n_axes): the disturbance observer's deadbeat gains (.disturbance.observer_gains);
    # an axis with a mode takes the gains designed with it (mode_law rows from DOB_ROW)
    disturbance_gain: np.ndarray = np.zeros((3, 0))


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
    landing: np.ndarray
    # (DOB_ROWS, n_axes): the disturbance observer's estimates (.disturbance)
    disturbance: np.ndarray


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
        :data:`~nurbsmotion.limits.SHORT_MOVE_SAMPLES` samples; with stops, planned
        from stop to stop) may go where that lets it arrive sooner, or as far as the
        speed profile's plan does if
        that is farther (:data:`~nurbsmotion.limits.DEFAULT_PATH_TOLERANCE`: one
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
    shorten_work : float
        > 0: the simplex work a short move's search may spend per sample, in pivot-rows
        (:data:`~.shorten.DEFAULT_SHORTEN_WORK`; ``math.inf``: no budget). Where it runs
        out, the plan keeps the earliest arrival found so far and :attr:`notes` says so.
    mode_shaper : bool
        Shape the plan's drive *axis by axis* at the model machine's two-mass modes (ZVD,
        :func:`.shaper.shape_plan`) and steer to the encoder's reading of the model's
        twist. Off by default: it cuts curves. Without it a model with a mode already
        gets its plan's *time law* shaped (:func:`.shaper.time_law_shaper`) and the
        model's twist taken off the reading (``PlannedPlan.twist``); with it the axes are
        shaped on top of that (docs/model.md#planned-on-a-real-machine).
    disturbance_observer : bool
        Estimate the axis' speed, position and the drive it gets besides the one asked for
        (a load, Coulomb friction) with a deadbeat observer on the model's plant, feed
        that drive forward in the tracking (per direction of the plan's motion), reject
        the deviation it made before it was estimated deadbeat, and hand its resting part
        to the landing's integral (:mod:`.disturbance`). Off by default: work in progress
        (issue 33); on item 1 it cuts the friction's contour from 109-131 to 8-30 um and
        the load's from 200-221 to 14-27 um, but lengthens the load's settle on the Pi and
        its chatter at rest (docs/model.md#planned-on-a-real-machine). On an axis whose
        model declares a mode the observer is the one designed with the mode
        (:func:`.mode_law.mode_disturbance_observer`: its pole the one of the fastest
        tracking loop over the model's uncertainty corners, no deadbeat rejection), read
        on the reading less the model's twist; on ``die-bonder-real`` (item 2) it cuts
        the contour on 50 of 54 runs (the Pi at 0.2 m/s from 528-542 to 72-209 um), but
        not where the true Kc is 10 % low at 1-2 m/s, and the item-1 mode row's contour
        at 1-2 m/s grows (38.6 -> 47.3, 93.4 -> 112 um).

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
                 max_samples: int = 10_000_000, mode_shaper: bool = False,
                 shorten_work: float = DEFAULT_SHORTEN_WORK,
                 disturbance_observer: bool = False):
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
        if machine.delay >= machine.sample_period:
            raise InvalidArgumentError(
                f"planned lands on a law that models a delay of less than one sample; the "
                f"machine's delay is {machine.delay:g} s ({machine.delay / machine.sample_period:g}"
                f" samples of {machine.sample_period:g} s): use another interpolator or a "
                f"shorter sample period's worth of delay")
        self.drive_headroom = float(drive_headroom)
        # The motion's speed and drive are not kept: the plan's drive_speed and
        # drive_accel hold them (u_ff = drive_speed + drive_accel), and a long move's
        # memory is mostly these per-sample arrays.
        p = plan_motion(curve, machine, feed, corner_tolerance=corner_tolerance,
                        path_tolerance=path_tolerance, drive_fraction=drive_fraction,
                        grid_size=grid_size, max_samples=max_samples,
                        shorten_work=shorten_work)
        if mode_shaper:  # the drive shaped at the model's modes (shaper.py; opt-in)
            p = shape_plan(p, machine, curve)
        self.duration = p.duration
        self.shorten_status = p.shorten_status   # step 6's search (MotionPlan's)
        if corner_tolerance > 0 and p.stop_times.size:  # asked to round, but stops
            self.notes += ("the motion stops at the sharp corners: rounding them within the "
                           "corner tolerance would not arrive sooner",)
        if p.time_law == "rigid, no shaped law":
            self.notes += ("no time law shaped at the model's modes stays within the drive "
                           "limit on this path: the plan is the rigid one, which may ring "
                           "the mode",)
        if p.shorten_status == "work budget":
            self.notes += (f"the short move's search for its earliest arrival stopped at its "
                           f"work budget (shorten_work={shorten_work:g} pivot-rows a "
                           f"sample): it arrives at sample {p.arrival}, the earliest found "
                           f"before that",)
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
        twist = encoder_offset(p.drive, machine)  # None without a mode
        if twist is not None and mode_shaper:  # what the encoder reads of the model's mode
            position = position + twist
            twist = None
        del p  # its speed, drive and desired positions before the support is built
        self.plan = PlannedPlan(
            parameter=parameter, path_step=path_step, position=position,
            drive_speed=drive_speed, drive_accel=drive_accel,
            support=_support(drive_accel, drive_speed, stops, SUPPORT_BLOCK),
            bounds=np.append(np.asarray(stops, dtype=np.int64), n),
            a=a, b0=b0, c=c, b1=b1, log_a=np.log(a), headroom=self.drive_headroom,
            # the clock's rate changes at most as fast as a deviation decays
            rate_gain=1.0 - self.tracking_pole, rest=rest, guards=guards,
            guard_offsets=guard_offsets, disturbance_observer=bool(disturbance_observer),
            **({} if twist is None else dict(twist=twist)),
            **machine_knowledge(machine, a, b0, c, b1, self.tracking_pole))
        release_freed_memory()  # the plan's temporaries, before a long run's peak

    def nominal_duration(self) -> float:
        return self.duration

    def new_state(self) -> PlannedState:
        n = self.machine.n_axes
        # the clock starts at plan sample 0 with the loop: the step gives sample 0's
        # setpoint too (registered below with first_sample=0)
        return PlannedState(np.zeros(1), np.ones(1), np.zeros(1), _prior_estimate(self.plan, self.machine.max_drive),
                            np.zeros((HIST_ROWS, n)), np.empty(n), np.empty(n), np.empty(n),
                            np.empty((n, SUPPORT_DIRECTIONS)), np.empty((2, n)),
                            np.zeros((LANDING_ROWS, n)), np.zeros((DOB_ROWS, n)))


def _example(n_axes: int):
    """Made-up plan and state of the types a run passes (zeros), for a cold first run's
    compilation (:func:`nurbsmotion._runtime.precompile.loop_example`)."""
    def f(*shape):
        return np.zeros(shape)

    n, d = n_axes, SUPPORT_DIRECTIONS
    plan = PlannedPlan(f(1), f(1), f(1, n), f(1, n), f(1, n), f(1, n, d),
                       np.zeros(2, np.int64), *(f(n) for _ in range(5)), 0.0, 0.0, 0,
                       f(1, 4), np.zeros(n + 1, np.int64))
    state = PlannedState(f(1), f(1), f(1), f(EST_ROWS, n), f(HIST_ROWS, n), f(n), f(n),
                         f(n), f(n, d), f(2, n), f(LANDING_ROWS, n), f(DOB_ROWS, n))
    return plan, state


# from sample 0: the plan's first drive u[0] moves the plant (inverse.LEAD)
stepping.register(PlannedPlan, planned_step, first_sample=0, name="planned",
                  make=PlannedInterpolator, example=_example, options=True)


def machine_knowledge(machine: Machine, a, b0, c, b1, tracking_pole: float) -> dict:
    """What the online step takes from the model machine beyond its rigid plant
    (:class:`PlannedPlan`'s fields): :func:`reading_knowledge` (the identification's
    dead zone and the landing's band), the model's ``delay`` [samples] and the landing's
    poles ``landing_pole``.

    - The delay (a fraction of a sample) is in the identification's regression (its
      drive weights, :func:`.identify._drive_weights`: without it, on a delayed drive it
      read a plant that is none, a' of 1.75 on the die bonder at half a sample), in the
      tracking (the state the drive will meet, predicted over the delay, step 1b of
      :func:`.step.online_step`) and in the landing's law
      (:func:`.identify._landing_law`).
    - The landing's poles are at ``tracking_pole`` (on a rigid axis read inexactly, slower
      where the reading's own change would move the drive beyond the headroom,
      :func:`.rest_observer.reading_pole`): deadbeat (poles at 0), as it once was,
      closes what a plant unlike the model has left of the move in three samples, but
      on the same plant with a load, friction or a mode the model does not know it
      limit-cycled or never settled (benchmarks/real_planned_item1.md).
    - On an axis whose model declares a mode, the landing's law is the one designed with
      the mode, its delay and the model's tau, Kc and mode each +-10 % off
      (``mode_law``, :func:`.mode_law.mode_landing_law`); the rigid placement on the
      identified plant left the mode unplaced and limit-cycled at rest.
    - ``disturbance_gain``: the opt-in disturbance observer's deadbeat gains on the
      model's plant (:func:`.disturbance.observer_gains`).
    - On a rigid axis whose model's reading is not exact (counts, noise), the landing's
      speed comes from an observer whose poles are the machine's own loop's slowest
      (``rest_observer``, :func:`.rest_observer.rest_observer`): from one increment, a
      count or the noise read as a speed of a count per sample kicked the law at rest;
      on an axis with a mode and such a reading too, where the law designed with the
      observer in its loop is stable on every corner (:func:`.mode_law.mode_rest_observer`:
      the designed law answered a count with up to 4.5 V on fast sampled axes)."""
    known = reading_knowledge(machine, a, b0, c, b1)
    band = known["landing_band"]
    return dict(known, delay=machine.delay / machine.sample_period,
                landing_pole=float(tracking_pole),
                mode_law=mode_landing_law(machine, tracking_pole, band),
                rest_observer=(rest_observer(machine, band)
                               + mode_rest_observer(machine, tracking_pole, band)),
                disturbance_gain=observer_gains(a, b0, c, b1))


def _path_steps(desired: np.ndarray) -> np.ndarray:
    """``|desired[k + 1] - desired[k]|`` [pulse] for every sample k (0 at the last), shape
    (n,), axis by axis (no temporary of the positions' size)."""
    steps = np.zeros(len(desired))
    for j in range(desired.shape[1]):
        d = np.diff(desired[:, j])
        steps[:-1] += np.square(d, out=d)
    return np.sqrt(steps, out=steps)


def _prior_estimate(plan: PlannedPlan, umax: float) -> np.ndarray:
    """The identification's start (:func:`_identify`): the model's a and drive weights
    (p1, p2, p3) with its delay (:func:`.identify._drive_weights`; without a delay (b1,
    beta, 0)) and no unknown drive (delta = 0), shape (EST_ROWS, n_axes) with the
    covariance. Prior standard deviations: 1 - a for a (a plant whose tau is half or
    twice the model's has 1 - a about twice or half the model's), the plan's
    ``gain_range`` times each drive weight (the drive's effect, proportional to Kc/tau;
    0 for p3 without a delay: it stays 0), and for delta an unknown drive of up to
    ``umax`` [V] through the model's ``p1 + p2 + p3``."""
    a, b0, c, b1 = plan.a, plan.b0, plan.c, plan.b1
    weights = np.array([_drive_weights(*v, plan.delay) for v in zip(a, b0, c, b1)]).T
    est = np.zeros((EST_ROWS, len(a)))
    est[0], est[1:4] = a, weights
    n = N_PARAMETERS
    for r, sigma in enumerate((1.0 - a, *(plan.gain_range * weights),
                               (weights[0] + weights[1] + weights[2]) * umax)):
        est[n + n * r + r] = sigma ** 2
    return est
