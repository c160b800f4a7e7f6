"""G-code import (LinuxCNC G5.2, G0-G3, Fanuc G06.2) and G5.2 export."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from nurbsmotion import NurbsCurve, builtin_path, make_circle
from nurbsmotion.errors import OutputExistsError, PathFileError
from nurbsmotion.paths import resolve_path
from nurbsmotion.paths.gcode import GcodeWarning, linuxcnc_knots, load_gcode, save_gcode

BUTTERFLY_NGC = Path(__file__).resolve().parents[1] / "examples" / "butterfly.ngc"


def write(tmp_path: Path, text: str, name: str = "p.ngc") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ---------------------------------------------------------------- independent oracle
def linuxcnc_nmix(i: int, k: int, u: float, knots) -> float:
    """Basis function as LinuxCNC's Nmix computes it (nurbs_additional_functions.cc):
    Cox-de Boor of order k with *closed* order-1 intervals and its 0/0 conventions."""
    if k == 1:
        return 1.0 if knots[i] <= u <= knots[i + 1] else 0.0
    left, right = knots[i + k - 1] - knots[i], knots[i + k] - knots[i + 1]
    a = (u - knots[i]) * linuxcnc_nmix(i, k - 1, u, knots) / left if left else 0.0
    b = (knots[i + k] - u) * linuxcnc_nmix(i + 1, k - 1, u, knots) / right if right else 0.0
    return a + b


def linuxcnc_points(points, weights, order):
    """The points LinuxCNC's NURBS_FEED sends to the planner: u = j * umax / div."""
    n = len(points) - 1
    knots = [0] * order + list(range(1, n - order + 2)) + [n - order + 2] * order
    umax, div = n - order + 2, len(points) * 15
    out, us = [], []
    u = 0.0
    while u + umax / div < umax:
        u += umax / div
        basis = np.array([linuxcnc_nmix(i, order, u, knots) for i in range(n + 1)])
        den = basis @ weights
        out.append((basis * weights) @ points / den)
        us.append(u / umax)
    return np.array(us), np.array(out)


# ---------------------------------------------------------------- LinuxCNC G5.2
DOC_EXAMPLE = """G21
G0 X0 Y0 (rapid move)
F10 (set feed rate)
G5.2 P1 L3
     X0 Y1 P1
     X2 Y2 P1
     X2 Y0 P1
     X0 Y0 P2
G5.3
; The rapid moves show the same path without the NURBS Block
G0 X0 Y1
   X2 Y2
   X2 Y0
   X0 Y0
M2
"""


def test_linuxcnc_manual_example_is_the_curve_linuxcnc_builds(tmp_path):
    program = load_gcode(write(tmp_path, DOC_EXAMPLE))
    assert len(program.contours) == 1  # the G0 lines after it are rapids, not path
    contour = program.contours[0]
    c = contour.curve
    points = np.array([[0, 0], [0, 1], [2, 2], [2, 0], [0, 0]], dtype=float)
    weights = np.array([1, 1, 1, 1, 2], dtype=float)
    assert c.degree == 2  # L3 = order 3: a quadratic
    np.testing.assert_array_equal(c.control_points, points)
    np.testing.assert_array_equal(c.weights, weights)
    np.testing.assert_array_equal(c.knots, np.array([0, 0, 0, 1, 2, 3, 3, 3]) / 3)
    u, ref = linuxcnc_points(points, weights, order=3)
    np.testing.assert_allclose(c(u), ref, rtol=0, atol=1e-14)
    assert contour.lines == (4,) and contour.programmed_feed.tolist() == [10.0]
    assert contour.feed_at(0.3) == pytest.approx(10.0 / 60.0)


def test_linuxcnc_knot_vector():
    np.testing.assert_array_equal(linuxcnc_knots(5, 3), [0, 0, 0, 1, 2, 3, 3, 3])
    np.testing.assert_array_equal(linuxcnc_knots(4, 4), [0, 0, 0, 0, 1, 1, 1, 1])
    np.testing.assert_array_equal(linuxcnc_knots(7, 4), [0, 0, 0, 0, 1, 2, 3, 4, 4, 4, 4])


