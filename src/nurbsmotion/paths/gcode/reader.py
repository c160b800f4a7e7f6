"""The motion layer of the G-code reader: :class:`_Reader` turns the blocks that
:class:`~nurbsmotion.paths.gcode.ngc.Program` executes into contours (modal state, units,
G0/G1 moves, group-0 codes, contours and their feeds), with its frames, curves, canned
cycles and bulk path mixed in from the sibling modules; :func:`load_gcode` reads a file.

Over 800 lines on purpose: :class:`_Reader`'s modal state (plane, units, distance mode,
offsets, the current contour) is one object that every motion method reads and changes in
LinuxCNC's order; what is separable from that state already lives in the sibling modules
(frames, curves, cycles, compensation, the program's control flow in :mod:`.ngc`).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from array import array
from pathlib import Path

import numpy as np

from ..._runtime.io import check_input_file
from ...errors import InvalidArgumentError, InvalidCurveError, NurbsmotionError, PathFileError
from ...nurbs import NurbsCurve
from ..pieces import PieceChain
from .bulk import _Bulk
from .compensation import _Compensation, read_tool_table
from .codes import (_AXES, _AXIS_INDEX, _COORD_SYSTEMS, _CYCLES, _END_M, _INCH, _MOTION,
                    _MOTION_WORDS, _PLAIN_G, _PLAIN_WORDS, _REFUSED_G, _SKIPPED_G, _SKIPPED_WORDS,
                    MAX_COORDINATE, MIN_MOVE, AxesOutsidePath, _g_name, _NeedAxes, _picker, _skipped_m)
from .curves import _Curves
from .cycles import _Cycles
from .frames import _Frames
from .ngc import Program, Rows, split_lines
from .program import GcodeContour, GcodeProgram, GcodeWarning, _source_line

__all__ = ["load_gcode"]


class _Reader(_Frames, _Curves, _Cycles, _Bulk, _Compensation):
    """The motion layer: executes blocks from :class:`ngc.Program` and collects pieces."""

    def __init__(self, source: str, axes: str, tool_table: dict | None = None, table_scale: float | None = None):
        self.source = source
        self.comp_init(tool_table, table_scale)
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
        # LinuxCNC's feed groups (XYZ, UVW, ABC) among the path's columns, where it has
        # more than one: F is the speed of the first group that moves (inverse_time_length)
        groups = [[c for c, i in enumerate(self.axes) if _AXES[i] in g] for g in ("XYZ", "UVW", "ABC")]
        self.feed_groups = [g for g in groups if g] if sum(1 for g in groups if g) > 1 else None
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
        self.called: tuple = ()  # (first, end, file, first in the file) of each called file's lines
        self.first_part = False  # reading a program's first lines only: keep each contour's pieces

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

    def where(self, line: int) -> tuple[str, int]:
        """The file and its own line of the program's ``line`` (the lines of the files that
        ``o<name> call`` runs are numbered after the program's own)."""
        return _source_line(self.called, self.source, line)

    def line_name(self, line: int) -> str:
        """``"line 7"``, or ``"line 4 of square.ngc"`` for a line of a called file."""
        file, own = self.where(line)
        return f"line {own}" if file == self.source else f"line {own} of {Path(file).name}"

    def warn(self, message: str, kind: str | None = None) -> None:
        if kind is not None:
            if kind in self.warned:
                return
            self.warned.add(kind)
        file, own = self.where(self.line)
        text = f"{file}, line {own}: {message}"
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

    def value(self, letter: str, v: float) -> float:
        if not abs(v) <= MAX_COORDINATE:
            raise self.error(f"{letter}{v:g} is beyond the largest coordinate read, "
                             f"{MAX_COORDINATE:g} (MAX_COORDINATE): check the number and its units")
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
                raise self.error("polar coordinates @ ^ cannot be given with X or Y: give the point "
                                 "one way or the other")
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
            raise self.error("feed move without a feed rate: no F word (or F0) before it; give the feed "
                             "with an F word on or before this line", line)
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
            feed = self.piece_feed(self.inverse_time_length(path_end, length), self.line)
        self.piece_feeds.append(feed)
        self.piece_lines.append(self.line)

    def inverse_time_length(self, path_end: tuple, length: float) -> float:
        """The length of a line piece to ``path_end`` that a G93 feed is taken along: on a
        path with axes of several of LinuxCNC's feed groups, the first of XYZ, UVW, ABC
        that moves (so that the feed, like a G94 one, is that group's speed and the
        move takes 1 / F); else ``length``."""
        if self.feed_groups is None or not self.inverse_time:
            return length
        start = self.path_of(self.pos)
        for group in self.feed_groups:
            d = math.sqrt(sum((path_end[c] - start[c]) ** 2 for c in group))
            if d > 0:
                return d
        return length

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
        if self.first_part:  # the pieces as read, not joined (first_part.read_first_part)
            self.contours.append(self.chain)
            self.chain, self.piece_feeds, self.piece_lines = None, array("d"), array("q")
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
                and self.block is None and self.units is not None and self.identity_frame()
                and self.comp is None and self.comp_exit is None):
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
        comp_code = None  # G40, G41, G42, G41.1 or G42.1
        for g in block.g:
            if g not in _MOTION:  # G1, G01 and G1.0 are read as 1.0 exactly; others may be computed
                g = round(g, 4)
            if g in _MOTION:
                if motion == "G80" or (g == 80.0 and motion is not None):  # LinuxCNC reads G80 G0
                    motion = motion if g == 80.0 else _MOTION[g]
                    continue
                if motion is not None:
                    raise self.error(f"two motion codes on one line: {motion} and {_g_name(g)}; write "
                                     "them on two lines")
                motion = _MOTION[g]
            elif g in (20.0, 21.0):
                if self.comp is not None and self.input_inch is not None and (g == 20.0) != self.input_inch:
                    self.comp_refuse(f"changing units ({_g_name(g)})")
                self.input_inch = g == 20.0
                self._k = None
                if self.units is None:
                    self.units = "inch" if self.input_inch else "mm"
                    self.units_source = f"{_g_name(g)} on {self.line_name(self.line)}"
            elif g in (90.0, 91.0):
                self.absolute = g == 90.0
            elif g in (90.1, 91.1):
                self.arc_absolute = g == 90.1
            elif g in (93.0, 94.0, 95.0):
                if (g == 95.0) != self.per_rev or (g == 93.0) != self.inverse_time:
                    self.feed = self.feed_per_rev = 0.0  # LinuxCNC's convert_feed_mode: F anew
                self.inverse_time, self.per_rev = g == 93.0, g == 95.0
            elif g in (17.0, 18.0, 19.0):
                if g != self.plane:
                    self.comp_refuse(f"changing planes ({_g_name(g)})")
                self.plane = g
            elif g in (98.0, 99.0):
                self.retract_old_level = g == 98.0
            elif g in _COORD_SYSTEMS:
                self.comp_refuse(f"changing the coordinate system ({_g_name(g)})")
                self.program.numbered[5220] = float(_COORD_SYSTEMS[g])
                self.frame_changes += 1
            elif g in (10.0, 28.0, 28.1, 30.0, 30.1, 53.0, 92.0, 92.1, 92.2, 92.3):
                if special is not None:
                    raise self.error(f"two codes of group 0 on one line: {_g_name(special)} and "
                                     f"{_g_name(g)}; write them on two lines")
                special = g
            elif g in (40.0, 41.0, 41.1, 42.0, 42.1):
                if comp_code is not None:
                    raise self.error(f"two cutter compensation codes on one line: {_g_name(comp_code)} "
                                     f"and {_g_name(g)}")
                comp_code = g
            elif g in _REFUSED_G:
                raise self.error(f"{_g_name(g)}: {_REFUSED_G[g]}")
            elif g in _SKIPPED_G:
                if g in (61.0, 61.1, 64.0):
                    self.comp_refuse(f"changing the path control mode ({_g_name(g)})")
                if _SKIPPED_G[g]:
                    self.warn(f"{_SKIPPED_G[g]} skipped: it does not change the path", _g_name(g))
                if g == 4.0:
                    rest.pop("P", None)
                    self.comp_stop()
                elif g == 64.0:
                    rest.pop("P", None), rest.pop("Q", None)
                elif g in (43.0, 43.2):
                    rest.pop("H", None)
                elif g == 43.1:
                    for a in "XYZABCUVW":
                        rest.pop(a, None)
            else:
                raise self.error(f"{_g_name(g)} is not a LinuxCNC G code this reader knows: remove it, or "
                                 "write the moves it stands for as G0/G1/G2/G3")
        if "T" in rest:  # selected before M6 on the same line, as in LinuxCNC
            self.tool_selected = int(rest["T"])
        for m in block.m:
            if m in _END_M:
                continue
            if m in (3.0, 4.0, 5.0):
                self.spindle_on = m != 5.0
            elif m == 6.0:
                self.tool_in_spindle = self.tool_selected
            elif m == 61.0 and "Q" in rest:
                self.tool_in_spindle = self.tool_selected = int(rest["Q"])
            name = _skipped_m(m)
            if name is None:
                raise self.error(f"M{m:g} is not an M code this reader knows: remove it (M codes of "
                                 "LinuxCNC, M0-M9, M30, M48-M68, M70-M73, M100-M199, are read)")
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
        if comp_code is not None:
            self.cutter_comp(comp_code, rest)
        if not rest.keys().isdisjoint(_SKIPPED_WORDS):
            for letter, what in _SKIPPED_WORDS.items():
                if letter in rest:
                    rest.pop(letter)
                    self.warn(f"{what} skipped: it does not change the path", letter)
        self.f_on_line = "F" in rest
        if "F" in rest:
            self.set_feed(rest.pop("F"))

        if self.block is not None and self.block["kind"] == "G5.2" and motion not in (None, "G5.2", "G5.3"):
            raise self.error(f"the G5.2 block opened on {self.line_name(self.block['line'])} is not closed "
                             f"with G5.3 before this {motion}")
        if self.block is not None and self.block["kind"] == "G6.2" and motion not in (None, "G6.2"):
            self.close_g6()
        previous = self.motion
        if motion is not None:
            self.motion = motion
        if self.comp is not None and self.motion not in (None, "G0", "G1", "G2", "G3", "G80") \
                and (motion is not None or rest):
            self.comp_refuse(self.motion)
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

    # -- group 0: G10 G28 G30 G53 G92
    def non_modal(self, g: float, w: dict) -> None:
        n = self.program.numbered
        if g == 53.0:
            if not self.absolute:
                raise self.error("G53 needs absolute mode G90")
            self.move(w, machine=True)
        elif g in (28.0, 30.0):
            self.comp_refuse(_g_name(g))
            home = 5161 if g == 28.0 else 5181
            self.end_contour()
            if w:
                self.position = self.target(w)
            self.position = np.array(n[home: home + 9]) * self.lengths()
        elif g in (28.1, 30.1):
            home = 5161 if g == 28.1 else 5181
            n[home: home + 9] = list(self.position / self.lengths())
        elif g == 92.0:
            self.comp_refuse("G92")
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
                self.set_tool_entry(w)  # its R and Q: the radius and orientation compensation uses
                if set(w) - {"P", "R", "Q"}:
                    self.warn(f"G10 L{L:g} tool table entries skipped: tool offsets are not applied",
                              "G10 tool")
                return
            if L in (2.0, 20.0):
                self.comp_refuse(f"G10 L{L:g} (a coordinate system's offsets)")
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
            raise self.error(f"word(s) {', '.join(extra)} not read with {kind}: remove them")
        if self.comp is not None or self.comp_exit is not None:
            if kind in ("G0", "G1", "G2", "G3") and (self.comp_active() or self.comp_exit is not None):
                self.comp_move(kind, w, machine)
                return
            if kind not in ("G0", "G1", "G2", "G3"):
                self.comp_refuse(kind)
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
        changes_path = moves_path = path_end != self.path_of(start)
        if moves_path and kind in ("G0", "G1") and math.dist(path_end, self.path_of(start)) < MIN_MOVE:
            moves_path = False  # LinuxCNC drops it (TP_ERR_ZERO_LENGTH); the position moves
        moves_other = self.others_of(end) != self.others_of(start)
        if moves_other or changes_path:
            self.note_moved(kind, start, end)
        if kind == "G0":
            if moves_path or moves_other:
                self.end_contour()
        elif moves_other and (moves_path or kind in ("G2", "G3")) and not self.project:
            others = "".join(_AXES[i] for i in range(9) if end[i] != start[i] and i not in self.axes)
            path = "".join(_AXES[i] for i in self.axes)
            if self.auto:
                raise _NeedAxes(set(others))
            raise AxesOutsidePath(kind, path, others, self.source, self.line)
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

    def note_moved(self, kind: str, start: list, end: list) -> None:
        """Record the axes a move changes, and the first line where a feed move changes
        an axis outside the path (:attr:`moved`, :attr:`fed_outside`)."""
        for i in range(9):
            if end[i] != start[i]:
                self.moved[i] = True
                if kind != "G0" and i not in self.axes and i not in self.fed_outside:
                    self.fed_outside[i] = self.line

    def finish(self) -> None:
        if self.block is not None and self.block["kind"] == "G5.2":
            raise self.error(f"the G5.2 block opened on {self.line_name(self.block['line'])} is never closed "
                             "with G5.3 (truncated program?): close it with G5.3", self.block["line"])
        if self.block is not None:
            self.close_g6()
        self.dequeue()
        self.end_contour()



