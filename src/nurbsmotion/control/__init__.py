"""The control law as data: LinuxCNC's ``pid`` HAL component, per axis.

The law is ``calc_pid`` of LinuxCNC's ``src/hal/components/pid.c``, evaluated once per
sample Ts for every axis (docs/model.md#beyond-the-paper)::

    e      = command - feedback, clamped to +-maxerror (0: no clamp), less the deadband
    errorI = errorI + e*Ts unless the output sat at its limit pushing the same way as e
             (anti-windup: frozen while e*limit_state > 0), clamped to +-maxerrorI
    errorD = (e - e_prev)/Ts, clamped to +-maxerrorD          (encoder differencing)
           = commandD - feedback_velocity                     (``feedback-deriv`` pin)
    cmdD   = (command - command_prev)/Ts, clamped to +-maxcmdD
    cmdDD  = (cmdD - cmdD_prev)/Ts, clamped to +-maxcmdDD
    output = bias + Pgain*e + Igain*errorI + Dgain*errorD + FF0*command + FF1*cmdD + FF2*cmdDD

and the output is limited to +-maxoutput (the machine's drive limit Umax), which sets the
limit state the integrator reads at the next sample. Positions are in pulses, the output
in volts, times in seconds.

The paper's laws are presets of it (docs/model.md#controllers, eq. 2.4, 2.12 and 3.3 of Yeh & Sun
2008): ``Pgain = Kp``, ``Dgain = Kd/Ke``, ``FF1 = 1/(Kc*Ke)``, ``FF2 = tau/(Kc*Ke)`` for PD+
(``FF1 = FF2 = 0`` for PD). The ``true`` speed measurement of the paper's PD+ is the
component's ``feedback-deriv`` pin fed with the motor speed: ``errorD = cmdD - Ke*w``.

Given the past, the output is affine in the new command between the clamps
(:func:`pid_affine`); an interpolator that predicts the drive uses that form (eq. 3.6 of
the paper for PD+) or evaluates :func:`pid_output` for a candidate command. Both are
plain functions on the law's numbers (:data:`PID_LAW`) and its state (:data:`PID_STATE`),
compiled by numba and runnable as plain Python (``NUMBA_DISABLE_JIT=1``); they live in
:mod:`.step` (loaded on first use, with numba), the law's data and its poles here, so
that a machine is read and checked without the compiler.

Glossary
--------
e : position error [pulse]; errorI [pulse*s]; errorD, cmdD [pulse/s]; cmdDD [pulse/s^2];
Ts : sample period [s]; Umax : drive limit [V].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .._runtime.lazy import lazy_names
from ..errors import InvalidMachineError

_LAZY = {"pid_output": "step", "pid_commit": "step", "pid_affine": "step"}
"""The compiled per-sample functions (:mod:`.step`), loaded with numba on first use: a
machine is read and checked without them."""

__all__ = ["PidGains", "PID_KEYS", "PID_LAW", "PID_STATE", "pid_law", "pid_state",
           "pid_output", "pid_commit", "pid_affine", "loop_poles"]

__getattr__, __dir__ = lazy_names(__name__, _LAZY)

def _number(value: Any, where: str) -> float:
    # bool is an int in Python: refuse it explicitly, a machine file's `true` is no gain
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidMachineError(f"{where} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise InvalidMachineError(f"{where} must be finite, got {value!r}")
    return v


@dataclass(frozen=True)
class PidGains:
    """The parameters of one axis's LinuxCNC ``pid`` component (its HAL names).

    Parameters
    ----------
    Pgain : float
        [V/pulse], >= 0.
    Igain : float
        [V/(pulse*s)], >= 0.
    Dgain : float
        [V/(pulse/s)], >= 0.
    bias : float
        Constant output offset [V].
    FF0, FF1, FF2 : float
        Feedforward of the command [V/pulse], its rate [V/(pulse/s)] and its second
        difference [V/(pulse/s^2)], >= 0.
    deadband, maxerror, maxerrorI, maxerrorD, maxcmdD, maxcmdDD : float
        Error deadband [pulse] and clamps of e [pulse], errorI [pulse*s], errorD, cmdD
        [pulse/s] and cmdDD [pulse/s^2], >= 0; 0 means no clamp.

    Raises
    ------
    InvalidMachineError
        Naming the parameter and its value.
    """

    Pgain: float = 0.0
    Igain: float = 0.0
    Dgain: float = 0.0
    bias: float = 0.0
    FF0: float = 0.0
    FF1: float = 0.0
    FF2: float = 0.0
    deadband: float = 0.0
    maxerror: float = 0.0
    maxerrorI: float = 0.0
    maxerrorD: float = 0.0
    maxcmdD: float = 0.0
    maxcmdDD: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            v = _number(getattr(self, f.name), f"pid {f.name}")
            if f.name != "bias" and v < 0:
                raise InvalidMachineError(f"pid {f.name} must be >= 0, got {v!r}")
            object.__setattr__(self, f.name, v)

    @classmethod
    def from_mapping(cls, data: Any, where: str = "pid") -> "PidGains":
        """From a machine file's ``[axes.pid]`` table; unknown keys are refused."""
        if not isinstance(data, dict):
            raise InvalidMachineError(f"{where} must be a table of {', '.join(PID_KEYS)}, "
                                      f"got {data!r}")
        unknown = sorted(set(data) - set(PID_KEYS))
        if unknown:
            raise InvalidMachineError(f"{where}: unknown key(s) {unknown}; expected any of "
                                      f"{list(PID_KEYS)}")
        try:
            return cls(**data)
        except InvalidMachineError as exc:
            raise InvalidMachineError(f"{where}: {exc}") from None

    @classmethod
    def paper_preset(cls, Kp: float, Kd: float, tau: float, Kc: float, Ke: float,
                     feedforward: bool) -> "PidGains":
        """The paper's PD+ (``feedforward=True``) or PD law as ``pid`` parameters."""
        ff = 1.0 if feedforward else 0.0
        return cls(Pgain=Kp, Dgain=Kd / Ke, FF1=ff / (Kc * Ke), FF2=ff * tau / (Kc * Ke))

    def to_dict(self) -> dict:
        """The non-zero parameters, as a machine file's ``[axes.pid]`` table holds them."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name)}


PID_KEYS = tuple(f.name for f in fields(PidGains))
"""Parameters of LinuxCNC's ``pid`` component a machine file may give (missing = 0): the
fields of :class:`PidGains`, the one place a parameter is declared."""


PID_LAW = np.dtype([(key, "f8") for key in PID_KEYS]
                   + [("feedback_deriv", "f8"), ("maxoutput", "f8"), ("period", "f8")])
"""The law of one axis as numbers, the form the compiled loop reads (an array of shape
(n_axes,) of this dtype is a machine's law): :data:`PID_KEYS` in the units of
:class:`PidGains`, then ``feedback_deriv`` (1.0 where errorD is
``cmdD - feedback_velocity``, the ``true`` speed measurement; 0.0 for encoder
differencing), ``maxoutput`` Umax [V] (``inf``: none) and ``period`` Ts [s]."""

PID_STATE = np.dtype([("prev_error", "f8"), ("error_i", "f8"), ("prev_cmd", "f8"),
                      ("cmd_d", "f8"), ("limit_state", "f8")])
"""One axis's memory of the law between samples: e[k-1] [pulse], errorI [pulse*s],
command[k-1] [pulse], cmdD[k-1] [pulse/s], and the output's limit state (+1, -1, 0)."""


def pid_law(gains, max_output: float, sample_period: float,
            feedback_deriv: bool) -> np.ndarray:
    """The law of a sequence of :class:`PidGains`, one per axis: shape (n_axes,), dtype
    :data:`PID_LAW` (read-only)."""
    law = np.zeros(len(gains), dtype=PID_LAW)
    for key in PID_KEYS:
        law[key] = [getattr(g, key) for g in gains]
    law["feedback_deriv"] = 1.0 if feedback_deriv else 0.0
    law["maxoutput"] = max_output
    law["period"] = sample_period
    law.flags.writeable = False
    return law


def pid_state(command: np.ndarray) -> np.ndarray:
    """A law at rest with the command (and the feedback) at ``command`` [pulse], shape
    (n_axes,): shape (n_axes,), dtype :data:`PID_STATE`."""
    st = np.zeros(len(command), dtype=PID_STATE)
    st["prev_cmd"] = command
    return st


def loop_poles(gains: PidGains, Ad: np.ndarray, Bd: np.ndarray, sample_period: float,
               mechanical_gain: float, feedback_deriv: bool) -> np.ndarray:
    """Poles of one axis's closed loop, linear (no clamps), as the discrete loop runs it.

    The state is ``[w, theta, theta_prev, errorI]`` (``theta_prev`` only with encoder
    differencing, ``errorI`` only with an integral gain); the command is an input and
    does not move the poles.

    Parameters
    ----------
    gains : PidGains
    Ad : ndarray, shape (2, 2)
    Bd : ndarray, shape (2,)
        The plant's ZOH matrices for the state ``[w, theta]``.
    sample_period : float
        Ts [s].
    mechanical_gain : float
        Ke [pulse/rad], the feedback velocity being ``Ke*w`` with ``feedback_deriv``.
    feedback_deriv : bool

    Returns
    -------
    ndarray, shape (n,), complex
    """
    Ts, Ke = sample_period, mechanical_gain
    P, I, D = gains.Pgain, gains.Igain, gains.Dgain
    # u as a row over [w, theta, theta_prev, errorI_prev] with command = 0:
    # e = -theta; errorI = errorI_prev - theta*Ts
    # errorD = (-theta + theta_prev)/Ts  or  -Ke*w
    if feedback_deriv:
        u = np.array([-D * Ke, -P - I * Ts, 0.0, I])
    else:
        u = np.array([0.0, -P - I * Ts - D / Ts, D / Ts, I])
    A = np.zeros((4, 4))
    A[0, :2] = Ad[0]
    A[1, :2] = Ad[1]
    A[0] += Bd[0] * u
    A[1] += Bd[1] * u
    A[2, 1] = 1.0
    A[3] = np.array([0.0, -Ts, 0.0, 1.0])
    keep = [0, 1] + ([] if feedback_deriv else [2]) + ([3] if I != 0.0 else [])
    return np.linalg.eigvals(A[np.ix_(keep, keep)])
