"""A G-code program refused for its sharp corners from its first lines (issue 37).

A million-line CAM zigzag was refused by ``run``/``bound`` only after the whole program
was read (5.3-5.8 s of CPU). Its first lines are now read by the reader itself
(:mod:`nurbsmotion.paths.gcode.first_part`), and where they already hold more sharp
corners than the planner's grid the command refuses without reading the rest. The limits
are lowered here (``planning.MAX_GRID_POINTS``); the first part's count is checked against
the whole program's as a run plans it (its chords joined, then
:meth:`NurbsCurve.sharp_corners` in pulses) on random programs: never more.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from nurbsmotion import planning, units
from nurbsmotion.cli import main
from nurbsmotion.errors import NurbsmotionError, WorkLimitError
from nurbsmotion.interpolators.planned.shorten import DEFAULT_PATH_TOLERANCE
from nurbsmotion.machine import load_machine
from nurbsmotion.paths.gcode.first_part import FIRST_PART_MARGIN, read_first_part
from nurbsmotion.study.run_input import load_run_contour

LIMIT = 1000
"""MAX_GRID_POINTS lowered: 19 sharp corners need 51 x 20 = 1,020 grid points, more
(most_corners() is 18)."""


def _zigzag(path, n: int, header: str = "G21 G90 G17\nG0 X0 Y0\nF600\n", every: str = "") -> str:
    """A program of ``n`` G1 lines of 0.01 mm turning by a right angle at every joint."""
    lines = [header]
    for i in range(1, n + 1):
        lines.append(f"G1 X{i * 0.01:.4f} Y{(i % 2) * 0.01:.4f}\n{every}")
    lines.append("M2\n")
    path.write_text("".join(lines))
    return str(path)


def _planned_corners(spec: str, machine) -> int:
    """The sharp corners of the path a run plans from ``spec`` (the whole program read)."""
    contour = load_run_contour(spec, machine)
    curve = contour.curve
    return len(units.Scale.of(curve, machine).path(curve).sharp_corners())


@pytest.fixture
def lowered(monkeypatch):
    monkeypatch.setattr(planning, "MAX_GRID_POINTS", LIMIT)
    assert planning.most_corners() == 18


@pytest.fixture
def no_whole_read(monkeypatch):
    """Fail where the whole program is read (load_gcode)."""
    import nurbsmotion.paths.gcode as gcode

    def whole(*args, **kwargs):
        raise AssertionError("the whole program was read")

    monkeypatch.setattr(gcode, "load_gcode", whole)


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_a_long_zigzag_is_refused_from_its_first_lines(tmp_path, capsys, lowered, no_whole_read):
    """run and bound refuse a 1,000-line zigzag from its first 22 + 64 lines, in one line
    naming the file, "at least" the corners counted and the lines they were counted in."""
    spec = _zigzag(tmp_path / "zigzag.ngc", 1000)
    for command in ("bound", "run"):
        out = ["--out", str(tmp_path / "o")] if command == "run" else []
        assert main([command, spec, "--feed", "100mm/s", *out]) == 2
        line = _one_error_line(capsys)
        lines = 18 + 4 + FIRST_PART_MARGIN
        # G1 lines 4 .. lines: that many - 3 pieces; its first and last vertex not counted
        assert (f"{spec}: the path has at least {lines - 5} sharp corners (in its first "
                f"{lines} lines)") in line, line
        assert f"more than the limit of {LIMIT:,}" in line
    assert not (tmp_path / "o").exists()


def test_the_first_part_count_is_at_most_the_planned_count(tmp_path, monkeypatch):
    """The whole zigzag's planned corners (999, the planner's own count) against the first
    part's at the real limits' size of the part and at the lowered one; a contour chosen
    with FILE#k counts that contour."""
    machine = load_machine("die-bonder")
    spec = _zigzag(tmp_path / "zigzag.ngc", 1000)
    truth = _planned_corners(spec, machine)
    assert truth == 999
    tol = DEFAULT_PATH_TOLERANCE / machine.pulses_per_unit("mm")
    for pieces in (23, 100, 400):
        part = read_first_part(spec, "xy", pieces)
        assert part is not None and part.pieces >= pieces and not part.ended
        corners, where = part.corners(tol, machine.pulses_per_unit("mm"))
        assert corners == part.pieces - 2 <= truth and where == f"its first {part.lines:,} lines"
    assert read_first_part(spec, "xy", 600) is None  # more than half the program: read whole
    two = tmp_path / "two.ngc"  # a first short contour, then the zigzag
    two.write_text("G21 G90\nG0 X0 Y5\nF600\nG1 X1 Y5\nG1 X1 Y6\n" + (tmp_path / "zigzag.ngc").read_text())
    assert read_first_part(two, "xy", 23) is None  # two contours: the run asks which
    part = read_first_part(two, "xy", 23, contour=2)
    assert part.corners(tol, 1000.0) == (part.pieces - 2, f"its first {part.lines:,} lines, contour #2")
    assert part.corners(tol, 1000.0)[0] <= _planned_corners(f"{two}#2", machine)
    assert read_first_part(two, "xy", 23, contour=1).corners(tol, 1000.0)[0] == 0


