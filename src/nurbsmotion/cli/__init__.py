"""Command-line interface: ``nurbsmotion interpolate | run | bound | reproduce | campaign``.

A thin layer over the library: it parses arguments, calls library functions, writes files
and turns the library's typed errors into one line on stderr and a non-zero exit code.
:mod:`.parser` holds the argparse tree and its types, :mod:`.commands` one function per
command, :mod:`.console` what the command shows and guards (progress, one-line warnings
and errors, Ctrl-C, the output folder); :func:`main` ties them together.
"""

from __future__ import annotations

import sys

from .console import (USER_ERRORS, _interruptible, _message, _one_line, _one_line_warnings,
                      project_outputs)
from .console import _interrupt, _outputs_of  # noqa: F401 - the names of cli.py, for tests
from .parser import _parser, parse_feed, synopsis

__all__ = ["main", "parse_feed", "synopsis", "project_outputs"]


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``nurbsmotion`` command; returns the exit code.

    0 on success; 2 with one line on stderr for a bad input (nothing is written); 130
    when interrupted (Ctrl-C; nothing is written); 1 for an internal error.
    """
    parser = _parser()
    args = parser.parse_args(argv)
    with _one_line_warnings(args.command), _interruptible():
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

