"""Machine description: servo axes, controller gains, drive limit, sample period.

A :class:`Machine` is a value object: named :class:`Axis` entries (plant and gains,
docs/model.md#servo-axis to #controllers), the drive limit ``max_drive`` (Umax), the ``sample_period`` (Ts) shared by
interpolation and control, the control law and how speed is measured, and the length of one
encoder pulse so that paths drawn in mm can run on it. It knows nothing of NURBS.

Built-in preset ``die-bonder``: Table 1 of Yeh & Sun (2008), Umax = 10 V, Ts = 1 ms,
1 pulse = 1 um. Users bring their own identified axes in a TOML or JSON machine file
(:func:`load_machine`); see ``examples/die_bonder.toml``.

Glossary (docs/model.md#units)
-------------------------
tau : time constant [s]; Kc : electrical gain [(rad/s)/V]; Ke : mechanical gain
[pulse/rad]; Kp : position gain [V/pulse]; Kd : speed gain [V/(rad/s)];
Umax : drive limit [V]; Ts : sample period [s].

Why one module of about 850 lines: :class:`Machine` and :class:`Axis` (about 530 of them)
validate every key a machine file may hold (gains or PID tables, the real-machine
effects, rotary axes) and read and write them (``from_dict``, ``to_dict``); the presets
beside them are built from the same keys. A machine is one value object, checked in one
place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .control import PidGains, loop_poles, pid_law
from ._runtime.io import parse_json_or_toml, read_text_file
from .errors import InvalidMachineError, PathFileError
from .limits import MIN_SAMPLE_PERIOD
from .plant.linear import linear_loop_poles
from .servo import ServoPlant, zoh_matrices

class UnstableModeWarning(UserWarning):
    """A machine whose linear loop (law, plant, delay) is stable rigid but unstable with
    an axis's two-mass mode (:meth:`Machine.mode_loop_poles`): runs on it ring the mode
    into a limit cycle against Umax. Named axis, mode and largest pole radius."""


MAX_MACHINE_FILE_BYTES = 1_000_000
"""Largest machine file read [byte] (a machine of 6 axes takes about 1 kB)."""

__all__ = ["Axis", "Disturbance", "Machine", "CONTROLLERS", "ENCODERS", "ENCODER_MASSES", "ROTARY_AXIS_NAMES",
           "SPEED_MEASUREMENTS", "LENGTH_UNITS_UM", "die_bonder", "die_bonder_real",
           "builtin_machine", "BUILTIN_MACHINES", "load_machine", "UnstableModeWarning",
           "mode_safe_gains", "MODE_BANDWIDTH_RATIO", "MODE_SAFE_DAMPING"]

CONTROLLERS = ("pd+", "pd", "pid")
"""Control laws: PD+ (eq. 2.12 / 3.3, the default), plain PD (eq. 2.4), and LinuxCNC's
``pid`` component with each axis's own parameters (:class:`nurbsmotion.control.PidGains`).
All run as the ``pid`` law: PD and PD+ are its presets."""

ENCODERS = ("exact", "counts")
"""How the position is read: an exact float, or whole counts of an incremental encoder."""

ENCODER_MASSES = ("motor", "load")
"""Which mass of a two-mass axis the encoder reads."""

MAX_DELAY_SAMPLES = 1000
"""Longest delay a machine may have [samples] (its drives on their way are kept)."""

AXIS_EFFECT_KEYS = ("coulomb_friction", "stiction", "disturbance", "resonance_frequency",
                    "resonance_damping", "load_fraction", "encoder_on")
"""Optional per-axis keys of the machine as it is (issue 32)."""

ROTARY_AXIS_NAMES = ("a", "b", "c")
"""Axis names of rotary axes (G-code's A, B, C, in degrees): such an axis may carry
``pulses_per_degree`` and a path that moves it runs on it in degrees (issue 36)."""

MACHINE_EFFECT_KEYS = ("encoder", "measurement_noise", "seed", "delay", "dac_bits")
"""Optional machine-level keys of the machine as it is (issue 32)."""

SPEED_MEASUREMENTS = ("encoder", "true")
"""Speed used by the controller: encoder differencing (default) or the true motor speed."""

LENGTH_UNITS_UM = {"um": 1.0, "mm": 1e3, "cm": 1e4, "m": 1e6, "in": 25_400.0, "inch": 25_400.0}
"""Length units a path may be drawn in, in micrometres."""


def _number(value: Any, name: str) -> float:
    """``value`` as a float; booleans and strings are never numbers."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer,
                                                                   np.floating)):
        raise InvalidMachineError(
            f"{name} must be a number, got {value!r:.60} ({type(value).__name__})")
    try:
        return float(value)
    except OverflowError:
        raise InvalidMachineError(f"{name} is too large for a double: {value!r:.60}") from None


def _positive(value: Any, name: str) -> float:
    v = _number(value, name)
    if not (math.isfinite(v) and v > 0):
        raise InvalidMachineError(f"{name} must be finite and > 0, got {value!r}")
    return v


