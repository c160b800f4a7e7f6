"""Run the benchmarks and write benchmarks/RESULTS.md, which nothing else writes.

    python benchmarks/run_all.py              # the quick benchmarks (minutes)
    python benchmarks/run_all.py --quick      # the same with fewer repeats
    python benchmarks/run_all.py --slow       # also the evaluations and sweeps (an hour+)
    python benchmarks/run_all.py --only loop_throughput memory

RESULTS.md holds the figures of one run of this script: its command, the machine (CPU,
cores, load, library versions), the date and the commit measured, then one section per
benchmark. A benchmark not run this time is listed under "Not regenerated in this run"
with the command that regenerates it; its old figures are not carried over (they are in
git's history of this file). Each script also runs on its own
(``python benchmarks/<name>.py``).
"""

from __future__ import annotations

import argparse
import datetime
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import _common

HERE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Benchmark:
    """One script of this folder and how run_all runs it.

    ``name`` is the script's stem; ``slow`` ones (the evaluations and sweeps: many
    minutes each on two cores) run only with ``--slow`` or ``--only``; ``env`` is the
    environment the documented command sets; ``in_process`` scripts have a ``main(...)``
    that returns their Markdown section (called with ``repeats`` chosen by ``--quick``),
    the others print and are run as a subprocess whose output is kept as it is.
    """

    name: str
    title: str
    slow: bool = False
    env: tuple[tuple[str, str], ...] = ()
    in_process: bool = False

    @property
    def command(self) -> str:
        prefix = " ".join(f"{k}={v}" for k, v in self.env)
        return (prefix + " " if prefix else "") + f"python benchmarks/{self.name}.py"


BENCHMARKS = (
    Benchmark("loop_throughput", "Closed loop and planning throughput", in_process=True),
    Benchmark("memory", "Memory of a 10-minute move", in_process=True),
    Benchmark("long_run", "A 10-minute move end to end", in_process=True),
    Benchmark("nurbs_eval", "Batch NURBS evaluation", in_process=True),
    Benchmark("compile_cost", "Compile cost (cold and warm numba cache)", in_process=True),
    Benchmark("reproduce_time", "`nurbsmotion reproduce` wall time", in_process=True),
    Benchmark("figure_time", "A run with its figures, and `reproduce`, warm", in_process=True),
    Benchmark("gcode_load", "Loading a 1,000,000-line G-code program"),
    Benchmark("bad_input", "Bad and huge inputs"),
    Benchmark("toppra_compare", "`planned` against TOPP-RA", in_process=True),
    Benchmark("planner_eval", "`planned` on the die-bonder (issue 10, items 1-6)", slow=True),
    Benchmark("campaign", "Campaign throughput (serial, local pool, Dask)", slow=True),
    Benchmark("planner_sweep", "`planned` on 1,000 random paths", slow=True),
    Benchmark("machine_sweep", "`planned` on 600 random machines", slow=True),
    Benchmark("file_sweep", "`planned` on the test corpus's files, 6 machines each",
              slow=True, env=(("FILE_SWEEP_DRAWS", "6"),)),
)
"""Every benchmark, in the order of RESULTS.md."""

_REPEATS = {  # name -> (keyword arguments of main(), full run, --quick)
    "loop_throughput": ({"repeats": 15}, {"repeats": 5}),
    "memory": ({}, {}),
    "long_run": ({"repeats": 2}, {"repeats": 1}),
    "nurbs_eval": ({"repeats": 7, "geomdl_repeats": 3}, {"repeats": 3, "geomdl_repeats": 1}),
    "compile_cost": ({"repeats": 3}, {"repeats": 1}),
    "reproduce_time": ({"repeats": 2}, {"repeats": 1}),
    "figure_time": ({"repeats": 3}, {"repeats": 1}),
    "toppra_compare": ({"repeats": 3}, {"repeats": 1}),
}


