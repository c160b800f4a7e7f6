"""The figures every run reports (docs/model.md#run-figures), computed from a trace.

- cycle time: time at which the setpoint first reaches the path's end;
- following error per axis thd[k] - tha[k], max |.| and RMS;
- contour error: distance from tha[k] to the nearest point of the *curve* (not to the
  setpoint), max and RMS, accurate to far better than 0.01 pulse;
- drive use per axis: max |u[k]|/Umax before clipping, and the samples with |u[k]| > Umax
  (by more than :data:`SATURATION_TOLERANCE`, far below one step of a 16-bit DAC, so that
  an interpolator that drives exactly at the limit is not counted for rounding errors);
- feedrate fluctuation ``(|thd[k] - thd[k-1]|/Ts - Vcmd[k]) / Vcmd[k]``, max |.| and RMS;
- docs/model.md#beyond-the-paper: settle time (the first time after which the actual position stays
  within ``settle_window`` of the end point until the trace ends), and the overshoot of
  the end point and of every sharp corner along the direction of arrival.

All figures are taken over every sample of the trace, the settling tail included.

Why one module of about 900 lines: every figure is computed twice over, on a whole trace
(:func:`trace_metrics`, :func:`trace_at_rest`) and block by block as the rows stream
(:class:`RunningMetrics`, :class:`RunningAtRest`), by the same compiled kernels (the
nearest-point search, the settle and overshoot rules); kept together so that the two
ways cannot drift apart (the tests compare them figure by figure).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from ._kernels import horner, power_basis, rational_horner
from .errors import InvalidArgumentError
from .geometry import distances_to
from .nurbs import NurbsCurve
from .loop.closed_loop import SETTLE_WINDOW
from .stepping import Status
from .units import in_pulses

__all__ = ["check_settle_window", "Metrics", "RunningMetrics", "trace_metrics", "AtRest", "RunningAtRest",
           "trace_at_rest", "feed_fluctuation", "contour_error",
           "nearest_parameter", "settle_time", "overshoot", "SATURATION_TOLERANCE", "SETTLE_WINDOW"]

SATURATION_TOLERANCE = 1e-6
"""Relative excess over Umax below which a sample is not counted as saturated."""



@dataclass(frozen=True)
class Metrics:
    """docs/model.md#run-figures figures of one run; per-axis values are dicts keyed by axis name.

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
        How far the actual position passes the end point along the direction of arrival
        [pulse], >= 0, from the sample whose setpoint is half way along the last
        corner-free piece (or has arrived, if sooner) on: a machine running ahead of its
        setpoint (``planned`` on a plant unlike the model) is counted too. Only samples
        whose nearest path point is the end (or, on a closed path, lies on the first half
        piece, which continues it) have passed it: one nearer an earlier point of a path
        that bends back past the end's plane is still on its way.
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
    """Feedrate fluctuation (max |.|, RMS) of docs/model.md#run-figures; see
    :meth:`nurbsmotion.loop.SetpointSeries.feed_fluctuation`."""
    if finished_index < 2:
        return 0.0, 0.0
    rel = _fluctuation(position[1:finished_index], position[0], feed[1:finished_index],
                       sample_period)
    if rel.size == 0:
        return 0.0, 0.0
    return float(np.max(np.abs(rel))), float(np.sqrt(np.mean(rel**2)))


def _fluctuation(position: np.ndarray, previous: np.ndarray, feed: np.ndarray,
                 sample_period: float) -> np.ndarray:
    """``(|thd[k] - thd[k-1]|/Ts - Vcmd[k]) / Vcmd[k]`` of the steps into the rows of
    ``position`` (the row before the first is ``previous``), for the steps that command
    motion (``feed > 0``), shape (m',)."""
    speed = np.zeros(len(position))
    for j in range(position.shape[1]):  # axis by axis: no temporary of the full rows
        step = np.diff(position[:, j], prepend=previous[j])
        speed += step * step
    speed = np.sqrt(speed, out=speed) / sample_period
    moving = feed > 0  # a step that commands no motion has no fluctuation
    return (speed[moving] - feed[moving]) / feed[moving]


_TURN_PER_CELL = 0.1
"""Largest turn of the tangent inside one cell of the search grid [rad]: cells are split
until the curve inside each is nearly straight, so the distance to a point has at most
one interior minimum in each half of a cell wherever that minimum can be the nearest
point."""

