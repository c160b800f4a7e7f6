"""G-code import (LinuxCNC and Fanuc NURBS dialects) and G5.2 export of a path.

Reading
-------
:func:`load_gcode` reads the motion of a program along the path axes and returns a
:class:`GcodeProgram`: the *contours* it cuts, each one :class:`NurbsCurve` joined from
the program's feed moves (as :func:`nurbsmotion.joining.join` joins pieces, built in bulk
by :class:`~nurbsmotion.paths.pieces.PieceChain`), plus the programmed feed of every piece.

Size
    Plain lines (words and comments, as CAM posts write them) are tokenised for the whole
    program at once (:class:`~nurbsmotion.paths.ngc.WordTable`: one multi-line regular
    expression search, then numpy), and each run of them is applied in bulk where
    :meth:`_Reader.read` would take its lean path (G0/G1 moves and F words under G90/G94,
    no offsets): the same pieces, feeds, lines and errors as one line at a time. A move
    costs a few numbers until its contour is joined: a CAM program of a million lines
    loads in a few seconds and about half a gigabyte (``benchmarks/gcode_load.py``).

What is read
    The language (parameters, expressions, O-word subroutines and control flow) is
    executed by :mod:`nurbsmotion.paths.ngc`; this module turns the executed blocks into
    motion, in LinuxCNC's canonical coordinates (G5x + G92 offsets and the XY rotation of
    ``G10 L2 R`` applied, as AXIS draws them): ``G0`` and ``G1``; ``G2``/``G3`` in the
    G17/G18/G19 plane in centre format (incremental, or absolute under ``G90.1``) or radius
    format, with ``P`` turns, as exact rational arcs, as a helix (cubic segments within
    :data:`HELIX_TOLERANCE` of the radius, :func:`~nurbsmotion.paths.pieces.spiral_segments`)
    when another axis moves along, or as a spiral
    when the end radius differs from the start radius by more than :data:`HELIX_TOLERANCE`
    of it (and within LinuxCNC's tolerance); ``G5``
    and ``G5.1`` (XY); ``G5.2``/``G5.3`` and ``G6.2`` (``P`` order, ``Q`` method, ``K``
    knots, ``R`` weights; Fanuc ``G06.2`` alike) in the XY, YZ and ZX planes; ``F`` under
    ``G94`` (units per minute) or ``G93`` (inverse time); ``G20``/``G21``; ``G90``/``G91``;
    ``G53``; ``G54``-``G59.3``; ``G10 L2/L20``; ``G92``, ``G92.1``/``.2``/``.3``;
    ``G28``/``G30`` (a rapid through the given point to the stored home: a new contour);
    polar ``@``/``^``; the canned cycles ``G73``, ``G74``, ``G81``-``G89`` with ``G98``/``G99``,
    ``L`` repeats, incremental and polar positions, in the three planes, expanded into G0
    and G1 moves as LinuxCNC's ``interp_cycles.cc`` does (:meth:`_Reader.canned_cycle`:
    each feed move along the depth axis a piece of a contour, every rapid, reversal or
    dwell the end of one), ``G80``. Words that do not change the path are skipped, each
    kind reported once as a :class:`GcodeWarning` (one line). ``M2``/``M30`` end the
    program; ``G4`` (dwell) ends the contour. What would change the path but is not read
    (cutter compensation, the G76 threading cycle, spindle-synchronised motion, probing, UVW
    planes) is a :class:`PathFileError` naming the line.

Contours
    The machine's axes decide which coordinates form the path (``axes``, default
    ``"xy"``). A contour is a maximal run of feed moves of those axes; a rapid move, or a
    move of an axis outside the path, ends it. A feed move of an outside axis together with
    path axes (a helix on a 2-axis machine, a rotary axis) is refused, naming the machine
    that could follow it. :func:`nurbsmotion.paths.resolve_path` asks the user to pick one
    contour (``file.ngc#k``) when there are several, rather than guessing.

LinuxCNC G5.2 (2.9, read from ``interp_convert.cc`` and ``nurbs_additional_functions.cc``)
    The current position is the first control point; ``G5.2 P-`` without X/Y sets its
    weight (a first listed point equal to it repeats it: C'(0) = 0, kept as given). Every later point needs X, Y and a positive P. ``L`` sets the order only when
    ``L > 3`` (default 3, i.e. quadratic). The knot vector is implicit and open-uniform
    over integers: ``k`` zeros, ``1 .. n-k+1``, ``k`` times ``n-k+2`` for ``n + 1``
    control points of order ``k`` (``knot_vector_creator``). Under ``G91`` every control
    point is relative to the position *before the block*. Z words inside the block are
    ignored (with a warning). X/Y on the opening line without P: the manual says weight 1,
    the 2.9 interpreter stores -1; this reader follows the manual and warns. The feed is
    the one in force at ``G5.3``, where LinuxCNC issues the move.

Fanuc G06.2
    ``G06.2 P<order> K<knot> X.. Y.. R<weight> F..`` then one ``K X Y [R]`` block per
    control point and ``order`` blocks of ``K`` only; the knot count must equal control
    points + order and the first and last ``order`` knots must be equal (clamped ends).
    P defaults to 4, R to 1. Without X/Y in the first block the current position is the
    first control point; if given, it must be the current position.

Writing
-------
:func:`save_gcode` writes a path as a LinuxCNC program of ``G5.2`` blocks. Since a G5.2
knot vector is implicit and uniform, the path is split into its rational Bézier segments
(exactly representable: order ``p + 1``, ``p + 1`` points, knots ``0..0 1..1``); degree-1
paths are first elevated to 2, the lowest order G5.2 accepts. Reading the file back gives
the same geometry to 1e-9 of the path size (the numbers are written with 12 significant
digits relative to the path size).

Glossary
--------
k : NURBS order (degree + 1); n + 1 : number of control points; w : weight;
F : programmed feed [units/min]; feed : F / 60 [units/s].
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from array import array
from operator import itemgetter
from pathlib import Path

import numpy as np

from .._runtime.io import check_input_file, write_output
from ..errors import InvalidCurveError, PathFileError
from ..feed import FeedLimit
from ..joining import bezier_segments, elevate_degree
from ..nurbs import NurbsCurve
from .ngc import MAX_LINE_LENGTH, Program, Rows, split_lines
from .pieces import HELIX_TOLERANCE, PieceChain, arc_by_center, arc_sweep

__all__ = [
    "GcodeContour",
    "GcodeProgram",
    "GcodeWarning",
    "load_gcode",
    "save_gcode",
    "linuxcnc_knots",
    "format_number",
    "MAX_LINE_LENGTH",
]

_INCH = 25.4  # [mm / inch]


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
    """

    contours: tuple
    units: str
    source: str
    warnings: tuple = field(default=())
    axes: str = "XY"
    units_source: str = ""
    rapids_only: bool = False


def linuxcnc_knots(n_points: int, order: int) -> np.ndarray:
    """LinuxCNC's implicit G5.2 knot vector (``knot_vector_creator`` in
    ``nurbs_additional_functions.cc``): ``order`` zeros, ``1 .. n-order+1`` and ``order``
    times ``n-order+2``, with ``n = n_points - 1``; ``n_points + order`` entries."""
    n = n_points - 1
    return np.concatenate(
        [np.zeros(order), np.arange(1, n - order + 2), np.full(order, n - order + 2)]
    ).astype(float)


# ---------------------------------------------------------------------- reader
_AXES = "XYZABCUVW"
_AXIS_INDEX = {letter: i for i, letter in enumerate(_AXES)}
_PLANES = {17.0: (0, 1, 2, "I", "J"), 18.0: (2, 0, 1, "K", "I"), 19.0: (1, 2, 0, "J", "K")}
"""G17/G18/G19: (first axis, second axis, linear axis, first offset word, second offset
word), as LinuxCNC's convert_arc passes them (XZ is (Z, X): G2 is clockwise seen from +Y)."""
_MOTION = {0.0: "G0", 1.0: "G1", 2.0: "G2", 3.0: "G3", 5.0: "G5", 5.1: "G5.1",
           5.2: "G5.2", 5.3: "G5.3", 6.2: "G6.2", 80.0: "G80", 33.0: "G33", 33.1: "G33.1",
           **{float(g): f"G{g}" for g in (73, 74, 81, 82, 83, 84, 85, 86, 87, 88, 89)}}  # fmt: skip
_CYCLES = frozenset(f"G{g}" for g in (73, 74, 81, 82, 83, 84, 85, 86, 87, 88, 89))
"""The canned cycles read (LinuxCNC's ``convert_cycle``)."""
PECK_CLEARANCE_INCH = 0.010
"""How far G73 and G83 back off above the depth reached before the next peck [inch]
(LinuxCNC 2.9's ``G83_RAPID_DELTA``, the interpreter the tests compare with; later
versions default to 0.050 inch or 1 mm, set in the INI file or by a ``D`` word)."""
_COORD_SYSTEMS = {54.0: 1, 55.0: 2, 56.0: 3, 57.0: 4, 58.0: 5, 59.0: 6, 59.1: 7, 59.2: 8, 59.3: 9}
_SKIPPED_G = {
    4.0: "G4 dwell", 40.0: None, 43.0: "G43 tool length offset (not applied)",
    43.1: "G43.1 tool length offset (not applied)", 43.2: "G43.2 tool length offset (not applied)",
    49.0: None, 61.0: None, 61.1: None, 64.0: "G64 path blending tolerance",
    94.0: None, 96.0: "G96 constant surface speed", 97.0: "G97 spindle RPM mode",
    7.0: "G7 lathe diameter mode", 8.0: "G8 lathe radius mode",
    17.0: None, 18.0: None, 19.0: None,
}  # fmt: skip
_REFUSED_G = {
    41.0: "cutter radius compensation changes the path", 42.0: "cutter radius compensation changes the path",
    41.1: "cutter radius compensation changes the path", 42.1: "cutter radius compensation changes the path",
    17.1: "the UVW planes are not read", 18.1: "the UVW planes are not read", 19.1: "the UVW planes are not read",
    76.0: "the G76 threading cycle is not read (its passes follow the spindle, which the "
          "path cannot; write the passes as G33 or G1 moves)", 38.2: "probing is not read", 38.3: "probing is not read",
    38.4: "probing is not read", 38.5: "probing is not read",
}  # fmt: skip
_END_M = {2.0, 30.0}
_PLAIN_G = {(0.0,): "G0", (1.0,): "G1"}
_PLAIN_WORDS = frozenset(_AXES + "F")
_SKIPPED_WORDS = {"S": "S spindle speed", "T": "T tool number", "H": "H tool offset",
                  "D": "D cutter radius", "$": "$ spindle selector"}
