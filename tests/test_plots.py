"""Figures: each function writes the PNG files it names; importing the library does not
import matplotlib."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

import nurbsmotion as nm
from nurbsmotion.interpolators import make_interpolator, make_open_loop
from nurbsmotion.loop import interpolate, run, simulate, to_pulses
from nurbsmotion.machine import die_bonder
from nurbsmotion.plots import plot_comparison, plot_setpoints, plot_trace, settling_time
from nurbsmotion.units import pulses_per_report_unit

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def machine():
    return die_bonder()


@pytest.fixture(scope="module")
def pi_runs(machine):
    """The Π move at 1 m/s, paper and taylor2."""
    path = nm.make_die_bonder_pi()
    return {name: simulate(make_interpolator(name, path, machine, 1e6), machine)
            for name in ("taylor2", "paper")}


@pytest.fixture(scope="module")
def butterfly_runs(machine):
    """The butterfly (no sharp corner) at 0.2 m/s, paper and taylor2."""
    path = to_pulses(nm.make_butterfly(), machine)
    return {name: simulate(make_interpolator(name, path, machine, 2e5), machine)
            for name in ("taylor2", "paper")}


def assert_pngs(paths, out_dir, names):
    assert [p.name for p in paths] == names
    for p in paths:
        assert p.parent == out_dir
        data = p.read_bytes()
        assert data.startswith(PNG_SIGNATURE) and len(data) > 5000


TRACE_FILES = ["contour.png", "following_error.png", "drive.png", "speed.png", "settle.png"]


@pytest.mark.parametrize("algorithm", ["paper", "taylor2"])
def test_plot_trace_pi(pi_runs, tmp_path, algorithm, monkeypatch):
    """Both drive X to several Umax at 1 m/s; the drive axes stay on the ±Umax frame."""
    from nurbsmotion import plots

    limits = []
    save = plots.figures._save

    def spy(fig, path, overwrite=True):
        if path.name.endswith("drive.png"):
            limits.extend(ax.get_ylim() for ax in fig.axes)
        return save(fig, path, overwrite)

    monkeypatch.setattr(plots.figures, "_save", spy)
    trace = pi_runs[algorithm]
    out = tmp_path / "new" / "folder"  # created if missing
    paths = plot_trace(trace, out, prefix=f"{algorithm}_")
    assert_pngs(paths, out, [f"{algorithm}_{n}" for n in TRACE_FILES])
    assert max(trace.metrics().max_drive_ratio.values()) > 4
    frame = plots.DRIVE_FRAME * trace.machine.max_drive
    assert limits and all(lim == pytest.approx((-frame, frame)) for lim in limits)


def test_trace_plot_method_butterfly(butterfly_runs, tmp_path):
    paths = butterfly_runs["paper"].plot(tmp_path)
    assert_pngs(paths, tmp_path, TRACE_FILES)


def test_plot_setpoints(machine, tmp_path):
    path = to_pulses(nm.make_butterfly(), machine)
    series = interpolate(make_open_loop("taylor2", path, machine.sample_period, 2e5))
    assert_pngs(plot_setpoints(series, tmp_path, units="pulse"), tmp_path, ["setpoints.png"])
    one_axis = interpolate(make_open_loop("taylor2", nm.make_line([0.0], [1000.0]), 1e-3, 1e4))
    out = tmp_path / "one"
    assert_pngs(one_axis.plot(out, axis_names=("x",)), out, ["setpoints.png"])


@pytest.mark.parametrize("runs, name", [("pi_runs", "pi_1.0"),
                                        ("butterfly_runs", "butterfly_0.2")])
def test_plot_comparison(request, tmp_path, runs, name):
    traces = request.getfixturevalue(runs)
    paths = plot_comparison(traces, tmp_path, name)
    assert_pngs(paths, tmp_path, [f"{name}_contour.png", f"{name}_speed_x.png",
                                  f"{name}_drive_x.png", f"{name}_speed_y.png",
                                  f"{name}_drive_y.png"])


def test_plot_comparison_without_bounds(pi_runs, tmp_path):
    paths = plot_comparison({"taylor2": pi_runs["taylor2"]}, tmp_path, "pi", feed=1e6, axis=0)
    assert_pngs(paths, tmp_path, ["pi_contour.png", "pi_speed_x.png", "pi_drive_x.png"])


def test_plot_comparison_needs_a_trace(tmp_path):
    with pytest.raises(ValueError):
        plot_comparison({}, tmp_path, "empty")


def test_import_does_not_import_matplotlib():
    code = ("import sys, nurbsmotion, nurbsmotion.loop, nurbsmotion.plots, "
            "nurbsmotion.interpolators, nurbsmotion.metrics, nurbsmotion.report, "
            "nurbsmotion.cli; heavy = ('matplotlib', 'pyarrow', 'tqdm'); "
            "sys.exit(int(any(m.split('.')[0] in heavy for m in sys.modules)))")
    src = str(Path(nm.__file__).resolve().parents[1])  # wherever the tests found it
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    assert subprocess.run([sys.executable, "-c", code], env=env).returncode == 0


def test_plot_trace_of_a_three_axis_path(tmp_path):
    """A 3-D path: the contour figure draws it in 3-D and in projections."""
    from nurbsmotion.machine import load_machine

    root = Path(__file__).parents[1] / "examples"
    machine = load_machine(root / "gantry3.toml")
    path = nm.load_path(root / "helix3d.json")
    trace = run(path, machine, "200mm/s", "taylor2")
    assert_pngs(trace.plot(tmp_path, feed=2e5), tmp_path, TRACE_FILES)


def test_settling_time_is_the_closed_loops_slowest_decay(machine):
    """4 / (slowest decay rate) of the PD loop, from python-control's poles of
    Kc Ke / (s (tau s + 1)) under position gain Kp and speed gain Kd / Ke."""
    control = pytest.importorskip("control")
    rates = []
    for tau, Kc, Ke, Kp, Kd in zip(machine.tau, machine.Kc, machine.Ke, machine.Kp,
                                   machine.Kd):
        plant = control.tf([Kc * Ke], [tau, 1, 0])  # u [V] -> theta [pulse]
        loop = control.feedback(plant, control.tf([Kd / Ke, Kp], [1]))
        rates.append(min(-loop.poles().real))
    assert settling_time(machine) == pytest.approx(4 / min(rates), rel=1e-9)
    # SPEC section 2: X's poles are about -123 +- 400j, so about 33 ms
    assert settling_time(machine) == pytest.approx(4 / 123, rel=0.02)


def test_settle_figure_measures_from_the_path_end_for_planned(machine, tmp_path,
                                                              monkeypatch):
    """``planned``'s setpoints lead the path, so the command at the finished sample is not
    the end point: the settle figure plots the actual position minus the curve's end (in
    the report unit, mm: 1,000 pulses on the die-bonder), and its titles say the axes
    settled (the summary's settle time is finite)."""
    from nurbsmotion import plots

    seen = {}
    save = plots.figures._save

    def spy(fig, path, overwrite=True):
        if path.name == "settle.png":
            seen["titles"] = [ax.get_title(loc="left") for ax in fig.axes]
            seen["last"] = [ax.lines[0].get_ydata()[-1] for ax in fig.axes[::2]]
        return save(fig, path, overwrite)

    monkeypatch.setattr(plots.figures, "_save", spy)
    path = nm.make_die_bonder_pi()
    trace = simulate(make_interpolator("planned", path, machine, 1e6), machine)
    assert trace.metrics().settled
    plot_trace(trace, tmp_path)
    end = path.end_points[1]
    per_mm = pulses_per_report_unit(path.units, machine)
    assert per_mm == 1000.0
    assert seen["last"] == pytest.approx(list((trace.position[-1] - end) / per_mm),
                                         rel=1e-9, abs=1e-15)
    assert all("not within" not in t for t in seen["titles"][::2])


@pytest.mark.parametrize("window", [1.0, 5.0])
def test_settle_figure_draws_the_runs_settle_window(machine, tmp_path, monkeypatch, window):
    """Regression: settle.png drew a ±1 pulse band whatever window the run's settle time
    was measured with; the band, the zoom (±5 windows) and the titles follow
    ``trace.settle_window`` [pulse]."""
    import numpy as np

    from nurbsmotion import plots

    seen = {}
    save = plots.figures._save

    def spy(fig, path, overwrite=True):
        if path.name == "settle.png":
            seen["bands"] = []
            for ax in fig.axes:
                patch = ax.patches[0]
                y = patch.get_patch_transform().transform(patch.get_path().vertices)[:, 1]
                seen["bands"].append((float(np.min(y)), float(np.max(y))))
            seen["zoom"] = [ax.get_ylim() for ax in fig.axes[1::2]]
            seen["titles"] = [ax.get_title(loc="left") for ax in fig.axes]
        return save(fig, path, overwrite)

    monkeypatch.setattr(plots.figures, "_save", spy)
    path = nm.make_die_bonder_pi()
    trace = simulate(make_interpolator("planned", path, machine, 1e6), machine,
                     settle_window=window)
    assert trace.settle_window == window
    plot_trace(trace, tmp_path)
    per_mm = pulses_per_report_unit(path.units, machine)
    band = window / per_mm
    assert seen["bands"] == [pytest.approx((-band, band), rel=1e-12)] * 4
    assert seen["zoom"] == [pytest.approx((-5 * band, 5 * band), rel=1e-12)] * 2
    assert all(f"±{window:g} pulse" in t for t in seen["titles"][::2])
    assert all(f"zoom ±{5 * window:g} pulse" in t for t in seen["titles"][1::2])


def test_plot_comparisons_forked_draw_what_one_process_draws(pi_runs, machine, tmp_path):
    """plot_comparisons draws each comparison as plot_comparison does, in forked workers
    or here: the same files, pixel for pixel (here the second job is drawn on the emptied
    figures of the first, in the workers each on its own: nothing of one is left on the
    next)."""
    from nurbsmotion.plots import comparison_figures, plot_comparisons

    slow = {"taylor2": simulate(make_interpolator("taylor2", nm.make_die_bonder_pi(), machine,
                                                  5e5), machine)}
    jobs = [(pi_runs, None, "fast", {"feed": 1e6}), (slow, None, "slow", {"feed": 5e5})]
    written = {}
    for processes in (1, 2):
        out = tmp_path / str(processes)
        done = []
        files = plot_comparisons([(t, out, name, o) for t, _, name, o in jobs],
                                 processes=processes, done=done.append)
        assert done == [0, 1]
        expected = comparison_figures("fast", machine.axis_names) + comparison_figures(
            "slow", machine.axis_names)
        assert sorted(p.name for p in files) == sorted(expected)
        written[processes] = {p.name: p.read_bytes() for p in files}
    assert written[1].keys() == written[2].keys()
    differ = [name for name in written[1] if written[1][name] != written[2][name]]
    assert not differ


def test_speed_figure_has_no_inset_of_the_drive_figure(machine, tmp_path, monkeypatch):
    """Regression: the speed figure is drawn on the drive figure's emptied panels, and
    the drive figure's inset of a run that holds after it settles (its applied drive,
    "chatter RMS ... V") was left on the speed figure's panels."""
    from nurbsmotion import plots

    insets = {}
    save = plots.figures._save

    def spy(fig, path, overwrite=True):
        insets[path.name] = [ax.get_title() for a in fig.axes for ax in a.child_axes]
        return save(fig, path, overwrite)

    monkeypatch.setattr(plots.figures, "_save", spy)
    trace = run(nm.make_die_bonder_pi(), machine, 1e6, "taylor2", hold=0.05)
    assert trace.hold_samples >= 2
    plot_trace(trace, tmp_path)
    assert len(insets["drive.png"]) == 2 and all("chatter" in t for t in insets["drive.png"])
    assert insets["speed.png"] == []


def test_every_event_panel_is_on_its_rows_y_scale(machine, tmp_path, monkeypatch):
    """Regression: the first event panel ("start") had y limits of its own while its tick
    labels were hidden as if shared, so a speed of 0 at the start was drawn where the
    whole-run panel draws its minimum."""
    from nurbsmotion import plots

    limits = {}
    save = plots.figures._save

    def spy(fig, path, overwrite=True):
        rows = {}
        for ax in fig.axes:
            spec = ax.get_subplotspec()
            if spec is not None and spec.get_gridspec().ncols > 1:
                rows.setdefault(spec.rowspan.start, []).append(ax.get_ylim())
        limits[path.name] = rows
        return save(fig, path, overwrite)

    monkeypatch.setattr(plots.figures, "_save", spy)
    plot_trace(run(nm.make_die_bonder_pi(), machine, 1e6, "planned"), tmp_path)
    for name in ("speed.png", "drive.png"):
        assert limits[name], name
        for row in limits[name].values():
            assert len(row) >= 3 and all(lim == row[0] for lim in row), (name, row)