def test_butterfly_sample_program_gives_five_contours():
    program = load_gcode(BUTTERFLY_NGC)
    assert program.units == "mm"
    assert [len(c.lines) for c in program.contours] == [2, 1, 1, 1, 1]
    first = program.contours[0]
    # two G5.2 blocks (lines 9 and 15) meeting at (0, -29.56) at an angle: one corner
    assert first.lines == (9, 15)
    np.testing.assert_allclose(first.curve(first.piece_edges[1]), [0.0, -29.56], atol=1e-12)
    assert first.curve.sharp_corners().size == 1
    np.testing.assert_allclose(first.curve(1.0), [0.0, 0.0], atol=1e-15)  # closed contour
    # wing contours are mirror images: equal lengths
    lengths = [c.curve.length for c in program.contours]
    assert lengths[1] == pytest.approx(lengths[2], rel=1e-12)
    assert lengths[3] == pytest.approx(lengths[4], rel=1e-12)
    for c in program.contours:
        assert np.all(c.programmed_feed == 600.0)
    # every block evaluates as LinuxCNC would, e.g. the second contour (order 3)
    second = program.contours[1].curve
    u, ref = linuxcnc_points(second.control_points, second.weights, 3)
    np.testing.assert_allclose(second(u), ref, atol=1e-12)


def test_resolve_path_asks_to_choose_a_contour():
    with pytest.raises(PathFileError, match=r"holds 5 separate contours .*butterfly\.ngc#1"):
        resolve_path(str(BUTTERFLY_NGC))
    third = resolve_path(f"{BUTTERFLY_NGC}#3")
    assert third.name == "butterfly#3" and third.units == "mm"
    with pytest.raises(PathFileError, match="contour #9 does not exist"):
        resolve_path(f"{BUTTERFLY_NGC}#9")


def test_g91_points_are_relative_to_the_block_start_and_order_l4(tmp_path):
    text = "G21 G91\nG0 X10 Y10\nF100\nG5.2 X1 Y0 L4\nX1 Y1 P2\nX0 Y1 P1\nG5.3\nM2\n"
    with pytest.warns(GcodeWarning, match="without P: weight 1"):
        c = load_gcode(write(tmp_path, text)).contours[0].curve
    np.testing.assert_array_equal(c.control_points, [[10, 10], [11, 10], [11, 11], [10, 11]])
    np.testing.assert_array_equal(c.weights, [1, 1, 2, 1])
    assert c.degree == 3  # L4 = order 4


def test_l_below_four_keeps_order_three_and_z_is_ignored(tmp_path):
    text = "G21\nG0 X0 Y0\nF60\nG5.2 P1 L2\nX1 Y1 P1 Z5\nX2 Y0 P1\nG5.3\n"
    with pytest.warns(GcodeWarning, match="Z word inside a G5.2 block is ignored"):
        c = load_gcode(write(tmp_path, text)).contours[0].curve
    assert c.degree == 2


# ---------------------------------------------------------------- G0 G1 G2 G3
def test_lines_and_arcs_join_with_corners_and_exact_arcs(tmp_path):
    text = """%
(square with a rounded corner, inches)
N10 G20 G17 G90 G94
N20 G0 X0 Y0 Z1
N30 G1 Z-0.1 F5
N40 G1 X2 F20
N50 G3 X3 Y1 I0 J1 ; quarter circle, tangent to the line
N60 G2 X4 Y2 R1 F10 ; clockwise quarter by radius: corner? no, tangent
N70 G1 Y4
N80 G0 Z1
M30
%
"""
    program = load_gcode(write(tmp_path, text))
    assert program.units == "inch"
    (contour,) = program.contours
    c = contour.curve
    assert contour.lines == (6, 7, 8, 9)
    assert contour.programmed_feed.tolist() == [20.0, 20.0, 10.0, 10.0]
    edges = contour.piece_edges
    np.testing.assert_allclose(c(edges), [[0, 0], [2, 0], [3, 1], [4, 2], [4, 4]], atol=1e-14)
    assert c.length == pytest.approx(2 + math.pi / 2 + math.pi / 2 + 2, rel=1e-12)
    # the G3 arc is exact: radius 1 about (2, 1)
    v = np.linspace(edges[1], edges[2], 50)
    np.testing.assert_allclose(np.hypot(*(c(v) - [2, 1]).T), 1.0, atol=1e-14)
    # G2 R1 from (3,1) to (4,2) clockwise: centre (4,1)
    v = np.linspace(edges[2], edges[3], 50)
    np.testing.assert_allclose(np.hypot(*(c(v) - [4, 1]).T), 1.0, atol=1e-14)
    assert c.sharp_corners().size == 1  # G2 end heads +x, the last G1 heads +y


