"""Issue 10 evaluation of the ``planned`` interpolator: items 1-6 (item 7: planner_sweep.py).

Prints, for the die-bonder preset (Ts = 1 ms, 1 pulse = 1 um), with ``taylor2``, ``paper``
and ``planned`` side by side where it applies:

- nominal plant, Pi at 0.2/0.5/1/2 m/s and butterfly (x1000) at 0.05/0.1/0.2 m/s: cycle
  time (setpoint at the end), move-and-settle time (first time after which the actual
  position stays within +-1 pulse of the end) over the time-optimal bound, max contour
  error, end overshoot (along the arrival direction) and saturated samples (items 2, 3).
  The contour error is the smaller of the library's and a dense nearest-point check
  (0.25 pulse spacing): the library's grid search misses the nearest point next to the
  closed butterfly's seam by up to 9 um;
- the 9 plants with tau and Kc scaled by {0.8, 1, 1.2}, and the corners of [0.5, 2]
  (Pi at 1 m/s, butterfly at 0.1 m/s; ``planned`` only; items 1, 4);
- corner tolerance eps = 0, 10 um, 0.1, 0.5, 1 mm on the Pi at 1 and 2 m/s: settle over
  the stop-at-corner bound and the contour error to the original sharp path (item 5);
- move-and-settle of the Pi at 0.2-8 m/s and the butterfly at 0.05-0.8 m/s (item 6);
- planning time of ``planned`` (and of TOPP-RA where ``toppra`` is importable, via
  benchmarks/toppra_compare.py's set-up);
- item 7 (seeded random paths) is benchmarks/planner_sweep.py.

Run: python benchmarks/planner_eval.py
"""

from __future__ import annotations

import time

import numpy as np

import _common  # noqa: F401  (puts src/ on the path)
from nurbsmotion.interpolators import PlannedInterpolator, make_interpolator
from nurbsmotion.loop import simulate, to_pulses
from nurbsmotion.machine import die_bonder
from nurbsmotion.metrics import contour_error
from nurbsmotion.nurbs import builtin_path
from nurbsmotion.planning import time_optimal_bound
from nurbsmotion.servo import ServoPlant

SETTLE_WINDOW = 1.0  # pulse
HOLD = 0.3  # s of holding the end after the setpoint reaches it
RUNS = {"die-bonder-pi": (2e5, 5e5, 1e6, 2e6), "butterfly": (5e4, 1e5, 2e5)}


def settle_time(trace, end) -> float:
    """First time after which the actual position stays within SETTLE_WINDOW of ``end``."""
    d = np.max(np.abs(trace.position - end), axis=1)
    out = np.nonzero(d > SETTLE_WINDOW)[0]
    if out.size and out[-1] == len(d) - 1:
        return float("inf")
    return float(trace.t[out[-1] + 1]) if out.size else 0.0


def end_overshoot(trace, curve) -> float:
    """How far the actual position passes the end along the arrival direction [pulse]."""
    t = curve.derivatives(1.0, 1, "left")[1]
    t = t / np.linalg.norm(t)
    rel = trace.position - curve(1.0)
    # only the final approach: after the last sample farther than 1 % of the path's length
    far = np.nonzero(np.linalg.norm(rel, axis=1) > 0.01 * curve.length)[0]
    rel = rel[far[-1] + 1:] if far.size else rel
    return float(max(0.0, np.max(rel @ t))) if len(rel) else 0.0


_DENSE: dict = {}


def dense_contour_error(curve, points, spacing=0.25):
    """Distance to the nearest of curve points spaced ``spacing`` pulse apart in arc
    length (an independent check of :func:`nurbsmotion.metrics.contour_error`, within
    ``spacing / 2``)."""
    from scipy.spatial import cKDTree

    key = id(curve)
    if key not in _DENSE:
        n = int(curve.length / spacing) + 2
        u = curve.parameter_at(np.linspace(0.0, curve.length, n))
        _DENSE[key] = (curve, cKDTree(curve(u)))
    return _DENSE[key][1].query(points)[0]


def row(trace, curve, bound):
    m = trace.machine
    sat = int(np.count_nonzero(np.abs(trace.drive) > m.max_drive * (1 + 1e-9)))
    ce = np.minimum(contour_error(curve, trace.position),
                    dense_contour_error(curve, trace.position))
    st = settle_time(trace, curve(1.0))
    return (trace.cycle_time, st, st / bound, float(np.max(ce)), end_overshoot(trace, curve),
            sat, float(np.max(np.abs(trace.drive)) / m.max_drive))


def run(curve, m, feed, name, plant=None, **options):
    if name == "planned":
        interp = PlannedInterpolator(curve, m, feed, **options)
    else:
        interp = make_interpolator(name, curve, m, feed)
    return simulate(interp, m, plant=plant, settle_time=HOLD), interp


HEAD = ("| path | feed [m/s] | interpolator | cycle [s] | settle [s] | settle / bound "
        "| max contour [um] | end overshoot [um] | saturated samples | max drive / Umax |\n"
        "|---|---|---|---|---|---|---|---|---|---|")


