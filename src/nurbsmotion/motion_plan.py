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
   the start at sample 0 (:data:`LEAD`) and its first moving sample is y[1].
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
   linearisation stays within the tolerance). N runs down while one is found, from a
   sample after the piece's continuous time-optimal duration if one is found there,
   else from the plan's arrival (where the landing could not put the plan at rest and
   it rings about the end by more than ``path_tolerance``, from the first of the
   arrival and the samples after it, up to where the ringing dies down, at which one
   is); the programs of one N are warm-started from the last one's basis (HiGHS'
   dual simplex through ``highspy``). The nearest path points of the motion found move
   by at most ``F*Ts +`` :data:`FEED_SLACK` a sample.

The plan is a :class:`MotionPlan`: arrays only, for the online step.

Glossary
--------
s : arc length [pulse]; y : desired axis positions [pulse]; w : motor speed [rad/s];
theta : axis position [pulse]; u : drive [V]; F : feed [pulse/s]; Ts : sample period [s];
eps : corner tolerance [pulse].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from numba import njit

from .errors import InfeasibleError, InvalidArgumentError
from .feed import FeedLimit
from .geometry import distances_to
from .machine import Machine
from .nurbs import NurbsCurve
from .planning import SpeedProfile, speed_profile
from .servo import ServoPlant, zoh_coefficients

__all__ = ["MotionPlan", "plan_motion", "axis_zoh", "move_tolerance"]

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

OVERSAMPLE = 32
"""Fine time steps per sample of the averaged time profile (linear interpolation between
them moves a position by at most ``(Ts/32)^2/8`` times the acceleration: a hundredth of a
pulse at the die-bonder's full acceleration)."""

MAX_GRID_REFINEMENT = 16
"""The speed profile's grid is refined at most to this many times its given size."""

DRIVE_FIT_ROUNDS = 16
"""At most this many rebuilds of the plan in step 4."""

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

LANDING_SAMPLES = 64
"""Most drives the landing of step 5 changes (:func:`_land_on_end`; each window size tried
costs a least-squares solve of its size). On the 300 seeded random paths of
``benchmarks/planner_sweep.py`` it changed 2-22."""

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


@njit(cache=True)
def _averaged_arc(s, V, t, h, n_fine, lag, times, out):
    """The piece's averaged time profile [pulse] at the nondecreasing ``times`` [s] (from
    the piece's start), into ``out``.

    The profile s(t) has constant acceleration between grid points (b = V^2 linear in s);
    it is sampled every ``h`` (``n_fine`` points from 0, at rest before and after),
    averaged with itself ``lag`` points later, ``(s[m] + s[m - lag])/2`` (``lag`` points
    longer), and read by linear interpolation between the fine points; the last point is
    the piece's end. The fine points stream through a ring of the last ``lag`` values, so
    nothing of the fine grid's size is held."""
    last = t.shape[0] - 1
    s0 = s[0]
    s_end = s[last]
    n_total = n_fine + lag                   # length of the averaged fine sequence
    ring = np.full(lag, s0)                  # the profile's last lag values, at m mod lag
    seg = 0
    acc = _segment_acceleration(s, V, np.int64(seg))  # not a literal 0: one signature
    m = -1                                   # last fine index produced
    f_prev = s0
    f_cur = s0
    for q in range(times.shape[0]):
        x = times[q]
        # the fine interval j with j*h <= x < (j+1)*h (np.interp's search)
        if x < 0.0:
            j = -1
        elif x > (n_total - 1) * h:
            j = n_total
        else:
            j = min(int(x / h), n_total - 1)
            while j + 1 <= n_total - 1 and (j + 1) * h <= x:
                j += 1
            while j > 0 and j * h > x:
                j -= 1
        need = min(max(j + 1, 0), n_total - 1)
        while m < need:
            m += 1
            # the profile at m*h (constant acceleration between grid points)
            if m < n_fine:
                tm = m * h
                while seg + 1 < last and t[seg + 1] <= tm:
                    seg += 1
                    acc = _segment_acceleration(s, V, seg)
                dt = max(tm - t[seg], 0.0)
                v = s[seg] + V[seg] * dt + 0.5 * acc * dt * dt
                v = min(v, s[seg + 1])
                if tm >= t[last]:
                    v = s_end
                if tm <= 0:
                    v = s0
            else:
                v = s_end
            slot = m % lag
            averaged = 0.5 * (v + ring[slot])
            ring[slot] = v
            f_prev = f_cur
            f_cur = s_end if m == n_total - 1 else averaged
        if j < 0 or j >= n_total - 1:  # before the start (m = 0) or at/after the end
            out[q] = f_cur
        elif j * h == x:
            out[q] = f_prev
        else:
            slope = (f_cur - f_prev) / ((j + 1) * h - j * h)
            out[q] = slope * (x - j * h) + f_prev


@njit(cache=True)
def _segment_acceleration(s, V, i):
    """Path acceleration [pulse/s^2] between grid points i and i + 1 of a profile whose
    b = V^2 is linear in s (0 where the points coincide)."""
    ds = s[i + 1] - s[i]
    return (V[i + 1] * V[i + 1] - V[i] * V[i]) / (2 * ds) if ds > 0 else 0.0


def _piece_motions(curve: NurbsCurve, profile: SpeedProfile, Ts: float):
    """Per corner-free piece: its duration [s] and a function ``times -> (positions, u)``
    (``times`` [s] nondecreasing from the piece's start).

    The piece's s(t) is averaged with itself one sample later (module docstring, step 1;
    at rest before and after): the piece lasts Ts longer and its sampled motion has
    nothing at the Nyquist frequency. Sampled on a fine grid of :data:`OVERSAMPLE` points
    per sample that is streamed, never stored (:func:`_averaged_arc`), and mapped to the
    curve by the compiled arc-length inverse
    (:meth:`nurbsmotion.geometry.CurveGeometry.parameter_at`, uncached)."""
    out = []
    h = Ts / OVERSAMPLE
    geometry = curve.geometry
    for (s, u, V), t in zip(profile.pieces, profile.piece_times()):
        n_fine = int(math.ceil(t[-1] / h)) + 1
        duration = (n_fine + OVERSAMPLE - 1) * h

        def motion(times, s=s, u=u, V=V, t=t, n_fine=n_fine):
            times = np.ascontiguousarray(times, dtype=float)  # nondecreasing
            sk = np.empty_like(times)
            _averaged_arc(s, V, t, h, n_fine, OVERSAMPLE, times, sk)
            uk = np.interp(sk, s, u)
            inner = (sk > s[0]) & (sk < s[-1])
            if np.any(inner):
                uk[inner] = np.clip(geometry.parameter_at(sk[inner], cache=False),
                                    u[0], u[-1])
            return curve(uk), uk
        out.append((float(duration), motion))
    return out


BLEND_STEPS = 16
"""Points a sample at which blended pieces are evaluated to measure their deviation."""

BLEND_ROUNDS = 5
"""Rounds that widen a blend until its deviation from the sharp corner reaches eps."""

BLEND_THINNING = 1.0 / 64
"""The path samples a blend's deviation is measured against are at least this fraction of
eps apart along the path (the others are dropped): the measured deviation is at most that
much above the distance to the nearest of all samples, and the nearest-sample search no
longer wades through the thousands of samples a slow approach to the corner leaves
within eps of every blended point (80 % of the planning of a 2.3 m program of 52 blended
corners)."""


class _Track(NamedTuple):
    """A motion every ``h = Ts/BLEND_STEPS`` from its start, and at its end."""
    times: np.ndarray      # (m + 1,) [s]: k*h, the last one the end
    points: np.ndarray     # (m + 1, n_axes) [pulse]
    arc: np.ndarray        # (m + 1,) distance travelled along the points [pulse]


