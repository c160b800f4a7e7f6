"""The axis of the plant stage, rigid or two-mass, advanced exactly over an interval
of constant drive: the stage's parameter and coefficient columns, the closed forms of
both blocks (:func:`oscillator`, :func:`_coefficients`), sliding and stuck motion, the
motor's speed and acceleration, and the coefficients of an interval's rest after a
stop (the model: :mod:`nurbsmotion.plant`).

Glossary
--------
See :mod:`nurbsmotion.plant`.
"""

from __future__ import annotations

import math

from numba import njit

from .linear import x_minus_one_minus_exp

__all__ = ["oscillator", "x_minus_one_minus_exp", "N_PARAM", "N_COEF"]

# Columns of PlantStage.param
TAU, KC, KE, LAM, SIG, W2, GAIN, SA1, SA0, KSPR, CDMP, FC, FS, ENC, TOOL, CHECK_SLIDE, \
    CHECK_STUCK, N_PARAM = range(18)
# Columns of the coefficients of one interval
CA, CKT, CB0, CB1, CEC, CES, CSC, CSS, N_COEF = range(9)
# (CSC, CSS: the stuck motor's load oscillator, ``oscillator(SA1, SA0, h)``, set by
# :func:`make_stage` for the two fixed intervals only)


_x_minus_g = njit(cache=True)(x_minus_one_minus_exp)
""":func:`x_minus_one_minus_exp` compiled, for the plant stage
(:func:`nurbsmotion.servo.zoh_matrices` calls the Python one)."""


@njit(cache=True)
def oscillator(a1, a0, h):
    """``exp(-m h)*C`` and ``exp(-m h)*S`` of ``y'' + a1 y' + a0 y = 0`` over ``h``:
    ``y(h) = eC*y0 + eS*(y0' + m*y0)``, ``y'(h) = eC*y0' - eS*(m*y0' + a0*y0)``,
    ``m = a1/2``, for any sign of ``m^2 - a0``."""
    m = 0.5 * a1
    q2 = m * m - a0
    e = math.exp(-m * h)
    if q2 < 0.0:
        wd = math.sqrt(-q2)
        return e * math.cos(wd * h), e * math.sin(wd * h) / wd
    if q2 > 0.0:
        q = math.sqrt(q2)
        return e * math.cosh(q * h), e * math.sinh(q * h) / q
    return e, e * h


@njit(cache=True)
def _coefficients(p, h):
    """The sliding coefficients of one axis (its parameters ``p``: a ``param`` row or
    :func:`_params`) over ``h`` [s]: a tuple indexed CA ... CSS (CSC, CSS: 0)."""
    x = h / p[TAU]
    g = -math.expm1(-x)
    if p[W2] > 0.0:
        ec, es = oscillator(2.0 * p[SIG], p[W2], h)
    else:
        ec = 0.0
        es = 0.0
    return (1.0 - g, p[KE] * p[TAU] * g, p[KC] * g,
            p[KE] * p[KC] * p[TAU] * _x_minus_g(x), ec, es, 0.0, 0.0)


NO_COEFFICIENTS = (0.0,) * N_COEF
"""A coefficient tuple never read (where the type needs one)."""


@njit(cache=True, inline="always")
def _params(P, j):
    """Axis ``j``'s row of the stage's ``param``, as a tuple: the event functions below
    take numbers and tuples, never arrays (an array passed to a compiled function costs
    an atomic reference count at the call and at the return)."""
    return (P[j, 0], P[j, 1], P[j, 2], P[j, 3], P[j, 4], P[j, 5], P[j, 6], P[j, 7],
            P[j, 8], P[j, 9], P[j, 10], P[j, 11], P[j, 12], P[j, 13], P[j, 14], P[j, 15],
            P[j, 16])


@njit(cache=True, inline="always")
def _coefficient_row(C, j, which):
    """The precomputed coefficients ``C[j, which]``, as a tuple."""
    return (C[j, which, 0], C[j, which, 1], C[j, which, 2], C[j, which, 3],
            C[j, which, 4], C[j, which, 5], C[j, which, 6], C[j, which, 7])


@njit(cache=True, inline="always")
def _slide(p, c, x, v):
    """The sliding state one interval (coefficients ``c``) after ``x`` under the
    constant net drive ``v`` [V]."""
    y0 = c[CA] * x[0] + c[CB0] * v
    y1 = x[1] + c[CKT] * x[0] + c[CB1] * v
    if p[W2] > 0.0:
        m = p[SIG]
        z0 = x[2] - p[GAIN] * v / p[W2]
        y2 = c[CEC] * z0 + c[CES] * (x[3] + m * z0) + p[GAIN] * v / p[W2]
        y3 = c[CEC] * x[3] - c[CES] * (m * x[3] + p[W2] * z0)
    else:
        y2 = 0.0
        y3 = 0.0
    return (y0, y1, y2, y3)


@njit(cache=True)
def _stuck(p, x, h):
    """The state ``h`` [s] after ``x`` with the motor held at rest (a two-mass load
    swings on the spring about it; a rigid axis does not move)."""
    ec, es = oscillator(p[SA1], p[SA0], h) if p[W2] > 0.0 else (0.0, 0.0)
    return _stuck_with(p, x, ec, es)


