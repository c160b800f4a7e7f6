"""The compiled phase-plane passes of :func:`nurbsmotion.planning.speed_profile`: the
admissible acceleration at a grid point for a speed (:func:`_range`), the drive-limited
speed curve (:func:`max_speed`) and the backward and forward integration under it
(:func:`passes`). Loaded, with numba, when a profile is computed: the planner's size
checks (:mod:`nurbsmotion.planning`) run without the compiler.

Glossary
--------
See :mod:`nurbsmotion.planning`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["max_speed", "passes", "ACTIVE_SLOPE", "MVC_TOLERANCE", "STIFF_STEP"]


ACTIVE_SLOPE = 1e-9
"""An axis whose |dx/ds| is below this takes no part in the acceleration limit (its drive
is fixed by the speed alone)."""


@njit(cache=True)
def _range(q1, q2, tau, M, i, b):
    """(amin, amax) [pulse/s^2] at grid point i and b = sd^2 (amin > amax: empty).

    ``q1``, ``q2``, ``M`` have shape (n, n_axes), ``tau`` (n_axes,)."""
    sd = math.sqrt(max(b, 0.0))
    lo, hi = -math.inf, math.inf
    for j in range(q1.shape[1]):
        c = tau[j] * q2[i, j] * b + q1[i, j] * sd     # drive part fixed by the speed
        if abs(q1[i, j]) > ACTIVE_SLOPE:
            tq1 = tau[j] * q1[i, j]
            a1, a2 = (-M[i, j] - c) / tq1, (M[i, j] - c) / tq1
            if a1 > a2:
                a1, a2 = a2, a1
            lo = max(lo, a1)
            hi = min(hi, a2)
        elif abs(c) > M[i, j]:
            return math.inf, -math.inf
    return lo, hi


@njit(cache=True)
def max_speed(q1, q2, tau, M, feed):
    """The MVC: the largest sd <= F with a non-empty range, per grid point [pulse/s];
    ``feed`` has one value per grid point (60 bisections below it when it is not
    admissible)."""
    n = q1.shape[0]
    out = np.empty(n)
    for i in range(n):
        lo, hi = _range(q1, q2, tau, M, i, feed[i] * feed[i])
        if lo <= hi:
            out[i] = feed[i]
            continue
        a, z = 0.0, feed[i]
        for _ in range(60):
            mid = 0.5 * (a + z)
            lo, hi = _range(q1, q2, tau, M, i, mid * mid)
            if lo <= hi:
                a = mid
            else:
                z = mid
        out[i] = a
    return out


MVC_TOLERANCE = 1e-9
"""A point whose b = sd^2 is within this fraction of the MVC's is on it (:func:`passes`
slides along the MVC from there where the drive bounds it, not the feed)."""


STIFF_STEP = 0.5
"""A step that raises the speed (in either pass) is taken implicitly
(:func:`_implicit_step`) where the far end's limit at the explicit step's speed is less
than this fraction of the near end's: there the limit changes within the step more than
a one-sided correction follows (elsewhere the step takes the smaller of the two, which
errs on the slow side by O(ds) and converges as the grid is refined)."""


@njit(cache=True)
def _step_excess(q1, q2, tau, M, j, b0, ds, forward, b):
    """How far ``b`` misses :func:`_implicit_step`'s condition (<= 0: met; inf where the
    range at ``b`` is empty)."""
    lo, hi = _range(q1, q2, tau, M, j, b)
    if lo > hi:
        return math.inf
    return (b - b0 - 2.0 * ds * hi) if forward else (2.0 * ds * lo - (b0 - b))


@njit(cache=True)
def _implicit_step(q1, q2, tau, M, j, b0, ds, forward, lo_b, hi_b, guess):
    """The largest b in ``[lo_b, hi_b]`` reached from ``b0`` over ``ds`` at a constant
    acceleration admissible at grid point ``j`` with that b: ``(b - b0)/(2 ds) <=
    amax(j, b)`` going forward, ``(b0 - b)/(2 ds) >= amin(j, b)`` going backward (an
    implicit Euler step; ``lo_b`` meets the condition; ``guess``, where it lies inside
    the bracket and meets it too, narrows the bracket first). Used where the limit changes with
    the speed faster than an explicit step follows: a forced fall (the change shrinks
    with the speed), or a rise toward an axis's steady speed over a grid interval longer
    than the distance it takes (its speed relaxes as exp(-t/tau)).

    Found to 1e-13 of b by the Illinois variant of false position, halving the bracket
    where the condition's excess is not finite."""
    g_hi = _step_excess(q1, q2, tau, M, j, b0, ds, forward, hi_b)
    if g_hi <= 0.0:
        return hi_b
    if lo_b < guess < hi_b:
        g = _step_excess(q1, q2, tau, M, j, b0, ds, forward, guess)
        if g <= 0.0:
            lo_b = guess
    g_lo = _step_excess(q1, q2, tau, M, j, b0, ds, forward, lo_b)
    side = 0
    for _ in range(200):
        if hi_b - lo_b <= 1e-13 * hi_b:
            break
        mid = 0.5 * (lo_b + hi_b)
        if math.isfinite(g_hi):
            guess = lo_b + (hi_b - lo_b) * (-g_lo) / (g_hi - g_lo)
            if lo_b < guess < hi_b:
                mid = guess
        g = _step_excess(q1, q2, tau, M, j, b0, ds, forward, mid)
        if g <= 0.0:
            lo_b, g_lo = mid, g
            if side < 0:
                g_hi *= 0.5
            side = -1
        else:
            hi_b, g_hi = mid, g
            if side > 0:
                g_lo *= 0.5
            side = 1
    return lo_b


