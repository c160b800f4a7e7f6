"""From a machine's own log to its machine file: identification and excitation.

:func:`read_log` reads a log (CSV with a header, or the project's ``trace.csv`` /
``trace.parquet``): time, and per axis the drive [V] and the encoder's reading.
:func:`identify` fits each axis to the real-machine plant of issue 32 (time constant,
gain, delay, Coulomb friction, stiction, and a mode where the data show one) and returns
an :class:`Identification`: per parameter the estimate, its standard deviation, the fit's
residual, and what the log cannot identify and why. :meth:`Identification.to_machine_dict`
is the machine file, with the gains of a base machine (identification never invents a
controller). :func:`excitation` makes a short drive sequence that makes every parameter
identifiable within the machine's limits, and :func:`excitation_gcode` its variant of
position moves. The method is in docs/identify.md.

Only Ke*Kc is seen in a log of drive and position; Ke comes from the base machine and Kc is
the product divided by it.

Glossary
--------
tau : time constant [s]; Kc : electrical gain [(rad/s)/V]; Ke : mechanical gain
[pulse/rad]; G = Ke*Kc : speed per volt [pulse/s/V]; Ts : sample period [s]; u : drive
[V]; y : encoder reading [pulse].
"""

from __future__ import annotations

import io
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._runtime.io import check_input_file, json_safe, write_output
from .errors import InvalidArgumentError, PathFileError
from .machine import LENGTH_UNITS_UM, Machine

__all__ = ["Log", "read_log", "log_from_arrays", "Estimate", "AxisIdentification",
           "Identification", "identify", "excitation", "excitation_gcode",
           "write_excitation_csv", "write_identification", "POSITION_SUFFIXES",
           "DRIVE_SUFFIXES", "LOG_UNITS"]

POSITION_SUFFIXES = ("_pos", "_meas", "_act")
"""Position columns looked for per axis, in order: a log's ``_pos``, then the project's
traces' ``_meas`` (what the controller read) and ``_act`` (the true position)."""

DRIVE_SUFFIXES = ("_drive_applied", "_drive")
"""Drive columns looked for per axis, in order: the project's traces' drive after the
clip, then a log's ``_drive``."""

LOG_UNITS = ("pulse", *LENGTH_UNITS_UM)
"""Position units a log may be in."""

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
"""Time units a log's ``t`` column may name in its header (``t [ms]``)."""

MAX_JITTER = 0.01
"""Largest deviation of a time step from the log's sample period [share of Ts]."""


def _bad(message: str, source: str | None) -> PathFileError:
    return PathFileError(message, source)


# -- the log ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Log:
    """A log of a machine: drive and encoder reading per axis at a fixed sample period.

    Parameters
    ----------
    time : ndarray, shape (n_samples,)
        Sample instants [s].
    drive : ndarray, shape (n_samples, n_axes)
        Drive held from each instant [V].
    position : ndarray, shape (n_samples, n_axes)
        Encoder reading at each instant [pulse].
    axis_names : tuple of str
    sample_period : float
        Ts [s].
    columns : dict
        The file's column read for each quantity (``{"x_drive": "x_drive_applied", ...}``).
    source : str
        The file name (or ``"arrays"``).
    """

    time: np.ndarray
    drive: np.ndarray
    position: np.ndarray
    axis_names: tuple
    sample_period: float
    columns: dict = field(default_factory=dict)
    source: str = "arrays"

    @property
    def n_samples(self) -> int:
        return self.time.shape[0]

    @property
    def duration(self) -> float:
        """Length of the log [s]."""
        return float(self.time[-1] - self.time[0])


def _unit_of(header: str) -> tuple[str, str | None]:
    """``"x_pos [mm]"`` -> ``("x_pos", "mm")``; a name without brackets has no unit."""
    text = header.strip()
    for open_, close in (("[", "]"), ("(", ")")):
        if text.endswith(close) and open_ in text:
            i = text.rindex(open_)
            return text[:i].strip(), text[i + 1:-1].strip()
    return text, None


