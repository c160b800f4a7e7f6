"""Cutter radius compensation of the G-code reader (G40, G41, G42, G41.1, G42.1) as
LinuxCNC's interpreter computes it, in the XY plane (G17) and the XZ plane (G18, a lathe's;
G19 is refused as LinuxCNC refuses it). A part of
:class:`~nurbsmotion.paths.gcode.reader._Reader`.

The algorithm is written for the XY plane; in G18 it runs on the plane's axes (Z, X) with
Y off the plane, as LinuxCNC's ``comp_get_current`` turns them. A lathe tool's orientation
(``G41.1/G42.1 L``, or ``Q`` of its tool table line or of ``G10 L1``; 1-8 in G18) names
its origin, which lies off the centre of its nose radius by the radius in Z and X: every
compensated move is sent moved by that (LinuxCNC's ``latheorigin_x/_z``), and an entry
arc starts with a line to the tool's origin.

The programmed contour is the part's edge; with G41 (tool left of the direction of
motion) or G42 (right) the tool centre runs at the tool radius ``r`` beside it. The
algorithm is LinuxCNC 2.9's (``convert_straight_comp1/2``, ``convert_arc_comp1/2`` in
``interp_convert.cc``, ``move_endpoint_and_flush`` in ``interp_queue.cc``), written anew:

* The first move after G41/G42 is the *entry move*: a line ends ``r`` beside the programmed
  end point, perpendicular to the line from the start (it must be longer than ``r``); an
  arc ends ``r`` inside or outside its programmed end, on an arc through the current point.
* Every later move is offset by ``r``; the previous move is held back (LinuxCNC's queue) so
  that at a *concave* corner (the tool inside) its end can be moved back to where the two
  offset moves meet: line-line, line-arc, arc-line and arc-arc intersections, refused when
  the tool cannot reach the corner without gouging. At a *convex* corner turning more than
  :data:`CORNER_TOLERANCE` the tool rolls round the programmed corner on an arc of radius
  ``r`` (a rapid goes straight to that arc's end instead).
* G40 ends the compensation; the next move starts where the tool is and goes to its
  programmed end (it must be a line, as in LinuxCNC).
* Under inverse time (G93) F is 1 / the duration of the *programmed* move: LinuxCNC sets
  the feed to F times the programmed length (a line from the programmed point, or from the
  tool for the entry move and the move after G40; an arc round its programmed centre;
  ``inverse_time_rate_straight/_arc``) and feeds the offset move, and the corner arc
  before it, at that rate.

The radius: ``G41.1/G42.1 D`` (the diameter, in program units), or ``G41/G42 [D n]``: the
radius of tool ``n`` (without D: of the tool in the spindle, ``T n M6`` or ``M61 Q n``)
from the tool table (``--tool-table``, ``load_gcode(tool_table=...)``: a LinuxCNC ``.tbl`` file) or from
``G10 L1/L10/L11 P n R`` in the program; without a table given, a table named like the
program beside it (``part.tbl`` for ``part.ngc``) is read when a radius is needed, with a
warning. The table's diameters are in ``tool_table_units``, by default the program's units
(its first G20/G21: LinuxCNC's tables are in the machine's units). A negative radius swaps
the side.

Glossary: ``op`` the last programmed point, ``cur`` the tool's compensated position, both
program coordinates of the plane's axes (XY, or ZX in G18) [output units]; ``turn`` LinuxCNC's signed turn count of an arc
(> 0 counter-clockwise).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from ...errors import PathFileError
from ..pieces import HELIX_TOLERANCE, arc_sweep
from .codes import _AXES, _INCH, _PLANES, AxesOutsidePath, _NeedAxes

__all__ = ["read_tool_table", "CORNER_TOLERANCE"]

CORNER_TOLERANCE = 0.05
"""Angle below which a corner of the compensated path is taken as straight [rad]
(LinuxCNC's ``TOLERANCE_CONCAVE_CORNER``)."""
_EQUAL = 0.0001  # LinuxCNC's TOLERANCE_EQUAL: cos of an entry arc's half angle [1]
_GOUGE_INCH = 0.001  # an arc shortened this much more than its sweep gouges [inch]
_HALF_PI = 0.5 * math.pi
_TWO_PI = 2.0 * math.pi
_TBL_WORD = re.compile(r"([TPDXYZABCUVWIJQ])\s*([+-]?(?:\d+\.?\d*|\.\d+))", re.I)


def read_tool_table(file, source: str = "") -> dict:
    """Tool diameters of a LinuxCNC tool table (``T1 P1 D6.0 Z10 ;comment`` per line).

    Parameters
    ----------
    file : str or path-like
        The ``.tbl`` file.
    source : str
        The program that uses it (named in errors).

    Returns
    -------
    dict
        Tool number -> (diameter [the table's units], orientation): ``Q``, a lathe tool's
        orientation 1-9 (0, a mill, where the line has none).

    Raises
    ------
    PathFileError
        A line without a T word, or a file that cannot be read.
    """
    path = Path(file)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise PathFileError(f"cannot read the tool table {path}: {exc}; give a LinuxCNC .tbl file",
                            source) from None
    table = {}
    for n, line in enumerate(text.splitlines(), 1):
        code = line.split(";", 1)[0].strip()
        if not code:
            continue
        words = {k.upper(): float(v) for k, v in _TBL_WORD.findall(code)}
        if "T" not in words:
            raise PathFileError(f"tool table {path}, line {n}: no T word in {code!r}; each line "
                                "names its tool as LinuxCNC's .tbl does (T1 P1 D6.0)", source)
        table[int(words["T"])] = (words.get("D", 0.0), int(words.get("Q", 0.0)))
    return table


class _Queued:
    """A move held back: its end may still move to a concave corner (LinuxCNC's
    ``queued_canon``)."""

    __slots__ = ("kind", "line", "end", "direction", "centre", "turn", "sweep", "feed")

    def __init__(self, kind, line, end, feed, direction=(0.0, 0.0), centre=None, turn=0, sweep=0.0):
        self.kind = kind  # "feed", "traverse", "arc" or "stop"
        self.line = line
        self.end = end  # X..W, program coordinates [output units]
        self.feed = feed
        self.direction = direction  # a line's programmed direction (x, y)
        self.centre = centre  # an arc's centre (x, y)
        self.turn = turn
        self.sweep = sweep  # an arc's sweep when queued (0: never checked) [rad]


def _straight_length(a: list, b: list) -> float:
    """Length of a line from ``a`` to ``b`` (X..W) that an inverse-time F applies to: of
    XYZ if any of them moves more than 1e-7, else of UVW, else of ABC (LinuxCNC's
    ``find_straight_length``)."""
    for group in ((0, 1, 2), (6, 7, 8), (3, 4, 5)):
        if any(abs(b[i] - a[i]) > 1e-7 for i in group) or group == (3, 4, 5):
            return math.sqrt(sum((b[i] - a[i]) ** 2 for i in group))
    return 0.0


def _find_turn(x1, y1, cx, cy, turn, x2, y2) -> float:
    """Signed sweep [rad] of an arc of ``turn`` turns from (x1, y1) round (cx, cy) to
    (x2, y2) (LinuxCNC's ``find_turn``)."""
    if turn == 0:
        return 0.0
    a = math.atan2(y1 - cy, x1 - cx)
    b = math.atan2(y2 - cy, x2 - cx)
    if turn > 0:
        if b <= a:
            b += _TWO_PI
        return b - a + (turn - 1) * _TWO_PI
    if a <= b:
        a += _TWO_PI
    return b - a + (turn + 1) * _TWO_PI


class _Compensation:
    """The reader's cutter radius compensation (mixed into
    :class:`~nurbsmotion.paths.gcode.reader._Reader`)."""

    def comp_init(self, tool_table: dict | None, table_scale: float) -> None:
        self.comp = None  # None, or "left" / "right" while G41/G42 is on
        self.comp_radius = 0.0  # [output units]
        self.comp_first = True
        self.comp_op = (0.0, 0.0)  # last programmed point XY (program coordinates)
        self.comp_queue: list = []
        self.comp_endpoint = None  # LinuxCNC's endpoint (start of the queued move), or None
        self.comp_xyz = [0.0] * 9  # the tool's position X..W after the last compensated move
        self.comp_exit = None  # after G40: the programmed XY the next move's words start from
        self.tools = {}  # tool -> radius [output units] from G10 L1/L10/L11 R
        self.tool_orientations = {}  # tool -> a lathe tool's orientation from G10 L1/L10/L11 Q
        self.tool_table = tool_table  # tool -> (diameter [table units], orientation), or None
        self.table_scale = table_scale  # table units -> mm, or None: the program's units
        self.sibling_table = tool_table is None  # may look for PROGRAM.tbl beside the program
        self.tool_selected = 0
        self.tool_in_spindle = 0
        self.c1, self.c2 = 0, 1  # the plane's first and second axes (G17: X, Y; G18: Z, X)
        self.comp_shift = None  # G18 with a lathe tool: (Z, X) from the radius centre to its origin

    # -- the tool's radius
    def tool_radius(self, tool: int, code: str) -> float:
        """Radius of ``tool`` [output units] from G10 L1 R or the tool table."""
        if tool in self.tools:
            return self.tools[tool]
        if self.tool_table is None and self.sibling_table and tool != 0:
            self.sibling_table = False
            sibling = Path(self.source).with_suffix(".tbl")
            if sibling.is_file():
                self.tool_table = read_tool_table(sibling, self.source)
                self.warn(f"{code}: tool radii from the tool table {sibling.name} beside the program, "
                          "its diameters in the program's units")
        if self.tool_table is not None and tool in self.tool_table:
            diameter = self.tool_table[tool][0]
            if self.table_scale is None:  # the program's units: the output units
                return 0.5 * diameter
            to_out = 1.0 if self.units in (None, "mm") else 1.0 / _INCH
            return 0.5 * diameter * self.table_scale * to_out
        if tool == 0:
            return 0.0
        if self.tool_table is None:
            raise self.error(f"{code} uses the radius of tool {tool}, and no tool table is given: "
                             f"put it beside the program as {Path(self.source).stem}.tbl (LinuxCNC's "
                             "format) or pass it (--tool-table FILE.tbl; load_gcode(..., tool_table=)), set it in the "
                             f"program (G10 L1 P{tool} R<radius>) or write G41.1/G42.1 D<diameter>")
        raise self.error(f"{code}: tool {tool} is not in the tool table; add it to the table or "
                         "write G41.1/G42.1 D<diameter>")

    def tool_orientation(self, tool: int) -> int:
        """A lathe tool's orientation (0: a mill) from G10 L1 Q or the tool table (LinuxCNC's
        ``Q``), read where its radius was."""
        if tool in self.tool_orientations:
            return self.tool_orientations[tool]
        if tool not in self.tools and self.tool_table is not None and tool in self.tool_table:
            return self.tool_table[tool][1]
        return 0

    def set_tool_entry(self, w: dict) -> None:
        """G10 L1/L10/L11 P<tool> R<radius> Q<orientation>: what cutter compensation uses."""
        p = w.get("P", 0.0)
        if ("R" in w or "Q" in w) and (p != int(p) or p < 0):
            raise self.error(f"G10 tool number P{p:g} must be a whole number >= 0")
        if "R" in w:
            self.tools[int(p)] = self.lengths()[0] * self.value("R", w["R"])
        if "Q" in w:
            q = w["Q"]
            if q != int(q) or not 0 <= q <= 9:
                raise self.error(f"G10 tool orientation Q{q:g} must be a whole number 0-9 (LinuxCNC's "
                                 "lathe tool orientations)")
            self.tool_orientations[int(p)] = int(q)

    def cutter_comp(self, g: float, w: dict) -> None:
        """G40, G41, G42, G41.1, G42.1 on this line (before its motion, as in LinuxCNC)."""
        if g == 40.0:
            w.pop("D", None)
            self.comp_off()
            return
        code = f"G{g:g}"
        if self.comp is not None:
            raise self.error(f"{code} while cutter compensation is already on: turn it off with G40 "
                             "first (and make a new entry move)")
        if self.plane not in (17.0, 18.0):
            raise self.error(f"{code}: cutter radius compensation allowed only in XY, XZ planes (as "
                             f"LinuxCNC says): select G17 or G18 before it (the program is in "
                             f"G{self.plane:g})")
        self.c1, self.c2 = _PLANES[self.plane][:2]
        if "L" in w and g in (41.1, 42.1) and self.plane != 18.0:
            raise self.error(f"{code} with an L word (a lathe tool's orientation), but the plane is "
                             f"not G18 (as LinuxCNC refuses it): select G18 or remove the L word")
        orientation = w.pop("L", 0.0) if g in (41.1, 42.1) else 0.0
        if orientation != int(orientation) or not 0 <= orientation <= 9:
            raise self.error(f"{code} L{orientation:g}: L is a lathe tool's orientation, a whole "
                             "number 0-9 (LinuxCNC's)")
        w.pop("L", None)
        if g in (41.1, 42.1):
            if "D" not in w:
                raise self.error(f"{code} needs the tool diameter as a D word ({code} D6)")
            radius = 0.5 * self.lengths()[0] * self.value("D", w.pop("D"))
        else:
            if "D" in w:
                d = w.pop("D")
                if d != int(d) or d < 0:
                    raise self.error(f"{code} D{d:g}: D is a tool number (a whole number >= 0); "
                                     f"for a diameter write {code}.1 D{d:g}")
                tool = int(d)
            else:
                tool = self.tool_in_spindle
            radius = self.tool_radius(tool, code)
            orientation = self.tool_orientation(tool)
            if self.plane != 18.0 and orientation not in (0, 9):
                raise self.error(f"{code} with a lathe tool (tool {tool}, orientation {orientation}), but "
                                 "the plane is not G18 (as LinuxCNC refuses it): select G18, or a "
                                 "tool without an orientation")
        left = g in (41.0, 41.1)
        if radius < 0.0:  # LinuxCNC: a negative radius swaps the side
            radius, left = -radius, not left
        if radius == 0.0:
            self.warn(f"{code} with a tool of radius 0: the path is not offset (give the tool's "
                      "radius: D, G10 L1 R or the tool table)", "comp radius 0")
        self.comp = "left" if left else "right"
        self.comp_radius = radius
        self.comp_first = True
        self.comp_shift = None
        o = int(orientation)
        if self.plane == 18.0 and o not in (0, 9) and radius > 0.0:
            # LinuxCNC's latheorigin_x/_z: the point a lathe tool's orientation names is its
            # origin, not the centre of its nose radius that the offset path is of
            dz = -radius if o in (2, 7, 3) else radius if o in (1, 5, 4) else 0.0
            dx = -radius if o in (2, 6, 1) else radius if o in (3, 8, 4) else 0.0
            self.comp_shift = (dz, dx)

    def comp_active(self) -> bool:
        """Whether moves are offset (compensation on with a radius > 0)."""
        return self.comp is not None and self.comp_radius > 0.0

    def comp_refuse(self, what: str) -> None:
        if self.comp is not None:
            raise self.error(f"{what} is not allowed while cutter radius compensation is on "
                             "(as in LinuxCNC): turn it off with G40 before this line")

    def comp_off(self) -> None:
        if self.comp_active() and not self.comp_first:
            cx, cy = self.comp_cur()
            self.move_endpoint_and_flush(cx, cy)
            self.comp_exit = self.comp_op
        self.comp = None
        self.comp_first = True
        self.comp_shift = None

    # -- coordinates
    def comp_cur(self) -> tuple:
        """The tool's position XY, program coordinates."""
        p = self.comp_tool()
        return p[self.c1], p[self.c2]

    def comp_tool(self) -> list:
        """The tool's position X..W, program coordinates: the end of the last compensated
        move (held or sent), or where the tool is before the entry move."""
        return list(self.comp_xyz) if not self.comp_first else self.to_program(self.pos)

    def comp_target(self, w: dict, machine: bool) -> list:
        """A move's programmed end [absolute X..W]: from the last programmed point where
        words are missing or incremental (LinuxCNC's find_ends)."""
        if self.comp_exit is None and (self.comp_first or not self.comp_active()):
            return self.target(w, machine=machine)
        saved = self.pos
        p = self.to_program(self.pos) if self.comp_exit is not None else self.comp_tool()
        p[self.c1], p[self.c2] = self.comp_exit if self.comp_exit is not None else self.comp_op
        self.pos = self.to_absolute_point(p)
        try:
            return self.target(w, machine=machine)
        finally:
            self.pos = saved

    # -- the queue
    def enqueue(self, kind: str, end: list, **kw) -> None:
        feed = math.nan if kind == "traverse" else self.feed
        self.comp_queue.append(_Queued(kind, self.line, end, feed, **kw))
        if kind != "stop":
            self.comp_xyz = list(end)

    def dequeue(self) -> None:
        """Send the held moves to the path."""
        self.comp_endpoint = None
        queue, self.comp_queue = self.comp_queue, []
        line, feed, inverse = self.line, self.feed, self.inverse_time
        self.inverse_time = False  # each held move carries its feed (under G93: F x its length)
        try:
            for q in queue:
                self.line = q.line
                if q.kind == "stop":
                    self.end_contour()
                    continue
                end, centre = list(q.end), q.centre
                if self.comp_shift is not None:  # a lathe tool: its origin, not its radius centre
                    d1, d2 = self.comp_shift
                    end[self.c1] += d1
                    end[self.c2] += d2
                    if centre is not None:
                        centre = (centre[0] + d1, centre[1] + d2)
                end = self.to_absolute_point(end)
                if q.kind == "arc":
                    self.comp_arc_piece(q, end, centre)
                else:
                    self.feed = q.feed
                    self.travel("G0" if q.kind == "traverse" else "G1", {}, end)
        finally:
            self.line, self.feed, self.inverse_time = line, feed, inverse

    def move_endpoint_and_flush(self, x: float, y: float) -> None:
        """Move the held moves' end to (x, y) (a concave corner), refusing a move that
        would run backwards (the tool cannot reach the corner), then send them."""
        gouge = _GOUGE_INCH * (1.0 if self.units == "inch" else _INCH)
        ep = self.comp_endpoint
        for q in self.comp_queue:
            if q.kind == "arc":
                r1 = math.hypot(q.end[self.c1] - q.centre[0], q.end[self.c2] - q.centre[1])
                r2 = math.hypot(x - q.centre[0], y - q.centre[1])
                if abs(r1 - r2) > 0.01 * self.lengths()[0]:
                    raise self.error(f"cutter compensation made an arc of {self.line_name(q.line)} with radii "
                                     f"{r1:.6g} and {r2:.6g}; check the contour near this line")
                if ep is not None and q.sweep != 0.0:
                    l2 = _find_turn(ep[0], ep[1], q.centre[0], q.centre[1], q.turn, x, y)
                    if abs(l2) > abs(q.sweep) + gouge:
                        raise self.error(self._gouge(f"the arc of {self.line_name(q.line)}"))
            elif q.kind != "stop":
                dx, dy = q.direction
                if ep is not None and dx * (x - ep[0]) + dy * (y - ep[1]) < 0:
                    raise self.error(self._gouge(f"the move of {self.line_name(q.line)}"))
            if q.kind != "stop":
                q.end = list(q.end)
                q.end[self.c1], q.end[self.c2] = x, y
        self.dequeue()
        self.comp_endpoint = (x, y)

    def _gouge(self, what: str) -> str:
        return (f"{what} ends in a concave corner the tool of radius {self.comp_radius:g} cannot "
                "reach without gouging (as LinuxCNC refuses it): use a smaller tool, or round the "
                "corner with an arc larger than the tool")

    # -- moves
    def comp_move(self, kind: str, w: dict, machine: bool) -> None:
        """A G0/G1/G2/G3 move while compensation is on, or the first after G40."""
        if machine:
            self.comp_refuse("G53 (machine coordinates)")
        if self.inverse_time and kind != "G0" and not self.f_on_line:
            raise self.error("inverse-time feed (G93) needs an F word on every feed move")
        end = self.comp_target(w, machine)
        if self.comp_exit is not None:  # the move after G40: from the tool to its end, a line
            exit_point, self.comp_exit = self.comp_exit, None
            if kind in ("G2", "G3"):
                raise self.error("the move after G40 must be a straight line (G0/G1), as in "
                                 "LinuxCNC: add a line before this arc")
            if not (self.inverse_time and kind == "G1"):
                self.travel(kind, w, end)
                return
            start = self.to_program(self.pos)  # G93: LinuxCNC's length from the programmed point
            start[self.c1], start[self.c2] = exit_point
            feed, self.feed = self.feed, self.feed_word * _straight_length(start, self.to_program(end))
            self.inverse_time = False
            try:
                self.travel(kind, w, end)
            finally:
                self.feed, self.inverse_time = feed, True
            return
        p = self.to_program(end)
        if kind in ("G0", "G1"):
            if self.inverse_time and kind == "G1":  # LinuxCNC's inverse_time_rate_straight
                start = self.comp_tool()
                if not self.comp_first:  # from the programmed point
                    start[self.c1], start[self.c2] = self.comp_op
                self.feed = self.feed_word * _straight_length(start, p)
            if self.comp_first:
                self.straight_comp1(kind, p)
            else:
                self.straight_comp2(kind, p)
        else:
            if self.comp_first:
                self.arc_comp1(kind, w, p)
            else:
                self.arc_comp2(kind, w, p)
        self._g5_pq = None

    def comp_arc_rate(self, x1: float, y1: float, start: list, ox: float, oy: float, turn: int,
                      p: list) -> None:
        """Under G93, the feed of a compensated arc [output units / min]: F times the length
        of the programmed arc from (x1, y1) round (ox, oy) to ``p`` (LinuxCNC's
        ``inverse_time_rate_arc`` and ``find_arc_length``, with the axis off the plane
        rising from ``start``'s to ``p``'s)."""
        if not self.inverse_time:
            return
        linear = _PLANES[self.plane][2]
        radius = math.hypot(ox - x1, oy - y1)
        theta = _find_turn(x1, y1, ox, oy, turn, p[self.c1], p[self.c2])
        rise = p[linear] - start[linear]
        self.feed = self.feed_word * (radius * abs(theta) if rise == 0.0 else math.hypot(radius * theta, rise))

    def comp_stop(self) -> None:
        """A dwell while compensation holds a move: it stops after that move."""
        if self.comp_queue:
            self.comp_queue.append(_Queued("stop", self.line, None, math.nan))
        else:
            self.end_contour()

    def straight_comp1(self, kind: str, p: list) -> None:
        """The entry line: it ends ``r`` beside the programmed end, perpendicular to it."""
        cx, cy = self.comp_cur()
        px, py = p[self.c1], p[self.c2]
        r = self.comp_radius
        distance = math.hypot(px - cx, py - cy)
        if distance <= r:
            raise self.error(f"the cutter compensation entry move, {distance:.6g} long, is not longer "
                             f"than the tool radius {r:g}: start it farther from the contour")
        alpha = math.atan2(py - cy, px - cx) + (_HALF_PI if self.comp == "left" else -_HALF_PI)
        end = list(p)
        end[self.c1], end[self.c2] = px + r * math.cos(alpha), py + r * math.sin(alpha)
        self.comp_endpoint = (cx, cy)
        self.enqueue("traverse" if kind == "G0" else "feed", end,
                     direction=(math.cos(alpha), math.sin(alpha)))
        self.comp_first = False
        self.comp_op = (px, py)

    def straight_comp2(self, kind: str, p: list) -> None:
        """A line after the entry: offset by ``r``, its corner with the previous move
        rolled round (convex) or cut back to the intersection (concave)."""
        cx, cy = self.comp_cur()
        cz = self.comp_tool()
        opx, opy = self.comp_op
        px, py = p[self.c1], p[self.c2]
        left = self.comp == "left"
        r = self.comp_radius
        small = CORNER_TOLERANCE
        if px == opx and py == opy:  # no XY motion: the tool stays where it is in XY
            end = list(p)
            end[self.c1], end[self.c2] = cx, cy
            self.enqueue("traverse" if kind == "G0" else "feed", end, direction=(0.0, 0.0))
            return
        theta = math.atan2(cy - opy, cx - opx)
        alpha = math.atan2(py - opy, px - opx)
        if left:
            if theta < alpha:
                theta += _TWO_PI
            beta = theta - alpha - _HALF_PI
            gamma = _HALF_PI
        else:
            if alpha < theta:
                alpha += _TWO_PI
            beta = alpha - theta - _HALF_PI
            gamma = -_HALF_PI
        end = list(p)
        end[self.c1], end[self.c2] = px + r * math.cos(alpha + gamma), py + r * math.sin(alpha + gamma)
        mid = (opx + r * math.cos(alpha + gamma), opy + r * math.sin(alpha + gamma))
        front = self.comp_queue[0] if self.comp_queue else None
        concave = beta < -small or beta > math.pi + small or (
            beta > math.pi - small and front is not None and front.kind == "arc"
            and ((not left and front.turn > 0) or (left and front.turn < 0)))  # the "h" shape
        if not concave and beta > small:  # convex: round the programmed corner
            self.move_endpoint_and_flush(cx, cy)
            corner = list(cz)
            corner[self.c1], corner[self.c2] = mid
            for i in range(3, 9):
                corner[i] = p[i]
            if kind == "G1":
                self.enqueue("arc", corner, centre=(opx, opy), turn=-1 if left else 1)
            else:
                self.enqueue("traverse", corner)
            self.dequeue()
            self.comp_endpoint = mid
        elif concave:
            if front is None or front.kind != "arc":  # line -> line
                halfcorner = 0.5 * (beta + math.pi)
                if halfcorner == 0.0:
                    raise self.error("a zero-degree inside corner cannot be compensated: the move "
                                     "turns straight back")
                retreat = r / math.tan(halfcorner)
                self.move_endpoint_and_flush(cx + retreat * math.cos(theta + gamma),
                                             cy + retreat * math.sin(theta + gamma))
            else:  # arc -> line
                ox, oy = front.centre
                oldrad = math.hypot(ox - front.end[self.c1], oy - front.end[self.c2])
                th = alpha + _HALF_PI if front.turn > 0 else alpha - _HALF_PI
                phi = math.atan2(oy - opy, ox - opx)
                inside = self._inside(front.turn)
                d = (oldrad + r if inside else oldrad - r) * math.cos(th - phi)
                ratio = (d - r if inside else d + r) / oldrad
                if not -1.0 <= ratio <= 1.0:
                    raise self.error(self._gouge(f"the arc of {self.line_name(front.line)}"))
                sign = -1.0 if (front.turn > 0) == inside else 1.0
                angle = sign * math.acos(ratio) + th + math.pi
                self.move_endpoint_and_flush(ox + oldrad * math.cos(angle), oy + oldrad * math.sin(angle))
        else:  # straight on (or a tangent arc -> line)
            self.dequeue()
            self.comp_endpoint = (cx, cy)
        self.enqueue("traverse" if kind == "G0" else "feed", end, direction=(px - opx, py - opy))
        self.comp_op = (px, py)

    def _inside(self, turn: int) -> bool:
        """Whether the tool is inside an arc of ``turn`` (LinuxCNC's TOOL_INSIDE_ARC)."""
        return (self.comp == "left" and turn > 0) or (self.comp == "right" and turn < 0)

    def _arc_data(self, kind: str, w: dict, sx: float, sy: float, ex: float, ey: float) -> tuple:
        """Centre and signed turns of an arc's words from (sx, sy) to (ex, ey), with the
        tool-inside check of LinuxCNC's arc_data_comp_ijk/_r."""
        cx, cy, turns = self.arc_centre(w, sx, sy, ex, ey)
        turn = -turns if kind == "G2" else turns
        radius = abs(w["R"]) * self.lengths()[0] if "R" in w else math.hypot(cx - sx, cy - sy)
        if radius <= self.comp_radius and self._inside(turn):
            raise self.error(self._too_small(radius))
        return cx, cy, turn

    def _too_small(self, radius: float) -> str:
        return (f"the arc's radius {radius:g} is not larger than the tool radius "
                f"{self.comp_radius:g} with the tool inside it: use a smaller tool or a larger arc")

    def arc_comp1(self, kind: str, w: dict, p: list) -> None:
        """The entry arc: through the tool's position, ending ``r`` inside or outside the
        programmed end, its centre on the line from that end to the programmed centre."""
        tool = self.comp_tool()
        cx, cy = tool[self.c1], tool[self.c2]
        ex, ey = p[self.c1], p[self.c2]
        r = self.comp_radius
        if math.hypot(ex - cx, ey - cy) <= r:
            raise self.error(f"the cutter compensation entry arc ends within the tool radius {r:g} "
                             "of its start: start it farther from the contour")
        ox, oy, turn = self._arc_data(kind, w, cx, cy, ex, ey)
        self.comp_arc_rate(cx, cy, tool, ox, oy, turn, p)
        if self._inside(turn):
            gamma = math.atan2(oy - ey, ox - ex)
        else:
            gamma = math.atan2(ey - oy, ex - ox)
        self.comp_first = False
        self.comp_op = (ex, ey)
        ex, ey = ex + r * math.cos(gamma), ey + r * math.sin(gamma)
        b_len = 0.5 * math.hypot(cy - ey, cx - ex)
        ab = math.atan2(oy - ey, ox - ex)
        a = math.atan2(cy - ey, cx - ex) - ab
        if abs(math.cos(a)) < _EQUAL:
            raise self.error(self._too_small(math.hypot(ox - p[self.c1], oy - p[self.c2])))
        c_len = b_len / math.cos(a)
        ox, oy = ex + c_len * math.cos(ab), ey + c_len * math.sin(ab)
        end = list(p)
        end[self.c1], end[self.c2] = ex, ey
        if self.comp_shift is not None:  # LinuxCNC: move the lathe tool's origin first, so
            first = list(p)  # that the arc is an arc (the axes off the plane to their ends)
            first[self.c1], first[self.c2] = cx, cy
            linear = _PLANES[self.plane][2]
            first[linear] = tool[linear]
            self.enqueue("feed", first)
            self.comp_endpoint = (cx, cy)
        self.enqueue("arc", end, centre=(ox, oy), turn=turn,
                     sweep=_find_turn(cx, cy, ox, oy, turn, ex, ey))

    def arc_comp2(self, kind: str, w: dict, p: list) -> None:
        """An arc after the entry: its radius changed by ``r``, the corner with the
        previous move rolled round (convex) or cut back to the intersection (concave)."""
        opx, opy = self.comp_op
        cx, cy = self.comp_cur()
        cz = self.comp_tool()
        ex, ey = p[self.c1], p[self.c2]
        ox, oy, turn = self.arc_centre(w, opx, opy, ex, ey)
        turn = -turn if kind == "G2" else turn
        self.comp_arc_rate(opx, opy, cz, ox, oy, turn, p)
        r = self.comp_radius
        small = CORNER_TOLERANCE
        arc_radius = math.hypot(ox - ex, oy - ey)
        left = self.comp == "left"
        theta = math.atan2(cy - opy, cx - opx)
        theta = theta - _HALF_PI if left else theta + _HALF_PI
        delta = math.atan2(oy - opy, ox - opx)
        alpha = delta - _HALF_PI if kind == "G3" else delta + _HALF_PI
        beta = theta - alpha if left else alpha - theta
        if beta > 1.5 * math.pi:
            beta -= _TWO_PI
        elif beta < -_HALF_PI:
            beta += _TWO_PI
        inside = self._inside(turn)
        if inside:
            gamma = math.atan2(oy - ey, ox - ex)
            if arc_radius <= r:
                raise self.error(self._too_small(arc_radius))
        else:
            gamma = math.atan2(ey - oy, ex - ox)
            delta += math.pi
        end = list(p)
        end[self.c1], end[self.c2] = ex + r * math.cos(gamma), ey + r * math.sin(gamma)
        sweep = _find_turn(opx, opy, ox, oy, turn, ex, ey)
        front = self.comp_queue[0] if self.comp_queue else None
        if beta < -small or beta > math.pi + small or (abs(beta - math.pi) < small and not inside):
            if front is None or front.kind != "arc":  # line -> arc
                toward = arc_radius * math.sin(beta - _HALF_PI)
                if inside:
                    dist = arc_radius - r
                    ratio = (toward + r) / dist
                else:
                    dist = arc_radius + r
                    ratio = (toward - r) / dist
                if not -1.0 <= ratio <= 1.0:
                    raise self.error(self._gouge("the line before this arc"))
                if inside:
                    angle = theta + math.asin(ratio) if turn > 0 else theta - math.asin(ratio)
                else:
                    angle = theta + math.pi - math.asin(ratio) if turn > 0 else theta + math.pi + math.asin(ratio)
                self.move_endpoint_and_flush(ox + dist * math.cos(angle), oy + dist * math.sin(angle))
            else:  # arc -> arc
                px_, py_ = front.centre
                oldrad = math.hypot(py_ - front.end[self.c2], px_ - front.end[self.c1])
                newrad = arc_radius - r if inside else arc_radius + r
                arc_cc = math.hypot(py_ - oy, px_ - ox)
                if oldrad == 0.0 or arc_cc == 0.0:
                    raise self.error(f"the arc of {self.line_name(front.line)} and this one have the same centre "
                                     "and meet in a corner: cutter compensation cannot join them")
                a = (oldrad ** 2 + arc_cc ** 2 - newrad ** 2) / (2 * oldrad * arc_cc)
                if not -1.0 <= a <= 1.0:
                    raise self.error(self._gouge(f"the arc of {self.line_name(front.line)}"))
                pullback = math.acos(a)
                cc_dir = math.atan2(oy - py_, ox - px_)
                plus = (turn > 0) == self._inside(front.turn)
                direction = cc_dir + pullback if plus else cc_dir - pullback
                self.move_endpoint_and_flush(px_ + oldrad * math.cos(direction),
                                             py_ + oldrad * math.sin(direction))
            self.enqueue("arc", end, centre=(ox, oy), turn=turn, sweep=sweep)
        elif beta > small:  # convex: round the programmed corner, then the arc
            mid = (opx + r * math.cos(delta), opy + r * math.sin(delta))
            self.dequeue()
            corner = list(cz)
            corner[self.c1], corner[self.c2] = mid
            for i in range(3, 9):
                corner[i] = p[i]
            self.enqueue("arc", corner, centre=(opx, opy), turn=-1 if left else 1)
            self.dequeue()
            self.comp_endpoint = mid
            self.enqueue("arc", end, centre=(ox, oy), turn=turn, sweep=sweep)
        else:
            self.dequeue()
            self.comp_endpoint = (cx, cy)
            self.enqueue("arc", end, centre=(ox, oy), turn=turn, sweep=sweep)
        self.comp_op = (ex, ey)

    def comp_arc_piece(self, q: _Queued, end: list, centre: tuple) -> None:
        """Send a held arc to the path: from the tool's position round ``centre`` (the
        plane's program coordinates) to its end (absolute coordinates), ``|turn|`` turns."""
        start = self.pos
        self.feed = q.feed
        c1, c2 = self.c1, self.c2
        plane_centre = centre
        centre = [0.0] * 9
        centre[c1], centre[c2] = plane_centre
        centre = self.to_absolute_point(centre)
        clockwise = q.turn < 0
        others = "".join(_AXES[i] for i in range(9) if end[i] != start[i] and i not in self.axes
                         and i != c1 and i != c2)
        if others and not self.project:
            if self.auto:
                raise _NeedAxes(set(others))
            raise AxesOutsidePath(f"G{'2' if clockwise else '3'}", "".join(_AXES[i] for i in self.axes),
                                  others, self.source, self.line)
        self.note_moved("G2", start, end)
        if c1 not in self.axes or c2 not in self.axes:
            if self.auto:
                raise _NeedAxes({_AXES[c1], _AXES[c2]})
            raise self.error(f"a compensated arc needs the axes {_AXES[c1]}{_AXES[c2]} in the path (the "
                             f"path has {''.join(_AXES[i] for i in self.axes)})")
        sx, sy, ex, ey, cx, cy = start[c1], start[c2], end[c1], end[c2], centre[c1], centre[c2]
        r1, r2 = math.hypot(sx - cx, sy - cy), math.hypot(ex - cx, ey - cy)
        a0, sweep = arc_sweep((sx, sy), (ex, ey), (cx, cy), clockwise)
        turns = abs(q.turn)
        linear = any(end[i] != start[i] for i in self.axes if i != c1 and i != c2)
        cols = (self.axes.index(c1), self.axes.index(c2))
        chain = self.open_chain()
        if not linear and abs(r2 - r1) <= HELIX_TOLERANCE * r1:
            full = math.copysign(2 * math.pi, sweep)
            for _ in range(turns - 1):
                self.add_length(chain.add_arc(self.path_of(start), cols, (cx, cy), r1, a0, full), q.line)
            self.add_length(chain.add_arc(self.path_of(end), cols, (cx, cy), r1, a0, sweep), q.line)
        else:
            sweep += math.copysign(2 * math.pi * (turns - 1), sweep)
            rise = math.dist(*((p[i] for i in self.axes if i != c1 and i != c2) for p in (start, end)))
            length = math.hypot(0.5 * (r1 + r2) * sweep, rise)
            self.add_length(chain.add_spiral(self.path_of(end), cols, (cx, cy), r1, r2, a0, sweep, length),
                            q.line)
        self.pos = end
