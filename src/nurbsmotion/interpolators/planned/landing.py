"""Step 5 of the plan (:mod:`.plan`): the last drives changed by the least that puts the
plant at rest exactly on the end (:func:`_land_on_end`), and the path helpers it shares with
step 6: the feed at a curve parameter, the nearest path points moving forward
(:func:`_nearest_forward`) within a stop-to-stop span (:class:`_Span`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...feed import FeedLimit
from ...machine import Machine
from ...nurbs import NurbsCurve
from .inverse import INVERSE_REACH, LEAD, PRECOMPENSATION_TOLERANCE, axis_zoh


LANDING_SAMPLES = 64
"""Most drives the landing of step 5 changes (:func:`_land_on_end`; each window size tried
costs a least-squares solve of its size). On the 300 seeded random paths of
``benchmarks/planner_sweep.py`` it changed 2-22."""


def _arrival(y: np.ndarray) -> int:
    """The first sample from which the positions ``y`` (n, n_axes) rest on their last."""
    moving = np.flatnonzero(np.any(y != y[-1], axis=1))
    return int(moving[-1]) + 1 if moving.size else 0


def _past_end(positions: np.ndarray, off: np.ndarray, end: np.ndarray,
              tangent: np.ndarray) -> float:
    """How far [pulse] the ``positions`` (m, n_axes) whose nearest point of a path is its
    ``end`` (their distance ``off`` to the path, shape (m,), is their distance to the end)
    pass it along the path's unit ``tangent`` there (0 if none does)."""
    past = np.linalg.norm(positions - end, axis=1) <= off * (1 + 1e-9) + 1e-12
    return float(np.max((positions[past] - end) @ tangent, initial=0.0))


def _impulse_responses(machine: Machine, size: int) -> np.ndarray:
    """``h[j, p] = A^p B`` of every axis' ZOH plant (docs/model.md#servo-axis), p < ``size``: the
    change of [speed, position] p + 1 samples after a unit drive. Shape (n_axes, size, 2)."""
    a, b0, c, b1 = axis_zoh(machine)
    h = np.empty((len(a), size, 2))
    h[:, 0, 0], h[:, 0, 1] = b0, b1
    for p in range(1, size):
        h[:, p, 0] = a * h[:, p - 1, 0]
        h[:, p, 1] = c * h[:, p - 1, 0] + h[:, p - 1, 1]
    return h


def _rest_on_end(h: np.ndarray, theta: np.ndarray, w: np.ndarray, target: np.ndarray,
                 end: np.ndarray, k0: int, N: int):
    """The least change of the drives k0 .. N - 1 (m = N - k0 <= ``h.shape[1]`` of them)
    that puts the plant at rest on ``end`` at sample N: per axis, equality-constrained
    least squares of the positions ``theta[k0 + 1:N]`` (the plant's, shape (>N, n_axes),
    with its speeds ``w``) against ``target``. The plant is linear, so a change du of the
    drives moves sample k by ``sum_i h[k - 1 - i] du[i]``. Returns ``du`` (m, n_axes) and
    the change it makes to [w, theta] at samples k0 + 1 .. N, shape (m, 2, n_axes)."""
    m = N - k0
    n_axes = h.shape[0]
    lag = np.subtract.outer(np.arange(m), np.arange(m))  # row q: sample k0 + q + 1
    du = np.empty((m, n_axes))
    moved = np.empty((m, 2, n_axes))
    for j in range(n_axes):
        Hw, H = (np.where(lag >= 0, h[j, np.clip(lag, 0, m - 1), i], 0.0) for i in (0, 1))
        E = np.vstack([Hw[m - 1], H[m - 1]])
        kkt = np.zeros((m + 2, m + 2))
        kkt[:m, :m] = H[:-1].T @ H[:-1]
        kkt[:m, m:] = E.T
        kkt[m:, :m] = E
        rhs = np.concatenate([-H[:-1].T @ (theta[k0 + 1:N, j] - target[k0 + 1:N, j]),
                              [-w[N, j], end[j] - theta[N, j]]])
        du[:, j] = np.linalg.lstsq(kkt, rhs, rcond=None)[0][:m]
        moved[:, 0, j], moved[:, 1, j] = Hw @ du[:, j], H @ du[:, j]
    return du, moved


