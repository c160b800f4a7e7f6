"""Files a run writes: ``trace.csv`` / ``trace.parquet``, ``summary.json``, and the
Markdown / JSON tables.

The column names and summary keys are contracts that users' scripts read; add, never
rename.

- ``trace.csv`` (or ``trace.parquet``): ``t,u,`` then for each axis ``a``:
  ``a_cmd,a_act,a_drive,a_drive_applied`` and, when the interpolator computed them,
  ``a_speed_min,a_speed_max`` [pulse/s]; then the same lengths in the report unit ``L``
  (:func:`nurbsmotion.units.report_unit`, ``mm`` or ``in``): for each axis
  ``a_cmd_L,a_act_L`` and ``a_speed_min_L_per_s,a_speed_max_L_per_s``. Row k is sample k:
  thd[k], tha[k] measured before u[k] is applied, u[k] before and after clipping [V].
  ``--trace-every N`` keeps one row in N (and the row where the end is reached and the
  last row).
- ``summary.json``: :data:`SUMMARY_KEYS`, then ``length_unit``, the length figures in that
  unit (``max_contour_error_mm``, ...; :func:`summary`) and a ``units`` block giving the
  unit of every key.

The trace is written in chunks of :data:`TRACE_CHUNK_ROWS` rows by pyarrow (imported
when a trace is written), so neither its text nor a copy of all its columns is ever held
in memory.
"""

from __future__ import annotations

import io
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from ._io import write_output
from .errors import OutputExistsError

__all__ = ["SUMMARY_KEYS", "SUMMARY_LENGTH_KEYS", "TRACE_FORMATS", "TRACE_FILES",
           "trace_columns", "write_trace", "write_trace_csv", "estimate_trace_bytes",
           "trace_rows", "summary", "summary_units", "write_json", "markdown_table",
           "check_writable"]

SUMMARY_KEYS = (
    "cycle_time_s", "steps", "max_following_error", "rms_following_error",
    "max_contour_error", "rms_contour_error", "max_drive_ratio", "saturated_samples",
    "feed_fluctuation_max", "feed_fluctuation_rms", "interpolator", "feed", "machine", "path",
    "time_optimal_bound_s", "cycle_time_ratio", "limited_samples", "cornered_samples",
    "success", "message", "settle_time_s", "settled", "settle_window", "end_overshoot",
    "corner_overshoot", "move_and_settle_ratio",
)
"""The first keys of ``summary.json``, in order (contract); more follow, see :func:`summary`."""

SUMMARY_LENGTH_KEYS = ("max_following_error", "rms_following_error", "max_contour_error",
                       "rms_contour_error", "end_overshoot", "corner_overshoot")
"""Summary keys in pulses that are repeated in the report unit (``<key>_mm``, ``<key>_in``)."""

_SUMMARY_UNITS = {
    "cycle_time_s": "s", "steps": "samples", "max_following_error": "pulse",
    "rms_following_error": "pulse", "max_contour_error": "pulse",
    "rms_contour_error": "pulse", "max_drive_ratio": "1 (max |u| / Umax, before clipping)",
    "saturated_samples": "samples", "feed_fluctuation_max": "1 (relative, 0.01 = 1 %)",
    "feed_fluctuation_rms": "1 (relative, 0.01 = 1 %)", "interpolator": "name",
    "feed": "pulse/s", "machine": "name", "path": "name or file",
    "time_optimal_bound_s": "s", "cycle_time_ratio": "1 (cycle time / bound)",
    "length_unit": "name", "limited_samples": "samples", "cornered_samples": "samples",
    "success": "true or false", "message": "text", "plant": "name or file",
    "corner_tolerance": "pulse", "feed_used": "text", "settle_time_s": "s",
    "settled": "true or false", "settle_window": "pulse", "end_overshoot": "pulse",
    "corner_overshoot": "pulse", "move_and_settle_ratio": "1 (settle time / bound)",
}

TRACE_FORMATS = ("csv", "parquet")
"""Formats of the trace file."""

TRACE_FILES = {fmt: f"trace.{fmt}" for fmt in TRACE_FORMATS}
"""Trace format -> file name."""

TRACE_CHUNK_ROWS = 4_096
"""Rows converted and written at a time (a few chunks are in flight: about 1 MB each
for two axes)."""


def check_writable(paths: Iterable[Path], overwrite: bool) -> None:
    """Raise :class:`OutputExistsError` naming the first existing output unless ``overwrite``."""
    if overwrite:
        return
    for p in paths:
        if Path(p).exists():
            raise OutputExistsError(f"{p} exists; choose another output folder or pass --overwrite")


