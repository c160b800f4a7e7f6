"""Plain G-code lines read in bulk (ngc.WordTable, gcode.reader._Reader.read_rows) give what the
line-by-line reader gives: the same blocks, curves, feeds, source lines, warnings and
errors, bit for bit.

Oracles: lower-cased lines, which never take the bulk path (the full parser reads them),
and the motion layer fed one block at a time (``Program.blocks(runs=False)``).
"""

from __future__ import annotations

import random
import warnings
from pathlib import Path

import pytest

from conftest import RANDOM_SWEEPS
from nurbsmotion.errors import PathFileError
from nurbsmotion.paths.gcode import ngc
from nurbsmotion.paths.gcode import load_gcode

CORPUS = Path(__file__).resolve().parent / "data" / "corpus"
GCODE_FILES = sorted(p for p in CORPUS.iterdir() if p.suffix in (".ngc", ".nc", ".gcode", ".tap")) + [
    Path(__file__).resolve().parents[1] / "examples" / "butterfly.ngc"]


def run(lines: list[str]):
    """The blocks a program executes, or the error that stops it."""
    try:
        return [tuple(b) for b in ngc.Program(lines, "p.ngc").blocks()]
    except PathFileError as exc:
        return str(exc)


def random_word_line(rng: random.Random) -> str:
    """A line of letter-number words as CAM posts and people write them, now and then
    with a number float() refuses, an overlong literal or a repeated letter."""
    number = rng.choice([
        lambda: f"{rng.uniform(-500, 500):.{rng.randint(0, 6)}f}",
        lambda: str(rng.randint(-20, 99)), lambda: f"+.{rng.randint(0, 99)}", lambda: "-0",
        lambda: f"{rng.randint(0, 9)}.", lambda: f"00{rng.randint(0, 9)}.50",
        lambda: "1.2.3", lambda: ".", lambda: "1" * rng.choice([39, 40, 41]),
    ])
    words = [rng.choice("GGGMXYZABCFIJKRPSTHDLQE") + number() for _ in range(rng.randint(0, 10))]
    text = rng.choice(["", " ", "\t"]).join(words)
    if rng.random() < 0.2:
        text = f"N{rng.randint(0, 9999)} " + text
    if rng.random() < 0.1:
        text = "/" + text
    if rng.random() < 0.3:
        text += rng.choice([" (cut X1 Y2)", "(a)", " ; X5 rest", "(x) ;y", " (T1 D=6)"])
    return text


def test_word_table_reads_plain_lines_as_the_full_parser(monkeypatch):
    monkeypatch.setattr(ngc, "_TABLE_CHUNK", 7)  # chunk edges inside the program
    rng = random.Random(11)
    for _ in range(400 * RANDOM_SWEEPS):
        lines = [random_word_line(rng) for _ in range(rng.randint(1, 30))]
        upper = [t.upper() for t in lines]
        assert run(upper) == run([t.lower() for t in lines]), upper


def test_runs_are_the_plain_lines_in_order():
    lines = ["G21 G90 F100", "G1 X1 Y1", "(comment)", "", "X2", "#1 = 3", "X#1", "G1 X4 Y4 (c)", "M2"]
    program = ngc.Program(lines, "p.ngc")
    items = list(program.blocks(runs=True))
    assert [type(i).__name__ for i in items] == ["Rows", "Block", "Rows"]
    expanded = [tuple(b) for i in items for b in (i.each() if isinstance(i, ngc.Rows) else [i])]
    assert expanded == run(lines)
    assert [b[0] for b in expanded] == [1, 2, 5, 7, 8, 9]


def test_endless_loop_is_stopped_at_the_same_line_inside_a_run(monkeypatch):
    monkeypatch.setattr(ngc, "MAX_EXTRA_BLOCKS", 25)
    lines = ["G21 F100", "o1 while [1]"] + [f"G1 X{i} Y1" for i in range(9)] + ["o1 endwhile"]
    upper = run(lines)
    assert isinstance(upper, str) and "endless loop" in upper
    assert upper == run([t.lower() for t in lines])


# ---------------------------------------------------------------- motion layer
def load(path: Path, axes: str, bulk: bool, monkeypatch):
    """Contours (as comparable tuples), units and warnings, or the error message."""
    with monkeypatch.context() as m:
        if not bulk:
            blocks = ngc.Program.blocks
            m.setattr(ngc.Program, "blocks", lambda self, runs=False: blocks(self, False))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                p = load_gcode(path, axes=axes)
        except PathFileError as exc:
            return str(exc)
    return [(c.curve.degree, c.curve.knots.tobytes(), c.curve.control_points.tobytes(),
             c.curve.weights.tobytes(), c.piece_edges.tobytes(), c.programmed_feed.tobytes(), c.lines)
            for c in p.contours], p.units, p.warnings


