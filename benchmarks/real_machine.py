"""The machine as it is (issue 32): each effect alone, and the ``die-bonder-real`` preset,
on the true plant under the ideal die-bonder's controller and planner.

For ``taylor2``, ``paper`` and ``planned``, on the Pi at 0.2, 0.5, 1 and 2 m/s and the
butterfly at 0.1 and 0.2 m/s: the true plant is the die-bonder with one effect (1-um
counts; 0.5 ms delay; 0.3 V Coulomb friction and 0.4 V stiction; a 0.5 V load step on
each axis half way through the ideal run's move; a 100 Hz mode of damping 0.02 with the
encoder on the motor; a 16-bit DAC) or all of them (``die-bonder-real``), while the
controller and the planner know only the ideal machine. Every run goes on 0.3 s after it
settles (within 1 pulse), or to the 10 s limit. Writes a markdown table to stdout and to
``benchmarks/real_machine.md``.

    python benchmarks/real_machine.py
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import _common  # noqa: F401  (puts src/ on the path)
from _common import section

CASES = [("die-bonder-pi", 2e5), ("die-bonder-pi", 5e5), ("die-bonder-pi", 1e6),
         ("die-bonder-pi", 2e6), ("butterfly", 1e5), ("butterfly", 2e5)]
INTERPOLATORS = ("taylor2", "paper", "planned")


def _effects():
    from nurbsmotion.machine import die_bonder, die_bonder_real

    m = die_bonder()

    def axes(**kw):
        return m.with_options(axes=tuple(dataclasses.replace(a, **kw) for a in m.axes))

    return [("none (ideal)", lambda at: m),
            ("1-um counts", lambda at: m.with_options(encoder="counts")),
            ("0.5 ms delay", lambda at: m.with_options(delay=0.5e-3)),
            ("0.3 V Coulomb, 0.4 V stiction",
             lambda at: axes(coulomb_friction=0.3, stiction=0.4)),
            ("0.5 V load step mid-move", lambda at: _with_step(m, at)),
            ("100 Hz mode, damping 0.02", lambda at: axes(resonance_frequency=100.0,
                                                          resonance_damping=0.02)),
            ("16-bit DAC", lambda at: m.with_options(dac_bits=16)),
            ("die-bonder-real (all)", lambda at: die_bonder_real())]


def _with_step(m, at):
    from nurbsmotion.machine import Disturbance

    return m.with_options(axes=tuple(dataclasses.replace(a, disturbance=(Disturbance(
        at, 0.5),)) for a in m.axes))


def _span(values, fmt="{:.3g}") -> str:
    lo, hi = min(values), max(values)
    return fmt.format(lo) if fmt.format(lo) == fmt.format(hi) else \
        f"{fmt.format(lo)}–{fmt.format(hi)}"


def measure() -> str:
    import nurbsmotion as nm
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate, to_pulses
    from nurbsmotion.machine import die_bonder
    from nurbsmotion.servo import ServoPlant

    m = die_bonder()
    rows = []
    for method in INTERPOLATORS:
        runs = {label: [] for label, _ in _effects()}
        for name, feed in CASES:
            path = to_pulses(nm.builtin_path(name), m)
            interp = make_interpolator(method, path, m, feed)
            ideal = simulate(interp, m)
            mid = 0.5 * ideal.cycle_time
            for label, make in _effects():
                true = make(mid)
                plant = ServoPlant(true.tau, true.Kc, true.Ke, m.max_drive,
                                   m.sample_period, path.end_points[0],
                                   true.effects() if true.has_effects else None)
                tr = simulate(interp, m, plant=plant, hold=0.3)
                mt, rest = tr.metrics(), tr.at_rest(window=300)
                runs[label].append((mt, rest))
        for label, results in runs.items():
            n = len(results)
            contour = [mt.max_contour_error for mt, _ in results]
            settled = sum(mt.settled for mt, _ in results)
            cycles = sum(any(r.limit_cycle.values()) for _, r in results)
            chatter = [max(r.drive_chatter_rms.values()) for _, r in results]
            vibration = [max(r.residual_vibration.values()) for _, r in results]
            rows.append([method, label, _span(contour), f"{settled}/{n}", f"{cycles}/{n}",
                         _span(chatter), _span(vibration)])
    return section(
        "The machine as it is: each effect alone on the true plant",
        ["interpolator", "effect on the true plant", "max contour [um]",
         "settled (1 um)", "limit cycles", "drive chatter RMS [V]",
         "residual vibration p-p [um]"], rows,
        "Controller and planner: the ideal die-bonder; the Pi at 0.2, 0.5, 1, 2 m/s and "
        "the butterfly at 0.1, 0.2 m/s (6 runs per row). Chatter, limit cycle and residual "
        "vibration over the run's last 0.3 s (the worst axis); 1 pulse = 1 um.")


def main() -> str:
    text = measure()
    Path(__file__).with_name("real_machine.md").write_text(text + "\n")
    return text


if __name__ == "__main__":
    main()
