"""The planned motion: the actual position, sample by sample, and the drive that makes it.

The ``planned`` interpolator (issue 10) plans what the machine does, not the setpoint. The
plant of every axis is known exactly (docs/model.md#servo-axis): under a zero-order hold, with the
state ``x = [w, theta]``,

    w[k+1]     = a*w[k] + b0*u[k]
    theta[k+1] = theta[k] + c*w[k] + b1*u[k]

so a drive sequence u[k] determines the motion, and a motion determines its drive. The plan
is built offline in six steps:

1. **Path speed.** The time-optimal speed along the path (:func:`planning.speed_profile`:
   phase-plane passes under the feedforward drive limit ``|tau*xdd + xd| <= f*Umax*Kc*Ke``,
   ``V <= F``, at rest at both ends and at every sharp corner). Each corner-free piece's
   time profile s(t) is averaged with itself one sample later, ``(s(t) + s(t - Ts))/2``
   (:func:`_averaged_arc`): sampled, that is the filter ``(1 + 1/z)/2``, whose zero lies
   exactly at the Nyquist frequency, which step 3 cannot realise (the sampled plant's
   zero near -1); it costs one sample per piece. The result is sampled every Ts into the
   desired positions ``y[k] = C(s(k*Ts))``: the ``planned`` interpolator gives the
   loop's setpoint from sample 0 on (:func:`nurbsmotion.stepping.first_sample`), so the
   first drive u[0] moves the plant over the first sample; the desired motion leaves
   the start at sample 0 (:data:`LEAD`) and its first moving sample is y[1]. Where the
   model machine declares a mode, the averaged time law is also shaped at it (ZVD,
   :func:`.shaper.time_law_shaper`: on the path, the mode not excited), the rigid
   motion leads the tool by the mode's lag across the path (:func:`.shaper.tool_lead`),
   and steps 5-6 are skipped (their bang-bang drives ring the mode).
2. **Corner blends** (``corner_tolerance`` eps > 0). The plant is linear, so motions can
   be superposed: the next piece starts before the current one has stopped, by the time
   it takes the current piece to cover its last eps plus the time the next one takes to
   cover its first eps. At every instant one of the two is within eps of the corner, so
   the blended position is within eps of the sharp path (a G64-style blend); the overlap
   is then widened while the deviation of the superposed motion, measured against every
   piece that moves, stays within eps. On segments far shorter than eps (CAM output) a
   piece may so start while several earlier ones still move; each stops no sooner than
   those before it. The drive is the sum of the pieces' drives, checked in step 4 (which
   eases all of them where a blend exceeds the limit). Easing a sum of several drives
   can cost more than the stops save: the plan that stops at the corners is made as well
   and kept where it arrives no later.
3. **Drive sequence.** Exact inversion of theta -> u is unstable in practice: the sampled
   plant has a zero at ``-c1/b1`` close to -1, and inverting it rings at the Nyquist
   frequency. Zero-phase-error tracking (Tomizuka 1987) inverts the speed exactly and the
   sampling zero by its zero-phase mirror; its small gain error (about ``Ts^2/4`` times the
   acceleration) is removed by iterating on the commanded positions (a pre-compensation
   that converges at every frequency the motion contains). The drive, speed and position
   of every sample follow in closed form (no simulation), and the plant's response to that
   drive *is* the plan, so it is exactly realisable.
4. **Drive limit.** Where the drive sequence uses more than ``drive_fraction`` of Umax on
   some axis (the sampled motion needs a little more than the continuous one, the speed
   profile's grid may step over a curvature peak, and blends add drives), the drive limit
   of step 1 is divided by the excess over the distance the motion covers in a few
   samples around it (a profile's acceleration, and its squared speed where the curvature
   limits it, scale with the limit, and so does the drive they need), and the plan is
   rebuilt. An excess left after that comes from further away than the easing reaches,
   so round r divides by its r-th power (squared, cubed, ...: a stubborn excess is gone
   in a few rounds, at the cost of easing a little more than it needs); where easing
   does not lower the drive, the grid is refined; where it does not on the finest grid,
   the whole path is eased by the excess as well (a profile at the limit over a long
   stretch can move an excess of 1e-7 from window to window without end).
5. **Landing** (:func:`_land_on_end`). The last drives are changed by the least that
   puts the plant at rest exactly on the end, at the earliest sample (up to
   ``INVERSE_REACH + 1`` before the desired motion arrives there) at which the drive
   allows it without leaving the desired path, instead of approaching it over the
   samples after.
6. **Short moves** (:func:`_shorten`; a plan of at most :data:`SHORT_MOVE_SAMPLES`
   samples without a blend). Steps 1-5 fix the timing along the path (the continuous
   profile, averaged and sampled); a short, fast move pays for that in whole samples,
   and the averaging costs a sample at every stop. Here the timing is free: from stop to
   stop (:func:`_shorten_pieces`: the pieces one after the other, each at rest at its
   stops at sample instants; kept if together they arrive sooner, and only where every
   axis that moves has moved before the first stop, so that the online step knows its
   plant before a piece drives it at the limit), the earliest sample N at which the
   plant can rest on the piece's end, its drive within the limit, while staying within
   ``path_tolerance`` of the path (or, failing that, no farther than the plan it
   replaces) all along its motion
   (checked at up to :data:`CHECK_POINTS` points a sample), its nearest path point moving
   forward no faster than the feed, is found by sequential linear programming over the
   drives and the plant's sampled states (the ZOH dynamics as equality constraints; a
   point within a sample is its sample's state advanced in closed form). Each program
   minimises the largest offset of the held points (the samples, the half samples and
   those a round found off the path) from the path linearised at their nearest points
   (along the normals; with 3 axes and more, along directions around the path and, where
   a round found a point outside the tolerance, along its own offset), within a trust
   region (as far as the feed goes in a sample; failing that, as far as the
   linearisation stays within the tolerance; the second is not solved where the feed
   never widened the first: its programs would be the same). N starts a sample after the
   piece's continuous time-optimal duration (rounded up) and runs down while one is
   found, to that duration (below it only as a short try, which ends at a program whose
   largest offset exceeds the tolerance); where none is found at the start
   within a few rounds, N comes down from the plan's arrival in steps that double while
   one is found, then halves the gap to the latest that failed, and ends one sample at a
   time while one is found (:func:`_shorten`: a motion at rest at N can wait there, so
   the motions sought exist from the earliest N on; the start sample again only within
   as few rounds; an N at which an axis cannot reach the piece's end at rest under the
   drive limit is not tried; where the landing could not put the
   plan at rest and it rings about the end by more than ``path_tolerance``, from the
   first of the arrival and the samples after it, up to where the ringing dies down, at
   which one is). Each program but the first of a sample's trust region is
   warm-started from the last one's basis (HiGHS' dual simplex through ``highspy``),
   where a round holds more points as well. The nearest path points of the motion found move
   by at most ``F*Ts +`` :data:`FEED_SLACK` a sample. The search spends at most
   ``shorten_work`` pivot-rows of simplex work per sample of a piece (a deterministic
   budget, :data:`.shorten.DEFAULT_SHORTEN_WORK`); where that runs out, the piece keeps
   the earliest arrival found so far and the plan's ``shorten_status`` says so.

The plan is a :class:`MotionPlan`: arrays only, for the online step.

Glossary
--------
s : arc length [pulse]; y : desired axis positions [pulse]; w : motor speed [rad/s];
theta : axis position [pulse]; u : drive [V]; F : feed [pulse/s]; Ts : sample period [s];
eps : corner tolerance [pulse].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...errors import InfeasibleError, InvalidArgumentError
from ...limits import DEFAULT_PATH_TOLERANCE, SHORT_MOVE_SAMPLES
from ...machine import Machine
from ...nurbs import NurbsCurve
from ...planning import speed_profile
from .blend import _desired_motion
from .inverse import (END_REST, INVERSE_REACH, LEAD, PRECOMPENSATION_ROUNDS,
                      PRECOMPENSATION_TOLERANCE, _drive_sequence, axis_zoh)
from .landing import _arrival, _land_on_end
from .shaper import time_law_shaper, tool_lead
from .shorten import DEFAULT_SHORTEN_WORK, SHORTEN_START, _shorten_pieces, _unit, move_tolerance

__all__ = ["MotionPlan", "plan_motion", "axis_zoh", "move_tolerance"]


MAX_GRID_REFINEMENT = 16
"""The speed profile's grid is refined at most to this many times its given size."""

