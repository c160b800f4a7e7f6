"""The closed loop, sample by sample: one implementation, compiled and readable.

At sample k (t = k*Ts), for every axis (docs/model.md#chain, #servo-axis and #controllers):

1. the plant's position tha[k] is measured, and its velocity: encoder differencing
   ``(tha[k] - tha[k-1])/Ts`` or the true motor speed ``Ke*w[k]`` [pulse/s];
2. the interpolator's registered step (:func:`nurbsmotion.stepping.step`) reads them and
   the law's memory and gives the setpoint thd[k] (sample 0's is the path's start, where
   the plant rests, but for an interpolator that steers the drive from sample 0 on,
   :func:`nurbsmotion.stepping.first_sample`; once at the end, the step holds it, or goes
   on steering the plant there);
3. the law (:func:`nurbsmotion.control.pid_output`) gives the drive u[k]; the actuator
   applies ``clip(u[k], -Umax, Umax)`` over [k*Ts, (k+1)*Ts) and the plant advances
   exactly (:func:`nurbsmotion.servo.plant_step`).

The run goes on after the setpoint reaches the end until the motion has settled: at
least ``min_samples`` more samples, and until the actual position has stayed within
``window`` of the end point, with no drive beyond Umax, for ``hold_samples`` samples in a
row (:class:`Settling`); ``limit_samples`` bounds the wait, ``max_samples`` the whole run.
Every array the loop writes is one of :class:`Rows`; its own state lives in two arrays
the caller owns (:class:`LoopState`, :class:`AxisState`), so a run whose rows are full is
resumed where it stopped: on grown rows, or (a streamed run, :func:`run` with a ``sink``)
on fresh rows for the next block while the sink consumes the last one.

:func:`run_samples` is compiled by numba once per interpolator type (its plan's type) and
runs as plain Python with ``NUMBA_DISABLE_JIT=1``.

Glossary
--------
thd, tha : commanded and measured position [pulse]; u : drive [V]; w : motor speed
[rad/s]; Ke : mechanical gain [pulse/rad]; Ts : sample period [s]; Umax : drive limit [V].
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .. import stepping
from ..control.step import pid_commit, pid_output
from ..plant.sensor import measure, positions
from ..plant.stage import is_active, new_plant_state
from ..plant.step import sample_step
from ..servo.step import plant_step

__all__ = ["Rows", "Settling", "LoopState", "AxisState", "Controller", "TruePlant", "Block",
           "Scratch", "DONE", "FULL", "FAILED",
           "OUT_OF_SAMPLES", "PAUSED", "BLOCK_SAMPLES", "SINK_BLOCK_SAMPLES", "new_rows",
           "run_samples", "settle_hold_samples"]

DONE, FULL, FAILED, OUT_OF_SAMPLES, PAUSED = 0, 1, 2, 3, 4
"""Return codes of :func:`run_samples`: settled; rows full (grow them and call again);
the interpolator could not advance; ``max_samples`` (or, after the end, ``limit_samples``)
reached first; the block's last sample done (call again to go on)."""

BLOCK_SAMPLES = 1 << 16
"""Samples per call of the compiled loop: between calls Python runs, so Ctrl-C stops a
long run within one block (a few hundredths of a second)."""

SETTLE_WINDOW = 1.0
"""Default distance from the end point within which the motion counts as settled [pulse]
(the loop's settle detection and :func:`nurbsmotion.metrics.settle_time`)."""

SINK_BLOCK_SAMPLES = 1 << 14
"""Samples per block handed to a sink (:func:`run`): a few MB of rows, so that the
blocks a sink still holds (a trace writer's chunks in flight) cost little memory."""

