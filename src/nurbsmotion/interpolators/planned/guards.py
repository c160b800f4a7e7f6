"""The online step's stop guards (:mod:`.step`): where the plant must stay able to stop,
braking at Umax, before a stop corner or the end (:func:`_stop_guards`, :func:`_guarded`),
and the travel to rest of the ZOH plant (:func:`_stopping_travel`, :func:`_short_of_stop`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .governor import RATE_BISECTIONS
from .shorten import move_tolerance


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
def _short_of_stop(u, x, w, stop, s, a, b0, c, b1, umax, bisections=RATE_BISECTIONS,
                   unknown=0.0):
    """The drive nearest ``u`` [V], within +-Umax, after which the ZOH plant ``(a, b0, c,
    b1)`` at position ``x`` [pulse] and speed ``w`` [rad/s], braking at Umax from the
    next sample on, stops before ``stop`` [pulse] (moving in direction ``s``, +-1): the
    travel grows with the drive, so it is ``u`` itself if that stops in time, the full
    brake if nothing does, and else the drive that stops on ``stop``, bisected
    ``bisections`` times. ``unknown`` [V]: a drive the plant gets besides the one asked
    for (the identified load or friction, :func:`.identify._identify`'s delta), added to
    the drive and to the brake; an unknown drive that the brake cannot overcome is a
    travel without end (the full brake)."""
    brake = -s * umax
    if (brake + unknown) * s >= 0.0:
        return brake

    def beyond(v):
        w1 = a * w + b0 * (v + unknown)
        return s * (x + c * w + b1 * (v + unknown)
                    + _stopping_travel(w1, a, b0, c, b1, brake + unknown) - stop)

    if beyond(u) <= 0.0:
        return u
    if beyond(brake) > 0.0:
        return brake
    good, bad = brake, u
    for _ in range(bisections):
        mid = 0.5 * (good + bad)
        if beyond(mid) > 0.0:
            bad = mid
        else:
            good = mid
    return good


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
    :func:`~.shorten.move_tolerance` of ``path_tolerance`` [pulse]."""
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
