"""Peak memory of a 10-minute move: 600,000 samples at Ts = 1 ms, with the trace.

The butterfly on the die-bonder at the feed that takes 600 s (its length / 600 s, about
0.64 mm/s), ``paper`` interpolator, in a fresh process; peak resident set size from
``/proc/self/status`` (VmHWM; ``resource.getrusage`` elsewhere) after the imports, after
``simulate()`` and after the metrics. VmHWM, not ``ru_maxrss``: on Linux ``ru_maxrss``
survives ``exec`` and so reports the parent's peak when that was larger.

    python benchmarks/memory.py
"""

from __future__ import annotations

import json

import _common  # noqa: F401  (puts src/ on the path)
from _common import PEAK_MB, run_python, section

CHILD = PEAK_MB + r"""
import json, time
import nurbsmotion as nm
from nurbsmotion.interpolators import make_interpolator
from nurbsmotion.loop import simulate, to_pulses
from nurbsmotion.machine import die_bonder

m = die_bonder()
path = to_pulses(nm.make_butterfly(), m)
feed = path.length / 600.0
simulate(make_interpolator("paper", path, m, 1e5), m)   # warm-up: load the kernels
before = peak_mb()
t0 = time.perf_counter()
trace = simulate(make_interpolator("paper", path, m, feed), m, max_samples=2_000_000)
t1 = time.perf_counter()
after_loop = peak_mb()
met = trace.metrics()
after_metrics = peak_mb()
trace_mb = sum(a.nbytes for a in (trace.t, trace.u, trace.position_command, trace.position,
               trace.speed_command, trace.speed, trace.drive, trace.drive_applied,
               trace.feed, trace.speed_bounds)) / 2**20
print(json.dumps({"samples": len(trace.t), "feed": feed, "cycle": trace.cycle_time,
                  "loop_s": t1 - t0, "before": before, "loop": after_loop,
                  "metrics": after_metrics, "trace_mb": trace_mb}))
"""


def main() -> str:
    r = json.loads(run_python(CHILD)[1])
    rows = [["after imports and a warm-up run", f"{r['before']:.0f}"],
            ["after `simulate()` (trace held)", f"**{r['loop']:.0f}**"],
            ["after `trace.metrics()` (contour error of every sample)", f"{r['metrics']:.0f}"]]
    title = f"Memory: a {r['cycle']:.0f} s move, {r['samples']:,} samples with the trace"
    return section(title,
                   ["peak RSS of the process", "[MB]"], rows,
                   intro=f"Butterfly at {r['feed']:.0f} pulse/s, `paper`; the trace's arrays "
                   f"take {r['trace_mb']:.0f} MB; the loop ran in {r['loop_s']:.2f} s.")


if __name__ == "__main__":
    main()
