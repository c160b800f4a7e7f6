"""Feeds with units, and the length unit results are reported in.

One rule for the library and the command line: a feed is either a bare number, in the
**path's units per second** (pulse/s for a path drawn in pulses, mm/s for a path drawn in
mm), or a text with a unit, ``"0.5m/s"``, ``"100mm/s"``, ``"600mm/min"``, ``"2e5pulse/s"``.
:func:`feed_in_pulses` turns either into the machine's pulse/s, the unit the loop runs in.

Results are computed in pulses and reported in pulses *and* in a length unit a user reads
(:func:`report_unit`): inches for a path drawn in inches, millimetres otherwise (a path in
pulses is converted through the machine's pulse length).
"""

from __future__ import annotations

import math
import re

import numpy as np

from .errors import InvalidArgumentError, InvalidFeedError
from .feed import FeedLimit
from .machine import LENGTH_UNITS_UM, Machine

__all__ = ["InvalidFeedError", "parse_feed", "feed_in_pulses", "feed_in_path_units",
           "length_in_pulses",
           "report_unit", "pulses_per_report_unit"]

_FEED = re.compile(r"^\s*([0-9.eE+-]+)\s*(?:([a-z]+)\s*/\s*(s|min))?\s*$")




def parse_feed(text: str) -> tuple[float, str | None]:
    """Read a feed text: ``"1e6"`` -> (1e6, None); ``"0.5m/s"`` -> (5e5, "um");
    ``"600mm/min"`` -> (1e4, "um"); ``"2e5pulse/s"`` -> (2e5, "pulse").

    Returns
    -------
    value : float
        [path unit/s] when ``unit`` is None, [um/s] when ``"um"``, [pulse/s] when
        ``"pulse"``.
    unit : {None, "um", "pulse"}

    Raises
    ------
    InvalidFeedError
        Naming the text, if it is not a positive finite number or a speed with one of
        the units ``pulse`` and :data:`~nurbsmotion.machine.LENGTH_UNITS_UM` per ``s`` or
        ``min``.
    """
    m = _FEED.match(text)
    if not m:
        raise InvalidFeedError(
            f"feed {text!r} is not a number or a speed such as 0.5m/s, 100mm/s, 600mm/min"
        )
    try:
        value = float(m.group(1))
    except ValueError:
        raise InvalidFeedError(f"feed {text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise InvalidFeedError(f"feed must be finite and > 0, got {text!r}")
    unit, per = m.group(2), m.group(3)
    if per == "min":
        value /= 60.0
    if unit is None or unit == "pulse":
        return value, unit
    if unit not in LENGTH_UNITS_UM:
        raise InvalidFeedError(
            f"feed unit {unit!r} unknown; use pulse or one of {sorted(LENGTH_UNITS_UM)}"
        )
    return value * LENGTH_UNITS_UM[unit], "um"


def _parsed(feed) -> tuple[float, str | None]:
    """A feed given as a number, a text, or an already parsed (value, unit) pair."""
    if isinstance(feed, str):
        return parse_feed(feed)
    if isinstance(feed, tuple):
        return feed
    if isinstance(feed, (bool, np.bool_)):  # True is no feed
        raise InvalidFeedError(f"feed must be a number or a text such as '100mm/s', "
                               f"got {feed!r}")
    try:
        value = float(feed)
    except (TypeError, ValueError):
        raise InvalidFeedError(f"feed must be a number or a text such as '100mm/s', "
                               f"got {feed!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise InvalidFeedError(f"feed must be finite and > 0, got {feed!r}")
    return value, None


_LENGTH = re.compile(r"^\s*([0-9.eE+-]+)\s*([a-z]*)\s*$")


def length_in_pulses(text: str, curve, machine: Machine, what: str = "length",
                     bare_unit: str | None = None) -> float:
    """A length text in the machine's pulses: ``"0.5mm"``, ``"10um"``, ``"200pulse"``, or
    a bare number in ``bare_unit`` (default: the path's units, like a bare feed). Must be
    finite and >= 0.

    Raises
    ------
    InvalidArgumentError
        Naming ``what`` and the text.
    """
    m = _LENGTH.match(str(text))
    value = None
    if m:
        try:
            value = float(m.group(1))
        except ValueError:
            value = None
    if value is None or not (math.isfinite(value) and value >= 0):
        raise InvalidArgumentError(
            f"{what} {text!r} is not a length >= 0 such as 0.5mm, 10um or a number in "
            + ("the path's units" if bare_unit is None else f"{bare_unit}s"))
    unit = m.group(2) or bare_unit
    if unit == "pulse":
        return value
    if unit is not None and unit not in LENGTH_UNITS_UM:
        raise InvalidArgumentError(f"{what} unit {unit!r} unknown; use pulse or one of "
                                   f"{sorted(LENGTH_UNITS_UM)}")
    return value * machine.pulses_per_unit(unit or curve.units)


def feed_in_pulses(feed, curve, machine: Machine):
    """A feed in the machine's pulse/s.

    Parameters
    ----------
    feed : float or str or tuple or FeedLimit
        A bare number [path units/s], a text with a unit (``"100mm/s"``), the pair
        :func:`parse_feed` returns, or a per-piece limit
        (:class:`nurbsmotion.feed.FeedLimit`, in path units/s; returned scaled).
    curve : NurbsCurve
        The path as the user gave it (its ``units`` say what a bare number means).
    machine : Machine
        Its ``pulse_length_um`` converts lengths to pulses.

    Returns
    -------
    float or FeedLimit
        Commanded feed F [pulse/s].
    """
    if isinstance(feed, FeedLimit):
        return feed.scaled(machine.pulses_per_unit(curve.units))
    value, unit = _parsed(feed)
    if unit == "pulse":
        return value
    if unit == "um":
        return value * machine.pulses_per_unit("um")
    return value * machine.pulses_per_unit(curve.units)


def feed_in_path_units(feed, curve) -> float:
    """A feed in the path's units per second, without a machine (open-loop setpoints).

    Raises
    ------
    InvalidFeedError
        For a feed with a length unit on a path without one (in pulses: the pulse length
        is the machine's), or a feed in pulse/s on a path drawn in a length unit.
    """
    value, unit = _parsed(feed)
    if unit is None or unit == curve.units or (unit == "pulse" and curve.units is None):
        return value
    if unit == "um" and curve.units in LENGTH_UNITS_UM:
        return value / LENGTH_UNITS_UM[curve.units]
    raise InvalidFeedError(
        f"cannot convert a feed {'in pulse/s' if unit == 'pulse' else 'with a length unit'} to "
        f"a path in {curve.units or 'no unit'} without a machine; give a bare number in "
        "path units per second"
    )


def report_unit(path_units: str | None) -> str:
    """The length unit results are reported in besides pulses: ``"in"`` for a path drawn
    in inches, ``"mm"`` otherwise."""
    return "in" if path_units in ("in", "inch") else "mm"


def pulses_per_report_unit(path_units: str | None, machine: Machine) -> float:
    """Pulses per :func:`report_unit` of a path on ``machine`` [pulse/mm or pulse/in]."""
    return machine.pulses_per_unit(report_unit(path_units))