_CALL = re.compile(r"O\s*<([^>]*)>\s*CALL")
_SUB = re.compile(r"^\s*O\s*<([^>]*)>\s*(SUB|ENDSUB)\b")


def _label(text: str) -> str:
    return "".join(text.split()).lower()


def _subroutine_files(lines: list, path: Path, search: tuple) -> tuple[list, list, str]:
    """The program's lines with the subroutines it calls from files appended: for each
    ``o<name> call`` of a name the text does not define, the ``o<name> sub`` ..
    ``o<name> endsub`` lines of the first ``name.ngc`` in the program's folder, then in
    ``search`` (LinuxCNC's SUBROUTINE_PATH), and so on for the calls in those. Returns the
    lines, the parts appended as (first index, end index, file, first index in the file),
    and a note of the folders looked in."""
    folders = [path.parent] + [Path(d) for d in search]
    note = " nor a file in " + ", ".join(str(f) for f in folders)

    def scan(text_lines):
        calls = {_label(m.group(1)) for t in text_lines if "CALL" in t for m in _CALL.finditer(t)}
        subs = {_label(m.group(1)) for t in text_lines if "SUB" in t
                for m in [_SUB.match(t)] if m and m.group(2) == "SUB"}
        return calls, subs

    calls, defined = scan(lines)
    first = next((i for i, t in enumerate(lines) if t.strip()), None)
    at = len(lines)
    if first is not None and lines[first].strip() == "%":
        at = next((i for i in range(first + 1, len(lines)) if lines[i].strip() == "%"), len(lines))
    parts, added = [], []
    todo = sorted(calls - defined)
    while todo:
        name = todo.pop(0)
        if name in defined:
            continue
        defined.add(name)
        file = next((f / f"{name}.ngc" for f in folders if (f / f"{name}.ngc").is_file()), None)
        if file is None:
            continue  # the call refuses when it runs, naming the folders
        sub_lines = split_lines(file.read_bytes(), str(file), upper=True)
        marks = [(i, m.group(2)) for i, t in enumerate(sub_lines) for m in [_SUB.match(t)]
                 if m and _label(m.group(1)) == name]
        begin = next((i for i, kw in marks if kw == "SUB"), None)
        end = next((i for i, kw in marks if kw == "ENDSUB" and begin is not None and i > begin), None)
        if begin is None or end is None:
            raise PathFileError(f"the subroutine file defines no o<{name}> sub .. o<{name}> endsub: "
                                "wrap its lines in them, as LinuxCNC reads a subroutine file",
                                str(file), 1)
        body = sub_lines[begin: end + 1]
        parts.append((at + len(added), at + len(added) + len(body), str(file), begin))
        added.extend(body)
        more, subs = scan(body)
        todo.extend(sorted(more - defined))
    if added:
        lines = lines[:at] + added + lines[at:]
    return lines, parts, note


