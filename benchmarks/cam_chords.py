"""CAM chord programs (issue 37 item 3): `bound` and `run` CPU time against the number of
chords, and `planned`'s time over the bound.

Writes programs of N G1 chords of 0.01 mm at F6000 (100 mm/s) along a wave (y = 2 sin(x/3)
mm; coordinates with 4 decimals, as CAM posts write them), and runs, each in a fresh
process on the die-bonder: `bound`, `bound --sampled`, and `run --no-figures --no-trace`
with `planned` (the chord runs joined within the default path tolerance, one pulse = 1 um).
`--as-programmed N` also runs the chords as programmed (`--path-tolerance 0`: every joint
a corner) up to N chords, for the ratio before the join. Reports each command's CPU time
(the child's user + system time: the machine is shared, wall times mean little) and the
cycle-time ratio. Usage::

    python benchmarks/cam_chords.py [--chords 1000 10000 100000] [--as-programmed 1000]
        [--markdown benchmarks/cam_chords.md]

``--markdown FILE`` also writes the table, with the commit and the command, to FILE.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from _common import python_env


def write_program(path: Path, n: int, chord: float = 0.01) -> None:
    """``n`` chords of ``chord`` mm along y = 2 sin(x / 3), 4 decimals, F6000."""
    x = np.linspace(0.0, n * chord, 20 * n + 1)
    y = 2.0 * np.sin(x / 3.0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    t = np.arange(n + 1) * chord
    xs, ys = np.interp(t, s, x), np.interp(t, s, y)
    with open(path, "w") as f:
        f.write("(CAM chords)\nG21 G90 G17\nG0 X0 Y0\nF6000\n")
        f.writelines(f"G1 X{a:.4f} Y{b:.4f}\n" for a, b in zip(xs[1:], ys[1:]))
        f.write("M2\n")


def cpu_of(args: list[str]) -> tuple[float, str, str]:
    """(CPU seconds, stdout, stderr) of ``python -m nurbsmotion ARGS`` in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, "-m", "nurbsmotion", *args], capture_output=True,
                         text=True, env=python_env(MPLBACKEND="Agg"))
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(args)}: {out.stderr.strip().splitlines()[-1:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, out.stdout, out.stderr


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--chords", type=int, nargs="+", default=[1000, 10000, 100000])
    p.add_argument("--as-programmed", type=int, default=1000,
                   help="also run the chords as programmed up to this many chords")
    p.add_argument("--markdown", help="also write the table to this Markdown file")
    args = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        warm = Path(tmp) / "warm.ngc"                # numba's caches filled first: a
        write_program(warm, 200)                     # cold run compiles for ~30 s of CPU
        for tol in ("1", "0"):
            cpu_of(["run", str(warm), "--out", str(Path(tmp) / f"warm{tol}"), "--no-figures",
                    "--no-trace", "--quiet", "--path-tolerance", tol])
        for n in args.chords:
            prog = Path(tmp) / f"chords_{n}.ngc"
            write_program(prog, n)
            for tol in (["1"] + (["0"] if n <= args.as_programmed else [])):
                extra = ["--path-tolerance", tol]
                row = {"chords": n, "path_tolerance_pulse": float(tol)}
                row["bound_cpu_s"], out, err = cpu_of(["bound", str(prog), *extra])
                row["bound_s"] = float(out)
                row["joined"] = next((ln[6:] for ln in err.splitlines()
                                      if ln.startswith("path: ")), "nothing")
                row["sampled_cpu_s"], out, _ = cpu_of(["bound", str(prog), "--sampled", *extra])
                row["sampled_bound_s"] = float(out)
                run_dir = Path(tmp) / f"run_{n}_{tol}"
                row["run_cpu_s"], _, _ = cpu_of(["run", str(prog), "--out", str(run_dir),
                                                 "--no-figures", "--no-trace", "--quiet",
                                                 *extra])
                data = json.loads((run_dir / "summary.json").read_text())
                row.update(cycle_time_s=data["cycle_time_s"],
                           ratio=data["cycle_time_s"] / data["time_optimal_bound_s"],
                           settle_time_s=data["settle_time_s"],
                           saturated=sum(data["saturated_samples"].values()))
                rows.append(row)
                print(json.dumps(row), flush=True)
    lines = [f"load average {os.getloadavg()[0]:.1f}; CPU = user + system of each command",
             "",
             "| chords | tolerance [pulse] | joined | bound CPU [s] | bound --sampled CPU [s] "
             "| run CPU [s] | planned / bound | sampled bound [s] | settle [s] | saturated |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['chords']:,} | {r['path_tolerance_pulse']:g} | {r['joined']} | "
              f"{r['bound_cpu_s']:.2f} | {r['sampled_cpu_s']:.2f} | {r['run_cpu_s']:.2f} | "
              f"{r['ratio']:.3f} | {r['sampled_bound_s']:.4g} | {r['settle_time_s']:.4g} | "
              f"{r['saturated']} |" for r in rows]
    print("\n" + "\n".join(lines))
    if args.markdown:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=Path(__file__).parent).stdout.strip()
        command = " ".join(["python benchmarks/cam_chords.py", *sys.argv[1:]])
        Path(args.markdown).write_text(
            "# CAM chord programs: `bound`, `bound --sampled` and `run` (issue 37 item 3)\n\n"
            f"Generated by `{command}` on commit {commit} (G1 chords of 0.01 mm at F6000 on "
            "the die-bonder, `planned`; each command in a fresh process).\n\n"
            + "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
