"""Runs of an interpolator: in the closed loop of a machine, to the end and settled
(:func:`simulate` -> :class:`Trace`; streamed block by block to a sink without keeping
the rows, :func:`simulate_streamed` -> :class:`RunOutcome`), or open loop
(:func:`interpolate` -> :class:`SetpointSeries`).

:func:`simulate` builds the run from data: the interpolator's plan and a fresh state, the
machine's control law (:meth:`nurbsmotion.machine.Machine.law`) and the true plant's ZOH
matrices, and runs :func:`nurbsmotion.loop.closed_loop.run_samples` (measure, step, law, clip,
plant; docs/model.md#chain and #controllers) until the setpoint has reached the end and the motion has
settled there. It changes none of the objects it is given.

The package holds the results (:mod:`.trace`: :class:`Trace`, :class:`RunOutcome`,
:class:`SetpointSeries`), the compiled loop itself (:mod:`.closed_loop`), the work
estimates a run is refused by (:mod:`.budget`) and the protocol of what takes the rows
of a streamed run (:mod:`.sink`); every name is re-exported here.
"""

from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np

from numba import njit

from .. import stepping
from . import closed_loop
from .closed_loop import settle_hold_samples
from .budget import MAX_SAMPLES, check_samples, estimate_samples
from ..control import PidGains, pid_law, pid_state
from ..errors import InfeasibleError, InvalidArgumentError, WorkLimitError
from ..feed import FeedLimit
from ..interpolators import DEFAULT_INTERPOLATOR, Interpolator, make_interpolator
from ..machine import Machine
from ..nurbs import NurbsCurve
from ..planning import check_feed_reachable, check_path_size
from ..servo import ServoPlant
from ..stepping import Status
from ..units import Scale
from .sink import Sink, fan_out
from .trace import RunOutcome, SetpointSeries, Trace

SETTLE_TIME = 0.05
"""Default least time a run goes on holding the end point [s] (:func:`simulate`)."""

SETTLE_LIMIT = 10.0
"""Default longest wait for the motion to settle after the setpoint reached the end [s]."""

HOLD_TIME = 0.3
"""Default time a run on a true plant with any effect of the machine as it is
(:mod:`nurbsmotion.plant`) goes on after it has settled, so that what happens at rest
(hunting, a limit cycle, a stuck axis) is seen [s]; 0 on an ideal plant."""

MAX_HOLD_SAMPLES = 2 ** 53
"""Most samples a run may hold after it settles (the loop counts samples in int64, and a
float holds every integer up to it); commands refuse far less, by ``--max-samples``."""

__all__ = ["Trace", "RunOutcome", "SetpointSeries", "simulate", "simulate_streamed",
           "background_sink", "interpolate", "run", "run_streamed", "to_pulses",
           "settle_hold_samples", "check_run_arguments", "hold_samples_of", "Sink", "fan_out"]


def to_pulses(curve: NurbsCurve, machine: Machine) -> NurbsCurve:
    """The path in the machine's pulses (a path in ``"mm"`` is scaled by pulses per mm;
    :meth:`nurbsmotion.units.Scale.path`)."""
    return Scale.of(curve, machine).path(curve)



@njit(cache=True)
def _run_open_loop(plan, state, law, law_state, us, feeds, positions, velocity, bounds):
    """Steps 1, 2, ... into rows ``us``, ``feeds``, ``positions`` (row 0 is the start)
    until the end or the rows are full; returns the rows written, or ``-k`` when step k
    failed."""
    n = us.shape[0]
    for k in range(1, n):
        u, feed, status = stepping.step(plan, state, law, law_state, positions[k - 1],
                                        velocity, positions[k], bounds)
        us[k] = u
        feeds[k] = feed
        if status == stepping.FAILED:
            return -k
        if status == stepping.FINISHED:
            return k + 1
    return n


