"""The planned motion's sampling (issue 13 item 4): the streamed, compiled time profile and
arc-length inverse of :mod:`nurbsmotion.motion_plan` against the fine-grid numpy
computation they replace and against the arc-length table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nurbsmotion import motion_plan as mp
from nurbsmotion.loop import to_pulses
from nurbsmotion.machine import die_bonder
from nurbsmotion.nurbs import builtin_path
from nurbsmotion.planning import speed_profile


def _fine_grid_reference(s, V, t, h, passes, width):
    """The whole fine grid as numpy arrays (the computation before the streamed kernel):
    constant acceleration between grid points, ``passes`` moving averages by cumulative
    sums, the last point on the piece's end. Returns (times, values)."""
    n_fine = int(math.ceil(t[-1] / h)) + 1
    tf = np.arange(n_fine) * h
    i = np.clip(np.searchsorted(t, tf, side="right") - 1, 0, len(t) - 2)
    ds = s[i + 1] - s[i]
    with np.errstate(divide="ignore", invalid="ignore"):
        acc = np.where(ds > 0, (V[i + 1] ** 2 - V[i] ** 2) / (2 * ds), 0.0)
    dt = np.clip(tf - t[i], 0.0, None)
    sf = np.minimum(s[i] + V[i] * dt + 0.5 * acc * dt * dt, s[i + 1])
    sf[tf >= t[-1]] = s[-1]
    sf[tf <= 0] = s[0]
    for _ in range(passes):
        padded = np.concatenate([np.full(width, s[0]), sf, np.full(width, s[-1])])
        csum = np.concatenate([[0.0], np.cumsum(padded - s[0])])
        sf = (s[0] + (csum[width:] - csum[:-width]) / width)[1:]
    sf[-1] = s[-1]
    return np.arange(len(sf)) * h, sf


@pytest.fixture(scope="module")
def pieces():
    m = die_bonder()
    out = []
    for name, feed in (("die-bonder-pi", 5e5), ("butterfly", 2e5)):
        curve = to_pulses(builtin_path(name), m)
        profile = speed_profile(curve, m, feed)
        out.append((curve, list(zip(profile.pieces, profile.piece_times())),
                    m.sample_period))
    return out


@pytest.mark.parametrize("passes", [1, 2])
def test_streamed_time_profile_equals_the_fine_grid(pieces, passes):
    """Every value, to the last bit, at sample times, off-grid times, the fine points
    themselves and beyond both ends."""
    rng = np.random.default_rng(3)
    width = mp.OVERSAMPLE * mp.SMOOTHING_WIDTH
    for _, piece_list, Ts in pieces:
        for (s, _, V), t in piece_list:
            h = Ts / mp.OVERSAMPLE
            tf, sf = _fine_grid_reference(s, V, t, h, passes, width)
            n_fine = int(math.ceil(t[-1] / h)) + 1
            for times in (np.arange(-2, len(tf) // mp.OVERSAMPLE + 3) * Ts,
                          np.sort(rng.uniform(-Ts, tf[-1] + Ts, 3000)), tf[::5]):
                out = np.empty_like(times)
                mp._smoothed_arc(s, V, t, h, n_fine, width, passes, times, out)
                np.testing.assert_array_equal(out, np.interp(times, tf, sf))


def test_arc_length_inverse_is_the_root_of_the_table(pieces):
    """``u(s)`` for dense increasing arc lengths (a motion's samples: each from the last)
    and for the same shuffled (each from the table): s(u) back to within a few roundings
    of s, with the cache and without."""
    for curve, _, _ in pieces:
        L = curve.length
        arc = np.linspace(0.0, L, 20001)[1:-1]
        shuffled = np.random.default_rng(5).permutation(arc)
        for s in (arc, shuffled):
            for cache in (True, False):
                u = curve.geometry.parameter_at(s, cache=cache)
                assert np.max(np.abs(curve.arc_length(u) - s)) <= 1e-15 * L * 8


def test_blend_deviation_equals_comparing_every_sample():
    """The nearest-sample distance restricted to the samples near the corner is that of
    comparing every point with every sample (a path that comes back near the corner)."""
    rng = np.random.default_rng(7)
    angle = np.linspace(0.0, 2 * np.pi, 4001)
    path = np.column_stack([np.cos(angle), np.sin(2 * angle)]) * 100.0
    corner = path[1000]
    points = corner + rng.normal(scale=3.0, size=(700, 2))
    brute = np.max(np.min(np.linalg.norm(points[:, None, :] - path[None, :, :], axis=2),
                          axis=1))
    assert mp._farthest_from(points, path, corner) == brute


def test_support_equals_running_maxima_by_numpy():
    """The planned step's support (running maxima back from each stop) equals numpy's
    accumulate over the reversed pieces, bit for bit."""
    from nurbsmotion.interpolators.planned import SUPPORT_DIRECTIONS, _support

    rng = np.random.default_rng(11)
    angles = np.linspace(0.0, 0.5 * np.pi, SUPPORT_DIRECTIONS)
    for n, stops in ((500, []), (500, [0, 40, 40, 300, 499]), (9, [9])):
        accel, speed = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
        values = np.abs(np.cos(angles) * accel[:, :, None] + np.sin(angles) * speed[:, :, None])
        expected = np.empty_like(values)
        bounds = [0, *stops, n]
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            if hi > lo:
                expected[lo:hi] = np.maximum.accumulate(values[lo:hi][::-1], axis=0)[::-1]
        np.testing.assert_array_equal(_support(accel, speed, np.array(stops, dtype=int)),
                                      expected)