def _read_program(path: Path, axes: str, project: bool, auto: bool, rapids: bool = False,
                  tools: tuple = (None, None), search: tuple = ()) -> _Reader:
    reader = _Reader(str(path), axes, *tools)
    reader.project, reader.auto, reader.rapids_as_path = project, auto, rapids
    lines = split_lines(path.read_bytes(), str(path), upper=True)
    lines, parts, note = _subroutine_files(lines, path, search)
    reader.called = tuple(parts)
    try:
        program = Program(lines, str(path), reader.system_parameter)  # upper-cased: plain lines in bulk
        program.search_note = note
        del lines  # the program keeps what it needs
        reader.program = program
        for item in program.blocks(runs=True):
            if not (reader.read_rows(item) if isinstance(item, Rows) else reader.read(item)):
                break
        reader.finish()
    except PathFileError as exc:
        if exc.source == str(path) and exc.line is not None:  # a line of a called file: name it
            file, own = _source_line(reader.called, str(path), exc.line)
            if file != str(path):
                raise PathFileError(f"{exc.message} (in o<{Path(file).stem}>, called from {path.name})",
                                    file, own) from None
        raise
    for line in program.nested_comments[:1]:
        reader.line = line
        reader.warn(f"nested comment read as one comment ({len(program.nested_comments)} line(s)); "
                    "LinuxCNC refuses it: remove the inner parentheses for LinuxCNC")
    return reader