def interpolate(interpolator: Interpolator, max_samples: int = 10_000_000) -> SetpointSeries:
    """Run an interpolator open loop (no loop state) from the start to the end of its path.

    An interpolator that reads the loop state (``paper``) sees a law with no gains and an
    axis that follows its setpoint exactly.

    Raises
    ------
    InvalidArgumentError
        If the interpolator has no setpoint stream without a loop (``planned``: its
        setpoints invert the loop's law; :func:`simulate` runs it).
    InfeasibleError
        If the interpolator cannot advance, or the end is not reached within
        ``max_samples`` samples.
    """
    if not interpolator.open_loop:
        raise InvalidArgumentError(
            f"the {interpolator.name} interpolator has no setpoints without a servo loop "
            "(they invert the loop's law): run it with simulate() or `nurbsmotion run`")
    curve = interpolator.curve
    Ts = interpolator.sample_period
    duration = interpolator.nominal_duration()
    guess = max_samples if duration is None else int(1.2 * duration / Ts) + 64
    capacity = max(2, min(guess, max_samples + 1))
    n_axes = curve.n_axes
    law = pid_law([PidGains()] * n_axes, math.inf, Ts, False)
    start = curve.end_points[0]
    state = interpolator.new_state()
    law_state = pid_state(start)
    velocity = np.zeros(n_axes)
    bounds = np.empty((n_axes, 2))
    us, feeds = np.zeros(capacity), np.zeros(capacity)
    positions = np.empty((capacity, n_axes))
    positions[0] = start
    done, k0 = 0, 1
    while True:
        # one block of rows per compiled call, so that Ctrl-C is seen between blocks
        end = min(capacity, k0 - 1 + closed_loop.BLOCK_SAMPLES)
        n = _run_open_loop(interpolator.plan, state, law, law_state, us[k0 - 1:end],
                           feeds[k0 - 1:end], positions[k0 - 1:end], velocity, bounds)
        if n < 0:
            raise InfeasibleError(f"{interpolator.name} interpolator cannot advance from "
                                  f"u = {us[k0 - 2 - n]:.9g}")
        done = k0 - 1 + n
        if done < end:
            break
        if end < capacity:
            k0 = end
            continue
        if capacity > max_samples:
            raise InfeasibleError(
                f"interpolation did not reach the end within {max_samples} samples "
                f"(u = {us[-1]:.6g}); the feed is too low for this path")
        k0 = capacity
        capacity = min(2 * capacity, max_samples + 1)
        us = np.resize(us, capacity)
        feeds = np.resize(feeds, capacity)
        positions = np.resize(positions, (capacity, n_axes))
    return SetpointSeries(t=np.arange(done) * Ts, u=us[:done].copy(),
                          position=positions[:done].copy(), feed=feeds[:done].copy(),
                          sample_period=Ts, finished_index=done - 1)


def simulate(
    interpolator: Interpolator,
    machine: Machine,
    *,
    plant: ServoPlant | None = None,
    settle_time: float = SETTLE_TIME,
    settle_window: float = closed_loop.SETTLE_WINDOW,
    settle_limit: float = SETTLE_LIMIT,
    max_samples: int | None = None,
    progress=None,
    hold: float | None = None,
) -> Trace:
    """Run the closed loop from the path's start until the motion has settled at its end.

    Parameters
    ----------
    interpolator : Interpolator
        Any stepper; its curve must be in pulses (see :func:`to_pulses`).
    machine : Machine
        The controller: its law, Umax and Ts (and the model the interpolator planned with).
    plant : ServoPlant, optional
        The true plant, when it differs from the model (e.g. tau and Kc off by 20 %);
        the machine's own by default. It starts at rest at its ``position`` (the path's
        start by default).
    settle_time : float
        The least time the run goes on holding the end point [s].
    settle_window : float
        The motion has settled once the actual position stays within this distance of the
        end point [pulse], with no drive beyond Umax, for :func:`settle_hold_samples`
        samples in a row; the run ends there (and not before ``settle_time``).
    settle_limit : float
        The longest time the run waits for that after the setpoint reached the end [s]; a
        motion that has not settled by then ends the trace with ``success=False``.
    max_samples : int, optional
        Safety limit against a stalled interpolator; by default twenty times the
        interpolator's :meth:`~nurbsmotion.interpolators.Interpolator.nominal_duration`
        plus ten seconds (or, where it has none, ten times the time at the slowest
        axis's full-drive speed plus ten seconds), plus ``settle_limit``.
    progress : callable, optional
        ``progress(k)`` with the samples run so far, every
        :data:`nurbsmotion.loop.closed_loop.BLOCK_SAMPLES` samples (a progress bar).
    hold : float, optional
        How long the run goes on after it has settled [s] (still within
        ``settle_limit``); by default :data:`HOLD_TIME` where the true plant has any
        effect of the machine as it is, else 0 (an ideal run is unchanged).

    Returns
    -------
    Trace

    Raises
    ------
    InfeasibleError
        If the interpolator cannot advance, or the end is not reached in ``max_samples``.
    """
    outcome, rows, _ = _closed_loop(interpolator, machine, None, plant=plant,
                                    settle_time=settle_time, settle_window=settle_window,
                                    settle_limit=settle_limit, max_samples=max_samples,
                                    progress=progress, hold=hold)
    return _trace(outcome, rows, interpolator.records_bounds)


