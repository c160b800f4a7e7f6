"""Is a machine's closed loop stable? The poles of the sampled loop, from the model.

Per axis, the loop the controller closes around the zero-order-hold plant (SPEC sections
3-4) is linear while the drive does not saturate. With the reference at rest (the
feedforward terms act only through the reference and do not move the poles), the state
``x[k] = [w[k], theta[k], theta[k-1]]`` follows ``x[k+1] = (A - B K) x[k]`` with
``[A, B]`` the exact ZOH matrices of :func:`nurbsmotion.servo.zoh_matrices` and the
feedback ``u[k] = -Kp*theta[k] - Kd*wa[k]``, where the measured speed is
``wa[k] = (theta[k] - theta[k-1]) / (Ke*Ts)`` (encoder) or ``w[k]`` (true speed).

A pole outside the unit circle means the loop's error grows without bound: with an ideal
drive the simulation diverges to inf/NaN; with a saturating one it produces nonsense (a
sample period of 1e6 s "reports" contour errors of 1e13 pulses). Such machines are
refused before a run, naming the poles.

Glossary
--------
w : motor speed [rad/s]; theta : position [pulse]; tau [s], Kc [(rad/s)/V],
Ke [pulse/rad], Kp [V/pulse], Kd [V/(rad/s)], Ts [s]: SPEC section 2.
"""

from __future__ import annotations

import numpy as np

from .errors import InvalidMachineError
from .machine import Machine
from .servo import zoh_matrices

__all__ = ["closed_loop_poles", "check_closed_loop_stable"]

_UNIT_CIRCLE_TOLERANCE = 1e-9
"""A pole radius up to 1 + this counts as on the unit circle (an integrator, Kp = 0)."""


def closed_loop_poles(machine: Machine) -> np.ndarray:
    """Poles of each axis's sampled closed loop, shape (n_axes, 3), complex."""
    Ts = machine.sample_period
    poles = []
    for a in machine.axes:
        Ad, Bd = zoh_matrices(a.time_constant, a.electrical_gain, a.mechanical_gain, Ts)
        A = np.zeros((3, 3))
        A[:2, :2] = Ad
        A[2, 1] = 1.0
        B = np.array([Bd[0], Bd[1], 0.0])
        if machine.speed_measurement == "encoder":
            kd = a.speed_gain / (a.mechanical_gain * Ts)
            K = np.array([0.0, a.position_gain + kd, -kd])
        else:
            K = np.array([a.speed_gain, a.position_gain, 0.0])
        with np.errstate(over="ignore", invalid="ignore"):
            closed = A - np.outer(B, K)
        if not np.all(np.isfinite(closed)):
            poles.append(np.full(3, np.inf, dtype=complex))
        else:
            poles.append(np.linalg.eigvals(closed))
    return np.array(poles)


def check_closed_loop_stable(machine: Machine) -> None:
    """Raise :class:`InvalidMachineError` if an axis's closed loop is unstable.

    The message names the axis, its largest pole radius and the sample period and gains
    that set it.
    """
    radius = np.abs(closed_loop_poles(machine)).max(axis=1)
    for a, r in zip(machine.axes, radius):
        if not r <= 1.0 + _UNIT_CIRCLE_TOLERANCE:
            raise InvalidMachineError(
                f"machine {machine.name!r}, axis {a.name!r}: the sampled closed loop is "
                f"unstable (largest pole radius {r:.6g} > 1) with Ts = "
                f"{machine.sample_period:g} s, Kp = {a.position_gain:g}, Kd = "
                f"{a.speed_gain:g}, tau = {a.time_constant:g} s; lower the gains or the "
                "sample period"
            )
