"""The servo plant: independent axes simulated exactly under a zero-order hold.

Each axis follows docs/model.md#servo-axis (eq. 2.1-2.2 with b = [Kc/tau, 0]^T)::

    tau * dw/dt = -w + Kc * u        dtheta/dt = Ke * w

The drive is clipped to ``[-Umax, Umax]`` and held over each sample, so one step is the
exact discretisation ``x[k+1] = Ad x[k] + Bd u[k]`` with ``[Ad Bd] = expm([[A, b], [0, 0]]*Ts)``
(never Euler), here in its closed form (:func:`zoh_matrices`). The plant knows nothing of
paths or controllers. Its one step, compiled (:func:`plant_step`), is in :mod:`.step`,
loaded with numba on first use.

Glossary
--------
x = [w, theta] : state, motor speed [rad/s] and position [pulse]; u : drive [V].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._runtime.lazy import lazy_names
from ..errors import InvalidMachineError
from ..plant.linear import x_minus_one_minus_exp

_LAZY = {"plant_step": "step"}
"""The compiled step (:mod:`.step`), loaded with numba on first use: a machine's plant is
made and checked without it."""

__all__ = ["ServoPlant", "zoh_matrices", "zoh_coefficients", "plant_step"]

__getattr__, __dir__ = lazy_names(__name__, _LAZY)


def zoh_matrices(time_constant: float, electrical_gain: float, mechanical_gain: float,
                 sample_period: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of one axis, ``expm([[A, b], [0, 0]]*Ts)`` in
    closed form.

    With ``x = Ts/tau``, ``a = exp(-x)`` and ``g = 1 - a``::

        Ad = [[a, 0], [Ke*tau*g, 1]]      Bd = [Kc*g, Ke*Kc*tau*(x - g)]

    ``g`` and ``x - g`` are evaluated without cancellation (``expm1`` and a series for
    small x), so the matrices are exact to rounding for any Ts/tau.

    Returns
    -------
    Ad : ndarray, shape (2, 2)
    Bd : ndarray, shape (2,)
        For the state ``[w, theta]``.
    """
    tau, Kc, Ke = float(time_constant), float(electrical_gain), float(mechanical_gain)
    x = float(sample_period) / tau
    g = -math.expm1(-x)
    Ad = np.array([[1.0 - g, 0.0], [Ke * tau * g, 1.0]])
    Bd = np.array([Kc * g, Ke * Kc * tau * x_minus_one_minus_exp(x)])
    return Ad, Bd


def zoh_coefficients(time_constant, electrical_gain, mechanical_gain, sample_period):
    """Per axis, the entries ``(a, b0, c, b1)`` of :func:`zoh_matrices` (``Ad = [[a, 0],
    [c, 1]]``, ``Bd = [b0, b1]``), each shape (n_axes,), from per-axis tau [s], Kc
    [(rad/s)/V] and Ke [pulse/rad] (sequences) and Ts [s]."""
    mats = [zoh_matrices(t, k, e, sample_period)
            for t, k, e in zip(time_constant, electrical_gain, mechanical_gain)]
    a = np.array([A[0, 0] for A, _ in mats])
    c = np.array([A[1, 0] for A, _ in mats])
    b0 = np.array([B[0] for _, B in mats])
    b1 = np.array([B[1] for _, B in mats])
    return a, b0, c, b1


