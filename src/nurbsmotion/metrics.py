"""The figures every run reports (SPEC section 9), computed from a trace.

- cycle time: time at which the setpoint first reaches the path's end;
- following error per axis thd[k] - tha[k], max |.| and RMS;
- contour error: distance from tha[k] to the nearest point of the *curve* (not to the
  setpoint), max and RMS, accurate to far better than 0.01 pulse;
- drive use per axis: max |u[k]|/Umax before clipping, and the samples with |u[k]| > Umax
  (by more than :data:`SATURATION_TOLERANCE`, far below one step of a 16-bit DAC, so that
  an interpolator that drives exactly at the limit is not counted for rounding errors);
- feedrate fluctuation ``(|thd[k] - thd[k-1]|/Ts - Vcmd[k]) / Vcmd[k]``, max |.| and RMS.

All figures are taken over every sample of the trace, the settling tail included.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from .nurbs import NurbsCurve
from .stepping import Status

__all__ = ["Metrics", "trace_metrics", "feed_fluctuation", "contour_error", "nearest_parameter",
           "SATURATION_TOLERANCE"]

SATURATION_TOLERANCE = 1e-6
"""Relative excess over Umax below which a sample is not counted as saturated."""


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


def nearest_parameter(curve: NurbsCurve, points: np.ndarray, grid_size: int = 20_000):
    """Parameter of the nearest curve point to each of ``points``.

    A coarse search over a dense grid (uniform in arc length, with every knot added, so no
    grid cell straddles a corner) finds the nearest sample; safeguarded Newton iterations
    on ``(C(u) - p) . C'(u) = 0`` in the two cells beside it refine it.

    Parameters
    ----------
    curve : NurbsCurve
    points : ndarray, shape (m, n_axes)
        [path units]
    grid_size : int
        Number of coarse grid points, uniform in arc length.

    Returns
    -------
    u : ndarray, shape (m,)
    distance : ndarray, shape (m,)
        [path units]
    """
    pts = np.asarray(points, dtype=float)
    grid = np.union1d(curve.geometry.uniform_parameters(grid_size),
                      curve.breakpoints)
    tree = cKDTree(curve(grid))
    _, j = tree.query(pts)
    best_u = grid[j]
    best_d = np.linalg.norm(curve(best_u) - pts, axis=1)
    for lo_idx, hi_idx in ((np.maximum(j - 1, 0), j), (j, np.minimum(j + 1, len(grid) - 1))):
        lo, hi = grid[lo_idx], grid[hi_idx]
        u = 0.5 * (lo + hi)
        for _ in range(30):
            d = curve.derivatives(u, 2)
            r = d[0] - pts
            g = np.sum(r * d[1], axis=1)
            dg = np.sum(d[1] * d[1], axis=1) + np.sum(r * d[2], axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(dg > 0, g / dg, 0.0)
            u_new = np.clip(u - step, lo, hi)
            if np.all(np.abs(u_new - u) <= 1e-15):
                u = u_new
                break
            u = u_new
        for cand in (u, lo, hi):
            dist = np.linalg.norm(curve(cand) - pts, axis=1)
            better = dist < best_d
            best_u = np.where(better, cand, best_u)
            best_d = np.where(better, dist, best_d)
    return best_u, best_d


def contour_error(curve: NurbsCurve, points: np.ndarray) -> np.ndarray:
    """Distance from each point to the curve, shape (m,) [path units]."""
    return nearest_parameter(curve, points)[1]


def trace_metrics(trace) -> Metrics:
    """All SPEC section 9 figures of a :class:`~nurbsmotion.loop.Trace` but the
    time-optimal bound."""
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
        limited_samples=int(np.count_nonzero(trace.status == Status.LIMITED)),
        cornered_samples={n: int(v) for n, v in zip(names, cornered_axes)},
        success=bool(trace.success),
        message=trace.message,
    )
