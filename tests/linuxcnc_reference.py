"""LinuxCNC's own interpreter as a reference for the G-code reader (helpers for the tests).

:func:`linuxcnc_moves` runs ``tests/tools/linuxcnc_points.py`` with an interpreter that
can import LinuxCNC's ``gcode`` module (Debian package ``linuxcnc-uspace``): this Python
if it can, else Debian's ``/usr/bin/python3``; it returns None when neither can, so the
tests skip. :func:`max_distance` measures how far LinuxCNC's feed points lie from the
contours nurbsmotion read.
"""

from __future__ import annotations

import functools
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

HELPER = Path(__file__).resolve().parent / "tools" / "linuxcnc_points.py"


@functools.lru_cache(maxsize=1)
def linuxcnc_python() -> str | None:
    """An interpreter that imports LinuxCNC's ``gcode`` module, or None."""
    for exe in (sys.executable, "/usr/bin/python3"):
        try:
            r = subprocess.run([exe, "-c", "import gcode, rs274.interpret"], capture_output=True,
                               timeout=60)
        except (OSError, subprocess.TimeoutExpired):
            continue
        if r.returncode == 0:
            return exe
    return None


def linuxcnc_moves(program: Path) -> dict:
    """``{"error": str | None, "moves": [[kind, line, [x..w], feed], ...]}`` in mm and
    mm/min (see the helper)."""
    exe = linuxcnc_python()
    with tempfile.TemporaryDirectory() as tmp:  # LinuxCNC writes its rs274ngc.var there
        r = subprocess.run([exe, str(HELPER), str(Path(program).resolve())], capture_output=True,
                           text=True, timeout=120, cwd=tmp)
    if r.returncode != 0:
        return {"error": r.stderr.strip().splitlines()[-1] if r.stderr.strip() else "failed", "moves": []}
    return json.loads(r.stdout)


def distances_to_path(points: np.ndarray, curves: list, seeds: int = 8) -> np.ndarray:
    """Distance of every point (shape (m, d)) to the nearest of ``curves``: from each of
    the ``seeds`` nearest of dense samples (several, so that a point between close passes
    of the path, such as the turns of a helical ramp, also starts on its own pass), the
    foot point is refined by Newton's method on ``(C(u) - p) . C'(u) = 0`` (clamped to
    [0, 1]), which is exact to rounding; a point at a corner is measured to the junction
    itself."""
    best = np.full(len(points), np.inf)
    for c in curves:
        n = max(4000, 40 * c.n_control_points)
        u0 = np.linspace(0.0, 1.0, n)
        _, idx = cKDTree(c(u0)).query(points, k=seeds)
        idx = idx.reshape(len(points), -1)
        target = np.repeat(points, idx.shape[1], axis=0)
        u = u0[idx.ravel()]
        for _ in range(30):
            d = c.derivatives(u, 2)
            r = d[0] - target
            g = np.sum(r * d[1], axis=1)
            h = np.sum(d[1] * d[1], axis=1) + np.sum(r * d[2], axis=1)
            step = np.where(h > 0, g / np.where(h > 0, h, 1.0), 0.0)
            u = np.clip(u - np.clip(step, -1.0 / n, 1.0 / n), 0.0, 1.0)
        dist = np.minimum(np.linalg.norm(c(u) - target, axis=1),
                          np.linalg.norm(c(u0[idx.ravel()]) - target, axis=1))
        best = np.minimum(best, dist.reshape(idx.shape).min(axis=1))
        # Newton's method does not settle on a corner (a junction knot, where C' jumps);
        # the junctions themselves are candidates too.
        corner_dist, _ = cKDTree(c(c.breakpoints)).query(points)
        best = np.minimum(best, corner_dist)
    return best


def max_distance(program: Path, contours: list, scale_to_mm: float = 1.0, axes: str = "xyz") -> tuple[float, int]:
    """Largest distance [mm] from LinuxCNC's feed and arc points to the contours, and the
    number of points compared."""
    ref = linuxcnc_moves(program)
    idx = ["xyzabcuvw".index(a) for a in axes]
    pts = np.array([m[2] for m in ref["moves"] if m[0] in ("feed", "arc")], dtype=float)
    if pts.size == 0:
        return 0.0, 0
    pts = pts[:, idx]
    curves = [c.scaled(scale_to_mm) if scale_to_mm != 1.0 else c for c in contours]
    return float(np.max(distances_to_path(pts, curves))), len(pts)
