"""The argparse tree of the ``nurbsmotion`` command and its argument types.

:func:`_parser` builds it (each command's options, help texts and its function of
:mod:`.commands`); errors are one line (:class:`_Parser`) with a close choice suggested;
:func:`synopsis` is its usage, from the parser itself (docs/cli.md opens with it).
"""

from __future__ import annotations

import argparse
import math

from ..limits import (DEFAULT_INTERPOLATOR, DEFAULT_PATH_TOLERANCE, LOOP_METHODS, MAX_SAMPLES,
                      MIN_SAMPLE_PERIOD, OPEN_LOOP_METHODS, PATH_UNITS, SHORT_MOVE_SAMPLES,
                      TRACE_FORMATS)
from .commands import (_cmd_bound, _cmd_campaign, _cmd_contours, _cmd_excite, _cmd_identify,
                       _cmd_interpolate, _cmd_reproduce, _cmd_run, _parse_columns)
from .console import EXPORT_FILES, _one_line

def parse_feed(text: str) -> tuple[float, str | None]:
    """argparse type of ``--feed``: :func:`nurbsmotion.units.parse_feed`, its error as an
    argparse error."""
    from .. import units

    try:
        return units.parse_feed(text)
    except units.InvalidFeedError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows ``(default: ...)`` for options that have a default worth showing (not for
    required options, flags, or options without a default)."""

    def _get_help_string(self, action):
        if action.required or action.default in (None, False) or isinstance(
                action, argparse._StoreTrueAction) or "(default:" in (action.help or ""):
            return action.help  # (the help that states its default itself says it once)
        return super()._get_help_string(action)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("nurbsmotion")
    except PackageNotFoundError:  # running from a source tree that is not installed
        from .. import __version__

        return __version__


class _VersionAction(argparse._VersionAction):
    """``--version``: the installed version, looked up when asked for (importlib.metadata
    costs a twentieth of a second of every start-up otherwise)."""

    def __call__(self, parser, namespace, values, option_string=None):
        self.version = f"%(prog)s {_version()}"
        super().__call__(parser, namespace, values, option_string)


def _float_above(low: float, inclusive: bool):
    """argparse type: a finite number > ``low`` (>= with ``inclusive``)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not (math.isfinite(value) and (value >= low if inclusive else value > low)):
            raise argparse.ArgumentTypeError(
                f"must be finite and {'>=' if inclusive else '>'} {low:g}, got {text!r}")
        return value
    return parse


_positive_float = _float_above(0.0, inclusive=False)
_non_negative_float = _float_above(0.0, inclusive=True)


def _sample_period(text: str) -> float:
    """argparse type: a sample period [s] of at least the machines' minimum."""
    value = _positive_float(text)
    if value < MIN_SAMPLE_PERIOD:
        raise argparse.ArgumentTypeError(
            f"{text!r} s is below the minimum sample period of {MIN_SAMPLE_PERIOD:g} s "
            "(machine.MIN_SAMPLE_PERIOD); is it in seconds?")
    return value


