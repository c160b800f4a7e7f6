"""Setpoint export: CSV/NPZ read back exactly, PVT against an analytic motion, G-code motion."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline

from nurbsmotion import builtin_path
from nurbsmotion.errors import OutputExistsError
from nurbsmotion.report.export import (
    ExportError,
    SetpointArrays,
    pvt_table,
    save_motion_gcode,
    save_pvt,
    save_setpoints,
)
from nurbsmotion.paths.gcode import load_gcode

TS = 1e-3  # [s]


def circle_motion(n=400, radius=10.0, omega=2 * math.pi):
    """Setpoints of a circle at constant angular speed: x = r cos(wt), y = r sin(wt)."""
    t = np.arange(n) * TS
    pos = radius * np.c_[np.cos(omega * t), np.sin(omega * t)]
    return SimpleNamespace(t=t, u=t / t[-1], position=pos, feed=np.full(n, radius * omega), axis_names=("x", "y"))


def test_csv_reads_back_bit_for_bit(tmp_path):
    sp = circle_motion()
    file = save_setpoints(sp, tmp_path / "setpoints.csv")
    assert file.read_text().splitlines()[0] == "t,u,x,y"
    data = np.loadtxt(file, delimiter=",", skiprows=1)
    np.testing.assert_array_equal(data[:, 0], sp.t)
    np.testing.assert_array_equal(data[:, 1], sp.u)
    np.testing.assert_array_equal(data[:, 2:], sp.position)


def test_npz_reads_back(tmp_path):
    sp = circle_motion()
    file = save_setpoints(sp, tmp_path / "setpoints.npz")
    with np.load(file) as data:
        np.testing.assert_array_equal(data["position"], sp.position)
        np.testing.assert_array_equal(data["feed"], sp.feed)
        assert tuple(data["axis_names"]) == ("x", "y")


def test_writers_never_clobber_and_validate_first(tmp_path):
    target = tmp_path / "setpoints.csv"
    target.write_text("old")
    with pytest.raises(OutputExistsError):
        save_setpoints(circle_motion(), target)
    assert target.read_text() == "old"
    bad = SimpleNamespace(t=[0.0, 0.001, 0.001], u=[0, 0.5, 1], position=np.zeros((3, 2)))
    with pytest.raises(ExportError, match=r"t\[2\] = 0.001 <= t\[1\]"):
        save_setpoints(bad, tmp_path / "bad.csv")
    with pytest.raises(ExportError, match=r"position must have shape \(2, n_axes\)"):
        SetpointArrays([0, 1], [0, 1], np.zeros((3, 2)))
    with pytest.raises(ExportError, match="unknown setpoint file ending"):
        save_setpoints(circle_motion(), tmp_path / "s.xlsx")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["setpoints.csv"]


def test_pvt_matches_analytic_motion_and_its_hermite_reconstruction(tmp_path):
    sp = circle_motion(n=1001)  # one full turn in 1 s
    table = pvt_table(sp, period=0.01)
    np.testing.assert_allclose(np.diff(table.t), 0.01, rtol=1e-9)
    w, r = 2 * math.pi, 10.0
    exact_v = r * w * np.c_[-np.sin(w * table.t), np.cos(w * table.t)]
    interior = slice(2, -2)  # not-a-knot ends are less accurate
    np.testing.assert_allclose(table.velocity[interior], exact_v[interior], atol=1e-6 * r * w)
    # the controller's cubic Hermite segments between PVT rows follow the true circle
    hermite = CubicHermiteSpline(table.t, table.position, table.velocity, axis=0)
    tt = np.linspace(0.05, 0.95, 997)
    exact = r * np.c_[np.cos(w * tt), np.sin(w * tt)]
    assert np.max(np.abs(hermite(tt) - exact)) < 1e-6 * r
    x = table.axis("x")
    assert x.shape == (len(table.t), 3)
    file = save_pvt(table, tmp_path / "pvt.csv")
    assert file.read_text().splitlines()[0] == "t,x,x_velocity,y,y_velocity"


def test_motion_gcode_reads_back_as_the_setpoints_with_timing(tmp_path):
    curve = builtin_path("butterfly")
    u = np.linspace(0, 1, 300)
    pos = curve(u)
    hold = np.vstack([pos, pos[-1:], pos[-1:]])  # the end is held: no extra lines
    sp = SetpointArrays(np.arange(302) * TS, np.r_[u, 1, 1], hold)
    file = save_motion_gcode(sp, tmp_path / "motion.ngc")
    (contour,) = load_gcode(file).contours
    c = contour.curve
    assert c.degree == 1 and len(contour.lines) == 299
    size = np.max(np.ptp(pos, axis=0))
    np.testing.assert_allclose(c(contour.piece_edges), pos, rtol=0, atol=1e-9 * size)
    # each G1's F makes it last one sample period: length / (F / 60) = Ts
    lengths = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    np.testing.assert_allclose(lengths / contour.feed, TS, rtol=1e-10)


def test_motion_gcode_scales_pulses_and_rejects_bad_axes(tmp_path):
    sp = SetpointArrays([0, 1e-3, 2e-3], [0, 0.5, 1], [[0, 0], [1000, 0], [1000, 0]])
    file = save_motion_gcode(sp, tmp_path / "m.ngc", scale=1e-3)
    assert "G1 X1 Y0 F60000" in file.read_text()
    with pytest.raises(ExportError, match="not G-code axis letters"):
        save_motion_gcode(SetpointArrays([0, 1], [0, 1], [[0, 0], [1, 1]], axis_names=("x", "q")), tmp_path / "n.ngc")
    assert not (tmp_path / "n.ngc").exists()


# ---------------------------------------------------------------- halstreamer, ROS, resolution
def test_halstreamer_one_line_per_period_in_machine_units(tmp_path):
    from nurbsmotion.report.export import save_halstreamer

    sp = circle_motion()  # [mm]
    file = save_halstreamer(sp, tmp_path / "halstreamer.txt", units="mm", scale=1.0, resolution=1e-6)
    text = file.read_text().splitlines()
    assert text[0] == "# nurbsmotion setpoints for LinuxCNC halstreamer: 400 lines, one per servo period of 0.001 s"
    assert text[1].endswith("cfg=ff") and text[2] == "# columns: x [mm] y [mm] (to 1e-06 mm)"
    data = np.loadtxt(file, comments="#")  # as halstreamer reads it: '#' lines skipped
    assert data.shape == (400, 2)
    np.testing.assert_allclose(data, sp.position, rtol=0, atol=0.5e-6 + 1e-12)
    assert all(len(x.split(".")[1]) == 6 for x in text[3].split())


def test_halstreamer_needs_one_setpoint_per_period(tmp_path):
    from nurbsmotion.report.export import save_halstreamer

    sp = circle_motion()
    sp.t = sp.t.copy()
    sp.t[100:] += 0.0005
    with pytest.raises(ExportError, match=r"one per servo period \(0.001 s\), but t\[100\] - t\[99\] = 0.0015 s"):
        save_halstreamer(sp, tmp_path / "h.txt")
    assert list(tmp_path.iterdir()) == []


def test_ros_trajectory_follows_the_circle(tmp_path):
    """Positions, velocities and accelerations of the YAML against the analytic circle
    (radius 10 mm at 1 rev/s: speed 62.8 mm/s, centripetal 395 mm/s^2), in SI units."""
    yaml = pytest.importorskip("yaml")
    from nurbsmotion.report.export import save_ros_trajectory

    sp = circle_motion()
    file = save_ros_trajectory(sp, tmp_path / "trajectory.yaml", period=0.01, scale=1e-3, resolution=1e-9)
    msg = yaml.safe_load(file.read_text())
    assert msg["joint_names"] == ["x", "y"]
    points = msg["points"]
    t = np.array([p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"] for p in points])
    np.testing.assert_allclose(t[:-1], np.arange(len(t) - 1) * 0.01, atol=1e-12)
    assert t[-1] == pytest.approx(sp.t[-1], abs=1e-12)
    pos = np.array([p["positions"] for p in points])
    vel = np.array([p["velocities"] for p in points])
    acc = np.array([p["accelerations"] for p in points])
    w, r = 2 * math.pi, 10e-3  # [rad/s], [m]
    inner = slice(2, -2)  # the spline's not-a-knot ends are less exact
    np.testing.assert_allclose(pos, r * np.c_[np.cos(w * t), np.sin(w * t)], atol=1e-9)
    np.testing.assert_allclose(vel[inner], r * w * np.c_[-np.sin(w * t), np.cos(w * t)][inner], atol=1e-7)
    np.testing.assert_allclose(acc[inner], -r * w * w * np.c_[np.cos(w * t), np.sin(w * t)][inner], atol=1e-4)


def test_resolution_writes_a_fraction_of_a_pulse(tmp_path):
    sp = circle_motion()
    file = save_setpoints(sp, tmp_path / "setpoints.csv", resolution=1e-6)
    lines = file.read_text().splitlines()
    assert lines[0] == "t,u,x,y"
    t, u, x, y = lines[1].split(",")
    assert (len(t.split(".")[1]), len(u.split(".")[1]), len(x.split(".")[1])) == (9, 12, 6)
    data = np.loadtxt(file, delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 2:], sp.position, rtol=0, atol=0.5e-6 + 1e-12)
    table = pvt_table(sp, 0.01)
    pvt = save_pvt(table, tmp_path / "pvt.csv", resolution=1e-6)
    back = np.loadtxt(pvt, delimiter=",", skiprows=1)
    np.testing.assert_allclose(back[:, 1], table.position[:, 0], rtol=0, atol=0.5e-6 + 1e-12)


def test_run_exports_halstreamer_and_ros_and_names_the_paths_unit(tmp_path, capsys):
    """``run --export halstreamer --export ros``: mm per servo period and a ROS 2
    trajectory in m; the printed line and summary.json say where the path's unit came
    from, and a copied machine file is named where its name differs."""
    import json
    from pathlib import Path

    from nurbsmotion.cli import main
    from nurbsmotion.machine import die_bonder

    machine = tmp_path / "weak.toml"
    machine.write_text(__import__("tomli_w").dumps(die_bonder().to_dict()))  # a copy, renamed
    ngc = str(Path(__file__).resolve().parents[1] / "examples" / "butterfly.ngc") + "#2"
    out = tmp_path / "out"
    assert main(["run", ngc, "--machine", str(machine), "--out", str(out), "--no-figures",
                 "--export", "halstreamer", "--export", "ros", "--export", "csv"]) == 0
    printed = capsys.readouterr().out
    assert f"planned on die-bonder (from {machine}) at" in printed
    assert "(path in mm, G21 on line 1)" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["path_unit"], summary["path_unit_source"]) == ("mm", "G21 on line 1")
    hal = np.loadtxt(out / "halstreamer.txt", comments="#")
    sp = np.loadtxt(out / "setpoints.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(hal, sp[:, 2:])  # mm both, to 1e-6 mm
    assert len(hal) == summary["steps"] + 1
    text = (out / "trajectory.yaml").read_text()
    assert "joint_names: [x, y]" in text and "time_from_start: {sec: 0, nanosec: 0}" in text


def test_csv_metadata_sidecars_name_every_column_and_unit(tmp_path):
    """Issue 36: beside setpoints.csv, pvt.csv and trace.csv, `run` writes the CSV on the
    Web metadata <name>.csv-metadata.json: its columns are the CSV header, in order, each
    with the unit docs/formats.md gives (QUDT IRI and the unit's text); --overwrite
    replaces them, and without it the folder is refused."""
    import json
    import re
    from pathlib import Path

    from nurbsmotion.cli import main
    from nurbsmotion.report.export import QUDT_UNITS

    out = tmp_path / "run"
    argv = ["run", "examples/butterfly.json", "--feed", "0.2m/s", "--out", str(out),
            "--no-figures", "--export", "csv", "--export", "pvt", "--quiet"]
    assert main(argv) == 0
    docs = (Path(__file__).parents[1] / "docs" / "formats.md").read_text()
    expected = {"setpoints.csv": ["s", "1", "mm", "mm"],
                "pvt.csv": ["s", "mm", "mm/s", "mm", "mm/s"],
                "trace.csv": ["s", "1"] + ["pulse", "pulse", "V", "V"] * 2 + ["mm"] * 4}
    for name, units in expected.items():
        header = (out / name).read_text().splitlines()[0].split(",")
        meta = json.loads((out / f"{name}-metadata.json").read_text())
        assert meta["url"] == name and meta["@context"][0] == "http://www.w3.org/ns/csvw"
        columns = meta["tableSchema"]["columns"]
        assert [c["name"] for c in columns] == header == [c["titles"] for c in columns]
        assert [c["nurbsmotion:unit"] for c in columns] == units
        for c in columns:
            assert c["qudt:unit"] == {"@id": f"unit:{QUDT_UNITS[c['nurbsmotion:unit']]}"}
            assert c["dc:description"].endswith(f"[{c['nurbsmotion:unit']}]")
            assert c["datatype"] == "double"
    assert "csv-metadata.json" in docs
    # the values are written to the resolution that matters, not 17 digits
    for name in ("setpoints.csv", "pvt.csv"):
        cells = (out / name).read_text().splitlines()[1].split(",")
        assert all(len(re.sub(r"[-.]", "", c)) < 17 for c in cells), cells
    # no temporary file left; a second run refuses the folder, --overwrite replaces all
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["summary.json", "setpoints.csv", "pvt.csv", "trace.csv", "setpoints.csv-metadata.json",
         "pvt.csv-metadata.json", "trace.csv-metadata.json"])
    assert main(argv) == 2
    assert main(argv[:-5] + ["--no-figures", "--quiet", "--overwrite"]) == 0
    assert not (out / "pvt.csv-metadata.json").exists()  # what this run did not write
    assert not (out / "setpoints.csv-metadata.json").exists()
    assert (out / "trace.csv-metadata.json").exists()


def test_csv_metadata_is_written_atomically(tmp_path, monkeypatch):
    """The sidecar goes through write_output (a temporary file renamed): a failure while
    writing leaves nothing, an existing file is refused without overwrite."""
    from nurbsmotion.errors import OutputExistsError
    from nurbsmotion.report import export
    from nurbsmotion.report.export import CsvColumn, save_csv_metadata

    cols = [CsvColumn("t", "s", "time"), CsvColumn("x", "mm", "x")]
    target = save_csv_metadata(tmp_path / "a.csv", cols)
    assert target.name == "a.csv-metadata.json" and [p.name for p in tmp_path.iterdir()] == [
        "a.csv-metadata.json"]
    with pytest.raises(OutputExistsError):
        save_csv_metadata(tmp_path / "a.csv", cols)
    monkeypatch.setattr(export.json if hasattr(export, "json") else __import__("json"),
                        "dumps", lambda *a, **k: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        save_csv_metadata(tmp_path / "b.csv", cols)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv-metadata.json"]
    with pytest.raises(export.ExportError, match="no QUDT unit"):
        save_csv_metadata(tmp_path / "c.csv", [CsvColumn("t", "furlong", "t")])


def test_interpolate_converts_a_feed_with_a_unit_through_the_machine(tmp_path, capsys):
    """Regression (found with issue 36): `interpolate die-bonder-pi --machine die-bonder
    --feed 0.2m/s` was refused as 'without a machine'; with --machine the feed goes
    through its pulse length (1 um: 0.2 m/s = 2e5 pulse/s), without it the message stays."""
    from nurbsmotion.cli import main

    assert main(["interpolate", "die-bonder-pi", "--machine", "die-bonder", "--feed", "0.2m/s",
                 "--out", str(tmp_path / "a")]) == 0
    assert "--feed 200000 pulse/s" in capsys.readouterr().out
    assert main(["interpolate", "die-bonder-pi", "--feed", "2e5", "--out",
                 str(tmp_path / "b")]) == 0
    assert (tmp_path / "a" / "setpoints.csv").read_bytes() == (
        tmp_path / "b" / "setpoints.csv").read_bytes()
    assert (tmp_path / "a" / "setpoints.csv-metadata.json").exists()
    assert main(["interpolate", "die-bonder-pi", "--feed", "0.2m/s", "--out",
                 str(tmp_path / "c")]) == 2
    assert "to a path in pulse without a machine" in capsys.readouterr().err