@njit(cache=True)
def passes(q1, q2, tau, M, M_acc, ds, bmax, bfeed):
    """Backward pass at the deceleration limit (drive bound ``M``), then forward pass at
    the acceleration limit (``M_acc``), on one piece; b = sd^2 at every point.

    Where the drive bounds the MVC its admissible range shrinks to a point whose slope the
    Euler step does not follow: the passes slide along it instead of falling below it.
    Elsewhere (below the MVC, or on it where the feed ``bfeed`` = F^2 bounds it) a step
    that must lower the speed stands: a speed the drive holds only while it decelerates
    (an axis beyond its steady speed ``Umax*Kc*Ke``, or the curvature's drive at the
    feed), implicit (:func:`_implicit_step`) where the explicit one would fall below rest.
    A step that raises the speed uses an acceleration admissible at both ends of its
    interval, at the speed it reaches (implicit where the far end's limit binds: toward
    an axis's steady speed the limit falls with the speed, over a distance ``v*tau``
    that may be much shorter than the grid interval).

    ``q1``, ``q2``, ``M``, ``M_acc`` have shape (n, n_axes); ``ds`` [pulse], shape
    (n - 1,), is the grid spacing (uniform, or refined in short knot spans); ``bmax`` and
    ``bfeed``, shape (n,), the MVC's and the feed's b."""
    slide = bmax < bfeed * (1.0 - MVC_TOLERANCE)
    n = len(bmax)
    back = np.empty(n)
    back[-1] = 0.0
    for i in range(n - 2, -1, -1):
        bn = back[i + 1]
        a = _range(q1, q2, tau, M, i + 1, bn)[0]
        b = bn - 2.0 * ds[i] * a
        if b > bn:  # the deceleration must be admissible at the earlier point too
            explicit = b
            a_far = _range(q1, q2, tau, M, i, b)[0]
            if a_far > STIFF_STEP * a and bn <= bmax[i] and _range(q1, q2, tau, M, i, bn)[0] <= 0.0:
                b = _implicit_step(q1, q2, tau, M, i, bn, ds[i], False, bn, explicit,
                                   bn - 2.0 * ds[i] * a_far)
            else:
                b = max(bn - 2.0 * ds[i] * max(a, a_far), min(bn, bmax[i]))
        elif slide[i + 1] and bn >= bmax[i + 1] * (1.0 - MVC_TOLERANCE):
            b = max(b, min(bn, bmax[i]))
        elif b < 0.0:
            b = _implicit_step(q1, q2, tau, M, i, bn, ds[i], False, 0.0, bn, 0.0)
        back[i] = min(b, bmax[i])
    out = np.empty(n)
    out[0] = 0.0
    for i in range(n - 1):
        bp = out[i]
        a = _range(q1, q2, tau, M_acc, i, bp)[1]
        b = bp + 2.0 * ds[i] * a
        if b > bp:  # the acceleration must be admissible at the next point too
            explicit = b
            a_far = _range(q1, q2, tau, M_acc, i + 1, b)[1]
            if a_far < STIFF_STEP * a and bp <= bmax[i + 1] \
                    and _range(q1, q2, tau, M_acc, i + 1, bp)[1] >= 0.0:
                b = _implicit_step(q1, q2, tau, M_acc, i + 1, bp, ds[i], True, bp, explicit,
                                   bp + 2.0 * ds[i] * a_far)
            else:
                b = max(bp + 2.0 * ds[i] * min(a, a_far), min(bp, bmax[i + 1]))
        elif slide[i] and bp >= bmax[i] * (1.0 - MVC_TOLERANCE):
            b = max(b, min(bp, bmax[i + 1]))
        elif b < 0.0:
            b = _implicit_step(q1, q2, tau, M_acc, i + 1, bp, ds[i], True, 0.0, bp, 0.0)
        out[i + 1] = min(b, back[i + 1])
    return out
