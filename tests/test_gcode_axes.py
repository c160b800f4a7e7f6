"""Which axes a G-code program is read on: every axis it moves (``axes=None``, what
``nurbsmotion contours`` lists), the machine's, or the projection on the machine's
(``project``, ``--project``), and the note on feed moves left out."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from nurbsmotion.cli import main
from nurbsmotion.errors import PathFileError
from nurbsmotion.paths.gcode import GcodeWarning, load_gcode

CORPUS = Path(__file__).resolve().parent / "data" / "corpus"

PLUNGE_THEN_XY = "G21 G90 F600\nG0 X0 Y0 Z5\nG1 Z-1\nG1 X10\nG1 Y10\nG0 Z5\nM2\n"
HELIX = "G21 G90 G17 F600\nG0 X10 Y0 Z0\nG3 X10 Y0 I-10 J0 Z-3 P2\nM2\n"
ROTARY = "G21 G90 F600\nG0 X0 Y0 Z0 C0\nG1 X10 C90\nG1 Y5 C180\nM2\n"
ARC_BETWEEN_EQUAL_Y = "G20 G90 F100\nG0 X0 Y0\nG1 X.1\nG2 X.2 R.1\nM2\n"


def load(tmp_path, text, **kw):
    path = tmp_path / "p.ngc"
    path.write_text(text)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        program = load_gcode(path, **kw)
    return program, [str(w.message) for w in caught if issubclass(w.category, GcodeWarning)]


@pytest.mark.parametrize("text, axes, n_contours", [
    (PLUNGE_THEN_XY, "XYZ", 1),  # the plunge is the first piece of the cut
    (HELIX, "XYZ", 1),
    (ROTARY, "XYC", 1),  # Z never moves: not a column
    (ARC_BETWEEN_EQUAL_Y, "XY", 1),  # the arc moves Y between ends of equal Y
])
def test_without_axes_every_axis_the_program_moves(tmp_path, text, axes, n_contours):
    program, _ = load(tmp_path, text, axes=None)
    assert program.axes == axes
    assert len(program.contours) == n_contours
    assert program.contours[0].curve.n_axes == len(axes)


def test_on_the_files_axes_the_plunge_is_part_of_the_contour(tmp_path):
    program, _ = load(tmp_path, PLUNGE_THEN_XY, axes=None)
    np.testing.assert_array_equal(program.contours[0].curve.control_points,
                                  [[0, 0, 5], [0, 0, -1], [10, 0, -1], [10, 10, -1]])


def test_a_plunge_left_out_on_two_axes_is_said_once(tmp_path):
    program, messages = load(tmp_path, PLUNGE_THEN_XY + "G0 X0 Y0\nG1 Z-2\nG1 X3\nM2\n", axes="xy")
    assert program.axes == "XY"
    said = [m for m in messages if "not part of the contours" in m]
    assert said == [f"{tmp_path / 'p.ngc'}, line 3: feed moves of Z (the first here) are not part "
                    "of the contours on the axes XY; a machine with the axes XYZ would follow them"]


def test_a_helix_on_two_axes_is_refused_or_projected_when_asked(tmp_path):
    with pytest.raises(PathFileError, match=r"line 3: G3 moves Z together with the path axes XY; "
                       r"a machine with the axes XYZ can follow it \(or read the path's "
                       r"projection on XY: --project xy\)"):
        load(tmp_path, HELIX, axes="xy")
    program, _ = load(tmp_path, HELIX, axes="xy", project=True)
    curve = program.contours[0].curve
    points = curve(np.linspace(0, 1, 2001))
    np.testing.assert_allclose(np.hypot(points[:, 0], points[:, 1]), 10.0, rtol=1e-8)
    assert curve.length == pytest.approx(2 * 2 * np.pi * 10, rel=1e-6)  # two turns


def test_a_refused_move_names_every_axis_the_program_moves(tmp_path):
    """A Z move refused on XY, with an A move further down: the message names XYZA (what
    `contours` lists), not only this line's XYZ, which would be refused at the A move."""
    text = "G21 G90 G17\nG0 X0 Y0 Z0 A0\nG1 X5 Y0 Z1 F100\nG1 X9 Y2 Z1 A30\nM2\n"
    with pytest.raises(PathFileError, match=r"line 3: G1 moves Z together with the path axes XY; "
                       r"the program moves XYZA: a machine with those axes can follow it \(or "
                       r"read the path's projection on XY: --project xy\)"):
        load(tmp_path, text, axes="xy")
    assert load(tmp_path, text, axes=None)[0].axes == "XYZA"


