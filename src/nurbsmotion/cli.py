"""Command-line interface: ``nurbsmotion interpolate | run | bound | reproduce``.

A thin layer over the library: it parses arguments, calls library functions, writes files
and turns the library's typed errors into one line on stderr and a non-zero exit code.
"""

from __future__ import annotations

import argparse
import re
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


def _contour(args, machine: Machine | None = None):
    """The path named on the command line with its programmed feed (a ``Contour``): read
    with ``--units`` and, for G-code and DXF, the machine's axes (XY without a machine)."""
    from .paths import resolve_contour

    names = [a.lower() for a in machine.axis_names] if machine is not None else ["x", "y"]
    axes = "".join(names) if all(len(a) == 1 and a in "xyzabcuvw" for a in names) else "xy"
    return resolve_contour(args.path, axes=axes, units=args.units)


def _feed_used(args, contour, cap, scale: float, unit: str):
    """The feed a command runs at, and a sentence saying which it is.

    ``cap`` is ``--feed`` in the target unit (None if not given), ``scale`` converts the
    path's units to the target unit (``unit``, e.g. ``"pulse/s"``). Where the file gives a
    feed (G-code F), it is the limit along the path and ``--feed`` caps it (the lower of the
    two per piece); where it gives none, ``--feed`` is required.

    Returns
    -------
    feed : float or FeedLimit
    note : str
    """
    programmed = contour.feed
    if programmed is None:
        if cap is None:
            raise NurbsmotionError(f"--feed is required: {args.path} gives no programmed feed")
        return cap, f"--feed {cap:.6g} {unit}"
    limit = programmed.scaled(scale)
    span = (f"{limit.lowest:.6g}" if limit.lowest == limit.highest
            else f"{limit.lowest:.6g} to {limit.highest:.6g}")
    if cap is None:
        return limit, f"the file's programmed feed ({span} {unit})"
    capped = limit.capped(cap)
    return capped, f"the lower of the file's programmed feed ({span} {unit}) and --feed {cap:.6g} {unit} per piece"


def _setup_warnings() -> None:
    """Warnings (G-code, DXF, path files) as one line each on stderr through ``logging``,
    without Python's source-line echo (``main`` restores the previous display after)."""
    import logging
    import warnings

    class _Stderr(logging.Handler):  # the stderr of the moment (tests swap it)
        def emit(self, record):
            print(self.format(record), file=sys.stderr)

    log = logging.getLogger("nurbsmotion")
    if not any(getattr(h, "nurbsmotion_cli", False) for h in log.handlers):
        handler = _Stderr()
        handler.nurbsmotion_cli = True
        handler.setFormatter(logging.Formatter("nurbsmotion: warning: %(message)s"))
        log.addHandler(handler)
        log.propagate = False

    def show(message, category, filename, lineno, file=None, line=None):
        log.warning(" ".join(str(message).split()))

    warnings.showwarning = show


def _cmd_contours(args) -> int:
    from .paths import load_contours

    contours = load_contours(args.path, axes=args.axes, units=args.units)
    print(f"{args.path}: {len(contours)} contour{'s' if len(contours) != 1 else ''} "
          f"(choose one with {args.path}#k)")
    print("| # | pieces | length | bounding box | units | programmed feed |")
    print("|---|---|---|---|---|---|")
    for k, c in enumerate(contours, start=1):
        curve = c.curve
        pts = curve(np.linspace(0.0, 1.0, 64 * max(curve.n_control_points, 2)))
        box = " ".join(f"{n}[{lo:.6g}, {hi:.6g}]" for n, lo, hi in
                       zip(_axis_names(curve.n_axes), pts.min(axis=0), pts.max(axis=0)))
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
    from .export import SetpointArrays, save_setpoints
    from .report import check_writable

    contour = _contour(args)
    curve = contour.curve
    cap = None if args.feed is None else _feed_in_path_units(args.feed, curve)
    feed, note = _feed_used(args, contour, cap, 1.0, f"{curve.units}/s")
    if args.method == "uniform" and not isinstance(feed, (int, float)):
        feed, note = feed.lowest, f"{note}: its lowest value (uniform steps have one feed)"
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
          f"feed fluctuation max {fl_max:.3%} RMS {fl_rms:.3%}; feed: {note} -> {out}")
    return 0


def _axis_names(n: int) -> list[str]:
    return list("xyzabc"[:n]) if n <= 6 else [f"axis{i}" for i in range(n)]


def _cmd_bound(args) -> int:
    from .loop import to_pulses

    machine = load_machine(args.machine)
    contour = _contour(args, machine)
    curve = contour.curve
    machine.check_path(curve.n_axes)
    cap = None if args.feed is None else _feed_in_pulses(args.feed, machine, curve)
    feed, note = _feed_used(args, contour, cap, machine.pulses_per_unit(curve.units), "pulse/s")
    bound = time_optimal_bound(to_pulses(curve, machine), machine, feed)
    print(f"{bound:.6g}")
    if contour.feed is not None:
        print(f"feed: {note}", file=sys.stderr)
    return 0


