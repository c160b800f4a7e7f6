"""One run, end to end: what to run (:class:`Job`) and what came of it (:class:`RunResult`).

A job is a path (in any unit the machine knows), a machine, a feed and how to run them.
:meth:`Job.run` is the one pipeline every caller uses (``nurbsmotion run``, a study's case,
``reproduce``): the path and the feed converted once by the job's
:class:`~nurbsmotion.units.Scale`, the time-optimal bound (first: a path it cannot be
computed for is refused before the run), the closed loop, the metrics and the machine at
rest. Either the whole trace is kept, or the rows stream block by block to the running
metrics and to the caller's sinks (:mod:`nurbsmotion.loop.sink`) on a thread beside the
loop, in memory that does not grow with the run. :meth:`RunResult.summary` is the
``summary.json`` dictionary.

Glossary
--------
F : commanded feed [pulse/s]; bound : the time-optimal bound [s].
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Callable, Iterable, Mapping

import numpy as np

from .feed import FeedLimit
from .interpolators import DEFAULT_INTERPOLATOR
from .loop import (SETTLE_TIME, RunOutcome, Trace, background_sink, fan_out,
                   hold_samples_of, run, run_streamed, settle_hold_samples)
from .loop.budget import MAX_SAMPLES
from .loop.closed_loop import SETTLE_WINDOW, Rows
from .machine import Machine
from .metrics import AtRest, Metrics, RunningAtRest, RunningMetrics
from .nurbs import NurbsCurve
from .servo import ServoPlant
from .units import OutputUnits, Scale

__all__ = ["Job", "RunResult"]


@dataclass(frozen=True, eq=False)
class Job:
    """A run to make: a path on a machine at a feed, with a named interpolator.

    Parameters
    ----------
    path : NurbsCurve
        The path, in any unit the machine knows (its ``units``; converted once by
        :attr:`scale`).
    machine : Machine
        The controller: its law, Umax, Ts, and the model the interpolator plans with.
    feed : float or str or tuple or FeedLimit
        Commanded feed F, as :meth:`nurbsmotion.units.Scale.feed` reads it: a bare number
        [path units/s], a text with a unit (``"100mm/s"``), a per-piece
        :class:`~nurbsmotion.feed.FeedLimit` [path units/s], or ``(value, "pulse")`` with
        ``value`` a number or a FeedLimit already in pulse/s.
    interpolator : str
        One of :data:`nurbsmotion.interpolators.LOOP_METHODS`; ``planned`` by default.
    interpolator_options : mapping, optional
        Passed to :func:`nurbsmotion.interpolators.make_interpolator`
        (``corner_tolerance``, ``path_tolerance`` [pulse] for ``planned``).
    plant : ServoPlant, optional
        The true plant, when it differs from the machine's model.
    settle_window : float
        Settling window around the end point [pulse], > 0.
    settle_time : float
        The least time the run goes on holding the end point [s].
    hold : float, optional
        How long the run goes on after it has settled [s] (:func:`nurbsmotion.loop.simulate`).
    max_samples : int
        Refuse a move longer than this many samples, before any work.
    time_optimal_bound : float, optional
        The bound [s] when the caller knows it already (the same path, model and feed run
        by several interpolators), or NaN for none; computed by
        :func:`nurbsmotion.planning.time_optimal_bound` when None.
    name : str
        The path's name in the summary (``path``).
    """

    path: NurbsCurve
    machine: Machine
    feed: object
    interpolator: str = DEFAULT_INTERPOLATOR
    interpolator_options: Mapping | None = None
    plant: ServoPlant | None = None
    settle_window: float = SETTLE_WINDOW
    settle_time: float = SETTLE_TIME
    hold: float | None = None
    max_samples: int = MAX_SAMPLES
    time_optimal_bound: float | None = None
    name: str = ""

    @cached_property
    def scale(self) -> Scale:
        """The path's units on the machine's pulses (:meth:`Scale.of`)."""
        return Scale.of(self.path, self.machine)

    @cached_property
    def pulses(self) -> NurbsCurve:
        """The path in the machine's pulses (the same object when it is in pulses)."""
        return self.scale.path(self.path)

    @cached_property
    def feed_pulses(self):
        """The commanded feed F [pulse/s], a number or a per-piece FeedLimit."""
        return self.scale.feed(self.feed)

    def with_options(self, **changes) -> "Job":
        """This job with ``changes`` to its fields (:func:`dataclasses.replace`), keeping
        the path already converted to pulses (and its arc-length tables) and the feed
        where the path, the machine and the feed stay the same."""
        job = replace(self, **changes)
        kept = ("scale", "pulses") + (("feed_pulses",) if "feed" not in changes else ())
        if "path" not in changes and "machine" not in changes:
            for name in kept:
                if name in self.__dict__:
                    job.__dict__[name] = self.__dict__[name]
        return job

    def bound(self) -> float:
        """The time-optimal bound [s] of the path at the feed (or the one given)."""
        if self.time_optimal_bound is not None:
            return float(self.time_optimal_bound)
        from .planning import time_optimal_bound

        return time_optimal_bound(self.pulses, self.machine, self.feed_pulses)

    def run(self, sinks: Iterable = (), *, keep_trace: bool = True,
            progress: Callable[[int], None] | None = None) -> "RunResult":
        """Run the job: bound, closed loop, metrics.

        Parameters
        ----------
        sinks : iterable of Sink
            Each takes the run's rows (:class:`nurbsmotion.loop.sink.Sink`): block by
            block beside the loop when the trace is not kept, else the whole trace as one
            block after the run.
        keep_trace : bool
            Keep every row (:attr:`RunResult.trace`); without it the rows stream to the
            metrics and the sinks, and only the outcome is kept.
        progress : callable, optional
            ``progress(k)`` with the samples run so far (a progress bar).

        Raises
        ------
        InvalidArgumentError, InvalidMachineError, WorkLimitError
            Before any work, naming the bad value.
        InfeasibleError
            If the bound cannot be computed, the interpolator cannot advance, or the loop
            diverges.
        """
        sinks = list(sinks)
        add = fan_out(sinks)  # a sink without add() is refused before any work
        bound = self.bound()
        options = dict(max_samples=self.max_samples,
                       interpolator_options=dict(self.interpolator_options or {}),
                       plant=self.plant, settle_window=self.settle_window,
                       settle_time=self.settle_time, hold=self.hold, progress=progress)
        if keep_trace:
            trace = run(self.pulses, self.machine, self.feed_pulses, self.interpolator,
                        **options)
            metrics = trace.metrics()
            if sinks:
                add(0, _rows_of(trace), trace.finished_index, True)
            return RunResult(self, trace, metrics, bound)
        running = RunningMetrics(self.pulses, self.machine, self.settle_window)
        plant = self.plant or self.machine.plant()
        resting = RunningAtRest(self.machine, self.pulses.end_points[1], self.settle_window,
                                hold_samples_of(plant, self.hold)
                                or settle_hold_samples(self.machine))
        everything = fan_out([running, resting, *sinks])
        # the metrics and the sinks beside the loop; left before the caller's sinks close
        with background_sink(everything) as beside:
            outcome = run_streamed(self.pulses, self.machine, self.feed_pulses, beside,
                                   self.interpolator, **options)
        metrics = running.result(outcome.finished_index, outcome.success, outcome.message)
        return RunResult(self, outcome, metrics, bound, resting.result())