def _land_on_end(y: np.ndarray, w: np.ndarray, theta: np.ndarray, u: np.ndarray,
                 machine: Machine, limit: float, tangent: np.ndarray, curve: NurbsCurve,
                 param: np.ndarray, feed) -> int:
    """Step 5: bring the plan to rest exactly on the end, at the earliest sample N the
    drive allows, no later than the sample where the desired motion arrives there (in
    place). Returns N (the arrival if the plan is left as it is).

    What the pre-compensation leaves (a pulse or two on a short, fast move, whose motion
    is mostly near the Nyquist frequency) ends as a slow approach to the end after the
    desired motion has arrived, which the move's settle time pays for; and the desired
    motion's last samples creep (the averaging of step 1 halves the last braking, and the
    arrival is rounded up to a sample). The plant is linear, so a change du of the last
    m drives moves sample k by ``sum_i h[k - 1 - i] du[i]`` with ``h[p] = A^p B`` (the ZOH
    plant, docs/model.md#servo-axis). Per axis, the change that puts the state at N at rest on the
    end and otherwise departs least from ``y`` (equality-constrained least squares over
    the window's positions) is applied, and the drive is 0 after N. It is kept if the
    changed drive is within ``limit`` [V] and the window's positions stay as near the
    ``curve`` as the plan was to ``y`` there (at least within
    :data:`PRECOMPENSATION_TOLERANCE`; the distance to the path point that Newton steps
    from the desired positions' curve parameters ``param`` (n,) find, never less than the
    true one: the polyline through ``y`` cuts a tight curl the samples step across) and
    none passes the end along the path's unit ``tangent`` there by more than that
    tolerance (:func:`_past_end`), and their nearest path points move forward by at most
    the ``feed`` (F [pulse/s] or a :class:`~nurbsmotion.feed.FeedLimit`) times Ts plus
    :data:`FEED_SLACK` a sample, from the last sample it leaves as it is to N (on a
    10 mm line at 10 mm/s the landing took the last 47 pulses in 2 samples, the tool at
    26 mm/s: the desired motion was already at the feed there). N runs from
    the arrival less the samples
    the averaging and the inverse shape (``INVERSE_REACH + 1``), changing at most that
    many drives, up to the arrival itself, where m grows up to :data:`LANDING_SAMPLES`
    (and N - LEAD: the drives before :data:`LEAD` stay 0); if none does, the plan is left
    as it is."""
    end = y[-1]
    arrive = _arrival(y)
    if arrive < LEAD + 2 or arrive >= len(y):
        return arrive
    if float(np.max(np.abs(theta[arrive - 1:] - y[arrive - 1:]))) == 0.0:
        return arrive
    reach = INVERSE_REACH + 1
    Ts = machine.sample_period
    h = _impulse_responses(machine, min(arrive - LEAD, LANDING_SAMPLES))
    for N in range(max(arrive - reach, LEAD + 2), arrive + 1):
        most = min(N - LEAD, h.shape[1] if N == arrive else reach)
        first = max(N - most - 1, 0)
        tolerance = max(PRECOMPENSATION_TOLERANCE,
                        float(np.max(np.abs(theta[first:] - y[first:]))))
        for m in range(2, most + 1):
            k0 = N - m
            du, moved = _rest_on_end(h, theta, w, y, end, k0, N)
            drive = u[k0:N] + du
            if np.max(np.abs(drive)) > limit:
                continue
            theta_new = theta[k0 + 1:N + 1] + moved[:, 1]
            near = _nearest_forward(curve, np.vstack([theta[k0:k0 + 1], theta_new]),
                                    curve.arc_length(param[k0:N + 1]))
            at = curve.parameter_at(near)
            off = np.linalg.norm(theta_new - curve(at[1:]), axis=1)
            if np.max(off) > tolerance \
                    or _past_end(theta_new, off, end, tangent) > PRECOMPENSATION_TOLERANCE \
                    or np.any(np.diff(near) > _feed_at(feed, at[1:]) * Ts + FEED_SLACK):
                continue
            u[k0:N] = drive
            w[k0 + 1:N + 1] += moved[:, 0]
            theta[k0 + 1:N + 1] = theta_new
            u[N:] = 0.0
            w[N:] = 0.0
            theta[N:] = end
            return N
    return arrive


FEED_SLACK = 2 * PRECOMPENSATION_TOLERANCE
"""How far [pulse] a plan's nearest path point may move beyond ``F*Ts`` in a sample: the
desired motion moves at most F*Ts a sample (its profile is within the feed and the
averaging of step 1 keeps it so), and the plan of step 3 is within
:data:`PRECOMPENSATION_TOLERANCE` of it at both ends of the sample. The landing (step 5)
is held to the same; the feed of the tool's sampled motion is thus F + FEED_SLACK/Ts."""


def _feed_at(feed, p: np.ndarray) -> np.ndarray:
    """The feed F [pulse/s] at the curve parameters ``p`` (m,), shape (m,)."""
    return np.asarray(feed(p) if isinstance(feed, FeedLimit) else np.full(len(p), feed),
                      dtype=float)


class _Span(NamedTuple):
    """A stretch of the path from one stop to the next (step 6): curve parameters
    [u0, u1] and arc lengths [s0, s1] [pulse]."""

    u0: float
    u1: float
    s0: float
    s1: float

    @classmethod
    def of(cls, curve: NurbsCurve, u0: float = 0.0, u1: float = 1.0) -> "_Span":
        s0, s1 = (float(curve.arc_length(u)) if 0.0 < u < 1.0 else u * curve.length
                  for u in (u0, u1))
        return cls(float(u0), float(u1), s0, s1)

    def tangents(self, curve: NurbsCurve, p: np.ndarray) -> np.ndarray:
        """Unit tangents at the parameters ``p`` (m,) of the span, from the span's side at
        its end (a sharp corner), shape (m, n_axes)."""
        T = curve.tangent(p)
        at_end = p >= self.u1
        if self.u1 < 1.0 and np.any(at_end):
            T[at_end] = curve.tangent(p[at_end], "left")
        return T


def _nearest_forward(curve: NurbsCurve, points: np.ndarray, s: np.ndarray,
                     span: _Span | None = None) -> np.ndarray:
    """Arc lengths [pulse] of the path points nearest ``points`` (m, n_axes) near the
    guesses ``s`` (m,) (Newton on the arc length), within the ``span`` (default: the
    whole path), made nondecreasing."""
    span = span or _Span.of(curve)
    for _ in range(3):
        p = curve.parameter_at(s)
        s = np.clip(s + np.sum(span.tangents(curve, p) * (points - curve(p)), axis=1),
                    span.s0, span.s1)
    return np.maximum.accumulate(s)