def _grid_steps(duration: float, h: float) -> int:
    """The steps of ``h`` [s] that reach ``duration`` [s]."""
    return int(math.ceil(duration / h - 1e-9))


def _grid_times(duration: float, h: float) -> np.ndarray:
    """A track's times [s]: every ``h`` [s] from 0, and ``duration`` [s] last."""
    return np.minimum(np.arange(_grid_steps(duration, h) + 1) * h, duration)


def _track(points: np.ndarray, times: np.ndarray) -> _Track:
    """The track of ``points`` (shape (m + 1, n_axes)) [pulse] at :func:`_grid_times`."""
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return _Track(times, points, np.concatenate([[0.0], np.cumsum(steps)]))


def _time_to_cover(track: _Track, distance: float, from_end: bool) -> float:
    """The time [s] a motion takes to cover its first (or last) ``distance`` [pulse]."""
    if from_end:
        i = int(np.searchsorted(track.arc, track.arc[-1] - distance, side="left"))
        return float(track.times[-1] - track.times[min(i, len(track.arc) - 1)])
    return float(track.times[int(np.searchsorted(track.arc, distance, side="right")) - 1])


def _thinned(points: np.ndarray, arc: np.ndarray, step: float) -> np.ndarray:
    """``points[0]`` and the first of ``points`` (shape (m, n_axes)) at or past each
    multiple of ``step`` [pulse] of ``arc`` (shape (m,), nondecreasing from 0) [pulse]."""
    bins = np.floor(arc / step)
    return points[np.r_[True, bins[1:] > bins[:-1]]]


def _farthest_from(points: np.ndarray, path: np.ndarray, corner: np.ndarray) -> float:
    """``max_i min_k |points[i] - path[k]|`` [pulse]: how far the points get from the
    nearest path sample (at least the distance to the path itself).

    ``corner`` is one of the path samples, so each point's nearest sample lies within
    twice the points' largest distance to it: only those samples go into a k-d tree
    (scipy's), which finds each point's nearest in O(log n). Comparing every point with
    every sample took 36 s per corner of a 0.2 m polyline at Ts = 0.1 ms (6,000 blended
    points, 12,000 samples near the corner, five rounds)."""
    from scipy.spatial import cKDTree

    radius = float(np.max(distances_to(points, corner)))
    near = path[distances_to(path, corner) <= 2.0 * radius * (1 + 1e-9) + 1e-300]
    gap, _ = cKDTree(near).query(points)
    return float(np.max(gap))


def _blend_start(moving: _Track, alone: int, nxt: _Track, path: np.ndarray,
                 tolerance: float) -> int:
    """The earliest step of ``moving`` (the superposed motion of the pieces so far, from
    the latest one's start) at which the next piece (``nxt``, from its start) may start so
    that the superposed motion stays within ``tolerance`` [pulse] of ``path`` (samples of
    every piece that moves then; module docstring, step 2). From step ``alone`` on only
    the latest piece moves.

    The guaranteed start: the latest piece alone, covering its last ``d`` while the next
    one covers its first ``d``, with d = eps (one of the two is then within eps of the
    corner). The start is then brought forward while the measured deviation stays within
    eps, d widened by the square root of eps over it (the deviation grows with d); it may
    start while earlier pieces still move, as on a program of segments far shorter than
    eps."""
    last = len(moving.times) - 1
    if last == 0:
        return 0
    corner = nxt.points[0]
    h = moving.times[1]
    # the next piece stops no sooner than everything before it: the latest piece is
    # always the last to stop, so from ``alone`` on the motion is on its path
    first = max(_grid_steps(moving.times[-1] - nxt.times[-1], h), 0)

    def start_for(d):
        want = _time_to_cover(moving, d, True) + _time_to_cover(nxt, d, False)
        return min(max(_grid_steps(moving.times[-1] - want, h), first), last)

    best = guaranteed = max(start_for(tolerance), alone)
    d = tolerance
    for round_ in range(BLEND_ROUNDS):
        j = start_for(d)
        if j >= last or (round_ and j >= best):
            break
        n = min(last - j, len(nxt.times) - 1) + 1
        blended = moving.points[j:j + n] + nxt.points[:n] - corner
        deviation = _farthest_from(blended, path, corner)
        if deviation <= tolerance:
            best = min(best, j)
        elif best < guaranteed:
            break       # beyond the widest blend within eps found
        if deviation <= 0:
            break
        d *= math.sqrt(tolerance / deviation)
    return best


def _blend_starts(pieces, Ts: float, tolerance: float) -> list:
    """The start [s] of every piece (``_piece_motions``), blended within ``tolerance``
    [pulse] of the sharp path (:func:`_blend_start`; back to back where it is 0)."""
    if tolerance <= 0 or len(pieces) < 2:
        return list(np.concatenate([[0.0], np.cumsum([p[0] for p in pieces[:-1]])]))
    h = Ts / BLEND_STEPS
    step = BLEND_THINNING * tolerance

    def track_of(dur, motion):
        # a piece's track and samples of its path
        times = _grid_times(dur, h)
        track = _track(motion(times)[0], times)
        return track, _thinned(track.points, track.arc, step)

    # the superposed motion from the latest piece's start on, the step from which only
    # that piece moves, and samples of the path of every piece that moves with when each
    # stops [s]
    moving, own = track_of(*pieces[0])
    alone, paths = 0, [(pieces[0][0], own)]
    starts = [0.0]
    for dur, motion in pieces[1:]:
        stops = starts[-1] + moving.times[-1]   # when everything before it stops [s]
        nxt, own = track_of(dur, motion)
        j = _blend_start(moving, alone, nxt, np.vstack([p for _, p in paths] + [own]),
                         tolerance)
        if j >= len(moving.times) - 1:          # back to back: it moves alone
            starts.append(stops)
            moving, alone, paths = nxt, 0, [(stops + dur, own)]
            continue
        t0 = starts[-1] + j * h
        starts.append(t0)
        times = _grid_times(max(stops, t0 + dur) - t0, h)
        k = np.arange(len(times))
        moving = _track(moving.points[np.minimum(j + k, len(moving.times) - 1)]
                        + nxt.points[np.minimum(k, len(nxt.times) - 1)] - nxt.points[0],
                        times)
        alone = _grid_steps(stops - t0, h)
        paths = [(e, p) for e, p in paths if e > t0] + [(t0 + dur, own)]
    return starts


def _desired_motion(curve: NurbsCurve, profile: SpeedProfile, Ts: float, tolerance: float,
                    lead: int):
    """y[k] (sum of the pieces, blended at corners), the parameter of each sample, the
    time of every corner [samples] and, for the samples where more than one piece moves
    (a blend), the parameter of the earliest of them (NaN elsewhere). Piece 0 starts at
    sample ``lead``."""
    pieces = _piece_motions(curve, profile, Ts)
    starts = _blend_starts(pieces, Ts, tolerance)
    # a corner's time: midway between the next piece's start and its own piece's end
    corner_times = [lead + (t0 + s + dur) / (2 * Ts)
                    for t0, s, (dur, _) in zip(starts[1:], starts, pieces)]
    total = max(t0 + p[0] for t0, p in zip(starts, pieces))
    n = lead + int(math.ceil(total / Ts - 1e-9)) + 1
    times = (np.arange(n) - lead) * Ts
    start = curve(0.0)
    y = np.broadcast_to(start, (n, curve.n_axes)).copy()
    param = np.zeros(n)
    earliest = np.full(n, np.nan)
    moving = np.zeros(n, dtype=int)   # pieces that move at each sample
    for (dur, motion), t0 in zip(pieces, starts):
        local = times - t0
        first = int(np.searchsorted(local, 0.0, side="right"))  # local > 0 from here on
        if first >= n:
            continue
        stop = max(first, int(np.searchsorted(local, dur, side="left")))  # local < dur
        # evaluated where it moves only (a program of 3,000 pieces evaluated each one at
        # every later sample: 83 of 100 s)
        pts, uk = motion(np.concatenate([[0.0], local[first:stop], [dur]]))
        y[first:stop] += pts[1:-1] - pts[0]
        y[stop:] += pts[-1] - pts[0]
        # The parameter of a sample is that of the latest piece that has started; the
        # earliest piece that still moves there is kept as well.
        inside = slice(first, stop)
        earliest[inside] = np.where(np.isnan(earliest[inside]), uk[1:-1], earliest[inside])
        moving[inside] += 1
        param[first:stop] = uk[1:-1]
        param[stop:] = uk[-1]
    earliest[moving < 2] = np.nan
    return y, param, np.array(corner_times), earliest


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


