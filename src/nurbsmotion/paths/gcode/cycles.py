"""The canned cycles G73, G74 and G81-G89 of the G-code reader, expanded into G0 and G1
moves as LinuxCNC's ``interp_cycles.cc`` does. A part of
:class:`~nurbsmotion.paths.gcode.reader._Reader`.
"""

from __future__ import annotations

import math

from .codes import _AXES, _CYCLES, _INCH, _MOTION_WORDS, _PLANES, PECK_CLEARANCE_INCH, _g_name


class _Cycles:
    """The reader's canned cycles (mixed into :class:`~nurbsmotion.paths.gcode.reader._Reader`)."""

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
