"""The command a new user runs first, on an empty numba cache (cold) and a filled one.

``nurbsmotion run die-bonder-pi --feed 1m/s --interpolator INTERPOLATOR --no-figures`` in
a fresh process with ``NUMBA_CACHE_DIR`` pointing at an empty folder (cold: numba
compiles and writes the cache), then again in a fresh process on the same folder (warm:
numba loads the machine code); wall time and CPU time (user + system) of the whole
command, for each interpolator. On a cold start the command compiles its closed loop in a
second process on the other core (:mod:`nurbsmotion._runtime.precompile`): the CPU time counts
both processes, and the command's own process is shown apart (on an idle 2-core machine
its CPU time is about the wall time). On a machine shared with other work the CPU times
are the figures to compare: the wall time then includes waiting for a core; the CPU time
the rest of the machine used during the cold runs (Linux) says how much that was.

    python benchmarks/compile_cost.py
"""

from __future__ import annotations

import os
import statistics

import _common  # noqa: F401  (puts src/ on the path)
from _common import cold_and_warm, machine_description, run_python_timed, section

CHILD = r"""
import resource, sys, tempfile
from nurbsmotion.cli import main
with tempfile.TemporaryDirectory() as out:
    code = main(["run", "die-bonder-pi", "--feed", "1m/s", "--interpolator", "{name}",
                 "--no-figures", "--out", out + "/run"])
own = resource.getrusage(resource.RUSAGE_SELF)
print("own-cpu", own.ru_utime + own.ru_stime)
sys.exit(code)
"""


def _busy() -> float:
    """CPU time the whole machine has spent busy since boot [s] (Linux; else 0)."""
    try:
        with open("/proc/stat") as f:
            ticks = [int(x) for x in f.readline().split()[1:]]
    except OSError:
        return 0.0
    return (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")  # not idle, iowait


def _timed(name: str, cache: str) -> tuple[float, float, float, float]:
    """(wall [s], CPU of the command with its second process [s], CPU of its own process
    [s], CPU the rest of the machine used meanwhile [s])."""
    busy = _busy()
    wall, cpu, out = run_python_timed(CHILD.replace("{name}", name), NUMBA_CACHE_DIR=cache)
    own = float(out.split("own-cpu")[-1])
    return wall, cpu, own, max(0.0, _busy() - busy - cpu)


INTERPOLATORS = ("paper", "taylor2", "planned")


def main(repeats: int = 3) -> str:
    rows = []
    machine = machine_description()
    for name in INTERPOLATORS:
        cold, warm = cold_and_warm(lambda cache: _timed(name, cache), repeats)
        rows.append([f"`run ... --interpolator {name}`",
                     f"{statistics.median(c[0] for c in cold):.2f}",
                     f"{statistics.median(c[1] for c in cold):.2f}",
                     f"{statistics.median(c[2] for c in cold):.2f}",
                     f"{statistics.median(c[3] for c in cold):.2f}",
                     f"{statistics.median(w[0] for w in warm):.2f}",
                     f"{statistics.median(w[1] for w in warm):.2f}"])
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return section("First command: empty numba cache (cold) against a filled one (warm)",
                   ["command, fresh process", "cold wall [s]", "cold CPU [s]",
                    "cold CPU, own process [s]", "others' CPU meanwhile [s]",
                    "warm wall [s]", "warm CPU [s]"], rows,
                   f"Medians of {repeats} process pairs. {machine}; load average {load} "
                   "at the end.")


if __name__ == "__main__":
    main()
