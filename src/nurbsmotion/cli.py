"""Command-line interface: ``nurbsmotion interpolate | run | bound | reproduce``.

A thin layer over the library: it parses arguments, calls library functions, writes files
and turns the library's typed errors into one line on stderr and a non-zero exit code.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from . import units
from .errors import NurbsmotionError
from .interpolators import LOOP_METHODS, OPEN_LOOP_METHODS, make_open_loop
from .machine import Machine, load_machine
from .planning import time_optimal_bound

__all__ = ["main", "parse_feed"]


def parse_feed(text: str) -> tuple[float, str | None]:
    """argparse type of ``--feed``: :func:`nurbsmotion.units.parse_feed`, its error as an
    argparse error."""
    try:
        return units.parse_feed(text)
    except units.InvalidFeedError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _load_path(spec: str):
    from .paths import resolve_path

    return resolve_path(spec)


def _cmd_interpolate(args) -> int:
    from .export import SetpointArrays, save_setpoints
    from .loop import interpolate
    from .report import check_writable

    curve = _load_path(args.path)
    feed = units.feed_in_path_units(args.feed, curve)
    out = Path(args.out)
    check_writable([out / "setpoints.csv", out / "setpoints.png"], args.overwrite)
    series = interpolate(make_open_loop(args.method, curve, args.sample_period, feed))
    out.mkdir(parents=True, exist_ok=True)
    names = _axis_names(curve.n_axes)
    save_setpoints(SetpointArrays(series.t, series.u, series.position, series.feed, names),
                   out / "setpoints.csv", overwrite=args.overwrite)
    from .plots import plot_setpoints

    plot_setpoints(series, out, axis_names=names, units=curve.units or "pulse")
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
    feed = units.feed_in_pulses(args.feed, curve, machine)
    bound = time_optimal_bound(to_pulses(curve, machine), machine, feed)
    print(f"{bound:.6g}")
    return 0


TRACE_NOTICE_BYTES = 200e6
"""A trace file larger than this [byte] is announced with its size and the options to
make it smaller (``--trace-every``, ``--no-trace``)."""


def _progress(args, **kwargs):
    """A tqdm bar on stderr; silent when stderr is not a terminal or with ``--quiet``."""
    from tqdm import tqdm

    return tqdm(disable=True if args.quiet else None, leave=False, **kwargs)


def _cmd_run(args) -> int:
    from .loop import run
    from .report import TRACE_FILES, check_writable, summary, write_json

    curve = _load_path(args.path)
    machine = load_machine(args.machine)
    machine.check_path(curve.n_axes)
    feed = units.feed_in_pulses(args.feed, curve, machine)
    unit = units.report_unit(curve.units)
    per_unit = units.pulses_per_report_unit(curve.units, machine)
    out = Path(args.out)
    trace_file = None if args.no_trace else out / TRACE_FILES[args.trace_format]
    check_writable([f for f in (trace_file, out / "summary.json") if f], args.overwrite)
    if not args.no_figures:
        from .plots import TRACE_FIGURES

        check_writable([out / f for f in TRACE_FIGURES], args.overwrite)
    exports = {fmt: out / EXPORT_FILES[fmt] for fmt in args.export or ()}
    check_writable(exports.values(), args.overwrite)
    stages = ["plan and run the closed loop", "time-optimal bound", "metrics", "summary"]
    stages += [] if args.no_figures else ["figures"]
    with _progress(args, total=len(stages), unit="stage", desc=stages[0]) as bar:
        def stage(name: str) -> None:
            bar.set_description(name)

        stage(stages[0])
        trace = run(curve, machine, (feed, "pulse"), args.interpolator)
        bar.update()
        out.mkdir(parents=True, exist_ok=True)
        if trace_file is not None:
            _write_trace(args, trace, trace_file, unit, per_unit)
        if exports:
            _export_setpoints(trace, curve, machine, exports, args)
        stage(stages[1])
        bound = time_optimal_bound(trace.curve, machine, feed)
        bar.update()
        stage(stages[2])
        metrics = trace.metrics()
        bar.update()
        data = summary(metrics, interpolator=args.interpolator, feed=feed,
                       machine=machine.name, path=args.path, time_optimal_bound=bound,
                       length_unit=unit, pulses_per_length_unit=per_unit)
        write_json(data, out / "summary.json", overwrite=args.overwrite)
        bar.update()
        if not args.no_figures:
            stage(stages[4])
            trace.plot(out, feed=feed, length_unit=unit, overwrite=args.overwrite)
            bar.update()
    sat = metrics.total_saturated_samples
    print(f"{args.interpolator} on {machine.name} at {feed / per_unit:.4g} {unit}/s "
          f"({feed:.4g} pulse/s): cycle time {metrics.cycle_time_s:.4g} s "
          f"({metrics.cycle_time_s / bound:.3f} x the time-optimal bound), max contour error "
          f"{metrics.max_contour_error / per_unit:.4g} {unit} "
          f"({metrics.max_contour_error:.4g} pulse), {sat} saturated "
          f"sample{'s' if sat != 1 else ''} -> {out}")
    return 0


def _write_trace(args, trace, file: Path, unit: str, per_unit: float) -> None:
    """Write the trace file, announcing its size first when it is large."""
    from .report import estimate_trace_bytes, trace_rows, write_trace

    options = dict(fmt=args.trace_format, every=args.trace_every, length_unit=unit,
                   pulses_per_length_unit=per_unit)
    size = estimate_trace_bytes(trace, **options)
    rows = len(trace_rows(trace, args.trace_every))
    if size > TRACE_NOTICE_BYTES:
        every = max(2, round(size / TRACE_NOTICE_BYTES * 2))
        print(f"nurbsmotion run: writing {file.name}: {rows:,} rows, about "
              f"{size / 1e6:.3g} MB; --trace-every {every} keeps one row in {every}, "
              "--no-trace writes none (the summary and figures use every sample either "
              "way)" + ("" if args.trace_format == "parquet" else
                        ", --trace-format parquet is smaller"), file=sys.stderr)
    with _progress(args, total=rows, unit="row", unit_scale=True,
                   desc=f"write {file.name}") as bar:
        write_trace(trace, file, overwrite=args.overwrite, progress=bar.update, **options)


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
    with _progress(args, unit="run") as bar:
        def progress(done: int, total: int, label: str) -> None:
            bar.total = total
            bar.set_description(label)
            bar.update(done - bar.n)

        result = reproduce(args.out, overwrite=args.overwrite, figures=not args.no_figures,
                           progress=progress)
    if not args.quiet:
        print((Path(args.out) / "table.md").read_text())
    print(f"{len(result.rows)} runs, {len(result.files)} files in {args.out} "
          f"({time.perf_counter() - t0:.1f} s)")
    return 0


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows ``(default: ...)`` for options that have a default worth showing (not for
    required options, flags, or options without a default)."""

    def _get_help_string(self, action):
        if action.required or action.default in (None, False) or isinstance(
                action, argparse._StoreTrueAction):
            return action.help
        return super()._get_help_string(action)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("nurbsmotion")
    except PackageNotFoundError:  # running from a source tree that is not installed
        from . import __version__

        return __version__


