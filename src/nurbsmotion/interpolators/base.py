"""The stepper interface every interpolator implements, and the open-loop driver.

An interpolator is a stepper, as in ruckig: :meth:`Interpolator.step` is called once per
sample with the measured :class:`LoopState` (or ``None`` when run open loop) and returns the
next :class:`Setpoint` with an explicit :class:`Status`. Sample 0 is the path's start, at
rest; step k (k >= 1) produces the setpoint thd[k]. The step that reaches ``u = 1`` lands
on it exactly and reports ``FINISHED``; later steps hold the end point.

Glossary
--------
u : curve parameter; D = C'(u), D2 = C''(u) [path units per unit u^k];
V : commanded feed [path units/s]; A : tangential acceleration dV/dt [path units/s^2];
Ts : sample period [s].
"""

from __future__ import annotations

import enum
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Callable, Union

import numpy as np

from ..errors import InfeasibleError
from ..nurbs import NurbsCurve

__all__ = ["Status", "LoopState", "Setpoint", "Interpolator", "SetpointSeries",
           "Feed", "taylor_increment", "interpolate"]

Feed = Union[float, Callable[[float], float]]
"""A commanded feed: a constant, or a function of the curve parameter u [path units/s]."""


class Status(enum.Enum):
    """What a step did."""

    WORKING = "working"
    """Moved along the path; the end is not reached yet."""
    FINISHED = "finished"
    """The setpoint is at the path's end (reached at this step or before)."""


@dataclass(frozen=True)
class LoopState:
    """What the loop measured at sample k, before the interpolator picks thd[k].

    Attributes
    ----------
    k : int
        Sample index.
    position_command_prev : ndarray, shape (n_axes,)
        thd[k-1] [pulse].
    speed_command_prev : ndarray, shape (n_axes,)
        wd[k-1] [rad/s].
    position : ndarray, shape (n_axes,)
        tha[k], measured [pulse].
    speed : ndarray, shape (n_axes,)
        wa[k], measured [rad/s].
    """

    k: int
    position_command_prev: np.ndarray
    speed_command_prev: np.ndarray
    position: np.ndarray
    speed: np.ndarray


@dataclass(frozen=True)
class Setpoint:
    """One interpolator output.

    Attributes
    ----------
    u : float
        Curve parameter of the setpoint.
    position : ndarray, shape (n_axes,)
        C(u) [path units].
    feed : float
        The feed V this step asked for [path units/s] (0 while holding the end).
    status : Status
    speed_bounds : ndarray, shape (n_axes, 2), optional
        ``[wmin, wmax]`` per axis [rad/s] where the interpolator computes them (eq. 3.6).
    """

    u: float
    position: np.ndarray
    feed: float
    status: Status
    speed_bounds: np.ndarray | None = None


def _feed_function(feed: Feed) -> Callable[[float], tuple[float, float]]:
    """``feed(u) -> (V, dV/du)``, checking that V is finite and > 0."""
    if callable(feed):
        def f(u: float) -> tuple[float, float]:
            V = float(feed(u))
            if not (math.isfinite(V) and V > 0):
                raise InfeasibleError(f"the feed function returned {V!r} at u = {u:.9g}; "
                                      "a feed must be finite and > 0")
            h = 1e-6
            a, b = max(u - h, 0.0), min(u + h, 1.0)
            return V, (float(feed(b)) - float(feed(a))) / (b - a)
        return f
    V = positive_feed(feed)
    return lambda u: (V, 0.0)


def positive_feed(feed) -> float:
    """``feed`` as a float, or :class:`InfeasibleError` unless it is finite and > 0."""
    try:
        V = float(feed)
    except (TypeError, ValueError):
        raise InfeasibleError(f"feed must be a number, got {feed!r}") from None
    if not (math.isfinite(V) and V > 0):
        raise InfeasibleError(f"feed must be finite and > 0, got {feed!r}")
    return V


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """``<a, b>`` summed left to right in plain double precision.

    Not ``a @ b``: BLAS may fuse or reorder the sum, and the compiled loop
    (:mod:`nurbsmotion._loop_kernel`) must be able to reproduce the reference step bit for
    bit, since the paper's feed amplifies a last-bit difference near saturation.
    """
    return float(sum(a * b))


