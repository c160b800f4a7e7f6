"""Feeds with units: one rule for the library and the command line; report units."""

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.loop import run
from nurbsmotion.machine import die_bonder
from nurbsmotion.report import markdown_table
from nurbsmotion.units import (InvalidFeedError, feed_in_path_units, feed_in_pulses,
                               parse_feed, report_unit)

MACHINE = die_bonder(pulse_length_um=0.5)  # 2 pulses per um: conversions must use it


@pytest.mark.parametrize("feed, curve, expected", [
    (100.0, nm.make_butterfly(), 100 * 2000),  # bare number: path units (mm) per second
    ("100", nm.make_butterfly(), 100 * 2000),
    ("100mm/s", nm.make_butterfly(), 100 * 2000),
    ("6m/min", nm.make_butterfly(), 100 * 2000),
    ("1in/s", nm.make_butterfly(), 25.4 * 2000),
    ("2e5pulse/s", nm.make_butterfly(), 2e5),
    (2e5, nm.make_die_bonder_pi(), 2e5),  # a path in pulses: pulse/s
    ("0.1m/s", nm.make_die_bonder_pi(), 1e5 * 2),
])
def test_feed_in_pulses(feed, curve, expected):
    assert feed_in_pulses(feed, curve, MACHINE) == pytest.approx(expected, rel=1e-15)


def test_feed_in_path_units():
    assert feed_in_path_units("6m/min", nm.make_butterfly()) == pytest.approx(100.0)
    assert feed_in_path_units(3.0, nm.make_die_bonder_pi()) == 3.0
    assert feed_in_path_units("3pulse/s", nm.make_die_bonder_pi()) == 3.0
    with pytest.raises(InvalidFeedError, match="with a length unit"):
        feed_in_path_units("1m/s", nm.make_die_bonder_pi())
    with pytest.raises(InvalidFeedError, match="in pulse/s"):
        feed_in_path_units("1pulse/s", nm.make_butterfly())


@pytest.mark.parametrize("bad", ["-1", "0", "nan", "inf", "fast", "1furlong/s", "1m/h", None,
                                 [1.0]])
def test_bad_feeds_are_named(bad):
    with pytest.raises(InvalidFeedError, match="feed"):
        feed_in_pulses(bad, nm.make_butterfly(), MACHINE)


def test_parse_feed_rounds_trips_minutes():
    assert parse_feed("600mm/min") == (pytest.approx(1e4), "um")


def test_library_run_reads_a_feed_as_the_command_line_does():
    """run(curve_in_mm, feed=100) is 100 mm/s, the same run as "100mm/s" and as the
    path scaled to pulses at 1e5 pulse/s."""
    m = die_bonder()
    mm = nm.make_line([0.0, 0.0], [20.0, 10.0], units="mm")
    a = run(mm, m, 100.0, "taylor1", settle_time=0.0)
    b = run(mm, m, "100mm/s", "taylor1", settle_time=0.0)
    c = run(mm.scaled(1000.0, units="pulse"), m, 1e5, "taylor1", settle_time=0.0)
    for other in (b, c):
        np.testing.assert_allclose(a.position_command, other.position_command, rtol=1e-12)
    step = np.linalg.norm(np.diff(a.position_command[: a.finished_index], axis=0), axis=1)
    assert np.median(step) == pytest.approx(100.0)  # 1e5 pulse/s * 1 ms


def test_report_unit():
    assert [report_unit(u) for u in (None, "pulse", "um", "mm", "m", "in", "inch")] == [
        "mm", "mm", "mm", "mm", "mm", "in", "in"]


def test_markdown_table_gives_each_axis_its_own_column():
    rows = [{"path": "p", "interpolator": "a", "max_drive_ratio": {"x": 1.9, "y": 1.01},
             "saturated_samples": {"x": 2, "y": 1}, "length_unit": "mm",
             "max_contour_error_mm": 0.25, "max_contour_error": 250.0}]
    lines = markdown_table(rows).splitlines()
    assert lines[0] == ("| path | interpolator | max drive x / Umax | max drive y / Umax | "
                        "saturated samples x | saturated samples y | max contour [mm] | "
                        "max contour [pulse] |")
    assert lines[2] == "| p | a | 1.9 | 1.01 | 2 | 1 | 0.25 | 250 |"


# --- units.Scale: a path in any unit at the library's entry points -------------------

def _mm_line():
    return nm.make_line([0.0, 0.0], [20.0, 10.0], units="mm")


