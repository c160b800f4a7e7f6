"""Typed errors raised by nurbsmotion.

Every error names the offending value, so that a user who gave a bad knot vector, a
negative weight or an unreachable constraint can find it without a traceback from numpy.
All derive from :class:`NurbsmotionError`; those about a bad input also derive from
:class:`ValueError`.

One rule decides which error a check raises (``tests/test_errors.py`` holds the code to it):

- a bad argument — of the wrong kind, out of its range, or inconsistent with another —
  raises :class:`InvalidArgumentError` or one of its kind: :class:`InvalidFeedError`, and
  for a whole object :class:`InvalidCurveError`, :class:`InvalidMachineError`, or
  :class:`PathFileError` for a file's content;
- valid arguments whose work cannot be done raise :class:`InfeasibleError` (the drive
  cannot move along the path, the plan or the loop never reaches the end) or
  :class:`WorkLimitError` (more samples or memory than a documented limit).

Both are :class:`ValueError`, so ``except ValueError`` catches either.
"""

from __future__ import annotations

__all__ = [
    "NurbsmotionError",
    "InvalidCurveError",
    "InvalidArgumentError",
    "InvalidMachineError",
    "PathFileError",
    "InfeasibleError",
    "OutputExistsError",
    "WorkLimitError",
    "InvalidFeedError",
]


class NurbsmotionError(Exception):
    """Base class of every error nurbsmotion raises on purpose."""


class InvalidCurveError(NurbsmotionError, ValueError):
    """A NURBS curve definition is invalid (knots, weights, control points, degree)."""


class InvalidArgumentError(NurbsmotionError, ValueError, TypeError):
    """A function argument is of the wrong kind or out of range (a curve parameter, a
    derivative order, a tolerance, a feed, something that is not a curve or a machine).

    Derives from both :class:`ValueError` and :class:`TypeError`, the built-in errors such
    an argument would otherwise raise."""


class InvalidMachineError(NurbsmotionError, ValueError):
    """A machine definition (axes, gains, drive limit, sample period) is invalid."""


class PathFileError(NurbsmotionError, ValueError):
    """A path or machine file cannot be read: missing, malformed, or a bad field.

    Parameters
    ----------
    message : str
        What is wrong, naming the field.
    source : str, optional
        The file name.
    line : int, optional
        1-based line number, where the format gives one.
    """

    def __init__(self, message: str, source: str | None = None, line: int | None = None):
        self.message = message
        self.source = source
        self.line = line
        where = ""
        if source is not None:
            where = f"{source}"
            if line is not None:
                where += f", line {line}"
            where += ": "
        super().__init__(where + message)


class InfeasibleError(NurbsmotionError, ValueError):
    """A requested motion cannot be executed within the machine's limits (its arguments
    are valid: a bad argument is an :class:`InvalidArgumentError`)."""


class OutputExistsError(NurbsmotionError, FileExistsError):
    """An output file already exists and overwriting it was not asked for."""


class InvalidFeedError(InvalidArgumentError):
    """A feed that is not a positive finite number, a speed with a known unit, or a valid
    per-piece feed limit."""
class WorkLimitError(NurbsmotionError, ValueError):
    """A command would compute more samples (or memory) than a documented limit allows
    (:mod:`nurbsmotion.loop.budget`)."""
