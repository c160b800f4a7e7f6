"""The planned motion's sampling (issue 13 item 4): the streamed, compiled time profile and
arc-length inverse of :mod:`nurbsmotion.interpolators.planned.blend` against the fine-grid numpy
computation they replace and against the arc-length table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nurbsmotion.interpolators.planned import blend as mp
from nurbsmotion.loop import to_pulses
from nurbsmotion.machine import die_bonder
from nurbsmotion.nurbs import builtin_path
from nurbsmotion.planning import speed_profile


def _profile(s, V, t, times):
    """The piece's time profile at ``times``: constant acceleration between grid points
    (b = V^2 linear in s), at rest before and after."""
    i = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 2)
    ds = s[i + 1] - s[i]
    with np.errstate(divide="ignore", invalid="ignore"):
        acc = np.where(ds > 0, (V[i + 1] ** 2 - V[i] ** 2) / (2 * ds), 0.0)
    dt = np.clip(times - t[i], 0.0, None)
    out = np.minimum(s[i] + V[i] * dt + 0.5 * acc * dt * dt, s[i + 1])
    out[times >= t[-1]] = s[-1]
    out[times <= 0] = s[0]
    return out


def _fine_grid_reference(s, V, t, h, lag):
    """The whole fine grid as numpy arrays: constant acceleration between grid points,
    averaged with itself ``lag`` points later (at rest before and after), the last point
    on the piece's end. Returns (times, values)."""
    n_fine = int(math.ceil(t[-1] / h)) + 1
    sf = _profile(s, V, t, np.arange(n_fine) * h)
    padded = np.concatenate([np.full(lag, s[0]), sf, np.full(lag, s[-1])])
    sf = 0.5 * (padded[lag:] + padded[:-lag])
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


def test_streamed_time_profile_equals_the_fine_grid(pieces):
    """Every value, to the last bit, at sample times, off-grid times, the fine points
    themselves and beyond both ends."""
    rng = np.random.default_rng(3)
    lag = mp.OVERSAMPLE
    for _, piece_list, Ts in pieces:
        for (s, _, V), t in piece_list:
            h = Ts / mp.OVERSAMPLE
            tf, sf = _fine_grid_reference(s, V, t, h, lag)
            n_fine = int(math.ceil(t[-1] / h)) + 1
            for times in (np.arange(-2, len(tf) // mp.OVERSAMPLE + 3) * Ts,
                          np.sort(rng.uniform(-Ts, tf[-1] + Ts, 3000)), tf[::5]):
                out = np.empty_like(times)
                mp._averaged_arc(s, V, t, h, n_fine, lag, times, out)
                np.testing.assert_array_equal(out, np.interp(times, tf, sf))


def test_sampled_average_is_the_nyquist_zero_filter(pieces):
    """At the sample instants the averaged profile is ``(1 + 1/z)/2`` of the profile's own
    samples (a zero exactly at the Nyquist frequency), from rest to rest."""
    for _, piece_list, Ts in pieces:
        for (s, _, V), t in piece_list:
            h = Ts / mp.OVERSAMPLE
            n_fine = int(math.ceil(t[-1] / h)) + 1
            k = np.arange(n_fine // mp.OVERSAMPLE + 2)
            raw = _profile(s, V, t, k * Ts)
            out = np.empty(len(k))
            mp._averaged_arc(s, V, t, h, n_fine, mp.OVERSAMPLE, k * Ts, out)
            prev = np.concatenate([[s[0]], raw[:-1]])
            np.testing.assert_allclose(out, 0.5 * (raw + prev), rtol=0, atol=1e-9 * s[-1])



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


def test_a_thinned_path_overstates_the_deviation_by_at_most_its_step():
    """Blends measure their deviation against path samples thinned to one per ``step`` of
    arc: each point's distance to the nearest kept sample is at least its distance to the
    nearest of all samples (numpy, every pair), and at most ``step`` more; the first
    sample (the corner) is kept."""
    rng = np.random.default_rng(8)
    t = np.sort(rng.uniform(0.0, 1.0, 3000)) ** 3          # dense near the start
    path = np.column_stack([np.cos(3 * t), np.sin(5 * t), t]) * 1000.0
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
    points = path[0] + rng.normal(scale=200.0, size=(500, 3))
    step = 7.0
    kept = mp._thinned(path, arc, step)
    assert np.array_equal(kept[0], path[0]) and len(kept) <= arc[-1] / step + 1

    def nearest(samples):
        return np.min(np.linalg.norm(points[:, None] - samples[None], axis=2), axis=1)

    every, thinned = nearest(path), nearest(kept)
    assert np.all(thinned >= every) and np.all(thinned <= every + step)


def test_support_equals_running_maxima_by_numpy():
    """The planned step's support (running maxima back from each stop) equals numpy's
    accumulate over the reversed pieces, bit for bit."""
    from nurbsmotion.interpolators.planned.governor import SUPPORT_DIRECTIONS, _support

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
        np.testing.assert_array_equal(
            _support(accel, speed, np.array(stops, dtype=int), 8), expected[::8])


def test_each_samples_support_from_the_stored_ones_equals_the_full_support():
    """The planned step's support of every sample, rebuilt from the plan's stored one at
    every SUPPORT_BLOCK-th sample and the samples before it, equals the support stored at
    every sample (stops inside, on and next to a block's start, and none)."""
    from nurbsmotion.interpolators.planned import PlannedPlan
    from nurbsmotion.interpolators.planned.governor import (SUPPORT_BLOCK, SUPPORT_DIRECTIONS,
                                                            _support, _support_at)

    rng = np.random.default_rng(12)
    for n, stops in ((203, []), (203, [5, 8, 9, 16, 17, 100, 202]), (3, [1])):
        accel, speed = rng.normal(size=(n, 2)), rng.normal(size=(n, 2))
        stops = np.array(stops, dtype=np.int64)
        full = _support(accel, speed, stops)
        plan = PlannedPlan(*([None] * 3), speed, accel,
                           _support(accel, speed, stops, SUPPORT_BLOCK),
                           np.append(stops, n), *([None] * 5), 0.0, 0.0, n, None, None)
        out = np.empty((2, SUPPORT_DIRECTIONS))
        for i in range(n):
            np.testing.assert_array_equal(_support_at(plan, i, out), full[i])
