"""The ``nurbsmotion`` command and ``python -m nurbsmotion``.

A thin shell around :func:`nurbsmotion.cli.main` that imports it first: a Ctrl-C while
numpy and numba load (a few tenths of a second) ends the command like one during its
work, with one line and exit code 130, not a traceback.
"""

from __future__ import annotations

import sys


def main() -> int:
    """Import the command line and run it; returns the exit code."""
    try:
        from .cli import main as run

        return run()  # it reports a Ctrl-C during its work itself
    except KeyboardInterrupt:
        command = " ".join(sys.argv[1:2])
        print(f"nurbsmotion{' ' + command if command else ''}: interrupted; no output was "
              "written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
