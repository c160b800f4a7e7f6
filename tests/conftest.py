"""Shared tolerance tiers, hypothesis profile and curve generators for the test suite.

Tolerance tiers (relative unless a test says otherwise)
-------------------------------------------------------
EXACT : 1e-12
    Closed-form results that only suffer rounding: the rational circle's radius and
    curvature, end points, identities between two evaluations of the same spline.
TIGHT : 1e-9
    Results of a numerical algorithm with its own tolerance: arc length (adaptive Gauss
    against scipy ``quad``), inverse arc length, continuity across knots.
FD : 1e-6
    Derivatives against fourth-order finite differences.

Hypothesis
----------
The ``nurbsmotion`` profile bounds ``max_examples`` so the whole suite stays fast; set
``NURBSMOTION_HYPOTHESIS_EXAMPLES`` (and ``NURBSMOTION_RANDOM_SWEEPS`` for the seeded numpy
sweeps) to run more.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, assume, note, settings
from hypothesis import strategies as st

from nurbsmotion import InvalidCurveError, NurbsCurve

EXACT = 1e-12
TIGHT = 1e-9
FD = 1e-6

HYPOTHESIS_EXAMPLES = int(os.environ.get("NURBSMOTION_HYPOTHESIS_EXAMPLES", "30"))
RANDOM_SWEEPS = int(os.environ.get("NURBSMOTION_RANDOM_SWEEPS", "1"))

settings.register_profile(
    "nurbsmotion",
    max_examples=HYPOTHESIS_EXAMPLES,
    deadline=None,
    derandomize=True,  # seeded, like the numpy sweeps: the same examples on every run
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
settings.load_profile("nurbsmotion")

SRC = Path(__file__).resolve().parents[1] / "src"


def source_env(**extra: str) -> dict:
    """The environment of a child Python that imports this checkout's nurbsmotion."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(SRC)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    env.update(extra)
    return env


def interrupt_command(argv: list[str], ready, env: dict | None = None) -> tuple[int, str]:
    """Run ``python -m nurbsmotion *argv`` in a child process, send it SIGINT (Ctrl-C) as soon as
    ``ready()`` is true (polled; also if the child has ended first), and return its exit
    code and stderr."""
    proc = subprocess.Popen([sys.executable, "-m", "nurbsmotion", *argv],
                            env=source_env() if env is None else env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        while proc.poll() is None and not ready():
            time.sleep(0.01)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, err


def clamped_knots(degree: int, interior: np.ndarray, multiplicities, domain=(0.0, 1.0)):
    """Clamped knot vector: ``degree + 1`` copies of each end, ``interior`` values repeated."""
    a, b = domain
    inner = np.repeat(np.asarray(interior, dtype=float), np.asarray(multiplicities, dtype=int))
    return np.concatenate([np.full(degree + 1, a), inner, np.full(degree + 1, b)])


def random_clamped_knots(rng: np.random.Generator, degree: int, max_interior: int = 4):
    """Random clamped knots on [0, 1]; interior values at least 0.05 apart, with
    multiplicities in ``1 .. max(1, degree - 1)`` (so the curve stays at least C1 for
    ``degree >= 2``)."""
    k = int(rng.integers(0, max_interior + 1))
    interior = np.sort(rng.choice(np.arange(1, 20), size=k, replace=False)) / 20.0
    mult = rng.integers(1, max(1, degree - 1) + 1, size=k)
    return clamped_knots(degree, interior, mult)


def random_points(rng: np.random.Generator, n: int, n_axes: int, spread: float = 10.0):
    """Random control points, shape (n, n_axes), in [-spread, spread]. With one axis they
    increase (positive steps): a one-axis path that reverses has C'(u) = 0 there, which
    the constructor rejects (variation diminishing keeps a monotone polygon's curve
    monotone)."""
    if n_axes == 1:
        steps = rng.uniform(0.2, 1.0, size=(n, 1))
        return -spread + 2 * spread * np.cumsum(steps, axis=0) / np.sum(steps)
    return rng.uniform(-spread, spread, size=(n, n_axes))


@st.composite
def curves(draw, max_degree: int = 5, max_axes: int = 4, rational: bool = True):
    """Valid clamped NURBS curves: degree 1..5, 1..4 axes, weights in [0.2, 5], interior
    knots on a 1/40 grid with multiplicities up to ``max(1, p - 1)``.

    Control points lie on an integer grid so that nearly coincident points (which make
    ``C'`` vanish to rounding) are not generated; curves the constructor rejects as
    degenerate are filtered out.
    """
    p = draw(st.integers(1, max_degree))
    n_axes = draw(st.integers(1, max_axes))
    interior = draw(st.lists(st.integers(1, 39), max_size=4, unique=True).map(sorted))
    mult = [draw(st.integers(1, max(1, p - 1))) for _ in interior]
    knots = clamped_knots(p, np.array(interior) / 40.0, mult)
    n = len(knots) - p - 1
    coords = st.integers(-20, 20).map(float)
    if n_axes == 1:  # monotone, see random_points
        P = np.cumsum(draw(st.lists(st.integers(1, 9).map(float), min_size=n, max_size=n)))
        P = P[:, None] - 20.0
    else:
        P = np.array(draw(st.lists(st.lists(coords, min_size=n_axes, max_size=n_axes),
                                   min_size=n, max_size=n)))
    if rational:
        w = np.array(draw(st.lists(st.floats(0.2, 5.0), min_size=n, max_size=n)))
    else:
        w = None
    note(f"curve: NurbsCurve({p}, {knots.tolist()}, {P.tolist()}, "
         f"{None if w is None else w.tolist()})")
    try:
        return NurbsCurve(p, knots, P, w)
    except InvalidCurveError as exc:
        assume("degenerate" not in str(exc))
        raise


def span_interiors(curve: NurbsCurve, fractions=(0.2, 0.5, 0.8)) -> np.ndarray:
    """Parameters strictly inside every knot span, at the given fractions of each span."""
    bp = curve.breakpoints
    f = np.asarray(fractions)
    return (bp[:-1, None] + np.diff(bp)[:, None] * f[None, :]).ravel()
