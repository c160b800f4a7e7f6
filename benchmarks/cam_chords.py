"""CAM chord programs (issue 37 item 3): `bound` and `run` CPU time against the number of
chords, and `planned`'s time over the bound.

Writes programs of N G1 chords of 0.01 mm at F6000 (100 mm/s) along a wave (y = 2 sin(x/3)
mm; coordinates with 4 decimals, as CAM posts write them), and runs, each in a fresh
process on the die-bonder: `bound`, `bound --sampled`, and `run --no-figures --no-trace`
with `planned` (the chord runs joined within the default path tolerance, one pulse = 1 um).
`--as-programmed N` also runs the chords as programmed (`--path-tolerance 0`: every joint
a corner) up to N chords, for the ratio before the join. Reports each command's CPU time
(the child's user + system time: the machine is shared, wall times mean little) and the
cycle-time ratio. ``--repeat R`` runs each command R times and reports the median CPU time
and the range (the machine is shared: one run varies by about 10 %). The table also gives
both bounds: ``bound`` (the feed's time-optimal bound, which the run is compared with) and
``bound --sampled``, which ignores the feed (its documented meaning: a lower bound for any
sampled motion within Umax, whatever its speed): on a feed-limited program it is far below
the run (0.17 s for 1,000 mm at 100 mm/s: the drive alone could move the path's extent
that fast). Usage::

    python benchmarks/cam_chords.py [--chords 1000 10000 30000 100000] [--as-programmed 1000]
        [--repeat 3] [--markdown benchmarks/cam_chords.md]

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
    p.add_argument("--chords", type=int, nargs="+", default=[1000, 10000, 30000, 100000])
    p.add_argument("--as-programmed", type=int, default=1000,
                   help="also run the chords as programmed up to this many chords")
    p.add_argument("--repeat", type=int, default=1, help="runs of each command (median, range)")
    p.add_argument("--markdown", help="also write the table to this Markdown file")
    args = p.parse_args()
    rows = []
    loads = [os.getloadavg()[0]]
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
                cpu = {"bound": [], "sampled": [], "run": []}
                for r in range(args.repeat):
                    t, out, err = cpu_of(["bound", str(prog), *extra])
                    cpu["bound"].append(t)
                    row["bound_s"] = float(out)
                    row["joined"] = next((ln[6:] for ln in err.splitlines()
                                          if ln.startswith("path: ")), "nothing")
                    t, out, _ = cpu_of(["bound", str(prog), "--sampled", *extra])
                    cpu["sampled"].append(t)
                    row["sampled_bound_s"] = float(out)
                    run_dir = Path(tmp) / f"run_{n}_{tol}_{r}"
                    t, _, _ = cpu_of(["run", str(prog), "--out", str(run_dir), "--no-figures",
                                      "--no-trace", "--quiet", *extra])
                    cpu["run"].append(t)
                for key, times in cpu.items():
                    row[f"{key}_cpu_s"] = float(np.median(times))
                    row[f"{key}_cpu_range_s"] = [min(times), max(times)]
                data = json.loads((run_dir / "summary.json").read_text())
                row.update(cycle_time_s=data["cycle_time_s"],
                           ratio=data["cycle_time_s"] / data["time_optimal_bound_s"],
                           settle_time_s=data["settle_time_s"],
                           saturated=sum(data["saturated_samples"].values()))
                rows.append(row)
                print(json.dumps(row), flush=True)
    loads.append(os.getloadavg()[0])

    def cpu(r, key):
        lo, hi = r[f"{key}_cpu_range_s"]
        return f"{r[f'{key}_cpu_s']:.2f}" + (f" ({lo:.2f}-{hi:.2f})" if args.repeat > 1 else "")

    lines = [f"load average {loads[0]:.1f} at the start, {loads[1]:.1f} at the end; CPU = "
             "user + system of each command"
             + (f", median of {args.repeat} runs (range)" if args.repeat > 1 else ""),
             "",
             "| chords | tolerance [pulse] | joined | bound CPU [s] | bound --sampled CPU [s] "
             "| run CPU [s] | bound [s] | settle [s] | planned / bound | sampled bound, feed "
             "ignored [s] | saturated |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['chords']:,} | {r['path_tolerance_pulse']:g} | {r['joined']} | "
              f"{cpu(r, 'bound')} | {cpu(r, 'sampled')} | {cpu(r, 'run')} | "
              f"{r['bound_s']:.4g} | {r['settle_time_s']:.4g} | {r['ratio']:.3f} | "
              f"{r['sampled_bound_s']:.4g} | {r['saturated']} |" for r in rows]
    print("\n" + "\n".join(lines))
    if args.markdown:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=Path(__file__).parent).stdout.strip()
        command = " ".join(["python benchmarks/cam_chords.py", *sys.argv[1:]])
        Path(args.markdown).write_text(
            "# CAM chord programs: `bound`, `bound --sampled` and `run` (issue 37 item 3)\n\n"
            f"Generated by `{command}` on commit {commit} (G1 chords of 0.01 mm at F6000 on "
            "the die-bonder, `planned`; each command in a fresh process).\n\n"
            "*bound*: `bound`, the time-optimal bound at the programmed feed, which `planned / "
            "bound` divides by. *sampled bound, feed ignored*: `bound --sampled`, a lower bound "
            "for any sampled motion within Umax whatever its speed (as documented): on these "
            "feed-limited programs it is the drive-limited time to move the path's extent, far "
            "below any run at the feed, which it bounds (a test checks that no run settles "
            "below it).\n\n"
            + "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
