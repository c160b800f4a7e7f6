"""Old import paths keep working after the layout moves of issue 31: each gives the same
objects as the new path (one test per old module)."""

import importlib


def _same(old: str, new: str, names) -> None:
    old_module, new_module = importlib.import_module(old), importlib.import_module(new)
    for name in names:
        assert getattr(old_module, name) is getattr(new_module, name), name


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
