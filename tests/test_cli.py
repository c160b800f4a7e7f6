"""The command line: file contracts, exit codes and one-line errors."""

import csv
import json
import os
from pathlib import Path

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.cli import main, parse_feed
from nurbsmotion.interpolators import TaylorInterpolator
from nurbsmotion.loop import interpolate
from nurbsmotion.report import SUMMARY_KEYS, SUMMARY_LENGTH_KEYS


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
    # written to the resolution that matters: u to 1e-12, positions to 1e-3 pulse, t to 1 ns
    np.testing.assert_allclose(data[:, 0], ref.t, rtol=0, atol=0.5e-9)
    np.testing.assert_allclose(data[:, 1], ref.u, rtol=0, atol=0.5e-12)
    np.testing.assert_allclose(data[:, 2:], ref.position, rtol=0, atol=0.5e-3)
    first = (tmp_path / "setpoints.csv").read_text().splitlines()[2]
    assert len(first.split(",")[2]) <= len("-12345.678")  # not 17 digits
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
    pulse_columns = ["t", "u"] + [f"{a}_{c}" for a in "xy" for c in per_axis]
    mm = ["cmd_mm", "act_mm", "speed_min_mm_per_s", "speed_max_mm_per_s"]
    assert header == pulse_columns + [f"{a}_{c}" for a in "xy" for c in mm]
    for pulses, mm in (("x_cmd", "x_cmd_mm"), ("y_act", "y_act_mm"),
                       ("y_speed_max", "y_speed_max_mm_per_s")):  # 1 pulse = 1 um
        np.testing.assert_allclose(data[:, header.index(pulses)] / 1000,
                                   data[:, header.index(mm)], rtol=1e-15)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert tuple(summary)[:len(SUMMARY_KEYS)] == SUMMARY_KEYS  # contract: first, in order
    assert summary["length_unit"] == "mm" and summary["feed_mm_per_s"] == 1000.0
    for key in SUMMARY_LENGTH_KEYS:
        assert summary[f"{key}_mm"] == pytest.approx(
            {a: v / 1000 for a, v in summary[key].items()} if isinstance(summary[key], dict)
            else summary[key] / 1000, rel=1e-15)
    assert set(summary["units"]) == set(summary) - {"units"}
    assert summary["units"]["max_contour_error"] == "pulse"
    assert summary["units"]["max_contour_error_mm"] == "mm"
    assert summary["saturated_samples"]["x"] > 0
    assert summary["feed"] == 1e6 and summary["interpolator"] == "paper"
    assert summary["steps"] == round(summary["cycle_time_s"] / 1e-3)
    assert len(data) > summary["steps"]
    # row k: drive_applied is the clipped drive
    np.testing.assert_array_equal(data[:, 5], np.clip(data[:, 4], -10, 10))
    for name in ("contour", "following_error", "drive", "speed"):
        assert (tmp_path / f"{name}.png").stat().st_size > 0


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_run_streams_without_figures_to_the_same_files(tmp_path, monkeypatch, fmt):
    """Without figures or exports `run` streams its rows (blocks of 97 here) to the
    metrics and the trace file; summary and trace equal those of a run that holds the
    whole trace (an export makes it do so)."""
    from nurbsmotion.loop import closed_loop

    monkeypatch.setattr(closed_loop, "SINK_BLOCK_SAMPLES", 97)
    args = ["run", "die-bonder-pi", "--feed", "1m/s", "--interpolator", "paper",
            "--no-figures", "--trace-every", "3", "--trace-format", fmt]
    assert main(args + ["--out", str(tmp_path / "streamed")]) == 0
    assert main(args + ["--out", str(tmp_path / "whole"), "--export", "npz"]) == 0
    summaries = [json.loads((tmp_path / d / "summary.json").read_text())
                 for d in ("streamed", "whole")]
    assert summaries[0].keys() == summaries[1].keys()
    for key, value in summaries[0].items():
        other = summaries[1][key]
        if isinstance(value, float):  # RMS figures are sums over blocks
            assert other == pytest.approx(value, rel=1e-12), key
        elif isinstance(value, dict) and key != "units":
            assert other == pytest.approx(value, rel=1e-12), key
        else:
            assert other == value, key
    if fmt == "csv":
        assert ((tmp_path / "streamed" / "trace.csv").read_bytes()
                == (tmp_path / "whole" / "trace.csv").read_bytes())
    else:
        import pyarrow.parquet as pq

        a, b = (pq.read_table(tmp_path / d / "trace.parquet") for d in ("streamed", "whole"))
        assert a.column_names == b.column_names and a.num_rows == b.num_rows
        np.testing.assert_array_equal(np.column_stack([c.to_numpy() for c in a.columns]),
                                      np.column_stack([c.to_numpy() for c in b.columns]))


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
        (["run", "die-bonder-pi", "--feed", "1m/s", "--settle-window", "0", "--out", "{out}"],
         "--settle-window must be > 0, got '0'"),
        (["run", "die-bonder-pi", "--feed", "1m/s", "--settle-window", "2parsec", "--out",
          "{out}"], "--settle-window unit 'parsec' unknown"),
        (["run", "die-bonder-pi", "--feed", "1m/s", "--path-tolerance", "-1", "--out",
          "{out}"], "--path-tolerance '-1' is not a length >= 0"),
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
    assert main(["reproduce", "--out", str(tmp_path), "--no-figures"]) == 0
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
    assert pi1["planned"]["max_contour_error_mm"] == pytest.approx(
        pi1["planned"]["max_contour_error"] / 1000, rel=1e-15)
    table = (tmp_path / "table.md").read_text()
    assert "| die-bonder-pi | 1 | paper |" in table
    assert "| max drive x / Umax | max drive y / Umax |" in table
    assert "max contour [mm]" in table
    assert not list(tmp_path.glob("*.png"))