def test_what_is_not_provably_a_first_part_is_read_whole(tmp_path, capsys, lowered):
    """O-words (a subroutine, a loop), rotary path axes, an error in the first lines and a
    program that is not twice the first part are read whole: the refusal, or the error,
    comes from the whole program, as before."""
    body = "".join(f"G1 X{i * 0.01:.4f} Y{(i % 2) * 0.01:.4f}\n" for i in range(1, 1001))
    sub = tmp_path / "sub.ngc"
    sub.write_text("o100 sub\nG1 X0 Y1\no100 endsub\nG21 G90\nG0 X0 Y0\nF600\n" + body + "M2\n")
    loop = tmp_path / "loop.ngc"
    loop.write_text("G21 G90\nG0 X0 Y0\nF600\n#1 = 0\no1 while [#1 LT 2]\n#1 = [#1 + 1]\no1 endwhile\n"
                    + body + "M2\n")
    bad = tmp_path / "bad.ngc"
    bad.write_text("G21 G90\nG0 X0 Y0\nF600\nG1 X1 Y1 Q\n" + body + "M2\n")
    short = _zigzag(tmp_path / "short.ngc", 150)
    for file in (sub, loop, bad, short):
        assert read_first_part(file, "xy", 23) is None, file
    assert read_first_part(_zigzag(tmp_path / "z.ngc", 1000), "xa", 23) is None
    assert main(["bound", str(sub), "--feed", "100mm/s"]) == 2
    line = _one_error_line(capsys)
    assert "MAX_GRID_POINTS" in line and "at least" not in line, line  # the planner's own
    assert line.startswith(f"nurbsmotion bound: error: {sub}#1: "), line  # its file, contour
    assert main(["run", str(sub), "--feed", "100mm/s", "--out", str(tmp_path / "o")]) == 2
    assert _one_error_line(capsys).startswith(f"nurbsmotion run: error: {sub}#1: ")


