"""The command line: file contracts, exit codes and one-line errors."""

import csv
import json

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.cli import main, parse_feed
from nurbsmotion.interpolators import TaylorInterpolator, interpolate
from nurbsmotion.report import SUMMARY_KEYS


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def test_interpolate_writes_the_setpoints_of_the_library(tmp_path):
    assert main(["interpolate", "die-bonder-pi", "--feed", "5e5", "--method", "taylor2",
                 "--out", str(tmp_path)]) == 0
    header, data = read_csv(tmp_path / "setpoints.csv")
    assert header == ["t", "u", "x", "y"]
    ref = interpolate(TaylorInterpolator(nm.make_die_bonder_pi(), 1e-3, 5e5, 2))
    np.testing.assert_array_equal(data[:, 1], ref.u)
    np.testing.assert_array_equal(data[:, 2:], ref.position)
    assert (tmp_path / "setpoints.png").stat().st_size > 0


def test_interpolate_converts_a_feed_with_units(tmp_path):
    assert main(["interpolate", "butterfly", "--feed", "6000mm/min", "--out",
                 str(tmp_path)]) == 0
    _, data = read_csv(tmp_path / "setpoints.csv")
    step = np.linalg.norm(np.diff(data[:, 2:], axis=0), axis=1)
    assert np.median(step) == pytest.approx(0.1, rel=1e-3)  # 100 mm/s * 1 ms


def test_run_writes_trace_and_summary_contracts(tmp_path):
    """The Pi at 1 m/s with the paper's algorithm: saturation is reported, not hidden."""
    assert main(["run", "die-bonder-pi", "--machine", "die-bonder", "--feed", "1m/s",
                 "--interpolator", "paper", "--out", str(tmp_path)]) == 0
    header, data = read_csv(tmp_path / "trace.csv")
    per_axis = ["cmd", "act", "drive", "drive_applied", "speed_min", "speed_max"]
    assert header == ["t", "u"] + [f"{a}_{c}" for a in "xy" for c in per_axis]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert tuple(summary) == SUMMARY_KEYS
    assert summary["saturated_samples"]["x"] > 0
    assert summary["feed"] == 1e6 and summary["interpolator"] == "paper"
    assert summary["steps"] == round(summary["cycle_time_s"] / 1e-3)
    assert len(data) > summary["steps"]
    # row k: drive_applied is the clipped drive
    np.testing.assert_array_equal(data[:, 5], np.clip(data[:, 4], -10, 10))
    for name in ("contour", "following_error", "drive", "speed"):
        assert (tmp_path / f"{name}.png").stat().st_size > 0


def test_run_without_bounds_has_no_bound_columns(tmp_path):
    assert main(["run", "die-bonder-pi", "--feed", "2e5", "--interpolator", "taylor1",
                 "--out", str(tmp_path), "--no-figures"]) == 0
    header, _ = read_csv(tmp_path / "trace.csv")
    assert header[2:6] == ["x_cmd", "x_act", "x_drive", "x_drive_applied"]
    assert not any("speed" in h for h in header)


def test_run_with_a_machine_file(tmp_path):
    assert main(["run", "examples/die_bonder_pi.json", "--machine",
                 "examples/die_bonder.toml", "--feed", "2e5", "--out", str(tmp_path),
                 "--no-figures"]) == 0


def test_outputs_are_not_overwritten_unless_asked(tmp_path, capsys):
    args = ["run", "die-bonder-pi", "--feed", "2e5", "--out", str(tmp_path), "--no-figures"]
    assert main(args) == 0
    before = (tmp_path / "summary.json").read_text()
    assert main(args) == 2
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "summary.json").read_text() == before
    assert main(args + ["--overwrite"]) == 0