EDGE_PROGRAMS = {
    "modes": "G21 G90\nF100\nG1 X1 Y1\nG91\nG1 X1\nX1 Y2\nG90\nG0 X5\nG1 Z1\nX7\nZ2\nX8\nG93\n"
             "G1 X9 F10\nG94 F50\nG1 X10 Y3 (c)\nG20\nG1 X1\nG21\nN10 G1 X2 Y2 M3\nS100 X3\n"
             "G2 X4 Y3 I0.5 J0.5\nG1 X5 Y5\nG1 X6\n/G1 X7 Y7\nG0 Z5\nG1 X8\nA3\nX9 A3\n",
    "frames": "G21 G90 F100\nG10 L2 P1 X1\nG1 X1 Y1\nG1 X2\nG54\nG1 X3\nG92 X0\nG1 X4\nG92.1\nX5\n",
    "g6 then lines": "G21 G90 F100\nG6.2 P3 K0 X0 Y0\nK0 X1 Y1\nK0 X2 Y0\nK1\nK1\nK1\nG1 X3 Y3\nX4\n",
    "g5.2 then lines": "G21 G90 F100\nG1 X1 Y0\nG5.2 P1 L3\nX2 Y1 P1\nX3 Y0 P1\nG5.3\nG1 X4\nX5 Y1\n",
    "arcs between lines": "G21 G90 F100\nG2 X1 Y0 I0.5 J0\nG1 X2\nG3 X3 Y0 I0.5 J0\nF200\nG1 X3 Y1\nX4\n",
    "two motion words": "G21 G90 F100\nG0 X1\nG90 G1 X2 Y2\nX3\nG0 G90 X4\nX5\nG1 X6\n",
    "inch": "G20 G90 F10\nG1 X1 Y1\nX2 Y1.5\nG21\nX30 Y40\nG20\nX2 Y2\n",
    "no units": "G90\nF100\nG1 X1 Y1\nG1 X2\n",
    "end": "G21 G90 F100\nG1 X1 Y1\nG1 X2 Y1 M2\nG1 X5 Y6\n",
    "feed zero": "G21 G90 F100\nG1 X1 Y1\nF0\nG1 X2\n",
    "no feed": "G21 G90\nG1 X1 Y1\n",
    "z with path": "G21 G90 F100\nG1 X1 Y1\nG1 X2 Y2 Z1\n",
    "beyond range": "G21 G90 F100\nG1 X1 Y1\nG1 X12345678901 Y1\n",
    "modal arc without centre": "G21 G90 F100\nG2 X1 Y0 I0.5 J0\nX2\n",
    "no motion mode": "G21 G90 F100\nX1 Y1\n",
    "subroutine": "G21 G90 F100\no100 sub\nG1 X[#1] Y1\nG1 X2 Y#2\nG1 X3 Y3\no100 endsub\nG1 X1 Y1\n"
                  "o100 call [5] [6]\no100 call [7] [8]\n#1=3\no200 repeat [3]\nG1 X#1 Y0\nG1 X0 Y0\n"
                  "G1 X1 Y1\n#1=[#1+1]\no200 endrepeat\nG0 X0 Y0\nG1 X1\nG1 Y1\nG1 X#<_x> Y[#<_y>+1]\nM2\n",
}


@pytest.mark.parametrize("name", sorted(EDGE_PROGRAMS))
@pytest.mark.parametrize("axes", ["xy", "xyz"])
def test_bulk_reading_equals_line_by_line_on_edge_programs(tmp_path, monkeypatch, name, axes):
    path = tmp_path / "p.ngc"
    path.write_text(EDGE_PROGRAMS[name])
    assert load(path, axes, True, monkeypatch) == load(path, axes, False, monkeypatch)


@pytest.mark.parametrize("path", GCODE_FILES, ids=lambda p: p.name)
def test_bulk_reading_equals_line_by_line_on_the_corpus(monkeypatch, path):
    for axes in ("xy", "xyz"):
        assert load(path, axes, True, monkeypatch) == load(path, axes, False, monkeypatch)


def random_program(rng: random.Random) -> str:
    """Moves, feeds, modes and offsets in a random order (each a line LinuxCNC reads)."""
    x = y = 0.0
    out = ["G21 G90 G17 F600"]
    for _ in range(rng.randint(5, 80)):
        kind = rng.random()
        if kind < 0.45:
            x, y = round(x + rng.uniform(-1, 1), 3), round(y + rng.uniform(-1, 1), 3)
            out.append(rng.choice(["G1 ", "", "G01 "]) + f"X{x} Y{y}" + rng.choice(["", " F900", " (c)"]))
        elif kind < 0.55:
            x = round(x + 1, 3)
            out.append(f"G{rng.choice([2, 3])} X{x} Y{y} I0.5 J0")
        else:
            out.append(rng.choice([
                f"G0 X{x} Y{y + 1}", "G0 Z1", "G1 Z-1", "G1 Z-1 X0", f"F{rng.randint(0, 3) * 500}",
                "G91", "G90", "G20", "G21", "M3 S1000", "M5", "G54", "G92 X0", "G92.1", "G1",
                "G0", f"X{x} Y{y}", "A5", "G64 P0.01", "(pass)", "", "G4 P1", "T1 M6",
            ]))
    return "\n".join(out) + "\n"


def test_bulk_reading_equals_line_by_line_on_random_programs(tmp_path, monkeypatch):
    rng = random.Random(5)
    path = tmp_path / "p.ngc"
    outcomes = set()
    for _ in range(60 * RANDOM_SWEEPS):
        path.write_text(random_program(rng))
        for axes in ("xy", "xyz"):
            bulk = load(path, axes, True, monkeypatch)
            assert bulk == load(path, axes, False, monkeypatch), path.read_text()
            outcomes.add(isinstance(bulk, str))
    assert outcomes == {True, False}  # the sweep reaches both paths and refusals


def test_long_numbers_before_a_bad_one_are_refused_at_once():
    # regression: the full parser's plain-line pattern matched "123" in several ways, so a
    # few long numbers before a bad word made it backtrack for hours
    line = " ".join(f"X{'1' * 39}" for _ in range(8)) + " Y1.2.3"
    for text in (line, line.lower()):
        result = run(["G21", text])
        assert isinstance(result, str) and "line 2: cannot read" in result