def test_scale_holds_a_factor_per_axis():
    from nurbsmotion.units import Scale

    scale = Scale.of(nm.make_butterfly(), MACHINE)  # drawn in mm; 0.5-um pulses
    np.testing.assert_array_equal(scale.pulses_per_path_unit, [2000.0, 2000.0])
    assert scale.factor == 2000.0 and scale.report_unit == "mm"
    assert scale.feed("6m/min") == pytest.approx(100 * 2000, rel=1e-15)
    assert scale.length("10um") == 20.0 and scale.length("0.5") == 1000.0
    np.testing.assert_array_equal(scale.to_report([[2000.0, 4000.0]]), [[1.0, 2.0]])
    assert scale.path(nm.make_die_bonder_pi().scaled(1.0, units="pulse")).units == "pulse"


def test_the_scale_carries_the_results_units_out():
    """:attr:`Scale.output`: the report unit of the path (inches for a path in inches,
    mm otherwise) and the machine's pulses per it, 0.5-um pulses here."""
    from nurbsmotion.units import OutputUnits, Scale

    out = Scale.of(nm.make_butterfly(), MACHINE).output
    assert isinstance(out, OutputUnits)
    assert out.unit == "mm" and out.pulses_per_unit == 2000.0 and out.axis_units == ("mm", "mm")
    assert out.length(3000.0) == 1.5 and out.factor == 1.0 / 2000.0
    inches = Scale.of(nm.make_line([0.0, 0.0], [1.0, 1.0], units="in"), MACHINE).output
    assert inches.unit == "in" and inches.pulses_per_unit == 25.4e3 / 0.5
    assert Scale.of(None, MACHINE).output.unit == "mm"  # pulses are reported in mm


def test_scale_refuses_a_length_along_axes_of_different_units():
    """A rotary axis beside linear ones (pulses per degree vs per mm): the curve scales
    axis by axis, but a feed along the path has no one factor and is refused, named."""
    from nurbsmotion.errors import InvalidArgumentError
    from nurbsmotion.units import Scale

    mixed = Scale("mm", np.array([1000.0, 1000.0, 50.0]), np.array([1.0, 1.0, 1.0]), "mm",
                  np.array([1000.0, 1000.0, 50.0]))
    with pytest.raises(InvalidArgumentError, match=r"1000.0, 1000.0, 50.0"):
        mixed.feed(100.0)
    np.testing.assert_array_equal(mixed.to_report([[1000.0, 2000.0, 50.0]]), [[1, 2, 1]])


def test_time_optimal_bound_takes_a_path_in_mm():
    """The bound of a path drawn in mm, with a bare feed in mm/s or a feed text, is the
    bound of the same path scaled to pulses by hand at the feed in pulse/s."""
    from nurbsmotion.planning import time_optimal_bound

    m = die_bonder()
    by_hand = time_optimal_bound(_mm_line().scaled(1000.0, units="pulse"), m, 1e5)
    assert time_optimal_bound(_mm_line(), m, 100.0) == pytest.approx(by_hand, rel=1e-12)
    assert time_optimal_bound(_mm_line(), m, "0.1m/s") == pytest.approx(by_hand, rel=1e-12)
    assert by_hand > 22.36 / 100.0  # the length over the feed: a lower bound [s]


def test_make_interpolator_simulate_and_running_metrics_take_a_path_in_mm():
    """simulate(make_interpolator(path in mm, feed in mm/s)) is the run of the path in
    pulses, and RunningMetrics of the mm path gives the figures of the pulse path."""
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate
    from nurbsmotion.metrics import RunningMetrics

    m = die_bonder()
    pulses = _mm_line().scaled(1000.0, units="pulse")
    a = simulate(make_interpolator("paper", _mm_line(), m, 100.0), m, settle_time=0.0)
    b = simulate(make_interpolator("paper", pulses, m, 1e5), m, settle_time=0.0)
    np.testing.assert_allclose(a.position, b.position, rtol=1e-12, atol=1e-9)
    step = np.linalg.norm(np.diff(a.position_command[: a.finished_index], axis=0), axis=1)
    assert np.median(step) == pytest.approx(100.0)  # 1e5 pulse/s * 1 ms [pulse]
    mm_metrics = RunningMetrics(_mm_line(), m, 1.0)
    assert mm_metrics.curve.units == "pulse"
    np.testing.assert_allclose(mm_metrics.end, RunningMetrics(pulses, m, 1.0).end, rtol=1e-12)