def _trace(outcome: RunOutcome, rows: closed_loop.Rows, with_bounds: bool) -> Trace:
    return Trace(
        position_measured=rows.measured if rows.measured.shape[0] else None,
        **outcome.__dict__,  # RunOutcome's fields (a plain dataclass: no slots)
        t=np.arange(outcome.n_samples) * outcome.machine.sample_period, u=rows.u,
        position_command=rows.command, position=rows.position,
        speed_command=rows.speed_command, speed=rows.speed, drive=rows.drive,
        drive_applied=rows.drive_applied, feed=rows.feed,
        speed_bounds=rows.bounds if with_bounds else None, status=rows.status)


def simulate_streamed(interpolator: Interpolator, machine: Machine, sink,
                      **options) -> RunOutcome:
    """:func:`simulate`, handing the rows to ``sink`` block by block instead of keeping
    them: the memory a run needs does not grow with its length.

    Parameters
    ----------
    interpolator, machine
        As in :func:`simulate`.
    sink : callable
        ``sink(first, rows, finished, last)`` after every
        :data:`nurbsmotion.loop.closed_loop.SINK_BLOCK_SAMPLES` samples: the block's rows
        (:class:`nurbsmotion.loop.closed_loop.Rows`, samples ``first`` on, arrays of their own),
        the first sample whose setpoint is the path's end (-1 while there is none) and
        whether this is the run's last block.
    **options
        As in :func:`simulate` (``plant``, ``settle_time``, ``settle_window``,
        ``settle_limit``, ``max_samples``, ``progress``; ``progress`` is called after every
        block of the sink's size).

    Returns
    -------
    RunOutcome
    """
    if not callable(sink):
        raise InvalidArgumentError(f"sink must be callable, got {sink!r:.60}")
    return _closed_loop(interpolator, machine, sink, **options)[0]


@contextmanager
def background_sink(sink):
    """``sink`` on one thread of its own, a block behind the loop: the compiled loop and
    the search of the metrics release the GIL, so a sink that gathers figures or writes a
    file costs hardly any time beside the loop. Blocks are taken in order, at most one
    waits; leaving the ``with`` waits for the last one (on an error, the ones not yet
    taken are dropped).

    Yields the callable to give :func:`simulate_streamed` or :func:`run_streamed`.
    """
    from concurrent.futures import ThreadPoolExecutor

    # One thread: every thread that allocates gets a malloc arena of its own (~10 MB more
    # at the peak of a long run).
    pool = ThreadPoolExecutor(1)
    previous = None

    def handoff(first, rows, finished, last):
        nonlocal previous
        submitted = pool.submit(sink, first, rows, finished, last)
        if previous is not None:
            previous.result()
        previous = submitted

    try:
        yield handoff
        if previous is not None:
            previous.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


class _Tally:
    """Counts over a run's rows, block by block: samples with a drive beyond Umax, samples
    per status, and whether every position and drive is finite."""

    def __init__(self, max_drive: float):
        self.max_drive = max_drive
        self.beyond = 0
        self.status = np.zeros(len(Status), dtype=np.int64)
        self.finite = True

    def add(self, rows: closed_loop.Rows) -> None:
        beyond, finite = _tally_rows(rows.drive, rows.position, rows.status,
                                     float(self.max_drive), self.status)
        self.beyond += int(beyond)
        self.finite = self.finite and bool(finite)


@njit(cache=True, nogil=True)
def _tally_rows(drive, position, status, max_drive, counts):
    """One pass over a block's rows, no temporaries (a short run's fixed cost was a dozen
    NumPy calls): ``(beyond, finite)``, the samples with a drive beyond ``max_drive``
    [V] on any axis and whether every position and drive is finite; ``counts[s]`` (one
    per :class:`~nurbsmotion.stepping.Status`) is raised by the samples of status s."""
    beyond = 0
    finite = True
    for i in range(drive.shape[0]):
        over = False
        for j in range(drive.shape[1]):
            d = drive[i, j]
            over = over or abs(d) > max_drive
            finite = finite and math.isfinite(d) and math.isfinite(position[i, j])
        if over:
            beyond += 1
        counts[status[i]] += 1
    return beyond, finite


