"""The closed loop of :func:`nurbsmotion.loop.simulate`, compiled (numba ``@njit``).

One call runs samples ``k0 ..`` of the loop until the run ends or the preallocated rows are
full; all the loop's state lives in two small arrays the caller owns, so a full buffer is
grown and the run resumed where it stopped. Each sample does what the readable reference
(:func:`nurbsmotion.loop.simulate` with ``compiled=False``) does, in the same order and with
the same floating-point expressions:

1. measure tha[k] and wa[k] (encoder differencing or the true speed);
2. the interpolator step: plan the feed (constant, or the paper's eq. 3.6-3.10 from the
   measured state), advance the parameter by the Taylor expansion (eq. 3.1 / 3.2),
   piecewise across knots where the curve loses the continuity the expansion needs
   (:meth:`nurbsmotion.interpolators.Interpolator._advance`), land on u = 1 and hold it;
3. the PD / PD+ law (eq. 3.3), clipping, and the exact zero-order-hold plant step.

Feed planners are selected by ``kind``: :data:`KIND_CONSTANT` (``taylor1``/``taylor2``) and
:data:`KIND_PAPER`, each with its data in the 2-D array ``plan``. A planner that
precomputes its feed as arrays (a speed profile V(u) with its tangential acceleration A(u))
plugs in as another kind: its rows go in ``plan``, a branch of :func:`_plan_feed` returns
``(V, A)`` from them, and everything after the feed (the piecewise Taylor step with the A
term, the law, the plant, the recording) is shared.

Glossary
--------
U, Pw, p : knots, homogeneous control points, degree (see :mod:`nurbsmotion._kernels`);
u : curve parameter; V : feed [pulse/s]; A : tangential acceleration [pulse/s^2];
thd, tha : commanded and measured position [pulse]; wd, wa : commanded and measured motor
speed [rad/s]; Ad, Bd : ZOH matrices per axis, state [w, theta].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._kernels import rational_derivatives_into, workspace

KIND_CONSTANT = 0
"""Constant commanded feed: the ``taylor1`` / ``taylor2`` interpolators."""
KIND_PAPER = 1
"""Yeh & Sun's saturation-aware feed (eq. 3.6-3.10): the ``paper`` interpolator."""

DONE, FULL, CANNOT_ADVANCE, TOO_MANY_SAMPLES = 0, 1, 2, 3
"""Return codes of :func:`run_loop`."""

# Indices into the scalar state array ``sc``.
S_K, S_U, S_FINISHED, S_ERR_DU, S_ERR_FEED = 0, 1, 2, 3, 4
# Rows of the per-axis state array ``ax``.
A_THD, A_WD, A_THA, A_W, A_TH = 0, 1, 2, 3, 4


@njit(cache=True)
def _derivatives(U, Pw, p, u, max_order, d3, work):
    """Right-sided ``C^(k)(u)`` into ``d3[k, 0, :]`` (``d3`` shape (3, 1, n_axes)); the
    last scratch array of ``work`` holds the parameter."""
    us = work[-1]
    us[0] = u
    rational_derivatives_into(U, Pw, p, us, max_order, False, d3, work)


@njit(cache=True)
def _taylor_increment(d, order, V, A, T):
    """``taylor_increment`` of :mod:`nurbsmotion.interpolators.base` (eq. 3.1 / 3.2)."""
    dim = d.shape[1]
    n2 = 0.0
    for c in range(dim):
        n2 += d[1, c] * d[1, c]
    n1 = math.sqrt(n2)
    first = V * T / n1
    if order == 1:
        return first
    d12 = 0.0
    for c in range(dim):
        d12 += d[1, c] * d[2, c]
    second = 0.5 * (A / n1 - V * V * d12 / (n2 * n2))
    du = first + second * T**2
    return du if du > 0 else first


@njit(cache=True)
def _time_to_reach(target, d, order, V, A, T):
    lo = 0.0
    hi = T
    for _ in range(60):  # the same bisection as the reference
        mid = 0.5 * (lo + hi)
        if _taylor_increment(d, order, V, A, mid) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(cache=True)
def _advance(U, Pw, p, breaks, order, u0, V, A, Ts, d3, work):
    """Parameter after one sample; ``d3[:, 0]`` holds the derivatives at ``u0``
    (overwritten)."""
    d = d3[:, 0, :]
    u = u0
    remaining = Ts
    while True:
        du = _taylor_increment(d, order, V, A, remaining)
        b = breaks[np.searchsorted(breaks, u, side="right")]
        if u + du <= b or b >= 1.0:
            return u + du
        dt = _time_to_reach(b - u, d, order, V, A, remaining)
        u = b
        V = V + A * dt
        remaining = remaining - dt
        if remaining <= 0.0 or V <= 0.0:
            return u
        _derivatives(U, Pw, p, u, order, d3, work)


