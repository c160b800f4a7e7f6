"""G2/G3 spirals and helices (PieceChain.add_spiral) against the exact LinuxCNC spiral:
angle a0 -> a0 + sweep, radius and the other coordinates linear in the angle."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from conftest import RANDOM_SWEEPS
from nurbsmotion.paths.pieces import (HELIX_TOLERANCE, PieceChain, arc_angle_deviation,
                                      spiral_segments)


def spiral(center, r0, r1, a0, sweep, rise=0.0):
    """The joined curve of one spiral piece, and the exact spiral's point at the angle of
    each of dense samples of it (in the XY plane, Z rising linearly when ``rise``)."""
    d = 3 if rise else 2
    start = [center[0] + r0 * math.cos(a0), center[1] + r0 * math.sin(a0)] + [0.0] * (d - 2)
    end = [center[0] + r1 * math.cos(a0 + sweep), center[1] + r1 * math.sin(a0 + sweep)] + [rise] * (d - 2)
    chain = PieceChain(start)
    chain.add_spiral(end, (0, 1), center, r0, r1, a0, sweep, 1.0)
    curve, _ = chain.build()
    X = curve(np.linspace(0.0, 1.0, 200_001))
    angle = np.unwrap(np.arctan2(X[:, 1] - center[1], X[:, 0] - center[0]))
    angle += a0 - angle[0]
    f = (angle - a0) / sweep
    radius = r0 + (r1 - r0) * f
    exact = np.column_stack([center[0] + radius * np.cos(angle), center[1] + radius * np.sin(angle)]
                            + ([rise * f] if rise else []))
    return curve, X, exact, angle, np.array(end)


CASES = {  # center, r0, r1, a0, sweep, rise
    "rounded half circle (CAM post)": ((0.5, 0.0), 0.5, 0.50008, math.pi, -math.pi, 0.0),
    "spiral at 0.1 % of the radius": ((3.0, 1.0), 100.0, 100.1, 0.3, 2 * math.pi * 0.9, 0.0),
    "spiral at LinuxCNC's tolerance": ((0.0, 0.0), 10.0, 10.028, 1.0, -5.0, 0.0),
    "shallow helix, two turns": ((0.0, 0.0), 5.0, 5.0, 0.0, 4 * math.pi, 0.01),
    "steep helix (thread)": ((0.0, 0.0), 1.0, 1.0, 0.0, 2 * math.pi, 10.0),
    "short spiral": ((0.0, 0.0), 2.0, 2.001, 0.0, 0.01, 0.0),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_spiral_is_within_tolerance_of_the_exact_spiral(name):
    center, r0, r1, a0, sweep, rise = CASES[name]
    curve, X, exact, angle, end = spiral(center, r0, r1, a0, sweep, rise)
    err = np.linalg.norm(X - exact, axis=1)
    assert np.max(err) <= HELIX_TOLERANCE * min(r0, r1)
    assert np.all(np.diff(angle) * np.sign(sweep) > 0)  # the angle runs one way
    assert np.array_equal(X[-1], end)  # ends exactly on the programmed point
    assert curve.degree == 3


def test_rounded_arcs_take_few_rational_segments_and_steep_helices_hermite():
    count, rational = spiral_segments(np.array([math.pi, 2 * math.pi]), np.array([0.5, 1.0]),
                                      np.array([0.50008, 1.0]), np.array([0.0, 10.0]))
    assert rational.tolist() == [True, False]
    hermite = np.ceil(np.array([math.pi, 2 * math.pi]) / (384 * HELIX_TOLERANCE) ** 0.25)
    assert count[0] < hermite[0] / 5 and count[1] == hermite[1]


def test_arc_angle_deviation_against_the_rational_arc():
    # the angle of the rational quadratic arc (weights 1, cos(phi/2), 1), sampled
    u = np.linspace(0.0, 1.0, 100_001)
    for phi in (math.pi / 2, 0.3, 0.01):
        w = math.cos(phi / 2)
        B = np.array([(1 - u) ** 2, 2 * u * (1 - u) * w, u ** 2])
        pts = np.array([[1.0, 0.0], [1.0, math.tan(phi / 2)], [math.cos(phi), math.sin(phi)]])
        X = (B.T @ pts) / B.sum(axis=0)[:, None]
        sampled = np.max(np.abs(np.arctan2(X[:, 1], X[:, 0]) - phi * u))
        assert arc_angle_deviation(phi) == pytest.approx(sampled, rel=1e-6)
        assert arc_angle_deviation(phi) == pytest.approx(phi ** 3 / 249.4, rel=0.05)


def test_random_spirals_are_within_tolerance():
    rng = random.Random(3)
    for _ in range(6 * RANDOM_SWEEPS):
        r0 = 10 ** rng.uniform(-2, 2)
        r1 = r0 * (1 + rng.choice([-1, 1]) * 10 ** rng.uniform(-8, -3))
        sweep = rng.choice([-1, 1]) * rng.uniform(0.01, 4 * math.pi)
        rise = rng.choice([0.0, r0 * 10 ** rng.uniform(-4, 1)])
        center = (rng.uniform(-50, 50), rng.uniform(-50, 50))
        _, X, exact, _, _ = spiral(center, r0, r1, rng.uniform(-3, 3), sweep, rise)
        err = np.max(np.linalg.norm(X - exact, axis=1))
        assert err <= HELIX_TOLERANCE * min(r0, r1), (r0, r1, sweep, rise)