def hold_samples_of(plant: ServoPlant, hold: float | None) -> int:
    """Samples a run goes on after it has settled: ``hold`` [s] (by default
    :data:`HOLD_TIME` on a plant with effects, 0 on an ideal one) at the plant's Ts."""
    if hold is None:
        hold = HOLD_TIME if plant.effects is not None else 0.0
    if isinstance(hold, bool) or not (isinstance(hold, (int, float)) and math.isfinite(hold)
                                      and hold >= 0):
        raise InvalidArgumentError(f"hold must be a finite number >= 0 [s], got {hold!r}")
    samples = hold / plant.sample_period
    if samples > MAX_HOLD_SAMPLES:  # beyond the loop's int64 counters
        raise WorkLimitError(f"hold {hold:g} s is {samples:.3g} samples at Ts = "
                             f"{plant.sample_period:g} s, more than any run "
                             f"({MAX_HOLD_SAMPLES:.3g})")
    return int(round(samples))


def _closed_loop(interpolator, machine, sink, *, plant=None, settle_time=SETTLE_TIME,
                 settle_window=closed_loop.SETTLE_WINDOW, settle_limit=SETTLE_LIMIT,
                 max_samples=None, progress=None, hold=None):
    """The run behind :func:`simulate` and :func:`simulate_streamed`: ``(outcome, rows,
    finite)``, ``rows`` None with a ``sink``, ``finite`` whether every position and drive
    was finite."""
    if not isinstance(interpolator, Interpolator):
        raise InvalidArgumentError(f"interpolator must be an Interpolator, got "
                                   f"{type(interpolator).__name__}")
    if not isinstance(machine, Machine):
        raise InvalidArgumentError(f"machine must be a Machine, got {type(machine).__name__}")
    curve = interpolator.curve
    machine.check_path(curve.n_axes)
    Ts = machine.sample_period
    if abs(interpolator.sample_period - Ts) > 1e-15 * Ts:
        raise InvalidArgumentError(f"interpolator sample period {interpolator.sample_period} s "
                                   f"differs from the machine's {Ts} s")
    for name, value in (("settle_time", settle_time), ("settle_window", settle_window),
                        ("settle_limit", settle_limit)):
        if isinstance(value, bool) or not (isinstance(value, (int, float))
                                           and math.isfinite(value) and value >= 0):
            raise InvalidArgumentError(f"{name} must be a finite number >= 0, got {value!r}")
    if plant is None:
        plant = machine.plant()
    elif plant.n_axes != machine.n_axes or plant.sample_period != Ts:
        raise InvalidArgumentError(f"the plant has {plant.n_axes} axes and Ts = "
                                   f"{plant.sample_period} s; the machine {machine.n_axes} "
                                   f"and {Ts} s")
    start, end = curve.end_points
    duration = interpolator.nominal_duration()
    n_limit = int(round(settle_limit / Ts))
    if max_samples is None:
        if duration is None:
            slowest = (float(np.min(machine.max_axis_speed))
                       if math.isfinite(machine.max_drive) else 1e300)
            max_samples = int(10 * curve.length / max(slowest, 1e-300) / Ts + 10 / Ts) + 10
        else:
            max_samples = int(20 * duration / Ts + 10 / Ts) + 10
        max_samples += n_limit
    n_settle = int(round(settle_time / Ts))
    n_hold = hold_samples_of(plant, hold)
    hold = settle_hold_samples(machine) + n_hold
    settling = closed_loop.Settling(np.ascontiguousarray(end, dtype=float),
                                    float(settle_window), n_settle, hold,
                                    max(n_limit, n_settle), int(max_samples))
    guess = (curve.length / machine.max_axis_speed.min() if duration is None else duration)
    # A plant with effects may hunt or limit-cycle at the end until the settle limit:
    # room for that from the start (rows not written are never touched, so not
    # resident) instead of growing the rows, copying them, several times on the way.
    wait = n_limit if plant.effects is not None else 0
    capacity = int(min(1.2 * guess / Ts + n_settle + hold + wait + 64, 1 << 22))
    tally = _Tally(machine.max_drive)

    def counted(first, rows, finished, last):
        tally.add(rows)
        sink(first, rows, finished, last)

    code, rows, loop = closed_loop.run(
        interpolator.plan, interpolator.new_state(), machine.law(), pid_state(start), plant,
        machine.speed_measurement == "encoder", start, settling,
        interpolator.records_bounds, capacity, progress=progress,
        sink=None if sink is None else counted)
    if rows is not None:
        tally.add(rows)
    u = float(loop.u[0])
    finished = int(loop.finished[0])
    if code == closed_loop.FAILED:
        raise InfeasibleError(f"{interpolator.name} interpolator cannot advance from "
                              f"u = {u:.9g}")
    if finished < 0:
        raise InfeasibleError(
            f"{interpolator.name}: the path's end was not reached within {max_samples} "
            f"samples ({max_samples * Ts:g} s; u = {u:.6g})")
    settled = code == closed_loop.DONE
    settled_index = loop.settled_index if settled else None
    success, message = _verdict(tally, settled, settled_index, Ts, settle_window,
                                settle_limit)
    message = "; ".join([message, *interpolator.notes])
    outcome = RunOutcome(int(loop.k[0]), finished, settled_index, float(settle_window),
                         success, message, curve, machine, interpolator.name,
                         tuple(interpolator.notes), n_hold)
    return outcome, rows, tally.finite