def taylor_increment(d1: np.ndarray, d2: np.ndarray | None, feed: float,
                     acceleration: float, duration: float) -> float:
    """Parameter step of the speed-controlled interpolator (eq. 3.1 / 3.2).

    ``du = V*T/|D| + (A/|D| - V^2 <D, D2>/|D|^4) * T^2 / 2`` with ``d2`` given (eq. 3.1
    plus the tangential-acceleration term A that eq. 3.1 omits, SPEC section 5; Farouki &
    Tsai 2001); ``du = V*T/|D|`` with ``d2=None`` (eq. 3.2). Should the second-order term
    make the step non-positive (a step far too long for the local curvature), the
    first-order step is used.

    Parameters
    ----------
    d1, d2 : ndarray, shape (n_axes,)
        C'(u), C''(u) (``d2=None`` for first order).
    feed : float
        V [path units/s].
    acceleration : float
        A = dV/dt [path units/s^2].
    duration : float
        T, the time the step covers [s] (Ts for a whole sample).
    """
    n2 = dot(d1, d1)
    n1 = math.sqrt(n2)
    first = feed * duration / n1
    if d2 is None:
        return first
    second = 0.5 * (acceleration / n1 - feed * feed * dot(d1, d2) / (n2 * n2))
    du = first + second * duration**2
    return du if du > 0 else first


def _time_to_reach(du_target: float, d1: np.ndarray, d2: np.ndarray | None, feed: float,
                   acceleration: float, duration: float) -> float:
    """Time within ``duration`` at which the Taylor expansion advances by ``du_target``."""
    lo, hi = 0.0, duration
    for _ in range(60):  # bisection: the expansion is increasing in time on [0, duration]
        mid = 0.5 * (lo + hi)
        if taylor_increment(d1, d2, feed, acceleration, mid) < du_target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


class Interpolator(ABC):
    """Base class: owns the parameter, lands exactly on u = 1, then holds the end point.

    Subclasses implement :meth:`_plan_step`, which returns the feed V of the step, its
    tangential acceleration A, the speed bounds it computed (or ``None``) and the curve
    derivatives at the current parameter it already evaluated (or ``None``).

    The step itself is the Taylor expansion of order :attr:`order` (eq. 3.1 / 3.2). A step
    that crosses a knot where the curve loses the continuity the expansion relies on (C1
    for first order, C2 for second order; a sharp corner is one) is integrated piecewise:
    the expansion is restarted at the knot with the derivatives of the span the step moves
    into (SPEC section 5's one-sided rule, applied inside the step), for the rest of Ts.

    Parameters
    ----------
    curve : NurbsCurve
        The path [path units; pulse when run in the servo loop].
    sample_period : float
        Ts [s], > 0.
    """

    name = "base"
    order = 2

    def __init__(self, curve: NurbsCurve, sample_period: float):
        if not isinstance(curve, NurbsCurve):
            raise TypeError(f"curve must be a NurbsCurve, got {type(curve).__name__}")
        Ts = float(sample_period)
        if not (math.isfinite(Ts) and Ts > 0):
            raise ValueError(f"sample_period must be finite and > 0, got {sample_period!r}")
        self.curve = curve
        self.sample_period = Ts
        self._end = curve(1.0)
        p = curve.degree
        self._breaks = np.array([b for b in curve.breakpoints[1:-1]
                                 if curve.knot_multiplicity(b) >= p - self.order + 1] + [1.0])
        self.reset()

    def reset(self) -> None:
        """Back to the start of the path."""
        self.u = 0.0

    @property
    def finished(self) -> bool:
        return self.u >= 1.0

    def nominal_duration(self) -> float | None:
        """The time the move takes at its commanded feed [s], or ``None`` if unknown.

        The loop's safety limit on the number of samples is a multiple of it, so that a
        long slow move runs and a stalled one stops."""
        return None

    @abstractmethod
    def _plan_step(self, state: LoopState | None):
        """Return ``(feed, acceleration, speed_bounds, derivatives)`` for a step from
        ``self.u``; ``derivatives`` is ``curve.derivatives(self.u, order)`` or ``None``."""

    def _advance(self, feed: float, acceleration: float, derivatives) -> float:
        """Parameter after one sample at feed V with tangential acceleration A."""
        u, V, remaining = self.u, feed, self.sample_period
        d = derivatives if derivatives is not None else self.curve.derivatives(u, self.order)
        while True:
            d2 = d[2] if self.order == 2 else None
            du = taylor_increment(d[1], d2, V, acceleration, remaining)
            b = self._breaks[np.searchsorted(self._breaks, u, side="right")]
            if u + du <= b or b >= 1.0:
                return u + du
            dt = _time_to_reach(b - u, d[1], d2, V, acceleration, remaining)
            u, V, remaining = b, V + acceleration * dt, remaining - dt
            if remaining <= 0.0 or V <= 0.0:
                return u
            d = self.curve.derivatives(u, self.order)

    def step(self, state: LoopState | None = None) -> Setpoint:
        """The next setpoint. ``state`` is the measured loop state (``None`` open loop)."""
        if self.finished:
            return Setpoint(1.0, self._end, 0.0, Status.FINISHED)
        feed, acceleration, bounds, derivatives = self._plan_step(state)
        u = self._advance(feed, acceleration, derivatives)
        du = u - self.u
        if not (du > 0 and math.isfinite(du)):
            raise InfeasibleError(
                f"{self.name} interpolator cannot advance from u = {self.u:.9g} "
                f"(parameter step {du!r}, feed {feed!r})"
            )
        if u >= 1.0:
            self.u = 1.0
            return Setpoint(1.0, self._end, feed, Status.FINISHED, bounds)
        self.u = u
        return Setpoint(u, self.curve(u), feed, Status.WORKING, bounds)