def _cmd_run(args) -> int:
    from .loop import run
    from .report import summary, write_json, write_trace_csv, check_writable

    machine = load_machine(args.machine)
    contour = _contour(args, machine)
    curve = contour.curve
    machine.check_path(curve.n_axes)
    cap = None if args.feed is None else _feed_in_pulses(args.feed, machine, curve)
    limit, note = _feed_used(args, contour, cap, machine.pulses_per_unit(curve.units), "pulse/s")
    feed = limit
    if not isinstance(limit, (int, float)):
        if args.interpolator.startswith("taylor"):  # the Taylor steppers read V(u)
            feed = limit
        else:  # paper/planned take one feed: the lowest programmed one
            feed, note = limit.lowest, f"{note}: its lowest value ({args.interpolator} takes one feed)"
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
    feed_number = feed if isinstance(feed, (int, float)) else feed.highest
    data = summary(metrics, interpolator=args.interpolator, feed=feed_number, machine=machine.name,
                   path=args.path, time_optimal_bound=bound)
    if contour.feed is not None:  # the file gave a feed: say which one ran
        data["feed_used"] = note
    write_json(data, out / "summary.json")
    if not args.no_figures:
        trace.plot(out, feed=feed_number)
    sat = metrics.total_saturated_samples
    print(f"{args.interpolator} on {machine.name} at {note}: cycle time "
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


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="nurbsmotion",
        description="NURBS interpolation for motion systems whose actuators saturate.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    feed_help = ("commanded feed: a number in path units per second, or a speed with a "
                 "unit such as 0.5m/s, 100mm/s, 600mm/min, 1e6pulse/s; optional where the "
                 "file gives a feed (G-code F), which it then caps piece by piece")
    from .paths import PATH_UNITS

    units_help = (f"read the path's numbers in this unit ({', '.join(PATH_UNITS)}), whatever "
                  "the file says (default: the file's unit; mm, with a warning, if it has none)")

    i = sub.add_parser("interpolate", help="open-loop setpoints of a path at a feed")
    i.add_argument("path", help="path file (.json, .toml, ...) or built-in name "
                   "(die-bonder-pi, butterfly)")
    i.add_argument("--feed", type=parse_feed, help=feed_help)
    i.add_argument("--units", choices=PATH_UNITS, help=units_help)
    i.add_argument("--method", choices=OPEN_LOOP_METHODS, default="taylor2")
    i.add_argument("--sample-period", type=float, default=1e-3, help="Ts [s] (default 0.001)")
    i.add_argument("--out", required=True, help="output folder")
    i.add_argument("--overwrite", action="store_true", help="replace existing output files")
    i.set_defaults(func=_cmd_interpolate)

    r = sub.add_parser("run", help="closed-loop servo simulation of a path on a machine")
    r.add_argument("path", help="path file or built-in name")
    r.add_argument("--machine", default="die-bonder",
                   help="built-in machine name or machine file (.toml/.json)")
    r.add_argument("--feed", type=parse_feed, help=feed_help)
    r.add_argument("--units", choices=PATH_UNITS, help=units_help)
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
    b.add_argument("--feed", type=parse_feed, help=feed_help)
    b.add_argument("--units", choices=PATH_UNITS, help=units_help)
    b.set_defaults(func=_cmd_bound)

    c = sub.add_parser("contours", help="list the contours of a path file: index, pieces, "
                       "length, bounding box, units, programmed feed (pick one with FILE#k)")
    c.add_argument("path", help="path file (.ngc, .dxf, .json, ...)")
    c.add_argument("--axes", default="xy", help="the machine's path axes for G-code and DXF, "
                   "e.g. xy or xyz (default xy)")
    c.add_argument("--units", choices=PATH_UNITS, help=units_help)
    c.set_defaults(func=_cmd_contours)

    e = sub.add_parser("reproduce", help="the paper's experiment on built-in defaults")
    e.add_argument("--out", default="results", help="output folder (default: results)")
    e.add_argument("--overwrite", action="store_true", help="replace existing output files")
    e.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    e.set_defaults(func=_cmd_reproduce)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``nurbsmotion`` command; returns the exit code."""
    import warnings

    parser = _parser()
    args = parser.parse_args(argv)
    shown = warnings.showwarning
    _setup_warnings()
    try:
        return args.func(args)
    except (NurbsmotionError, FileExistsError, FileNotFoundError, KeyError, ValueError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"nurbsmotion {args.command}: error: {msg}", file=sys.stderr)
        return 2
    finally:
        warnings.showwarning = shown


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