_CHUNK = 65_536
"""Points searched per call of the compiled search: between calls Python runs (a Ctrl-C
is seen within a fraction of a second); the search itself needs no memory per point."""


class _GridArrays(NamedTuple):
    """The arrays and numbers of a :class:`_SearchGrid`, as the compiled search takes
    them (:func:`_nearest_points`)."""

    u: np.ndarray              # (n_cells + 1,)
    points: np.ndarray         # (n_cells + 1, n_axes) [path units]
    tangent_right: np.ndarray  # (n_cells + 1, n_axes)
    tangent_left: np.ndarray   # (n_cells + 1, n_axes)
    coef: np.ndarray           # (n_cells, p + 1, n_axes + 1): each cell's power form
    cell_length: np.ndarray    # (n_cells,) [path units], upper bounds
    box_lo: np.ndarray         # (2 * leaves, n_axes) [path units]
    box_hi: np.ndarray         # (2 * leaves, n_axes) [path units]
    leaves: int
    half_cell: float           # [path units]


class _SearchGrid:
    """The grid the nearest-point search runs on, built once per curve.

    ``u`` holds at least ``size`` parameters uniform in arc length, every breakpoint, and
    extra points where the tangent turns fast (tight curls, near-cusps), so that the
    tangent turns by at most :data:`_TURN_PER_CELL` inside any cell. Per grid point: the
    point, and the tangent of the cell that starts there and of the cell that ends there
    (they differ at a sharp corner). Per cell: an upper bound of its arc length. And a
    binary tree over the cells whose nodes hold the bounding box of their grid points
    (node 1 is the root, node k has children 2k and 2k+1, cell i is leaf ``leaves + i``).
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
        self.tangent_right = curve(u, 1)
        self.tangent_left = curve(u, 1, "left")
        s = geometry.arc_length(u)
        n_cells = len(u) - 1
        # Each cell lies in one knot span (the breakpoints are in u): the curve's power
        # form about the cell's start is exact on it.
        self.coef = power_basis(curve.knots, curve.homogeneous, curve.degree, u[:-1])
        # Margin for the arc-length table's own tolerance (far below 1e-9 relative).
        self.cell_length = np.diff(s) * (1 + 1e-6) + 2e-9 * geometry.length
        self.half_cell = 0.5 * float(np.max(self.cell_length))
        leaves = 1 << max(0, (n_cells - 1).bit_length())
        lo = np.full((2 * leaves, curve.n_axes), np.inf)
        hi = np.full((2 * leaves, curve.n_axes), -np.inf)
        lo[leaves:leaves + n_cells] = np.minimum(self.points[:-1], self.points[1:])
        hi[leaves:leaves + n_cells] = np.maximum(self.points[:-1], self.points[1:])
        level = leaves
        while level > 1:
            half = level // 2
            lo[half:level] = np.minimum(lo[level:2 * level:2], lo[level + 1:2 * level:2])
            hi[half:level] = np.maximum(hi[level:2 * level:2], hi[level + 1:2 * level:2])
            level = half
        self.box_lo, self.box_hi, self.leaves = lo, hi, leaves

    def arrays(self) -> _GridArrays:
        """The grid as :func:`_nearest_points` takes it."""
        return _GridArrays(self.u, self.points, self.tangent_right, self.tangent_left,
                           self.coef, self.cell_length, self.box_lo, self.box_hi,
                           self.leaves, self.half_cell)


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

    Exact for any curve — closed, self-intersecting, passing near itself. The search grid
    (:class:`_SearchGrid`) splits the curve into cells whose arc length ``L`` is known;
    every point of a cell lies within ``L/2`` along the curve of one of its two ends, so a
    point ``p`` is at least ``(|p - C(a)| + |p - C(b)| - L) / 2`` from cell ``[a, b]``, and
    at least ``dist(p, box) - max L/2`` from any cell of a tree node whose grid points lie
    in ``box``. A branch-and-bound walk of the tree visits only the cells that can hold a
    point nearer than the best found so far (the previous point's cell is tried first, so
    for a trace that is one or two cells). In a cell the distance is minimised exactly:
    its two ends, its middle, and, in each half where ``g = (C(u) - p) . C'(u)`` changes
    from negative to positive, the root of ``g`` by safeguarded Newton iterations
    (bisection where a step leaves the bracket) to a few ulp. Compiled; the points are
    searched :data:`_CHUNK` at a time, with no memory per point beyond the results.

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
    pts = np.ascontiguousarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != curve.n_axes:
        raise InvalidArgumentError(f"points must have shape (m, {curve.n_axes}), got {pts.shape}")
    grid = _search_grid(curve, grid_size).arrays()
    best_u = np.empty(len(pts))
    best_d = np.empty(len(pts))
    hint = np.full(1, -1, dtype=np.int64)
    for lo in range(0, len(pts), _CHUNK):
        chunk = slice(lo, lo + _CHUNK)
        _nearest_points(grid, pts[chunk], best_u[chunk], best_d[chunk], hint)
    return best_u, best_d


@njit(cache=True, nogil=True)  # a streamed run searches beside its loop
def _nearest_points(grid, pts, out_u, out_d, hint):
    """:func:`nearest_parameter` for the rows of ``pts`` into ``out_u``, ``out_d`` on
    ``grid`` (:class:`_GridArrays`); ``hint[0]`` is the cell to try first (-1: none) and
    is left at the last point's."""
    gu, gp, tr, tl, coef = grid.u, grid.points, grid.tangent_right, grid.tangent_left, grid.coef
    cell_length, box_lo, box_hi = grid.cell_length, grid.box_lo, grid.box_hi
    leaves, h = grid.leaves, grid.half_cell
    n_cells = gu.shape[0] - 1
    stack = np.empty(128, dtype=np.int64)
    for i in range(pts.shape[0]):
        q = pts[i]
        best_d = math.inf
        best_u = 0.0
        best_cell = -1
        first = hint[0]
        if first >= 0:
            best_d, best_u = _cell_minimum(gu, gp, tr, tl, coef[first], first, q)
            best_cell = first
        stack[0] = 1
        top = 1
        while top > 0:
            top -= 1
            node = stack[top]
            if node >= leaves:
                c = node - leaves
                if c >= n_cells or c == first:
                    continue
                if 0.5 * (_distance(gp[c], q) + _distance(gp[c + 1], q)
                          - cell_length[c]) > best_d:
                    continue
                d, u = _cell_minimum(gu, gp, tr, tl, coef[c], c, q)
                if d < best_d or (d == best_d and u < best_u):
                    best_d, best_u, best_cell = d, u, c
                continue
            child = 2 * node
            bl = _box_distance(box_lo[child], box_hi[child], q) - h
            br = _box_distance(box_lo[child + 1], box_hi[child + 1], q) - h
            # Push the farther child first, so that the nearer one is walked first.
            if bl > br:
                bl, br = br, bl
                near, far = child + 1, child
            else:
                near, far = child, child + 1
            if br <= best_d:
                stack[top] = far
                top += 1
            if bl <= best_d:
                stack[top] = near
                top += 1
        out_u[i] = best_u
        out_d[i] = best_d
        hint[0] = best_cell


