"""Old public import paths keep working after the layout moves of issue 31: each old path
gives the very object its new home holds (one test per old module)."""

from __future__ import annotations

import importlib


def _same(old: str, new: str, names) -> None:
    old_module, new_module = importlib.import_module(old), importlib.import_module(new)
    for name in names:
        assert getattr(old_module, name) is getattr(new_module, name), f"{old}.{name}"


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