def _parser() -> argparse.ArgumentParser:
    from .report import TRACE_FORMATS

    p = argparse.ArgumentParser(
        prog="nurbsmotion",
        description="NURBS interpolation for motion systems whose actuators saturate.",
        epilog="Reference: docs/cli.md; file formats: docs/formats.md; the model and every "
        "metric: docs/model.md.",
        formatter_class=_HelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    feed_help = ("commanded feed: a bare number in the path's units per second (pulse/s for "
                 "a path in pulses), or a speed with a unit: 0.5m/s, 100mm/s, 600mm/min, "
                 "2in/s, 1e6pulse/s")
    path_help = ("path: a built-in name (die-bonder-pi, butterfly) or a file .json, .toml, "
                 ".ngc/.nc/.gcode, .dxf; FILE#k picks the k-th contour of a file")
    machine_help = "built-in machine name (die-bonder) or a machine file (.toml/.json)"

    def command(name: str, help: str) -> argparse.ArgumentParser:
        return sub.add_parser(name, help=help, description=help,
                              formatter_class=_HelpFormatter)

    def common(c: argparse.ArgumentParser, out_default: str | None = None,
               progress: bool = True) -> None:
        if out_default is None:
            c.add_argument("--out", required=True, help="output folder (created)")
        else:
            c.add_argument("--out", default=out_default, help="output folder (created)")
        c.add_argument("--overwrite", action="store_true", help="replace existing output files")
        if progress:
            c.add_argument("--quiet", action="store_true",
                           help="no progress bar (there is none either when stderr is not "
                           "a terminal)")

    i = command("interpolate", "open-loop setpoints of a path at a constant feed")
    i.add_argument("path", help=path_help)
    i.add_argument("--feed", type=parse_feed, required=True, help=feed_help)
    i.add_argument("--method", choices=OPEN_LOOP_METHODS, default="taylor2",
                   help="interpolation: uniform parameter steps, or Taylor of 1st/2nd order")
    i.add_argument("--sample-period", type=float, default=1e-3, help="Ts [s]")
    common(i, progress=False)  # open loop: done in a moment
    i.set_defaults(func=_cmd_interpolate)

    r = command("run", "closed-loop servo simulation of a path on a machine")
    r.add_argument("path", help=path_help)
    r.add_argument("--machine", default="die-bonder", help=machine_help)
    r.add_argument("--feed", type=parse_feed, required=True, help=feed_help)
    r.add_argument("--interpolator", choices=LOOP_METHODS, default="planned",
                   help="planned: look-ahead, plans every drive within ±Umax; paper: Yeh & "
                   "Sun (2008), saturation-aware one step ahead; taylor1/taylor2: constant "
                   "feed")
    common(r)
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    r.add_argument("--no-trace", action="store_true",
                   help="write no trace file (the summary and figures use every sample "
                   "either way)")
    r.add_argument("--trace-every", type=_positive_int, default=1, metavar="N",
                   help="keep one trace row in N (and the rows where the end is reached and "
                   "the last)")
    r.add_argument("--trace-format", choices=TRACE_FORMATS, default="csv",
                   help="trace.csv or trace.parquet (smaller, faster to read)")
    r.add_argument("--export", action="append", choices=sorted(EXPORT_FILES),
                   help="also write the commanded setpoints (up to the end point, in the "
                   "path's units): csv, npz, pvt (position-velocity-time table), gcode "
                   "(LinuxCNC G1 per sample, in mm); repeat for several")
    r.add_argument("--pvt-period", type=float, default=0.01,
                   help="period of the PVT table [s]")
    r.set_defaults(func=_cmd_run)

    b = command("bound", "print the time-optimal bound of a path [s]: the least time at "
                "rest at both ends within the drive limits and the feed")
    b.add_argument("path", help=path_help)
    b.add_argument("--machine", default="die-bonder", help=machine_help)
    b.add_argument("--feed", type=parse_feed, required=True, help=feed_help)
    b.set_defaults(func=_cmd_bound)

    e = command("reproduce", "the paper's experiment on built-in defaults: the Π and the "
                "butterfly at three feeds each, taylor1 / paper / planned")
    common(e, out_default="results")
    e.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    e.set_defaults(func=_cmd_reproduce)
    return p


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``nurbsmotion`` command; returns the exit code."""
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (NurbsmotionError, FileExistsError, FileNotFoundError, KeyError, ValueError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"nurbsmotion {args.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
