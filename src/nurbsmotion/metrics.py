"""The figures every run reports (SPEC section 9), computed from a trace.

- cycle time: time at which the setpoint first reaches the path's end;
- following error per axis thd[k] - tha[k], max |.| and RMS;
- contour error: distance from tha[k] to the nearest point of the *curve* (not to the
  setpoint), max and RMS, accurate to far better than 0.01 pulse;
- drive use per axis: max |u[k]|/Umax before clipping, and the samples with |u[k]| > Umax
  (by more than :data:`SATURATION_TOLERANCE`, far below one step of a 16-bit DAC, so that
  an interpolator that drives exactly at the limit is not counted for rounding errors);
- feedrate fluctuation ``(|thd[k] - thd[k-1]|/Ts - Vcmd[k]) / Vcmd[k]``, max |.| and RMS;
- SPEC section 10: settle time (the first time after which the actual position stays
  within ``settle_window`` of the end point until the trace ends), and the overshoot of
  the end point and of every sharp corner along the direction of arrival.

All figures are taken over every sample of the trace, the settling tail included.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from .nurbs import NurbsCurve
from .stepping import Status

__all__ = ["Metrics", "trace_metrics", "feed_fluctuation", "contour_error", "nearest_parameter",
           "settle_time", "overshoot", "SATURATION_TOLERANCE", "SETTLE_WINDOW"]

SATURATION_TOLERANCE = 1e-6
"""Relative excess over Umax below which a sample is not counted as saturated."""

SETTLE_WINDOW = 1.0
"""Default distance from the end point within which the motion counts as settled [pulse]."""


@dataclass(frozen=True)
class Metrics:
    """SPEC section 9 figures of one run; per-axis values are dicts keyed by axis name.

    Attributes
    ----------
    cycle_time_s : float
        [s]
    steps : int
        Interpolation steps to reach the end (cycle_time_s / Ts).
    max_following_error, rms_following_error : dict of str to float
        [pulse] per axis.
    max_contour_error, rms_contour_error : float
        [pulse]
    max_drive_ratio : dict of str to float
        max |u|/Umax per axis, before clipping (0 for an unlimited drive).
    saturated_samples : dict of str to int
        Samples with |u| > Umax (1 + SATURATION_TOLERANCE) per axis.
    feed_fluctuation_max, feed_fluctuation_rms : float
        Relative (1 = 100 %).
    settle_time_s : float
        First time after which the actual position stays within ``settle_window`` of the
        end point until the end of the trace [s]; ``inf`` if it never does (then
        ``settled`` is False).
    settled : bool
        Whether the actual position ends the trace within ``settle_window`` of the end.
    settle_window : float
        [pulse]
    end_overshoot : float
        How far the actual position passes the end point along the direction of arrival,
        once the setpoint has arrived [pulse], >= 0.
    corner_overshoot : float
        The same at the sharp corners (where the motion must stop), the largest over the
        corners [pulse], >= 0; 0 for a path without sharp corners.
    limited_samples : int
        Samples whose step the interpolator changed to keep every drive within Umax.
    cornered_samples : dict of str to int
        Samples at which no admissible step existed, counted per axis whose drive then
        exceeded Umax.
    success : bool
        The motion settled at the end with every drive within Umax.
    message : str
        The run's verdict in one line.
    """

    cycle_time_s: float
    steps: int
    max_following_error: dict
    rms_following_error: dict
    max_contour_error: float
    rms_contour_error: float
    max_drive_ratio: dict
    saturated_samples: dict
    feed_fluctuation_max: float
    feed_fluctuation_rms: float
    settle_time_s: float
    settled: bool
    settle_window: float
    end_overshoot: float
    corner_overshoot: float
    limited_samples: int
    cornered_samples: dict
    success: bool
    message: str

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def total_saturated_samples(self) -> int:
        """Saturated samples summed over the axes."""
        return int(sum(self.saturated_samples.values()))


def feed_fluctuation(position: np.ndarray, feed: np.ndarray, sample_period: float,
                     finished_index: int) -> tuple[float, float]:
    """Feedrate fluctuation (max |.|, RMS) of SPEC section 9; see
    :meth:`nurbsmotion.loop.SetpointSeries.feed_fluctuation`."""
    k = np.arange(1, finished_index)
    k = k[feed[k] > 0]  # a step that commands no motion has no fluctuation
    if k.size == 0:
        return 0.0, 0.0
    speed = np.linalg.norm(position[k] - position[k - 1], axis=1) / sample_period
    rel = (speed - feed[k]) / feed[k]
    return float(np.max(np.abs(rel))), float(np.sqrt(np.mean(rel**2)))


_TURN_PER_CELL = 0.1
"""Largest turn of the tangent inside one cell of the search grid [rad]: cells are split
until the curve inside each is nearly straight, so the distance to a point has a single
minimum per cell wherever that minimum can be the nearest point."""

_CHUNK = 4096
"""Points searched at once: the search's memory is the grid plus a fixed multiple of this."""


