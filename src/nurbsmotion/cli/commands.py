"""The commands, one function each: ``_cmd_<command>(args) -> int``.

Each parses nothing and checks nothing argparse has not: it reads the path and the
machine, calls the library (the loop, the bound, the study engine, identification), and
writes its files through the output folder of :mod:`.console`. The helpers of ``run``
(the feed used, the streamed run, the trace file, the exports, the true plant) sit
beside it.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import math
import sys
import time
from pathlib import Path

from typing import TYPE_CHECKING

from .._runtime.forked import ForkedWorker, usable_cpus
from .._runtime.io import OutputFolder
from ..errors import InvalidArgumentError, InvalidFeedError, WorkLimitError
from .console import EXPORT_FILES, _outputs, _progress

if TYPE_CHECKING:  # annotations only: the modules below load numba and the loop, which a
    # command imports where it needs them (a path refused as it is read does not pay them)
    from .. import units
    from ..machine import Machine


def _contour(args, machine: Machine | None = None, size_check=None):
    """The path named on the command line with its programmed feed (a ``Contour``): read
    with ``--units`` and, for G-code and DXF, the machine's axes (XY without a machine),
    as a study's cases read theirs (:func:`nurbsmotion.study.run_input.load_run_contour`);
    ``size_check(degree, spans)`` as the file is read (``run`` and ``bound``: the
    planner's, :func:`nurbsmotion.planning.check_span_count`)."""
    from ..study.run_input import load_run_contour

    return load_run_contour(args.path, machine, units=args.units,
                            project=getattr(args, "project", None),
                            path_tolerance=getattr(args, "path_tolerance", None),
                            tool_table=args.tool_table, size_check=size_check)


def _feed_used(args, contour, cap, scale: float, unit: str, *,
               shown: units.OutputUnits | None = None):
    """The feed a command runs at, and a sentence saying which it is.

    ``cap`` is ``--feed`` in the target unit (None if not given), ``scale`` converts the
    path's units to the target unit (``unit``, e.g. ``"pulse/s"``). Where the file gives a
    feed (G-code F), it is the limit along the path and ``--feed`` caps it (the lower of the
    two per piece); where it gives none, ``--feed`` is required. With ``shown`` (a run's
    units on the way out; the target unit is then pulse/s) the sentence gives the feeds in
    its unit per second first, then "= ..." in the target unit.

    Returns
    -------
    feed : float or FeedLimit
    note : str
    """
    def speed(lo: float, hi: float | None = None) -> str:
        def one(convert, u: str) -> str:
            text = f"{convert(lo):.6g}" if hi is None or hi == lo else (
                f"{convert(lo):.6g} to {convert(hi):.6g}")
            return f"{text} {u}"
        if shown is None:
            return one(lambda x: x, unit)
        return f"{one(shown.length, f'{shown.unit}/s')} = {one(lambda x: x, unit)}"

    from ..study.run_input import programmed_feed

    feed = programmed_feed(cap, contour.feed, scale, args.path,  # campaigns' rule too
                           contour.feed_ratio)
    if contour.feed is None:
        return feed, f"--feed {speed(cap)}"
    limit = contour.feed.scaled(scale)
    span = speed(limit.lowest, limit.highest)
    rule = ""
    if contour.feed_ratio is not None:  # a path with rotary axes: LinuxCNC's feed rule
        rule = (", F the speed of X, Y, Z where they move, else of the rotary axes "
                "[deg/min] (LinuxCNC's rule)")
    if cap is None:
        return feed, f"the file's programmed feed ({span}){rule}"
    return feed, (f"the lower of the file's programmed feed ({span}) and --feed "
                    f"{speed(cap)} per piece{rule}")


def _cmd_contours(args) -> int:
    from ..paths import load_contours

    contours = load_contours(args.path, axes=args.axes, units=args.units, tool_table=args.tool_table)
    print(f"{args.path}: {len(contours)} contour{'s' if len(contours) != 1 else ''} "
          f"(choose one with {args.path}#k)")
    named = contours[0].axes if contours and contours[0].axes else None
    if named:
        how = "as --axes gives them" if args.axes else "every axis the file moves; --axes to choose"
        rotary = " (A, B, C in degrees)" if set(named) & set("ABC") else ""
        print(f"axes: {named}{rotary} ({how})")
    print("| # | pieces | length | bounding box | units | programmed feed |")
    print("|---|---|---|---|---|---|")
    for k, c in enumerate(contours, start=1):
        curve = c.curve
        box = " ".join(f"{n}[{lo:.6g}, {hi:.6g}]{' deg' if n in 'abc' and c.axes else ''}" for n, lo, hi in
                       zip(list(c.axes.lower()) if c.axes else _axis_names(curve.n_axes),
                           *curve.bounding_box()))
        pieces = len(c.feed.speeds) if c.feed is not None else len(curve.sharp_corners()) + 1
        if c.feed is None:
            feed = "none"
        else:
            lo, hi = c.feed.lowest * 60.0, c.feed.highest * 60.0
            feed = f"F{lo:.6g}" if lo == hi else f"F{lo:.6g} to F{hi:.6g}"
            feed += f" {curve.units}/min"
        print(f"| {k} | {pieces} | {curve.length:.6g} | {box} | {curve.units} | {feed} |")
    return 0


def _cmd_interpolate(args) -> int:
    from .. import units
    from ..machine import load_machine

    machine = load_machine(args.machine or "die-bonder")
    contour = _contour(args, machine)  # as run reads it: chord runs joined
    # (after the path is read: a path refused there does not load numba's modules)
    from ..interpolators import make_open_loop
    from ..loop import interpolate
    from ..loop.budget import check_samples, estimate_samples
    from ..plots import plot_setpoints
    from ..report.export import SetpointArrays, save_csv_metadata, save_setpoints, setpoint_columns

    curve = contour.curve
    cap = None if args.feed is None else _open_loop_feed(args, curve, machine)
    feed, note = _feed_used(args, contour, cap, 1.0, f"{curve.units}/s")
    if args.method == "uniform" and not isinstance(feed, (int, float)):
        feed, note = feed.lowest, f"{note}: its lowest value (uniform steps have one feed)"
    lowest = feed if isinstance(feed, (int, float)) else feed.lowest
    highest = feed if isinstance(feed, (int, float)) else feed.highest
    if not highest * args.sample_period < curve.length:  # "cannot advance from u = 0"
        raise InvalidArgumentError(
            f"at {highest:g} {curve.units or 'path units'}/s a sample of "
            f"{args.sample_period:g} s moves {highest * args.sample_period:g}, not less than "
            f"the whole path ({curve.length:.6g}): check the feed and --sample-period")
    check_samples(estimate_samples(curve.length, lowest, args.sample_period),
                  limit=args.max_samples, n_axes=curve.n_axes,
                  what=f"interpolating {curve.length:.6g} {curve.units or 'path units'} "
                       f"at {lowest:g} per s every {args.sample_period:g} s",
                  option="--max-samples")
    with _outputs(args) as staged:
        out = staged.staging
        series = interpolate(make_open_loop(args.method, curve, args.sample_period, feed),
                             max_samples=args.max_samples)
        names = _axis_names(curve.n_axes)
        # to a thousandth of the finest axis's pulse of the machine the path is read on
        # (die-bonder's 1 um without --machine: 1 nm), as run's exports
        per_unit = units.Scale.of(curve, machine).pulses_per_path_unit  # [pulse/path unit]
        save_setpoints(SetpointArrays(series.t, series.u, series.position, series.feed, names),
                       out / "setpoints.csv",
                       resolution=EXPORT_PULSE_FRACTION / float(max(per_unit)))
        save_csv_metadata(out / "setpoints.csv", setpoint_columns(names, curve.units or "pulse"),
                          title="nurbsmotion setpoints (open loop)")
        plot_setpoints(series, out, axis_names=names, units=curve.units or "pulse")
    out = Path(args.out)
    fl_max, fl_rms = series.feed_fluctuation()
    print(f"{args.method}: {len(series.t)} samples, cycle time {series.cycle_time:.6g} s, "
          f"feed fluctuation max {fl_max:.3%} RMS {fl_rms:.3%}; feed: {note} -> {out}")
    _print_joined(contour, machine)
    return 0


def _open_loop_feed(args, curve, machine: Machine) -> float:
    """``--feed`` of ``interpolate`` in the path's units per second: converted by its own
    unit where it can be (a length unit on a path in a length unit); otherwise, with
    ``--machine`` given, through the machine's Scale (a feed in m/s on a path in pulses:
    the machine's pulse length); without it, refused as before."""
    from .. import units
    try:
        return units.feed_in_path_units(args.feed, curve)
    except InvalidFeedError:
        if args.machine is None:
            raise
    scale = units.Scale.of(curve, machine)
    return scale.feed(args.feed) / scale.factor  # [pulse/s] / [pulse/path unit]


def _axis_names(n: int) -> list[str]:
    return list("xyzabc"[:n]) if n <= 6 else [f"axis{i}" for i in range(n)]


def _check_bound(bound: float, machine: Machine, curve, max_samples: int) -> None:
    """Refuse a time-optimal bound longer than ``max_samples`` samples: no run of the path
    could finish within them (``run`` and ``bound`` alike)."""
    from ..loop.budget import check_samples
    check_samples(bound / machine.sample_period, limit=max_samples, n_axes=curve.n_axes,
                  what=f"the time-optimal bound ({bound:.4g} s at Ts = "
                       f"{machine.sample_period:g} s): a run", option="--max-samples")


def _settle_window(args, scale, path, source: str) -> float:
    """``--settle-window`` [pulse] of ``run`` and ``bound``: > 0 and below the farthest
    distance of ``path`` [pulse] from its end (one check, one message for both commands:
    bound printed nanoseconds for a path run refused as settled from the start)."""
    from ..metrics import check_settle_window

    window = scale.length(args.settle_window, "--settle-window", bare_unit="pulse")
    if window <= 0:
        raise InvalidArgumentError(f"--settle-window must be > 0, got {args.settle_window!r}")
    check_settle_window(window, path, f"{source}: --settle-window {args.settle_window}:")
    return window


def _check_profile_size(path, source: str) -> None:
    """The planner's size (:func:`nurbsmotion.planning.check_profile_size`), before any
    arc length (issue 37), its refusal naming the path's file (or built-in name)."""
    from ..planning import check_profile_size

    try:
        check_profile_size(path)
    except WorkLimitError as exc:
        raise WorkLimitError(f"{source}: {exc}") from None


def _cmd_bound(args) -> int:
    from .. import units
    from ..machine import load_machine
    from ..planning import check_span_count, sampled_stop_bound, time_optimal_bound

    machine = load_machine(args.machine)
    # the planner's size as the file is read (the sampled bound has no planner grid)
    contour = _contour(args, machine, None if args.sampled else check_span_count)
    from ..loop import check_run_arguments  # (after the size checks: numba's loop modules)

    curve = contour.curve
    machine.check_path(curve.n_axes)
    scale = units.Scale.of(curve, machine)
    path = scale.path(curve)
    if args.sampled:
        bound = sampled_stop_bound(path, machine,
                                   settle_window=_settle_window(args, scale, path, contour.source),
                                   max_samples=args.max_samples)
        print(f"{bound:.6g}")
        _print_joined(contour, machine)
        return 0
    _check_profile_size(path, contour.source)
    cap = None if args.feed is None else scale.feed(args.feed)
    feed, note = _feed_used(args, contour, cap, scale.factor, "pulse/s", shown=scale.output)
    # What `run` refuses, `bound` refuses: the same checks, and a bound no run could
    # reach within its samples.
    check_run_arguments(path, machine, feed, args.max_samples, option="--max-samples")
    _settle_window(args, scale, path, contour.source)
    bound = time_optimal_bound(path, machine, feed)
    _check_bound(bound, machine, curve, args.max_samples)
    print(f"{bound:.6g}")
    if contour.feed is not None:
        print(f"feed: {note}", file=sys.stderr)
    _print_joined(contour, machine)
    return 0


def _print_joined(contour, machine: Machine) -> None:
    """Say on stderr which chords the path's runs joined (nothing where none were)."""
    from .. import units
    joined = contour.joined
    if joined is not None and joined.chords_joined:
        scale = units.Scale.of(contour.curve, machine)
        shown = scale.output.length(scale.factor)  # report units per path unit
        print("path: " + joined.describe(scale.output.unit, shown), file=sys.stderr)


TRACE_NOTICE_BYTES = 200e6
"""A trace file larger than this [byte] is announced with its size and the options to
make it smaller (``--trace-every``, ``--no-trace``)."""


def _cmd_run(args) -> int:
    from ..machine import load_machine
    from ..planning import check_span_count
    machine = load_machine(args.machine)
    # the planner's size, as it is read: a path refused there is refused before the
    # loop's modules load (and the cache is looked at, below)
    contour = _contour(args, machine, check_span_count)
    # The loop's modules (numba) load here, before the second process starts, as they did
    # when the machine loaded them: a Ctrl-C while numba loads beside a compiling second
    # process ended the command by SIGINT (exit -2) instead of 130 after its message.
    from .. import job  # noqa: F401
    from .._runtime.precompile import Precompiler

    # On an empty numba cache the closed loop compiles on the other core meanwhile.
    with Precompiler(args.interpolator) as precompiler:
        return _run(args, precompiler, machine, contour)


def _run(args, precompiler, machine: Machine, contour) -> int:
    from .. import units
    from ..loop.budget import check_samples, estimate_samples
    from ..machine import load_machine
    from ..job import Job
    from ..loop import check_run_arguments
    from ..report import TRACE_FILES, write_json

    curve = contour.curve
    machine.check_path(curve.n_axes)
    scale = units.Scale.of(curve, machine)  # the one conversion of this run's units
    cap = None if args.feed is None else scale.feed(args.feed)
    shown = scale.output  # and of its results, on the way out
    unit = shown.unit
    feed, note = _feed_used(args, contour, cap, scale.factor, "pulse/s", shown=shown)
    job = Job(curve, machine, (feed, "pulse"), args.interpolator, name=args.path,
              max_samples=args.max_samples)
    path = job.pulses
    _check_profile_size(path, contour.source)
    try:
        check_run_arguments(path, machine, feed, args.max_samples, option="--max-samples")
    except WorkLimitError:  # too many samples: a bare feed number in the wrong unit?
        _ask_for_feed_unit(args, curve, machine, path.length, feed)
        raise
    plant_machine = machine if args.plant is None else load_machine(args.plant)
    plant = None if args.plant is None else _true_plant(plant_machine, machine)
    if args.hold is not None:  # 1e300 s was a numba typing error deep in the loop
        check_samples(args.hold / plant_machine.sample_period, limit=args.max_samples,
                      n_axes=curve.n_axes, what=f"--hold {args.hold:g} s at Ts = "
                      f"{plant_machine.sample_period:g} s", option="--max-samples")
    eps = scale.length(args.corner_tolerance, "--corner-tolerance")
    if eps and args.interpolator != "planned":
        raise InvalidArgumentError(
            f"--corner-tolerance applies to the planned interpolator, not {args.interpolator}")
    extent = math.dist(*path.bounding_box())  # [pulse]
    if eps >= extent:  # the blends could leave the whole path: no corner left to mean
        raise InvalidArgumentError(
            f"--corner-tolerance {args.corner_tolerance} ({eps:g} pulse) is not below the "
            f"path's extent (its bounding box's diagonal, {extent:.6g} pulse)")
    options = {"corner_tolerance": eps} if eps else {}
    path_tolerance = contour.joined.tolerance * scale.factor
    if args.path_tolerance is not None and args.interpolator == "planned":
        options["path_tolerance"] = path_tolerance
    window = _settle_window(args, scale, path, contour.source)
    lowest = feed if isinstance(feed, (int, float)) else feed.lowest
    if "pvt" in (args.export or ()):
        check_samples(estimate_samples(path.length, lowest, args.pvt_period),
                      limit=args.max_samples, n_axes=curve.n_axes,
                      what=f"the PVT table at --pvt-period {args.pvt_period:g} s",
                      option="--max-samples (or a longer --pvt-period)")
    job = job.with_options(interpolator_options=options, plant=plant, settle_window=window,
                           hold=args.hold)
    # Without figures or exports nothing needs the whole run at once: it streams, and
    # its memory does not grow with its length.
    stream = args.no_figures and not args.export
    stages = ["time-optimal bound", "plan and run the closed loop", "metrics", "trace",
              "summary"]
    stages += [] if args.no_figures else ["figures"]
    with _outputs(args) as staged, _figure_worker(args, path, machine, unit) as figures, \
            _progress(args, total=len(stages), unit="stage", desc=stages[0]) as bar:
        out = staged.staging
        exports = {fmt: out / EXPORT_FILES[fmt] for fmt in args.export or ()}

        def stage(name: str) -> None:
            bar.set_description(name)

        # The bound first: a path it cannot be computed for is refused before the run.
        bound = job.bound()
        _check_bound(bound, machine, curve, args.max_samples)
        if "pvt" in exports and not args.pvt_period < bound:  # a table of one row
            raise InvalidArgumentError(
                f"--pvt-period {args.pvt_period:g} s is not shorter than the move (its "
                f"time-optimal bound is {bound:.6g} s): the PVT table would hold one row")
        job = job.with_options(time_optimal_bound=bound)
        bar.update()
        stage(stages[1])
        expected = estimate_samples(path.length, lowest, machine.sample_period)
        precompiler.wait()
        file = None if args.no_trace else out / TRACE_FILES[args.trace_format]
        if stream:  # the rows go to the metrics and the trace file as the loop runs
            result = _run_streamed(args, job, file, expected)
            bar.update(3)
        else:
            with _progress(args, total=_total(expected), unit="sample", unit_scale=True,
                           desc="closed loop") as samples:
                # the metrics before the trace file: their temporaries are gone before
                # the writer's buffers are made (the peak memory is the larger, not the sum)
                result = job.run(progress=lambda k: samples.update(k - samples.n))
            if not args.no_figures:  # drawn by the worker while the files are written
                from ..plots import plot_trace

                figures.submit(plot_trace, result.trace, out, feed=result.feed,
                               length_unit=unit, overwrite=True, processes=usable_cpus())
            bar.update(2)
            stage(stages[3])
            if file is not None:
                _write_trace(args, result.trace, file, result.output_units)
            if exports:
                _export_setpoints(result.trace, scale, exports, args)
            bar.update()
        metrics = result.metrics
        stage(stages[4])
        extra = {"plant": machine.name if args.plant is None else args.plant,
                 "corner_tolerance": eps,
                 f"corner_tolerance_{unit}": shown.length(eps),
                 f"settle_window_{unit}": shown.length(window)}
        if args.interpolator == "planned" or contour.joined.chords_joined:
            extra.update({"path_tolerance": path_tolerance,
                          f"path_tolerance_{unit}": shown.length(path_tolerance)})
        if contour.joined.chords_joined:  # what the path run is: said where it differs
            extra.update({"chords_joined": contour.joined.chords_joined,
                          "chord_runs": contour.joined.runs})
        extra.update(result.at_rest_keys())
        if machine.has_effects or plant_machine.has_effects:  # both, as they were read
            extra["machine_model"] = machine.to_dict()
            extra["true_plant"] = plant_machine.to_dict()
        if contour.feed is not None:  # the file gave a feed: say which one ran
            extra["feed_used"] = note
        extra["notes"] = list(result.notes)
        extra["path_unit"] = curve.units
        if machine.rotary_axes:  # their trace columns are in degrees
            extra["rotary_axes"] = {a.name: {"unit": "deg", "pulses_per_degree": a.pulses_per_degree}
                                    for a in machine.axes if a.pulses_per_degree is not None}
        if contour.units_source:
            extra["path_unit_source"] = contour.units_source
        write_json(result.summary(extra), out / "summary.json")
        bar.update()
        if not args.no_figures:
            stage(stages[5])
            figures.result()
            bar.update()
    out = Path(args.out)
    sat = metrics.total_saturated_samples
    at = (f"{shown.length(feed):.4g} {unit}/s ({feed:.4g} pulse/s)"
          if contour.feed is None else note)
    settled = (f"settled at {metrics.settle_time_s:.4g} s "
               f"({metrics.settle_time_s / bound:.3f} x)" if metrics.settled
               else "not settled by the end of the run")
    source = f", {contour.units_source}" if contour.units_source else ""
    joined = ("; path: " + contour.joined.describe(unit, shown.length(scale.factor))
              if contour.joined.chords_joined else "")
    print(f"{args.interpolator} on {_machine_label(args.machine, machine)} at {at} (path in "
          f"{curve.units}{source}): cycle time {metrics.cycle_time_s:.4g} s "
          f"({metrics.cycle_time_s / bound:.3f} x the time-optimal bound), {settled}, "
          "max contour error "
          f"{shown.length(metrics.max_contour_error):.4g} {unit} "
          f"({metrics.max_contour_error:.4g} pulse), {sat} saturated "
          f"sample{'s' if sat != 1 else ''}{joined} -> {out}")
    return 0


def _figure_worker(args, path, machine: Machine, unit: str) -> ForkedWorker:
    """The process that draws a run's figures: forked now, before the run, it imports
    matplotlib and prepares the path's figure data and empty figures
    (:func:`nurbsmotion.plots.prepare_trace_steps`) on the other core while this process
    runs, until the trace is there; then it draws the figures of the trace it is sent,
    shared with a process it forks (one per usable CPU; what was not prepared yet is made
    by the process that needs it), while this one writes the trace file and the summary. No
    process with ``--no-figures``, nor where the platform does not fork (the figures are
    then drawn here)."""
    if args.no_figures:
        return ForkedWorker(enabled=False)
    from ..plots import prepare_trace_steps

    return ForkedWorker(functools.partial(prepare_trace_steps, path, machine,
                                          length_unit=unit), shared=(path, machine))


def _ask_for_feed_unit(args, curve, machine: Machine, length: float, feed) -> None:
    """A bare ``--feed`` number (no unit) that makes the move too long to run is most
    likely in another unit than the path's: raise asking for it, instead of pointing at
    ``--max-samples``."""
    given = getattr(args, "feed", None)
    if given is None or given[1] is not None or not isinstance(feed, (int, float)) or feed <= 0:
        return
    value, unit = given[0], curve.units or "pulse"
    hours = length / feed / 3600.0
    raise InvalidArgumentError(
        f"--feed {value:g} is a bare number, read in the path's unit per second ({value:g} "
        f"{unit}/s): the move would take {hours:.3g} h. {value:g} m/s? give the unit (e.g. "
        f"--feed {value:g}m/s, {value:g}mm/s or {value:g}mm/min), or raise --max-samples if "
        f"{value:g} {unit}/s is meant")


def _machine_label(spec: str, machine: Machine) -> str:
    """The machine's name, and the file it came from where that is named otherwise
    (a copied machine file keeps the name inside it)."""
    path = Path(spec)
    if path.suffix.lower() in (".toml", ".json") and path.stem != machine.name:
        return f"{machine.name} (from {spec})"
    return machine.name


def _total(expected: float) -> int | None:
    """A progress bar's total from an estimate that may be infinite."""
    return int(expected) if math.isfinite(expected) else None


def _run_streamed(args, job, file: Path | None, expected: float):
    """Run ``job`` with its rows streamed to the metrics and the trace file (if any),
    announcing the file's size once its first rows are written when it is large."""
    from ..report import TraceWriter

    with contextlib.ExitStack() as stack:
        writer = None if file is None else stack.enter_context(TraceWriter(
            file, job.machine, fmt=args.trace_format, every=args.trace_every,
            units=job.scale.output, overwrite=args.overwrite, threads=0, metadata=True))
        samples = stack.enter_context(_progress(
            args, total=_total(expected), unit="sample", unit_scale=True,
            desc="closed loop" if writer is None else f"closed loop -> {file.name}"))
        sinks = [] if writer is None else [writer]
        if writer is not None and math.isfinite(expected):
            sinks.append(_TraceNotice(args, file, writer, expected, samples))
        # the sinks run beside the loop and are left before the writer closes
        return job.run(sinks, keep_trace=False,
                       progress=lambda k: samples.update(k - samples.n))


class _TraceNotice:
    """A sink that announces the trace file's size (:func:`_trace_notice`) once the
    writer has written its first rows."""

    def __init__(self, args, file: Path, writer, expected: float, bar):
        self.args, self.file, self.writer = args, file, writer
        self.expected, self.bar, self.done = expected, bar, False

    def add(self, first, rows, finished, last) -> None:
        if self.done or not self.writer.rows_written:
            return
        self.done = True
        total = max(self.writer.rows_written, int(self.expected / self.args.trace_every))
        _trace_notice(self.args, self.file, total, self.writer.bytes_per_row() * total,
                      self.bar)


def _trace_notice(args, file: Path, rows: int, size: float, bar=None) -> None:
    """Say the trace file's size and how to make it smaller, when it is large."""
    if size <= TRACE_NOTICE_BYTES:
        return
    every = max(2, round(size / TRACE_NOTICE_BYTES * 2))
    text = (f"nurbsmotion run: writing {file.name}: {rows:,} rows, about "
            f"{size / 1e6:.3g} MB; --trace-every {every} keeps one row in {every}, "
            "--no-trace writes none (the summary and figures use every sample either way)"
            + ("" if args.trace_format == "parquet" else
               ", --trace-format parquet is smaller"))
    if bar is None:
        print(text, file=sys.stderr)
    else:
        bar.write(text, file=sys.stderr)


def _write_trace(args, trace, file: Path, shown: units.OutputUnits) -> None:
    """Write the trace file of a whole run (lengths also in ``shown``'s units),
    announcing its size first when it is large."""
    from ..report import estimate_trace_bytes, trace_rows, write_trace

    options = dict(fmt=args.trace_format, every=args.trace_every, units=shown)
    rows = len(trace_rows(trace, args.trace_every))
    _trace_notice(args, file, rows, estimate_trace_bytes(trace, **options))
    with _progress(args, total=rows, unit="row", unit_scale=True,
                   desc=f"write {file.name}") as bar:
        write_trace(trace, file, overwrite=args.overwrite, progress=bar.update, metadata=True,
                    **options)


EXPORT_PULSE_FRACTION = 1e-3
"""Exported positions are written to this fraction of a pulse (CSV, PVT, halstreamer, ROS)."""


def _export_setpoints(trace, path_scale: units.Scale, files: dict, args) -> None:
    """The commanded setpoints of a run, in the path's own units (``path_scale``'s;
    G-code, halstreamer and ROS in their fixed units)."""
    from ..report.export import (SetpointArrays, pvt_table, save_csv_metadata, save_halstreamer,
                                 save_motion_gcode, save_pvt, save_ros_trajectory, save_setpoints,
                                 setpoint_columns)

    machine = trace.machine
    scale = path_scale.factor  # [pulse/path unit]
    unit = path_scale.path_units or "pulse"  # the exported positions' unit
    end = trace.finished_index + 1
    sp = SetpointArrays(trace.t[:end], trace.u[:end], trace.position_command[:end] / scale,
                        trace.feed[:end] / scale, machine.axis_names)
    # Values to a thousandth of a pulse: finer digits are below what the encoder resolves.
    per_mm = path_scale.pulses_per("mm")
    resolution = EXPORT_PULSE_FRACTION / scale  # [path units]
    rotary = [j for j, a in enumerate(machine.axes) if a.pulses_per_degree is not None]
    if rotary:  # a rotary axis in degrees (radians for ROS), its CSV/PVT column named so
        sp = _rotary_setpoints(sp, trace.position_command[:end], machine, rotary)
    for fmt, file in files.items():
        out = sp
        if rotary and fmt in ("halstreamer", "ros", "gcode"):  # written times a length scale:
            ros = fmt == "ros"  # the rotary columns so that they come out in deg (rad for ROS)
            position = sp.position.copy()
            position[:, rotary] *= (math.pi / 180.0 if ros else 1.0) / (
                scale / per_mm * (1e-3 if ros else 1.0))
            out = SetpointArrays(sp.t, sp.u, position, sp.feed, machine.axis_names)
        if fmt in ("csv", "npz"):
            save_setpoints(out, file, resolution=resolution, overwrite=args.overwrite)
            if fmt == "csv":
                save_csv_metadata(file, setpoint_columns(out.axis_names, unit),
                                  title="nurbsmotion setpoints", overwrite=args.overwrite)
        elif fmt == "pvt":
            save_pvt(pvt_table(out, args.pvt_period), file, resolution=resolution,
                     overwrite=args.overwrite)
            save_csv_metadata(file, setpoint_columns(out.axis_names, unit, velocity=True, u=False),
                              title=f"nurbsmotion PVT table, period {args.pvt_period:g} s",
                              overwrite=args.overwrite)
        elif fmt == "halstreamer":  # LinuxCNC's machine unit: mm
            save_halstreamer(out, file, units="mm", scale=scale / per_mm,
                             resolution=EXPORT_PULSE_FRACTION / per_mm, overwrite=args.overwrite)
        elif fmt == "ros":  # ROS joint values are SI: m
            save_ros_trajectory(out, file, period=args.pvt_period, scale=scale / per_mm * 1e-3,
                                resolution=EXPORT_PULSE_FRACTION / per_mm * 1e-3,
                                overwrite=args.overwrite)
        else:  # G-code is in mm whatever the path's units
            save_motion_gcode(out, file, units="mm", overwrite=args.overwrite,
                              scale=scale / per_mm)


def _rotary_setpoints(sp, pulses, machine: Machine, rotary: list):
    """``sp`` with each rotary axis's column in degrees (pulses / pulses_per_degree) and,
    for the CSV and PVT headers, named ``<axis>_deg``."""
    from ..report.export import SetpointArrays

    position = sp.position.copy()
    for j in rotary:
        position[:, j] = pulses[:, j] / machine.axes[j].pulses_per_degree
    names = tuple(f"{a}_deg" if j in rotary else a for j, a in enumerate(machine.axis_names))
    return SetpointArrays(sp.t, sp.u, position, sp.feed, names)


def _true_plant(plant_machine: Machine, machine: Machine):
    """The plant of ``plant_machine`` (tau, Kc, Ke per axis, and the effects of the
    machine as it is) with the drive limit and the sample period of ``machine``, the
    controller's."""
    from ..servo import ServoPlant

    if plant_machine.n_axes != machine.n_axes:
        raise InvalidArgumentError(
            f"--plant {plant_machine.name!r} has {plant_machine.n_axes} axes, --machine "
            f"{machine.name!r} {machine.n_axes}")
    # the true machine's effects (counts, delay, friction, mode...) go with its plant
    return ServoPlant(plant_machine.tau, plant_machine.Kc, plant_machine.Ke,
                      machine.max_drive, machine.sample_period, None,
                      plant_machine.effects() if plant_machine.has_effects else None)


def _cmd_reproduce(args) -> int:
    from ..study.reproduce import run_experiment

    t0 = time.perf_counter()
    with _outputs(args) as staged, _progress(args, unit="run") as bar:
        def progress(done: int, total: int, label: str) -> None:
            bar.total = total
            bar.set_description(label)
            bar.update(done - bar.n)

        result = run_experiment(staged.staging, figures=not args.no_figures, progress=progress)
    if not args.quiet:
        print((Path(args.out) / "table.md").read_text())
    print(f"{len(result.rows)} runs, {len(result.files)} files in {args.out} "
          f"({time.perf_counter() - t0:.1f} s)")
    return 0


def _cmd_campaign(args) -> int:
    from ..study.run import run_study
    from ..study.spec import find_case, load_study

    if args.out is not None and not args.out.strip():
        raise InvalidArgumentError(f"--out {args.out!r} is empty; name a folder ('.' for the "
                                   "current one) or leave --out out")
    study = load_study(args.study)
    out = Path(args.out) if args.out else Path(args.study).with_suffix("").with_name(
        Path(args.study).stem + "-campaign")
    if args.case:
        return _campaign_case(find_case(study, args.case), out / args.case, args)
    # Ctrl-C or SIGTERM (a machine that shuts down; main's handler): the finished rows
    # are written.
    try:
        result = run_study(study, out, workers=args.workers, scheduler=args.scheduler,
                           resume=args.resume, overwrite=args.overwrite,
                           progress=not args.no_progress)
    except KeyboardInterrupt:
        print(f"nurbsmotion campaign: interrupted; the finished cases are in {out}/rows; "
              f"go on with: nurbsmotion campaign {args.study} --out {out} --resume",
              file=sys.stderr)
        return 130
    print(f"{result.n_cases} cases: {result.computed} run now, {result.skipped} already "
          f"done, {result.failed} failed, {result.wall_time_s:.1f} s -> {out}/digest.md")
    return 0


def _campaign_case(case, out: Path, args) -> int:
    """``campaign --case ID``: one case's normal run output."""
    from ..study.case import case_trace
    from ..plots import TRACE_FIGURES
    from ..report import write_json, write_trace_csv

    trace_files = ["trace.csv", "trace.csv-metadata.json"]
    names = trace_files + ["summary.json"] + ([] if args.no_figures else list(TRACE_FIGURES))
    with OutputFolder(out, names, overwrite=args.overwrite,  # checked first
                      replaces=[*trace_files, "summary.json", *TRACE_FIGURES]) as staged:
        trace, data, _, _ = case_trace(case)
        write_trace_csv(trace, staged.staging / "trace.csv", metadata=True)
        write_json(data, staged.staging / "summary.json")
        if not args.no_figures:
            trace.plot(staged.staging, feed=data["feed"], overwrite=True)
    print(f"{case.case_id}: {case.interpolator} on {case.machine}, {case.path} at "
          f"{case.feed_value:g} {case.feed_unit}, plant {case.plant.name}: cycle time "
          f"{data['cycle_time_s']:.4g} s, max contour error {data['max_contour_error']:.4g} "
          f"pulse -> {out}")
    return 0
def _parse_columns(text: str) -> dict:
    """argparse type of ``--columns``: ``KEY=NAME,KEY=NAME`` (``x_pos=enc0,t=time``)."""
    mapping = {}
    for part in text.split(","):
        key, sep, name = part.partition("=")
        if not sep or not key.strip() or not name.strip():
            raise argparse.ArgumentTypeError(
                f"{part!r} is not KEY=NAME (e.g. x_pos=encoder_x,x_drive=dac_x,t=time)")
        mapping[key.strip()] = name.strip()
    return mapping


def _cmd_identify(args) -> int:
    from ..machine import load_machine
    from ..identify.plot import IDENTIFY_FIGURE
    from ..identify import identify, read_log

    base = load_machine(args.machine)
    out = Path(args.out)
    names = [out.name, "identify.json"] + ([] if args.no_figures else [IDENTIFY_FIGURE])
    with OutputFolder(out.parent if str(out.parent) else ".", names,
                      overwrite=args.overwrite) as staged:  # checked before any work
        log = read_log(args.log, base.axis_names, columns=args.columns,
                       sample_period=args.sample_period, units=args.units,
                       pulse_length_um=base.pulse_length_um)
        result = identify(log, base)
        (staged.staging / out.name).write_text(result.to_toml(), encoding="utf-8")
        import json

        from .._runtime.io import json_safe

        (staged.staging / "identify.json").write_text(
            json.dumps(json_safe(result.to_dict()), indent=2), encoding="utf-8")
        if not args.no_figures:
            result.plot(staged.staging, overwrite=True)
    for a in result.axes:
        shown = ", ".join(f"{k} {e.value:.5g}" + (f" +- {e.sigma:.2g}" if e.sigma == e.sigma
                                                  else "") for k, e in a.estimates.items())
        print(f"axis {a.name}: {shown}; residual RMS {a.residual_rms:.3g} pulse/sample")
        for note in a.notes:
            print(f"  not identified: {note}")
    print(f"{log.n_samples} samples in {result.seconds:.2f} s -> {out}")
    return 0


def _cmd_excite(args) -> int:
    from .. import units
    from ..machine import load_machine
    from .._runtime.io import write_output
    from ..identify import excitation, excitation_gcode, write_excitation_csv

    machine = load_machine(args.machine)
    out = Path(args.out)
    travel = None
    if args.travel is not None:
        travel = units.length_in_pulses(args.travel, None, machine, "--travel",
                                        bare_unit="pulse")
    suffix = out.suffix.lower()
    if suffix == ".csv":
        t, drive = excitation(machine, travel=travel, seed=args.seed)
        out.parent.mkdir(parents=True, exist_ok=True)  # once there is something to write
        write_excitation_csv(t, drive, machine.axis_names, out, overwrite=args.overwrite)
        print(f"{len(t)} samples ({t[-1]:.3g} s) of drive commands within +-"
              f"{abs(drive).max():.3g} V -> {out}")
    elif suffix in (".ngc", ".nc", ".gcode"):
        text = excitation_gcode(machine, travel=travel)
        out.parent.mkdir(parents=True, exist_ok=True)
        write_output(out, lambda h: h.write(text), overwrite=args.overwrite)
        print(f"position moves -> {out} (run it: nurbsmotion run {out} --machine "
              f"{args.machine} --out DIR, then nurbsmotion identify DIR/trace.csv)")
    else:
        raise InvalidArgumentError(f"--out must end in .csv (drive commands) or .ngc "
                                   f"(G-code moves), got {out.name!r}")
    return 0