@njit(cache=True)
def _distance(a, b):
    s = 0.0
    for j in range(a.shape[0]):
        s += (a[j] - b[j]) ** 2
    return math.sqrt(s)


@njit(cache=True)
def _box_distance(lo, hi, q):
    s = 0.0
    for j in range(q.shape[0]):
        e = max(lo[j] - q[j], q[j] - hi[j], 0.0)
        s += e * e
    return math.sqrt(s)


@njit(cache=True)
def _g_at(coef, t, q):
    """``(g, g', |C - q|)`` at ``u = gu[c] + t`` of the cell whose Taylor coefficients
    are ``coef`` (p + 1, n_axes + 1): g = (C - q) . C' (Horner, then the quotient rule)."""
    dim = q.shape[0]
    w0, w1, w2 = horner(coef, dim, t)
    g = 0.0
    dg = 0.0
    r2 = 0.0
    for j in range(dim):
        c0, c1, c2 = rational_horner(coef, j, t, w0, w1, w2)
        r = c0 - q[j]
        g += r * c1
        dg += c1 * c1 + r * c2
        r2 += r * r
    return g, dg, math.sqrt(r2)


@njit(cache=True)
def _cell_minimum(gu, gp, tr, tl, coef, c, q):
    """``(distance, u)`` of the point of cell ``c`` nearest to ``q`` (``coef``: the cell's
    Taylor coefficients, :func:`nurbsmotion._kernels.power_basis`)."""
    a = gu[c]
    b = gu[c + 1]
    ga = 0.0
    gb = 0.0
    for j in range(q.shape[0]):
        ga += (gp[c, j] - q[j]) * tr[c, j]
        gb += (gp[c + 1, j] - q[j]) * tl[c + 1, j]
    best_d = _distance(gp[c], q)
    best_u = a
    d = _distance(gp[c + 1], q)
    if d < best_d:
        best_d, best_u = d, b
    m = 0.5 * (a + b)
    gm, _, d = _g_at(coef, m - a, q)
    if d < best_d:
        best_d, best_u = d, m
    if ga < 0.0 and gm > 0.0:
        d, u = _root(coef, a, a, m, ga, gm, q)
        if d < best_d:
            best_d, best_u = d, u
    if gm < 0.0 and gb > 0.0:
        d, u = _root(coef, a, m, b, gm, gb, q)
        if d < best_d:
            best_d, best_u = d, u
    return best_d, best_u


