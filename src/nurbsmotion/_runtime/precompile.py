"""A first ``run`` on an empty numba cache: the loop compiles on the other core (private).

On an empty cache, ``nurbsmotion run`` spends most of its first seconds compiling kernels,
one after the other on one core: the path's geometry, the time-optimal bound, the
interpolator's plan, the closed loop (the largest: the loop with the interpolator's step)
and the metrics. The closed loop's argument types depend only on the interpolator (not
on the path, the machine or the plan's numbers), so a second Python process (:func:`main`)
compiles it from made-up arguments of the same types (:func:`loop_example`) while the
command computes the geometry and the bound. Then the command compiles, from made-up
arguments too, the kernels it would compile after the loop's (the metrics' and
``planned``'s motion plan's: :func:`examples_here`), waits for the second process
(:meth:`Precompiler.wait`), and loads the loop from numba's cache. The two processes
compile disjoint sets of kernels, and numba writes every cache file under a temporary
name and renames it, so a reader sees a whole file or none.

Nothing is started when the loop is cached already, when numba cannot write its cache,
or with ``NUMBA_DISABLE_JIT``; the process is stopped when the command ends, however it
ends (Ctrl-C included), and, in a session of its own, it gets no Ctrl-C of the terminal.
Should anything here fail, the command compiles everything itself, as it would without.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

WAIT_LIMIT = 30.0
"""Seconds the command waits at most for the second process (then stops it and compiles
the loop itself)."""

STOP_LIMIT = 0.5
"""Seconds a stopped process gets to exit before it is killed."""


def _zeros(*shape, writeable: bool = True) -> np.ndarray:
    a = np.zeros(shape)
    a.flags.writeable = writeable
    return a


def loop_example(interpolator: str) -> tuple | None:
    """``(kernel, arguments)``: :func:`nurbsmotion.loop.closed_loop.run_samples` and made-up
    arguments of the types a run with ``interpolator`` passes (kept equal by a test), or
    ``None`` for an interpolator without one."""
    from ..loop.closed_loop import (AxisState, Block, Controller, LoopState, Scratch,
                                    Settling, TruePlant, new_rows, run_samples)
    from ..control import PID_LAW, PID_STATE
    from ..interpolators import LOOP_METHODS  # noqa: F401  (every interpolator registered)
    from ..plant import inactive_stage, new_plant_state
    from ..stepping import named

    f, n = _zeros, 2  # n_axes: any number gives the same types
    registered = named(interpolator)
    if registered is None or registered.example is None or registered.make is None:
        return None
    plan, state = registered.example(n)  # its module knows its types
    law = np.zeros(n, PID_LAW)
    law.flags.writeable = False
    ro = dict(writeable=False)
    plant = TruePlant(f(n, 2, 2, **ro), f(n, 2, **ro), f(n, **ro), inactive_stage(n),
                      new_plant_state(inactive_stage(n), f(n)))
    return run_samples, (plan, state, Controller(law, np.zeros(n, PID_STATE), True), plant,
                         f(n, **ro), Settling(f(n, **ro), 0.0, 0, 0, 0, 0), LoopState.new(),
                         AxisState(f(n), f(n), f(n)), Block(new_rows(1, n, True), 0, 0),
                         Scratch.new(n))


def examples_here(interpolator: str) -> list[tuple]:
    """``(kernel, arguments)`` pairs the command compiles before it waits for the second
    process, which it would otherwise compile after the wait: the metrics' nearest-point
    search and, for ``planned``, its motion plan's kernels; made-up arguments of the types
    a run passes (kept equal by a test)."""
    from ..interpolators.planned import blend, governor, inverse
    from ..metrics import _GridArrays, _nearest_points

    f = _zeros
    grid = _GridArrays(f(2), f(2, 1), f(2, 1), f(2, 1), f(1, 2, 2), f(1), f(2, 1), f(2, 1), 1,
                       0.0)
    pairs = [(_nearest_points, (grid, f(0, 1), f(0), f(0), np.zeros(1, np.int64)))]
    if interpolator == "planned":
        plant = inverse._InversePlant(f(1), f(1), f(1), f(1))
        sets = tuple(tuple(f(1, 1) for _ in range(3)) for _ in range(2))  # two (w, theta, u)
        pairs += [(blend._averaged_arc, (f(2), f(2), f(2), 0.0, 0, 0, f(1), f(1))),
                  (inverse._precompensate, (f(1, 1), plant, 0, 0.0, 0.0, f(1, 1), sets, f(1))),
                  (governor._support_into, (f(1, 1), f(1, 1), np.zeros(2, np.int64), 0,
                                            f(1, 1, 1)))]
    return pairs


def _signature(args) -> tuple:
    import numba

    return tuple(numba.typeof(a) for a in args)


def _missing(interpolator: str) -> bool:
    """The loop of ``interpolator`` is not in numba's cache, and the cache can be written.
    Reads numba's cache index (private API: any failure means no)."""
    import numba

    if numba.config.DISABLE_JIT:
        return False
    try:
        kernel, args = loop_example(interpolator)
        cache = kernel._cache
        cache._impl.locator.ensure_cache_path()  # OSError when not writable
        key = cache._index_key(_signature(args), kernel.targetctx.codegen())
        return key not in cache._cache_file._load_index()
    except Exception:
        return False


class Precompiler:
    """The second process of one command (a context manager: stopped on exit)."""

    def __init__(self, interpolator: str):
        self.process = None
        self.interpolator = interpolator
        if not _missing(interpolator):  # also None for an interpolator without example
            return
        package_parent = str(Path(__file__).resolve().parents[2])
        code = ("import sys; sys.path.insert(0, sys.argv[1]); "
                "from nurbsmotion._runtime.precompile import main; main(sys.argv[2])")
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-c", code, package_parent, interpolator],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL, start_new_session=True)
        except OSError:
            self.process = None

    def wait(self) -> None:
        """Compile :func:`examples_here` here, then wait until the second process has
        written the loop (at most :data:`WAIT_LIMIT`). Call it before the loop runs."""
        if self.process is None:
            return
        for kernel, args in examples_here(self.interpolator):
            kernel.compile(_signature(args))
        try:
            self.process.wait(WAIT_LIMIT)
        except subprocess.TimeoutExpired:
            pass
        self.stop()

    def stop(self) -> None:
        """Stop the process if it still runs, and reap it."""
        if self.process is None:
            return
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(STOP_LIMIT)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process = None

    def __enter__(self) -> "Precompiler":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def main(interpolator: str) -> None:
    """The second process: compile :func:`loop_example` into numba's cache."""
    kernel, args = loop_example(interpolator)
    kernel.compile(_signature(args))
