"""Subroutine files, nested comments and a running LinuxCNC's parameters.

``o<name> call`` of a subroutine the program does not define runs ``name.ngc`` from the
program's folder or ``subroutine_path`` (LinuxCNC's SUBROUTINE_PATH), nested calls too;
the path is the one ``rs274 -g`` (LinuxCNC's standalone interpreter, run in that folder,
4 decimals) prints. An error inside such a file names that file and its line. A nested
comment, which LinuxCNC refuses but CAM posts write, is read as one comment with one
warning; ``#<_hal[...]>`` and ``#<_ini[...]>`` are refused, naming the line and the remedy.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest

from nurbsmotion.errors import PathFileError
from nurbsmotion.paths.gcode import GcodeWarning, load_gcode

SQUARE = """(a square of side #3 from X#1 Y#2, then o<back>)
o<square> sub
  G1 X[#1 + #3] Y#2
  Y[#2 + #3]
  X#1
  Y#2
  o<back> call [#1]
o<square> endsub
M2
"""
BACK = """o<back> sub
  G1 X[#1 - 1] Y-1
o<back> endsub
"""
MAIN = """G21 G90
G0 X0 Y0
G1 F100 X1
o<square> call [1] [0] [5]
o<square> call [10] [0] [2]
G1 X20 Y20
M2
"""


def load_quiet(path: Path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GcodeWarning)
        return load_gcode(path, **kw)


def ends(program) -> np.ndarray:
    (contour,) = program.contours
    return contour.curve(contour.piece_edges[1:])


@pytest.mark.skipif(shutil.which("rs274") is None, reason="LinuxCNC's rs274 is not installed")
def test_subroutine_files_run_as_linuxcnc_runs_them(tmp_path):
    (tmp_path / "square.ngc").write_text(SQUARE)
    (tmp_path / "back.ngc").write_text(BACK)
    (tmp_path / "main.ngc").write_text(MAIN)
    out = subprocess.run(["rs274", "-g", "main.ngc"], input="\n\n", capture_output=True, text=True,
                         timeout=60, cwd=tmp_path).stdout
    printed = np.array([[float(v) for v in a.split(",")[:2]]
                        for a in re.findall(r"STRAIGHT_FEED\(([^)]*)\)", out)])
    assert len(printed) == 12
    got = ends(load_quiet(tmp_path / "main.ngc"))
    assert got.shape == printed.shape
    assert np.max(np.abs(got - printed)) <= 0.5e-4


def test_subroutine_path_and_the_line_numbers_of_called_files(tmp_path):
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "square.ngc").write_text(SQUARE)
    (lib / "back.ngc").write_text(BACK)
    (tmp_path / "main.ngc").write_text(MAIN)
    with pytest.raises(PathFileError, match=r"main.ngc, line 4: o<square> call: no subroutine o<square> in "
                                            r"this file nor a file in .*: define it here or put it in a file "
                                            r"square.ngc beside the program \(or on subroutine_path\)"):
        load_quiet(tmp_path / "main.ngc")
    program = load_quiet(tmp_path / "main.ngc", subroutine_path=[lib])
    assert ends(program)[:4].tolist() == [[1.0, 0.0], [6.0, 0.0], [6.0, 5.0], [1.0, 5.0]]
    n = len(MAIN.splitlines())
    assert program.contours[0].lines[:3] == (3, n + 2, n + 3)  # o<square> sub is line n + 1


def test_an_error_in_a_subroutine_file_names_that_file_and_line(tmp_path):
    (tmp_path / "square.ngc").write_text(SQUARE.replace("Y[#2 + #3]", "Y[#2 / [#3 - 5]]"))
    (tmp_path / "back.ngc").write_text(BACK)
    (tmp_path / "main.ngc").write_text(MAIN)
    with pytest.raises(PathFileError, match=r"square.ngc, line 4: expression cannot be evaluated: .*"
                                            r"\(in o<square>, called from main.ngc\)") as info:
        load_quiet(tmp_path / "main.ngc")
    assert info.value.line == 4 and info.value.source.endswith("square.ngc")


def test_a_subroutine_file_without_sub_and_endsub_is_refused(tmp_path):
    (tmp_path / "square.ngc").write_text("G1 X1\n")
    (tmp_path / "main.ngc").write_text(MAIN)
    with pytest.raises(PathFileError, match=r"square.ngc, line 1: the subroutine file defines no o<square> sub "
                                            r"\.\. o<square> endsub: wrap its lines in them"):
        load_quiet(tmp_path / "main.ngc")


def test_nested_comment_is_one_comment_with_a_warning(tmp_path):
    text = "G21\nG0 X0 Y0\n(HSS Twist Drill, 3mm (R)) G1 X5 F100\nG1 Y5 (a (b (c)) d)\nM2\n"
    path = tmp_path / "n.ngc"
    path.write_text(text)
    with pytest.warns(GcodeWarning, match=r"n.ngc, line 3: nested comment read as one comment \(2 line\(s\)\); "
                                          r"LinuxCNC refuses it: remove the inner parentheses"):
        program = load_gcode(path)
    plain = tmp_path / "p.ngc"
    plain.write_text(re.sub(r"\(.*\)", "", text))
    assert program.contours[0].curve == load_quiet(plain).contours[0].curve
    path.write_text("G21\nG1 X1 F10 (a (b)\n")
    with pytest.raises(PathFileError, match=r"line 2: comment '\(' is not closed on this line: close it"):
        load_quiet(path)


@pytest.mark.parametrize("name,what", [("_hal[plasmac.cut-feed-rate]", "a HAL pin of a running LinuxCNC"),
                                       ("_ini[axis_x]max_velocity", "the INI file of a LinuxCNC configuration")])
def test_hal_and_ini_parameters_are_refused_with_the_remedy(tmp_path, name, what):
    path = tmp_path / "h.ngc"
    path.write_text(f"G21\nG0 X0 Y0\nF#<{name}>\nG1 X1\n")
    with pytest.raises(PathFileError, match=rf"line 3: #<{re.escape(name)}> reads {what}, which a program file "
                                            r"alone does not give: replace it with its value \(a number\)"):
        load_quiet(path)
