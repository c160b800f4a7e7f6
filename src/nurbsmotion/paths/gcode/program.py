"""What :func:`~nurbsmotion.paths.gcode.load_gcode` returns: the program's contours, each a
joined path with the programmed feed of its pieces, and the warning class its reader issues.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...feed import FeedLimit
from ...nurbs import NurbsCurve

__all__ = ["GcodeWarning", "GcodeContour", "GcodeProgram"]


class GcodeWarning(UserWarning):
    """Something in a G-code program was read in a documented but noteworthy way."""


@dataclass(frozen=True)
class GcodeContour:
    """One contour of a program: a path and the programmed feed of each of its pieces.

    Attributes
    ----------
    curve : NurbsCurve
        The joined path [program units].
    piece_edges : ndarray, shape (n_pieces + 1,)
        Curve parameter where each piece starts; the last entry is 1.
    programmed_feed : ndarray, shape (n_pieces,)
        F in force for each piece [program units / min].
    lines : tuple of int, length n_pieces
        Source line of each piece (the opening line for a G5.2 or G06.2 block).
    """

    curve: NurbsCurve
    piece_edges: np.ndarray
    programmed_feed: np.ndarray
    lines: tuple

    @property
    def feed(self) -> np.ndarray:
        """Programmed feed of each piece [program units / s], shape (n_pieces,)."""
        return self.programmed_feed / 60.0

    @property
    def feed_limit(self) -> FeedLimit:
        """The programmed feed as a :class:`~nurbsmotion.feed.FeedLimit` [program units / s]
        (pieces whose edges coincide to rounding merged, keeping the lower feed)."""
        edges, feed = np.asarray(self.piece_edges, float), self.feed
        keep = np.concatenate([[True], np.diff(edges) > 0])
        keep[-1] = True
        idx = np.flatnonzero(keep)
        speeds = np.minimum.reduceat(feed, idx[:-1]) if len(idx) > 1 else feed[:1]
        return FeedLimit(edges[idx], speeds[: len(idx) - 1])

    def feed_at(self, u) -> np.ndarray:
        """Programmed feed [program units / s] of the piece containing each ``u`` in
        ``[0, 1]`` (the later piece at a junction), shape of ``u``."""
        uu = np.asarray(u, dtype=float)
        i = np.searchsorted(self.piece_edges, uu, side="right") - 1
        return self.feed[np.clip(i, 0, len(self.feed) - 1)]


@dataclass(frozen=True)
class GcodeProgram:
    """What :func:`load_gcode` read.

    Attributes
    ----------
    contours : tuple of GcodeContour
        In program order.
    units : str
        ``"mm"`` or ``"inch"``: the unit of the first G20/G21 (mm if there is none);
        numbers read in the other unit are converted.
    source : str
        The file name.
    warnings : tuple of str
        The :class:`GcodeWarning` messages issued while reading.
    axes : str
        The path axes the contours have, in their column order (e.g. ``"XYZ"``).
    units_source : str
        Where ``units`` came from (``"G21 on line 3"``, or that it was assumed).
    rapids_only : bool
        The program has no feed move: its rapids are the contours, with no programmed
        feed (``programmed_feed`` NaN), as LinuxCNC's trajectory-planner tests of rapids
        are run.
    called_files : tuple of (int, int, str, int)
        For each file ``o<name> call`` ran: its lines are the program's lines ``first + 1``
        to ``end`` (numbered after the program's own, as in ``GcodeContour.lines``), its
        file name, and the line of the file that ``first + 1`` is, less one
        (:meth:`source_line` reads it).
    """

    contours: tuple
    units: str
    source: str
    warnings: tuple = field(default=())
    axes: str = "XY"
    units_source: str = ""
    rapids_only: bool = False
    called_files: tuple = ()

    def source_line(self, line: int) -> tuple[str, int]:
        """The file and its own line of ``line``, a line number of
        ``GcodeContour.lines`` or of the reader (the program's own lines, then those of
        the files it calls)."""
        return _source_line(self.called_files, self.source, line)


def _source_line(called: tuple, source: str, line: int) -> tuple[str, int]:
    """The file and its own line of the program's ``line``: ``called`` holds, for each
    called file, (first, end, file, first in the file) as :func:`_subroutine_files`
    returns its parts (program lines first < line <= end are that file's)."""
    for a, b, file, begin in called:
        if a < line <= b:
            return file, line - a + begin
    return source, line