def test_metric_program_in_inches_is_converted(tmp_path):
    text = "G21\nG0 X0 Y0\nG20 F1\nG1 X1\nG2 X2 Y0 I0.5 J0\nM2\n"
    (contour,) = load_gcode(write(tmp_path, text)).contours
    assert contour.curve.units == "mm"
    np.testing.assert_allclose(contour.curve(1.0), [50.8, 0.0], atol=1e-12)
    assert contour.programmed_feed[0] == pytest.approx(25.4)


def test_full_circle_with_turns(tmp_path):
    text = "G21\nG0 X10 Y0\nF100\nG2 I-10 J0 P2\nM2\n"
    (contour,) = load_gcode(write(tmp_path, text)).contours
    assert contour.curve.length == pytest.approx(2 * 2 * math.pi * 10, rel=1e-12)
    np.testing.assert_allclose(np.linalg.norm(contour.curve(np.linspace(0, 1, 99)), axis=1), 10, atol=1e-12)


def test_rapid_and_z_moves_split_contours(tmp_path):
    text = "G21\nG0 X0 Y0\nG1 F100 X1\nG1 Z-1\nG1 X2\nG0 X5\nG1 X6\nM2\n"
    program = load_gcode(write(tmp_path, text))
    assert [c.lines for c in program.contours] == [(3,), (5,), (7,)]


# ---------------------------------------------------------------- Fanuc G06.2
def test_fanuc_quadratic_example(tmp_path):
    """The quadratic G06.2 example of the Fanuc-format manuals (P3, three control points,
    knots 0 0 0 1 1 1). Their G05 P10000 / G05 P0 high-precision-mode lines are left out:
    in LinuxCNC G5 is a cubic spline, and the mode does not change the path."""
    text = """N001 G21 G0 X0.0 Y0.0 Z0.0
N003 G06.2 P3 K0.0 X0.0 Y0.0 Z0.0 R1.0 F5000.
N004 K0.0 X0.0 Y5.0 Z0.0 R1.0
N005 K0.0 X5.0 Y5.0 Z0.0 R1.0
N006 K1.0
N007 K1.0
N008 K1.0
N009 G01 X10 Y5
M30
"""
    (contour,) = load_gcode(write(tmp_path, text)).contours
    c = contour.curve
    assert contour.lines == (2, 8) and contour.programmed_feed.tolist() == [5000.0, 5000.0]
    nurbs_end = contour.piece_edges[1]
    # quadratic Bezier (0,0) (0,5) (5,5): B(t) = (5 t^2, 10 t - 5 t^2)
    t = np.linspace(0, 1, 101)
    ref = np.c_[5 * t**2, 10 * t - 5 * t**2]
    # the joined curve runs the Bezier over [0, nurbs_end] with the same (linear) parameter
    np.testing.assert_allclose(c(t * nurbs_end), ref, atol=1e-13)
    # the Bezier ends at (5, 5) heading +x, and the G01 goes on to (10, 5): no corner
    assert c.sharp_corners().size == 0
    np.testing.assert_allclose(c(1.0), [10.0, 5.0], atol=1e-14)


def test_fanuc_cubic_with_weights(tmp_path):
    text = """G21 G0 X0 Y0
G06.2 P4 K0 X0 Y0 F600
K0 X1 Y2 R2
K0 X3 Y2 R0.5
K0 X4 Y0
K1
K1
K1
K1
"""
    c = load_gcode(write(tmp_path, text)).contours[0].curve
    ref = NurbsCurve(3, [0, 0, 0, 0, 1, 1, 1, 1], [[0, 0], [1, 2], [3, 2], [4, 0]], [1, 2, 0.5, 1])
    assert c == ref