def test_cutter_compensation_keeps_the_count_a_lower_bound(tmp_path, monkeypatch, capsys):
    """Under G41.1 the held move is not yet a piece, and the arc the tool rolls round a
    convex corner is no line (a zigzag's corners alternate: none is counted). A square
    spiral turning left (every corner concave, cut back) is counted between its lines:
    no more than the planner's count of the whole compensated program, and refused from
    its first lines."""
    machine = load_machine("die-bonder")
    per_unit = machine.pulses_per_unit("mm")
    zig = _zigzag(tmp_path / "zig.ngc", 1000, header="G21 G90 G17\nG0 X0 Y-1\nF600\nG41.1 D0.002\n"
                  "G1 X0 Y0\n")
    part = read_first_part(zig, "xy", 23)
    assert (np.frombuffer(part.contours[0].kind, dtype=np.int8) == 1).any()  # rolled round
    assert part.corners(DEFAULT_PATH_TOLERANCE / per_unit, per_unit)[0] == 0
    lines, x, y = ["G21 G90 G17\nG0 X0 Y-1\nF600\nG41.1 D0.002\nG1 X0 Y0\n"], 0.0, 0.0
    for i in range(1000):
        step = (i // 2 + 1) * 0.01
        x, y = x + step * (1, 0, -1, 0)[i % 4], y + step * (0, 1, 0, -1)[i % 4]
        lines.append(f"G1 X{x:.4f} Y{y:.4f}\n")
    spiral = tmp_path / "spiral.ngc"
    spiral.write_text("".join(lines) + "G40\nG1 X0 Y-1\nM2\n")
    part = read_first_part(spiral, "xy", 23)
    corners, _ = part.corners(DEFAULT_PATH_TOLERANCE / per_unit, per_unit)
    assert 18 < corners <= _planned_corners(str(spiral), machine)
    monkeypatch.setattr(planning, "MAX_GRID_POINTS", LIMIT)
    import nurbsmotion.paths.gcode as gcode
    monkeypatch.setattr(gcode, "load_gcode", None)  # not called: refused from the first lines
    assert main(["bound", str(spiral), "--feed", "100mm/s"]) == 2
    assert "the path has at least" in _one_error_line(capsys)


def test_an_ended_program_and_a_closing_percent_end_the_first_part(tmp_path):
    body = "".join(f"G1 X{i * 0.01:.4f} Y{(i % 2) * 0.01:.4f}\n" for i in range(1, 101))
    ended = tmp_path / "ended.ngc"
    ended.write_text("G21 G90\nG0 X0 Y0\nF600\n" + body + "M30\n" + "(after the end)\n" * 2000)
    part = read_first_part(ended, "xy", 200)
    assert part.ended and part.pieces == 100
    percent = tmp_path / "percent.ngc"
    percent.write_text("%\nG21 G90\nG0 X0 Y0\nF600\n" + body + "%\n" + "G1 X5 Y5\n" * 2000)
    part = read_first_part(percent, "xy", 200)
    assert part.ended and part.pieces == 100


# ---------------------------------------------------------------------- random programs
_MOVE = st.tuples(st.sampled_from(["G1"] * 8 + ["G2", "G3", "G0", "comment", "blank"]),
                  st.integers(-40, 40), st.integers(-40, 40), st.sampled_from([0.0, 0.3, 1.2, 2.0]))


def _program(moves, comp: str | None, sub: bool) -> str:
    """A program of ``moves`` (kind, dx, dy in 0.01 mm, arc sweep [rad]) from (0, 0),
    under cutter compensation ``comp`` (``"G41.1"``, ``"G42.1"``) where given."""
    out = ["G21 G90 G17\n"]
    if sub:
        out.append("o<leg> sub\nG1 X[#1] Y[#2]\no<leg> endsub\n")
    out.append("G0 X0 Y0\nF600\n")
    if comp:
        out.append(f"{comp} D0.004\nG1 X0.5 Y0\n")
    x, y = (0.5, 0.0) if comp else (0.0, 0.0)
    for i, (kind, dx, dy, sweep) in enumerate(moves):
        if kind == "comment":
            out.append(f"(move {i}) ; note\n")
            continue
        if kind == "blank":
            out.append("\n")
            continue
        if dx == 0 and dy == 0:
            continue
        if kind in ("G2", "G3") and sweep > 0:
            # the centre beside the chord's start, the end on its circle after `sweep`
            cx, cy = x - dy * 0.01, y + dx * 0.01
            turn = sweep if kind == "G3" else -sweep
            a = math.atan2(y - cy, x - cx) + turn
            r = math.hypot(x - cx, y - cy)
            ex, ey = round(cx + r * math.cos(a), 9), round(cy + r * math.sin(a), 9)
            out.append(f"{kind} X{ex:.9f} Y{ey:.9f} I{cx - x:.9f} J{cy - y:.9f}\n")
            x, y = ex, ey
            continue
        x, y = round(x + dx * 0.01, 4), round(y + dy * 0.01, 4)
        word = "G0" if kind == "G0" and not comp else "G1"
        if sub and i % 7 == 0:
            out.append(f"o<leg> call [{x:.4f}] [{y:.4f}]\n")
        else:
            out.append(f"{word} X{x:.4f} Y{y:.4f}\n")
    if comp:
        out.append("G40\nG1 X-1 Y-1\n")
    out.append("M2\n")
    return "".join(out)


@settings(max_examples=int(os.environ.get("NURBSMOTION_SWEEP", "60")), deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(moves=st.lists(_MOVE, min_size=60, max_size=240), comp=st.sampled_from([None, "G41.1", "G42.1"]),
       sub=st.sampled_from([False, False, False, True]), pieces=st.integers(3, 40),
       contour=st.sampled_from([None, 1, 2]))
def test_the_first_part_never_counts_more_than_the_whole_program(tmp_path_factory, moves, comp, sub,
                                                                 pieces, contour):
    machine = load_machine("die-bonder")
    path = tmp_path_factory.mktemp("random") / "random.ngc"
    path.write_text(_program(moves, comp, sub))
    part = read_first_part(path, "xy", pieces, contour=contour)
    if part is None:
        return
    assert not sub  # O-words: the whole program is read
    spec = str(path) if contour is None else f"{path}#{contour}"
    try:
        truth = _planned_corners(spec, machine)
    except NurbsmotionError:  # the whole program is refused (a gouge, no such contour): nothing
        assume(False)         # to compare with
    per_unit = machine.pulses_per_unit("mm")
    corners, _ = part.corners(DEFAULT_PATH_TOLERANCE / per_unit, per_unit)
    assert corners <= truth


def test_a_refusal_from_the_first_part_is_one_the_whole_program_makes(tmp_path, lowered):
    """Where the first part refuses, so does the planner on the whole program (with the
    exact count, at least as many)."""
    machine = load_machine("die-bonder")
    spec = _zigzag(tmp_path / "zigzag.ngc", 1000, every="(chord)\n")
    with pytest.raises(WorkLimitError, match="at least") as first:
        load_run_contour(spec, machine, size_check=planning.check_span_count)
    counted = int(str(first.value).split("at least ")[1].split(" ")[0].replace(",", ""))
    truth = _planned_corners(spec, machine)
    assert truth == 999
    with pytest.raises(WorkLimitError, match="999 sharp corners"):
        planning.check_corner_count(truth)
    assert 18 < counted <= truth


def test_sparse_moves_are_read_from_more_lines(tmp_path, lowered, no_whole_read, capsys):
    """A program with three comments after every move needs about four times the lines
    for the same pieces: its first lines are read again, at least twice as many."""
    spec = _zigzag(tmp_path / "sparse.ngc", 2000, every="(a)\n(b)\n(c)\n")
    part = read_first_part(spec, "xy", 22)
    assert part.pieces >= 22 and part.lines == 2 * (22 + FIRST_PART_MARGIN)
    assert main(["bound", spec, "--feed", "100mm/s"]) == 2
    assert "the path has at least" in _one_error_line(capsys)