def _rows_of(trace: Trace) -> Rows:
    """A kept trace's rows as one block of :class:`~nurbsmotion.loop.closed_loop.Rows`."""
    n, n_axes = trace.position.shape
    return Rows(trace.u, trace.feed, trace.status, trace.position_command, trace.position,
                trace.speed_command, trace.speed, trace.drive, trace.drive_applied,
                np.empty((0, n_axes, 2)) if trace.speed_bounds is None else trace.speed_bounds,
                np.empty((0, n_axes)) if trace.position_measured is None
                else trace.position_measured)


@dataclass(frozen=True, eq=False)
class RunResult:
    """What a :class:`Job` run gave.

    Attributes
    ----------
    job : Job
    outcome : RunOutcome
        The run's verdict and counts; a :class:`~nurbsmotion.loop.Trace` (every row) when
        the trace was kept.
    metrics : Metrics
        The docs/model.md#run-figures figures [pulse, s].
    bound : float
        The time-optimal bound [s] (NaN where the job asked for none).
    """

    job: Job
    outcome: RunOutcome
    metrics: Metrics
    bound: float
    _at_rest: AtRest | None = field(default=None, repr=False)

    @property
    def trace(self) -> Trace | None:
        """Every row of the run, or None when they streamed."""
        return self.outcome if isinstance(self.outcome, Trace) else None

    @property
    def scale(self) -> Scale:
        """The job's :class:`~nurbsmotion.units.Scale` (the report unit of the results)."""
        return self.job.scale

    @property
    def output_units(self) -> OutputUnits:
        """The results' units on the way out (:attr:`nurbsmotion.units.Scale.output`):
        what the summary, the trace file and the figures convert pulses with."""
        return self.job.scale.output

    @property
    def feed(self) -> float:
        """The commanded feed as one number [pulse/s]: a per-piece feed's highest."""
        feed = self.job.feed_pulses
        return feed.highest if isinstance(feed, FeedLimit) else feed

    @property
    def notes(self) -> tuple:
        """What the interpolator noted of the run."""
        return self.outcome.notes

    def at_rest(self) -> AtRest:
        """What the machine did at rest and at its peaks (:class:`nurbsmotion.metrics.AtRest`)."""
        return self._at_rest if self._at_rest is not None else self.trace.at_rest()

    def at_rest_keys(self, in_report_unit: bool = True) -> dict:
        """The summary keys of :meth:`at_rest` (``hold_window_s``, ``drive_chatter_rms``,
        ...), with ``in_report_unit`` the peaks also in the report unit
        (``peak_speed_mm_per_s``, ``peak_acceleration_mm_per_s2``, ``peak_jerk_mm_per_s3``)."""
        data = self.at_rest().to_dict()
        out = {"hold_window_s": data.pop("window_s"), **data}
        if in_report_unit:
            units = self.output_units
            for key, suffix in (("peak_speed", "per_s"), ("peak_acceleration", "per_s2"),
                                ("peak_jerk", "per_s3")):
                out[f"{key}_{units.unit}_{suffix}"] = {a: units.length(v)
                                                       for a, v in data[key].items()}
        return out

    def summary(self, extra: dict | None = None, *, in_report_unit: bool = True) -> dict:
        """The ``summary.json`` dictionary (:func:`nurbsmotion.report.summary`): the
        figures, the run's names, the bound, with ``in_report_unit`` the lengths also in
        the report unit, then ``extra``."""
        from .report import summary

        return summary(self.metrics, interpolator=self.job.interpolator, feed=self.feed,
                       machine=self.job.machine.name, path=self.job.name,
                       time_optimal_bound=self.bound,
                       units=self.output_units if in_report_unit else None, extra=extra)
