"""First-call compile cost of the numba kernels, against loading them from the disk cache.

Each stage runs in a fresh process with ``NUMBA_CACHE_DIR`` pointing at an empty folder
(cold: numba compiles and writes the cache), then again in a fresh process on the same
folder (warm: numba loads the machine code).

    python benchmarks/compile_cost.py
"""

from __future__ import annotations

import json
import statistics

import _common  # noqa: F401  (puts src/ on the path)
from _common import cold_and_warm, run_python, section

CHILD = r"""
import json, time
t0 = time.perf_counter()
import nurbsmotion as nm
from nurbsmotion.loop import run
from nurbsmotion.machine import die_bonder
t1 = time.perf_counter()
pi = nm.make_die_bonder_pi()           # the first curve evaluates: batch kernels
t2 = time.perf_counter()
run(pi, die_bonder(), 1e6, "paper")    # the first compiled loop
t3 = time.perf_counter()
run(pi, die_bonder(), 1e6, "paper")
t4 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "curve": t2 - t1, "loop": t3 - t2, "again": t4 - t3}))
"""

STAGES = [("import", "`import nurbsmotion`"),
          ("curve", "first curve (evaluation kernels)"),
          ("loop", "first `run(..., 'paper')` (loop kernel)"),
          ("again", "second `run(..., 'paper')`")]


def main(repeats: int = 3) -> str:
    cold, warm = cold_and_warm(
        lambda cache: json.loads(run_python(CHILD, NUMBA_CACHE_DIR=cache)[1]), repeats)
    rows = []
    for key, label in STAGES:
        c = statistics.median(r[key] for r in cold)
        w = statistics.median(r[key] for r in warm)
        rows.append([label, f"{c:.3f}", f"{w:.3f}"])
    total_c = statistics.median(sum(r[k] for k, _ in STAGES) for r in cold)
    total_w = statistics.median(sum(r[k] for k, _ in STAGES) for r in warm)
    rows.append(["**total**", f"**{total_c:.2f}**", f"**{total_w:.2f}**"])
    return section("Compile cost: empty numba cache (cold) against a filled one (warm)",
                   ["stage, fresh process", "cold [s]", "warm [s]"], rows,
                   f"Medians of {repeats} process pairs.")


if __name__ == "__main__":
    main()