def _program_axes(path: Path, tool_table, tool_table_units, subroutine_path) -> str | None:
    """Every axis the program moves (``load_gcode`` without axes), or None where that read
    fails too (its own error is reported when those axes are given)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return load_gcode(path, None, tool_table=tool_table, tool_table_units=tool_table_units,
                              subroutine_path=subroutine_path).axes
    except NurbsmotionError:
        return None


def _project(contour: GcodeContour, cols: list) -> GcodeContour:
    c = contour.curve
    curve = NurbsCurve(c.degree, c.knots, c.control_points[:, cols], c.weights, name=c.name, units=c.units)
    return GcodeContour(curve, contour.piece_edges, contour.programmed_feed, contour.lines)


def load_gcode(file: str | os.PathLike, axes: str | None = "xy", *, project: bool = False,
               tool_table: str | os.PathLike | None = None, tool_table_units: str | None = None,
               subroutine_path: tuple = ()) -> GcodeProgram:
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
    tool_table : str or path-like, optional
        A LinuxCNC tool table (``.tbl``): the tool diameters ``G41 D<tool>`` / ``G42`` (the
        tool in the spindle) compensate with. Without it, ``G41.1/G42.1 D<diameter>`` and
        ``G10 L1 P<tool> R<radius>`` in the program give the radius, or a table named like
        the program beside it (``part.tbl``), read with a warning when a radius is needed.
    tool_table_units : {"mm", "inch"} or None
        The unit of the table's diameters (LinuxCNC: the machine's linear units); None: the
        program's units (its first G20/G21).
    subroutine_path : sequence of str or path-like
        Folders where ``o<name> call`` finds ``name.ngc`` when the program does not define
        ``o<name>`` (after the program's own folder; LinuxCNC's ``SUBROUTINE_PATH``). The
        lines of a called file are numbered after the program's own in ``GcodeContour.lines``
        (:meth:`GcodeProgram.source_line` gives the file and its own line); an error or a
        warning on one names that file and its own line.

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
    if tool_table_units not in ("mm", "inch", None):
        raise InvalidArgumentError(f"tool_table_units {tool_table_units!r} must be 'mm', 'inch' or None "
                                   "(the program's units)")
    scale = None if tool_table_units is None else _INCH if tool_table_units == "inch" else 1.0
    tools = (None, scale)
    if tool_table is not None:
        tools = (read_tool_table(check_input_file(tool_table), str(path)), scale)
    search = tuple(subroutine_path)
    auto = axes is None
    axes = "XYZ" if auto else str(axes).upper()
    if not axes or len(set(axes)) != len(axes) or not set(axes) <= set(_AXES):
        raise PathFileError(f"path axes {axes!r} must be distinct letters of {_AXES}", str(path))
    rapids = False
    for _ in range(2 * len(_AXES)):
        with warnings.catch_warnings(record=True) as caught:  # shown once, from the last pass
            warnings.simplefilter("always")
            try:
                reader = _read_program(path, axes, project, auto, rapids, tools, search)
            except _NeedAxes as exc:
                axes = "".join(a for a in _AXES if a in set(axes) | exc.letters)
                continue
            except AxesOutsidePath as exc:  # name every axis the program moves, not this line's
                raise exc.naming(_program_axes(path, tool_table, tool_table_units,
                                               subroutine_path)) from None
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
        subs = sorted(set(reader.program.subs) - reader.program.called)
        if subs and not reader.program.called:
            remedy = (f"it only defines {', '.join('o' + s for s in subs)} (a subroutine file): call it "
                      f"from a program (o{subs[0]} call [arguments]) and read that program")
        elif reader.fed_outside:
            outside = "".join(_AXES[i] for i in sorted(reader.fed_outside))
            remedy = f"its feed moves change only {outside}: read it on axes that include {outside}"
        else:
            remedy = "it sets modes, offsets or tools only; read a program with G1/G2/G3 moves"
        raise PathFileError(f"the program has no feed move of the path axes {axes} to make a path from: "
                            f"{remedy}",
                            str(path))
    return GcodeProgram(tuple(contours), reader.units or "mm", str(path), tuple(reader.warnings), axes,
                        reader.units_source, rapids, reader.called)
