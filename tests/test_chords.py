"""Runs of short chords joined into smooth curves within a tolerance (issue 37 item 3).

The fit is checked against an independent dense sampling: the distance of every sampled
point of the fitted curve to the chords (exact point-to-segment distance), and of every
sampled point of the chords to the curve, both at most the tolerance.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.chords import join_chords
from nurbsmotion.cli import main
from nurbsmotion.errors import InvalidArgumentError
from nurbsmotion.feed import FeedLimit

from conftest import RANDOM_SWEEPS


def cam_chords(points: np.ndarray, chord: float = 0.01, decimals: int = 4) -> np.ndarray:
    """Vertices every ``chord`` [mm] of arc length along the dense polyline ``points``,
    rounded to ``decimals`` as a CAM post writes them."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    t = np.append(np.arange(0.0, s[-1], chord), s[-1])
    V = np.column_stack([np.interp(t, s, points[:, j]) for j in range(points.shape[1])])
    return np.round(V, decimals)


def wave(n_chords: int, chord: float = 0.01) -> np.ndarray:
    """A wavy line (y = 2 sin(x / 3) mm) as ``n_chords`` CAM chords of ``chord`` mm."""
    x = np.linspace(0.0, n_chords * chord, 40 * n_chords + 1)
    return cam_chords(np.column_stack([x, 2.0 * np.sin(x / 3.0)]), chord)[:n_chords + 1]


def distance_to_segments(points: np.ndarray, V: np.ndarray, block: int = 2000) -> np.ndarray:
    """Exact distance of each point to the polyline through ``V`` (brute force)."""
    A, B = V[:-1], V[1:]
    d = B - A
    dd = np.einsum("ij,ij->i", d, d)
    out = np.empty(len(points))
    for i in range(0, len(points), block):
        p = points[i:i + block, None, :]
        t = np.clip(np.einsum("pij,ij->pi", p - A, d) / dd, 0.0, 1.0)
        out[i:i + block] = np.min(np.linalg.norm(p - (A + t[..., None] * d), axis=2), axis=1)
    return out


def dense(curve, per_span: int = 40) -> np.ndarray:
    """Points of ``curve`` at ``per_span`` even parameters in every knot span."""
    bp = curve.breakpoints
    u = np.unique(np.concatenate([np.linspace(a, b, per_span + 1) for a, b in zip(bp[:-1], bp[1:])]))
    return curve(u)


def assert_within(curve, V, tol):
    """Both directions of the Hausdorff distance between ``curve`` and the chords through
    ``V``, from dense samples of each, at most ``tol``."""
    C = dense(curve)
    gap = np.max(np.linalg.norm(np.diff(C, axis=0), axis=1))
    assert np.max(distance_to_segments(C, V)) <= tol
    # chord points, every tenth of a chord, to the densely sampled curve (its polyline is
    # within gap^2 * curvature / 8 of the curve, far below the tolerance here)
    W = np.vstack([V[:-1] + f * (V[1:] - V[:-1]) for f in np.linspace(0, 1, 11)])
    assert np.max(distance_to_segments(W, C)) <= tol + gap ** 2
    return C


@pytest.mark.parametrize("tol", [1e-3, 1e-4])
def test_a_cam_wave_becomes_one_smooth_curve_within_the_tolerance(tol):
    V = wave(600)
    chords = nm.make_polyline(V, units="mm")
    joined = join_chords(chords, tol)
    assert (joined.chords_joined, joined.runs) == (len(V) - 1, 1)
    assert joined.max_deviation <= tol
    curve = joined.curve
    assert curve.degree == 3 and curve.n_control_points < 600 / 4
    np.testing.assert_array_equal(curve([0.0, 1.0]), V[[0, -1]])
    assert curve.sharp_corners(1e-9).size == 0        # C2 inside: no corner left
    assert_within(curve, V, tol)
    assert curve.length == pytest.approx(chords.length, rel=1e-4)


