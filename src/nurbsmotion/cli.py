"""Command-line interface: ``nurbsmotion interpolate | run | bound | reproduce``.

A thin layer over the library: it parses arguments, calls library functions, writes files
and turns the library's typed errors into one line on stderr and a non-zero exit code.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from ._io import OutputFolder
from .budget import MAX_SAMPLES, check_samples, estimate_samples
from .errors import NurbsmotionError
from .interpolators import LOOP_METHODS, OPEN_LOOP_METHODS, interpolate, make_open_loop
from .machine import LENGTH_UNITS_UM, Machine, load_machine
from .planning import time_optimal_bound

__all__ = ["main", "parse_feed"]

_FEED = re.compile(r"^\s*([0-9.eE+-]+)\s*(?:([a-z]+)\s*/\s*(s|min))?\s*$")


def parse_feed(text: str) -> tuple[float, str | None]:
    """``"1e6"`` -> (1e6, None); ``"0.5m/s"`` -> (0.5e6, "um"); ``"600mm/min"`` -> (10e3, "um").

    A bare number is in path units per second. With a unit, the value is converted to
    micrometres per second (or kept in pulse/s for ``pulse/s``).
    """
    m = _FEED.match(text)
    if not m:
        raise argparse.ArgumentTypeError(
            f"feed {text!r} is not a number or a speed such as 0.5m/s, 100mm/s, 600mm/min"
        )
    try:
        value = float(m.group(1))
    except ValueError:
        raise argparse.ArgumentTypeError(f"feed {text!r} is not a number") from None
    if not (np.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"feed must be finite and > 0, got {text!r}")
    unit, per = m.group(2), m.group(3)
    if per == "min":
        value /= 60.0
    if unit is None or unit == "pulse":
        return value, unit
    if unit not in LENGTH_UNITS_UM:
        raise argparse.ArgumentTypeError(
            f"feed unit {unit!r} unknown; use pulse or one of {sorted(LENGTH_UNITS_UM)}"
        )
    return value * LENGTH_UNITS_UM[unit], "um"


def _feed_in_path_units(feed: tuple[float, str | None], curve) -> float:
    """A parsed feed in the path's units per second (no machine needed)."""
    value, unit = feed
    if unit is None or unit == curve.units:
        return value
    if unit == "um" and curve.units in LENGTH_UNITS_UM:
        return value / LENGTH_UNITS_UM[curve.units]
    raise NurbsmotionError(
        f"cannot convert a feed with a length unit to a path in {curve.units or 'no unit'}; "
        "give a bare number in path units per second"
    )


def _feed_in_pulses(feed: tuple[float, str | None], machine: Machine, curve) -> float:
    """A parsed feed in the machine's pulse/s."""
    value, unit = feed
    if unit == "pulse":
        return value
    if unit == "um":
        return value * machine.pulses_per_unit("um")
    return value * machine.pulses_per_unit(curve.units)


def _load_path(spec: str):
    from .paths import resolve_path

    return resolve_path(spec)


def _cmd_interpolate(args) -> int:
    from .export import SetpointArrays, save_setpoints
    from .plots import plot_setpoints

    with _outputs(args) as staged:
        out = staged.staging
        curve = _load_path(args.path)
        feed = _feed_in_path_units(args.feed, curve)
        check_samples(estimate_samples(curve.length, feed, args.sample_period),
                      limit=args.max_samples, n_axes=curve.n_axes,
                      what=f"interpolating {curve.length:.6g} {curve.units or 'path units'} "
                           f"at {feed:g} per s every {args.sample_period:g} s",
                      option="--max-samples")
        series = interpolate(make_open_loop(args.method, curve, args.sample_period, feed),
                             max_samples=args.max_samples)
        names = _axis_names(curve.n_axes)
        save_setpoints(SetpointArrays(series.t, series.u, series.position, series.feed, names),
                       out / "setpoints.csv")
        plot_setpoints(series, out, axis_names=names)
    out = Path(args.out)
    fl_max, fl_rms = series.feed_fluctuation()
    print(f"{args.method}: {len(series.t)} samples, cycle time {series.cycle_time:.6g} s, "
          f"feed fluctuation max {fl_max:.3%} RMS {fl_rms:.3%} -> {out}")
    return 0


def _axis_names(n: int) -> list[str]:
    return list("xyzabc"[:n]) if n <= 6 else [f"axis{i}" for i in range(n)]


def _cmd_bound(args) -> int:
    from .loop import to_pulses

    curve = _load_path(args.path)
    machine = load_machine(args.machine)
    machine.check_path(curve.n_axes)
    feed = _feed_in_pulses(args.feed, machine, curve)
    bound = time_optimal_bound(to_pulses(curve, machine), machine, feed)
    print(f"{bound:.6g}")
    return 0


