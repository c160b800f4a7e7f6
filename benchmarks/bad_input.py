"""Issue 14: how fast bad or huge inputs are answered, and how a large valid one loads.

- wall time of the ``nurbsmotion`` command (a fresh process, imports and kernel cache load
  included) to refuse: a 28-hour move (``run die-bonder-pi --feed 1``), ``interpolate
  butterfly --feed 1e-3`` (3.8e8 samples), ``--pvt-period 1e-12``, ``bound --feed 1e-320``,
  a tiny ``--sample-period``; each must exit 2 with one line;
- the load time of a 600,000-point degree-1 JSON polyline (about 27 MB) and of one of
  60,000 points (linear in size);
- the time-optimal bound of a 25 m path of 5 mm sine waves (32,001 control points) with
  the default grid against a 10 times finer one (the grid adapts to the knot spans).

    python benchmarks/bad_input.py
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import _common  # noqa: F401  (puts src/ on the path)
from _common import ROOT, python_env, section

REFUSALS = [
    ["run", "die-bonder-pi", "--feed", "1", "--out", "{out}"],
    ["interpolate", "butterfly", "--feed", "1e-3", "--out", "{out}"],
    ["run", "die-bonder-pi", "--feed", "1m/s", "--export", "pvt", "--pvt-period", "1e-12",
     "--out", "{out}"],
    ["bound", "die-bonder-pi", "--feed", "1e-320"],
    ["interpolate", "butterfly", "--feed", "100", "--sample-period", "1e-12", "--out",
     "{out}"],
]


def refusal_rows(folder: Path) -> list[list]:
    rows = []
    for argv in REFUSALS:
        args = [a.format(out=folder / "out") for a in argv]
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "nurbsmotion.cli", *args],
                              env=python_env(), capture_output=True, text=True, cwd=ROOT)
        wall = time.perf_counter() - t0
        lines = done.stderr.strip().splitlines()
        rows.append([" ".join(argv[:4]) + " ...", done.returncode, len(lines),
                     f"{wall:.2f}"])
    return rows


def polyline_file(folder: Path, n: int) -> Path:
    x = np.round(np.linspace(0.0, n / 1000.0, n), 6)
    y = np.round(0.5 * np.sin(7.0 * x), 6)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    path = folder / f"poly{n}.json"
    path.write_text(json.dumps({"degree": 1, "knots": [0.0, *(s / s[-1]).tolist(), 1.0],
                                "control_points": np.column_stack([x, y]).tolist(),
                                "units": "mm"}))
    return path


def load_rows(folder: Path) -> list[list]:
    from nurbsmotion.paths import load_path

    rows = []
    for n in (60_000, 600_000):
        path = polyline_file(folder, n)
        t0 = time.perf_counter()
        load_path(path)
        rows.append([f"{n:,}", f"{path.stat().st_size / 1e6:.1f}",
                     f"{time.perf_counter() - t0:.2f}"])
    return rows


def sine_rows() -> list[list]:
    from scipy.interpolate import make_interp_spline

    from nurbsmotion.loop import to_pulses
    from nurbsmotion.machine import die_bonder
    from nurbsmotion.nurbs import NurbsCurve
    from nurbsmotion.planning import time_optimal_bound

    x = np.linspace(0.0, 25_000.0, 31_999)
    spline = make_interp_spline(x, np.column_stack([x, np.sin(2 * np.pi * x / 5.0)]), k=3)
    machine = die_bonder()
    curve = to_pulses(NurbsCurve(3, spline.t, spline.c, units="mm"), machine)
    rows = []
    for grid in (20_000, 200_000):
        t0 = time.perf_counter()
        bound = time_optimal_bound(curve, machine, 1e6, grid_size=grid)
        rows.append([f"{grid:,}", f"{bound:.6g}", f"{time.perf_counter() - t0:.1f}"])
    return rows


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        section("Refusals (fresh process each)", ["command", "exit", "stderr lines",
                                                   "wall [s]"], refusal_rows(folder))
        section("Loading a degree-1 JSON polyline", ["points", "MB", "load [s]"],
                load_rows(folder))
    section("Bound of 25 m of 5 mm sine waves at 1 m/s (32,001 control points)",
            ["grid_size", "bound [s]", "time [s]"], sine_rows())


if __name__ == "__main__":
    main()
