"""Dump the points LinuxCNC's own interpreter computes for a G-code program, as JSON.

Runs under Debian's /usr/bin/python3 with the ``gcode`` module of ``linuxcnc-uspace``
(the one AXIS uses for its preview): ``gcode.parse(file, canon, "G21", "")`` with a canon
that records every move the way AXIS's ``rs274.glcanon`` does — program coordinates
translated by the G92 and G5x offsets, arcs cut into points by ``gcode.arc_to_segments``
— converted from the module's inches to mm. Usage::

    /usr/bin/python3 linuxcnc_points.py PROGRAM.ngc > points.json

(run in a scratch folder: it writes ``program.ngc`` and ``rs274ngc.var`` there).

Output: ``{"error": null | "message", "moves": [[kind, line, [x, y, z, a, b, c, u, v, w],
feed], ...]}`` with kind ``"feed"``, ``"traverse"`` or ``"arc"`` (arc points), in mm, and
the feed rate in force (the last ``SET_FEED_RATE``; under G93 what LinuxCNC computes from
F and the move's length) [mm/min].
"""

import json
import re
import sys

import gcode
from rs274.interpret import ArcsToSegmentsMixin, Translated


class Canon(Translated, ArcsToSegmentsMixin):
    def __init__(self):
        self.moves = []
        self.lineno = 0
        self.lo = (0.0,) * 9
        self.arcdivision = 64
        self.rate = 0.0  # the feed rate in force [mm/min]
        # A parameter file in the working folder (a temporary one): LinuxCNC rewrites it
        # when a program changes persistent parameters (a tool change sets #5400).
        self.parameter_file = "rs274ngc.var"
        open(self.parameter_file, "a").close()

    def __getattr__(self, name):  # every canon call we do not need: a no-op
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *args, **kw: None

    def next_line(self, state):
        self.lineno = state.sequence_number

    def get_external_length_units(self):
        return 0.03937007874015748

    def get_external_angular_units(self):
        return 1.0

    def get_axis_mask(self):
        return 511

    def get_block_delete(self):
        return False

    def get_tool(self, idx):
        return (-1,) + (0.0,) * 12 + (0,)

    def set_feed_rate(self, rate):  # the module's lengths are inches
        self.rate = rate * 25.4

    def record(self, kind, point):
        self.moves.append([kind, self.lineno, [v * 25.4 if i in (0, 1, 2, 6, 7, 8) else v
                                               for i, v in enumerate(point)], self.rate])
        self.lo = tuple(point)

    def straight_traverse_translated(self, *p):
        self.record("traverse", p)

    def straight_feed_translated(self, *p):
        self.record("feed", p)

    def straight_arcsegments(self, segs):
        for p in segs:
            self.record("arc", p)


# LinuxCNC 2.9's module looks tool numbers up in a tool database that only a running
# LinuxCNC provides, and crashes without it (T17 alone is a segmentation fault). Tool
# selection and change do not shape the path the preview draws (the tool table is empty,
# so no tool length offset applies), so T words and M6 are blanked out of a copy of the
# program, on the same lines, before it is parsed.
TOOL_WORDS = re.compile(r"(?<![A-Za-z_#<0-9.])(?:[Tt]\s*[0-9]+|[Mm]\s*0*6(?![0-9.]))")


def main():
    canon = Canon()
    with open(sys.argv[1], encoding="utf-8", errors="replace", newline="") as f:
        text = f.read()
    with open("program.ngc", "w", encoding="utf-8", newline="") as f:
        f.write(TOOL_WORDS.sub(lambda m: " " * len(m.group()), text))
    result, seq = gcode.parse("program.ngc", canon, "G21", "")
    error = None
    if result > gcode.MIN_ERROR:
        error = f"line {seq}: {gcode.strerror(result)}"
    json.dump({"error": error, "moves": canon.moves}, sys.stdout)


if __name__ == "__main__":
    main()
