"""The ``planned`` interpolator's offline plan (kept importable; moved).

The plan now lives in :mod:`nurbsmotion.interpolators.planned` (:mod:`.plan` and the
modules of its steps); this module re-exports its public names.
"""

from __future__ import annotations

from .interpolators.planned.blend import BLEND_ROUNDS, BLEND_STEPS, BLEND_THINNING, OVERSAMPLE
from .interpolators.planned.inverse import (END_REST, INVERSE_REACH, LEAD,
                                            PRECOMPENSATION_ROUNDS,
                                            PRECOMPENSATION_TOLERANCE, axis_zoh)
from .interpolators.planned.landing import FEED_SLACK, LANDING_SAMPLES
from .interpolators.planned.plan import (DRIVE_FIT_ROUNDS, MAX_GRID_REFINEMENT, MotionPlan,
                                         plan_motion)
from .interpolators.planned.shorten import (CHECK_POINTS, SHORTEN_ROUNDS, SHORTEN_STALL,
                                            SHORTEN_START, move_tolerance)
from .limits import DEFAULT_PATH_TOLERANCE, SHORT_MOVE_SAMPLES

__all__ = ["MotionPlan", "plan_motion", "axis_zoh", "move_tolerance",
           "DEFAULT_PATH_TOLERANCE", "SHORT_MOVE_SAMPLES", "PRECOMPENSATION_TOLERANCE",
           "PRECOMPENSATION_ROUNDS", "OVERSAMPLE", "MAX_GRID_REFINEMENT", "DRIVE_FIT_ROUNDS",
           "LEAD", "END_REST", "LANDING_SAMPLES", "INVERSE_REACH", "BLEND_STEPS",
           "BLEND_ROUNDS", "BLEND_THINNING", "FEED_SLACK", "CHECK_POINTS", "SHORTEN_ROUNDS",
           "SHORTEN_STALL", "SHORTEN_START"]
