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
