"""Issue 10, item 7: the ``planned`` interpolator on seeded random paths nobody tuned for.

Every case draws, from ``numpy.random.default_rng([SEED, i])``: a random-path family
(:data:`nurbsmotion.paths.random_paths.FAMILIES`, in turn: free-form degree 3-5, sharp
corners, near-corners under 2 degrees, near-cusps, knot spans of 1e-6 of the domain,
duplicated control points, hairpins, closed loops, short moves whose bound is under
50 ms, ...), 2 or 3 axes, a feed log-uniform in 0.05-3 m/s, and one of three loops on the
die-bonder (z = a copy of x): the nominal plant; a plant whose tau and Kc are scaled
independently per axis in [0.8, 1.2] (the planner sees the nominal model); Kp and Kd
doubled. Per case it records: refused (a typed error from the planner; a path the curve
class itself refuses is counted apart), saturated samples, NaN, the parameter monotone,
at rest on the end (settled within 1 pulse), move-and-settle minus the bound against
max(5 % of the bound, 3 ms), whether that target is reachable at all by a sampled motion
that stops at the corners (:func:`nurbsmotion.planning.sampled_stop_bound`: whole
samples per piece, each at least the slowest axis' rest-to-rest minimum; a case is
unreachable when even this bound misses the target), the per-piece
estimate (:func:`piece_estimate`: what a motion on the path takes at least, the continuous
optimum of every piece rounded up to whole samples; an estimate, not a bound), the max
contour error, how far the run passes the end and the stop corners (the run's metrics,
:meth:`nurbsmotion.loop.Trace.metrics`), and the planning time (the interpolator's
construction, wall clock).

Prints the counts and the distributions (median, 95th percentile, max) per condition.

With ``PLANNER_SWEEP_PLAN_ONLY=1`` it only plans (issue 35's planning-time target): per
case the interpolator's construction (wall clock), the plan's arrival against the bound
and the sampled bound (on the nominal plant the run settles where its plan rests), and
the slowest cases with what they are. The sweep plans case 0 once, untimed, first
(:func:`_warm_up`: numba's kernels load, or compile, in the first plan of a process).

With ``PLANNER_SWEEP_BOUNDS_ONLY=1`` it computes only each case's bound columns (the
time-optimal bound and the sampled bound, from the same seeded draw; nothing is planned or
run) and reports per condition how many cases cannot meet the target: the column a
change of :func:`~nurbsmotion.planning.sampled_stop_bound` alone moves, in minutes where
the whole sweep takes hours on a shared machine.

Run: PLANNER_SWEEP_CASES=1000 python benchmarks/planner_sweep.py   (default 1000 cases).
``PLANNER_SWEEP_LOG=FILE`` appends every case's row to FILE as it ends (one JSON object a
line); ``PLANNER_SWEEP_REPORT=FILE`` prints the report of such a file's first
``PLANNER_SWEEP_CASES`` rows instead of running (a sweep stopped part-way);
``PLANNER_SWEEP_FIRST=k`` runs cases k, k + 1, ... (a part of the sweep in a second
process); with ``PLANNER_SWEEP_PLAN_ONLY=1``, ``PLANNER_SWEEP_REFERENCE=FILE`` (a log of
another tree) lists the cases whose arrival differs from that log's, and the report counts
the plans whose step 6 stopped at its work budget (``shorten_work``).
"""

from __future__ import annotations

import inspect
import math
import os
import time

import numpy as np

import _common  # puts src/ on the path
from nurbsmotion.errors import InvalidCurveError, NurbsmotionError
from nurbsmotion.interpolators import PlannedInterpolator
from nurbsmotion.loop import simulate
from nurbsmotion.machine import Axis, die_bonder
from nurbsmotion.paths.random_paths import FAMILIES, random_path
from nurbsmotion.planning import sampled_stop_bound, speed_profile, time_optimal_bound
from nurbsmotion.servo import ServoPlant
from planner_eval import HOLD, settle_time  # the same settle time (1 pulse) as the tables

SEED = 10
CONDITIONS = ("nominal", "box", "gains x2")


