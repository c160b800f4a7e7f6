"""The one run pipeline (:class:`nurbsmotion.job.Job`) against the stages it strings
together, called one by one: the same trace, metrics, bound and summary, for a path drawn
in mm as for one in pulses, kept or streamed to sinks."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion.errors import InvalidArgumentError
from nurbsmotion.job import Job, RunResult
from nurbsmotion.loop import Sink, run
from nurbsmotion.machine import die_bonder
from nurbsmotion.metrics import RunningMetrics, trace_metrics
from nurbsmotion.planning import time_optimal_bound
from nurbsmotion.report import summary
from nurbsmotion.units import OutputUnits

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def machine():
    return die_bonder()


@pytest.fixture(scope="module")
def line_mm():
    """A 22.4-mm line drawn in mm (the die-bonder has 1-um pulses: 1000 pulse/mm)."""
    return nm.make_line([0.0, 0.0], [20.0, 10.0], units="mm")


@pytest.fixture(scope="module")
def kept(line_mm, machine):
    return Job(line_mm, machine, "0.1m/s", "paper", name="line").run()


def test_a_path_in_mm_runs_as_the_stages_one_by_one(kept, line_mm, machine):
    # the stages by hand, on the path scaled to pulses independently of the job's Scale
    pulses = line_mm.scaled(1000.0, units="pulse")
    trace = run(pulses, machine, 1e5, "paper")
    assert kept.job.pulses.units == "pulse"
    np.testing.assert_array_equal(kept.trace.position, trace.position)
    np.testing.assert_array_equal(kept.trace.drive, trace.drive)
    assert kept.bound == time_optimal_bound(pulses, machine, 1e5)
    assert kept.metrics == trace_metrics(trace)
    assert kept.summary() == summary(trace_metrics(trace), interpolator="paper", feed=1e5,
                                     machine=machine.name, path="line",
                                     time_optimal_bound=kept.bound,
                                     units=OutputUnits("mm", 1000.0, ("mm", "mm"),
                                                       np.array([1000.0, 1000.0])))
    # the end of the move back in the path's unit: the line's end, within the window
    end = kept.scale.to_report(kept.trace.position[-1])
    np.testing.assert_allclose(end, [20.0, 10.0], atol=1e-3)  # 1 pulse = 1e-3 mm


def test_units_of_the_job_and_its_summary(kept):
    assert kept.feed == 1e5  # 0.1 m/s in pulse/s
    assert kept.scale.report_unit == "mm" and kept.scale.report_factor == 1000.0
    data = kept.summary()
    assert data["length_unit"] == "mm" and data["feed_mm_per_s"] == pytest.approx(100.0)
    assert data["max_contour_error_mm"] == pytest.approx(data["max_contour_error"] / 1000)
    plain = kept.summary(in_report_unit=False)
    assert "length_unit" not in plain and plain["cycle_time_s"] == data["cycle_time_s"]
    rest = kept.at_rest_keys()
    assert rest["peak_speed_mm_per_s"]["x"] == pytest.approx(rest["peak_speed"]["x"] / 1000)


class _Collect:
    """A sink that keeps every block's positions."""

    def __init__(self):
        self.blocks, self.last = [], 0

    def add(self, first, rows, finished, last):
        assert first == sum(len(b) for b in self.blocks)  # in order, none missing
        self.blocks.append(np.array(rows.position))
        self.last += bool(last)


def test_streamed_rows_reach_every_sink_and_give_the_same_figures(kept):
    sink = _Collect()
    assert isinstance(sink, Sink)
    streamed = kept.job.run(sinks=[sink], keep_trace=False)
    assert streamed.trace is None and sink.last == 1
    np.testing.assert_array_equal(np.concatenate(sink.blocks), kept.trace.position)
    assert streamed.bound == kept.bound
    a, b = streamed.metrics, kept.metrics
    assert (a.cycle_time_s, a.steps, a.settle_time_s, a.saturated_samples) == (
        b.cycle_time_s, b.steps, b.settle_time_s, b.saturated_samples)
    assert a.max_contour_error == pytest.approx(b.max_contour_error, rel=1e-12, abs=1e-12)
    rest, kept_rest = streamed.at_rest_keys(), kept.at_rest_keys()
    assert rest.keys() == kept_rest.keys()
    for key in ("peak_speed_mm_per_s", "residual_vibration", "drive_chatter_rms"):
        assert rest[key] == pytest.approx(kept_rest[key], rel=1e-9, abs=1e-9), key


def test_a_kept_trace_reaches_the_sinks_as_one_block(kept):
    sink = _Collect()
    again = kept.job.run(sinks=[sink])
    assert len(sink.blocks) == 1 and sink.last == 1
    np.testing.assert_array_equal(sink.blocks[0], again.trace.position)


def test_running_metrics_is_a_sink_of_a_job(kept, machine):
    figures = RunningMetrics(kept.job.path, machine, settle_window=1.0)
    out = kept.job.run(sinks=[figures], keep_trace=False)
    got = figures.result(out.outcome.finished_index, out.outcome.success, out.outcome.message)
    assert got.cycle_time_s == kept.metrics.cycle_time_s


def test_a_sink_without_add_is_refused_before_any_work(kept):
    with pytest.raises(InvalidArgumentError, match="add"):
        kept.job.run(sinks=[print])


def test_a_given_bound_is_used_and_options_keep_the_converted_path(kept):
    job = kept.job.with_options(time_optimal_bound=0.5, interpolator="taylor1")
    assert job.pulses is kept.job.pulses  # no second conversion (its arc-length tables)
    assert job.bound() == 0.5
    moved = kept.job.with_options(feed="0.05m/s")
    assert moved.pulses is kept.job.pulses and moved.feed_pulses == 5e4


def test_a_feed_in_pulses_is_taken_as_it_is(line_mm, machine):
    from nurbsmotion.feed import FeedLimit

    limit = FeedLimit(np.array([0.0, 0.5, 1.0]), np.array([5e4, 1e5]))
    job = Job(line_mm, machine, (limit, "pulse"), "paper")
    assert job.feed_pulses is limit
    assert Job(line_mm, machine, limit, "paper").feed_pulses.highest == 1e8  # mm/s scaled
    with pytest.raises(InvalidArgumentError):
        Job(line_mm, machine, (limit, "mm"), "paper").feed_pulses


def test_the_package_exports_what_a_library_user_needs():
    for name in ("Machine", "run", "simulate", "Trace", "Metrics", "time_optimal_bound",
                 "Job", "RunResult"):
        assert name in nm.__all__ and getattr(nm, name) is not None
    assert nm.Job is Job and nm.RunResult is RunResult


def test_the_library_docs_job_example_runs(tmp_path, monkeypatch, capsys):
    """docs/library.md's Job block runs as written and prints what its comments say."""
    text = (ROOT / "docs" / "library.md").read_text(encoding="utf-8")
    blocks = [b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "nm.Job(" in b]
    assert len(blocks) == 1
    monkeypatch.chdir(tmp_path)
    exec(compile(blocks[0], "docs/library.md", "exec"), {})
    printed = capsys.readouterr().out.splitlines()
    promised = [re.sub(r"\s*\(.*\)$", "", p.strip())
                for p in re.findall(r"print\(.*?#\s*(.+)$", blocks[0], re.M)]
    assert printed == promised
    assert (tmp_path / "trace.csv").exists()
