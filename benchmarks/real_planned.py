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

Item 4, random real machines: case ``i`` draws from ``[ITEM4_SEED, i]`` a random machine
as it is (:func:`nurbsmotion.random_machines.random_machine` with ``real=True``: every law,
Ts 0.1-2 ms; counts of 0.1-10 um, 0-0.5 count of noise, 0-0.6 Ts of delay, a 12-16-bit
or no DAC, Coulomb friction 0-5 % of Umax, on some axes a 30-300 Hz mode of damping
0.01-0.1 above the axis's own), what its controller knows of it
(:func:`nurbsmotion.random_machines.random_model`: no friction; each mode unknown or
known within +-10 %), 2 or 3 axes, a random path (the families of
:mod:`nurbsmotion.paths.random_paths` in turn) and a feed of 0.02-3x the slowest axis's
steady speed, and runs each interpolator on it (settle window 2 counts, 0.3 s hold, at
most :data:`ITEM4_SETTLE_LIMIT` after the setpoint's end). Reported per interpolator:
refusals, runs with saturated samples (the law's output beyond Umax, before the clip;
``paper``'s cornered samples, where no admissible step existed, apart), limit cycles, runs
that did not settle, NaN, the settle/bound and contour distributions and the share within
max(5 %, 3 ms) of the bound (bound: the rigid time-optimal bound on the model).

    python benchmarks/real_planned.py [item1|item2] [--methods planned,paper,...]
    python benchmarks/real_planned.py item4 [--cases 1000] [--start 0] [--methods ...]
        [--rows FILE.jsonl]

Writes markdown to stdout (items 1 and 2 print each row to stderr as it is measured),
and to ``benchmarks/real_planned_<item>.md`` only for a complete run (every
interpolator; item 4: the 1,000 cases from case 0, or ``--report`` of rows gathered in
pieces), so a subset never replaces the committed table; ``--out FILE`` writes any run's
tables there instead. ``--rows`` appends each case's rows as JSON
lines, and ``item4 --report FILE.jsonl`` writes the tables of rows gathered in pieces.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
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
    return _run_on(interp, model, _plant(true, model, start))


def _run_on(interp, model, plant):
    from nurbsmotion.loop import simulate

    tr = simulate(interp, model, plant=plant, hold=HOLD,
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
    rigid model and its modes only, so it is made once per case and set of modes and
    given what it knows of each model beyond it
    (:func:`nurbsmotion.interpolators.planned.machine_knowledge`) as the constructor
    would."""
    import copy

    import nurbsmotion as nm
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.interpolators import planned
    from nurbsmotion.loop import to_pulses

    path = to_pulses(nm.builtin_path(name), model)
    if method != "planned":
        return path, make_interpolator(method, path, model, feed)
    # a model with a mode shapes the plan's time law at it (planned.shaper.time_law_shaper)
    key = (name, feed, tuple((a.resonance_frequency, a.resonance_damping) for a in model.axes))
    if key not in _PLANS:
        _PLANS[key] = make_interpolator(method, path, model, feed)
    interp = copy.copy(_PLANS[key])
    p = interp.plan
    interp.machine = model
    interp.plan = p._replace(**planned.machine_knowledge(model, p.a, p.b0, p.c, p.b1,
                                                         interp.tracking_pole))
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
                print(lines[-1], file=sys.stderr, flush=True)  # progress; the table on stdout
    return "\n".join(lines)


def item2(methods):
    from nurbsmotion.machine import die_bonder, die_bonder_real
    from nurbsmotion.planning import time_optimal_bound
    from nurbsmotion.servo import ServoPlant

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
                    # the plant itself, not a Machine: a machine whose linear loop is
                    # unstable with its delay is refused, and at tau x0.9, Kc x1.1 the
                    # preset's is (the run shows what that does)
                    plant = ServoPlant.of_machine(model, path.end_points[0],
                                                  time_constant_scale=ft,
                                                  electrical_gain_scale=fk)
                    r = _run_on(interp, model, plant)
                    lines.append(_row(method, f"{ft:g}, {fk:g}", case, r, bound, 25.0,
                                      1.15))
                    print(lines[-1], file=sys.stderr, flush=True)  # progress; the table on stdout
    return "\n".join(lines)


ITEM4_SEED = 33
ITEM4_SETTLE_LIMIT = 2.0
"""Longest wait for a random real machine to settle after the setpoint's end [s]: a run
not settled by then counts as not settled (settle/bound infinite)."""
FEEDS = (0.02, 3.0)
"""Feeds drawn, log-uniform, in these multiples of the slowest axis's steady speed."""


def item4_case(i, methods):
    """Case ``i`` of item 4 (module docstring): one row per interpolator (dicts)."""
    import time

    import numpy as np

    from nurbsmotion.errors import InvalidCurveError, NurbsmotionError
    from nurbsmotion.interpolators import make_interpolator
    from nurbsmotion.loop import simulate
    from nurbsmotion.paths.random_paths import FAMILIES, random_path
    from nurbsmotion.planning import time_optimal_bound
    from nurbsmotion.random_machines import random_machine, random_model
    from nurbsmotion.servo import ServoPlant

    rng = np.random.default_rng([ITEM4_SEED, i])
    n_axes = int(rng.integers(2, 4))
    true = random_machine([ITEM4_SEED, i], n_axes, real=True)
    model = random_model(true, [ITEM4_SEED, i, 1])
    family = sorted(FAMILIES)[i % len(FAMILIES)]
    steady = float(np.min(model.max_axis_speed))
    feed = float(np.exp(rng.uniform(*np.log(FEEDS)))) * steady
    base = dict(case=i, family=family, n_axes=n_axes, controller=true.controller,
                Ts=true.sample_period, feed_per_steady=feed / steady,
                delay_per_Ts=true.delay / true.sample_period,
                pulse_um=true.pulse_length_um, noise=true.measurement_noise,
                modes=[a.resonance_frequency for a in true.axes],
                known_modes=[a.resonance_frequency for a in model.axes])
    try:
        curve = random_path(family, [ITEM4_SEED, i], n_axes=n_axes)
    except InvalidCurveError:
        return [dict(base, method=m, status="invalid path") for m in methods]
    try:
        bound = time_optimal_bound(curve, model, feed)
    except NurbsmotionError as exc:
        return [dict(base, method=m, status="no bound", error=f"{type(exc).__name__}: {exc}")
                for m in methods]
    plant = ServoPlant.of_machine(true, curve(0.0))
    rows = []
    for method in methods:
        row = dict(base, method=method, bound=bound, status="ran")
        c0 = time.process_time()
        try:
            interp = make_interpolator(method, curve, model, feed)
            tr = simulate(interp, model, plant=plant, settle_window=SETTLE_WINDOW,
                          hold=HOLD, settle_limit=ITEM4_SETTLE_LIMIT)
            mt, rest = tr.metrics(), tr.at_rest()
        except NurbsmotionError as exc:
            rows.append(dict(row, status="refused", error=f"{type(exc).__name__}: {exc}",
                             cpu=time.process_time() - c0))
            continue
        except Exception as exc:  # noqa: BLE001 - a crash is what the sweep is for
            rows.append(dict(row, status="crashed", error=f"{type(exc).__name__}: {exc}",
                             cpu=time.process_time() - c0))
            continue
        finite = all(bool(np.all(np.isfinite(a))) for a in
                     (tr.position, tr.position_command, tr.drive, tr.drive_applied))
        rows.append(dict(
            row, cpu=time.process_time() - c0, samples=len(tr.t), nan=not finite,
            saturated=mt.total_saturated_samples,
            cornered=int(sum(mt.cornered_samples.values())),
            cycle=any(rest.limit_cycle.values()), settled=bool(mt.settled),
            ratio=mt.settle_time_s / bound,
            within=bool(mt.settle_time_s - bound <= max(0.05 * bound, 3e-3)),
            contour=mt.max_contour_error,
            contour_um=mt.max_contour_error * true.pulse_length_um,
            chatter=max(rest.drive_chatter_rms.values())))
    return rows


def item4_report(rows, methods):
    """The markdown tables of item 4's rows."""
    import collections

    import numpy as np

    cases = sorted({r["case"] for r in rows})
    lines = [f"## Item 4: random real machines, {len(cases)} cases "
             f"({cases[0] if cases else 0}-{cases[-1] if cases else 0}, seed {ITEM4_SEED})\n",
             "| interpolator | ran | refused | crashed | saturated runs (cornered only) "
             "| limit cycles | not settled | NaN | settle / bound median / 95 % / max "
             "| the same, settled runs | within max(5 %, 3 ms) "
             "| max contour [pulse] median / 95 % / max "
             "| max contour [um] median / 95 % / max | CPU [s] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for method in methods:
        mine = [r for r in rows if r["method"] == method]
        ran = [r for r in mine if r["status"] == "ran"]
        status = collections.Counter(r["status"] for r in mine)
        sat = [r for r in ran if r["saturated"]]
        only_cornered = [r for r in sat if r["saturated"] <= r["cornered"]]

        def spread(key, runs=ran):
            v = np.sort(np.array([r[key] for r in runs], dtype=float))
            if not len(v):
                return "-"
            # nearest rank: an infinite value (not settled) is a value, not a NaN
            at = [v[min(len(v) - 1, int(np.ceil(q * len(v))) - 1)] for q in (0.5, 0.95, 1)]
            return " / ".join("∞" if not np.isfinite(x) else f"{x:.3g}" for x in at)

        lines.append(
            f"| {method} | {len(ran)} | {status['refused']} | {status['crashed']} "
            f"| {len(sat)} ({len(only_cornered)}) | {sum(r['cycle'] for r in ran)} "
            f"| {sum(not r['settled'] for r in ran)} | {sum(r['nan'] for r in ran)} "
            f"| {spread('ratio')} | {spread('ratio', [r for r in ran if r['settled']])} "
            f"| {100 * np.mean([r['within'] for r in ran]) if ran else 0:.1f} % "
            f"| {spread('contour')} | {spread('contour_um')} "
            f"| {sum(r.get('cpu', 0.0) for r in mine):.0f} |")
    lines += ["\nBy the machine's modes (runs: limit cycles / not settled / within "
              "max(5 %, 3 ms)):\n",
              "| interpolator | no mode | every mode known (+-10 %) | a mode unknown |",
              "|---|---|---|---|"]

    def kind(r):
        if not any(r["modes"]):
            return 0
        return 1 if all(bool(k) == bool(f) for f, k in zip(r["modes"], r["known_modes"])) \
            else 2

    for method in methods:
        ran = [r for r in rows if r["method"] == method and r["status"] == "ran"]
        cells = []
        for k in range(3):
            sub = [r for r in ran if kind(r) == k]
            cells.append(f"{len(sub)}: {sum(r['cycle'] for r in sub)} / "
                         f"{sum(not r['settled'] for r in sub)} / "
                         f"{sum(r['within'] for r in sub)}")
        lines.append(f"| {method} | " + " | ".join(cells) + " |")
    for method in methods:
        ran = [r for r in rows if r["method"] == method and r["status"] == "ran"]
        top = sorted(ran, key=lambda r: -r["contour"])[:3]
        if top:
            lines.append(f"\n{method}'s largest contour errors: " + "; ".join(
                f"case {r['case']} ({r['family']}, {r['controller']}, Ts {r['Ts'] * 1e3:g} ms, "
                f"{r['feed_per_steady']:.2f}x steady): {r['contour']:.3g} pulse"
                for r in top))
    other = collections.Counter(r["status"] for r in rows
                                if r["status"] in ("invalid path", "no bound"))
    if other:
        lines.append(f"\nCases not run (per interpolator): {dict(other)}")
    for r in rows:
        if r["status"] in ("refused", "crashed"):
            lines.append(f"- case {r['case']} ({r['family']}, {r['method']}): {r['error']}")
    worst = collections.defaultdict(list)
    for r in rows:
        if r["status"] == "ran" and (r["cycle"] or not r["settled"] or r["saturated"]):
            worst[r["method"]].append(r)
    for method, bad in worst.items():
        lines.append(f"\n{method}: {len(bad)} runs with a limit cycle, saturated or not "
                     "settled; the first 12:")
        for r in bad[:12]:
            modes = "/".join(f"{f:.0f}" for f in r["modes"])
            known = "/".join(f"{f:.0f}" for f in r["known_modes"])
            lines.append(
                f"- case {r['case']} {r['family']} {r['n_axes']} axes {r['controller']} Ts "
                f"{r['Ts'] * 1e3:g} ms, feed {r['feed_per_steady']:.2f}x steady, delay "
                f"{r['delay_per_Ts']:.2f} Ts, noise {r['noise']:.2f}, modes [Hz] {modes} "
                f"(model {known}): saturated {r['saturated']} (cornered {r['cornered']}), "
                f"limit cycle {'yes' if r['cycle'] else 'no'}, settle/bound "
                f"{r['ratio']:.3g}, contour {r['contour']:.3g} pulse")
    return "\n".join(lines)


def item4(methods, cases, start, rows_file=None):
    import json

    rows = []
    for i in range(start, start + cases):
        case_rows = item4_case(i, methods)
        rows += case_rows
        if rows_file:
            with open(rows_file, "a") as f:
                for r in case_rows:
                    f.write(json.dumps(r) + "\n")
    return item4_report(rows, methods)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("item", choices=("item1", "item2", "item4"))
    p.add_argument("--methods", default=",".join(INTERPOLATORS))
    p.add_argument("--cases", type=int, default=1000, help="item 4: cases to run")
    p.add_argument("--start", type=int, default=0, help="item 4: first case")
    p.add_argument("--rows", help="item 4: append each case's rows to this JSON-lines file")
    p.add_argument("--report", help="item 4: only the tables of the rows in this file")
    p.add_argument("--out", help="write the tables to this file (default: the committed "
                                 "table, for a complete run only)")
    args = p.parse_args()
    methods = args.methods.split(",")
    complete = set(methods) == set(INTERPOLATORS) and (
        args.item != "item4" or args.report or (args.start == 0 and args.cases >= 1000))
    out = (Path(args.out) if args.out else
           Path(__file__).with_name(f"real_planned_{args.item}.md") if complete else None)
    if args.item == "item4":
        if args.report:
            import json

            with open(args.report) as f:
                rows = [json.loads(line) for line in f]
            text = item4_report(rows, methods)
        else:
            text = item4(methods, args.cases, args.start, args.rows)
    else:
        text = (item1 if args.item == "item1" else item2)(methods)
    print(text)
    if out is not None:
        out.write_text(text + "\n")


if __name__ == "__main__":
    main()
