"""The figures of :mod:`nurbsmotion.plots`: contour, following error, drive, speed and
settle of a run (:func:`plot_trace`), the setpoints of an open-loop interpolation
(:func:`plot_setpoints`) and the comparison of several runs (:func:`plot_comparison`,
:func:`plot_comparisons` in forked workers), with the windowed figures (the whole run
beside a window per event) reused between files of one layout.
"""

from __future__ import annotations

import contextlib
import functools
import math
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InvalidArgumentError
from ..metrics import nearest_parameter
from ..units import OutputUnits
from ._canvas import (
    _arrange, _axis_labels, _feed_text, _figure, _fit_in_view, _legend_below,
    _output_dir, _save, _STYLES, _title,
)
from .events import (
    MAX_EVENT_WINDOWS, _desired_in_window, _desired_parameters, _desired_points, _Event,
    _event_time, _events, _label_corners, _make_run, _MAX_ERROR_ZOOMS,
    _MIN_ZOOM_HALF_WIDTH_PULSES, _Run, _SETTLE_ZOOM, settling_time, _window, _zoom_windows,
)

TRACE_FIGURES = ("contour.png", "following_error.png", "drive.png", "speed.png",
                 "settle.png")
"""Files :func:`plot_trace` writes (after its prefix)."""


SETPOINT_FIGURES = ("setpoints.png",)
"""Files :func:`plot_setpoints` writes (after its ``prefix``)."""


def comparison_figures(name: str, axis_names) -> list[str]:
    """Files :func:`plot_comparison` writes for ``name`` and the axes it draws (all)."""
    return ([f"{name}_contour.png"] + [f"{name}_speed_{a}.png" for a in axis_names]
            + [f"{name}_drive_{a}.png" for a in axis_names])


DRIVE_FRAME = 1.25
"""The drive axes span ±DRIVE_FRAME × Umax: the limit lines and a margin above them."""


def _window_columns(fig, n_rows: int, n_events: int):
    """Axes grid: a wide whole-run column then one column per event, every event panel
    on its row's y scale (their tick labels are hidden); shape (n_rows, 1 + n_events)."""
    grid = fig.add_gridspec(n_rows, 1 + n_events, width_ratios=[2.4] + [1] * n_events)
    axes = np.empty((n_rows, 1 + n_events), dtype=object)
    for r in range(n_rows):
        for c in range(1 + n_events):
            share = axes[r, 0] if c > 0 else None
            axes[r, c] = fig.add_subplot(grid[r, c], sharey=share)
    return axes


_reused: dict | None = None
"""Figures kept for reuse by layout while a :func:`_figure_reuse` block runs, and the
paths in the report unit (:func:`_in_report_unit`, :func:`_desired_of`)."""


@contextlib.contextmanager
def _figure_reuse():
    """Within this block the windowed figures of one layout (rows, events, size) are drawn
    on one Figure, its panels emptied between files (:func:`_windowed_figure`): making the
    panels and their ticks was about a third of the time of such a figure; and a path
    drawn again (at another feed) is scaled to the report unit once, its geometry and
    nearest-point grid with it. Nested blocks share the outermost one's figures and
    paths; they are dropped when it ends."""
    global _reused
    outer = _reused
    if outer is None:
        _reused = {}
    try:
        yield
    finally:
        if outer is None:
            _reused = None


def _windowed_layout(n_rows: int, n_events: int):
    """A new figure and its :func:`_window_columns` grid, shape (n_rows, 1 + n_events)."""
    fig = _figure(4.0 + 2.3 * n_events, 2.7 * n_rows + 1.0)
    return fig, _window_columns(fig, n_rows, n_events)


def _windowed_figure(n_rows: int, events: list[_Event]):
    """A figure and its :func:`_window_columns` grid, shape (n_rows, 1 + len(events)):
    inside :func:`_figure_reuse` the one of this layout, emptied, else one made ahead
    (:func:`prepare_trace`) or a new one."""
    return _reusable(("windowed", n_rows, len(events)))


def _reusable(key: tuple):
    """The figure of layout ``key`` and its panels: inside :func:`_figure_reuse` the one
    of this layout, emptied, else one made ahead (:func:`prepare_trace`) or a new one."""
    if _reused is not None and key in _reused:
        fig, axes = _reused[key]
        _empty(fig, fig.axes)
        return fig, axes
    fig, axes = _blank(key)
    if _reused is not None:
        _reused[key] = (fig, axes)
    return fig, axes


_LAYOUTS: dict[str, Callable] = {}
"""Layout name -> function(*sizes) -> (fig, axes) making an empty figure of that layout;
a layout key is ``(name, *sizes)``."""

_made_ahead: dict = {}
"""Empty figures :func:`prepare_trace` made before the trace existed, by layout key; each
is taken once (:func:`_blank`)."""

_EXTRA_TICKS = 2
"""Major ticks made ahead per axis of such a figure beyond the labels that fit along it
(``Axis.get_tick_space``, what the default locator aims at): its locator may add one at
either end, just outside the view. A tick is a few artists (lines, labels) that matplotlib
makes when a draw first needs it, the largest cost of a new panel; any more that a draw
needs are made then, as always."""


def _blank(key: tuple):
    """An empty figure of layout ``key``: one made ahead, or a new one."""
    made = _made_ahead.pop(key, None)
    return made if made is not None else _LAYOUTS[key[0]](*key[1:])


