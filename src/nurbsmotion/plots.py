"""Figures of a run, written as PNG files (SPEC section 9; Figs. 5-7 of Yeh & Sun (2008)).

matplotlib is imported inside the functions, so ``import nurbsmotion`` never imports it.
Figures are built as :class:`matplotlib.figure.Figure` objects on an Agg canvas, without
pyplot: no global figure registry, no backend to select, nothing left open afterwards.

Every function takes an output folder (created if missing) and returns the paths it wrote.
Positions are plotted in pulses, speeds in pulse/ms (the unit of the paper's Fig. 6).

Glossary
--------
thd, tha : commanded and actual axis positions [pulse]; wd : commanded axis speed [rad/s];
wmin, wmax : speed bounds of eq. 3.6 [rad/s]; Ke : mechanical gain [pulse/rad];
u : drive before clipping [V]; Umax : drive limit [V]; F : commanded feed [pulse/s];
Ts : sample period [s].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._io import write_output
from .metrics import nearest_parameter

__all__ = ["plot_trace", "plot_setpoints", "plot_comparison", "TRACE_FIGURES",
           "SETPOINT_FIGURES", "comparison_figures"]

TRACE_FIGURES = ("contour.png", "following_error.png", "drive.png", "speed.png")
"""Files :func:`plot_trace` writes (after its ``prefix``)."""

SETPOINT_FIGURES = ("setpoints.png",)
"""Files :func:`plot_setpoints` writes (after its ``prefix``)."""


def comparison_figures(name: str, axis_name: str) -> list[str]:
    """Files :func:`plot_comparison` writes for ``name`` and the axis it draws."""
    return [f"{name}_contour.png", f"{name}_speed_{axis_name}.png",
            f"{name}_drive_{axis_name}.png"]

_DPI = 110
_STYLES = (("C0", "-"), ("C3", "--"), ("C2", "-."), ("C1", ":"), ("C4", "-"), ("C5", "--"))
"""(colour, line style) per run, in order: solid first, as the paper draws its proposed
algorithm solid and the uncompensated one dashed (Figs. 5 and 7)."""
_MIN_ZOOM_HALF_WIDTH = 50.0  # [pulse] so a 10-pulse deviation spans a tenth of a zoom
_ZOOM_MARGIN = 1.3  # the zoom holds the largest nearby contour error with this margin
_CORNER_REACH = 0.05  # samples within this fraction of the length size a corner's zoom
_CLOSE_ZOOM_RATIO = 3.0  # add a closer zoom when the runs' errors differ by this factor


@dataclass(frozen=True)
class _Run:
    """One line in a figure: a run's actual positions and how to draw them."""

    label: str
    t: np.ndarray  # (n_samples,) [s]
    position: np.ndarray  # (n_samples, n_axes) [pulse]
    color: str
    linestyle: str


@dataclass(frozen=True)
class _Zoom:
    """A square window of the path plane, centred on ``center`` (2,) [pulse]."""

    label: str
    center: np.ndarray
    half_width: float  # [pulse]


def _output_dir(out_dir) -> Path:
    path = Path(out_dir)
    path.mkdir(parents=True, exist_ok=True)
    return path


