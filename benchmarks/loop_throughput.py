"""Closed-loop throughput of the one compiled loop, and the planning time of ``planned``.

Constant-feed Taylor, the paper's interpolator (Yeh & Sun) and ``planned`` with the
die-bonder's 2-axis PD+ servo (LinuxCNC ``pid`` law), every sample's status and the trace
recorded, on the Pi and the butterfly: samples per second of ``simulate()`` as a user calls
it (set-up, the run until the motion has settled, and trace assembly included), from the
least process CPU time over repeats after a warm-up run that also pays any compilation
(CPU time, best of N: the machine is shared, and wall times or medians measure the other
processes too). The ``planned`` rows are planned once, outside the timing; a second table
times that planning. Writes the tables to stdout and to ``benchmarks/loop_throughput.md``.

    python benchmarks/loop_throughput.py
"""

from __future__ import annotations

import time
from pathlib import Path

import _common  # noqa: F401  (puts src/ on the path)
from _common import median_time, section


def best_cpu_time(fn, repeats: int) -> float:
    """The least process CPU time of ``fn()`` over ``repeats`` calls after one warm-up
    call [s]."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best

CASES = [("taylor2", "die-bonder-pi", 2e5), ("taylor2", "butterfly", 5e4),
         ("paper", "die-bonder-pi", 2e5), ("paper", "die-bonder-pi", 1e6),
         ("paper", "butterfly", 5e4), ("paper", "butterfly", 2e5),
         ("planned", "die-bonder-pi", 2e5), ("planned", "die-bonder-pi", 1e6),
         ("planned", "die-bonder-pi", 2e6), ("planned", "butterfly", 5e4),
         ("planned", "butterfly", 2e5)]

PLANNING_CASES = [("die-bonder-pi", 2e5), ("die-bonder-pi", 1e6), ("die-bonder-pi", 2e6),
                  ("butterfly", 5e4), ("butterfly", 2e5)]


def throughput(repeats: int) -> str:
    import numpy as np

    import nurbsmotion as nm
    from nurbsmotion.interpolators import Status, make_interpolator
    from nurbsmotion.loop import simulate, to_pulses
    from nurbsmotion.machine import die_bonder

    m = die_bonder()
    rows = []
    for method, name, feed in CASES:
        path = to_pulses(nm.builtin_path(name), m)
        interp = make_interpolator(method, path, m, feed)
        tr = simulate(interp, m)
        n = len(tr.t)
        fast = best_cpu_time(lambda: simulate(interp, m), repeats)
        limited = int(np.count_nonzero(tr.status == Status.LIMITED))
        rows.append([method, name, f"{feed / 1e6:g}", n, limited, f"{n / fast:,.0f}",
                     f"{n * m.sample_period / fast:,.0f}x"])
    return section(
        "Closed loop, samples per second",
        ["interpolator", "path", "feed [m/s]", "samples", "limited samples",
         "samples/s", "faster than real time"], rows,
        f"Least process CPU time of {repeats} runs of `simulate()` after one warm-up run; "
        "each run goes "
        "on until the motion has settled at the end (`planned`: its online governor and "
        "feedback, from the law's affine form, every sample).")


REAL_CASES = [("paper", "die-bonder-pi", 2e5), ("paper", "die-bonder-pi", 1e6),
              ("taylor2", "die-bonder-pi", 2e5), ("planned", "die-bonder-pi", 1e6),
              ("paper", "butterfly", 2e5)]
# the ideal die-bonder's rows of these cases are in throughput()'s table


def real_throughput(repeats: int) -> str:
    """The loop with every effect of the machine as it is on (issue 32): the die-bonder's
    controller on the ``die-bonder-real`` plant (counts, 16-bit DAC, 0.5 ms delay, 0.3 V
    Coulomb and 0.4 V stiction, a 100 Hz mode) plus 0.5 pulse of noise and a 0.5 V load
    step; and the same without the mode (which the die-bonder's gains destabilise)."""
    import dataclasses

    import nurbsmotion as nm
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate, to_pulses
    from nurbsmotion.machine import Disturbance, die_bonder, die_bonder_real
    from nurbsmotion.servo import ServoPlant

    m = die_bonder()
    step = (Disturbance(0.05, 0.5),)
    full = die_bonder_real(measurement_noise=0.5, seed=1)
    full = full.with_options(axes=tuple(dataclasses.replace(a, disturbance=step)
                                        for a in full.axes))
    rigid = full.with_options(axes=tuple(dataclasses.replace(a, resonance_frequency=0.0)
                                         for a in full.axes))
    rows = []
    for label, true in (("every effect", full), ("every effect but the mode", rigid)):
        for method, name, feed in REAL_CASES:
            path = to_pulses(nm.builtin_path(name), m)
            interp = make_interpolator(method, path, m, feed)
            start = path.end_points[0]
            plant = ServoPlant(true.tau, true.Kc, true.Ke, m.max_drive, m.sample_period,
                               start, true.effects())
            tr = simulate(interp, m, plant=plant)
            n = len(tr.t)
            fast = best_cpu_time(lambda: simulate(interp, m, plant=plant), repeats)
            rows.append([label, method, name, f"{feed / 1e6:g}", n, f"{n / fast:,.0f}"])
    return section(
        "Closed loop on the machine as it is, samples per second",
        ["plant", "interpolator", "path", "feed [m/s]", "samples", "samples/s"], rows,
        f"Least process CPU time of {repeats} runs of `simulate()` after one warm-up run; "
        "the controller "
        "and planner are the ideal die-bonder's, the true plant `die-bonder-real` with 0.5 "
        "pulse of noise and a 0.5 V load step at 50 ms on each axis (runs that do not "
        "settle go on to the 10 s settle limit).")


EFFECTS = [  # (label, machine-level keys, axis-level keys), each alone on die-bonder
    ("none (the ideal plant)", {}, {}),
    ("encoder counts", {"encoder": "counts"}, {}),
    ("0.5 pulse of noise", {"measurement_noise": 0.5, "seed": 1}, {}),
    ("0.5 ms delay", {"delay": 0.5e-3}, {}),
    ("16-bit DAC", {"dac_bits": 16}, {}),
    ("0.3 V Coulomb, 0.4 V stiction", {}, {"coulomb_friction": 0.3, "stiction": 0.4}),
    ("0.5 V load step at 50 ms", {}, "step"),
    ("100 Hz mode, damping 0.02", {}, {"resonance_frequency": 100.0,
                                       "resonance_damping": 0.02}),
]


def effect_cost(repeats: int) -> str:
    """The loop's time per sample with one effect of the machine as it is on at a time
    (the profile behind the table above): ``paper`` on the Pi at 1 m/s, the ideal
    die-bonder's controller, the die-bonder with that one effect as the true plant, and
    the whole of the previous table's plant."""
    import dataclasses

    import nurbsmotion as nm
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate, to_pulses
    from nurbsmotion.machine import Disturbance, die_bonder, die_bonder_real
    from nurbsmotion.servo import ServoPlant

    m = die_bonder()
    path = to_pulses(nm.builtin_path("die-bonder-pi"), m)
    interp = make_interpolator("paper", path, m, 1e6)
    start = path.end_points[0]
    step = (Disturbance(0.05, 0.5),)
    full = die_bonder_real(measurement_noise=0.5, seed=1)
    full = full.with_options(axes=tuple(dataclasses.replace(a, disturbance=step)
                                        for a in full.axes))
    cases = []
    for label, machine_keys, axis_keys in EFFECTS:
        if axis_keys == "step":
            axis_keys = {"disturbance": step}
        axes = tuple(dataclasses.replace(a, **axis_keys) for a in m.axes)
        ideal = not (machine_keys or axis_keys)
        cases.append((label, m.with_options(axes=axes, **machine_keys), ideal))
    cases.append(("every effect (the table above)", full, False))
    rows = []
    for label, true, ideal in cases:
        plant = ServoPlant(true.tau, true.Kc, true.Ke, m.max_drive, m.sample_period, start,
                           None if ideal else true.effects())
        tr = simulate(interp, m, plant=plant)
        n = len(tr.t)
        fast = best_cpu_time(lambda: simulate(interp, m, plant=plant), repeats)
        rows.append([label, n, f"{n / fast:,.0f}", f"{fast / n * 1e9:,.0f}"])
    return section(
        "Cost of each effect, one at a time",
        ["effect on the true plant", "samples", "samples/s", "ns per sample"], rows,
        f"`paper` on the die-bonder-pi at 1 m/s with the ideal die-bonder's controller; "
        f"least process CPU time of {repeats} runs of `simulate()` after one warm-up run, "
        "set-up and trace included (a run that ends within a few hundred samples is "
        "mostly set-up; one that hunts or limit-cycles goes on to the 10 s settle "
        "limit).")


def planning_time(repeats: int) -> str:
    import nurbsmotion as nm
    from nurbsmotion.interpolators import PlannedInterpolator
    from nurbsmotion.loop import to_pulses
    from nurbsmotion.machine import die_bonder

    m = die_bonder()
    rows = []
    for name, feed in PLANNING_CASES:
        path = to_pulses(nm.builtin_path(name), m)
        t, _ = median_time(lambda: PlannedInterpolator(path, m, feed), repeats)
        n = len(PlannedInterpolator(path, m, feed).plan.parameter)
        rows.append([name, f"{feed / 1e6:g}", n, f"{t:.3f}"])
    return section(
        "Planning time of the `planned` interpolator",
        ["path", "feed [m/s]", "planned samples", "planning [s]"], rows,
        f"Medians of {repeats} constructions of `PlannedInterpolator(path, machine, feed)` "
        "(speed profile, motion plan, drive sequence and its drive-limit rounds), after "
        "one warm-up construction.")


def main(repeats: int = 15) -> str:
    return (throughput(repeats) + "\n" + real_throughput(max(3, repeats // 3)) + "\n"
            + effect_cost(max(3, repeats // 3)) + "\n" + planning_time(max(1, repeats // 5)))


if __name__ == "__main__":
    text = main()
    (Path(__file__).resolve().parent / "loop_throughput.md").write_text(
        "# Loop throughput\n\n(`python benchmarks/loop_throughput.py`; "
        + _common.machine_description() + ")\n\n" + text)