def _make_ahead(key: tuple) -> None:
    """Make an empty figure of layout ``key`` with its ticks, for :func:`_blank`."""
    fig, axes = _LAYOUTS[key[0]](*key[1:])
    for ax in fig.axes:
        if ax.name == "rectilinear":  # (a 3-D panel makes its ticks at its draw)
            for axis in (ax.xaxis, ax.yaxis):
                axis.get_major_ticks(axis.get_tick_space() + _EXTRA_TICKS)
    fig.canvas.get_renderer()
    _made_ahead[key] = (fig, axes)


def _rows_layout(width: float, row_height: float, n_rows: int, n_cols: int):
    """A new figure of ``n_rows`` x ``n_cols`` panels sharing their time axis [inch]."""
    fig = _figure(width, row_height * n_rows + 1.0)
    return fig, fig.subplots(n_rows, n_cols, sharex=True, squeeze=False)


_LAYOUTS.update(windowed=_windowed_layout, rows=_rows_layout)


def _empty(fig, axes) -> None:
    """Remove what was drawn on ``fig`` and its ``axes`` (keeping the panels, their
    shared scales, tick settings and ticks), and let the scales follow the data again."""
    for legend in list(fig.legends):
        legend.remove()
    for ax in axes:
        for inset in list(ax.child_axes):  # the drive figure's hold inset
            inset.remove()
        for artist in [*ax.lines, *ax.patches, *ax.collections, *ax.texts]:
            artist.remove()
        for text in (ax.title, ax._left_title, ax._right_title):
            text.set_text("")
        ax.set_xlabel("")
        ax.set_ylabel("")
        ax.relim()
        ax.autoscale(True)


def _plot_windowed(axes_row, runs: list[_Run], events: list[_Event], settle: float,
                   values, *, frame: float | None = None, bounds=None) -> None:
    """One quantity over the whole run (first panel) and around each event.

    ``values(run)`` gives the (n_samples,) series of a run; ``bounds(run)`` optionally
    (n_samples, 2) lower/upper bounds drawn in black. With ``frame``, the value axis is
    ±frame and samples beyond it are marked on its edge.
    """
    for c, ax in enumerate(axes_row):
        event = None if c == 0 else events[c - 1]
        for run in runs:
            y = values(run)
            t = run.t
            if event is not None:
                t0 = _event_time(run, event)
                lo, hi = _window(event, settle)
                sel = (t >= t0 + lo - 1e-12) & (t <= t0 + hi + 1e-12)
                t, y = t[sel] - t0, y[sel]
                yb = None if bounds is None or bounds(run) is None else bounds(run)[sel]
            else:
                yb = None if bounds is None else bounds(run)
            ax.plot(t, y, color=run.color, linestyle=run.linestyle, linewidth=1.1,
                    label=run.label)
            if yb is not None:
                ax.plot(t, yb[:, 1], color="k", linewidth=0.8, label="upper bound (eq. 3.6)")
                ax.plot(t, yb[:, 0], color="k", linewidth=0.8, linestyle="--",
                        label="lower bound (eq. 3.6)")
            if frame is not None:
                _mark_beyond(ax, t, y, frame, run.color)
        if event is None:
            for run in runs:
                ax.axvline(run.trace.cycle_time, color="0.6", linestyle=":", linewidth=0.8)
            ax.set_xlabel("time [s]")
        else:
            ax.axvline(0.0, color="0.6", linestyle=":", linewidth=0.8)
            ax.set_xlim(*_window(event, settle))
            ax.set_xlabel("t − t_event [s]")
            ax.tick_params(labelleft=False)
        if frame is not None:
            ax.set_ylim(-frame, frame)
        ax.grid(True, linewidth=0.3, color="0.85")


def _mark_beyond(ax, t, y, frame: float, color: str) -> None:
    """Triangles on the frame's edge where ``y`` lies beyond ±frame."""
    for sign, marker in ((1, "^"), (-1, "v")):
        out = sign * y > frame
        if np.any(out):
            ax.plot(t[out], np.full(np.count_nonzero(out), sign * frame * 0.97), marker,
                    color=color, markersize=4, linestyle="none", clip_on=False,
                    label="beyond the frame (clipped)")


def _drive_title(runs: list[_Run], j: int, umax: float, fig, ax) -> str:
    """Peak |u| / Umax of axis j per run, and how many samples lie beyond the frame,
    wrapped to the width of the panel ``ax`` (a longer line would run into the title of
    the next panel)."""
    import textwrap

    parts = []
    for run in runs:
        d = np.abs(run.trace.drive[:, j])
        beyond = int(np.count_nonzero(d > DRIVE_FRAME * umax))
        text = f"{run.label} {np.max(d) / umax:.3g}"
        if beyond:
            text += f" ({beyond} off-frame ▲▼)"
        parts.append(text)
    width_in = ax.get_position().width * fig.get_figwidth()
    chars = max(20, int(width_in * 72 / (0.6 * 8.5)))  # "small" text: about 8.5 pt
    lines = ["max |u| / Umax:"]
    for part in parts:  # whole runs per line, never a run's figures split
        if len(lines[-1]) + 2 + len(part) <= chars:
            lines[-1] += (" " if lines[-1].endswith(":") else ", ") + part
        else:
            lines[-1] += "," if not lines[-1].endswith(":") else ""
            lines.append(part)
    return "\n".join(textwrap.shorten(line, chars, placeholder="…") if len(line) > chars
                     else line for line in lines)