# ---------------------------------------------------------------- malformed input
@pytest.mark.parametrize(
    "text,pattern",
    [
        ("G21\nG0 X0 Y0\nF10\nG5.2 P1\nX1 Y1 P1\nX2 Y0 P1\n", r"line 4: the G5.2 block opened on line 4 is never closed"),
        ("G21\nG0 X0 Y0\nF10\nG5.2 P1\nX1 Y1 P1\nG0 X5\n", r"line 6: the G5.2 block opened on line 4 is not closed with G5.3"),
        ("G21\nG0 X0 Y0\nF10\nG5.2 P1 L4\nX1 Y1 P1\nX2 Y0 P1\nG5.3\n", r"line 7: the G5.2 block opened on line 4 has 3 control points .* L = 4 needs at least 4"),
        ("G21\nF10\nG5.2\nX1 Y1 P0\nX2 Y0 P1\nG5.3\n", r"line 4: weight P0 must be positive"),
        ("G21\nF10\nG5.2\nX1 Y1 P-2\nX2 Y0 P1\nG5.3\n", r"line 4: weight P-2 must be positive"),
        ("G21\nF10\nG5.2\nX1 Y1 P1\nX2 Y0\nG5.3\n", r"line 5: a G5.2 control point after the first line needs a weight P"),
        ("G21\nF10\nG5.2\nX1 P1\n", r"line 4: a G5.2 control point needs both X and Y"),
        ("G21\nF10\nG5.3\n", r"line 3: G5.3 without an open G5.2 block"),
        ("G21\nG06.2 P3 K0 X0 Y0 F10\nK0 X1 Y1 R0\nK0 X2 Y0\nK1\nK1\nK1\n", r"line 3: weight R0 must be positive"),
        ("G21\nG06.2 P3 K0 X0 Y0 F10\nK0 X1 Y1\nK0 X2 Y0\nK1\nK1\nG01 X5\n", r"line 2: the G6.2 block of line 2 has 5 knots, expected 6"),
        ("G21\nG06.2 P3 K0 X0 Y0 F10\nK0.5 X1 Y1\nK0.5 X2 Y0\nK1\nK1\nK1\n", r"must start and end with 3 equal knots"),
        ("G21\nG06.2 P3 K0 X1 Y0 F10\n", r"line 2: the first G6.2 control point \[1\.0, 0\.0\] is not the current position"),
        ("G21\nG1 X1 Y1\n", r"line 2: feed move without a feed rate"),
        ("G21\nG1 X1 Y1 Z1 F10\n", r"line 2: G1 moves Z together with the path axes XY; a machine with the axes XYZ"),
        ("G21\nG1 X#1 F10 Y[1/0]\n", r"line 2: expression cannot be evaluated: \[1 / 0\]"),
        ("G21\nG1 X[1+2 F10\n", r"line 2: expected '\]'"),
        ("G21\nG41 D1\n", r"line 2: G41 uses the radius of tool 1, and no tool table is given: put it beside the program"),
        ("G21\nG18\nG41.1 D2\n", r"line 3: G41.1: cutter radius compensation is read in the XY plane only; select G17"),
        ("G21\nM98 P100\n", r"line 2: M98 is not an M code"),
        ("G21\no<x> call\n", r"line 2: o<x> call: no subroutine o<x> in this file"),
        ("G21\nG1 X#<nope> F10\n", r"line 2: named parameter #<nope> is not defined"),
        ("G21\no1 while [1]\no1 endwhile\n", r"an endless loop"),
        ("G21\nG0 X0 Y0\nF10\nG2 X1 I0.5 P1000000\n", r"line 4: arc turns P1e\+06 are more than the 100 read"),
        ("G21\nG0 X0 Y0\nF10\nG2 X0 Y0 I1000000000000 J0\n", r"line 4: I1e\+12 is beyond the largest coordinate read, 1e\+09"),
        ("G21\nG1 F10 X" + "9" * 100 + "\n", r"line 2: number 9999999999999999... has 100 characters; at most 40"),
        ("G21\nG1 F10 X" + "9" * 300 + "\n", r"line 2: line is longer than 256 characters"),
        ("G21\nG1 X1 F10 (unclosed\n", r"line 2: comment '\(' is not closed"),
        ("G21\nG1 X1 E3 F10\n", r"line 2: word\(s\) E not read with G1"),
        ("G21\nG0 X0 Y0\nF10\nG2 X10 Y0 I5.1 J0\n", r"line 4: radius to end of arc differs"),
        ("G21\nG0 X0 Y0\nG1 Z-1 F100\n", r"no feed move of the path axes XY"),  # Z only (rapids only: read as the path)
    ],
)
def test_malformed_programs_give_one_clear_error(tmp_path, text, pattern):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GcodeWarning)
        with pytest.raises(PathFileError, match=pattern):
            load_gcode(write(tmp_path, text))
    assert [p.name for p in tmp_path.iterdir()] == ["p.ngc"]  # nothing written


