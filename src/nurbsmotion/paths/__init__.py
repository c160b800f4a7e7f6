"""Path files: built-in benchmarks, JSON/TOML path files, G-code and DXF import/export.

``resolve_path(spec)`` is the one entry point the command line needs: a built-in name
(``"die-bonder-pi"``, ``"butterfly"``) or a file, dispatched by its ending (``.json``,
``.toml``, ``.ngc``/``.nc``/``.gcode``, ``.dxf``).
"""

from .files import (PATH_FILE_SUFFIXES, PATH_UNITS, Contour, PathWarning, curve_from_dict,
                    load_contour, load_contours, load_path, resolve_contour, resolve_path,
                    save_path)

_LAZY = {name: "dxf" for name in ("DxfWarning", "load_dxf", "save_dxf")}
_LAZY.update({name: "gcode" for name in ("GcodeContour", "GcodeProgram", "GcodeWarning",
                                         "load_gcode", "save_gcode")})


def __getattr__(name):
    """The G-code and DXF readers load on first use (a run of a built-in or JSON path
    does not pay their import)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value

__all__ = [
    "Contour",
    "PathWarning",
    "PATH_UNITS",
    "load_contour",
    "load_contours",
    "resolve_contour",
    "load_path",
    "save_path",
    "resolve_path",
    "curve_from_dict",
    "PATH_FILE_SUFFIXES",
    "load_gcode",
    "save_gcode",
    "GcodeProgram",
    "GcodeContour",
    "GcodeWarning",
    "load_dxf",
    "save_dxf",
    "DxfWarning",
]