def _read_table(path: Path) -> tuple[list[str], dict]:
    """Header names and columns (float64 arrays, NaN where a cell is empty) of a CSV or
    Parquet file; a cell that is not a number is an error naming its column and row."""
    if path.suffix.lower() == ".parquet":
        import pyarrow.parquet as pq

        try:
            table = pq.read_table(path)
        except Exception as exc:  # pyarrow's errors are not typed for a bad file
            raise _bad(f"not a readable Parquet file ({exc})", str(path)) from None
    else:
        import pyarrow as pa
        import pyarrow.csv as pacsv

        try:
            table = pacsv.read_csv(path, read_options=pacsv.ReadOptions(),
                                   parse_options=pacsv.ParseOptions(),
                                   convert_options=pacsv.ConvertOptions(
                                       strings_can_be_null=True))
        except pa.ArrowInvalid as exc:
            raise _bad(f"not a CSV table with a header ({' '.join(str(exc).split())})",
                       str(path)) from None
    names = list(table.column_names)
    columns = {}
    for name in names:
        col = table.column(name)
        try:
            columns[name] = col.to_numpy(zero_copy_only=False).astype(float)
        except (TypeError, ValueError):
            values = col.to_pylist()
            for row, v in enumerate(values):
                try:
                    float(v) if v is not None else None
                except (TypeError, ValueError):
                    raise _bad(f"column {name!r}, row {row + 1} (line {row + 2}): "
                               f"{v!r:.40} is not a number", str(path)) from None
            columns[name] = np.array([math.nan if v is None else float(v) for v in values])
    return names, columns


