"""What the figures of :mod:`nurbsmotion.plots` look at: a run as drawn (:class:`_Run`), the
events that get a time window of their own (start, sharp corners or the largest drive,
stop; :func:`_events`) and the window's span (:func:`settling_time`, from the model), and
on the contour the zoom windows on the largest errors and the corners' labels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MAX_EVENT_WINDOWS = 3
"""Corner windows shown at most (the corners with the largest drive), besides start and stop."""


_MIN_ZOOM_HALF_WIDTH_PULSES = 50.0  # so a 10-pulse deviation spans a tenth of a zoom


_ZOOM_MARGIN = 1.3  # the zoom holds the largest nearby contour error with this margin


_CORNER_REACH = 0.05  # samples within this fraction of the length size a corner's zoom


_CLOSE_ZOOM_RATIO = 3.0  # add a closer zoom when the runs' errors differ by this factor


_MAX_ERROR_ZOOMS = 4  # zooms on the largest contour errors of a path without corners


_SETTLE_ZOOM = 5.0  # the settle zoom spans ±5 settle windows: the band and what enters it


@dataclass(frozen=True)
class _Run:
    """One run as a figure draws it, every length already in the report unit."""

    label: str
    trace: object  # the Trace (pulses); for its time, drive and bounds
    position: np.ndarray  # (n_samples, n_axes) [L]
    position_command: np.ndarray  # (n_samples, n_axes) [L]
    speed_command: np.ndarray  # (n_samples, n_axes) [L/s]
    speed_bounds: np.ndarray | None  # (n_samples, n_axes, 2) [L/s]
    color: str
    linestyle: str

    @property
    def t(self) -> np.ndarray:
        return self.trace.t


@dataclass(frozen=True)
class _Zoom:
    """A square window of the path plane, centred on ``center`` (2,) [L]."""

    label: str
    center: np.ndarray
    half_width: float  # [L]
    corner: int | None = None  # the sharp corner it shows (1, 2, ...), if any


@dataclass(frozen=True)
class _Event:
    """A moment worth a time window: where on the path (``u``) and its name."""

    label: str
    u: float
    kind: str  # "start", "corner", "peak" or "stop"


def settling_time(machine) -> float:
    """2 % settling time of the slowest axis's closed position loop [s], at least 10 Ts.

    Each axis's plant ``tau w' = -w + Kc u``, ``th' = Ke w`` under the PD law
    ``u = Kp (thd - th) - Kd w`` (the feedforward of PD+ does not move the poles) has the
    characteristic polynomial ``tau s^2 + (1 + Kc Kd) s + Kc Kp Ke``; the slowest decay
    rate ``sigma = min |Re(s)|`` over the axes gives ``4 / sigma``.
    """
    rates = []
    for tau, Kc, Ke, Kp, Kd in zip(machine.tau, machine.Kc, machine.Ke, machine.Kp,
                                   machine.Kd):
        roots = np.roots([tau, 1.0 + Kc * Kd, Kc * Kp * Ke])
        rates.append(float(np.min(np.abs(roots.real))))
    sigma = min(rates)
    settle = 4.0 / sigma if sigma > 0 else math.inf
    return max(min(settle, 1.0), 10.0 * machine.sample_period)


def _make_run(trace, label: str, style: tuple[str, str], per_unit: float) -> _Run:
    k = 1.0 / per_unit
    Ke = trace.machine.Ke
    bounds = None if trace.speed_bounds is None else trace.speed_bounds * Ke[None, :, None] * k
    return _Run(label, trace, trace.position * k, trace.position_command * k,
                trace.speed_command * Ke * k, bounds, *style)


def _index_at(trace, u: float) -> int:
    """First sample whose setpoint reaches path parameter ``u``."""
    i = int(np.searchsorted(trace.u[: trace.finished_index + 1], u - 1e-12))
    return min(i, trace.finished_index)


def _drive_peaks(traces: list, settle: float) -> list[_Event]:
    """On a path without corners: the places of the largest drive of the run that drives
    hardest, at most :data:`MAX_EVENT_WINDOWS`, a settling time apart, in path order."""
    worst = max(traces, key=lambda tr: float(np.max(np.abs(tr.drive))))
    end = worst.finished_index
    peak = np.max(np.abs(worst.drive[: end + 1]), axis=1)
    chosen: list[int] = []
    for k in np.argsort(peak)[::-1]:
        t = worst.t[k]
        if 0 < worst.u[k] < 1 and all(abs(t - worst.t[c]) > settle for c in chosen):
            chosen.append(int(k))
        if len(chosen) == MAX_EVENT_WINDOWS:
            break
    return [_Event(f"drive peak, t = {worst.t[k]:.3g} s", float(worst.u[k]), "peak")
            for k in sorted(chosen)]


def _events(curve, traces: list, settle: float) -> list[_Event]:
    """Start, the sharp corners with the largest drive near them (or, without corners,
    the places of the largest drive), and the stop."""
    corners = curve.sharp_corners()
    events = [_Event("start", 0.0, "start")]
    if corners.size:
        def drive_near(uc: float) -> float:
            peak = 0.0
            for tr in traces:
                i = _index_at(tr, uc)
                lo, hi = max(i - 20, 0), min(i + 40, len(tr.t))
                peak = max(peak, float(np.max(np.abs(tr.drive[lo:hi]))))
            return peak

        chosen = sorted(sorted(corners, key=drive_near, reverse=True)[:MAX_EVENT_WINDOWS])
        index = {float(c): n for n, c in enumerate(corners, start=1)}
        events += [_Event(f"corner {index[float(c)]}", float(c), "corner") for c in chosen]
    else:
        events += _drive_peaks(traces, settle)
    events.append(_Event("stop", 1.0, "stop"))
    return events


def _window(event: _Event, settle: float) -> tuple[float, float]:
    """Time span [s] of an event's window, relative to the event."""
    if event.kind == "start":
        return -0.1 * settle, 1.4 * settle
    return -0.5 * settle, settle


