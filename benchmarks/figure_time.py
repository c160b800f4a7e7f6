"""Wall and CPU time of the figures, warm (issue 35's targets: a short run with every figure
<= 2 s, ``nurbsmotion reproduce`` <= 10 s).

Each command runs in a fresh process (as ``python -m nurbsmotion ...``, its exit included)
on a numba cache that an earlier run of the same command has filled (warm), with and
without its figures, so that the figures' share is the difference:

1. ``nurbsmotion run die-bonder-pi --feed 1m/s --out DIR`` (five figures) and the same with
   ``--no-figures``;
2. ``nurbsmotion reproduce --out DIR`` (30 figures) and the same with ``--no-figures``.

The wall time depends on what else the machine runs; the CPU time (user + system of the
child) much less, so both are given, with the load average at the start.

    python benchmarks/figure_time.py [repeats]
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
from pathlib import Path

import _common  # noqa: F401  (puts src/ on the path)
from _common import machine_description, run_python_timed, section

COMMANDS = {
    "run die-bonder-pi --feed 1m/s": ["run", "die-bonder-pi", "--feed", "1m/s"],
    "reproduce": ["reproduce"],
}
"""Label -> CLI arguments (the output folder is added)."""

TARGETS = {"run die-bonder-pi --feed 1m/s": 2.0, "reproduce": 10.0}
"""Issue 35's warm wall-time targets with every figure [s]."""


def measure(argv: list[str], cache: str) -> tuple[float, float]:
    """(wall [s], CPU [s]) of one CLI call in a fresh process writing a fresh folder."""
    with tempfile.TemporaryDirectory() as out:
        full = argv + ["--out", str(Path(out) / "results")]
        # as `python -m nurbsmotion` runs it (the command's exit included)
        code = (f"import runpy, sys; sys.argv = ['nurbsmotion'] + {full!r}; "
                f"runpy.run_module('nurbsmotion', run_name='__main__')")
        wall, cpu, _ = run_python_timed(code, NUMBA_CACHE_DIR=cache, MPLBACKEND="Agg")
    return wall, cpu


def main(repeats: int = 3) -> str:
    machine = machine_description()  # with the load average at the start
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        for label, argv in COMMANDS.items():
            measure(argv + ["--no-figures"], cache)  # fills the cache: later runs are warm
            result = {}
            for figures in (True, False):
                args = argv + ([] if figures else ["--no-figures"])
                runs = [measure(args, cache) for _ in range(repeats)]
                result[figures] = (statistics.median(w for w, _ in runs),
                                   statistics.median(c for _, c in runs),
                                   min(w for w, _ in runs))
            (wall, cpu, best), (wall_nf, cpu_nf, best_nf) = result[True], result[False]
            rows.append([f"`nurbsmotion {label}`", f"{wall:.2f}", f"{best:.2f}", f"{cpu:.2f}",
                         f"{wall_nf:.2f}", f"{best_nf:.2f}", f"{cpu_nf:.2f}",
                         f"{wall - wall_nf:.2f}", f"{cpu - cpu_nf:.2f}",
                         f"{TARGETS[label]:g}"])
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return section(
        "Figures: warm wall and CPU time of a fresh process",
        ["command", "wall [s]", "best wall [s]", "CPU [s]", "wall, --no-figures [s]",
         "best wall, --no-figures [s]", "CPU, --no-figures [s]", "figures, wall [s]",
         "figures, CPU [s]", "target, wall [s]"], rows,
        f"Medians (and the best wall time) of {repeats} runs each on a warm numba cache; "
        f"CPU = user + system time of the child and of the processes it forks and waits "
        f"for (run's figure worker and its second drawing process, reproduce's figure "
        f"workers). Load average at the end: {load}. {machine}.")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