def _path_panel(ax, desired, runs: list[_Run], i: int, j: int, names, unit: str) -> None:
    """Desired path and actual positions in the plane of axes i and j, equal scales."""
    ax.plot(desired[:, i], desired[:, j], color="k", linewidth=1, label="desired path")
    for r in runs:
        ax.plot(r.position[:, i], r.position[:, j], color=r.color, linestyle=r.linestyle,
                linewidth=1.2, label=f"actual, {r.label}")
    ax.set_xlabel(f"{names[i]} [{unit}]")
    ax.set_ylabel(f"{names[j]} [{unit}]")
    ax.set_aspect("equal", adjustable="datalim")


def _contour_layout(n_axes: int, n_zooms: int):
    """A new contour figure (:func:`_contour_figure`) of a path of ``n_axes`` axes with
    ``n_zooms`` zooms, and its panels: ``(fig, (path, projections, error, zooms))``; the
    path panel is 3-D, with three projections beneath, for 3 axes or more."""
    one_row = n_zooms == 1  # path, error and the zoom side by side
    n_cols = 3 if n_axes >= 3 or one_row else max(2, min(n_zooms, 4))
    n_rows = 2 if n_axes >= 3 else (1 if one_row else 1 + math.ceil(n_zooms / n_cols))
    fig = _figure(4.4 * n_cols, 4.4 * n_rows + 0.6)
    grid = fig.add_gridspec(n_rows, 2 * n_cols)
    half = 2 if one_row else (3 if n_axes >= 3 else n_cols)
    err_slot = grid[0, half:4] if one_row else grid[0, half:]
    zoom_slots = ([grid[0, 4:]] if one_row else
                  [grid[1 + j // n_cols, 2 * (j % n_cols):2 * (j % n_cols) + 2]
                   for j in range(n_zooms)])
    # made in the order the figure was always drawn in (the order of fig.axes)
    ax_path = fig.add_subplot(grid[0, :half], projection="3d" if n_axes >= 3 else None)
    projections = ([fig.add_subplot(grid[1, 2 * c:2 * c + 2]) for c in range(3)]
                   if n_axes >= 3 else [])
    ax_err = fig.add_subplot(err_slot)
    return fig, (ax_path, projections, ax_err, [fig.add_subplot(s) for s in zoom_slots])


_LAYOUTS["contour"] = _contour_layout


def _contour_figure(curve, runs: list[_Run], title: str, path: Path, names, unit: str,
                    per_unit: float, overwrite: bool) -> Path:
    """The desired path against each run's actual positions, the contour error over time,
    and square zooms (equal axes) on the corners; a 3-D path as a 3-D view and its three
    projections. ``curve`` and the runs are in the report unit."""
    from matplotlib.colors import to_rgba
    from matplotlib.ticker import MaxNLocator

    # Searched on the path in pulses, whose nearest-point grid the run's metrics made
    # (kept on it), and scaled: the contour error in the report unit.
    pulses = runs[0].trace.curve
    nearest = [(u, d / per_unit) for u, d in (nearest_parameter(pulses, r.trace.position)
                                              for r in runs)]
    n_axes = curve.n_axes
    planar = n_axes == 2
    zooms = (_zoom_windows(curve, runs, nearest, _MIN_ZOOM_HALF_WIDTH_PULSES / per_unit)
             if planar else [])
    key = ("contour", n_axes, len(zooms))
    # a planar layout is reused (its panels emptied) like the windowed ones; a 3-D one not
    fig, (ax_path, projections, ax_err, zoom_axes) = _reusable(key) if planar else _blank(key)
    if ax_err.get_yscale() != "linear":  # a reused panel: the last figure's log scale
        ax_err.set_yscale("linear")
    desired_u, desired = _desired_of(curve)

    if n_axes >= 3:
        ax_path.plot(desired[:, 0], desired[:, 1], desired[:, 2], color="k", linewidth=1,
                     label="desired path")
        for r in runs:
            ax_path.plot(r.position[:, 0], r.position[:, 1], r.position[:, 2], color=r.color,
                         linestyle=r.linestyle, linewidth=1.2, label=f"actual, {r.label}")
        for k, setter in enumerate((ax_path.set_xlabel, ax_path.set_ylabel,
                                    ax_path.set_zlabel)):
            setter(f"{names[k]} [{unit}]")
        ax_path.set_box_aspect(np.maximum(np.ptp(desired[:, :3], axis=0), 1e-9))
        _title(ax_path, "contour (3-D view)" + ("" if n_axes == 3 else ", first 3 axes"))
        for ax, (i, j) in zip(projections, ((0, 1), (0, 2), (1, 2))):
            _path_panel(ax, desired, runs, i, j, names, unit)
            _title(ax, f"projection on {names[i]}{names[j]}", fontsize="medium")
    elif planar:
        _path_panel(ax_path, desired, runs, 0, 1, names, unit)
        _title(ax_path, "contour")
        labels = _label_corners(ax_path, curve, zooms)
    else:
        for r in runs:
            ax_path.plot(r.t, r.position[:, 0], color=r.color, linestyle=r.linestyle,
                         label=f"actual, {r.label}")
        ax_path.set_xlabel("time [s]")
        ax_path.set_ylabel(f"{names[0]} [{unit}]")
        _title(ax_path, "position")

    for r, (_, dist) in zip(runs, nearest):
        ax_err.plot(r.t, dist, color=r.color, linestyle=r.linestyle,
                    label=f"contour error, {r.label} (max {np.max(dist):.3g} {unit})")
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel(f"contour error [{unit}]")
    _title(ax_err, "contour error (distance to the curve)")
    peaks = [float(np.max(d)) for _, d in nearest if np.max(d) > 0]
    if len(peaks) > 1 and max(peaks) > 20 * min(peaks):
        # Runs orders of magnitude apart: on a linear axis the smaller ones are a flat line.
        ax_err.set_yscale("log")
        ax_err.set_ylim(min(peaks) / 100, 2 * max(peaks))
    else:
        ax_err.set_ylim(bottom=0)
    ax_err.grid(True, linewidth=0.3, color="0.85")

    for j, (z, ax) in enumerate(zip(zooms, zoom_axes)):
        fine = _desired_in_window(curve, desired_u, desired, z)
        ax.plot(fine[:, 0], fine[:, 1], color="k", linewidth=1)
        for r in runs:
            # the samples are what the encoder measured; the faint line only orders them
            # (the machine does not move in straight lines between samples)
            ax.plot(r.position[:, 0], r.position[:, 1], color=to_rgba(r.color, 0.35),
                    linestyle=r.linestyle, linewidth=0.8, marker=".", markersize=5,
                    markerfacecolor=r.color, markeredgecolor=r.color)
        (cx, cy), h = z.center, z.half_width
        ax.set_xlim(cx - h, cx + h)
        ax.set_ylim(cy - h, cy + h)
        ax.set_aspect("equal", adjustable="box")
        _title(ax, f"{chr(65 + j)}: {z.label}, ±{h:.2g} {unit}", fontsize="small")
        ax.set_xlabel(f"{names[0]} [{unit}]")
        ax.set_ylabel(f"{names[1]} [{unit}]")
        ax.ticklabel_format(useOffset=False, style="plain")
        ax.xaxis.set_major_locator(MaxNLocator(4))
    _legend_below(fig, [ax_path, ax_err], ncol=2)
    fig.suptitle(title)
    if planar:
        _arrange(fig)  # the labels are fitted on the panel's final size
        _fit_in_view(ax_path, labels)
    return _save(fig, path, overwrite)


def _trace_title(trace, feed: float | None, per_unit: float, unit: str) -> str:
    if feed is None:
        feed = float(np.max(trace.feed))
    name = trace.curve.name or "path"
    return f"{name}, {trace.interpolator}, {_feed_text(feed, per_unit, unit)}"


def _drive_figure(runs: list[_Run], events, settle: float, title: str, path: Path,
                  axes_shown, overwrite: bool) -> Path:
    """u before clipping [V] per axis (rows): whole run and event windows (columns)."""
    machine = runs[0].trace.machine
    names, umax = machine.axis_names, machine.max_drive
    fig, grid = _windowed_figure(len(axes_shown), events)
    finite = math.isfinite(umax)
    for row, j in zip(grid, axes_shown):
        _plot_windowed(row, runs, events, settle, lambda r, j=j: r.trace.drive[:, j],
                       frame=DRIVE_FRAME * umax if finite else None)
        for ax in row:
            if finite:
                for sign in (1, -1):
                    ax.axhline(sign * umax, color="k", linestyle="--", linewidth=0.9,
                               label="±Umax" if sign > 0 else None)
        row[0].set_ylabel(f"{names[j]}: u [V]")
        _hold_inset(row[0], runs[0], j)
        if finite:
            _title(row[0], _drive_title(runs, j, umax, fig, row[0]), fontsize="small",
                             loc="left")
    for c, event in enumerate(events, start=1):
        _title(grid[0, c], event.label, fontsize="medium")
    _legend_below(fig, grid)
    fig.suptitle(f"drive before clipping (Fig. 7), {title}")
    return _save(fig, path, overwrite)


def _hold_inset(ax, run: _Run, j: int) -> None:
    """On a run that went on after it settled (a true plant with effects): the applied
    drive over that hold, on its own scale, so that its chatter is seen."""
    tr = run.trace
    hold = getattr(tr, "hold_samples", 0)
    if hold < 2:
        return
    t, y = tr.t[-hold:], tr.drive_applied[-hold:, j]
    inset = ax.inset_axes([0.56, 0.06, 0.42, 0.36])
    inset.plot(t, y, color=run.color, linewidth=0.7, marker=".", markersize=1.5)
    chatter = float(np.sqrt(np.mean(np.diff(y) ** 2)))
    inset.set_title(f"last {hold * tr.machine.sample_period:.3g} s (hold): chatter RMS "
                    f"{chatter:.3g} V", fontsize="x-small")
    inset.tick_params(labelsize="x-small")
    inset.grid(True, linewidth=0.3, color="0.85")


def _speed_figure(rows: list, events, settle: float, title: str, path: Path, unit: str,
                  overwrite: bool) -> Path:
    """Commanded axis speed [L/s] and its eq. 3.6 bounds where computed; one panel row per
    ``(run, axis index, label)`` in ``rows``."""
    fig, grid = _windowed_figure(len(rows), events)
    for panels, (run, j, label) in zip(grid, rows):
        _plot_windowed(panels, [run], events, settle, lambda r, j=j: r.speed_command[:, j],
                       bounds=(lambda r, j=j: None if r.speed_bounds is None
                               else r.speed_bounds[:, j, :]))
        panels[0].set_ylabel(f"{label} speed [{unit}/s]")
    for col, event in enumerate(events, start=1):
        _title(grid[0, col], event.label, fontsize="medium")
    _legend_below(fig, grid)
    fig.suptitle(title)
    return _save(fig, path, overwrite)


def _settle_figure(run: _Run, title: str, path: Path, unit: str, per_unit: float,
                   settle: float, overwrite: bool) -> Path:
    """Actual position minus the end point per axis [L] from shortly before the setpoint
    reaches the end to the last sample: the whole approach (left) and a zoom (right,
    ±:data:`_SETTLE_ZOOM` windows) on the run's settle band, ±``trace.settle_window``
    [pulse] (the window its settle time was measured with)."""
    tr = run.trace
    names = tr.machine.axis_names
    # the path's end point (a planned setpoint leads the path: the command at the
    # finished sample is not the end point)
    end = tr.curve.end_points[1] / per_unit
    t0 = tr.cycle_time
    sel = tr.t >= t0 - 0.5 * settle
    t = tr.t[sel] - t0
    window = float(tr.settle_window)  # [pulse]
    band = window / per_unit
    within = f"±{window:g} pulse"
    measured = getattr(tr, "position_measured", None)
    start = tr.curve.end_points[0]
    counts = measured is not None and bool(np.all(
        measured - start == np.floor(measured - start)))
    fig, axes = _blank(("rows", 11.0, 2.3, len(names), 2))
    for j, (ax_all, ax_zoom) in enumerate(axes):
        dev = run.position[sel, j] - end[j]
        after = np.nonzero((t >= 0) & (np.abs(dev) > band))[0]
        if after.size == 0:
            when = f"within {within} when the setpoint reaches the end"
        elif after[-1] + 1 < len(t):
            when = f"within {within} from t_end + {t[after[-1] + 1]:.4g} s on"
        else:
            when = f"not within {within} by the last sample"
        for ax in (ax_all, ax_zoom):
            ax.axhspan(-band, band, color="C2", alpha=0.25,
                       label=f"settle window {within} (±{band:.3g} {unit})")
            ax.plot(t, dev, color=run.color, marker=".", markersize=3, linewidth=1,
                    label=f"actual − end point, {run.label}")
            if measured is not None:  # what the controller read, beside the truth
                ax.step(t, measured[sel, j] / per_unit - end[j], where="post",
                        color="C3", linewidth=0.8, label="measured − end point")
            ax.axvline(0.0, color="0.6", linestyle=":", linewidth=0.8,
                       label="setpoint reaches the end")
            ax.grid(True, linewidth=0.3, color="0.85")
        ax_zoom.set_ylim(-_SETTLE_ZOOM * band, _SETTLE_ZOOM * band)
        if counts:  # the encoder's count grid, where a reading can fall
            origin = (tr.curve.end_points[0][j] - tr.curve.end_points[1][j]) % 1.0
            reach = math.ceil(_SETTLE_ZOOM * window) + 1  # [pulse]
            for n in np.arange(-reach, reach + 1):
                ax_zoom.axhline((n + origin) / per_unit, color="0.5", linewidth=0.4,
                                linestyle="-", label="encoder counts" if n == 0 else None)
        ax_all.set_ylabel(f"{names[j]} − end [{unit}]")
        _title(ax_all, f"{names[j]}: {when}", fontsize="medium", loc="left")
        _title(ax_zoom, f"{names[j]}, zoom ±{_SETTLE_ZOOM * window:g} pulse",
               fontsize="medium", loc="left")
    for ax in axes[-1]:
        ax.set_xlabel("t − t_end [s] (t_end: the setpoint reaches the end point)")
    _legend_below(fig, axes, ncol=3)
    fig.suptitle(f"settling at the end point, {title}")
    return _save(fig, path, overwrite)


def _following_figure(run: _Run, title: str, path: Path, unit: str,
                      overwrite: bool) -> Path:
    """thd - tha per axis [L] over the whole run."""
    trace = run.trace
    names = trace.machine.axis_names
    fig, axes = _blank(("rows", 8.0, 2.2, len(names), 1))
    axes = axes[:, 0]
    error = run.position_command - run.position
    for j, ax in enumerate(axes):
        ax.plot(trace.t, error[:, j], color=run.color, label="θd − θa")
        ax.axvline(trace.cycle_time, color="0.6", linestyle=":", linewidth=0.8,
                   label="setpoint reaches the end")
        ax.set_ylabel(f"{names[j]}: θd − θa [{unit}]")
        _title(ax, f"{names[j]}: max |e| = {np.max(np.abs(error[:, j])):.4g} {unit}",
                     fontsize="medium", loc="left")
        ax.grid(True, linewidth=0.3, color="0.85")
    axes[-1].set_xlabel("time [s]")
    _legend_below(fig, axes, ncol=2)
    fig.suptitle(f"following error, {title}")
    return _save(fig, path, overwrite)


_ahead: tuple | None = None
"""What :func:`prepare_trace` computed of a path: ``(path [pulse], machine, length unit
asked, unit, pulses per unit, the path in that unit, its desired parameters and points)``."""


def _in_report_unit(curve, machine, length_unit: str | None):
    """``(unit, pulses per unit, curve in that unit)`` of a path [pulse] on ``machine``:
    the one :func:`prepare_trace` made for these very objects, or a new one."""
    if _ahead is not None and _ahead[0] is curve and _ahead[1] is machine \
            and _ahead[2] == length_unit:
        return _ahead[3:6]
    # Inside a _figure_reuse block (reproduce's comparisons: one path at several feeds)
    # the scaled path is kept, and with it its geometry and nearest-point grid.
    key = ("path", id(curve), id(machine), length_unit)
    if _reused is not None and key in _reused:
        return _reused[key][2:]
    units = OutputUnits.of(machine, curve.units, length_unit or None)
    unit, per_unit = units.unit, units.pulses_per_unit
    result = unit, per_unit, curve.scaled(1.0 / per_unit, units=unit)
    if _reused is not None:  # the objects are kept with it: their ids stay theirs
        _reused[key] = (curve, machine, *result)
    return result


def _desired_of(curve) -> tuple[np.ndarray, np.ndarray]:
    """The desired path as drawn: :func:`_desired_parameters` of ``curve`` [L] and its
    points, shape (m, n_axes) [L] (made ahead for the curve of :func:`prepare_trace`, kept
    for a curve :func:`_in_report_unit` kept)."""
    if _ahead is not None and _ahead[5] is curve:
        return _ahead[6:8]
    key = ("desired", id(curve))
    if _reused is not None and key in _reused:
        return _reused[key][1:]
    desired_u = _desired_parameters(curve)
    result = desired_u, curve(desired_u)
    if _reused is not None:
        _reused[key] = (curve, *result)
    return result


def prepare_trace(curve, machine, *, length_unit: str | None = None) -> None:
    """Do what :func:`plot_trace` of a run of ``curve`` on ``machine`` needs before the
    run's trace exists, so that it is not done then: import matplotlib, measure the
    fonts, compute the path in the report unit, its points and its nearest-point grid, its
    corners, and make the empty figures (with their ticks) of the layouts the run's
    figures will most likely have. A process that draws the run later (the command forks
    one before the run: :class:`nurbsmotion._runtime.forked.ForkedWorker`) calls it while
    the run goes on (step by step, :func:`prepare_trace_steps`); the figures are the same
    with or without it.

    Parameters
    ----------
    curve : NurbsCurve
        The run's path in the machine's pulses: the very object the trace will hold
        (``trace.curve``); another object, even an equal one, finds nothing prepared.
    machine : Machine
        The run's machine (``trace.machine``), the same way.
    length_unit : str, optional
        As :func:`plot_trace` will be given it.
    """
    for _ in prepare_trace_steps(curve, machine, length_unit=length_unit):
        pass


def prepare_trace_steps(curve, machine, *, length_unit: str | None = None):
    """:func:`prepare_trace` one step at a time: a generator that yields after each step
    (the imports, the path's data, the fonts, each empty figure), so that a process that
    prepares can stop as soon as the trace is there and draw, making what is left as the
    figures need it (:class:`nurbsmotion._runtime.forked.ForkedWorker` does); the steps
    are the figures' own work done early, in the order :func:`plot_trace` needs them.
    Parameters as :func:`prepare_trace`.
    """
    global _ahead
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401
    from PIL import PngImagePlugin  # noqa: F401

    from ._canvas import _label_extent
    import matplotlib as mpl
    from matplotlib.font_manager import FontProperties

    yield
    unit, per_unit, scaled = _in_report_unit(curve, machine, length_unit)
    desired_u = _desired_parameters(scaled)
    _ahead = (curve, machine, length_unit, unit, per_unit, scaled, desired_u,
              scaled(desired_u))
    # the grid of the path in pulses, kept on it, as _contour_figure searches it
    nearest_parameter(curve, np.asarray(curve.end_points)[:1])
    n_axes = curve.n_axes
    n_corners = len(curve.sharp_corners())
    scaled.sharp_corners()
    if n_axes == 2:
        _desired_points(scaled, 500)
    yield
    for name in ("xtick", "ytick"):  # the fonts, loaded and measured once
        size = FontProperties(size=mpl.rcParams[f"{name}.labelsize"]).get_size_in_points()
        _label_extent("lp", size)
    yield
    names = machine.axis_names
    # One run: a zoom per sharp corner of a planar path (else the largest errors, at most
    # _MAX_ERROR_ZOOMS); a window per corner (at most MAX_EVENT_WINDOWS; else as many
    # drive peaks) besides the start and the stop.
    n_zooms = 0 if n_axes != 2 else n_corners or _MAX_ERROR_ZOOMS
    n_events = 2 + min(n_corners or MAX_EVENT_WINDOWS, MAX_EVENT_WINDOWS)
    for key in (("contour", n_axes, n_zooms), ("rows", 8.0, 2.2, len(names), 1),
                ("windowed", len(names), n_events), ("rows", 11.0, 2.3, len(names), 2)):
        _make_ahead(key)
        yield


@_figure_reuse()
def plot_trace(trace, out_dir, prefix: str = "", *, feed: float | None = None,
               length_unit: str | None = None, overwrite: bool = True,
               processes: int = 1) -> list[Path]:
    """Write the figures of one closed-loop run.

    Parameters
    ----------
    trace : Trace
        The run (:func:`nurbsmotion.loop.simulate`); positions in pulses.
    out_dir : str or Path
        Folder for the PNG files, created if missing.
    prefix : str
        Put in front of every file name.
    feed : float, optional
        The commanded feed F for the title [pulse/s]; by default the largest feed the
        interpolator asked for.
    length_unit : str, optional
        Unit of every length in the figures (``"mm"``, ``"in"``, ...); by default the
        report unit of the trace's path (:func:`nurbsmotion.units.report_unit`).
    overwrite : bool
        Replace existing files.
    processes : int
        Processes that draw the figures, this one and one forked from it (where the
        platform forks) for 2 or more: one draws the drive and speed figures (one
        layout), the other the rest; the files are the same whatever the number.

    Returns
    -------
    list of Path
        :data:`TRACE_FIGURES`: ``contour.png`` (desired path against the actual
        positions, contour error over time [L], zooms on the sharp corners or on the
        largest contour error; a 3-D path in 3-D and in its projections),
        ``following_error.png`` (thd - tha per axis [L]), ``drive.png`` (u before
        clipping per axis [V], framed on ±Umax, with event windows), ``speed.png``
        (commanded axis speed [L/s] and the eq. 3.6 bounds where computed, with event
        windows) and ``settle.png`` (actual position minus the end point per axis [L]
        with the run's settle band, ±``trace.settle_window``).
    """
    from .._runtime.forked import call_forked

    out = _output_dir(out_dir)
    unit, per_unit, curve = _in_report_unit(trace.curve, trace.machine, length_unit)
    run = _make_run(trace, trace.interpolator, _STYLES[0], per_unit)
    names = trace.machine.axis_names
    title = _trace_title(trace, feed, per_unit, unit)
    settle = settling_time(trace.machine)
    events = _events(trace.curve, [trace], settle)
    n = range(len(names))
    figures = [
        lambda: _contour_figure(curve, [run], title, out / f"{prefix}contour.png", names,
                                unit, per_unit, overwrite),
        lambda: _following_figure(run, title, out / f"{prefix}following_error.png", unit,
                                  overwrite),
        lambda: _drive_figure([run], events, settle, title, out / f"{prefix}drive.png", n,
                              overwrite),
        lambda: _speed_figure([(run, j, names[j]) for j in n], events, settle,
                              f"axis speed command and its bounds (Fig. 6), {title}",
                              out / f"{prefix}speed.png", unit, overwrite),
        lambda: _settle_figure(run, title, out / f"{prefix}settle.png", unit, per_unit,
                               settle, overwrite),
    ]
    # The drive and speed figures have one layout: one process draws both, the second on
    # the first's emptied panels (_figure_reuse), where two would each make its panels
    # and ticks; the contour, following-error and settle figures are about as much work.
    groups = [(2, 3), (0, 1, 4)]
    drawn = call_forked([functools.partial(_draw_group, figures, g) for g in groups],
                        processes)
    written: list = [None] * len(figures)
    for group, files in zip(groups, drawn):
        for index, file in zip(group, files):
            written[index] = file
    return written


def _draw_group(figures: list, group) -> list:
    """``[figures[i]() for i in group]``: figures drawn by one process, in this order."""
    return [figures[i]() for i in group]


def plot_setpoints(series, out_dir, axis_names=None, *, units: str | None = None,
                   prefix: str = "", overwrite: bool = True) -> list[Path]:
    """Write ``setpoints.png`` of an open-loop interpolation.

    Left: the path of the setpoints (first two axes; a 3-D path in 3-D; position against
    time for a single axis). Right: the commanded feed and the chord speed
    ``|thd[k] - thd[k-1]| / Ts`` the setpoints actually move at (the last, shortened step
    reaches the end exactly).

    Parameters
    ----------
    series : SetpointSeries
        From :func:`nurbsmotion.interpolators.interpolate`.
    out_dir : str or Path
        Folder for the PNG file, created if missing.
    axis_names : sequence of str, optional
        Axis labels; ``("x", "y", "z", ...)`` by default.
    units : str, optional
        Length unit of the positions for the labels (e.g. ``"pulse"``, ``"mm"``);
        ``"path unit"`` by default.
    prefix : str
        Put in front of the file name.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    list of Path
        ``[out_dir / (prefix + "setpoints.png")]``.
    """
    out = _output_dir(out_dir)
    unit = units or "path unit"
    pos = series.position
    names = _axis_labels(pos.shape[1], axis_names)
    fig = _figure(11.0, 5.0)
    three_d = pos.shape[1] >= 3
    ax_path = fig.add_subplot(1, 2, 1, projection="3d" if three_d else None)
    ax_feed = fig.add_subplot(1, 2, 2)
    if pos.shape[1] >= 2:
        few = len(pos) <= 500  # sample dots only where they stay apart
        cols = [pos[:, k] for k in range(3 if three_d else 2)]
        ax_path.plot(*cols, color="C0", linewidth=1, marker="." if few else None,
                     markersize=3, label="setpoints")
        ax_path.plot(*[[c[0]] for c in cols], "o", color="C2", label="start")
        ax_path.plot(*[[c[-1]] for c in cols], "s", color="C3", label="end")
        ax_path.set_xlabel(f"{names[0]} [{unit}]")
        ax_path.set_ylabel(f"{names[1]} [{unit}]")
        if three_d:
            ax_path.set_zlabel(f"{names[2]} [{unit}]")
            ax_path.set_box_aspect(np.maximum(np.ptp(pos[:, :3], axis=0), 1e-9))
        else:
            ax_path.set_aspect("equal", adjustable="datalim")
    else:
        ax_path.plot(series.t, pos[:, 0], color="C0", label="setpoints")
        ax_path.set_xlabel("time [s]")
        ax_path.set_ylabel(f"{names[0]} [{unit}]")
    _title(ax_path, "setpoints")

    chord = np.linalg.norm(np.diff(pos, axis=0), axis=1) / series.sample_period
    ax_feed.plot(series.t[1:], series.feed[1:], color="k", linewidth=1, label="commanded feed")
    ax_feed.plot(series.t[1:], chord, color="C3", linestyle="--", linewidth=1,
                 label="chord speed |Δθd|/Ts")
    ax_feed.axvline(series.cycle_time, color="0.6", linestyle=":", linewidth=0.8,
                    label="end reached")
    ax_feed.set_xlabel("time [s]")
    ax_feed.set_ylabel(f"feed [{unit}/s]")
    ax_feed.set_ylim(bottom=0)
    fl_max, fl_rms = series.feed_fluctuation()
    _title(ax_feed, f"feed fluctuation max {100 * fl_max:.3g} %, RMS {100 * fl_rms:.3g} %",
                      fontsize="medium")
    _legend_below(fig, [ax_path, ax_feed], ncol=3)
    fig.suptitle(f"{series.finished_index} steps, cycle time {series.cycle_time:.4g} s")
    return [_save(fig, out / f"{prefix}setpoints.png", overwrite)]


@_figure_reuse()
def plot_comparison(traces: dict, out_dir, name: str, *, feed: float | None = None,
                    axis: int | None = None, length_unit: str | None = None,
                    overwrite: bool = True) -> list[Path]:
    """Write the figures comparing algorithms on one path at one feed (``reproduce``).

    Parameters
    ----------
    traces : dict of str to Trace
        Algorithm name (``"taylor2"``, ``"paper"``, ...) to its run of the same path at
        the same feed; drawn in this order, the first solid, the second dashed, ...
    out_dir : str or Path
        Folder for the PNG files, created if missing.
    name : str
        Prefix of the file names and the path's name in the titles (e.g. ``"pi_1.0"``).
    feed : float, optional
        The commanded feed F [pulse/s]; by default the largest feed any run asked for.
    axis : int, optional
        Only this axis for the speed and drive figures; every axis by default.
    length_unit : str, optional
        Unit of every length (``"mm"``, ``"in"``); by default the report unit of the
        path (:func:`nurbsmotion.units.report_unit`).
    overwrite : bool
        Replace existing files.

    Returns
    -------
    list of Path
        ``{name}_contour.png`` (Fig. 5: desired path and every run's actual contour, with
        corner zooms), then per axis ``ax``: ``{name}_speed_{ax}.png`` (Fig. 6: each
        run's commanded speed [L/s] inside its eq. 3.6 bounds where it computed them,
        one row per run) and ``{name}_drive_{ax}.png`` (Fig. 7: every run's drive [V],
        framed on ±Umax); both with the whole run and windows around the start, the
        corners and the stop.
    """
    if not traces:
        raise InvalidArgumentError("plot_comparison needs at least one trace")
    out = _output_dir(out_dir)
    items = list(traces.items())
    first = items[0][1]
    machine = first.machine
    names = machine.axis_names
    if axis is not None and not 0 <= axis < len(names):
        raise InvalidArgumentError(f"axis {axis} out of range for axes {names}")
    shown = range(len(names)) if axis is None else [axis]
    unit, per_unit, curve = _in_report_unit(first.curve, machine, length_unit)
    if feed is None:
        feed = max(float(np.max(tr.feed)) for _, tr in items)
    title = f"{name}: {_feed_text(feed, per_unit, unit)}"
    runs = [_make_run(tr, label, _STYLES[i % len(_STYLES)], per_unit)
            for i, (label, tr) in enumerate(items)]
    settle = settling_time(machine)
    events = _events(first.curve, [tr for _, tr in items], settle)
    written = [_contour_figure(curve, runs, title, out / f"{name}_contour.png", names, unit,
                               per_unit, overwrite)]
    for j in shown:
        written.append(_speed_figure([(r, j, f"{r.label}: {names[j]}") for r in runs],
                                     events, settle, f"{names[j]} speed command and its "
                                     f"bounds (Fig. 6), {title}",
                                     out / f"{name}_speed_{names[j]}.png", unit, overwrite))
        written.append(_drive_figure(runs, events, settle, f"{names[j]}, {title}",
                                     out / f"{name}_drive_{names[j]}.png", [j], overwrite))
    return written


def plot_comparisons(jobs: list, *, processes: int | None = None,
                     done: Callable[[int], None] | None = None) -> list[Path]:
    """Write the figures of several comparisons (:func:`plot_comparison`), shared between
    this process and processes forked from it where the platform forks
    (:func:`nurbsmotion._runtime.forked.call_forked`, as :func:`plot_trace` shares its
    figures).

    Parameters
    ----------
    jobs : list of (dict, path-like, str, dict)
        ``(traces, out_dir, name, options)`` per comparison: the arguments of
        :func:`plot_comparison`, ``options`` its keyword arguments.
    processes : int, optional
        Processes that draw, this one included; by default one per CPU this process may
        run on (at most one per job). 1 draws here, one comparison after the other.
    done : callable, optional
        ``done(index)`` after the figures of ``jobs[index]`` are written, in job order.

    Returns
    -------
    list of Path
        Every file written, job after job, each job's in :func:`plot_comparison`'s order.
    """
    from .._runtime.forked import call_forked, usable_cpus

    if processes is None:
        processes = usable_cpus()
    import matplotlib.backends.backend_agg  # noqa: F401  (imported once, before forking)

    calls = [functools.partial(plot_comparison, traces, out_dir, name, **options)
             for traces, out_dir, name, options in jobs]
    with _figure_reuse():  # each process draws its comparisons on figures of its own
        drawn = call_forked(calls, processes, done=done)
    return [path for files in drawn for path in files]
