"""Batch NURBS evaluation: point, first and second derivative at 10^6 parameters.

What is measured, exactly: the butterfly (cubic, 2 axes, rational, 51 control points)
evaluated at the same 10^6 seeded uniform random parameters (unsorted) by

- ``NurbsCurve.derivatives(u, 2)``: the library's compiled kernels, one thread, span search
  by bisection, basis derivatives by A2.3 and the rational quotient by A4.2 per parameter
  (the arithmetic every planner and metric of the library uses; a faster route that
  changed the last bits would change the runs);
- its scipy reference route (``BSpline`` in homogeneous coordinates, then A4.2);
- geomdl (PyPI ``geomdl``, pure Python, ``Curve.derivatives(u, order=2)`` per parameter;
  a benchmark-only dependency, ``pip install geomdl``).

The three must agree within 1e-9 relative. The ratio to geomdl is of process CPU time
(user + system of this process), each evaluator timed in alternating rounds (ours, geomdl,
ours, ...): wall time on a shared machine depends on what else runs, and other processes
slow the two evaluators differently (the ratio in wall time has been 66x-154x on this
2-core machine from one load to another).

    python benchmarks/nurbs_eval.py
"""

from __future__ import annotations

import os
import statistics
import time

import _common  # noqa: F401  (puts src/ on the path)
from _common import section

N_PARAMETERS = 1_000_000


def geomdl_curve(curve):
    from geomdl import NURBS

    g = NURBS.Curve()
    g.degree = curve.degree
    g.ctrlpts = curve.control_points.tolist()
    g.weights = curve.weights.tolist()
    g.knotvector = curve.knots.tolist()
    return g


def cpu_time(fn) -> float:
    """Process CPU time (user + system) of one call of ``fn()`` [s]."""
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def main(repeats: int = 7, geomdl_repeats: int = 3) -> str:
    import numpy as np

    import nurbsmotion as nm

    curve = nm.make_butterfly()
    u = np.random.default_rng(2026).uniform(0.0, 1.0, N_PARAMETERS)
    ours = curve.derivatives(u, 2)  # and a warm-up of the kernels
    reference = curve._derivatives_reference(u, 2)
    ours_t = [cpu_time(lambda: curve.derivatives(u, 2)) for _ in range(repeats)]
    scipy_t = statistics.median(cpu_time(lambda: curve._derivatives_reference(u, 2))
                                for _ in range(repeats))

    def rel_error(other):
        return max(float(np.max(np.abs(other[k] - ours[k])) / np.max(np.abs(ours[k])))
                   for k in range(3))

    rows = []
    try:
        g = geomdl_curve(curve)
    except ImportError:
        geomdl_row = ["geomdl", "not installed (pip install geomdl)", "", "", ""]
    else:
        result = {}

        def run_geomdl():
            result["d"] = np.array([g.derivatives(x, order=2) for x in u.tolist()])

        geo_t = []
        for _ in range(geomdl_repeats):  # alternating rounds: the same load on both
            geo_t.append(cpu_time(run_geomdl))
            ours_t += [cpu_time(lambda: curve.derivatives(u, 2)) for _ in range(2)]
        geo = np.transpose(result["d"], (1, 0, 2))
        err = rel_error(geo)
        geo_med = statistics.median(geo_t)
        geomdl_row = [f"geomdl {__import__('geomdl').__version__}", f"{geo_med:.3f}",
                      f"{geo_med / u.size * 1e9:.0f}",
                      f"**{geo_med / statistics.median(ours_t):.0f}x**",
                      f"{err:.1e} ({'within' if err <= 1e-9 else 'NOT within'} 1e-9)"]
    ours_med = statistics.median(ours_t)
    rows.append(["nurbsmotion (compiled kernels, 1 thread)", f"{ours_med:.3f}",
                 f"{ours_med / u.size * 1e9:.0f}", "1x", "-"])
    rows.append(["scipy BSpline route (the reference)", f"{scipy_t:.3f}",
                 f"{scipy_t / u.size * 1e9:.0f}", f"{scipy_t / ours_med:.1f}x",
                 f"{rel_error(reference):.1e}"])
    rows.append(geomdl_row)
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return section(
        f"Batch evaluation, point + 1st + 2nd derivative, cubic, 2 axes, {N_PARAMETERS:,} "
        "random parameters (butterfly)",
        ["evaluator", "CPU time [s]", "per parameter [ns]", "CPU time / ours",
         "max relative difference to ours"], rows,
        f"Process CPU time (user + system), medians of {len(ours_t)} runs (ours, in "
        f"rounds alternating with geomdl's), {repeats} (scipy) and {geomdl_repeats} "
        "(geomdl); relative difference per derivative order, to the largest value of that "
        f"order. Load average at the end: {load}.")


if __name__ == "__main__":
    main()
