"""Cutter radius compensation (G40, G41, G42, G41.1, G42.1) against LinuxCNC's interpreter.

The offset path is LinuxCNC's: every point its ``gcode`` module computes for a written
program lies on the contours read (within 1e-9 mm, 1e-6 mm where a helix is approximated
by cubic pieces), and every junction of those contours is one of its points (no piece too
many or too few). The radius from a tool table (``G41 D<tool>``) and from ``G10 L1 R`` with
``T M6`` is checked against ``rs274 -t TABLE -g``, which prints 4 decimals. Where LinuxCNC
refuses a program (a corner the tool cannot reach, an arc smaller than the tool, a short
entry move, an arc right after G40), the reader refuses it at the same line, naming what to
change. Without LinuxCNC these comparisons skip; the refusals without a reference always run.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from linuxcnc_reference import linuxcnc_moves, linuxcnc_python, max_distance
from nurbsmotion.errors import InvalidArgumentError, PathFileError
from nurbsmotion.paths.gcode import GcodeWarning, load_gcode

needs_linuxcnc = pytest.mark.skipif(linuxcnc_python() is None,
                                    reason="LinuxCNC's gcode module (linuxcnc-uspace) is not installed")
needs_rs274 = pytest.mark.skipif(shutil.which("rs274") is None, reason="LinuxCNC's rs274 is not installed")

# Programs written for this test, each for a part of the algorithm: entry lines and arcs,
# convex corners (rolled round), concave corners line-line, line-arc, arc-line, arc-arc
# (cut back), tangent moves, rapids and Z moves while compensating, G91, R arcs, inches,
# a helix with P turns, the "h" and "m" shapes LinuxCNC treats specially, G40 exits.
PROGRAMS = {
    "corners_arcs_and_exit": """G21 G90 G17
G0 X0 Y0 Z1
G1 Z0 F100
G41.1 D4
G1 X10 Y0
G1 X20 Y0
G1 X20 Y10
G3 X10 Y20 I-10 J0
G1 X0 Y10
G1 X5 Y5
G1 X0 Y0
G40
G1 X-5 Y-5
M2
""",
    "right_side_r_arcs": """G21 G90 G17
G0 X-10 Y-10 Z2
G1 Z-1 F200
G42.1 D3
G1 X0 Y0
G1 X30
G2 X40 Y10 I0 J10
G1 Y30
G3 X30 Y40 R10
G1 X20
G2 X10 Y30 I-10 J0
G3 X0 Y20 I0 J-10
G1 Y10
G1 X5 Y5
G1 X0 Y0
G40
G1 X-10 Y-10
G0 Z2
M2
""",
    "rapids_plunges_incremental": """G21 G90 G17
G0 X60 Y-10 Z1
G1 Z-1 F100
G41.1 D4
G1 X50 Y0
G3 X0 Y50 I-50 J0
G1 X-30 Y50
G1 Z-2
G1 X-30 Y0
G91 G1 X10 Y-10
G90 G2 X0 Y-20 R15
G0 X40 Y-20
G1 X50 Y0
G40 G0 X60 Y10
M2
""",
    "inch_entry_arc_and_arc_pairs": """G20 G90 G17
G0 X0 Y0
G42.1 D0.25
G3 X2 Y0 I1 J0 F20
G1 X2 Y2
G3 X0 Y2 I-1 J0
G3 X-1 Y1 I0 J-1
G1 X0 Y0
G40 G1 X-1 Y-1
M2
""",
    "dwell_and_tight_concave_corner": """G21 G90 G17
G0 X0 Y0 Z1
G1 Z0 F100
G41.1 D2
G1 X10 Y0
G1 X10 Y10
G1 X5 Y10.5
G1 X0 Y10
G1 X0 Y5
G1 X0.2 Y0.2
G4 P1
G1 X10 Y0.1
G40 G1 X20 Y-5
M2
""",
    "h_and_m_shapes": """G21 G90 G17
