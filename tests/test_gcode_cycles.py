"""Canned cycles (G73, G74, G81-G89, G98/G99, L repeats), spindle-synchronised moves
(G33, G33.1, G95) and programs of rapids only, against LinuxCNC's interpreter.

Every feed move LinuxCNC's own interpreter (``linuxcnc-uspace``'s ``gcode`` module, the
one AXIS previews with) makes for a program must be one line piece of a contour nurbsmotion
reads, in the same order, with the same end points to 1e-9 mm; its rapids are where
the contours break. Without LinuxCNC the comparisons skip; the properties below (each
hole's plunge a contour, the refusals) always run.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from linuxcnc_reference import linuxcnc_moves, linuxcnc_python
from nurbsmotion.errors import PathFileError
from nurbsmotion.paths.gcode import GcodeWarning, load_gcode

needs_linuxcnc = pytest.mark.skipif(linuxcnc_python() is None,
                                    reason="LinuxCNC's gcode module (linuxcnc-uspace) is not installed")

CYCLES = {
    "g81_g99_absolute": "G21 G90 G17 F300\nG0 X0 Y0 Z10\nG99 G81 X5 Y5 Z-3 R2\nX10\nY10 Z-4\nG80\nG0 Z20\nM2\n",
    "g81_g98_initial_level": "G21 G90 F300\nG0 X0 Y0 Z10\nG98 G81 X5 Y5 Z-3 R2\nX10\nG80 G0 X0\nM2\n",
    "g81_incremental_repeats": "G20 G91 F20\nG0 X0.5 Y0.5 Z0.5\nG81 X0.25 Y0.1 Z-0.4 R-0.3 L4\nG90 G80\nM2\n",
    "g82_dwell": "G21 G90 F200\nG0 X1 Y1 Z5\nG82 X2 Y3 Z-2 R1 P0.5\nX4\nG80\nM2\n",
    "g83_peck": "G21 G90 F150\nG0 X0 Y0 Z5\nG83 X3 Y2 Z-7.3 R1 Q2\nX6 Q1.5\nG80\nM2\n",
    "g73_chip_break": "G20 G90 F30\nG0 X0 Y0 Z0.5\nG98 G73 X1 Y1 Z-0.33 R0.1 Q0.1\nX2\nG80\nM2\n",
    "g85_g89_boring": "G21 G90 F100\nG0 X0 Y0 Z8\nG85 X1 Y1 Z-2 R2\nG89 X3 Y1 Z-3 R2 P1\nX5\nG80\nM2\n",
    "g86_g88_spindle": "G21 G90 F100 S1000 M3\nG0 X0 Y0 Z8\nG86 X1 Y1 Z-2 R2 P0.2\nX2\nG88 X4 Y4 Z-1 R3 P0.1\nG80 G0 Z10\nM2\n",
    "g87_back_bore": "G21 G90 F120 S800 M3\nG0 X0 Y0 Z20\nG87 X10 Y10 Z-8 R5 I2 J0 K-4\nX20\nG80\nM2\n",
    "g84_g74_tapping": "G21 G90 F120 S500 M3\nG0 X0 Y0 Z10\nG84 X2 Y2 Z-5 R3\nX4\nG80\nM5\nM4\nG74 X6 Y6 Z-5 R3\nG80\nM2\n",
    "planes_yz_xz": "G21 G90 F100\nG0 X10 Y0 Z0\nG19 G81 Y3 Z2 X-1 R5\nZ4\nG80\nG0 Y10 X10\nG18 G83 Z1 X2 Y-4 R4 Q1.5\nG80\nM2\n",
    "offsets_and_rotation": "G21 G90 F100\nG10 L2 P2 X5 Y3 Z1 R30\nG55\nG0 X0 Y0 Z6\nG81 X4 Y1 Z-2 R2\nX8 Y-1\nG80\nM2\n",
    "g33_threading": "G20 G90 G18\nG0 X1 Z0.1\nS100 M3\nG33 Z-2 K0.025\nG0 X1.25\nZ0.1\nM5\nM2\n",
    "g95_per_revolution": "G21 G90 G94\nM3 S1000\nG0 X0 Z0\nG95 F0.1\nG1 X5\nG1 X10 Z-1\nG94 F300\nG1 Z-3\n"
                          "G95 F0.1\nS500\nG1 X12\nM2\n",
    "polar_repeats": "G21 G90 F100\nG0 X10 Y0 Z0\nG91 G81 ^45 R2 Z-3 L8\nG90 G80\nG0 X0 Y0\nG81 @15 ^10 R1 Z-1\n^70\nG80\nM2\n",
}


def load(path, axes="xyz"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GcodeWarning)
        return load_gcode(path, axes=axes)


def feed_segments_of_linuxcnc(ref: dict) -> np.ndarray:
    """LinuxCNC's feed moves as (start, end) in XYZ [mm], shape (m, 2, 3)."""
    out, last = [], np.zeros(3)
    for kind, _, point, _ in ref["moves"]:
        p = np.array(point[:3])
        if kind == "feed" and np.any(p != last):
            out.append((last, p))
        last = p
    return np.array(out)


