"""A machine's log, read: time, and per axis the drive [V] and the encoder's reading.

:func:`read_log` reads a CSV file with a header or the project's ``trace.csv`` /
``trace.parquet`` (columns found by their suffixes, or mapped), checks it and names the
column and row of what is wrong; :func:`log_from_arrays` makes a :class:`Log` from arrays.
(Part of :mod:`nurbsmotion.identify`, which re-exports the public names.)

Glossary
--------
tau : time constant [s]; Kc : electrical gain [(rad/s)/V]; Ke : mechanical gain
[pulse/rad]; G = Ke*Kc : speed per volt [pulse/s/V]; Ts : sample period [s]; u : drive
[V]; y : encoder reading [pulse].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._runtime.io import check_input_file
from ..errors import InvalidArgumentError, PathFileError
from ..machine import LENGTH_UNITS_UM

__all__ = ["Log", "read_log", "log_from_arrays", "POSITION_SUFFIXES", "DRIVE_SUFFIXES",
           "LOG_UNITS", "TIME_UNITS", "MAX_JITTER"]

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


def _read_table(path: Path) -> tuple[list[str], dict, dict]:
    """Header names, columns (float64 arrays, NaN where a cell is empty) and the empty
    cells (a boolean mask per column that has any) of a CSV or Parquet file; a cell that
    is not a number is an error naming its column and row. Only an empty cell is empty:
    ``nan``, ``NA`` and the like are read as written (NaN, or not a number)."""
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
                                       strings_can_be_null=True, null_values=[""]))
        except pa.ArrowInvalid as exc:
            raise _bad(_ragged_row(path) or
                       f"not a CSV table with a header ({' '.join(str(exc).split())})",
                       str(path)) from None
    names = list(table.column_names)
    columns = {}
    empty = {}
    for name in names:
        col = table.column(name)
        if col.null_count:  # NaN in the array; read_log names it "empty"
            empty[name] = np.asarray(col.is_null().to_numpy(zero_copy_only=False),
                                     dtype=bool)
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
    return names, columns, empty


def _ragged_row(path: Path) -> str | None:
    """The first line of a CSV file whose number of cells is not the header's, as an
    error message naming it (pyarrow's names the cells, not the line), or None."""
    import csv

    try:
        with open(path, newline="") as handle:
            rows = csv.reader(handle)
            header = next(rows, None)
            if not header:
                return None
            for line, row in enumerate(rows, start=2):
                if row and len(row) != len(header):
                    return (f"row {line - 1} (line {line}) has {len(row)} cells, the header "
                            f"{len(header)} ({', '.join(header)})")
    except (OSError, UnicodeDecodeError, csv.Error):
        return None
    return None


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
    names, table, empty = _read_table(path)
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
            cell = "empty" if col in empty and empty[col][row] else values[row]
            raise _bad(f"column {col!r}, row {row + 1} (line {row + 2}): {cell} is not a "
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
