"""What a run of a named path on a machine reads: the contour and the feed, by one rule.

``nurbsmotion run`` and a study's cases (:mod:`nurbsmotion.study`) both call these
functions, so a path in mm, inches or pulses, a G-code program with its F words and a DXF
drawing are read, and their feeds converted to the machine's pulse/s, the same way
whichever of the two runs them.

Rotary axes
    A path that moves a rotary axis (G-code A, B, C, in degrees) runs on a machine whose
    axis of that name gives ``pulses_per_degree`` (:class:`nurbsmotion.machine.Axis`):
    :func:`load_run_contour` rescales the rotary columns so that one pulse is the same
    step on every axis (a degree becomes ``pulses_per_degree / pulses per path unit``
    path units) and the whole run, which has one scale, runs the machine's own pulses.
    The programmed feed follows LinuxCNC's rule (:data:`FEED_GROUPS`): on each piece F is
    the speed of the X, Y, Z axes if any of them moves, else of U, V, W, else of the
    rotary axes [deg/s]; the others start and stop with them. So the feed along the
    rescaled path is F times the ratio of the piece's length on the rescaled path to its
    length in the group F applies to (:func:`feed_ratio`), and ``--feed`` caps F the same
    way. Inverse-time feed (G93) gives the move's duration, which no rescaling changes.

Glossary
--------
F : commanded feed [pulse/s]; scale : pulses (or target units) per path unit;
r : feed ratio, path length per length of the feed's axis group [1].
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import InvalidArgumentError, InvalidFeedError
from ..feed import FeedLimit
from ..machine import Machine
from .. import units

__all__ = ["path_axes", "load_run_contour", "join_run_chords", "programmed_feed", "run_feed",
           "feed_ratio", "FEED_GROUPS"]

FEED_GROUPS = ("XYZ", "UVW", "ABC")
"""LinuxCNC's feed rule (G-code manual, "Machining center", section Feed Rate): if any of
XYZ moves, F is in units per minute in the XYZ system and every other axis moves so as to
start and stop with them; otherwise if any of UVW moves, in the UVW system; otherwise the
move is purely rotary and F is in degrees per minute in the ABC 'pseudo-cartesian' system."""

_GAUSS_POINTS = 16
"""Gauss-Legendre points per knot span of a piece for :func:`feed_ratio` (a span of the
joined path is one polynomial or rational piece of low degree: exact to rounding for
lines, below 1e-12 relative for arcs and the cubic helix segments)."""


def path_axes(machine: Machine | None) -> str:
    """The axes a G-code or DXF file is read on for ``machine``: its axis names when each
    is one G-code axis letter (``"xy"``, ``"xyz"``), else ``"xy"`` (also without a
    machine)."""
    names = [a.lower() for a in machine.axis_names] if machine is not None else ["x", "y"]
    return "".join(names) if all(len(a) == 1 and a in "xyzabcuvw" for a in names) else "xy"


def load_run_contour(spec: str, machine: Machine | None = None, *, units: str | None = None,
                     project: str | None = None, path_tolerance=None, tool_table=None,
                     size_check=None):
    """The path ``spec`` names (a built-in name or a file, ``FILE#k`` for a contour) with
    its programmed feed, read on ``machine``'s axes (:func:`path_axes`).

    ``project`` (``--project``), if given, must name those axes: a G-code file's moves are
    then read as their projection on them instead of refused where they change other axes.

    With a machine, every run of short chords (CAM output) is joined into one smooth curve
    within ``path_tolerance`` of the chords (:func:`nurbsmotion.chords.join_chords`); real
    corners stay. This is where a path file enters a run, so ``run``, ``bound`` and
    ``bound --sampled`` plan the same path.

    Parameters
    ----------
    tool_table : str or path-like, optional
        ``--tool-table``: a LinuxCNC tool table a G-code program's cutter radius
        compensation takes its tools' diameters from (in the program's units).
    path_tolerance : str or float, optional
        ``--path-tolerance`` as given: a length (``"2um"``) or a bare number of pulses;
        default :data:`nurbsmotion.limits.DEFAULT_PATH_TOLERANCE` (one
        pulse); 0 joins nothing.
    size_check : callable, optional
        ``size_check(degree, spans)``: what the command can plan, checked as a large file
        is read (:func:`nurbsmotion.paths.load_contours`). Given, a large degree-1 JSON or
        TOML file also has its sharp corners as the run plans them (its chord runs joined
        at the default ``path_tolerance``) counted from its first vertices against the
        planner's grid (:func:`nurbsmotion.planning.check_corner_count`): exactly where
        nothing is joined, else at least those between pieces that stay chords
        (:func:`nurbsmotion.chords.polyline_corners`); so has a G-code program, from its
        first lines where they are provably the first part of its execution (at least
        those its runs of lines keep, :mod:`nurbsmotion.paths.gcode.first_part`).

    Returns
    -------
    Contour
        :class:`nurbsmotion.paths.Contour`; its ``joined`` says what was joined (None
        without a machine).

    Raises
    ------
    PathFileError
        Naming the file, if it cannot be read.
    InvalidArgumentError
        If ``project`` does not name the machine's axes, or the path moves a rotary axis
        the machine gives no ``pulses_per_degree`` for.
    """
    from ..paths import resolve_contour

    axes = path_axes(machine)
    if project is not None and project.lower() != axes:
        raise InvalidArgumentError(f"--project {project} must name the machine's axes ({axes}): "
                                   "the path is read as its projection on them")
    polyline_check = None
    if size_check is not None and machine is not None and path_tolerance is None:
        polyline_check = _polyline_check(machine, units)
    contour = resolve_contour(spec, axes=axes, units=units, project=project is not None,
                              tool_table=tool_table, size_check=size_check,
                              polyline_check=polyline_check)
    rotary = [j for j, a in enumerate(contour.axes or "") if a in "ABC"]
    if rotary:
        contour = _on_rotary_axes(contour, machine, rotary, spec)
    elif contour.feed is not None and sum(
            any(a in g for a in contour.axes or "") for g in FEED_GROUPS) > 1:
        # XYZ with UVW: F is the speed of XYZ where they move (LinuxCNC's rule)
        contour = replace(contour, feed_ratio=feed_ratio(
            contour.curve, np.ones(contour.curve.n_axes), contour.axes, contour.feed.breakpoints))
    if machine is None:
        return contour
    return join_run_chords(contour, machine, path_tolerance)


def _polyline_check(machine: Machine, units: str | None):
    """``polyline_check(rows, file_units)`` of :func:`load_run_contour` (see
    there): the path read in ``units`` (else the file's, else mm as the reader assumes)
    on ``machine``, joined at :data:`DEFAULT_PATH_TOLERANCE` as
    :func:`join_run_chords` joins it."""
    def check(rows, file_units: str | None) -> None:
        from ..chords import polyline_corners
        from ..limits import DEFAULT_PATH_TOLERANCE, PATH_UNITS
        from ..planning import check_corner_count, most_corners

        # enough vertices to hold one corner more than the planner's grid can
        read = rows(most_corners() + 4)  # the ends, and a last vertex whose next piece is unread
        if read is None:
            return  # the parser says what is wrong
        gcode = not isinstance(read, tuple)  # a G-code program's first part (FirstPart)
        unit = units or (read.units if gcode else file_units) or "mm"
        if unit not in PATH_UNITS or (read.n_axes if gcode else read[0].shape[1]) != machine.n_axes:
            return  # the reader, or the machine's axis check, says what is wrong
        per_unit = machine.pulses_per_unit(unit)  # [pulse/path unit], as Scale.factor
        if gcode:
            check_corner_count(*read.corners(DEFAULT_PATH_TOLERANCE / per_unit, per_unit))
            return
        points, whole = read
        corners, exact = polyline_corners(points, DEFAULT_PATH_TOLERANCE / per_unit,
                                          per_unit, whole=whole)
        check_corner_count(corners, None if exact else f"its first {points.shape[0]:,} points")

    return check


def join_run_chords(contour, machine: Machine, path_tolerance=None):
    """``contour`` with its chord runs joined within ``path_tolerance`` (as
    :func:`load_run_contour`), its ``joined`` set.

    Raises
    ------
    InvalidArgumentError
        If ``path_tolerance`` is not a length >= 0 below the path's extent (the diagonal
        of its bounding box).
    """
    from ..chords import ChordJoin, join_chords
    from ..limits import DEFAULT_PATH_TOLERANCE

    import math

    curve = contour.curve
    scale = units.Scale.of(curve, machine)
    tol = DEFAULT_PATH_TOLERANCE if path_tolerance is None else scale.length(
        path_tolerance, "--path-tolerance", bare_unit="pulse")
    per_unit = scale.factor  # [pulse/path unit]
    # the extent only where a tolerance was given (the exact bounding box of a
    # million-span spline costs a minute)
    if path_tolerance is not None and tol > 0 and tol >= (
            extent := math.dist(*curve.bounding_box()) * per_unit):  # [pulse]
        # the run (and planned's short moves) could leave the whole path (1e300 overflowed)
        raise InvalidArgumentError(
            f"--path-tolerance {path_tolerance} ({tol:g} pulse) is not below the path's "
            f"extent (its bounding box's diagonal, {extent:.6g} pulse)")
    tol /= per_unit  # [path units]
    if contour.feed_ratio is not None:  # LinuxCNC's feed rule is per programmed piece: kept
        return replace(contour, joined=ChordJoin(curve, contour.feed, tol))
    joined = join_chords(curve, tol, contour.feed)
    return replace(contour, curve=joined.curve, feed=joined.feed, joined=joined)


def _on_rotary_axes(contour, machine: Machine | None, rotary: list, spec: str):
    """``contour`` with its rotary columns [deg] rescaled to the machine's pulses per
    degree (in path units, see the module docstring) and its programmed feed along the
    rescaled path by LinuxCNC's rule (``feed_ratio`` of the result: None where there is no
    programmed feed)."""
    from ..nurbs import NurbsCurve

    names = [contour.axes[j] for j in rotary]
    missing = [n for j, n in zip(rotary, names)
               if machine is None or machine.axes[j].pulses_per_degree is None]
    if missing:
        on = "the default machine" if machine is None else f"machine {machine.name!r}"
        raise InvalidArgumentError(
            f"the path moves the rotary axis {', '.join(missing)} [deg], but {on} gives no "
            f"pulses_per_degree for it: give its [[axes]] table 'pulses_per_degree' [pulse/deg] "
            f"(docs/formats.md), or list the contours with 'nurbsmotion contours {spec}'")
    curve = contour.curve
    factor = np.ones(curve.n_axes)  # path units per file unit of each column
    factor[rotary] = [machine.axes[j].pulses_per_degree for j in rotary]
    factor[rotary] /= machine.pulses_per_unit(curve.units)
    scaled = NurbsCurve(curve.degree, curve.knots, curve.control_points * factor, curve.weights,
                        name=curve.name, units=curve.units)
    ratio = None if contour.feed is None else feed_ratio(
        scaled, factor, contour.axes, contour.feed.breakpoints)
    return replace(contour, curve=scaled, feed_ratio=ratio)


def feed_ratio(curve, factor, axes: str, breakpoints) -> np.ndarray:
    """Per piece, the length of ``curve`` over it divided by the length of the axis group
    the programmed feed applies to (:data:`FEED_GROUPS`), in the file's units.

    Parameters
    ----------
    curve : NurbsCurve
        The path as it runs, each column the file's times ``factor``.
    factor : ndarray, shape (n_axes,)
        Path units per file unit of each column (1 for a length, path units per degree
        for a rotary axis).
    axes : str
        The file's axis letter of each column (``"XYZA"``).
    breakpoints : ndarray, shape (n_pieces + 1,)
        Where each piece starts in the curve parameter; the last entry is 1.

    Returns
    -------
    ndarray, shape (n_pieces,)
        r >= 1 [1]: the feed along ``curve`` is F r, so that each piece takes as long as
        it takes LinuxCNC.
    """
    axes = axes.upper()
    b = np.asarray(breakpoints, dtype=float)
    knots = np.unique(curve.knots)
    x, w = np.polynomial.legendre.leggauss(_GAUSS_POINTS)
    groups = [[j for j, a in enumerate(axes) if a in g] for g in FEED_GROUPS]
    ratio = np.empty(len(b) - 1)
    for k in range(len(b) - 1):
        edges = np.concatenate([[b[k]], knots[(knots > b[k]) & (knots < b[k + 1])], [b[k + 1]]])
        mid, half = (edges[1:] + edges[:-1]) / 2, (edges[1:] - edges[:-1]) / 2
        u = (mid[:, None] + half[:, None] * x[None, :]).ravel()
        weight = (half[:, None] * w[None, :]).ravel()
        derivative = curve(u, 1)
        total = weight @ np.linalg.norm(derivative, axis=1)
        d = derivative / factor  # in the file's units (mm, deg) per column
        for cols in groups:
            length = weight @ np.linalg.norm(d[:, cols], axis=1) if cols else 0.0
            if length > 1e-12 * total:
                break
        ratio[k] = total / length if length > 0 else 1.0
    return ratio


def programmed_feed(cap, programmed: FeedLimit | None, scale: float, source: str = "the path",
                    ratio=None):
    """The feed a command runs at, from the user's feed and the file's programmed one.

    Where the file gives a feed (G-code F), it is the limit along the path and ``cap``
    lowers it piece by piece; where it gives none, ``cap`` is the feed and is required.

    Parameters
    ----------
    cap : float or None
        The user's feed in the target unit (e.g. [pulse/s]); None if not given.
    programmed : FeedLimit or None
        The file's feed [path units/s].
    scale : float
        Target units per path unit (e.g. pulses per mm).
    source : str
        The path, for the message.
    ratio : ndarray, shape (n_pieces,), optional
        Per piece of ``programmed``, the feed along the path per F (a path that moves a
        rotary axis, :func:`feed_ratio`); applied after ``cap``, which caps F.

    Returns
    -------
    float or FeedLimit
        [target units/s].

    Raises
    ------
    InvalidFeedError
        If neither gives a feed.
    """
    if programmed is None:
        if cap is None:
            raise InvalidFeedError(f"--feed is required: {source} gives no programmed feed")
        return cap
    limit = programmed.scaled(scale)
    limit = limit if cap is None else limit.capped(cap)
    return limit if ratio is None else FeedLimit(limit.breakpoints, limit.speeds * ratio)


def run_feed(feed, contour, machine: Machine):
    """The feed a closed-loop run of ``contour`` on ``machine`` runs at [pulse/s].

    Parameters
    ----------
    feed : float or str or tuple or None
        The user's feed as :meth:`nurbsmotion.units.Scale.feed` reads it (a bare
        number in the path's units per second, ``"50mm/s"``, ...); None to run at the
        file's programmed feed.
    contour : Contour
        The path and its programmed feed (:func:`load_run_contour`).
    machine : Machine

    Returns
    -------
    float or FeedLimit
        Commanded feed F [pulse/s], per piece where the file programs one.
    """
    scale = units.Scale.of(contour.curve, machine)
    cap = None if feed is None else scale.feed(feed)
    return programmed_feed(cap, contour.feed, scale.factor, contour.source,
                           contour.feed_ratio)