def feed_segments_of(program) -> np.ndarray:
    """The line pieces of the contours, in order, as (start, end) [mm], shape (m, 2, 3)."""
    scale = 25.4 if program.units == "inch" else 1.0
    out = []
    for c in program.contours:
        assert c.curve.degree == 1
        P = c.curve.control_points * scale
        out.extend(zip(P[:-1], P[1:]))
    return np.array(out)


@needs_linuxcnc
@pytest.mark.parametrize("name", sorted(CYCLES))
def test_cycles_feed_as_linuxcnc_does(tmp_path, name):
    path = tmp_path / f"{name}.ngc"
    path.write_text(CYCLES[name])
    ref = linuxcnc_moves(path)
    assert ref["error"] is None, ref["error"]
    expected = feed_segments_of_linuxcnc(ref)
    got = feed_segments_of(load(path))
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)


@needs_linuxcnc
@pytest.mark.parametrize("name", sorted(CYCLES))
def test_cycles_rapid_where_linuxcnc_does(tmp_path, name):
    """Every contour starts where LinuxCNC's rapids (or a stop at the bottom) leave the
    tool, and nothing is fed that LinuxCNC rapids."""
    path = tmp_path / f"{name}.ngc"
    path.write_text(CYCLES[name])
    ref = linuxcnc_moves(path)
    traverse_ends = np.array([m[2][:3] for m in ref["moves"] if m[0] == "traverse"])
    program = load(path)
    scale = 25.4 if program.units == "inch" else 1.0
    for c in program.contours:
        start = c.curve.control_points[0] * scale
        bottoms = feed_segments_of_linuxcnc(ref)[:, 1]
        near = np.min(np.linalg.norm(np.vstack([traverse_ends, bottoms]) - start, axis=1))
        assert near <= 1e-9


def test_each_plunge_is_a_contour_with_the_programmed_feed(tmp_path):
    path = tmp_path / "holes.ngc"
    path.write_text(CYCLES["g81_g99_absolute"])
    program = load(path)
    assert len(program.contours) == 3
    for c, (x, y, z) in zip(program.contours, [(5, 5, -3), (10, 5, -3), (10, 10, -4)]):
        np.testing.assert_array_equal(c.curve.control_points, [[x, y, 2], [x, y, z]])
        np.testing.assert_array_equal(c.programmed_feed, [300.0])


def test_g83_pecks_reach_the_bottom_in_q_steps(tmp_path):
    path = tmp_path / "peck.ngc"
    path.write_text(CYCLES["g83_peck"])
    first = [c for c in load(path).contours if c.curve.control_points[0][0] == 3]
    depths = [c.curve.control_points[-1][2] for c in first]
    np.testing.assert_allclose(depths, [-1, -3, -5, -7, -7.3], atol=1e-12)
    # each peck after the first starts 0.010 inch above the depth reached (LinuxCNC 2.9)
    starts = [c.curve.control_points[0][2] for c in first[1:]]
    np.testing.assert_allclose(starts, np.array(depths[:-1]) + 0.254, atol=1e-12)


def test_cycles_on_a_2_axis_machine_leave_no_xy_contour(tmp_path):
    path = tmp_path / "holes.ngc"
    path.write_text(CYCLES["g81_g99_absolute"])
    with pytest.raises(PathFileError, match="no feed move of the path axes XY"):
        load(path, axes="xy")