def _non_negative(value: Any, name: str) -> float:
    v = _number(value, name)
    if not (math.isfinite(v) and v >= 0):
        raise InvalidMachineError(f"{name} must be finite and >= 0, got {value!r}")
    return v


@dataclass(frozen=True)
class Disturbance:
    """A load step on an axis: from ``at`` [s] (>= 0) on, ``drive`` [V] more acts on it
    (an ``[[axes.disturbance]]`` table of a machine file)."""

    at: float
    drive: float

    def __post_init__(self):
        object.__setattr__(self, "at", _non_negative(self.at, "disturbance at"))
        d = _number(self.drive, "disturbance drive")
        if not math.isfinite(d):
            raise InvalidMachineError(f"disturbance drive must be finite, got {self.drive!r}")
        object.__setattr__(self, "drive", d)

    @classmethod
    def from_mapping(cls, data: Any, where: str = "") -> "Disturbance":
        if not isinstance(data, dict) or set(data) != {"at", "drive"}:
            raise InvalidMachineError(
                f"{where}a disturbance must be a table with exactly 'at' [s] and 'drive' "
                f"[V], got {data!r:.80}")
        return cls(data["at"], data["drive"])

    def to_dict(self) -> dict:
        return {"at": self.at, "drive": self.drive}


@dataclass(frozen=True)
class Axis:
    """One servo axis: first-order speed loop plus integrator, and its PD gains.

    Parameters
    ----------
    name : str
        Axis label (``"x"``, ``"y"``, ...), used in file columns and summaries.
    time_constant : float
        tau [s], > 0.
    electrical_gain : float
        Kc [(rad/s)/V], > 0.
    mechanical_gain : float
        Ke [pulse/rad], > 0.
    position_gain : float
        Kp [V/pulse], >= 0 (PD and PD+ machines).
    speed_gain : float
        Kd [V/(rad/s)], >= 0 (PD and PD+ machines).
    pid : PidGains, optional
        LinuxCNC ``pid`` parameters of this axis (machines with ``controller="pid"``).
    coulomb_friction : float
        Coulomb friction on the motor, as an equivalent drive [V], >= 0 (issue 32;
        :mod:`nurbsmotion.plant`).
    stiction : float
        Breakaway drive of the motor at rest [V], >= 0; a motor at rest stays at rest
        while the net drive on it is within ``max(stiction, coulomb_friction)``.
    disturbance : tuple of Disturbance
        Load steps: from ``at`` [s] on, ``drive`` [V] more acts on the axis.
    resonance_frequency : float
        Natural frequency of the two-mass axis's mode [Hz], >= 0; 0 for a rigid axis.
    resonance_damping : float
        Its damping ratio, in ``[1/(2*wn*tau), 1)`` (the viscous damping of the axis is
        part of it).
    load_fraction : float
        The load's share of the axis's inertia, in (0, 1) (two-mass axes).
    encoder_on : {"motor", "load"}
        Which mass the encoder reads (two-mass axes; the tool is the load).
    pulses_per_degree : float, optional
        Encoder pulses per degree of a rotary axis [pulse/deg], > 0; only on an axis named
        ``a``, ``b`` or ``c`` (:data:`ROTARY_AXIS_NAMES`). A path's rotary coordinate
        [deg] runs on the axis at this scale, its linear ones at ``pulse_length_um``.
        None: the axis is linear (or a rotary axis no path moves).
    """

    name: str
    time_constant: float
    electrical_gain: float
    mechanical_gain: float
    position_gain: float = 0.0
    speed_gain: float = 0.0
    pid: PidGains | None = None
    coulomb_friction: float = 0.0
    stiction: float = 0.0
    disturbance: tuple = ()
    resonance_frequency: float = 0.0
    resonance_damping: float = 0.0
    load_fraction: float = 0.5
    encoder_on: str = "motor"
    pulses_per_degree: float | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise InvalidMachineError(
                f"axis name must be a short identifier such as 'x', got {self.name!r}"
            )
        where = f"axis {self.name!r}: "
        for f in ("time_constant", "electrical_gain", "mechanical_gain"):
            object.__setattr__(self, f, _positive(getattr(self, f), where + f))
        for f in ("position_gain", "speed_gain"):
            object.__setattr__(self, f, _non_negative(getattr(self, f), where + f))
        if self.pid is not None and not isinstance(self.pid, PidGains):
            raise InvalidMachineError(f"{where}pid must be a PidGains, got {self.pid!r}")
        for f in ("coulomb_friction", "stiction", "resonance_frequency",
                  "resonance_damping"):
            object.__setattr__(self, f, _non_negative(getattr(self, f), where + f))
        object.__setattr__(self, "load_fraction",
                           _number(self.load_fraction, where + "load_fraction"))
        if not 0.0 < self.load_fraction < 1.0:
            raise InvalidMachineError(
                f"{where}load_fraction must be in (0, 1), got {self.load_fraction!r}")
        if self.encoder_on not in ENCODER_MASSES:
            raise InvalidMachineError(f"{where}encoder_on must be one of {ENCODER_MASSES}, "
                                      f"got {self.encoder_on!r}")
        if self.resonance_frequency > 0:
            lowest = 1.0 / (4.0 * math.pi * self.resonance_frequency * self.time_constant)
            if not lowest <= self.resonance_damping < 1.0:
                raise InvalidMachineError(
                    f"{where}resonance_damping must be in [{lowest:.6g}, 1) for a "
                    f"{self.resonance_frequency:g} Hz mode with tau = "
                    f"{self.time_constant:g} s (the axis's own viscous damping is part "
                    f"of it), got {self.resonance_damping!r}")
        if self.pulses_per_degree is not None:
            if self.name.lower() not in ROTARY_AXIS_NAMES:
                raise InvalidMachineError(
                    f"{where}pulses_per_degree is for a rotary axis, named a, b or c (as "
                    f"G-code names them), not {self.name!r}")
            object.__setattr__(self, "pulses_per_degree",
                               _positive(self.pulses_per_degree, where + "pulses_per_degree"))
        steps = self.disturbance
        if isinstance(steps, (Disturbance, dict)) or not isinstance(steps, (tuple, list)):
            raise InvalidMachineError(
                f"{where}disturbance must be a list of Disturbance (at, drive), got "
                f"{steps!r:.60}")
        object.__setattr__(self, "disturbance", tuple(
            d if isinstance(d, Disturbance) else Disturbance.from_mapping(d, where)
            for d in steps))

    @property
    def has_effects(self) -> bool:
        """Whether any key of the machine as it is (friction, load steps, a mode) is set."""
        return bool(self.coulomb_friction or self.stiction or self.disturbance
                    or self.resonance_frequency)

    def effects(self) -> dict:
        """The axis's effect keys, as :func:`nurbsmotion.plant.make_stage` reads them."""
        return {"coulomb_friction": self.coulomb_friction, "stiction": self.stiction,
                "disturbance": [d.to_dict() for d in self.disturbance],
                "resonance_frequency": self.resonance_frequency,
                "resonance_damping": self.resonance_damping,
                "load_fraction": self.load_fraction, "encoder_on": self.encoder_on}