_SKIPPED_M = {0.0: "M0 pause", 1.0: "M1 optional pause", 3.0: "M3/M4/M5 spindle",
              4.0: "M3/M4/M5 spindle", 5.0: "M3/M4/M5 spindle", 6.0: "M6 tool change",
              7.0: "M7/M8/M9 coolant", 8.0: "M7/M8/M9 coolant", 9.0: "M7/M8/M9 coolant",
              60.0: "M60 pallet change", 61.0: "M61 tool number"}  # fmt: skip
_SKIPPED_M_RANGES = ((48, 53, "M48-M53 override switches"), (62, 68, "M62-M68 digital/analog I/O"),
                     (70, 73, "M70-M73 modal state save/restore"), (100, 199, "M100-M199 user commands"))
_MOTION_WORDS = {kind: frozenset(_AXES + words) for kind, words in (
    ("G0", "@^"), ("G1", "@^"), ("G2", "IJKRP"), ("G3", "IJKRP"), ("G5", "IJPQ"), ("G5.1", "IJ"),
    ("G5.2", "PL"), ("G6.2", "PQKRL"), ("G80", ""), ("G33", "K"), ("G33.1", "KI"),
    *((cycle, "RLPQIJK@^") for cycle in _CYCLES))}
"""The words each motion mode reads: the axes X..W and its own (polar @ ^ for G0/G1)."""
MAX_COORDINATE = 1e9
"""Largest coordinate, centre offset or radius read [program units]: beyond it a path of
ordinary size cannot be computed to 1e-9 of its size in double precision."""
MAX_ARC_TURNS = 100
"""Most turns (``P``) a G2/G3 arc may have."""

def _g_name(value: float) -> str:
    return f"G{value:g}"


def _skipped_m(m: float) -> str | None:
    if m in _SKIPPED_M:
        return _SKIPPED_M[m]
    for lo, hi, name in _SKIPPED_M_RANGES:
        if lo <= m <= hi and m == int(m):
            return name
    return None


def _picker(indices: list):
    """``f(point) -> tuple`` of the point's entries at ``indices``."""
    if len(indices) == 1:
        i = indices[0]
        return lambda p: (p[i],)
    return itemgetter(*indices) if indices else (lambda p: ())


def _embed(curve: NurbsCurve, base: np.ndarray, cols: tuple) -> NurbsCurve:
    """A planar curve placed in ``len(base)`` dimensions: its two coordinates go to
    ``cols``, the others stay at ``base``."""
    P = np.repeat(base[None, :], curve.n_control_points, axis=0)
    P[:, list(cols)] = curve.control_points
    return NurbsCurve(curve.degree, curve.knots, P, curve.weights)


def helix(center, radius0: float, radius1: float, a0: float, sweep: float, start: np.ndarray,
          end: np.ndarray, cols: tuple, name: str | None = None) -> NurbsCurve:
    """A helix (or spiral) as one piecewise cubic curve: angle ``a0 -> a0 + sweep``
    [rad] round ``center`` in the coordinates ``cols``, radius ``radius0 -> radius1`` and
    every other coordinate ``start -> end`` linearly in the angle, within
    :data:`HELIX_TOLERANCE` of the radius (:meth:`PieceChain.add_spiral`)."""
    chain = PieceChain(start)
    chain.add_spiral(end, cols, center, radius0, radius1, a0, sweep, 1.0)
    return chain.build(name=name)[0]