@dataclass(frozen=True)
class _Column:
    """One trace column: its name and how to read rows ``idx`` of it from a trace."""

    name: str
    read: Callable[[np.ndarray], np.ndarray]


def _columns(trace, length_unit: str | None, pulses_per_length_unit: float | None):
    """The trace file's columns, in order (see the module docstring)."""
    cols = [_Column("t", lambda i: trace.t[i]), _Column("u", lambda i: trace.u[i])]
    Ke = trace.machine.Ke
    bounds = trace.speed_bounds
    for j, a in enumerate(trace.machine.axis_names):
        cols += [_Column(f"{a}_cmd", lambda i, j=j: trace.position_command[i, j]),
                 _Column(f"{a}_act", lambda i, j=j: trace.position[i, j]),
                 _Column(f"{a}_drive", lambda i, j=j: trace.drive[i, j]),
                 _Column(f"{a}_drive_applied", lambda i, j=j: trace.drive_applied[i, j])]
        if bounds is not None:
            cols += [_Column(f"{a}_speed_min", lambda i, j=j: bounds[i, j, 0] * Ke[j]),
                     _Column(f"{a}_speed_max", lambda i, j=j: bounds[i, j, 1] * Ke[j])]
    if length_unit is None:
        return cols
    L, k = length_unit, 1.0 / pulses_per_length_unit
    for j, a in enumerate(trace.machine.axis_names):
        cols += [_Column(f"{a}_cmd_{L}", lambda i, j=j: trace.position_command[i, j] * k),
                 _Column(f"{a}_act_{L}", lambda i, j=j: trace.position[i, j] * k)]
        if bounds is not None:
            cols += [
                _Column(f"{a}_speed_min_{L}_per_s", lambda i, j=j: bounds[i, j, 0] * Ke[j] * k),
                _Column(f"{a}_speed_max_{L}_per_s", lambda i, j=j: bounds[i, j, 1] * Ke[j] * k),
            ]
    return cols


def trace_rows(trace, every: int = 1) -> np.ndarray:
    """Sample indices a trace file keeps: every ``every``-th, plus the sample where the
    end is reached and the last one, shape (m,)."""
    n = len(trace.t)
    if every < 1:
        raise ValueError(f"trace_every must be >= 1, got {every}")
    if every == 1:
        return np.arange(n)
    return np.union1d(np.arange(0, n, every), [trace.finished_index, n - 1])


def trace_columns(trace, length_unit: str | None = None,
                  pulses_per_length_unit: float | None = None) -> tuple[list[str], np.ndarray]:
    """Header and data of the trace file, shape (n_samples, n_columns) (small traces; the
    writers stream instead)."""
    cols = _columns(trace, length_unit, pulses_per_length_unit)
    idx = np.arange(len(trace.t))
    return [c.name for c in cols], np.column_stack([c.read(idx) for c in cols])


def _chunk_table(cols, idx):
    import pyarrow as pa

    return pa.table({c.name: np.ascontiguousarray(c.read(idx), dtype=float) for c in cols})


def _chunks(rows: np.ndarray):
    """Row selections of :data:`TRACE_CHUNK_ROWS` rows: slices where ``rows`` is every
    sample (views, no copy), index arrays otherwise."""
    every_row = len(rows) == 0 or (rows[-1] - rows[0] == len(rows) - 1)
    for start in range(0, len(rows), TRACE_CHUNK_ROWS):
        if every_row:
            yield slice(int(rows[start]), int(rows[min(start + TRACE_CHUNK_ROWS,
                                                          len(rows)) - 1]) + 1)
        else:
            yield rows[start:start + TRACE_CHUNK_ROWS]


def _csv_bytes(cols, idx) -> bytes:
    import pyarrow.csv as pacsv

    buffer = io.BytesIO()
    pacsv.write_csv(_chunk_table(cols, idx), buffer,
                    write_options=pacsv.WriteOptions(include_header=False,
                                                     quoting_style="none"))
    return buffer.getvalue()


def _rows_in(idx) -> int:
    return idx.stop - idx.start if isinstance(idx, slice) else len(idx)


def _write_csv_chunks(handle, cols, rows, progress) -> None:
    """CSV text of the chunks, formatted on a few threads (pyarrow releases the GIL)
    and written in order; at most ``workers + 1`` chunks are held at a time."""
    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    # pyarrow quotes header names; the header is written here, unquoted, as csv readers
    # and the contract expect.
    handle.write((",".join(c.name for c in cols) + "\n").encode())
    workers = max(1, min(2, os.cpu_count() or 1))
    pending: deque = deque()
    with ThreadPoolExecutor(workers) as pool:
        def drain(limit: int) -> None:
            while len(pending) > limit:
                n, future = pending.popleft()
                handle.write(future.result())
                if progress is not None:
                    progress(n)

        for idx in _chunks(rows):
            pending.append((_rows_in(idx), pool.submit(_csv_bytes, cols, idx)))
            drain(workers)
        drain(0)


