"""Files a run writes: ``trace.csv``, ``summary.json``, and the Markdown / JSON tables.

The column names and summary keys are contracts that users' scripts read; add, never
rename.

- ``trace.csv``: ``t,u,`` then for each axis ``a``:
  ``a_cmd,a_act,a_drive,a_drive_applied`` and, when the interpolator computed them,
  ``a_speed_min,a_speed_max`` [pulse/s]; row k is sample k: thd[k], tha[k] measured before
  u[k] is applied, u[k] before and after clipping.
- ``summary.json``: :data:`SUMMARY_KEYS`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Iterable

import numpy as np

from .errors import OutputExistsError

__all__ = ["SUMMARY_KEYS", "trace_columns", "write_trace_csv", "summary", "write_json",
           "markdown_table", "check_writable"]

SUMMARY_KEYS = (
    "cycle_time_s", "steps", "max_following_error", "rms_following_error",
    "max_contour_error", "rms_contour_error", "max_drive_ratio", "saturated_samples",
    "feed_fluctuation_max", "feed_fluctuation_rms", "interpolator", "feed", "machine", "path",
    "time_optimal_bound_s", "cycle_time_ratio", "settle_time_s", "settled", "settle_window",
    "end_overshoot", "corner_overshoot", "move_and_settle_ratio",
)
"""Keys of ``summary.json``, in order."""


def check_writable(paths: Iterable[Path], overwrite: bool) -> None:
    """Raise :class:`OutputExistsError` naming the first existing output unless ``overwrite``."""
    if overwrite:
        return
    for p in paths:
        if Path(p).exists():
            raise OutputExistsError(f"{p} exists; choose another output folder or pass --overwrite")


def trace_columns(trace) -> tuple[list[str], np.ndarray]:
    """Header and data of ``trace.csv``, shape (n_samples, n_columns)."""
    header = ["t", "u"]
    cols = [trace.t, trace.u]
    Ke = trace.machine.Ke
    for j, a in enumerate(trace.machine.axis_names):
        header += [f"{a}_cmd", f"{a}_act", f"{a}_drive", f"{a}_drive_applied"]
        cols += [trace.position_command[:, j], trace.position[:, j], trace.drive[:, j],
                 trace.drive_applied[:, j]]
        if trace.speed_bounds is not None:
            header += [f"{a}_speed_min", f"{a}_speed_max"]
            cols += [trace.speed_bounds[:, j, 0] * Ke[j], trace.speed_bounds[:, j, 1] * Ke[j]]
    return header, np.column_stack(cols)


def write_trace_csv(trace, path: Path) -> Path:
    """Write ``trace.csv`` (full double precision)."""
    header, data = trace_columns(trace)
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="", fmt="%.17g")
    return Path(path)


def summary(metrics, *, interpolator: str, feed: float, machine: str, path: str,
            time_optimal_bound: float) -> dict:
    """The ``summary.json`` dictionary (:data:`SUMMARY_KEYS`, in that order).

    ``feed`` is the commanded feed [pulse/s]; ``time_optimal_bound`` is the SPEC section 9
    bound [s] (:func:`nurbsmotion.planning.time_optimal_bound`), and ``cycle_time_ratio``
    the cycle time divided by it; ``move_and_settle_ratio`` is the settle time (SPEC
    section 10) divided by the bound (``inf`` when the motion did not settle).
    """
    data = metrics.to_dict()
    data.update(interpolator=interpolator, feed=float(feed), machine=machine, path=path,
                time_optimal_bound_s=float(time_optimal_bound),
                cycle_time_ratio=metrics.cycle_time_s / time_optimal_bound,
                move_and_settle_ratio=metrics.settle_time_s / time_optimal_bound)
    return {k: data[k] for k in SUMMARY_KEYS}


def _json_safe(value):
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None  # JSON has no inf/NaN
    return value


def write_json(data, path: Path) -> Path:
    """Write JSON (inf and NaN as null), indented."""
    Path(path).write_text(json.dumps(_json_safe(data), indent=2) + "\n")
    return Path(path)


def _fmt(value, digits=3) -> str:
    if isinstance(value, dict):
        return " / ".join(_fmt(v, digits) for v in value.values())
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if value is None or not math.isfinite(value):
        return "–"
    return f"{value:.{digits}g}"


TABLE_COLUMNS = (
    ("path", "path"), ("feed_m_s", "feed [m/s]"), ("interpolator", "interpolator"),
    ("cycle_time_s", "cycle time [s]"), ("time_optimal_bound_s", "bound [s]"),
    ("cycle_time_ratio", "cycle / bound"), ("max_drive_ratio", "max drive / Umax"),
    ("saturated_samples", "saturated samples"), ("max_contour_error", "max contour [pulse]"),
    ("rms_contour_error", "RMS contour [pulse]"), ("max_following_error",
                                                   "max following [pulse]"),
    ("rms_following_error", "RMS following [pulse]"),
    ("feed_fluctuation_max", "feed fluct. max"), ("feed_fluctuation_rms", "feed fluct. RMS"),
)
"""Columns of the reproduce table: (key in a row, header)."""


_TIMES = ("cycle_time_s", "time_optimal_bound_s", "cycle_time_ratio")


def markdown_table(rows: list[dict], columns=TABLE_COLUMNS) -> str:
    """A Markdown table of summary rows; per-axis values are shown as ``x / y``.

    Rows are ``summary.json`` dictionaries with an added ``feed_m_s``; the axis order of
    per-axis cells is given in the header line.
    """
    present = [(k, h) for k, h in columns if any(k in r for r in rows)]
    axes = next((list(r["max_drive_ratio"]) for r in rows if "max_drive_ratio" in r), [])
    lines = ["| " + " | ".join(h for _, h in present) + " |",
             "|" + "|".join("---" for _ in present) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(
            r[k] if isinstance(r.get(k), str) else _fmt(r.get(k), 4 if k in _TIMES else 3)
            for k, _ in present) + " |")
    if axes:
        lines.append("")
        lines.append(f"Per-axis cells read {' / '.join(axes)}.")
    return "\n".join(lines) + "\n"