MAX_DRIVE_ACCELERATION = 1e150
"""Largest full-drive acceleration of an axis, ``max_drive * Kc * Ke / tau`` [pulse/s^2]:
the planner squares speeds and accelerations (1.8e308 is the largest double). Real
machines are below 1e12."""

@dataclass(frozen=True)
class Machine:
    """A multi-axis motion system with a saturating drive.

    Parameters
    ----------
    axes : tuple of Axis
        One entry per path axis, in the path's column order.
    max_drive : float
        Umax [V], > 0; ``math.inf`` for an ideal, unsaturated drive.
    sample_period : float
        Ts [s], > 0, shared by the interpolator and the controller.
    controller : {"pd+", "pd", "pid"}
        Control law (docs/model.md#controllers and #beyond-the-paper): the paper's PD+ or PD from each axis's Kp
        and Kd, or LinuxCNC's ``pid`` from each axis's ``pid`` parameters.
    speed_measurement : {"encoder", "true"}
        ``"encoder"``: speed by differencing positions (eq. 3.3 (docs/model.md#controllers)); ``"true"``: the
        simulated motor speed.
    pulse_length_um : float
        Length of one encoder pulse [um], to convert paths drawn in mm, m or inch.
    name : str
        Label carried into summaries.
    encoder : {"exact", "counts"}
        How the controller reads the position: exact, or in whole counts of an
        incremental encoder zeroed at the start (``start + floor(theta - start)``).
    measurement_noise : float
        Gaussian noise on the position read [pulse, standard deviation], >= 0.
    seed : int
        Seed of that noise (the same seed gives the same draws), >= 0.
    delay : float
        From the sample instant until the drive reaches the plant [s], >= 0 (at most
        :data:`MAX_DELAY_SAMPLES` samples); the previous drive holds meanwhile.
    dac_bits : int, optional
        The drive is quantised to this many bits over ``[-Umax, Umax)`` (2 to 32).

    The last five and each axis's ``coulomb_friction``, ``stiction``, ``disturbance``,
    ``resonance_frequency``, ``resonance_damping``, ``load_fraction`` and ``encoder_on``
    describe the machine as it is (:mod:`nurbsmotion.plant`); with none of them set the
    plant is the ideal one of docs/model.md#servo-axis.

    Raises
    ------
    InvalidMachineError
        Naming the bad field, or the axis whose closed loop (its law and plant, linear,
        as sampled, with its delay) has a pole on or outside the unit circle: an
        unstable machine is refused, not simulated. A two-mass mode is not part of that
        check (:meth:`mode_loop_poles` gives the loop's poles with it).
    """

    axes: tuple[Axis, ...]
    max_drive: float
    sample_period: float
    controller: str = "pd+"
    speed_measurement: str = "encoder"
    pulse_length_um: float = 1.0
    name: str = "custom"
    encoder: str = "exact"
    measurement_noise: float = 0.0
    seed: int = 0
    delay: float = 0.0
    dac_bits: int | None = None
    _arrays: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        axes = tuple(self.axes)
        if not axes or not all(isinstance(a, Axis) for a in axes):
            raise InvalidMachineError("a machine needs at least one Axis in 'axes'")
        names = [a.name for a in axes]
        if len(set(names)) != len(names):
            raise InvalidMachineError(f"axis names must be unique, got {names}")
        object.__setattr__(self, "axes", axes)
        if self.max_drive != math.inf:  # an ideal drive (no saturation) is allowed
            object.__setattr__(self, "max_drive", _positive(self.max_drive, "max_drive"))
        object.__setattr__(self, "sample_period", _positive(self.sample_period, "sample_period"))
        if self.max_drive != math.inf:
            for a in axes:  # the planner squares speeds and accelerations
                accel = self.max_drive * a.electrical_gain * a.mechanical_gain / a.time_constant
                if not accel <= MAX_DRIVE_ACCELERATION:
                    raise InvalidMachineError(
                        f"axis {a.name!r}: max_drive * Kc * Ke / time constant = {accel:.3g} "
                        f"pulse/s^2 (max_drive {self.max_drive:g} V) is beyond "
                        f"{MAX_DRIVE_ACCELERATION:g} (machine.MAX_DRIVE_ACCELERATION): its "
                        "square cannot be computed in double precision")
        if self.sample_period < MIN_SAMPLE_PERIOD:
            raise InvalidMachineError(
                f"sample_period {self.sample_period:g} s is below the minimum of "
                f"{MIN_SAMPLE_PERIOD:g} s (machine.MIN_SAMPLE_PERIOD, a 100 kHz loop): "
                "is it in seconds?")
        object.__setattr__(
            self, "pulse_length_um", _positive(self.pulse_length_um, "pulse_length_um")
        )
        if not isinstance(self.name, str):
            raise InvalidMachineError(f"name must be a string, got {self.name!r:.60}")
        if self.controller not in CONTROLLERS:
            raise InvalidMachineError(
                f"controller must be one of {CONTROLLERS}, got {self.controller!r}"
            )
        if self.speed_measurement not in SPEED_MEASUREMENTS:
            raise InvalidMachineError(
                f"speed_measurement must be one of {SPEED_MEASUREMENTS}, "
                f"got {self.speed_measurement!r}"
            )
        for a in axes:
            if (self.controller == "pid") != (a.pid is not None):
                raise InvalidMachineError(
                    f"axis {a.name!r}: " + ("a controller = 'pid' machine needs the axis's "
                                            "pid parameters" if a.pid is None else
                                            f"pid parameters need controller = 'pid', not "
                                            f"{self.controller!r}"))
        self._check_effects()
        self._check_stable()
        self._warn_unstable_mode()

    def _check_effects(self) -> None:
        if self.encoder not in ENCODERS:
            raise InvalidMachineError(f"encoder must be one of {ENCODERS}, got {self.encoder!r}")
        object.__setattr__(self, "measurement_noise",
                           _non_negative(self.measurement_noise, "measurement_noise"))
        if (isinstance(self.seed, (bool, np.bool_))
                or not isinstance(self.seed, (int, np.integer)) or not 0 <= self.seed < 2**63):
            raise InvalidMachineError(f"seed must be an integer in [0, 2**63), got "
                                      f"{self.seed!r:.60}")
        object.__setattr__(self, "seed", int(self.seed))
        delay = _non_negative(self.delay, "delay")
        if delay > MAX_DELAY_SAMPLES * self.sample_period:
            raise InvalidMachineError(
                f"delay must be at most {MAX_DELAY_SAMPLES} samples "
                f"({MAX_DELAY_SAMPLES * self.sample_period:g} s), got {self.delay!r}")
        object.__setattr__(self, "delay", delay)
        bits = self.dac_bits
        if bits is not None:
            if (isinstance(bits, (bool, np.bool_)) or not isinstance(bits, (int, np.integer))
                    or not 2 <= bits <= 32):
                raise InvalidMachineError(f"dac_bits must be an integer from 2 to 32, got "
                                          f"{bits!r:.60}")
            if not math.isfinite(self.max_drive):
                raise InvalidMachineError(f"dac_bits = {bits} quantises over +-max_drive, "
                                          "which must then be finite, got inf")
            object.__setattr__(self, "dac_bits", int(bits))
        for a in self.axes:
            brk = max(a.stiction, a.coulomb_friction)
            if not brk < self.max_drive:
                raise InvalidMachineError(
                    f"axis {a.name!r}: stiction {a.stiction:g} V and coulomb_friction "
                    f"{a.coulomb_friction:g} V must be below max_drive {self.max_drive:g} V "
                    "(else the axis could never move)")

    @property
    def has_effects(self) -> bool:
        """Whether any key of the machine as it is is set (else its plant is ideal)."""
        return bool(self.encoder != "exact" or self.measurement_noise or self.delay
                    or self.dac_bits is not None or any(a.has_effects for a in self.axes))

    def effects(self) -> dict:
        """The effect keys, as :func:`nurbsmotion.plant.make_stage` reads them."""
        return {"encoder": self.encoder, "measurement_noise": self.measurement_noise,
                "seed": self.seed, "delay": self.delay, "dac_bits": self.dac_bits,
                "axes": [a.effects() for a in self.axes]}

    def _check_stable(self) -> None:
        feedback_deriv = self.speed_measurement == "true"
        for a, gains in zip(self.axes, self.pid_gains):
            Ad, Bd = zoh_matrices(a.time_constant, a.electrical_gain, a.mechanical_gain,
                                  self.sample_period)
            if not (np.all(np.isfinite(Ad)) and np.all(np.isfinite(Bd))):
                # Ts / tau beyond double precision (a subnormal tau): numpy's eigvals
                # would say "Array must not contain infs or NaNs"
                raise InvalidMachineError(
                    f"axis {a.name!r}: its sampled plant cannot be computed in double "
                    f"precision (time constant {a.time_constant:g} s, Kc "
                    f"{a.electrical_gain:g}, Ke {a.mechanical_gain:g} at Ts = "
                    f"{self.sample_period:g} s): its zero-order-hold matrices overflow")
            # The delay is part of the loop the machine is refused for; a mode is not (it
            # may well destabilise the linear loop: the run shows what that does).
            if self.delay:
                poles = linear_loop_poles(
                    gains, a.time_constant, a.electrical_gain, a.mechanical_gain,
                    self.sample_period, feedback_deriv, self.delay)
            else:
                poles = loop_poles(gains, Ad, Bd, self.sample_period, a.mechanical_gain,
                                   feedback_deriv)
            radius = float(np.max(np.abs(poles)))
            self._arrays["pole_radius"] = max(radius, self._arrays.get("pole_radius", 0.0))
            self._arrays.setdefault("poles", []).append(poles)
            if not radius < 1.0:
                shown = ", ".join(f"{p.real:.6g}{p.imag:+.6g}j" for p in poles)
                extra = f", delay = {self.delay:g} s" if self.delay else ""
                raise InvalidMachineError(
                    f"axis {a.name!r}: the closed loop is unstable at Ts = "
                    f"{self.sample_period:g} s{extra}: poles {shown} (largest |p| = "
                    f"{radius:.6g}, must be < 1); change the gains or the sample period"
                    + (" or shorten the delay" if self.delay else ""))

    def _warn_unstable_mode(self) -> None:
        """Warn (:class:`UnstableModeWarning`) per axis whose loop with its mode has a
        pole on or outside the unit circle. A warning, not a refusal: the mode is the
        least certain part of a machine file (identified within +-10 %, often not at all),
        a machine given as ``--plant`` runs under another machine's gains (its own are
        not used), and the run is how the user sees what the mode does (issue 33)."""
        if not any(a.resonance_frequency for a in self.axes):
            return
        import warnings

        for a, poles in zip(self.axes, self.mode_loop_poles()):
            if not a.resonance_frequency:
                continue
            radius = float(np.max(np.abs(poles)))
            if not radius < 1.0:
                warnings.warn(
                    f"machine {self.name!r}, axis {a.name!r}: the closed loop with its "
                    f"{a.resonance_frequency:g} Hz mode (damping {a.resonance_damping:g}"
                    + (f", delay {self.delay:g} s" if self.delay else "")
                    + f") is unstable: largest pole radius {radius:.4g} (must be < 1); a "
                    "run on it rings the mode into a limit cycle. Lower the gains below "
                    "the mode (machine.mode_safe_gains) or add damping",
                    UnstableModeWarning, stacklevel=4)

    @property
    def n_axes(self) -> int:
        return len(self.axes)

    @property
    def axis_names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.axes)

    def _column(self, attr: str) -> np.ndarray:
        if attr not in self._arrays:
            arr = np.array([getattr(a, attr) for a in self.axes])
            arr.flags.writeable = False
            self._arrays[attr] = arr
        return self._arrays[attr]

    @property
    def tau(self) -> np.ndarray:
        """Time constants, shape (n_axes,) [s]."""
        return self._column("time_constant")

    @property
    def Kc(self) -> np.ndarray:
        """Electrical gains, shape (n_axes,) [(rad/s)/V]."""
        return self._column("electrical_gain")

    @property
    def Ke(self) -> np.ndarray:
        """Mechanical gains, shape (n_axes,) [pulse/rad]."""
        return self._column("mechanical_gain")

    @property
    def Kp(self) -> np.ndarray:
        """Position gains, shape (n_axes,) [V/pulse]."""
        return self._column("position_gain")

    @property
    def Kd(self) -> np.ndarray:
        """Speed gains, shape (n_axes,) [V/(rad/s)]."""
        return self._column("speed_gain")

    @property
    def pid_gains(self) -> tuple[PidGains, ...]:
        """Each axis's law as LinuxCNC ``pid`` parameters (PD and PD+ as presets)."""
        if self.controller == "pid":
            return tuple(a.pid for a in self.axes)
        return tuple(PidGains.paper_preset(a.position_gain, a.speed_gain, a.time_constant,
                                           a.electrical_gain, a.mechanical_gain,
                                           self.controller == "pd+") for a in self.axes)

    def closed_loop_poles(self) -> list:
        """Poles of each axis's closed loop (its law and plant, linear, sampled): one
        complex array per axis (:func:`nurbsmotion.control.loop_poles`)."""
        return [p.copy() for p in self._arrays["poles"]]

    def mode_loop_poles(self) -> list:
        """Poles of each axis's linear closed loop with its delay *and* its two-mass mode
        (:func:`nurbsmotion.plant.linear_loop_poles`): one complex array per axis. Not a
        reason to refuse the machine: a mode the gains destabilise is what a run on it
        shows (a limit cycle against Umax)."""
        feedback_deriv = self.speed_measurement == "true"
        return [linear_loop_poles(g, a.time_constant, a.electrical_gain, a.mechanical_gain,
                                  self.sample_period, feedback_deriv, self.delay,
                                  a.resonance_frequency, a.resonance_damping,
                                  a.load_fraction, a.encoder_on)
                for a, g in zip(self.axes, self.pid_gains)]

    @property
    def loop_pole_radius(self) -> float:
        """The largest pole radius of the axes' closed loops (linear, sampled), < 1."""
        return self._arrays["pole_radius"]

    def law(self) -> np.ndarray:
        """The control law of every axis as numbers (shape (n_axes,), dtype :data:`nurbsmotion.control.PID_LAW`)."""
        if "law" not in self._arrays:
            self._arrays["law"] = pid_law(self.pid_gains, self.max_drive, self.sample_period,
                                          self.speed_measurement == "true")
        return self._arrays["law"]

    def plant(self) -> ServoPlant:
        """The machine's own plant, at rest at the path's start (made once)."""
        if "plant" not in self._arrays:
            self._arrays["plant"] = ServoPlant.of_machine(self)
        return self._arrays["plant"]

    @property
    def max_axis_speed(self) -> np.ndarray:
        """Steady speed at full drive, Umax*Kc*Ke, shape (n_axes,) [pulse/s]."""
        return self.max_drive * self.Kc * self.Ke

    def pulses_per_unit(self, units: str | None) -> float:
        """Pulses per path length unit: 1 for ``"pulse"`` (or no unit), else by
        :data:`LENGTH_UNITS_UM` and ``pulse_length_um``."""
        if units is None or units == "pulse":
            return 1.0
        if units not in LENGTH_UNITS_UM:
            raise InvalidMachineError(
                f"path unit {units!r} is unknown; use 'pulse' or one of {sorted(LENGTH_UNITS_UM)}"
            )
        return LENGTH_UNITS_UM[units] / self.pulse_length_um

    def pulses_per_axis_unit(self, units: str | None) -> np.ndarray:
        """Pulses per unit of each axis, shape (n_axes,): ``pulses_per_degree`` [pulse/deg]
        for a rotary axis that has it, :meth:`pulses_per_unit` of the path's ``units``
        for the others."""
        per_unit = self.pulses_per_unit(units)
        return np.array([per_unit if a.pulses_per_degree is None else a.pulses_per_degree
                         for a in self.axes])

    @property
    def rotary_axes(self) -> tuple[str, ...]:
        """Names of the axes that have ``pulses_per_degree`` (run in degrees)."""
        return tuple(a.name for a in self.axes if a.pulses_per_degree is not None)

    def check_path(self, n_axes: int) -> None:
        """Raise :class:`InvalidMachineError` unless the path has one column per axis."""
        if n_axes != self.n_axes:
            raise InvalidMachineError(
                f"the path has {n_axes} axes but machine {self.name!r} has {self.n_axes} "
                f"({', '.join(self.axis_names)})"
            )

    def with_options(self, **changes: Any) -> "Machine":
        """A copy with some fields replaced (validated again)."""
        return replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain-Python form, the schema of a machine file."""
        return {
            "name": self.name,
            "max_drive": self.max_drive,
            "sample_period": self.sample_period,
            "controller": self.controller,
            "speed_measurement": self.speed_measurement,
            "pulse_length_um": self.pulse_length_um,
            **{k: getattr(self, k) for k in MACHINE_EFFECT_KEYS
               if getattr(self, k) != _MACHINE_DEFAULTS[k]},
            "axes": [_axis_dict(a, self.controller) for a in self.axes],
        }

    @classmethod
    def from_dict(cls, data: dict, source: str | None = None) -> "Machine":
        """Build from the machine-file schema; errors name the field (and the file)."""
        if not isinstance(data, dict):
            raise PathFileError("a machine file must hold a table/object", source)
        known = set(cls.__dataclass_fields__) - {"_arrays"}
        unknown = set(data) - known
        if unknown:
            raise PathFileError(
                f"unknown machine field(s) {sorted(unknown)}; expected {sorted(known)}", source
            )
        for key in ("axes", "max_drive", "sample_period"):
            if key not in data:
                raise PathFileError(f"machine field {key!r} is missing", source)
        umax = data["max_drive"]
        if isinstance(umax, float) and not math.isfinite(umax):
            # an ideal drive is a library value (max_drive=math.inf), not a machine's:
            # planned plans within +-Umax and diverged on one (issue 37)
            raise PathFileError(f"machine field 'max_drive' must be a finite number > 0 [V], "
                                f"got {umax!r}", source)
        if not isinstance(data["axes"], list):
            raise PathFileError("machine field 'axes' must be a list of axis tables", source)
        pid = data.get("controller") == "pid"
        plant_fields = {"name", "time_constant", "electrical_gain", "mechanical_gain"}
        axis_fields = plant_fields | ({"pid"} if pid else {"position_gain", "speed_gain"})
        axes = []
        for i, entry in enumerate(data["axes"]):
            if (not isinstance(entry, dict) or not axis_fields <= set(entry)
                    or set(entry) - axis_fields - set(AXIS_EFFECT_KEYS) - {"pulses_per_degree"}):
                got = sorted(entry) if isinstance(entry, dict) else entry
                raise PathFileError(
                    f"axes[{i}] must have exactly the fields {sorted(axis_fields)} "
                    f"(controller {data.get('controller', 'pd+')!r}), and optionally "
                    f"{list(AXIS_EFFECT_KEYS)} and pulses_per_degree (a rotary axis), got {got}",
                    source,
                )
            try:
                if pid:
                    name = entry.get("name")
                    entry = {**entry, "pid": PidGains.from_mapping(
                        entry["pid"], f"axis {name!r} pid")}
                if "disturbance" in entry:
                    steps = entry["disturbance"]
                    if not isinstance(steps, list):
                        raise InvalidMachineError(
                            f"disturbance must be a list of tables [[axes.disturbance]], "
                            f"got {steps!r:.60}")
                    entry = {**entry, "disturbance": tuple(
                        Disturbance.from_mapping(d, "disturbance: ") for d in steps)}
                axes.append(Axis(**entry))
            except InvalidMachineError as exc:
                raise PathFileError(f"axes[{i}]: {exc}", source) from None
        try:
            return cls(**{**data, "axes": tuple(axes)})
        except InvalidMachineError as exc:
            raise PathFileError(str(exc), source) from None


def _axis_dict(axis: Axis, controller: str) -> dict:
    """One axis as a machine file's ``[[axes]]`` table holds it."""
    out = {k: getattr(axis, k) for k in ("name", "time_constant", "electrical_gain",
                                          "mechanical_gain")}
    if controller == "pid":
        out["pid"] = axis.pid.to_dict()
    else:
        out["position_gain"], out["speed_gain"] = axis.position_gain, axis.speed_gain
    if axis.pulses_per_degree is not None:
        out["pulses_per_degree"] = axis.pulses_per_degree
    for k in AXIS_EFFECT_KEYS:  # only those set: an ideal machine's file is unchanged
        value = getattr(axis, k)
        if value != _AXIS_DEFAULTS[k]:
            out[k] = [d.to_dict() for d in value] if k == "disturbance" else value
    return out


