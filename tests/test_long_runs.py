"""Long runs (issue 13 items 4 and 5): Ctrl-C during a run, the blocked closed loop."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion import cli
from nurbsmotion.loop import closed_loop
from nurbsmotion.loop import run
from nurbsmotion.machine import die_bonder

SRC = Path(__file__).resolve().parents[1] / "src"


def test_ctrl_c_inside_a_compiler_callback_is_retried_not_raised():
    """Raised inside a ctypes callback of llvmlite it would be printed and dropped: the
    handler arms a short timer instead; anywhere else it raises KeyboardInterrupt."""
    inside = {"__name__": "llvmlite.binding.executionengine", "cli": cli, "signal": signal,
              "sys": sys}
    try:
        exec("cli._interrupt(signal.SIGINT, sys._getframe())", inside)
        assert signal.getitimer(signal.ITIMER_REAL)[0] > 0
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    with pytest.raises(KeyboardInterrupt):
        cli._interrupt(signal.SIGINT, sys._getframe())


@pytest.mark.skipif(not hasattr(signal, "SIGINT") or os.name != "posix", reason="POSIX")
@pytest.mark.parametrize("signum", ["SIGINT", "SIGTERM"])
def test_sigint_during_a_long_run_exits_130_with_one_line_and_writes_nothing(tmp_path,
                                                                             signum):
    """The command is interrupted (Ctrl-C, or SIGTERM from a machine shutting down) once
    its work has started (its staging folder exists): exit code 130, one line on stderr,
    and the output folder keeps only what was there."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("keep")
    feed = f"{nm.make_butterfly().length / 120.0!r}mm/s"   # a 2-minute move
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(SRC)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    proc = subprocess.Popen([sys.executable, "-m", "nurbsmotion.cli", "run", "butterfly",
                             "--feed", feed, "--no-figures", "--out", str(out)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        while proc.poll() is None and not any(p.name.startswith(".nurbsmotion-")
                                              for p in out.iterdir()):
            time.sleep(0.01)
        proc.send_signal(getattr(signal, signum))
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert err.strip().splitlines() == ["nurbsmotion run: interrupted; no output was written"]
    assert sorted(os.listdir(out)) == ["notes.txt"]


def test_the_loop_in_blocks_equals_one_call(monkeypatch):
    """The compiled loop returns to Python every BLOCK_SAMPLES samples (so Ctrl-C is
    seen); a run paused every 7 samples equals one that is not."""
    curve = nm.make_die_bonder_pi()
    m = die_bonder()
    whole = run(curve, m, 5e5, "planned")
    monkeypatch.setattr(closed_loop, "BLOCK_SAMPLES", 7)
    blocks = run(curve, m, 5e5, "planned")
    for name in ("u", "position_command", "position", "drive", "drive_applied", "feed",
                 "status"):
        np.testing.assert_array_equal(getattr(whole, name), getattr(blocks, name))
    assert whole.settled_index == blocks.settled_index


def test_open_loop_interpolation_in_blocks_equals_one_call(monkeypatch):
    """``interpolate`` also runs its compiled steps a block at a time; the series is the
    same as in one call (and across the growth of its rows)."""
    from nurbsmotion.interpolators import make_open_loop
    from nurbsmotion.loop import interpolate

    curve = nm.make_butterfly()
    whole = interpolate(make_open_loop("taylor2", curve, 1e-3, 50.0))
    monkeypatch.setattr(closed_loop, "BLOCK_SAMPLES", 5)
    blocks = interpolate(make_open_loop("taylor2", curve, 1e-3, 50.0))
    for name in ("u", "position", "feed"):
        np.testing.assert_array_equal(getattr(whole, name), getattr(blocks, name))
    assert whole.finished_index == blocks.finished_index


def test_the_loop_reports_its_progress_after_every_block(monkeypatch):
    """``progress(k)`` after each block: increasing sample counts ending at the run's."""
    monkeypatch.setattr(closed_loop, "BLOCK_SAMPLES", 50)
    seen = []
    tr = run(nm.make_die_bonder_pi(), die_bonder(), 5e5, "planned", progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == len(tr.t)
    assert seen[:-1] == list(range(50, len(tr.t), 50))


def _same_figures(a: dict, b: dict) -> None:
    """Equal figures: counts and maxima exactly, sums (RMS) to rounding."""
    assert a.keys() == b.keys()
    for key, x in a.items():
        y = b[key]
        if isinstance(x, dict):
            for axis in x:
                assert y[axis] == pytest.approx(x[axis], rel=1e-12, abs=1e-300), (key, axis)
        elif isinstance(x, float):
            assert y == pytest.approx(x, rel=1e-12, abs=1e-300), key
        else:
            assert y == x, key


STREAMED_CASES = [  # sharp corners; a closed path passing near itself; end overshoot
    ("die-bonder-pi", 1e6, "planned"),
    ("butterfly", 5e4, "paper"),
    ("butterfly", 5e4, "taylor2"),
]


@pytest.mark.parametrize("name, feed, method", STREAMED_CASES)
def test_a_streamed_run_gives_the_figures_and_file_of_the_whole_run(
        tmp_path, monkeypatch, name, feed, method):
    """Blocks of 13 samples through :class:`RunningMetrics` and :class:`TraceWriter` give
    the figures :func:`trace_metrics` takes from the whole trace, and the trace file
    :func:`write_trace` writes from it, byte for byte (every 4th row, and every row)."""
    from nurbsmotion import report
    from nurbsmotion.loop import run_streamed
    from nurbsmotion.metrics import RunningMetrics

    from nurbsmotion.units import OutputUnits

    curve, m = nm.builtin_path(name), die_bonder()
    mm = OutputUnits("mm", 1000.0, ("mm", "mm"), np.array([1000.0, 1000.0]))  # 1-um pulses
    whole = run(curve, m, feed, method)
    monkeypatch.setattr(closed_loop, "SINK_BLOCK_SAMPLES", 13)
    running = RunningMetrics(whole.curve, m, whole.settle_window)
    blocks = []
    files = {}
    with contextlib.ExitStack() as stack:
        writers = [stack.enter_context(report.TraceWriter(
            tmp_path / f"s{every}.{fmt}", m, fmt=fmt, every=every, units=mm))
            for fmt in report.TRACE_FORMATS for every in (1, 4)]

        def sink(first, rows, finished, last):
            blocks.append((first, len(rows.u), finished, last))
            running.add(first, rows, finished, last)
            for w in writers:
                w.add(first, rows, finished, last)

        outcome = run_streamed(curve, m, feed, sink, method)
    assert outcome.n_samples == len(whole.t) and outcome.message == whole.message
    assert outcome.finished_index == whole.finished_index
    assert [b[0] for b in blocks] == list(range(0, len(whole.t), 13))
    assert [b[3] for b in blocks] == [False] * (len(blocks) - 1) + [True]
    _same_figures(whole.metrics().to_dict(),
                  running.result(outcome.finished_index, outcome.success,
                                 outcome.message).to_dict())
    for fmt in report.TRACE_FORMATS:
        for every in (1, 4):
            files = report.write_trace(whole, tmp_path / f"w{every}.{fmt}", fmt=fmt,
                                       every=every, units=mm)
            if fmt == "csv":
                assert (tmp_path / f"s{every}.csv").read_bytes() == files.read_bytes()
            else:
                import pyarrow.parquet as pq

                a, b = pq.read_table(tmp_path / f"s{every}.parquet"), pq.read_table(files)
                assert a.column_names == b.column_names
                np.testing.assert_array_equal(  # NaN where the bound was not computed
                    np.column_stack([c.to_numpy() for c in a.columns]),
                    np.column_stack([c.to_numpy() for c in b.columns]))


def test_a_streamed_run_keeps_no_rows_and_refuses_a_bad_sink():
    from nurbsmotion.errors import InvalidArgumentError
    from nurbsmotion.loop import run_streamed

    sizes = []
    out = run_streamed(nm.make_die_bonder_pi(), die_bonder(), 1e6,
                       lambda first, rows, finished, last: sizes.append(len(rows.u)),
                       "planned")
    assert sum(sizes) == out.n_samples and max(sizes) <= closed_loop.SINK_BLOCK_SAMPLES
    assert out.cycle_time == out.finished_index * die_bonder().sample_period
    with pytest.raises(InvalidArgumentError, match="sink"):
        run_streamed(nm.make_die_bonder_pi(), die_bonder(), 1e6, "not callable")


def test_a_failing_sink_leaves_no_trace_file(tmp_path, monkeypatch):
    """A writer whose run raises (disk full, Ctrl-C) removes its temporary file."""
    from nurbsmotion import report
    from nurbsmotion.loop import run_streamed

    m = die_bonder()
    monkeypatch.setattr(closed_loop, "SINK_BLOCK_SAMPLES", 50)

    def sink(first, rows, finished, last):
        writer.add(first, rows, finished, last)
        if first > 0:
            raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        with report.TraceWriter(tmp_path / "trace.csv", m) as writer:
            run_streamed(nm.make_die_bonder_pi(), m, 1e6, sink, "paper")
    assert os.listdir(tmp_path) == []


def test_ctrl_c_while_the_command_loads_ends_with_one_line():
    """The command's entry point imports the command line inside its own handler: a
    Ctrl-C while numpy and numba load exits 130 with one line, no traceback."""
    script = (
        "import sys\n"
        "class Interrupt:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'nurbsmotion.cli':\n"
        "            raise KeyboardInterrupt\n"
        "sys.meta_path.insert(0, Interrupt())\n"
        "sys.argv = ['nurbsmotion', 'run', 'butterfly']\n"
        "from nurbsmotion.__main__ import main\n"
        "sys.exit(main())\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(SRC)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 130
    assert done.stderr.strip().splitlines() == [
        "nurbsmotion run: interrupted; no output was written"]


@pytest.mark.skipif(not sys.platform.startswith("linux")
                    or __import__("platform").libc_ver()[0] != "glibc",
                    reason="malloc_trim is glibc's")
def test_the_plans_freed_temporaries_go_back_to_the_system(monkeypatch):
    """glibc keeps large freed blocks on its heap once its mmap threshold has risen; the
    ``planned`` interpolator hands its plan's temporaries back (``malloc_trim``, found
    on glibc) once the plan is built, before the run. The effect on the resident set is
    measured by ``benchmarks/long_run.py`` (the 10-minute move's peak: 297 -> 275 MB),
    not here: it depends on the heap's history."""
    from nurbsmotion._runtime import memory as _memory
    from nurbsmotion.interpolators.planned import interpolator

    assert _memory.release_freed_memory()
    calls = []
    monkeypatch.setattr(interpolator, "release_freed_memory", lambda: calls.append(1) or True)
    interpolator.PlannedInterpolator(nm.make_line([0.0, 0.0], [500.0, 0.0]), die_bonder(), 1e5)
    assert calls == [1]
