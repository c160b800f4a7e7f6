"""Rotary axes A, B, C run as path axes of an N-axis machine (issue 36): a machine file
gives a rotary axis's pulses per degree, the path runs in the machine's pulses, the feed
follows LinuxCNC's rule (F the speed of XYZ where they move, else of the rotary axes in
deg/min), and a rotary axis's trace columns are in degrees. The geometry that runs is
compared with the points LinuxCNC's own interpreter computes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from nurbsmotion.errors import InvalidArgumentError, InvalidMachineError, PathFileError
from nurbsmotion.loop import to_pulses
from nurbsmotion.machine import Axis, Machine, load_machine
from nurbsmotion.run_input import load_run_contour, run_feed

from linuxcnc_reference import distances_to_path, linuxcnc_moves, linuxcnc_python

ROOT = Path(__file__).resolve().parents[1]
GANTRY4A = ROOT / "examples" / "gantry4a.toml"
ABC_TANGENT = ROOT / "tests" / "data" / "corpus" / "linuxcnc_tp" / "diagnostic__abc_tangent.ngc"
PPD = 1000.0  # gantry4a's A axis [pulse/deg]
PULSES_PER_INCH = 25_400.0  # gantry4a: 1 um pulses


def _duration(feed, curve) -> np.ndarray:
    """Time of each piece of ``curve`` at exactly ``feed`` [s]."""
    s = curve.arc_length(feed.breakpoints)
    return np.diff(s) / feed.speeds


def test_the_machine_file_key_round_trips():
    machine = load_machine(GANTRY4A)
    assert machine.axis_names == ("x", "y", "z", "a") and machine.rotary_axes == ("a",)
    assert machine.axes[3].pulses_per_degree == PPD
    again = Machine.from_dict(machine.to_dict())
    assert again.axes[3].pulses_per_degree == PPD and again.axes[0].pulses_per_degree is None
    np.testing.assert_array_equal(machine.pulses_per_axis_unit("inch"),
                                  [PULSES_PER_INCH] * 3 + [PPD])
    assert "pulses_per_degree" not in load_machine("die-bonder").to_dict()["axes"][0]


@pytest.mark.parametrize("name, value, message", [
    ("x", 100.0, "pulses_per_degree is for a rotary axis, named a, b or c"),
    ("a", 0.0, "pulses_per_degree must be finite and > 0"),
    ("c", "10", "pulses_per_degree must be a number"),
])
def test_bad_pulses_per_degree_are_refused(name, value, message):
    with pytest.raises(InvalidMachineError, match=message):
        Axis(name, 0.1, 2000.0, 1591.5, 0.006, 0.02, pulses_per_degree=value)


def test_a_machine_file_with_a_bad_key_names_the_file(tmp_path):
    data = load_machine(GANTRY4A).to_dict()
    data["axes"][3]["pulses_per_degre"] = 5.0
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(PathFileError, match="pulses_per_degree"):
        load_machine(path)


def test_the_rotary_column_runs_in_the_machines_pulses():
    machine = load_machine(GANTRY4A)
    contour = load_run_contour(f"{ABC_TANGENT}#1", machine)
    path = to_pulses(contour.curve, machine)
    # G1 X1 A100, G1 Y1 A200, G1 Z1 A300, G1 Z2 A400 (inch, degrees) from the origin
    corners = path(path.breakpoints)
    expected = [[0, 0, 0, 0], [1, 0, 0, 100], [1, 1, 0, 200], [1, 1, 1, 300], [1, 1, 2, 400]]
    np.testing.assert_allclose(corners, np.array(expected) * ([PULSES_PER_INCH] * 3 + [PPD]),
                               rtol=0, atol=1e-6)


def test_the_feed_follows_linuxcncs_rule():
    """Each piece takes what LinuxCNC's rule gives it: 1 inch of XYZ at F100 inch/min is
    0.6 s whatever A does; --feed caps F, not the speed along the mixed path."""
    machine = load_machine(GANTRY4A)
    contour = load_run_contour(f"{ABC_TANGENT}#1", machine)
    path = to_pulses(contour.curve, machine)
    np.testing.assert_allclose(_duration(run_feed(None, contour, machine), path), [0.6] * 4,
                               rtol=1e-12)
    capped = run_feed("50in/min", contour, machine)  # half of F
    np.testing.assert_allclose(_duration(capped, path), [1.2] * 4, rtol=1e-12)


def test_a_pure_rotary_move_is_in_degrees_per_minute(tmp_path):
    program = tmp_path / "turn.ngc"
    program.write_text("G21 G90 G94\nG0 X0 Y0 Z0 A0\nG1 X10 F600\nG1 A90 F900\n"
                       "G1 X20 A180 F600\nG1 Y3 Z4 F300\nM2\n")
    machine = load_machine(GANTRY4A)
    contour = load_run_contour(str(program), machine)
    path = to_pulses(contour.curve, machine)
    # 10 mm at 600 mm/min; 90 deg at 900 deg/min; 10 mm of X (A follows) at 600 mm/min;
    # 5 mm of YZ at 300 mm/min
    np.testing.assert_allclose(_duration(run_feed(None, contour, machine), path),
                               [1.0, 6.0, 1.0, 1.0], rtol=1e-12)


def test_a_machine_without_pulses_per_degree_is_refused():
    machine = load_machine(GANTRY4A)
    data = machine.to_dict()
    del data["axes"][3]["pulses_per_degree"]
    with pytest.raises(InvalidArgumentError, match="rotary axis A .deg., but machine 'gantry4a' "
                                                   "gives no pulses_per_degree"):
        load_run_contour(f"{ABC_TANGENT}#1", Machine.from_dict(data))


def test_a_rotary_axis_trace_columns_are_in_degrees():
    from nurbsmotion.report.trace_file import _columns
    from nurbsmotion.units import OutputUnits, Scale

    machine = load_machine(GANTRY4A)
    units = OutputUnits.of(machine, "in")  # a path drawn in inches
    assert Scale.of(None, machine).output.axis_units == ("mm", "mm", "mm", "deg")
    # the one converter on the way out: lengths in inches, the A axis in degrees
    assert units.unit == "in" and units.pulses_per_unit == PULSES_PER_INCH
    assert units.axis_units == ("in", "in", "in", "deg")
    np.testing.assert_array_equal(units.pulses_per_axis_unit, [PULSES_PER_INCH] * 3 + [PPD])
    columns = _columns(machine, True, units)
    names = [c.name for c in columns]
    assert {"x_cmd_in", "a_cmd_deg", "a_act_deg", "a_speed_max_deg_per_s"} <= set(names)
    assert not any(n.startswith("a_") and n.endswith(("_in", "_in_per_s")) for n in names)
    # the values: 2,000 pulses of A are 2 deg, of X 2000/25400 in
    block = type("Block", (), {"position_command": np.array([[2000.0, 0.0, 0.0, 2000.0]])})
    read = {c.name: c.read for c in columns}
    assert read["a_cmd_deg"](block, 0) == 2.0
    assert read["x_cmd_in"](block, 0) == pytest.approx(2000.0 / PULSES_PER_INCH, rel=1e-15)


@pytest.mark.skipif(linuxcnc_python() is None, reason="LinuxCNC's gcode module (linuxcnc-uspace) is not installed")
def test_the_path_that_runs_passes_through_linuxcncs_points():
    """LinuxCNC's feed points of the 4-axis program, in the machine's pulses (inch and
    degrees scaled by the machine file), lie on the path the run follows."""
    ref = linuxcnc_moves(ABC_TANGENT)
    assert ref["error"] is None
    points = np.array([m[2] for m in ref["moves"] if m[0] == "feed"], dtype=float)[:, [0, 1, 2, 3]]
    points *= [PULSES_PER_INCH / 25.4] * 3 + [PPD]  # the helper gives mm and degrees
    machine = load_machine(GANTRY4A)
    curves = [to_pulses(load_run_contour(f"{ABC_TANGENT}#{k}", machine).curve, machine)
              for k in (1, 2)]
    assert len(points) >= 8
    assert np.max(distances_to_path(points, curves)) <= 1e-6  # [pulse]


def test_inverse_time_gives_each_move_its_duration(tmp_path):
    """G93: F is 1 / the move's time [1/min], whatever the axes; the reader keeps it as
    the speed of the feed group, which the rule then turns into the speed along the path."""
    program = tmp_path / "g93.ngc"
    program.write_text("G21 G90\nG0 X0 Y0 Z0 A0\nG93 G1 X10 A90 F30\nG1 A180 F20\n"
                       "G1 X0 Y10 A0 F60\nM2\n")
    machine = load_machine(GANTRY4A)
    contour = load_run_contour(str(program), machine)
    path = to_pulses(contour.curve, machine)
    np.testing.assert_allclose(_duration(run_feed(None, contour, machine), path),
                               [2.0, 3.0, 1.0], rtol=1e-12)


def test_uvw_with_xyz_feed_is_the_speed_of_xyz(tmp_path):
    """No rotary axis, two feed groups: F applies to XYZ where they move, else to UVW."""
    from nurbsmotion.machine import die_bonder

    program = tmp_path / "xyu.ngc"
    program.write_text("G21 G90 F600\nG0 X0 Y0 U0\nG1 X30 U40\nG1 U0\nM2\n")
    d = die_bonder().to_dict()
    d["axes"] = [dict(d["axes"][0], name=n) for n in "xyu"]
    machine = Machine.from_dict(d)
    contour = load_run_contour(str(program), machine)
    path = to_pulses(contour.curve, machine)
    # 30 mm of X at 600 mm/min (U follows); then 40 mm of U alone at 600 mm/min
    np.testing.assert_allclose(_duration(run_feed(None, contour, machine), path), [3.0, 4.0],
                               rtol=1e-12)


def test_a_4_axis_program_runs_and_exports_the_rotary_axis_in_degrees(tmp_path, capsys):
    """`run FILE --machine gantry4a.toml` on LinuxCNC's 4-axis program: the cycle takes
    LinuxCNC's 2.4 s (4 inches at F100 inch/min), the trace, setpoints, PVT table and
    motion G-code give A in degrees (it ends at A400), ROS in radians."""
    from nurbsmotion.cli import main

    out = tmp_path / "abc"
    assert main(["run", f"{ABC_TANGENT}#1", "--machine", str(GANTRY4A), "--out", str(out),
                 "--no-figures", "--export", "csv", "--export", "pvt", "--export", "gcode",
                 "--export", "ros"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["rotary_axes"] == {"a": {"unit": "deg", "pulses_per_degree": PPD}}
    assert 2.4 <= summary["cycle_time_s"] <= 2.4 * 1.01
    header = (out / "trace.csv").open().readline().strip().split(",")
    assert "a_cmd_deg" in header and "a_cmd_in" not in header
    rows = np.loadtxt(out / "setpoints.csv", delimiter=",", skiprows=1)
    assert (out / "setpoints.csv").open().readline().strip() == "t,u,x,y,z,a_deg"
    # the last setpoint within a sample's travel of the end (0.55 ms at 100 deg/inch)
    np.testing.assert_allclose(rows[-1, 2:], [1.0, 1.0, 2.0, 400.0], atol=0.1)
    assert rows[:, 5].max() > 399.9
    assert (out / "pvt.csv").open().readline().startswith("t,x,x_velocity,y,y_velocity,z,"
                                                          "z_velocity,a_deg,a_deg_velocity")
    moves = [ln for ln in (out / "motion.ngc").read_text().splitlines() if ln.startswith("G1 ")]
    a_end = float(moves[-1].split(" A")[1].split()[0])
    x_end = float(moves[-1].split(" X")[1].split()[0])
    assert abs(a_end - rows[-1, 5]) < 1e-3 and abs(x_end - 25.4) < 1e-3  # deg; mm
    ros = (out / "trajectory.yaml").read_text()
    assert "joint_names: [x, y, z, a]" in ros and "6.98" in ros  # 400 deg = 6.981 rad
