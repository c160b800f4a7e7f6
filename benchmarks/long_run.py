"""A 10-minute move end to end: ``nurbsmotion run ... --no-figures`` on 600,000 samples.

The butterfly on the die-bonder at the feed that takes 600 s (its length / 600 s, about
0.64 mm/s), ``paper`` interpolator (its planning is one sample ahead, so the figure is the
loop, the metrics and the trace writer), with ``trace.csv``, ``trace.parquet`` and no
trace, then the same three with the default ``planned``. Without figures the run streams
(the rows go block by block to the metrics and the trace file, none is kept). In a fresh
process each: wall time from the interpreter's start to its exit, the CPU time it used (on a loaded machine
the wall time grows, the CPU time hardly), and the peak resident set size (VmHWM). Then
the same run's stages one by one in one process: the imports, the loop, the metrics, the
time-optimal bound, and writing the trace as CSV and as Parquet; ``planned``'s plan, loop
and metrics, then its plan and its streamed loop with the metrics and ``trace.csv``
written block by block (what the command does); and the load average.

Last, Ctrl-C: the same ``run`` (the default ``planned``, ``trace.csv``) as a command in a
subprocess, sent SIGINT at several moments of its work; each time the latency from the
signal to the process's exit, its exit code and stderr, and what it left in the output
folder (nothing may appear under a name a finished run writes).

    python benchmarks/long_run.py
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _common  # noqa: F401  (puts src/ on the path)
from _common import PEAK_MB, python_env, run_python, section

END_TO_END = PEAK_MB + r"""
import json, os, sys
from nurbsmotion.cli import main
import nurbsmotion as nm
feed = f"{nm.make_butterfly().length / 600.0!r}mm/s"
trace = ["--no-trace"] if sys.argv[2] == "none" else ["--trace-format", sys.argv[2]]
code = main(["run", "butterfly", "--feed", feed, "--interpolator", sys.argv[3],
             "--no-figures", "--quiet", "--out", sys.argv[1]] + trace)
cpu = os.times()
print(json.dumps({"code": code, "peak": peak_mb(), "cpu": cpu.user + cpu.system}))
"""

STAGES = PEAK_MB + r"""
import json, sys, time
t_import = time.perf_counter()
from pathlib import Path
import nurbsmotion as nm
from nurbsmotion.loop import run
from nurbsmotion.machine import die_bonder
from nurbsmotion.planning import time_optimal_bound
from nurbsmotion.report import write_trace
from nurbsmotion.units import OutputUnits
import nurbsmotion.cli
t_import = time.perf_counter() - t_import
m = die_bonder()
curve = nm.make_butterfly()
run(curve, m, 100.0, "paper")  # warm-up: load the kernels
out = Path(sys.argv[1])
t = {}
t0 = time.perf_counter(); tr = run(curve, m, curve.length / 600.0, "paper")
t["loop"] = time.perf_counter() - t0
t0 = time.perf_counter(); tr.metrics(); t["metrics"] = time.perf_counter() - t0
t0 = time.perf_counter(); time_optimal_bound(tr.curve, m, tr.feed.max())
t["bound"] = time.perf_counter() - t0
for fmt in ("csv", "parquet"):
    t0 = time.perf_counter()
    f = write_trace(tr, out / f"trace.{fmt}", fmt=fmt, units=OutputUnits.of(m, unit="mm"))
    t[fmt] = time.perf_counter() - t0
    t[fmt + "_mb"] = f.stat().st_size / 1e6
t["samples"] = len(tr.t)
t["import"] = t_import
del tr
from nurbsmotion.interpolators import make_interpolator
from nurbsmotion.loop import simulate, to_pulses
path = to_pulses(curve, m)
t0 = time.perf_counter(); ip = make_interpolator("planned", path, m, path.length / 600.0)
t["plan"] = time.perf_counter() - t0
t0 = time.perf_counter(); tr = simulate(ip, m); t["planned_loop"] = time.perf_counter() - t0
del ip
t0 = time.perf_counter(); tr.metrics(); t["planned_metrics"] = time.perf_counter() - t0
del tr
from nurbsmotion.loop import simulate_streamed
from nurbsmotion.metrics import RunningMetrics
from nurbsmotion.report import TraceWriter
t0 = time.perf_counter(); ip = make_interpolator("planned", path, m, path.length / 600.0)
running = RunningMetrics(path, m, 1.0)
with TraceWriter(out / "streamed.csv", m, units=OutputUnits.of(m, unit="mm"),
                 threads=1) as writer:
    def sink(first, rows, finished, last):
        running.add(first, rows, finished, last)
        writer.add(first, rows, finished, last)
    outcome = simulate_streamed(ip, m, sink)