def _verdict(tally: _Tally, settled: bool, settled_index, Ts: float, window: float,
             limit: float) -> tuple[bool, str]:
    """``(success, message)`` of a run: finite, settled, and every drive within Umax."""
    over = tally.beyond
    limited = int(tally.status[Status.LIMITED])
    cornered = int(tally.status[Status.CORNERED])
    parts = [f"settled within {window:g} pulse of the end at {settled_index * Ts:.6g} s"
             if settled else
             f"did not settle within {window:g} pulse of the end in {limit:g} s"]
    parts.append(f"{over} samples with a drive beyond Umax" if over else
                 "every drive within Umax")
    if limited:
        parts.append(f"{limited} steps limited to keep the drive within Umax")
    if cornered:
        parts.append(f"{cornered} steps cornered (no admissible step)")
    if not tally.finite:
        parts.insert(0, "the closed loop diverged (non-finite positions or drives)")
    return tally.finite and settled and over == 0, "; ".join(parts)


def run(curve: NurbsCurve, machine: Machine, feed, interpolator: str = DEFAULT_INTERPOLATOR,
        *, max_samples: int = MAX_SAMPLES, interpolator_options: dict | None = None,
        **simulate_options) -> Trace:
    """Run a path on a machine with a named interpolator.

    Parameters
    ----------
    curve : NurbsCurve
        The path, in any unit the machine knows (converted by its
        :class:`~nurbsmotion.units.Scale`).
    machine : Machine
    feed : float or str
        Commanded feed F: a bare number in the path's units per second (pulse/s for a
        path in pulses), or a text with a unit such as ``"100mm/s"``
        (:meth:`nurbsmotion.units.Scale.feed`).
    interpolator : str
        One of :data:`nurbsmotion.interpolators.LOOP_METHODS`; by default ``planned``
        (:data:`~nurbsmotion.interpolators.DEFAULT_INTERPOLATOR`, as the command's).
    max_samples : int
        Refuse (:class:`~nurbsmotion.errors.WorkLimitError`) a move that would take more
        samples than this, before any work (:data:`nurbsmotion.loop.budget.MAX_SAMPLES`).
    interpolator_options : dict, optional
        Passed to the interpolator (:func:`nurbsmotion.interpolators.make_interpolator`),
        e.g. ``{"corner_tolerance": 500.0}`` [pulse] for ``planned``.
    **simulate_options
        Passed to :func:`simulate` (``plant``, ``settle_time``, ``settle_window``,
        ``settle_limit``, ``progress``).

    Raises
    ------
    InvalidArgumentError, InvalidMachineError, WorkLimitError
        From :func:`check_run_arguments`, before any work.
    InfeasibleError
        If the interpolator cannot advance, or the loop diverges.
    """
    ip = _named_interpolator(curve, machine, feed, interpolator, max_samples,
                             interpolator_options)
    outcome, rows = _checked(ip, machine, None, simulate_options)
    return _trace(outcome, rows, ip.records_bounds)