def _axis_values(values, name: str) -> np.ndarray:
    arr = np.array(values, dtype=float).reshape(-1)
    if arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise InvalidMachineError(f"plant {name} must be finite and > 0 per axis, got {values!r}")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class ServoPlant:
    """All axes of a machine's plant: a value object (the loop owns the motion's state).

    Parameters
    ----------
    time_constant, electrical_gain, mechanical_gain : array_like, shape (n_axes,)
        tau [s], Kc [(rad/s)/V], Ke [pulse/rad] per axis (the *true* plant, which may differ
        from the model an interpolator plans with).
    max_drive : float
        Umax [V] (``inf`` for no saturation).
    sample_period : float
        Ts [s].
    position : array_like, shape (n_axes,), optional
        Where the plant starts, at rest [pulse]; by default the path's start.
    effects : dict, optional
        The machine-as-it-is keys of the true machine (``Machine.effects()``: counts,
        noise, delay, DAC, friction, load steps, a two-mass mode), run by the plant stage
        of :mod:`nurbsmotion.plant`; ``None`` for the ideal plant.

    Attributes
    ----------
    Ad : ndarray, shape (n_axes, 2, 2)
    Bd : ndarray, shape (n_axes, 2)
        ZOH matrices per axis, state ``[w, theta]``.
    """

    time_constant: np.ndarray
    electrical_gain: np.ndarray
    mechanical_gain: np.ndarray
    max_drive: float
    sample_period: float
    position: np.ndarray | None = None
    effects: dict | None = None
    Ad: np.ndarray = field(init=False, repr=False)
    Bd: np.ndarray = field(init=False, repr=False)
    _cache: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self):
        tau = _axis_values(self.time_constant, "time_constant")
        Kc = _axis_values(self.electrical_gain, "electrical_gain")
        Ke = _axis_values(self.mechanical_gain, "mechanical_gain")
        if not (tau.size == Kc.size == Ke.size):
            raise InvalidMachineError("plant parameters must have one value per axis, got "
                                      f"{tau.size}, {Kc.size} and {Ke.size}")
        Ts = float(self.sample_period)
        if not (math.isfinite(Ts) and Ts > 0):
            raise InvalidMachineError(f"plant sample_period must be finite and > 0, "
                                      f"got {self.sample_period!r}")
        umax = float(self.max_drive)
        if not umax > 0:
            raise InvalidMachineError(f"plant max_drive must be > 0, got {self.max_drive!r}")
        mats = [zoh_matrices(t, c, e, Ts) for t, c, e in zip(tau, Kc, Ke)]
        Ad = np.array([a for a, _ in mats])
        Bd = np.array([b for _, b in mats])
        Ad.flags.writeable = Bd.flags.writeable = False
        for name, value in (("time_constant", tau), ("electrical_gain", Kc),
                            ("mechanical_gain", Ke), ("max_drive", umax),
                            ("sample_period", Ts), ("Ad", Ad), ("Bd", Bd)):
            object.__setattr__(self, name, value)
        if self.effects is not None:
            if not isinstance(self.effects, dict) or len(self.effects.get("axes", ())) != tau.size:
                raise InvalidMachineError(f"plant effects must be a Machine.effects() dict "
                                          f"of {tau.size} axes, got {self.effects!r:.80}")
        if self.position is not None:
            pos = np.array(self.position, dtype=float).reshape(-1)
            if pos.size != tau.size or not np.all(np.isfinite(pos)):
                raise InvalidMachineError(f"plant position must be {tau.size} finite numbers, "
                                          f"got {self.position!r}")
            pos.flags.writeable = False
            object.__setattr__(self, "position", pos)

    @property
    def n_axes(self) -> int:
        return self.time_constant.size

    @classmethod
    def of_machine(cls, machine, position=None, *, time_constant_scale=1.0,
                   electrical_gain_scale=1.0, mechanical_gain_scale=1.0) -> "ServoPlant":
        """The plant of ``machine``, optionally with tau, Kc and Ke scaled (model mismatch;
        a scale may be one number or one per axis), with the machine's effects if it has
        any."""
        return cls(machine.tau * np.asarray(time_constant_scale, dtype=float),
                   machine.Kc * np.asarray(electrical_gain_scale, dtype=float),
                   machine.Ke * np.asarray(mechanical_gain_scale, dtype=float),
                   machine.max_drive, machine.sample_period, position,
                   machine.effects() if getattr(machine, "has_effects", False) else None)

    def stage(self):
        """The plant stage of :mod:`nurbsmotion.plant` (inactive for an ideal plant),
        made once."""
        if "stage" not in self._cache:
            from ..plant import inactive_stage, make_stage

            self._cache["stage"] = (
                inactive_stage(self.n_axes) if self.effects is None else
                make_stage(self.effects, self.time_constant, self.electrical_gain,
                           self.mechanical_gain, self.max_drive, self.sample_period))
        return self._cache["stage"]

    def at_rest(self, position) -> "ServoPlant":
        """The same dynamics, starting at rest at ``position`` [pulse]."""
        return ServoPlant(self.time_constant, self.electrical_gain, self.mechanical_gain,
                          self.max_drive, self.sample_period, position, self.effects)

    def saturate(self, drive: np.ndarray) -> np.ndarray:
        """The drive the actuator applies: ``clip(u, -Umax, Umax)`` [V]."""
        return np.clip(drive, -self.max_drive, self.max_drive)

    def response(self, drive: np.ndarray, position=None) -> tuple[np.ndarray, np.ndarray]:
        """Speed and position under a drive sequence, from rest.

        Parameters
        ----------
        drive : ndarray, shape (n_samples, n_axes)
            u[k] [V], clipped to +-Umax and held over each sample.
        position : array_like, shape (n_axes,), optional
            Start [pulse]; :attr:`position` (or 0) by default.

        Returns
        -------
        speed : ndarray, shape (n_samples + 1, n_axes)
            w[k] [rad/s].
        position : ndarray, shape (n_samples + 1, n_axes)
            theta[k] [pulse].
        """
        drive = np.asarray(drive, dtype=float)
        start = self.position if position is None else np.asarray(position, dtype=float)
        w = np.zeros((drive.shape[0] + 1, self.n_axes))
        th = np.zeros_like(w)
        th[0] = 0.0 if start is None else start
        from .step import _respond

        _respond(self.Ad, self.Bd, np.ascontiguousarray(drive.reshape(-1, self.n_axes)),
                 self.max_drive, w, th)
        return w, th
