"""The per-sample contract between an interpolator and the loop, and its registry.

An interpolator is, for the loop, two pieces of data and one compiled function:

- its *plan*: an immutable :class:`typing.NamedTuple` of numbers and arrays (the path,
  the feed, a schedule, ...), built once in Python;
- its *state*: a NamedTuple of arrays (the parameter ``u`` and whatever else the stepper
  carries between samples, as one-element arrays, and scratch arrays), made fresh for
  every run;
- its *step*, registered here for the plan's type::

      step(plan, state, law, law_state, position, velocity, command, bounds)
          -> (u, feed, status)

  called once per sample k >= 1 (k >= 0 for an interpolator registered with
  ``first_sample=0``: sample 0's setpoint is otherwise the path's start, which the plant
  rests on, so the drive u[0] is 0 and the plant moves from sample 1) with the measured
  position tha[k] [pulse] and velocity [pulse/s] (shape (n_axes,)), the control law
  (:data:`nurbsmotion.control.PID_LAW`) and its memory from sample k-1 (so that the step
  can predict the drive any candidate setpoint would cause:
  :func:`nurbsmotion.control.pid_output` and :func:`~nurbsmotion.control.pid_affine`).
  It writes the setpoint thd[k] into
  ``command`` and the speed bounds it used into ``bounds`` (shape (n_axes, 2), [pulse/s];
  NaN where it has none), and returns the curve parameter, the feed it commanded
  [pulse/s] and a :class:`Status` code. It is called at every sample, also after it
  first reported ``FINISHED``: then it holds the end (:func:`hold_end`) or, if it steers
  the plant rather than the setpoint, goes on steering it there. Open loop
  (:func:`nurbsmotion.loop.interpolate`, from sample 1; not for an interpolator whose
  ``open_loop`` is False, as one that steps from sample 0 steers the drive) the law is :func:`nurbsmotion.control.pid_law` of no gains and the state is the
  setpoint's own.

:func:`step` dispatches on the plan's type at compile time (numba ``overload``), so the
loop is compiled once per interpolator type and cached on disk; with
``NUMBA_DISABLE_JIT=1`` the same functions run as plain Python. Adding an interpolator
means one module that defines its plan, state and step and calls :func:`register`; given
a ``name`` there, the same call makes it a named interpolator (:class:`Named`): its
factory serves :func:`nurbsmotion.interpolators.make_interpolator` (or ``make_open_loop``),
its name :data:`nurbsmotion.interpolators.LOOP_METHODS` and the command's choices, and its
made-up plan and state a cold first run's compilation
(:func:`nurbsmotion._runtime.precompile.loop_example`).
:func:`first_sample` (compiled: a constant per plan type) says from which sample the loop
calls the step.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numba import njit
from numba.extending import overload

from .errors import InvalidArgumentError

__all__ = ["Status", "WORKING", "FINISHED", "LIMITED", "CORNERED", "FAILED", "register",
           "step", "first_sample", "hold_end", "Named", "named", "interpolator_names"]

WORKING, FINISHED, LIMITED, CORNERED, FAILED = 0, 1, 2, 3, 4
"""Status codes a step returns (see :class:`Status`)."""


class Status(enum.IntEnum):
    """What one sample's step did."""

    WORKING = WORKING
    """Moved along the plan; the end is not reached yet."""
    FINISHED = FINISHED
    """The setpoint is at the path's end (reached at this step or before)."""
    LIMITED = LIMITED
    """The step was changed from the plan (shortened, or lengthened while braking) so
    that every predicted drive stays within Umax."""
    CORNERED = CORNERED
    """No admissible step existed: the drive of at least one axis will exceed Umax."""
    FAILED = FAILED
    """The interpolator cannot advance (a zero or non-finite step); the run stops."""


_STEPS: dict = {}
_FIRST_SAMPLES: dict = {}