@njit(cache=True)
def _root(coef, a, lo, hi, glo, ghi, q):
    """``(distance, u)`` at the root of g in ``(lo, hi)`` where g(lo) < 0 < g(hi): Newton
    from the secant's point, bisection when a step leaves the bracket, until the step is
    a few ulp; the nearest point evaluated on the way."""
    u = lo - glo * (hi - lo) / (ghi - glo)
    if not (lo < u < hi):
        u = 0.5 * (lo + hi)
    best_d = math.inf
    best_u = u
    for _ in range(200):
        g, dg, d = _g_at(coef, u - a, q)
        if d < best_d:
            best_d, best_u = d, u
        if g == 0.0:
            break
        if g < 0.0:
            lo = u
        else:
            hi = u
        nxt = u - g / dg if dg > 0.0 else 0.5 * (lo + hi)
        if not (lo < nxt < hi):
            nxt = 0.5 * (lo + hi)
        if abs(nxt - u) <= 4e-16 * max(1.0, abs(u)) or not (lo < nxt < hi):
            break
        u = nxt
    return best_d, best_u


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
    _check_window(window)
    first = _settled_from(_last_outside(position, end, window), len(t))
    return math.inf if first is None else float(t[first])


def check_settle_window(window: float, curve: NurbsCurve, name: str = "settle window") -> None:
    """Refuse a settle window [pulse] that is not below the farthest distance of ``curve``
    [pulse] from its end point: a motion on the path would be within it from the start,
    "settled" at 0 s whatever it did (``--settle-window 1e300``, issue 37).

    Raises
    ------
    InvalidArgumentError
        Naming ``name``, the window and that distance.
    """
    _check_window(window)
    u = np.union1d(np.linspace(0.0, 1.0, 4097), curve.breakpoints)
    farthest = float(np.max(distances_to(curve(u), curve(1.0))))
    if window >= farthest:
        raise InvalidArgumentError(
            f"{name} {window:g} pulse is not below the path's farthest distance from its end "
            f"point ({farthest:.6g} pulse): the motion would be settled from the start; give a "
            "window below that distance, or read the path on a machine with a finer pulse")


def _check_window(window: float) -> None:
    """A settle window [pulse] must be finite and > 0."""
    if not (math.isfinite(window) and window > 0):
        raise InvalidArgumentError(f"settle window must be finite and > 0 pulse, got {window!r}")


def _last_outside(position: np.ndarray, end: np.ndarray, window: float) -> int:
    """Index of the last row of ``position`` farther than ``window`` from ``end``, -1 if
    none."""
    outside = np.flatnonzero(distances_to(position, end) > window)
    return int(outside[-1]) if outside.size else -1


def _settled_from(last_outside: int, n: int) -> int | None:
    """First sample after which all of ``n`` stay inside the window, ``None`` if the
    last is outside (not settled)."""
    return None if last_outside == n - 1 else last_outside + 1


def overshoot(position: np.ndarray, point: np.ndarray, direction: np.ndarray,
              off_path: np.ndarray | None = None) -> float:
    """How far ``position`` passes ``point`` along ``direction``, >= 0 [pulse].

    Parameters
    ----------
    position : ndarray, shape (n_samples, n_axes)
        The samples to consider [pulse].
    point : ndarray, shape (n_axes,)
        [pulse]
    direction : ndarray, shape (n_axes,)
        Any non-zero length; only its direction counts.
    off_path : ndarray, shape (n_samples,), optional
        A bound per sample on how far it passes ``point`` [pulse]: 0 for a sample that
        has not passed it whatever its side of ``point``'s plane (its nearest path point
        lies before ``point``, on a path that bends back past that plane), inf for no
        bound (:func:`_past`).
    """
    if len(position) == 0:
        return 0.0
    n = direction / np.linalg.norm(direction)
    along = np.zeros(len(position))
    for j in range(position.shape[1]):  # not BLAS: see RunningMetrics.add
        along += (position[:, j] - point[j]) * n[j]
    if off_path is not None:
        along = np.minimum(along, off_path)
    return max(0.0, float(np.max(along)))