class _SearchGrid:
    """The grid the nearest-point search starts from, built once per curve.

    ``u`` holds at least ``size`` parameters uniform in arc length, every breakpoint, and
    extra points where the tangent turns fast (tight curls, near-cusps), so that the
    tangent turns by at most :data:`_TURN_PER_CELL` inside any cell; ``half_cell`` is half
    the longest cell's arc length [path units].
    """

    def __init__(self, curve: NurbsCurve, size: int):
        geometry = curve.geometry
        u = np.union1d(geometry.uniform_parameters(size), curve.breakpoints)
        for _ in range(12):
            a, b = u[:-1], u[1:]
            t_a = curve(a, 1)
            t_b = curve(b, 1, "left")
            t_m = curve(0.5 * (a + b), 1)
            turn = np.maximum(_angle(t_a, t_m), _angle(t_m, t_b))
            split = turn > _TURN_PER_CELL
            if not np.any(split):
                break
            fractions = np.arange(1, 8) / 8.0
            extra = (a[split, None] + (b - a)[split, None] * fractions).ravel()
            u = np.union1d(u, extra)
        self.u = u
        self.points = curve(u)
        s = geometry.arc_length(u)
        # Margin for the arc-length table's own tolerance (far below 1e-9 relative).
        self.half_cell = 0.5 * float(np.max(np.diff(s))) * (1 + 1e-6) + 1e-9 * geometry.length
        self.tree = cKDTree(self.points)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between rows of ``a`` and ``b`` [rad] (0 where either is zero)."""
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.sum(a * b, axis=1) / (na * nb)
    return np.arccos(np.clip(np.nan_to_num(c, nan=1.0), -1.0, 1.0))


def _search_grid(curve: NurbsCurve, size: int) -> _SearchGrid:
    """:class:`_SearchGrid` of ``curve``, kept on its (cached) geometry for the next run."""
    cache = curve.geometry.__dict__.setdefault("_nearest_grids", {})
    if size not in cache:
        cache[size] = _SearchGrid(curve, size)
    return cache[size]


def nearest_parameter(curve: NurbsCurve, points: np.ndarray, grid_size: int = 20_000):
    """Parameter of the nearest curve point to each of ``points``, and the distance.

    Exact for any curve — closed, self-intersecting, passing near itself: the search
    grid (:class:`_SearchGrid`) has cells of arc length at most ``2 h``, so the true
    nearest point lies within ``h`` along the curve of a grid point, hence within
    ``d0 + h`` of the point, where ``d0`` is the distance to the nearest grid point.
    Every grid point inside that ball is a candidate, and the minimum in both cells beside
    each candidate is found by safeguarded Newton iterations on ``(C(u) - p) . C'(u) = 0``
    (bisection where Newton leaves the bracket), started from both ends and the middle of
    the cell. The points are searched :data:`_CHUNK` at a time, so memory stays linear in
    the number of points.

    Parameters
    ----------
    curve : NurbsCurve
    points : ndarray, shape (m, n_axes)
        [path units]
    grid_size : int
        Least number of grid points uniform in arc length.

    Returns
    -------
    u : ndarray, shape (m,)
    distance : ndarray, shape (m,)
        [path units]
    """
    pts = np.asarray(points, dtype=float)
    grid = _search_grid(curve, grid_size)
    best_u = np.empty(len(pts))
    best_d = np.empty(len(pts))
    for lo in range(0, len(pts), _CHUNK):
        chunk = slice(lo, lo + _CHUNK)
        best_u[chunk], best_d[chunk] = _nearest_chunk(curve, grid, pts[chunk])
    return best_u, best_d


def _nearest_chunk(curve: NurbsCurve, grid: _SearchGrid, pts: np.ndarray):
    d0, j0 = grid.tree.query(pts)
    best_u, best_d = grid.u[j0].copy(), d0.copy()
    near = grid.tree.query_ball_point(pts, d0 + grid.half_cell)
    counts = np.fromiter((len(c) for c in near), dtype=np.intp, count=len(near))
    owner = np.repeat(np.arange(len(pts)), counts)
    j = np.fromiter((i for c in near for i in c), dtype=np.intp, count=int(counts.sum()))
    # Both cells beside each candidate grid point, once per point.
    last = len(grid.u) - 1
    cell = np.concatenate([np.maximum(j - 1, 0), np.minimum(j, last - 1)])
    pair = np.unique(np.concatenate([owner, owner]) * last + cell)
    owner, cell = pair // last, pair % last
    a, b, p = grid.u[cell], grid.u[cell + 1], pts[owner]
    for start in (a, 0.5 * (a + b), b):
        u = _newton_in_cell(curve, p, a, b, start.copy())
        dist = np.linalg.norm(curve(u) - p, axis=1)
        order = np.lexsort((dist, owner))  # per point, its best candidate first
        first = np.ones(len(order), dtype=bool)
        first[1:] = owner[order][1:] != owner[order][:-1]
        k, o = order[first], owner[order[first]]
        better = dist[k] < best_d[o]
        best_d[o[better]] = dist[k][better]
        best_u[o[better]] = u[k][better]
    return best_u, best_d


def _newton_in_cell(curve, p, a, b, u, iterations: int = 40):
    """Minimise |C(u) - p| over [a, b] per row: Newton on g = (C - p) . C' with a bracket
    kept from the sign of g, bisection when a step leaves it. Each row stops on its own,
    so a row's result does not depend on the others (nor on how points are chunked)."""
    lo, hi = a.copy(), b.copy()
    active = np.arange(len(u))
    for _ in range(iterations):
        ua, la, ha, pa = u[active], lo[active], hi[active], p[active]
        d = curve.derivatives(ua, 2)
        r = d[0] - pa
        g = np.sum(r * d[1], axis=1)
        dg = np.sum(d[1] * d[1], axis=1) + np.sum(r * d[2], axis=1)
        la = np.where(g < 0, ua, la)
        ha = np.where(g > 0, ua, ha)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = ua - g / dg
        bad = ~((dg > 0) & (step > la) & (step < ha))
        u_new = np.where(g == 0, ua, np.where(bad, 0.5 * (la + ha), step))
        u[active], lo[active], hi[active] = u_new, la, ha
        active = active[np.abs(u_new - ua) > 4e-16 * np.maximum(1.0, np.abs(ua))]
        if active.size == 0:
            break
    return u


