"""The servo plant: independent axes simulated exactly under a zero-order hold.

Each axis follows SPEC section 3 (eq. 2.1-2.2 with b = [Kc/tau, 0]^T)::

    tau * dw/dt = -w + Kc * u        dtheta/dt = Ke * w

The drive is clipped to ``[-Umax, Umax]`` and held over each sample, so one step is the
exact discretisation ``x[k+1] = Ad x[k] + Bd u[k]`` with ``[Ad Bd] = expm([[A, b], [0, 0]]*Ts)``
(never Euler). The plant knows nothing of paths or controllers.

Glossary
--------
x = [w, theta] : state, motor speed [rad/s] and position [pulse]; u : drive [V].
"""

from __future__ import annotations

import functools

import copy

import numpy as np
from scipy.linalg import expm

__all__ = ["ServoPlant", "zoh_matrices"]


def zoh_matrices(time_constant: float, electrical_gain: float, mechanical_gain: float,
                 sample_period: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of one axis.

    Returns
    -------
    Ad : ndarray, shape (2, 2)
    Bd : ndarray, shape (2,)
        For the state ``[w, theta]``.
    """
    E = _zoh_exponential(float(time_constant), float(electrical_gain), float(mechanical_gain),
                         float(sample_period))
    return E[:2, :2].copy(), E[:2, 2].copy()


@functools.lru_cache(maxsize=256)
def _zoh_exponential(time_constant, electrical_gain, mechanical_gain, sample_period):
    # Cached: a sweep builds the same plant for every run, and expm costs more than a
    # short compiled run.
    M = np.zeros((3, 3))
    M[0, 0] = -1.0 / time_constant
    M[1, 0] = mechanical_gain
    M[0, 2] = electrical_gain / time_constant
    E = expm(M * sample_period)
    E.flags.writeable = False
    return E


class ServoPlant:
    """All axes of a machine's plant, stepped together.

    Parameters
    ----------
    time_constant, electrical_gain, mechanical_gain : array_like, shape (n_axes,)
        tau [s], Kc [(rad/s)/V], Ke [pulse/rad] per axis (the *true* plant, which may differ
        from the model an interpolator plans with).
    max_drive : float
        Umax [V] (``inf`` for no saturation).
    sample_period : float
        Ts [s].
    position : array_like, shape (n_axes,)
        Initial position [pulse]; the plant starts at rest.
    """

    def __init__(self, time_constant, electrical_gain, mechanical_gain, max_drive,
                 sample_period, position):
        mats = [zoh_matrices(t, c, e, sample_period)
                for t, c, e in zip(time_constant, electrical_gain, mechanical_gain)]
        self._Ad = np.array([a for a, _ in mats])  # (n_axes, 2, 2)
        self._Bd = np.array([b for _, b in mats])  # (n_axes, 2)
        self.max_drive = max_drive
        self.speed = np.zeros(len(mats))
        self.position = np.array(position, dtype=float)

    @classmethod
    def of_machine(cls, machine, position, *, time_constant_scale=1.0, electrical_gain_scale=1.0):
        """The plant of ``machine``, optionally with tau and Kc scaled (model mismatch)."""
        return cls(machine.tau * time_constant_scale, machine.Kc * electrical_gain_scale,
                   machine.Ke, machine.max_drive, machine.sample_period, position)

    def at_rest(self, position) -> "ServoPlant":
        """A new plant with the same dynamics, at rest at ``position`` [pulse]."""
        plant = copy.copy(self)
        plant.speed = np.zeros_like(self.speed)
        plant.position = np.array(position, dtype=float)
        return plant

    def saturate(self, drive: np.ndarray) -> np.ndarray:
        """The drive the actuator applies: ``clip(u, -Umax, Umax)`` [V]."""
        return np.clip(drive, -self.max_drive, self.max_drive)

    def step(self, drive_applied: np.ndarray) -> None:
        """Advance one sample holding ``drive_applied`` [V], shape (n_axes,)."""
        Ad, Bd = self._Ad, self._Bd
        w, th = self.speed, self.position
        self.speed = Ad[:, 0, 0] * w + Ad[:, 0, 1] * th + Bd[:, 0] * drive_applied
        self.position = Ad[:, 1, 0] * w + Ad[:, 1, 1] * th + Bd[:, 1] * drive_applied