@pytest.mark.parametrize(
    "args, message",
    [
        (["interpolate", "missing.json", "--feed", "1", "--out", "{out}"], "no such file"),
        (["interpolate", "{bad_json}", "--feed", "1", "--out", "{out}"], "JSON"),
        (["interpolate", "{bad_curve}", "--feed", "1", "--out", "{out}"],
         "weight 1 is -1; weights must be > 0"),
        (["run", "die-bonder-pi", "--machine", "lathe", "--feed", "1", "--out", "{out}"],
         "not a built-in machine"),
        (["run", "{three_axes}", "--feed", "1", "--out", "{out}"],
         "the path has 3 axes but machine 'die-bonder' has 2"),
        (["interpolate", "die-bonder-pi", "--feed", "1m/s", "--out", "{out}"],
         "cannot convert a feed with a length unit"),
    ],
)
def test_errors_are_one_clear_line(tmp_path, capsys, args, message):
    bad_json = tmp_path / "bad.json"
    bad_json.write_text('{"degree": 1,\n "knots": [0, 0, 1, 1,\n}')
    bad_curve = tmp_path / "bad_curve.json"
    bad_curve.write_text(json.dumps({"degree": 1, "knots": [0, 0, 1, 1],
                                     "control_points": [[0, 0], [1, 1]], "weights": [1, -1],
                                     "units": "mm"}))
    three = tmp_path / "three.json"
    three.write_text(json.dumps({"degree": 1, "knots": [0, 0, 1, 1],
                                 "control_points": [[0, 0, 0], [1, 1, 1]], "units": "mm"}))
    out = tmp_path / "out"
    fmt = dict(out=out, bad_json=bad_json, bad_curve=bad_curve, three_axes=three)
    assert main([a.format(**fmt) for a in args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_negative_feed_is_refused_by_the_parser(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["interpolate", "butterfly", "--feed", "-3", "--out", "x"])
    assert exc.value.code == 2
    assert "feed must be finite and > 0, got '-3'" in capsys.readouterr().err


@pytest.mark.parametrize(
    "text, expected",
    [("1e6", (1e6, None)), ("0.5m/s", (5e5, "um")), ("100 mm/s", (1e5, "um")),
     ("600mm/min", (1e4, "um")), ("2e5pulse/s", (2e5, "pulse"))],
)
def test_parse_feed(text, expected):
    value, unit = parse_feed(text)
    assert (pytest.approx(value), unit) == (expected[0], expected[1])


def test_reproduce_writes_tables_and_figures(tmp_path):
    assert main(["reproduce", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "table.json").read_text())
    assert len(rows) == 18
    pi1 = {r["interpolator"]: r for r in rows
           if r["path"] == "die-bonder-pi" and r["feed_m_s"] == 1.0}
    assert pi1["taylor1"]["max_drive_ratio"]["x"] > 5
    assert 0 < pi1["paper"]["max_drive_ratio"]["x"] < pi1["taylor1"]["max_drive_ratio"]["x"]
    assert pi1["planned"]["saturated_samples"] == {"x": 0, "y": 0}
    assert pi1["planned"]["time_optimal_bound_s"] == pytest.approx(0.1153, abs=5e-4)
    assert pi1["planned"]["cycle_time_ratio"] == pytest.approx(
        pi1["planned"]["cycle_time_s"] / pi1["planned"]["time_optimal_bound_s"])
    assert "| die-bonder-pi | 1 | paper |" in (tmp_path / "table.md").read_text()
    assert len(list(tmp_path.glob("*.png"))) == 18


def test_run_exports_the_commanded_setpoints_in_path_units(tmp_path):
    """The butterfly is drawn in mm: exported setpoints are in mm, G-code too."""
    assert main(["run", "butterfly", "--feed", "0.1m/s", "--interpolator", "taylor2",
                 "--out", str(tmp_path), "--no-figures", "--export", "csv", "--export",
                 "npz", "--export", "pvt", "--export", "gcode"]) == 0
    header, trace = read_csv(tmp_path / "trace.csv")
    _, sp = read_csv(tmp_path / "setpoints.csv")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert len(sp) == summary["steps"] + 1
    np.testing.assert_allclose(sp[:, 2:] * 1000, trace[: len(sp), [2, 6]], rtol=1e-15)
    npz = np.load(tmp_path / "setpoints.npz")
    np.testing.assert_array_equal(npz["position"], sp[:, 2:])
    assert (tmp_path / "pvt.csv").read_text().startswith("t,x,x_velocity,y,y_velocity")
    gcode = (tmp_path / "motion.ngc").read_text()
    assert "G21" in gcode and "G1 X54.59" in gcode


def test_run_reads_a_gcode_contour(tmp_path):
    assert main(["run", "examples/butterfly.ngc#1", "--feed", "0.05m/s", "--out",
                 str(tmp_path), "--no-figures"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    # the file's F600 (10 mm/s = 1e4 pulse/s) is lower than --feed: it rules (issue 11)
    assert summary["path"] == "examples/butterfly.ngc#1" and summary["feed"] == 1e4
    assert summary["feed_used"] == ("the lower of the file's programmed feed (10000 pulse/s) and "
                                    "--feed 50000 pulse/s per piece: its lowest value (paper "
                                    "takes one feed)")


def test_bound_prints_the_time_optimal_bound(capsys):
    """SPEC section 9: about 0.115 s for the Pi at 1 m/s."""
    assert main(["bound", "die-bonder-pi", "--feed", "1m/s"]) == 0
    assert float(capsys.readouterr().out) == pytest.approx(0.1153, abs=5e-4)
    assert main(["bound", "examples/butterfly.toml", "--machine", "examples/die_bonder.toml",
                 "--feed", "50mm/s"]) == 0
    assert float(capsys.readouterr().out) == pytest.approx(382.86 / 50, rel=2e-3)


# ---------------------------------------------------------------- path files: units, feed
def test_contours_lists_index_pieces_length_box_units_and_feed(capsys):
    from pathlib import Path

    ngc = Path(__file__).resolve().parents[1] / "examples" / "butterfly.ngc"
    assert main(["contours", str(ngc)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("5 contours (choose one with " + str(ngc) + "#k)")
    rows = [line for line in out if line.startswith("| ") and line[2].isdigit()]
    assert [r.split(" | ")[0] for r in rows] == ["| 1", "| 2", "| 3", "| 4", "| 5"]
    assert all(r.endswith("| mm | F600 mm/min |") for r in rows)


def test_gcode_feed_is_optional_and_capped_and_units_override(capsys):
    from pathlib import Path

    ngc = str(Path(__file__).resolve().parents[1] / "examples" / "butterfly.ngc") + "#4"
    assert main(["bound", ngc]) == 0
    programmed = float(capsys.readouterr().out)
    assert main(["bound", ngc, "--feed", "5mm/s"]) == 0  # lower than F600 = 10 mm/s
    capped = float(capsys.readouterr().out)
    assert main(["bound", ngc, "--feed", "1m/s"]) == 0  # higher: the file's F rules
    assert float(capsys.readouterr().out) == programmed
    assert capped > 1.9 * programmed
    # read in inches: 25.4 x longer, capped at 10 mm/s (below F600 in/min): 25.4 / 2 x the
    # time at 5 mm/s (the feed, not the drive, limits this slow move)
    assert main(["bound", ngc, "--units", "in", "--feed", "10mm/s"]) == 0
    assert float(capsys.readouterr().out) == pytest.approx(capped * 25.4 / 2, rel=1e-3)
    assert main(["bound", "die-bonder-pi"]) == 2
    assert "--feed is required: die-bonder-pi gives no programmed feed" in capsys.readouterr().err


def test_warnings_are_one_line_without_source_echo(tmp_path, capsys):
    ngc = tmp_path / "p.ngc"
    ngc.write_text("G0 X0 Y0\nM3 S1000\nG1 X5 F100\nM2\n")
    assert main(["contours", str(ngc)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"nurbsmotion: warning: {ngc}, line 1: no G20/G21 before the first move; reading millimetres (G21)",
        f"nurbsmotion: warning: {ngc}, line 2: M3/M4/M5 spindle skipped: it does not change the path",
        f"nurbsmotion: warning: {ngc}, line 2: S spindle speed skipped: it does not change the path",
    ]
