"""Time and peak memory to load a large G-code program (issue 14: 1M lines <= 10 s, <= 1 GB).

Writes a CAM-like program of ``--lines`` lines into a temporary folder — a zig-zag of G1
moves (a new F every 1,000 lines) with a G2/G3 arc every 50 lines, as a 2-axis contour —
and loads it in a fresh process with :func:`nurbsmotion.paths.gcode.load_gcode`, reporting
the wall time of the load and the process's peak resident memory. Usage::

    python benchmarks/gcode_load.py --lines 1000000
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
import json, resource, sys, time, warnings
warnings.simplefilter("ignore")
t0 = time.perf_counter()
from nurbsmotion.paths.gcode import load_gcode
t1 = time.perf_counter()
program = load_gcode(sys.argv[1])
t2 = time.perf_counter()
c = program.contours[0]
print(json.dumps({"import_s": t1 - t0, "load_s": t2 - t1, "contours": len(program.contours),
                  "pieces": len(c.lines), "length": c.curve.length,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def write_program(path: Path, n_lines: int) -> None:
    with open(path, "w") as f:
        f.write("G21 G90 G17\nG0 X0 Y0\nF1200\n")
        x, y, k = 0.0, 0.0, 3
        while k < n_lines - 1:
            if k % 1000 == 0:
                f.write(f"F{1000 + (k // 1000) % 7 * 100}\n")
            elif k % 50 == 0:  # a half circle of radius 0.5 up and over
                f.write(f"G{2 + (k // 50) % 2} X{x + 1:.4f} Y{y:.4f} I0.5 J0\n")
                x += 1
            else:
                y = 0.2 if y == 0.0 else 0.0
                x += 0.05
                f.write(f"G1 X{x:.4f} Y{y:.4f}\n")
            k += 1
        f.write("M2\n")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--lines", type=int, default=1_000_000)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.ngc"
        t0 = time.perf_counter()
        write_program(path, args.lines)
        print(f"wrote {args.lines:,} lines ({path.stat().st_size / 1e6:.1f} MB) in "
              f"{time.perf_counter() - t0:.1f} s")
        src = str(Path(__file__).resolve().parents[1] / "src")
        out = subprocess.run([sys.executable, "-c", CHILD, str(path)], capture_output=True, text=True,
                             env={"PYTHONPATH": src, "PATH": "/usr/bin:/bin"})
        if out.returncode != 0:
            print(out.stderr.strip().splitlines()[-1])
            return 1
        r = json.loads(out.stdout)
        print(f"load_gcode: {r['load_s']:.2f} s (import {r['import_s']:.2f} s), peak RSS "
              f"{r['peak_rss_mb']:.0f} MB; {r['contours']} contour of {r['pieces']:,} pieces, "
              f"length {r['length']:.6g} mm")
    return 0


if __name__ == "__main__":
    sys.exit(main())
