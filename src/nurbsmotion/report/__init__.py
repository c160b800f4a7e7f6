"""Files a run writes: ``trace.csv`` / ``trace.parquet`` (:mod:`.trace_file`, re-exported
here), ``summary.json``, and the Markdown / JSON tables; a motion's setpoints, PVT tables
and G-code are :mod:`.export`.

The column names and summary keys are contracts that users' scripts read; add, never
rename.

- ``trace.csv`` (or ``trace.parquet``): ``t,u,`` then for each axis ``a``:
  ``a_cmd,a_act,a_drive,a_drive_applied`` and, when the interpolator computed them,
  ``a_speed_min,a_speed_max`` [pulse/s]; on a true plant with effects (issue 32) then
  ``a_meas`` for each axis, what the controller read (``a_act`` is the tool's true
  position); then the same lengths in the report unit ``L``
  (:func:`nurbsmotion.units.report_unit`, ``mm`` or ``in``): for each axis
  ``a_cmd_L,a_act_L`` and ``a_speed_min_L_per_s,a_speed_max_L_per_s`` (``L`` = ``deg`` for a
  rotary axis, one with ``pulses_per_degree``). Row k is sample k:
  thd[k], tha[k] measured before u[k] is applied, u[k] before and after clipping [V].
  ``--trace-every N`` keeps one row in N (and the row where the end is reached and the
  last row).
- ``summary.json``: :data:`SUMMARY_KEYS`, then ``length_unit``, the length figures in that
  unit (``max_contour_error_mm``, ...; :func:`summary`) and a ``units`` block giving the
  unit of every key.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Iterable

import numpy as np

from .._runtime.io import json_safe, write_output
from ..errors import OutputExistsError
from .trace_file import (TRACE_FILES, TRACE_FORMATS, TraceWriter,
                         estimate_trace_bytes, trace_columns, trace_rows, write_trace,
                         write_trace_csv)

if TYPE_CHECKING:
    from ..units import OutputUnits

__all__ = ["SUMMARY_KEYS", "SUMMARY_LENGTH_KEYS", "TRACE_FORMATS", "TRACE_FILES",
           "trace_columns", "TraceWriter", "write_trace", "write_trace_csv", "estimate_trace_bytes",
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
    "corner_tolerance": "pulse", "path_tolerance": "pulse", "feed_used": "text",
    "chords_joined": "chords", "chord_runs": "curves",
    "settle_time_s": "s",
    "settled": "true or false", "settle_window": "pulse", "end_overshoot": "pulse",
    "corner_overshoot": "pulse", "move_and_settle_ratio": "1 (settle time / bound)",
    "notes": "list of text", "path_unit": "name", "path_unit_source": "text",
    "hold_window_s": "s", "drive_chatter_rms": "V", "limit_cycle": "true or false",
    "residual_vibration": "pulse", "peak_speed": "pulse/s", "peak_acceleration": "pulse/s^2",
    "peak_jerk": "pulse/s^3", "drive_limit_time_s": "s", "machine_model": "machine file",
    "true_plant": "machine file",
}


def check_writable(paths: Iterable[Path], overwrite: bool) -> None:
    """Raise :class:`OutputExistsError` naming the first existing output unless ``overwrite``."""
    if overwrite:
        return
    for p in paths:
        if Path(p).exists():
            raise OutputExistsError(f"{p} exists; choose another output folder or pass --overwrite")



def summary(metrics, *, interpolator: str, feed: float, machine: str, path: str,
            time_optimal_bound: float, units: OutputUnits | None = None,
            extra: dict | None = None) -> dict:
    """The ``summary.json`` dictionary.

    Keys: :data:`SUMMARY_KEYS` in that order; then, given ``units`` whose report unit is
    ``L``, ``length_unit``, ``<key>_L`` for each of :data:`SUMMARY_LENGTH_KEYS` and
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
        docs/model.md#run-figures bound [s] (:func:`nurbsmotion.planning.time_optimal_bound`);
        ``cycle_time_ratio`` is the cycle time divided by it, ``move_and_settle_ratio``
        the settle time (docs/model.md#beyond-the-paper) divided by it (``inf`` when the motion did not
        settle).
    units : OutputUnits, optional
        The run's units on the way out (:attr:`nurbsmotion.job.RunResult.output_units`):
        the length keys are repeated in its report unit (``"mm"``, ``"in"``); none without.
    extra : dict, optional
        Further keys of the run (``plant``, ``corner_tolerance``, ``path_tolerance``,
        ``feed_used``, ``notes``), added before ``units``.
    """
    data = metrics.to_dict()
    data.update(interpolator=interpolator, feed=float(feed), machine=machine, path=path,
                time_optimal_bound_s=float(time_optimal_bound),
                cycle_time_ratio=metrics.cycle_time_s / time_optimal_bound,
                move_and_settle_ratio=metrics.settle_time_s / time_optimal_bound)
    out = {k: data[k] for k in SUMMARY_KEYS}
    if units is not None:
        k, length_unit = units.factor, units.unit
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
        elif L is not None and key.startswith("peak_") and f"_{L}_per_s" in key:
            units[key] = f"{L}/s" + key.rsplit("per_s", 1)[1].replace("2", "^2").replace(
                "3", "^3")
        elif L is not None and key.endswith(f"_{L}"):
            units[key] = L
    return units



def write_json(data, path: Path, *, overwrite: bool = False) -> Path:
    """Write JSON (inf and NaN as null), indented, through a temporary name."""
    text = json.dumps(json_safe(data), indent=2) + "\n"
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
