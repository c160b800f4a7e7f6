"""What the controller reads of the plant stage: the tool's and the encoder mass's
positions, seeded Gaussian noise (a counter-based generator) and whole encoder counts
(the model: :mod:`nurbsmotion.plant`).

Glossary
--------
See :mod:`nurbsmotion.plant`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .two_mass import ENC, KE, TOOL

__all__ = ["noise_draw", "positions", "measure"]

@njit(cache=True, inline="always")
def _mix(z):
    """splitmix64's finaliser."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def noise_draw(seed, k, j):
    """A standard normal draw for sample k, axis j (Box-Muller on two splitmix64 words)."""
    base = (np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15)
            + np.uint64(k) * np.uint64(64) + np.uint64(2 * j))
    a = _mix(base + np.uint64(1))
    b = _mix(base + np.uint64(2))
    u1 = ((a >> np.uint64(11)) + np.uint64(1)) * (1.0 / 9007199254740993.0)
    u2 = (b >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@njit(cache=True, inline="always")
def positions(P, X, j):
    """``(tool, encoder, encoder_speed)`` of axis j (``P``, ``X``: the stage's ``param``
    and the state's ``x``): the load's and the encoder mass's true positions [pulse] and
    the encoder mass's speed [rad/s]."""
    tool = X[j, 1] + P[j, TOOL] * X[j, 2]
    enc = X[j, 1] + P[j, ENC] * X[j, 2]
    return tool, enc, X[j, 0] + P[j, ENC] * X[j, 3] / P[j, KE]


@njit(cache=True, inline="always")
def measure(noise, seed, counts, true_position, start, k, j):
    """What the controller reads of a true position [pulse] at sample k, axis j: with
    Gaussian noise of standard deviation ``noise`` [pulse] (seeded by ``seed``), in whole
    counts from ``start`` [pulse] if ``counts``."""
    m = true_position
    if noise > 0.0:
        m = m + noise * noise_draw(seed, k, j)
    if counts:
        m = start + math.floor(m - start)
    return m