def test_the_fit_is_scipys_least_squares_spline():
    """The joined curve of a CAM wave is the cubic least-squares spline of the module
    docstring's points on the chords, as scipy's QR solve (``make_lsq_spline``) gives it on
    the same knots, its end control points then set to the chords' ends."""
    from scipy.interpolate import make_lsq_spline

    V = wave(600)
    joined = join_chords(nm.make_polyline(V, units="mm"), 1e-3)
    c = np.linalg.norm(np.diff(V, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(c)])
    q = np.clip(np.ceil(4.0 * c / np.median(c)), 4, 256).astype(int)
    x = np.append(np.concatenate([s[k] + np.arange(n) / n * c[k] for k, n in enumerate(q)]),
                  s[-1])
    D = np.column_stack([np.interp(x, s, V[:, j]) for j in range(2)])
    reference = make_lsq_spline(x, D, joined.curve.knots * s[-1], k=3).c
    reference[[0, -1]] = V[[0, -1]]
    np.testing.assert_allclose(joined.curve.control_points, reference, rtol=0, atol=1e-9)  # [mm]


@pytest.mark.parametrize("seed", range(RANDOM_SWEEPS))
def test_the_banded_solve_and_its_evaluation_match_scipy(seed):
    """The fit's pieces on random uneven knots and points: the least-squares coefficients
    against scipy's QR solve, the spline and its second derivative against ``BSpline``."""
    from scipy.interpolate import BSpline, make_lsq_spline

    from nurbsmotion.chords import _combine, _cubic_basis, _least_squares, _second_derivative

    rng = np.random.default_rng(seed)
    m = int(rng.integers(20, 400))
    s = np.concatenate([[0.0], np.cumsum(rng.uniform(0.01, 1.0, m))])     # vertices
    inner = np.unique(rng.choice(np.arange(1, m), m // 5, replace=False))  # knots at some
    x = np.sort(np.concatenate([s, rng.uniform(0.0, s[-1], 8 * m)]))
    owner = np.clip(np.searchsorted(s, x, side="right") - 1, 0, m - 1)
    D = np.column_stack([np.sin(x), np.cos(2 * x)]) + 0.01 * rng.normal(size=(x.size, 2))
    t = np.concatenate([[0.0] * 4, s[inner], [s[-1]] * 4])
    first = np.searchsorted(inner, owner, side="right")
    N = _cubic_basis(t, x, first + 3)
    coef = _least_squares(N, first, D, t.size - 4)
    np.testing.assert_allclose(coef, make_lsq_spline(x, D, t, k=3).c, rtol=0, atol=1e-9)
    spline = BSpline(t, coef, 3)
    np.testing.assert_allclose(_combine(N, first, coef), spline(x), rtol=0, atol=1e-12)
    scale = np.max(np.abs(spline(x, 2)))
    np.testing.assert_allclose(_second_derivative(t, coef, x), spline(x, 2), rtol=0,
                               atol=1e-9 * scale)


def test_real_corners_stay_corners():
    """A 2 mm square of 0.01 mm chords: four runs, the square's corners kept (their turn,
    90 degrees, is never a chord joint), each within the tolerance of its chords."""
    side = np.linspace(0.0, 2.0, 201)
    zero, two = np.zeros_like(side), np.full_like(side, 2.0)
    sides = [np.column_stack(c) for c in ((side, zero), (two, side), (side[::-1], two),
                                          (zero, side[::-1]))]
    V = np.vstack([sides[0]] + [s[1:] for s in sides[1:]])
    V[1:-1] += np.random.default_rng(3).uniform(-5e-5, 5e-5, V[1:-1].shape)  # CAM rounding
    joined = join_chords(nm.make_polyline(V), 1e-3)
    assert (joined.chords_joined, joined.runs) == (800, 4)
    corners = joined.curve(joined.curve.sharp_corners(0.1))
    np.testing.assert_allclose(corners, [[2, 0], [2, 2], [0, 2]], atol=1e-4)
    assert_within(joined.curve, V, 1e-3)


def test_a_feed_change_is_a_corner_and_the_feed_follows_the_curve():
    """Chords at F1200 then F600: two runs, the feed limit's breakpoint where the first
    run ends (its share of the length), the speeds unchanged."""
    V = wave(400)
    chords = nm.make_polyline(V, units="mm")
    u_change = chords.arc_length(chords.breakpoints[250]) / chords.length
    feed = FeedLimit([0.0, chords.breakpoints[250], 1.0], [20.0, 10.0])
    joined = join_chords(chords, 1e-3, feed)
    assert joined.runs == 2
    np.testing.assert_array_equal(joined.feed.speeds, [20.0, 10.0])
    b = joined.feed.breakpoints[1]
    np.testing.assert_allclose(joined.curve(b), V[250], atol=1e-12)
    assert b == pytest.approx(u_change, abs=1e-4)


def test_long_lines_and_arcs_are_kept_as_programmed():
    """A rectangle with a rounded corner: its lines are far longer than the tolerance
    allows a joint to be rounded, the arc is no chord; nothing is joined."""
    program = "G21 G90\nG0 X0 Y0\nF600\nG1 X10\nG3 X12 Y2 I0 J2\nG1 Y10\nG1 X0\nG1 Y0\nM2\n"
    from nurbsmotion.paths.gcode import load_gcode
    import tempfile, pathlib

    with tempfile.TemporaryDirectory() as tmp:
        f = pathlib.Path(tmp) / "rect.ngc"
        f.write_text(program)
        contour = load_gcode(f).contours[0]
    joined = join_chords(contour.curve, 1e-3, contour.feed_limit)
    assert joined.chords_joined == 0 and joined.curve is contour.curve


def test_chords_among_arcs_are_joined_and_the_arcs_kept(tmp_path):
    """A G-code program: a half circle (G2), 300 chords of a wave, a long line. Lines are
    elevated beside the arc, so the chord test reads collinear control points; the arc
    and the long line are kept, the chords become one curve."""
    V = wave(300)
    lines = "".join(f"G1 X{x:.4f} Y{y:.4f}\n" for x, y in V[1:])
    end = V[-1]
    f = tmp_path / "mixed.ngc"
    f.write_text(f"G21 G90\nG0 X-2 Y0\nF600\nG2 X0 Y0 I1 J0\n{lines}G1 X{end[0] + 5:.4f} "
                 f"Y{end[1]:.4f}\nM2\n")
    from nurbsmotion.paths.gcode import load_gcode

    contour = load_gcode(f).contours[0]
    joined = join_chords(contour.curve, 1e-3, contour.feed_limit)
    # every chord joined (the long line too where its joint with the last chord is a
    # chord joint: it turns by 0.35 rad, 0.44 um from a smooth curve)
    assert joined.chords_joined >= len(V) - 1 and joined.max_deviation <= 1e-3
    new = joined.curve
    # the arc, unchanged: its midpoint on the circle of radius 1 round (-1, 0)
    u_arc = new.breakpoints[new.breakpoints > 0][0]
    mid = new(0.5 * u_arc)
    assert np.hypot(mid[0] + 1.0, mid[1]) == pytest.approx(1.0, abs=1e-12)
    assert new.length == pytest.approx(contour.curve.length, rel=1e-5)


@pytest.mark.parametrize("tol", [0.0])
def test_no_tolerance_joins_nothing(tol):
    chords = nm.make_polyline(wave(50))
    assert join_chords(chords, tol).curve is chords


@pytest.mark.parametrize("bad", [-1e-3, float("nan"), float("inf")])
def test_a_bad_tolerance_is_refused(bad):
    with pytest.raises(InvalidArgumentError, match="tolerance"):
        join_chords(nm.make_polyline(wave(10)), bad)


# ---------------------------------------------------------------- the command line
def _program(tmp_path, n=1000):
    f = tmp_path / "cam.ngc"
    V = wave(n)
    f.write_text("G21 G90 G17\nG0 X0 Y0\nF6000\n"
                 + "".join(f"G1 X{x:.4f} Y{y:.4f}\n" for x, y in V[1:]) + "M2\n")
    return f, V


def test_run_of_a_cam_program_reaches_the_feed_and_says_what_it_joined(tmp_path, capsys):
    """1,000 chords of 0.01 mm at F6000 (100 mm/s): planned ran at 2.70 x the bound on
    the chords as corners; joined, within 1.05 x a bound that is the length at the feed
    (10 mm / 100 mm/s, plus the drive-limited start and stop)."""
    f, V = _program(tmp_path)
    out = tmp_path / "run"
    assert main(["run", str(f), "--out", str(out), "--no-figures", "--quiet"]) == 0
    line = capsys.readouterr().out
    assert "path: 1,000 chords joined into 1 smooth curve within 0.001 mm" in line
    data = json.loads((out / "summary.json").read_text())
    assert data["chords_joined"] == 1000 and data["chord_runs"] == 1
    assert data["path_tolerance_mm"] == pytest.approx(1e-3)
    length = float(np.sum(np.linalg.norm(np.diff(V, axis=0), axis=1)))
    bound = data["time_optimal_bound_s"]
    assert length / 100.0 <= bound <= 1.02 * length / 100.0
    assert data["cycle_time_s"] <= 1.05 * bound
    assert sum(data["saturated_samples"].values()) == 0
    assert main(["bound", str(f), "--path-tolerance", "0"]) == 0   # the chords as corners
    assert float(capsys.readouterr().out) > 2 * bound


@pytest.mark.parametrize("interpolator", ["taylor1", "paper", "planned"])
def test_no_run_of_a_joined_program_settles_below_the_sampled_bound(tmp_path, capsys,
                                                                    interpolator):
    f, _ = _program(tmp_path, 300)
    assert main(["bound", str(f), "--sampled"]) == 0
    captured = capsys.readouterr()
    sampled = float(captured.out)
    assert "300 chords joined" in captured.err
    out = tmp_path / interpolator
    assert main(["run", str(f), "--out", str(out), "--no-figures", "--quiet",
                 "--interpolator", interpolator]) == 0
    data = json.loads((out / "summary.json").read_text())
    if sum(data["saturated_samples"].values()) == 0:
        assert data["settle_time_s"] >= sampled


def test_interpolate_reads_a_cam_program_as_run_does(tmp_path, capsys):
    """Regression (issue 37): ``interpolate`` read a CAM program's chords as programmed
    while ``run`` joins them. Its setpoints now follow the joined curve, within the
    default tolerance (1 pulse = 0.001 mm) of the chords, and it says so; with
    ``--path-tolerance 0`` nothing is joined."""
    f, V = _program(tmp_path, 300)
    out = tmp_path / "joined"
    assert main(["interpolate", str(f), "--out", str(out)]) == 0
    assert "path: 300 chords joined into 1 smooth curve within 0.001 mm" in capsys.readouterr().err
    table = np.loadtxt(out / "setpoints.csv", delimiter=",", skiprows=1)
    setpoints = table[:, 2:4]
    assert np.max(distance_to_segments(setpoints, V)) <= 1e-3 + 1e-9
    kept = tmp_path / "kept"
    assert main(["interpolate", str(f), "--out", str(kept), "--path-tolerance", "0"]) == 0
    assert "joined" not in capsys.readouterr().err


def test_the_sampled_bound_of_a_cam_program_ignores_its_feed(tmp_path, capsys):
    """``benchmarks/cam_chords.md`` lists 0.169 s as the sampled bound of 1,000 mm of
    chords at 100 mm/s, a run of 10 s: the bound is right, it ignores the feed (as
    documented): on a wave of chords it is the sampled bound of the straight line between
    its ends, the drive-limited rest-to-rest time of x (which a test checks against
    scipy's linear programming), far below the feed's bound."""
    from nurbsmotion.machine import die_bonder
    from nurbsmotion.planning import sampled_stop_bound

    f, V = _program(tmp_path, 3000)
    assert main(["bound", str(f), "--sampled"]) == 0
    sampled = float(capsys.readouterr().out)
    machine = die_bonder()
    line = nm.make_line(V[0] * 1000.0, V[-1] * 1000.0)            # [pulse]: 1 um each
    assert sampled == pytest.approx(sampled_stop_bound(line, machine), abs=1e-9)
    assert main(["bound", str(f)]) == 0
    length = float(np.sum(np.linalg.norm(np.diff(V, axis=0), axis=1)))   # [mm]
    assert float(capsys.readouterr().out) >= length / 100.0 > 10 * sampled