@dataclass(frozen=True)
class Named:
    """A named interpolator (:func:`register` with a ``name``).

    Attributes
    ----------
    name : str
        What a user calls it (``"paper"``).
    plan_type : type
        The type of its plans, whose registered step the loop runs.
    make : callable or None
        ``make(curve, machine, feed, **options) -> Interpolator`` for the closed loop
        (curve [pulse], feed [pulse/s] or a per-piece FeedLimit); None: open loop only.
    open_loop : callable or None
        ``open_loop(curve, sample_period, feed) -> Interpolator`` without a loop state
        (:func:`nurbsmotion.loop.interpolate`); None: closed loop only.
    example : callable or None
        ``example(n_axes) -> (plan, state)``: made-up values of the types a run passes
        the loop (zeros: only their types count), for a cold first run's compilation.
    options : bool
        Whether ``make`` takes options (``corner_tolerance``, ...).
    """

    name: str
    plan_type: type
    make: Callable | None = None
    open_loop: Callable | None = None
    example: Callable | None = None
    options: bool = False


_NAMED: dict[str, Named] = {}


@njit(cache=True)
def hold_end(end, command, bounds):
    """The step of an interpolator that has reached the end: hold it (feed 0)."""
    for j in range(command.shape[0]):
        command[j] = end[j]
        bounds[j, 0] = np.nan
        bounds[j, 1] = np.nan
    return 1.0, 0.0, FINISHED


def register(plan_type: type, step_function, first_sample: int = 1, *,
             name: str | None = None, make: Callable | None = None,
             open_loop: Callable | None = None, example: Callable | None = None,
             options: bool = False) -> None:
    """Make ``step_function`` the step of plans of type ``plan_type`` (a NamedTuple),
    called from sample ``first_sample`` on: 1 (sample 0's setpoint is the path's start) or
    0 (the step gives sample 0's setpoint too, as a planner of the drive does).

    With a ``name``, also a named interpolator (:class:`Named`: ``make``, ``open_loop``,
    ``example`` and ``options`` as its attributes); several names may share a plan type
    (``taylor1`` and ``taylor2``). Names keep the order they were registered in.
    """
    if first_sample not in (0, 1):
        raise InvalidArgumentError(f"first_sample must be 0 or 1, got {first_sample!r}")
    if name is not None and make is None and open_loop is None:
        raise InvalidArgumentError(f"interpolator {name!r} needs make or open_loop")
    _STEPS[plan_type] = step_function
    _FIRST_SAMPLES[plan_type] = first_sample
    if name is not None:
        _NAMED[name] = Named(name, plan_type, make, open_loop, example, options)


def named(name: str) -> Named | None:
    """The named interpolator ``name`` (None if there is none)."""
    return _NAMED.get(name)


def interpolator_names(open_loop: bool = False) -> tuple[str, ...]:
    """Names of the registered interpolators that run in the closed loop (with
    ``open_loop``: without a loop state), in the order they were registered."""
    return tuple(n for n, r in _NAMED.items()
                 if (r.open_loop if open_loop else r.make) is not None)


def first_sample(plan) -> int:
    """The first sample whose setpoint the registered step of ``type(plan)`` gives."""
    return _FIRST_SAMPLES[type(plan)]


def step(plan, state, law, law_state, position, velocity, command, bounds):
    """The registered step of ``type(plan)`` (see the module docstring)."""
    return _STEPS[type(plan)](plan, state, law, law_state, position, velocity, command,
                              bounds)


# Not inlined at numba IR level: the step is one compiled call per sample (its own
# helpers are inlined into it), which costs a few percent of the loop's speed, while
# inlining it into the loop deep-copies its IR at every typing pass (compile 3x longer).
@overload(step, jit_options={"cache": True})
def _step_overload(plan, state, law, law_state, position, velocity, command, bounds):
    from numba.core import types

    if not isinstance(plan, types.BaseNamedTuple):
        return None
    fn = _STEPS.get(plan.instance_class)
    if fn is None:
        return None

    def impl(plan, state, law, law_state, position, velocity, command, bounds):
        return fn(plan, state, law, law_state, position, velocity, command, bounds)
    return impl


@overload(first_sample, jit_options={"cache": True})
def _first_sample_overload(plan):
    from numba.core import types

    if not isinstance(plan, types.BaseNamedTuple):
        return None
    value = _FIRST_SAMPLES.get(plan.instance_class)
    if value is None:
        return None

    def impl(plan):
        return value
    return impl
