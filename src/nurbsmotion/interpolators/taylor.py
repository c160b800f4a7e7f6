"""Open-loop parameter interpolators: uniform (eq. 1.1) and Taylor (eq. 3.1 / 3.2).

Neither reads the loop state. At a sharp corner the derivatives are taken from the right
(the span the step moves into, docs/model.md#interpolation); a step may jump over a corner.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .. import stepping
from ..errors import InvalidArgumentError, InvalidFeedError
from ..feed import FeedLimit
from ..nurbs import NurbsCurve
from .base import (Interpolator, PathData, advance, check_taylor_starts, example_feed, example_path,
                   finish_step, land, path_data,
                   path_derivatives, path_scratch, positive_feed)

__all__ = ["UniformInterpolator", "TaylorInterpolator", "FeedTableInterpolator", "feed_table"]

class StepState(NamedTuple):
    """The state of a stepper that carries only its parameter: u, shape (1,), and the
    scratch of :func:`~nurbsmotion.interpolators.base.path_derivatives`, shape (3, n_axes)."""

    u: np.ndarray
    derivatives: np.ndarray

    @classmethod
    def new(cls, path: PathData) -> "StepState":
        return cls(np.zeros(1), path_scratch(path))


FEED_FUNCTION_SAMPLES = 4096
"""Intervals of the parameter a feed function is tabulated on (plus the curve's knots)."""


def feed_table(feed, curve: NurbsCurve) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A commanded feed as data: V(u) linear on each interval of the curve parameter.

    Parameters
    ----------
    feed : float, callable or FeedLimit
        A number [path units/s]; a function of the parameter u (tabulated on
        :data:`FEED_FUNCTION_SAMPLES` intervals and the curve's knots); or a
        :class:`nurbsmotion.feed.FeedLimit`, constant on each interval of u (e.g. the
        programmed F of each piece of a G-code file).
    curve : NurbsCurve

    Returns
    -------
    breaks : ndarray, shape (m + 1,)
    start, end : ndarray, shape (m,)
        V at the start and the end of each interval [path units/s], finite and > 0.
        Read-only, all three.

    Raises
    ------
    InvalidFeedError
        Naming the value (and for a function, the parameter) that is not finite and > 0.
    """
    if not (isinstance(feed, FeedLimit) or callable(feed)):
        feed = FeedLimit.constant(positive_feed(feed))
    if isinstance(feed, FeedLimit):  # validated at its construction; read-only arrays
        return feed.breakpoints, feed.speeds, feed.speeds
    if callable(feed):
        u = np.union1d(np.linspace(0.0, 1.0, FEED_FUNCTION_SAMPLES + 1), curve.breakpoints)
        V = np.empty_like(u)
        for i, ui in enumerate(u):
            try:
                V[i] = float(feed(float(ui)))
            except (TypeError, ValueError) as exc:
                raise InvalidFeedError(f"the feed function failed at u = {ui:.9g}: {exc}") from None
            if not (math.isfinite(V[i]) and V[i] > 0):
                raise InvalidFeedError(f"the feed function returned {float(V[i])!r} at "
                                       f"u = {ui:.9g}; a feed must be finite and > 0")
    u.flags.writeable = V.flags.writeable = False  # as a FeedLimit's: one compiled loop
    return u, V[:-1], V[1:]


def table_duration(curve: NurbsCurve, breaks, start, end) -> float:
    """The time along ``curve`` at the lower feed of each interval of a feed table [s]."""
    s = curve.arc_length(breaks)
    return float(np.sum(np.diff(s) / np.minimum(start, end)))


@njit(cache=True, inline="always")
def feed_at(breaks, start, end, u):
    """V(u) and dV/du of a feed table (:func:`feed_table`) [path units/s, per unit u]."""
    i = min(max(np.searchsorted(breaks, u, side="right") - 1, 0), breaks.shape[0] - 2)
    dV_du = (end[i] - start[i]) / (breaks[i + 1] - breaks[i])
    return start[i] + dV_du * (u - breaks[i]), dV_du


class UniformPlan(NamedTuple):
    path: PathData
    parameter_step: float
    feed: float


class TaylorPlan(NamedTuple):
    path: PathData
    order: int
    feed_breaks: np.ndarray     # (m + 1,) in u
    feed_start: np.ndarray      # (m,) V at each interval's start [path units/s]
    feed_end: np.ndarray        # (m,) V at each interval's end [path units/s]


class FeedTableInterpolator(Interpolator):
    """Base of the steppers whose plan holds a path and a feed table (:func:`feed_table`:
    ``feed_breaks``, ``feed_start``, ``feed_end``) and whose state is the parameter."""

    def new_state(self) -> StepState:
        return StepState.new(self.plan.path)

    @staticmethod
    def taylor_order(order) -> int:
        """``order`` as 1 (eq. 3.2) or 2 (eq. 3.1), or :class:`InfeasibleError`."""
        if order not in (1, 2) or isinstance(order, bool):
            raise InvalidArgumentError(f"Taylor order must be 1 or 2, got {order!r}")
        return int(order)

    def nominal_duration(self) -> float:
        return self._nominal_duration

    @functools.cached_property
    def _nominal_duration(self) -> float:
        p = self.plan
        return table_duration(self.curve, p.feed_breaks, p.feed_start, p.feed_end)


class UniformInterpolator(Interpolator):
    """Fixed parameter step, eq. 1.1: ``u[i+1] = u[i] + parameter_step``.

    Parameters
    ----------
    curve : NurbsCurve
    sample_period : float
        Ts [s].
    parameter_step : float
        epsilon, in (0, 1].
    nominal_feed : float, optional
        The feed this step stands for [path units/s], reported as the commanded feed
        (the default is ``length * parameter_step / Ts``, the mean speed).
    """

    name = "uniform"

    def __init__(self, curve: NurbsCurve, sample_period: float, parameter_step: float,
                 nominal_feed: float | None = None):
        super().__init__(curve, sample_period)
        eps = float(parameter_step)
        if not (math.isfinite(eps) and 0 < eps <= 1):
            raise InvalidArgumentError(f"parameter_step must be in (0, 1], got {parameter_step!r}")
        self.parameter_step = eps
        feed = (curve.length * eps / self.sample_period if nominal_feed is None
                else positive_feed(nominal_feed))
        self.plan = UniformPlan(path_data(curve, 1), eps, feed)

    @classmethod
    def for_feed(cls, curve: NurbsCurve, sample_period: float, feed: float):
        """The uniform step whose mean speed is ``feed``: ``epsilon = feed*Ts/length``."""
        V = positive_feed(feed)
        return cls(curve, sample_period, min(V * sample_period / curve.length, 1.0), V)

    @property
    def nominal_feed(self) -> float:
        return self.plan.feed

    def new_state(self) -> StepState:
        return StepState.new(self.plan.path)

    def nominal_duration(self) -> float:
        return math.ceil(1.0 / self.parameter_step) * self.sample_period


@njit(cache=True, inline="always")
def uniform_step(plan, state, law, law_state, position, velocity, command, bounds):
    """Eq. 1.1; the step contract of :mod:`nurbsmotion.stepping`."""
    if state.u[0] >= 1.0:
        return stepping.hold_end(plan.path.end, command, bounds)
    bounds[:] = np.nan
    u, status = land(plan.path, state.u[0] + plan.parameter_step, command)
    state.u[0] = u
    return u, plan.feed, status


class TaylorInterpolator(FeedTableInterpolator):
    """Speed-controlled interpolation by Taylor expansion at a commanded feed.

    Parameters
    ----------
    curve : NurbsCurve
    sample_period : float
        Ts [s].
    feed : float, callable or piecewise feed
        V [path units/s]: a constant, a function of the curve parameter u, or a
        piecewise-constant feed over u (see :func:`feed_table`). A varying feed enters the
        second-order step with its tangential acceleration (docs/model.md#interpolation).
    order : {1, 2}
        1: eq. 3.2; 2: eq. 3.1.
    """

    def __init__(self, curve: NurbsCurve, sample_period: float, feed, order: int = 2):
        super().__init__(curve, sample_period)
        self.order = self.taylor_order(order)
        self.name = f"taylor{order}"
        path = path_data(curve, self.order)
        check_taylor_starts(curve, path, self.name)
        self.plan = TaylorPlan(path, self.order,
                               *feed_table(feed, curve))


@njit(cache=True, inline="always")
def taylor_step(plan, state, law, law_state, position, velocity, command, bounds):
    """Eq. 3.1 / 3.2 at the commanded feed; the step contract of :mod:`nurbsmotion.stepping`."""
    if state.u[0] >= 1.0:
        return stepping.hold_end(plan.path.end, command, bounds)
    u0 = state.u[0]
    bounds[:] = np.nan
    V, dV_du = feed_at(plan.feed_breaks, plan.feed_start, plan.feed_end, u0)
    d = path_derivatives(plan.path, u0, plan.order, state.derivatives)
    n2 = 0.0
    for c in range(d.shape[1]):
        n2 += d[1, c] * d[1, c]
    A = dV_du * V / math.sqrt(n2)                   # dV/dt = dV/du * du/dt
    u_new = advance(plan.path, plan.order, u0, V, A, law[0]["period"], d, True)
    u, status = finish_step(plan.path, u0, u_new, command, state)
    return u, V, status


def _taylor(order: int):
    """The factories and the example of ``taylor<order>``."""
    def open_loop(curve, sample_period, feed):
        return TaylorInterpolator(curve, sample_period, feed, order=order)

    def make(curve, machine, feed):
        return open_loop(curve, machine.sample_period, feed)

    def example(n_axes: int):
        path = example_path(n_axes)
        return TaylorPlan(path, order, *example_feed()), StepState.new(path)

    return dict(make=make, open_loop=open_loop, example=example)


stepping.register(UniformPlan, uniform_step, name="uniform",
                  open_loop=UniformInterpolator.for_feed)
stepping.register(TaylorPlan, taylor_step, name="taylor1", **_taylor(1))
stepping.register(TaylorPlan, taylor_step, name="taylor2", **_taylor(2))
