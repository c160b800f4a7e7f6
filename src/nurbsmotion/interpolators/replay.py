"""Replay a precomputed parameter sequence through the loop (a plan made elsewhere).

Feeds a setpoint stream planned outside nurbsmotion (by another planner, a CAM system,
a previous run) through the same servo loop and metrics, so that planners can be compared
on equal terms. Sample k's setpoint is C(parameters[k]).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .. import stepping
from ..errors import InvalidArgumentError
from ..nurbs import NurbsCurve
from .base import Interpolator, PathData, land, path_data

__all__ = ["ReplayInterpolator"]


class ReplayState(NamedTuple):
    u: np.ndarray               # (1,)
    k: np.ndarray               # (1,) int64: the sample whose setpoint was given last


class ReplayPlan(NamedTuple):
    path: PathData
    parameters: np.ndarray      # (n,) u at samples 0, 1, ...
    feeds: np.ndarray           # (n,) arc length into each sample over Ts [path units/s]


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
    InvalidArgumentError
        If the sequence does not start at 0, end at 1, or decreases.
    """

    def __init__(self, curve: NurbsCurve, sample_period: float, parameters,
                 name: str = "replay"):
        super().__init__(curve, sample_period)
        u = np.asarray(parameters, dtype=float)
        if u.ndim != 1 or u.size < 2:
            raise InvalidArgumentError(f"parameters must have shape (n_samples,), n >= 2, got {u.shape}")
        if not np.all(np.isfinite(u)):
            raise InvalidArgumentError("parameters must be finite")
        if u[0] != 0.0 or u[-1] != 1.0:
            raise InvalidArgumentError(f"parameters must start at 0 and end at 1, got {u[0]!r} .. "
                                  f"{u[-1]!r}")
        if np.any(np.diff(u) < 0):
            k = int(np.flatnonzero(np.diff(u) < 0)[0])
            raise InvalidArgumentError(f"parameters decrease at sample {k + 1}: {u[k + 1]!r} < {u[k]!r}")
        self.name = name
        feeds = np.concatenate([[0.0], np.diff(curve.arc_length(u)) / self.sample_period])
        u.flags.writeable = False
        self.plan = ReplayPlan(path_data(curve, 1), u, feeds)

    @property
    def parameters(self) -> np.ndarray:
        return self.plan.parameters

    def new_state(self) -> ReplayState:
        return ReplayState(np.zeros(1), np.zeros(1, np.int64))

    def nominal_duration(self) -> float:
        return (len(self.plan.parameters) - 1) * self.sample_period


@njit(cache=True)
def replay_step(plan, state, law, law_state, position, velocity, command, bounds):
    """Sample k's setpoint is C(parameters[k]); the contract of :mod:`nurbsmotion.stepping`."""
    if state.u[0] >= 1.0:
        return stepping.hold_end(plan.path.end, command, bounds)
    k = state.k[0] + 1
    state.k[0] = k
    bounds[:] = np.nan
    u, status = land(plan.path, plan.parameters[k], command)
    state.u[0] = u
    return u, plan.feeds[k], status


stepping.register(ReplayPlan, replay_step)
