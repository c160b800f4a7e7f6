"""Time and peak memory to load a large G-code program (issue 11: 1M lines <= 10 s, <= 1 GB).

Writes a CAM-like program of ``--lines`` lines into a temporary folder — a header of
comments, then a zig-zag of G1 moves (a new F every 1,000 lines, a comment line every 100,
a trailing comment on every 10th move) with a G2/G3 half circle every 50 lines, as a 2-axis
contour — and loads it in a fresh process with :func:`nurbsmotion.paths.gcode.load_gcode`,
reporting the wall and CPU time of the load, the process's peak resident memory right
after it, and the load average of the machine. ``--rounded-arcs`` writes the arcs' centres
with the rounding CAM posts leave (end radius 8e-5 mm off the start radius), which LinuxCNC
and this reader follow as spirals (rational cubic segments, about 19 per half circle here:
:func:`nurbsmotion.paths.pieces.spiral_segments`). Usage::

    python benchmarks/gcode_load.py --lines 1000000 [--rounded-arcs]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = r"""
import json, os, resource, sys, time, warnings
warnings.simplefilter("ignore")
t0 = time.perf_counter()
from nurbsmotion.paths.gcode import load_gcode
t1, c1 = time.perf_counter(), time.process_time()
program = load_gcode(sys.argv[1])
t2, c2 = time.perf_counter(), time.process_time()
c = program.contours[0]
print(json.dumps({"import_s": t1 - t0, "load_s": t2 - t1, "cpu_s": c2 - c1,
                  "contours": len(program.contours), "pieces": len(c.lines),
                  "control_points": c.curve.n_control_points, "degree": c.curve.degree,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "load_average": os.getloadavg()[0]}))
"""


def write_program(path: Path, n_lines: int, rounded_arcs: bool = False) -> None:
    centre = "I0.50004 J0" if rounded_arcs else "I0.5 J0"
    with open(path, "w") as f:
        f.write("(benchmark program, CAM-like)\n(T1 D=6 CR=0 - ZMIN=-1 - flat end mill)\n"
                "G21 G90 G17\nG0 X0 Y0\nF1200\n")
        x, y, k = 0.0, 0.0, 5
        while k < n_lines - 1:
            if k % 1000 == 0:
                f.write(f"F{1000 + (k // 1000) % 7 * 100}\n")
            elif k % 100 == 0:
                f.write(f"(pass {k // 100})\n")
            elif k % 50 == 25:  # a half circle of radius 0.5, up (G2) or down (G3)
                f.write(f"G{2 + (k // 50) % 2} X{x + 1:.4f} Y{y:.4f} {centre}\n")
                x += 1
            else:
                y = 0.2 if y == 0.0 else 0.0
                x += 0.05
                f.write(f"G1 X{x:.4f} Y{y:.4f}{' (cut)' if k % 10 == 0 else ''}\n")
            k += 1
        f.write("M2\n")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--lines", type=int, default=1_000_000)
    p.add_argument("--rounded-arcs", action="store_true", help="arcs as spirals (CAM rounding)")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.ngc"
        t0 = time.perf_counter()
        write_program(path, args.lines, args.rounded_arcs)
        print(f"wrote {args.lines:,} lines ({path.stat().st_size / 1e6:.1f} MB) in "
              f"{time.perf_counter() - t0:.1f} s")
        src = str(Path(__file__).resolve().parents[1] / "src")
        out = subprocess.run([sys.executable, "-c", CHILD, str(path)], capture_output=True, text=True,
                             env={"PYTHONPATH": src, "PATH": "/usr/bin:/bin"})
        if out.returncode != 0:
            print(out.stderr.strip().splitlines()[-1])
            return 1
        r = json.loads(out.stdout)
        print(f"load_gcode: {r['load_s']:.2f} s wall, {r['cpu_s']:.2f} s CPU (import {r['import_s']:.2f} s), "
              f"peak RSS {r['peak_rss_mb']:.0f} MB, load average {r['load_average']:.1f}; "
              f"{r['contours']} contour of {r['pieces']:,} pieces, degree {r['degree']}, "
              f"{r['control_points']:,} control points")
    return 0


if __name__ == "__main__":
    sys.exit(main())
