"""Feeds with units, and the length unit results are reported in.

One rule for the library and the command line: a feed is either a bare number, in the
**path's units per second** (pulse/s for a path drawn in pulses, mm/s for a path drawn in
mm), or a text with a unit, ``"0.5m/s"``, ``"100mm/s"``, ``"600mm/min"``, ``"2e5pulse/s"``.
:func:`feed_in_pulses` turns either into the machine's pulse/s, the unit the loop runs in.

Results are computed in pulses and reported in pulses *and* in a length unit a user reads
(:func:`report_unit`): inches for a path drawn in inches, millimetres otherwise (a path in
pulses is converted through the machine's pulse length); a rotary axis in degrees.

:class:`Scale` is the one boundary: built once per path and machine, it holds the pulses
per path unit of every axis and converts the path, a feed and a length into the machine's
pulses where a run enters. On the way out its :attr:`Scale.output`, an
:class:`OutputUnits` carried by the run's result
(:attr:`nurbsmotion.job.RunResult.output_units`), is the one converter the summary, the
trace file, the figures and the command line read lengths through. The functions below
are their one-call forms.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from .errors import InvalidArgumentError, InvalidFeedError
from .feed import FeedLimit
from .machine import LENGTH_UNITS_UM, Machine
from .nurbs import NurbsCurve

__all__ = ["Scale", "OutputUnits", "in_pulses", "curve_in_pulses", "InvalidFeedError", "parse_feed", "feed_in_pulses", "feed_in_path_units",
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


@dataclass(frozen=True, eq=False)
class OutputUnits:
    """The units a run's results are written in besides pulses: the one converter on the
    way out.

    Built once per run from its :class:`Scale` (:attr:`Scale.output`) and carried by its
    result (:attr:`nurbsmotion.job.RunResult.output_units`) to ``summary.json``
    (:func:`nurbsmotion.report.summary`), the trace file
    (:class:`nurbsmotion.report.TraceWriter`), the figures and the command line's lines,
    none of which converts a length otherwise. A length along the path (a contour error, a
    feed, a tolerance) is in :attr:`unit`; each axis's positions and speeds in its own
    entry of :attr:`axis_units`: the report unit for a linear axis, ``"deg"`` for a rotary
    axis (one with ``pulses_per_degree``), so that degrees are never converted as a length.

    Attributes
    ----------
    unit : str
        The report unit (:func:`report_unit`): ``"mm"``, or ``"in"`` for a path drawn in
        inches.
    pulses_per_unit : float
        Pulses per :attr:`unit` of a linear axis [pulse/mm or pulse/in], > 0.
    axis_units : tuple of str, length n_axes
        The unit of each axis's columns: :attr:`unit`, or ``"deg"`` for a rotary axis.
    pulses_per_axis_unit : ndarray, shape (n_axes,)
        Pulses per unit of each axis [pulse/axis unit]: :attr:`pulses_per_unit`, or the
        rotary axis's ``pulses_per_degree`` [pulse/deg].
    """

    unit: str
    pulses_per_unit: float
    axis_units: tuple
    pulses_per_axis_unit: np.ndarray

    @classmethod
    def of(cls, machine: Machine, path_units: str | None = None,
           unit: str | None = None) -> "OutputUnits":
        """The output units of a path drawn in ``path_units`` on ``machine``: its report
        unit (:func:`report_unit`), or ``unit`` (one of :data:`LENGTH_UNITS_UM`) when given.

        Raises
        ------
        InvalidArgumentError
            If ``machine`` is not a :class:`Machine`.
        InvalidMachineError
            If ``unit`` is not a length unit the machine knows.
        """
        if not isinstance(machine, Machine):
            raise InvalidArgumentError(f"machine must be a Machine, got {machine!r:.60}")
        unit = report_unit(path_units) if unit is None else unit
        return cls(unit, machine.pulses_per_unit(unit),
                   tuple(unit if a.pulses_per_degree is None else "deg" for a in machine.axes),
                   machine.pulses_per_axis_unit(unit))

    @property
    def factor(self) -> float:
        """:attr:`unit` per pulse, ``1 / pulses_per_unit`` [mm/pulse or in/pulse]: the
        multiplier of the summary's length keys."""
        return 1.0 / self.pulses_per_unit

    @property
    def axis_factor(self) -> np.ndarray:
        """Axis unit per pulse, shape (n_axes,) [mm/pulse, in/pulse or deg/pulse]: the
        multiplier of the trace file's columns in the axes' units."""
        return 1.0 / self.pulses_per_axis_unit

    def length(self, pulses):
        """A length along the path [pulse] (a scalar, or an array of them) in :attr:`unit`."""
        return pulses / self.pulses_per_unit