def _missing_dependency(bench: Benchmark) -> str | None:
    """Why ``bench`` cannot run here (a benchmark-only package not installed), or None."""
    if bench.name == "toppra_compare":
        try:
            import toppra  # noqa: F401
        except ImportError:
            return "`toppra` is not installed (`pip install toppra`, benchmark-only)"
    return None


def _run(bench: Benchmark, quick: bool) -> str:
    """The Markdown section of one benchmark, run now."""
    if bench.in_process:
        module = __import__(bench.name)
        return module.main(**_REPEATS[bench.name][1 if quick else 0])
    env = _common.python_env(**dict(bench.env))
    done = subprocess.run([sys.executable, str(HERE / f"{bench.name}.py")], env=env,
                          capture_output=True, text=True, cwd=_common.ROOT)
    out = done.stdout.strip()
    if done.returncode != 0:
        out += f"\n\n(exit code {done.returncode}: {done.stderr.strip()[-500:]})"
    if out.startswith("###"):  # the script prints Markdown sections itself
        return out + "\n"
    return f"### {bench.title}\n\n```text\n{out}\n```\n"


def _commit() -> str:
    """The commit measured: short hash and subject, and whether the tree had changes."""
    def git(*args):
        return subprocess.run(["git", *args], cwd=_common.ROOT, capture_output=True,
                              text=True).stdout.strip()

    head = git("log", "-1", "--format=%h (%s)")
    if not head:
        return "unknown (not a git checkout)"
    if len(head) > 100:
        head = head[:97] + "...)"
    dirty = git("status", "--porcelain", "--untracked-files=no", "--", "src", "benchmarks")
    return head + (", with uncommitted changes in src/ or benchmarks/" if dirty else "")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    parser.add_argument("--slow", action="store_true",
                        help="also the evaluations and sweeps (each many minutes)")
    parser.add_argument("--only", nargs="+", metavar="NAME",
                        choices=[b.name for b in BENCHMARKS], help="just these benchmarks")
    parser.add_argument("--out", default=str(HERE / "RESULTS.md"), help="Markdown file")
    args = parser.parse_args(argv)
    machine = _common.machine_description()
    started = datetime.datetime.now(datetime.timezone.utc)
    commit = _commit()
    t0 = time.perf_counter()
    sections, skipped = [], []
    for bench in BENCHMARKS:
        chosen = bench.name in args.only if args.only else (args.slow or not bench.slow)
        why = _missing_dependency(bench) if chosen else (
            "not chosen (`--only`)" if args.only else "slow: run with `--slow`")
        if why:
            skipped.append(f"- {bench.title}: {why}; `{bench.command}`")
            continue
        print(f"run_all: {bench.name}", file=sys.stderr, flush=True)
        t = time.perf_counter()
        sections.append(_run(bench, args.quick).rstrip() + "\n\n"
                        f"(`{bench.command}`, {time.perf_counter() - t:.0f} s)\n")
    took = time.perf_counter() - t0
    command = "python benchmarks/run_all.py" + "".join(
        f" {a}" for a in (argv if argv is not None else sys.argv[1:]) if a != "--out")
    head = [
        "# Benchmark results",
        "",
        "Generated by `benchmarks/run_all.py`; do not edit by hand (earlier results are in "
        "this file's git history).",
        "",
        f"- command: `{command}`",
        f"- date: {started:%Y-%m-%d %H:%M} UTC, {took:.0f} s in all",
        f"- commit: {commit}",
        f"- machine: {machine}; load average "
        + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + " at the end",
        "",
        "One process per measurement (numba kernels single-threaded). A shared machine "
        "depresses wall times: the load average above says by how much; CPU times, where "
        "given, hardly depend on it.",
    ]
    if skipped:
        head += ["", "## Not regenerated in this run", "", *skipped]
    text = "\n".join(head) + "\n\n## Results\n\n" + "\n".join(sections)
    Path(args.out).write_text(text)
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