def contour_error(curve: NurbsCurve, points: np.ndarray) -> np.ndarray:
    """Distance from each point to the curve, shape (m,) [path units]."""
    return nearest_parameter(curve, points)[1]


def settle_time(t: np.ndarray, position: np.ndarray, end: np.ndarray,
                window: float = SETTLE_WINDOW) -> float:
    """First time after which ``position`` stays within ``window`` of ``end`` [s].

    Parameters
    ----------
    t : ndarray, shape (n_samples,)
        [s]
    position : ndarray, shape (n_samples, n_axes)
        Actual positions [pulse].
    end : ndarray, shape (n_axes,)
        [pulse]
    window : float
        Radius of the settling window [pulse], > 0.

    Returns
    -------
    float
        ``inf`` if the last sample is outside the window (not settled within the trace).
    """
    if not (math.isfinite(window) and window > 0):
        raise ValueError(f"settle window must be finite and > 0 pulse, got {window!r}")
    outside = np.flatnonzero(np.linalg.norm(position - end, axis=1) > window)
    if outside.size == 0:
        return float(t[0])
    if outside[-1] == len(t) - 1:
        return math.inf
    return float(t[outside[-1] + 1])


def overshoot(position: np.ndarray, point: np.ndarray, direction: np.ndarray) -> float:
    """How far ``position`` passes ``point`` along ``direction``, >= 0 [pulse].

    Parameters
    ----------
    position : ndarray, shape (n_samples, n_axes)
        The samples to consider [pulse].
    point : ndarray, shape (n_axes,)
        [pulse]
    direction : ndarray, shape (n_axes,)
        Any non-zero length; only its direction counts.
    """
    if len(position) == 0:
        return 0.0
    n = direction / np.linalg.norm(direction)
    return max(0.0, float(np.max((position - point) @ n)))