def run_streamed(curve: NurbsCurve, machine: Machine, feed, sink,
                 interpolator: str = DEFAULT_INTERPOLATOR, *, max_samples: int = MAX_SAMPLES,
                 interpolator_options: dict | None = None,
                 **simulate_options) -> RunOutcome:
    """:func:`run`, handing the rows to ``sink`` block by block instead of keeping them
    (see :func:`simulate_streamed`).

    Raises
    ------
    InvalidArgumentError, InvalidMachineError, WorkLimitError
        From :func:`check_run_arguments`, before any work.
    InfeasibleError
        If the interpolator cannot advance, or the loop diverges (after the sink has seen
        the rows).
    """
    if not callable(sink):
        raise InvalidArgumentError(f"sink must be callable, got {sink!r:.60}")
    ip = _named_interpolator(curve, machine, feed, interpolator, max_samples,
                             interpolator_options)
    return _checked(ip, machine, sink, simulate_options)[0]


def _named_interpolator(curve, machine, feed, interpolator: str, max_samples: int,
                        options: dict | None) -> Interpolator:
    """The interpolator :func:`run` runs, after :func:`check_run_arguments`."""
    if not isinstance(curve, NurbsCurve):
        raise InvalidArgumentError(f"curve must be a NurbsCurve, got {curve!r:.60}")
    if not isinstance(machine, Machine):
        raise InvalidArgumentError(f"machine must be a Machine, got {machine!r:.60}")
    scale = Scale.of(curve, machine)  # the run's one conversion into pulses
    feed = scale.feed(feed)
    check_run_arguments(curve, machine, feed, max_samples)
    return make_interpolator(interpolator, scale.path(curve), machine, feed,
                             **(options or {}))


def _checked(interpolator: Interpolator, machine: Machine, sink, options: dict):
    """``(outcome, rows)`` of the closed loop; a diverged loop is an error."""
    outcome, rows, finite = _closed_loop(interpolator, machine, sink, **options)
    if not finite:
        raise InfeasibleError(
            f"the closed loop diverged (non-finite positions or drives) running "
            f"{interpolator.name} on machine {machine.name!r}")
    return outcome, rows


def check_run_arguments(curve, machine, feed, max_samples: int = MAX_SAMPLES, *,
                        option: str = "max_samples") -> None:
    """The checks :func:`run` makes before any work: typed errors naming the value.

    ``curve`` must be a :class:`NurbsCurve` and ``machine`` a :class:`Machine` (whose
    closed loop is stable: it was checked when the machine was made); ``feed`` a finite
    number > 0 [pulse/s] or a :class:`~nurbsmotion.feed.FeedLimit` (its lowest feed sizes
    the estimate), at most :data:`~nurbsmotion.planning.MAX_FEED_RATIO` times the
    machine's top speed (:func:`~nurbsmotion.planning.check_feed_reachable`); the path
    within the planner's size (:func:`~nurbsmotion.planning.check_path_size`); and the
    move at most ``max_samples`` samples long
    (:func:`nurbsmotion.loop.budget.check_samples`; ``option`` names the way to raise it).
    """
    if not isinstance(curve, NurbsCurve):
        raise InvalidArgumentError(f"curve must be a NurbsCurve, got {curve!r:.60}")
    if not isinstance(machine, Machine):
        raise InvalidArgumentError(f"machine must be a Machine, got {machine!r:.60}")
    highest = feed
    if isinstance(feed, FeedLimit):
        feed = feed.lowest
    if isinstance(feed, (bool, np.bool_)) or not isinstance(feed, (int, float, np.integer,
                                                                 np.floating)):
        raise InvalidArgumentError(f"feed must be a number [pulse/s], got {feed!r:.60}")
    if not (math.isfinite(feed) and feed > 0):
        raise InvalidArgumentError(f"feed must be finite and > 0 [pulse/s], got {feed!r}")
    check_feed_reachable(highest, machine)
    check_path_size(curve)  # counted from the knots, before the arc-length tables
    length = curve.length * machine.pulses_per_unit(curve.units)  # [pulse], cached
    check_samples(estimate_samples(length, float(feed), machine.sample_period),
                  limit=max_samples, n_axes=curve.n_axes,
                  what=f"a {length:.6g}-pulse move at {feed:g} pulse/s with Ts = "
                       f"{machine.sample_period:g} s", option=option)
