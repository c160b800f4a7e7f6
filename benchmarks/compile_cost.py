"""The command a new user runs first, on an empty numba cache (cold) and a filled one.

``nurbsmotion run die-bonder-pi --feed 1m/s --interpolator INTERPOLATOR --no-figures`` in
a fresh process with ``NUMBA_CACHE_DIR`` pointing at an empty folder (cold: numba
compiles and writes the cache), then again in a fresh process on the same folder (warm:
numba loads the machine code); wall time and CPU time (user + system) of the whole
process, for each interpolator. On a machine shared with other work the CPU time is the
figure to compare: the wall time then includes waiting for a core.

    python benchmarks/compile_cost.py
"""

from __future__ import annotations

import statistics

import _common  # noqa: F401  (puts src/ on the path)
from _common import cold_and_warm, machine_description, run_python_timed, section

CHILD = r"""
import sys, tempfile
from nurbsmotion.cli import main
with tempfile.TemporaryDirectory() as out:
    sys.exit(main(["run", "die-bonder-pi", "--feed", "1m/s", "--interpolator", "{name}",
                   "--no-figures", "--out", out + "/run"]))
"""

INTERPOLATORS = ("paper", "taylor2", "planned")


def main(repeats: int = 3) -> str:
    rows = []
    machine = machine_description()
    for name in INTERPOLATORS:
        cold, warm = cold_and_warm(
            lambda cache: run_python_timed(CHILD.replace("{name}", name),
                                           NUMBA_CACHE_DIR=cache)[:2], repeats)
        rows.append([f"`run ... --interpolator {name}`",
                     f"{statistics.median(c[0] for c in cold):.2f}",
                     f"{statistics.median(c[1] for c in cold):.2f}",
                     f"{statistics.median(w[0] for w in warm):.2f}",
                     f"{statistics.median(w[1] for w in warm):.2f}"])
    return section("First command: empty numba cache (cold) against a filled one (warm)",
                   ["command, fresh process", "cold wall [s]", "cold CPU [s]",
                    "warm wall [s]", "warm CPU [s]"], rows,
                   f"Medians of {repeats} process pairs. {machine}.")


if __name__ == "__main__":
    main()