def test_contours_lists_the_files_axes_without_a_flag(capsys):
    assert main(["contours", str(CORPUS / "tp_helix_slowdown.ngc")]) == 0
    out = capsys.readouterr().out
    assert "\naxes: XYZ (every axis the file moves; --axes to choose)\n" in out and " z[" in out


def test_contours_labels_rotary_axes_in_degrees(tmp_path, capsys):
    path = tmp_path / "rot.ngc"
    path.write_text(ROTARY)
    assert main(["contours", str(path)]) == 0
    out = capsys.readouterr().out
    assert "axes: XYC (A, B, C in degrees)" in out and "c[0, 180] deg" in out


def test_project_must_name_the_machines_axes(capsys):
    assert main(["bound", str(CORPUS / "tp_helix_slowdown.ngc"), "--feed", "10mm/s",
                 "--project", "xz"]) != 0
    assert "--project xz must name the machine's axes (xy)" in capsys.readouterr().err
    assert main(["bound", str(CORPUS / "tp_helix_slowdown.ngc"), "--feed", "10mm/s",
                 "--project", "xy"]) == 0


# The public files of tests/data/corpus that `nurbsmotion contours FILE` lists with no flag:
# every one but those whose own content is the reason (LinuxCNC refuses them too, or they
# move nothing).
NOT_LISTED = {
    "freecad_test_centroid_00.ngc",  # no F word at all
    "factorial.ngc", "gosper.ngc", "helix.ngc", "m70m72-demo.ngc", "offsets.ngc",  # no feed move
    "metric_wrench.ngc",  # needs a HAL pin of a running plasma machine
    "nestedcall.ngc",  # an O-word LinuxCNC refuses too
}


@pytest.mark.parametrize("path", sorted(p for p in CORPUS.iterdir() if p.is_file() and p.suffix.lower() != ".md"),
                         ids=lambda p: p.name)
def test_corpus_files_list_without_flags(path, capsys):
    code = main(["contours", str(path)])
    assert (code == 0) == (path.name not in NOT_LISTED), capsys.readouterr().err


def test_a_rotary_path_is_refused_on_a_machine_without_pulses_per_degree(tmp_path, capsys):
    """Degrees would be scaled by the pulse length as if they were lengths: refused,
    naming the axis and the machine-file key that runs it (tests/test_rotary_axes.py)."""
    import json

    from nurbsmotion.machine import die_bonder

    d = die_bonder().to_dict()
    x = d["axes"][0]
    d["axes"] = [dict(x, name=n) for n in "xyc"]
    machine = tmp_path / "xyc.json"
    machine.write_text(json.dumps(d))
    path = tmp_path / "rot.ngc"
    path.write_text(ROTARY)
    assert main(["bound", str(path), "--machine", str(machine), "--feed", "10mm/s"]) != 0
    err = capsys.readouterr().err
    assert "the path moves the rotary axis C [deg], but machine 'die-bonder' gives no " \
        "pulses_per_degree for it" in err


@pytest.mark.parametrize("bulk", [True, False])
def test_a_move_shorter_than_linuxcncs_epsilon_is_dropped(tmp_path, bulk):
    """LinuxCNC's planner drops a segment under TP_POS_EPSILON = 1e-12 (tp.c,
    TP_ERR_ZERO_LENGTH); cone.ngc's 100*sin[-180] = -1.2e-14 mm made a piece with no
    direction, whose bound was an infinite time. Read in bulk (plain lines) and line by
    line (an expression on each line), the same."""
    y = "-0.0000000000000122" if bulk else "[100 * SIN[-180]]"
    program, _ = load(tmp_path, f"G21 G90 F600\nG0 X0 Y0\nG1 X10\nG1 X10 Y{y}\nG1 Y10\nM2\n",
                      axes="xy")
    contour = program.contours[0]
    assert len(contour.programmed_feed) == 2 and contour.lines == (3, 5)
    np.testing.assert_allclose(contour.curve(np.array([0.0, 1.0])), [[0, 0], [10, 10]], atol=1e-12)