@dataclass(frozen=True)
class SetpointSeries:
    """The setpoint stream of an open-loop interpolation, one row per sample.

    Attributes
    ----------
    t : ndarray, shape (n_samples,)
        Sample times k*Ts [s]; row 0 is the start, at rest.
    u : ndarray, shape (n_samples,)
        Curve parameter.
    position : ndarray, shape (n_samples, n_axes)
        Setpoints C(u) [path units].
    feed : ndarray, shape (n_samples,)
        Feed commanded for the step into each sample [path units/s] (0 at row 0).
    sample_period : float
        Ts [s].
    finished_index : int
        First row at the path's end.
    """

    t: np.ndarray
    u: np.ndarray
    position: np.ndarray
    feed: np.ndarray
    sample_period: float
    finished_index: int

    @property
    def cycle_time(self) -> float:
        """Time at which the setpoint first reaches the path's end [s]."""
        return float(self.t[self.finished_index])

    def feed_fluctuation(self) -> tuple[float, float]:
        """SPEC section 9: ``(|thd[k] - thd[k-1]|/Ts - Vcmd[k]) / Vcmd[k]``, (max |.|, RMS).

        Taken over the full steps 1 .. finished_index - 1: the last step is cut short to
        land on the end exactly, so it is not a fluctuation.
        """
        return feed_fluctuation(self.position, self.feed, self.sample_period,
                                self.finished_index)

    def plot(self, out_dir, **kwargs):
        """Write ``setpoints.png`` (see :func:`nurbsmotion.plots.plot_setpoints`)."""
        from ..plots import plot_setpoints

        return plot_setpoints(self, out_dir, **kwargs)


def feed_fluctuation(position: np.ndarray, feed: np.ndarray, sample_period: float,
                     finished_index: int) -> tuple[float, float]:
    """Feedrate fluctuation (max |.|, RMS) of SPEC section 9; see
    :meth:`SetpointSeries.feed_fluctuation`."""
    k = np.arange(1, finished_index)
    if k.size == 0:
        return 0.0, 0.0
    speed = np.linalg.norm(position[k] - position[k - 1], axis=1) / sample_period
    rel = (speed - feed[k]) / feed[k]
    return float(np.max(np.abs(rel))), float(np.sqrt(np.mean(rel**2)))


def interpolate(interpolator: Interpolator, max_samples: int = 10_000_000) -> SetpointSeries:
    """Run an interpolator open loop from the start to the end of its path.

    Raises
    ------
    InfeasibleError
        If the end is not reached within ``max_samples`` samples.
    """
    interpolator.reset()
    curve = interpolator.curve
    us, positions, feeds = [0.0], [curve(0.0)], [0.0]
    while True:
        sp = interpolator.step(None)
        us.append(sp.u)
        positions.append(sp.position)
        feeds.append(sp.feed)
        if sp.status is Status.FINISHED:
            break
        if len(us) > max_samples:
            raise InfeasibleError(
                f"interpolation did not reach the end within {max_samples} samples "
                f"(u = {sp.u:.6g}); the feed is too low for this path"
            )
    n = len(us)
    return SetpointSeries(
        t=np.arange(n) * interpolator.sample_period,
        u=np.array(us),
        position=np.array(positions),
        feed=np.array(feeds),
        sample_period=interpolator.sample_period,
        finished_index=n - 1,
    )
