"""Machine description: servo axes, controller gains, drive limit, sample period.

A :class:`Machine` is a value object: named :class:`Axis` entries (plant and gains, SPEC
sections 3-4), the drive limit ``max_drive`` (Umax), the ``sample_period`` (Ts) shared by
interpolation and control, the control law and how speed is measured, and the length of one
encoder pulse so that paths drawn in mm can run on it. It knows nothing of NURBS.

Built-in preset ``die-bonder``: Table 1 of Yeh & Sun (2008), Umax = 10 V, Ts = 1 ms,
1 pulse = 1 um. Users bring their own identified axes in a TOML or JSON machine file
(:func:`load_machine`); see ``examples/die_bonder.toml``.

Glossary (SPEC section 2)
-------------------------
tau : time constant [s]; Kc : electrical gain [(rad/s)/V]; Ke : mechanical gain
[pulse/rad]; Kp : position gain [V/pulse]; Kd : speed gain [V/(rad/s)];
Umax : drive limit [V]; Ts : sample period [s].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .control import PidGains, loop_poles, pid_law
from ._io import parse_json_or_toml, read_text_file
from .errors import InvalidMachineError, PathFileError
from .servo import ServoPlant, zoh_matrices

MAX_MACHINE_FILE_BYTES = 1_000_000
"""Largest machine file read [byte] (a machine of 6 axes takes about 1 kB)."""

__all__ = ["Axis", "Machine", "CONTROLLERS", "SPEED_MEASUREMENTS", "LENGTH_UNITS_UM",
           "die_bonder", "builtin_machine", "BUILTIN_MACHINES", "load_machine"]

CONTROLLERS = ("pd+", "pd", "pid")
"""Control laws: PD+ (eq. 2.12 / 3.3, the default), plain PD (eq. 2.4), and LinuxCNC's
``pid`` component with each axis's own parameters (:class:`nurbsmotion.control.PidGains`).
All run as the ``pid`` law: PD and PD+ are its presets."""

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
    """

    name: str
    time_constant: float
    electrical_gain: float
    mechanical_gain: float
    position_gain: float = 0.0
    speed_gain: float = 0.0
    pid: PidGains | None = None

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


MIN_SAMPLE_PERIOD = 1e-5
"""Shortest sample period Ts a machine may have [s] (100 kHz). Position loops of servo
drives and motion controllers run at 1-32 kHz (LinuxCNC's servo thread at 1 kHz); a
shorter period is most likely a unit slip (microseconds written as seconds), and it
multiplies the samples of every move."""

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
        Control law (SPEC sections 4 and 10): the paper's PD+ or PD from each axis's Kp
        and Kd, or LinuxCNC's ``pid`` from each axis's ``pid`` parameters.
    speed_measurement : {"encoder", "true"}
        ``"encoder"``: speed by differencing positions (SPEC eq. 3.3); ``"true"``: the
        simulated motor speed.
    pulse_length_um : float
        Length of one encoder pulse [um], to convert paths drawn in mm, m or inch.
    name : str
        Label carried into summaries.

    Raises
    ------
    InvalidMachineError
        Naming the bad field, or the axis whose closed loop (its law and plant, linear,
        as sampled) has a pole on or outside the unit circle: an unstable machine is
        refused, not simulated.
    """

    axes: tuple[Axis, ...]
    max_drive: float
    sample_period: float
    controller: str = "pd+"
    speed_measurement: str = "encoder"
    pulse_length_um: float = 1.0
    name: str = "custom"
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
        self._check_stable()

    def _check_stable(self) -> None:
        feedback_deriv = self.speed_measurement == "true"
        for a, gains in zip(self.axes, self.pid_gains):
            Ad, Bd = zoh_matrices(a.time_constant, a.electrical_gain, a.mechanical_gain,
                                  self.sample_period)
            poles = loop_poles(gains, Ad, Bd, self.sample_period, a.mechanical_gain,
                               feedback_deriv)
            radius = float(np.max(np.abs(poles)))
            self._arrays["pole_radius"] = max(radius, self._arrays.get("pole_radius", 0.0))
            self._arrays.setdefault("poles", []).append(poles)
            if not radius < 1.0:
                shown = ", ".join(f"{p.real:.6g}{p.imag:+.6g}j" for p in poles)
                raise InvalidMachineError(
                    f"axis {a.name!r}: the closed loop is unstable at Ts = "
                    f"{self.sample_period:g} s: poles {shown} (largest |p| = {radius:.6g}, "
                    "must be < 1); change the gains or the sample period")

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
        if not isinstance(data["axes"], list):
            raise PathFileError("machine field 'axes' must be a list of axis tables", source)
        pid = data.get("controller") == "pid"
        plant_fields = {"name", "time_constant", "electrical_gain", "mechanical_gain"}
        axis_fields = plant_fields | ({"pid"} if pid else {"position_gain", "speed_gain"})
        axes = []
        for i, entry in enumerate(data["axes"]):
            if not isinstance(entry, dict) or set(entry) != axis_fields:
                got = sorted(entry) if isinstance(entry, dict) else entry
                raise PathFileError(
                    f"axes[{i}] must have exactly the fields {sorted(axis_fields)} "
                    f"(controller {data.get('controller', 'pd+')!r}), got {got}",
                    source,
                )
            try:
                if pid:
                    name = entry.get("name")
                    entry = {**entry, "pid": PidGains.from_mapping(
                        entry["pid"], f"axis {name!r} pid")}
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
    return out


def die_bonder(**changes: Any) -> Machine:
    """The die-bonder of Yeh & Sun (2008), Table 1 (SPEC section 3).

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


BUILTIN_MACHINES = {"die-bonder": die_bonder}


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
    # JSON has no inf; Infinity (as json.dumps writes it) stands for an ideal drive.
    data = parse_json_or_toml(text, toml=suffix == ".toml", source=str(path), constants=True)
    return Machine.from_dict(data, str(path))