def read_log(file, axes=None, *, columns: dict | None = None,
             sample_period: float | None = None, units: str = "pulse",
             pulse_length_um: float = 1.0) -> Log:
    """Read a log of drive and encoder position.

    Parameters
    ----------
    file : path-like
        A CSV file with a header, or the project's ``trace.csv`` / ``trace.parquet``.
        A header may give units in brackets (``t [ms]``, ``x_pos [mm]``).
    axes : sequence of str, optional
        Axis names (a base machine's); by default every ``<a>`` with a drive column.
    columns : dict, optional
        The file's names for ``t``, ``<a>_drive`` and ``<a>_pos`` (``{"x_pos": "enc0"}``).
    sample_period : float, optional
        Ts [s] where the log has no ``t`` column (else it must agree with ``t``).
    units : str
        The positions' unit (:data:`LOG_UNITS`, default pulse) unless the header says.
    pulse_length_um : float
        Length of one pulse [um], to read positions in a length unit.

    Raises
    ------
    PathFileError
        One line naming the column and row: a missing column, a cell that is not a number
        or is NaN, time that does not increase or is not evenly sampled, positions in
        different units, a constant drive.
    """
    path = check_input_file(file)
    source = str(path)
    if units not in LOG_UNITS:
        raise InvalidArgumentError(f"units must be one of {LOG_UNITS}, got {units!r}")
    names, table = _read_table(path)
    header = {}
    for name in names:
        base, unit = _unit_of(name)
        header[base] = (name, unit)
    columns = dict(columns or {})
    for key, value in columns.items():
        if _unit_of(value)[0] not in header:
            raise _bad(f"--columns maps {key} to column {value!r}, which the log does not "
                       f"have (it has {', '.join(names)})", source)

    def find(key: str, candidates) -> str | None:
        if key in columns:
            return _unit_of(columns[key])[0]
        for c in candidates:
            if c in header:
                return c
        return None

    if axes is None:
        axes = []
        for base in header:
            for suffix in DRIVE_SUFFIXES:
                if base.endswith(suffix):
                    a = base[: -len(suffix)]
                    if a and a not in axes:
                        axes.append(a)
                    break
        for key in columns:
            if key.endswith("_drive") and key[:-6] not in axes:
                axes.append(key[:-6])
        if not axes:
            raise _bad("no drive column: expected <axis>_drive (or <axis>_drive_applied) "
                       f"columns, or --columns; the log has {', '.join(names)}", source)
    axes = tuple(axes)
    used = {}
    drives, positions, pos_units = [], [], []
    for a in axes:
        d = find(f"{a}_drive", [a + s for s in DRIVE_SUFFIXES])
        if d is None:
            raise _bad(f"column {a}_drive (axis {a!r}'s drive [V]) is missing; the log has "
                       f"{', '.join(names)} (map another name with --columns {a}_drive=NAME)",
                       source)
        p = find(f"{a}_pos", [a + s for s in POSITION_SUFFIXES])
        if p is None:
            raise _bad(f"column {a}_pos (axis {a!r}'s encoder position) is missing; the log "
                       f"has {', '.join(names)} (map another name with --columns "
                       f"{a}_pos=NAME)", source)
        d_unit = header[d][1]
        if d_unit not in (None, "V", "v"):
            raise _bad(f"column {header[d][0]!r}: the drive must be in V, not {d_unit}",
                       source)
        used[f"{a}_drive"], used[f"{a}_pos"] = header[d][0], header[p][0]
        drives.append(table[header[d][0]])
        positions.append(table[header[p][0]])
        pos_units.append((header[p][0], header[p][1] or units))
    distinct = sorted({u for _, u in pos_units})
    if len(distinct) > 1:
        shown = ", ".join(f"{c} in {u}" for c, u in pos_units)
        raise _bad(f"mixed units in the position columns ({shown}), row 0 (the header): "
                   "give every axis in one unit", source)
    unit = distinct[0]
    if unit not in LOG_UNITS:
        raise _bad(f"column {pos_units[0][0]!r}: unknown position unit {unit!r}; use one of "
                   f"{', '.join(LOG_UNITS)}", source)
    scale = 1.0 if unit == "pulse" else LENGTH_UNITS_UM[unit] / pulse_length_um
    n = len(drives[0])
    t_name = find("t", ["t", "time"])
    if t_name is None:
        if sample_period is None:
            raise _bad(f"column t (time [s]) is missing and no --sample-period was given; "
                       f"the log has {', '.join(names)}", source)
        t = np.arange(n) * float(sample_period)
    else:
        t_unit = header[t_name][1] or "s"
        if t_unit not in TIME_UNITS:
            raise _bad(f"column {header[t_name][0]!r}: unknown time unit {t_unit!r}; use "
                       f"one of {', '.join(TIME_UNITS)}", source)
        t = table[header[t_name][0]] * TIME_UNITS[t_unit]
        used["t"] = header[t_name][0]
    if n < 50:
        raise _bad(f"the log has {n} rows; identification needs at least 50", source)
    check = [("t", used.get("t", "t"), t)] if t_name is not None else []
    for a, d, p in zip(axes, drives, positions):
        check += [(f"{a}_drive", used[f"{a}_drive"], d), (f"{a}_pos", used[f"{a}_pos"], p)]
    for _, col, values in check:
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            row = int(bad[0])
            raise _bad(f"column {col!r}, row {row + 1} (line {row + 2}): "
                       f"{'empty' if math.isnan(values[row]) else values[row]} is not a "
                       "finite number", source)
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        row = int(bad[0]) + 1
        raise _bad(f"column {used.get('t', 't')!r}, row {row + 1} (line {row + 2}): time "
                   f"does not increase ({t[row - 1]:.9g} then {t[row]:.9g} s)", source)
    Ts = float(np.median(steps))
    jitter = np.flatnonzero(np.abs(steps - Ts) > MAX_JITTER * Ts)
    if jitter.size:
        row = int(jitter[0]) + 1
        raise _bad(f"column {used.get('t', 't')!r}, row {row + 1} (line {row + 2}): the "
                   f"time step {steps[row - 1]:.9g} s is not the log's sample period "
                   f"{Ts:.9g} s (missing rows?)", source)
    if sample_period is not None and t_name is not None and abs(Ts - sample_period) > \
            MAX_JITTER * sample_period:
        raise _bad(f"column {used['t']!r}: the log is sampled every {Ts:.9g} s, not "
                   f"--sample-period {sample_period:g} s (is t in ms? say so: 't [ms]')",
                   source)
    drive = np.column_stack(drives)
    position = np.column_stack(positions) * scale
    for j, a in enumerate(axes):
        if np.ptp(drive[:, j]) == 0:
            raise _bad(f"column {used[f'{a}_drive']!r}: the drive is constant "
                       f"({drive[0, j]:g} V over all {n} rows); nothing can be identified "
                       "from it", source)
    return Log(t - t[0], drive, position, axes, Ts, used, source)


def log_from_arrays(drive, position, sample_period: float, axis_names=None) -> Log:
    """A :class:`Log` from arrays: drive [V] and position [pulse], shape (n_samples,
    n_axes), sampled every ``sample_period`` [s]."""
    drive = np.asarray(drive, dtype=float)
    position = np.asarray(position, dtype=float)
    if drive.ndim == 1:
        drive, position = drive[:, None], position.reshape(-1, 1)
    if drive.shape != position.shape or drive.ndim != 2:
        raise InvalidArgumentError(f"drive and position must have one shape (n_samples, "
                                   f"n_axes), got {drive.shape} and {position.shape}")
    for what, arr in (("drive", drive), ("position", position)):
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            raise InvalidArgumentError(f"{what}[{bad[0][0]}, {bad[0][1]}] is not finite")
    names = tuple(axis_names or ("x", "y", "z", "a", "b", "c")[: drive.shape[1]])
    n = drive.shape[0]
    return Log(np.arange(n) * float(sample_period), drive, position, names,
               float(sample_period))