_AXIS_DEFAULTS = {k: Axis.__dataclass_fields__[k].default for k in AXIS_EFFECT_KEYS}
_MACHINE_DEFAULTS = {k: Machine.__dataclass_fields__[k].default for k in MACHINE_EFFECT_KEYS}


def die_bonder(**changes: Any) -> Machine:
    """The die-bonder of Yeh & Sun (2008), Table 1 (docs/model.md#servo-axis).

    Umax = 10 V, Ts = 1 ms, PD+ with encoder differencing, 1 pulse = 1 um. Keyword
    arguments replace fields (e.g. ``max_drive=math.inf``).
    """
    m = Machine(
        axes=(
            Axis("x", 0.31, 2506.17, 1591.5494, 0.0136, 0.03),
            Axis("y", 0.135, 3156.23, 1591.5494, 0.00577, 0.028),
        ),
        max_drive=10.0,
        sample_period=1e-3,
        name="die-bonder",
    )
    return m.with_options(**changes) if changes else m


MODE_BANDWIDTH_RATIO = 4.0
"""The mode's frequency over the rigid loop's natural frequency in
:func:`mode_safe_gains`: the usual rule for a position loop on a compliant axis (its
bandwidth a quarter to a fifth of the first mode), which leaves the loop with the mode
stable for the mode's frequency, tau and Kc each +-10 % (docs/model.md#real-machine)."""