@njit(cache=True, fastmath={"nnan", "ninf", "nsz"})  # max in any order: exact
def _precompensate(y, alpha, beta, a, b0, rounds, limit, slack, y_cmd, w0, theta0, u0, w1,
                   theta1, u1, peaks):
    """:func:`_drive_sequence`'s rounds, compiled: ``y_cmd`` (in: ``y``, C-contiguous,
    shape (n, n_axes)) is corrected by the realised position's error each round.
    ``(w0, theta0, u0)`` and ``(w1, theta1, u1)`` (each shape (n, n_axes)) receive two
    rounds. Returned are a set (0 or 1) and whether it is accepted: the set holding the
    round with the smallest error whose drive stays within ``limit``, accepted if that
    error is within ``slack`` [pulse] of the smallest error of any round (-1 and not
    accepted if no round is within the limit). The two sets take turns, so no round is
    copied, and they are separate arrays, so the caller keeps the one it returns without
    the other. ``peaks`` (n,) receives the largest |drive| of every sample [V] in the
    round with the smallest error when that round's drive exceeds ``limit`` (where the
    drive limit must be eased; the round is not accepted then)."""
    n, n_axes = y.shape
    yf, cf = y.reshape(-1), y_cmd.reshape(-1)
    best_error = math.inf
    least_error = math.inf
    best = -1
    cur = 0
    for _ in range(rounds + 1):
        if cur == 0:
            w, theta, u = w0, theta0, u0
        else:
            w, theta, u = w1, theta1, u1
        _realise_into(y_cmd, alpha, beta, a, b0, w, theta, u)
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


def _arrival(y: np.ndarray) -> int:
    """The first sample from which the positions ``y`` (n, n_axes) rest on their last."""
    moving = np.flatnonzero(np.any(y != y[-1], axis=1))
    return int(moving[-1]) + 1 if moving.size else 0


def _past_end(positions: np.ndarray, off: np.ndarray, end: np.ndarray,
              tangent: np.ndarray) -> float:
    """How far [pulse] the ``positions`` (m, n_axes) whose nearest point of a path is its
    ``end`` (their distance ``off`` to the path, shape (m,), is their distance to the end)
    pass it along the path's unit ``tangent`` there (0 if none does)."""
    past = np.linalg.norm(positions - end, axis=1) <= off * (1 + 1e-9) + 1e-12
    return float(np.max((positions[past] - end) @ tangent, initial=0.0))


def _impulse_responses(machine: Machine, size: int) -> np.ndarray:
    """``h[j, p] = A^p B`` of every axis' ZOH plant (docs/model.md#servo-axis), p < ``size``: the
    change of [speed, position] p + 1 samples after a unit drive. Shape (n_axes, size, 2)."""
    a, b0, c, b1 = axis_zoh(machine)
    h = np.empty((len(a), size, 2))
    h[:, 0, 0], h[:, 0, 1] = b0, b1
    for p in range(1, size):
        h[:, p, 0] = a * h[:, p - 1, 0]
        h[:, p, 1] = c * h[:, p - 1, 0] + h[:, p - 1, 1]
    return h


def _rest_on_end(h: np.ndarray, theta: np.ndarray, w: np.ndarray, target: np.ndarray,
                 end: np.ndarray, k0: int, N: int):
    """The least change of the drives k0 .. N - 1 (m = N - k0 <= ``h.shape[1]`` of them)
    that puts the plant at rest on ``end`` at sample N: per axis, equality-constrained
    least squares of the positions ``theta[k0 + 1:N]`` (the plant's, shape (>N, n_axes),
    with its speeds ``w``) against ``target``. The plant is linear, so a change du of the
    drives moves sample k by ``sum_i h[k - 1 - i] du[i]``. Returns ``du`` (m, n_axes) and
    the change it makes to [w, theta] at samples k0 + 1 .. N, shape (m, 2, n_axes)."""
    m = N - k0
    n_axes = h.shape[0]
    lag = np.subtract.outer(np.arange(m), np.arange(m))  # row q: sample k0 + q + 1
    du = np.empty((m, n_axes))
    moved = np.empty((m, 2, n_axes))
    for j in range(n_axes):
        Hw, H = (np.where(lag >= 0, h[j, np.clip(lag, 0, m - 1), i], 0.0) for i in (0, 1))
        E = np.vstack([Hw[m - 1], H[m - 1]])
        kkt = np.zeros((m + 2, m + 2))
        kkt[:m, :m] = H[:-1].T @ H[:-1]
        kkt[:m, m:] = E.T
        kkt[m:, :m] = E
        rhs = np.concatenate([-H[:-1].T @ (theta[k0 + 1:N, j] - target[k0 + 1:N, j]),
                              [-w[N, j], end[j] - theta[N, j]]])
        du[:, j] = np.linalg.lstsq(kkt, rhs, rcond=None)[0][:m]
        moved[:, 0, j], moved[:, 1, j] = Hw @ du[:, j], H @ du[:, j]
    return du, moved


def _land_on_end(y: np.ndarray, w: np.ndarray, theta: np.ndarray, u: np.ndarray,
                 machine: Machine, limit: float, tangent: np.ndarray, curve: NurbsCurve,
                 param: np.ndarray, feed) -> int:
    """Step 5: bring the plan to rest exactly on the end, at the earliest sample N the
    drive allows, no later than the sample where the desired motion arrives there (in
    place). Returns N (the arrival if the plan is left as it is).

    What the pre-compensation leaves (a pulse or two on a short, fast move, whose motion
    is mostly near the Nyquist frequency) ends as a slow approach to the end after the
    desired motion has arrived, which the move's settle time pays for; and the desired
    motion's last samples creep (the averaging of step 1 halves the last braking, and the
    arrival is rounded up to a sample). The plant is linear, so a change du of the last
    m drives moves sample k by ``sum_i h[k - 1 - i] du[i]`` with ``h[p] = A^p B`` (the ZOH
    plant, docs/model.md#servo-axis). Per axis, the change that puts the state at N at rest on the
    end and otherwise departs least from ``y`` (equality-constrained least squares over
    the window's positions) is applied, and the drive is 0 after N. It is kept if the
    changed drive is within ``limit`` [V] and the window's positions stay as near the
    ``curve`` as the plan was to ``y`` there (at least within
    :data:`PRECOMPENSATION_TOLERANCE`; the distance to the path point that Newton steps
    from the desired positions' curve parameters ``param`` (n,) find, never less than the
    true one: the polyline through ``y`` cuts a tight curl the samples step across) and
    none passes the end along the path's unit ``tangent`` there by more than that
    tolerance (:func:`_past_end`), and their nearest path points move forward by at most
    the ``feed`` (F [pulse/s] or a :class:`~nurbsmotion.feed.FeedLimit`) times Ts plus
    :data:`FEED_SLACK` a sample, from the last sample it leaves as it is to N (on a
    10 mm line at 10 mm/s the landing took the last 47 pulses in 2 samples, the tool at
    26 mm/s: the desired motion was already at the feed there). N runs from
    the arrival less the samples
    the averaging and the inverse shape (``INVERSE_REACH + 1``), changing at most that
    many drives, up to the arrival itself, where m grows up to :data:`LANDING_SAMPLES`
    (and N - LEAD: the drives before :data:`LEAD` stay 0); if none does, the plan is left
    as it is."""
    end = y[-1]
    arrive = _arrival(y)
    if arrive < LEAD + 2 or arrive >= len(y):
        return arrive
    if float(np.max(np.abs(theta[arrive - 1:] - y[arrive - 1:]))) == 0.0:
        return arrive
    reach = INVERSE_REACH + 1
    Ts = machine.sample_period
    h = _impulse_responses(machine, min(arrive - LEAD, LANDING_SAMPLES))
    for N in range(max(arrive - reach, LEAD + 2), arrive + 1):
        most = min(N - LEAD, h.shape[1] if N == arrive else reach)
        first = max(N - most - 1, 0)
        tolerance = max(PRECOMPENSATION_TOLERANCE,
                        float(np.max(np.abs(theta[first:] - y[first:]))))
        for m in range(2, most + 1):
            k0 = N - m
            du, moved = _rest_on_end(h, theta, w, y, end, k0, N)
            drive = u[k0:N] + du
            if np.max(np.abs(drive)) > limit:
                continue
            theta_new = theta[k0 + 1:N + 1] + moved[:, 1]
            near = _nearest_forward(curve, np.vstack([theta[k0:k0 + 1], theta_new]),
                                    curve.arc_length(param[k0:N + 1]))
            at = curve.parameter_at(near)
            off = np.linalg.norm(theta_new - curve(at[1:]), axis=1)
            if np.max(off) > tolerance \
                    or _past_end(theta_new, off, end, tangent) > PRECOMPENSATION_TOLERANCE \
                    or np.any(np.diff(near) > _feed_at(feed, at[1:]) * Ts + FEED_SLACK):
                continue
            u[k0:N] = drive
            w[k0 + 1:N + 1] += moved[:, 0]
            theta[k0 + 1:N + 1] = theta_new
            u[N:] = 0.0
            w[N:] = 0.0
            theta[N:] = end
            return N
    return arrive