DRIVE_FIT_ROUNDS = 16
"""At most this many rebuilds of the plan in step 4."""


@dataclass(frozen=True, eq=False)
class MotionPlan:
    """The planned motion of every sample, and the drive that makes it (model's plant).

    Sample 0 is the start, at rest; the first drive that moves the plant is u[LEAD]
    (:data:`LEAD`).

    Attributes
    ----------
    position : ndarray, shape (n, n_axes)
        theta_ff[k], the planned actual position [pulse].
    speed : ndarray, shape (n, n_axes)
        w_ff[k], the planned motor speed [rad/s].
    drive : ndarray, shape (n, n_axes)
        u_ff[k] [V]; the model's plant driven by it from rest at the start follows
        ``position`` and ``speed`` exactly. 0 at the last sample (at rest on the end).
    parameter : ndarray, shape (n,)
        Curve parameter of the desired position of each sample (for the trace).
    desired : ndarray, shape (n, n_axes)
        y[k], the desired position (on the path, or within eps of it in a blend) [pulse].
    drive_fraction : float
        The fraction of Umax the drive sequence stays within.
    corner_times : ndarray, shape (n_corners,)
        Sample index (fractional) at which the motion is at each stop corner (or at the
        middle of its blend).
    sample_period : float
        Ts [s].
    arrival : int
        The first sample from which the plan and its desired motion rest on the end: where
        the landing (step 5) or a short move's compression (step 6) puts the plan exactly
        there; where neither could, the sample from which the desired motion does (0 if it
        never leaves the start).
    corner_tolerance : float
        eps [pulse] the plan was made with (0: it stops at every sharp corner).
    shorten_status : str
        Step 6's search: ``"not run"`` (not a short move, or its corners blended),
        ``"complete"``, or ``"work budget"`` (it stopped where its work budget ran out,
        ``shorten_work`` of :func:`plan_motion`: ``arrival`` is the earliest found before
        that, which a search without the budget may improve on).
    time_law : str
        ``"rigid"`` (the model declares no mode), ``"shaped"`` (the time law shaped at the
        model's modes, :func:`.shaper.time_law_shaper`) or ``"rigid, no shaped law"`` (a
        mode is declared, but no shaped profile stays within the drive limit, so the plan
        is the rigid one, which may ring the mode).
    """

    position: np.ndarray
    speed: np.ndarray
    drive: np.ndarray
    parameter: np.ndarray
    desired: np.ndarray
    drive_fraction: float
    corner_times: np.ndarray
    sample_period: float
    arrival: int
    corner_tolerance: float = 0.0
    shorten_status: str = "not run"
    time_law: str = "rigid"

    @property
    def stop_times(self) -> np.ndarray:
        """The fractional samples at which the motion rests at its stop corners (none when
        corners are blended: a blend's middle is not a stop), shape (n_stops,)."""
        return self.corner_times if self.corner_tolerance == 0 else self.corner_times[:0]

    @property
    def stop_indices(self) -> np.ndarray:
        """The first sample at or after each stop corner (none when corners are blended)."""
        return np.ceil(self.stop_times - 1e-9).astype(int)

    @property
    def n_samples(self) -> int:
        return len(self.position)

    @property
    def duration(self) -> float:
        """Time from the start to the last sample (at rest on the end) [s]."""
        return (self.n_samples - 1) * self.sample_period