def _event_time(run: _Run, event: _Event) -> float:
    tr = run.trace
    return float(tr.t[tr.finished_index if event.kind == "stop" else _index_at(tr, event.u)])


def _desired_parameters(curve, n: int = 20000) -> np.ndarray:
    """Parameters uniform in arc length plus every breakpoint (corners drawn sharp)."""
    return np.union1d(curve.parameter_at(np.linspace(0.0, curve.length, n)),
                      curve.breakpoints)


def _desired_points(curve, n: int = 20000) -> np.ndarray:
    """Curve points uniform in arc length plus every breakpoint, shape (m, n_axes) [L]."""
    return curve(_desired_parameters(curve, n))


_ZOOM_SUBDIVISION = 64
"""Each segment of the desired polyline that crosses a zoom window is redrawn from this
many curve points (a zoom of a few pulses on a long path would otherwise show the
polyline's chords, not the curve)."""


def _desired_in_window(curve, u: np.ndarray, points: np.ndarray, zoom: _Zoom) -> np.ndarray:
    """The desired path inside ``zoom``, evaluated finely: shape (m, 2) [L], NaN rows
    between separate passes through the window. ``u`` and ``points`` are
    :func:`_desired_parameters` and the curve's points there."""
    h = zoom.half_width
    inside = np.all(np.abs(points[:, :2] - zoom.center) <= h, axis=1)
    near = inside.copy()  # the segments that enter or leave the window too
    near[:-1] |= inside[1:]
    near[1:] |= inside[:-1]
    starts = np.nonzero(near[:-1] & near[1:])[0]
    if starts.size == 0:
        return np.empty((0, 2))
    t = np.linspace(0.0, 1.0, _ZOOM_SUBDIVISION + 1)
    fine = u[starts, None] + (u[starts + 1] - u[starts])[:, None] * t[None, :]
    xy = curve(fine.ravel())[:, :2].reshape(len(starts), -1, 2)
    gap = np.append(np.diff(starts) > 1, True)  # a NaN row after each separate pass
    rows = [np.vstack([seg, np.full((1, 2), np.nan)]) if g else seg
            for seg, g in zip(xy, gap)]
    return np.vstack(rows)