def _cmd_run(args) -> int:
    from .loop import check_run_arguments, run, to_pulses
    from .report import summary, write_json, write_trace_csv

    with _outputs(args) as staged:
        out = staged.staging
        curve = _load_path(args.path)
        machine = load_machine(args.machine)
        machine.check_path(curve.n_axes)
        feed = _feed_in_pulses(args.feed, machine, curve)
        check_run_arguments(curve, machine, feed, args.max_samples, option="--max-samples")
        exports = {fmt: out / EXPORT_FILES[fmt] for fmt in args.export or ()}
        if "pvt" in exports:
            length = curve.length * machine.pulses_per_unit(curve.units)  # [pulse]
            check_samples(estimate_samples(length, feed, args.pvt_period),
                          limit=args.max_samples, n_axes=curve.n_axes,
                          what=f"the PVT table at --pvt-period {args.pvt_period:g} s",
                          option="--max-samples (or a longer --pvt-period)")
        # The bound first: a path it cannot be computed for is refused before the run.
        bound = time_optimal_bound(to_pulses(curve, machine), machine, feed)
        trace = run(curve, machine, feed, args.interpolator, max_samples=args.max_samples)
        write_trace_csv(trace, out / "trace.csv")
        if exports:
            _export_setpoints(trace, curve, machine, exports, args)
        metrics = trace.metrics()
        data = summary(metrics, interpolator=args.interpolator, feed=feed,
                       machine=machine.name, path=args.path, time_optimal_bound=bound)
        write_json(data, out / "summary.json")
        if not args.no_figures:
            trace.plot(out, feed=feed)
    out = Path(args.out)
    sat = metrics.total_saturated_samples
    print(f"{args.interpolator} on {machine.name} at {feed:g} pulse/s: cycle time "
          f"{metrics.cycle_time_s:.4g} s ({metrics.cycle_time_s / bound:.3f} x the "
          f"time-optimal bound), max contour error {metrics.max_contour_error:.4g} "
          f"pulse, {sat} saturated sample{'s' if sat != 1 else ''} -> {out}")
    return 0


EXPORT_FILES = {"csv": "setpoints.csv", "npz": "setpoints.npz", "pvt": "pvt.csv",
                "gcode": "motion.ngc"}
"""``run --export`` formats and the files they write."""


def _export_setpoints(trace, curve, machine: Machine, files: dict, args) -> None:
    """The commanded setpoints of a run, in the path's own units (G-code: in mm)."""
    from .export import SetpointArrays, pvt_table, save_motion_gcode, save_pvt, save_setpoints

    scale = machine.pulses_per_unit(curve.units)
    end = trace.finished_index + 1
    sp = SetpointArrays(trace.t[:end], trace.u[:end], trace.position_command[:end] / scale,
                        trace.feed[:end] / scale, machine.axis_names)
    for fmt, file in files.items():
        if fmt in ("csv", "npz"):
            save_setpoints(sp, file, overwrite=args.overwrite)
        elif fmt == "pvt":
            save_pvt(pvt_table(sp, args.pvt_period), file, overwrite=args.overwrite)
        else:  # G-code is in mm whatever the path's units
            save_motion_gcode(sp, file, units="mm", overwrite=args.overwrite,
                              scale=scale / machine.pulses_per_unit("mm"))


def _cmd_reproduce(args) -> int:
    from .experiments import reproduce

    t0 = time.perf_counter()
    with _outputs(args) as staged:
        result = reproduce(staged.staging, figures=not args.no_figures)
    print((Path(args.out) / "table.md").read_text())
    print(f"{len(result.rows)} runs, {len(result.files)} files in {args.out} "
          f"({time.perf_counter() - t0:.1f} s)")
    return 0


def _outputs_of(args) -> list[str]:
    """Every file name the command of ``args`` may write: the one list its guard checks."""
    if args.command == "interpolate":
        from .plots import SETPOINT_FIGURES

        return ["setpoints.csv", *SETPOINT_FIGURES]
    if args.command == "run":
        from .plots import TRACE_FIGURES

        return (["trace.csv", "summary.json"] + [EXPORT_FILES[f] for f in args.export or ()]
                + ([] if args.no_figures else list(TRACE_FIGURES)))
    if args.command == "reproduce":
        from .experiments import reproduce_outputs

        return reproduce_outputs(figures=not args.no_figures)
    return []


def _outputs(args) -> OutputFolder:
    """The command's output folder: its files checked now, before any work, written
    through a staging folder and moved into place only when all are complete."""
    return OutputFolder(args.out, _outputs_of(args), overwrite=args.overwrite)


def _positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be finite and > 0, got {text!r}")
    return value


