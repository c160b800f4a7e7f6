"""The limits, defaults and names a user is shown: the command's choices, defaults and
help texts, and the refusals that quote them.

Each is defined here once and imported from here by the module that uses it (and
re-exported there under its old name: ``loop.budget.MAX_SAMPLES``,
``machine.MIN_SAMPLE_PERIOD``, ``interpolators.LOOP_METHODS``, ...). This module imports
nothing, so the command's parser and ``--help``, and a path or machine refused as it is
read, do not load the modules that compile (numba) to show them (issue 37: a refusal
within a second, start-up included).
"""

from __future__ import annotations

__all__ = ["MAX_SAMPLES", "MIN_SAMPLE_PERIOD", "DEFAULT_PATH_TOLERANCE", "SHORT_MOVE_SAMPLES",
           "LOOP_METHODS", "OPEN_LOOP_METHODS", "DEFAULT_INTERPOLATOR", "TRACE_FORMATS",
           "PATH_UNITS"]

MAX_SAMPLES = 10_000_000
"""Default limit on the samples of one run or one setpoint table (about 2.8 hours at
Ts = 1 ms; a 2-axis trace of that many samples holds 1.4 GB)."""

MIN_SAMPLE_PERIOD = 1e-5
"""Shortest sample period Ts a machine may have [s] (100 kHz). Position loops of servo
drives and motion controllers run at 1-32 kHz (LinuxCNC's servo thread at 1 kHz); a
shorter period is most likely a unit slip (microseconds written as seconds), and it
multiplies the samples of every move."""

DEFAULT_PATH_TOLERANCE = 1.0
"""How far [pulse] from the path step 6 of ``planned`` may take a short move's motion by
default: one pulse, the encoder's resolution (the plan it replaces is held within a
quarter of it, :data:`nurbsmotion.interpolators.planned.inverse.PRECOMPENSATION_TOLERANCE`,
where the drive allows); also the tolerance within which runs of short chords are joined."""

SHORT_MOVE_SAMPLES = 128
"""Step 6 of ``planned`` plans the moves that rest on the end within this many samples.
Its linear programs grow with the piece (0.05-0.5 s each at 50-120 samples cold, a tenth
of that warm-started, and a move takes some tens of them): on the first 99 random paths
of ``benchmarks/planner_sweep.py`` (PLANNER_SWEEP_PLAN_ONLY=1) planning takes a median
0.15 s of CPU, 1.5 s at the 95th percentile and 29 s at most (before the warm starts and
the search from the estimate: 0.17, 2.6 and 19 s); the slow ones are 3-axis moves of
60-120 samples whose programs grow by the points found off the path round after round
and, at the earliest arrival, never come within the tolerance."""

LOOP_METHODS = ("taylor1", "taylor2", "paper", "planned")
"""Interpolators offered in the servo loop (``nurbsmotion run --interpolator``), in the
order :mod:`nurbsmotion.interpolators` registers them: the registrations give exactly
these names (tests/test_registry.py checks it; a new interpolator adds its name here)."""

OPEN_LOOP_METHODS = ("uniform", "taylor1", "taylor2")
"""Interpolators that need no loop state (``nurbsmotion interpolate --method``), in the
order they are registered; checked like :data:`LOOP_METHODS`."""

DEFAULT_INTERPOLATOR = "planned"
"""The interpolator a run uses when none is named: :func:`nurbsmotion.loop.run`,
:func:`~nurbsmotion.loop.run_streamed` and ``nurbsmotion run``. The look-ahead planner,
the one that keeps every drive within ±Umax; ``paper`` (the library's default until
issue 31) is one argument away. A study file names its interpolators itself (its own
default, ``["paper"]``, is kept for the digests of existing studies)."""

TRACE_FORMATS = ("csv", "parquet")
"""Formats of the trace file (``nurbsmotion run --trace-format``)."""

PATH_UNITS = ("mm", "cm", "m", "um", "in", "inch", "pulse")
"""Units a path may be given in (a curve's ``units``, a path file's, ``--units``):
lengths of :data:`nurbsmotion.machine.LENGTH_UNITS_UM` and ``pulse`` (the machine's
encoder pulse); a curve's ``None`` means unspecified (pulses on a machine)."""
