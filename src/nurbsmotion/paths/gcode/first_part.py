"""A G-code program's first lines, read by the reader itself, for a size limit checked
before the whole program is read (issue 37: every size limit checked where it is known).

A CAM program of a million G1 lines takes seconds to read whole, and a run refuses it
afterwards when its sharp corners exceed the planner's grid
(:func:`nurbsmotion.planning.check_corner_count`). :func:`read_first_part` reads only
its first lines with the same reader (:class:`~nurbsmotion.paths.gcode.reader._Reader`
on a :class:`~nurbsmotion.paths.gcode.ngc.Program` of those lines: one parser, one motion
layer), keeping each contour's pieces as read (not joined), and
:meth:`FirstPart.corners` counts the sharp corners those pieces *provably* keep in the
path a run plans, so that a refusal needs only them.

When the first lines are a first part of the program's execution
    Only when they hold no O-word (no subroutine, call, condition or loop: a jump could
    leave them, or repeat them, and a call may read a subroutine defined further on or in
    another file): then the program runs them in order, exactly as the whole program
    does, and every piece they add to a contour is one of the whole program's, in the
    same place. Pieces are only ever appended to a contour: cutter compensation (G41/G42)
    holds back the last move until the next one is known, and changes only that held move
    (LinuxCNC's queue), never a piece already added; an open G5.2/G6.2 block or a held
    move adds nothing until it closes. A contour ended within the first lines (a rapid, a
    move of another axis) is whole. The reading is given up (None: the whole program is
    read, which names its own error) at an O-word, at any error in the first lines
    (an error further on is then not the first reported: the size refusal comes first),
    on rotary path axes (a run rescales them), where the first lines would be more than
    half the program, and where a piece is so short that the joined path's knots could
    merge (below ``1e-9`` of the length before it).

What the count is
    A lower bound of the sharp corners of the contour as a run plans it (its chord runs
    joined within the path tolerance, :func:`nurbsmotion.chords.join_chords`): for each
    run of consecutive line pieces, :func:`nurbsmotion.chords.polyline_corners` of its
    vertices as the first vertices of a longer path (its last vertex's next piece is not
    known: a line beyond the first lines, or an arc or spline that may be straight enough
    to join the chords), less one where an arc or spline comes before it (its first
    vertex's previous piece is not known either: only that vertex's count depends on it).
    Joints at arcs and splines are not counted, feeds are taken as equal everywhere (a
    feed change only makes a corner), so the count never exceeds the whole program's.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import NurbsmotionError
from .codes import _NeedAxes
from .ngc import Program, Rows, split_lines

__all__ = ["FirstPart", "read_first_part", "FIRST_PART_MARGIN"]

FIRST_PART_MARGIN = 64
"""Lines read beyond the pieces asked for: a program's header (units, modes, the first
rapid and feed) before its moves [lines]."""

_SHORT_PIECE = 1e-9
"""A piece shorter than this times the contour's length before it may share its knot with
its neighbour once the contour is joined (its parameter share rounds away): such a first
part is not counted."""


@dataclass(frozen=True)
class FirstPart:
    """The first lines of a G-code program as the reader reads them.

    Attributes
    ----------
    source : str
        The program file.
    lines : int
        Lines of text read.
    units : str or None
        The program's units once G20/G21 (or a first move) set them, else None.
    n_axes : int
        Path axes (columns of every contour).
    contours : tuple of PieceChain
        The pieces of each contour begun in those lines, in order [path units]; the last
        may go on beyond them.
    contour : int or None
        The contour a run takes (1-based, ``FILE#k``), None: the program's only one.
    ended : bool
        Whether the program ended within those lines (M2, M30).
    """

    source: str
    lines: int
    units: str | None
    n_axes: int
    contours: tuple
    contour: int | None
    ended: bool

    def _chosen(self):
        k = 1 if self.contour is None else self.contour
        return self.contours[k - 1] if 1 <= k <= len(self.contours) else None

    @property
    def pieces(self) -> int:
        """Pieces of the chosen contour read."""
        chain = self._chosen()
        return 0 if chain is None else len(chain)

    def corners(self, tolerance: float, factor: float = 1.0) -> tuple[int, str]:
        """At least how many sharp corners the chosen contour keeps once its chord runs
        are joined within ``tolerance`` (see the module docstring), and where they were
        counted, for :func:`nurbsmotion.planning.check_corner_count`.

        Parameters
        ----------
        tolerance : float
            The chord join's tolerance [path units], >= 0.
        factor : float
            Pulses per path unit (the planner's path is the contour times ``factor``).

        Returns
        -------
        corners : int
        counted_in : str
            ``"its first 98,106 lines"`` (with ``", contour #2"`` for a chosen contour).
        """
        from ...chords import polyline_corners

        where = f"its first {self.lines:,} lines" + (
            "" if self.contour is None else f", contour #{self.contour}")
        chain = self._chosen()
        if chain is None or len(chain) < 3:
            return 0, where
        kind = np.frombuffer(chain.kind, dtype=np.int8)
        V = np.vstack([np.array(chain.start)[None, :],
                       np.frombuffer(chain.ends, dtype=float).reshape(len(kind), self.n_axes)])
        line = np.concatenate([[0], (kind == 0).astype(np.int8), [0]])
        starts = np.flatnonzero(np.diff(line) == 1)
        stops = np.flatnonzero(np.diff(line) == -1)
        total = 0
        for a, b in zip(starts.tolist(), stops.tolist()):  # line pieces a .. b - 1
            after_other = a > 0
            if b - a < 3 + after_other:  # no vertex counted
                continue
            with np.errstate(invalid="ignore", divide="ignore"):
                c, _ = polyline_corners(V[a:b + 1], tolerance, factor, whole=False)
            total += max(c - after_other, 0)
        return total, where


def read_first_part(file: str | os.PathLike, axes: str, pieces: int, *, contour: int | None = None,
                    project: bool = False, tool_table: dict | None = None,
                    table_scale: float | None = None) -> FirstPart | None:
    """The first lines of a program that hold ``pieces`` pieces of its contour (or its
    end), read by the reader itself; None where they are not provably a first part of the
    program's execution or would be more than half of it (module docstring).

    Starts with ``pieces + FIRST_PART_MARGIN`` lines and, while the contour has fewer
    pieces, reads again as many lines as the pieces per line read ask for (at least twice
    as many), up to half the program.

    Parameters
    ----------
    file : str or path-like
        The program.
    axes : str
        The path axes (``"xy"``, ``"xyz"``), as :func:`~nurbsmotion.paths.gcode.load_gcode`.
    pieces : int
        Pieces of the contour wanted.
    contour : int, optional
        The contour a run takes (``FILE#k``, 1-based); None: the program's only one (None
        is returned where the first lines already hold two: the run names them all).
    project : bool
        As :func:`~nurbsmotion.paths.gcode.load_gcode`.
    tool_table : dict, optional
        Tool diameters (:func:`~nurbsmotion.paths.gcode.compensation.read_tool_table`).
    table_scale : float, optional
        Output units per table unit, None: the program's.

    Returns
    -------
    FirstPart or None
    """
    path = Path(file)
    axes = str(axes).upper()
    if any(a in "ABC" for a in axes):  # a run rescales rotary axes: other angles
        return None
    try:
        size = path.stat().st_size
        f = open(path, "rb")
    except OSError:
        return None
    want = pieces + FIRST_PART_MARGIN
    with f:
        head = b""
        while True:
            while True:  # the bytes of the first `want` lines
                ends = np.flatnonzero(np.frombuffer(head, dtype=np.uint8) == 10)
                if ends.size >= want or len(head) >= size:
                    break
                more = f.read(max(64 * want + 4096, len(head)))
                if not more:
                    break
                head += more
            if ends.size < want:
                return None  # fewer lines: the program is its first part
            cut = int(ends[want - 1]) + 1
            if 2 * cut > size:
                return None  # most of the program: read it whole
            part = _read(path, head[:cut], axes, contour, project, tool_table, table_scale)
            if part is None or part.ended or part.pieces >= pieces or (contour or 1) < len(part.contours):
                return part  # (a contour before the last is whole)
            # as many more lines as the pieces read per line ask for (at least twice as
            # many): one more read, or none where that is more than half the program
            want = max(2 * want, want * pieces // max(part.pieces, 1) * 11 // 10 + 1)


def _read(path: Path, data: bytes, axes: str, contour, project, tool_table, table_scale):
    """The first part ``data`` (whole lines of the program) read, or None (module
    docstring)."""
    from .reader import _Reader

    source = str(path)
    reader = _Reader(source, axes, tool_table, table_scale)
    reader.project, reader.first_part = project, True
    ended = False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the whole program's read says them
        try:
            lines = split_lines(data, source, upper=True)
            program = Program(lines, source, reader.system_parameter)
            if program.olabels:
                return None
            reader.program = program
            for item in program.blocks(runs=True):
                if not (reader.read_rows(item) if isinstance(item, Rows) else reader.read(item)):
                    ended = True
                    break
            ended = ended or program.stop < len(lines)  # a closing %: the rest is not run
        except (NurbsmotionError, _NeedAxes):
            return None
    chains = list(reader.contours) + ([reader.chain] if reader.chain is not None else [])
    if contour is None and len(chains) > 1:
        return None  # the run asks which contour (FILE#k)
    for chain in chains:
        lengths = np.frombuffer(chain.lengths, dtype=float)
        if np.any(lengths[1:] <= _SHORT_PIECE * np.cumsum(lengths)[:-1]):
            return None
    return FirstPart(source, len(lines), reader.units, len(reader.axes), tuple(chains), contour,
                     ended)
