"""The plant as it is on a machine: encoder counts, noise, delay, DAC, friction, load steps
and a two-mass resonance, as data for the one compiled loop.

An ideal machine's plant is the rigid axis of docs/model.md#servo-axis, read exactly, driven at
once (:mod:`nurbsmotion.servo`). A machine with any of the keys of issue 32 (see
:class:`nurbsmotion.machine.Machine` and :class:`~nurbsmotion.machine.Axis`) gets a plant
*stage* (:class:`PlantStage`, numbers only) that :func:`nurbsmotion.loop.closed_loop.run_samples`
runs in place of :func:`nurbsmotion.servo.plant_step`. Everything in it is exact, never
sub-stepped:

**Two-mass axis.** The motor (inertia share ``1 - lam``) and the load (``lam``, the
``load_fraction``) are joined by a spring and a damper; the viscous damping is split in
proportion to the inertia, so that the centre-of-mass motion obeys exactly the axis's
``tau*dw/dt = -w + Kc*v``, ``dtheta/dt = Ke*w``, and the relative coordinate
``delta = theta_motor - theta_load`` [pulse] is a decoupled damped oscillator::

    delta'' + 2*zeta*wn*delta' + wn^2*delta = Ke*Kc/((1 - lam)*tau) * v

with ``wn = 2*pi*resonance_frequency`` and ``zeta = resonance_damping`` exactly (the
damper is ``c = mu*(2*zeta*wn - 1/tau)``, ``mu = lam*(1 - lam)*tau``, which needs
``zeta >= 1/(2*wn*tau)``). The state per axis is ``x = [w_cm, theta_cm, delta, delta']``;
the motor is at ``theta_cm + lam*delta``, the load (the tool) at
``theta_cm - (1 - lam)*delta``. A rigid axis has ``delta = 0``. Both blocks have closed
forms for any interval (:func:`_coefficients`); those of the two fixed intervals of a
sample are computed once.

**Delay.** The drive of sample k reaches the plant ``delay`` later:
``delay = n*Ts + h1``, so over ``[k*Ts, k*Ts + h1)`` the plant sees the drive of sample
``k - n - 1`` and over ``[k*Ts + h1, (k+1)*Ts)`` that of sample ``k - n`` (0 before the
start). Each of the two intervals is advanced exactly.

**Friction** acts on the motor (bearing, screw and guide friction reflected to it), as an
equivalent drive: sliding, ``v = u + d - coulomb*sign(w_motor)``; at rest, the motor
stays at rest while the net drive on it (drive, load step, spring and damper) is within
``max(stiction, coulomb)`` [V]. Between events the motion is the exact linear solution;
the instant the motor speed reaches zero inside an interval is found in closed form on a
rigid axis and by a safeguarded root find (Illinois regula falsi on the exact solution,
bracketed by checks every eighth of the mode's period) on a two-mass one; the breakaway of
a stuck two-mass motor (whose load still swings on the spring) likewise.

**Load steps** (``[[axes.disturbance]]``) add their drive from their instant ``at`` on,
splitting the interval they fall in.

**Measurement.** The controller reads the encoder's mass (motor or load): its position
plus seeded Gaussian noise (a counter-based generator: the draw of sample k, axis j
depends on ``seed``, k and j only) and, with ``encoder = "counts"``, in whole counts
zeroed at the start, ``start + floor(theta - start)``; its speed is differenced from
those readings (or, with ``speed_measurement = "true"``, the encoder mass's true speed).

**DAC.** The clipped drive is quantised to ``dac_bits`` over ``[-Umax, Umax)``: step
``q = 2*Umax/2**dac_bits``, levels ``q*i`` with ``-2**(bits-1) <= i < 2**(bits-1)``,
rounded to the nearest.

Glossary
--------
tau [s], Kc [(rad/s)/V], Ke [pulse/rad] : the axis (docs/model.md#servo-axis); lam : load fraction;
wn [rad/s], zeta : the mode; v : net drive [V]; h : an interval [s]; Ts : sample period.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.extending import overload

from .errors import InvalidMachineError

__all__ = ["oscillator", "PlantStage", "IdleStage", "is_active", "PlantState", "make_stage", "inactive_stage",
           "new_plant_state",
           "linear_loop_poles", "continuous_model", "stage_response", "stage_arrays"]

# Columns of PlantStage.param
TAU, KC, KE, LAM, SIG, W2, GAIN, SA1, SA0, KSPR, CDMP, FC, FS, ENC, TOOL, CHECK_SLIDE, \
    CHECK_STUCK, N_PARAM = range(18)
# Columns of the coefficients of one interval
CA, CKT, CB0, CB1, CEC, CES, CSC, CSS, N_COEF = range(9)
# (CSC, CSS: the stuck motor's load oscillator, ``oscillator(SA1, SA0, h)``, set by
# :func:`make_stage` for the two fixed intervals only)

MAX_EVENTS = 64
"""Friction events (stops, breakaways) one interval may hold at most: beyond, the motor is
taken as stuck for the rest of it (a guard against a chattering degenerate case)."""


class PlantStage(NamedTuple):
    """The true plant's effects, as numbers (see the module docstring).

    active : bool -- False for an ideal plant (the loop uses ``servo.plant_step``);
    counts : bool -- the position is read in whole counts;
    noise : float -- measurement noise, standard deviation [pulse];
    seed : int -- its seed;
    dac_step : float -- the DAC's step q [V] (0: none);
    dac_levels : float -- ``2**(dac_bits - 1)``;
    delay_samples : int -- n, whole samples of delay;
    split : float -- h1, the rest of the delay [s] (0: none);
    sample_period : float -- Ts [s];
    param : ndarray, shape (n_axes, N_PARAM) -- per axis, columns TAU ... CHECK_STUCK;
    friction : ndarray, shape (n_axes,), bool -- the axis has friction;
    two_mass : ndarray, shape (n_axes,), bool;
    coef : ndarray, shape (n_axes, 2, N_COEF) -- sliding (and stuck: CSC, CSS)
    coefficients of h1 and Ts - h1;
    disturbance_time : ndarray, shape (n_axes, m + 1) -- load step instants [s], sorted,
    then inf; disturbance_drive : same shape -- the summed load drive from each on [V].
    """

    active: bool
    counts: bool
    noise: float
    seed: int
    dac_step: float
    dac_levels: float
    delay_samples: int
    split: float
    sample_period: float
    param: np.ndarray
    friction: np.ndarray
    two_mass: np.ndarray
    coef: np.ndarray
    disturbance_time: np.ndarray
    disturbance_drive: np.ndarray


class PlantState(NamedTuple):
    """The plant stage's state, per axis: ``x`` (n_axes, 4) = [w_cm, theta_cm, delta,
    delta'], ``direction`` (n_axes,) float: the sliding direction of the motor (+1, -1)
    or 0 stuck; ``line`` (n_axes, n + 2): the drives on their way (ring buffer by
    sample); ``next_disturbance`` (n_axes,) int64: the next load step's index;
    ``origin`` (n_axes,): where the run started [pulse] (the counts' zero); and scratch:
    ``tool`` (n_axes,), ``scratch`` (SCRATCH,)."""

    x: np.ndarray
    direction: np.ndarray
    line: np.ndarray
    next_disturbance: np.ndarray
    origin: np.ndarray
    tool: np.ndarray
    scratch: np.ndarray


IdleStage = NamedTuple("IdleStage", list(PlantStage.__annotations__.items()))
IdleStage.__doc__ = """An ideal plant's stage: the fields of :class:`PlantStage`, never run.
A type of its own, so that the compiled loop knows at compile time that it has no plant
stage (:func:`is_active`) and an ideal run's loop is the one it was before the stage."""


def is_active(stage) -> bool:
    """Whether the loop runs the stage (a constant of the stage's type when compiled)."""
    return bool(stage.active)


@overload(is_active, inline="always", jit_options={"cache": True})
def _is_active_overload(stage):
    from numba.core import types

    if not isinstance(stage, types.BaseNamedTuple):
        return None
    value = stage.instance_class is not IdleStage

    def impl(stage):
        return value
    return impl


def x_minus_one_minus_exp(x: float) -> float:
    """``x - (1 - exp(-x))`` for x > 0, accurate to rounding: the series
    ``sum_{n>=2} (-1)^n x^n / n!`` below 0.5 (where the difference cancels), else direct."""
    if x >= 0.5:
        return x + math.expm1(-x)
    term = x * x / 2.0
    total = 0.0
    n = 2
    while abs(term) > 1e-17 * x * x:
        total += term
        n += 1
        term *= -x / n
    return total


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


@njit(cache=True)
def sample_step(P, C, F, DT, DD, dac_step, dac_levels, delay_samples, split, Ts, X, D, LINE,
                ND, k, drive, row, series):
    """Every axis over sample k: the DAC on its drive ``drive[row, j]`` [V] (clipped),
    the delay line, the load steps, and each interval of constant drive advanced exactly:
    by the precomputed coefficients when the axis has no friction or no friction event
    in it (:func:`_friction_quiet`), else by :func:`_advance_events`. The arguments
    before ``k`` are :func:`stage_arrays` (the stage's and its state's arrays and
    numbers); ``series`` (SCRATCH,) scratch.

    One call per sample for all axes, not inlined, and the axes' numbers go to the
    functions it calls as tuples: an array handed to a compiled function (inlined or
    not) costs an atomic reference count at the call and at the return, which here
    would cost more than the plant's arithmetic."""
    length = LINE.shape[1]  # delay_samples + 2: one wrap of an index suffices
    now = k % length  # one division per sample (an integer division costs tens of cycles)
    i_new = now - delay_samples
    if i_new < 0:
        i_new += length
    i_old = i_new - 1
    if i_old < 0:
        i_old += length
    t0 = k * Ts
    q = dac_step
    for j in range(X.shape[0]):
        applied = drive[row, j]
        if q > 0.0:
            level = math.floor(applied / q + 0.5)
            level = min(max(level, -dac_levels), dac_levels - 1.0)
            applied = level * q
        LINE[j, now] = applied
        new = LINE[j, i_new]
        old = LINE[j, i_old]
        p = _params(P, j)
        x = (X[j, 0], X[j, 1], X[j, 2], X[j, 3])
        d = D[j]
        friction = F[j]
        t = 0.0
        while t < Ts:
            if t < split:
                seg_start, seg_end, seg_which, u = 0.0, split, 0, old
            else:
                seg_start, seg_end, u = split, Ts, new
                seg_which = 1 if split > 0.0 else 0
            i = ND[j]
            at = DT[j, i] - t0
            if at <= t:  # a load step due now (or, by rounding, a hair before)
                ND[j] = i + 1
                continue
            load = DD[j, i - 1] if i > 0 else 0.0
            end = min(seg_end, at)
            which = seg_which if (t == seg_start and end == seg_end) else -1
            v = u + load
            h = end - t
            if which >= 0:
                cf = _coefficient_row(C, j, which)
                if not friction:  # the common case
                    x = _slide(p, cf, x, v)
                else:
                    quiet, x = _friction_quiet(p, cf, x, d, v, h)
                    if not quiet:
                        x, d = _advance_events(p, cf, friction, x, d, v, h, which, series)
            else:
                x, d = _advance_events(p, NO_COEFFICIENTS, friction, x, d, v, h, which,
                                       series)
            t = end
        X[j, 0] = x[0]
        X[j, 1] = x[1]
        X[j, 2] = x[2]
        X[j, 3] = x[3]
        D[j] = d


def stage_arrays(stage: "PlantStage", pstate: "PlantState") -> tuple:
    """The first arguments of :func:`sample_step`, from a stage and its state."""
    return (stage.param, stage.coef, stage.friction, stage.disturbance_time,
            stage.disturbance_drive, stage.dac_step, stage.dac_levels,
            stage.delay_samples, stage.split, stage.sample_period, pstate.x,
            pstate.direction, pstate.line, pstate.next_disturbance)


@njit(cache=True, inline="always")
def _mix(z):
    """splitmix64's finaliser."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def noise_draw(seed, k, j):
    """A standard normal draw for sample k, axis j (Box-Muller on two splitmix64 words)."""
    base = (np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15)
            + np.uint64(k) * np.uint64(64) + np.uint64(2 * j))
    a = _mix(base + np.uint64(1))
    b = _mix(base + np.uint64(2))
    u1 = ((a >> np.uint64(11)) + np.uint64(1)) * (1.0 / 9007199254740993.0)
    u2 = (b >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@njit(cache=True, inline="always")
def positions(P, X, j):
    """``(tool, encoder, encoder_speed)`` of axis j (``P``, ``X``: the stage's ``param``
    and the state's ``x``): the load's and the encoder mass's true positions [pulse] and
    the encoder mass's speed [rad/s]."""
    tool = X[j, 1] + P[j, TOOL] * X[j, 2]
    enc = X[j, 1] + P[j, ENC] * X[j, 2]
    return tool, enc, X[j, 0] + P[j, ENC] * X[j, 3] / P[j, KE]


@njit(cache=True, inline="always")
def measure(noise, seed, counts, true_position, start, k, j):
    """What the controller reads of a true position [pulse] at sample k, axis j: with
    Gaussian noise of standard deviation ``noise`` [pulse] (seeded by ``seed``), in whole
    counts from ``start`` [pulse] if ``counts``."""
    m = true_position
    if noise > 0.0:
        m = m + noise * noise_draw(seed, k, j)
    if counts:
        m = start + math.floor(m - start)
    return m


def inactive_stage(n_axes: int) -> PlantStage:
    """The stage of an ideal plant (same types, never run)."""
    z = np.zeros((n_axes, N_PARAM))
    z[:, TAU] = z[:, KC] = z[:, KE] = 1.0
    arrays = (z, np.zeros(n_axes, np.bool_), np.zeros(n_axes, np.bool_),
              np.zeros((n_axes, 2, N_COEF)), np.full((n_axes, 1), np.inf),
              np.zeros((n_axes, 1)))
    for arr in arrays:  # read-only as a made stage's
        arr.flags.writeable = False
    return IdleStage(False, False, 0.0, 0, 0.0, 1.0, 0, 0.0, 1.0, *arrays)


def _mode(tau: float, lam: float, frequency: float, damping: float):
    """``(sig, w2, c)``: the mode's decay rate zeta*wn [1/s], wn^2 [1/s^2] and the
    damper ``c = mu*(2*zeta*wn - 1/tau)`` (normalised so that viscous damping is 1)."""
    wn = 2.0 * math.pi * frequency
    mu = lam * (1.0 - lam) * tau
    return damping * wn, wn * wn, mu * (2.0 * damping * wn - 1.0 / tau), mu


def make_stage(effects, tau, Kc, Ke, max_drive: float, sample_period: float) -> PlantStage:
    """The :class:`PlantStage` of a plant with ``effects`` (a
    :class:`nurbsmotion.machine.Machine`'s effect keys: ``machine.effects()``), per-axis
    tau [s], Kc [(rad/s)/V], Ke [pulse/rad], the drive limit [V] and Ts [s]."""
    n = len(tau)
    Ts = float(sample_period)
    param = np.zeros((n, N_PARAM))
    friction = np.zeros(n, np.bool_)
    two = np.zeros(n, np.bool_)
    m = max([len(a["disturbance"]) for a in effects["axes"]] + [0])
    dist_t = np.full((n, m + 1), np.inf)
    dist_d = np.zeros((n, m + 1))
    for j, a in enumerate(effects["axes"]):
        p = param[j]
        p[TAU], p[KC], p[KE] = tau[j], Kc[j], Ke[j]
        if a["resonance_frequency"] > 0:
            lam = a["load_fraction"]
            sig, w2, c, mu = _mode(tau[j], lam, a["resonance_frequency"],
                                   a["resonance_damping"])
            p[LAM], p[SIG], p[W2] = lam, sig, w2
            p[GAIN] = Ke[j] * Kc[j] / ((1.0 - lam) * tau[j])
            p[SA1] = 1.0 / tau[j] + c / (lam * tau[j])
            p[SA0] = w2 * (1.0 - lam)
            p[KSPR] = w2 * mu / (Ke[j] * Kc[j])
            p[CDMP] = c / (Ke[j] * Kc[j])
            p[TOOL] = -(1.0 - lam)
            p[ENC] = lam if a["encoder_on"] == "motor" else -(1.0 - lam)
            two[j] = True
            p[CHECK_SLIDE] = 2.0 * math.pi / math.sqrt(w2) / 8.0
            p[CHECK_STUCK] = 2.0 * math.pi / math.sqrt(p[SA0]) / 8.0
        else:
            p[CHECK_SLIDE] = p[CHECK_STUCK] = math.inf
        p[FC] = a["coulomb_friction"]
        p[FS] = max(a["stiction"], a["coulomb_friction"])
        friction[j] = p[FS] > 0.0
        steps = sorted((d["at"], d["drive"]) for d in a["disturbance"])
        total = 0.0
        for i, (at, drive) in enumerate(steps):
            total += drive
            dist_t[j, i] = at
            dist_d[j, i] = total
    delay = float(effects["delay"])
    whole = int(math.floor(delay / Ts))
    split = delay - whole * Ts
    if split <= 1e-12 * Ts:
        split = 0.0
    elif split >= Ts * (1.0 - 1e-12):
        whole, split = whole + 1, 0.0
    coef = np.zeros((n, 2, N_COEF))
    for j in range(n):
        intervals = (split, Ts - split) if split > 0.0 else (Ts,)
        for i, h in enumerate(intervals):
            coef[j, i] = _coefficients(param[j], h)
            if two[j]:
                coef[j, i, CSC], coef[j, i, CSS] = oscillator(param[j, SA1], param[j, SA0], h)
    bits = effects["dac_bits"]
    if bits is not None and not math.isfinite(max_drive):
        raise InvalidMachineError(f"dac_bits = {bits} needs a finite max_drive, got "
                                  f"{max_drive!r}")
    dac_step = 0.0 if bits is None else 2.0 * max_drive / 2.0 ** bits
    levels = 1.0 if bits is None else 2.0 ** (bits - 1)
    for arr in (param, friction, two, coef, dist_t, dist_d):
        arr.flags.writeable = False
    return PlantStage(True, effects["encoder"] == "counts",
                      float(effects["measurement_noise"]), int(effects["seed"]),
                      dac_step, levels, whole, split, Ts, param,
                      friction, two, coef, dist_t, dist_d)


_IDLE_STATES: dict = {}


def new_plant_state(stage: PlantStage, position) -> PlantState:
    """The stage at rest at ``position`` [pulse] (shape (n_axes,)); a motor with friction
    starts stuck. An inactive stage's state is never read or written: one per number of
    axes is shared (an ideal run makes none)."""
    n = len(position)
    if not stage.active:
        if n not in _IDLE_STATES:
            _IDLE_STATES[n] = new_plant_state(PlantStage(*stage)._replace(active=True),
                                              np.zeros(n))
        return _IDLE_STATES[n]
    x = np.zeros((n, 4))
    x[:, 1] = position
    direction = np.where(stage.friction, 0.0, 1.0)
    return PlantState(x, direction, np.zeros((n, stage.delay_samples + 2)),
                      np.zeros(n, np.int64), np.array(position, dtype=float),
                      np.zeros(n), np.zeros(SCRATCH))


def stage_response(stage: PlantStage, drive, position=None):
    """Run the stage open loop under a drive sequence (tests, studies).

    Parameters
    ----------
    drive : ndarray, shape (n_samples, n_axes)
        Applied drive per sample [V] (before the DAC and the delay).
    position : array_like, shape (n_axes,), optional
        Start at rest [pulse]; 0 by default.

    Returns
    -------
    x : ndarray, shape (n_samples + 1, n_axes, 4)
        The state ``[w_cm, theta_cm, delta, delta']`` at every sample instant.
    tool : ndarray, shape (n_samples + 1, n_axes)
        The load's (the tool's) position [pulse].
    """
    drive = np.asarray(drive, dtype=float)
    n_axes = stage.param.shape[0]
    start = np.zeros(n_axes) if position is None else np.asarray(position, float)
    pstate = new_plant_state(stage, start)
    xs = np.empty((drive.shape[0] + 1, n_axes, 4))
    xs[0] = pstate.x
    args = stage_arrays(stage, pstate)
    for k in range(drive.shape[0]):
        sample_step(*args, k, drive, k, pstate.scratch)
        xs[k + 1] = pstate.x
    tool = xs[:, :, 1] + stage.param[:, TOOL] * xs[:, :, 2]
    return xs, tool


def continuous_model(tau: float, Kc: float, Ke: float, resonance_frequency: float = 0.0,
                     resonance_damping: float = 0.0, load_fraction: float = 0.5):
    """The axis's linear continuous model in physical coordinates
    ``[w_motor, theta_motor, w_load, theta_load]`` (speeds [rad/s], positions [pulse]):
    ``(A, B)``, shapes (4, 4) and (4,), input the drive [V]. A rigid axis is two equal
    halves locked together (returned as the 2-state ``[w, theta]``)."""
    if resonance_frequency <= 0:
        return (np.array([[-1.0 / tau, 0.0], [Ke, 0.0]]), np.array([Kc / tau, 0.0]))
    lam = load_fraction
    sig, w2, c, mu = _mode(tau, lam, resonance_frequency, resonance_damping)
    k = w2 * mu
    Jm, Jl = (1.0 - lam) * tau, lam * tau
    bm, bl = 1.0 - lam, lam
    # spring on the angle difference [rad] = (theta_m - theta_l)/Ke
    A = np.array([[-(bm + c) / Jm, -k / (Ke * Jm), c / Jm, k / (Ke * Jm)],
                  [Ke, 0.0, 0.0, 0.0],
                  [c / Jl, k / (Ke * Jl), -(bl + c) / Jl, -k / (Ke * Jl)],
                  [0.0, 0.0, Ke, 0.0]])
    B = np.array([Kc / Jm, 0.0, 0.0, 0.0])
    return A, B


def linear_loop_poles(gains, tau: float, Kc: float, Ke: float, sample_period: float,
                      feedback_deriv: bool, delay: float = 0.0,
                      resonance_frequency: float = 0.0, resonance_damping: float = 0.0,
                      load_fraction: float = 0.5, encoder_on: str = "motor") -> np.ndarray:
    """Poles of one axis's closed loop, linear (no clamps, friction or quantisers), with
    its delay and its mode: the sampled plant over the two intervals of a sample
    (``scipy.linalg.expm`` of the augmented matrix), the drives on their way as states,
    and the law of :func:`nurbsmotion.control.loop_poles`.

    Returns
    -------
    ndarray, complex
    """
    from scipy.linalg import expm

    A, B = continuous_model(tau, Kc, Ke, resonance_frequency, resonance_damping,
                            load_fraction)
    nx = A.shape[0]
    pos = np.zeros(nx)
    spd = np.zeros(nx)
    if nx == 2 or encoder_on == "motor":
        pos[1], spd[0] = 1.0, Ke
    else:
        pos[3], spd[2] = 1.0, Ke
    Ts = float(sample_period)
    whole = int(math.floor(delay / Ts))
    split = delay - whole * Ts
    if split <= 1e-12 * Ts:
        split = 0.0
    elif split >= Ts * (1.0 - 1e-12):
        whole, split = whole + 1, 0.0

    def zoh(h):
        M = np.zeros((nx + 1, nx + 1))
        M[:nx, :nx], M[:nx, nx] = A, B
        E = expm(M * h)
        return E[:nx, :nx], E[:nx, nx]

    P1, G1 = zoh(split) if split > 0 else (np.eye(nx), np.zeros(nx))
    P2, G2 = zoh(Ts - split)
    P, I, D = gains.Pgain, gains.Igain, gains.Dgain
    nd = whole + 1  # d_1 .. d_{n+1}: drives of samples k-1 .. k-n-1
    # state z = [x (nx), y_prev, errorI, d_1 .. d_nd]
    nz = nx + 2 + nd
    law = np.zeros(nz)
    if feedback_deriv:
        law[:nx] = -D * spd - (P + I * Ts) * pos
    else:
        law[:nx] = -(P + I * Ts + D / Ts) * pos
        law[nx] = D / Ts
    law[nx + 1] = I

    def drive_of(m):  # the row giving u[k - m]
        row = np.zeros(nz)
        if m == 0:
            row[:] = law
        else:
            row[nx + 1 + m] = 1.0
        return row

    T = np.zeros((nz, nz))
    T[:nx, :nx] = P2 @ P1
    T[:nx] += np.outer(P2 @ G1, drive_of(whole + 1)) + np.outer(G2, drive_of(whole))
    T[nx, :nx] = pos
    T[nx + 1, :nx] = -Ts * pos
    T[nx + 1, nx + 1] = 1.0
    T[nx + 2] = law
    for i in range(1, nd):
        T[nx + 2 + i, nx + 1 + i] = 1.0
    keep = list(range(nx))
    if not feedback_deriv:
        keep.append(nx)
    if I != 0.0:
        keep.append(nx + 1)
    keep += list(range(nx + 2, nz))
    return np.linalg.eigvals(T[np.ix_(keep, keep)])