class _Reader:
    """The motion layer: executes blocks from :class:`ngc.Program` and collects pieces."""

    def __init__(self, source: str, axes: str):
        self.source = source
        self.axes = [_AXES.index(a.upper()) for a in axes]
        self.units: str | None = None  # output units
        self.units_source = "assumed: no G20/G21"  # where self.units came from
        self.input_inch: bool | None = None
        self.absolute = True
        self.arc_absolute = False
        self.plane = 17.0
        self.pos = [0.0] * 9  # absolute position of X..W [output units]
        self.feed = 0.0  # [output units / min]
        self.inverse_time = False  # G93
        self.feed_word = 0.0  # F of this line under G93 [1/min]
        self.f_on_line = False
        self.motion: str | None = None
        self.chain: PieceChain | None = None  # the pieces of the open contour
        self.piece_feeds = array("d")  # F of each piece of the open contour
        self.piece_lines = array("q")  # source line of each piece of the open contour
        self.contours: list[GcodeContour] = []
        self.warnings: list[str] = []
        self.warned: set = set()
        self.block: dict | None = None  # open G5.2 or G6.2 block
        self._g5_pq: np.ndarray | None = None
        self.line = 0
        self.program: Program | None = None
        self.frame_changes = 0  # bumped by blocks that change offsets or the coordinate system
        self._frame_key = None
        self._frame = self._identity = None
        others = [i for i in range(9) if i not in self.axes]
        self.path_of = _picker(self.axes)  # X..W -> tuple of the path coordinates
        self.others_of = _picker(others)
        self._k = None  # lengths(), until G20/G21 changes the input units
        self.project = False  # feed moves of other axes with the path axes: keep their projection
        self.auto = False  # no axes given: a feed move of other axes with the path axes is _NeedAxes
        self.moved = [False] * 9  # axes X..W that any move changed
        self.fed_outside: dict = {}  # axis outside the path -> first line a feed move changed it
        self.spindle_on = False  # M3/M4 (True) or M5
        self.per_rev = False  # G95: F is a length per spindle revolution
        self.feed_per_rev = 0.0  # [output units / rev]
        self.spindle_rpm = 0.0  # the last S word [rev/min]
        self.pitch = 0.0  # G33 / G33.1 K [output units / rev]
        self.rapids_as_path = False  # a program without feed moves: its rapids are the path
        self.rapid = False  # the move being read is a rapid read as the path
        self.retract_old_level = False  # G98 (True) or G99, LinuxCNC's default
        self.cycle_words: dict = {}  # R, depth, P, Q, I/J/K kept from the last cycle [input units]
        self.cycle_level: float | None = None  # the initial level of a series of cycles [output units]

    @property
    def position(self) -> np.ndarray:
        """The absolute position of X..W [output units], shape (9,)."""
        return np.array(self.pos)

    @position.setter
    def position(self, value) -> None:
        self.pos = [float(v) for v in value]

    # -- helpers
    def error(self, message: str, line: int | None = None) -> PathFileError:
        return PathFileError(message, self.source, line if line is not None else self.line)

    def warn(self, message: str, kind: str | None = None) -> None:
        if kind is not None:
            if kind in self.warned:
                return
            self.warned.add(kind)
        text = f"{self.source}, line {self.line}: {message}"
        self.warnings.append(text)
        warnings.warn(text, GcodeWarning, stacklevel=2)

    def scale(self) -> float:
        if self.units is None:
            self.units = "mm"
            self.units_source = "assumed: no G20/G21 before the first move"
            self.input_inch = False
            self.warn("no G20/G21 before the first move; reading millimetres (G21)")
        if self.input_inch == (self.units == "inch"):
            return 1.0
        return _INCH if self.input_inch else 1.0 / _INCH

    def frame(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The active G5x offset, G92 offset (X..W, [output units]) and XY rotation [deg]
        (parameters #5221.. per system, #5211.., #5210), as LinuxCNC keeps them; cached
        until a block or an assignment changes them."""
        key = (self.program.frame_version, self.frame_changes)
        if self._frame_key != key:
            self._frame = self._read_frame()
            self._frame_key = key
            g5x, g92, rot = self._frame
            self._identity = not (rot or np.any(g5x) or np.any(g92))
        return self._frame

    def identity_frame(self) -> bool:
        """Whether no offset or rotation is active (program = absolute coordinates)."""
        if self._frame_key is None or self._frame_key[0] != self.program.frame_version \
                or self._frame_key[1] != self.frame_changes:
            self.frame()
        return self._identity

    def _read_frame(self) -> tuple[np.ndarray, np.ndarray, float]:
        n = self.program.numbered
        system = int(n[5220]) or 1
        base = 5201 + 20 * system
        g92 = np.array(n[5211:5220]) if n[5210] else np.zeros(9)
        return np.array(n[base: base + 9]), g92, n[base + 9]

    def to_program(self, p) -> list:
        """Absolute (machine) coordinates X..W -> program coordinates (LinuxCNC's
        unrotate), as a new list."""
        g5x, g92, rot = self.frame()
        if self._identity:
            return list(p)
        q = np.array(p, dtype=float) - g5x
        if rot:
            c, s = math.cos(math.radians(rot)), math.sin(math.radians(rot))
            q[0], q[1] = c * q[0] + s * q[1], -s * q[0] + c * q[1]
        return (q - g92).tolist()

    def to_absolute_point(self, q: list) -> list:
        """:meth:`to_absolute` of one point X..W, as a new list."""
        self.frame()
        return list(q) if self._identity else self.to_absolute(np.array(q, dtype=float)).tolist()

    def to_absolute(self, q: np.ndarray) -> np.ndarray:
        """Program coordinates (shape (..., 9)) -> absolute: + G92, rotate XY, + G5x."""
        g5x, g92, rot = self.frame()
        if self._identity:
            return q
        p = q + g92
        if rot:
            c, s = math.cos(math.radians(rot)), math.sin(math.radians(rot))
            p = p.copy()
            p[..., 0], p[..., 1] = c * (q[..., 0] + g92[0]) - s * (q[..., 1] + g92[1]), \
                s * (q[..., 0] + g92[0]) + c * (q[..., 1] + g92[1])
        return p + g5x

    def system_parameter(self, name: str) -> float | None:
        """``#<_x>`` .. ``#<_w>`` and a few modal flags, for the language layer."""
        if len(name) == 2 and name[1].upper() in _AXES:
            i = _AXES.index(name[1].upper())
            k = 1.0 / self.scale() if self.units and i not in (3, 4, 5) else 1.0
            return float(self.to_program(self.pos)[i] * k)
        flags = {"_metric": not self.input_inch, "_imperial": bool(self.input_inch),
                 "_absolute": self.absolute, "_incremental": not self.absolute}
        if name in flags:
            return float(flags[name])
        if name == "_feed":
            return self.feed
        return None

    def value(self, letter: str, v: float) -> float:
        if not abs(v) <= MAX_COORDINATE:
            raise self.error(f"{letter}{v:g} is beyond the largest coordinate read, "
                             f"{MAX_COORDINATE:g} (MAX_COORDINATE)")
        return v

    def lengths(self) -> list:
        """Factor from the words' units to output units for X..W (1 for rotary A B C)."""
        if self._k is None:
            k = self.scale()
            self._k = [k, k, k, 1.0, 1.0, 1.0, k, k, k]
        return self._k

    def axis_words(self, words: dict, cur: list, ref: list) -> list:
        """``cur`` with the axis words applied, in output units: absolute (G90), or
        relative to ``ref`` (G91), as a new list."""
        end = list(cur)
        k = self.lengths()
        absolute = self.absolute
        for letter, v in words.items():
            axis = _AXIS_INDEX.get(letter)
            if axis is not None:
                if not abs(v) <= MAX_COORDINATE:
                    self.value(letter, v)
                end[axis] = v * k[axis] if absolute else ref[axis] + v * k[axis]
        return end

    def plain_target(self, words: dict) -> list:
        """:meth:`target` without offsets, rotation or polar words: the common case, lean."""
        return self.axis_words(words, self.pos, self.pos)

    def target(self, words: dict, base=None, machine: bool = False) -> list:
        """End point of a move from its axis words [absolute X..W, output units]: absolute
        under G90, relative to ``base`` (default: the current position) under G91; polar
        ``@`` (radius) and ``^`` (angle, degrees) in the XY plane as LinuxCNC reads them;
        ``machine``: the words are machine coordinates (G53)."""
        if base is None and not machine and self.identity_frame() and "@" not in words \
                and "^" not in words:
            return self.plain_target(words)
        k = self.lengths()
        if machine:
            end = list(self.pos)
            for letter, v in words.items():
                axis = _AXIS_INDEX.get(letter)
                if axis is not None:
                    end[axis] = k[axis] * self.value(letter, v)
            return end
        cur = self.to_program(self.pos)
        end = self.axis_words(words, cur, cur if base is None else self.to_program(base))
        if "@" in words or "^" in words:
            if "X" in words or "Y" in words:
                raise self.error("polar coordinates @ ^ cannot be given with X or Y")
            r0, t0 = math.hypot(cur[0], cur[1]), math.degrees(math.atan2(cur[1], cur[0]))
            r = k[0] * self.value("@", words["@"]) + (0.0 if self.absolute else r0) if "@" in words else r0
            t = self.value("^", words["^"]) + (0.0 if self.absolute else t0) if "^" in words else t0
            end[0], end[1] = r * math.cos(math.radians(t)), r * math.sin(math.radians(t))
        return self.to_absolute_point(end)

    def piece_feed(self, length: float, line: int) -> float:
        """The feed of a piece of ``length`` [output units] with the F in force. Under G93
        (inverse time) F is 1 / the move's duration [1/min], so the piece's feed is its
        length times F."""
        feed = self.feed
        if self.inverse_time:
            if not self.f_on_line:
                raise self.error("inverse-time feed (G93) needs an F word on every feed move")
            feed = self.feed_word * length
        if feed <= 0 and self.per_rev:
            raise self.error("feed per revolution (G95) needs a turning spindle: an S word and "
                             "M3/M4 before the move", line)
        if feed <= 0:
            raise self.error("feed move without a feed rate: no F word (or F0) before it", line)
        return feed

    def open_chain(self) -> PieceChain:
        if self.chain is None:
            self.chain = PieceChain(self.path_of(self.pos))
        return self.chain

    def add_piece(self, piece: NurbsCurve, line: int, length: float | None = None) -> None:
        """Add a piece in path coordinates; ``length``: its arc length where known exactly."""
        self.add_length(self.open_chain().add_curve(piece, length), line)

    def add_line(self, path_end: tuple) -> None:
        """A G1 move from the current position to ``path_end`` (the path coordinates)."""
        length = (self.chain if self.chain is not None else self.open_chain()).add_line(path_end)
        feed = self.feed
        if self.rapid:  # a rapid read as the path: no programmed feed
            feed = math.nan
        elif not (feed > 0 and not self.inverse_time):
            feed = self.piece_feed(length, self.line)
        self.piece_feeds.append(feed)
        self.piece_lines.append(self.line)

    def add_length(self, length: float, line: int) -> None:
        """Record the feed and line of the piece of ``length`` just added to the chain."""
        self.piece_feeds.append(self.piece_feed(length, line))
        self.piece_lines.append(line)

    def add_curve(self, curve: NurbsCurve, line: int, length: float | None = None) -> None:
        """Add a piece given in program coordinates X..W (9 columns)."""
        P = self.to_absolute(curve.control_points)
        piece = self.make(lambda: NurbsCurve(curve.degree, curve.knots, P[:, self.axes],
                                             curve.weights, name=f"line {line}"), line)
        self.add_piece(piece, line, length)

    def make(self, build, line: int):
        try:
            return build()
        except InvalidCurveError as exc:
            raise self.error(str(exc), line) from None

    def end_contour(self) -> None:
        if self.chain is None:
            return
        name = f"{Path(self.source).stem}#{len(self.contours) + 1}"
        lines = tuple(self.piece_lines)
        try:
            curve, edges = self.chain.build(name=name, units=self.units)
        except InvalidCurveError as exc:
            raise self.error(f"cannot join the moves into one path: {exc}", lines[0]) from None
        feeds = np.frombuffer(self.piece_feeds, dtype=float).copy()
        self.contours.append(GcodeContour(curve, edges, feeds, lines))
        self.chain, self.piece_feeds, self.piece_lines = None, array("d"), array("q")

    # -- one block
    def set_feed(self, f: float) -> None:
        """An F word: the feed [output units / min], or 1 / duration under G93."""
        if not (0 <= f <= MAX_COORDINATE):
            raise self.error(f"feed F{f:g} must be >= 0 and at most {MAX_COORDINATE:g}")
        if self.inverse_time:
            self.feed_word = f
        elif self.per_rev:
            self.feed_per_rev = f * (1.0 if self.units is None else self.scale())
            self.feed = self.feed_per_rev * self.spindle_rpm
        else:
            self.feed = f * (1.0 if self.units is None else self.scale())

    def read(self, block) -> bool:
        """Process one block; return False when the program ends (M2/M30)."""
        line, gs, ms, words = block
        self.line = line
        if (not ms and (not gs or gs in _PLAIN_G) and words.keys() <= _PLAIN_WORDS
                and self.block is None and self.units is not None and self.identity_frame()):
            kind = _PLAIN_G[gs] if gs else self.motion
            if kind == "G0" or kind == "G1":  # the lines of CAM output: a lean path
                self.motion = kind
                self.f_on_line = "F" in words
                if self.f_on_line:
                    self.set_feed(words["F"])
                    if len(words) == 1:
                        return True
                if words:
                    self.travel(kind, words, self.plain_target(words))
                return True
        rest = dict(words)
        if "$$" in rest:
            self.warn("controller console commands ($..., ?, !, ~: GRBL's settings, status, "
                      "jog, feed hold, cycle start) skipped: they are not part of the program", "$$")
            return True
        motion = None
        special = None  # a non-modal G code of group 0 that uses the axis words
        for g in block.g:
            if g not in _MOTION:  # G1, G01 and G1.0 are read as 1.0 exactly; others may be computed
                g = round(g, 4)
            if g in _MOTION:
                if motion == "G80" or (g == 80.0 and motion is not None):  # LinuxCNC reads G80 G0
                    motion = motion if g == 80.0 else _MOTION[g]
                    continue
                if motion is not None:
                    raise self.error(f"two motion codes on one line: {motion} and {_g_name(g)}")
                motion = _MOTION[g]
            elif g in (20.0, 21.0):
                self.input_inch = g == 20.0
                self._k = None
                if self.units is None:
                    self.units = "inch" if self.input_inch else "mm"
                    self.units_source = f"{_g_name(g)} on line {self.line}"
            elif g in (90.0, 91.0):
                self.absolute = g == 90.0
            elif g in (90.1, 91.1):
                self.arc_absolute = g == 90.1
            elif g in (93.0, 94.0, 95.0):
                if (g == 95.0) != self.per_rev or (g == 93.0) != self.inverse_time:
                    self.feed = self.feed_per_rev = 0.0  # LinuxCNC's convert_feed_mode: F anew
                self.inverse_time, self.per_rev = g == 93.0, g == 95.0
            elif g in (17.0, 18.0, 19.0):
                self.plane = g
            elif g in (98.0, 99.0):
                self.retract_old_level = g == 98.0
            elif g in _COORD_SYSTEMS:
                self.program.numbered[5220] = float(_COORD_SYSTEMS[g])
                self.frame_changes += 1
            elif g in (10.0, 28.0, 28.1, 30.0, 30.1, 53.0, 92.0, 92.1, 92.2, 92.3):
                if special is not None:
                    raise self.error(f"two codes of group 0 on one line: {_g_name(special)} and {_g_name(g)}")
                special = g
            elif g in _REFUSED_G:
                raise self.error(f"{_g_name(g)}: {_REFUSED_G[g]}")
            elif g in _SKIPPED_G:
                if _SKIPPED_G[g]:
                    self.warn(f"{_SKIPPED_G[g]} skipped: it does not change the path", _g_name(g))
                if g == 4.0:
                    rest.pop("P", None)
                    self.end_contour()
                elif g == 64.0:
                    rest.pop("P", None), rest.pop("Q", None)
                elif g in (43.0, 43.2):
                    rest.pop("H", None)
                elif g == 43.1:
                    for a in "XYZABCUVW":
                        rest.pop(a, None)
            else:
                raise self.error(f"{_g_name(g)} is not a LinuxCNC G code this reader knows")
        for m in block.m:
            if m in _END_M:
                continue
            if m in (3.0, 4.0, 5.0):
                self.spindle_on = m != 5.0
            name = _skipped_m(m)
            if name is None:
                raise self.error(f"M{m:g} is not an M code this reader knows")
            self.warn(f"{name} skipped: it does not change the path", name)
            if m >= 48:  # the words of M48-M53, M61-M68 (P, Q, E, L, R) go with them
                for letter in "PEQLR":
                    rest.pop(letter, None)
        if "S" in rest:
            if not 0 <= rest["S"] <= MAX_COORDINATE:
                raise self.error(f"spindle speed S{rest['S']:g} must be >= 0")
            self.spindle_rpm = rest["S"]
            if self.per_rev:
                self.feed = self.feed_per_rev * self.spindle_rpm
        if not rest.keys().isdisjoint(_SKIPPED_WORDS):
            for letter, what in _SKIPPED_WORDS.items():
                if letter in rest:
                    rest.pop(letter)
                    self.warn(f"{what} skipped: it does not change the path", letter)
        self.f_on_line = "F" in rest
        if "F" in rest:
            self.set_feed(rest.pop("F"))

        if self.block is not None and self.block["kind"] == "G5.2" and motion not in (None, "G5.2", "G5.3"):
            raise self.error(f"the G5.2 block opened on line {self.block['line']} is not closed "
                             f"with G5.3 before this {motion}")
        if self.block is not None and self.block["kind"] == "G6.2" and motion not in (None, "G6.2"):
            self.close_g6()
        previous = self.motion
        if motion is not None:
            self.motion = motion
        if special is not None:
            self.non_modal(special, rest)
            self.frame_changes += 1
            rest = {}

        if motion == "G5.3":
            self.close_g5(rest)
        elif self.motion == "G5.2" and (motion == "G5.2" or self.block is not None or rest):
            self.g5_point(rest, opening=self.block is None)
        elif self.motion == "G6.2" and (motion == "G6.2" or rest):
            self.g6_point(rest, opening=self.block is None)
        elif self.motion in _CYCLES and (motion is not None or rest):
            self.canned_cycle(rest, previous)
        elif self.motion == "G80" and rest:
            raise self.error(f"axis words {sorted(rest)} after G80 (canned cycles off) need a "
                             "motion code (G0, G1, ...)")
        elif rest or motion in ("G2", "G3"):
            self.move(rest)
        return not (block.m and any(m in _END_M for m in block.m))

    # -- runs of plain lines, in bulk
    def read_rows(self, rows: Rows) -> bool:
        """Process a run of plain lines (:class:`ngc.Rows`); return False when the program
        ends. The rows that :meth:`read` takes on its lean path (G0/G1 with axis and F
        words under G90 and G94, no offset, no open G5.2/G6.2 block) are applied in bulk
        (:class:`_RunState`); every other row goes through :meth:`read`, after which the
        bulk state is checked against the reader's and recomputed where they differ."""
        table = rows.table
        if self.rapids_as_path:  # rare (a program of rapids only) and small: line by line
            return all(self.read(table.block(r)) for r in range(rows.start, rows.stop))
        run = _RunColumns(table, rows.start, rows.stop)
        state = None
        s = 0
        while s < run.n:
            if self.lean():
                if state is None or not state.agrees(self, s):  # first, or read() did otherwise
                    state = _RunState(self, run, s, run.n if state is None else run.next_other(s))
                t = state.next_stop(s)
                if t > s:
                    self.apply_rows(run, state, s, t)
                    s = t
                    if s == run.n:
                        break
            if not self.read(table.block(rows.start + s)):
                return False
            s += 1
        return True

    def lean(self) -> bool:
        """Whether :meth:`read`'s lean path (and so :meth:`read_rows`'s bulk) applies."""
        return (self.block is None and self.units is not None and self.absolute
                and not self.inverse_time and not self.per_rev and self.identity_frame())

    def apply_rows(self, run: "_RunColumns", state: "_RunState", s: int, t: int) -> None:
        """Apply rows ``s .. t - 1`` of a run as :meth:`read` would, one by one."""
        i, k = state.pieces.searchsorted((s, t)).tolist()
        pieces = state.pieces[i:k]
        i, k = state.breaks.searchsorted((s, t)).tolist()
        parts = [pieces] if i == k else np.split(pieces, pieces.searchsorted(state.breaks[i:k]))
        for n, part in enumerate(parts):  # a rapid or a move of another axis ends the contour
            if n:
                self.line = int(run.line[state.breaks[i + n - 1]])
                self.end_contour()
            if len(part):
                rel = part - state.s  # rows of line pieces, relative to the state's first
                ends_at = rel + 1
                if self.chain is None:
                    self.chain = PieceChain(self.path_of(state.position(int(rel[0]))))
                ends = np.empty((len(rel), len(self.axes)))
                for c, axis in enumerate(self.axes):
                    ends[:, c] = state.column(axis, ends_at)
                self.chain.add_lines(ends)
                self.piece_feeds.frombytes(state.feed[ends_at].tobytes())
                self.piece_lines.frombytes(run.line[part].tobytes())
        j0, j = s - state.s, t - state.s
        for i, col in state._columns.items():
            if not self.moved[i] or (i not in self.axes and i not in self.fed_outside):
                changed = col[j0 + 1: j + 1] != col[j0: j]
                if changed.any():
                    self.moved[i] = True
                    fed = changed & (state.motion[j0 + 1: j + 1] == 1.0)
                    if i not in self.axes and fed.any():
                        self.fed_outside.setdefault(i, int(run.line[s + int(np.argmax(fed))]))
        self.pos = state.position(j)
        self.feed = float(state.feed[j])
        if state.motion[j] >= 0:
            self.motion = "G1" if state.motion[j] else "G0"
        self.line = int(run.line[t - 1])
        self.f_on_line = bool(run.has_feed[t - 1])
        if run.has_axis[s:t].any():
            self._g5_pq = None

    # -- group 0: G10 G28 G30 G53 G92
    def non_modal(self, g: float, w: dict) -> None:
        n = self.program.numbered
        if g == 53.0:
            if not self.absolute:
                raise self.error("G53 needs absolute mode G90")
            self.move(w, machine=True)
        elif g in (28.0, 30.0):
            home = 5161 if g == 28.0 else 5181
            self.end_contour()
            if w:
                self.position = self.target(w)
            self.position = np.array(n[home: home + 9]) * self.lengths()
        elif g in (28.1, 30.1):
            home = 5161 if g == 28.1 else 5181
            n[home: home + 9] = list(self.position / self.lengths())
        elif g == 92.0:
            if not w:
                raise self.error("G92 needs at least one axis word")
            _, g92, _ = self.frame()
            unshifted = np.array(self.to_program(self.pos)) + g92
            for axis, letter in enumerate(_AXES):
                if letter in w:
                    g92[axis] = unshifted[axis] - self.value(letter, w[letter]) * self.lengths()[axis]
            n[5211:5220] = list(g92)
            n[5210] = 1.0
        elif g in (92.1, 92.2):
            n[5210] = 0.0
            if g == 92.1:
                n[5211:5220] = [0.0] * 9
        elif g == 92.3:
            n[5210] = 1.0
        else:  # G10
            L = w.pop("L", None)
            if L in (1.0, 10.0, 11.0):
                self.warn(f"G10 L{L:g} tool table entries skipped: tool offsets are not applied", "G10 tool")
                return
            if L not in (2.0, 20.0):
                raise self.error(f"G10 L{L if L is None else format(L, 'g')} is not read (G10 L2/L20 are)")
            p = w.pop("P", 0.0)
            if p != int(p) or not 0 <= p <= 9:
                raise self.error(f"G10 L{L:g} P{p:g}: coordinate system must be 0..9")
            system = int(p) or int(n[5220]) or 1
            base = 5201 + 20 * system
            if "R" in w:
                n[base + 9] = w.pop("R")
            extra = sorted(set(w) - set(_AXES))
            if extra:
                raise self.error(f"word(s) {', '.join(extra)} not allowed with G10")
            for axis, letter in enumerate(_AXES):
                if letter in w:
                    v = self.value(letter, w[letter]) * self.lengths()[axis]
                    if L == 2.0:
                        n[base + axis] = v
                    else:  # L20: the current point gets coordinate v
                        g92 = n[5211 + axis] if n[5210] else 0.0
                        n[base + axis] = self.position[axis] - g92 - v

    # -- G0 G1 G2 G3 G5 G5.1
    def move(self, w: dict, machine: bool = False) -> None:
        kind = self.motion
        if kind is None:
            raise self.error(f"axis words {sorted(w)} without a motion mode (G0/G1/...)")
        if not w.keys() <= _MOTION_WORDS[kind]:
            extra = sorted(set(w) - _MOTION_WORDS[kind])
            raise self.error(f"word(s) {', '.join(extra)} not read with {kind}")
        if kind in ("G5", "G5.1") and self.plane != 17.0:
            raise self.error(f"{kind} is only allowed in the XY plane (G17), as in LinuxCNC")
        if kind in ("G33", "G33.1"):
            self.synchronised(kind, w, machine)
            return
        self.travel(kind, w, self.target(w, machine=machine))

    def synchronised(self, kind: str, w: dict, machine: bool) -> None:
        """G33 (a line at the spindle's pace: feed = pitch K x S) and G33.1 (rigid tapping:
        in to the end point and back to the start at that pace, the spindle reversing at
        the bottom), read with the last S word as the spindle's speed, as LinuxCNC moves
        them with the spindle at that speed (``convert_straight``)."""
        if "K" in w:
            self.pitch = self.lengths()[0] * self.value("K", w.pop("K"))
        w.pop("I", None)  # G33.1 I: the spindle's speed scale on the way out, not the path
        if self.pitch <= 0:
            raise self.error(f"{kind} needs the pitch K (a length per revolution, > 0)")
        if not (self.spindle_on and self.spindle_rpm > 0):
            raise self.error(f"{kind} moves with the spindle: it needs an S word and M3/M4 before it")
        feed, self.feed = self.feed, self.pitch * self.spindle_rpm  # [output units / min]
        per_rev, inverse, self.per_rev, self.inverse_time = self.per_rev, self.inverse_time, False, False
        try:
            start = list(self.pos)
            end = self.target(w, machine=machine)
            self.travel("G1", {}, end)
            if kind == "G33.1":  # the spindle reverses at the bottom: a stop, then out again
                self.end_contour()
                self.travel("G1", {}, start)
                self.end_contour()
        finally:
            self.feed, self.per_rev, self.inverse_time = feed, per_rev, inverse

    def travel(self, kind: str, w: dict, end: list) -> None:
        """Move to ``end`` (absolute X..W) with motion ``kind``: a piece of the open
        contour, or the end of it (rapid, move of an axis outside the path)."""
        self.rapid = kind == "G0" and self.rapids_as_path
        if self.rapid:
            kind = "G1"
        start = self.pos
        path_end = self.path_of(end)
        moves_path = path_end != self.path_of(start)
        moves_other = self.others_of(end) != self.others_of(start)
        if moves_other or moves_path:
            self.note_moved(kind, start, end)
        if kind == "G0":
            if moves_path or moves_other:
                self.end_contour()
        elif moves_other and (moves_path or kind in ("G2", "G3")) and not self.project:
            others = "".join(_AXES[i] for i in range(9) if end[i] != start[i] and i not in self.axes)
            path = "".join(_AXES[i] for i in self.axes)
            if self.auto:
                raise _NeedAxes(set(others))
            raise self.error(
                f"{kind} moves {others} together with the path axes {path}; "
                f"a machine with the axes {''.join(sorted(set(path) | set(others), key=_AXES.index))} "
                f"can follow it (or read the path's projection on {path}: --project {path.lower()})")
        elif moves_other and not moves_path and kind not in ("G2", "G3"):
            self.end_contour()  # a plunge or lift of an axis outside the path ends the contour
        elif kind == "G1":
            if moves_path:
                self.add_line(path_end)
        elif kind in ("G2", "G3"):
            self.arc(w, start, end)
        else:
            self.spline(kind, w, np.array(start), np.array(end))
        if kind != "G5":
            self._g5_pq = None
        self.pos = end

    # -- canned cycles G73, G74, G81-G89
    def canned_cycle(self, w: dict, previous: str | None) -> None:
        """One block of a canned cycle, expanded into G0 and G1 moves as LinuxCNC's
        ``convert_cycle_xy`` / ``_yz`` / ``_zx`` (``interp_cycles.cc``) do: in the selected
        plane's axes (a, b) and the axis across it (c, the depth), every repeat (``L``)
        rapids to the hole at the clearance level, down to ``R``, runs the cycle's feed
        moves along c, and retracts to ``R`` (G99) or to the level the series of cycles
        started at (G98) if that is higher. Each feed move along c is a piece of a contour
        (a path with c), a rapid ends the contour; a dwell, a spindle stop or orientation
        does not change the path and is not kept. G88's manual retract is a jump to the
        clearance level (a new contour), as the interpreter assumes it."""
        kind = self.motion
        again = previous == kind  # LinuxCNC: motion_mode == motion, the words may be left out
        if not w.keys() <= _MOTION_WORDS[kind]:
            extra = sorted(set(w) - _MOTION_WORDS[kind])
            raise self.error(f"word(s) {', '.join(extra)} not read with {kind}")
        if self.inverse_time:
            raise self.error(f"{kind}: canned cycles cannot use inverse-time feed (G93)")
        if self.feed <= 0:
            raise self.error(f"{kind}: a canned cycle needs a feed rate (F)")
        ia, ib, ic, oa, ob = _PLANES[self.plane]
        la, lb, lc = _AXES[ia], _AXES[ib], _AXES[ic]
        if set(w) & set("UVW"):
            raise self.error(f"{kind}: U, V or W in a canned cycle in the {_g_name(self.plane)} plane")
        if ("@" in w or "^" in w) and self.plane != 17.0:
            raise self.error(f"{kind}: polar coordinates @ ^ are read in the XY plane (G17) only")
        if ("@" in w or "^" in w) and ("X" in w or "Y" in w):
            raise self.error("polar coordinates @ ^ cannot be given with X or Y")
        kept = self.cycle_words
        if "R" not in w and not again:
            raise self.error(f"{kind} needs the retract level R the first time")
        if lc not in w and not again:
            raise self.error(f"{kind} needs the depth {lc} the first time (in the "
                             f"{_g_name(self.plane)} plane)")
        needs = {"G82": "P", "G86": "P", "G88": "P", "G89": "P", "G73": "Q", "G83": "Q"}.get(kind)
        if needs and needs not in w and not again:
            raise self.error(f"{kind} needs {needs} the first time")
        offsets = {17.0: "IJK", 19.0: "JKI", 18.0: "KIJ"}[self.plane]  # a, b offsets; c middle
        if kind == "G87" and not again:
            missing = [x for x in offsets if x not in w]
            if missing:
                raise self.error(f"G87 needs {', '.join(missing)} the first time")
        repeats = w.get("L", 1.0)
        if repeats != int(repeats) or not 1 <= repeats <= 100_000:
            raise self.error(f"{kind}: repeats L{repeats:g} must be a whole number from 1 to 100000")
        for letter in "RPQIJK" + lc:
            if letter in w:
                kept[letter if letter != lc else "depth"] = self.value(letter, w[letter])
        k = self.lengths()[ic]
        cur = self.to_program(self.pos)
        level = cur[ic]
        if previous not in _CYCLES or self.cycle_level is None:
            self.cycle_level = level  # LinuxCNC's cycle_il: where the series of cycles began
        initial = self.cycle_level
        pa, pb = cur[ia], cur[ib]
        step_a = step_b = step_radius = step_angle = 0.0
        if self.absolute:
            r, bottom = k * kept["R"], k * kept["depth"]
            if "@" in w or "^" in w:
                radius = k * self.value("@", w["@"]) if "@" in w else math.hypot(pa, pb)
                theta = math.radians(self.value("^", w["^"])) if "^" in w else math.atan2(pb, pa)
                pa, pb = radius * math.cos(theta), radius * math.sin(theta)
            else:
                pa = k * w[la] if la in w else pa
                pb = k * w[lb] if lb in w else pb
        else:
            step_a, step_b = k * w.get(la, 0.0), k * w.get(lb, 0.0)
            step_radius = k * self.value("@", w["@"]) if "@" in w else 0.0
            step_angle = math.radians(self.value("^", w["^"])) if "^" in w else 0.0
            r = k * kept["R"] + initial
            bottom = r + k * kept["depth"]
        if r < bottom:
            raise self.error(f"{kind}: the retract level R ({r:g}) is below the depth "
                             f"{lc} ({bottom:g})")

        def go(kind_: str, a: float, b: float, c: float) -> None:  # the other axes stay
            q = list(cur)
            q[ia], q[ib], q[ic] = a, b, c
            self.travel(kind_, {}, self.to_absolute_point(q))

        a, b = cur[ia], cur[ib]
        if initial < r:  # below the R level: straight up to it first
            go("G0", a, b, r)
            initial = level = r
        clear = initial if self.retract_old_level else r
        peck = PECK_CLEARANCE_INCH * _INCH / (_INCH if self.units == "inch" else 1.0)
        for n in range(int(repeats)):
            pa, pb = (pa + step_a, pb + step_b) if not self.absolute else (pa, pb)
            if step_radius or step_angle:
                if pa == 0.0 and pb == 0.0:
                    raise self.error("incremental polar motion is indeterminate at the origin")
                radius, theta = math.hypot(pa, pb) + step_radius, math.atan2(pb, pa) + step_angle
                pa, pb = radius * math.cos(theta), radius * math.sin(theta)
            if n == 0 and level > r:
                go("G0", pa, pb, level)
                go("G0", pa, pb, r)
            else:
                go("G0", pa, pb, clear)
                if clear > r:
                    go("G0", pa, pb, r)
            self.cycle_moves(kind, go, pa, pb, r, clear, bottom, kept, offsets, k, peck)
        if kind == "G88":  # the operator retracts by hand; the interpreter continues at clear
            self.end_contour()
            q = list(cur)
            q[ia], q[ib], q[ic] = pa, pb, clear
            self.pos = self.to_absolute_point(q)
        self.cycle_words = kept

    def cycle_moves(self, kind, go, a, b, r, clear, bottom, kept, offsets, k, peck) -> None:
        """The moves of one repeat of a cycle at (a, b) from the R level
        (``convert_cycle_g81`` .. ``_g89``)."""
        if kind in ("G73", "G83"):
            delta = k * kept["Q"]
            if delta <= 0:
                raise self.error(f"{kind}: peck depth Q{kept['Q']:g} must be > 0")
            if (r - bottom) / delta > 100_000:
                raise self.error(f"{kind}: peck depth Q{kept['Q']:g} makes more than 100000 pecks")
            depth = r - delta
            while depth > bottom:
                go("G1", a, b, depth)
                if kind == "G83":
                    go("G0", a, b, r)
                go("G0", a, b, depth + peck)
                depth -= delta
            go("G1", a, b, bottom)
            go("G0", a, b, clear)
        elif kind in ("G81", "G82", "G86"):
            go("G1", a, b, bottom)
            self.end_contour()  # a dwell, or the spindle stopping, at the bottom
            go("G0", a, b, clear)
        elif kind in ("G74", "G84", "G89"):
            go("G1", a, b, bottom)
            self.end_contour()  # the spindle reverses or the tool dwells at the bottom
            go("G1", a, b, clear)
            self.end_contour()
        elif kind == "G85":
            go("G1", a, b, bottom)
            self.end_contour()  # the feed reverses at the bottom: a stop
            go("G1", a, b, r)
            self.end_contour()
            go("G0", a, b, clear)
        elif kind == "G87":
            oa, ob = a + k * kept[offsets[0]], b + k * kept[offsets[1]]
            middle = k * kept[offsets[2]] + (0.0 if self.absolute else bottom)
            go("G0", oa, ob, r)
            go("G0", oa, ob, bottom)
            go("G0", a, b, bottom)
            go("G1", a, b, middle)
            go("G1", a, b, bottom)
            go("G0", oa, ob, bottom)
            go("G0", oa, ob, clear)
            go("G0", a, b, clear)
        else:  # G88
            go("G1", a, b, bottom)
            self.end_contour()

    def note_moved(self, kind: str, start: list, end: list) -> None:
        """Record the axes a move changes, and the first line where a feed move changes
        an axis outside the path (:attr:`moved`, :attr:`fed_outside`)."""
        for i in range(9):
            if end[i] != start[i]:
                self.moved[i] = True
                if kind != "G0" and i not in self.axes and i not in self.fed_outside:
                    self.fed_outside[i] = self.line

    def arc(self, w: dict, start: list, end: list) -> None:
        """G2/G3 in the selected plane, computed in program coordinates as LinuxCNC does:
        an exact arc when only the plane's axes move, else a helix; a spiral when the
        end radius differs from the start radius within LinuxCNC's tolerance."""
        clockwise = self.motion == "G2"
        k = self.scale()
        line = self.line
        i1, i2, lin, o1, o2 = _PLANES[self.plane]
        turns = w.get("P", 1.0)
        if turns != int(turns) or turns < 1:
            raise self.error(f"arc turns P{turns:g} must be a whole number >= 1")
        if turns > MAX_ARC_TURNS:
            raise self.error(f"arc turns P{turns:g} are more than the {MAX_ARC_TURNS} read "
                             "(MAX_ARC_TURNS)")
        wrong = "IJK"[lin]
        if wrong in w:
            raise self.error(f"{wrong} word not allowed with an arc in the {_g_name(self.plane)} plane")
        ps, pe = self.to_program(start), self.to_program(end)
        sx, sy, ex, ey = ps[i1], ps[i2], pe[i1], pe[i2]
        if "R" in w:
            if o1 in w or o2 in w:
                raise self.error("arc with both R and a centre offset")
            r = k * self.value("R", w["R"])
            dx, dy = ex - sx, ey - sy
            d = math.hypot(dx, dy)
            if d == 0.0:
                raise self.error("a radius-format arc cannot end where it starts")
            if d > 2 * abs(r) * (1 + 1e-9):
                raise self.error(f"arc radius {abs(r):g} is too small for the chord of length {d:g}")
            h = math.sqrt(max(r * r - d * d / 4, 0.0)) * (1.0 if (not clockwise) == (r > 0) else -1.0)
            cx, cy = (sx + ex) / 2 - h * dy / d, (sy + ey) / 2 + h * dx / d
        else:
            if o1 not in w and o2 not in w:
                raise self.error(f"{self.motion} needs {o1}/{o2} (centre) or R (radius) in the "
                                 f"{_g_name(self.plane)} plane")
            off1, off2 = k * self.value(o1, w.get(o1, 0.0)), k * self.value(o2, w.get(o2, 0.0))
            if self.arc_absolute and not (o1 in w and o2 in w):
                raise self.error(f"absolute arc centre (G90.1) needs both {o1} and {o2}")
            cx, cy = (off1, off2) if self.arc_absolute else (sx + off1, sy + off2)
        r1, r2 = math.hypot(sx - cx, sy - cy), math.hypot(ex - cx, ey - cy)
        if r1 == 0.0:
            raise self.error(f"arc centre {[cx, cy]} coincides with its start point")
        # LinuxCNC's check (interp_arc.cc): |r2 - r1| > 100 tol, or > tol and > 0.1 %
        tol = (2 * 0.01 * math.sqrt(2)) * (1.0 if self.units == "mm" else 1.0 / _INCH)
        diff = abs(r2 - r1)
        if diff > 100 * tol or (diff > tol and diff / max(r1, r2) > 0.001):
            raise self.error(
                f"radius to end of arc differs from radius to start: start {[sx, sy]} "
                f"centre {[cx, cy]} end {[ex, ey]} r1 {r1:.6g} r2 {r2:.6g}")
        if i1 not in self.axes or i2 not in self.axes:
            if self.auto:
                raise _NeedAxes({_AXES[i1], _AXES[i2]})
            raise self.error(f"an arc in the {_g_name(self.plane)} plane needs the axes "
                             f"{_AXES[i1]}{_AXES[i2]} in the path (the path has "
                             f"{''.join(_AXES[i] for i in self.axes)})")
        linear = any(pe[i] != ps[i] for i in range(9) if i != i1 and i != i2
                     and (i in self.axes or not self.project))  # projected: the path's own axes
        # Within HELIX_TOLERANCE the exact arc ending on the programmed point (its last
        # control point moved by at most the radius difference) is as close to LinuxCNC's
        # spiral as the spiral's own cubic pieces are.
        exact = not linear and diff <= HELIX_TOLERANCE * r1
        a0, sweep = arc_sweep((sx, sy), (ex, ey), (cx, cy), clockwise)
        if self.frame()[2]:  # a rotated frame: built in program coordinates and turned
            if exact:
                build = lambda: arc_by_center((sx, sy), (ex, ey), (cx, cy), clockwise=clockwise, turns=int(turns))
                for piece in self.make(build, line):  # rational quadratics: sweep 2 acos(w_mid) each
                    sweep = 2.0 * float(np.sum(np.arccos(np.clip(piece.weights[1::2], -1.0, 1.0))))
                    self.add_curve(_embed(piece, np.array(ps), (i1, i2)), line, r1 * sweep)
            else:
                sweep += math.copysign(2 * math.pi * (int(turns) - 1), sweep)
                center, ps, pe = np.array([cx, cy]), np.array(ps), np.array(pe)
                self.add_curve(self.make(lambda: helix(center, r1, r2, a0, sweep, ps, pe, (i1, i2)), line), line)
            return
        centre = self.to_absolute_point([cx if i == i1 else cy if i == i2 else 0.0 for i in range(9)])
        cols, c2 = (self.axes.index(i1), self.axes.index(i2)), (centre[i1], centre[i2])
        chain = self.open_chain()
        if exact:
            full = math.copysign(2 * math.pi, sweep)
            for _ in range(int(turns) - 1):
                self.add_length(chain.add_arc(self.path_of(start), cols, c2, r1, a0, full), line)
            self.add_length(chain.add_arc(self.path_of(end), cols, c2, r1, a0, sweep), line)
        else:  # a helix or spiral; its length: the helix's of the mean radius
            sweep += math.copysign(2 * math.pi * (int(turns) - 1), sweep)
            rise = math.dist(*((p[i] for i in self.axes if i != i1 and i != i2) for p in (start, end)))
            length = math.hypot(0.5 * (r1 + r2) * sweep, rise)
            self.add_length(chain.add_spiral(self.path_of(end), cols, c2, r1, r2, a0, sweep, length), line)

    def spline(self, kind: str, w: dict, start: np.ndarray, end: np.ndarray) -> None:
        k = self.scale()
        line = self.line
        ps = np.array(self.to_program(start))
        s2, e2 = ps[[0, 1]], np.array(self.to_program(end))[[0, 1]]
        if kind == "G5.1":
            if "I" not in w and "J" not in w:
                raise self.error("G5.1 needs I and/or J")
            ctrl = [s2, s2 + k * np.array([w.get("I", 0.0), w.get("J", 0.0)]), e2]
        else:
            if not ("P" in w and "Q" in w):
                raise self.error("G5 needs both P and Q")
            if ("I" in w) != ("J" in w):
                raise self.error("G5 needs both I and J, or neither")
            if "I" in w:
                first = k * np.array([self.value("I", w["I"]), self.value("J", w["J"])])
            elif self._g5_pq is not None:
                first = -self._g5_pq
            else:
                raise self.error("the first G5 of a series needs I and J")
            self._g5_pq = k * np.array([self.value("P", w["P"]), self.value("Q", w["Q"])])
            ctrl = [s2, s2 + first, e2 + self._g5_pq, e2]
        p = len(ctrl) - 1
        curve = self.make(lambda: NurbsCurve(p, [0.0] * (p + 1) + [1.0] * (p + 1), ctrl), line)
        self.add_curve(_embed(curve, ps, (0, 1)), line)

    # -- LinuxCNC G5.2 / G5.3: (first, second) = (X, Y), (Y, Z) or (Z, X) as LinuxCNC
    def g5_axes(self) -> tuple:
        return {17.0: (0, 1), 19.0: (1, 2), 18.0: (2, 0)}[self.plane]

    def g5_point(self, w: dict, opening: bool) -> None:
        a, b = self.g5_axes()
        la, lb = _AXES[a], _AXES[b]
        extra = sorted(set(w) - set(_AXES) - set("PL"))
        if extra:
            raise self.error(f"word(s) {', '.join(extra)} not allowed in a G5.2 block")
        if (la in w) != (lb in w):
            raise self.error(f"a G5.2 control point needs both {la} and {lb}")
        others = sorted(set(w) & set(_AXES) - {la, lb})
        if others:
            self.warn(f"{', '.join(others)} word inside a G5.2 block is ignored (LinuxCNC reads "
                      f"{la}{lb} only in the {_g_name(self.plane)} plane)", "G5.2 other axes")
        if opening:
            w0 = 1.0
            if "P" in w and la not in w:
                w0 = w["P"]
                if not 0 < w0 <= MAX_COORDINATE:
                    raise self.error(f"weight P{w0:g} of the first control point must be positive")
            self.block = {"kind": "G5.2", "line": self.line, "order": 3, "plane": (a, b),
                          "base": self.position.copy(), "points": [self.position.copy()],
                          "weights": [w0]}  # fmt: skip
        bl = self.block
        if "L" in w:
            if w["L"] != int(w["L"]) or w["L"] > 64:
                raise self.error(f"order L{w['L']:g} must be a whole number (at most 64)")
            if w["L"] > 3:
                bl["order"] = int(w["L"])
        if la in w:
            if "P" not in w:
                if not opening:
                    raise self.error("a G5.2 control point after the first line needs a weight P")
                self.warn(f"{la}/{lb} on the opening G5.2 line without P: weight 1, as the "
                          "LinuxCNC manual says", "G5.2 no P")
            weight = w.get("P", 1.0)
            if not 0 < weight <= MAX_COORDINATE:
                raise self.error(f"weight P{weight:g} must be positive")
            bl["points"].append(self.target({la: w[la], lb: w[lb]}, base=bl["base"]))
            bl["weights"].append(weight)
        elif "P" in w and not opening:
            raise self.error(f"P without {la} and {lb} is only allowed on the opening G5.2 line")

    def close_g5(self, w: dict) -> None:
        bl = self.block
        if bl is None or bl["kind"] != "G5.2":
            raise self.error("G5.3 without an open G5.2 block")
        if w:
            raise self.error(f"word(s) {', '.join(sorted(w))} not allowed with G5.3")
        points, order = np.array(bl["points"]), bl["order"]
        if len(points) < order:
            raise self.error(
                f"the G5.2 block opened on line {bl['line']} has {len(points)} control points "
                f"(counting the start point); order L = {order} needs at least {order}")
        line = bl["line"]
        self.block = None
        self.motion = None
        self.finish_nurbs(lambda: NurbsCurve(order - 1, linuxcnc_knots(len(points), order), points,
                                             bl["weights"]), bl["plane"], points[-1], line)

    def finish_nurbs(self, build, plane: tuple, last: np.ndarray, line: int) -> None:
        """Add a G5.2/G6.2 curve whose control points are absolute X..W rows. A first
        control point repeating the start (LinuxCNC's own examples) gives C'(0) = 0, which
        the path keeps (see NurbsCurve)."""
        if not set(plane) <= set(self.axes):
            if self.auto:
                raise _NeedAxes({_AXES[i] for i in plane})
            raise self.error(f"the curve lies in the {''.join(_AXES[i] for i in plane)} plane but "
                             f"the path has the axes {''.join(_AXES[i] for i in self.axes)}")
        curve = self.make(build, line)
        piece = self.make(lambda: NurbsCurve(curve.degree, curve.knots, curve.control_points[:, self.axes],
                                             curve.weights, name=f"line {line}"), line)
        self.add_piece(piece, line, piece.length if self.inverse_time else None)
        self.position = np.array(last, dtype=float)

    # -- G6.2 (LinuxCNC) / G06.2 (Fanuc)
    def g6_point(self, w: dict, opening: bool) -> None:
        a, b = self.g5_axes()
        la, lb = _AXES[a], _AXES[b]
        extra = sorted(set(w) - set(_AXES) - set("KRPQL"))
        if extra:
            raise self.error(f"word(s) {', '.join(extra)} not allowed in a G6.2 block")
        if opening:
            order = w.get("P", 4.0)
            if order != int(order) or not 2 <= order <= 64:
                raise self.error(f"G6.2 order P{order:g} must be a whole number in 2..64")
            q = w.get("Q", 1.0)
            if q not in (1.0, 2.0, 3.0):
                raise self.error(f"G6.2 Q{q:g} must be 1, 2 or 3 (LinuxCNC's interpolation method)")
            self.block = {"kind": "G6.2", "line": self.line, "order": int(order), "points": [],
                          "weights": [], "knots": [], "tail": 0, "plane": (a, b)}  # fmt: skip
        elif "P" in w or "Q" in w:
            raise self.error("the G6.2 order P and method Q may only be given on the opening line")
        bl = self.block
        if "K" not in w and not opening:
            raise self.error("every G6.2 block needs a knot K")
        others = set(w) & set(_AXES) - {la, lb}
        if others and self.target({x: w[x] for x in others}) != self.pos:
            raise self.error(f"{', '.join(sorted(others))} moves inside G6.2 are not read "
                             f"(the curve lies in the {la}{lb} plane)")
        weight = w.get("R", 1.0)
        if not 0 < weight <= MAX_COORDINATE:
            raise self.error(f"weight R{weight:g} must be positive")
        if la in w or lb in w:
            if bl["tail"]:
                raise self.error("G6.2 control point after the knot-only blocks")
            point = np.array(self.target({x: w[x] for x in (la, lb) if x in w}))
            here = self.position
            if opening and np.max(np.abs(point - here)) > 1e-9 * max(1.0, np.max(np.abs(point))):
                raise self.error(f"the first G6.2 control point {point[[a, b]].tolist()} is not the "
                                 f"current position {here[[a, b]].tolist()}")
            bl["points"].append(point)
            bl["weights"].append(weight)
        elif opening:
            bl["points"].append(self.position.copy())
            bl["weights"].append(weight)
        else:
            bl["tail"] += 1
        bl["knots"].append(w.get("K"))
        if bl["knots"][0] is None and len(bl["knots"]) > 1:
            bl["knots"][0] = bl["knots"][1]
        if bl["tail"] == bl["order"]:
            self.close_g6()

    def close_g6(self) -> None:
        bl = self.block
        self.block = None
        self.motion = None
        line = bl["line"]
        points, order, knots = np.array(bl["points"]), bl["order"], bl["knots"]
        n = len(points)
        if len(knots) != n + order:
            raise self.error(f"the G6.2 block of line {line} has {len(knots)} knots, expected "
                             f"{n + order} = control points ({n}) + order ({order})", line)
        if len(set(knots[:order])) != 1 or len(set(knots[-order:])) != 1:
            raise self.error(f"the G6.2 block of line {line} must start and end with {order} equal "
                             f"knots (clamped ends), got {knots[:order]} ... {knots[-order:]}", line)
        self.finish_nurbs(lambda: NurbsCurve(order - 1, knots, points, bl["weights"]), bl["plane"],
                          points[-1], line)

    def finish(self) -> None:
        if self.block is not None and self.block["kind"] == "G5.2":
            raise self.error(f"the G5.2 block opened on line {self.block['line']} is never closed "
                             "with G5.3 (truncated program?)", self.block["line"])
        if self.block is not None:
            self.close_g6()
        self.end_contour()


_AXIS_OF_CODE = np.full(256, -1, dtype=np.int64)  # ASCII letter -> axis index (X..W), else -1
_AXIS_OF_CODE[[ord(a) for a in _AXES]] = np.arange(len(_AXES))
_OTHER_MOTION = np.array(sorted(set(_MOTION) - {0.0, 1.0}))


class _RunColumns:
    """The words of a run of plain lines (:class:`ngc.Rows`) as one array per kind, for
    :meth:`_Reader.read_rows`; NaN where a row has no such word.

    Attributes
    ----------
    n : int
        Rows.
    line : ndarray of int64, shape (n,)
    motion : ndarray, shape (n,)
        0 or 1 where a row's one G word is G0 or G1, -1 where it is another motion (G2,
        G5.2, ...), NaN where the row leaves the motion mode as it is (to :meth:`read`).
    feed : ndarray, shape (n,)
        The F word [program units / min].
    axis : dict of int to ndarray, shape (n,)
        The words of each axis (index into X..W) that occurs in the run.
    has_axis, has_feed : ndarray of bool, shape (n,)
    ok : ndarray of bool, shape (n,)
        Rows that :meth:`_Reader.read` reads on its lean path when the reader's state
        allows: no M word, at most one G word (G0 or G1), only axis and F words, every
        value in range. Other rows go through :meth:`_Reader.read`.
    """

    def __init__(self, table, start: int, stop: int):
        n = self.n = stop - start
        offsets = table.offsets[start: stop + 1]
        code = table.letter[offsets[0]: offsets[-1]]
        value = table.value[offsets[0]: offsets[-1]]
        row = np.repeat(np.arange(n), np.diff(offsets))
        self.line = table.line[start:stop]
        is_g, is_m, is_f = code == ord("G"), code == ord("M"), code == ord("F")
        axis = _AXIS_OF_CODE[code]
        is_axis = axis >= 0
        count = lambda mask: np.bincount(row[mask], minlength=n)  # noqa: E731
        n_g = count(is_g)
        g = np.full(n, np.nan)
        g[row[is_g]] = value[is_g]
        one_g = n_g == 1
        lean_g = one_g & ((g == 0.0) | (g == 1.0))
        self.motion = np.full(n, np.nan)
        self.motion[lean_g] = g[lean_g]
        self.motion[one_g & np.isin(g, _OTHER_MOTION)] = -1.0
        self.feed = np.full(n, np.nan)
        self.feed[row[is_f]] = value[is_f]
        self.has_feed = ~np.isnan(self.feed)
        self.axis = {}
        for i in np.unique(axis[is_axis]).tolist():
            column = self.axis[i] = np.full(n, np.nan)
            at = axis == i
            column[row[at]] = value[at]
        self.has_axis = count(is_axis) > 0
        out_of_range = (is_axis & ~(np.abs(value) <= MAX_COORDINATE)) | (
            is_f & ~((value >= 0) & (value <= MAX_COORDINATE)))
        self.ok = ((n_g == 0) | lean_g) & (count(is_m) == 0) & (count(~(is_g | is_f | is_axis)) == 0) \
            & (count(out_of_range) == 0)
        self._other = np.append(np.flatnonzero(~self.ok), n)

    def next_other(self, s: int) -> int:
        """The first row at or after ``s`` that is not ``ok`` (``n`` if none)."""
        return int(self._other[np.searchsorted(self._other, s)])


class _RunState:
    """The reader's state through rows ``s .. e - 1`` of a run as :meth:`_Reader.read`'s
    lean path leaves it, from the reader's state now; rows that are not ``ok`` count with
    their own G0/G1/motion, F and axis words (:meth:`agrees` checks that after
    :meth:`_Reader.read` has read them). Entry ``j`` of the arrays is the state before
    row ``s + j``.

    Attributes
    ----------
    motion : ndarray, shape (e - s + 1,)
        0 (G0), 1 (G1) or -1 (another motion mode, or none).
    feed : ndarray, shape (e - s + 1,)
        [output units / min]
    stops : ndarray of int64
        Rows (absolute in the run) that the bulk cannot apply: not ``ok``, an axis move
        under a motion other than G0/G1, a G1 of path and other axes together, a G1
        without a feed; ``e`` last.
    pieces, breaks : ndarray of int64
        Rows that add a line piece; rows that end the contour (a rapid that moves, a G1
        of an axis outside the path only).
    """

    def __init__(self, reader: "_Reader", run: _RunColumns, s: int, e: int):
        self.s, self.e = s, e
        self.k, self.scale = list(reader.lengths()), reader.scale()
        self.start = list(reader.pos)
        self.motion = _forward_fill(run.motion[s:e], {"G0": 0.0, "G1": 1.0}.get(reader.motion, -1.0))
        self.feed = _forward_fill(run.feed[s:e] * self.scale, reader.feed)
        self._columns = {i: _forward_fill(col[s:e] * self.k[i], self.start[i]) for i, col in run.axis.items()}
        moves_path, moves_other = np.zeros(e - s, dtype=bool), np.zeros(e - s, dtype=bool)
        for i, col in self._columns.items():
            moved = col[1:] != col[:-1]
            if i in reader.axes:
                moves_path |= moved
            else:
                moves_other |= moved
        travel, motion = run.has_axis[s:e], self.motion[1:]
        g0, g1 = travel & (motion == 0.0), travel & (motion == 1.0)
        stop = ~run.ok[s:e] | (travel & ~(g0 | g1)) | (g1 & moves_path & (moves_other | (self.feed[1:] <= 0)))
        self.stops = np.append(s + np.flatnonzero(stop), e)
        self.pieces = s + np.flatnonzero(g1 & moves_path & ~stop)
        self.breaks = s + np.flatnonzero((g0 & (moves_path | moves_other)) | (g1 & moves_other & ~moves_path))

    def column(self, i: int, rows: np.ndarray):
        """Axis ``i`` before the rows ``rows`` (relative to ``s``) [output units]: an array,
        or its start value where the run never moves it (no array of the whole run per
        call: a stretch between two stop rows costs its own rows only)."""
        col = self._columns.get(i)
        return col[rows] if col is not None else self.start[i]

    def position(self, j: int) -> list:
        """X..W before row ``s + j`` [output units]."""
        pos = list(self.start)
        for i, col in self._columns.items():
            pos[i] = float(col[j])
        return pos

    def agrees(self, reader: "_Reader", s: int) -> bool:
        """Whether the reader's state before row ``s`` is this one's."""
        if not self.s <= s < self.e:
            return False
        j = s - self.s
        return (reader.pos == self.position(j) and reader.feed == self.feed[j]
                and {"G0": 0.0, "G1": 1.0}.get(reader.motion, -1.0) == self.motion[j]
                and reader.lengths() == self.k and reader.scale() == self.scale)

    def next_stop(self, s: int) -> int:
        return int(self.stops[np.searchsorted(self.stops, s)])


def _forward_fill(values: np.ndarray, first: float) -> np.ndarray:
    """``first`` followed by ``values`` (shape (m,)) with each NaN replaced by the last
    number before it; shape (m + 1,)."""
    full = np.concatenate([[first], values])
    index = np.where(np.isnan(full), 0, np.arange(len(full)))
    np.maximum.accumulate(index, out=index)
    return full[index]


class _NeedAxes(Exception):
    """A feed move changes these axes (letters) together with the path axes: read again
    with them (:func:`load_gcode` without ``axes``)."""

    def __init__(self, letters: set):
        super().__init__("".join(sorted(letters)))
        self.letters = letters


def _read_program(path: Path, axes: str, project: bool, auto: bool, rapids: bool = False) -> _Reader:
    reader = _Reader(str(path), axes)
    reader.project, reader.auto, reader.rapids_as_path = project, auto, rapids
    lines = split_lines(path.read_bytes(), str(path), upper=True)
    program = Program(lines, str(path), reader.system_parameter)  # upper-cased: plain lines in bulk
    del lines  # the program keeps what it needs
    reader.program = program
    for item in program.blocks(runs=True):
        if not (reader.read_rows(item) if isinstance(item, Rows) else reader.read(item)):
            break
    reader.finish()
    return reader


def _project(contour: GcodeContour, cols: list) -> GcodeContour:
    c = contour.curve
    curve = NurbsCurve(c.degree, c.knots, c.control_points[:, cols], c.weights, name=c.name, units=c.units)
    return GcodeContour(curve, contour.piece_edges, contour.programmed_feed, contour.lines)


def load_gcode(file: str | os.PathLike, axes: str | None = "xy", *, project: bool = False) -> GcodeProgram:
    """Read the contours of a G-code program (see the module docstring).

    Parameters
    ----------
    file : str or path-like
        The program.
    axes : str or None
        The machine's axes that form the path, in order, from ``XYZABCUVW`` (e.g. ``"xy"``
        for a 2-axis machine, ``"xyz"`` for a 3-axis one). A move of any other axis ends
        the contour; a feed move of another axis together with path axes is refused (or
        projected, with ``project``). None: every axis the program moves (by a feed or a
        rapid), in the order X Y Z A B C U V W (what ``nurbsmotion contours`` lists).
    project : bool
        Read a feed move of other axes together with path axes as its projection on the
        path axes (``--project xy``: a helix becomes its circle) instead of refusing it.

    Returns
    -------
    GcodeProgram
        Its contours (each a joined NurbsCurve with per-piece feeds), units and axes. A
        program whose feed moves change axes outside the path (a plunge in Z on an XY
        machine) gets one :class:`GcodeWarning` naming them and the machine that would
        follow them.

    Raises
    ------
    PathFileError
        At the first malformed line or the first thing that changes the path but is not
        read, naming the file, the line and the value.
    """
    path = check_input_file(file)
    auto = axes is None
    axes = "XYZ" if auto else str(axes).upper()
    if not axes or len(set(axes)) != len(axes) or not set(axes) <= set(_AXES):
        raise PathFileError(f"path axes {axes!r} must be distinct letters of {_AXES}", str(path))
    rapids = False
    for _ in range(2 * len(_AXES)):
        with warnings.catch_warnings(record=True) as caught:  # shown once, from the last pass
            warnings.simplefilter("always")
            try:
                reader = _read_program(path, axes, project, auto, rapids)
            except _NeedAxes as exc:
                axes = "".join(a for a in _AXES if a in set(axes) | exc.letters)
                continue
        if not reader.contours and not reader.fed_outside and not rapids and any(reader.moved):
            rapids = True  # no feed move at all: LinuxCNC's planner tests of rapids
            continue
        for c in reader.contours:  # an arc or a spline moves its plane's axes between its ends
            for col, i in enumerate(reader.axes):
                reader.moved[i] = reader.moved[i] or bool(np.ptp(c.curve.control_points[:, col]) > 0)
        moved = "".join(a for i, a in enumerate(_AXES) if reader.moved[i])
        if not auto or set(moved) <= set(axes):
            break
        axes = "".join(a for a in _AXES if a in set(axes) | set(moved))
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    contours = reader.contours
    if auto and moved and moved != axes:  # an axis of the first guess (XYZ) that never moves
        contours = [_project(c, [axes.index(a) for a in moved]) for c in contours]
        axes = moved
    if reader.fed_outside:
        outside = "".join(_AXES[i] for i in sorted(reader.fed_outside))
        first = min(reader.fed_outside.values())
        every = "".join(a for a in _AXES if a in set(axes) | set(outside))
        reader.line = first
        reader.warn(f"feed moves of {outside} (the first here) are not part of the contours on "
                    f"the axes {axes}; a machine with the axes {every} would follow them")
    if rapids and contours:
        text = (f"{path}: the program has no feed move: its rapids (G0) are read as the path, "
                "with no programmed feed (give one)")
        reader.warnings.append(text)
        warnings.warn(text, GcodeWarning, stacklevel=2)
    if not contours:
        raise PathFileError(f"the program has no feed move of the path axes {axes} to make a path from",
                            str(path))
    return GcodeProgram(tuple(contours), reader.units or "mm", str(path), tuple(reader.warnings), axes,
                        reader.units_source, rapids)

# ---------------------------------------------------------------------- writer
def format_number(x: float, decimals: int) -> str:
    """``x`` in plain positional notation (G-code has no exponents), at most ``decimals``
    digits after the point, trailing zeros trimmed."""
    text = np.format_float_positional(float(x), precision=decimals, unique=True, trim="-")
    return "0" if text in ("-0", "-0.") else text


def decimals_for(size: float, significant: int = 12) -> int:
    """Digits after the point that give ``significant`` digits relative to ``size``."""
    return max(0, significant - int(math.floor(math.log10(size))) - 1) if size > 0 else significant


def save_gcode(
    curve: NurbsCurve,
    file: str | os.PathLike,
    *,
    feed: float,
    units: str | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``curve`` as a LinuxCNC program of G5.2 NURBS blocks (see the module docstring).

    Parameters
    ----------
    curve : NurbsCurve
        A 2-axis path.
    file : str or path-like
        Output program (``.ngc``).
    feed : float
        Programmed feed [path units / s]; written as F in units per minute.
    units : {"mm", "inch"}, optional
        Units to declare (G21/G20); defaults to ``curve.units``, which must then be one of
        these. Numbers are written as they are, not converted.
    overwrite : bool
        Replace an existing file.

    Raises
    ------
    PathFileError
        For a curve that is not 2-axis, units that G-code cannot declare, or a bad feed.
    OutputExistsError
        If the file exists and ``overwrite`` is false.
    """
    units = units or curve.units
    if units not in ("mm", "inch"):
        raise PathFileError(
            f"G-code declares mm (G21) or inch (G20), but the curve is in {curve.units!r}; "
            "scale it (e.g. curve.scaled(1e-3, units='mm') for pulses of 1 um) or pass "
            "units='mm' to write its numbers unchanged",
            source=str(file),
        )
    if curve.n_axes != 2:
        raise PathFileError(f"G5.2 carries XY paths; the curve has {curve.n_axes} axes", str(file))
    if not (np.isfinite(feed) and feed > 0):
        raise PathFileError(f"feed must be finite and > 0, got {feed!r}", str(file))
    d = decimals_for(float(np.max(np.ptp(curve.control_points, axis=0))))

    def xy(point) -> str:
        return f"X{format_number(point[0], d)} Y{format_number(point[1], d)}"

    def weight(w) -> str:
        return format_number(w, decimals_for(abs(w), 15))

    lines = [
        f"(nurbsmotion path {curve.name or ''}: {curve.n_control_points} control points, "
        f"degree {curve.degree}, length {curve.length:.9g} {units})",
        f"{'G21' if units == 'mm' else 'G20'} G90 G17 G94",
        f"G0 {xy(curve.control_points[0])}",
        f"F{format_number(feed * 60.0, decimals_for(feed * 60.0, 12))}",
    ]
    source = elevate_degree(curve, 2) if curve.degree < 2 else curve
    order = source.degree + 1
    for segment in bezier_segments(source):
        w = segment.weights
        lines.append(f"G5.2 P{weight(w[0])} L{order}")
        lines.extend(f"     {xy(pt)} P{weight(wi)}" for pt, wi in zip(segment.control_points[1:], w[1:]))
        lines.append("G5.3")
    lines.append("M2")
    text = "\n".join(lines) + "\n"
    return write_output(file, lambda f: f.write(text), overwrite=overwrite)