def _write_parquet_chunks(handle, cols, rows, progress) -> None:
    """Parquet row groups of the chunks: plain byte-stream-split doubles with zstd (float
    columns gain nothing from dictionaries, which cost most of the time)."""
    import pyarrow.parquet as pq

    writer = None
    try:
        for idx in _chunks(rows):
            table = _chunk_table(cols, idx)
            if writer is None:
                writer = pq.ParquetWriter(handle, table.schema, use_dictionary=False,
                                          compression="zstd",
                                          column_encoding="BYTE_STREAM_SPLIT")
            writer.write_table(table)
            if progress is not None:
                progress(_rows_in(idx))
    finally:
        if writer is not None:
            writer.close()


def write_trace(trace, path, *, fmt: str = "csv", every: int = 1,
                length_unit: str | None = None, pulses_per_length_unit: float | None = None,
                overwrite: bool = False,
                progress: Callable[[int], None] | None = None) -> Path:
    """Write the trace file, streamed in chunks, atomically.

    Parameters
    ----------
    trace : Trace
    path : path-like
        Target file (``trace.csv`` or ``trace.parquet``).
    fmt : {"csv", "parquet"}
        CSV (shortest text that reads back to the same double) or Parquet.
    every : int
        Keep one row in ``every`` (see :func:`trace_rows`).
    length_unit : str, optional
        Report unit (``"mm"``, ``"in"``) of the added length columns; none without it.
    pulses_per_length_unit : float, optional
        Pulses per ``length_unit``.
    overwrite : bool
        Replace an existing file.
    progress : callable, optional
        Called with the number of rows written after each chunk.
    """
    if fmt not in TRACE_FORMATS:
        raise ValueError(f"trace format must be one of {TRACE_FORMATS}, got {fmt!r}")
    cols = _columns(trace, length_unit, pulses_per_length_unit)
    rows = trace_rows(trace, every)
    write = _write_csv_chunks if fmt == "csv" else _write_parquet_chunks
    return write_output(path, lambda h: write(h, cols, rows, progress), overwrite=overwrite,
                        binary=True)


def write_trace_csv(trace, path: Path, *, overwrite: bool = True) -> Path:
    """Write ``trace.csv`` with the pulse columns only (full double precision)."""
    return write_trace(trace, path, overwrite=overwrite)


def estimate_trace_bytes(trace, *, fmt: str = "csv", every: int = 1,
                         length_unit: str | None = None,
                         pulses_per_length_unit: float | None = None) -> int:
    """Size the trace file would have [byte], from 2,000 of its rows spread over the run."""
    cols = _columns(trace, length_unit, pulses_per_length_unit)
    rows = trace_rows(trace, every)
    sample = rows[np.linspace(0, len(rows) - 1, min(len(rows), 2000)).astype(int)]
    buffer = io.BytesIO()
    if fmt == "csv":
        _write_csv_chunks(buffer, cols, sample, None)
    else:
        _write_parquet_chunks(buffer, cols, sample, None)
    return int(buffer.tell() * len(rows) / len(sample))


def summary(metrics, *, interpolator: str, feed: float, machine: str, path: str,
            time_optimal_bound: float, length_unit: str | None = None,
            pulses_per_length_unit: float | None = None, extra: dict | None = None) -> dict:
    """The ``summary.json`` dictionary.

    Keys: :data:`SUMMARY_KEYS` in that order; then, given a ``length_unit`` ``L``,
    ``length_unit``, ``<key>_L`` for each of :data:`SUMMARY_LENGTH_KEYS` and
    ``feed_L_per_s``; last, ``units``: the unit of every other key
    (:func:`summary_units`).

    Parameters
    ----------
    metrics : Metrics
    interpolator, machine, path : str
        Names carried into the summary.
    feed : float
        Commanded feed [pulse/s].
    time_optimal_bound : float
        SPEC section 9 bound [s] (:func:`nurbsmotion.planning.time_optimal_bound`);
        ``cycle_time_ratio`` is the cycle time divided by it, ``move_and_settle_ratio``
        the settle time (SPEC section 10) divided by it (``inf`` when the motion did not
        settle).
    length_unit : str, optional
        The report unit (``"mm"``, ``"in"``; :func:`nurbsmotion.units.report_unit`).
    pulses_per_length_unit : float, optional
        Pulses per ``length_unit``; required with it.
    extra : dict, optional
        Further keys of the run (``plant``, ``corner_tolerance``, ``feed_used``), added
        before ``units``.
    """
    data = metrics.to_dict()
    data.update(interpolator=interpolator, feed=float(feed), machine=machine, path=path,
                time_optimal_bound_s=float(time_optimal_bound),
                cycle_time_ratio=metrics.cycle_time_s / time_optimal_bound,
                move_and_settle_ratio=metrics.settle_time_s / time_optimal_bound)
    out = {k: data[k] for k in SUMMARY_KEYS}
    if length_unit is not None:
        k = 1.0 / pulses_per_length_unit
        out["length_unit"] = length_unit
        for key in SUMMARY_LENGTH_KEYS:
            v = out[key]
            out[f"{key}_{length_unit}"] = ({a: x * k for a, x in v.items()}
                                           if isinstance(v, dict) else v * k)
        out[f"feed_{length_unit}_per_s"] = out["feed"] * k
    out.update(extra or {})
    out["units"] = summary_units(out)
    return out