G0 X-5 Y5 Z1
G1 Z0 F100
G41.1 D2
G1 X0 Y5
G1 X0 Y20
G2 X10 Y30 I10 J0
G2 X20 Y20 I0 J-10
G1 X20 Y10
G3 X30 Y0 I10 J0
G1 X40 Y0
G3 X40 Y20 I0 J10
G3 X30 Y10 I-10 J0
G1 X30 Y5
G2 X20 Y-5 I-10 J0
G1 X5 Y-5
G1 X0 Y5
G40 G1 X-5 Y10
M2
""",
    "inside_arcs_helix_and_entry_arc": """G21 G90 G17
G0 X5 Y-30 Z1
G1 Z0 F100
G41.1 D4
G1 X10 Y-20
G1 X20 Y0
G3 X-20 Y0 I-20 J0
G3 X20 Y0 I20 J0 Z-1 P2
G1 X25 Y-10
G40 G1 X30 Y-20
G0 Z5
G0 X0 Y0
G42.1 D3
G3 X10 Y10 I10 J0
G3 X0 Y20 I-10 J0
G1 X-10 Y20
G40 G1 X-20 Y20
M2
""",
    "arc_then_concave_lines": """G21 G90 G17
G0 X-5 Y-5
G41.1 D4 G1 X0 Y0 F100
G3 X10 Y0 I5 J0
G1 X10 Y-1
G1 X0 Y-1.1
M2
""",
}
HELIX = {"inside_arcs_helix_and_entry_arc"}  # approximated within HELIX_TOLERANCE


def load_quiet(path: Path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GcodeWarning)
        return load_gcode(path, **kw)


def write(tmp_path: Path, text: str, name: str = "p.ngc") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@needs_linuxcnc
@pytest.mark.parametrize("name", sorted(PROGRAMS))
def test_compensated_path_is_linuxcncs(tmp_path, name):
    path = write(tmp_path, PROGRAMS[name], f"{name}.ngc")
    ref = linuxcnc_moves(path)
    assert ref["error"] is None, ref["error"]
    program = load_quiet(path, axes="xyz")
    scale = 25.4 if program.units == "inch" else 1.0
    curves = [c.curve for c in program.contours]
    dist, n = max_distance(path, curves, scale)
    assert n >= 9
    assert dist <= (1e-6 if name in HELIX else 1e-9)
    # the other way: every junction of the contours is one of LinuxCNC's points
    points = np.array([m[2][:3] for m in ref["moves"]], dtype=float)
    junctions = np.concatenate([c.curve(c.piece_edges) * scale for c in program.contours])
    gap, _ = cKDTree(points).query(junctions)
    assert np.max(gap) <= 1e-9


def rs274_ends(program: Path, tmp_path: Path, table: Path | None = None) -> np.ndarray:
    """End points XY of the feed moves ``rs274 -g`` prints (4 decimals, program units)."""
    args = ["rs274"] + (["-t", str(table)] if table is not None else []) + ["-g", str(program)]
    out = subprocess.run(args, input="\n\n", capture_output=True, text=True, timeout=60, cwd=tmp_path).stdout
    calls = re.findall(r"N\.+\s+(STRAIGHT_FEED|ARC_FEED)\(([^)]*)\)", out)
    return np.array([[float(v) for v in args.split(",")[:2]] for _, args in calls])


TOOL_PROGRAM = """G20 G90 G17
{setup}
G0 X-1 Y-1
{comp}
G1 X0 Y0 F20
G1 X3
G2 X4 Y-1 I0 J-1
G1 Y-3
G1 X0
G1 Y0
G40 G1 X-1 Y1
M2
"""


@needs_rs274
@pytest.mark.parametrize("setup,comp,table", [
    ("", "G42 D3", "T3 P3 D0.2 ;a 0.2 inch cutter\n"),
    ("G10 L1 P2 R0.1\nT2 M6", "G42", None),
    ("", "G42.1 D0.2", None),
], ids=["tool_table", "g10_l1_and_m6", "g42_1_diameter"])
def test_tool_radius_from_table_g10_or_d_word_matches_rs274(tmp_path, setup, comp, table):
    path = write(tmp_path, TOOL_PROGRAM.format(setup=setup, comp=comp))
    tbl = None
    if table is not None:
        tbl = tmp_path / "tool.tbl"
        tbl.write_text(table)
    printed = rs274_ends(path, tmp_path, tbl)
    assert len(printed) == 7
    program = load_quiet(path, axes="xy", tool_table=tbl, tool_table_units="inch")
    (contour,) = program.contours
    ends = contour.curve(contour.piece_edges[1:])
    assert ends.shape == printed.shape
    assert np.max(np.abs(ends - printed)) <= 0.5e-4 + 1e-12  # rs274's rounding
    assert np.max(np.abs(ends[1] - [3.0, -0.1])) <= 1e-12  # 0.1 inch right of X3 Y0


# Programs LinuxCNC refuses for the cutter compensation: the reader refuses them at the
# same line, with what to change.
REFUSED = {
    "concave_corner_tighter_than_the_tool": (
        "G21 G90 G17\nG0 X-5 Y5\nG41.1 D4 G1 X0 Y0 F100\nG1 X10 Y0\nG1 X10 Y1\nG1 X0 Y1\nG40 G1 X-5 Y5\nM2\n",
        r"line 6: the move of line 5 ends in a concave corner the tool of radius 2 cannot reach "
        r"without gouging .*use a smaller tool"),
    "arc_smaller_than_the_tool_inside_it": (
        "G21 G90 G17\nG0 X-5 Y-5\nG41.1 D10 G1 X0 Y0 F100\nG1 X10 Y0\nG3 X10 Y6 I0 J3\nM2\n",
        r"line 5: the arc's radius 3 is not larger than the tool radius 5 with the tool inside it: "
        r"use a smaller tool or a larger arc"),
    "entry_move_shorter_than_the_radius": (
        "G21 G90 G17\nG0 X0 Y0\nG41.1 D10 G1 X4 Y0 F100\nG1 X10 Y0\nM2\n",
        r"line 3: the cutter compensation entry move, 4 long, is not longer than the tool radius 5: "
        r"start it farther from the contour"),
    "arc_right_after_g40": (
        "G21 G90 G17\nG0 X-5 Y-5\nG41.1 D2 G1 X0 Y0 F100\nG1 X10 Y0\nG40\nG2 X20 Y0 I5 J0\nM2\n",
        r"line 6: the move after G40 must be a straight line \(G0/G1\).*add a line before this arc"),
}


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_refused_where_linuxcnc_refuses(tmp_path, name):
    text, pattern = REFUSED[name]
    path = write(tmp_path, text)
    with pytest.raises(PathFileError, match=pattern) as info:
        load_quiet(path, axes="xy")
    assert "\n" not in str(info.value)
    if linuxcnc_python() is not None:
        error = linuxcnc_moves(path)["error"]
        assert error is not None
        assert error.startswith(re.match(r"line \d+", pattern).group())


@pytest.mark.parametrize("text,pattern", [
    ("G21\nG18\nG41.1 D2\n", r"line 3: G41.1: cutter radius compensation is read in the XY plane only; "
                              r"select G17 before it \(the program is in G18\)"),
    ("G21\nG41.1 D2\nG42.1 D2\n", r"line 3: G42.1 while cutter compensation is already on: turn it off with G40"),
    ("G21\nG41.1\n", r"line 2: G41.1 needs the tool diameter as a D word"),
    ("G21\nG41 D1\n", r"line 2: G41 uses the radius of tool 1, and no tool table is given: put it beside the "
                      r"program as p.tbl \(LinuxCNC's format\) or pass it \(load_gcode\(..., tool_table=FILE.tbl\)\), "
                      r"set it in the program \(G10 L1 P1 R<radius>\) or write G41.1/G42.1 D<diameter>"),
    ("G21\nG41 D2.5\n", r"line 2: G41 D2.5: D is a tool number .*; for a diameter write G41.1 D2.5"),
    ("G21\nG0 X-5\nG41.1 D2\nG1 X0 F10\nG92 X0\n", r"line 5: G92 is not allowed while cutter radius compensation "
                                                  r"is on \(as in LinuxCNC\): turn it off with G40"),
    ("G21\nG0 X-5\nG41.1 D2\nG1 X0 F10\nG81 X1 Y1 Z-1 R1\n", r"line 5: G81 is not allowed while cutter radius "
                                                           r"compensation is on"),
    ("G21\nG0 X-5\nG41.1 D2\nG1 X0 F10\nG55\n", r"line 5: changing the coordinate system \(G55\) is not allowed"),
    ("G21\nG0 X-5\nG41.1 D2\nG1 X0 F10\nG20\n", r"line 5: changing units \(G20\) is not allowed"),
    ("G21\nG0 X-5\nG41.1 D2\nG1 X0 F10\nG64 P0.1\n", r"line 5: changing the path control mode \(G64\) is not allowed"),
    ("G21\nG0 X-5\nG41.1 D2\nG1 X0 F10\nG10 L2 P1 X3\n", r"line 5: G10 L2 \(a coordinate system's offsets\) is not "
                                                       r"allowed while cutter radius compensation is on"),
    ("G21\nG0 X-5\nG41.1 D2\nG93 G1 X0 F10\n", r"line 4: inverse-time feed \(G93\) with cutter radius "
                                               r"compensation is not read: write the compensated moves in G94"),
])
def test_compensation_refusals_name_the_line_and_the_remedy(tmp_path, text, pattern):
    with pytest.raises(PathFileError, match=pattern) as info:
        load_quiet(write(tmp_path, text))
    assert "\n" not in str(info.value)


def test_tool_table_errors(tmp_path):
    program = write(tmp_path, "G21\nG0 X-5\nG41 D7 G1 X0 F10\nG1 X10\nM2\n")
    table = write(tmp_path, "T3 P3 D6\n", "tool.tbl")
    with pytest.raises(PathFileError, match=r"line 3: G41: tool 7 is not in the tool table; add it"):
        load_quiet(program, tool_table=table)
    bad = write(tmp_path, "P3 D6\n", "bad.tbl")
    with pytest.raises(PathFileError, match=r"bad.tbl, line 1: no T word in 'P3 D6'"):
        load_quiet(program, tool_table=bad)
    with pytest.raises(InvalidArgumentError, match="tool_table_units 'cm' must be 'mm', 'inch' or None"):
        load_quiet(program, tool_table=table, tool_table_units="cm")


def test_zero_radius_compensates_nothing_and_says_so(tmp_path):
    """G41 without D and without a tool in the spindle: LinuxCNC's radius 0, no offset."""
    text = "G21\nG0 X-5 Y0\nG41 G1 X0 F10\nG1 X10\nG1 Y10\nG40 G1 X20\nM2\n"
    with pytest.warns(GcodeWarning, match=r"line 3: G41 with a tool of radius 0: the path is not offset"):
        program = load_gcode(write(tmp_path, text))
    plain = load_quiet(write(tmp_path, text.replace("G41 ", "").replace("G40 ", ""), "q.ngc"))
    assert program.contours[0].curve == plain.contours[0].curve


