"""Command-line interface: ``nurbsmotion interpolate | run | bound | reproduce | campaign``.

A thin layer over the library: it parses arguments, calls library functions, writes files
and turns the library's typed errors into one line on stderr and a non-zero exit code.
"""

from __future__ import annotations

import argparse
import re
import signal
import sys
import time
from pathlib import Path

import numpy as np

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
    from .report import check_writable

    curve = _load_path(args.path)
    feed = _feed_in_path_units(args.feed, curve)
    out = Path(args.out)
    check_writable([out / "setpoints.csv", out / "setpoints.png"], args.overwrite)
    series = interpolate(make_open_loop(args.method, curve, args.sample_period, feed))
    out.mkdir(parents=True, exist_ok=True)
    names = _axis_names(curve.n_axes)
    save_setpoints(SetpointArrays(series.t, series.u, series.position, series.feed, names),
                   out / "setpoints.csv", overwrite=args.overwrite)
    from .plots import plot_setpoints

    plot_setpoints(series, out, axis_names=names)
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
    from .loop import run
    from .report import summary, write_json, write_trace_csv, check_writable

    curve = _load_path(args.path)
    machine = load_machine(args.machine)
    machine.check_path(curve.n_axes)
    feed = _feed_in_pulses(args.feed, machine, curve)
    out = Path(args.out)
    check_writable([out / "trace.csv", out / "summary.json"], args.overwrite)
    exports = {fmt: out / EXPORT_FILES[fmt] for fmt in args.export or ()}
    check_writable(exports.values(), args.overwrite)
    trace = run(curve, machine, feed, args.interpolator)
    out.mkdir(parents=True, exist_ok=True)
    write_trace_csv(trace, out / "trace.csv")
    if exports:
        _export_setpoints(trace, curve, machine, exports, args)
    metrics = trace.metrics()
    bound = time_optimal_bound(trace.curve, machine, feed)
    data = summary(metrics, interpolator=args.interpolator, feed=feed, machine=machine.name,
                   path=args.path, time_optimal_bound=bound)
    write_json(data, out / "summary.json")
    if not args.no_figures:
        trace.plot(out, feed=feed)
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
    result = reproduce(args.out, overwrite=args.overwrite, figures=not args.no_figures)
    print((Path(args.out) / "table.md").read_text())
    print(f"{len(result.rows)} runs, {len(result.files)} files in {args.out} "
          f"({time.perf_counter() - t0:.1f} s)")
    return 0


def _cmd_campaign(args) -> int:
    from .campaign import find_case, load_study, run_study

    study = load_study(args.study)
    out = Path(args.out) if args.out else Path(args.study).with_suffix("").with_name(
        Path(args.study).stem + "-campaign")
    if args.case:
        return _campaign_case(find_case(study, args.case), out / args.case, args)
    # A machine that shuts down sends SIGTERM: stop as on Ctrl-C, finished rows written.
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        result = run_study(study, out, workers=args.workers, scheduler=args.scheduler,
                           resume=args.resume, overwrite=args.overwrite,
                           progress=not args.no_progress)
    except KeyboardInterrupt:
        print(f"nurbsmotion campaign: interrupted; the finished cases are in {out}/rows; "
              f"go on with: nurbsmotion campaign {args.study} --out {out} --resume",
              file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)
    print(f"{result.n_cases} cases: {result.computed} run now, {result.skipped} already "
          f"done, {result.failed} failed, {result.wall_time_s:.1f} s -> {out}/digest.md")
    return 0


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def _campaign_case(case, out: Path, args) -> int:
    """``campaign --case ID``: one case's normal run output."""
    from .campaign import case_trace
    from .report import check_writable, write_json, write_trace_csv

    check_writable([out / "trace.csv", out / "summary.json"], args.overwrite)
    trace, data, _, _ = case_trace(case)
    out.mkdir(parents=True, exist_ok=True)
    write_trace_csv(trace, out / "trace.csv")
    write_json(data, out / "summary.json")
    if not args.no_figures:
        trace.plot(out, feed=data["feed"])
    print(f"{case.case_id}: {case.interpolator} on {case.machine}, {case.path} at "
          f"{case.feed_value:g} {case.feed_unit}, plant {case.plant.name}: cycle time "
          f"{data['cycle_time_s']:.4g} s, max contour error {data['max_contour_error']:.4g} "
          f"pulse -> {out}")
    return 0


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
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
    i.add_argument("--sample-period", type=float, default=1e-3, help="Ts [s] (default 0.001)")
    i.add_argument("--out", required=True, help="output folder")
    i.add_argument("--overwrite", action="store_true", help="replace existing output files")
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
    r.add_argument("--pvt-period", type=float, default=0.01,
                   help="period of the PVT table [s] (default 0.01)")
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

    c = sub.add_parser("campaign", help="run a study (paths x feeds x machines x plants x "
                       "interpolators) into a Parquet dataset and a digest")
    c.add_argument("study", help="study file (.toml; see docs/campaign.md)")
    c.add_argument("--out", help="output folder (default: the study file's name + "
                   "'-campaign', beside it)")
    c.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    c.add_argument("--scheduler", help="address of a Dask scheduler (tcp://host:8786): run "
                   "the cases on that cluster")
    c.add_argument("--resume", action="store_true", help="keep the finished cases of an "
                   "existing output folder and run the others")
    c.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    c.add_argument("--case", help="re-run one case (e.g. c0000042) and write its run output "
                   "(trace.csv, summary.json, figures) into OUT/ID")
    c.add_argument("--no-figures", action="store_true", help="with --case: skip the figures")
    c.add_argument("--no-progress", action="store_true", help="no progress bar")
    c.set_defaults(func=_cmd_campaign)
    return p


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
