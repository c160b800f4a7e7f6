"""Long runs (issue 13 items 4 and 5): Ctrl-C during a run, the blocked closed loop."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion import cli, closed_loop
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
def test_sigint_during_a_long_run_exits_130_with_one_line_and_writes_nothing(tmp_path):
    """The command is interrupted once its work has started (its staging folder exists):
    exit code 130, one line on stderr, and the output folder keeps only what was there."""
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
        proc.send_signal(signal.SIGINT)
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
