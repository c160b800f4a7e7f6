"""What every interpolator shares: the path as data, the Taylor step, the open-loop driver.

An interpolator is a Python object that holds an immutable *plan* (a NamedTuple of
numbers and arrays) and makes a fresh *state* for every run; its per-sample step is a
compiled function registered with :func:`nurbsmotion.stepping.register` (the contract is
in :mod:`nurbsmotion.stepping`). The object is never changed by a run.

The step itself is the Taylor expansion of order 1 or 2 (eq. 3.2 / 3.1 of Yeh & Sun 2008,
with the tangential-acceleration term of docs/model.md#interpolation). A step that crosses a knot where
the curve loses the continuity the expansion relies on (C1 for first order, C2 for second
order; a sharp corner is one) is integrated piecewise: the expansion restarts at the knot
with the derivatives of the span the step moves into (docs/model.md#interpolation: the one-sided rule),
for the rest of Ts. The step that reaches u = 1 lands on it exactly and reports
``FINISHED``.

Glossary
--------
u : curve parameter; D = C'(u), D2 = C''(u) [path units per unit u^k];
V : commanded feed [path units/s]; A : tangential acceleration dV/dt [path units/s^2];
Ts : sample period [s].
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .. import stepping
from .._kernels import horner
from ..control.step import pid_affine
from ..errors import InvalidArgumentError, InvalidCurveError, InvalidFeedError
from ..nurbs import NurbsCurve
from ..stepping import Status

__all__ = ["Status", "Interpolator", "PathData", "path_data", "path_scratch",
           "taylor_increment", "advance", "land", "finish_step", "path_point", "path_derivatives",
           "speed_bounds", "positive_feed", "check_taylor_starts"]


class PathData(NamedTuple):
    """A NURBS path as the compiled steps read it: the homogeneous curve ``[w*C, w]`` as a
    polynomial on each knot span (:func:`nurbsmotion._kernels.power_basis`), so that a
    point and its derivatives cost one Horner pass per coordinate.

    spans : (m + 1,) the distinct knots, 0 .. 1; coefficients : (m, p + 1, n_axes + 1),
    ``[w*C, w](u) = sum_k coefficients[i, k] * (u - spans[i])**k`` on span i; restarts :
    knots inside (0, 1) where a Taylor step of the interpolator's order is restarted, then
    1.0; end : C(1), shape (n_axes,) [path units]."""

    spans: np.ndarray
    coefficients: np.ndarray
    restarts: np.ndarray
    end: np.ndarray


def path_data(curve: NurbsCurve, order: int) -> PathData:
    """The path of ``curve`` for steps of Taylor order ``order`` (1 or 2)."""
    p = curve.degree
    spans, coefficients = curve.power_form
    # the interior breakpoints where the step restarts: knots of multiplicity at least
    # p - order + 1
    inner = spans[1:-1]
    restarts = np.append(inner[curve.knot_multiplicity(inner) >= p - order + 1], 1.0)
    return PathData(spans, coefficients, restarts,
                    np.ascontiguousarray(curve.end_points[1], dtype=float))


def _zeros(*shape, writeable: bool = True) -> np.ndarray:
    a = np.zeros(shape)
    a.flags.writeable = writeable
    return a


def example_path(n_axes: int) -> PathData:
    """Made-up :class:`PathData` of the types a run passes (zeros; a registered
    interpolator's ``example``, :func:`nurbsmotion.stepping.register`)."""
    f = _zeros
    return PathData(f(2, writeable=False), f(1, 2, n_axes + 1, writeable=False), f(1),
                    f(n_axes, writeable=False))


def example_feed() -> tuple:
    """Made-up feed table (breakpoints, start and end feeds) of the types a run passes."""
    f = _zeros
    return (f(2, writeable=False), f(1, writeable=False), f(1, writeable=False))


def check_taylor_starts(curve: NurbsCurve, path: PathData, name: str) -> None:
    """Refuse a path whose Taylor step would start at a point of zero speed: ``u = 0`` or
    a restart knot where ``C'(u) = 0`` from the right (a repeated control point there).
    The step ``V*T/|C'(u)|`` (eq. 3.1 / 3.2) and the tangent cannot be taken there; it was
    a ZeroDivisionError inside the compiled loop.

    Raises
    ------
    InvalidCurveError
        Naming the parameter and the point.
    """
    starts = np.concatenate([[0.0], path.restarts[:-1]])
    speed = np.linalg.norm(curve(starts, 1), axis=1)
    if np.any(speed == 0.0):
        u = float(starts[int(np.argmax(speed == 0.0))])
        where = "starts" if u == 0.0 else f"restarts its step at u = {u:.6g}"
        raise InvalidCurveError(
            f"the path {where} at a point of zero speed, C'(u) = 0 at {curve(u).tolist()} "
            f"(a repeated control point): {name}'s Taylor step V*T/|C'(u)| cannot leave it; "
            "run it with planned, or remove the repeated control point")


def path_scratch(path: PathData) -> np.ndarray:
    """Scratch for :func:`path_derivatives`: shape (3, n_axes)."""
    return np.empty((3, path.coefficients.shape[2] - 1))


@njit(cache=True, inline="always")
def _span(path, u):
    """The span of ``u``, right-sided (the last one at u = 1), and ``u`` from its start."""
    i = np.searchsorted(path.spans, u, side="right") - 1
    i = min(max(i, 0), path.spans.shape[0] - 2)
    return i, u - path.spans[i]


@njit(cache=True, inline="always")
def path_derivatives(path, u, order, out):
    """``C^(k)(u)`` for k = 0 .. order (right-sided; order <= 2) into ``out`` (3, n_axes);
    returns it. The quotient rule of A4.2 (Piegl & Tiller) on ``[w*C, w]``."""
    i, t = _span(path, u)
    c = path.coefficients[i]
    dim = out.shape[1]
    w, w1, w2 = horner(c, dim, t)
    for a in range(dim):
        A, A1, A2 = horner(c, a, t)
        x = A / w
        out[0, a] = x
        if order >= 1:
            x1 = (A1 - w1 * x) / w
            out[1, a] = x1
            if order >= 2:
                out[2, a] = (A2 - 2.0 * w1 * x1 - w2 * x) / w
    return out


@njit(cache=True, inline="always")
def path_point(path, u, out):
    """``C(u)`` (right-sided) into ``out``, shape (n_axes,)."""
    i, t = _span(path, u)
    c = path.coefficients[i]
    p = c.shape[0] - 1
    dim = out.shape[0]
    w = c[p, dim]
    for k in range(p - 1, -1, -1):
        w = w * t + c[k, dim]
    for a in range(dim):
        x = c[p, a]
        for k in range(p - 1, -1, -1):
            x = x * t + c[k, a]
        out[a] = x / w


@njit(cache=True, inline="always")
def taylor_increment(d, order, V, A, T):
    """Parameter step of the speed-controlled interpolator (eq. 3.1 / 3.2).

    ``du = V*T/|D| + (A/|D| - V^2 <D, D2>/|D|^4) * T^2 / 2`` for order 2 (eq. 3.1 plus the
    tangential-acceleration term A that eq. 3.1 omits, docs/model.md#interpolation; Farouki & Tsai
    2001); ``du = V*T/|D|`` for order 1 (eq. 3.2). Should the second-order term make the
    step non-positive (a step far too long for the local curvature), the first-order step
    is used.

    Parameters
    ----------
    d : ndarray, shape (>= order + 1, n_axes)
        C(u), C'(u), C''(u).
    order : int
    V : float
        Feed [path units/s].
    A : float
        dV/dt [path units/s^2].
    T : float
        The time the step covers [s].
    """
    dim = d.shape[1]
    n2 = 0.0
    for c in range(dim):
        n2 += d[1, c] * d[1, c]
    n1 = math.sqrt(n2)
    first = V * T / n1
    if order == 1:
        return first
    d12 = 0.0
    for c in range(dim):
        d12 += d[1, c] * d[2, c]
    second = 0.5 * (A / n1 - V * V * d12 / (n2 * n2))
    du = first + second * T**2
    return du if du > 0 else first


@njit(cache=True)
def _time_to_reach(target, d, order, V, A, T):
    """Time within ``T`` at which the expansion advances by ``target`` (bisection: the
    expansion is increasing in time on [0, T])."""
    lo = 0.0
    hi = T
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if taylor_increment(d, order, V, A, mid) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(cache=True, inline="always")
def advance(path, order, u0, V, A, Ts, d, fresh):
    """Parameter after one sample from ``u0`` at feed V and tangential acceleration A,
    piecewise across :attr:`PathData.restarts`; ``d`` (3, n_axes) is the scratch of
    :func:`path_derivatives`, ``fresh``: it already holds the derivatives at ``u0``."""
    u = u0
    remaining = Ts
    while True:
        if not fresh:  # one inlined copy of the derivatives for both uses (compile time)
            path_derivatives(path, u, order, d)
        fresh = False
        du = taylor_increment(d, order, V, A, remaining)
        b = path.restarts[np.searchsorted(path.restarts, u, side="right")]
        if u + du <= b or b >= 1.0:
            return u + du
        dt = _time_to_reach(b - u, d, order, V, A, remaining)
        u = b
        V = V + A * dt
        remaining = remaining - dt
        if remaining <= 0.0 or V <= 0.0:
            return u


@njit(cache=True, inline="always")
def land(path, u, command):
    """Finish a step at parameter ``u``: the setpoint C(u) into ``command``, or the end
    point when ``u >= 1``. Returns ``(u, status)`` with u capped at 1."""
    if u >= 1.0:
        for j in range(command.shape[0]):
            command[j] = path.end[j]
        return 1.0, stepping.FINISHED
    path_point(path, u, command)
    return u, stepping.WORKING


@njit(cache=True, inline="always")
def finish_step(path, u0, u_new, command, state):
    """The end of a Taylor-type step from ``u0`` to ``u_new``: ``(u, status)`` with the
    setpoint in ``command`` and ``state.u`` advanced (:func:`land`), or ``FAILED`` with
    nothing changed when the step is not a finite advance."""
    du = u_new - u0
    if not (du > 0 and math.isfinite(du)):
        return u0, stepping.FAILED
    u, status = land(path, u_new, command)
    state.u[0] = u
    return u, status


@njit(cache=True, inline="always")
def speed_bounds(law, law_state, Ke, position, velocity, bounds):
    """The range of speed commands that keeps every drive within Umax, into ``bounds``
    (n_axes, 2) [rad/s]: eq. 3.6 of Yeh & Sun (2008) from the law's affine form
    (:func:`nurbsmotion.control.pid_affine`), ``wd = (thd - thd_prev)/(Ke*Ts)``."""
    Ts = law[0]["period"]
    umax = law[0]["maxoutput"]
    for j in range(position.shape[0]):
        slope, offset = pid_affine(law, law_state, j, position[j], velocity[j])
        ksig = slope * Ke[j] * Ts                       # section 3.2: u = Ksig*wd + v
        v = slope * law_state[j]["prev_cmd"] + offset
        bounds[j, 0] = (-umax - v) / ksig
        bounds[j, 1] = (umax - v) / ksig


def positive_feed(feed) -> float:
    """``feed`` as a float, or :class:`~nurbsmotion.errors.InvalidFeedError` unless it is
    finite and > 0."""
    if isinstance(feed, bool):
        raise InvalidFeedError(f"feed must be a number, got {feed!r}")
    try:
        V = float(feed)
    except (TypeError, ValueError):
        raise InvalidFeedError(f"feed must be a number, got {feed!r}") from None
    if not (math.isfinite(V) and V > 0):
        raise InvalidFeedError(f"feed must be finite and > 0, got {feed!r}")
    return V


class Interpolator:
    """Base class: a plan (immutable data) and a compiled step (:mod:`nurbsmotion.stepping`).

    Subclasses set :attr:`plan` in their constructor, implement :meth:`new_state`, and
    register their step for the plan's type.

    Parameters
    ----------
    curve : NurbsCurve
        The path [path units; pulse when run in the servo loop].
    sample_period : float
        Ts [s], > 0.

    Attributes
    ----------
    name : str
        Label in traces and summaries.
    records_bounds : bool
        The step computes speed bounds (eq. 3.6) worth recording in the trace.
    open_loop : bool
        The step gives a setpoint stream without a servo loop (an interpolator that
        plans the drive through the loop's law has none: ``planned``).
    plan : NamedTuple
        What the step reads; never changed.
    notes : tuple of str
        What the interpolator chose that the user did not ask for exactly (e.g. stops
        where a corner tolerance was given), added to a run's message.
    """

    name = "base"
    records_bounds = False
    open_loop = True
    notes: tuple = ()
    plan: tuple

    def __init__(self, curve: NurbsCurve, sample_period: float):
        if not isinstance(curve, NurbsCurve):
            raise InvalidArgumentError(f"curve must be a NurbsCurve, got {type(curve).__name__}")
        Ts = float(sample_period)
        if not (math.isfinite(Ts) and Ts > 0):
            raise InvalidArgumentError(f"sample_period must be finite and > 0, got {sample_period!r}")
        self.curve = curve
        self.sample_period = Ts

    def new_state(self) -> tuple:
        """A fresh state for one run from the path's start (:mod:`nurbsmotion.stepping`)."""
        raise NotImplementedError

    def nominal_duration(self) -> float | None:
        """The time the move takes at its commanded feed [s], or ``None`` if unknown.

        The loop's safety limit on the number of samples is a multiple of it, so that a
        long slow move runs and a stalled one stops."""
        return None
