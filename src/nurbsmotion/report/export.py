"""Export of a motion: setpoints (CSV, NumPy .npz), PVT tables, and a G-code program.

This module works on plain arrays so that it does not depend on the interpolators: any
object with attributes ``t`` (n,) [s], ``u`` (n,), ``position`` (n, n_axes) [path units]
and, optionally, ``feed`` (n,) [path units/s] and ``axis_names`` (the interpolators'
setpoint series, or :class:`SetpointArrays` built from arrays) can be exported. Writers
never overwrite an existing file unless asked, and write through a temporary file, so a
failed export leaves nothing behind.

Formats
-------
setpoints CSV
    Header ``t,u,x,y[,z...]`` (axis names), one row per sample: ``t`` [s], ``u`` the
    curve parameter (0 at the start of the path, 1 at its end; dimensionless) and each
    axis' commanded position [path units]. Numbers with 17 significant digits (they read
    back bit for bit), or, with ``resolution``, positions to that length (e.g. a thousandth
    of a pulse), ``t`` to the nanosecond and ``u`` to 1e-12.
setpoints NPZ
    Arrays ``t``, ``u``, ``position``, ``axis_names`` and, when known, ``feed``.
PVT table
    Position-velocity-time rows at a fixed period, the form buffered motion controllers
    (PVT / "PT with velocity" modes) take: the controller joins consecutive rows by cubic
    Hermite segments. Positions and velocities come from the C2 cubic spline through the
    setpoints (``scipy.interpolate.CubicSpline``, not-a-knot ends), so the Hermite segments
    the controller builds follow the setpoint motion. Saved as CSV with header
    ``t,x,x_velocity,y,y_velocity,...``.
halstreamer
    One line per servo period, a float per axis separated by blanks, as LinuxCNC's
    ``halstreamer`` feeds a ``streamer`` loaded with ``cfg=ff...`` (one ``f`` per axis):
    the commanded position [the machine's length unit, mm or inch] at each sample. Comment
    lines (``#``) first name the period, the streamer configuration and each column's unit.
ROS trajectory
    A ``trajectory_msgs/msg/JointTrajectory`` (ROS 2) as YAML: ``joint_names`` (the axis
    names), then ``points`` at a fixed period, each with ``positions`` [m], ``velocities``
    [m/s], ``accelerations`` [m/s^2] (SI, as REP 103 has joint values; from the C2 cubic
    spline through the setpoints, as the PVT table) and ``time_from_start`` (``sec``,
    ``nanosec``), the last point at the end of the setpoints.
motion G-code
    One ``G1`` per sample period with the F that makes the move last exactly that period
    (``F = distance / period * 60``), ``G4`` dwells where the setpoint stands still, in
    LinuxCNC's dialect; the path itself as G5.2 blocks is
    :func:`nurbsmotion.paths.save_gcode`.

CSV metadata (CSV on the Web)
    Beside each CSV file it writes (``setpoints.csv``, ``pvt.csv``, ``trace.csv``) the
    command writes ``<name>.csv-metadata.json``, the W3C "Metadata Vocabulary for Tabular
    Data" description at the standard's default location for that file's metadata
    (``{+url}-metadata.json``): ``url``, and under ``tableSchema.columns`` one entry per
    column in the header's order with ``name`` and ``titles`` (the header cell),
    ``datatype`` (``double``), ``dc:description`` (what it is, with its unit in brackets)
    and ``qudt:unit``, the QUDT unit IRI (:data:`QUDT_UNITS`; a pulse, an encoder count,
    is ``unit:NUM`` with ``nurbsmotion:unit`` ``"pulse"``). :func:`save_csv_metadata`.

Glossary
--------
t : time [s]; u : curve parameter; T : PVT period [s]; F : feed [units/min].
"""

from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._runtime.io import write_output
from ..errors import NurbsmotionError

__all__ = [
    "SetpointArrays",
    "PvtTable",
    "ExportError",
    "save_setpoints",
    "pvt_table",
    "save_pvt",
    "save_motion_gcode",
    "save_halstreamer",
    "save_ros_trajectory",
    "decimals_for_resolution",
    "CsvColumn",
    "QUDT_UNITS",
    "metadata_file",
    "save_csv_metadata",
    "setpoint_columns",
]

_DEFAULT_AXES = ("x", "y", "z", "a", "b", "c", "u", "v", "w")