def test_huge_garbage_file_fails_fast(tmp_path):
    from test_path_files import assert_fails_fast, write_garbage

    assert_fails_fast(load_gcode, write_garbage(tmp_path / "garbage.ngc"), r"garbage\.ngc, line 1: ")


def test_one_huge_line_fails_fast(tmp_path):
    path = tmp_path / "long.ngc"
    path.write_bytes(b"G1 X1 " + b"Y1 " * 20_000_000)
    from test_path_files import assert_fails_fast

    assert_fails_fast(load_gcode, path, "line 1: line is longer than 256")


# ---------------------------------------------------------------- G5.2 export
def piecewise_distance(original: NurbsCurve, contour) -> float:
    """Largest distance between the original's Bezier spans and the read-back pieces."""
    bp = original.breakpoints
    v = np.linspace(0, 1, 201)
    worst = 0.0
    for k, (a, b) in enumerate(zip(bp[:-1], bp[1:])):
        e0, e1 = contour.piece_edges[k], contour.piece_edges[k + 1]
        worst = max(worst, np.max(np.abs(contour.curve(e0 + (e1 - e0) * v) - original(a + (b - a) * v))))
    return worst


@pytest.mark.parametrize(
    "curve",
    [
        builtin_path("butterfly"),
        builtin_path("die-bonder-pi").scaled(1e-3, units="mm"),
        make_circle(7.5, center=(1.0, -2.0), units="inch"),
    ],
    ids=["butterfly", "die-bonder-pi-mm", "circle-inch"],
)
def test_path_to_gcode_to_path_round_trip(tmp_path, curve):
    file = save_gcode(curve, tmp_path / "out.ngc", feed=25.0)
    (contour,) = load_gcode(file).contours
    size = np.max(np.ptp(curve.control_points, axis=0))
    assert piecewise_distance(curve, contour) <= 1e-9 * size
    assert contour.curve.length == pytest.approx(curve.length, rel=1e-9)
    assert np.all(contour.programmed_feed == 1500.0)
    assert contour.curve.sharp_corners().size == curve.sharp_corners().size


def test_gcode_export_refuses_pulses_and_overwrite(tmp_path):
    with pytest.raises(PathFileError, match="curve is in 'pulse'"):
        save_gcode(builtin_path("die-bonder-pi"), tmp_path / "pi.ngc", feed=1.0)
    assert list(tmp_path.iterdir()) == []
    file = save_gcode(builtin_path("die-bonder-pi"), tmp_path / "pi.ngc", feed=1.0, units="mm")
    with pytest.raises(OutputExistsError):
        save_gcode(builtin_path("butterfly"), file, feed=1.0)


def test_console_commands_are_skipped_with_one_warning(tmp_path):
    """A sender's script (GRBL): $ settings, status ?, feed hold !, cycle start ~ and a $J
    jog are not part of the program; one warning names them all."""
    path = tmp_path / "console.gcode"
    path.write_text("G21 G90\n$I\n$G\n?\n$H\n!\n~\n$X\n$J=G91 X1 F100\nG0 X0 Y0\nG1 X10 F100\n"
                    "?\nG1 Y5\n$$\nM2\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        program = load_gcode(path)
    said = [str(w.message) for w in caught if "console" in str(w.message)]
    assert said == [f"{path}, line 2: controller console commands ($..., ?, !, ~: GRBL's settings, "
                    "status, jog, feed hold, cycle start) skipped: they are not part of the program"]
    np.testing.assert_array_equal(program.contours[0].curve.control_points, [[0, 0], [10, 0], [10, 5]])
