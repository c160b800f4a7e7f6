"""Steps 1-2 of the plan (:mod:`.plan`): each corner-free piece's time profile, averaged with
itself a sample later and sampled (:func:`_piece_motions`), and the corner blends that start
the next piece before the current one has stopped (:func:`_blend_starts`), superposed into
the desired motion (:func:`_desired_motion`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ...geometry import distances_to
from ...nurbs import NurbsCurve
from ...planning import SpeedProfile


OVERSAMPLE = 32
"""Fine time steps per sample of the averaged time profile (linear interpolation between
them moves a position by at most ``(Ts/32)^2/8`` times the acceleration: a hundredth of a
pulse at the die-bonder's full acceleration)."""


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


def _piece_motions(curve: NurbsCurve, profile: SpeedProfile, Ts: float,
                   shaper: np.ndarray | None = None):
    """Per corner-free piece: its duration [s] and a function ``times -> (positions, u)``
    (``times`` [s] nondecreasing from the piece's start).

    The piece's s(t) is averaged with itself one sample later (module docstring, step 1;
    at rest before and after): the piece lasts Ts longer and its sampled motion has
    nothing at the Nyquist frequency. Sampled on a fine grid of :data:`OVERSAMPLE` points
    per sample that is streamed, never stored (:func:`_averaged_arc`), and mapped to the
    curve by the compiled arc-length inverse
    (:meth:`nurbsmotion.geometry.CurveGeometry.parameter_at`, uncached).

    ``shaper`` (taps h[n] >= 0 summing to 1, one per sample; :func:`.shaper.plan_shaper`):
    the averaged s(t) is shaped as well, ``sum_n h[n]*s(t - n*Ts)`` (the *time law*, not
    the axes, so the motion stays on the path; the piece lasts ``len(shaper) - 1``
    samples longer; :func:`.shaper.shape_time_law`)."""
    out = []
    h = Ts / OVERSAMPLE
    geometry = curve.geometry
    taps = () if shaper is None else tuple(enumerate(np.asarray(shaper, dtype=float)))
    for (s, u, V), t in zip(profile.pieces, profile.piece_times()):
        n_fine = int(math.ceil(t[-1] / h)) + 1
        duration = (n_fine + OVERSAMPLE - 1) * h
        if taps:
            duration += (len(taps) - 1) * Ts

        def motion(times, s=s, u=u, V=V, t=t, n_fine=n_fine, duration=duration):
            times = np.ascontiguousarray(times, dtype=float)  # nondecreasing
            sk = np.empty_like(times)
            if taps:
                sk = _shaped_arc(s, V, t, h, n_fine, taps, Ts, times, duration)
            else:
                _averaged_arc(s, V, t, h, n_fine, OVERSAMPLE, times, sk)
            uk = np.interp(sk, s, u)
            inner = (sk > s[0]) & (sk < s[-1])
            if np.any(inner):
                uk[inner] = np.clip(geometry.parameter_at(sk[inner], cache=False),
                                    u[0], u[-1])
            return curve(uk), uk
        out.append((float(duration), motion))
    return out


def _shaped_arc(s, V, t, h, n_fine, taps, Ts, times, duration):
    """The averaged time profile (:func:`_averaged_arc`) shaped by ``taps`` ((n, h[n])
    pairs, h[n] >= 0 summing to 1): ``sum_n h[n]*s_avg(times - n*Ts)`` [pulse], exactly
    the piece's start before ``times`` 0 and its end from ``duration`` [s] on (a convex
    combination of the profile's positions, so within its ends)."""
    out = np.zeros_like(times)
    copy = np.empty_like(times)
    for n, weight in taps:
        if weight > 0:
            _averaged_arc(s, V, t, h, n_fine, OVERSAMPLE, times - n * Ts, copy)
            out += weight * copy
    np.clip(out, s[0], s[-1], out=out)
    out[times <= 0.0] = s[0]
    out[times >= duration] = s[-1]
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
                    lead: int, shaper: np.ndarray | None = None):
    """y[k] (sum of the pieces, blended at corners), the parameter of each sample, the
    time of every corner [samples] and, for the samples where more than one piece moves
    (a blend), the parameter of the earliest of them (NaN elsewhere). Piece 0 starts at
    sample ``lead``; each piece's time law shaped by ``shaper`` if given
    (:func:`_piece_motions`)."""
    pieces = _piece_motions(curve, profile, Ts, shaper)
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
