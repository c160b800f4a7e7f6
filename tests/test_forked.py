"""Work in forked processes (:mod:`nurbsmotion._runtime.forked`): the calls give what they
give called here, errors come back typed, a killed process's work is done here, nothing is
left running; and the command's figures, drawn by its forked worker, are pixel for pixel
the figures :func:`nurbsmotion.plots.plot_trace` draws in one process."""

from __future__ import annotations

import functools
import os
import signal
import time
from pathlib import Path

import pytest

from nurbsmotion._runtime.forked import ForkedWorker, call_forked, can_fork
from nurbsmotion.errors import InvalidArgumentError

pytestmark = pytest.mark.skipif(not can_fork(), reason="the platform does not fork")


def _square(x: int) -> int:
    return x * x


def _pid_after(seconds: float) -> int:
    time.sleep(seconds)
    return os.getpid()


def _fail(x: int) -> int:
    raise InvalidArgumentError(f"bad value {x}")


def _identity_check(obj, holder, x):
    """Whether ``obj`` is ``holder[0]`` (a shared object sent twice stays one object)."""
    return obj is holder[0], obj["prepared_in"], os.getpid(), x


def _gone(pid: int) -> bool:
    """No process ``pid``, or a zombie that nobody has reaped yet."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] in "ZX"
    except FileNotFoundError:
        return True


@pytest.mark.parametrize("processes", [1, 2, 3])
def test_call_forked_gives_the_results_in_order(processes):
    calls = [functools.partial(_square, x) for x in range(7)]
    assert call_forked(calls, processes) == [x * x for x in range(7)]


def test_call_forked_shares_the_calls_between_processes():
    """Each process takes the next call when it is free: with calls that wait, the forked
    process takes some (which pids, not how long: no timing is asserted)."""
    pids = call_forked([functools.partial(_pid_after, 0.2) for _ in range(4)], 2)
    assert os.getpid() in pids and len(set(pids)) == 2


def test_call_forked_raises_the_first_error_typed_with_the_forked_traceback():
    calls = [functools.partial(_pid_after, 0.2), functools.partial(_fail, 1),
             functools.partial(_fail, 2)]
    with pytest.raises(InvalidArgumentError, match="bad value 1") as info:
        call_forked(calls, 2)
    assert info.value.__notes__ and "_fail" in info.value.__notes__[0]


def test_call_forked_calls_here_what_a_killed_process_took():
    """A forked process ended before it reported (killed): its calls are made here."""
    parent = os.getpid()

    def die_if_forked(x):
        if os.getpid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)
        return x

    calls = [functools.partial(_pid_after, 0.3)] + [functools.partial(die_if_forked, x)
                                                    for x in range(3)]
    results = call_forked(calls, 2)
    assert results[1:] == [0, 1, 2]


@pytest.mark.parametrize("processes", [1, 2])
def test_call_forked_says_done_in_order(processes):
    """``done(index)`` once every call up to ``index`` has returned, in order, whichever
    process made it (a progress bar)."""
    said = []
    calls = [functools.partial(_pid_after, 0.05 * (x % 3)) for x in range(6)]
    call_forked(calls, processes, done=said.append)
    assert said == list(range(6))


def _frozen_in() -> tuple[int, int]:
    import gc

    time.sleep(0.1)
    return os.getpid(), gc.get_freeze_count()


def test_forking_freezes_for_the_child_only():
    """What exists at the fork is frozen for the forked process's garbage collector (it
    neither traverses nor copies what it inherits); the caller's is as it was, during the
    calls and after."""
    import gc

    assert gc.get_freeze_count() == 0
    for pid, frozen in call_forked([_frozen_in] * 4, 2):
        assert (frozen > 0) == (pid != os.getpid())
    assert gc.get_freeze_count() == 0


def _count_steps(state):
    return state["steps"]


def test_worker_stops_preparing_when_the_call_arrives():
    """A ``prepare`` that yields is advanced step by step until the call is there: the
    call runs after a few of its 10,000 steps, not all (each step waits 0.05 s: all of
    them would take over 8 minutes)."""
    state = {"steps": 0}

    def prepare():
        for _ in range(10_000):
            state["steps"] += 1
            yield
            time.sleep(0.05)

    with ForkedWorker(prepare, shared=[state]) as worker:
        worker.submit(_count_steps, state)
        steps = worker.result()
    assert 1 <= steps < 10_000


def test_worker_runs_the_call_on_what_it_prepared():
    """``prepare`` runs in the worker; the shared object arrives as the very object the
    worker prepared (its caches included), not a copy."""
    state = {"prepared_in": None}

    def prepare():
        state["prepared_in"] = os.getpid()

    with ForkedWorker(prepare, shared=[state]) as worker:
        assert worker.pid not in (None, os.getpid())
        worker.submit(_identity_check, state, [state], 5)
        same, prepared_in, ran_in, x = worker.result()
    assert same and prepared_in == ran_in != os.getpid() and x == 5
    assert state["prepared_in"] is None  # nothing of it here


def test_worker_raises_the_calls_error():
    with ForkedWorker() as worker:
        worker.submit(_fail, 3)
        with pytest.raises(InvalidArgumentError, match="bad value 3"):
            worker.result()


def test_a_killed_worker_leaves_the_call_to_this_process():
    with ForkedWorker(functools.partial(time.sleep, 30)) as worker:
        os.kill(worker.pid, signal.SIGKILL)
        worker.submit(_square, 4)
        assert worker.result() == 16


def test_a_call_that_does_not_pickle_runs_here():
    with ForkedWorker() as worker:
        worker.submit(lambda: os.getpid())
        assert worker.result() == os.getpid()


def test_without_a_process_the_call_runs_here():
    worker = ForkedWorker(enabled=False)
    assert worker.pid is None
    worker.submit(os.getpid)
    assert worker.result() == os.getpid()


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_stop_ends_the_worker_and_what_it_forked():
    """Stopped (a failed or interrupted command), the worker and the processes it forked
    (the second drawing process) are gone: they share its process group."""
    read, write = os.pipe()

    def prepare():
        os.close(read)
        child = os.fork()
        if child == 0:
            time.sleep(60)
            os._exit(0)
        os.write(write, f"{child}\n".encode())
        time.sleep(60)

    worker = ForkedWorker(prepare)
    os.close(write)
    with os.fdopen(read) as f:
        grandchild = int(f.readline())
    pid = worker.pid
    worker.stop()
    assert worker.pid is None and _gone(pid)
    deadline = time.monotonic() + 10
    while not _gone(grandchild) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _gone(grandchild)


def test_run_figures_are_those_drawn_in_one_process(tmp_path, monkeypatch):
    """``nurbsmotion run`` draws its figures in its forked worker, prepared before the
    run (:func:`nurbsmotion.plots.prepare_trace`: made-ahead figures, the path's data) and
    shared with a second process: the files are pixel for pixel those the same command
    draws here, in one process, without preparing."""
    import numpy as np
    from PIL import Image

    from nurbsmotion.cli import commands, main
    from nurbsmotion.plots import TRACE_FIGURES

    argv = ["run", "die-bonder-pi", "--feed", "1m/s", "--quiet", "--no-trace", "--out"]
    assert main(argv + [str(tmp_path / "forked")]) == 0
    monkeypatch.setattr(commands, "ForkedWorker",
                        lambda *args, **kwargs: ForkedWorker(enabled=False))
    monkeypatch.setattr(commands, "usable_cpus", lambda: 1)
    assert main(argv + [str(tmp_path / "here")]) == 0
    for name in TRACE_FIGURES:
        forked, here = (np.asarray(Image.open(tmp_path / d / name)) for d in ("forked", "here"))
        assert np.array_equal(forked, here), name


def test_a_figure_error_in_the_worker_is_the_commands_one_line(tmp_path, capsys,
                                                              monkeypatch):
    """An error while the worker draws is the command's error (one line, exit 2) and
    nothing is written."""
    from nurbsmotion.cli import main
    from nurbsmotion.plots import figures

    def fail(*args, **kwargs):
        raise InvalidArgumentError("planted figure failure")

    monkeypatch.setattr(figures, "_settle_figure", fail)  # the fork inherits it
    out = tmp_path / "new"
    assert main(["run", "die-bonder-pi", "--feed", "1m/s", "--quiet", "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["nurbsmotion run: error: planted figure failure"]
    assert not out.exists()


def _children(pid: int) -> list[int]:
    """The processes ``pid`` forked and their own, from /proc (Linux)."""
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            with open(f"/proc/{p}/task/{p}/children") as f:
                kids = [int(k) for k in f.read().split()]
        except OSError:
            kids = []
        found += kids
        todo += kids
    return found


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs Linux /proc")
def test_ctrl_c_while_the_figures_are_drawn_ends_every_process(tmp_path):
    """Interrupted once its summary is written (the figures being drawn by its worker),
    the command exits 130 with its one line, writes nothing, and its worker and the
    worker's second process are gone with it."""
    import subprocess
    import sys

    from conftest import source_env

    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "nurbsmotion", "run", "die-bonder-pi",
                             "--feed", "1m/s", "--out", str(out)], env=source_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    workers: list[int] = []
    try:
        while proc.poll() is None and not list(out.glob(".nurbsmotion-*/summary.json")):
            workers = _children(proc.pid) or workers
            time.sleep(0.005)
        workers = _children(proc.pid) or workers
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    if proc.returncode == 0:
        pytest.skip("the command ended before it could be interrupted")
    assert workers, "no figure worker was seen"
    assert proc.returncode == 130
    assert err.strip().splitlines() == ["nurbsmotion run: interrupted; no output was written"]
    assert not out.exists()
    deadline = time.monotonic() + 10
    while not all(_gone(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(_gone(p) for p in workers)