PARAMETER_TOLERANCE = 1e-9
"""A sample whose nearest path parameter lies within this of a corner's (or the end's)
has that point as its nearest path point."""


def _past(nearest: np.ndarray, *spans) -> np.ndarray:
    """:func:`overshoot`'s ``off_path`` for the samples that can have passed a point:
    inf for a sample whose nearest path parameter lies in one of the closed ``spans``
    ``(lo, hi)`` (the point itself and the path after it), 0 for the others (their
    nearest path point lies before it: they are still on the way)."""
    counted = np.zeros(len(nearest), dtype=bool)
    for lo, hi in spans:
        counted |= (nearest >= lo - PARAMETER_TOLERANCE) & (nearest <= hi)
    return np.where(counted, np.inf, 0.0)


class RunningMetrics:
    """The figures of :func:`trace_metrics`, gathered block by block as a run streams
    (:func:`nurbsmotion.loop.simulate_streamed`): memory independent of the run's length.

    Parameters
    ----------
    curve : NurbsCurve
        The path, in any unit the machine knows (converted to pulses by
        :class:`nurbsmotion.units.Scale`; the rows and the figures are in pulses).
    machine : Machine
    settle_window : float
        Radius of the settling window around the end point [pulse], > 0.

    Give it the rows in order (:meth:`add`, a sink of
    :func:`nurbsmotion.loop.simulate_streamed`), then take :meth:`result`.
    """

    def __init__(self, curve: NurbsCurve, machine, settle_window: float):
        _check_window(settle_window)
        curve, _ = in_pulses(curve, machine)
        self.curve, self.machine, self.window = curve, machine, float(settle_window)
        n_axes = curve.n_axes
        self.n = 0
        self.follow_max = np.zeros(n_axes)
        self.follow_sq = np.zeros(n_axes)
        self.drive_max = np.zeros(n_axes)
        self.saturated = np.zeros(n_axes, dtype=np.int64)
        self.cornered = np.zeros(n_axes, dtype=np.int64)
        self.limited = 0
        self.contour_max = 0.0
        self.contour_sq = 0.0
        self.fluct_max = 0.0
        self.fluct_sq = 0.0
        self.fluct_n = 0
        self.previous_command = None  # the last row's setpoint, for the next block's step
        self.last_outside = -1  # last sample outside the settle window
        self.end = curve(1.0)
        self.end_direction = curve(1.0, 1, "left")
        self.end_overshoot = 0.0
        corners = curve.sharp_corners()
        self.corner_u = corners
        self.corner_mid = 0.5 * (corners + np.append(corners[1:], 1.0))
        # each corner's (and the end's) overshoot counts from half way along the piece
        # before it
        self.corner_from = 0.5 * (corners + np.append(0.0, corners[:-1]))
        self.end_from = 0.5 * (1.0 + (corners[-1] if corners.size else 0.0))
        # past the end: the end itself, and on a closed path the first half piece too
        self.past_end = [(1.0, 1.0)]
        if np.linalg.norm(self.end - curve(0.0)) <= self.window:
            self.past_end.append((0.0, 0.5 * (corners[0] if corners.size else 1.0)))
        if corners.size:
            t_in = curve.limit_tangent(corners, "left")  # unit, also where C' = 0 (a cusp)
            t_out = curve.limit_tangent(corners, "right")
            normal = t_in - np.sum(t_in * t_out, axis=1)[:, None] * t_out
            reversal = np.linalg.norm(normal, axis=1) < 1e-9  # back along the incoming line
            normal[reversal] = t_in[reversal]
            self.corner_points, self.corner_normals = curve(corners), normal
        self.corner_overshoot = 0.0
        self.u_max = -math.inf  # the setpoint's parameter so far, its running maximum

    def add(self, first: int, rows, finished: int, last: bool) -> None:
        """Take a block of samples ``first ..`` (``rows``: a
        :class:`nurbsmotion.loop.closed_loop.Rows`); ``finished`` is the first sample at the
        path's end (-1: none yet), ``last`` whether no rows follow (unused: the figures
        are complete after every block)."""
        if first != self.n:
            raise InvalidArgumentError(f"rows from sample {first} after {self.n} samples: blocks "
                             "must come in order")
        self._add(rows.u, rows.feed, rows.status, rows.command, rows.position, rows.drive,
                  finished)

    def _add(self, u, feed, status, command, position, drive, finished: int) -> None:
        """Take the next rows.

        Parameters
        ----------
        u, feed, status : ndarray, shape (m,)
            The rows' curve parameter, commanded feed [pulse/s] and status.
        command, position, drive : ndarray, shape (m, n_axes)
            thd [pulse], tha [pulse], u before clipping [V].
        finished : int
            First sample of the run whose setpoint is the path's end, -1 if none so far.
        """
        first, m = self.n, len(u)
        if m == 0:
            return
        # Sums of squares by np.sum, not np.dot: a BLAS call wakes OpenBLAS's threads,
        # which then spin beside the compiled loop of the next block (on two busy cores
        # a streamed run took 3x as long).
        umax = self.machine.max_drive
        corner_rows = status == Status.CORNERED
        for j in range(command.shape[1]):  # axis by axis: no temporary of the full rows
            follow = command[:, j] - position[:, j]
            self.follow_max[j] = max(self.follow_max[j], np.max(np.abs(follow)))
            self.follow_sq[j] += np.sum(follow * follow)
            a = np.abs(drive[:, j])
            self.drive_max[j] = max(self.drive_max[j], np.max(a))
            self.saturated[j] += np.count_nonzero(a > umax * (1 + SATURATION_TOLERANCE))
            self.cornered[j] += np.count_nonzero(corner_rows & (a > umax))
        del follow, a
        self.limited += int(np.count_nonzero(status == Status.LIMITED))
        nearest, contour = nearest_parameter(self.curve, position)
        self.contour_max = max(self.contour_max, float(np.max(contour)))
        self.contour_sq += float(np.sum(contour * contour))
        self._add_fluctuation(first, feed, command, finished)
        last = _last_outside(position, self.end, self.window)
        if last >= 0:
            self.last_outside = first + last
        # the setpoint's parameter so far (its running maximum) places the samples on the
        # path's pieces, whatever the actual position does
        reached = np.maximum.accumulate(np.maximum(u, self.u_max))
        self.u_max = float(reached[-1])
        start = int(np.searchsorted(reached, self.end_from, "left"))
        if 0 <= finished < first + m:
            start = min(start, max(0, finished - first))
        self.end_overshoot = max(self.end_overshoot, overshoot(
            position[start:], self.end, self.end_direction,
            _past(nearest[start:], *self.past_end)))
        self._add_corners(reached, position, nearest)
        self.n = first + m

    def _add_fluctuation(self, first, feed, command, finished) -> None:
        """Steps k - 1 -> k for k = 1 .. finished - 1 (see :func:`feed_fluctuation`)."""
        stop = len(feed) if finished < 0 else min(len(feed), finished - first)
        skip = 1 if first == 0 else 0  # row 0 is the start: no step into it
        previous = command[0] if first == 0 else self.previous_command
        self.previous_command = command[-1].copy()
        if stop <= skip:
            return
        rel = _fluctuation(command[skip:stop], previous, feed[skip:stop],
                           self.machine.sample_period)
        if rel.size:
            self.fluct_max = max(self.fluct_max, float(np.max(np.abs(rel))))
            self.fluct_sq += float(np.sum(rel * rel))
            self.fluct_n += int(rel.size)

    def _add_corners(self, reached, position, nearest) -> None:
        """How far the samples pass each sharp corner at ``u_c``: along the incoming
        tangent's part normal to the outgoing tangent (the incoming tangent itself at a
        reversal), beyond where the path itself goes there. Right after the corner the
        path does not advance along that direction, so any positive excursion passes the
        corner; a sample whose nearest path point (``nearest``,
        :func:`nearest_parameter`) lies further on is counted by how far it goes beyond
        that point's own excursion (the outgoing piece may curve back along it), and one
        whose nearest point lies before the corner not at all (it is still on the way,
        :func:`_past`). The samples counted run from the first whose setpoint
        (``reached``: the running maximum of its parameter) is half way along the piece
        before the corner until it passes half way to the next corner (or the end): an
        actual position that runs ahead of its setpoint passes the corner before the
        setpoint gets there."""
        if self.corner_u.size == 0:
            return
        start = np.searchsorted(reached, self.corner_from, "left")
        stop = np.searchsorted(reached, self.corner_mid, "left")
        for c in np.flatnonzero(start < stop):
            window = slice(start[c], stop[c])
            counted = _past(nearest[window], (self.corner_u[c], self.corner_mid[c])) > 0
            if not counted.any():
                continue
            point, normal = self.corner_points[c], self.corner_normals[c]
            n = normal / np.linalg.norm(normal)
            # elementwise, not BLAS (see add)
            path_along = np.sum((self.curve(nearest[window][counted]) - point) * n, axis=1)
            along = np.sum((position[window][counted] - point) * n, axis=1)
            self.corner_overshoot = max(self.corner_overshoot,
                                        float(np.max(along - np.maximum(path_along, 0.0))))

    def result(self, finished_index: int, success: bool, message: str) -> Metrics:
        """The figures of the rows taken, for a run that reached the end at sample
        ``finished_index`` with the verdict ``(success, message)``."""
        names = self.machine.axis_names
        n = max(self.n, 1)
        Ts = self.machine.sample_period
        settled = _settled_from(self.last_outside, self.n)
        settle = math.inf if settled is None else settled * Ts

        def per_axis(values):
            return {a: float(v) for a, v in zip(names, values)}

        fluct_rms = math.sqrt(self.fluct_sq / self.fluct_n) if self.fluct_n else 0.0
        return Metrics(
            cycle_time_s=finished_index * Ts,
            steps=int(finished_index),
            max_following_error=per_axis(self.follow_max),
            rms_following_error=per_axis(np.sqrt(self.follow_sq / n)),
            max_contour_error=self.contour_max,
            rms_contour_error=math.sqrt(self.contour_sq / n),
            max_drive_ratio=per_axis(self.drive_max / self.machine.max_drive),
            saturated_samples={a: int(v) for a, v in zip(names, self.saturated)},
            feed_fluctuation_max=self.fluct_max,
            feed_fluctuation_rms=fluct_rms,
            settle_time_s=settle,
            settled=math.isfinite(settle),
            settle_window=self.window,
            end_overshoot=self.end_overshoot,
            corner_overshoot=self.corner_overshoot,
            limited_samples=self.limited,
            cornered_samples={a: int(v) for a, v in zip(names, self.cornered)},
            success=bool(success),
            message=message,
        )


