"""Path files: built-in benchmarks, JSON/TOML path files, G-code and DXF import/export.

``resolve_path(spec)`` is the one entry point the command line needs: a built-in name
(``"die-bonder-pi"``, ``"butterfly"``) or a file, dispatched by its ending (``.json``,
``.toml``, ``.ngc``/``.nc``/``.gcode``, ``.dxf``).
"""

from .files import (PATH_FILE_SUFFIXES, PATH_UNITS, Contour, PathWarning, curve_from_dict,
                    load_contour, load_contours, load_path, resolve_contour, resolve_path,
                    save_path)
from .dxf import DxfWarning, load_dxf, save_dxf
from .gcode import GcodeContour, GcodeProgram, GcodeWarning, load_gcode, save_gcode

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
