"""Drive-limited speed along a path: the time-optimal bound and the look-ahead profile.

The path is parametrised by arc length s; per axis j, x_j(s) with derivatives q1_j =
dx_j/ds and q2_j = d2x_j/ds2. A motion s(t) with speed sd = ds/dt and acceleration sdd
gives the axis speed xd_j = q1_j*sd and acceleration xdd_j = q2_j*sd^2 + q1_j*sdd. The
drive of a perfectly tracked axis (the feedforward of the PD+ law, docs/model.md#servo-axis to #controllers)
stays within the limit when

    |tau_j*xdd_j + xd_j| <= Umax*Kc_j*Ke_j = M_j          (docs/model.md#run-figures)

For a given s and sd this is an interval of sdd per axis; their intersection is the
admissible acceleration range [amin(s, sd), amax(s, sd)]. The largest sd at which the range
is not empty (and sd <= F) is the maximum velocity curve (MVC). The time-optimal motion,
at rest at both ends and at every sharp corner, is found by the classic phase-plane
method (Bobrow, Dubowsky & Gibson 1985; Shin & McKay 1985) on an arc-length grid of
each corner-free piece (uniform, refined to ``2p`` intervals in every knot span shorter
than its spacing, and wherever the tangent turns by more than :data:`MAX_TURN` over an
interval, so that no feature of the path falls between grid points), with b = sd^2 as
the state (db/ds = 2*sdd): a backward pass
from the piece's end at the deceleration limit, then a forward pass from its start at the
acceleration limit, each clipped by the MVC and by the other. Each step uses the smaller
of the limits at its two ends (a one-step implicit correction); where the MVC itself is
the limit the profile slides along it. The time converges as the grid is refined (first
order in the grid spacing).

:func:`speed_profile` returns the profile (:class:`SpeedProfile`), which the ``planned``
interpolator reuses with a reduced drive limit; :func:`time_optimal_bound` its duration.

Glossary
--------
s : arc length [pulse]; sd, V : speed along the path [pulse/s]; sdd : tangential
acceleration [pulse/s^2]; b = sd^2; q1, q2 : first and second derivatives of the axis
positions with respect to s [1, 1/pulse]; tau [s], Kc [(rad/s)/V], Ke [pulse/rad], Umax
[V]: docs/model.md#units; M = Umax*Kc*Ke : the largest steady axis speed [pulse/s]; F : the
commanded feed [pulse/s].

Why one module of about 900 lines: it is one algorithm, the phase-plane passes above,
used three ways (the look-ahead :func:`speed_profile`, the :func:`time_optimal_bound` and
the :func:`sampled_stop_bound`) over the same arc-length grid, limits and compiled step;
each part alone would be a module of helpers the others import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InfeasibleError, InvalidArgumentError, InvalidFeedError, WorkLimitError
from .feed import FeedLimit
from .machine import Machine
from .nurbs import NurbsCurve, point_extent
from .servo import zoh_coefficients
from .units import in_pulses

__all__ = ["SpeedProfile", "speed_profile", "time_optimal_bound", "sampled_stop_bound",
           "check_path_size", "check_span_count", "check_profile_size", "check_corner_count",
           "most_corners", "top_speed", "check_feed_reachable", "MAX_FEED_RATIO"]


@dataclass(frozen=True, eq=False)
class SpeedProfile:
    """A speed along the path, at rest at both ends and at every sharp corner.

    Attributes
    ----------
    pieces : tuple of (ndarray, ndarray, ndarray)
        One ``(s, u, V)`` triple per corner-free piece, in path order: arc length from the
        path's start [pulse], shape (n,); curve parameter, shape (n,); speed [pulse/s],
        shape (n,), 0 at both ends of each piece.
    feed : float
        The feed limit F [pulse/s].
    drive_fraction : float
        Fraction of Umax the profile may use (1 for the time-optimal bound).
    """

    pieces: tuple
    feed: float
    drive_fraction: float

    @property
    def s(self) -> np.ndarray:
        """Arc length of every grid point [pulse], shape (n,); corners appear twice."""
        return np.concatenate([p[0] for p in self.pieces])

    @property
    def speed(self) -> np.ndarray:
        """V(s) at every grid point [pulse/s], shape (n,)."""
        return np.concatenate([p[2] for p in self.pieces])

    def piece_times(self) -> list[np.ndarray]:
        """Time of every grid point from the start of its piece [s], one array per piece.

        Between grid points the acceleration is taken constant (b linear in s), which gives
        ``dt = 2*ds / (V_i + V_{i+1})``.
        """
        out = []
        for s, _, V in self.pieces:
            ds = np.diff(s)
            vsum = V[:-1] + V[1:]
            with np.errstate(divide="ignore"):
                dt = np.where(ds > 0, 2.0 * ds / vsum, 0.0)
            out.append(np.concatenate([[0.0], np.cumsum(dt)]))
        return out

    @property
    def duration(self) -> float:
        """Time to traverse the path along the profile [s]."""
        return float(sum(t[-1] for t in self.piece_times()))


SPAN_POINTS_PER_DEGREE = 2
"""Grid points per knot span and per unit of degree: a span's drive limits vary like a
polynomial of degree about 2p in its parameter, so 2p intervals resolve their shape."""

MAX_TURN = 0.1
"""Largest turn [rad] of the path's tangent over one grid interval. A turn sharper than
the grid's spacing (a near-cusp: a smooth turn of radius far below the spacing inside a
knot span) is refined until every interval turns by at most this much: the profile's
limits are taken at the grid points, so an interval that steps over a curvature peak
either misses it (the profile is too fast for the drive) or lands on it and crawls over
the whole interval (on a random near-cusp the bound came out 2.8x its converged value at
20,000 points and 10x at 4,000). At 0.1 rad the profile's time on such paths changes by
under 1e-5 when it is halved or the uniform grid is refined 80 times."""

REFINE_SPLIT = 16
"""Most parts an interval is split into per refinement round (the turn is estimated from
the curvature at its ends, which overstates it near a curvature peak: splitting a little
at a time, and estimating again, adds few points)."""

MAX_GRID_POINTS = 5_000_000
"""Most grid points of a speed profile (the passes run about 10^5 points per second)."""


def top_speed(machine: Machine) -> float:
    """The fastest any motion within the drive limits moves along a path [pulse/s]:
    ``sqrt(sum_j (Umax*Kc_j*Ke_j)^2)``. Each axis's speed obeys ``tau_j*xdd_j + xd_j =
    Kc_j*Ke_j*u_j`` (docs/model.md#servo-axis), a first-order filter of a drive ``|u_j| <= Umax``,
    so from rest ``|xd_j|`` never exceeds ``Umax*Kc_j*Ke_j``. ``inf`` for an ideal drive."""
    if machine.max_drive == math.inf:
        return math.inf
    v = machine.max_drive * machine.Kc * machine.Ke
    top = float(np.sqrt(np.sum(v ** 2)))
    if top in (0.0, math.inf) and np.all(np.isfinite(v)) and np.any(v):
        # the squares under- or overflowed (Umax = 1e-300 gave 0, and a division by it)
        big = float(np.max(np.abs(v)))
        top = big * float(np.sqrt(np.sum((v / big) ** 2)))
    return top


MAX_FEED_RATIO = 1000.0
"""A feed more than this many times :func:`top_speed` is refused by ``run``, ``bound`` and
campaigns (:func:`check_feed_reachable`): no motion comes near it, and such a number is a
slip of its unit (1e12 mm/s is faster than light)."""


def check_feed_reachable(feed, machine: Machine, shown: str | None = None) -> None:
    """Refuse a feed [pulse/s] (its highest piece for a :class:`FeedLimit`) above
    :data:`MAX_FEED_RATIO` times the machine's :func:`top_speed`.

    Parameters
    ----------
    feed : float or FeedLimit
        [pulse/s].
    machine : Machine
    shown : str, optional
        The feed as the user gave it, for the message (e.g. ``"1e12mm/s"``).

    Raises
    ------
    InvalidFeedError
        Naming the feed, the top speed and the ratio.
    """
    F = feed.highest if isinstance(feed, FeedLimit) else float(feed)
    top = top_speed(machine)
    if F > MAX_FEED_RATIO * top:
        given = f"{shown} = " if shown else ""
        raise InvalidFeedError(
            f"feed {given}{F:.3g} pulse/s is {F / top:.3g} times the fastest any motion of "
            f"{machine.name} moves ({top:.3g} pulse/s, sqrt(sum (Umax*Kc*Ke)^2)), more than "
            f"the {MAX_FEED_RATIO:g} x a run accepts (planning.MAX_FEED_RATIO); is its unit "
            "right?")


def check_path_size(curve: NurbsCurve) -> None:
    """Refuse, before any table is built, a path whose speed profile cannot fit in
    :data:`MAX_GRID_POINTS`: every knot span gets at least ``SPAN_POINTS_PER_DEGREE * p``
    grid intervals (:func:`speed_profile`), so a path of ``n`` spans needs at least
    ``n * SPAN_POINTS_PER_DEGREE * p + 1`` points. Counted from the knots alone (no
    arc length), in microseconds.

    Raises
    ------
    WorkLimitError
        Naming the spans, the degree and the limit.
    """
    check_span_count(curve.degree, len(curve.breakpoints) - 1)


def check_span_count(degree: int, spans: int) -> None:
    """:func:`check_path_size` from the counts alone: a path of ``spans`` knot spans of
    degree ``degree`` (a path file's, counted as it is read:
    :func:`nurbsmotion.paths.load_contours`'s ``size_check``).

    Raises
    ------
    WorkLimitError
        Naming the spans, the degree and the limit.
    """
    least = spans * SPAN_POINTS_PER_DEGREE * degree + 1
    if least > MAX_GRID_POINTS:
        raise WorkLimitError(
            f"the path has {spans:,} knot spans of degree {degree}: at "
            f"{SPAN_POINTS_PER_DEGREE} x degree grid points each its speed profile needs "
            f"{least:,} points, more than the limit of {MAX_GRID_POINTS:,} "
            "(planning.MAX_GRID_POINTS); split the path or join its chords")


PIECE_GRID_POINTS = 51
"""Fewest grid points of a corner-free piece of a speed profile (:func:`speed_profile`:
at least 50 intervals a piece, whatever its length)."""


def check_profile_size(curve: NurbsCurve) -> None:
    """Refuse a path whose speed profile (:func:`speed_profile`, so
    :func:`time_optimal_bound` and every ``run``) cannot fit in :data:`MAX_GRID_POINTS`,
    from its knots and sharp corners alone, before any arc length: the knot spans as
    :func:`check_path_size`, and :data:`PIECE_GRID_POINTS` per corner-free piece (its sharp
    corners split it; :func:`speed_profile` splits it at least there). One vectorised
    pass over the corner candidates (a second on a million-span path).

    Raises
    ------
    WorkLimitError
        Naming the spans (or the corners), the points they need and the limit.
    """
    check_path_size(curve)
    check_corner_count(len(curve.sharp_corners()))


def most_corners() -> int:
    """The most sharp corners a path's speed profile can hold: ``PIECE_GRID_POINTS *
    (corners + 1)`` grid points within :data:`MAX_GRID_POINTS` (:func:`check_corner_count`
    refuses one more)."""
    return MAX_GRID_POINTS // PIECE_GRID_POINTS - 1


def check_corner_count(corners: int, counted_in: str | None = None) -> None:
    """:func:`check_profile_size`'s corner check from the count alone: refuse a path of
    ``corners`` sharp corners (more than :func:`most_corners`).

    Parameters
    ----------
    corners : int
        Sharp corners of the path as it is planned (at least that many, with
        ``counted_in``).
    counted_in : str, optional
        Where a lower bound was counted (``"its first 98,042 points"``: a large path
        file's, as it is read, :func:`nurbsmotion.study.run_input.load_run_contour`);
        None for the path's exact count.

    Raises
    ------
    WorkLimitError
        Naming the corners, the points they need and the limit.
    """
    least = PIECE_GRID_POINTS * (corners + 1)
    if least > MAX_GRID_POINTS:
        many = f"{corners:,}" if counted_in is None else f"at least {corners:,}"
        where = "" if counted_in is None else f" (in {counted_in})"
        more = "" if counted_in is None else " or more"
        raise WorkLimitError(
            f"the path has {many} sharp corners{where}; its {corners + 1:,}{more} corner-free "
            f"pieces need at least {least:,} grid points ({PIECE_GRID_POINTS} a piece), more "
            f"than the limit of {MAX_GRID_POINTS:,} (planning.MAX_GRID_POINTS); smooth the "
            "path or join its nearly collinear segments")


def _span_points(curve: NurbsCurve, u0: float, u1: float, s: np.ndarray) -> np.ndarray:
    """Arc lengths [pulse] that refine the grid ``s`` of the piece [u0, u1] in every knot
    span holding fewer than ``SPAN_POINTS_PER_DEGREE * p`` grid intervals: that many
    equal arc-length intervals there (its ends included). Empty when no span needs it.

    A fixed grid coarser than the knot spans steps over the path's features (a 25 m path
    of 5 mm waves gave an infinite or far too long bound); this makes the grid adapt."""
    bp = curve.breakpoints
    edges = np.concatenate([[u0], bp[(bp > u0) & (bp < u1)], [u1]])
    s_edges = curve.arc_length(edges)
    s_edges[0], s_edges[-1] = s[0], s[-1]
    m = SPAN_POINTS_PER_DEGREE * curve.degree
    inside = np.searchsorted(s, s_edges[1:]) - np.searchsorted(s, s_edges[:-1], side="right")
    short = np.flatnonzero(inside + 1 < m)
    if short.size == 0:
        return np.empty(0)
    frac = np.arange(m + 1) / m
    a, b = s_edges[short], s_edges[short + 1]
    return (a[:, None] + (b - a)[:, None] * frac).ravel()


def _piece_bounds(curve: NurbsCurve) -> np.ndarray:
    """Where the motion stops: the ends, every sharp corner, and every point where
    ``C' = 0`` (a repeated control point: the tangent is continuous there, but the
    curvature in arc length is unbounded unless the curve happens to be straight, so the
    drive-limited speed is zero)."""
    inner = np.union1d(curve.sharp_corners(), curve.zero_speed_points)
    return np.concatenate([[0.0], inner[(inner > 0.0) & (inner < 1.0)], [1.0]])


def _arc_derivatives(curve: NurbsCurve, u: np.ndarray, side: np.ndarray):
    """q1 = dx/ds and q2 = d2x/ds2 at parameters ``u``, shape (n, n_axes) each.

    ``side`` (bool, shape (n,)) selects the left derivative (True) at a piece's end.
    """
    dr = curve.derivatives(u, 2, "right")
    if np.any(side):
        dl = curve.derivatives(u[side], 2, "left")
        dr[:, side] = dl
    d1, d2 = dr[1], dr[2]
    n2 = np.sum(d1 * d1, axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        q1 = d1 / np.sqrt(n2)
        # d2x/ds2 = (C'' - (C''.t) t) / |C'|^2 : the normal part of C'' over |C'|^2.
        q2 = (d2 - np.sum(d2 * q1, axis=1, keepdims=True) * q1) / n2
    # At a zero-speed point (a piece's end, where the motion is at rest: _piece_bounds)
    # the direction is the limit tangent and the speed limit is zero anyway.
    scale = point_extent(curve.control_points)
    still = n2[:, 0] <= (1e-9 * scale) ** 2
    if np.any(still):
        for name, rows in (("right", still & ~side), ("left", still & side)):
            if np.any(rows):
                q1[rows] = curve.limit_tangent(u[rows], name)
        q2[still] = 0.0
    return q1, q2


def _interval_turns(q1: np.ndarray, q2: np.ndarray, ds: np.ndarray) -> np.ndarray:
    """An estimate of how far the tangent turns [rad] over each grid interval, shape
    (n - 1,): the angle between the tangents at its ends, or the larger curvature at its
    ends times its length where that is more (a peak between the points, or a loop)."""
    cosine = np.clip(np.sum(q1[1:] * q1[:-1], axis=1), -1.0, 1.0)
    curvature = np.linalg.norm(q2, axis=1)
    return np.maximum(np.arccos(cosine), np.maximum(curvature[1:], curvature[:-1]) * ds)


def _refine_turns(curve: NurbsCurve, s, u, ds, q1, q2):
    """The grid ``(s, u, ds, q1, q2)`` refined until no interval turns by more than
    :data:`MAX_TURN` (:func:`_interval_turns`), or it is shorter than ``1e-12`` of the
    path (a turn the arc length cannot resolve further); the new points lie inside the
    piece, so its end points and their one-sided derivatives are kept."""
    floor = 1e-12 * curve.length
    for _ in range(64):
        turns = _interval_turns(q1, q2, ds)
        bad = np.flatnonzero((turns > MAX_TURN) & (ds > floor))
        if bad.size == 0:
            break
        parts = np.minimum(np.ceil(turns[bad] / MAX_TURN), REFINE_SPLIT).astype(int)
        starts = np.repeat(bad, parts - 1)
        first = np.repeat(np.cumsum(parts - 1) - (parts - 1), parts - 1)
        step = (np.arange(len(starts)) - first + 1) / np.repeat(parts, parts - 1)
        new = s[starts] + ds[starts] * step
        new_u = curve.parameter_at(new)
        new_q1, new_q2 = _arc_derivatives(curve, new_u, np.zeros(len(new), dtype=bool))
        order = np.argsort(np.concatenate([s, new]), kind="stable")
        s = np.concatenate([s, new])[order]
        u = np.concatenate([u, new_u])[order]
        q1 = np.concatenate([q1, new_q1])[order]
        q2 = np.concatenate([q2, new_q2])[order]
        ds = np.diff(s)
    return s, u, ds, q1, q2


def _piece_grid(curve: NurbsCurve, ends: np.ndarray, s_ends: np.ndarray, k: int,
                grid_size: int):
    """Piece k's grid (see :func:`speed_profile`): arc length s [pulse], parameter u,
    spacing ds [pulse] and the path derivatives q1, q2 (:func:`_arc_derivatives`)."""
    L = s_ends[-1]
    s0, s1 = float(s_ends[k]), float(s_ends[k + 1])
    n = max(50, int(math.ceil(grid_size * (s1 - s0) / L))) + 1
    s = np.linspace(s0, s1, n)
    ds = np.full(n - 1, (s1 - s0) / (n - 1))
    finer = _span_points(curve, ends[k], ends[k + 1], s)
    if finer.size:  # knot spans shorter than the grid spacing: refine there
        s = np.union1d(s, finer)
        n, ds = len(s), np.diff(s)
    u = np.empty(n)
    u[1:-1] = curve.parameter_at(s[1:-1])
    u[0], u[-1] = ends[k], ends[k + 1]
    left = np.zeros(n, dtype=bool)
    left[-1] = True
    q1, q2 = _arc_derivatives(curve, u, left)
    return _refine_turns(curve, s, u, ds, q1, q2)


def speed_profile(curve: NurbsCurve, machine: Machine, feed: float, *,
                  drive_fraction: float = 1.0, acceleration_fraction: float | None = None,
                  drive_scale=None, acceleration_scale=None, grid_size: int = 20_000,
                  min_speed_ratio: float = 1e-6, grids: dict | None = None) -> SpeedProfile:
    """The fastest speed along ``curve`` that keeps the feedforward drive within bounds.

    Per axis ``|tau_j*xdd_j + xd_j| <= drive_fraction*Umax*Kc_j*Ke_j``, ``V <= feed``, and
    ``V = 0`` at both ends and at every sharp corner (docs/model.md#run-figures).

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        tau, Kc, Ke and Umax of every axis.
    feed : float or FeedLimit
        F [pulse/s], finite and > 0; or a piecewise limit ``V <= F(u)`` (the programmed
        feed of a G-code file, :class:`~nurbsmotion.feed.FeedLimit` scaled to pulse/s).
    drive_fraction : float
        Fraction of Umax the profile may use, in (0, 1]: on the deceleration limit (the
        backward pass) and on the maximum velocity curve.
    acceleration_fraction : float, optional
        Fraction of Umax on the acceleration limit (the forward pass), in (0, 1];
        ``drive_fraction`` by default.
    drive_scale : callable, optional
        ``drive_scale(s) -> ndarray`` in (0, 1], a further factor on both fractions along
        the path (s [pulse], shape (n,)); used by the planner to ease off locally.
    acceleration_scale : callable, optional
        The factor on ``acceleration_fraction`` alone, in place of ``drive_scale``
        (same form); ``drive_scale`` by default.
    grid_size : int
        Arc-length grid points over the whole path (each piece gets its share by length,
        at least 50); knot spans with fewer than ``SPAN_POINTS_PER_DEGREE * p`` grid
        intervals are refined to that many, and every interval over which the tangent
        turns by more than :data:`MAX_TURN` is split, up to :data:`MAX_GRID_POINTS` in
        all.
    min_speed_ratio : float
        A speed limit below ``min_speed_ratio*feed`` inside a piece means the drive cannot
        move the path there at all.
    grids : dict, optional
        A cache of the pieces' grids and path derivatives for this ``curve``, filled and
        reused across calls (a planner that recomputes the profile under other drive
        limits passes the same empty dict every time).

    Returns
    -------
    SpeedProfile

    Raises
    ------
    InvalidFeedError, InvalidArgumentError
        If the feed is not finite and > 0, or a fraction or the grid size is out of range.
    InfeasibleError
        If the drive cannot move along some part of the path (its speed limit there is
        zero).
    """
    from .phase_plane import max_speed, passes  # numba: loaded when a profile is made

    F = _check_feed(feed)
    check_path_size(curve)
    # No motion within the drive limits is faster than top_speed: a higher feed never
    # binds, and the profile is computed below twice that (the MVC's feed ratio and F^2
    # stay meaningful for any feed, 1e300 included).
    ceiling = 2.0 * top_speed(machine)
    if F > ceiling:
        feed = feed.capped(ceiling) if isinstance(feed, FeedLimit) else ceiling
        F = ceiling
    fa = drive_fraction if acceleration_fraction is None else acceleration_fraction
    for name, f in (("drive_fraction", drive_fraction), ("acceleration_fraction", fa)):
        if not (0 < f <= 1):
            raise InvalidArgumentError(f"{name} must lie in (0, 1], got {f!r}")
    if int(grid_size) < 10:
        raise InvalidArgumentError(f"grid_size must be >= 10, got {grid_size!r}")
    machine.check_path(curve.n_axes)
    M = machine.max_drive * machine.Kc * machine.Ke
    tau = machine.tau
    ends = _piece_bounds(curve)

    def check_grid(least: int) -> None:
        if least > MAX_GRID_POINTS:
            raise InfeasibleError(
                f"the path has {len(ends) - 2} sharp corners; its {len(ends) - 1} corner-free "
                f"pieces need at least {least:.3g} grid points (51 a piece), more than the "
                f"limit of {MAX_GRID_POINTS:.3g} (planning.MAX_GRID_POINTS); smooth the path "
                "or join its nearly collinear segments")

    check_grid(51 * (len(ends) - 1))  # before the arc length, which costs seconds there
    L = curve.length
    s_ends = curve.arc_length(ends)
    s_ends[0], s_ends[-1] = 0.0, L
    check_grid(int(np.sum(np.maximum(50, np.ceil(grid_size * np.diff(s_ends) / L)) + 1)))
    pieces = []
    total_points = 0
    for k in range(len(ends) - 1):
        key = (int(grid_size), k)
        if grids is None or key not in grids:
            grid = _piece_grid(curve, ends, s_ends, k, grid_size)
            if grids is not None:
                grids[key] = grid
        else:
            grid = grids[key]
        s, u, ds, q1, q2 = grid
        n = len(s)
        total_points += n
        if total_points > MAX_GRID_POINTS:
            raise InfeasibleError(
                f"the path has {len(curve.breakpoints) - 1} knot spans, too many to resolve "
                f"with {SPAN_POINTS_PER_DEGREE} x degree grid points each within the "
                f"limit of {MAX_GRID_POINTS:.3g} grid points (planning.MAX_GRID_POINTS)")
        scale = np.ones(n) if drive_scale is None else np.asarray(drive_scale(s), float)
        M_dec = np.ascontiguousarray(drive_fraction * scale[:, None] * M)
        if acceleration_scale is not None:
            scale = np.asarray(acceleration_scale(s), float)
        M_acc = M_dec if (fa == drive_fraction and acceleration_scale is None) \
            else np.ascontiguousarray(fa * scale[:, None] * M)
        F_here = feed(u) if isinstance(feed, FeedLimit) else F
        F_grid = np.ascontiguousarray(np.broadcast_to(F_here, (n,)), dtype=float)
        vmax = max_speed(q1, q2, tau, M_dec, F_grid)
        inner = vmax[1:-1]
        if inner.size and np.min(inner / np.broadcast_to(F_here, vmax.shape)[1:-1]) < min_speed_ratio:
            i = int(np.argmin(inner)) + 1
            raise InfeasibleError(
                f"the drive cannot move along the path at s = {s[i]:.6g} pulse "
                f"(u = {u[i]:.6g}): its speed limit there is {vmax[i]:.3g} pulse/s with "
                f"{drive_fraction:g} x Umax = {drive_fraction * machine.max_drive:g} V; "
                "the curvature is too high for the drive"
            )
        b = passes(q1, q2, tau, M_dec, M_acc, np.asarray(ds, dtype=float), vmax**2,
                   F_grid**2)
        pieces.append((s, u, np.sqrt(b)))
    return SpeedProfile(tuple(pieces), F, float(drive_fraction))


def _check_feed(feed) -> float:
    """The (highest) feed [pulse/s] of a number or a :class:`~nurbsmotion.feed.FeedLimit`."""
    if isinstance(feed, FeedLimit):
        return feed.highest
    try:
        F = float(feed)
    except (TypeError, ValueError):
        raise InvalidFeedError(f"feed must be a number [pulse/s], got {feed!r}") from None
    if not (math.isfinite(F) and F > 0):
        raise InvalidFeedError(f"feed must be finite and > 0, got {feed!r} pulse/s")
    return F


def _rest_to_rest_reach(a: float, b0: float, c: float, b1: float, n: int,
                        speed_slack: float = 0.0) -> float:
    """The farthest [pulse per V of Umax] one ZOH axis (docs/model.md#servo-axis: ``w[k+1] = a*w[k] +
    b0*u[k]``, ``theta[k+1] = theta[k] + c*w[k] + b1*u[k]``) moves in ``n`` samples from
    rest, under ``|u| <= 1``, ending with ``|w[n]| <= speed_slack`` [rad/s per V].

    The drive of sample ``n - 1 - p`` moves the end state by ``G[p] = b1 + c*b0*(1 -
    a^p)/(1 - a)`` and ``Gw[p] = b0*a^p``; by linear-programming duality, ``max G.u``
    subject to ``|Gw.u| <= slack`` and ``|u| <= 1`` equals ``min_l sum|G - l*Gw| +
    slack*|l|``, a weighted median: ``l`` is the weighted median of ``G/Gw`` (weights
    ``Gw``) together with 0 (weight ``slack``)."""
    if n <= 0:
        return 0.0
    p = np.arange(n, dtype=float)
    Gw = b0 * a ** p
    G = b1 + c * b0 * (-np.expm1(p * math.log(a))) / (1.0 - a)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(Gw > 0, G / Gw, math.inf)
    ratio = np.append(ratio, 0.0)
    weight = np.append(Gw, speed_slack)
    order = np.argsort(ratio, kind="stable")
    cumulative = np.cumsum(weight[order])
    median = ratio[order][min(int(np.searchsorted(cumulative, 0.5 * cumulative[-1])),
                              len(order) - 1)]
    if not math.isfinite(median):
        median = 0.0
    return float(np.sum(np.abs(G - median * Gw)) + speed_slack * abs(median))


def _least_samples(reach, distance: float, max_samples: int = 1 << 40) -> int:
    """The least n >= 0 with ``reach(n) >= distance`` (``reach`` nondecreasing, 0 at 0):
    doubling, then bisection; refused beyond ``max_samples`` (``reach(n)`` costs O(n):
    a drive that barely moves an axis made 2^40-element arrays, a hang)."""
    if distance <= 0:
        return 0
    hi = 1
    while reach(hi) < distance:
        hi *= 2
        if hi > 2 * max_samples:
            raise WorkLimitError(
                f"the drive moves {distance:g} pulse in no fewer than {max_samples:.3g} "
                "samples (the sample limit, --max-samples): it barely moves that axis")
    lo = hi // 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if reach(mid) >= distance:
            hi = mid
        else:
            lo = mid
    return hi


STILL_TANGENT = 1e-9
"""An axis whose component of the unit tangent on one side of a corner is at most this
[1] is still there (:func:`rest_corners`): a line along the other axes, drawn exactly."""

EXTENT_POINTS = 4097
"""Even parameters at which :func:`sampled_stop_bound` looks for the path's farthest
points, besides every breakpoint (any point of the path gives a valid bound; more only
tighten it)."""


def rest_corners(curve: NurbsCurve) -> np.ndarray:
    """The sharp corners at which a sampled motion that follows ``curve`` without cutting
    a corner is at rest at a sample instant: those where every axis is still on at least
    one side (it stops there for good or starts there from rest, as the die-bonder
    Pi's axes do), shape (n,) [curve parameter].

    Under a held drive (ZOH) an axis speed is monotone within a sample: an axis cannot
    come to rest between samples and stay, nor start from rest between them; so at such a
    corner the last axis arrives at a sample instant and the next starts at one no earlier
    (sooner cuts the corner). Where some axis moves on both sides, the motion need not
    rest at a sample instant: the axis passes the corner moving or reverses within a
    sample, and a sampled motion passes such a corner (a CAM chord joint, turning by a
    fraction of a degree) within a fraction of a pulse of it, as ``planned``'s does.
    The continuous motion of :func:`time_optimal_bound` and of ``planned``'s plan stops
    at every sharp corner (:meth:`NurbsCurve.sharp_corners`); these are the ones of them
    where the sampled motion stops too."""
    corners = curve.sharp_corners()
    if corners.size == 0:
        return corners
    left = np.abs(curve.tangent(corners, "left")) <= STILL_TANGENT
    right = np.abs(curve.tangent(corners, "right")) <= STILL_TANGENT
    return corners[np.all(left | right, axis=1)]


def _reach_time(distance: np.ndarray, tau: float, top_speed: float) -> np.ndarray:
    """The least time [s] in which an axis moves ``distance`` [pulse] from rest under
    ``|u| <= Umax``: under full drive, ``theta(t) = V (t - tau (1 - exp(-t/tau)))`` with
    ``V = Umax Kc Ke`` [pulse/s] ``top_speed`` (no drive moves it farther by any time).
    Found by bisection; the lower end is returned, so the time is never over-stated."""
    x = np.maximum(np.asarray(distance, dtype=float), 0.0) / top_speed  # [s]
    lo, hi = x, x + tau   # theta(t)/V lies in [t - tau, t]
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        below = mid + tau * np.expm1(-mid / tau) < x
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return lo


def _extent_time(curve: NurbsCurve, machine: Machine, window: float) -> float:
    """A lower bound [s] on the time of a motion from rest at the start to within
    ``window`` [pulse] of the end that passes within ``window`` of every point of
    ``curve``. Where a point q lies beyond the start and the end on an axis (not between
    them), the axis goes out at least as far as q (less the window), turns there (its
    speed is 0 at that instant) and comes back to the end: each leg from a speed of 0
    takes at least the full-drive time from rest (:func:`_reach_time`). Any axis also
    moves from its start to its end from rest. So a closed path gets the time to reach
    its farthest point and come back, where the corners alone give 0."""
    if not math.isfinite(machine.max_drive):
        return 0.0
    u = np.union1d(np.linspace(0.0, 1.0, EXTENT_POINTS), curve.breakpoints)
    points = curve(u)
    start, end = curve(0.0), curve(1.0)
    best = 0.0
    for j, (tau, kc, ke) in enumerate(zip(machine.tau, machine.Kc, machine.Ke)):
        top_speed = machine.max_drive * kc * ke
        beyond = (points[:, j] - start[j]) * (points[:, j] - end[j]) > 0
        q = points[beyond, j]
        out = _reach_time(np.abs(q - start[j]) - window, tau, top_speed)
        back = _reach_time(np.abs(q - end[j]) - 2.0 * window, tau, top_speed)
        through = _reach_time(np.abs(end[j] - start[j]) - window, tau, top_speed)
        best = max(best, float(np.max(out + back, initial=0.0)), float(through))
    return best


def sampled_stop_bound(curve: NurbsCurve, machine: Machine, *,
                       settle_window: float = 1.0, max_samples: int = 1 << 40) -> float:
    """A lower bound [s] on the move-and-settle time of any motion of the sampled loop along
    ``curve`` that does not cut its corners, within ``|u| <= Umax``.

    :func:`time_optimal_bound` lets the drive change at any instant; the loop's drive is
    held for a sample (ZOH). At a corner where every axis stops or starts
    (:func:`rest_corners`) the plant is at rest at a sample instant, so the motion takes
    a whole number of samples between such corners, each stretch at least
    what the slowest axis needs to move its displacement across it from rest to
    rest under ``|u| <= Umax`` (:func:`_rest_to_rest_reach`, exact for the ZOH plant of
    docs/model.md#servo-axis). The last stretch only has to end within ``settle_window`` of the end
    on each axis, and slow enough to be within it at the next sample too: a motor speed
    w moves the axis by at least ``c*|w| - b1*Umax`` over a sample, so ``|w| <= (2*window
    + b1*Umax)/c``. The whole motion also takes at least the time to reach the path's
    farthest points and come back (:func:`_extent_time`: a closed path gets more than 0),
    in whole samples.
    The feed is ignored (it only lengthens a motion), so this is a bound, not a plan: no
    interpolator beats it while it keeps the drive within Umax and passes within the
    settle window of the path. (An interpolator whose setpoint of
    sample 0 is the start, :func:`nurbsmotion.stepping.first_sample`, takes a sample
    more: its first drive u[0] is 0.)

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        tau, Kc, Ke, Umax, Ts.
    settle_window : float
        Radius [pulse] of the settle window (as :func:`nurbsmotion.metrics.settle_time`).
    max_samples : int
        A piece needing more samples than this is refused (:class:`WorkLimitError`).

    Returns
    -------
    float
        The bound [s], a whole number of samples.
    """
    if not (math.isfinite(settle_window) and settle_window >= 0):
        raise InvalidArgumentError(f"settle_window must be finite and >= 0, got "
                                   f"{settle_window!r}")
    Ts, umax = machine.sample_period, machine.max_drive
    ends = np.concatenate([[0.0], rest_corners(curve), [1.0]])
    stops = curve(ends)
    axes = list(zip(*zoh_coefficients(machine.tau, machine.Kc, machine.Ke, Ts)))
    samples = 0
    for k in range(len(ends) - 1):
        last = k == len(ends) - 2
        need = 0
        for j, (a, b0, c, b1) in enumerate(axes):
            distance = abs(stops[k + 1, j] - stops[k, j]) - (settle_window if last else 0.0)
            if not math.isfinite(umax):  # any distance in two samples (one if not at rest)
                need = max(need, (1 if last else 2) if distance > 0 else 0)
                continue
            slack = (2.0 * settle_window / umax + b1) / c if last else 0.0
            need = max(need, _least_samples(
                lambda n: umax * _rest_to_rest_reach(a, b0, c, b1, n, slack), distance,
                max_samples))
        samples += need
    extent = _extent_time(curve, machine, settle_window) / Ts  # [samples]
    if not extent <= max_samples:  # inf where an axis barely moves (Ke = 1e-300)
        raise WorkLimitError(
            f"the path's extent takes at least {extent:.3g} samples at full drive, more than "
            f"the sample limit of {max_samples:.3g} (--max-samples): the drive barely moves "
            "an axis")
    # whole samples, never rounded up past the time itself (a lower bound)
    return max(samples, math.ceil(extent * (1.0 - 1e-12))) * Ts


def time_optimal_bound(curve: NurbsCurve, machine: Machine, feed: float, *,
                       grid_size: int = 20_000) -> float:
    """The least time to traverse ``curve`` at rest at both ends (docs/model.md#run-figures) [s].

    Under ``|tau_j*xdd_j + xd_j| <= Umax*Kc_j*Ke_j`` on every axis (the feedforward drive
    of a perfectly tracked motion), ``V <= feed`` and ``V = 0`` at sharp corners; computed
    by forward/backward phase-plane integration (:func:`speed_profile`). The discretised
    value converges from above as ``grid_size`` grows; at the default it is within about
    0.1 % of the limit on the benchmarks.

    Parameters
    ----------
    curve : NurbsCurve
        The path, in any unit the machine knows (one drawn in a length unit is converted
        to pulses by :class:`nurbsmotion.units.Scale`, as :func:`nurbsmotion.loop.run`
        does).
    machine : Machine
    feed : float or str or FeedLimit
        F: a bare number in the path's units per second ([pulse/s] for a path in pulses),
        a text with a unit (``"0.5m/s"``), or a piecewise limit ``V <= F(u)`` [path
        units/s].
    grid_size : int
        Arc-length grid points over the path (refined in short knot spans, see
        :func:`speed_profile`).

    Raises
    ------
    InvalidFeedError
        If the feed is not finite and > 0.
    InfeasibleError
        If the drive cannot move along the path, the path needs more than
        :data:`MAX_GRID_POINTS` grid points, or the bound is not a finite time (a feed of
        1e-320).
    """
    curve, feed = in_pulses(curve, machine, feed)
    F = _check_feed(feed)
    check_path_size(curve)  # before the arc-length tables
    if machine.max_drive == math.inf or not math.isfinite(curve.length / F):
        # a lower bound; not finite: refused below, at once
        bound = feed.duration(curve) if isinstance(feed, FeedLimit) else curve.length / F
    else:
        bound = speed_profile(curve, machine, feed, grid_size=grid_size).duration
    if not (math.isfinite(bound) and bound > 0):
        raise InfeasibleError(
            f"the time-optimal bound is not a finite time ({bound!r} s) for a "
            f"{curve.length:.6g}-pulse path at {F!r} pulse/s: the feed is too small (or the "
            "path too long) for double precision")
    return bound
