"""JSON/TOML path files: exact round trips, shipped examples, one clear error per fault."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from nurbsmotion import NurbsCurve, builtin_path
from nurbsmotion.errors import OutputExistsError, PathFileError
from nurbsmotion.paths import load_path, resolve_path, save_path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
N_RANDOM = int(os.environ.get("NURBSMOTION_N_RANDOM", "20"))


def random_curve(rng: np.random.Generator, n_axes: int = 2) -> NurbsCurve:
    """A random valid clamped NURBS with awkward floats (non-terminating binary fractions)."""
    p = int(rng.integers(1, 5))
    n = int(rng.integers(p + 1, p + 9))
    interior = np.sort(rng.random(n - p - 1))
    knots = np.concatenate([[0.0] * (p + 1), interior, [1.0] * (p + 1)])
    points = rng.normal(scale=[1e4, 1e-3, 7.0][:n_axes], size=(n, n_axes)) + np.cumsum(
        np.ones((n, n_axes)), axis=0
    )
    if n_axes == 1:  # a one-axis path must not reverse (C' = 0 is rejected)
        points = np.cumsum(np.abs(points), axis=0)
    weights = rng.uniform(0.2, 5.0, n) / 3.0
    return NurbsCurve(p, knots, points, weights, name="random π", units="mm")


@pytest.mark.parametrize("stem,name", [("die_bonder_pi", "die-bonder-pi"), ("butterfly", "butterfly")])
@pytest.mark.parametrize("ext", ["json", "toml"])
def test_shipped_examples_equal_builtins(stem, name, ext):
    curve = load_path(EXAMPLES / f"{stem}.{ext}")
    ref = builtin_path(name)
    assert curve == ref
    assert (curve.name, curve.units) == (ref.name, ref.units)


@pytest.mark.parametrize("ext", ["json", "toml"])
def test_round_trip_is_bit_exact(tmp_path, ext):
    rng = np.random.default_rng(20240601)
    for i in range(N_RANDOM):
        curve = random_curve(rng, n_axes=1 + i % 3)
        file = save_path(curve, tmp_path / f"c{i}.{ext}")
        back = load_path(file)
        assert back == curve  # array_equal on knots, points, weights: bit for bit
        assert (back.name, back.units) == (curve.name, curve.units)


def test_json_format_matches_package_data(tmp_path):
    """The writer produces the layout of paths/data/die_bonder_pi.json (same fields)."""
    file = save_path(builtin_path("die-bonder-pi"), tmp_path / "pi.json")
    written = json.loads(file.read_text())
    assert set(written) == {"name", "units", "degree", "control_points", "weights", "knots"}
    assert written["knots"][4] == 1 / 3


@pytest.mark.parametrize("ext", ["json", "toml", "dxf"])
def test_refuses_to_overwrite(tmp_path, ext):
    target = tmp_path / f"p.{ext}"
    target.write_text("keep me")
    with pytest.raises(OutputExistsError, match="overwrite=True"):
        save_path(builtin_path("die-bonder-pi"), target)
    assert target.read_text() == "keep me"
    save_path(builtin_path("die-bonder-pi"), target, overwrite=True)
    assert load_path(target).n_control_points == 10
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"p.{ext}"]  # no temp files left


def test_save_gcode_ending_points_to_save_gcode(tmp_path):
    with pytest.raises(PathFileError, match="save_gcode"):
        save_path(builtin_path("die-bonder-pi"), tmp_path / "p.ngc")
    assert list(tmp_path.iterdir()) == []


GOOD_TOML = """name = "line"
degree = 1
knots = [0.0, 0.0, 1.0, 1.0]
control_points = [
    [0.0, 0.0],
    [1.0, 2.0],
]
weights = [1.0, 1.0]
"""


@pytest.mark.parametrize(
    "text,pattern",
    [
        # wrong types name the field and the line where it is defined
        (GOOD_TOML.replace("degree = 1", "degree = 1.5"), r"t\.toml, line 2: field 'degree' must be an integer"),
        (GOOD_TOML.replace("[1.0, 2.0]", '[1.0, "2"]'), r"line 4: field 'control_points\[1\]' entry 1 is '2'"),
        (GOOD_TOML.replace("weights = [1.0, 1.0]", "weights = 1.0"), r"line 8: field 'weights' must be a list"),
        (GOOD_TOML.replace("[1.0, 2.0]", "[1.0]"), r"line 4: field 'control_points' rows must all have the same"),
        (GOOD_TOML + "wieghts = [1.0]\n", r"line 9: field 'wieghts' is not a path-file field"),
        (GOOD_TOML.replace("knots = [0.0, 0.0, 1.0, 1.0]\n", ""), r"field 'knots' is missing"),
        # syntax errors carry the parser's line
        (GOOD_TOML.replace("[0.0, 0.0],", "[0.0, 0.0],,"), r"t\.toml, line 5: not valid TOML"),
        # an invalid curve is the InvalidCurveError message, wrapped with the file name
        (GOOD_TOML.replace("weights = [1.0, 1.0]", "weights = [1.0, -2.0]"), r"t\.toml: invalid curve: weight 1 is -2"),
        (GOOD_TOML.replace("weights = [1.0, 1.0]", "weights = [1.0, 0.0]"), r"invalid curve: weight 1 is 0"),
        (GOOD_TOML.replace("[0.0, 0.0, 1.0, 1.0]", "[0.0, 0.0, 1.0]"), r"invalid curve: knot vector has 3 entries, expected 4"),
    ],
)
def test_toml_errors_name_field_and_line(tmp_path, text, pattern):
    file = tmp_path / "t.toml"
    file.write_text(text)
    with pytest.raises(PathFileError, match=pattern):
        load_path(file)


@pytest.mark.parametrize(
    "text,pattern",
    [
        ('{"degree": 1,\n "knots": [0, 0, 1, 1],\n "control_points": [[0, 0], [1, 2]\n}', r"j\.json, line 4: not valid JSON"),
        ('{"degree": 1, "knots": [0, 0, 1, NaN], "control_points": [[0, 0], [1, 2]]}', r"NaN is not a number"),
        ('{"degree": 1,\n "knots": [0, 0, 1, true],\n "control_points": [[0, 0], [1, 2]]}', r"line 2: field 'knots' entry 3 is True"),
        ("[1, 2, 3]", r"must be a table/object of fields"),
        ('{"degree": 1, "knots": [0, 0, 1, 1], "control_points": [[0, 0], [0, 0]]}', r"j\.json: invalid curve: degenerate curve"),
    ],
)
def test_json_errors(tmp_path, text, pattern):
    file = tmp_path / "j.json"
    file.write_text(text)
    with pytest.raises(PathFileError, match=pattern):
        load_path(file)


def test_missing_file_and_unknown_ending(tmp_path):
    with pytest.raises(PathFileError, match=r"nope\.json: no such file"):
        load_path(tmp_path / "nope.json")
    (tmp_path / "p.txt").write_text("x")
    with pytest.raises(PathFileError, match=r"unknown path file ending '\.txt'"):
        load_path(tmp_path / "p.txt")


def write_garbage(path: Path, size: int = 100_000_000) -> Path:
    """``size`` bytes of seeded random garbage, written in 1 MB blocks."""
    block = np.random.default_rng(7).integers(0, 256, 1_000_000, dtype=np.uint8).tobytes()
    with open(path, "wb") as f:
        for _ in range(size // len(block)):
            f.write(block)
    return path


def assert_fails_fast(load, path: Path, pattern: str, seconds: float = 1.0) -> None:
    """``load(path)`` raises one PathFileError matching ``pattern`` within ``seconds`` of
    CPU time (not wall time: on a loaded machine the wall clock also counts the waits for a
    core; reading the whole file would take many CPU seconds)."""
    start = time.process_time()
    with pytest.raises(PathFileError, match=pattern):
        load(path)
    assert time.process_time() - start < seconds


@pytest.mark.parametrize("ext", ["json", "toml"])
def test_huge_garbage_file_fails_fast(tmp_path, ext):
    assert_fails_fast(load_path, write_garbage(tmp_path / f"garbage.{ext}"), r"100\.0 MB")


def test_resolve_path_builtin_names_and_files(tmp_path, monkeypatch):
    assert resolve_path("die-bonder-pi") == builtin_path("die-bonder-pi")
    assert resolve_path("butterfly") == builtin_path("butterfly")
    assert resolve_path(str(EXAMPLES / "butterfly.toml")) == builtin_path("butterfly")
    with pytest.raises(PathFileError, match="neither a built-in path"):
        resolve_path("die-bonder-p")
    with pytest.raises(PathFileError, match="no such file"):
        resolve_path(str(tmp_path / "absent.toml"))


# ---------------------------------------------------------------- command-line wording (issue 36)
def test_a_misspelt_choice_gets_a_did_you_mean(capsys):
    from nurbsmotion.cli import main

    with pytest.raises(SystemExit):
        main(["run", "butterfly", "--interpolator", "planed", "--out", "x"])
    err = capsys.readouterr().err
    assert "; did you mean 'planned'? (see nurbsmotion run --help)" in err
    with pytest.raises(SystemExit):
        main(["rnu", "butterfly"])
    assert "did you mean 'run'?" in capsys.readouterr().err


def test_settle_window_help_states_its_default_once(capsys):
    from nurbsmotion.cli import main

    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    start = text.index("--settle-window SETTLE_WINDOW the motion")
    entry = text[start: text.index("--out OUT", start)]
    assert entry.count("default") == 1


def test_a_bare_feed_far_too_slow_asks_for_its_unit(tmp_path, capsys):
    from nurbsmotion.cli import main

    assert main(["run", "die-bonder-pi", "--feed", "5", "--out", str(tmp_path / "o")]) != 0
    err = capsys.readouterr().err
    assert "--feed 5 is a bare number, read in the path's unit per second (5 pulse/s)" in err
    assert "5 m/s? give the unit (e.g. --feed 5m/s, 5mm/s or 5mm/min)" in err
