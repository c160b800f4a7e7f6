"""The ``nurbsmotion`` command and ``python -m nurbsmotion``.

A thin shell around :func:`nurbsmotion.cli.main` that imports it first: a Ctrl-C while
numpy and numba load (a few tenths of a second) ends the command like one during its
work, with one line and exit code 130, not a traceback.
"""

from __future__ import annotations

import gc
import signal
import sys


class _Interrupted:
    """SIGINT handler while the command line loads: remembers the Ctrl-C and raises
    KeyboardInterrupt (a C extension that is loading may turn it into an ImportError)."""

    seen = False

    def __call__(self, signum, frame):
        self.seen = True
        raise KeyboardInterrupt


def main() -> int:
    """Import the command line and run it; returns the exit code."""
    interrupted = _Interrupted()
    try:
        previous = signal.signal(signal.SIGINT, interrupted)
    except ValueError:  # not the main thread: no handler of ours
        previous = None
    try:
        try:
            from .cli import main as run
        finally:
            if previous is not None:
                signal.signal(signal.SIGINT, previous)
        code = run()  # it reports a Ctrl-C during its work itself
        if previous is not None:  # the work is done and its files are complete: a late
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C must not kill the exit
        # The process ends now: its last collections need not traverse every object of
        # numba, scipy and matplotlib (0.25-0.3 s of CPU after a run, on every command).
        gc.freeze()
        return code
    except (KeyboardInterrupt, ImportError):
        if not (interrupted.seen or sys.exc_info()[0] is KeyboardInterrupt):
            raise
        command = " ".join(sys.argv[1:2])
        print(f"nurbsmotion{' ' + command if command else ''}: interrupted; no output was "
              "written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
