"""Open-loop parameter interpolators: uniform (eq. 1.1) and Taylor (eq. 3.1 / 3.2).

Neither reads the loop state. At a sharp corner the derivatives are taken from the right
(the span the step moves into, SPEC section 5); a step may jump over a corner.
"""

from __future__ import annotations

import math

from ..nurbs import NurbsCurve
from .base import Feed, Interpolator, LoopState, _feed_function, dot, positive_feed

__all__ = ["UniformInterpolator", "TaylorInterpolator"]


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
        eps = float(parameter_step)
        if not (math.isfinite(eps) and 0 < eps <= 1):
            raise ValueError(f"parameter_step must be in (0, 1], got {parameter_step!r}")
        self.parameter_step = eps
        super().__init__(curve, sample_period)
        self.nominal_feed = (curve.length * eps / self.sample_period
                             if nominal_feed is None else float(nominal_feed))

    @classmethod
    def for_feed(cls, curve: NurbsCurve, sample_period: float, feed: float):
        """The uniform step whose mean speed is ``feed``: ``epsilon = feed*Ts/length``."""
        V = positive_feed(feed)
        return cls(curve, sample_period, min(V * sample_period / curve.length, 1.0), V)

    def nominal_duration(self) -> float:
        return math.ceil(1.0 / self.parameter_step) * self.sample_period

    def _plan_step(self, state: LoopState | None):
        return self.nominal_feed, 0.0, None, None

    def _advance(self, feed, acceleration, derivatives) -> float:
        return self.u + self.parameter_step


class TaylorInterpolator(Interpolator):
    """Speed-controlled interpolation by Taylor expansion at a commanded feed.

    Parameters
    ----------
    curve : NurbsCurve
    sample_period : float
        Ts [s].
    feed : float or callable
        V [path units/s]: a constant, or a function of the parameter u. For a varying feed
        the second-order step includes the tangential acceleration term (SPEC section 5).
    order : {1, 2}
        1: eq. 3.2; 2: eq. 3.1 (with the A term).
    """

    def __init__(self, curve: NurbsCurve, sample_period: float, feed: Feed, order: int = 2):
        if order not in (1, 2):
            raise ValueError(f"Taylor order must be 1 or 2, got {order!r}")
        self.order = order
        self.name = f"taylor{order}"
        self._feed = _feed_function(feed)
        # A constant feed lets the compiled loop (nurbsmotion._loop_kernel) run this stepper.
        self._constant_feed = None if callable(feed) else float(feed)
        super().__init__(curve, sample_period)

    def nominal_duration(self) -> float | None:
        if self._constant_feed is None:
            return None
        return self.curve.length / self._constant_feed

    def _plan_step(self, state: LoopState | None):
        d = self.curve.derivatives(self.u, self.order)
        V, dV_du = self._feed(self.u)
        A = dV_du * V / math.sqrt(dot(d[1], d[1]))  # dV/dt = dV/du * du/dt
        return V, A, None, d