class LoopState(NamedTuple):
    """The loop's own state, one-element arrays: the next sample, the first sample at the
    end (-1 before), the samples in a row spent settled (inside the window, every drive
    within Umax; counted from the setpoint's end), the samples in a row whose actual
    position is inside the window (counted from the start), and the curve parameter of the
    last setpoint."""

    k: np.ndarray
    finished: np.ndarray
    calm: np.ndarray
    inside: np.ndarray
    u: np.ndarray

    @classmethod
    def new(cls) -> "LoopState":
        return cls(np.zeros(1, np.int64), np.full(1, -1, np.int64), np.zeros(1, np.int64),
                   np.zeros(1, np.int64), np.zeros(1))

    @property
    def settled_index(self) -> int:
        """The first sample from which the actual position stays inside the window."""
        return int(self.k[0] - self.inside[0])


class AxisState(NamedTuple):
    """Per axis, shape (n_axes,): the plant's motor speed w [rad/s] and position [pulse]
    now, and the position measured at the previous sample [pulse]."""

    speed: np.ndarray
    position: np.ndarray
    position_prev: np.ndarray


class Rows(NamedTuple):
    """The trace, one row per sample (see :class:`nurbsmotion.loop.Trace`)."""

    u: np.ndarray               # (n,)
    feed: np.ndarray            # (n,) [pulse/s]
    status: np.ndarray          # (n,) int8, stepping.Status codes
    command: np.ndarray         # (n, n_axes) [pulse]
    position: np.ndarray        # (n, n_axes) [pulse]
    speed_command: np.ndarray   # (n, n_axes) [rad/s]
    speed: np.ndarray           # (n, n_axes) [rad/s]
    drive: np.ndarray           # (n, n_axes) [V], before the limit
    drive_applied: np.ndarray   # (n, n_axes) [V]
    bounds: np.ndarray          # (n or 0, n_axes, 2) [pulse/s]
    measured: np.ndarray        # (n or 0, n_axes) [pulse], what the controller read


class Settling(NamedTuple):
    """When a run ends (see the module docstring).

    end : ndarray, shape (n_axes,) -- the path's end point [pulse];
    window : float -- settle window, a distance to the end point [pulse];
    min_samples : int -- samples the run goes on at least after the setpoint's end;
    hold_samples : int -- samples in a row inside the window that count as settled;
    limit_samples : int -- samples after the setpoint's end the run waits at most;
    max_samples : int -- samples of the whole run at most."""

    end: np.ndarray
    window: float
    min_samples: int
    hold_samples: int
    limit_samples: int
    max_samples: int


class Controller(NamedTuple):
    """The controller as the loop runs it: the law's numbers and memory, and how it reads
    the axis's speed.

    law : ndarray, shape (n_axes,), dtype PID_LAW -- :meth:`nurbsmotion.machine.Machine.law`;
    state : ndarray, shape (n_axes,), dtype PID_STATE -- its memory, changed in place
    (:func:`nurbsmotion.control.pid_state`);
    encoder : bool -- velocity by encoder differencing (else the true speed)."""

    law: np.ndarray
    state: np.ndarray
    encoder: bool


class TruePlant(NamedTuple):
    """The true plant as the loop advances it.

    Ad, Bd : ndarray, shapes (n_axes, 2, 2), (n_axes, 2) -- its ZOH matrices
    (:class:`nurbsmotion.servo.ServoPlant`);
    Ke : ndarray, shape (n_axes,) -- its mechanical gains [pulse/rad] (its speed in
    pulse/s is ``Ke*w``);
    stage : nurbsmotion.plant.PlantStage -- its effects; when ``stage.active``, it runs in
    place of ``Ad``, ``Bd``: the controller reads what :func:`nurbsmotion.plant.measure`
    gives of the encoder's mass, the rows' ``position`` is the tool's true position and
    the settle window is judged on it;
    state : nurbsmotion.plant.PlantState -- the stage's state (unused when inactive)."""

    Ad: np.ndarray
    Bd: np.ndarray
    Ke: np.ndarray
    stage: tuple
    state: tuple


class Block(NamedTuple):
    """Where one call of :func:`run_samples` writes: ``rows`` (:class:`Rows`), ``first``
    the sample of its row 0, ``stop`` the sample before which it pauses
    (:data:`PAUSED`)."""

    rows: Rows
    first: int
    stop: int