MODE_SAFE_DAMPING = 1.0 / math.sqrt(2.0)
"""The rigid loop's damping ratio in :func:`mode_safe_gains` (Butterworth: no overshoot
beyond 4.3 %, the flattest response)."""


def mode_safe_gains(tau: float, Kc: float, Ke: float, resonance_frequency: float,
                    ratio: float = MODE_BANDWIDTH_RATIO,
                    damping: float = MODE_SAFE_DAMPING) -> tuple[float, float]:
    """PD gains that place the rigid axis's closed-loop poles at natural frequency
    ``wn = 2*pi*resonance_frequency/ratio`` with damping ratio ``damping``.

    The rigid loop of the PD / PD+ law (docs/model.md#controllers) has the characteristic
    polynomial ``tau*s^2 + (1 + Kc*Kd)*s + Kc*Ke*Kp`` (continuous; the feedforward does not
    move its poles), so ``Kp = tau*wn^2/(Kc*Ke)`` and ``Kd = (2*damping*wn*tau - 1)/Kc``.

    Parameters
    ----------
    tau : float
        Time constant [s].
    Kc : float
        Electrical gain [(rad/s)/V].
    Ke : float
        Mechanical gain [pulse/rad].
    resonance_frequency : float
        The axis's first mode [Hz], > 0.
    ratio, damping : float
        See :data:`MODE_BANDWIDTH_RATIO`, :data:`MODE_SAFE_DAMPING`.

    Returns
    -------
    (Kp, Kd) : tuple of float
        [V/pulse], [V/(rad/s)].

    Raises
    ------
    InvalidMachineError
        When the axis's own viscous damping already exceeds ``damping`` at ``wn``
        (Kd would be negative).
    """
    wn = 2.0 * math.pi * _positive(resonance_frequency, "resonance_frequency") \
        / _positive(ratio, "ratio")
    Kp = tau * wn * wn / (Kc * Ke)
    Kd = (2.0 * damping * wn * tau - 1.0) / Kc
    if not Kd >= 0.0:
        raise InvalidMachineError(
            f"mode_safe_gains: the axis's own damping 1/(2*wn*tau) = "
            f"{1.0 / (2.0 * wn * tau):.4g} exceeds damping {damping:g} at wn = {wn:.4g} "
            "rad/s: no speed gain places it")
    return Kp, Kd