# -- the result ------------------------------------------------------------------------


@dataclass(frozen=True)
class Estimate:
    """One identified parameter: its value and standard deviation (NaN where the fit
    gives none), in the unit of its machine-file key."""

    value: float
    sigma: float
    unit: str

    def to_dict(self) -> dict:
        return {"value": self.value, "sigma": None if math.isnan(self.sigma) else self.sigma,
                "unit": self.unit}


@dataclass(frozen=True)
class AxisIdentification:
    """The identification of one axis.

    Attributes
    ----------
    name : str
    estimates : dict of str to Estimate
        By machine-file key: ``time_constant`` [s], ``electrical_gain`` [(rad/s)/V],
        ``delay`` [s], ``coulomb_friction`` and ``stiction`` [V], and where a mode was
        found ``resonance_frequency`` [Hz], ``resonance_damping``, ``load_fraction``.
        Only what the log identifies.
    mechanical_gain : float
        Ke [pulse/rad], from the base machine (a log cannot tell Ke from Kc).
    encoder_on : str or None
        ``"motor"`` or ``"load"`` where a mode was found.
    residual_rms : float
        RMS of the fit's residual on the increments [pulse per sample].
    simulated : ndarray, shape (n_samples,)
        The fitted model's response to the logged drive [pulse].
    notes : list of str
        What the log cannot identify, and why.
    """

    name: str
    estimates: dict
    mechanical_gain: float
    encoder_on: str | None
    residual_rms: float
    simulated: np.ndarray
    notes: tuple


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`: per axis the estimates, the machine-level ones, and
    the machine file they make (with a base machine's gains)."""

    axes: tuple
    delay: Estimate
    encoder: str
    measurement_noise: float
    log: Log
    base: Machine | None
    notes: tuple
    seconds: float

    def to_machine_dict(self) -> dict:
        """The machine file as a dict (issue 32's keys). Gains, drive limit, sample
        period and the rest come from the base machine; without one, the axes have no
        gains (and the file is not a runnable machine until they are added)."""
        base = self.base
        data = base.to_dict() if base is not None else {
            "name": "identified", "max_drive": math.inf,
            "sample_period": self.log.sample_period, "controller": "pd+",
            "speed_measurement": "encoder", "pulse_length_um": 1.0,
            "axes": [{"name": a.name} for a in self.axes]}
        data["name"] = f"{data['name']}-identified"
        data["delay"] = self.delay.value
        data["encoder"] = self.encoder
        data["measurement_noise"] = self.measurement_noise
        for entry, ax in zip(data["axes"], self.axes):
            est = ax.estimates
            entry["time_constant"] = est["time_constant"].value
            entry["electrical_gain"] = est["electrical_gain"].value
            entry["mechanical_gain"] = ax.mechanical_gain
            for key in ("coulomb_friction", "stiction", "resonance_frequency",
                        "resonance_damping", "load_fraction"):
                if key in est:
                    entry[key] = est[key].value
            if "resonance_damping" in est:
                # The machine file's resonance_damping is the twist's whole damping ratio
                # (docs/model.md section 11), which includes the axis's own viscous
                # damping split by inertia, 1/(2*wn*tau); the fit's is the spring-damper's.
                wn = 2.0 * math.pi * est["resonance_frequency"].value
                entry["resonance_damping"] += 1.0 / (2.0 * wn * entry["time_constant"])
            if ax.encoder_on is not None:
                entry["encoder_on"] = ax.encoder_on
        return data

    @property
    def machine(self) -> Machine:
        """The identified machine as a :class:`Machine` (needs a base machine for the
        gains). Only the keys :class:`Machine` knows are kept: the others are in
        :meth:`to_machine_dict`."""
        if self.base is None:
            raise InvalidArgumentError("the identified machine needs a base machine for "
                                       "its gains: identify(log, base=...)")
        data = self.to_machine_dict()
        known = set(Machine.__dataclass_fields__) - {"_arrays"}
        keep = {k: v for k, v in data.items() if k in known}
        from .machine import Axis

        axis_keys = set(Axis.__dataclass_fields__)
        keep["axes"] = [{k: v for k, v in a.items() if k in axis_keys} for a in data["axes"]]
        return Machine.from_dict(keep)

    def to_dict(self) -> dict:
        """``identify.json``: every estimate with its uncertainty, residual and notes."""
        return {
            "source": self.log.source,
            "columns": self.log.columns,
            "sample_period_s": self.log.sample_period,
            "duration_s": self.log.duration,
            "samples": self.log.n_samples,
            "base_machine": None if self.base is None else self.base.name,
            "delay": self.delay.to_dict(),
            "encoder": self.encoder,
            "measurement_noise": {"value": self.measurement_noise, "unit": "pulse"},
            "axes": {a.name: {
                "estimates": {k: e.to_dict() for k, e in a.estimates.items()},
                "mechanical_gain": {"value": a.mechanical_gain, "unit": "pulse/rad",
                                    "from": "base machine"},
                "encoder_on": a.encoder_on,
                "residual_rms": {"value": a.residual_rms, "unit": "pulse per sample"},
                "notes": list(a.notes)} for a in self.axes},
            "notes": list(self.notes),
            "seconds": self.seconds,
        }

    def to_toml(self) -> str:
        """The machine file's text: :meth:`to_machine_dict` with each estimate's
        uncertainty, the residual and the notes in comments at its head."""
        import tomli_w

        lines = [f"# Identified by nurbsmotion identify from {self.log.source}",
                 f"# ({self.log.n_samples} samples every {self.log.sample_period:g} s"
                 + (f"; gains from base machine {self.base.name!r}" if self.base else
                    "; no base machine: add the gains") + ")",
                 f"# delay = {_shown(self.delay)}"]
        for a in self.axes:
            lines.append(f"# axis {a.name}: residual RMS {a.residual_rms:.4g} pulse per "
                         f"sample; Ke {a.mechanical_gain:.8g} pulse/rad from the base")
            for key, e in a.estimates.items():
                lines.append(f"#   {key} = {_shown(e)}")
            for note in a.notes:
                lines.append(f"#   not identified: {note}")
        for note in self.notes:
            lines.append(f"# note: {note}")
        data = _finite(self.to_machine_dict())
        return "\n".join(lines) + "\n\n" + tomli_w.dumps(data)

    def plot(self, out, *, overwrite: bool = False):
        """Write ``identify.png``: measured against simulated response (matplotlib is
        imported here)."""
        from ._identify_plot import plot_identification

        return plot_identification(self, out, overwrite=overwrite)


def _shown(e: Estimate) -> str:
    s = "" if math.isnan(e.sigma) else f" +- {e.sigma:.3g}"
    return f"{e.value:.6g}{s} {e.unit}".rstrip()


def _finite(data):
    """``inf`` as TOML writes it is fine; NaN is not a value a machine file holds."""
    if isinstance(data, dict):
        return {k: _finite(v) for k, v in data.items() if not (isinstance(v, float)
                                                               and math.isnan(v))}
    if isinstance(data, list):
        return [_finite(v) for v in data]
    return data


# -- identification --------------------------------------------------------------------


TAU_SPREAD = 0.05
"""A time constant whose standard deviation exceeds this share of it is reported as poorly
identified."""

DEFAULT_MECHANICAL_GAIN = 10_000 / (2 * math.pi)
"""Ke [pulse/rad] without a base machine: 10,000 pulses per revolution (the die-bonder's)."""


def identify(log, base: Machine | None = None, *, max_drive: float | None = None
             ) -> Identification:
    """Identify a machine from a log of drive and encoder position.

    Parameters
    ----------
    log : Log or path-like
        A :class:`Log`, or a log file read with :func:`read_log` (with the base's axes).
    base : Machine, optional
        Ke per axis, the gains, the drive limit and the sample period of the machine file;
        its tau and Kc start the fit where the log says little.
    max_drive : float, optional
        Umax [V] bounding the friction; the base's, or the log's largest |drive|.

    Returns
    -------
    Identification

    Raises
    ------
    PathFileError, InvalidArgumentError
        A bad log (see :func:`read_log`), or a log whose axes are not the base's.
    """
    from ._identify_fit import fit_axis

    started = time.perf_counter()
    if not isinstance(log, Log):
        log = read_log(log, None if base is None else base.axis_names,
                       pulse_length_um=1.0 if base is None else base.pulse_length_um)
    if base is not None and tuple(log.axis_names) != tuple(base.axis_names):
        raise InvalidArgumentError(f"the log's axes {', '.join(log.axis_names)} are not the "
                                   f"base machine's {', '.join(base.axis_names)}")
    Ts = log.sample_period
    umax = max_drive if max_drive is not None else (
        base.max_drive if base is not None and math.isfinite(base.max_drive)
        else float(np.max(np.abs(log.drive))))
    counts = bool(np.all(log.position == np.round(log.position)))
    notes = []
    axes = []
    delays, delay_sig = [], []
    noise_vars = []
    for j, name in enumerate(log.axis_names):
        u = log.drive[:, j]
        y = log.position[:, j]
        dy = np.diff(y)
        if np.all(np.abs(dy) <= 1.0):
            raise PathFileError(f"column {log.columns.get(f'{name}_pos', name + '_pos')!r}: "
                                "the axis never moved more than a count per sample; "
                                "nothing can be identified", log.source)
        Ke = base.Ke[j] if base is not None else DEFAULT_MECHANICAL_GAIN
        start = None if base is None else {"time_constant": base.tau[j],
                                           "gain": base.Kc[j] * base.Ke[j]}
        fit = fit_axis(u, y, Ts, max_drive=umax, base=start)
        v, s = fit.values, fit.sigma
        est = {"time_constant": Estimate(v["time_constant"], s["time_constant"], "s"),
               "electrical_gain": Estimate(v["gain"] / Ke, s["gain"] / Ke, "(rad/s)/V"),
               "delay": Estimate(v["delay"], s["delay"], "s")}
        if fit.identified["coulomb_friction"]:
            est["coulomb_friction"] = Estimate(v["coulomb_friction"],
                                               s["coulomb_friction"], "V")
        if fit.identified["stiction"]:
            est["stiction"] = Estimate(v["stiction"], s["stiction"], "V")
        encoder_on = None
        axis_notes = list(fit.notes)
        spread = s["time_constant"] / v["time_constant"]
        if not spread <= TAU_SPREAD:
            axis_notes.append(
                f"time_constant and electrical_gain: poorly identified (tau +- {spread:.0%}):"
                " the log's moves are short against tau, so only Kc/tau (the acceleration "
                "per volt) is sharp; log longer moves (more --travel in excite, or its "
                "G-code variant in closed loop)")
        if fit.identified["resonance"]:
            est["resonance_frequency"] = Estimate(v["resonance_frequency"],
                                                  s["resonance_frequency"], "Hz")
            est["resonance_damping"] = Estimate(v["resonance_damping"],
                                                s["resonance_damping"], "")
            c, sc = v["coupling"], s["coupling"]
            if c > 0:
                encoder_on = "motor"
                share = c / (1 + c)
                est["load_fraction"] = Estimate(share, sc / (1 + c) ** 2, "")
            else:
                encoder_on = "load"
                axis_notes.append(f"load_fraction: not identifiable with the encoder on the "
                                  f"load (the mode's coupling {c:.3g} is about -1 whatever "
                                  "the share); the machine file keeps the default")
        axis_notes.append("mechanical_gain: a log of drive and position shows only Ke*Kc; "
                          "Ke is the base machine's" if base is not None else
                          "mechanical_gain: a log shows only Ke*Kc; Ke is taken as 10,000 "
                          "pulse/rev without a base machine")
        delays.append(v["delay"])
        delay_sig.append(s["delay"])
        # The increments' residual holds the reading noise twice, and a count's rounding.
        noise_vars.append(max(fit.residual_rms ** 2 / 2 - (1 / 12 if counts else 0.0), 0.0))
        axes.append(AxisIdentification(name, est, float(Ke), encoder_on, fit.residual_rms,
                                       fit.simulated, tuple(axis_notes)))
    d = float(np.mean(delays))
    sd = float(math.sqrt(np.sum(np.square(delay_sig)))) / len(delays)
    if len(delays) > 1 and np.ptp(delays) > 0.1 * Ts:
        notes.append(f"the axes' delays differ ({', '.join(f'{x:.4g}' for x in delays)} s); "
                     "the machine file's one delay is their mean")
    if base is not None and abs(base.sample_period - Ts) > 1e-9 * Ts:
        notes.append(f"the log is sampled every {Ts:g} s and the base machine's controller "
                     f"every {base.sample_period:g} s; the plant is continuous, the "
                     "machine file keeps the base's period")
    notes.append("dac_bits: not identifiable from a log of the drive command; not written")
    noise = float(math.sqrt(min(noise_vars)))
    return Identification(tuple(axes), Estimate(d, sd, "s"), "counts" if counts else "exact",
                          noise, log, base, tuple(notes), time.perf_counter() - started)


def write_identification(result: Identification, out, *, figure: bool = True,
                         overwrite: bool = False) -> list:
    """Write ``result``'s machine file ``out`` (TOML), ``identify.json`` beside it and the
    figure ``identify.png``; nothing is overwritten unless asked."""
    out = Path(out)
    folder = out.parent
    written = [write_output(out, lambda h: h.write(result.to_toml()), overwrite=overwrite)]
    written.append(write_output(folder / "identify.json",
                                lambda h: json.dump(json_safe(result.to_dict()), h,
                                                    indent=2),
                                overwrite=overwrite))
    if figure:
        written.append(result.plot(folder, overwrite=overwrite))
    return written



# -- excitation ------------------------------------------------------------------------


DEFAULT_TRAVEL_MM = 20.0
"""Default bound of the excitation's excursion from its start on a frictionless axis
[mm]."""


def _rigid_positions(tau: float, gain: float, drive: np.ndarray, Ts: float) -> np.ndarray:
    """Positions of a frictionless rigid axis from rest [pulse] (exact ZOH)."""
    from ._identify_model import simulate

    return simulate(drive, Ts, {"time_constant": tau, "gain": gain, "delay": 0.0})


def _doublet(level: float, width: int) -> np.ndarray:
    """+level for width samples, -level for 2 width, +level for width: the speed and the
    position come back near zero."""
    return np.concatenate([np.full(width, level), np.full(2 * width, -level),
                           np.full(width, level)])


def _returning(pieces, tau: float, gain: float, Ts: float, level: float,
               rest: np.ndarray) -> np.ndarray:
    """The pieces in a row, each followed by a move back towards the start (+-level for
    w samples each way, then a rest) where the previous ones left the axis off it, so
    that the excursions do not add up (frictionless rigid axis)."""
    seq = np.zeros(0)
    accel = gain * level / tau  # [pulse/s^2]
    for piece in pieces:
        seq = np.concatenate([seq, piece])
        y = _rigid_positions(tau, gain, np.concatenate([seq, [0.0, 0.0]]), Ts)
        off = float(y[-1] + (y[-1] - y[-2]) / Ts * tau)  # where it coasts to
        width = int(round(math.sqrt(abs(off) / accel) / Ts))
        if width >= 1:
            s = -math.copysign(level, off)
            seq = np.concatenate([seq, np.full(width, s), np.full(width, -s), rest])
    return seq


def excitation(machine: Machine, *, travel: float | None = None, seed: int = 0
               ) -> tuple[np.ndarray, np.ndarray]:
    """A drive sequence that makes every parameter of :func:`identify` identifiable.

    Per axis, all axes at once: a rest, slow drive ramps both ways from rest (the
    breakaway: stiction), doublets (+A, -2A, +A) at five levels from 5 % to 80 % of Umax in
    both orders (friction against gain, and tau from their curvature), a random binary
    sequence of short bits (the delay and a mode up to half the sample rate), and a rest.
    Each piece's length is set so that on the base machine, without friction, it moves the
    axis at most ``travel / 2``, and a slow move back after each piece brings the axis near
    its start again: the whole sequence stays within ``travel`` of it.

    Parameters
    ----------
    machine : Machine
        Its tau, Kc, Ke, Umax and Ts (an ideal drive, Umax = inf, is taken as 10 V).
    travel : float, optional
        Bound of the excursion [pulse]; default :data:`DEFAULT_TRAVEL_MM` mm.
    seed : int
        Seed of the random binary sequence.

    Returns
    -------
    time : ndarray, shape (n_samples,)
        [s].
    drive : ndarray, shape (n_samples, n_axes)
        [V], within +-Umax.
    """
    Ts = machine.sample_period
    umax = machine.max_drive if math.isfinite(machine.max_drive) else 10.0
    if travel is None:
        travel = DEFAULT_TRAVEL_MM * 1e3 / machine.pulse_length_um
    if not (math.isfinite(travel) and travel > 0):
        raise InvalidArgumentError(f"travel must be finite and > 0 [pulse], got {travel!r}")
    rng = np.random.default_rng(seed)
    columns = []
    for j in range(machine.n_axes):
        tau, gain = float(machine.tau[j]), float(machine.Kc[j] * machine.Ke[j])

        def fits(seq: np.ndarray) -> bool:
            return float(np.max(np.abs(_rigid_positions(tau, gain, seq, Ts)))) <= travel / 2

        def widest(make, lo: int = 1, hi: int | None = None) -> int:
            """The most samples n (<= hi) for which make(n) stays within the travel."""
            hi = hi or max(int(round(tau / Ts)), 2)
            if not fits(make(lo)):
                return lo
            while lo < hi:
                mid = (lo + hi + 1) // 2
                if fits(make(mid)):
                    lo = mid
                else:
                    hi = mid - 1
            return lo

        rest = np.zeros(max(int(round(0.1 / Ts)), 5))
        pieces = [rest]
        # Ramps from rest to 20 % of Umax and back, both ways: the breakaway.
        top = 0.2 * umax

        def ramp(n: int, sign: float) -> np.ndarray:
            up = np.linspace(0.0, sign * top, n + 1)[1:]
            return np.concatenate([up, up[::-1], -up, -up[::-1]])

        n_ramp = widest(lambda n: ramp(n, 1.0), lo=5, hi=max(int(round(0.3 / Ts)), 10))
        pieces += [ramp(n_ramp, 1.0), rest, ramp(n_ramp, -1.0), rest]
        for share in (0.05, 0.1, 0.2, 0.4, 0.8):
            level = share * umax
            width = widest(lambda n: _doublet(level, n), lo=2)
            pieces += [_doublet(level, width), rest[: len(rest) // 2],
                       _doublet(-level, width), rest[: len(rest) // 2]]
        # Short random bits (1-4 samples) at half of Umax, in +- pairs so that the speed
        # does not wander: the delay and a mode.
        level = 0.5 * umax
        bits = []
        while sum(len(b) for b in bits) < int(round(1.0 / Ts)):
            n = int(rng.integers(1, 5))
            s = level if rng.random() < 0.5 else -level
            bits += [np.full(n, s), np.full(n, -s)]
        prbs = np.concatenate(bits)
        while not fits(prbs) and level > 0.01 * umax:
            level *= 0.7
            prbs = prbs * 0.7
        pieces += [prbs, rest, rest]
        columns.append(_returning(pieces, tau, gain, Ts, 0.05 * umax, rest))
    n = max(len(c) for c in columns)
    drive = np.zeros((n, machine.n_axes))
    for j, c in enumerate(columns):
        drive[: len(c), j] = c
    drive = np.clip(drive, -umax, umax)
    return np.arange(n) * Ts, drive


def write_excitation_csv(time_s: np.ndarray, drive: np.ndarray, axis_names, file, *,
                         overwrite: bool = False) -> Path:
    """``t,<a>_drive,...`` [s, V], full precision."""
    def write(handle):
        buf = io.StringIO()
        buf.write(",".join(["t"] + [f"{a}_drive" for a in axis_names]) + "\n")
        np.savetxt(buf, np.column_stack([time_s, drive]), delimiter=",",
                   fmt=["%.12g"] + ["%.17g"] * drive.shape[1])
        handle.write(buf.getvalue())
    return write_output(file, write, overwrite=overwrite)


def excitation_gcode(machine: Machine, *, travel: float | None = None) -> str:
    """G-code of position moves that make the closed-loop log identifiable: per axis,
    back-and-forth moves (reversals) at feeds from a crawl (friction, stiction) to the
    axis's top speed over the travel (gain, tau), and short fast moves (delay, a mode).
    Lengths in mm, feeds in mm/min, from the start point (G91)."""
    if travel is None:
        travel = DEFAULT_TRAVEL_MM * 1e3 / machine.pulse_length_um
    mm_per_pulse = machine.pulse_length_um * 1e-3
    span = travel / 2 * mm_per_pulse  # [mm]
    letters = [a.upper() for a in machine.axis_names]
    lines = ["(nurbsmotion excite: position moves for nurbsmotion identify)",
             "G21 G91"]
    for j, letter in enumerate(letters):
        vmax = float(machine.max_axis_speed[j]) if math.isfinite(machine.max_drive) else (
            10.0 * machine.Kc[j] * machine.Ke[j])
        top = 0.2 * vmax * mm_per_pulse * 60.0  # [mm/min]
        for share in (5e-4, 5e-3, 0.05, 0.25, 1.0):
            feed = max(top * share, 1.0)
            lines += [f"G1 {letter}{span:.4f} F{feed:.6g}", f"G1 {letter}{-span:.4f}"]
        short = span / 20
        for _ in range(5):
            lines += [f"G1 {letter}{short:.4f} F{top:.6g}", f"G1 {letter}{-short:.4f}"]
    lines.append("M2")
    return "\n".join(lines) + "\n"
