"""The saturation-aware interpolation of Yeh & Sun (2008), sections 3.3-3.4, faithfully.

Each sample, for every axis j (SPEC section 7):

1. V = commanded feed; unit tangent D = C'(u_i)/|C'(u_i)|; estimated axis speed
   wd_j = D_j*V/Ke_j (eq. 3.7);
2. the bounds [wmin_j, wmax_j] of eq. 3.6 from the measured loop state;
3. Vm_j = |wmax_j*Ke_j/D_j| if wd_j > wmax_j, |wmin_j*Ke_j/D_j| if wd_j < wmin_j, else V
   (eq. 3.10); an axis with D_j = 0 imposes no limit;
4. Vm = min_j Vm_j, and the step is eq. 3.2 with Vm (eq. 3.8-3.9).

Known gaps, reproduced on purpose (SPEC section 7): the tangent at u_i misses the other
axis's motion when a step crosses a sharp corner; one sample of look-ahead cannot slow down
before a corner or the path's end; nothing bounds jerk or contour error.
"""

from __future__ import annotations

import math

import numpy as np

from ..control import ControlLaw
from ..machine import Machine
from ..nurbs import NurbsCurve
from .base import Interpolator, LoopState, dot, positive_feed

__all__ = ["PaperInterpolator"]


class PaperInterpolator(Interpolator):
    """Saturation-aware speed-controlled interpolation (Yeh & Sun 2008, eq. 3.6-3.10).

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        The model the bounds are computed with (gains, tau, Kc, Ke, Umax, Ts).
    feed : float
        Commanded feed F [pulse/s].
    order : {1, 2}
        Parameter step with Vm: 1 is eq. 3.2, as section 3.4 of the paper states; 2 is
        eq. 3.1, the speed-controlled interpolator the paper builds on [25], which also
        accounts for the change of |C'(u)| within the step. Vm is a per-sample value with
        no profile behind it, so the tangential acceleration term is zero.
    """

    name = "paper"

    def __init__(self, curve: NurbsCurve, machine: Machine, feed: float, order: int = 1):
        machine.check_path(curve.n_axes)
        if order not in (1, 2):
            raise ValueError(f"order must be 1 or 2, got {order!r}")
        self.feed = positive_feed(feed)
        self.order = order
        self.machine = machine
        self.law = ControlLaw(machine)
        super().__init__(curve, machine.sample_period)

    def nominal_duration(self) -> float:
        return self.curve.length / self.feed

    def _plan_step(self, state: LoopState | None):
        if state is None:
            raise ValueError("the paper interpolator reads the measured loop state: run it "
                             "in the servo loop (nurbsmotion.simulate), not open loop")
        d = self.curve.derivatives(self.u, self.order)
        d1 = d[1]
        Ke = self.machine.Ke
        V = self.feed
        tangent = d1 / math.sqrt(dot(d1, d1))
        bounds = self.law.speed_bounds(state.position_command_prev, state.speed_command_prev,
                                       state.position, state.speed)
        wmin, wmax = bounds[:, 0], bounds[:, 1]
        wd = tangent * V / Ke                                          # eq. 3.7
        with np.errstate(divide="ignore", invalid="ignore"):
            vm = np.where(wd > wmax, np.abs(wmax * Ke / tangent),      # eq. 3.10
                          np.where(wd < wmin, np.abs(wmin * Ke / tangent), V))
        vm = np.where(tangent == 0.0, V, vm)
        Vm = float(np.min(vm))
        return Vm, 0.0, bounds, d  # the base class steps with eq. 3.8-3.9