FEED_SLACK = 2 * PRECOMPENSATION_TOLERANCE
"""How far [pulse] a plan's nearest path point may move beyond ``F*Ts`` in a sample: the
desired motion moves at most F*Ts a sample (its profile is within the feed and the
averaging of step 1 keeps it so), and the plan of step 3 is within
:data:`PRECOMPENSATION_TOLERANCE` of it at both ends of the sample. The landing (step 5)
is held to the same; the feed of the tool's sampled motion is thus F + FEED_SLACK/Ts."""


def _feed_at(feed, p: np.ndarray) -> np.ndarray:
    """The feed F [pulse/s] at the curve parameters ``p`` (m,), shape (m,)."""
    return np.asarray(feed(p) if isinstance(feed, FeedLimit) else np.full(len(p), feed),
                      dtype=float)


CHECK_POINTS = 32
"""Most points per sample at which step 6 checks a move's distance to the path (as many
as put the path's chord between two of them within the tolerance at the feed; the
linear programs hold the samples, the half samples and the points found off the path)."""

SHORTEN_ROUNDS = 24
"""Most linear programs step 6 solves for one arrival sample (each re-linearises the path
at the motion's nearest points)."""

SHORTEN_STALL = 8
"""Step 6 gives up an arrival sample when this many rounds in a row bring the motion's
farthest point from the path no nearer than the nearest it has been."""

SHORT_MOVE_SAMPLES = 128
"""Step 6 plans the moves that rest on the end within this many samples. Its linear
programs grow with the piece (0.05-0.5 s each at 50-120 samples cold, a tenth of that
warm-started, and a move takes some tens of them): on the first 99 random paths of
``benchmarks/planner_sweep.py`` (PLANNER_SWEEP_PLAN_ONLY=1) planning takes a median
0.15 s of CPU, 1.5 s at the 95th percentile and 29 s at most (before the warm starts and
the search from the estimate: 0.17, 2.6 and 19 s); the slow ones are 3-axis moves of
60-120 samples whose programs grow by the points found off the path round after round
and, at the earliest arrival, never come within the tolerance."""

SHORTEN_START = 1
"""Step 6 starts its search for a piece's arrival this many samples after the piece's
continuous time-optimal duration (rounded up; :func:`planning.speed_profile` before any
easing), not at the plan's arrival, and runs down from there: a short move's earliest
arrival lies within a sample or two of that duration, and each sample it need not step
down from costs one or more linear programs (on six 60-120 mm free-form moves at 1.7 m/s
the plan arrived 1-10 samples later, and the search from there took 10-71 programs)."""

DEFAULT_PATH_TOLERANCE = 1.0
"""How far [pulse] from the path step 6 may take a short move's motion by default: one
pulse, the encoder's resolution (the plan it replaces is held within a quarter of it,
:data:`PRECOMPENSATION_TOLERANCE`, where the drive allows)."""


def move_tolerance(path_tolerance: float) -> float:
    """The least displacement [pulse] that counts as a move of an axis in a plan: the
    pre-compensation's tolerance or ``path_tolerance``, whichever is larger (the plan's
    position, inverted through the sampled plant's zero near -1, wavers by a fraction of
    a pulse, and a short move's plan may leave the path, and pass its end, by the path
    tolerance)."""
    return max(PRECOMPENSATION_TOLERANCE, path_tolerance)


def _normal_directions(tangent: np.ndarray) -> np.ndarray:
    """Unit directions normal to each unit ``tangent`` (m, n_axes), shape (m, r, n_axes):
    an orthonormal basis of the normal space (the other columns of the Householder
    reflection that takes the first axis to the tangent) and, where it is a plane, its
    two diagonals (a regular octagon: a point whose offsets along all of them are within
    E lies within E/cos(pi/8) = 1.08 E of the path)."""
    m, n_axes = tangent.shape
    v = tangent.copy()
    v[:, 0] += np.where(tangent[:, 0] >= 0, 1.0, -1.0)
    scale = 1.0 / (1.0 + np.abs(tangent[:, 0]))
    H = np.eye(n_axes)[None] - scale[:, None, None] * v[:, :, None] * v[:, None, :]
    basis = np.swapaxes(H[:, :, 1:], 1, 2)
    if n_axes != 3:
        return basis
    diagonals = np.stack([basis[:, 0] + basis[:, 1], basis[:, 0] - basis[:, 1]], axis=1)
    return np.concatenate([basis, diagonals / math.sqrt(2.0)], axis=1)


class _Span(NamedTuple):
    """A stretch of the path from one stop to the next (step 6): curve parameters
    [u0, u1] and arc lengths [s0, s1] [pulse]."""

    u0: float
    u1: float
    s0: float
    s1: float

    @classmethod
    def of(cls, curve: NurbsCurve, u0: float = 0.0, u1: float = 1.0) -> "_Span":
        s0, s1 = (float(curve.arc_length(u)) if 0.0 < u < 1.0 else u * curve.length
                  for u in (u0, u1))
        return cls(float(u0), float(u1), s0, s1)

    def tangents(self, curve: NurbsCurve, p: np.ndarray) -> np.ndarray:
        """Unit tangents at the parameters ``p`` (m,) of the span, from the span's side at
        its end (a sharp corner), shape (m, n_axes)."""
        T = curve.tangent(p)
        at_end = p >= self.u1
        if self.u1 < 1.0 and np.any(at_end):
            T[at_end] = curve.tangent(p[at_end], "left")
        return T