def trace_metrics(trace, settle_window: float | None = None) -> Metrics:
    """All docs/model.md#run-figures and #beyond-the-paper figures of a :class:`~nurbsmotion.loop.Trace` but the
    time-optimal bound (:class:`RunningMetrics` over the whole trace).

    Parameters
    ----------
    trace : Trace
    settle_window : float, optional
        Radius of the settling window around the end point [pulse]; by default the one
        the run settled to (``trace.settle_window``).
    """
    if settle_window is None:
        settle_window = trace.settle_window
    running = RunningMetrics(trace.curve, trace.machine, settle_window)
    running._add(trace.u, trace.feed, trace.status, trace.position_command, trace.position,
                 trace.drive, trace.finished_index)
    return running.result(trace.finished_index, trace.success, trace.message)


LIMIT_CYCLE_DRIVE = 0.1
"""A drive still swinging both ways beyond this share of Umax over the last hold window
is a limit cycle (:class:`AtRest`)."""


@dataclass(frozen=True)
class AtRest:
    """What the machine did, measured on the tool's true position (issue 32): per axis,
    dicts keyed by axis name.

    Attributes
    ----------
    window_s : float
        The last window of the run the first three figures are taken over [s]: the run's
        hold (:data:`nurbsmotion.loop.HOLD_TIME`), or on a run without one the samples
        its settling took (:func:`nurbsmotion.loop.settle_hold_samples`).
    drive_chatter_rms : dict of str to float
        RMS of the sample-to-sample change of the applied drive over that window [V].
    limit_cycle : dict of str to bool
        Over that window the applied drive still swings between signs with peaks beyond
        :data:`LIMIT_CYCLE_DRIVE` of Umax, or the tool, once inside the settle window,
        leaves it again by more than one pulse more (hunting by one count is neither).
    residual_vibration : dict of str to float
        Peak-to-peak of the tool's position over that window [pulse].
    peak_speed, peak_acceleration, peak_jerk : dict of str to float
        Largest first, second and third finite difference of the tool's position at Ts
        over the run [pulse/s, pulse/s^2, pulse/s^3].
    drive_limit_time_s : dict of str to float
        Time the law's drive was at or beyond Umax [s].
    """

    window_s: float
    drive_chatter_rms: dict
    limit_cycle: dict
    residual_vibration: dict
    peak_speed: dict
    peak_acceleration: dict
    peak_jerk: dict
    drive_limit_time_s: dict

    def to_dict(self) -> dict:
        return asdict(self)


