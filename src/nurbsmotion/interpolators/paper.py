"""The saturation-aware interpolation of Yeh & Sun (2008), sections 3.3-3.4, faithfully.

Each sample, for every axis j (docs/model.md#paper-algorithm):

1. V = commanded feed; unit tangent D = C'(u_i)/|C'(u_i)|; estimated axis speed
   wd_j = D_j*V/Ke_j (eq. 3.7);
2. the bounds [wmin_j, wmax_j] of eq. 3.6 from the measured loop state;
3. Vm_j = |wmax_j*Ke_j/D_j| if wd_j > wmax_j, |wmin_j*Ke_j/D_j| if wd_j < wmin_j, else V
   (eq. 3.10); an axis with D_j = 0 imposes no limit;
4. Vm = min_j Vm_j, and the step is eq. 3.2 with Vm (eq. 3.8-3.9).

The bounds of step 2 come from the loop's control law as it is (its affine form in the
new setpoint, :func:`nurbsmotion.control.pid_affine`): for the paper's PD+ they are eq. 3.6
exactly; for PD or any LinuxCNC ``pid`` law the same construction gives that law's bounds.

Known gaps, reproduced on purpose (docs/model.md#paper-algorithm): the tangent at u_i misses the other
axis's motion when a step crosses a sharp corner; one sample of look-ahead cannot slow down
before a corner or the path's end; nothing bounds jerk or contour error.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .. import stepping
from ..machine import Machine
from ..nurbs import NurbsCurve
from .base import (PathData, advance, check_taylor_starts, example_feed, example_path,
                   finish_step, path_data,
                   path_derivatives, speed_bounds)
from .taylor import FeedTableInterpolator, StepState, feed_at, feed_table

__all__ = ["PaperInterpolator"]


class PaperPlan(NamedTuple):
    path: PathData
    order: int
    feed_breaks: np.ndarray     # the commanded feed F(u) as a table (taylor.feed_table)
    feed_start: np.ndarray      # [pulse/s]
    feed_end: np.ndarray
    mechanical_gain: np.ndarray  # Ke per axis [pulse/rad]


class PaperInterpolator(FeedTableInterpolator):
    """Saturation-aware speed-controlled interpolation (Yeh & Sun 2008, eq. 3.6-3.10).

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        Ke per axis and Ts (the bounds come from the loop's law and Umax).
    feed : float or FeedLimit
        Commanded feed F [pulse/s], or a limit per piece of the path (the paper's V of
        each step is F at the step's start).
    order : {1, 2}
        Parameter step with Vm: 1 is eq. 3.2, as section 3.4 of the paper states; 2 is
        eq. 3.1, the speed-controlled interpolator the paper builds on [25], which also
        accounts for the change of |C'(u)| within the step. Vm is a per-sample value with
        no profile behind it, so the tangential acceleration term is zero.
    """

    name = "paper"
    records_bounds = True

    def __init__(self, curve: NurbsCurve, machine: Machine, feed: float, order: int = 1):
        machine.check_path(curve.n_axes)
        super().__init__(curve, machine.sample_period)
        self.order = self.taylor_order(order)
        path = path_data(curve, self.order)
        check_taylor_starts(curve, path, "paper")
        self.plan = PaperPlan(path, self.order,
                              *feed_table(feed, curve), np.array(machine.Ke, dtype=float))


@njit(cache=True, inline="always")
def paper_step(plan, state, law, law_state, position, velocity, command, bounds):
    """Eq. 3.6-3.10 and the step of eq. 3.8-3.9; the contract of :mod:`nurbsmotion.stepping`."""
    if state.u[0] >= 1.0:
        return stepping.hold_end(plan.path.end, command, bounds)
    u0 = state.u[0]
    d = path_derivatives(plan.path, u0, plan.order, state.derivatives)
    dim = d.shape[1]
    n2 = 0.0
    for c in range(dim):
        n2 += d[1, c] * d[1, c]
    norm = math.sqrt(n2)
    speed_bounds(law, law_state, plan.mechanical_gain, position, velocity, bounds)  # eq. 3.6
    V = feed_at(plan.feed_breaks, plan.feed_start, plan.feed_end, u0)[0]
    Vm = np.inf     # eq. 3.10 may also raise the feed, where a bound forces motion
    for j in range(dim):
        Ke = plan.mechanical_gain[j]
        wmin, wmax = bounds[j, 0], bounds[j, 1]
        tangent = d[1, j] / norm
        wd = tangent * V / Ke                                             # eq. 3.7
        if tangent == 0.0:
            vm = V
        elif wd > wmax:
            vm = abs(wmax * Ke / tangent)                                 # eq. 3.10
        elif wd < wmin:
            vm = abs(wmin * Ke / tangent)
        else:
            vm = V
        if vm < Vm:
            Vm = vm
    u_new = advance(plan.path, plan.order, u0, Vm, 0.0, law[0]["period"], d, True)
    u, status = finish_step(plan.path, u0, u_new, command, state)
    if status == stepping.WORKING and Vm != V:
        status = stepping.LIMITED
    return u, Vm, status


def _example(n_axes: int):
    """Made-up plan and state of the types a run passes (a cold first run's compilation)."""
    path = example_path(n_axes)
    return PaperPlan(path, 1, *example_feed(), np.zeros(n_axes)), StepState.new(path)


stepping.register(PaperPlan, paper_step, name="paper", make=PaperInterpolator,
                  example=_example)
