"""Batch NURBS evaluation: point, first and second derivative at 10^6 parameters.

The butterfly (cubic, 2 axes, rational) evaluated by ``NurbsCurve.derivatives(u, 2)`` (the
compiled kernels), by its scipy reference route, and by geomdl (PyPI ``geomdl``, pure
Python, ``Curve.derivatives(u, order=2)`` per parameter; a benchmark-only dependency), in
the same run, on the same seeded parameters; all three must agree within 1e-9 relative.

    python benchmarks/nurbs_eval.py
"""

from __future__ import annotations

import _common  # noqa: F401  (puts src/ on the path)
from _common import median_time, section

N_PARAMETERS = 1_000_000


def geomdl_curve(curve):
    from geomdl import NURBS

    g = NURBS.Curve()
    g.degree = curve.degree
    g.ctrlpts = curve.control_points.tolist()
    g.weights = curve.weights.tolist()
    g.knotvector = curve.knots.tolist()
    return g


def main(repeats: int = 7, geomdl_repeats: int = 3) -> str:
    import numpy as np

    import nurbsmotion as nm

    curve = nm.make_butterfly()
    u = np.random.default_rng(2026).uniform(0.0, 1.0, N_PARAMETERS)
    ours_t, _ = median_time(lambda: curve.derivatives(u, 2), repeats)
    scipy_t, _ = median_time(lambda: curve._derivatives_reference(u, 2), repeats)
    ours = curve.derivatives(u, 2)
    reference = curve._derivatives_reference(u, 2)
    rows = [["nurbsmotion (compiled kernels)", f"{ours_t:.3f}", f"{ours_t / u.size * 1e9:.0f}",
             "1x", "-"]]

    def rel_error(other):
        return max(float(np.max(np.abs(other[k] - ours[k])) / np.max(np.abs(ours[k])))
                   for k in range(3))

    rows.append(["scipy BSpline route (the reference)", f"{scipy_t:.3f}",
                 f"{scipy_t / u.size * 1e9:.0f}", f"{scipy_t / ours_t:.1f}x",
                 f"{rel_error(reference):.1e}"])
    try:
        g = geomdl_curve(curve)
    except ImportError:
        rows.append(["geomdl", "not installed (pip install geomdl)", "", "", ""])
    else:
        result = {}

        def run_geomdl():
            result["d"] = np.array([g.derivatives(x, order=2) for x in u.tolist()])

        geo_t, _ = median_time(run_geomdl, geomdl_repeats, warmup=0)
        geo = np.transpose(result["d"], (1, 0, 2))
        err = rel_error(geo)
        rows.append([f"geomdl {__import__('geomdl').__version__}", f"{geo_t:.3f}",
                     f"{geo_t / u.size * 1e9:.0f}", f"**{geo_t / ours_t:.0f}x**",
                     f"{err:.1e} ({'within' if err <= 1e-9 else 'NOT within'} 1e-9)"])
    return section(
        f"Batch evaluation, point + 1st + 2nd derivative, cubic, 2 axes, {N_PARAMETERS:,} "
        "parameters (butterfly)",
        ["evaluator", "time [s]", "per parameter [ns]", "time / ours",
         "max relative difference to ours"], rows,
        f"Medians of {repeats} runs (ours, scipy) and {geomdl_repeats} (geomdl); relative "
        "difference per derivative order, to the largest value of that order.")


if __name__ == "__main__":
    main()