class ExportError(NurbsmotionError, ValueError):
    """Setpoints or export options are not fit for the requested format."""


@dataclass(frozen=True)
class SetpointArrays:
    """Setpoints as plain arrays, validated (a value object for the exporters).

    Parameters
    ----------
    t : ndarray, shape (n_samples,)
        Strictly increasing sample times [s].
    u : ndarray, shape (n_samples,)
        Curve parameter at each sample.
    position : ndarray, shape (n_samples, n_axes)
        Setpoint per axis [path units].
    feed : ndarray, shape (n_samples,), optional
        Commanded feed at each sample [path units / s].
    axis_names : tuple of str, optional
        One per axis; ``("x", "y", ...)`` by default.
    """

    t: np.ndarray
    u: np.ndarray
    position: np.ndarray
    feed: np.ndarray | None = None
    axis_names: tuple | None = None

    def __post_init__(self):
        t = np.asarray(self.t, dtype=float)
        u = np.asarray(self.u, dtype=float)
        position = np.asarray(self.position, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise ExportError(f"t must have shape (n_samples,) with n_samples >= 2, got {t.shape}")
        n = t.size
        if position.ndim != 2 or position.shape[0] != n:
            raise ExportError(f"position must have shape ({n}, n_axes), got {position.shape}")
        if u.shape != (n,):
            raise ExportError(f"u must have shape ({n},), got {u.shape}")
        for name, arr in (("t", t), ("u", u), ("position", position)):
            if not np.all(np.isfinite(arr)):
                raise ExportError(f"{name} holds non-finite values")
        if np.any(np.diff(t) <= 0):
            k = int(np.flatnonzero(np.diff(t) <= 0)[0])
            raise ExportError(f"t must increase strictly, but t[{k + 1}] = {t[k + 1]:.17g} <= t[{k}] = {t[k]:.17g}")
        feed = None if self.feed is None else np.asarray(self.feed, dtype=float)
        if feed is not None and feed.shape != (n,):
            raise ExportError(f"feed must have shape ({n},), got {feed.shape}")
        names = self.axis_names
        if names is None:
            if position.shape[1] > len(_DEFAULT_AXES):
                raise ExportError(f"give axis_names for {position.shape[1]} axes")
            names = _DEFAULT_AXES[: position.shape[1]]
        names = tuple(str(a) for a in names)
        if len(names) != position.shape[1] or len(set(names)) != len(names):
            raise ExportError(f"axis_names {names} must name the {position.shape[1]} axes once each")
        for attr, value in (("t", t), ("u", u), ("position", position), ("feed", feed), ("axis_names", names)):
            object.__setattr__(self, attr, value)

    @classmethod
    def from_series(cls, series: Any) -> "SetpointArrays":
        """From any object with attributes t, u, position (and optionally feed, axis_names)."""
        if isinstance(series, cls):
            return series
        try:
            t, u, position = series.t, series.u, series.position
        except AttributeError as exc:
            raise ExportError(f"setpoints need attributes t, u and position: {exc}") from None
        return cls(t, u, position, getattr(series, "feed", None), getattr(series, "axis_names", None))

    @property
    def n_axes(self) -> int:
        return self.position.shape[1]


def decimals_for_resolution(resolution: float | None) -> int | None:
    """Digits after the point that write a value to within ``resolution`` (half a unit
    of the last digit at most), or None (17 significant digits) for None."""
    if resolution is None:
        return None
    if not (np.isfinite(resolution) and resolution > 0):
        raise ExportError(f"resolution must be finite and > 0, got {resolution!r}")
    return max(0, int(math.ceil(-math.log10(2.0 * resolution))))


def _fixed(values: np.ndarray, decimals: int | None) -> str:
    """A column format: fixed ``decimals`` or 17 significant digits."""
    return "%.17g" if decimals is None else f"%.{decimals}f"


def save_setpoints(setpoints: Any, file: str | os.PathLike, *, resolution: float | None = None,
                   overwrite: bool = False) -> Path:
    """Write setpoints as CSV (``t,u,x,y,...``) or NumPy ``.npz``, chosen by the ending.

    Parameters
    ----------
    setpoints : SetpointArrays or any object with t, u, position [, feed, axis_names]
    file : str or path-like
        ``*.csv`` or ``*.npz``.
    resolution : float, optional
        CSV: write positions to this length [path units] (e.g. a thousandth of a pulse),
        ``t`` to 1 ns and ``u`` to 1e-12; by default 17 significant digits. NPZ keeps every
        bit.
    overwrite : bool
        Replace an existing file.

    Raises
    ------
    ExportError
        For bad arrays or an unknown ending (nothing is written).
    OutputExistsError
        If the file exists and ``overwrite`` is false.
    """
    sp = SetpointArrays.from_series(setpoints)
    suffix = Path(file).suffix.lower()
    if suffix == ".csv":
        header = ",".join(("t", "u") + sp.axis_names)
        table = np.column_stack([sp.t, sp.u, sp.position])
        d = decimals_for_resolution(resolution)
        fmt = "%.17g" if d is None else ["%.9f", "%.12f"] + [f"%.{d}f"] * sp.n_axes
        return write_output(file, lambda f: _write_csv(f, header, table, fmt), overwrite=overwrite)
    if suffix == ".npz":
        arrays = {"t": sp.t, "u": sp.u, "position": sp.position, "axis_names": np.array(sp.axis_names)}
        if sp.feed is not None:
            arrays["feed"] = sp.feed
        return write_output(file, lambda f: np.savez(f, **arrays), overwrite=overwrite, binary=True)
    raise ExportError(f"{file}: unknown setpoint file ending {suffix!r}; use .csv or .npz")


QUDT_UNITS = {
    "s": "SEC", "1": "UNITLESS", "V": "V", "pulse": "NUM", "pulse/s": "PER-SEC",
    "deg": "DEG", "deg/s": "DEG-PER-SEC", "rad": "RAD",
    "um": "MicroM", "mm": "MilliM", "cm": "CentiM", "m": "M", "in": "IN", "inch": "IN",
    "um/s": "MicroM-PER-SEC", "mm/s": "MilliM-PER-SEC", "cm/s": "CentiM-PER-SEC",
    "m/s": "M-PER-SEC", "in/s": "IN-PER-SEC", "inch/s": "IN-PER-SEC",
}
"""A column's unit as written in docs/formats.md -> its QUDT unit (``unit:`` prefix,
http://qudt.org/vocab/unit/). A pulse (an encoder count, a number of steps) is ``NUM``, a
pulse per second ``PER-SEC``; the metadata also names them in ``nurbsmotion:unit``."""

_CSVW_CONTEXT = ["http://www.w3.org/ns/csvw", {
    "@language": "en",
    "qudt": "http://qudt.org/schema/qudt/",
    "unit": "http://qudt.org/vocab/unit/",
    "nurbsmotion": "https://github.com/nurbsmotion/nurbsmotion/blob/main/docs/formats.md#",
}]


@dataclass(frozen=True)
class CsvColumn:
    """One column of a CSV file for its metadata: ``name`` (the header cell), ``unit`` (a
    key of :data:`QUDT_UNITS`) and ``description`` (what it is)."""

    name: str
    unit: str
    description: str


def metadata_file(csv_file: str | os.PathLike) -> Path:
    """The metadata file of ``csv_file``: CSV on the Web's default location,
    ``<csv_file>-metadata.json`` (``setpoints.csv`` -> ``setpoints.csv-metadata.json``)."""
    path = Path(csv_file)
    return path.with_name(path.name + "-metadata.json")


def save_csv_metadata(csv_file: str | os.PathLike, columns: list, *, title: str | None = None,
                      overwrite: bool = False) -> Path:
    """Write the CSV on the Web metadata of ``csv_file`` beside it (see the module
    docstring), atomically (a temporary file renamed), never over an existing file unless
    ``overwrite``.

    Parameters
    ----------
    csv_file : str or path-like
        The CSV file described; its name is the metadata's ``url`` (relative: the two
        files move together).
    columns : list of CsvColumn
        Every column, in the header's order.
    title : str, optional
        ``dc:title`` of the table.
    overwrite : bool

    Returns
    -------
    Path
        The metadata file (:func:`metadata_file`).

    Raises
    ------
    ExportError
        For a unit without a QUDT unit, or a repeated or empty column name.
    """
    import json

    names = [c.name for c in columns]
    if not names or len(set(names)) != len(names) or not all(names):
        raise ExportError(f"CSV columns must have distinct non-empty names, got {names}")
    unknown = [c.unit for c in columns if c.unit not in QUDT_UNITS]
    if unknown:
        raise ExportError(f"no QUDT unit for {unknown}; known: {', '.join(QUDT_UNITS)}")
    table = {"@context": _CSVW_CONTEXT, "url": Path(csv_file).name}
    if title:
        table["dc:title"] = title
    table["dialect"] = {"header": True, "delimiter": ","}
    table["tableSchema"] = {"columns": [{
        "name": c.name, "titles": c.name, "datatype": "double",
        "dc:description": f"{c.description} [{c.unit}]",
        "qudt:unit": {"@id": f"unit:{QUDT_UNITS[c.unit]}"},
        "nurbsmotion:unit": c.unit,
    } for c in columns]}
    text = json.dumps(table, indent=1) + "\n"
    return write_output(metadata_file(csv_file), lambda f: f.write(text), overwrite=overwrite)


def setpoint_columns(axis_names, unit: str, *, velocity: bool = False, u: bool = True) -> list:
    """The :class:`CsvColumn` list of a setpoints CSV (``t,u,<axes>``) or, with
    ``velocity`` (and ``u=False``), of a PVT table (``t,<a>,<a>_velocity,...``); an axis
    named ``<a>_deg`` is a rotary axis in degrees, the others in ``unit``."""
    cols = [CsvColumn("t", "s", "time from the start of the move")]
    if u:
        cols.append(CsvColumn("u", "1", "curve parameter of the setpoint, 0 at the path's "
                                        "start and 1 at its end"))
    for a in axis_names:
        L = "deg" if a.endswith("_deg") else unit
        cols.append(CsvColumn(a, L, f"commanded position of axis {a.removesuffix('_deg')}"))
        if velocity:
            cols.append(CsvColumn(f"{a}_velocity", f"{L}/s",
                                  f"commanded velocity of axis {a.removesuffix('_deg')}"))
    return cols


def _write_csv(handle, header: str, table: np.ndarray, fmt="%.17g") -> None:
    buffer = io.StringIO()
    np.savetxt(buffer, table, delimiter=",", fmt=fmt, header=header, comments="")
    handle.write(buffer.getvalue())


@dataclass(frozen=True)
class PvtTable:
    """Position-velocity-time rows at a fixed period.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Row times [s]: ``0, T, 2T, ...`` and the last setpoint time.
    position : ndarray, shape (m, n_axes)
        [path units].
    velocity : ndarray, shape (m, n_axes)
        [path units / s].
    axis_names : tuple of str
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    axis_names: tuple

    def axis(self, name: str) -> np.ndarray:
        """The PVT table of one axis, shape (m, 3): columns t [s], position, velocity."""
        if name not in self.axis_names:
            raise ExportError(f"no axis {name!r}; axes are {self.axis_names}")
        j = self.axis_names.index(name)
        return np.column_stack([self.t, self.position[:, j], self.velocity[:, j]])


def pvt_table(setpoints: Any, period: float) -> PvtTable:
    """Resample setpoints to a PVT table at ``period`` (see the module docstring).

    Parameters
    ----------
    setpoints : SetpointArrays or any object with t, u, position
    period : float
        PVT period T [s], > 0 (typically a multiple of the sample period, e.g. 10 ms).

    Returns
    -------
    PvtTable
    """
    from scipy.interpolate import CubicSpline  # loaded by these two exports only

    sp = SetpointArrays.from_series(setpoints)
    if not (np.isfinite(period) and period > 0):
        raise ExportError(f"PVT period must be finite and > 0 s, got {period!r}")
    t_end = sp.t[-1] - sp.t[0]
    times = np.arange(0.0, t_end, period)
    if t_end - times[-1] > 1e-9 * period:
        times = np.append(times, t_end)
    spline = CubicSpline(sp.t - sp.t[0], sp.position, axis=0)
    return PvtTable(times + sp.t[0], spline(times), spline(times, 1), sp.axis_names)


def save_pvt(table: PvtTable, file: str | os.PathLike, *, resolution: float | None = None,
             overwrite: bool = False) -> Path:
    """Write a PVT table as CSV with header ``t,x,x_velocity,y,y_velocity,...``: ``t``
    [s], positions [path units], velocities [path units / s]. With ``resolution`` [path
    units], positions to that length, velocities to that length per second and ``t`` to
    1 ns; by default 17 significant digits."""
    columns, names = [table.t], ["t"]
    for j, axis in enumerate(table.axis_names):
        columns += [table.position[:, j], table.velocity[:, j]]
        names += [axis, f"{axis}_velocity"]
    table_array = np.column_stack(columns)
    d = decimals_for_resolution(resolution)
    fmt = "%.17g" if d is None else ["%.9f"] + [f"%.{d}f"] * (2 * len(table.axis_names))
    return write_output(file, lambda f: _write_csv(f, ",".join(names), table_array, fmt),
                        overwrite=overwrite)


def _uniform_period(t: np.ndarray) -> float:
    """The sample period of setpoints taken at a fixed period [s], else ExportError."""
    dt = np.diff(t)
    period = float(np.median(dt))
    bad = np.flatnonzero(np.abs(dt - period) > 1e-9 * period)
    if bad.size:
        k = int(bad[0])
        raise ExportError(f"setpoints must be one per servo period ({period:.9g} s), but "
                          f"t[{k + 1}] - t[{k}] = {dt[k]:.9g} s")
    return period


def save_halstreamer(setpoints: Any, file: str | os.PathLike, *, units: str = "mm", scale: float = 1.0,
                     resolution: float | None = None, overwrite: bool = False) -> Path:
    """Write the setpoints as LinuxCNC ``halstreamer`` input (see the module docstring).

    Parameters
    ----------
    setpoints : SetpointArrays or any object with t, u, position [, axis_names]
        One per servo period.
    file : str or path-like
    units : str
        The machine's length unit the positions are written in (named in the header).
    scale : float
        Factor from path units to ``units`` (e.g. 1e-3 for pulses of 1 um to mm).
    resolution : float, optional
        Write positions to this length [``units``], e.g. a thousandth of a pulse; by
        default 17 significant digits.
    overwrite : bool

    Raises
    ------
    ExportError
        For setpoints not at a fixed period, or a bad scale.
    """
    sp = SetpointArrays.from_series(setpoints)
    if not (np.isfinite(scale) and scale > 0):
        raise ExportError(f"scale must be finite and > 0, got {scale!r}")
    period = _uniform_period(sp.t)
    d = decimals_for_resolution(resolution)
    position = sp.position * scale
    head = [
        f"# nurbsmotion setpoints for LinuxCNC halstreamer: {len(sp.t)} lines, one per servo "
        f"period of {period:.9g} s",
        f"# load the streamer with: loadrt streamer depth=... cfg={'f' * sp.n_axes}",
        "# columns: " + " ".join(f"{a} [{units}]" for a in sp.axis_names)
        + ("" if d is None else f" (to {10.0 ** -d:g} {units})"),
    ]
    fmt = " ".join([_fixed(position, d)] * sp.n_axes)

    def write(f) -> None:
        buffer = io.StringIO()
        np.savetxt(buffer, position, fmt=fmt, header="\n".join(head), comments="")
        f.write(buffer.getvalue())

    return write_output(file, write, overwrite=overwrite)


def save_ros_trajectory(setpoints: Any, file: str | os.PathLike, *, period: float, scale: float = 1.0,
                        resolution: float | None = None, overwrite: bool = False) -> Path:
    """Write the motion as a ROS 2 ``trajectory_msgs/msg/JointTrajectory`` in YAML (see
    the module docstring).

    Parameters
    ----------
    setpoints : SetpointArrays or any object with t, u, position [, axis_names]
    file : str or path-like
    period : float
        Time between points [s], > 0.
    scale : float
        Factor from path units to metres (e.g. 1e-6 for pulses of 1 um).
    resolution : float, optional
        Write positions to this length [m] (velocities and accelerations to that length
        per second and per second squared); by default 17 significant digits.
    overwrite : bool
    """
    from scipy.interpolate import CubicSpline  # loaded by these two exports only

    sp = SetpointArrays.from_series(setpoints)
    if not (np.isfinite(scale) and scale > 0):
        raise ExportError(f"scale must be finite and > 0, got {scale!r}")
    table = pvt_table(sp, period)
    spline = CubicSpline(sp.t - sp.t[0], sp.position * scale, axis=0)
    since = table.t - sp.t[0]
    position, velocity, acceleration = spline(since), spline(since, 1), spline(since, 2)
    d = decimals_for_resolution(resolution)
    number = (lambda x: f"{x:.17g}") if d is None else (lambda x: f"{x:.{d}f}")
    nanoseconds = np.rint(since * 1e9).astype(np.int64)
    lines = [
        "# trajectory_msgs/msg/JointTrajectory (ROS 2), written by nurbsmotion: positions [m],",
        "# velocities [m/s], accelerations [m/s^2], time_from_start [s + ns]",
        "header:",
        "  stamp: {sec: 0, nanosec: 0}",
        "  frame_id: ''",
        f"joint_names: [{', '.join(sp.axis_names)}]",
        "points:",
    ]
    for k in range(len(since)):
        sec, nanosec = divmod(int(nanoseconds[k]), 1_000_000_000)
        lines += [
            f"  - positions: [{', '.join(map(number, position[k]))}]",
            f"    velocities: [{', '.join(map(number, velocity[k]))}]",
            f"    accelerations: [{', '.join(map(number, acceleration[k]))}]",
            "    effort: []",
            f"    time_from_start: {{sec: {sec}, nanosec: {nanosec}}}",
        ]
    text = "\n".join(lines) + "\n"
    return write_output(file, lambda f: f.write(text), overwrite=overwrite)


def save_motion_gcode(
    setpoints: Any,
    file: str | os.PathLike,
    *,
    units: str = "mm",
    scale: float = 1.0,
    overwrite: bool = False,
) -> Path:
    """Write the motion as a LinuxCNC program: one G1 per sample with its own F.

    Parameters
    ----------
    setpoints : SetpointArrays or any object with t, u, position [, axis_names]
        Axis names must be G-code axis letters (x, y, z, a, b, c, u, v, w).
    file : str or path-like
        Output program.
    units : {"mm", "inch"}
        Units to declare (G21/G20) for ``position * scale``.
    scale : float
        Factor from path units to ``units``, e.g. 1e-3 for pulses of 1 um to mm.
    overwrite : bool
        Replace an existing file.

    Notes
    -----
    Each G1 lasts exactly one sample period at its F (``F = |dp| / dt * 60``); a sample
    where the setpoint does not move becomes a ``G4`` dwell of that period, trailing holds
    are dropped. Use ``G64`` blending tolerance or ``G61`` on the controller as suits it;
    the program sets ``G61`` (exact path) so the programmed points are met.
    """
    # The G-code package (its reader and all) is not loaded by the other exports, nor by
    # a run's trace file metadata, which this module also writes.
    from ..paths.gcode.writer import decimals_for, format_number

    sp = SetpointArrays.from_series(setpoints)
    if units not in ("mm", "inch"):
        raise ExportError(f"units must be 'mm' or 'inch', got {units!r}")
    if not (np.isfinite(scale) and scale > 0):
        raise ExportError(f"scale must be finite and > 0, got {scale!r}")
    letters = [a.upper() for a in sp.axis_names]
    bad = [a for a in letters if a not in "XYZABCUVW" or len(a) != 1]
    if bad:
        raise ExportError(f"axis names {bad} are not G-code axis letters")
    position = sp.position * scale
    d = decimals_for(float(np.max(np.ptp(position, axis=0))) or 1.0)
    dt = np.diff(sp.t)
    last = int(np.max(np.flatnonzero(np.any(np.diff(position, axis=0) != 0, axis=1)), initial=-1)) + 1

    def coords(p) -> str:
        return " ".join(f"{a}{format_number(x, d)}" for a, x in zip(letters, p))

    lines = [
        f"(nurbsmotion motion: {len(sp.t)} setpoints, period {format_number(np.median(dt), 9)} s)",
        f"{'G21' if units == 'mm' else 'G20'} G90 G17 G94 G61",
        f"G0 {coords(position[0])}",
    ]
    for k in range(1, last + 1):
        step = position[k] - position[k - 1]
        distance = float(np.linalg.norm(step))
        if distance == 0.0:
            lines.append(f"G4 P{format_number(dt[k - 1], 9)}")
            continue
        feed = distance / dt[k - 1] * 60.0
        lines.append(f"G1 {coords(position[k])} F{format_number(feed, decimals_for(feed, 12))}")
    lines.append("M2")
    text = "\n".join(lines) + "\n"
    return write_output(file, lambda f: f.write(text), overwrite=overwrite)