def plan_motion(curve: NurbsCurve, machine: Machine, feed, *,
                corner_tolerance: float = 0.0, drive_fraction: float = 1.0,
                path_tolerance: float = DEFAULT_PATH_TOLERANCE, grid_size: int = 4000,
                max_samples: int = 10_000_000,
                shorten_work: float = DEFAULT_SHORTEN_WORK) -> MotionPlan:
    """Plan the actual motion along ``curve`` and the drive that makes it (module docstring).

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        The model: tau, Kc, Ke, Umax, Ts.
    feed : float or FeedLimit
        F [pulse/s], or a limit per piece of the path.
    corner_tolerance : float
        eps [pulse], >= 0: how far the motion may leave a sharp corner (0: stop there).
    drive_fraction : float
        Fraction of Umax the planned drive may use, in (0, 1].
    path_tolerance : float
        [pulse], >= 0: how far from the path a short move's motion may go where that
        lets it arrive sooner (step 6; where the plan it replaces is farther, that far).
    grid_size : int
        Arc-length grid of the speed profile.
    max_samples : int
        A plan longer than this is refused.
    shorten_work : float
        > 0 (``math.inf``: no budget): the simplex work step 6 may spend on a piece, per
        sample of the piece's plan, in pivot-rows (:data:`.shorten.DEFAULT_SHORTEN_WORK`);
        the plan's ``shorten_status`` says whether it ran out.

    Returns
    -------
    MotionPlan
        Its ``corner_tolerance`` is 0 where stopping at the sharp corners arrives no later
        than rounding them (blends superpose the pieces' drives, and easing their sum can
        cost more than the stops it saves).

    Raises
    ------
    InvalidArgumentError
        If a tolerance is not finite and >= 0, ``drive_fraction`` not in (0, 1], or
        ``shorten_work`` not > 0.
    InfeasibleError
        If the drive cannot move along the path or the plan is too long.
    """
    for name, value in (("corner_tolerance", corner_tolerance),
                        ("path_tolerance", path_tolerance)):
        if not (math.isfinite(value) and value >= 0):
            raise InvalidArgumentError(f"{name} must be finite and >= 0, got {value!r}")
    if not (0 < drive_fraction <= 1):
        raise InvalidArgumentError(f"drive_fraction must lie in (0, 1], got {drive_fraction!r}")
    if isinstance(shorten_work, bool) or not (isinstance(shorten_work, (int, float))
                                              and shorten_work > 0):
        raise InvalidArgumentError(f"shorten_work must be a number > 0 (math.inf: no "
                                   f"budget), got {shorten_work!r}")
    options = dict(drive_fraction=drive_fraction, path_tolerance=path_tolerance,
                   grid_size=grid_size, max_samples=max_samples, shorten_work=shorten_work)

    def shaped_or_rigid(tolerance):
        # a mode declared: the time law shaped at it; where no shaped profile is within
        # the drive limit (the easing of step 4 collapses on a sharp turn the shaper's
        # length spans), the rigid plan, as for a machine without a mode
        try:
            return _plan_motion(curve, machine, feed, tolerance, **options)
        except InfeasibleError:
            if time_law_shaper(machine) is None:
                raise
        return replace(_plan_motion(curve, machine, feed, tolerance, shape=False, **options),
                       time_law="rigid, no shaped law")

    def stopping_plan():
        return shaped_or_rigid(0.0)

    if corner_tolerance == 0:
        return stopping_plan()
    try:
        plan = shaped_or_rigid(corner_tolerance)
    except InfeasibleError as refused:
        try:
            return stopping_plan()
        except InfeasibleError:
            raise refused from None
    if plan.corner_times.size:
        try:
            stopping = stopping_plan()
        except InfeasibleError:
            return plan
        if stopping.arrival <= plan.arrival:
            return stopping
    return plan