def machine_for(n_axes: int, gains: float = 1.0):
    """The die-bonder with ``n_axes`` axes (z a copy of x), Kp and Kd times ``gains``."""
    base = die_bonder()
    axes = base.axes + ((Axis("z", *_axis_numbers(base.axes[0])),) if n_axes == 3 else ())
    axes = tuple(Axis(a.name, a.time_constant, a.electrical_gain, a.mechanical_gain,
                      a.position_gain * gains, a.speed_gain * gains) for a in axes)
    return base.with_options(axes=axes)


def _axis_numbers(a):
    return a.time_constant, a.electrical_gain, a.mechanical_gain, a.position_gain, a.speed_gain


def _draw(i: int):
    """Case ``i``'s row (family, axes, feed, condition), random path (None where the
    draw is not a valid curve: the row says so), machine, and its generator (the box
    condition draws the plant from it next)."""
    rng = np.random.default_rng([SEED, i])
    families = sorted(FAMILIES)
    family = families[i % len(families)]
    n_axes = int(rng.integers(2, 4))
    feed = float(np.exp(rng.uniform(np.log(5e4), np.log(3e6))))
    condition = CONDITIONS[(i // len(families)) % len(CONDITIONS)]
    row = {"case": i, "family": family, "n_axes": n_axes, "feed": feed,
           "condition": condition, "status": "ran"}
    try:
        curve = random_path(family, [SEED, i], n_axes=n_axes)
    except InvalidCurveError:
        row["status"] = "invalid path"
        return row, None, None, rng
    return row, curve, machine_for(n_axes, 2.0 if condition == "gains x2" else 1.0), rng


def one_case(i: int) -> dict:
    row, curve, m, rng = _draw(i)
    if curve is None:
        return row
    condition, feed, n_axes = row["condition"], row["feed"], row["n_axes"]
    plant = None
    if condition == "box":
        plant = ServoPlant.of_machine(m, curve(0.0),
                                      time_constant_scale=rng.uniform(0.8, 1.2, n_axes),
                                      electrical_gain_scale=rng.uniform(0.8, 1.2, n_axes))
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        interp = PlannedInterpolator(curve, m, feed)
        planning = time.perf_counter() - t0
        planning_cpu = time.process_time() - c0
        bound = time_optimal_bound(curve, m, feed)
    except NurbsmotionError as exc:
        row["status"] = "refused"
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    tr = simulate(interp, m, plant=plant, settle_time=HOLD)
    st = settle_time(tr, curve(1.0))
    metrics = tr.metrics()
    row.update(
        bound=bound, settle=st, planning=planning, planning_cpu=planning_cpu,
        end_overshoot=metrics.end_overshoot, corner_overshoot=metrics.corner_overshoot,
        saturated=int(np.count_nonzero(np.abs(tr.drive) > m.max_drive * (1 + 1e-9))),
        nan=not (np.all(np.isfinite(tr.position_command)) and np.all(np.isfinite(tr.drive))),
        monotone=bool(np.all(np.diff(tr.u) >= 0)),
        at_rest=bool(np.isfinite(st)),
        contour=metrics.max_contour_error,
    )
    allowance = max(0.05 * bound, 3e-3)
    row["settle_ok"] = bool(st - bound <= allowance)
    # No sampled motion that stops at the corners meets the target when even its lower
    # bound misses it (sampled_stop_bound: whole samples per piece).
    row["sampled_bound"] = sampled_stop_bound(curve, m)
    row["reachable"] = bool(row["sampled_bound"] - bound <= allowance)
    row["piece_estimate"] = piece_estimate(curve, m, feed)
    row["within_estimate"] = bool(row["piece_estimate"] - bound <= allowance)
    return row


def plan_only_case(i: int) -> dict:
    """Case ``i`` (as :func:`one_case` draws it) planned only: planning time [s], the
    plan's arrival [s], the bound and the sampled bound [s], and the path's length
    [pulse]."""
    row, curve, m, _ = _draw(i)
    if curve is None:
        return row
    feed = row["feed"]
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        interp = PlannedInterpolator(curve, m, feed)
        row["planning"] = time.perf_counter() - t0
        row["planning_cpu"] = time.process_time() - c0
        row["bound"] = time_optimal_bound(curve, m, feed)
    except NurbsmotionError as exc:
        row["status"] = "refused"
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    row["arrival"] = interp.plan.rest * m.sample_period
    row["shorten_status"] = interp.shorten_status
    row["sampled_bound"] = sampled_stop_bound(curve, m)
    row["length"] = curve.length
    return row


def bounds_case(i: int) -> dict:
    """Case ``i`` (as :func:`one_case` draws it): its bound and sampled bound [s] only, and
    whether the target max(5 %, 3 ms) over the bound is reachable (as :func:`one_case`)."""
    row, curve, m, _ = _draw(i)
    if curve is None:
        return row
    try:
        bound = time_optimal_bound(curve, m, row["feed"])
    except NurbsmotionError as exc:
        row["status"] = "refused"
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    row.update(bound=bound, sampled_bound=sampled_stop_bound(curve, m))
    row["reachable"] = bool(row["sampled_bound"] - bound <= max(0.05 * bound, 3e-3))
    return row


def report_bounds_only(rows: list) -> None:
    ran = [r for r in rows if r["status"] == "ran"]
    print(f"cases {len(rows)}: bounded {len(ran)}, refused "
          f"{sum(r['status'] == 'refused' for r in rows)}, invalid paths "
          f"{sum(r['status'] == 'invalid path' for r in rows)}")
    print("\n| condition | cases | unreachable (sampled bound misses it) "
          "| sampled bound / bound median / 95 % / max |\n|---|---|---|---|")
    for cond in CONDITIONS:
        rs = [r for r in ran if r["condition"] == cond]
        if rs:
            unreachable = sum(not r["reachable"] for r in rs)
            print(f"| {cond} | {len(rs)} | {unreachable} ({unreachable / len(rs) * 100:.1f} %) | "
                  f"{_common.spread([r['sampled_bound'] / r['bound'] for r in rs])} |")


def report_plan_only(rows: list) -> None:
    ran = [r for r in rows if r["status"] == "ran"]
    times = np.array([r["planning"] for r in ran])
    print(f"cases {len(rows)}: planned {len(ran)}, refused "
          f"{sum(r['status'] == 'refused' for r in rows)}, invalid paths "
          f"{sum(r['status'] == 'invalid path' for r in rows)}")
    cpu = np.array([r["planning_cpu"] for r in ran])
    print(f"planning [s] median / 95 % / max: wall {_common.spread(times)}, CPU "
          f"{_common.spread(cpu)} (the CPU time is the wall time of an unloaded core); "
          f"CPU over 0.3 s: {int(np.sum(cpu > 0.3))}, over 2 s: {int(np.sum(cpu > 2))}")
    nominal = [r for r in ran if r["condition"] == "nominal"]
    ok = [r["arrival"] - r["bound"] <= max(0.05 * r["bound"], 3e-3) for r in nominal]
    short = [o for o, r in zip(ok, nominal) if r["bound"] < 0.05]
    print(f"nominal plans arriving within max(5 %, 3 ms) of the bound: "
          f"{np.mean(ok) * 100:.1f} % of {len(ok)}; of those whose bound is under 50 ms "
          f"{np.mean(short) * 100:.1f} % of {len(short)}")
    print("nominal plans beyond it (case, family, axes, feed [m/s], bound, sampled bound, "
          "arrival [ms], step 6):")
    for o, r in zip(ok, nominal):
        if not o:
            print(f"  case {r['case']} {r['family']} {r['n_axes']} {r['feed'] / 1e6:.3g} "
                  f"{r['bound'] * 1e3:.1f} {r['sampled_bound'] * 1e3:.0f} "
                  f"{r['arrival'] * 1e3:.0f} {r.get('shorten_status', '-')}")
    below = [r for r in ran if r["arrival"] < r["sampled_bound"] - 1e-9]
    print(f"plans arriving before the sampled bound: {len(below)}")
    budget = [r for r in ran if r.get("shorten_status") == "work budget"]
    print(f"plans whose step 6 stopped at its work budget (shorten_work): {len(budget)}")
    if os.environ.get("PLANNER_SWEEP_REFERENCE"):   # a log of the same cases, another tree
        import json
        with open(os.environ["PLANNER_SWEEP_REFERENCE"]) as f:
            ref = {r["case"]: r for r in map(json.loads, f) if r["status"] == "ran"}
        Ts = die_bonder().sample_period
        later = [(r["case"], round((r["arrival"] - ref[r["case"]]["arrival"]) / Ts))
                 for r in ran if r["case"] in ref]
        moved = [(c, d) for c, d in later if d != 0]
        print(f"arrival against the reference, of {len(later)} cases: {len(moved)} differ "
              f"(case, samples later): {moved}")
    print("slowest plans:")
    for r in sorted(ran, key=lambda r: r["planning_cpu"])[-12:]:
        print(f"  case {r['case']} {r['family']} {r['n_axes']} axes {r['condition']}, "
              f"{r['length'] / 1e3:.3g} mm at {r['feed'] / 1e6:.3g} m/s: "
              f"{r['planning']:.2f} s ({r['planning_cpu']:.2f} s CPU), arrival {r['arrival'] * 1e3:.0f} ms, "
              f"bound {r['bound'] * 1e3:.1f} ms")


def piece_estimate(curve, m, feed) -> float:
    """Every corner-free piece's continuous time-optimal duration (SPEC section 9, the
    bound's own grid) rounded up to whole samples [s]; ``planned`` moves from sample 0.

    A motion *on* the path that stops at the corners takes at least this: each piece is a
    rest-to-rest motion under the bound's constraints (a held drive within Umax meets
    them), and it rests at its corner at a sample instant. Not a bound for a motion that
    may leave the path by ``path_tolerance`` (it may cut a turn) or settle within the
    window before the end; the piece times are taken 0.1 % short, the grid's accuracy
    (:func:`~nurbsmotion.planning.time_optimal_bound`)."""
    grid = inspect.signature(time_optimal_bound).parameters["grid_size"].default
    Ts = m.sample_period
    pieces = speed_profile(curve, m, feed, grid_size=grid).piece_times()
    return Ts * sum(math.ceil(t[-1] * (1 - 1e-3) / Ts) for t in pieces)


def report(rows: list) -> None:
    ran = [r for r in rows if r["status"] == "ran"]
    print(f"cases {len(rows)}: ran {len(ran)}, refused "
          f"{sum(r['status'] == 'refused' for r in rows)}, invalid paths (the curve class "
          f"refuses them) {sum(r['status'] == 'invalid path' for r in rows)}")
    for r in rows:
        if r["status"] == "refused":
            print(f"  refused case {r['case']} ({r['family']}, {r['feed'] / 1e6:.3g} m/s): "
                  f"{r['error'][:160]}")
    print("\n| condition | runs | saturated runs | NaN | parameter not monotone | not at rest "
          "| settle - bound within max(5 %, 3 ms) | unreachable (sampled bound misses it) "
          "| beyond the per-piece estimate "
          "| settle / bound median / 95 % / max "
          "| max contour [um] median / 95 % / max | passes the end / a stop corner by > 1 um "
          "| planning CPU [s] median / 95 % / max |"
          "\n|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for cond in CONDITIONS:
        rs = [r for r in ran if r["condition"] == cond]
        if not rs:
            continue
        ratio = np.array([r["settle"] / r["bound"] for r in rs])
        ce = np.array([r["contour"] for r in rs])
        unreachable = sum(not r["reachable"] for r in rs)
        beyond = sum(not r["within_estimate"] for r in rs)
        print(f"| {cond} | {len(rs)} | {sum(r['saturated'] > 0 for r in rs)} | "
              f"{sum(r['nan'] for r in rs)} | {sum(not r['monotone'] for r in rs)} | "
              f"{sum(not r['at_rest'] for r in rs)} | "
              f"{np.mean([r['settle_ok'] for r in rs]) * 100:.1f} % | "
              f"{unreachable} ({unreachable / len(rs) * 100:.1f} %) | "
              f"{beyond} ({beyond / len(rs) * 100:.1f} %) | "
              f"{_common.spread(ratio)} | {_common.spread(ce)} | "
              f"{sum(r['end_overshoot'] > 1 for r in rs)} / "
              f"{sum(r['corner_overshoot'] > 1 for r in rs)} | "
              f"{_common.spread([r['planning_cpu'] for r in rs])} |")
    nominal = [r for r in ran if r["condition"] == "nominal"]
    if nominal:
        reachable = [r for r in nominal if r["reachable"]]
        estimated = [r for r in nominal if r["within_estimate"]]
        print(f"\nnominal: the target is reachable in at most "
              f"{len(reachable) / len(nominal) * 100:.1f} % of the cases; `planned` meets it in "
              f"{np.mean([r['settle_ok'] for r in reachable]) * 100:.1f} % of those. "
              f"A motion on the path meets it in at most {len(estimated) / len(nominal) * 100:.1f}"
              f" % (the per-piece estimate); `planned` meets it in "
              f"{np.mean([r['settle_ok'] for r in estimated]) * 100:.1f} % of those, and in "
              f"{sum(r['settle_ok'] for r in nominal if not r['within_estimate'])} beyond it")
    below = [r for r in ran if r["settle"] < r["sampled_bound"] - 1e-9]
    print(f"\nruns settling before the sampled bound (it would not be a bound): {len(below)}"
          + "".join(f"; case {r['case']} {r['settle']:.4g} s < {r['sampled_bound']:.4g} s"
                    for r in below[:5]))
    worst = sorted((r for r in ran if r["condition"] == "nominal"),
                   key=lambda r: r["settle"] / r["bound"])[-5:]
    print("\nslowest nominal cases (settle / bound):",
          ", ".join(f"{r['case']} {r['family']} {r['feed'] / 1e6:.3g} m/s "
                    f"{r['settle'] / r['bound']:.3g}" for r in worst))


def _warm_up() -> None:
    """Plan case 0 once, untimed, before the sweep: the first plan of a process loads
    numba's compiled kernels from their cache (about 1 s of CPU), and in a fresh checkout
    compiles them first (13.5 s of CPU measured on case 0 of a new worktree), which is
    the cost of the process, not of planning that case."""
    _, curve, m, _ = _draw(0)
    if curve is not None:
        PlannedInterpolator(curve, m, _draw(0)[0]["feed"])


def main():
    n = int(os.environ.get("PLANNER_SWEEP_CASES", "1000"))
    plan_only = os.environ.get("PLANNER_SWEEP_PLAN_ONLY", "") not in ("", "0")
    bounds_only = os.environ.get("PLANNER_SWEEP_BOUNDS_ONLY", "") not in ("", "0")
    case, show = ((bounds_case, report_bounds_only) if bounds_only else
                  (plan_only_case, report_plan_only) if plan_only else (one_case, report))
    if os.environ.get("PLANNER_SWEEP_REPORT"):   # the report of a PLANNER_SWEEP_LOG so far
        import json
        with open(os.environ["PLANNER_SWEEP_REPORT"]) as f:
            rows = [json.loads(line) for line in f][:n]
        show(rows)
        return
    if not bounds_only:
        _warm_up()
    t0 = time.perf_counter()
    rows = []
    log = os.environ.get("PLANNER_SWEEP_LOG")   # one JSON row a line, as each case ends
    first = int(os.environ.get("PLANNER_SWEEP_FIRST", "0"))   # a later part of the sweep
    for i in range(first, first + n):
        rows.append(case(i))
        if log:
            import json
            with open(log, "a") as f:
                f.write(json.dumps(rows[-1], default=float) + "\n")
        if (i + 1 - first) % 50 == 0:
            print(f"  {i + 1} cases, {time.perf_counter() - t0:.0f} s", flush=True)
    show(rows)
    if os.environ.get("PLANNER_SWEEP_JSON"):   # every row, for a closer look
        import json
        with open(os.environ["PLANNER_SWEEP_JSON"], "w") as f:
            json.dump(rows, f, indent=0, default=float)
    print(f"(wall time {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
