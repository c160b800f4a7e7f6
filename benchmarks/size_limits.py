"""Size limits checked early (issue 37): CPU time of `run`, `bound`, `interpolate` and
`contours` on path files of a million points, each to its one-line refusal (or its
listing).

Writes, in a temporary folder, four files of ``--points`` points (default 1,000,000):
``wave.json`` (a cubic B-spline along y = 2 sin(x/3) mm, 0.01 mm apart: its knot spans
exceed the planner's grid, planning.MAX_GRID_POINTS / (2 p)), ``zigzag.json`` (a degree-1
zigzag of 0.01 mm steps: every joint a right-angle corner, 51 grid points a piece), and
the same zigzag as G-code (``G1`` lines), as a DXF POLYLINE and as DXF LINE entities
(``lines.dxf``: shuffled, half of them drawn backwards, so the reader chains them by their
ends, as a CAD drawing's entities come). Runs each command in a
fresh process on the die-bonder at 100 mm/s and reports its CPU time (the child's user +
system time: the machine is shared, wall times mean little) and the first line of its
message. Usage::

    python benchmarks/size_limits.py [--points 1000000] [--timeout 300]
        [--files zigzag.dxf lines.dxf] [--commands contours] [--markdown FILE]

A path that is valid however large (a 100,000-chord CAM program) is measured by
benchmarks/cam_chords.py.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from _common import python_env

COMMANDS = {
    "run": ["run", "{file}", "--feed", "100mm/s", "--out", "{tmp}/run_{name}", "--no-figures",
            "--quiet"],
    "bound": ["bound", "{file}", "--feed", "100mm/s"],
    "interpolate": ["interpolate", "{file}", "--feed", "100mm/s", "--out",
                    "{tmp}/interpolate_{name}"],
    "contours": ["contours", "{file}"],
}


FILES = ("wave.json", "zigzag.json", "zigzag.ngc", "zigzag.dxf", "lines.dxf")


def write_files(folder: Path, n: int) -> dict:
    """The four path files of ``n`` points (see the module docstring) -> {name: path}."""
    x = np.round(np.arange(n) * 0.01, 4)
    wave = np.round(2.0 * np.sin(x / 3.0), 4)
    zig = np.round((np.arange(n) % 2) * 0.01, 4)
    files = {name: folder / name for name in FILES}
    knots3 = [0, 0, 0] + list(range(n - 2)) + [n - 3] * 3
    files["wave.json"].write_text(json.dumps({
        "units": "mm", "degree": 3, "knots": knots3,
        "control_points": np.column_stack([x, wave]).tolist()}, separators=(",", ":")))
    files["zigzag.json"].write_text(json.dumps({
        "units": "mm", "degree": 1, "knots": [0] + list(range(n)) + [n - 1],
        "control_points": np.column_stack([x, zig]).tolist()}, separators=(",", ":")))
    with open(files["zigzag.ngc"], "w") as f:
        f.write("G21 G90 G17\nG0 X0 Y0\nF6000\n")
        f.writelines(f"G1 X{a:.4f} Y{b:.4f}\n" for a, b in zip(x[1:], zig[1:]))
        f.write("M2\n")
    with open(files["zigzag.dxf"], "w") as f:  # R12: one POLYLINE, millimetres
        f.write("0\nSECTION\n2\nHEADER\n9\n$INSUNITS\n70\n4\n0\nENDSEC\n0\nSECTION\n2\n"
                "ENTITIES\n0\nPOLYLINE\n8\n0\n66\n1\n10\n0\n20\n0\n30\n0\n")
        f.writelines(f"0\nVERTEX\n8\n0\n10\n{a:.4f}\n20\n{b:.4f}\n30\n0\n"
                     for a, b in zip(x, zig))
        f.write("0\nSEQEND\n0\nENDSEC\n0\nEOF\n")
    rng = np.random.default_rng(0)
    order, backwards = rng.permutation(n - 1), rng.random(n - 1) < 0.5
    with open(files["lines.dxf"], "w") as f:  # R12: n - 1 LINE entities, millimetres
        f.write("0\nSECTION\n2\nHEADER\n9\n$INSUNITS\n70\n4\n0\nENDSEC\n0\nSECTION\n2\n"
                "ENTITIES\n")
        for i in order:
            a, b = (i + 1, i) if backwards[i] else (i, i + 1)
            f.write(f"0\nLINE\n8\n0\n10\n{x[a]:.4f}\n20\n{zig[a]:.4f}\n30\n0\n"
                    f"11\n{x[b]:.4f}\n21\n{zig[b]:.4f}\n31\n0\n")
        f.write("0\nENDSEC\n0\nEOF\n")
    return files


def cpu_of(args: list[str], timeout: float) -> tuple[float | None, int | None, str]:
    """(CPU seconds, exit code, first line of stderr or stdout) of ``python -m nurbsmotion
    ARGS`` in a fresh process; (None, None, 'timeout') beyond ``timeout`` s of wall time."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        out = subprocess.run([sys.executable, "-m", "nurbsmotion", *args], capture_output=True,
                             text=True, env=python_env(MPLBACKEND="Agg"), timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, None, f"not finished within {timeout:g} s"
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = (out.stderr.strip() or out.stdout.strip()).splitlines()
    return cpu, out.returncode, lines[-1] if lines else ""


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=1_000_000)
    p.add_argument("--timeout", type=float, default=300.0, help="wall seconds per command")
    p.add_argument("--files", nargs="+", choices=FILES, default=list(FILES),
                   help="the files to measure (default: all)")
    p.add_argument("--commands", nargs="+", choices=list(COMMANDS), default=list(COMMANDS),
                   help="the commands to run on each (default: all)")
    p.add_argument("--markdown", help="also write the table to this Markdown file")
    args = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        files = write_files(Path(tmp), args.points)
        for name, file in files.items():
            if name not in args.files:
                continue
            for command in args.commands:
                template = COMMANDS[command]
                argv = [a.format(file=file, tmp=tmp, name=name) for a in template]
                cpu, code, message = cpu_of(argv, args.timeout)
                rows.append((name, command, cpu, code, message))
                shown = "-" if cpu is None else f"{cpu:.2f}"
                print(f"| {name} | {command} | {shown} | {code} | {message[:160]} |",
                      flush=True)
    if args.markdown:
        head = ["| file | command | CPU [s] | exit | message |", "|---|---|---|---|---|"]
        body = [f"| {n} | {c} | {'-' if t is None else f'{t:.2f}'} | {e} | {m[:160]} |"
                for n, c, t, e, m in rows]
        Path(args.markdown).write_text("\n".join(
            [f"`python benchmarks/size_limits.py --points {args.points}`", ""] + head + body)
            + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
