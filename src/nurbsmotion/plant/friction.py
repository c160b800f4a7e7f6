"""Friction on the motor, integrated exactly (piecewise analytic, never sub-stepped):
the instant a sliding motor stops (closed form on a rigid axis; a safeguarded Newton
iteration from a Hermite and a Taylor guess on a two-mass one) or a stuck motor breaks
away, the quiet test of an interval without an event, and an interval through its
events (the model: :mod:`nurbsmotion.plant`).

Glossary
--------
See :mod:`nurbsmotion.plant`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .two_mass import (CA, CB0, CDMP, CEC, CES, CHECK_SLIDE, CHECK_STUCK, CSC, CSS, FC,
                       FS, GAIN, KC, KE, KSPR, LAM, NO_COEFFICIENTS, SA0, SA1, SIG, TAU,
                       W2, _coefficients, _complete_coefficients, _motor_accel,
                       _motor_speed, _net_drive, _rest_coefficients, _slide, _slide_for,
                       _speed_accel_after, _stuck, _stuck_with)

__all__ = ["MAX_EVENTS", "TAYLOR_TERMS", "SCRATCH"]

MAX_EVENTS = 64
"""Friction events (stops, breakaways) one interval may hold at most: beyond, the motor is
taken as stuck for the rest of it (a guard against a chattering degenerate case)."""


@njit(cache=True, inline="always")
def _hermite_root(lo, hi, f_lo, a_lo, f_hi, a_hi):
    """The root in ``[lo, hi]`` [s] of the cubic Hermite interpolant of a function with
    values ``f_lo > 0 >= f_hi`` and derivatives ``a_lo``, ``a_hi`` at the ends (a few
    Newton steps on the cubic from the secant's root): the first guess of
    :func:`_stop_time`'s Newton iteration, within the bracket."""
    H = hi - lo
    s = f_lo / (f_lo - f_hi)
    b_lo = H * a_lo
    b_hi = H * a_hi
    for _ in range(4):
        s2 = s * s
        s3 = s2 * s
        val = (f_lo * (2.0 * s3 - 3.0 * s2 + 1.0) + b_lo * (s3 - 2.0 * s2 + s)
               + f_hi * (3.0 * s2 - 2.0 * s3) + b_hi * (s3 - s2))
        der = (6.0 * (f_lo - f_hi) * (s2 - s) + b_lo * (3.0 * s2 - 4.0 * s + 1.0)
               + b_hi * (3.0 * s2 - 2.0 * s))
        if not der < 0.0:
            break
        sn = s - val / der
        if not 0.0 < sn < 1.0:
            break
        s = sn
    return lo + s * H


TAYLOR_TERMS = 20
"""Terms of the motor speed's Taylor series :func:`_taylor_root` sums at most: the
20th is ``(wn*h)**20/20!`` of the oscillation's amplitude, 1e-20 for an interval of
an eighth of the mode's period (the checks' step)."""


@njit(cache=True, inline="always")
def _taylor_root(p, x, v, direction, hi, f_hi, t, series):
    """The root in ``(0, hi]`` [s] of the motor speed's Taylor series about the state
    ``x`` at 0 (``series``: room for :data:`TAYLOR_TERMS` coefficients), by Newton
    steps on the polynomial from ``t`` (kept if a step leaves the bracket): the guess
    of :func:`_stop_time`'s exact Newton iteration, without a transcendental. The
    derivatives come from the axis's equations: ``w_cm^(n) = w_cm'*(-1/tau)^(n-1)``,
    ``z^(n+2) = -2*zeta*wn*z^(n+1) - wn^2*z^(n)`` for ``z = delta - GAIN*v/wn^2``; the
    series stops where two terms in a row are below 1e-17 of the largest at ``hi``."""
    tau = p[TAU]
    m2 = 2.0 * p[SIG]
    w2 = p[W2]
    r = p[LAM] / p[KE]
    dw = (p[KC] * v - x[0]) / tau  # w_cm'
    z_prev = x[2] - p[GAIN] * v / w2  # z
    z_cur = x[3]  # z'
    series[0] = direction * (x[0] + r * z_cur)
    largest = abs(series[0])
    power = 1.0
    inv_fact = direction  # direction/n!: no division in the loop
    decay = -1.0 / tau
    small = 0
    n_terms = TAYLOR_TERMS
    for n in range(1, TAYLOR_TERMS):
        z_next = -m2 * z_cur - w2 * z_prev  # z^(n+1)
        inv_fact *= INVERSE[n]
        series[n] = (dw + r * z_next) * inv_fact
        dw *= decay
        z_prev = z_cur
        z_cur = z_next
        power *= hi
        size = abs(series[n]) * power
        largest = max(largest, size)
        small = small + 1 if size <= 1e-17 * largest else 0
        if small == 2:
            n_terms = n + 1
            break
    for _ in range(8):
        val = series[n_terms - 1]
        der = 0.0
        for n in range(n_terms - 2, -1, -1):
            der = der * t + val
            val = val * t + series[n]
        if not der < 0.0:
            break
        tn = t - val / der
        if not 0.0 < tn <= hi:
            break
        if abs(tn - t) <= 1e-16 * hi:
            return tn
        t = tn
    return t


INVERSE = np.array([0.0] + [1.0 / n for n in range(1, TAYLOR_TERMS)])
"""1/n, n < TAYLOR_TERMS (entry 0 unused), for the series' 1/n!."""
INVERSE.flags.writeable = False

SCRATCH = TAYLOR_TERMS
"""Length of :class:`PlantState`'s ``scratch``: a Taylor series (:func:`_taylor_root`)."""

NEWTON_STEPS = 8
"""Newton steps :func:`_stop_time` takes at most before it falls back on regula falsi
(from the Hermite guess it converges in two or three)."""

NEWTON_TOLERANCE = 1e-14
"""A Newton step below this fraction of the interval ends :func:`_stop_time`'s root
find (the step estimates the iterate's error; it is far below the rounding of the
stage's state over an interval)."""


@njit(cache=True)
def _stop_time(p, x, v, h, direction, cf, fixed, series):
    """The first instant in (0, h] [s] at which the sliding motor's speed reaches zero
    (``direction*w_motor <= 0``), or -1 if none. Rigid: closed form. Two-mass: checks
    every eighth of the mode's period bracket the first stop; then a safeguarded Newton
    iteration on the exact motor speed, whose derivative (the motor's acceleration,
    :func:`_motor_accel`) costs no transcendental beyond the speed's, started from the
    cubic Hermite interpolant of the bracket's ends (speed and acceleration known there
    from the checks); a step out of the bracket is replaced by the bracket's secant,
    and Illinois regula falsi finishes if Newton does not converge.
    ``cf``: the coefficients of ``h`` when ``fixed`` (a precomputed interval: the check
    at ``h`` costs no transcendental); ``series``: :func:`_taylor_root`'s room.
    Returns ``(t, at_end, c, y)``: at a stop, ``c`` the sliding coefficients of ``t``;
    ``at_end`` when there is no stop and ``y`` is the state at ``h`` (exactly as sliding
    over ``h`` gives)."""
    c = NO_COEFFICIENTS
    y = x
    if p[W2] == 0.0:
        wss = p[KC] * v
        w0 = x[0]
        if direction * wss >= 0.0:  # monotone towards wss: no reversal
            return -1.0, False, c, y
        if direction * w0 <= 0.0:
            return 0.0, False, _coefficients(p, 0.0), y
        t = p[TAU] * math.log1p(-w0 / wss)
        if t <= h:
            return t, False, _coefficients(p, t), y
        return -1.0, False, c, y
    n = max(1, int(math.ceil(h / p[CHECK_SLIDE])))
    lo = 0.0
    hi = -1.0
    f_lo = direction * _motor_speed(p, x)
    a_lo = direction * _motor_accel(p, x, v)
    f_hi = 0.0
    a_hi = 0.0
    for i in range(1, n + 1):
        t = h * i / n
        if fixed and t == h:
            y = _slide(p, cf, x, v)
        else:
            c, y = _slide_for(p, x, v, t)
        f = direction * _motor_speed(p, y)
        a = direction * _motor_accel(p, y, v)
        if f <= 0.0:
            hi = t
            f_hi = f
            a_hi = a
            break
        lo = t
        f_lo = f
        a_lo = a
    if hi < 0.0:
        return -1.0, lo == h, c, y
    if f_lo > 0.0:
        t = _hermite_root(lo, hi, f_lo, a_lo, f_hi, a_hi)
        if lo == 0.0:
            t = _taylor_root(p, x, v, direction, hi, f_hi, t, series)
        for _ in range(NEWTON_STEPS):
            f, a, c = _speed_accel_after(p, x, v, t)
            f *= direction
            a *= direction
            if f > 0.0:
                lo, f_lo = t, f
            else:
                hi, f_hi = t, f
            if f == 0.0:
                return t, False, _complete_coefficients(p, t, c), y
            step = f / a if a != 0.0 else math.inf
            if abs(step) <= NEWTON_TOLERANCE * h:
                return t, False, _complete_coefficients(p, t, c), y
            t = t - step
            if not lo < t < hi:  # out of the bracket: its secant instead
                t = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
                if not lo < t < hi:
                    t = 0.5 * (lo + hi)
    side = 0
    for _ in range(100):
        if hi - lo <= 1e-15 * h + 1e-300:
            break
        if f_lo <= 0.0:
            t = 0.5 * (lo + hi)
        else:
            t = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            if not (lo < t < hi):
                t = 0.5 * (lo + hi)
        f, _, c = _speed_accel_after(p, x, v, t)
        f *= direction
        if f > 0.0:
            lo, f_lo = t, f
            if side == -1:
                f_hi *= 0.5
            side = -1
        else:
            hi, f_hi = t, f
            if side == 1:
                f_lo *= 0.5
            side = 1
    return hi, False, _coefficients(p, hi), y


@njit(cache=True)
def _breakaway_time(p, x, v, h, cf, fixed):
    """The first instant in [0, h] [s] at which the net drive on a stuck motor exceeds
    the breakaway drive, or -1. Rigid: constant over the interval. ``cf``, ``fixed`` as
    :func:`_stop_time`'s; returns ``(t, at_end, y)``, ``y`` the stuck state at ``h``
    when ``at_end``."""
    limit = p[FS]
    if abs(_net_drive(p, x, v)) > limit:
        return 0.0, False, x
    if p[W2] == 0.0:
        return -1.0, False, x
    n = max(1, int(math.ceil(h / p[CHECK_STUCK])))
    lo = 0.0
    hi = -1.0
    y = x
    for i in range(1, n + 1):
        t = h * i / n
        if fixed and t == h:
            y = _stuck_with(p, x, cf[CSC], cf[CSS])
        else:
            y = _stuck(p, x, t)
        if abs(_net_drive(p, y, v)) > limit:
            hi = t
            break
        lo = t
    if hi < 0.0:
        return -1.0, lo == h, y
    for _ in range(80):  # bisection: a breakaway is rare
        if hi - lo <= 1e-15 * h + 1e-300:
            break
        t = 0.5 * (lo + hi)
        if abs(_net_drive(p, _stuck(p, x, t), v)) > limit:
            hi = t
        else:
            lo = t
    return hi, False, y


@njit(cache=True, inline="always")
def _friction_quiet(p, c, x, d, v, h):
    """A friction axis over a precomputed interval (coefficients ``c``) with no event,
    if it is one: sliding with no stop, or stuck with no breakaway, decided by the very
    tests :func:`_advance_events` makes first (the single check at the interval's end
    when the interval is within one check step), so the state is the same to the bit.
    ``d``: the motor's direction. Returns ``(True, the state at the interval's end)``,
    or ``(False, x)`` when there is an event."""
    if d != 0.0:
        veff = v - p[FC] * d
        if p[W2] == 0.0:
            if d * (p[KC] * veff) >= 0.0:  # monotone towards a speed in d's sense
                return True, _slide(p, c, x, veff)
            return False, x
        if h / p[CHECK_SLIDE] > 1.0:
            return False, x
        w = c[CA] * x[0] + c[CB0] * veff
        ys = p[GAIN] * veff / p[W2]
        z0 = x[2] - ys
        x3 = x[3]
        d3 = c[CEC] * x3 - c[CES] * (p[SIG] * x3 + p[W2] * z0)
        if d * (w + p[LAM] * d3 / p[KE]) <= 0.0:
            return False, x
        return True, _slide(p, c, x, veff)
    limit = p[FS]
    if abs(v - p[KSPR] * x[2] - p[CDMP] * x[3]) > limit:
        return False, x
    if p[W2] == 0.0:
        return True, (0.0, x[1], 0.0, 0.0)
    if h / p[CHECK_STUCK] > 1.0:
        return False, x
    lam = p[LAM]
    x2 = x[2]
    x3 = x[3]
    motor = x[1] + lam * x2
    ec = c[CSC]
    es = c[CSS]
    m = 0.5 * p[SA1]
    y2 = ec * x2 + es * (x3 + m * x2)
    y3 = ec * x3 - es * (m * x3 + p[SA0] * x2)
    if abs(v - p[KSPR] * y2 - p[CDMP] * y3) > limit:
        return False, x
    return True, (-lam * y3 / p[KE], motor - lam * y2, y2, y3)


@njit(cache=True)
def _advance_events(p, cf, friction, x, d, v, h, which, series):
    """The state ``x`` of an axis (parameters ``p``) advanced by ``h`` [s] under the
    constant drive ``v`` [V] (applied drive plus load steps) through its friction events
    (stops, breakaways), from the motor's direction ``d`` (+1, -1, 0 stuck); ``which``
    (0 or 1) names the precomputed interval ``h`` is (``cf`` its coefficients), or -1;
    ``series`` (SCRATCH,) scratch. Returns ``(x, d)`` at the interval's end."""
    fixed = which >= 0  # cf holds the coefficients of remaining
    if not friction:
        if fixed:
            return _slide(p, cf, x, v), d
        return _slide_for(p, x, v, h)[1], d
    remaining = h
    for _ in range(MAX_EVENTS):
        if remaining <= 0.0:
            return x, d
        if d == 0.0:
            t, at_end, y = _breakaway_time(p, x, v, remaining, cf, fixed)
            if t < 0.0:
                return (y if at_end else _stuck(p, x, remaining)), d
            if t > 0.0:
                x = _stuck(p, x, t)
            d = 1.0 if _net_drive(p, x, v) > 0.0 else -1.0
            remaining -= t
            fixed = fixed and t == 0.0
            continue
        veff = v - p[FC] * d
        t, at_end, c, y = _stop_time(p, x, veff, remaining, d, cf, fixed, series)
        if t < 0.0:
            if at_end:
                return y, d  # already the state at the interval's end
            if fixed:
                return _slide(p, cf, x, veff), d
            return _slide_for(p, x, veff, remaining)[1], d
        y = _slide(p, c, x, veff)
        # the motor at rest exactly (root's rounding)
        x = (-p[LAM] * y[3] / p[KE], y[1], y[2], y[3])
        net = _net_drive(p, x, v)
        if abs(net) <= p[FS]:
            d = 0.0
            fixed = False  # a stuck motor's checks need CSC, CSS
        else:
            d = 1.0 if net > 0.0 else -1.0
            if fixed:  # the rest's coefficients without a transcendental but one
                cf = _rest_coefficients(p, cf, c, remaining - t)
        remaining -= t
    # MAX_EVENTS reached: the motor is held for the rest of the interval
    x = (-p[LAM] * x[3] / p[KE], x[1], x[2], x[3])
    return _stuck(p, x, remaining), 0.0