class Scratch(NamedTuple):
    """The loop's per-sample scratch, per axis: the setpoint [pulse], the velocity the
    controller reads [pulse/s], the position it reads [pulse], shapes (n_axes,); the step's
    speed bounds [pulse/s], shape (n_axes, 2)."""

    command: np.ndarray
    velocity: np.ndarray
    position: np.ndarray
    bounds: np.ndarray

    @classmethod
    def new(cls, n_axes: int) -> "Scratch":
        return cls(np.empty(n_axes), np.empty(n_axes), np.empty(n_axes),
                   np.empty((n_axes, 2)))


def new_rows(capacity: int, n_axes: int, with_bounds: bool, with_measured: bool = False) -> Rows:
    """Uninitialised rows for ``capacity`` samples (``measured`` only for a plant whose
    reading differs from its true position: otherwise it is ``position``)."""
    shape = (capacity, n_axes)
    return Rows(np.empty(capacity), np.empty(capacity), np.empty(capacity, np.int8),
                np.empty(shape), np.empty(shape), np.empty(shape), np.empty(shape),
                np.empty(shape), np.empty(shape),
                np.empty((capacity if with_bounds else 0, n_axes, 2)),
                np.empty((capacity if with_measured else 0, n_axes)))


@njit(cache=True, nogil=True)  # a sink's thread (metrics, trace file) runs meanwhile
def run_samples(plan, state, controller, plant, start, settling, loop, axes, block, scratch):
    """Run the loop from ``loop.k[0]`` until it ends, the block's rows are full or sample
    ``block.stop`` is reached; sample k goes to row ``k - block.first``.

    Parameters
    ----------
    plan, state
        The interpolator's plan and state (:mod:`nurbsmotion.stepping`).
    controller : Controller
        The law, its memory (changed) and how it reads the speed.
    plant : TruePlant
        The true plant (its state changed).
    start : ndarray, shape (n_axes,)
        The path's start [pulse]: the setpoint of sample 0 (where the step does not give
        it, :func:`nurbsmotion.stepping.first_sample`).
    settling : Settling
    loop : LoopState
    axes : AxisState
    block : Block
        The rows written, the sample of their row 0, the sample to pause before.
    scratch : Scratch

    Returns
    -------
    int
        :data:`DONE`, :data:`FULL`, :data:`FAILED`, :data:`OUT_OF_SAMPLES` or
        :data:`PAUSED`.
    """
    # every group taken apart once: the loop below reads plain arrays and numbers
    law, law_state, encoder = controller.law, controller.state, controller.encoder
    Ad, Bd, Ke, stage, pstate = plant.Ad, plant.Bd, plant.Ke, plant.stage, plant.state
    rows, first, stop = block.rows, block.first, block.stop
    command, velocity = scratch.command, scratch.velocity
    position, bounds = scratch.position, scratch.bounds
    Ts = law[0]["period"]
    umax = law[0]["maxoutput"]
    n_axes = start.shape[0]
    k = loop.k[0]
    capacity = rows.u.shape[0]
    record_bounds = rows.bounds.shape[0] > 0
    end = settling.end
    window2 = settling.window * settling.window
    real = is_active(stage)  # a constant of the stage's type: an ideal loop has no stage
    record_measured = rows.measured.shape[0] > 0
    tool = pstate.tool
    # the stage's arrays and numbers, taken out of their tuples once (a tuple of arrays
    # passed to a function costs a reference count of each array at every call)
    P, X, origin, scratch = stage.param, pstate.x, pstate.origin, pstate.scratch
    noise, seed, counts = stage.noise, stage.seed, stage.counts
    C, F, DT, DD = stage.coef, stage.friction, stage.disturbance_time, stage.disturbance_drive
    dac_step, dac_levels, n_delay = stage.dac_step, stage.dac_levels, stage.delay_samples
    split, Tp = stage.split, stage.sample_period
    D, LINE, ND = pstate.direction, pstate.line, pstate.next_disturbance
    while True:
        if k >= settling.max_samples:
            loop.k[0] = k
            return OUT_OF_SAMPLES
        if k - first >= capacity:
            loop.k[0] = k
            return FULL
        if k >= stop:
            loop.k[0] = k
            return PAUSED
        for j in range(n_axes):
            if real:
                tool[j], reading, speed = positions(P, X, j)
                position[j] = measure(noise, seed, counts, reading, origin[j], k, j)
                if encoder:
                    velocity[j] = (position[j] - axes.position_prev[j]) / Ts
                else:
                    velocity[j] = Ke[j] * speed
                continue
            position[j] = axes.position[j]
            if encoder:
                velocity[j] = (position[j] - axes.position_prev[j]) / Ts
            else:
                velocity[j] = Ke[j] * axes.speed[j]
        if k < stepping.first_sample(plan):
            u, feed, status = 0.0, 0.0, stepping.WORKING
            for j in range(n_axes):
                command[j] = start[j]
                bounds[j, 0] = np.nan
                bounds[j, 1] = np.nan
        else:
            u, feed, status = stepping.step(plan, state, law, law_state, position, velocity,
                                            command, bounds)
            if status == stepping.FAILED:
                loop.k[0] = k
                loop.u[0] = u
                return FAILED
            if status == stepping.FINISHED and loop.finished[0] < 0:
                loop.finished[0] = k
        i = k - first
        rows.u[i] = u
        rows.feed[i] = feed
        rows.status[i] = status
        over = False
        for j in range(n_axes):
            prev_cmd = law_state[j]["prev_cmd"]
            out, e, ei, cd = pid_output(law, law_state, j, command[j], position[j],
                                        velocity[j])
            pid_commit(law, law_state, j, command[j], out, e, ei, cd)
            applied = min(max(out, -umax), umax)
            over = over or not abs(out) <= umax
            rows.command[i, j] = command[j]
            rows.position[i, j] = tool[j] if real else position[j]
            if record_measured:
                rows.measured[i, j] = position[j]
            rows.speed_command[i, j] = (command[j] - prev_cmd) / (Ke[j] * Ts)
            rows.speed[i, j] = velocity[j] / Ke[j]
            rows.drive[i, j] = out
            rows.drive_applied[i, j] = applied
            if record_bounds:
                rows.bounds[i, j, 0] = bounds[j, 0]
                rows.bounds[i, j, 1] = bounds[j, 1]
            if real:  # every axis's plant at once, below
                axes.position_prev[j] = position[j]
                continue
            w, th = plant_step(Ad, Bd, j, axes.speed[j], axes.position[j], applied)
            axes.position_prev[j] = position[j]
            axes.speed[j] = w
            axes.position[j] = th
        if real:
            sample_step(P, C, F, DT, DD, dac_step, dac_levels, n_delay, split, Tp, X, D, LINE,
                        ND, k, rows.drive_applied, i, scratch)
        loop.u[0] = u
        dist2 = 0.0
        for j in range(n_axes):
            dist2 += ((tool[j] if real else position[j]) - end[j]) ** 2
        inside = dist2 <= window2
        loop.inside[0] = loop.inside[0] + 1 if inside else 0
        if loop.finished[0] >= 0:
            if inside and not over:
                loop.calm[0] += 1
            else:
                loop.calm[0] = 0
            if (k >= loop.finished[0] + settling.min_samples
                    and loop.calm[0] >= settling.hold_samples):
                loop.k[0] = k + 1
                return DONE
            if k >= loop.finished[0] + settling.limit_samples:
                loop.k[0] = k + 1
                return OUT_OF_SAMPLES
        k += 1


