"""G-code export: a path written as a LinuxCNC program of ``G5.2`` blocks, one per rational
Bézier segment (:func:`save_gcode`), and the number formatting it and other writers use.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..._runtime.io import write_output
from ...errors import PathFileError
from ...joining import bezier_segments, elevate_degree
from ...nurbs import NurbsCurve

__all__ = ["save_gcode", "format_number", "decimals_for"]


def format_number(x: float, decimals: int) -> str:
    """``x`` in plain positional notation (G-code has no exponents), at most ``decimals``
    digits after the point, trailing zeros trimmed."""
    text = np.format_float_positional(float(x), precision=decimals, unique=True, trim="-")
    return "0" if text in ("-0", "-0.") else text


def decimals_for(size: float, significant: int = 12) -> int:
    """Digits after the point that give ``significant`` digits relative to ``size``."""
    return max(0, significant - int(math.floor(math.log10(size))) - 1) if size > 0 else significant


def save_gcode(
    curve: NurbsCurve,
    file: str | os.PathLike,
    *,
    feed: float,
    units: str | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``curve`` as a LinuxCNC program of G5.2 NURBS blocks (see the module docstring).

    Parameters
    ----------
    curve : NurbsCurve
        A 2-axis path.
    file : str or path-like
        Output program (``.ngc``).
    feed : float
        Programmed feed [path units / s]; written as F in units per minute.
    units : {"mm", "inch"}, optional
        Units to declare (G21/G20); defaults to ``curve.units``, which must then be one of
        these. Numbers are written as they are, not converted.
    overwrite : bool
        Replace an existing file.

    Raises
    ------
    PathFileError
        For a curve that is not 2-axis, units that G-code cannot declare, or a bad feed.
    OutputExistsError
        If the file exists and ``overwrite`` is false.
    """
    units = units or curve.units
    if units not in ("mm", "inch"):
        raise PathFileError(
            f"G-code declares mm (G21) or inch (G20), but the curve is in {curve.units!r}; "
            "scale it (e.g. curve.scaled(1e-3, units='mm') for pulses of 1 um) or pass "
            "units='mm' to write its numbers unchanged",
            source=str(file),
        )
    if curve.n_axes != 2:
        raise PathFileError(f"G5.2 carries XY paths; the curve has {curve.n_axes} axes", str(file))
    if not (np.isfinite(feed) and feed > 0):
        raise PathFileError(f"feed must be finite and > 0, got {feed!r}", str(file))
    d = decimals_for(float(np.max(np.ptp(curve.control_points, axis=0))))

    def xy(point) -> str:
        return f"X{format_number(point[0], d)} Y{format_number(point[1], d)}"

    def weight(w) -> str:
        return format_number(w, decimals_for(abs(w), 15))

    lines = [
        f"(nurbsmotion path {curve.name or ''}: {curve.n_control_points} control points, "
        f"degree {curve.degree}, length {curve.length:.9g} {units})",
        f"{'G21' if units == 'mm' else 'G20'} G90 G17 G94",
        f"G0 {xy(curve.control_points[0])}",
        f"F{format_number(feed * 60.0, decimals_for(feed * 60.0, 12))}",
    ]
    source = elevate_degree(curve, 2) if curve.degree < 2 else curve
    order = source.degree + 1
    for segment in bezier_segments(source):
        w = segment.weights
        lines.append(f"G5.2 P{weight(w[0])} L{order}")
        lines.extend(f"     {xy(pt)} P{weight(wi)}" for pt, wi in zip(segment.control_points[1:], w[1:]))
        lines.append("G5.3")
    lines.append("M2")
    text = "\n".join(lines) + "\n"
    return write_output(file, lambda f: f.write(text), overwrite=overwrite)