REAL_AXIS_KEYS = {"coulomb_friction": 0.3, "stiction": 0.4, "resonance_frequency": 100.0,
                  "resonance_damping": 0.02, "load_fraction": 0.5, "encoder_on": "motor"}
"""The per-axis effects of the ``die-bonder-real`` preset: representative of such machines,
not measured on the paper's."""


def die_bonder_real(**changes: Any) -> Machine:
    """The die-bonder as it is (issue 32): :func:`die_bonder` read in whole 1-um counts,
    a 16-bit DAC, 0.5 ms of delay, and on each axis 0.3 V Coulomb friction, 0.4 V
    stiction and a 100 Hz mode of damping 0.02 with the encoder on the motor.

    Its gains are not the paper's: with the mode those are unstable (pole radii 1.09 x,
    1.28 y). They are :func:`mode_safe_gains` of each axis at its mode, as a vendor
    would tune a compliant axis (issue 33; docs/model.md#real-machine).

    These values are representative of such machines, not measured on the paper's.
    Keyword arguments replace fields."""
    base = die_bonder()
    f = REAL_AXIS_KEYS["resonance_frequency"]
    axes = []
    for a in base.axes:
        Kp, Kd = mode_safe_gains(a.time_constant, a.electrical_gain, a.mechanical_gain, f)
        axes.append(replace(a, position_gain=Kp, speed_gain=Kd, **REAL_AXIS_KEYS))
    m = base.with_options(
        axes=tuple(axes), encoder="counts",
        dac_bits=16, delay=0.5e-3, name="die-bonder-real")
    return m.with_options(**changes) if changes else m


