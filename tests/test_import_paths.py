"""Old public import paths keep working after the layout moves of issue 31: each old path
gives the very objects its new home holds (one test per old module)."""

from __future__ import annotations

import importlib

import pytest


def _same(old: str, new: str, names) -> None:
    old_module, new_module = importlib.import_module(old), importlib.import_module(new)
    for name in names:
        assert getattr(old_module, name) is getattr(new_module, name), f"{old}.{name}"


def _same_each(old: str, new: dict[str, str]) -> None:
    """Every name of ``new`` (name -> new module) is the same object at ``old``."""
    before = importlib.import_module(old)
    for name, module in new.items():
        assert getattr(before, name) is getattr(importlib.import_module(module), name), name


def test_campaign():
    from nurbsmotion import campaign

    # ``digest``, the old name of make_digest, is kept by its module, not the package
    _same("nurbsmotion.campaign", "nurbsmotion.study", set(campaign.__all__) - {"digest"})
    _same("nurbsmotion.campaign", "nurbsmotion.study.digest", ["digest", "make_digest"])


def test_experiments():
    from nurbsmotion import experiments

    _same("nurbsmotion.experiments", "nurbsmotion.study.reproduce", experiments.__all__)
    _same("nurbsmotion.experiments", "nurbsmotion.study", set(experiments.__all__)
          - {"reproduce", "PAPER_INTERPOLATORS"})


def test_digest_and_reproduce_are_modules_of_study_and_their_functions_have_names():
    """Issue 31: ``study.digest`` and ``study.reproduce`` were both a module and a
    function; the modules keep the names, the functions are ``make_digest`` and
    ``run_experiment``, and the old function names still import from the modules."""
    import types

    import nurbsmotion.study as study
    from nurbsmotion.study.digest import digest
    from nurbsmotion.study.reproduce import reproduce

    assert isinstance(study.digest, types.ModuleType)
    assert isinstance(study.reproduce, types.ModuleType)
    assert digest is study.make_digest and reproduce is study.run_experiment


def test_run_input():
    from nurbsmotion import run_input

    _same("nurbsmotion.run_input", "nurbsmotion.study.run_input", run_input.__all__)


@pytest.mark.parametrize("name", ["run_study", "run_case", "load_study", "read_rows",
                                  "write_digest", "reproduce_outputs", "make_digest",
                                  "run_experiment"])
def test_study_package_exports(name):
    import nurbsmotion.study as study

    assert callable(getattr(study, name))


def test_cli():
    """cli.py became the package cli/: its public names and main keep their path."""
    from nurbsmotion import cli

    _same("nurbsmotion.cli", "nurbsmotion.cli.parser", ["parse_feed", "synopsis"])
    _same("nurbsmotion.cli", "nurbsmotion.cli.console", ["project_outputs"])
    assert callable(cli.main) and cli.__all__ == ["main", "parse_feed", "synopsis",
                                                  "project_outputs"]


def test_loop():
    # nurbsmotion.loop became a package: its results moved to loop.trace, and the run
    # functions stay in the package itself.
    import nurbsmotion.loop as loop

    _same("nurbsmotion.loop", "nurbsmotion.loop.trace", ["Trace", "RunOutcome", "SetpointSeries"])
    assert set(loop.__all__) <= set(dir(loop))


def test_export():
    from nurbsmotion.report import export

    _same("nurbsmotion.export", "nurbsmotion.report.export", export.__all__)


def test_report():
    # the trace file's writer moved to report.trace_file; nurbsmotion.report keeps its names
    from nurbsmotion.report import trace_file

    _same("nurbsmotion.report", "nurbsmotion.report.trace_file", trace_file.__all__[:2] + trace_file.__all__[3:])


def test_plots():
    # plots.py became a package (canvas, events, figures); its public names stay here
    import nurbsmotion.plots as plots

    _same("nurbsmotion.plots", "nurbsmotion.plots.figures",
          set(plots.__all__) - {"settling_time", "MAX_EVENT_WINDOWS"})
    _same("nurbsmotion.plots", "nurbsmotion.plots.events", ["settling_time", "MAX_EVENT_WINDOWS"])


def test_motion_plan():
    """``nurbsmotion.motion_plan`` (now ``interpolators/planned/``): the plan, its
    functions and the constants the CLI and the benchmarks read."""
    p = "nurbsmotion.interpolators.planned."
    _same_each("nurbsmotion.motion_plan", {
        "plan_motion": p + "plan", "MotionPlan": p + "plan", "axis_zoh": p + "inverse",
        "move_tolerance": p + "shorten", "DEFAULT_PATH_TOLERANCE": "nurbsmotion.limits",
        "SHORT_MOVE_SAMPLES": "nurbsmotion.limits", "PRECOMPENSATION_TOLERANCE": p + "inverse",
        "LEAD": p + "inverse", "FEED_SLACK": p + "landing", "OVERSAMPLE": p + "blend"})
    import nurbsmotion.motion_plan as old
    assert set(old.__all__) <= set(dir(old))