def test_reproduce_figures(tmp_path):
    """Per path and feed: the contour, and the speed and drive of every axis."""
    from nurbsmotion.study.reproduce import run_experiment

    seen = []
    result = run_experiment(tmp_path, experiment={"die-bonder-pi": (0.5,)},
                       interpolators=("taylor1", "planned"),
                       progress=lambda done, total, label: seen.append((done, total)))
    names = ["contour", "speed_x", "drive_x", "speed_y", "drive_y"]
    assert sorted(p.name for p in tmp_path.glob("*.png")) == sorted(
        f"die-bonder-pi_0.5ms_{n}.png" for n in names)
    assert len(result.rows) == 2 and seen == [(1, 3), (2, 3), (3, 3)]


def test_run_exports_the_commanded_setpoints_in_path_units(tmp_path):
    """The butterfly is drawn in mm: exported setpoints are in mm, G-code too."""
    assert main(["run", "butterfly", "--feed", "0.1m/s", "--interpolator", "taylor2",
                 "--out", str(tmp_path), "--no-figures", "--export", "csv", "--export",
                 "npz", "--export", "pvt", "--export", "gcode"]) == 0
    header, trace = read_csv(tmp_path / "trace.csv")
    _, sp = read_csv(tmp_path / "setpoints.csv")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert len(sp) == summary["steps"] + 1
    # written to a thousandth of a pulse (1 pulse = 1 um)
    np.testing.assert_allclose(sp[:, 2:] * 1000, trace[: len(sp), [2, 6]], rtol=0, atol=5e-4 + 1e-9)
    npz = np.load(tmp_path / "setpoints.npz")
    np.testing.assert_allclose(npz["position"], sp[:, 2:], rtol=0, atol=5e-7 + 1e-12)
    assert (tmp_path / "pvt.csv").read_text().startswith("t,x,x_velocity,y,y_velocity")
    gcode = (tmp_path / "motion.ngc").read_text()
    assert "G21" in gcode and "G1 X54.59" in gcode