@pytest.mark.parametrize("text, match", [
    ("G21 G90 F100\nG0 Z5\nG81 X1 Y1 Z-1\nM2\n", r"line 3: G81 needs the retract level R"),
    ("G21 G90 F100\nG0 Z5\nG81 X1 Y1 R1\nM2\n", r"line 3: G81 needs the depth Z"),
    ("G21 G90 F100\nG0 Z5\nG83 X1 Y1 R1 Z-3\nM2\n", r"line 3: G83 needs Q"),
    ("G21 G90 F100\nG0 Z5\nG81 X1 Y1 R-3 Z-1\nM2\n", r"line 3: G81: the retract level R \(-3\) is below"),
    ("G21 G90\nG0 Z5\nG81 X1 Y1 R1 Z-1\nM2\n", r"line 3: G81: a canned cycle needs a feed rate"),
    ("G21 G90 F100\nG0 Z5\nG81 X1 Y1 R1 Z-1 L0\nM2\n", r"line 3: G81: repeats L0"),
    ("G21 G90 F100\nG0 Z5\nG76 P0.1 Z-10 I-0.1 J0.1 K0.5\nM2\n", r"line 3: G76: the G76 threading cycle is not read"),
    ("G21 G90 F100\nG0 Z5\nG81 X1 Y1 R1 Z-1\nG80\nX3\nM2\n", r"line 5: axis words \['X'\] after G80"),
])
def test_cycle_refusals_name_the_line(tmp_path, text, match):
    path = tmp_path / "bad.ngc"
    path.write_text(text)
    with pytest.raises(PathFileError, match=match) as info:
        load(path)
    assert "\n" not in str(info.value)


def test_spindle_paced_moves_take_their_feed_from_s(tmp_path):
    """G95: F per revolution x S; G33: pitch K x S; G33.1 in and out at that pace."""
    (tmp_path / "g95.ngc").write_text(CYCLES["g95_per_revolution"])
    program = load(tmp_path / "g95.ngc")
    feeds = np.concatenate([c.programmed_feed for c in program.contours])
    # F0.1 mm/rev at 1000 rpm = 100 mm/min; G94 F300; F0.1 at 500 rpm = 50 mm/min
    np.testing.assert_allclose(feeds, [100, 100, 300, 50])
    path = tmp_path / "tap.ngc"
    path.write_text("G20 G90\nM3 S200\nG0 X1 Y1 Z0.1\nG33.1 Z-0.75 K0.05\nG0 X2\nM2\n")
    tap = load(path)
    assert len(tap.contours) == 2  # in, and out after the spindle reverses
    np.testing.assert_allclose(tap.contours[0].curve.control_points, [[1, 1, 0.1], [1, 1, -0.75]])
    np.testing.assert_allclose(tap.contours[1].curve.control_points, [[1, 1, -0.75], [1, 1, 0.1]])
    np.testing.assert_allclose([c.programmed_feed[0] for c in tap.contours], [10.0, 10.0])  # 0.05 in x 200


@pytest.mark.parametrize("text, match", [
    ("G21 G90\nG0 X0 Z0\nG33 Z-2 K1\nM2\n", r"line 3: G33 moves with the spindle: it needs an S word and M3/M4"),
    ("G21 G90\nS100 M3\nG0 X0 Z0\nG33 Z-2\nM2\n", r"line 4: G33 needs the pitch K"),
    ("G21 G90 G95 F0.1\nG0 X0\nG1 X5\nM2\n", r"line 3: feed per revolution \(G95\) needs a turning spindle"),
])
def test_spindle_paced_moves_need_a_turning_spindle(tmp_path, text, match):
    path = tmp_path / "bad.ngc"
    path.write_text(text)
    with pytest.raises(PathFileError, match=match):
        load(path)


def test_a_program_of_rapids_only_is_its_rapids_with_no_feed(tmp_path):
    """LinuxCNC's trajectory-planner tests of rapids (quick-tests/long-kink.ngc)."""
    path = tmp_path / "rapids.ngc"
    path.write_text("G20 G90 G64 G17\nG0 x0 y0 z0\nG0 X1.0\nG0 X1.01 y.001\nG0 X2.0\nM2\n")
    with pytest.warns(GcodeWarning, match=r"no feed move: its rapids \(G0\) are read as the path, with no "
                      r"programmed feed \(give one\)"):
        program = load_gcode(path, axes=None)
    assert program.rapids_only and program.axes == "XY"
    (c,) = program.contours
    np.testing.assert_array_equal(c.curve.control_points, [[0, 0], [1, 0], [1.01, 0.001], [2, 0.001]])
    assert np.all(np.isnan(c.programmed_feed))