def distance_to_polygon(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Distance of each point (shape (m, 2)) to the closed polygon's edges."""
    a, b = corners, np.roll(corners, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("mkd,kd->mk", points[:, None, :] - a[None], ab) / np.sum(ab * ab, axis=1), 0, 1)
    foot = a[None] + t[..., None] * ab[None]
    return np.min(np.linalg.norm(points[:, None, :] - foot, axis=2), axis=1)


@pytest.mark.parametrize("comp,outside", [("G42.1 D4", True), ("G41.1 D4", False)])
def test_offset_path_runs_at_the_tool_radius_from_the_contour(tmp_path, comp, outside):
    """Without any reference: round a counter-clockwise pentagon, G42 puts the tool outside
    (corners rolled round on arcs of radius r), G41 inside (corners cut back); between the
    entry and the exit every point of the path is r from the contour, inside or outside it
    (but near the first and the last point: the entry and exit move round them as LinuxCNC's)."""
    corners = np.array([[0.0, 0.0], [20.0, 0.0], [26.0, 14.0], [10.0, 24.0], [-4.0, 12.0]])
    text = "G21 G90 G17\nG0 X-10 Y-10\n" + f"{comp} G1 X0 Y0 F100\n" + "".join(
        f"G1 X{x:g} Y{y:g}\n" for x, y in corners[1:]) + "G1 X0 Y0\nG40 G1 X-10 Y-10\nM2\n"
    program = load_quiet(write(tmp_path, text), axes="xy")
    (contour,) = program.contours
    edges = contour.piece_edges  # the pieces of the sides of lines 5-7 (and the corner arcs before them)
    u = np.concatenate([np.linspace(edges[k], edges[k + 1], 50)
                        for k, line in enumerate(contour.lines) if 5 <= line <= 7])
    points = contour.curve(u)
    assert np.max(np.abs(distance_to_polygon(points, corners) - 2.0)) <= 1e-9
    from matplotlib.path import Path as Polygon  # point-in-polygon only

    inside = Polygon(corners).contains_points(points)
    assert not inside.any() if outside else inside.all()
    assert len(u) == (6 if outside else 3) * 50  # three sides, with an arc before each outside
    # entry, 5 sides, exit; outside an arc at each of 4 corners, inside one round the first point
    assert len(contour.piece_edges) - 1 == (11 if outside else 8)


CCOMP = Path(__file__).resolve().parent / "data" / "corpus" / "linuxcnc_ccomp"


@pytest.mark.parametrize("name", ["mill-line-arc-entry", "mill-g90g91g92", "mill-zchanges"])
def test_linuxcncs_own_cutter_compensation_tests(name):
    """LinuxCNC's regression tests of cutter compensation (``tests/ccomp/``: a program, its
    tool table in inches, and the canonical calls ``rs274 -t test.tbl -g`` must print, 4
    decimals): every feed end LinuxCNC expects is a junction of the contours read (the
    table found beside the program), and every junction is one of its feed or rapid ends.
    The canon prints program coordinates: ``mill-g90g91g92`` shifts Z by G92, so it is
    compared in XY."""
    expected = (CCOMP / "expected" / f"{name}.txt").read_text()
    feed, every = [], []
    for call, args in re.findall(r"(STRAIGHT_FEED|ARC_FEED|STRAIGHT_TRAVERSE)\(([^)]*)\)", expected):
        v = [float(x) for x in args.split(",")]
        point = [v[0], v[1], v[5]] if call == "ARC_FEED" else v[:3]
        every.append(point)
        if call != "STRAIGHT_TRAVERSE":
            feed.append(point)
    cols = 2 if name == "mill-g90g91g92" else 3
    with pytest.warns(GcodeWarning, match=rf"tool radii from the tool table {name}.tbl beside the program"):
        program = load_gcode(CCOMP / f"{name}.ngc", axes="xyz")
    assert program.units == "inch"
    junctions = np.concatenate([c.curve(c.piece_edges) for c in program.contours])[:, :cols]
    rounding = 0.5e-4 * np.sqrt(cols) + 1e-12  # [inch]
    assert np.max(cKDTree(junctions).query(np.array(feed)[:, :cols])[0]) <= rounding
    assert np.max(cKDTree(np.array(every)[:, :cols]).query(junctions)[0]) <= rounding
