"""``planned`` on random machines: every law, sample period and drive the loop model
accepts, on the random paths of ``planner_sweep.py``, on the model's own plant.

Each case draws a machine (:func:`nurbsmotion.random_machines.random_machine`: Ts 0.1-2 ms,
tau 2-100 ms, PD+, PD or a LinuxCNC pid with integrator, deadband and clamp), a path of
2 or 3 axes (the families in turn) and a feed of 0.02-3x the slowest axis' steady speed
``Umax*Kc*Ke``. Reported: refusals and errors, saturated samples, runs that did not
settle, the contour error, how far a run passes the end or a stop corner, move-and-settle
against the time-optimal bound, and the planning time. The die-bonder preset's sweep is
``planner_sweep.py``; this one finds what only other machines show (a fuzz over such
machines found the speed profile's held speeds and the deadband's setpoints).

Run: MACHINE_SWEEP_CASES=600 python benchmarks/machine_sweep.py   (default 600 cases)
"""

from __future__ import annotations

import collections
import os
import time
import traceback

import numpy as np

import _common  # noqa: F401  (puts src/ on the path)
from nurbsmotion.errors import InvalidCurveError, NurbsmotionError
from nurbsmotion.interpolators import PlannedInterpolator
from nurbsmotion.loop import simulate
from nurbsmotion.paths.random_paths import FAMILIES, random_path
from nurbsmotion.planning import time_optimal_bound
from nurbsmotion.random_machines import random_machine

SEED = 77


def one_case(i: int) -> dict:
    rng = np.random.default_rng([SEED, i, 1])
    n_axes = int(rng.integers(2, 4))
    m = random_machine([SEED, i], n_axes)
    family = sorted(FAMILIES)[i % len(FAMILIES)]
    row = {"case": i, "family": family, "controller": m.controller,
           "sample_period": m.sample_period, "status": "ran"}
    try:
        curve = random_path(family, [SEED, i], n_axes=n_axes)
    except InvalidCurveError:
        row["status"] = "invalid path"
        return row
    steady = float(np.min(m.max_axis_speed))
    feed = float(np.exp(rng.uniform(np.log(0.02), np.log(3.0)))) * steady
    row["feed_per_steady_speed"] = feed / steady
    try:
        t0 = time.perf_counter()
        interp = PlannedInterpolator(curve, m, feed)
        row["planning"] = time.perf_counter() - t0
        bound = time_optimal_bound(curve, m, feed)
        tr = simulate(interp, m)
    except NurbsmotionError as exc:
        row.update(status="refused", error=f"{type(exc).__name__}: {exc}")
        return row
    except Exception:  # noqa: BLE001 - a crash is what the sweep is for
        row.update(status="crashed", error=traceback.format_exc(limit=3))
        return row
    metrics = tr.metrics()
    row.update(
        success=bool(tr.success), message=tr.message,
        saturated=int(np.count_nonzero(np.abs(tr.drive) > m.max_drive * (1 + 1e-9))),
        contour=metrics.max_contour_error, end_overshoot=metrics.end_overshoot,
        corner_overshoot=metrics.corner_overshoot,
        ratio=(tr.settled_index * m.sample_period / bound
               if tr.settled_index is not None else float("nan")))
    return row


def report(rows: list) -> None:
    print("cases:", dict(collections.Counter(r["status"] for r in rows)))
    for r in rows:
        if r["status"] in ("refused", "crashed"):
            print(f"  case {r['case']} ({r['family']}, {r['controller']}): {r['error']}")
    ran = [r for r in rows if r["status"] == "ran"]
    if not ran:
        return

    def pct(key):
        v = np.array([r[key] for r in ran], dtype=float)
        return " / ".join(f"{x:.3g}" for x in np.nanpercentile(v, [50, 95, 100]))

    print("\n| runs | saturated | not settled | contour [um] median / 95 % / max "
          "| past the end / a stop corner by > 1 um | settle / bound median / 95 % / max "
          "| planning [s] median / 95 % / max |")
    print("|---|---|---|---|---|---|---|")
    print(f"| {len(ran)} | {sum(r['saturated'] > 0 for r in ran)} "
          f"| {sum(not r['success'] for r in ran)} | {pct('contour')} "
          f"| {sum(r['end_overshoot'] > 1 for r in ran)} / "
          f"{sum(r['corner_overshoot'] > 1 for r in ran)} | {pct('ratio')} "
          f"| {pct('planning')} |")
    def cases(selected, key, unit):
        return ", ".join(
            f"case {r['case']} ({r['family']}, {r['controller']}, Ts "
            f"{r['sample_period'] * 1e3:g} ms, {r['feed_per_steady_speed']:.2f}x): "
            f"{r[key]:.3g} {unit}" for r in selected)

    print("\nlargest contour errors:",
          cases(sorted(ran, key=lambda r: -r["contour"])[:5], "contour", "um"))
    print("slowest planning:",
          cases(sorted(ran, key=lambda r: -r["planning"])[:5], "planning", "s"))
    for key in ("end_overshoot", "corner_overshoot"):
        over = [r for r in ran if r[key] > 1]
        if over:
            print(f"{key} > 1 um:", cases(over, key, "um"))


def main():
    from multiprocessing import Pool

    n = int(os.environ.get("MACHINE_SWEEP_CASES", "600"))
    t0 = time.perf_counter()
    with Pool(min(os.cpu_count() or 1, 8)) as pool:
        rows = pool.map(one_case, range(n), chunksize=1)
    report(rows)
    print(f"\n{n} cases in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
