"""The G and M codes, words and limits the G-code reader knows, as tables, and the small
helpers its parts share (code names, the picker of path coordinates, the signal that a
program needs more path axes). Axes are indexed X..W = 0..8 throughout.
"""

from __future__ import annotations

from operator import itemgetter

from ...errors import PathFileError

_INCH = 25.4  # [mm / inch]

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
    4.0: "G4 dwell", 43.0: "G43 tool length offset (not applied)",
    43.1: "G43.1 tool length offset (not applied)", 43.2: "G43.2 tool length offset (not applied)",
    49.0: None, 61.0: None, 61.1: None, 64.0: "G64 path blending tolerance",
    94.0: None, 96.0: "G96 constant surface speed", 97.0: "G97 spindle RPM mode",
    7.0: "G7 lathe diameter mode", 8.0: "G8 lathe radius mode",
    17.0: None, 18.0: None, 19.0: None,
}  # fmt: skip
_REFUSED_G = {
    **dict.fromkeys((17.1, 18.1, 19.1), "the UVW planes are not read: write the arcs in G17, G18 or G19"),
    76.0: "the G76 threading cycle is not read (its passes follow the spindle, which the "
          "path cannot; write the passes as G33 or G1 moves)",
    **dict.fromkeys((38.2, 38.3, 38.4, 38.5), "probing is not read (its moves end where the probe touches "
                    "the part): remove the probing lines, or write the moves they make"),
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
MIN_MOVE = 1e-12
"""Shortest G0/G1 move of the path axes kept [output units]: LinuxCNC's trajectory planner
drops a shorter segment (``TP_POS_EPSILON``, ``TP_ERR_ZERO_LENGTH`` in ``tp.c``), and a
piece far below the rounding of its coordinates has no direction to plan a speed along
(LinuxCNC's ``nc_files/cone.ngc``'s ``100*sin[-180]`` = -1.2e-14 mm)."""
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



class AxesOutsidePath(PathFileError):
    """A feed move changes axes outside the path together with the path axes (a machine's
    axes given): the message names the axes a machine needs to follow it, and, where the
    program moves more (:func:`load_gcode` reads it again to find them), those too: a user
    who adds only this line's axes would meet the next refusal further down.

    Parameters
    ----------
    move : str
        The motion, ``"G1"``, ``"G2"``, ...
    path_axes, others : str
        The path's axes, and the other axes the move changes (letters).
    source : str
        The file.
    line : int
        Its line.
    program_axes : str, optional
        Every axis the whole program moves, in ``XYZABCUVW`` order.
    """

    def __init__(self, move: str, path_axes: str, others: str, source: str, line: int,
                 program_axes: str | None = None):
        self.move, self.path_axes, self.others = move, path_axes, others
        self.program_axes = program_axes
        needed = "".join(a for a in _AXES if a in set(path_axes) | set(others))
        if program_axes is None or set(program_axes) <= set(needed):
            machine = f"a machine with the axes {needed} can follow it"
        else:
            machine = (f"the program moves {program_axes}: a machine with those axes can follow "
                       f"it")
        super().__init__(f"{move} moves {others} together with the path axes {path_axes}; "
                         f"{machine} (or read the path's projection on {path_axes}: "
                         f"--project {path_axes.lower()})", source, line)

    def naming(self, program_axes: str) -> "AxesOutsidePath":
        """The same refusal, naming every axis the program moves."""
        return AxesOutsidePath(self.move, self.path_axes, self.others, self.source, self.line,
                               program_axes)


class _NeedAxes(Exception):
    """A feed move changes these axes (letters) together with the path axes: read again
    with them (:func:`load_gcode` without ``axes``)."""

    def __init__(self, letters: set):
        super().__init__("".join(sorted(letters)))
        self.letters = letters
