"""nurbsmotion: NURBS interpolation for motion systems whose actuators saturate."""
from ._jit_cache import drop_stale_caches

drop_stale_caches()  # before any compiled function is loaded from disk

from .errors import (  # noqa: E402
    InfeasibleError,
    InvalidCurveError,
    InvalidMachineError,
    NurbsmotionError,
    PathFileError,
)
from .nurbs import (
    NurbsCurve,
    builtin_path,
    make_arc,
    make_butterfly,
    make_circle,
    make_die_bonder_pi,
    make_line,
    make_polyline,
)
from .joining import elevate_degree, join

__all__ = ["InfeasibleError", "InvalidCurveError", "InvalidMachineError", "NurbsmotionError",
           "PathFileError", "NurbsCurve", "builtin_path", "make_arc", "make_butterfly",
           "make_circle", "make_die_bonder_pi", "make_line", "make_polyline",
           "elevate_degree", "join", "load_path", "resolve_path", "save_path"]


def __getattr__(name):
    """The path-file functions load with :mod:`nurbsmotion.paths` on first use."""
    if name in ("load_path", "resolve_path", "save_path"):
        from . import paths

        return getattr(paths, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__version__ = "0.1.0"
