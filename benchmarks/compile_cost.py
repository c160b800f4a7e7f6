"""The command a new user runs first, on an empty numba cache (cold) and a filled one.

``nurbsmotion run die-bonder-pi --feed 1m/s --interpolator INTERPOLATOR --no-figures`` in
a fresh process with ``NUMBA_CACHE_DIR`` pointing at an empty folder (cold: numba
compiles and writes the cache), then again in a fresh process on the same folder (warm:
numba loads the machine code); wall time of the whole process, for each interpolator.

    python benchmarks/compile_cost.py
"""

from __future__ import annotations

import statistics

import _common  # noqa: F401  (puts src/ on the path)
from _common import cold_and_warm, run_python, section

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
    for name in INTERPOLATORS:
        cold, warm = cold_and_warm(
            lambda cache: run_python(CHILD.replace("{name}", name), NUMBA_CACHE_DIR=cache)[0],
            repeats)
        rows.append([f"`run ... --interpolator {name}`", f"{statistics.median(cold):.2f}",
                     f"{statistics.median(warm):.2f}"])
    return section("First command: empty numba cache (cold) against a filled one (warm)",
                   ["command, fresh process", "cold [s]", "warm [s]"], rows,
                   f"Wall time of the whole process, medians of {repeats} process pairs.")


if __name__ == "__main__":
    main()