def test_interpolators_planned():
    """``nurbsmotion.interpolators.planned`` (a module, now a package): its public names."""
    p = "nurbsmotion.interpolators.planned."
    _same_each("nurbsmotion.interpolators.planned", {
        "PlannedInterpolator": p + "interpolator", "PlannedPlan": p + "interpolator",
        "PlannedState": p + "interpolator", "online_step": p + "step",
        "DEFAULT_TRACKING_POLE": p + "interpolator", "DEFAULT_DRIVE_HEADROOM": p + "interpolator",
        "reading_knowledge": p + "identify", "SUPPORT_DIRECTIONS": p + "governor",
        "GAIN_RANGE": p + "identify", "RATE_WINDOW": p + "governor"})


def test_paths_ngc():
    from nurbsmotion.paths.gcode import ngc

    _same("nurbsmotion.paths.ngc", "nurbsmotion.paths.gcode.ngc", ngc.__all__)


def test_paths_gcode():
    """paths.gcode is now a package; what the module exported comes from its parts."""
    _same("nurbsmotion.paths.gcode", "nurbsmotion.paths.gcode.reader", ["load_gcode"])
    _same("nurbsmotion.paths.gcode", "nurbsmotion.paths.gcode.program",
          ["GcodeContour", "GcodeProgram", "GcodeWarning"])
    _same("nurbsmotion.paths.gcode", "nurbsmotion.paths.gcode.writer",
          ["save_gcode", "format_number", "decimals_for"])
    _same("nurbsmotion.paths.gcode", "nurbsmotion.paths.gcode.curves", ["linuxcnc_knots"])
    _same("nurbsmotion.paths", "nurbsmotion.paths.gcode",
          ["GcodeContour", "GcodeProgram", "GcodeWarning", "load_gcode", "save_gcode"])


def test_identify():
    """``nurbsmotion.identify`` was one module; it is a subpackage whose ``__init__``
    re-exports every public name the module had."""
    _same("nurbsmotion.identify", "nurbsmotion.identify.log",
          ["Log", "read_log", "log_from_arrays", "POSITION_SUFFIXES", "DRIVE_SUFFIXES",
           "LOG_UNITS", "TIME_UNITS", "MAX_JITTER"])
    _same("nurbsmotion.identify", "nurbsmotion.identify.identification",
          ["Estimate", "AxisIdentification", "Identification", "identify",
           "write_identification", "TAU_SPREAD", "DEFAULT_MECHANICAL_GAIN"])
    _same("nurbsmotion.identify", "nurbsmotion.identify.excite",
          ["excitation", "excitation_gcode", "write_excitation_csv", "DEFAULT_TRAVEL_MM"])
    import nurbsmotion.identify as package

    assert callable(package.identify)  # the function, not a submodule of that name
    assert set(package.__all__) <= set(dir(package))


def test_plant():
    # plant.py became the subpackage plant/ (issue 31): every public name of the module
    # is still at nurbsmotion.plant, the very object of its new home.
    _same_each("nurbsmotion.plant", {
        "oscillator": "nurbsmotion.plant.two_mass",
        "x_minus_one_minus_exp": "nurbsmotion.plant.linear",
        "N_PARAM": "nurbsmotion.plant.two_mass", "N_COEF": "nurbsmotion.plant.two_mass",
        "MAX_EVENTS": "nurbsmotion.plant.friction",
        "TAYLOR_TERMS": "nurbsmotion.plant.friction", "SCRATCH": "nurbsmotion.plant.friction",
        "PlantStage": "nurbsmotion.plant.stage", "IdleStage": "nurbsmotion.plant.stage",
        "PlantState": "nurbsmotion.plant.stage", "is_active": "nurbsmotion.plant.stage",
        "make_stage": "nurbsmotion.plant.stage", "inactive_stage": "nurbsmotion.plant.stage",
        "new_plant_state": "nurbsmotion.plant.stage",
        "sample_step": "nurbsmotion.plant.step", "stage_arrays": "nurbsmotion.plant.step",
        "stage_response": "nurbsmotion.plant.step",
        "measure": "nurbsmotion.plant.sensor", "noise_draw": "nurbsmotion.plant.sensor",
        "positions": "nurbsmotion.plant.sensor",
        "continuous_model": "nurbsmotion.plant.linear",
        "linear_loop_poles": "nurbsmotion.plant.linear"})