def test_run_reads_a_gcode_contour(tmp_path):
    assert main(["run", "examples/butterfly.ngc#1", "--feed", "0.05m/s", "--out",
                 str(tmp_path), "--no-figures"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    # the file's F600 (10 mm/s = 1e4 pulse/s) is lower than --feed: it rules (issue 11)
    assert summary["path"] == "examples/butterfly.ngc#1" and summary["feed"] == 1e4
    # every interpolator follows the per-piece limit itself
    # in the path's unit first (issue 13), then in pulses
    assert summary["feed_used"] == (
        "the lower of the file's programmed feed (10 mm/s = 10000 pulse/s) and "
        "--feed 50 mm/s = 50000 pulse/s per piece")


@pytest.mark.parametrize("stream", [False, True])
def test_summary_notes_say_the_motion_stopped_at_the_corners(tmp_path, stream):
    """A hairpin (20 mm out, back 0.1 mm beside): rounding its corner within 0.5 um
    would not arrive sooner, so ``planned`` stops there, and ``summary.json`` says so in
    ``notes`` (beside the message), streamed or not; without a corner tolerance there is
    nothing to note."""
    path = tmp_path / "hairpin.ngc"
    path.write_text("G21 G90\nG1 X20 Y0 F60000\nG1 X0 Y0.1\nM2\n")
    notes = []
    for eps in ("0.5um", "0"):
        out = tmp_path / f"run{eps}"
        assert main(["run", str(path), "--corner-tolerance", eps, "--out", str(out)]
                    + ["--no-figures"] + ([] if stream else ["--export", "pvt"])) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["units"]["notes"] == "list of text"
        notes.append(summary["notes"])
    assert len(notes[0]) == 1 and "stops at the sharp corners" in notes[0][0]
    assert notes[0][0] in json.loads((tmp_path / "run0.5um" / "summary.json").read_text())[
        "message"]
    assert notes[1] == []


def test_bound_prints_the_time_optimal_bound(capsys):
    """SPEC section 9: about 0.115 s for the Pi at 1 m/s."""
    assert main(["bound", "die-bonder-pi", "--feed", "1m/s"]) == 0
    assert float(capsys.readouterr().out) == pytest.approx(0.1153, abs=5e-4)
    assert main(["bound", "examples/butterfly.toml", "--machine", "examples/die_bonder.toml",
                 "--feed", "50mm/s"]) == 0
    assert float(capsys.readouterr().out) == pytest.approx(382.86 / 50, rel=2e-3)


def test_bound_sampled_prints_the_sampled_stop_bound(capsys):
    """``bound --sampled``: the library's sampled bound of the Pi (no feed needed), a
    whole number of samples below the time-optimal bound at 1 m/s; a closed path without
    corners gets the time to reach its farthest point and come back, where it printed 0
    (issue 37)."""
    from nurbsmotion.loop import to_pulses
    from nurbsmotion.machine import die_bonder
    from nurbsmotion.planning import sampled_stop_bound
    machine = die_bonder()
    assert main(["bound", "die-bonder-pi", "--sampled"]) == 0
    got = float(capsys.readouterr().out)
    assert got == pytest.approx(
        sampled_stop_bound(to_pulses(nm.make_die_bonder_pi(), machine), machine))
    assert got / machine.sample_period == pytest.approx(round(got / machine.sample_period))
    assert got < 0.1153
    assert main(["bound", "butterfly", "--sampled"]) == 0
    got = float(capsys.readouterr().out)
    assert got == pytest.approx(
        sampled_stop_bound(to_pulses(nm.make_butterfly(), machine), machine))
    assert got > 0.0 and got / machine.sample_period == pytest.approx(
        round(got / machine.sample_period))


def test_run_and_bound_refuse_a_path_within_the_settle_window_alike(tmp_path, capsys):
    """Issue 37: `run` refused a 0.5 um line (within 1 pulse of its end from the start)
    while `bound` printed 0.000125 s and `bound --sampled` 0: one check, one message."""
    path = tmp_path / "short.json"
    path.write_text('{"units": "mm", "degree": 1, "knots": [0, 0, 1, 1], '
                    '"control_points": [[0, 0], [0.0005, 0]]}')
    errors = []
    for args in (["run", str(path), "--feed", "10mm/s", "--out", str(tmp_path / "o")],
                 ["bound", str(path), "--feed", "10mm/s"], ["bound", str(path), "--sampled"]):
        assert main(args) == 2
        captured = capsys.readouterr()
        assert captured.out == "" and captured.err.count("\n") == 1
        errors.append(captured.err.split(": error: ", 1)[1])
    assert errors[0] == errors[1] == errors[2]
    assert f"{path}: --settle-window 1: 1 pulse is not below the path's farthest distance from " \
        "its end point (0.5 pulse): the motion would be settled from the start; give a window " \
        "below that distance, or read the path on a machine with a finer pulse" in errors[0]
    # a smaller window, given to either command, lets the same path through
    assert main(["bound", str(path), "--sampled", "--settle-window", "0.1"]) == 0
    assert float(capsys.readouterr().out) > 0.0


def test_run_defaults_to_planned_and_reports_in_mm(tmp_path, capsys):
    assert main(["run", "butterfly", "--feed", "100mm/s", "--out", str(tmp_path),
                 "--no-figures"]) == 0
    out, err = capsys.readouterr()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["interpolator"] == "planned"
    assert summary["feed"] == 1e5 and summary["feed_mm_per_s"] == pytest.approx(100.0)
    assert f"{summary['max_contour_error_mm']:.4g} mm" in out
    assert err == ""  # no progress bar when stderr is not a terminal


def test_every_help_shows_the_defaults(capsys):
    for command, shown in [("run", ["(default: planned)", "(default: die-bonder)",
                                    "(default: csv)", "period of the PVT table [s] "
                                    "(default: 0.01)"]),
                           ("interpolate", ["(default: taylor2)",
                                            "Ts [s], at least 1e-05 (default: 0.001)"]),
                           ("bound", ["(default: die-bonder)"]),
                           ("reproduce", ["(default: results)"])]:
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        for s in shown:
            assert s in text, (command, s)
        assert "(default: None)" not in text and "(default: False)" not in text


def test_every_option_is_in_the_cli_reference():
    import argparse
    from pathlib import Path

    from nurbsmotion.cli import _parser

    doc = (Path(__file__).parents[1] / "docs" / "cli.md").read_text()
    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, parser in sub.choices.items():
        assert f"nurbsmotion {name}" in doc
        for action in parser._actions:
            for option in action.option_strings:
                if option not in ("-h", "--help"):
                    assert f"`{option}" in doc, (name, option)


def test_version(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"nurbsmotion {version('nurbsmotion')}"


def test_trace_options(tmp_path, capsys, monkeypatch):
    """--trace-every keeps every N-th row and the end; Parquet holds the CSV's numbers;
    --no-trace writes none; a large trace is announced with its size and the options."""
    import pyarrow.parquet as pq

    from nurbsmotion import cli

    base = ["run", "die-bonder-pi", "--feed", "5e5", "--interpolator", "paper",
            "--no-figures"]
    assert main(base + ["--out", str(tmp_path / "all")]) == 0
    header, full = read_csv(tmp_path / "all" / "trace.csv")
    steps = json.loads((tmp_path / "all" / "summary.json").read_text())["steps"]
    assert main(base + ["--out", str(tmp_path / "every"), "--trace-every", "7"]) == 0
    _, every = read_csv(tmp_path / "every" / "trace.csv")
    rows = sorted(set(range(0, len(full), 7)) | {steps, len(full) - 1})
    np.testing.assert_array_equal(every, full[rows])
    assert main(base + ["--out", str(tmp_path / "pq"), "--trace-format", "parquet"]) == 0
    table = pq.read_table(tmp_path / "pq" / "trace.parquet")
    assert table.column_names == header
    np.testing.assert_array_equal(np.column_stack([c.to_numpy() for c in table.columns]),
                                  full)
    assert main(base + ["--out", str(tmp_path / "none"), "--no-trace"]) == 0
    assert sorted(p.name for p in (tmp_path / "none").iterdir()) == ["summary.json"]
    capsys.readouterr()
    monkeypatch.setattr(cli.commands, "TRACE_NOTICE_BYTES", 1000)
    assert main(base + ["--out", str(tmp_path / "big")]) == 0
    err = capsys.readouterr().err
    assert "trace.csv" in err and "--trace-every" in err and "--no-trace" in err
    size = (tmp_path / "big" / "trace.csv").stat().st_size
    mb = float(err.split(" MB")[0].split("about ")[-1].replace(",", ""))
    assert mb == pytest.approx(size / 1e6, rel=0.2, abs=0.01)


# ---------------------------------------------------------------- path files: units, feed
def test_contours_lists_index_pieces_length_box_units_and_feed(capsys):
    from pathlib import Path

    ngc = Path(__file__).resolve().parents[1] / "examples" / "butterfly.ngc"
    assert main(["contours", str(ngc), "--axes", "xy"]) == 0  # as a 2-axis machine reads it
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("5 contours (choose one with " + str(ngc) + "#k)")
    rows = [line for line in out if line.startswith("| ") and line[2].isdigit()]
    assert [r.split(" | ")[0] for r in rows] == ["| 1", "| 2", "| 3", "| 4", "| 5"]
    assert all(r.endswith("| mm | F600 mm/min |") for r in rows)
    # without --axes: on every axis the file moves, the plunge (F100) part of each contour
    assert main(["contours", str(ngc)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1] == "axes: XYZ (every axis the file moves; --axes to choose)"
    rows = [line for line in out if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == 5 and all(r.endswith("| mm | F100 to F600 mm/min |") for r in rows)


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
        f"nurbsmotion contours: warning: {ngc}, line 1: no G20/G21 before the first move; reading millimetres (G21)",
        f"nurbsmotion contours: warning: {ngc}, line 2: M3/M4/M5 spindle skipped: it does not change the path",
        f"nurbsmotion contours: warning: {ngc}, line 2: S spindle speed skipped: it does not change the path",
    ]


def test_path_tolerance_takes_a_length_or_pulses(tmp_path):
    """planned records its path tolerance (default one pulse) in pulses and the path's
    unit; a run of another interpolator has none."""
    for text, pulses in ((None, 1.0), ("3", 3.0), ("0.002mm", 2.0)):
        out = tmp_path / str(text)
        extra = [] if text is None else ["--path-tolerance", text]
        assert main(["run", "die-bonder-pi", "--feed", "1m/s", *extra, "--out", str(out),
                     "--no-figures", "--no-trace"]) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["path_tolerance"] == pytest.approx(pulses)
        assert summary["path_tolerance_mm"] == pytest.approx(pulses * 1e-3)
        assert summary["units"]["path_tolerance"] == "pulse"
    out = tmp_path / "paper"
    assert main(["run", "die-bonder-pi", "--feed", "1m/s", "--interpolator", "paper",
                 "--out", str(out), "--no-figures", "--no-trace"]) == 0
    assert "path_tolerance" not in json.loads((out / "summary.json").read_text())


def test_settle_window_takes_a_length_or_pulses(tmp_path):
    """A bare number is pulses (as before); a length is converted; both are in the
    summary, in pulses and in the path's unit, and the settle time follows the window."""
    times = {}
    for text, pulses in (("1", 1.0), ("0.5um", 0.5), ("0.02mm", 20.0)):
        out = tmp_path / text
        assert main(["run", "die-bonder-pi", "--feed", "1m/s", "--settle-window", text,
                     "--out", str(out), "--no-figures", "--no-trace"]) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["settle_window"] == pytest.approx(pulses)
        assert summary["settle_window_mm"] == pytest.approx(pulses * 1e-3)
        assert summary["units"]["settle_window_mm"] == "mm"
        times[pulses] = summary["settle_time_s"]
    assert times[20.0] <= times[1.0] <= times[0.5]


# ------------------------------------------------------- issue 37, item 5: one run per folder
def test_overwrite_replaces_the_whole_set_of_outputs(tmp_path, capsys):
    """Regression: --overwrite into the folder of a run with more outputs left its trace,
    figures and exports beside the new summary.json."""
    from nurbsmotion.cli import project_outputs

    out = tmp_path / "out"
    base = ["run", "die-bonder-pi", "--feed", "1m/s", "--interpolator", "taylor1",
            "--quiet", "--out", str(out)]
    assert main(base + ["--export", "csv", "--export", "pvt"]) == 0
    first = {p.name for p in out.iterdir()}
    assert {"trace.csv", "summary.json", "setpoints.csv", "pvt.csv", "contour.png"} <= first
    (out / "notes.txt").write_text("mine")  # a user's file: never touched
    assert main(base + ["--no-figures", "--no-trace"]) == 2  # without --overwrite: refused
    assert {p.name for p in out.iterdir()} == first | {"notes.txt"}
    capsys.readouterr()
    assert main(base + ["--no-figures", "--no-trace", "--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "summary.json"]
    assert first <= set(project_outputs())
    # another command's outputs are the earlier run's too
    assert main(["interpolate", "die-bonder-pi", "--feed", "5e5", "--out", str(out),
                 "--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "setpoints.csv",
                                                     "setpoints.csv-metadata.json",
                                                     "setpoints.png"]


@pytest.mark.parametrize("command", [
    ["run", "die-bonder-pi", "--feed", "1m/s", "--no-figures"],
    ["interpolate", "die-bonder-pi", "--feed", "5e5"],
    ["reproduce", "--no-figures"],
])
@pytest.mark.parametrize("out", ["", "  "])
def test_an_empty_out_is_refused(tmp_path, capsys, monkeypatch, command, out):
    """Regression: --out "" wrote into the current folder."""
    monkeypatch.chdir(tmp_path)
    assert main(command + ["--out", out]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "output folder name" in err[0] and "empty" in err[0]
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------- issue 37, item 7: docs true to the tool
DOCS = __import__("pathlib").Path(__file__).resolve().parents[1] / "docs"


def test_the_cli_doc_opens_with_the_parsers_synopsis():
    """Regression: docs/cli.md's synopsis lacked `contours` and `campaign`."""
    import argparse

    from nurbsmotion.cli import _parser, synopsis

    doc = (DOCS / "cli.md").read_text()
    block = doc.split("```\n", 2)[1]
    assert block.strip() == synopsis().strip()
    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in sub.choices.items():  # every command has its section ...
        assert f"## `nurbsmotion {name}" in doc, name
        for action in command._actions:  # ... and every option is described
            for option in action.option_strings:
                if option.startswith("--") and option != "--help":
                    assert f"`{option}" in doc, (name, option)


def test_a_path_file_without_units_is_read_in_mm_as_formats_md_says(tmp_path):
    """Regression: docs/formats.md said such a file is read in pulses."""
    from nurbsmotion.paths import PathWarning, load_path

    file = tmp_path / "p.json"
    file.write_text(json.dumps({"degree": 1, "knots": [0, 0, 1, 1],
                                "control_points": [[0, 0], [10, 0]]}))
    with pytest.warns(PathWarning, match="no 'units'.*millimetres"):
        assert load_path(file).units == "mm"
    row = next(line for line in (DOCS / "formats.md").read_text().splitlines()
               if line.startswith("| `units` |"))
    assert "read in mm" in row and "(the default)" not in row


def test_the_docs_need_no_package_that_is_not_installed():
    """Regression: docs/campaign.md suggested pandas, which nurbsmotion does not install."""
    import importlib.util
    import tomllib

    project = tomllib.loads((DOCS.parent / "pyproject.toml").read_text())["project"]
    needed = " ".join(project["dependencies"]).lower()
    for page in ("campaign.md", "formats.md", "cli.md"):
        for paragraph in (DOCS / page).read_text().split("\n\n"):
            if "pandas" in paragraph and "pandas" not in needed:
                assert ("if you have it" in paragraph or "pandas installed" in paragraph
                        or "pandas is not a dependency" in paragraph), paragraph
    assert importlib.util.find_spec("pyarrow") is not None and "pyarrow" in needed


# ------------------------------------------------------- no run beats `bound --sampled`
def _sampled_bound_cases():
    """(name, path, feed [path units/s], planned's options) per case."""
    from nurbsmotion.paths.random_paths import random_path
    from test_chords import wave

    pi = nm.make_die_bonder_pi()
    corners = nm.make_polyline([[0, 0], [3000, 0], [3000, 2000], [6000, 2500]])
    short = random_path("short_moves", [37, 1], n_axes=2)
    curl = random_path("sharp_corners", [37, 2], n_axes=2, length=5000.0)
    # at 5e4 pulse/s every interpolator stays within Umax on the first three; at the
    # higher feeds only planned does (the others saturate, which the bound does not cover)
    # 300 CAM chords of 0.01 mm as programmed (`--path-tolerance 0`): planned passes
    # their joints moving, within a fraction of a pulse, and beat the bound that counted
    # every joint as a stop at a sample instant (issue 37)
    chords = nm.make_polyline(wave(300), units="mm")
    return [("die-bonder-pi", pi, 5e4, {}), ("corners", corners, 5e4, {}),
            ("sharp_corners", curl, 5e4, {}), ("corners", corners, 5e5, {}),
            ("short_moves", short, 1e6, {}), ("sharp_corners", curl, 3e5, {}),
            ("cam-chords", chords, 100.0, {"path_tolerance": 0.0})]


@pytest.mark.parametrize("interpolator", ["taylor1", "taylor2", "paper", "planned"])
def test_no_run_within_the_drive_limit_settles_below_the_sampled_bound(interpolator, capsys):
    """`bound --sampled` is a lower bound on the move-and-settle time of any motion of the
    sampled loop along the path: no run that keeps its drive within Umax settles sooner
    (a run that saturates may: it is not a motion the bound covers), on CAM chords as
    programmed too."""
    from nurbsmotion.loop import run, to_pulses
    from nurbsmotion.machine import die_bonder
    from nurbsmotion.planning import sampled_stop_bound

    machine = die_bonder()
    checked = 0
    for name, curve, feed, options in _sampled_bound_cases():
        path = to_pulses(curve, machine)
        bound = sampled_stop_bound(path, machine)
        if name == "die-bonder-pi":
            assert main(["bound", name, "--sampled"]) == 0  # the command prints the same
            assert float(capsys.readouterr().out) == pytest.approx(bound, abs=1e-12)
        trace = run(curve, machine, feed, interpolator,
                    interpolator_options=options if interpolator == "planned" else None)
        metrics = trace.metrics()
        if metrics.total_saturated_samples or not metrics.settled:
            continue
        checked += 1
        assert metrics.settle_time_s >= bound - 1e-9, (
            f"{interpolator} on {name} at {feed}: settled at {metrics.settle_time_s} s, "
            f"below the sampled bound {bound} s")
    assert checked >= 3  # most of the cases stay within the drive limit


def test_a_refusal_as_the_input_is_read_loads_no_compiled_or_plotting_module(tmp_path):
    """Issue 37 (refusals within a second of CPU, start-up included): importing the
    command line loads neither numpy nor numba, scipy or matplotlib (its choices,
    defaults and help texts come from nurbsmotion.limits); ``run`` and ``bound`` read and
    check the machine (numba-free value objects: control, servo, plant.linear) and the
    path up to a size refusal (planner grid, corners, DXF pieces) or a machine refused
    for its sample period, without numba, scipy, matplotlib or any compiled module of the
    package. One fresh process (sys.modules), the limits lowered so the files are small."""
    import subprocess
    import sys

    from nurbsmotion.paths import save_path

    n = 303
    x = np.arange(n) * 0.01
    wave = save_path(nm.NurbsCurve(3, np.r_[[0.0] * 3, np.arange(n - 2.0), [n - 3.0] * 3],
                                   np.column_stack([x, np.sin(x)]), units="mm"),
                     tmp_path / "wave.json")
    zigzag = save_path(nm.NurbsCurve(1, np.r_[0.0, np.arange(n + 0.0), n - 1.0],
                                     np.column_stack([x, (np.arange(n) % 2) * 0.01]),
                                     units="mm"), tmp_path / "zigzag.json")
    dxf = tmp_path / "lines.dxf"
    dxf.write_text("0\nSECTION\n2\nENTITIES\n" + "".join(
        f"0\nLINE\n8\n0\n10\n{k}\n20\n0\n30\n0\n11\n{k + 1}\n21\n0\n31\n0\n"
        for k in range(40)) + "0\nENDSEC\n0\nEOF\n")
    machine = tmp_path / "fast.toml"
    machine.write_text((Path(__file__).parents[1] / "examples" / "die_bonder.toml").read_text()
                       .replace("sample_period = 0.001", "sample_period = 1e-9"))
    out = str(tmp_path / "out")
    commands = [["run", str(wave), "--feed", "1mm/s", "--out", out],
                ["bound", str(wave), "--feed", "1mm/s"],
                ["run", str(zigzag), "--feed", "1mm/s", "--out", out],
                ["run", str(dxf), "--feed", "1mm/s", "--out", out],
                ["interpolate", str(dxf), "--feed", "1mm/s", "--out", out],
                ["run", "die-bonder-pi", "--feed", "1mm/s", "--machine", str(machine),
                 "--out", out],
                ["interpolate", "die-bonder-pi", "--feed", "1mm/s", "--sample-period",
                 "1e-9", "--out", out]]
    script = f"""
import sys

def heavy():
    return sorted(m for m in sys.modules if m.split(".")[0] in ("numba", "scipy",
                  "matplotlib") or m.startswith(("nurbsmotion.control.step",
                  "nurbsmotion.servo.step", "nurbsmotion.plant.", "nurbsmotion.phase_plane",
                  "nurbsmotion._kernels", "nurbsmotion.stepping", "nurbsmotion.loop",
                  "nurbsmotion.interpolators", "nurbsmotion.report", "nurbsmotion.plots"))
                  and m != "nurbsmotion.plant.linear")

import nurbsmotion.cli
print(heavy(), "numpy" in sys.modules)
from nurbsmotion import planning
from nurbsmotion.paths import dxf, files
planning.MAX_GRID_POINTS, files.SIZE_SCAN_BYTES, dxf.MAX_PIECES = 1000, 1000, 10
for argv in {commands!r}:
    try:
        code = nurbsmotion.cli.main(argv)
    except SystemExit as exc:  # argparse's refusal
        code = exc.code
    print(code, heavy())
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(Path(nm.__file__).parents[1])})
    lines = done.stdout.strip().splitlines()
    assert lines == ["[] False"] + ["2 []"] * len(commands), (done.stdout, done.stderr)
    errors = done.stderr.strip().splitlines()
    assert len(errors) == len(commands), done.stderr
    for text, error in zip(["300 knot spans of degree 3", "300 knot spans of degree 3",
                            "sharp corners", "path pieces", "path pieces",
                            "below the minimum of 1e-05 s", "minimum sample period"], errors):
        assert text in error, (text, error)
