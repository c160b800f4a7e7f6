"""Replay a precomputed parameter sequence through the loop (a plan made elsewhere).

Feeds a setpoint stream planned outside nurbsmotion (by another planner, a CAM system,
a previous run) through the same servo loop and metrics, so that planners can be compared
on equal terms. Sample k's setpoint is C(parameters[k]).
"""

from __future__ import annotations

import numpy as np

from ..nurbs import NurbsCurve
from .base import Interpolator, LoopState, Setpoint, Status

__all__ = ["ReplayInterpolator"]


class ReplayInterpolator(Interpolator):
    """Step through given curve parameters, one per sample.

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse in the servo loop].
    sample_period : float
        Ts [s].
    parameters : array_like, shape (n_samples,)
        u at samples 0, 1, ...: starts at 0, never decreases, ends at exactly 1.
    name : str
        Label in traces and summaries.

    Raises
    ------
    ValueError
        If the sequence does not start at 0, end at 1, or decreases.
    """

    def __init__(self, curve: NurbsCurve, sample_period: float, parameters,
                 name: str = "replay"):
        u = np.asarray(parameters, dtype=float)
        if u.ndim != 1 or u.size < 2:
            raise ValueError(f"parameters must have shape (n_samples,), n >= 2, got {u.shape}")
        if not np.all(np.isfinite(u)):
            raise ValueError("parameters must be finite")
        if u[0] != 0.0 or u[-1] != 1.0:
            raise ValueError(f"parameters must start at 0 and end at 1, got {u[0]!r} .. "
                             f"{u[-1]!r}")
        if np.any(np.diff(u) < 0):
            k = int(np.flatnonzero(np.diff(u) < 0)[0])
            raise ValueError(f"parameters decrease at sample {k + 1}: {u[k + 1]!r} < {u[k]!r}")
        self.parameters = u
        self.name = name
        super().__init__(curve, sample_period)
        self._s = curve.arc_length(u)

    def nominal_duration(self) -> float:
        return (len(self.parameters) - 1) * self.sample_period

    def reset(self) -> None:
        super().reset()
        self._k = 0

    def _plan_step(self, state: LoopState | None):  # pragma: no cover - step() overrides
        raise NotImplementedError

    def step(self, state: LoopState | None = None) -> Setpoint:
        if self.finished:
            return Setpoint(1.0, self._end, 0.0, Status.FINISHED)
        self._k += 1
        k = self._k
        u = float(self.parameters[k])
        feed = (self._s[k] - self._s[k - 1]) / self.sample_period
        self.u = u
        status = Status.FINISHED if u >= 1.0 else Status.WORKING
        return Setpoint(u, self.curve(u), feed, status)