def fmt(path, feed, name, r):
    return (f"| {path} | {feed / 1e6:g} | {name} | {r[0]:.4f} | {r[1]:.4f} | {r[2]:.4f} | "
            f"{r[3]:.3g} | {r[4]:.3g} | {r[5]} | {r[6]:.3f} |")


def nominal(m):
    print("## Items 2-3: nominal plant\n")
    print(HEAD)
    for path, feeds in RUNS.items():
        curve = to_pulses(builtin_path(path), m)
        for F in feeds:
            bound = time_optimal_bound(curve, m, F)
            for name in ("taylor2", "paper", "planned"):
                tr, _ = run(curve, m, F, name)
                print(fmt(path, F, name, row(tr, curve, bound)))
    print()


def mismatch(m):
    print("## Items 1, 4: mismatched plants (planned; the planner sees the nominal model)\n")
    print("| path | feed [m/s] | tau x | Kc x | settle / bound | max contour [um] "
          "| end overshoot [um] | saturated samples |\n|---|---|---|---|---|---|---|---|")
    scales = [(t, k) for t in (0.8, 1.0, 1.2) for k in (0.8, 1.0, 1.2)]
    scales += [(0.5, 0.5), (0.5, 2.0), (2.0, 0.5), (2.0, 2.0)]
    for path, F in (("die-bonder-pi", 1e6), ("butterfly", 1e5)):
        curve = to_pulses(builtin_path(path), m)
        bound = time_optimal_bound(curve, m, F)
        interp = PlannedInterpolator(curve, m, F)
        for ts, ks in scales:
            plant = ServoPlant.of_machine(m, curve(0.0), time_constant_scale=ts,
                                          electrical_gain_scale=ks)
            tr = simulate(interp, m, plant=plant, settle_time=HOLD)
            r = row(tr, curve, bound)
            print(f"| {path} | {F / 1e6:g} | {ts} | {ks} | {r[2]:.4f} | {r[3]:.3g} | "
                  f"{r[4]:.3g} | {r[5]} |")
    print()


def corner_tolerance(m):
    print("## Item 5: corner tolerance (Pi; settle over the stop-at-corner bound)\n")
    print("| feed [m/s] | eps [um] | settle / bound | max contour to the sharp path [um] "
          "| saturated samples |\n|---|---|---|---|---|")
    curve = to_pulses(builtin_path("die-bonder-pi"), m)
    for F in (1e6, 2e6):
        bound = time_optimal_bound(curve, m, F)
        for eps in (0.0, 10.0, 100.0, 500.0, 1000.0):
            tr, _ = run(curve, m, F, "planned", corner_tolerance=eps)
            r = row(tr, curve, bound)
            print(f"| {F / 1e6:g} | {eps:g} | {r[2]:.4f} | {r[3]:.3g} | {r[5]} |")
    print()


MONOTONE_FEEDS = {"die-bonder-pi": (2e5, 5e5, 1e6, 1.5e6, 2e6, 3e6, 4e6, 6e6, 8e6),
                  "butterfly": (5e4, 1e5, 2e5, 4e5, 8e5)}


def faster_is_never_slower(m):
    print("## Item 6: move-and-settle against the commanded feed (planned, nominal)\n")
    print("| path | feeds [m/s] | settle [s] | never slower when faster |\n|---|---|---|---|")
    for path, feeds in MONOTONE_FEEDS.items():
        curve = to_pulses(builtin_path(path), m)
        settles = [settle_time(run(curve, m, F, "planned")[0], curve(1.0)) for F in feeds]
        print(f"| {path} | {' / '.join(f'{F / 1e6:g}' for F in feeds)} | "
              f"{' / '.join(f'{s:.3f}' for s in settles)} | "
              f"{all(b <= a for a, b in zip(settles, settles[1:]))} |")
    print()


def planning_time(m):
    print("## Planning time (median of 3) [s]\n")
    print("TOPP-RA with 400 gridpoints a corner-free piece, and on the grid `planned` "
          "starts from (its arc-length grid size shared among the pieces).\n")
    print("| path | feed [m/s] | planned | TOPP-RA, 400 a piece | TOPP-RA, same grid |\n"
          "|---|---|---|---|---|")
    try:
        import toppra  # noqa: F401  (a benchmark-only comparison)
        from toppra_compare import planned_grid_size, toppra_plan
    except ImportError:
        toppra_plan = None
    for path, feeds in RUNS.items():
        curve = to_pulses(builtin_path(path), m)
        for F in feeds:
            t_plan = _common.median_time(lambda: PlannedInterpolator(curve, m, F), 3)[0]
            if toppra_plan is None:
                t_topp = [float("nan")] * 2
            else:
                t_topp = [_common.median_time(lambda: toppra_plan(curve, m, F, **grid), 3)[0]
                          for grid in ({}, {"grid_size": planned_grid_size()})]
            print(f"| {path} | {F / 1e6:g} | {t_plan:.3f} | {t_topp[0]:.3f} "
                  f"| {t_topp[1]:.3f} |")
    print()


def main():
    m = die_bonder()
    t0 = time.perf_counter()
    nominal(m)
    mismatch(m)
    corner_tolerance(m)
    faster_is_never_slower(m)
    planning_time(m)
    print(f"(wall time {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
