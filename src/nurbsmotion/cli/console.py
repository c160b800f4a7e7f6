"""What the command shows and guards: progress bars, one-line warnings and errors,
Ctrl-C and SIGTERM, and the output folder's list of files.

:func:`_one_line_warnings` prints warnings and log records as one line each;
:func:`_interruptible` turns Ctrl-C and SIGTERM into KeyboardInterrupt wherever the
command is (retried outside numba's compiler callbacks); :data:`USER_ERRORS` are the
errors reported as one line with exit code 2. :func:`_outputs` is a command's output
folder, checked against every file name it may write (:func:`_outputs_of`,
:func:`project_outputs`) before any work.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
import threading
import warnings

from .._runtime.io import OutputFolder
from ..errors import NurbsmotionError


def _progress(args, **kwargs):
    """A tqdm bar on stderr; silent when stderr is not a terminal or with ``--quiet``."""
    from tqdm import tqdm

    return tqdm(disable=True if args.quiet else None, leave=False, **kwargs)


EXPORT_FILES = {"csv": "setpoints.csv", "npz": "setpoints.npz", "pvt": "pvt.csv",
                "halstreamer": "halstreamer.txt", "ros": "trajectory.yaml",
                "gcode": "motion.ngc"}
"""``run --export`` formats and the files they write."""


def _with_metadata(names: list) -> list:
    """``names`` and, after each CSV file, its CSV on the Web metadata file
    (``<name>.csv-metadata.json``, :func:`nurbsmotion.report.export.metadata_file`)."""
    return [m for n in names for m in ([n, n + "-metadata.json"] if n.endswith(".csv") else [n])]


def _outputs_of(args) -> list[str]:
    """Every file name the command of ``args`` may write: the one list its guard checks."""
    return _with_metadata(_data_outputs_of(args))


def _data_outputs_of(args) -> list[str]:
    if args.command == "interpolate":
        from ..plots import SETPOINT_FIGURES

        return ["setpoints.csv", *SETPOINT_FIGURES]
    if args.command == "run":
        from ..plots import TRACE_FIGURES

        from ..report import TRACE_FILES

        return (([] if args.no_trace else [TRACE_FILES[args.trace_format]]) + ["summary.json"]
                + [EXPORT_FILES[f] for f in args.export or ()]
                + ([] if args.no_figures else list(TRACE_FIGURES)))
    if args.command == "reproduce":
        from ..study.reproduce import reproduce_outputs

        return reproduce_outputs(figures=not args.no_figures)
    return []


def project_outputs() -> list[str]:
    """Every file name ``interpolate``, ``run`` and ``reproduce`` may write into their
    output folder (with any option): what ``--overwrite`` removes when this run does not
    write it, and what refuses a folder without it. docs/cli.md lists them."""
    from ..study.reproduce import reproduce_outputs
    from ..plots import SETPOINT_FIGURES, TRACE_FIGURES
    from ..report import TRACE_FILES

    names = ["setpoints.csv", *SETPOINT_FIGURES, *TRACE_FILES.values(), "summary.json",
             *EXPORT_FILES.values(), *TRACE_FIGURES, *reproduce_outputs(figures=True)]
    return list(dict.fromkeys(_with_metadata(names)))


def _outputs(args) -> OutputFolder:
    """The command's output folder: its files checked now, before any work, written
    through a staging folder and moved into place only when all are complete; with
    ``--overwrite`` an earlier run's outputs that this one does not write are removed
    (:func:`project_outputs`), and without it they refuse the folder."""
    return OutputFolder(args.out, _outputs_of(args), overwrite=args.overwrite,
                        replaces=project_outputs())


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

    class _Stderr(logging.Handler):  # the stderr of the moment (tests swap it)
        def emit(self, record):
            print(f"nurbsmotion {command}: {record.levelname.lower()}: "
                  f"{_one_line(record.getMessage())}", file=sys.stderr)

    handler = _Stderr()
    logger = logging.getLogger("nurbsmotion")
    saved = warnings.showwarning
    warnings.showwarning = show
    logger.addHandler(handler)
    try:
        yield
    finally:
        warnings.showwarning = saved
        logger.removeHandler(handler)


INTERRUPT_RETRY = 0.02
"""Seconds after which a Ctrl-C that arrived inside a callback of the compiler's native
library is raised again (raised there, ctypes would print it and drop it)."""


def _interrupt(signum, frame) -> None:
    """SIGINT and SIGTERM (and the retry's SIGALRM): KeyboardInterrupt, except inside llvmlite's
    callbacks (numba loading or compiling a kernel), where it is retried shortly."""
    f = frame
    while f is not None:
        if f.f_globals.get("__name__", "").startswith("llvmlite"):
            signal.setitimer(signal.ITIMER_REAL, INTERRUPT_RETRY)
            return
        f = f.f_back
    raise KeyboardInterrupt


@contextlib.contextmanager
def _interruptible():
    """Ctrl-C (and SIGTERM) raise KeyboardInterrupt wherever the command is (see
    :func:`_interrupt`); the previous handlers are restored after. Only in the main thread
    (where signals go)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    # SIGTERM (a machine shutting down, a job scheduler) stops the command like Ctrl-C:
    # its staging folder and temporary files are removed on the way out.
    saved = {s: signal.signal(s, _interrupt)
             for s in (signal.SIGINT, signal.SIGALRM, signal.SIGTERM)}
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        for s, handler in saved.items():
            signal.signal(s, handler)


USER_ERRORS = (NurbsmotionError, OSError, KeyError, ValueError, ArithmeticError,
               RecursionError, MemoryError)
"""Errors reported as one line and exit code 2: the library's typed errors, and what
the system, the parsers and the arithmetic raise on a bad file, folder or number."""
