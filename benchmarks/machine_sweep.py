"""``planned`` on random machines: every law, sample period and drive the loop model
accepts, on the random paths of ``planner_sweep.py``.

Each case draws a machine (:func:`nurbsmotion.random_machines.random_machine`: Ts 0.1-2 ms,
tau 2-100 ms, PD+, PD or a LinuxCNC pid with integrator, deadband and clamp), a path of
2 or 3 axes (the families in turn) and a feed of 0.02-3x the slowest axis' steady speed
``Umax*Kc*Ke``; each is run on the model's plant and on a plant whose tau and Kc per axis
are the model's times random factors in [0.5, 2] (issue 10, item 1: never a saturated
drive, whatever the plant). Reported: refusals and errors, saturated samples, runs that
did not settle, the contour error, how far a run passes the end or a stop corner,
move-and-settle against the time-optimal bound, and the planning time. The die-bonder
preset's sweep is ``planner_sweep.py``; this one finds what only other machines show (a
fuzz over such machines found the speed profile's held speeds and the deadband's
setpoints).

Run: MACHINE_SWEEP_CASES=600 python benchmarks/machine_sweep.py   (default 600 cases)
"""

from __future__ import annotations

import collections
import os
import time
import traceback

import numpy as np

import _common  # puts src/ on the path
from nurbsmotion.errors import InvalidCurveError, NurbsmotionError
from nurbsmotion.interpolators import PlannedInterpolator
from nurbsmotion.loop import simulate
from nurbsmotion.paths.random_paths import FAMILIES, random_path
from nurbsmotion.planning import time_optimal_bound
from nurbsmotion.random_machines import random_machine
from nurbsmotion.servo import ServoPlant

SEED = 77


CONDITIONS = ("model", "x0.5-2")
"""The true plant: the model's, or every axis's tau and Kc each scaled by a random factor
in [0.5, 2] (the planner always sees the model)."""


def one_case(i: int) -> list:
    """Case ``i`` on each of :data:`CONDITIONS`: one row each."""
    rng = np.random.default_rng([SEED, i, 1])
    n_axes = int(rng.integers(2, 4))
    m = random_machine([SEED, i], n_axes)
    family = sorted(FAMILIES)[i % len(FAMILIES)]
    base = {"case": i, "family": family, "controller": m.controller,
            "sample_period": m.sample_period, "status": "ran"}
    try:
        curve = random_path(family, [SEED, i], n_axes=n_axes)
    except InvalidCurveError:
        return [dict(base, condition=c, status="invalid path") for c in CONDITIONS]
    steady = float(np.min(m.max_axis_speed))
    feed = float(np.exp(rng.uniform(np.log(0.02), np.log(3.0)))) * steady
    base["feed_per_steady_speed"] = feed / steady
    scales = np.random.default_rng([SEED, i, 2]).uniform(0.5, 2.0, (2, n_axes))
    plants = {"model": None,
              "x0.5-2": ServoPlant.of_machine(m, curve(0.0), time_constant_scale=scales[0],
                                              electrical_gain_scale=scales[1])}
    try:
        t0 = time.perf_counter()
        interp = PlannedInterpolator(curve, m, feed)
        base["planning"] = time.perf_counter() - t0
        bound = time_optimal_bound(curve, m, feed)
    except NurbsmotionError as exc:
        return [dict(base, condition=c, status="refused",
                     error=f"{type(exc).__name__}: {exc}") for c in CONDITIONS]
    rows = []
    for condition, plant in plants.items():
        row = dict(base, condition=condition)
        try:
            tr = simulate(interp, m, plant=plant)
        except NurbsmotionError as exc:
            rows.append(dict(row, status="refused", error=f"{type(exc).__name__}: {exc}"))
            continue
        except Exception:  # noqa: BLE001 - a crash is what the sweep is for
            rows.append(dict(row, status="crashed", error=traceback.format_exc(limit=3)))
            continue
        metrics = tr.metrics()
        rows.append(dict(
            row, success=bool(tr.success), message=tr.message,
            saturated=int(np.count_nonzero(np.abs(tr.drive) > m.max_drive * (1 + 1e-9))),
            contour=metrics.max_contour_error, end_overshoot=metrics.end_overshoot,
            corner_overshoot=metrics.corner_overshoot,
            ratio=(tr.settled_index * m.sample_period / bound
                   if tr.settled_index is not None else float("nan"))))
    return rows


def report(rows: list) -> None:
    print("rows:", dict(collections.Counter(r["status"] for r in rows)))
    for r in rows:
        if r["status"] in ("refused", "crashed"):
            print(f"  case {r['case']} ({r['family']}, {r['controller']}, {r['condition']}): "
                  f"{r['error']}")
    print("\n| plant | runs | saturated | not settled | contour [um] median / 95 % / max "
          "| past the end / a stop corner by > 1 um | settle / bound median / 95 % / max "
          "| planning [s] median / 95 % / max |")
    print("|---|---|---|---|---|---|---|---|")
    for condition in CONDITIONS:
        ran = [r for r in rows if r["status"] == "ran" and r["condition"] == condition]
        if not ran:
            continue

        def pct(key):
            return _common.spread([r[key] for r in ran])

        print(f"| {condition} | {len(ran)} | {sum(r['saturated'] > 0 for r in ran)} "
              f"| {sum(not r['success'] for r in ran)} | {pct('contour')} "
              f"| {sum(r['end_overshoot'] > 1 for r in ran)} / "
              f"{sum(r['corner_overshoot'] > 1 for r in ran)} | {pct('ratio')} "
              f"| {pct('planning')} |")

    def cases(selected, key, unit):
        return ", ".join(
            f"case {r['case']} ({r['family']}, {r['controller']}, Ts "
            f"{r['sample_period'] * 1e3:g} ms, {r['feed_per_steady_speed']:.2f}x): "
            f"{r[key]:.3g} {unit}" for r in selected)

    model = [r for r in rows if r["status"] == "ran" and r["condition"] == "model"]
    print("\non the model's plant:")
    print("largest contour errors:",
          cases(sorted(model, key=lambda r: -r["contour"])[:5], "contour", "um"))
    print("slowest planning:",
          cases(sorted(model, key=lambda r: -r["planning"])[:5], "planning", "s"))
    for key in ("end_overshoot", "corner_overshoot"):
        over = [r for r in model if r[key] > 1]
        if over:
            print(f"{key} > 1 um:", cases(over, key, "um"))


def main():
    from multiprocessing import Pool

    n = int(os.environ.get("MACHINE_SWEEP_CASES", "600"))
    t0 = time.perf_counter()
    with Pool(min(os.cpu_count() or 1, 8)) as pool:
        rows = [row for case in pool.map(one_case, range(n), chunksize=1) for row in case]
    report(rows)
    print(f"\n{n} cases in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
