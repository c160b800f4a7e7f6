"""nurbsmotion: NURBS interpolation for motion systems whose actuators saturate."""
from .errors import (
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
from .paths import load_path, resolve_path, save_path

__version__ = "0.1.0"
