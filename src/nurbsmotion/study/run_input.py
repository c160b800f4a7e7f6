"""What a run of a named path on a machine reads: the contour and the feed, by one rule.

``nurbsmotion run`` and a study's cases (:mod:`nurbsmotion.study`) both call these
functions, so a path in mm, inches or pulses, a G-code program with its F words and a DXF
drawing are read, and their feeds converted to the machine's pulse/s, the same way
whichever of the two runs them.

Glossary
--------
F : commanded feed [pulse/s]; scale : pulses (or target units) per path unit.
"""

from __future__ import annotations

import dataclasses

from ..errors import InvalidArgumentError, InvalidFeedError
from ..feed import FeedLimit
from ..machine import Machine
from .. import units
from ..interpolators.planned.shorten import DEFAULT_PATH_TOLERANCE

__all__ = ["path_axes", "load_run_contour", "join_run_chords", "programmed_feed", "run_feed"]


def path_axes(machine: Machine | None) -> str:
    """The axes a G-code or DXF file is read on for ``machine``: its axis names when each
    is one G-code axis letter (``"xy"``, ``"xyz"``), else ``"xy"`` (also without a
    machine)."""
    names = [a.lower() for a in machine.axis_names] if machine is not None else ["x", "y"]
    return "".join(names) if all(len(a) == 1 and a in "xyzabcuvw" for a in names) else "xy"


def load_run_contour(spec: str, machine: Machine | None = None, *, units: str | None = None,
                     project: str | None = None, path_tolerance=None):
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
    path_tolerance : str or float, optional
        ``--path-tolerance`` as given: a length (``"2um"``) or a bare number of pulses;
        default :data:`nurbsmotion.motion_plan.DEFAULT_PATH_TOLERANCE` (one
        pulse); 0 joins nothing.

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
        If ``project`` does not name the machine's axes, or the path moves a rotary axis.
    """
    from ..paths import resolve_contour

    axes = path_axes(machine)
    if project is not None and project.lower() != axes:
        raise InvalidArgumentError(f"--project {project} must name the machine's axes ({axes}): "
                                   "the path is read as its projection on them")
    contour = resolve_contour(spec, axes=axes, units=units, project=project is not None)
    rotary = sorted(set(contour.axes or "") & set("ABC"))
    if rotary:  # degrees would be scaled by the pulse length as if they were lengths
        raise InvalidArgumentError(
            f"the path moves the rotary axis {', '.join(rotary)} [deg]; running rotary axes is "
            "not supported yet (a machine has one pulse length, no pulses per degree): list "
            f"the contours with 'nurbsmotion contours {spec}'")
    if machine is None:
        return contour
    return join_run_chords(contour, machine, path_tolerance)


def join_run_chords(contour, machine: Machine, path_tolerance=None):
    """``contour`` with its chord runs joined within ``path_tolerance`` (as
    :func:`load_run_contour`), its ``joined`` set.

    Raises
    ------
    InvalidArgumentError
        If ``path_tolerance`` is not a length >= 0.
    """
    from ..chords import join_chords

    curve = contour.curve
    tol = DEFAULT_PATH_TOLERANCE if path_tolerance is None else units.length_in_pulses(
        path_tolerance, curve, machine, "--path-tolerance", bare_unit="pulse")
    joined = join_chords(curve, tol / machine.pulses_per_unit(curve.units), contour.feed)
    return dataclasses.replace(contour, curve=joined.curve, feed=joined.feed, joined=joined)


def programmed_feed(cap, programmed: FeedLimit | None, scale: float, source: str = "the path"):
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
    return limit if cap is None else limit.capped(cap)


def run_feed(feed, contour, machine: Machine):
    """The feed a closed-loop run of ``contour`` on ``machine`` runs at [pulse/s].

    Parameters
    ----------
    feed : float or str or tuple or None
        The user's feed as :func:`nurbsmotion.units.feed_in_pulses` reads it (a bare
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
    curve = contour.curve
    cap = None if feed is None else units.feed_in_pulses(feed, curve, machine)
    return programmed_feed(cap, contour.feed, machine.pulses_per_unit(curve.units),
                           contour.source)