class RunningAtRest:
    """:class:`AtRest` gathered block by block (rows of
    :class:`nurbsmotion.loop.closed_loop.Rows`, in order), keeping only the last ``window``
    samples.

    Parameters
    ----------
    machine : Machine
    end : ndarray, shape (n_axes,)
        The path's end point [pulse].
    settle_window : float
        [pulse]
    window : int
        Samples of the last window, >= 2.
    """

    def __init__(self, machine, end, settle_window: float, window: int):
        self.machine, self.end = machine, np.asarray(end, dtype=float)
        self.settle_window = float(settle_window)
        self.window = max(2, int(window))
        n = machine.n_axes
        self.tail_position = np.empty((0, n))
        self.tail_drive = np.empty((0, n))
        self.last3 = np.empty((0, n))  # the last three positions, for the differences
        self.peaks = np.zeros((3, n))
        self.at_limit = np.zeros(n, dtype=np.int64)

    def add(self, first: int, rows, finished: int = -1, last: bool = False) -> None:
        """Take the next block of rows (a sink of :func:`nurbsmotion.loop.simulate_streamed`)."""
        self._add(rows.position, rows.drive, rows.drive_applied)

    def _add(self, position, drive, drive_applied) -> None:
        if len(position) == 0:
            return
        Ts = self.machine.sample_period
        p = np.concatenate([self.last3, position])
        for order in range(3):
            p = np.diff(p, axis=0) / Ts  # with the last block's: a maximum, counted twice
            if len(p):
                self.peaks[order] = np.maximum(self.peaks[order], np.max(np.abs(p), axis=0))
        self.last3 = np.concatenate([self.last3, position])[-3:]
        self.at_limit += np.count_nonzero(np.abs(drive) >= self.machine.max_drive, axis=0)
        self.tail_position = np.concatenate([self.tail_position, position])[-self.window:]
        self.tail_drive = np.concatenate([self.tail_drive, drive_applied])[-self.window:]

    def result(self) -> AtRest:
        names = self.machine.axis_names
        Ts = self.machine.sample_period
        umax = self.machine.max_drive
        pos, drv = self.tail_position, self.tail_drive
        chatter = (np.sqrt(np.mean(np.diff(drv, axis=0) ** 2, axis=0)) if len(drv) > 1
                   else np.zeros(len(names)))
        swing = ((np.max(drv, axis=0) > LIMIT_CYCLE_DRIVE * umax)
                 & (np.min(drv, axis=0) < -LIMIT_CYCLE_DRIVE * umax))
        distance = np.abs(pos - self.end)
        leaves = np.zeros(len(names), dtype=bool)
        for j in range(len(names)):
            inside = np.flatnonzero(distance[:, j] <= self.settle_window)
            if inside.size:
                later = distance[inside[0]:, j]
                leaves[j] = bool(np.any(later > self.settle_window + 1.0))
        vibration = np.ptp(pos, axis=0) if len(pos) else np.zeros(len(names))

        def per_axis(values, kind=float):
            return {a: kind(v) for a, v in zip(names, values)}

        return AtRest(window_s=len(pos) * Ts,
                      drive_chatter_rms=per_axis(chatter),
                      limit_cycle=per_axis(swing | leaves, bool),
                      residual_vibration=per_axis(vibration),
                      peak_speed=per_axis(self.peaks[0]),
                      peak_acceleration=per_axis(self.peaks[1]),
                      peak_jerk=per_axis(self.peaks[2]),
                      drive_limit_time_s=per_axis(self.at_limit * Ts))


def trace_at_rest(trace, window: int | None = None) -> AtRest:
    """:class:`AtRest` of a :class:`~nurbsmotion.loop.Trace` over its last ``window``
    samples (by default its hold, or without one the samples its settling took)."""
    if window is None:
        window = trace.hold_samples or _settling_samples(trace.machine)
    running = RunningAtRest(trace.machine, trace.curve.end_points[1], trace.settle_window,
                            window)
    running._add(trace.position, trace.drive, trace.drive_applied)
    return running.result()


def _settling_samples(machine) -> int:
    from .loop.closed_loop import settle_hold_samples  # the loop's own rule

    return settle_hold_samples(machine)
