"""Closed-loop throughput: the compiled loop against the reference loop, same run.

The ``paper`` (Yeh & Sun) and ``planned`` (look-ahead with safety layer) interpolators with
the die-bonder's 2-axis PD+ servo and the trace recorded, on the Pi and the butterfly;
samples per second of ``simulate()`` as a user calls it (plant set-up and trace assembly
included), medians over repeats after a warm-up run that also pays any compilation. The
``planned`` rows are planned once, outside the timing.

A second table times the ``planned`` interpolator's offline planning, whose closed-loop
check simulates the stepper on five plants per round: with the compiled loop (as a user
gets it) and with the reference loop (``simulate(..., compiled=False)`` patched in for the
check only), same run.

    python benchmarks/loop_throughput.py
"""

from __future__ import annotations

import _common  # noqa: F401  (puts src/ on the path)
from _common import median_time, section

CASES = [("paper", "die-bonder-pi", 2e5), ("paper", "die-bonder-pi", 1e6),
         ("paper", "butterfly", 5e4), ("paper", "butterfly", 2e5),
         ("planned", "die-bonder-pi", 2e5), ("planned", "die-bonder-pi", 5e5),
         ("planned", "die-bonder-pi", 1e6), ("planned", "die-bonder-pi", 2e6),
         ("planned", "butterfly", 5e4), ("planned", "butterfly", 1e5),
         ("planned", "butterfly", 2e5)]

PLANNING_CASES = [("die-bonder-pi", 2e5), ("die-bonder-pi", 5e5), ("die-bonder-pi", 1e6),
                  ("die-bonder-pi", 2e6), ("butterfly", 5e4), ("butterfly", 1e5),
                  ("butterfly", 2e5)]

FIELDS = ("position_command", "position", "drive")


def _same(a, b) -> bool:
    import numpy as np

    return len(a.t) == len(b.t) and all(
        np.allclose(getattr(a, f), getattr(b, f), rtol=1e-12, atol=0) for f in FIELDS)


def throughput(repeats: int, reference_repeats: int) -> str:
    import nurbsmotion as nm
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate, to_pulses
    from nurbsmotion.machine import die_bonder

    m = die_bonder()
    rows = []
    for method, name, feed in CASES:
        path = to_pulses(nm.builtin_path(name), m)
        interp = make_interpolator(method, path, m, feed)
        n = len(simulate(interp, m).t)
        fast, _ = median_time(lambda: simulate(interp, m), repeats)
        slow, _ = median_time(lambda: simulate(interp, m, compiled=False), reference_repeats,
                              warmup=0)
        same = _same(simulate(interp, m), simulate(interp, m, compiled=False))
        rows.append([method, name, f"{feed / 1e6:g}", n, f"{n / fast:,.0f}",
                     f"{n / slow:,.0f}", f"{slow / fast:.0f}x",
                     f"{n * m.sample_period / fast:,.0f}x", "yes" if same else "NO"])
    return section(
        "Closed loop, samples per second",
        ["interpolator", "path", "feed [m/s]", "samples", "compiled [samples/s]",
         "reference [samples/s]", "compiled / reference", "faster than real time",
         "same trace (1e-12)"], rows,
        f"Medians of {repeats} (compiled) and {reference_repeats} (reference) runs "
        "of `simulate()`, after one warm-up run. A `planned` sample where the safety "
        "layer changes the step costs some 20 drive predictions (the candidates nearest "
        "the plan until an admissible one, then 12 bisections, as the reference does "
        "them) and an arc length (10 Gauss nodes): the Pi at 1 and 2 m/s changes 14 and "
        "33 of its 178 and 145 samples, most of the run's time at 2 m/s.")


def planning_time(repeats: int) -> str:
    import functools

    import nurbsmotion as nm
    import nurbsmotion.loop as loop
    from nurbsmotion.interpolators import PlannedInterpolator
    from nurbsmotion.loop import to_pulses
    from nurbsmotion.machine import die_bonder

    m = die_bonder()
    compiled_simulate = loop.simulate
    reference_simulate = functools.partial(compiled_simulate, compiled=False)
    rows = []
    for name, feed in PLANNING_CASES:
        path = to_pulses(nm.builtin_path(name), m)
        plans = {}
        times = {}
        for label, sim in (("compiled", compiled_simulate), ("reference", reference_simulate)):
            loop.simulate = sim  # the planner's check imports it at call time
            try:
                times[label], _ = median_time(
                    lambda: plans.__setitem__(label, PlannedInterpolator(path, m, feed)),
                    repeats)
            finally:
                loop.simulate = compiled_simulate
        same = all(
            (plans["compiled"].plan_s == plans["reference"].plan_s).all() for _ in [0]
        ) and len(plans["compiled"].plan_s) == len(plans["reference"].plan_s)
        rows.append([name, f"{feed / 1e6:g}", len(plans["compiled"].plan_u) - 1,
                     f"{times['compiled']:.3f}", f"{times['reference']:.3f}",
                     f"{times['reference'] / times['compiled']:.1f}x",
                     "yes" if same else "NO"])
    return section(
        "Planning time of the `planned` interpolator",
        ["path", "feed [m/s]", "planned samples", "compiled check [s]",
         "reference check [s]", "reference / compiled", "same schedule"], rows,
        f"Medians of {repeats} constructions of `PlannedInterpolator(path, machine, feed)` "
        "(speed profile, schedule, and the closed-loop check of up to 12 rounds on 5 "
        "plants), after one warm-up construction.")


def main(repeats: int = 15, reference_repeats: int = 3) -> str:
    return (throughput(repeats, reference_repeats) + "\n"
            + planning_time(max(1, reference_repeats)))


if __name__ == "__main__":
    main()
