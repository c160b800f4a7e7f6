"""nurbsmotion: NURBS interpolation for motion systems whose actuators saturate."""
from ._runtime.jit_cache import drop_stale_caches

drop_stale_caches()  # before any compiled function is loaded from disk

from ._runtime.lazy import lazy_names  # noqa: E402
from .errors import (  # noqa: E402
    InfeasibleError,
    InvalidCurveError,
    InvalidMachineError,
    NurbsmotionError,
    PathFileError,
)
_LAZY = {"NurbsCurve": "nurbs", "builtin_path": "nurbs", "make_arc": "nurbs",
         "make_butterfly": "nurbs", "make_circle": "nurbs", "make_die_bonder_pi": "nurbs",
         "make_line": "nurbs", "make_polyline": "nurbs", "elevate_degree": "joining",
         "join": "joining", "load_path": "paths", "resolve_path": "paths",
         "save_path": "paths", "Machine": "machine", "load_machine": "machine",
         "die_bonder": "machine", "run": "loop", "run_streamed": "loop", "simulate": "loop",
         "interpolate": "loop", "Trace": "loop", "Metrics": "metrics",
         "time_optimal_bound": "planning", "Scale": "units", "Job": "job",
         "RunResult": "job"}
"""Names loaded with their module on first use (PEP 562): importing the package costs
nothing, so the command can take a Ctrl-C while numpy and numba load."""

__all__ = ["InfeasibleError", "InvalidCurveError", "InvalidMachineError", "NurbsmotionError",
           "PathFileError", *_LAZY]


__getattr__, __dir__ = lazy_names(__name__, _LAZY)


__version__ = "0.1.0"