def _positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text!r}")
    return value


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (no usage block)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {_one_line(message)} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="nurbsmotion",
        description="NURBS interpolation for motion systems whose actuators saturate.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    feed_help = ("commanded feed: a number in path units per second, or a speed with a "
                 "unit such as 0.5m/s, 100mm/s, 600mm/min, 1e6pulse/s")

    i = sub.add_parser("interpolate", help="open-loop setpoints of a path at a feed")
    i.add_argument("path", help="path file (.json, .toml, ...) or built-in name "
                   "(die-bonder-pi, butterfly)")
    i.add_argument("--feed", type=parse_feed, required=True, help=feed_help)
    i.add_argument("--method", choices=OPEN_LOOP_METHODS, default="taylor2")
    i.add_argument("--sample-period", type=_positive_float, default=1e-3,
                   help="Ts [s] (default 0.001)")
    i.add_argument("--out", required=True, help="output folder")
    i.add_argument("--overwrite", action="store_true", help="replace existing output files")
    i.add_argument("--max-samples", type=_positive_int, default=MAX_SAMPLES,
                   help="refuse, before any work, a move estimated to take more samples "
                     f"than this (default {MAX_SAMPLES:.0e}, about 2.8 h at 1 ms)")
    i.set_defaults(func=_cmd_interpolate)

    r = sub.add_parser("run", help="closed-loop servo simulation of a path on a machine")
    r.add_argument("path", help="path file or built-in name")
    r.add_argument("--machine", default="die-bonder",
                   help="built-in machine name or machine file (.toml/.json)")
    r.add_argument("--feed", type=parse_feed, required=True, help=feed_help)
    r.add_argument("--interpolator", choices=LOOP_METHODS, default="paper")
    r.add_argument("--out", required=True, help="output folder")
    r.add_argument("--overwrite", action="store_true", help="replace existing output files")
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    r.add_argument("--export", action="append", choices=sorted(EXPORT_FILES),
                   help="also write the commanded setpoints (up to the end point, in the "
                   "path's units): csv, npz, pvt (position-velocity-time table), gcode "
                   "(LinuxCNC G1 per sample); repeat for several")
    r.add_argument("--pvt-period", type=_positive_float, default=0.01,
                   help="period of the PVT table [s] (default 0.01)")
    r.add_argument("--max-samples", type=_positive_int, default=MAX_SAMPLES,
                   help="refuse, before any work, a move estimated to take more samples "
                     f"than this (default {MAX_SAMPLES:.0e}, about 2.8 h at 1 ms)")
    r.set_defaults(func=_cmd_run)

    b = sub.add_parser("bound", help="print the time-optimal bound of a path [s]: the "
                       "least time at rest at both ends within the drive limits and the feed")
    b.add_argument("path", help="path file or built-in name")
    b.add_argument("--machine", default="die-bonder",
                   help="built-in machine name or machine file (.toml/.json)")
    b.add_argument("--feed", type=parse_feed, required=True, help=feed_help)
    b.set_defaults(func=_cmd_bound)

    e = sub.add_parser("reproduce", help="the paper's experiment on built-in defaults")
    e.add_argument("--out", default="results", help="output folder (default: results)")
    e.add_argument("--overwrite", action="store_true", help="replace existing output files")
    e.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    e.set_defaults(func=_cmd_reproduce)
    return p


def _one_line(text) -> str:
    """``text`` on one line (a library's message may embed newlines)."""
    return " ".join(str(text).split())


def _message(exc: BaseException) -> str:
    """What went wrong, for a user: the typed error's text, or a plain sentence."""
    if isinstance(exc, KeyError) and exc.args:
        return str(exc.args[0])
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.strerror}: {exc.filename}" if exc.filename else exc.strerror
    if isinstance(exc, MemoryError):
        return "out of memory; lower --max-samples or use a higher feed"
    if isinstance(exc, RecursionError):
        return "input nested too deeply to process"
    if isinstance(exc, OverflowError):
        return f"a number is too large for double precision ({exc})"
    return str(exc) or type(exc).__name__


@contextlib.contextmanager
def _one_line_warnings(command: str):
    """Warnings and log records as one line each on stderr, without the source echo."""
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"nurbsmotion {command}: warning: {_one_line(message)}", file=sys.stderr)

    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(f"nurbsmotion {command}: %(levelname)s: "
                                           "%(message)s"))
    logger = logging.getLogger("nurbsmotion")
    saved = warnings.showwarning
    warnings.showwarning = show
    logger.addHandler(handler)
    try:
        yield
    finally:
        warnings.showwarning = saved
        logger.removeHandler(handler)


USER_ERRORS = (NurbsmotionError, OSError, KeyError, ValueError, ArithmeticError,
               RecursionError, MemoryError)
"""Errors reported as one line and exit code 2: the library's typed errors, and what
the system, the parsers and the arithmetic raise on a bad file, folder or number."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``nurbsmotion`` command; returns the exit code.

    0 on success; 2 with one line on stderr for a bad input (nothing is written); 130
    when interrupted (Ctrl-C; nothing is written); 1 for an internal error.
    """
    parser = _parser()
    args = parser.parse_args(argv)
    with _one_line_warnings(args.command):
        try:
            return args.func(args)
        except KeyboardInterrupt:
            print(f"nurbsmotion {args.command}: interrupted; no output was written",
                  file=sys.stderr)
            return 130
        except USER_ERRORS as exc:
            print(f"nurbsmotion {args.command}: error: {_one_line(_message(exc))}",
                  file=sys.stderr)
            return 2
        except Exception as exc:  # a bug: still one line, and a distinct exit code
            print(f"nurbsmotion {args.command}: internal error: {type(exc).__name__}: "
                  f"{_one_line(exc)}", file=sys.stderr)
            return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
