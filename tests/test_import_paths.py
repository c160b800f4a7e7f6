"""Old import paths keep working after the modules moved (issue 31): each old path gives
the very objects of the new one. One test per old module."""

from __future__ import annotations

import importlib


def _same(old: str, new: dict[str, str]) -> None:
    """Every name of ``new`` (name -> new module) is the same object at ``old``."""
    before = importlib.import_module(old)
    for name, module in new.items():
        assert getattr(before, name) is getattr(importlib.import_module(module), name), name


def test_motion_plan():
    """``nurbsmotion.motion_plan`` (now ``interpolators/planned/``): the plan, its
    functions and the constants the CLI and the benchmarks read."""
    p = "nurbsmotion.interpolators.planned."
    _same("nurbsmotion.motion_plan", {
        "plan_motion": p + "plan", "MotionPlan": p + "plan", "axis_zoh": p + "inverse",
        "move_tolerance": p + "shorten", "DEFAULT_PATH_TOLERANCE": p + "shorten",
        "SHORT_MOVE_SAMPLES": p + "shorten", "PRECOMPENSATION_TOLERANCE": p + "inverse",
        "LEAD": p + "inverse", "FEED_SLACK": p + "landing", "OVERSAMPLE": p + "blend"})
    import nurbsmotion.motion_plan as old
    assert set(old.__all__) <= set(dir(old))


def test_interpolators_planned():
    """``nurbsmotion.interpolators.planned`` (a module, now a package): its public names."""
    p = "nurbsmotion.interpolators.planned."
    _same("nurbsmotion.interpolators.planned", {
        "PlannedInterpolator": p + "interpolator", "PlannedPlan": p + "interpolator",
        "PlannedState": p + "interpolator", "online_step": p + "step",
        "DEFAULT_TRACKING_POLE": p + "interpolator", "DEFAULT_DRIVE_HEADROOM": p + "interpolator",
        "reading_knowledge": p + "identify", "SUPPORT_DIRECTIONS": p + "governor",
        "GAIN_RANGE": p + "identify", "RATE_WINDOW": p + "governor"})
