"""G-code import (LinuxCNC and Fanuc NURBS dialects) and G5.2 export of a path.

Reading
-------
:func:`load_gcode` reads the motion of a program in the XY plane and returns a
:class:`GcodeProgram`: the *contours* it cuts, each one :class:`NurbsCurve` built by
:func:`nurbsmotion.joining.join` from the program's feed moves, plus the programmed feed
of every piece.

What is read
    ``G0`` rapid and ``G1`` linear moves; ``G2``/``G3`` arcs in centre format (``I J``,
    incremental by default, absolute under ``G90.1``) or radius format (``R``, negative
    for more than a half turn), with ``P`` turns, as exact rational arcs; ``G5`` cubic
    and ``G5.1`` quadratic splines (LinuxCNC); ``G5.2``/``G5.3`` NURBS blocks (LinuxCNC);
    ``G06.2`` NURBS (Fanuc); ``F`` feed (units per minute, ``G94``); ``G20``/``G21``;
    ``G90``/``G91``; ``G17``; ``N`` line numbers; comments in ``( )`` and after ``;``;
    ``%`` lines. Accepted because they do not change the XY path: ``G40 G49 G54 G61
    G61.1 G64 G80 G94``, ``M0 M1 M3 M4 M5 M6 M7 M8 M9``, ``S`` and ``T`` words. ``M2``
    or ``M30`` ends the program. ``G4`` (dwell) ends the current contour.
    Anything else (other G/M codes, parameters ``#``, expressions ``[ ]``, O-words, block
    delete ``/``, a second plane, a helix, inverse-time feed) is a :class:`PathFileError`
    naming the line: nothing is skipped silently.

Contours
    A 2-axis XY path cannot hold a lift or a plunge. A contour is therefore a maximal run
    of XY feed moves at a constant Z; a rapid move (``G0``) or any move that changes Z
    ends it, and the next feed move starts a new one. A feed move that changes X/Y and Z
    together (a ramp or helix) is refused. The sample ``examples/butterfly.ngc`` thus gives
    five contours. :func:`nurbsmotion.paths.resolve_path` asks the user to pick one
    (``file.ngc#k``) when there are several, rather than guessing.

LinuxCNC G5.2 (2.9, read from ``interp_convert.cc`` and ``nurbs_additional_functions.cc``)
    The current position is the first control point; ``G5.2 P-`` without X/Y sets its
    weight. Every later point needs X, Y and a positive P. ``L`` sets the order only when
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
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._io import check_input_file, write_output
from ..errors import InvalidCurveError, PathFileError
from ..joining import bezier_segments, elevate_degree, join_with_edges
from ..nurbs import NurbsCurve, make_line
from .pieces import arc_by_center, arc_by_radius

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

MAX_LINE_LENGTH = 256
"""Longest line read [characters]; LinuxCNC's own limit (LINELEN) is 255."""

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
    """

    contours: tuple
    units: str
    source: str
    warnings: tuple = field(default=())


def linuxcnc_knots(n_points: int, order: int) -> np.ndarray:
    """LinuxCNC's implicit G5.2 knot vector (``knot_vector_creator`` in
    ``nurbs_additional_functions.cc``): ``order`` zeros, ``1 .. n-order+1`` and ``order``
    times ``n-order+2``, with ``n = n_points - 1``; ``n_points + order`` entries."""
    n = n_points - 1
    return np.concatenate(
        [np.zeros(order), np.arange(1, n - order + 2), np.full(order, n - order + 2)]
    ).astype(float)


# ---------------------------------------------------------------------- tokenizer
_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")


def _strip_comments(text: str, line: int, source: str) -> str:
    out = []
    i = 0
    while i < len(text):
        ch = text[i]
        if ch == ";":
            break
        if ch == "(":
            close = text.find(")", i + 1)
            if close < 0:
                raise PathFileError("comment '(' is not closed on this line", source, line)
            if "(" in text[i + 1 : close]:
                raise PathFileError("nested comments are not allowed", source, line)
            i = close + 1
            continue
        out.append(ch)
        i += 1
    return "".join(out)


def _words(text: str, line: int, source: str) -> list[tuple[str, float]]:
    code = "".join(_strip_comments(text, line, source).split()).upper()
    words = []
    pos = 0
    while pos < len(code):
        match = _WORD.match(code, pos)
        if not match:
            bad = code[pos : pos + 20]
            hint = ""
            if "#" in bad or "[" in bad or bad[0] == "O":
                hint = " (parameters, expressions and O-words are not supported)"
            raise PathFileError(f"cannot read {bad!r}{hint}", source, line)
        words.append((match.group(1), float(match.group(2))))
        pos = match.end()
    return words


def _lines(path: Path):
    """(line number, text) of each line, decoded lazily with a length cap."""
    with open(path, "rb") as f:
        number = 0
        while True:
            raw = f.readline(MAX_LINE_LENGTH + 2)
            if not raw:
                return
            number += 1
            if len(raw.rstrip(b"\r\n")) > MAX_LINE_LENGTH:
                raise PathFileError(
                    f"line is longer than {MAX_LINE_LENGTH} characters; is this a G-code file?",
                    str(path),
                    number,
                )
            try:
                yield number, raw.decode("ascii").rstrip("\r\n")
            except UnicodeDecodeError:
                raise PathFileError(
                    "line holds non-ASCII bytes; is this a G-code file?", str(path), number
                ) from None


# ---------------------------------------------------------------------- reader
_MOTION = {0.0: "G0", 1.0: "G1", 2.0: "G2", 3.0: "G3", 5.0: "G5", 5.1: "G5.1",
           5.2: "G5.2", 5.3: "G5.3", 6.2: "G06.2"}  # fmt: skip
_HARMLESS_G = {17.0, 40.0, 49.0, 54.0, 61.0, 61.1, 64.0, 80.0, 94.0}
_HARMLESS_M = {0.0, 1.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0}
_END_M = {2.0, 30.0}


def _g_name(value: float) -> str:
    return f"G{value:g}"


class _Reader:
    """State machine over the lines of one program."""

    def __init__(self, source: str):
        self.source = source
        self.units: str | None = None  # output units
        self.input_inch: bool | None = None
        self.absolute = True
        self.arc_absolute = False
        self.position = np.zeros(3)  # x, y, z [output units]
        self.feed = 0.0  # [output units / min]
        self.motion: str | None = None
        self.pieces: list[tuple[NurbsCurve, int, float]] = []
        self.contours: list[GcodeContour] = []
        self.warnings: list[str] = []
        self.block: dict | None = None  # open G5.2 or G06.2 block
        self._g5_pq: np.ndarray | None = None  # last G5's P Q, for a G5 without I J
        self.line = 0

    # -- helpers
    def error(self, message: str, line: int | None = None) -> PathFileError:
        return PathFileError(message, self.source, line if line is not None else self.line)

    def warn(self, message: str) -> None:
        text = f"{self.source}, line {self.line}: {message}"
        self.warnings.append(text)
        warnings.warn(text, GcodeWarning, stacklevel=4)

    def scale(self) -> float:
        if self.units is None:
            self.units = "mm"
            self.input_inch = False
            self.warn("no G20/G21 before the first move; reading millimetres (G21)")
        if self.input_inch == (self.units == "inch"):
            return 1.0
        return _INCH if self.input_inch else 1.0 / _INCH

    def target(self, words: dict, base: np.ndarray | None = None) -> np.ndarray:
        """End point of a move from its X/Y/Z words [output units]: absolute under G90,
        relative to ``base`` (default: the current position) under G91."""
        k = self.scale()
        end = self.position.copy()
        ref = self.position if base is None else base
        for axis, letter in enumerate("XYZ"):
            if letter in words:
                end[axis] = k * words[letter] + (0.0 if self.absolute else ref[axis])
        return end

    def add_piece(self, curve: NurbsCurve, line: int) -> None:
        if self.feed <= 0:
            raise self.error("feed move without a feed rate: no F word (or F0) before it", line)
        self.pieces.append((curve, line, self.feed))

    def end_contour(self) -> None:
        if not self.pieces:
            return
        curves = [c for c, _, _ in self.pieces]
        try:
            curve, edges = join_with_edges(
                curves, name=f"{Path(self.source).stem}#{len(self.contours) + 1}", units=self.units
            )
        except InvalidCurveError as exc:
            raise self.error(f"cannot join the moves into one path: {exc}", self.pieces[0][1]) from None
        self.contours.append(
            GcodeContour(
                curve,
                edges,
                np.array([f for _, _, f in self.pieces]),
                tuple(n for _, n, _ in self.pieces),
            )
        )
        self.pieces = []

    def make(self, build, line: int):
        """Run a piece constructor, turning InvalidCurveError into a PathFileError."""
        try:
            return build()
        except InvalidCurveError as exc:
            raise self.error(str(exc), line) from None

    # -- one line
    def read_line(self, words: list[tuple[str, float]]) -> bool:
        """Process one line; return False when the program ends (M2/M30)."""
        gs = [v for k, v in words if k == "G"]
        ms = [v for k, v in words if k == "M"]
        rest: dict[str, float] = {}
        for k, v in words:
            if k in "GMN":
                continue
            if k in rest:
                raise self.error(f"word {k} appears twice")
            rest[k] = v

        motion = None
        dwell = False
        for g in gs:
            g = round(g, 4)
            if g in _MOTION:
                if motion is not None:
                    raise self.error(f"two motion codes on one line: {motion} and {_g_name(g)}")
                motion = _MOTION[g]
            elif g in (20.0, 21.0):
                self.input_inch = g == 20.0
                if self.units is None:
                    self.units = "inch" if self.input_inch else "mm"
            elif g in (90.0, 91.0):
                self.absolute = g == 90.0
            elif g in (90.1, 91.1):
                self.arc_absolute = g == 90.1
            elif g == 4.0:
                dwell = True
            elif g in (18.0, 19.0):
                raise self.error(f"{_g_name(g)} selects another plane; only the XY plane (G17) is read")
            elif g == 93.0 or g == 95.0:
                raise self.error(f"{_g_name(g)} feed mode is not supported; use G94 (units per minute)")
            elif g not in _HARMLESS_G:
                raise self.error(f"{_g_name(g)} is not supported")
        for m in ms:
            if m not in _HARMLESS_M | _END_M:
                raise self.error(f"M{m:g} is not supported")
        for letter in ("S", "T"):
            rest.pop(letter, None)
        if dwell:
            rest.pop("P", None)
            self.end_contour()
        if 64.0 in gs:
            rest.pop("P", None), rest.pop("Q", None)
        if "F" in rest:
            if rest["F"] < 0:
                raise self.error(f"negative feed F{rest['F']:g}")
            self.scale_feed(rest.pop("F"))

        if self.block is not None and (motion is not None and motion not in ("G5.2", "G5.3")
                                       and self.block["kind"] == "G5.2"):  # fmt: skip
            raise self.error(
                f"the G5.2 block opened on line {self.block['line']} is not closed with G5.3 "
                f"before this {motion}"
            )
        if self.block is not None and self.block["kind"] == "G06.2" and motion is not None:
            self.close_fanuc()
        if motion is not None:
            self.motion = motion

        if motion == "G5.3":
            self.close_nurbs(rest)
        elif self.motion == "G5.2" and (motion == "G5.2" or self.block is not None or rest):
            self.nurbs_point(rest, opening=motion == "G5.2" and self.block is None)
        elif self.motion == "G06.2" and (motion == "G06.2" or rest):
            self.fanuc_point(rest, opening=motion == "G06.2")
        elif rest or motion in ("G2", "G3"):
            self.move(rest)

        if any(m in _END_M for m in ms):
            return False
        return True

    def scale_feed(self, f: float) -> None:
        k = 1.0 if self.units is None else self.scale()
        self.feed = f * k

    # -- G0 G1 G2 G3 G5 G5.1
    def move(self, w: dict) -> None:
        kind = self.motion
        if kind is None:
            raise self.error(f"axis words {sorted(w)} without a motion mode (G0/G1/...)")
        allowed = {"G0": "XYZ", "G1": "XYZ", "G2": "XYZIJRP", "G3": "XYZIJRP",
                   "G5": "XYIJPQ", "G5.1": "XYIJ"}[kind]  # fmt: skip
        extra = sorted(set(w) - set(allowed))
        if extra:
            raise self.error(f"word(s) {', '.join(extra)} not supported with {kind}")
        end = self.target(w)
        start = self.position
        moves_xy = not np.array_equal(end[:2], start[:2])
        moves_z = end[2] != start[2]
        line = self.line
        if kind == "G0":
            if moves_xy or moves_z:
                self.end_contour()
        elif moves_z:
            if kind != "G1" or moves_xy:
                raise self.error(
                    f"{kind} moves Z together with X/Y (a ramp or helix); only XY paths at "
                    "constant Z are read"
                )
            self.end_contour()  # a plunge or lift at fixed XY ends the contour
        elif kind == "G1":
            if moves_xy:
                self.add_piece(self.make(lambda: make_line(start[:2], end[:2], name=f"line {line}"), line), line)
        elif kind in ("G2", "G3"):
            self.arc(w, start, end)
        else:
            self.spline(kind, w, start, end)
        if kind != "G5":
            self._g5_pq = None
        self.position = end

    def arc(self, w: dict, start: np.ndarray, end: np.ndarray) -> None:
        clockwise = self.motion == "G2"
        k = self.scale()
        line = self.line
        turns = w.get("P", 1.0)
        if turns != int(turns) or turns < 1:
            raise self.error(f"arc turns P{turns:g} must be a whole number >= 1")
        if "R" in w:
            if "I" in w or "J" in w:
                raise self.error("arc with both R and I/J")
            if turns != 1:
                raise self.error("P turns need the centre format (I J)")
            build = lambda: arc_by_radius(start[:2], end[:2], k * w["R"], clockwise=clockwise,
                                          name=f"line {line}")  # fmt: skip
            self.add_piece(self.make(build, line), line)
            return
        if "I" not in w and "J" not in w:
            raise self.error(f"{self.motion} needs I/J (centre) or R (radius)")
        if self.arc_absolute:
            if not ("I" in w and "J" in w):
                raise self.error("absolute arc centre (G90.1) needs both I and J")
            center = np.array([k * w["I"], k * w["J"]])
        else:
            center = start[:2] + k * np.array([w.get("I", 0.0), w.get("J", 0.0)])
        r1 = float(np.hypot(*(start[:2] - center)))
        r2 = float(np.hypot(*(end[:2] - center)))
        # LinuxCNC's check: |r2 - r1| > 0.5 mm, or > 0.005 mm and > 0.1 % of the radius
        mm = 1.0 if self.units == "mm" else 1.0 / _INCH
        diff = abs(r2 - r1)
        if diff > 0.5 * mm or (diff > 0.005 * mm and diff > 0.001 * r1):
            raise self.error(
                f"radius to end of arc differs from radius to start: start {start[:2].tolist()} "
                f"centre {center.tolist()} end {end[:2].tolist()} r1 {r1:.6g} r2 {r2:.6g}"
            )
        build = lambda: arc_by_center(start[:2], end[:2], center, clockwise=clockwise,
                                      turns=int(turns), name=f"line {line}")  # fmt: skip
        for piece in self.make(build, line):
            self.add_piece(piece, line)

    def spline(self, kind: str, w: dict, start: np.ndarray, end: np.ndarray) -> None:
        k = self.scale()
        line = self.line
        if kind == "G5.1":
            if "I" not in w and "J" not in w:
                raise self.error("G5.1 needs I and/or J")
            ctrl = [start[:2], start[:2] + k * np.array([w.get("I", 0.0), w.get("J", 0.0)]), end[:2]]
        else:
            if not ("P" in w and "Q" in w):
                raise self.error("G5 needs both P and Q")
            if ("I" in w) != ("J" in w):
                raise self.error("G5 needs both I and J, or neither")
            if "I" in w:
                first = k * np.array([w["I"], w["J"]])
            elif self._g5_pq is not None:
                first = -self._g5_pq
            else:
                raise self.error("the first G5 of a series needs I and J")
            self._g5_pq = k * np.array([w["P"], w["Q"]])
            ctrl = [start[:2], start[:2] + first, end[:2] + self._g5_pq, end[:2]]
        p = len(ctrl) - 1
        build = lambda: NurbsCurve(p, [0.0] * (p + 1) + [1.0] * (p + 1), ctrl, name=f"line {line}")
        self.add_piece(self.make(build, line), line)

    # -- LinuxCNC G5.2 / G5.3
    def nurbs_point(self, w: dict, opening: bool) -> None:
        extra = sorted(set(w) - set("XYZPL"))
        if extra:
            raise self.error(f"word(s) {', '.join(extra)} not allowed in a G5.2 block")
        if ("X" in w) != ("Y" in w):
            raise self.error("a G5.2 control point needs both X and Y")
        if "Z" in w:
            self.warn("Z word inside a G5.2 block is ignored (LinuxCNC reads XY only)")
        if opening:
            w0 = 1.0
            if "P" in w and "X" not in w:
                w0 = w["P"]
                if w0 <= 0:
                    raise self.error(f"weight P{w0:g} of the first control point must be positive")
            self.block = {"kind": "G5.2", "line": self.line, "order": 3,
                          "base": self.position.copy(), "points": [self.position[:2].copy()],
                          "weights": [w0]}  # fmt: skip
        b = self.block
        if "L" in w:
            if w["L"] != int(w["L"]):
                raise self.error(f"order L{w['L']:g} must be a whole number")
            if w["L"] > 3:
                b["order"] = int(w["L"])
        if "X" in w:
            if "P" not in w:
                if not opening:
                    raise self.error("a G5.2 control point after the first line needs a weight P")
                self.warn(
                    "X/Y on the opening G5.2 line without P: weight 1, as the LinuxCNC manual "
                    "says (the LinuxCNC 2.9 interpreter would store -1)"
                )
            weight = w.get("P", 1.0)
            if weight <= 0:
                raise self.error(f"weight P{weight:g} must be positive")
            xy = {k: v for k, v in w.items() if k in "XY"}
            b["points"].append(self.target(xy, base=b["base"])[:2])
            b["weights"].append(weight)
        elif "P" in w and not opening:
            raise self.error("P without X and Y is only allowed on the opening G5.2 line")

    def close_nurbs(self, w: dict) -> None:
        b = self.block
        if b is None or b["kind"] != "G5.2":
            raise self.error("G5.3 without an open G5.2 block")
        if w:
            raise self.error(f"word(s) {', '.join(sorted(w))} not allowed with G5.3")
        points, order = np.array(b["points"]), b["order"]
        if len(points) < order:
            raise self.error(
                f"the G5.2 block opened on line {b['line']} has {len(points)} control points "
                f"(counting the start point); order L = {order} needs at least {order}"
            )
        line = b["line"]
        build = lambda: NurbsCurve(order - 1, linuxcnc_knots(len(points), order), points,
                                   b["weights"], name=f"line {line}")  # fmt: skip
        self.block = None
        self.add_piece(self.make(build, line), line)
        self.position = np.array([*points[-1], self.position[2]])
        self.motion = None

    # -- Fanuc G06.2
    def fanuc_point(self, w: dict, opening: bool) -> None:
        extra = sorted(set(w) - set("XYZKRP"))
        if extra:
            raise self.error(f"word(s) {', '.join(extra)} not allowed in a G06.2 block")
        if opening:
            order = w.get("P", 4.0)
            if order != int(order) or order < 2:
                raise self.error(f"G06.2 order P{order:g} must be a whole number >= 2")
            self.block = {"kind": "G06.2", "line": self.line, "order": int(order), "points": [],
                          "weights": [], "knots": [], "tail": 0}  # fmt: skip
        elif "P" in w:
            raise self.error("the G06.2 order P may only be given on the G06.2 line")
        b = self.block
        if b is None:
            raise self.error("G06.2 data after the block was closed; start a new one with G06.2")
        if "K" not in w and not opening:
            raise self.error("every G06.2 block needs a knot K")
        if "Z" in w and self.target({"Z": w["Z"]})[2] != self.position[2]:
            raise self.error("Z moves inside G06.2 are not supported (XY paths only)")
        weight = w.get("R", 1.0)
        if weight <= 0:
            raise self.error(f"weight R{weight:g} must be positive")
        if "X" in w or "Y" in w:
            if b["tail"]:
                raise self.error("G06.2 control point after the knot-only blocks")
            point = self.target({k: v for k, v in w.items() if k in "XY"})[:2]
            if opening and np.max(np.abs(point - self.position[:2])) > 1e-9 * max(1.0, np.max(np.abs(point))):
                raise self.error(
                    f"the first G06.2 control point {point.tolist()} is not the current "
                    f"position {self.position[:2].tolist()}"
                )
            b["points"].append(point)
            b["weights"].append(weight)
        elif opening:  # the current position is the first control point
            b["points"].append(self.position[:2].copy())
            b["weights"].append(weight)
        else:
            b["tail"] += 1
        b["knots"].append(w.get("K"))
        if b["knots"][0] is None and len(b["knots"]) > 1:
            b["knots"][0] = b["knots"][1]  # "omitted in the first block": the second's value
        if b["tail"] == b["order"]:
            self.close_fanuc()

    def close_fanuc(self) -> None:
        b = self.block
        self.block = None
        self.motion = None
        line = b["line"]
        points, order, knots = np.array(b["points"]), b["order"], b["knots"]
        n = len(points)
        if len(knots) != n + order:
            raise self.error(
                f"the G06.2 block of line {line} has {len(knots)} knots, expected "
                f"{n + order} = control points ({n}) + order ({order})",
                line,
            )
        if len(set(knots[:order])) != 1 or len(set(knots[-order:])) != 1:
            raise self.error(
                f"the G06.2 block of line {line} must start and end with {order} equal knots "
                f"(clamped ends), got {knots[:order]} ... {knots[-order:]}",
                line,
            )
        build = lambda: NurbsCurve(order - 1, knots, points, b["weights"], name=f"line {line}")
        self.add_piece(self.make(build, line), line)
        self.position = np.array([*points[-1], self.position[2]])

    def finish(self) -> None:
        if self.block is not None and self.block["kind"] == "G5.2":
            raise self.error(
                f"the G5.2 block opened on line {self.block['line']} is never closed with G5.3 "
                "(truncated program?)",
                self.block["line"],
            )
        if self.block is not None:
            self.close_fanuc()
        self.end_contour()


def load_gcode(file: str | os.PathLike) -> GcodeProgram:
    """Read the XY contours of a G-code program (see the module docstring).

    Parameters
    ----------
    file : str or path-like
        The program.

    Returns
    -------
    GcodeProgram
        Its contours (each a joined NurbsCurve with per-piece feeds) and units.

    Raises
    ------
    PathFileError
        At the first unsupported or malformed line, naming it; nothing is skipped.
        Reading is line by line with lines capped at :data:`MAX_LINE_LENGTH`, so a huge
        file of garbage fails at once.
    """
    path = check_input_file(file)
    reader = _Reader(str(path))
    for number, text in _lines(path):
        reader.line = number
        stripped = text.strip()
        if stripped == "%" or not stripped:
            continue
        if stripped.startswith("/"):
            raise reader.error("block delete '/' is not supported")
        if not reader.read_line(_words(text, number, str(path))):
            break
    reader.finish()
    if not reader.contours:
        raise PathFileError("the program has no XY feed move to make a path from", str(path))
    return GcodeProgram(tuple(reader.contours), reader.units or "mm", str(path), tuple(reader.warnings))


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
