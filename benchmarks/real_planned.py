"""``planned`` on a real machine (issue 33): items 1 and 2, ``taylor2``, ``paper`` and
``planned`` side by side.

Cases: the Pi at 0.2, 0.5, 1 and 2 m/s and the butterfly at 0.1 and 0.2 m/s. Settle = the
true tool position within 2 pulses of the end for good; bound = the rigid time-optimal
bound (:func:`nurbsmotion.planning.time_optimal_bound`); chatter, limit cycle and residual
vibration over the run's last 0.3 s (:meth:`nurbsmotion.loop.Trace.at_rest`).

Item 1, each effect alone on the true plant. What a machine's maker knows is known to the
model the controller and the planner get (the encoder's counts and noise, the delay, the
DAC, the mode's frequency, given 10 % low, and damping); friction and the load are not.
Item 2, the ``die-bonder-real`` preset (friction unknown to the model) with the true
plant's tau and Kc at x0.9 / 1 / 1.1 of the model's (nine combinations, all axes).

    python benchmarks/real_planned.py [item1|item2] [--methods planned,paper,...]

Writes markdown to stdout and to ``benchmarks/real_planned_<item>.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import _common  # noqa: F401  (puts src/ on the path)

CASES = [("die-bonder-pi", 2e5), ("die-bonder-pi", 5e5), ("die-bonder-pi", 1e6),
         ("die-bonder-pi", 2e6), ("butterfly", 1e5), ("butterfly", 2e5)]
INTERPOLATORS = ("taylor2", "paper", "planned")
SETTLE_WINDOW = 2.0   # pulse
HOLD = 0.3            # s after settling
MODE_ERROR = 0.9      # the model's mode frequency over the true one


def _axes(m, **kw):
    return m.with_options(axes=tuple(dataclasses.replace(a, **kw) for a in m.axes))


def effects():
    """(label, true machine(at), model machine, contour limit [um], settle limit)."""
    from nurbsmotion.machine import Disturbance, die_bonder

    m = die_bonder()
    counts = m.with_options(encoder="counts")
    noise = m.with_options(measurement_noise=0.3)
    delay = m.with_options(delay=0.5e-3)
    dac = m.with_options(dac_bits=16)
    mode = _axes(m, resonance_frequency=100.0, resonance_damping=0.02)
    mode_model = _axes(m, resonance_frequency=100.0 * MODE_ERROR, resonance_damping=0.02)
    friction = _axes(m, coulomb_friction=0.3, stiction=0.4)

    def step(at):
        return _axes(m, disturbance=(Disturbance(at, 0.5),))

    return [("none (ideal)", lambda at: m, m, 0.1, 1.05),
            ("1-um counts", lambda at: counts, counts, 5.0, 1.10),
            ("noise 0.3 pulse", lambda at: noise, noise, 5.0, 1.10),
            ("0.5 ms delay (known)", lambda at: delay, delay, 10.0, 1.10),
            ("16-bit DAC", lambda at: dac, dac, 5.0, 1.10),
            ("0.3 V Coulomb, 0.4 V stiction", lambda at: friction, m, 25.0, 1.15),
            ("0.5 V load step mid-move", step, m, 25.0, 1.15),
            ("100 Hz mode (model 90 Hz)", lambda at: mode, mode_model, 25.0, 1.15)]


def _plant(true, m, start):
    from nurbsmotion.servo import ServoPlant

    return ServoPlant(true.tau, true.Kc, true.Ke, m.max_drive, m.sample_period, start,
                      true.effects() if true.has_effects else None)


def _run(interp, model, true, start):
    from nurbsmotion.loop import simulate

    tr = simulate(interp, model, plant=_plant(true, model, start), hold=HOLD,
                  settle_window=SETTLE_WINDOW)
    mt, rest = tr.metrics(), tr.at_rest(window=300)
    return dict(contour=mt.max_contour_error, settle=mt.settle_time_s,
                settled=mt.settled, sat=mt.total_saturated_samples,
                cycle=any(rest.limit_cycle.values()),
                chatter=max(rest.drive_chatter_rms.values()),
                vib=max(rest.residual_vibration.values()))


def _fmt(v, f="{:.3g}"):
    return "∞" if not math.isfinite(v) else f.format(v)


def _row(method, label, case, r, bound, contour_limit, settle_limit):
    ratio = r["settle"] / bound
    ok = (not r["cycle"] and r["chatter"] <= 0.05 and ratio <= settle_limit
          and r["contour"] <= contour_limit)
    return (f"| {label} | {case} | {method} | {_fmt(ratio, '{:.3f}')} | "
            f"{_fmt(r['contour'])} | {'yes' if r['cycle'] else 'no'} | "
            f"{r['chatter']:.3g} | {_fmt(r['vib'])} | {r['sat']} | {'ok' if ok else 'MISS'} |")


HEAD = ("| effect | case | interpolator | settle / bound | max contour [um] | limit cycle "
        "| chatter RMS [V] | residual vib. p-p [um] | saturated | target |\n"
        "|---|---|---|---|---|---|---|---|---|---|")


_PLANS = {}


def _interp(method, name, feed, model):
    """The interpolator on the model machine. ``planned``'s offline plan depends on the
    rigid model only, so it is made once per case and given each model's reading
    (:func:`nurbsmotion.interpolators.planned.reading_knowledge`) as the constructor
    would."""
    import copy

    import nurbsmotion as nm
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.interpolators import planned
    from nurbsmotion.loop import to_pulses

    path = to_pulses(nm.builtin_path(name), model)
    if method != "planned":
        return path, make_interpolator(method, path, model, feed)
    if (name, feed) not in _PLANS:
        _PLANS[name, feed] = make_interpolator(method, path, model, feed)
    interp = copy.copy(_PLANS[name, feed])
    p = interp.plan
    interp.machine = model
    if hasattr(planned, "reading_knowledge"):
        interp.plan = p._replace(**planned.reading_knowledge(model, p.a, p.b0, p.c, p.b1))
    return path, interp


def item1(methods):
    from nurbsmotion.loop import simulate
    from nurbsmotion.machine import die_bonder
    from nurbsmotion.planning import time_optimal_bound

    m = die_bonder()
    lines = ["## Item 1: each effect alone on the true plant\n", HEAD]
    for name, feed in CASES:
        path, ideal = _interp("paper", name, feed, m)
        mid = 0.5 * simulate(ideal, m).cycle_time
        bound = time_optimal_bound(path, m, feed)
        case = f"{name} {feed / 1e6:g} m/s"
        for label, true, model, climit, slimit in effects():
            for method in methods:
                _, interp = _interp(method, name, feed, model)
                r = _run(interp, model, true(mid), path.end_points[0])
                lines.append(_row(method, label, case, r, bound, climit, slimit))
                print(lines[-1], flush=True)
    return "\n".join(lines)


def item2(methods):
    from nurbsmotion.machine import die_bonder, die_bonder_real
    from nurbsmotion.planning import time_optimal_bound

    model = die_bonder_real()
    lines = ["## Item 2: die-bonder-real, true tau and Kc x0.9 / 1 / 1.1\n",
             HEAD.replace("| effect |", "| tau x, Kc x |")]
    for name, feed in CASES:
        path, _ = _interp("paper", name, feed, die_bonder())
        bound = time_optimal_bound(path, die_bonder(), feed)
        case = f"{name} {feed / 1e6:g} m/s"
        for method in methods:
            _, interp = _interp(method, name, feed, model)
            for ft in (0.9, 1.0, 1.1):
                for fk in (0.9, 1.0, 1.1):
                    true = model.with_options(axes=tuple(dataclasses.replace(
                        a, time_constant=a.time_constant * ft,
                        electrical_gain=a.electrical_gain * fk) for a in model.axes))
                    r = _run(interp, model, true, path.end_points[0])
                    lines.append(_row(method, f"{ft:g}, {fk:g}", case, r, bound, 25.0,
                                      1.15))
                    print(lines[-1], flush=True)
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("item", choices=("item1", "item2"))
    p.add_argument("--methods", default=",".join(INTERPOLATORS))
    args = p.parse_args()
    methods = args.methods.split(",")
    text = (item1 if args.item == "item1" else item2)(methods)
    Path(__file__).with_name(f"real_planned_{args.item}.md").write_text(text + "\n")


if __name__ == "__main__":
    main()