running.result(outcome.finished_index, outcome.success, outcome.message)
t["planned_streamed"] = time.perf_counter() - t0
print(json.dumps(t))
"""


CASES = (("paper", "csv"), ("paper", "parquet"), ("paper", "none"), ("planned", "csv"),
         ("planned", "parquet"), ("planned", "none"))
"""(interpolator, trace format or "none" for ``--no-trace``) of the end-to-end runs."""


def main(repeats: int = 1) -> str:
    rows = []
    for interpolator, fmt in CASES:
        walls, cpus, peaks = [], [], []
        for _ in range(repeats):
            with tempfile.TemporaryDirectory() as out:
                wall, text = run_python(END_TO_END.replace("sys.argv[1]", repr(out))
                                        .replace("sys.argv[2]", repr(fmt))
                                        .replace("sys.argv[3]", repr(interpolator)))
            r = json.loads(text.splitlines()[-1])
            assert r["code"] == 0
            walls.append(wall)
            cpus.append(r["cpu"])
            peaks.append(r["peak"])
        trace = "--no-trace" if fmt == "none" else f"--trace-format {fmt}"
        rows.append([f"`run butterfly --feed <0.638 mm/s> --interpolator {interpolator} "
                     f"--no-figures {trace}`", f"**{min(walls):.1f}**", f"{min(cpus):.1f}",
                     f"**{max(peaks):.0f}**"])
    with tempfile.TemporaryDirectory() as out:
        _, text = run_python(STAGES.replace("sys.argv[1]", repr(out)))
    s = json.loads(text.splitlines()[-1])
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    note = (f"Stages of the same run in one warm process ({s['samples']:,} samples): imports "
            f"{s['import']:.2f} s, loop {s['loop']:.2f} s, metrics {s['metrics']:.2f} s, "
            f"time-optimal bound {s['bound']:.2f} s, trace.csv {s['csv']:.2f} s "
            f"({s['csv_mb']:.0f} MB), trace.parquet {s['parquet']:.2f} s "
            f"({s['parquet_mb']:.0f} MB); `planned`: plan {s['plan']:.2f} s, loop "
            f"{s['planned_loop']:.2f} s, metrics {s['planned_metrics']:.2f} s; plan, loop, "
            f"metrics and trace.csv streamed together {s['planned_streamed']:.2f} s. Wall time "
            f"includes starting Python and importing "
            f"(kernels from the disk cache). Load average at the end: {load:.1f} on "
            f"{os.cpu_count()} cores.")
    return section("A 10-minute move end to end", ["command", "wall time [s]", "CPU time [s]",
                                                   "peak RSS [MB]"], rows, note=note)


INTERRUPT_DELAYS = (0.1, 0.3, 1.0, 1.5, 2.0, 2.5, 3.0)
"""Seconds after the command's start at which SIGINT is sent (imports, planning, the
loop with the metrics and the trace file: where each falls depends on the machine)."""


def interrupt_once(delay: float) -> dict:
    """Start ``nurbsmotion run`` on the 10-minute move, send SIGINT after ``delay`` s;
    the latency [s] from the signal to the exit, the exit code, stderr's lines and the
    entries left in the output folder."""
    import nurbsmotion as nm

    feed = f"{nm.make_butterfly().length / 600.0!r}mm/s"
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        proc = subprocess.Popen(
            [sys.executable, "-m", "nurbsmotion", "run", "butterfly", "--feed", feed,
             "--no-figures", "--out", str(out)],
            env=python_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        sent = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate()
        latency = time.perf_counter() - sent
        left = sorted(p.name for p in out.iterdir()) if out.exists() else []
    lines = [line for line in err.splitlines() if line.strip()]
    return {"delay": delay, "latency": latency, "code": proc.returncode, "stderr": lines,
            "left": left}


def interrupts() -> str:
    """:func:`interrupt_once` at each of :data:`INTERRUPT_DELAYS`, as a Markdown table."""
    rows = []
    for delay in INTERRUPT_DELAYS:
        r = interrupt_once(delay)
        rows.append([f"{delay:.1f}", f"**{r['latency']:.2f}**", r["code"],
                     "<br>".join(r["stderr"]) or "(none)",
                     ", ".join(r["left"]) or "(nothing)"])
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return section("Ctrl-C during a 10-minute move",
                   ["SIGINT after [s]", "to exit [s]", "exit code", "stderr",
                    "left in the output folder"], rows,
                   note=f"`nurbsmotion run butterfly --feed <0.638 mm/s> --no-figures` "
                        f"(planned, trace.csv) in a subprocess. Load average at the end: "
                        f"{load:.1f} on {os.cpu_count()} cores.")


if __name__ == "__main__":
    main()
    interrupts()