def _error_peaks(curve, runs: list[_Run], nearest: list[tuple]) -> list[tuple]:
    """On a path without corners: the places of the largest contour error, at most
    :data:`_MAX_ERROR_ZOOMS`, at least ``2 * _CORNER_REACH`` of the length apart; each as
    (label, points (2,) [L] to hold, error [L])."""
    candidates = []  # (error, run index, sample)
    for i, (_, d) in enumerate(nearest):
        for k in np.argsort(d)[::-1][:2000]:
            candidates.append((float(d[k]), i, int(k)))
    candidates.sort(reverse=True)
    chosen, places = [], []
    for err, i, k in candidates:
        s = float(curve.arc_length(nearest[i][0][k]))
        if all(abs(s - q) > 2 * _CORNER_REACH * curve.length for q in places):
            places.append(s)
            run = runs[i]
            chosen.append((f"{run.label}, t = {run.t[k]:.3f} s",
                           [run.position[k, :2], curve(nearest[i][0][k])[:2]], err))
        if len(chosen) == _MAX_ERROR_ZOOMS:
            break
    return chosen


def _zoom_windows(curve, runs: list[_Run], nearest: list[tuple],
                  min_half: float) -> list[_Zoom]:
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
    cap = max(cap, min_half)

    def window(label: str, points: list, err: float, corner: int | None = None) -> _Zoom:
        """Square around ``points`` (each (2,) [L]) with room for ``err`` [L]."""
        pts = np.array(points)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        half = 0.5 * float(np.max(hi - lo)) + (_ZOOM_MARGIN - 1.0) * err
        half = min(max(min_half, half, _ZOOM_MARGIN * err), cap)
        return _Zoom(label, 0.5 * (lo + hi), half, corner)

    corners = curve.sharp_corners()
    if corners.size == 0:
        return [window(label, points, err)
                for label, points, err in _error_peaks(curve, runs, nearest)]
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
                # the worst sample is held in the window when it is a deviation at the
                # corner (an overshoot), not a tiny error far along the next piece
                if (np.linalg.norm(r.position[k, :2] - corner)
                        <= 2.0 * _ZOOM_MARGIN * float(d[k]) + min_half):
                    points.append(r.position[k, :2])
                local.append(float(d[k]))
            else:
                local.append(0.0)
        zooms.append(window(f"corner {n} (u = {uc:.3g})", points, max(local), n))
        if max(local) > _CLOSE_ZOOM_RATIO * max(min(local), min_half / 2):
            zooms.append(window(f"corner {n}, closer", [corner], min(local), n))
    return zooms


def _label_corners(ax, curve, zooms: list[_Zoom]) -> list:
    """Zoom boxes, and one label per place beside (not on) the path with a leader line:
    "corner n (A, B)" at a sharp corner, the zoom letters elsewhere; returns the labels
    (for :func:`_fit_in_view` once the panels are placed)."""
    from matplotlib.patches import Rectangle

    pts = _desired_points(curve, 500)[:, :2]
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    size = float(np.max(np.ptp(pts, axis=0)))
    lo = pts.min(axis=0) - 0.1 * size
    hi = pts.max(axis=0) + 0.1 * size
    box = dict(boxstyle="round,pad=0.25", facecolor="white", edgecolor="0.5", alpha=0.95)
    places: dict = {}  # corner number or zoom index -> (anchor (2,) [L], letters)
    corners = curve.sharp_corners()
    for j, z in enumerate(zooms):
        (cx, cy), h = z.center, z.half_width
        ax.add_patch(Rectangle((cx - h, cy - h), 2 * h, 2 * h, fill=False, edgecolor="0.3",
                               linewidth=0.9))
        key = ("corner", z.corner) if z.corner is not None else ("zoom", j)
        anchor = curve(corners[z.corner - 1])[:2] if z.corner is not None else z.center
        places.setdefault(key, (anchor, []))[1].append(chr(65 + j))
    labels = []
    for (kind, n), (p, letters) in places.items():
        away = p - centre
        norm = float(np.linalg.norm(away))
        away = away / norm if norm > 0 else np.array([0.0, 1.0])
        # Outward from the path's centre, the text on the far side of its anchor (so that
        # it runs away from the path, not across it).
        text_at = np.clip(p + 0.12 * size * away, lo, hi)
        ha = "right" if away[0] < -0.35 else "left" if away[0] > 0.35 else "center"
        va = "top" if away[1] < -0.35 else "bottom" if away[1] > 0.35 else "center"
        text = ", ".join(letters)
        labels.append(ax.annotate(
            f"corner {n} ({text})" if kind == "corner" else text, p, xytext=text_at,
            fontsize="medium", ha=ha, va=va, bbox=box,
            arrowprops=dict(arrowstyle="-", color="0.4", linewidth=0.8)))
    return labels