def _corner_overshoot(trace) -> float:
    """Largest :func:`overshoot` of the actual position at the path's sharp corners.

    At a corner at ``u_c`` the direction measured is the incoming tangent's part normal
    to the outgoing tangent (the incoming tangent itself at a reversal): along it the path
    does not advance after the corner, so any positive excursion passes the corner. The
    samples counted run from the first whose setpoint is at or past the corner until the
    setpoint passes half way to the next corner (or the end)."""
    curve = trace.curve
    corners = curve.sharp_corners()
    if corners.size == 0:
        return 0.0
    t_in = curve(corners, 1, "left")
    t_out = curve(corners, 1)
    nexts = np.append(corners[1:], 1.0)
    worst = 0.0
    for u_c, u_next, a, b, point in zip(corners, nexts, t_in, t_out, curve(corners)):
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        normal = a - (a @ b) * b
        if np.linalg.norm(normal) < 1e-9:  # a reversal: back along the incoming line
            normal = a
        reached = np.flatnonzero(trace.u >= u_c)
        left = np.flatnonzero(trace.u >= 0.5 * (u_c + u_next))
        if reached.size == 0:
            continue
        stop = left[0] if left.size else len(trace.u)
        worst = max(worst, overshoot(trace.position[reached[0]:stop], point, normal))
    return worst


def trace_metrics(trace, settle_window: float | None = None) -> Metrics:
    """All SPEC section 9 and 10 figures of a :class:`~nurbsmotion.loop.Trace` but the
    time-optimal bound.

    Parameters
    ----------
    trace : Trace
    settle_window : float, optional
        Radius of the settling window around the end point [pulse]; by default the one
        the run settled to (``trace.settle_window``).
    """
    if settle_window is None:
        settle_window = trace.settle_window
    names = trace.machine.axis_names
    follow = trace.position_command - trace.position
    contour = contour_error(trace.curve, trace.position)
    umax = trace.machine.max_drive
    ratio = np.max(np.abs(trace.drive), axis=0) / umax
    saturated = np.count_nonzero(np.abs(trace.drive) > umax * (1 + SATURATION_TOLERANCE),
                                 axis=0)
    fl_max, fl_rms = feed_fluctuation(trace.position_command, trace.feed,
                                      trace.machine.sample_period, trace.finished_index)
    cornered = trace.status == Status.CORNERED
    cornered_axes = np.count_nonzero(cornered[:, None] & (np.abs(trace.drive) > umax), axis=0)
    end = trace.curve(1.0)
    settle = settle_time(trace.t, trace.position, end, settle_window)

    def per_axis(values):
        return {n: float(v) for n, v in zip(names, values)}

    return Metrics(
        cycle_time_s=trace.cycle_time,
        steps=int(trace.finished_index),
        max_following_error=per_axis(np.max(np.abs(follow), axis=0)),
        rms_following_error=per_axis(np.sqrt(np.mean(follow**2, axis=0))),
        max_contour_error=float(np.max(contour)),
        rms_contour_error=float(np.sqrt(np.mean(contour**2))),
        max_drive_ratio=per_axis(ratio),
        saturated_samples={n: int(v) for n, v in zip(names, saturated)},
        feed_fluctuation_max=fl_max,
        feed_fluctuation_rms=fl_rms,
        settle_time_s=settle,
        settled=math.isfinite(settle),
        settle_window=float(settle_window),
        end_overshoot=overshoot(trace.position[trace.finished_index:], end,
                                trace.curve(1.0, 1, "left")),
        corner_overshoot=_corner_overshoot(trace),
        limited_samples=int(np.count_nonzero(trace.status == Status.LIMITED)),
        cornered_samples={n: int(v) for n, v in zip(names, cornered_axes)},
        success=bool(trace.success),
        message=trace.message,
    )