def run(plan, state, law, law_state, plant, encoder: bool, start: np.ndarray,
        settling: Settling, with_bounds: bool, capacity: int, *, progress=None, sink=None):
    """:func:`run_samples` from sample 0 to the end, in blocks of :data:`BLOCK_SAMPLES`
    (:data:`SINK_BLOCK_SAMPLES` with a ``sink``).

    Parameters
    ----------
    plan, state
        The interpolator's plan and a fresh state.
    law : ndarray, shape (n_axes,), dtype PID_LAW
    law_state : ndarray, shape (n_axes,), dtype PID_STATE
        The law at rest at ``start`` (:func:`nurbsmotion.control.pid_state`); changed.
    plant : ServoPlant
        The true plant; its ``position`` (or ``start``) is where the motion starts, at rest.
    encoder : bool
    start : ndarray, shape (n_axes,)
        Setpoint of sample 0 [pulse].
    settling : Settling
    with_bounds : bool
        Record the step's speed bounds.
    capacity : int
        First guess of the number of samples (rows kept whole, without ``sink``).
    progress : callable, optional
        ``progress(k)`` with the samples run so far, after every block.
    sink : callable, optional
        ``sink(first, rows, finished, last)`` after every block: its rows (samples
        ``first`` on, arrays of their own), the first sample at the path's end so far
        (-1: not yet) and whether the run has ended. With a sink, the rows are not kept.

    Returns
    -------
    code : int
        :data:`DONE`, :data:`FAILED` or :data:`OUT_OF_SAMPLES`.
    rows : Rows or None
        The samples run (``None`` with a ``sink``).
    loop : LoopState
    """
    n_axes = start.shape[0]
    loop = LoopState.new()
    origin = np.array(start if plant.position is None else plant.position, dtype=float)
    axes = AxisState(np.zeros(n_axes), origin.copy(), origin.copy())
    stage = plant.stage()
    pstate = new_plant_state(stage, origin)
    if sink is not None:
        capacity = SINK_BLOCK_SAMPLES
    capacity = max(1, min(int(capacity), settling.max_samples))
    real = bool(is_active(stage))
    rows = new_rows(capacity, n_axes, with_bounds, real)
    controller = Controller(law, law_state, encoder)
    true_plant = TruePlant(plant.Ad, plant.Bd, plant.mechanical_gain, stage, pstate)
    scratch = Scratch.new(n_axes)
    first = 0
    while True:
        code = run_samples(plan, state, controller, true_plant, start, settling, loop, axes,
                           Block(rows, first, int(loop.k[0]) + BLOCK_SAMPLES), scratch)
        k = int(loop.k[0])
        more = code in (PAUSED, FULL)
        if sink is not None:
            sink(first, _trimmed(rows, k - first), int(loop.finished[0]), not more)
        if progress is not None:
            progress(k)
        if not more:
            break
        if sink is not None:
            first, rows = k, new_rows(capacity, n_axes, with_bounds, real)
        elif code == FULL:
            capacity = min(2 * capacity, settling.max_samples)
            rows = _grown(rows, capacity, k)
    return code, (None if sink is not None else _trimmed(rows, k)), loop


def _trimmed(rows: Rows, n: int) -> Rows:
    """The first ``n`` rows (views)."""
    return Rows(*(r[:n] if r.shape[0] else r for r in rows))


def _grown(rows: Rows, capacity: int, written: int) -> Rows:
    """The rows with room for ``capacity`` samples: the ``written`` ones copied, the rest
    uninitialised (untouched memory, so not resident until the loop writes it)."""
    def grow(r):
        if not r.shape[0]:
            return r
        new = np.empty((capacity,) + r.shape[1:], dtype=r.dtype)
        new[:written] = r[:written]
        return new
    return Rows(*(grow(r) for r in rows))


def settle_hold_samples(machine) -> int:
    """Samples a motion must stay inside the settle window to count as settled: the time
    the slowest mode of the machine's closed loop (its largest pole radius r, linear,
    sampled) takes to decay by 1000, ``ceil(ln(1e-3)/ln r)``, at least one sample."""
    r = machine.loop_pole_radius
    if r <= 0.0:
        return 1
    return max(1, int(math.ceil(math.log(1e-3) / math.log(r))))