def _nearest_forward(curve: NurbsCurve, points: np.ndarray, s: np.ndarray,
                     span: _Span | None = None) -> np.ndarray:
    """Arc lengths [pulse] of the path points nearest ``points`` (m, n_axes) near the
    guesses ``s`` (m,) (Newton on the arc length), within the ``span`` (default: the
    whole path), made nondecreasing."""
    span = span or _Span.of(curve)
    for _ in range(3):
        p = curve.parameter_at(s)
        s = np.clip(s + np.sum(span.tangents(curve, p) * (points - curve(p)), axis=1),
                    span.s0, span.s1)
    return np.maximum.accumulate(s)


def _partial_zoh(machine: Machine, points: int):
    """ZOH coefficients ``(a, b0, c, b1)`` over j/``points`` of a sample, j = 0 ..
    ``points``: each shape (points + 1, n_axes) (j = 0: no time, the identity)."""
    parts = [zoh_coefficients(machine.tau, machine.Kc, machine.Ke,
                              machine.sample_period * j / points)
             for j in range(1, points + 1)]
    ident = (np.ones(len(machine.tau)), *(np.zeros(len(machine.tau)),) * 3)
    return tuple(np.vstack([i, *(part[q] for part in parts)]) for q, i in enumerate(ident))


def _fine_positions(plant: ServoPlant, zoh, u: np.ndarray):
    """Speed [rad/s] and position [pulse] of the model's ``plant`` (at rest at its start)
    at every sample, each shape (N + 1, n_axes) (:meth:`ServoPlant.response`), and its
    position at every fine point (Q per sample, ``zoh`` from :func:`_partial_zoh`: each
    sample's state advanced by part of a sample), shape (N*Q + 1, n_axes), under ``u``
    (N, n_axes; u[k] held over sample k, within Umax)."""
    w, theta = plant.response(u)
    c, b1 = zoh[2], zoh[3]
    fine = (theta[:-1, None] + c[None, :-1] * w[:-1, None]
            + b1[None, :-1] * u[:, None]).reshape(-1, u.shape[1])
    return w, theta, np.vstack([fine, theta[-1:]])


def _highs():
    """The HiGHS module and its solver class: ``highspy`` (a dependency), or the same
    bindings that scipy carries for its ``linprog`` where highspy is not installed."""
    try:
        import highspy
        return highspy, highspy.Highs
    except ImportError:   # pragma: no cover - highspy is a dependency
        from scipy.optimize._highspy import _core
        return _core, _core._Highs


def _silent(Highs):
    """A HiGHS solver with its output off. HiGHS 1.16 prints its banner on the C level's
    standard output when the process makes its first solver, before any option can be set
    (it would land in the middle of a command's printed results); so the file descriptor
    is pointed at the null device for that construction alone."""
    import os
    import sys

    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no standard output to protect
        highs = Highs()
    else:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 1)
            highs = Highs()
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            os.close(null)
    highs.setOptionValue("output_flag", False)
    return highs


class _WarmProgram:
    """The linear programs of one arrival sample of step 6, solved by HiGHS' dual simplex
    (Huangfu & Hall 2018, through ``highspy``), each from the last one's optimal basis
    where it has the same rows and columns: a round re-linearises the path at new points,
    which changes the numbers but not the shape, and the last basis is then a few tens of
    pivots from the new optimum instead of about a thousand (10-30 x fewer iterations on
    the rounds of a 78 mm move at 1.7 m/s, 85 samples)."""

    def __init__(self):
        self.highs = None
        self.basis = None
        self.shape = None

    def solve(self, cost, A_ub, b_ub, A_eq, bounds):
        """Minimise ``cost @ x`` subject to ``A_ub @ x <= b_ub``, ``A_eq @ x = 0`` and the
        ``bounds`` (n, 2) of x; the optimal x, or None where there is none."""
        from scipy import sparse

        highspy, Highs = _highs()

        A = sparse.vstack([A_ub, A_eq]).tocsc()
        lp = highspy.HighsLp()
        lp.num_col_, lp.num_row_ = A.shape[1], A.shape[0]
        lp.col_cost_ = np.asarray(cost, dtype=float)
        lp.col_lower_ = np.ascontiguousarray(bounds[:, 0])
        lp.col_upper_ = np.ascontiguousarray(bounds[:, 1])
        lp.row_lower_ = np.concatenate([np.full(A_ub.shape[0], -highspy.kHighsInf),
                                        np.zeros(A_eq.shape[0])])
        lp.row_upper_ = np.concatenate([b_ub, np.zeros(A_eq.shape[0])])
        lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
        lp.a_matrix_.start_ = A.indptr
        lp.a_matrix_.index_ = A.indices
        lp.a_matrix_.value_ = A.data
        lp.a_matrix_.num_col_, lp.a_matrix_.num_row_ = A.shape[1], A.shape[0]
        if self.highs is None:
            self.highs = _silent(Highs)
        h = self.highs
        h.passModel(lp)
        warm = self.basis is not None and self.shape == A.shape
        h.setOptionValue("presolve", "off" if warm else "choose")
        if warm:
            h.setBasis(self.basis)
        h.run()
        if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            self.basis = None
            return None
        self.basis, self.shape = h.getBasis(), A.shape
        return np.array(h.getSolution().col_value)


