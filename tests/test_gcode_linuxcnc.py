"""G-code geometry against LinuxCNC's own interpreter, and the real-world corpus.

Where LinuxCNC's Python ``gcode`` module is importable (Debian/Ubuntu package
``linuxcnc-uspace``; with a venv Python, through Debian's ``/usr/bin/python3`` in a
subprocess), every feed and arc point LinuxCNC computes for a program must lie on the path
nurbsmotion reads, within 1e-6 mm. Without it these comparisons skip; the corpus test
(every file loads, or is refused for a reason the file has) always runs.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from linuxcnc_reference import linuxcnc_moves, linuxcnc_python, max_distance
from nurbsmotion.errors import PathFileError
from nurbsmotion.paths.gcode import GcodeWarning, load_gcode

CORPUS = Path(__file__).resolve().parent / "data" / "corpus"
GCODE_FILES = sorted(p for p in CORPUS.iterdir() if p.suffix.lower() in (".ngc", ".nc", ".gcode", ".tap", ".cnc"))
needs_linuxcnc = pytest.mark.skipif(linuxcnc_python() is None,
                                    reason="LinuxCNC's gcode module (linuxcnc-uspace) is not installed")

# Programs written for this test: each exercises a part of the language or the motion
# model that shapes the path; LinuxCNC's interpreter is the reference for all of them.
PROGRAMS = {
    "parameters_and_expressions": """G21 G90 G17
#1 = 10
#<side> = [#1 * 2]
#<_depth> = -1
G0 X0 Y0 Z5
G1 Z#<_depth> F[100 + 20]
G1 X#<side> Y[#1 / 4 + sin[30] * 2]
G1 X[sqrt[144] + 2 ** 3] Y[atan[1]/[1] - 40]
G1 X[abs[-3] MOD 2 + fix[2.7] + fup[0.2] + round[1.5]] Y[exp[ln[5]]]
G1 X[cos[60] * 10] Y[10 * [1 GT 0] + [2 EQ 2] + [1 AND 0] + [0 OR 1] + [1 XOR 1]]
M2
""",
    "subroutines_and_control_flow": """G21 G90