def _plan_motion(curve: NurbsCurve, machine: Machine, feed, corner_tolerance: float, *,
                 drive_fraction: float, path_tolerance: float, grid_size: int,
                 max_samples: int, shorten_work: float, shape: bool = True) -> MotionPlan:
    """:func:`plan_motion` for one corner tolerance (its arguments checked); ``shape``:
    the time law shaped at the model's modes (:func:`.shaper.time_law_shaper`)."""
    Ts = machine.sample_period
    umax = machine.max_drive
    lead = LEAD
    # None without a mode: the rigid plan as it was
    shaper = time_law_shaper(machine) if shape else None
    shaped_reach = 0 if shaper is None else len(shaper) - 1
    eases: list = []  # per round: (low, high [pulse], factor) arrays, by falling factor
    spacing = 2.0 * curve.length / grid_size

    def drive_scale(s_query):
        # per round, the smallest factor of the intervals (low, high) that hold each
        # point: those that reach the points, written in order of falling factor (the
        # smallest last). Called once a piece: a program of 3,000 pieces spent 224 of
        # 335 s here when every interval was looked at for every piece.
        order = np.argsort(s_query, kind="stable")
        s_sorted = s_query[order]
        scale = np.ones_like(s_query)
        for low, high, factor in eases:
            reach = np.flatnonzero((low < s_sorted[-1]) & (high > s_sorted[0]))
            if reach.size == 0:
                continue
            lo = np.searchsorted(s_sorted, low[reach], side="right").tolist()
            hi = np.searchsorted(s_sorted, high[reach], side="left").tolist()
            least = np.ones_like(s_query)
            for i, k in enumerate(reach.tolist()):
                least[lo[i]:hi[i]] = factor[k]
            scale[order] *= least
        return scale

    grids: dict = {}  # the profile's grids, reused while only its drive limit changes
    last_use = math.inf
    widen = 1.0
    initial_grid = grid_size
    everywhere = False  # ease the whole path as well (step 4)
    for _ in range(DRIVE_FIT_ROUNDS):
        profile = speed_profile(curve, machine, feed, drive_fraction=drive_fraction,
                                drive_scale=drive_scale if eases else None,
                                grid_size=grid_size, grids=grids)
        if not eases:   # step 6 starts its search at each piece's uneased time
            estimate = [math.ceil(t[-1] / Ts - 1e-9) + SHORTEN_START
                        for t in profile.piece_times()]
        if profile.duration / Ts > max_samples:
            raise InfeasibleError(
                f"the planned motion takes {profile.duration:g} s, more than "
                f"{max_samples} samples; " + ("the feed is too low for this path"
                                              if not eases else
                                              f"easing the drive limit (the sampled drive "
                                              f"needed {last_use:.3g} x Umax) slowed it "
                                              "this far"))
        y, param, corners, earliest = _desired_motion(curve, profile, Ts, corner_tolerance,
                                                     lead, shaper)
        y = np.vstack([y, np.repeat(y[-1:], END_REST, axis=0)])
        param = np.concatenate([param, np.ones(END_REST)])
        earliest = np.concatenate([earliest, np.full(END_REST, np.nan)])
        # A round within the limit that is as near y as the best one, give or take what
        # the loop cannot see (PRECOMPENSATION_TOLERANCE), ends the easing.
        # a mode declared: the rigid motion leads the tool by what the mode lags it
        target = y if shaper is None else y + tool_lead(y, machine, shaper, corners)
        plant, peaks = _drive_sequence(target, machine, PRECOMPENSATION_ROUNDS,
                                       drive_fraction * umax * (1 + 1e-9),
                                       PRECOMPENSATION_TOLERANCE)
        if plant is not None:
            break
        per_sample = peaks / umax
        use = float(np.max(per_sample))
        # Ease the profile's drive limit where the sampled drive exceeds it, over the
        # distance the motion covers while the averaging and the inverse see it.
        k = np.nonzero(per_sample > drive_fraction)[0]
        speed = np.linalg.norm(y[np.minimum(k + 1, len(y) - 1)] - y[np.maximum(k - 1, 0)],
                               axis=1) / (2 * Ts)
        if use >= last_use * (1 - 1e-6):
            # Easing did not lower the drive: the grid steps over a curvature peak, or
            # the excess comes from further away. Refine the grid and widen the easing.
            if grid_size < MAX_GRID_REFINEMENT * initial_grid:
                grid_size *= 4
                spacing /= 4
            else:
                everywhere = True
            widen *= 2.0
        last_use = use
        # (a shaped time law mixes the profile over the shaper's length as well)
        half = np.maximum(speed * Ts * (1 + INVERSE_REACH + shaped_reach) * widen, spacing)
        # The first round's excess is the profile's own (its drive scales with its limit):
        # divided by it; what is left comes from further away (module docstring, step 4).
        factor = (drive_fraction / per_sample[k]) ** (1 + len(eases))
        # In a blend the drive is the sum of the pieces' (step 2): ease all of them over
        # the whole blend (from where the earliest is at its start to where the latest
        # is at its end), by its largest excess. Easing only the later piece where the
        # excess is leaves the earlier one braking at the limit (the later one then
        # slows without end), and easing only there moves the excess within the blend
        # as its timing changes.
        alone = np.isnan(earliest[k])
        centre = curve.arc_length(param[k[alone]])
        windows = [centre - half[alone]], [centre + half[alone]], [factor[alone]]
        if everywhere:
            windows[0].append(np.array([-spacing]))
            windows[1].append(np.array([curve.length + spacing]))
            windows[2].append(np.array([drive_fraction / use]))
        blended = ~np.isnan(earliest)
        run_start = np.flatnonzero(blended & ~np.r_[False, blended[:-1]])
        run_end = np.flatnonzero(blended & ~np.r_[blended[1:], False]) + 1
        for a, b in zip(run_start, run_end):
            inside = k[(k >= a) & (k < b)]
            if inside.size == 0:
                continue
            f = (drive_fraction / float(np.max(per_sample[inside]))) ** (1 + len(eases))
            s0, s1 = curve.arc_length(np.array([earliest[a], param[b - 1]]))
            windows[0].append(np.array([s0 - spacing]))
            windows[1].append(np.array([s1 + spacing]))
            windows[2].append(np.array([f]))
        low, high, factor = (np.concatenate(w) for w in windows)
        falling = np.argsort(-factor, kind="stable")
        eases.append((low[falling], high[falling], np.minimum(factor, 1.0)[falling]))
    else:
        # The excess that easing could not remove comes from the pre-compensation's last
        # rounds (motion near the Nyquist frequency): keep its last round within the limit.
        plant, peaks = _drive_sequence(target, machine, PRECOMPENSATION_ROUNDS,
                                       drive_fraction * umax * (1 + 1e-9))
        if plant is None:
            use = float(np.max(peaks)) / umax
            raise InfeasibleError(
                f"the planned drive needs {use:.3g} x Umax after {DRIVE_FIT_ROUNDS} rounds "
                "of easing the path speed's drive limit where it exceeds it")
    w, theta, u = plant
    shorten_status = "not run"
    if shaper is not None:
        # Steps 5 and 6 re-time the end and short moves at the rigid plant's limit: their
        # bang-bang drives would ring the mode the shaped time law leaves alone.
        landed = _arrival(y)
    else:
        tangent = _unit(curve(1.0, 1, "left"))
        landed = _land_on_end(y, w, theta, u, machine, drive_fraction * umax, tangent, curve,
                              param, feed)
        y[landed:] = y[-1]       # the desired motion rests where the plan does
        param[landed:] = 1.0
    if shaper is None and landed <= SHORT_MOVE_SAMPLES and (corners.size == 0
                                                             or corner_tolerance == 0):
        stops = np.array([piece[1][0] for piece in profile.pieces] + [1.0])
        short, exhausted = _shorten_pieces(curve, stops, corners, theta, param, landed,
                                           machine, drive_fraction * umax, path_tolerance,
                                           tangent, feed, estimate, shorten_work)
        shorten_status = "work budget" if exhausted else "complete"
        if short is not None:
            landed, y, param, w, theta, u, corners = short
    theta[-1] = y[-1]
    w[-1] = 0.0
    return MotionPlan(position=theta, speed=w, drive=u, parameter=param, desired=y,
                      drive_fraction=drive_fraction, corner_times=corners, sample_period=Ts,
                      arrival=landed, corner_tolerance=float(corner_tolerance),
                      shorten_status=shorten_status,
                      time_law="rigid" if shaper is None else "shaped")