def _int_at_least(low: int):
    """argparse type: an integer >= ``low`` (a seed >= 0: NumPy's "expected non-negative
    integer" leaked for -1; a count >= 1)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {text!r}")
        return value
    return parse


_non_negative_int = _int_at_least(0)
_positive_int = _int_at_least(1)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (no usage block)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {_one_line(message)}{_did_you_mean(message)} "
                     f"(see {self.prog} --help)\n")


def _did_you_mean(message: str) -> str:
    """``; did you mean 'run'?`` for argparse's invalid choice of a command or an option
    value that is close to one of the choices (difflib's ratio), else ``""``."""
    import difflib
    import re

    found = re.search(r"invalid choice: '([^']*)' \(choose from ([^)]*)\)", message)
    if not found:
        return ""
    choices = re.findall(r"'([^']*)'", found.group(2))
    close = difflib.get_close_matches(found.group(1), choices, n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="nurbsmotion",
        description="NURBS interpolation for motion systems whose actuators saturate.",
        epilog="Reference: docs/cli.md; file formats: docs/formats.md; the model and every "
        "metric: docs/model.md.",
        formatter_class=_HelpFormatter,
    )
    p.add_argument("--version", action=_VersionAction)
    sub = p.add_subparsers(dest="command", required=True)
    feed_help = ("commanded feed: a bare number in the path's units per second (pulse/s for "
                 "a path in pulses), or a speed with a unit: 0.5m/s, 100mm/s, 600mm/min, "
                 "2in/s, 1e6pulse/s; optional where the file gives a feed (G-code F), which "
                 "it then caps piece by piece")
    units_help = (f"read the path's numbers in this unit ({', '.join(PATH_UNITS)}), whatever "
                  "the file says (default: the file's unit; mm, with a warning, if it has none)")
    path_help = ("path: a built-in name (die-bonder-pi, butterfly) or a file .json, .toml, "
                 ".ngc/.nc/.gcode, .dxf; FILE#k picks the k-th contour of a file")
    machine_help = "built-in machine name (die-bonder) or a machine file (.toml/.json)"
    path_tolerance_help = (
        "how far the path run may leave the programmed one: runs of short chords (CAM "
        "output) whose joints turn by small angles are joined into one smooth curve within "
        "it, real corners kept (0: the chords as programmed); a length (2um) or a number of "
        f"pulses (default: {DEFAULT_PATH_TOLERANCE:g} pulse)")

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

    def tool_table(c):
        """``--tool-table``: where a G-code program's cutter compensation finds its tools."""
        c.add_argument("--tool-table", metavar="FILE",
                       help="LinuxCNC tool table (.tbl: T1 P1 D6.0 per line) whose diameters "
                       "a G-code program's cutter radius compensation (G41/G42 D<tool>, or "
                       "the tool of T M6) uses, in the program's units (default: PROGRAM.tbl "
                       "beside the program, if there is one)")

    def path_input(c, machine=True):
        """The path, its machine, feed, units, projection and tool table, as run reads them."""
        c.add_argument("path", help=path_help)
        if machine:
            c.add_argument("--machine", default="die-bonder", help=machine_help)
        c.add_argument("--feed", type=parse_feed, help=feed_help)
        c.add_argument("--units", choices=PATH_UNITS, help=units_help)
        tool_table(c)
        c.add_argument("--project", metavar="AXES",
                       help="read a G-code file's moves as their projection on the "
                       "machine's axes (e.g. xy: a helix becomes its circle, a Z move is "
                       "dropped) instead of refusing moves that change other axes with them")

    i = command("interpolate", "open-loop setpoints of a path at a constant feed")
    path_input(i, machine=False)  # its --machine says what it is for here
    i.add_argument("--machine", default=None,
                   help=machine_help + " (default die-bonder): the path is read on it as "
                   "run reads it (the axes of G-code and DXF, rotary axes, the pulse of "
                   "--path-tolerance); the setpoints stay in the path's units. Given, it also "
                   "converts a --feed with a length unit on a path in pulses (its pulse "
                   "length)")
    i.add_argument("--path-tolerance", help=path_tolerance_help)
    i.add_argument("--method", default="taylor2", choices=OPEN_LOOP_METHODS,
                   help="interpolation: uniform parameter steps, or Taylor of 1st/2nd order")
    i.add_argument("--sample-period", type=_sample_period, default=1e-3,
                   help=f"Ts [s], at least {MIN_SAMPLE_PERIOD:g}")
    i.add_argument("--max-samples", type=_positive_int,
                   default=MAX_SAMPLES,
                   help="refuse, before any work, a move estimated to take more samples "
                   "than this (about 2.8 h at 1 ms)")
    common(i, progress=False)  # open loop: done in a moment
    i.set_defaults(func=_cmd_interpolate)

    r = command("run", "closed-loop servo simulation of a path on a machine")
    path_input(r)
    r.add_argument("--interpolator", default=DEFAULT_INTERPOLATOR, choices=LOOP_METHODS,
                   help="planned: plans the actual motion within ±Umax and steers the plant "
                   "along it; paper: Yeh & Sun (2008), saturation-aware one step ahead; "
                   "taylor1/taylor2: constant feed")
    r.add_argument("--plant", metavar="MACHINE",
                   help="simulate a true plant whose tau, Kc, Ke per axis and effects "
                   "(encoder counts, noise, delay, DAC, friction, load steps, a two-mass "
                   "mode) come from this machine (its gains are ignored), while the "
                   "controller and the planner use --machine (default: the --machine's "
                   "own plant)")
    r.add_argument("--hold", type=_non_negative_float, default=None, metavar="SECONDS",
                   help="go on this long after the motion has settled, to see what it does "
                   "at rest (default: 0.3 s where the true plant has any effect, else 0)")
    r.add_argument("--corner-tolerance", default="0",
                   help="planned: how far the motion may leave a sharp corner instead of "
                   "stopping there, a length (0.5mm, 10um) or a number in the path's units")
    r.add_argument("--path-tolerance", help=path_tolerance_help + "; planned: also how far "
                   f"from the path a short move (a plan of at most {SHORT_MOVE_SAMPLES:d} "
                   "samples; with stops, planned from stop to stop) may go where that lets "
                   "it arrive sooner")
    settle_window_help = ("the motion has settled once it stays within this distance of "
                          "the end point: a length (1um, 0.001mm) or a number of pulses "
                          "(default: 1 pulse)")
    r.add_argument("--settle-window", default="1", help=settle_window_help)
    common(r)
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    r.add_argument("--no-trace", action="store_true",
                   help="write no trace file (the summary and figures use every sample "
                   "either way)")
    r.add_argument("--trace-every", type=_positive_int, default=1, metavar="N",
                   help="keep one trace row in N (and the rows where the end is reached and "
                   "the last)")
    r.add_argument("--trace-format", default="csv", choices=TRACE_FORMATS,
                   help="trace.csv or trace.parquet (smaller, faster to read)")
    r.add_argument("--export", action="append", choices=sorted(EXPORT_FILES),
                   help="also write the commanded setpoints (up to the end point, in the "
                   "path's units, to a thousandth of a pulse): csv, npz, pvt "
                   "(position-velocity-time table), gcode (LinuxCNC G1 per sample, in mm), "
                   "halstreamer (one line per servo period for LinuxCNC's halstreamer, in mm), "
                   "ros (ROS 2 JointTrajectory YAML at --pvt-period, in m); repeat for several")
    r.add_argument("--pvt-period", type=_positive_float, default=0.01,
                   help="period of the PVT table [s]")
    r.add_argument("--max-samples", type=_positive_int,
                   default=MAX_SAMPLES,
                   help="refuse, before any work, a move estimated to take more samples "
                   "than this (about 2.8 h at 1 ms)")
    r.set_defaults(func=_cmd_run)

    b = command("bound", "print the time-optimal bound of a path [s]: the least time at "
                "rest at both ends within the drive limits and the feed")
    path_input(b)
    b.add_argument("--path-tolerance", help=path_tolerance_help)
    b.add_argument("--sampled", action="store_true",
                   help="print instead a lower bound for any sampled motion along the path "
                   "within Umax [s]: whole samples between the corners where every axis "
                   "stops or starts, each stretch at least what the slowest axis needs from "
                   "rest to rest, and at least the time out to the farthest point and back "
                   "(ignores the feed; within 1 pulse of the path, and --settle-window of the end)")
    b.add_argument("--settle-window", default="1", help=settle_window_help + "; a path "
                   "that stays within it of its end is refused, as run refuses it")
    b.add_argument("--max-samples", type=_positive_int,
                   default=MAX_SAMPLES,
                   help="refuse, as run does, a move estimated (or bounded) to take more "
                   "samples than this")
    b.set_defaults(func=_cmd_bound)

    c = command("contours", "list the contours of a path file: index, pieces, length, "
                "bounding box, units, programmed feed (pick one with FILE#k)")
    c.add_argument("path", help="path file (.ngc, .dxf, .json, ...)")
    c.add_argument("--axes", help="read G-code and DXF on these path axes, e.g. xy or xyz, as a "
                   "machine with them would (default: every axis the file moves)")
    c.add_argument("--units", choices=PATH_UNITS, help=units_help)
    tool_table(c)
    c.set_defaults(func=_cmd_contours)

    e = command("reproduce", "the paper's experiment on built-in defaults: the Π and the "
                "butterfly at three feeds each, taylor1 / paper / planned")
    common(e, out_default="results")
    e.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    e.set_defaults(func=_cmd_reproduce)

    c = command("campaign", "run a study (paths x feeds x machines x plants x "
                "interpolators) into a Parquet dataset and a digest")
    c.add_argument("study", help="study file (.toml; see docs/campaign.md)")
    c.add_argument("--out", help="output folder (default: the study file's name + "
                   "'-campaign', beside it)")
    c.add_argument("--workers", type=_positive_int,
                   help="local worker processes (default: all cores)")
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
    d = command("identify", "fit a machine file (tau, Kc, delay, friction, a mode) to a "
                "log of drive and encoder position; gains from --machine")
    d.add_argument("log", help="log: CSV with a header (t, <axis>_drive [V], <axis>_pos) "
                   "or a trace.csv / trace.parquet of nurbsmotion run")
    d.add_argument("--out", required=True, help="machine file to write (.toml); "
                   "identify.json and identify.png go beside it")
    d.add_argument("--machine", default="die-bonder", help=machine_help + ": its axes, "
                   "Ke, gains, drive limit and sample period")
    d.add_argument("--columns", type=_parse_columns, help="the log's names for t, "
                   "<axis>_drive, <axis>_pos: KEY=NAME,... (e.g. x_pos=enc0,t=time)")
    d.add_argument("--sample-period", type=_positive_float,
                   help="Ts [s] of a log without a t column")
    d.add_argument("--units", default="pulse", help="unit of the log's positions "
                   "(pulse, um, mm, cm, m, in)")
    d.add_argument("--overwrite", action="store_true", help="replace existing output files")
    d.add_argument("--no-figures", action="store_true", help="skip identify.png")
    d.set_defaults(func=_cmd_identify)

    x = command("excite", "a short test sequence that makes every parameter identifiable: "
                "drive commands (.csv) or position moves (.ngc)")
    x.add_argument("--machine", default="die-bonder", help=machine_help)
    x.add_argument("--out", required=True, help="excitation.csv or excitation.ngc")
    x.add_argument("--travel", help="bound of the excursion from the start, a length "
                   "(20mm) or pulses (default: 20 mm)")
    x.add_argument("--seed", type=_non_negative_int, default=0,
                   help="seed of the random binary part (an integer >= 0)")
    x.add_argument("--overwrite", action="store_true", help="replace an existing file")
    x.set_defaults(func=_cmd_excite)
    return p


def synopsis(width: int = 88) -> str:
    """The command's synopsis, from the parser itself: the top-level usage, then each
    command's, wrapped at ``width`` columns (docs/cli.md opens with it; a test checks
    that it is this text)."""
    parser = _parser()

    def usage(p: argparse.ArgumentParser) -> str:
        formatter = argparse.HelpFormatter(p.prog, width=width)
        formatter.add_usage(p.usage, p._actions, p._mutually_exclusive_groups, prefix="")
        return formatter.format_help().strip()

    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return "\n".join([usage(parser)] + [usage(c) for c in sub.choices.values()])
