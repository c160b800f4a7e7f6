"""Closed-loop throughput: the compiled loop against the reference loop, same run.

The ``paper`` interpolator (Yeh & Sun) with the die-bonder's 2-axis PD+ servo and the trace
recorded, on the Pi and the butterfly; samples per second of ``simulate()`` as a user calls
it (plant set-up and trace assembly included), medians over repeats after a warm-up run
that also pays any compilation.

    python benchmarks/loop_throughput.py
"""

from __future__ import annotations

import _common  # noqa: F401  (puts src/ on the path)
from _common import median_time, section

CASES = [("die-bonder-pi", 2e5), ("die-bonder-pi", 1e6), ("butterfly", 5e4),
         ("butterfly", 2e5)]


def main(repeats: int = 15, reference_repeats: int = 3) -> str:
    import numpy as np

    import nurbsmotion as nm
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate, to_pulses
    from nurbsmotion.machine import die_bonder

    m = die_bonder()
    rows = []
    for name, feed in CASES:
        path = to_pulses(nm.builtin_path(name), m)
        interp = make_interpolator("paper", path, m, feed)
        n = len(simulate(interp, m).t)
        fast, _ = median_time(lambda: simulate(interp, m), repeats)
        slow, _ = median_time(lambda: simulate(interp, m, compiled=False), reference_repeats,
                              warmup=0)
        a, b = simulate(interp, m), simulate(interp, m, compiled=False)
        same = all(np.allclose(getattr(a, f), getattr(b, f), rtol=1e-12, atol=0)
                   for f in ("position_command", "position", "drive"))
        rows.append([name, f"{feed / 1e6:g}", n, f"{n / fast:,.0f}", f"{n / slow:,.0f}",
                     f"{slow / fast:.0f}x", f"{n * m.sample_period / fast:,.0f}x",
                     "yes" if same else "NO"])
    return section(
        "Closed loop, `paper` interpolator, samples per second",
        ["path", "feed [m/s]", "samples", "compiled [samples/s]", "reference [samples/s]",
         "compiled / reference", "faster than real time", "same trace (1e-12)"], rows,
        f"Medians of {repeats} (compiled) and {reference_repeats} (reference) runs "
        "of `simulate()`, after one warm-up run.")


if __name__ == "__main__":
    main()