@njit(cache=True, inline="always")
def _stuck_with(p, x, ec, es):
    """:func:`_stuck` of a two-mass axis given the load oscillator's ``ec``, ``es`` of
    the interval (precomputed for the two fixed intervals of a sample)."""
    if p[W2] > 0.0:
        lam = p[LAM]
        motor = x[1] + lam * x[2]
        m = 0.5 * p[SA1]
        y2 = ec * x[2] + es * (x[3] + m * x[2])
        y3 = ec * x[3] - es * (m * x[3] + p[SA0] * x[2])
        return (-lam * y3 / p[KE], motor - lam * y2, y2, y3)
    return (0.0, x[1], 0.0, 0.0)


@njit(cache=True, inline="always")
def _motor_speed(p, x):
    """The motor's speed [rad/s]."""
    return x[0] + p[LAM] * x[3] / p[KE]


@njit(cache=True, inline="always")
def _net_drive(p, x, v):
    """The drive on the motor but for friction [V]: ``v`` less spring and damper."""
    return v - p[KSPR] * x[2] - p[CDMP] * x[3]


@njit(cache=True)
def _slide_for(p, x, v, h):
    """``(c, y)``: the coefficients of ``h`` [s] and :func:`_slide` over it."""
    c = _coefficients(p, h)
    return c, _slide(p, c, x, v)


@njit(cache=True, inline="always")
def _motor_accel(p, x, v):
    """The sliding motor's acceleration [rad/s^2] in the state ``x`` of a two-mass axis
    under the constant net drive ``v`` [V]: ``w_cm' = (Kc*v - w_cm)/tau`` plus ``lam/Ke``
    times ``delta'' = -2*zeta*wn*delta' - wn^2*(delta - GAIN*v/wn^2)`` (the module
    docstring's equations). No transcendental: the derivative of the root find's
    function comes free with the function."""
    wdot = (p[KC] * v - x[0]) / p[TAU]
    z = x[2] - p[GAIN] * v / p[W2]
    ddot = -2.0 * p[SIG] * x[3] - p[W2] * z
    return wdot + p[LAM] * ddot / p[KE]


@njit(cache=True, inline="always")
def _speed_accel_after(p, x, v, h):
    """The sliding motor's speed [rad/s] and acceleration [rad/s^2] ``h`` [s] after
    ``x`` under the constant net drive ``v`` [V] of a two-mass axis, and the sliding
    coefficients of ``h`` but ``CB1`` (:func:`_complete_coefficients` adds it): the
    operations of :func:`_coefficients`, :func:`_slide` and :func:`_motor_speed` on the
    same numbers (so the same bits), without the positions'."""
    g = -math.expm1(-(h / p[TAU]))
    ca = 1.0 - g
    cb0 = p[KC] * g
    ec, es = oscillator(2.0 * p[SIG], p[W2], h)
    w = ca * x[0] + cb0 * v
    m = p[SIG]
    ys = p[GAIN] * v / p[W2]
    z0 = x[2] - ys
    z = ec * z0 + es * (x[3] + m * z0)
    d = ec * x[3] - es * (m * x[3] + p[W2] * z0)
    speed = w + p[LAM] * d / p[KE]
    accel = (p[KC] * v - w) / p[TAU] + p[LAM] * (-2.0 * m * d - p[W2] * z) / p[KE]
    return speed, accel, (ca, p[KE] * p[TAU] * g, cb0, 0.0, ec, es, 0.0, 0.0)


@njit(cache=True, inline="always")
def _complete_coefficients(p, h, c):
    """The coefficients :func:`_speed_accel_after` gave for ``h`` [s], with ``CB1``
    (the position's series: no transcendental below x = 0.5)."""
    return (c[CA], c[CKT], c[CB0], p[KE] * p[KC] * p[TAU] * _x_minus_g(h / p[TAU]),
            c[CEC], c[CES], c[CSC], c[CSS])


@njit(cache=True)
def _rest_coefficients(p, ch, ct, r):
    """The sliding coefficients of ``r = h - t`` [s] from those of ``h`` (``ch``) and of
    ``t`` (``ct``): the interval's rest after a stop. The first-order block by its own
    formulas (one ``expm1``); the mode's ``exp(-m r)*C`` and ``exp(-m r)*S`` by the
    angle-difference formulas (no transcendental): with ``E = ec_t^2 + wd^2*es_t^2 =
    exp(-2*m*t)`` (``wd^2 = wn^2 - m^2``, of either sign), ``ec_r = (ec_h*ec_t +
    wd^2*es_h*es_t)/E``, ``es_r = (es_h*ec_t - ec_h*es_t)/E``. Not the stuck
    coefficients (CSC, CSS: 0)."""
    x = r / p[TAU]
    g = -math.expm1(-x)
    if p[W2] > 0.0:
        wd2 = p[W2] - p[SIG] * p[SIG]
        ec_h, es_h, ec_t, es_t = ch[CEC], ch[CES], ct[CEC], ct[CES]
        e2 = ec_t * ec_t + wd2 * es_t * es_t
        ec = (ec_h * ec_t + wd2 * es_h * es_t) / e2
        es = (es_h * ec_t - ec_h * es_t) / e2
    else:
        ec = 0.0
        es = 0.0
    return (1.0 - g, p[KE] * p[TAU] * g, p[KC] * g,
            p[KE] * p[KC] * p[TAU] * _x_minus_g(x), ec, es, 0.0, 0.0)