o<square> sub
  G1 X[#1 + #3] Y#2
  G1 Y[#2 + #3]
  G1 X#1
  G1 Y#2
o<square> endsub
o<twice> sub
  o<twice> return [#1 * 2]
o<twice> endsub
G0 X0 Y0 Z1
G1 Z0 F300
#<i> = 0
o100 while [#<i> LT 3]
  o<square> call [#<i> * 12] [0] [10]
  #<i> = [#<i> + 1]
o100 endwhile
o<twice> call [7]
o101 if [#<_value> GT 20]
  G1 X99
o101 elseif [#<_value> GT 10]
  G1 X14 Y20
o101 else
  G1 X1
o101 endif
o102 repeat [3]
  G91 G1 X1 Y1
o102 endrepeat
G90
#2 = 0
o103 do
  G1 X[50 + #2] Y30
  #2 = [#2 + 5]
o103 while [#2 LT 20]
M2
""",
    "planes_helices_offsets": """G20 G90 G17
G10 L2 P2 X1 Y0.5 Z0
G55
G0 X0 Y0 Z0.1
G1 Z0 F20
G2 X1 Y0 I0.5 J0
G3 X0 Y0 R0.5
G2 X0 Y0 Z-0.3 I0.25 J0 P2
G18 G2 X0.5 Z-0.3 I0.25 K0
G19 G3 Y0.5 Z-0.1 J0.25 K0.1
G17
G92 X0 Y0
G1 X0.3 Y0.2
G91 G1 X0.1 Y-0.1
G90.1 G90 G2 X0.6 Y0.1 I0.5 J0.15
G91.1
G54 G92.1
G53 G1 X2 Y2
G28
M2
""",
    "nurbs_g5_g5_1_g5_2": """G21 G90 G17
G0 X0 Y0
G1 X1 F120
G5 X10 Y10 I3 J0 P-3 Q0
G5 X20 Y0 P-2 Q-3
G5.1 X25 Y5 I2 J3
G5.2 P1 L4
  X25 Y5 P1
  X30 Y15 P2
  X40 Y-5 P0.5
  X45 Y5 P1
  X50 Y0 P1
G5.3
M2
""",
}

# LinuxCNC cuts an arc whose end radius differs from its start radius (within its
# tolerance) into preview points on the *start* circle and then jumps to the end; its
# motion (and nurbsmotion) follows a spiral. The preview points of such an arc are off the
# spiral by up to the radius difference, which these files have:
# CAM posts write rounded numbers, so nearly every arc of theirs is such a spiral: the
# largest |end radius - start radius| of each file's arcs, from its X Y I J words.
SPIRAL_MISMATCH_MM = {"tp_arc-with-spiral.ngc": 0.0127, "tp_linearc-stellabee.ngc": 0.001,
                      "tp_tort-sam-mach3.ngc": 2e-6, "estlcam_3-SpoolFixture.nc": 7.64e-5,
                      "fusion360_eighth_inch_two_holes.nc": 1.065e-3,
                      "inkscape_gcodetools_0_0.gcode": 1.19e-6}


def load_quiet(path: Path, axes: str = "xyz"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GcodeWarning)
        return load_gcode(path, axes=axes)


@needs_linuxcnc
@pytest.mark.parametrize("name", sorted(PROGRAMS))
def test_written_programs_pass_through_linuxcncs_points(tmp_path, name):
    path = tmp_path / f"{name}.ngc"
    path.write_text(PROGRAMS[name])
    ref = linuxcnc_moves(path)
    assert ref["error"] is None, ref["error"]
    program = load_quiet(path)
    scale = 25.4 if program.units == "inch" else 1.0
    dist, n = max_distance(path, [c.curve for c in program.contours], scale)
    assert n >= 5
    assert dist <= 1e-6


def linuxcnc_accepts(path: Path) -> bool:
    ref = linuxcnc_moves(path)
    return ref["error"] is None and any(m[0] in ("feed", "arc") for m in ref["moves"])


@needs_linuxcnc
@pytest.mark.parametrize("path", GCODE_FILES, ids=lambda p: p.name)
def test_corpus_programs_pass_through_linuxcncs_points(path):
    if not linuxcnc_accepts(path):
        pytest.skip("LinuxCNC 2.9's interpreter refuses the program or draws nothing")
    try:
        program = load_quiet(path)
    except PathFileError:
        expected = CORPUS_EXPECTED[path.name]
        assert expected != "ok"
        return
    scale = 25.4 if program.units == "inch" else 1.0
    dist, n = max_distance(path, [c.curve for c in program.contours], scale)
    assert dist <= 1e-6 + SPIRAL_MISMATCH_MM.get(path.name, 0.0)


# Every corpus file: "ok" (loads on a 3-axis XYZ machine), or the reason the file itself
# gives for a refusal (a regular expression of the one-line error).
CORPUS_EXPECTED = {
    "3dtest.ngc": "ok",
    "G5_butterfly-zx.ngc": "ok",
    "G5_leto-xy.ngc": "ok",
    "G5_nurbs-yz.ngc": "ok",
    "G5_trident-xy-yz-zx.ngc": "ok",
    "G5_trident-xy.ngc": "ok",
    "G6_Curva_Mazatrol_1=1-xy-yz-zx.ngc": "ok",
    "G6_Curva_Stella_1=1.ngc": "ok",
    "G6_Ruota_dentata_1=2.ngc": "ok",
    "cone.ngc": r"line 17: G1 moves C together with the path axes XYZ",  # a rotary C axis
    "estlcam_3-SpoolFixture.nc": "ok",
    "estlcam_BackPlate.nc": "ok",  # a nested comment, read as one comment with a warning (LinuxCNC refuses it)
    "freecad_test_centroid_00.ngc": r"line 15: feed move without a feed rate",  # no F in the file
    "fusion360_eighth_inch_two_holes.nc": "ok",
    "inkscape_gcodetools_0_0.gcode": "ok",
    "daisy.ngc": r"G1 moves A together with the path axes XYZ",  # a rotary A axis
    "factorial.ngc": r"no feed move",  # prints a table, moves nothing
    "flowsnake.ngc": "ok",
    "gosper.ngc": r"no feed move",  # an ngcgui subroutine file: defines, never calls
    "helix.ngc": r"no feed move",  # likewise
    "hole-circle.ngc": "ok",  # G81 in G91 with polar ^ and L repeats
    "m70m72-demo.ngc": r"no feed move",  # shows modal state, moves nothing
    "metric_wrench.ngc": r"line 9: #<_hal\[plasmac.cut-feed-rate\]> reads a HAL pin of a running LinuxCNC, "
                         r"which a program file alone does not give: replace it with its value",  # a HAL pin
    "nestedcall.ngc": r"line 11: cannot read the O-word 'o<g20sub>callsub': 'callsub' is not a keyword "
                      r"\(LinuxCNC refuses it too\); write o<g20sub> call",  # LinuxCNC: line 11 too
    "offsets.ngc": r"no feed move",  # sets tool offsets only
    "polar.ngc": "ok",  # G81 with polar @ ^
    "tp_arc-arc-planeswitch.ngc": "ok",
    "tp_arc-with-spiral.ngc": "ok",
    "tp_full_xz.ngc": "ok",
    "tp_full_yz.ngc": "ok",
    "tp_helix_slowdown.ngc": "ok",
    "tp_linearc-stellabee.ngc": "ok",
    "tp_tort-sam-mach3.ngc": "ok",
    "tp_spiral_tight_circular.ngc": "ok",
}


@pytest.mark.parametrize("path", GCODE_FILES, ids=lambda p: p.name)
def test_every_corpus_program_loads_or_is_refused_for_its_own_reason(path):
    expected = CORPUS_EXPECTED[path.name]
    if expected == "ok":
        program = load_quiet(path)
        assert program.contours and all(c.curve.length > 0 for c in program.contours)
        for c in program.contours:
            assert np.all(np.isfinite(c.curve.control_points))
            assert len(c.programmed_feed) == len(c.piece_edges) - 1 == len(c.lines)
    else:
        with pytest.raises(PathFileError, match=expected) as info:
            load_quiet(path)
        assert "\n" not in str(info.value)


def test_corpus_has_its_sources_listed():
    sources = (CORPUS / "SOURCES.md").read_text()
    for path in CORPUS.iterdir():
        if path.name != "SOURCES.md":
            assert f"`{path.name}`" in sources, path.name


def rs274_canon(program: Path, tmp_path: Path) -> list[tuple[str, list[float]]]:
    """The canonical calls of LinuxCNC's standalone interpreter ``rs274 -g`` (name and
    numbers, as it prints them: 4 decimals in the program's units)."""
    import re
    import subprocess

    out = subprocess.run(["rs274", "-g", str(program)], input="\n\n", capture_output=True, text=True,
                         timeout=60, cwd=tmp_path).stdout
    calls = re.findall(r"N\.+\s+(STRAIGHT_FEED|ARC_FEED|STRAIGHT_TRAVERSE)\(([^)]*)\)", out)
    return [(name, [float(v) for v in args.split(",")]) for name, args in calls]


@pytest.mark.skipif(__import__("shutil").which("rs274") is None, reason="LinuxCNC's rs274 is not installed")
def test_r_word_arcs_in_inches_agree_with_linuxcnc_to_rounding_only(tmp_path):
    """spiral_tight_circular (LinuxCNC's own test, R-word arcs in inches) was once reported
    2e-3 mm off LinuxCNC's interpreter. It is not: its arcs' end points and centres agree
    with the interpreter's full-precision numbers (the ``gcode`` module, to 1e-9 mm in
    ``test_corpus_programs_pass_through_linuxcncs_points``), while ``rs274 -g`` prints them
    with 4 decimals of an inch: up to 5e-5 inch = 1.27e-3 mm per coordinate, 1.8e-3 mm in
    XY. The reader is right; the 2e-3 mm was the print's rounding."""
    path = CORPUS / "tp_spiral_tight_circular.ngc"
    program = load_quiet(path)
    assert program.units == "inch"
    arcs = [args for name, args in rs274_canon(path, tmp_path) if name == "ARC_FEED"]
    assert len(arcs) == 60
    (contour,) = [c for c in program.contours if len(c.lines) > 1]
    ends = contour.curve(contour.piece_edges[1:])[:, :2]  # [inch]
    printed = np.array([a[:2] for a in arcs])
    error = np.abs(ends - printed)
    assert np.max(error) <= 0.5e-4 + 1e-12  # within the print's rounding ...
    assert np.max(np.hypot(*error.T)) * 25.4 > 1e-3  # ... which is the reported 2e-3 mm
    # the centres LinuxCNC prints: equidistant (to that rounding) from each arc's ends
    starts = contour.curve(contour.piece_edges[:-1])[:, :2]
    centres = np.array([a[2:4] for a in arcs])
    radii = np.hypot(*(starts - centres).T), np.hypot(*(ends - centres).T)
    assert np.max(np.abs(radii[0] - radii[1])) <= 2 * 0.5e-4 * np.sqrt(2)


KEYWORDS = ["sub", "endsub", "call", "do", "while", "repeat", "if", "elseif", "else", "endif",
            "break", "continue", "endwhile", "endrepeat", "return"]


@pytest.mark.skipif(__import__("shutil").which("rs274") is None, reason="LinuxCNC's rs274 is not installed")
@pytest.mark.parametrize("keyword", KEYWORDS)
def test_an_o_word_keyword_with_letters_glued_on_is_refused_as_linuxcnc_refuses_it(tmp_path, keyword):
    """LinuxCNC's lexer (read_o in interp_read.cc) matches the keyword's letters and refuses
    what follows ('Unexpected character after O-word', or 'Left bracket missing' after
    if/while/repeat): nestedcall.ngc's `O<g20sub> callsub` (issue 36). Refused here on the
    same line, naming the keyword to write."""
    import subprocess

    program = tmp_path / "glued.ngc"
    program.write_text(f"G21 F100\nG1 X1\no100 {keyword}zz\nG1 X2\nM2\n")
    r = subprocess.run(["rs274", "-g", str(program)], stdin=subprocess.DEVNULL, capture_output=True,
                       text=True, timeout=60, cwd=tmp_path)
    assert r.returncode != 0 and f"o100 {keyword}zz" in r.stderr  # LinuxCNC refuses that line
    with pytest.raises(PathFileError, match=rf"line 3: cannot read the O-word 'o100{keyword}zz': "
                                            rf"'{keyword}zz' is not a keyword \(LinuxCNC refuses it "
                                            rf"too\); write o100 {keyword} with nothing glued") as info:
        load_quiet(program)
    assert "\n" not in str(info.value)


# An arc from (r, 0) about the origin to (0, r + diff): its end radius differs by diff.
# LinuxCNC accepts it as a spiral unless diff > 100 tol, or diff > tol and diff > 0.1 % of
# the radius (interp_arc.cc), tol its default per unit: 2 * 0.01 * sqrt(2) mm, 2 * 0.001 *
# sqrt(2) inch. Cases on both sides of each rule, in each unit.
SPIRAL_CASES = [("G21", 10.0, 0.02), ("G21", 10.0, 0.03), ("G21", 10000.0, 2.8), ("G21", 10000.0, 2.9),
                ("G20", 1.0, 0.002), ("G20", 1.0, 0.0029), ("G20", 1000.0, 0.28), ("G20", 1000.0, 0.29),
                ("G20", 1.0, 0.0011), ("G20", 10.0, 0.009)]


@pytest.mark.skipif(__import__("shutil").which("rs274") is None, reason="LinuxCNC's rs274 is not installed")
@pytest.mark.parametrize("units,radius,diff", SPIRAL_CASES)
def test_spiral_arcs_are_read_where_linuxcnc_reads_them(tmp_path, units, radius, diff):
    """Issue 36: an inch program's spiral within LinuxCNC's inch tolerance (0.0028 inch) was
    refused here (the mm tolerance converted, 0.0011 inch); LinuxCNC's standalone
    interpreter is the oracle for each case, and where both read it the end point agrees."""
    program = tmp_path / "spiral.ngc"
    program.write_text(f"{units} G90 G17 F10\nG0 X{radius} Y0\nG3 X0 Y{radius + diff} I{-radius} J0\nM2\n")
    arcs = [args for name, args in rs274_canon(program, tmp_path) if name == "ARC_FEED"]
    if not arcs:
        with pytest.raises(PathFileError, match=r"line 3: radius to end of arc differs .*LinuxCNC "
                                                r"refuses it too") as info:
            load_quiet(program)
        assert "\n" not in str(info.value)
        return
    (contour,) = load_quiet(program, axes="xy").contours
    np.testing.assert_allclose(contour.curve(1.0), arcs[0][:2], atol=1e-4 * max(1.0, radius))