BUILTIN_MACHINES = {"die-bonder": die_bonder, "die-bonder-real": die_bonder_real}


def builtin_machine(name: str) -> Machine:
    if name not in BUILTIN_MACHINES:
        raise KeyError(f"no built-in machine {name!r}; choose from {sorted(BUILTIN_MACHINES)}")
    return BUILTIN_MACHINES[name]()


def load_machine(spec: str | Path) -> Machine:
    """A built-in machine by name, or a machine file (``.toml`` or ``.json``).

    Raises
    ------
    PathFileError
        Missing or malformed file, naming the field (and for TOML and JSON the line).
    """
    if isinstance(spec, str) and spec in BUILTIN_MACHINES:
        return builtin_machine(spec)
    path = Path(spec)
    if not path.is_file():
        raise PathFileError(
            f"no such machine file, and not a built-in machine ({', '.join(BUILTIN_MACHINES)})",
            str(spec),
        )
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise PathFileError("machine files must end in .toml or .json", str(path))
    text = read_text_file(path, MAX_MACHINE_FILE_BYTES)
    # JSON has no inf; Infinity (as json.dumps writes it) is read, and refused by name.
    data = parse_json_or_toml(text, toml=suffix == ".toml", source=str(path), constants=True)
    return Machine.from_dict(data, str(path))