@njit(cache=True)
def _plan_feed(kind, feed, d, thd_prev, wd_prev, tha, wa, plan, bounds_row):
    """Feed V and tangential acceleration A of the next step from ``u`` (derivatives
    ``d``); the paper's bounds (eq. 3.6) are written to ``bounds_row`` (shape (n_axes, 2)).

    ``plan`` is the planner's data: unused for :data:`KIND_CONSTANT`; for
    :data:`KIND_PAPER` the rows of the interpolator's model per axis: Kp, Kd,
    ka = tau/(Kc*Ts) (0 for PD), Ksig (drive per unit speed command), Ke, Umax.
    """
    if kind == KIND_CONSTANT:
        return feed, 0.0
    dim = d.shape[1]
    n2 = 0.0
    for c in range(dim):
        n2 += d[1, c] * d[1, c]
    norm = math.sqrt(n2)
    V = feed
    Vm = np.inf
    for j in range(dim):
        Kp, Kd, ka, ksig, Ke, umax = plan[0, j], plan[1, j], plan[2, j], plan[3, j], \
            plan[4, j], plan[5, j]
        v = Kp * (thd_prev[j] - tha[j]) - Kd * wa[j] - ka * wd_prev[j]   # section 3.2
        wmin = (-umax - v) / ksig                                         # eq. 3.6
        wmax = (umax - v) / ksig
        bounds_row[j, 0] = wmin
        bounds_row[j, 1] = wmax
        tangent = d[1, j] / norm
        wd = tangent * V / Ke                                             # eq. 3.7
        if tangent == 0.0:
            vm = V
        elif wd > wmax:
            vm = abs(wmax * Ke / tangent)                                 # eq. 3.10
        elif wd < wmin:
            vm = abs(wmin * Ke / tangent)
        else:
            vm = V
        if vm < Vm:
            Vm = vm
    return Vm, 0.0


@njit(cache=True)
def run_loop(U, Pw, p, breaks, kind, order, feed, plan, start, end,
             Kp, Kd, Kc, tau, Ke_Ts, Ts, feedforward, umax, Ad, Bd, encoder,
             n_settle, max_samples, sc, ax,
             r_u, r_feed, r_thd, r_tha, r_wd, r_wa, r_drive, r_applied, r_bounds,
             record_bounds):
    """Run the loop from the state in ``sc``/``ax`` until done or the rows are full.

    Returns one of :data:`DONE`, :data:`FULL` (resume after growing the rows),
    :data:`CANNOT_ADVANCE` (``sc`` holds u, the step and the feed) and
    :data:`TOO_MANY_SAMPLES`. ``sc[S_K]`` is the next sample to run (the row count
    after :data:`DONE`).
    """
    dim = start.shape[0]
    capacity = r_u.shape[0]
    d3 = np.empty((3, 1, dim))
    d = d3[:, 0, :]
    work = workspace(p, 2, dim)
    thd = np.empty(dim)
    tha = np.empty(dim)
    wa = np.empty(dim)
    bounds_row = np.empty((dim, 2))
    k = int(sc[S_K])
    u = sc[S_U]
    finished = int(sc[S_FINISHED])
    thd_prev = ax[A_THD]
    wd_prev = ax[A_WD]
    tha_prev = ax[A_THA]
    w = ax[A_W]
    th = ax[A_TH]
    while True:
        if k >= capacity:
            sc[S_K] = k
            sc[S_U] = u
            sc[S_FINISHED] = finished
            return FULL
        for j in range(dim):
            tha[j] = th[j]
            wa[j] = (tha[j] - tha_prev[j]) / Ke_Ts[j] if encoder else w[j]
        has_bounds = False
        step_feed = 0.0
        if k == 0:
            for j in range(dim):
                thd[j] = start[j]
        elif u >= 1.0:
            for j in range(dim):
                thd[j] = end[j]
        else:
            _derivatives(U, Pw, p, u, order, d3, work)
            V, A = _plan_feed(kind, feed, d, thd_prev, wd_prev, tha, wa, plan, bounds_row)
            has_bounds = kind == KIND_PAPER
            u_new = _advance(U, Pw, p, breaks, order, u, V, A, Ts, d3, work)
            du = u_new - u
            if not (du > 0 and math.isfinite(du)):
                sc[S_K] = k
                sc[S_U] = u
                sc[S_ERR_DU] = du
                sc[S_ERR_FEED] = V
                return CANNOT_ADVANCE
            step_feed = V
            if u_new >= 1.0:
                u = 1.0
                for j in range(dim):
                    thd[j] = end[j]
            else:
                u = u_new
                _derivatives(U, Pw, p, u, 0, d3, work)
                for j in range(dim):
                    thd[j] = d[0, j]
            if u >= 1.0 and finished < 0:
                finished = k
        r_u[k] = u if k > 0 else 0.0
        r_feed[k] = step_feed
        for j in range(dim):
            wd = (thd[j] - thd_prev[j]) / Ke_Ts[j]
            drive = Kp[j] * (thd[j] - tha[j]) + Kd[j] * (wd - wa[j])
            if feedforward:
                ad = (wd - wd_prev[j]) / Ts
                drive = drive + wd / Kc[j] + tau[j] * ad / Kc[j]
            applied = min(max(drive, -umax), umax)
            r_thd[k, j] = thd[j]
            r_tha[k, j] = tha[j]
            r_wd[k, j] = wd
            r_wa[k, j] = wa[j]
            r_drive[k, j] = drive
            r_applied[k, j] = applied
            if record_bounds:
                if has_bounds:
                    r_bounds[k, j, 0] = bounds_row[j, 0]
                    r_bounds[k, j, 1] = bounds_row[j, 1]
                else:
                    r_bounds[k, j, 0] = np.nan
                    r_bounds[k, j, 1] = np.nan
            w_next = Ad[j, 0, 0] * w[j] + Ad[j, 0, 1] * th[j] + Bd[j, 0] * applied
            th[j] = Ad[j, 1, 0] * w[j] + Ad[j, 1, 1] * th[j] + Bd[j, 1] * applied
            w[j] = w_next
            thd_prev[j] = thd[j]
            wd_prev[j] = wd
            tha_prev[j] = tha[j]
        if finished >= 0 and k >= finished + n_settle:
            sc[S_K] = k + 1
            sc[S_U] = u
            sc[S_FINISHED] = finished
            return DONE
        k += 1
        if k >= max_samples:
            sc[S_K] = k
            sc[S_U] = u
            sc[S_FINISHED] = finished
            return TOO_MANY_SAMPLES
