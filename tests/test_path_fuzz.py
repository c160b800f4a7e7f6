"""Mutated G-code and DXF inputs: a typed one-line error or a valid path, in bounded time.

Hypothesis mutates real programs and drawings (bytes deleted, duplicated, replaced; numbers
blown up; lines shuffled). The contract (issue 14): ``load_gcode`` / ``load_dxf`` return
contours of finite control points, or raise :class:`PathFileError` whose message is one
line naming the file; never another exception, never a hang (each case within a minute,
generous on a loaded 2-core machine, checked by hypothesis' deadline; the compiled
kernels are loaded before the first case). Seeds are derandomized, so the generated
corpus is the same on every run.
"""

from __future__ import annotations

import warnings
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nurbsmotion.errors import PathFileError
from nurbsmotion.paths.dxf import load_dxf
from nurbsmotion.paths.gcode import load_gcode

ROOT = Path(__file__).resolve().parent
SEEDS_NGC = [ROOT.parent / "examples" / "butterfly.ngc"] + sorted(
    p for p in (ROOT / "data" / "corpus").glob("*.ngc") if p.stat().st_size < 3000)
SEEDS_DXF = [ROOT / "data" / "corpus" / "bjnortier_lwpolylines.dxf",
             ROOT / "data" / "corpus" / "bjnortier_splines.dxf",
             ROOT / "data" / "corpus" / "bjnortier_ellipticalarcs.dxf"]
FUZZ = settings(max_examples=60, deadline=timedelta(seconds=60), derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

NASTY = [b"1" * 300, b"-", b"#", b"[", b"]", b"1e300", b"\r", b"\xef\xbb\xbf", b"o100 while [1]\n",
         b"G2 P1000000", b"I1000000000000", b"nan", b"inf", b"(", b"%\n", b"\x00", b"\xff",
         b"G5.2", b"G6.2 P3 Q1", b"#<x>=", b"o<s> call", b"999999999999999999999", b"0.0", b"\n"]


@pytest.fixture(scope="module", autouse=True)
def compiled_kernels():
    """Load (or compile) the kernels a path's checks use, outside the cases' deadline."""
    for seed in SEEDS_NGC[:1] + SEEDS_DXF[:1]:
        check(lambda p: load_gcode(p, axes="xyz") if p.suffix == ".ngc" else load_dxf(p),
              seed)


@st.composite
def mutated(draw, seeds):
    data = bytearray(draw(st.sampled_from(seeds)).read_bytes())
    for _ in range(draw(st.integers(1, 4))):
        if not data:
            break
        i = draw(st.integers(0, len(data) - 1))
        op = draw(st.integers(0, 3))
        if op == 0:  # delete a run
            del data[i: i + draw(st.integers(1, 40))]
        elif op == 1:  # insert something nasty
            data[i:i] = draw(st.sampled_from(NASTY))
        elif op == 2:  # replace a byte
            data[i] = draw(st.integers(0, 255))
        else:  # duplicate a run
            j = min(len(data), i + draw(st.integers(1, 200)))
            data[j:j] = data[i:j] * draw(st.integers(1, 3))
    return bytes(data)


def check(load, path: Path) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = load(path)
        except PathFileError as exc:
            text = str(exc)
            assert "\n" not in text and text.startswith(str(path)), text
            return
    curves = [c.curve for c in result.contours] if hasattr(result, "contours") else result
    assert curves
    for c in curves:
        assert np.all(np.isfinite(c.control_points)) and c.length > 0 and np.isfinite(c.length)
    assert all("\n" not in str(w.message) for w in caught)


@FUZZ
@given(mutated(SEEDS_NGC))
def test_mutated_gcode_is_a_path_or_one_typed_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("g") / "m.ngc"
    path.write_bytes(data)
    check(lambda p: load_gcode(p, axes="xyz"), path)


@FUZZ
@given(mutated(SEEDS_DXF))
def test_mutated_dxf_is_a_path_or_one_typed_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("d") / "m.dxf"
    path.write_bytes(data)
    check(load_dxf, path)


# ---------------------------------------------------------------- regressions (issue 14)
@pytest.mark.parametrize("text, pattern", [
    ("G21\nG1 F10 X" + "9" * 200 + "\n", r"line 2: number 9999999999999999\.\.\. has 200 characters"),
    ("G21\nG1 F10 X" + "9" * 300 + "\n", r"line 2: line is longer than 256 characters"),
    ("G21\nG0 X0 Y0\nF10\nG2 X1 I0.5 P1000000\n", r"line 4: arc turns P1e\+06 are more than the 100 read"),
    ("G21\nG0 X0 Y0\nF10\nG2 X0 Y0 I1000000000000 J0\n", r"line 4: I1e\+12 is beyond the largest coordinate"),
    ("G21\nG0 X0 Y0\nF10\nG2 X0 Y0 I0 J[10**12]\n", r"line 4: J1e\+12 is beyond the largest coordinate"),
])
def test_issue_14_gcode_cases_are_refused_with_the_limit(tmp_path, text, pattern):
    path = tmp_path / "p.ngc"
    path.write_text(text)
    with pytest.raises(PathFileError, match=pattern):
        load_gcode(path)


@pytest.mark.parametrize("ending", [b"\r\n", b"\r", b"\n"])
@pytest.mark.parametrize("bom", [b"", b"\xef\xbb\xbf"])
def test_line_endings_and_byte_order_mark(tmp_path, ending, bom):
    lines = [b"G21 G90", b"G0 X0 Y0", b"G1 X10 F100", b"G3 X0 Y0 I-5 J0", b"M2"]
    path = tmp_path / "p.ngc"
    path.write_bytes(bom + ending.join(lines) + ending)
    (c,) = load_gcode(path).contours
    assert c.lines == (3, 4)
    assert c.curve.length == pytest.approx(10 + np.pi * 5, rel=1e-12)
