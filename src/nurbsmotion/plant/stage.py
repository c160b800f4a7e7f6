"""The plant stage as data: :class:`PlantStage` (numbers only) made from a machine's
effect keys, its state :class:`PlantState`, and the ideal plant's stage, a type of its
own (:class:`IdleStage`, :func:`is_active`) (the model: :mod:`nurbsmotion.plant`).

Glossary
--------
See :mod:`nurbsmotion.plant`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba.extending import overload

from ..errors import InvalidMachineError
from .two_mass import (CDMP, CHECK_SLIDE, CHECK_STUCK, CSC, CSS, ENC, FC, FS, GAIN, KC,
                       KE, KSPR, LAM, N_COEF, N_PARAM, SA0, SA1, SIG, TAU, TOOL, W2,
                       _coefficients, oscillator)
from .friction import SCRATCH
from .linear import _mode, split_delay

__all__ = ["PlantStage", "IdleStage", "is_active", "PlantState", "make_stage",
           "inactive_stage", "new_plant_state"]

class PlantStage(NamedTuple):
    """The true plant's effects, as numbers (see :mod:`nurbsmotion.plant`).

    active : bool -- False for an ideal plant (the loop uses ``servo.plant_step``);
    counts : bool -- the position is read in whole counts;
    noise : float -- measurement noise, standard deviation [pulse];
    seed : int -- its seed;
    dac_step : float -- the DAC's step q [V] (0: none);
    dac_levels : float -- ``2**(dac_bits - 1)``;
    delay_samples : int -- n, whole samples of delay;
    split : float -- h1, the rest of the delay [s] (0: none);
    sample_period : float -- Ts [s];
    param : ndarray, shape (n_axes, N_PARAM) -- per axis, columns TAU ... CHECK_STUCK;
    friction : ndarray, shape (n_axes,), bool -- the axis has friction;
    two_mass : ndarray, shape (n_axes,), bool;
    coef : ndarray, shape (n_axes, 2, N_COEF) -- sliding (and stuck: CSC, CSS)
    coefficients of h1 and Ts - h1;
    disturbance_time : ndarray, shape (n_axes, m + 1) -- load step instants [s], sorted,
    then inf; disturbance_drive : same shape -- the summed load drive from each on [V].
    """

    active: bool
    counts: bool
    noise: float
    seed: int
    dac_step: float
    dac_levels: float
    delay_samples: int
    split: float
    sample_period: float
    param: np.ndarray
    friction: np.ndarray
    two_mass: np.ndarray
    coef: np.ndarray
    disturbance_time: np.ndarray
    disturbance_drive: np.ndarray


class PlantState(NamedTuple):
    """The plant stage's state, per axis: ``x`` (n_axes, 4) = [w_cm, theta_cm, delta,
    delta'], ``direction`` (n_axes,) float: the sliding direction of the motor (+1, -1)
    or 0 stuck; ``line`` (n_axes, n + 2): the drives on their way (ring buffer by
    sample); ``next_disturbance`` (n_axes,) int64: the next load step's index;
    ``origin`` (n_axes,): where the run started [pulse] (the counts' zero); and scratch:
    ``tool`` (n_axes,), ``scratch`` (SCRATCH,)."""

    x: np.ndarray
    direction: np.ndarray
    line: np.ndarray
    next_disturbance: np.ndarray
    origin: np.ndarray
    tool: np.ndarray
    scratch: np.ndarray


IdleStage = NamedTuple("IdleStage", list(PlantStage.__annotations__.items()))
IdleStage.__doc__ = """An ideal plant's stage: the fields of :class:`PlantStage`, never run.
A type of its own, so that the compiled loop knows at compile time that it has no plant
stage (:func:`is_active`) and an ideal run's loop is the one it was before the stage."""


def is_active(stage) -> bool:
    """Whether the loop runs the stage (a constant of the stage's type when compiled)."""
    return bool(stage.active)


@overload(is_active, inline="always", jit_options={"cache": True})
def _is_active_overload(stage):
    from numba.core import types

    if not isinstance(stage, types.BaseNamedTuple):
        return None
    value = stage.instance_class is not IdleStage

    def impl(stage):
        return value
    return impl


def inactive_stage(n_axes: int) -> PlantStage:
    """The stage of an ideal plant (same types, never run)."""
    z = np.zeros((n_axes, N_PARAM))
    z[:, TAU] = z[:, KC] = z[:, KE] = 1.0
    arrays = (z, np.zeros(n_axes, np.bool_), np.zeros(n_axes, np.bool_),
              np.zeros((n_axes, 2, N_COEF)), np.full((n_axes, 1), np.inf),
              np.zeros((n_axes, 1)))
    for arr in arrays:  # read-only as a made stage's
        arr.flags.writeable = False
    return IdleStage(False, False, 0.0, 0, 0.0, 1.0, 0, 0.0, 1.0, *arrays)


def make_stage(effects, tau, Kc, Ke, max_drive: float, sample_period: float) -> PlantStage:
    """The :class:`PlantStage` of a plant with ``effects`` (a
    :class:`nurbsmotion.machine.Machine`'s effect keys: ``machine.effects()``), per-axis
    tau [s], Kc [(rad/s)/V], Ke [pulse/rad], the drive limit [V] and Ts [s]."""
    n = len(tau)
    Ts = float(sample_period)
    param = np.zeros((n, N_PARAM))
    friction = np.zeros(n, np.bool_)
    two = np.zeros(n, np.bool_)
    m = max([len(a["disturbance"]) for a in effects["axes"]] + [0])
    dist_t = np.full((n, m + 1), np.inf)
    dist_d = np.zeros((n, m + 1))
    for j, a in enumerate(effects["axes"]):
        p = param[j]
        p[TAU], p[KC], p[KE] = tau[j], Kc[j], Ke[j]
        if a["resonance_frequency"] > 0:
            lam = a["load_fraction"]
            sig, w2, c, mu = _mode(tau[j], lam, a["resonance_frequency"],
                                   a["resonance_damping"])
            p[LAM], p[SIG], p[W2] = lam, sig, w2
            p[GAIN] = Ke[j] * Kc[j] / ((1.0 - lam) * tau[j])
            p[SA1] = 1.0 / tau[j] + c / (lam * tau[j])
            p[SA0] = w2 * (1.0 - lam)
            p[KSPR] = w2 * mu / (Ke[j] * Kc[j])
            p[CDMP] = c / (Ke[j] * Kc[j])
            p[TOOL] = -(1.0 - lam)
            p[ENC] = lam if a["encoder_on"] == "motor" else -(1.0 - lam)
            two[j] = True
            p[CHECK_SLIDE] = 2.0 * math.pi / math.sqrt(w2) / 8.0
            p[CHECK_STUCK] = 2.0 * math.pi / math.sqrt(p[SA0]) / 8.0
        else:
            p[CHECK_SLIDE] = p[CHECK_STUCK] = math.inf
        p[FC] = a["coulomb_friction"]
        p[FS] = max(a["stiction"], a["coulomb_friction"])
        friction[j] = p[FS] > 0.0
        steps = sorted((d["at"], d["drive"]) for d in a["disturbance"])
        total = 0.0
        for i, (at, drive) in enumerate(steps):
            total += drive
            dist_t[j, i] = at
            dist_d[j, i] = total
    whole, split = split_delay(float(effects["delay"]), Ts)
    coef = np.zeros((n, 2, N_COEF))
    for j in range(n):
        intervals = (split, Ts - split) if split > 0.0 else (Ts,)
        for i, h in enumerate(intervals):
            coef[j, i] = _coefficients(param[j], h)
            if two[j]:
                coef[j, i, CSC], coef[j, i, CSS] = oscillator(param[j, SA1], param[j, SA0], h)
    bits = effects["dac_bits"]
    if bits is not None and not math.isfinite(max_drive):
        raise InvalidMachineError(f"dac_bits = {bits} needs a finite max_drive, got "
                                  f"{max_drive!r}")
    dac_step = 0.0 if bits is None else 2.0 * max_drive / 2.0 ** bits
    levels = 1.0 if bits is None else 2.0 ** (bits - 1)
    for arr in (param, friction, two, coef, dist_t, dist_d):
        arr.flags.writeable = False
    return PlantStage(True, effects["encoder"] == "counts",
                      float(effects["measurement_noise"]), int(effects["seed"]),
                      dac_step, levels, whole, split, Ts, param,
                      friction, two, coef, dist_t, dist_d)


_IDLE_STATES: dict = {}


def new_plant_state(stage: PlantStage, position) -> PlantState:
    """The stage at rest at ``position`` [pulse] (shape (n_axes,)); a motor with friction
    starts stuck. An inactive stage's state is never read or written: one per number of
    axes is shared (an ideal run makes none)."""
    n = len(position)
    if not stage.active:
        if n not in _IDLE_STATES:
            _IDLE_STATES[n] = new_plant_state(PlantStage(*stage)._replace(active=True),
                                              np.zeros(n))
        return _IDLE_STATES[n]
    x = np.zeros((n, 4))
    x[:, 1] = position
    direction = np.where(stage.friction, 0.0, 1.0)
    return PlantState(x, direction, np.zeros((n, stage.delay_samples + 2)),
                      np.zeros(n, np.int64), np.array(position, dtype=float),
                      np.zeros(n), np.zeros(SCRATCH))