def _shorten_at(curve: NurbsCurve, span: _Span, plant: ServoPlant, zoh, N: int,
                s: np.ndarray, limit: float, tolerance: float, tangent: np.ndarray, feed,
                Ts: float, wide: bool, most_rounds: int = SHORTEN_ROUNDS):
    """One arrival sample N of step 6 (:func:`_shorten`) along the ``span`` of the curve
    from stop to stop (the plant at rest on its start at sample 0): drives u[LEAD] .. u[N-1]
    (|u| <= ``limit`` [V]) that keep the model's ``plant`` (at rest at the start) within
    ``tolerance`` [pulse] of the curve at every fine point inside the move (``zoh`` from
    :func:`_partial_zoh`: Q points per sample, fine points LEAD*Q + 1 .. N*Q - 1), their
    nearest points moving forward no faster than ``feed`` and none past the end along
    its unit ``tangent``, and put it at rest on the end at N; ``s`` (N*Q - LEAD*Q - 1,)
    is the first guess of the nearest points' arc lengths. Returns ``(u, s)`` (u shape
    (N, n_axes), 0 before :data:`LEAD`, and s at the fine points), or None if the
    linearised programs find none.

    The programs hold the samples, the half samples and every point that a round found
    off the path (the worst of each sample interval); every fine point is checked.
    Variables: the drives, the plant's state at every sample (the ZOH dynamics are
    equality constraints; a held point's position is its sample's state advanced by its
    part of the sample, three terms), each held point's |tangential step| and the
    largest normal offset E, which is minimised (module docstring, step 6). E bounds the
    offsets along the normal directions (:func:`_normal_directions`; from 3 axes on a
    polygon around the path, which bounds the distance by ``spread*E`` only) and, for a
    point a round found farther than the tolerance, along its own offset (a cut). The trust
    region of the tangential steps is as wide as the linearisation stays within the
    tolerance, or (``wide``) as the feed goes in a sample if that is wider. N is given up
    when E cannot reach the tolerance at its pace in the rounds left, or when
    :data:`SHORTEN_STALL` rounds in a row bring the farthest fine point no nearer (on a
    random 3-axis machine, 24 rounds of E at 0.998 against held points at 1.07: 42 s
    where this rule takes 14 s; on the sweep's 461 step-6 runs it changes no arrival)."""
    from scipy import sparse

    n_axes = curve.n_axes
    Q = zoh[0].shape[0] - 1
    s0, s1 = span.s0, span.s1
    start, end = curve(span.u0), curve(span.u1)
    a, b0, c, b1 = (x[-1] for x in zoh)
    n_u = n_axes * (N - LEAD)
    col_w = n_u + 2 * (np.arange(n_axes)[:, None] * (N + 1) + np.arange(N + 1))
    col_theta = col_w + 1                                   # (n_axes, N + 1)
    col_u = np.full((n_axes, N), -1)                        # before LEAD: 0, no variable
    col_u[:, LEAD:] = np.arange(n_u).reshape(n_axes, N - LEAD)
    # the ZOH dynamics from sample to sample, two rows per axis and sample
    k = np.arange(N)
    rows, cols, vals = [], [], []
    for j in range(n_axes):
        for q, (out, terms, drive) in enumerate((
                (col_w[j, 1:], [(col_w[j, :-1], -a[j])], -b0[j]),
                (col_theta[j, 1:], [(col_theta[j, :-1], -1.0), (col_w[j, :-1], -c[j])],
                 -b1[j]))):
            r = (2 * j + q) * N + k
            rows += [r, r[LEAD:]] + [r] * len(terms)
            cols += [out, col_u[j, LEAD:]] + [cc for cc, _ in terms]
            vals += [np.ones(N), np.full(N - LEAD, drive)] + [np.full(N, v)
                                                              for _, v in terms]
    dynamics = (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols)))
    n_fixed = col_theta[-1, -1] + 1
    fine = np.arange(LEAD * Q + 1, N * Q)                   # the points inside the move
    held = fine[fine % (Q // 2) == 0] - LEAD * Q - 1        # index into fine
    spread = {2: 1.0, 3: 1.0 / math.cos(math.pi / 8)}.get(n_axes, math.sqrt(n_axes - 1))
    # cuts: the unit normal offset of every point a round found farther than the
    # tolerance (renewed every round; none with 2 axes, whose normal is exact)
    cut = np.zeros((len(fine), n_axes))
    has_cut = np.zeros(len(fine), bool)
    reach, previous = 1.0, math.inf
    closest, stalled = math.inf, 0  # the least of the farthest points so far; rounds since
    program = _WarmProgram()
    for rounds in range(most_rounds):
        m = len(held)
        col_step = n_fixed + np.arange(m)
        col_E = n_fixed + m
        n_var = col_E + 1
        A_eq = sparse.csr_matrix(dynamics, shape=(2 * n_axes * N, n_var))
        f = fine[held]
        ks, js = f // Q, f % Q                              # sample, part of it
        # position of axis j at held point i: theta[ks] + c_js*w[ks] + b1_js*u[ks]
        pos_cols = np.stack([col_theta[:, ks], col_w[:, ks], col_u[:, ks]], axis=-1)
        pos_vals = np.stack([np.ones((n_axes, m)), zoh[2][js].T, zoh[3][js].T], axis=-1)

        def rows_along(directions):
            """Rows (m*r, n_var) of ``directions`` (m, r, n_axes) . position."""
            r = directions.shape[1]
            v = directions[..., None] * pos_vals.transpose(1, 0, 2)[:, None]
            cc = np.broadcast_to(pos_cols.transpose(1, 0, 2)[:, None], v.shape)
            rr = np.broadcast_to(np.arange(m * r).reshape(m, r)[:, :, None, None], v.shape)
            keep = cc >= 0
            return sparse.csr_matrix((v[keep], (rr[keep], cc[keep])), shape=(m * r, n_var))

        sh = s[held]
        p = curve.parameter_at(sh)
        point, T = curve(p), span.tangents(curve, p)
        F = np.asarray(feed(p) if isinstance(feed, FeedLimit) else np.full(m, feed))
        # the trust region: as far as the chord C(s) + T d stays within the tolerance of
        # the curve (kappa d^2/2), or as far as the feed goes in a sample (a guess
        # compressed by a sample is off by about that much), whichever is farther
        # (fmax: a stop at a point where the curve's speed is zero has no curvature)
        trust = np.minimum(reach * np.maximum(np.sqrt(2.0 * tolerance / np.fmax(
            curve.curvature(p), 1e-300)), F * Ts * wide), s1 - s0)
        normals = _normal_directions(T)                     # (m, r, n_axes)
        if n_axes > 2:  # (m, r + 1, n_axes): the held points' cuts, and where a point
            # has none its first normal again (a row that changes nothing), so that the
            # program keeps its shape from round to round and is warm-started
            normals = np.concatenate([normals, np.where(
                has_cut[held][:, None], cut[held], normals[:, 0])[:, None]], axis=1)
        A_t = rows_along(T[:, None, :])                     # d = A_t x - b_t
        b_t = np.einsum("ij,ij->i", T, point)
        A_n = rows_along(normals)
        b_n = np.einsum("iqj,ij->iq", normals, point).ravel()
        E = sparse.csr_matrix((np.ones(len(b_n)), (np.arange(len(b_n)),
                                                   np.full(len(b_n), col_E))),
                              shape=(len(b_n), n_var))
        S = sparse.csr_matrix((np.ones(m), (np.arange(m), col_step)), shape=(m, n_var))
        D = sparse.diags([np.ones(m - 1), -np.ones(m - 1)], [0, 1], shape=(m - 1, m))
        Dt = D @ A_t
        # the nearest points move forward, no faster than the feed, from the start
        # (sample LEAD) through every held point to the end (sample N)
        gap = np.diff(np.concatenate([[LEAD * Q], f, [N * Q]])) * Ts / Q
        travel = np.maximum(F[1:], F[:-1]) * gap[1:-1]
        ahead = sh[1:] - sh[:-1] + b_t[:-1] - b_t[1:]      # s + d nondecreasing
        A_ub = sparse.vstack([A_n - E, -A_n - E, A_t - S, -A_t - S, A_t, -A_t, Dt, -Dt,
                              A_t[:1], -A_t[-1:]]).tocsr()
        b_ub = np.concatenate([b_n, -b_n, b_t, -b_t,
                               np.minimum(trust, s1 - sh) + b_t,
                               np.minimum(trust, sh - s0) - b_t,
                               ahead, travel - ahead,
                               [F[0] * gap[0] + s0 - sh[0] + b_t[0]],
                               [F[-1] * gap[-1] - s1 + sh[-1] - b_t[-1]]])
        bounds = np.empty((n_var, 2))
        bounds[:, 0], bounds[:, 1] = -np.inf, np.inf
        bounds[:n_u] = (-limit, limit)
        bounds[col_w[:, 0]] = bounds[col_w[:, -1]] = 0.0
        bounds[col_theta[:, 0], 0] = bounds[col_theta[:, 0], 1] = start
        bounds[col_theta[:, -1], 0] = bounds[col_theta[:, -1], 1] = end
        bounds[col_step] = (0.0, np.inf)
        bounds[col_E] = (0.0, np.inf)
        cost = np.zeros(n_var)
        cost[col_E] = 1.0
        # a tie-break: of the motions with the least E, the one whose nearest points
        # move least (the chord is exact there); moving all by the trust costs E/16
        cost[col_step] = tolerance / (16.0 * m * trust)
        x = program.solve(cost, A_ub, b_ub, A_eq, bounds)
        if x is None:
            return None
        u = np.zeros((N, n_axes))
        u[LEAD:] = x[:n_u].reshape(n_axes, N - LEAD).T
        positions = _fine_positions(plant, zoh, u)[2][LEAD * Q + 1:N * Q]
        guess = s.copy()
        guess[held] = np.clip(sh + np.einsum("ij,ij->i", T, positions[held] - point),
                              s0, s1)
        s_new = _nearest_forward(curve, positions, np.maximum.accumulate(guess), span)
        p_new = curve.parameter_at(s_new)
        offset = positions - curve(p_new)
        off = np.linalg.norm(offset, axis=1)
        at_end = s_new >= s1 - curve.length * 1e-12
        past = float(np.max((positions[at_end] - end) @ tangent, initial=0.0))
        # the nearest points of the samples (the start at LEAD, the end at N) move by at
        # most F*Ts + FEED_SLACK a sample: the programs hold the linearised ones to F
        at_samples = np.concatenate([[s0], s_new[Q - 1::Q], [s1]])
        fast = np.any(np.diff(at_samples) > _feed_at(feed, np.concatenate(
            [p_new[Q - 1::Q], [span.u1]])) * Ts + FEED_SLACK)
        if np.max(off) <= tolerance and past <= PRECOMPENSATION_TOLERANCE and not fast:
            return u, s_new
        farthest = float(np.max(off))
        stalled = 0 if farthest < closest else stalled + 1
        closest = min(closest, farthest)
        if stalled >= SHORTEN_STALL:
            return None
        worst = float(np.max(off[held]))
        E_now = float(x[col_E])
        left = most_rounds - 1 - rounds
        if E_now > tolerance and E_now - tolerance > left * (previous - E_now):
            return None    # at this pace the program will not come within the tolerance
        if worst > E_now * spread + tolerance / 16:
            reach *= 0.5   # the chord misled the program: a smaller step
        elif np.any(np.abs(guess[held] - sh) >= trust * (1 - 1e-6)):
            reach *= 2.0   # the chord was right, and the trust region held it back
        previous = min(previous, E_now)
        if n_axes > 2:
            T_new = span.tangents(curve, p_new)
            normal = offset - np.einsum("ij,ij->i", offset, T_new)[:, None] * T_new
            size = np.linalg.norm(normal, axis=1)
            renew = (has_cut | (off > tolerance)) & (size > 0.0)
            cut[renew] = normal[renew] / size[renew, None]
            has_cut |= renew
        # once the held points are within the tolerance, hold the worst point of each
        # sample interval that is not
        loose = np.ones(len(fine), bool)
        loose[held] = False
        bad = np.flatnonzero(loose & (off > tolerance))
        if E_now <= tolerance and bad.size:
            interval = fine[bad] // Q
            order = np.lexsort((-off[bad], interval))
            first = np.unique(interval[order], return_index=True)[1]
            held = np.union1d(held, bad[order][first])
            previous = math.inf
        s = s_new
    return None


def _shorten(curve: NurbsCurve, span: _Span, theta: np.ndarray, param: np.ndarray,
             arrival: int, machine: Machine, limit: float, tolerance: float,
             tangent: np.ndarray, feed, earliest: int | None = None):
    """Step 6 (module docstring): the plan ``theta`` (n, n_axes) of a move along the
    ``span`` of the curve that does not stop on the way, from rest on its start at
    sample 0 to rest on its end at ``arrival`` (<= :data:`SHORT_MOVE_SAMPLES`),
    replaced by one at rest there at the earliest sample N at which a drive within
    ``limit`` [V] keeps the plant within ``tolerance`` [pulse] of the curve all along its
    motion (failing that, as near as ``theta`` is), its nearest path point moving forward
    no faster than ``feed`` and not past the end along its unit ``tangent``
    (:func:`_shorten_at`); None if none before ``arrival`` does (where the plan leaves
    the end by more than ``tolerance`` after it: none before it has settled within
    ``tolerance`` either).

    N runs down from ``arrival - 1`` while one is found (where none is, and the plan so
    leaves the end, from the first of ``arrival``, ``arrival + 1``, ... at which one is);
    given the ``earliest`` sample worth trying first (:data:`SHORTEN_START`), from there
    if one is found there within :data:`SHORTEN_STALL` rounds, else from the top. The first guess of the nearest
    points is the plan's (its parameters ``param``, shape (n,)), compressed in time to
    arrive at N; each later N starts from the last motion found, compressed by a sample.
    The programs of one N are warm-started (:class:`_WarmProgram`).
    Returns ``(N, y, param, w, theta, u)``, arrays of N + 1 + :data:`END_REST` samples,
    y the nearest path points of the samples."""
    Ts = machine.sample_period
    start, end = curve(span.u0), curve(span.u1)
    plant = ServoPlant.of_machine(machine, start)
    grid = curve.geometry.uniform_parameters(8 * CHECK_POINTS)
    inside = grid[(grid >= span.u0) & (grid <= span.u1)]
    kappa = float(np.nanmax(curve.curvature(inside if inside.size else grid)))
    fastest = feed.highest if isinstance(feed, FeedLimit) else feed
    plan_s = np.clip(curve.arc_length(param[:arrival + 1]), span.s0, span.s1)
    nearest = curve.parameter_at(_nearest_forward(curve, theta[:arrival + 1], plan_s,
                                                  span))
    # the plan's distance from the path, at most that to the nearest points found or to
    # its desired points (on a tight curl a sample may move farther than the Newton steps
    # of _nearest_forward reach: they then find a point far from the nearest)
    to_nearest = np.linalg.norm(theta[:arrival + 1] - curve(nearest), axis=1)
    to_desired = np.linalg.norm(theta[:arrival + 1] - curve(param[:arrival + 1]), axis=1)
    own = float(np.max(np.minimum(to_nearest, to_desired)))
    # Where the landing (step 5) could not put the plan at rest exactly, what the
    # pre-compensation leaves rings about the end after the arrival: farther from it than
    # the tolerance (a short 3-axis move: 2.6 pulses at Nyquist, settled within a pulse 4
    # samples late), a plan at rest at the arrival itself, or at any sample before the
    # ringing has died down to the tolerance, is worth finding.
    off = np.flatnonzero(np.linalg.norm(theta[arrival:] - end, axis=1) > tolerance)
    settled = arrival + (int(off[-1]) + 1 if off.size else 0)

    def descend(tolerance, top):
        # fine points: the path's chord between two within the tolerance at the feed
        Q = 2 * math.ceil(fastest * Ts * math.sqrt(kappa / (8.0 * tolerance)) / 2)
        zoh = _partial_zoh(machine, int(min(max(Q, 2), CHECK_POINTS)))
        Q = zoh[0].shape[0] - 1
        known = [np.arange(arrival + 1, dtype=float), plan_s]   # times, arc lengths
        best = None

        def found_at(N, most_rounds=SHORTEN_ROUNDS):
            # the last motion found (first: the plan) compressed in time to arrive at N
            nonlocal best
            times, s_known = known
            t = np.arange(LEAD * Q + 1, N * Q) / Q            # fine points [samples]
            guess = np.interp(LEAD + (t - LEAD) * (times[-1] - LEAD) / (N - LEAD), times,
                              s_known)
            # a trust region as wide as the feed goes in a sample, failing that as wide
            # as the linearisation stays within the tolerance
            found = None
            for wide in (True, False):
                found = found or _shorten_at(curve, span, plant, zoh, N,
                                             np.maximum.accumulate(guess),
                                             limit, tolerance, tangent, feed, Ts, wide,
                                             most_rounds)
            if found is not None:
                best = (N, *found, zoh)
                known[:] = [np.concatenate([[float(LEAD)], t, [N]]),
                            np.concatenate([[span.s0], found[1], [span.s1]])]
            return found is not None

        # from the estimate down while one is found; where none is found there within
        # SHORTEN_STALL rounds (a probe: from the plan's guess, compressed by several
        # samples, a program that does not converge soon seldom does), from the top down
        # (each from the motion found a sample later)
        N = top if earliest is None else min(max(earliest, LEAD + 2), top)
        if N == top or not found_at(N, SHORTEN_STALL):
            N = top + 1
        while N > LEAD + 2 and found_at(N - 1):
            N -= 1
        return best

    # within the path tolerance; failing that, no farther from the path than the plan;
    # failing both, a plan at rest at the arrival or later, before this one settles, if
    # this one rings about the end
    tops = [arrival - 1] + list(range(arrival, settled))
    tries = [(top, t) for top in tops
             for t in dict.fromkeys([tolerance, max(tolerance, own)]) if t > 0]
    for top, tolerance in tries:
        best = descend(tolerance, top)
        if best is not None:
            break
    else:
        return None
    N, u_moving, s_fine, zoh = best
    Q = zoh[0].shape[0] - 1
    n = N + 1 + END_REST
    u = np.zeros((n, curve.n_axes))
    u[:N] = u_moving
    w, theta = (x[:-1] for x in _fine_positions(plant, zoh, u)[:2])
    w[N:], theta[N:] = 0.0, end
    y = np.broadcast_to(end, theta.shape).copy()
    new_param = np.full(n, span.u1)
    y[:LEAD + 1], new_param[:LEAD + 1] = start, span.u0
    moving = slice(LEAD + 1, N)
    new_param[moving] = curve.parameter_at(s_fine[Q - 1::Q])  # samples LEAD + 1 .. N - 1
    y[moving] = curve(new_param[moving])
    return N, y, new_param, w, theta, u


def _shorten_pieces(curve: NurbsCurve, stops: np.ndarray, corner_times: np.ndarray,
                    theta: np.ndarray, param: np.ndarray, arrival: int, machine: Machine,
                    limit: float, tolerance: float, tangent: np.ndarray, feed,
                    earliest=None):
    """Step 6 from stop to stop: every piece of the plan ``theta`` (n, n_axes; its
    parameters ``param`` (n,), at rest on the end at ``arrival``) between the stops at
    the curve parameters ``stops`` (n_pieces + 1,: the start, the stop corners, the end),
    where it stops at the fractional samples ``corner_times`` (n_pieces - 1,), replaced
    by :func:`_shorten`'s (at rest at its stops at sample instants), the pieces one after
    the other. None unless every piece is found and together they arrive before
    ``arrival``, or if an axis first moves after a stop (by more than
    :func:`move_tolerance` of ``tolerance``): a piece's plan drives every axis at the limit
    from its first sample, and the online step knows an axis' plant only once it has
    seen it move (on the die-bonder's Pi, whose x starts at the first corner, plants
    with tau x0.8 and Kc x1.2 then went 71 um off the arch; the plan of the whole path
    starts the x drive over the sample in which y still brakes). Returns
    ``(N, y, param, w, theta, u, corner_times)``: the arrays as :func:`_shorten`'s, the
    corner times whole samples."""
    edges = np.concatenate([[0.0], corner_times, [float(arrival)]])
    # the plan's samples around each piece: from the last before its first stop to the
    # first after its next (the end: all, for the ringing after it)
    first = np.floor(edges[:-1] + 1e-9).astype(int)
    after = np.append(np.ceil(edges[1:-1] - 1e-9).astype(int), arrival)
    moves = move_tolerance(tolerance)
    for a, b in zip(first[1:], after[1:]):
        before, moving = (np.ptp(theta[k:m], axis=0) > moves for k, m in ((0, a + 1),
                                                                          (a, b + 1)))
        if np.any(moving & ~before):
            return None
    parts = []
    for i, (a, b) in enumerate(zip(first, after)):
        last = i == len(stops) - 2
        piece = _shorten(curve, _Span.of(curve, stops[i], stops[i + 1]),
                         theta[a:] if last else theta[a:b + 1], param[a:b + 1], b - a,
                         machine, limit, tolerance,
                         tangent if last else _unit(curve(stops[i + 1], 1, "left")), feed,
                         None if earliest is None else int(earliest[i]))
        if piece is None:
            return None
        parts.append(piece)
    if len(parts) == 1:
        return parts[0] + (corner_times,)
    N = sum(part[0] for part in parts)
    if N >= arrival:
        return None
    # piece by piece, each up to its arrival; the last with its rest on the end
    cut = [part[0] for part in parts[:-1]] + [len(parts[-1][1])]
    y, param, w, theta, u = (np.concatenate([part[q][:k] for part, k in zip(parts, cut)])
                             for q in range(1, 6))
    return (N, y, param, w, theta, u,
            np.cumsum([part[0] for part in parts[:-1]]).astype(float))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-300)


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
    kept, accepted = _precompensate(y, alpha, beta, a, b0, rounds, float(limit),
                                    float(slack), y.copy(), *sets[0], *sets[1], peaks)
    return (sets[kept] if accepted else None), peaks


def plan_motion(curve: NurbsCurve, machine: Machine, feed, *,
                corner_tolerance: float = 0.0, drive_fraction: float = 1.0,
                path_tolerance: float = DEFAULT_PATH_TOLERANCE, grid_size: int = 4000,
                max_samples: int = 10_000_000) -> MotionPlan:
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

    Returns
    -------
    MotionPlan
        Its ``corner_tolerance`` is 0 where stopping at the sharp corners arrives no later
        than rounding them (blends superpose the pieces' drives, and easing their sum can
        cost more than the stops it saves).

    Raises
    ------
    InvalidArgumentError
        If a tolerance is not finite and >= 0, or ``drive_fraction`` not in (0, 1].
    InfeasibleError
        If the drive cannot move along the path or the plan is too long.
    """
    for name, value in (("corner_tolerance", corner_tolerance),
                        ("path_tolerance", path_tolerance)):
        if not (math.isfinite(value) and value >= 0):
            raise InvalidArgumentError(f"{name} must be finite and >= 0, got {value!r}")
    if not (0 < drive_fraction <= 1):
        raise InvalidArgumentError(f"drive_fraction must lie in (0, 1], got {drive_fraction!r}")
    options = dict(drive_fraction=drive_fraction, path_tolerance=path_tolerance,
                   grid_size=grid_size, max_samples=max_samples)

    def stopping_plan():
        return _plan_motion(curve, machine, feed, 0.0, **options)

    if corner_tolerance == 0:
        return stopping_plan()
    try:
        plan = _plan_motion(curve, machine, feed, corner_tolerance, **options)
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
                 max_samples: int) -> MotionPlan:
    """:func:`plan_motion` for one corner tolerance (its arguments checked)."""
    Ts = machine.sample_period
    umax = machine.max_drive
    lead = LEAD
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
                                                     lead)
        y = np.vstack([y, np.repeat(y[-1:], END_REST, axis=0)])
        param = np.concatenate([param, np.ones(END_REST)])
        earliest = np.concatenate([earliest, np.full(END_REST, np.nan)])
        # A round within the limit that is as near y as the best one, give or take what
        # the loop cannot see (PRECOMPENSATION_TOLERANCE), ends the easing.
        plant, peaks = _drive_sequence(y, machine, PRECOMPENSATION_ROUNDS,
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
        half = np.maximum(speed * Ts * (1 + INVERSE_REACH) * widen, spacing)
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
        plant, peaks = _drive_sequence(y, machine, PRECOMPENSATION_ROUNDS,
                                       drive_fraction * umax * (1 + 1e-9))
        if plant is None:
            use = float(np.max(peaks)) / umax
            raise InfeasibleError(
                f"the planned drive needs {use:.3g} x Umax after {DRIVE_FIT_ROUNDS} rounds "
                "of easing the path speed's drive limit where it exceeds it")
    w, theta, u = plant
    tangent = _unit(curve(1.0, 1, "left"))
    landed = _land_on_end(y, w, theta, u, machine, drive_fraction * umax, tangent, curve,
                          param, feed)
    y[landed:] = y[-1]       # the desired motion rests where the plan does
    param[landed:] = 1.0
    if landed <= SHORT_MOVE_SAMPLES and (corners.size == 0 or corner_tolerance == 0):
        stops = np.array([piece[1][0] for piece in profile.pieces] + [1.0])
        short = _shorten_pieces(curve, stops, corners, theta, param, landed, machine,
                                drive_fraction * umax, path_tolerance, tangent, feed,
                                estimate)
        if short is not None:
            landed, y, param, w, theta, u, corners = short
    theta[-1] = y[-1]
    w[-1] = 0.0
    return MotionPlan(position=theta, speed=w, drive=u, parameter=param, desired=y,
                      drive_fraction=drive_fraction, corner_times=corners, sample_period=Ts,
                      arrival=landed, corner_tolerance=float(corner_tolerance))
