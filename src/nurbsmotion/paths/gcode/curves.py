"""The curved moves of the G-code reader: G2/G3 arcs (exact rational arcs, helices and
spirals), G5 and G5.1 splines, LinuxCNC's G5.2/G5.3 NURBS blocks with their implicit knot
vector (:func:`linuxcnc_knots`) and Fanuc's G6.2 blocks. A part of
:class:`~nurbsmotion.paths.gcode.reader._Reader`.
"""

from __future__ import annotations

import math

import numpy as np

from ...nurbs import NurbsCurve
from ..pieces import HELIX_TOLERANCE, PieceChain, arc_by_center, arc_sweep
from .codes import _AXES, _PLANES, MAX_ARC_TURNS, MAX_COORDINATE, _NeedAxes, _g_name

__all__ = ["linuxcnc_knots", "helix"]


def linuxcnc_knots(n_points: int, order: int) -> np.ndarray:
    """LinuxCNC's implicit G5.2 knot vector (``knot_vector_creator`` in
    ``nurbs_additional_functions.cc``): ``order`` zeros, ``1 .. n-order+1`` and ``order``
    times ``n-order+2``, with ``n = n_points - 1``; ``n_points + order`` entries."""
    n = n_points - 1
    return np.concatenate(
        [np.zeros(order), np.arange(1, n - order + 2), np.full(order, n - order + 2)]
    ).astype(float)



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


class _Curves:
    """The reader's curved moves (mixed into :class:`~nurbsmotion.paths.gcode.reader._Reader`)."""

    def arc_centre(self, w: dict, sx: float, sy: float, ex: float, ey: float) -> tuple:
        """Centre (program coordinates of the plane's axes) and turns of a G2/G3 from
        (sx, sy) to (ex, ey) by its words (R, or the centre offsets; P), with LinuxCNC's
        checks of the words and of the radii to the start and the end."""
        clockwise = self.motion == "G2"
        k = self.scale()
        _, _, lin, o1, o2 = _PLANES[self.plane]
        turns = w.get("P", 1.0)
        if turns != int(turns) or turns < 1:
            raise self.error(f"arc turns P{turns:g} must be a whole number >= 1")
        if turns > MAX_ARC_TURNS:
            raise self.error(f"arc turns P{turns:g} are more than the {MAX_ARC_TURNS} read "
                             "(MAX_ARC_TURNS)")
        wrong = "IJK"[lin]
        if wrong in w:
            raise self.error(f"{wrong} word not allowed with an arc in the {_g_name(self.plane)} plane")
        if "R" in w:
            if o1 in w or o2 in w:
                raise self.error("arc with both R and a centre offset: give one of them")
            r = k * self.value("R", w["R"])
            dx, dy = ex - sx, ey - sy
            d = math.hypot(dx, dy)
            if d == 0.0:
                raise self.error("a radius-format arc cannot end where it starts: write a full circle "
                                 "with its centre (I/J/K)")
            if d > 2 * abs(r) * (1 + 1e-9):
                raise self.error(f"arc radius {abs(r):g} is too small for the chord of length {d:g}: "
                                 f"give a radius of at least {d / 2:g} or correct the end point")
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
            raise self.error(f"arc centre {[cx, cy]} coincides with its start point: correct the "
                             "centre offsets")
        # LinuxCNC's check (interp_arc.cc): |r2 - r1| > 100 tol, or > tol and > 0.1 %, with
        # its default tol per unit (interp_internal.hh): CENTER_ARC_RADIUS_TOLERANCE_MM =
        # 2 * 0.01 * sqrt(2) mm, CENTER_ARC_RADIUS_TOLERANCE_INCH = 2 * 0.001 * sqrt(2) inch
        # (2.5 times the mm one converted: an inch program within it was refused, issue 36)
        tol = 2 * math.sqrt(2) * (0.01 if self.units == "mm" else 0.001)  # [program units]
        diff = abs(r2 - r1)
        if diff > 100 * tol or (diff > tol and diff / max(r1, r2) > 0.001):
            raise self.error(
                f"radius to end of arc differs from radius to start: start {[sx, sy]} "
                f"centre {[cx, cy]} end {[ex, ey]} r1 {r1:.6g} r2 {r2:.6g} (LinuxCNC refuses it too): "
                "correct the arc's end point or centre")
        return cx, cy, int(turns)

    def arc(self, w: dict, start: list, end: list) -> None:
        """G2/G3 in the selected plane, computed in program coordinates as LinuxCNC does:
        an exact arc when only the plane's axes move, else a helix; a spiral when the
        end radius differs from the start radius within LinuxCNC's tolerance."""
        clockwise = self.motion == "G2"
        line = self.line
        i1, i2, lin, o1, o2 = _PLANES[self.plane]
        ps, pe = self.to_program(start), self.to_program(end)
        sx, sy, ex, ey = ps[i1], ps[i2], pe[i1], pe[i2]
        cx, cy, turns = self.arc_centre(w, sx, sy, ex, ey)
        r1, r2 = math.hypot(sx - cx, sy - cy), math.hypot(ex - cx, ey - cy)
        diff = abs(r2 - r1)
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
                f"the G5.2 block opened on {self.line_name(bl['line'])} has {len(points)} control points "
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
            raise self.error(f"the G6.2 block of {self.line_name(line)} has {len(knots)} knots, expected "
                             f"{n + order} = control points ({n}) + order ({order})", line)
        if len(set(knots[:order])) != 1 or len(set(knots[-order:])) != 1:
            raise self.error(f"the G6.2 block of {self.line_name(line)} must start and end with {order} equal "
                             f"knots (clamped ends), got {knots[:order]} ... {knots[-order:]}", line)
        self.finish_nurbs(lambda: NurbsCurve(order - 1, knots, points, bl["weights"]), bl["plane"],
                          points[-1], line)
