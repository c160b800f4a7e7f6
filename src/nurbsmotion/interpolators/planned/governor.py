"""The online step's clock-rate governor (:mod:`.step`): the largest rate of the plan's clock
the drive left allows over the next :data:`RATE_WINDOW` samples (:func:`_window_rate`) and,
beyond them up to the next stop, from the support function of the plan's drive
(:func:`_support`, stored every :data:`SUPPORT_BLOCK` samples, and :func:`_demand`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


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
def _window_rate(i0, r_tail, gains, a, drive_speed, drive_accel, headroom, umax, window):
    """The largest clock rate at plan samples ``i0`` and ``i0 + 1`` (the clock passes
    both within the sample) from which the estimated plant can follow the plan: a
    backward pass over the plan samples ``i0 .. i0 + window`` (:data:`RATE_WINDOW` by
    default, the plan's ``rate_window``) from ``r_tail`` (the
    uniform rate that holds from there to the next stop; the window may cross stops: the
    plan is at rest there, and its rate may change freely). At sample k the rate r may be
    at most the static rate
    (:func:`_static_rate`: ``|ga*A*r^2 + gv*V*r|`` within the limit) and at most the next
    sample's rate plus what the drive left can take off over one plan sample: slowing the
    clock by dr slows axis j by ``w_ff*dr``, which costs ``ga*V/(1 - a)*dr`` [V] (V the
    speed part of the plan's drive, ``w_ff/Kc``), over 1/r loop samples. ``gains`` (2,
    n_axes): ga, gv. Both sample k's and k + 1's drives bound the change (the clock may
    lie anywhere between them while the rate changes)."""
    end = min(i0 + window, drive_speed.shape[0])
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
