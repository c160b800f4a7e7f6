"""Seeded random NURBS curves for the compiled-versus-reference sweeps.

``NURBSMOTION_RANDOM_CASES`` raises the number of curves a sweep draws.
"""

import os

import numpy as np

import nurbsmotion as nm

N_CASES = int(os.environ.get("NURBSMOTION_RANDOM_CASES", "12"))


def random_curve(rng: np.random.Generator, scale: float = 1.0) -> nm.NurbsCurve:
    """A clamped NURBS of degree 1-5 in 1-4 axes, interior knots of multiplicity up to p
    (full multiplicity makes sharp corners), weights in [0.3, 4]."""
    while True:
        p = int(rng.integers(1, 6))
        n_axes = int(rng.integers(1, 5))
        n_distinct = int(rng.integers(0, 5))
        interior = np.sort(rng.uniform(0.05, 0.95, n_distinct))
        mult = rng.integers(1, p + 1, n_distinct)
        inner = np.repeat(interior, mult)
        knots = np.concatenate([np.zeros(p + 1), inner, np.ones(p + 1)])
        n = len(knots) - p - 1
        points = scale * np.cumsum(rng.normal(size=(n, n_axes)), axis=0)
        weights = rng.uniform(0.3, 4.0, n)
        try:
            return nm.NurbsCurve(p, knots * rng.uniform(0.5, 3.0), points, weights)
        except nm.InvalidCurveError:
            continue
