"""Interpolators: one module each; a plan (data) and a compiled step each, registered by
name with :func:`nurbsmotion.stepping.register`. Adding one means one module (imported
here): its registration gives :func:`make_interpolator` (or :func:`make_open_loop`) and
the made-up plan a cold first run compiles from; its name goes into
:data:`LOOP_METHODS` (the command's ``--interpolator`` choices) or
:data:`OPEN_LOOP_METHODS`, declared in :mod:`nurbsmotion.limits` so that the command
shows them without loading the compiled interpolators (tests/test_registry.py checks that
they are the registered names, in their order).

- ``uniform``: fixed parameter step (eq. 1.1);
- ``taylor1`` / ``taylor2``: constant (or parameter-dependent) feed, eq. 3.2 / 3.1;
- ``paper``: the saturation-aware interpolation of Yeh & Sun (2008), reading the loop state;
- ``planned``: look-ahead, jerk-limited, drive-limited profile with a real-time safety layer;
- ``replay``: a parameter sequence planned elsewhere, fed through the same loop.
"""

from .. import stepping
from ..errors import InvalidArgumentError
from ..limits import DEFAULT_INTERPOLATOR, LOOP_METHODS, OPEN_LOOP_METHODS
from ..units import in_pulses
from .base import Interpolator, Status, taylor_increment
# registered in this order (the order of the names): taylor's, paper, planned
from .taylor import TaylorInterpolator, UniformInterpolator
from .paper import PaperInterpolator
from .replay import ReplayInterpolator
from .planned import PlannedInterpolator

__all__ = ["Interpolator", "Status", "taylor_increment", "PaperInterpolator", "PlannedInterpolator",
           "ReplayInterpolator", "TaylorInterpolator", "UniformInterpolator",
           "OPEN_LOOP_METHODS", "LOOP_METHODS", "make_open_loop", "make_interpolator",
           "DEFAULT_INTERPOLATOR"]


def make_open_loop(method: str, curve, sample_period: float, feed) -> Interpolator:
    """An open-loop interpolator by name (one of :data:`OPEN_LOOP_METHODS`)."""
    named = stepping.named(method) if isinstance(method, str) else None
    if named is None or named.open_loop is None:
        raise InvalidArgumentError(f"unknown interpolation method {method!r}; choose from "
                                   f"{stepping.interpolator_names(open_loop=True)}")
    return named.open_loop(curve, sample_period, feed)


def make_interpolator(method: str, curve, machine, feed, **options) -> Interpolator:
    """A servo-loop interpolator by name (one of :data:`LOOP_METHODS`).

    ``curve`` is in any unit the machine knows and ``feed`` a bare number in the path's
    units per second, a text with a unit (``"0.5m/s"``) or a per-piece ``FeedLimit``
    (converted to pulses and pulse/s by :class:`nurbsmotion.units.Scale`; the
    interpolator steps in pulses); the sample period is the machine's. ``options`` go to
    the interpolator's constructor (``planned``: ``corner_tolerance`` [pulse],
    ``tracking_pole``, ...).
    """
    curve, feed = in_pulses(curve, machine, feed)
    named = stepping.named(method) if isinstance(method, str) else None
    if named is None or named.make is None:
        raise InvalidArgumentError(f"unknown interpolator {method!r}; choose from "
                                   f"{stepping.interpolator_names()}")
    if options and not named.options:
        raise InvalidArgumentError(f"{method} takes no options, got {sorted(options)}")
    return named.make(curve, machine, feed, **options)