def _figure(width: float, height: float):
    """A Figure on its own Agg canvas (no pyplot state) [inch]."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: Path) -> Path:
    # Through a temporary name, so an interrupted save leaves no half-written PNG.
    write_output(path, lambda f: fig.savefig(f, dpi=_DPI, format="png"), overwrite=True,
                 binary=True)
    fig.clear()  # the figure is not registered anywhere; this frees its artists now
    return path


def _axis_labels(n_axes: int, axis_names=None) -> tuple[str, ...]:
    if axis_names is not None:
        names = tuple(str(a) for a in axis_names)
        if len(names) < n_axes:
            raise ValueError(f"{n_axes} axes need {n_axes} axis_names, got {names}")
        return names[:n_axes]
    default = ("x", "y", "z")
    return tuple(default[j] if j < 3 else f"axis {j}" for j in range(n_axes))


def _feed_text(feed: float, pulse_length_um: float | None) -> str:
    """``F = 1 m/s (1e+06 pulse/s)``; without a pulse length, pulse/s only."""
    if pulse_length_um is None:
        return f"F = {feed:.4g} pulse/s"
    return f"F = {feed * pulse_length_um * 1e-6:.4g} m/s ({feed:.3g} pulse/s)"


def _mark_end(ax, t_end: float) -> None:
    """Dotted vertical line at the cycle time (setpoint reaches the path's end)."""
    ax.axvline(t_end, color="0.5", linestyle=":", linewidth=1, label="end reached")


def _draw_drive_limits(ax, max_drive: float) -> None:
    """Dashed +-Umax lines (nothing for an ideal drive)."""
    if math.isfinite(max_drive):
        for sign in (1, -1):
            ax.axhline(sign * max_drive, color="k", linestyle="--", linewidth=1,
                       label="±Umax" if sign > 0 else None)


def _draw_speed(ax, t, speed_command, speed_bounds, Ke: float, color="C0", linestyle="-",
                label="speed command") -> None:
    """Commanded axis speed and its eq. 3.6 bounds, converted to pulse/ms.

    ``speed_command`` (n,) and ``speed_bounds`` (n, 2) or None are in rad/s; rad/s * Ke
    [pulse/rad] / 1000 gives pulse/ms. Bounds are drawn as the paper's Fig. 6 draws them
    (upper solid, lower dashed); NaN rows (not computed) leave gaps.
    """
    to_pulse_ms = Ke / 1000.0
    ax.plot(t, speed_command * to_pulse_ms, color=color, linestyle=linestyle, label=label)
    if speed_bounds is not None:
        ax.plot(t, speed_bounds[:, 1] * to_pulse_ms, color="k", linewidth=1,
                label="upper bound (eq. 3.6)")
        ax.plot(t, speed_bounds[:, 0] * to_pulse_ms, color="k", linewidth=1,
                linestyle="--", label="lower bound (eq. 3.6)")


def _desired_points(curve, n: int = 20000) -> np.ndarray:
    """Curve points uniform in arc length plus every breakpoint (corners drawn sharp),
    shape (m, n_axes) [pulse]."""
    u = np.union1d(curve.parameter_at(np.linspace(0.0, curve.length, n)), curve.breakpoints)
    return curve(u)


def _zoom_windows(curve, runs: list[_Run], nearest: list[tuple]) -> list[_Zoom]:
    """Where to zoom: every sharp corner, or the largest contour error if there is none.

    A corner's window holds the corner and, for every run, its sample of largest contour
    error near the corner (within ``_CORNER_REACH`` of the path length), with a margin.
    When the runs' errors there differ by more than ``_CLOSE_ZOOM_RATIO``, a closer
    window on the corner, sized to the smallest of them, is added so the better run's
    deviation (often 10-100 pulses) stays visible.

    ``nearest`` holds ``(u, distance)`` of :func:`~nurbsmotion.metrics.nearest_parameter`
    per run.
    """
    cap = 0.5 * float(np.max(np.ptp(_desired_points(curve, 500)[:, :2], axis=0)))
    cap = max(cap, _MIN_ZOOM_HALF_WIDTH)

    def window(label: str, points: list, err: float) -> _Zoom:
        """Square around ``points`` (each (2,) [pulse]) with room for ``err`` [pulse]."""
        pts = np.array(points)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        half = 0.5 * float(np.max(hi - lo)) + (_ZOOM_MARGIN - 1.0) * err
        half = min(max(_MIN_ZOOM_HALF_WIDTH, half, _ZOOM_MARGIN * err), cap)
        return _Zoom(label, 0.5 * (lo + hi), half)

    corners = curve.sharp_corners()
    if corners.size == 0:
        worst = [float(np.max(d)) for _, d in nearest]
        i = int(np.argmax(worst))
        k = int(np.argmax(nearest[i][1]))
        points = [runs[i].position[k, :2], curve(nearest[i][0][k])[:2]]
        return [window(f"largest contour error ({runs[i].label}, t = {runs[i].t[k]:.3f} s)",
                       points, worst[i])]
    zooms = []
    reach = _CORNER_REACH * curve.length
    for n, uc in enumerate(corners, start=1):
        corner = curve(uc)[:2]
        s_corner = float(curve.arc_length(uc))
        points, local = [corner], []
        for r, (u, d) in zip(runs, nearest):
            near = np.abs(curve.arc_length(u) - s_corner) <= reach
            if np.any(near):
                k = int(np.argmax(np.where(near, d, -1.0)))
                points.append(r.position[k, :2])
                local.append(float(d[k]))
            else:
                local.append(0.0)
        zooms.append(window(f"corner {n} (u = {uc:.3g})", points, max(local)))
        if max(local) > _CLOSE_ZOOM_RATIO * max(min(local), _MIN_ZOOM_HALF_WIDTH / 2):
            zooms.append(window(f"corner {n}, closer", [corner], min(local)))
    return zooms


def _contour_figure(curve, runs: list[_Run], title: str, path: Path,
                    axis_names: tuple[str, ...]) -> Path:
    """The desired path against each run's actual positions, its contour error over time,
    and square zooms (equal axes) on the corners; one figure for one run or several."""
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import MaxNLocator

    nearest = [nearest_parameter(curve, r.position) for r in runs]
    planar = curve.n_axes >= 2
    zooms = _zoom_windows(curve, runs, nearest) if planar else []
    n_cols = max(2, min(len(zooms), 4))
    n_zoom_rows = math.ceil(len(zooms) / n_cols)
    fig = _figure(4.2 * n_cols, 4.4 * (1 + n_zoom_rows))
    grid = fig.add_gridspec(1 + n_zoom_rows, 2 * n_cols)
    ax_path = fig.add_subplot(grid[0, :n_cols])
    ax_err = fig.add_subplot(grid[0, n_cols:])
    desired = _desired_points(curve)

    if planar:
        ax_path.plot(desired[:, 0], desired[:, 1], color="k", linewidth=1, label="desired path")
        for r in runs:
            ax_path.plot(r.position[:, 0], r.position[:, 1], color=r.color,
                         linestyle=r.linestyle, linewidth=1.2, label=f"actual, {r.label}")
        ax_path.set_xlabel(f"{axis_names[0]} [pulse]")
        ax_path.set_ylabel(f"{axis_names[1]} [pulse]")
        ax_path.set_aspect("equal", adjustable="datalim")
        ax_path.ticklabel_format(style="sci", scilimits=(-4, 4), useMathText=True)
        ax_path.set_title("contour" + ("" if curve.n_axes == 2 else " (first two axes)"))
    else:
        for r in runs:
            ax_path.plot(r.t, r.position[:, 0], color=r.color, linestyle=r.linestyle,
                         label=f"actual, {r.label}")
        ax_path.set_xlabel("time [s]")
        ax_path.set_ylabel(f"{axis_names[0]} [pulse]")
        ax_path.set_title("position")
    ax_path.legend(fontsize="small")

    for r, (_, dist) in zip(runs, nearest):
        ax_err.plot(r.t, dist, color=r.color, linestyle=r.linestyle,
                    label=f"{r.label} (max {np.max(dist):.4g} pulse)")
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel("contour error [pulse]")
    ax_err.set_title("contour error (distance to the curve)")
    ax_err.legend(fontsize="small")

    for j, z in enumerate(zooms):
        ax = fig.add_subplot(grid[1 + j // n_cols, 2 * (j % n_cols):2 * (j % n_cols) + 2])
        ax.plot(desired[:, 0], desired[:, 1], color="k", linewidth=1)
        for r in runs:
            ax.plot(r.position[:, 0], r.position[:, 1], color=r.color, linestyle=r.linestyle,
                    linewidth=1.2, marker=".", markersize=4)
        (cx, cy), h = z.center, z.half_width
        ax.set_xlim(cx - h, cx + h)
        ax.set_ylim(cy - h, cy + h)
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(f"{chr(65 + j)}: {z.label}, ±{h:.3g} pulse", fontsize="medium")
        ax.set_xlabel(f"{axis_names[0]} [pulse]")
        ax.set_ylabel(f"{axis_names[1]} [pulse]")
        ax.ticklabel_format(useOffset=False, style="plain")
        ax.xaxis.set_major_locator(MaxNLocator(4))
        ax_path.add_patch(Rectangle((cx - h, cy - h), 2 * h, 2 * h, fill=False,
                                    edgecolor="0.4", linewidth=0.8))
        ax_path.annotate(chr(65 + j), (cx + h, cy + h), fontsize="small", color="0.3")
    fig.suptitle(title)
    return _save(fig, path)


def _trace_title(trace, feed: float | None) -> str:
    if feed is None:
        feed = float(np.max(trace.feed))
    name = trace.curve.name or "path"
    return f"{name}, {trace.interpolator}, {_feed_text(feed, trace.machine.pulse_length_um)}"


def _run_of(trace, label: str, style: tuple[str, str]) -> _Run:
    return _Run(label, trace.t, trace.position, *style)


def plot_trace(trace, out_dir, prefix: str = "", *, feed: float | None = None) -> list[Path]:
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

    Returns
    -------
    list of Path
        ``contour.png`` (desired path against the actual positions, contour error over
        time, zooms on each sharp corner, or on the largest contour error when there is
        none), ``following_error.png`` (thd - tha per axis [pulse]), ``drive.png`` (u before
        clipping per axis [V], dashed +-Umax) and ``speed.png`` (commanded axis speed
        [pulse/ms] and, when the interpolator computed them, the eq. 3.6 bounds).
    """
    out = _output_dir(out_dir)
    names = trace.machine.axis_names
    n_axes = len(names)
    title = _trace_title(trace, feed)
    t_end = trace.cycle_time
    written = [_contour_figure(trace.curve, [_run_of(trace, trace.interpolator, _STYLES[0])],
                               title, out / f"{prefix}contour.png", names)]

    def panels(kind: str):
        fig = _figure(8.0, 2.4 * n_axes + 0.6)
        axes = fig.subplots(n_axes, 1, sharex=True, squeeze=False)[:, 0]
        axes[-1].set_xlabel("time [s]")
        fig.suptitle(f"{kind}: {title}")
        return fig, axes

    fig, axes = panels("following error")
    error = trace.position_command - trace.position
    for j, ax in enumerate(axes):
        ax.plot(trace.t, error[:, j], color="C0")
        _mark_end(ax, t_end)
        ax.set_ylabel(f"{names[j]}: θd − θa [pulse]")
        ax.legend(fontsize="small", loc="upper right")
        ax.set_title(f"{names[j]}: max |e| = {np.max(np.abs(error[:, j])):.4g} pulse",
                     fontsize="medium", loc="left")
    written.append(_save(fig, out / f"{prefix}following_error.png"))

    fig, axes = panels("drive")
    umax = trace.machine.max_drive
    for j, ax in enumerate(axes):
        ax.plot(trace.t, trace.drive[:, j], color="C0", label="u before clipping")
        _draw_drive_limits(ax, umax)
        _mark_end(ax, t_end)
        ax.set_ylabel(f"{names[j]}: u [V]")
        if math.isfinite(umax):
            ax.set_title(f"{names[j]}: max |u| = {np.max(np.abs(trace.drive[:, j])) / umax:.3g}"
                         " Umax", fontsize="medium", loc="left")
        ax.legend(fontsize="small", loc="upper right")
    written.append(_save(fig, out / f"{prefix}drive.png"))

    fig, axes = panels("axis speed")
    for j, ax in enumerate(axes):
        bounds = None if trace.speed_bounds is None else trace.speed_bounds[:, j, :]
        _draw_speed(ax, trace.t, trace.speed_command[:, j], bounds, trace.machine.Ke[j])
        _mark_end(ax, t_end)
        ax.set_ylabel(f"{names[j]}: speed [pulse/ms]")
        ax.legend(fontsize="small", loc="upper right")
    written.append(_save(fig, out / f"{prefix}speed.png"))
    return written


def plot_setpoints(series, out_dir, axis_names=None, *, units: str | None = None,
                   prefix: str = "") -> list[Path]:
    """Write ``setpoints.png`` of an open-loop interpolation.

    Left: the path of the setpoints (first two axes; position against time for a single
    axis). Right: the commanded feed and the chord speed ``|thd[k] - thd[k-1]| / Ts`` the
    setpoints actually move at (the last, shortened step reaches the end exactly).

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

    Returns
    -------
    list of Path
        ``[out_dir / (prefix + "setpoints.png")]``.
    """
    out = _output_dir(out_dir)
    unit = units or "path unit"
    pos = series.position
    names = _axis_labels(pos.shape[1], axis_names)
    fig = _figure(11.0, 4.6)
    ax_path, ax_feed = fig.subplots(1, 2)
    if pos.shape[1] >= 2:
        few = len(pos) <= 500  # sample dots only where they stay apart
        ax_path.plot(pos[:, 0], pos[:, 1], color="C0", linewidth=1,
                     marker="." if few else None, markersize=3)
        ax_path.plot(*pos[0, :2], "o", color="C2", label="start")
        ax_path.plot(*pos[-1, :2], "s", color="C3", label="end")
        ax_path.set_xlabel(f"{names[0]} [{unit}]")
        ax_path.set_ylabel(f"{names[1]} [{unit}]")
        ax_path.set_aspect("equal", adjustable="datalim")
        ax_path.legend(fontsize="small")
    else:
        ax_path.plot(series.t, pos[:, 0], color="C0")
        ax_path.set_xlabel("time [s]")
        ax_path.set_ylabel(f"{names[0]} [{unit}]")
    ax_path.set_title("setpoints")

    chord = np.linalg.norm(np.diff(pos, axis=0), axis=1) / series.sample_period
    ax_feed.plot(series.t[1:], series.feed[1:], color="k", linewidth=1, label="commanded feed")
    ax_feed.plot(series.t[1:], chord, color="C3", linestyle="--", linewidth=1,
                 label="chord speed |Δθd|/Ts")
    _mark_end(ax_feed, series.cycle_time)
    ax_feed.set_xlabel("time [s]")
    ax_feed.set_ylabel(f"feed [{unit}/s]")
    ax_feed.set_ylim(bottom=0)
    ax_feed.legend(fontsize="small", loc="lower center")
    fl_max, fl_rms = series.feed_fluctuation()
    ax_feed.set_title(f"feed fluctuation max {100 * fl_max:.3g} %, RMS {100 * fl_rms:.3g} %",
                      fontsize="medium")
    fig.suptitle(f"{series.finished_index} steps, cycle time {series.cycle_time:.4g} s")
    return [_save(fig, out / f"{prefix}setpoints.png")]


def plot_comparison(traces: dict, out_dir, name: str, *, feed: float | None = None,
                    axis: int = 0) -> list[Path]:
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
    axis : int
        The axis of the speed and drive figures (X, as in the paper, by default).

    Returns
    -------
    list of Path
        ``{name}_contour.png`` (Fig. 5: desired path and every run's actual contour, with
        corner zooms), ``{name}_speed_{ax}.png`` (Fig. 6: commanded speed of that axis
        inside its eq. 3.6 bounds [pulse/ms], one panel per run that computed bounds, or
        every run's command in one panel if none did) and ``{name}_drive_{ax}.png``
        (Fig. 7: every run's drive on that axis with +-Umax [V]); ``ax`` is the axis's
        name (``x`` on the die-bonder).
    """
    if not traces:
        raise ValueError("plot_comparison needs at least one trace")
    out = _output_dir(out_dir)
    items = list(traces.items())
    first = items[0][1]
    machine = first.machine
    names = machine.axis_names
    if not 0 <= axis < len(names):
        raise ValueError(f"axis {axis} out of range for axes {names}")
    if feed is None:
        feed = max(float(np.max(tr.feed)) for _, tr in items)
    title = f"{name}: {_feed_text(feed, machine.pulse_length_um)}"
    styles = {label: _STYLES[i % len(_STYLES)] for i, (label, _) in enumerate(items)}
    runs = [_run_of(tr, label, styles[label]) for label, tr in items]
    ax_name = names[axis]
    written = [_contour_figure(first.curve, runs, title, out / f"{name}_contour.png", names)]

    bounded = [(label, tr) for label, tr in items if tr.speed_bounds is not None]
    shown = bounded or items
    fig = _figure(8.0, 2.8 * len(shown) + 0.6)
    axes = fig.subplots(len(shown), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (label, tr) in zip(axes, shown):
        bounds = tr.speed_bounds[:, axis, :] if tr.speed_bounds is not None else None
        color, style = styles[label]
        _draw_speed(ax, tr.t, tr.speed_command[:, axis], bounds, machine.Ke[axis],
                    color=color, linestyle=style, label=f"{label}: speed command")
        _mark_end(ax, tr.cycle_time)
        ax.set_ylabel(f"{ax_name} speed [pulse/ms]")
        ax.legend(fontsize="small", loc="upper right")
        if not bounded:
            ax.set_title("no run computed eq. 3.6 bounds", fontsize="medium", loc="left")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"{ax_name} speed command and its bounds (Fig. 6), {title}")
    written.append(_save(fig, out / f"{name}_speed_{ax_name}.png"))

    fig = _figure(8.0, 4.2)
    ax = fig.subplots()
    for label, tr in items:
        color, style = styles[label]
        ratio = np.max(np.abs(tr.drive[:, axis])) / machine.max_drive
        ax.plot(tr.t, tr.drive[:, axis], color=color, linestyle=style,
                label=f"{label} (max {ratio:.3g} Umax)" if math.isfinite(machine.max_drive)
                else label)
    _draw_drive_limits(ax, machine.max_drive)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{ax_name} drive u before clipping [V]")
    ax.legend(fontsize="small", loc="upper right")
    fig.suptitle(f"{ax_name} drive (Fig. 7), {title}")
    written.append(_save(fig, out / f"{name}_drive_{ax_name}.png"))
    return written