def summary_units(data: dict) -> dict:
    """The unit of every key of a summary dictionary (per-axis values share one unit)."""
    units = {}
    L = data.get("length_unit")
    for key in data:
        if key in _SUMMARY_UNITS:
            units[key] = _SUMMARY_UNITS[key]
        elif L is not None and key == f"feed_{L}_per_s":
            units[key] = f"{L}/s"
        elif L is not None and key.endswith(f"_{L}"):
            units[key] = L
    return units


def _json_safe(value):
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None  # JSON has no inf/NaN
    return value


def write_json(data, path: Path, *, overwrite: bool = False) -> Path:
    """Write JSON (inf and NaN as null), indented, through a temporary name."""
    text = json.dumps(_json_safe(data), indent=2) + "\n"
    return write_output(path, lambda h: h.write(text), overwrite=overwrite)


def _fmt(value, digits=3) -> str:
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if value is None or not math.isfinite(value):
        return "–"
    return f"{value:.{digits}g}"


TABLE_COLUMNS = (
    ("path", "path"), ("feed_m_s", "feed [m/s]"), ("interpolator", "interpolator"),
    ("cycle_time_s", "cycle time [s]"), ("time_optimal_bound_s", "bound [s]"),
    ("cycle_time_ratio", "cycle / bound"), ("settle_time_s", "settled [s]"),
    ("move_and_settle_ratio", "settled / bound"), ("end_overshoot_{L}", "end overshoot [{L}]"),
    ("end_overshoot", "end overshoot [pulse]"),
    ("max_drive_ratio", "max drive {axis} / Umax"),
    ("saturated_samples", "saturated samples {axis}"),
    ("max_contour_error_{L}", "max contour [{L}]"), ("max_contour_error", "max contour [pulse]"),
    ("rms_contour_error_{L}", "RMS contour [{L}]"),
    ("max_following_error_{L}", "max following {axis} [{L}]"),
    ("feed_fluctuation_max", "feed fluct. max"), ("feed_fluctuation_rms", "feed fluct. RMS"),
)
"""Columns of the reproduce table: (key in a row, header). ``{L}`` is the rows'
``length_unit``; a per-axis value gets one column per axis, ``{axis}`` naming it."""


_TIMES = ("cycle_time_s", "time_optimal_bound_s", "cycle_time_ratio", "settle_time_s",
          "move_and_settle_ratio")


def markdown_table(rows: list[dict], columns=TABLE_COLUMNS) -> str:
    """A Markdown table of summary rows, one column per axis for per-axis values.

    Rows are ``summary.json`` dictionaries with an added ``feed_m_s``. Columns whose key
    no row has are left out.
    """
    unit = next((r["length_unit"] for r in rows if "length_unit" in r), None)
    present = []  # (header, key, axis or None)
    for key, header in columns:
        if "{L}" in key:
            if unit is None:
                continue
            key, header = key.format(L=unit), header.replace("{L}", unit)
        first = next((r[key] for r in rows if key in r), None)
        if first is None:
            continue
        if isinstance(first, dict):
            present += [(header.replace("{axis}", a), key, a) for a in first]
        else:
            present.append((header.replace(" {axis}", ""), key, None))
    lines = ["| " + " | ".join(h for h, _, _ in present) + " |",
             "|" + "|".join("---" for _ in present) + "|"]
    for r in rows:
        cells = []
        for _, key, axis in present:
            v = r.get(key)
            if axis is not None and isinstance(v, dict):
                v = v.get(axis)
            cells.append(v if isinstance(v, str) else _fmt(v, 4 if key in _TIMES else 3))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