@dataclass(frozen=True, eq=False)
class Scale:
    """Where a path meets a machine: its units and the machine's pulses, once per run.

    Built by :meth:`of` from the path as the user gave it and the machine; every
    conversion of a run goes through it: :meth:`path` (the curve in pulses), :meth:`feed`
    (pulse/s), :meth:`length` (pulses) on the way in, :meth:`to_report` (pulses to the
    report unit) on the way out.

    Each axis has its own factor, so a machine whose axes differ in kind (a rotary axis
    in degrees beside linear ones in mm) fits the same object; a feed or a length along
    the path needs one factor, which is only defined while every axis has the same
    (:attr:`factor`), and a curve is scaled axis by axis.

    Attributes
    ----------
    path_units : str or None
        The units the path is drawn in (``None`` or ``"pulse"``: pulses).
    pulses_per_path_unit : ndarray, shape (n_axes,)
        Pulses per path unit, per axis [pulse/path unit].
    pulse_length_um : ndarray, shape (n_axes,)
        The length of one pulse, per axis [um] (feeds and lengths with a length unit).
    report_unit : str
        The length unit results are reported in besides pulses (:func:`report_unit`).
    pulses_per_report_unit : ndarray, shape (n_axes,)
        Pulses per report unit, per axis [pulse/mm or pulse/in].
    output : OutputUnits or None
        The results' units on the way out, rotary axes in degrees (built by :meth:`of`;
        None for a scale made by hand).
    """

    path_units: str | None
    pulses_per_path_unit: np.ndarray
    pulse_length_um: np.ndarray
    report_unit: str
    pulses_per_report_unit: np.ndarray
    output: OutputUnits | None = None

    @classmethod
    def of(cls, curve: NurbsCurve | None, machine: Machine) -> "Scale":
        """The scale of ``curve`` (its ``units``) on ``machine`` (its pulse length);
        ``curve`` None: a move without a path, in pulses, on the machine's axes.

        Raises
        ------
        InvalidArgumentError
            If ``curve`` is not a :class:`NurbsCurve` or ``machine`` not a :class:`Machine`.
        InvalidMachineError
            If the path's unit is unknown.
        """
        if not isinstance(machine, Machine):
            raise InvalidArgumentError(f"machine must be a Machine, got {machine!r:.60}")
        if curve is None:
            path_units, n_axes = None, machine.n_axes
        elif isinstance(curve, NurbsCurve):
            path_units, n_axes = curve.units, curve.n_axes
        else:
            raise InvalidArgumentError(f"curve must be a NurbsCurve, got {curve!r:.60}")
        unit = report_unit(path_units)

        def per_axis(units):
            # one linear pulse length today; a per-axis (rotary) factor replaces this line
            return np.full(n_axes, machine.pulses_per_unit(units))

        return cls(path_units, per_axis(path_units),
                   np.full(n_axes, float(machine.pulse_length_um)), unit, per_axis(unit),
                   OutputUnits.of(machine, path_units))

    @staticmethod
    def _common(per_axis: np.ndarray, what: str) -> float:
        """The one factor of ``per_axis`` [pulse/unit], if every axis has it."""
        first = float(per_axis[0])
        if np.any(per_axis != first):
            raise InvalidArgumentError(
                f"{what} along the path needs one pulses-per-unit factor, but the axes have "
                f"{per_axis.tolist()}: convert it per axis")
        return first

    def _pulses_per(self, unit: str, what: str) -> float:
        """Pulses per ``unit`` of :data:`LENGTH_UNITS_UM`, the same on every axis."""
        return LENGTH_UNITS_UM[unit] / self._common(self.pulse_length_um, what)

    @property
    def factor(self) -> float:
        """Pulses per path unit, the same on every axis [pulse/path unit]."""
        return self._common(self.pulses_per_path_unit, "a length")

    def pulses_per(self, unit: str) -> float:
        """Pulses per ``unit`` (one of :data:`LENGTH_UNITS_UM`), the same on every axis
        [pulse/unit]: outputs whose unit is fixed (G-code and halstreamer in mm)."""
        return self._pulses_per(unit, f"a length in {unit}")

    @property
    def report_factor(self) -> float:
        """Pulses per :attr:`report_unit`, the same on every axis [pulse/mm or pulse/in]."""
        return self._common(self.pulses_per_report_unit, "a length")

    def path(self, curve: NurbsCurve) -> NurbsCurve:
        """``curve`` (drawn in :attr:`path_units`) in the machine's pulses; the same object
        when it is already in pulses."""
        factor = self.factor
        if factor == 1.0:
            return curve
        return curve.scaled(factor, units="pulse")

    def feed(self, feed):
        """A feed in the machine's pulse/s.

        Parameters
        ----------
        feed : float or str or tuple or FeedLimit
            A bare number [path units/s], a text with a unit (``"100mm/s"``), the pair
            :func:`parse_feed` returns, or a per-piece limit
            (:class:`nurbsmotion.feed.FeedLimit`, in path units/s; returned scaled).
            A pair ``(value, "pulse")`` is in pulse/s already, ``value`` a number or a
            :class:`~nurbsmotion.feed.FeedLimit` (returned as it is).

        Returns
        -------
        float or FeedLimit
            Commanded feed F [pulse/s].
        """
        if isinstance(feed, FeedLimit):
            return feed.scaled(self.factor)
        if isinstance(feed, tuple) and len(feed) == 2 and isinstance(feed[0], FeedLimit):
            limit, unit = feed  # a per-piece limit with its unit: path units or pulse
            if unit == "pulse":
                return limit
            if unit is None:
                return limit.scaled(self.factor)
            raise InvalidFeedError(f"a feed limit's unit must be None (the path's units) "
                                   f"or 'pulse', got {unit!r}")
        value, unit = _parsed(feed)
        if unit == "pulse":
            return value
        if unit == "um":
            return value * self._pulses_per("um", "a feed")
        return value * self.factor

    def length(self, text, what: str = "length", bare_unit: str | None = None) -> float:
        """A length text in the machine's pulses: ``"0.5mm"``, ``"10um"``, ``"200pulse"``,
        or a bare number in ``bare_unit`` (default: the path's units, like a bare feed).
        Must be finite and >= 0.

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
        if unit is None or unit == self.path_units:
            return value * self._common(self.pulses_per_path_unit, what)
        return value * self._pulses_per(unit, what)

    def to_report(self, pulses):
        """Lengths [pulse] in :attr:`report_unit`: a scalar or an array along the path
        by the common factor, an array of shape (..., n_axes) axis by axis."""
        pulses = np.asarray(pulses, dtype=float)
        if pulses.ndim and pulses.shape[-1] == len(self.pulses_per_report_unit):
            return pulses / self.pulses_per_report_unit
        return pulses / self._common(self.pulses_per_report_unit, "a length")


def in_pulses(curve: NurbsCurve, machine: Machine, feed=None):
    """``(curve, feed)`` in the machine's pulses and pulse/s, for the library's entry
    points that plan or step in pulses (:func:`~nurbsmotion.planning.time_optimal_bound`,
    :func:`~nurbsmotion.interpolators.make_interpolator`,
    :class:`~nurbsmotion.metrics.RunningMetrics`).

    A path in pulses with a feed that is a number or a
    :class:`~nurbsmotion.feed.FeedLimit` comes back as it was given (the same objects),
    so those entry points keep their own checks of it; any other path or feed goes
    through :class:`Scale` (a bare number is then in the path's units per second).
    """
    if curve_in_pulses(curve) and not isinstance(feed, (str, tuple)):
        return curve, feed
    scale = Scale.of(curve, machine)
    return scale.path(curve), (None if feed is None else scale.feed(feed))


def curve_in_pulses(curve) -> bool:
    """Whether ``curve`` is drawn in pulses (``units`` None or ``"pulse"``); anything
    that is not a curve counts as in pulses, for its own entry point to refuse."""
    return getattr(curve, "units", None) in (None, "pulse")


def length_in_pulses(text: str, curve, machine: Machine, what: str = "length",
                     bare_unit: str | None = None) -> float:
    """A length text in the machine's pulses (:meth:`Scale.length` of ``curve``, or of no
    path when None, on ``machine``)."""
    return Scale.of(curve, machine).length(text, what, bare_unit)


def feed_in_pulses(feed, curve, machine: Machine):
    """A feed in the machine's pulse/s (:meth:`Scale.feed` of ``curve`` on ``machine``).

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
    return Scale.of(curve, machine).feed(feed)


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
