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
:data:`KIND_PAPER`, each with its data in the 2-D array ``plan``; :data:`KIND_PLANNED` (the
``planned`` interpolator) replaces step 2 by its own online step on the offline schedule
(:func:`_planned_step`: the planned sample, the predicted drive and the safety layer's
bisection), with its arrays in the tuple ``tables`` (indices ``T_*``). A planner that
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

from ._kernels import rational_derivatives_into, rational_point_into, workspace

KIND_CONSTANT = 0
"""Constant commanded feed: the ``taylor1`` / ``taylor2`` interpolators."""
KIND_PAPER = 1
"""Yeh & Sun's saturation-aware feed (eq. 3.6-3.10): the ``paper`` interpolator."""
KIND_PLANNED = 2
"""The look-ahead schedule with its online safety layer: the ``planned`` interpolator
(:class:`nurbsmotion.interpolators.PlannedInterpolator`)."""

DONE, FULL, CANNOT_ADVANCE, TOO_MANY_SAMPLES = 0, 1, 2, 3
"""Return codes of :func:`run_loop`."""

# Indices into the scalar state array ``sc`` (the last three: the planned stepper's
# fractional schedule index, arc length reached and count of safety slow-downs).
S_K, S_U, S_FINISHED, S_ERR_DU, S_ERR_FEED, S_PHI, S_S, S_SLOWDOWNS = range(8)
N_STATE = 8
# Arrays of ``tables`` for KIND_PLANNED (empty for the other kinds): the schedule's arc
# length and parameter per sample with |C'| on both sides of each planned parameter; the
# caps of a lengthened step (sharp corners and 1); the arc-length table (piece starts and
# cumulative lengths) and the 10-point Gauss-Legendre rule of
# :class:`nurbsmotion.geometry.CurveGeometry`; the factors of the look-ahead candidates;
# and the scalars (Umax, 1 for PD+, Ts, 1 when the safety layer is on, the safety layer's
# number of bisections).
(T_PLAN_S, T_PLAN_U, T_SPEED_RIGHT, T_SPEED_LEFT, T_CAPS, T_TABLE_U, T_TABLE_S, T_GL_X,
 T_GL_W, T_AHEAD, T_SCALARS) = range(11)
N_TABLES = 11
# Rows of ``plan`` for KIND_PLANNED, per axis: the interpolator's own model of the law.
P_KP, P_KD, P_KE_TS, P_KC, P_TAU, P_KA, P_KSIG = range(7)
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


# ------------------------------------------------------------------ the planned stepper
# Each function is the method of PlannedInterpolator named in its docstring, with the same
# floating-point expressions in the same order (Python's ``t**3`` is libm's pow(t, 3.0);
# ``t**2`` and ``t*t`` round alike).


@njit(cache=True, inline="always")
def _schedule_at(phi, plan_s, plan_u, speed_right, speed_left):
    """``PlannedInterpolator._at``: ``(u, s)`` at the fractional schedule index ``phi``
    (cubic Hermite u(s) between planned samples)."""
    k = int(math.floor(phi))
    if phi == k or plan_s[k + 1] == plan_s[k]:
        return plan_u[k], plan_s[k]
    s0, s1 = plan_s[k], plan_s[k + 1]
    u0, u1 = plan_u[k], plan_u[k + 1]
    h = s1 - s0
    t = phi - k
    m0, m1 = h / speed_right[k], h / speed_left[k + 1]
    t2 = t**2
    t3 = math.pow(t, 3.0)
    u = ((2 * t3 - 3 * t2 + 1) * u0 + (t3 - 2 * t2 + t) * m0
         + (-2 * t3 + 3 * t2) * u1 + (t3 - t2) * m1)
    return min(max(u, u0), u1), s0 + t * h


@njit(cache=True)
def _schedule_index(s, plan_s):
    """``np.interp(s, plan_s, arange(len(plan_s)))``, numpy's formula."""
    n = plan_s.shape[0]
    if math.isnan(s):
        return np.nan
    if s < plan_s[0]:
        return 0.0
    if s >= plan_s[n - 1]:
        return float(n - 1)
    j = np.searchsorted(plan_s, s, side="right") - 1
    if plan_s[j] == s:
        return float(j)
    slope = (float(j + 1) - float(j)) / (plan_s[j + 1] - plan_s[j])
    return slope * (s - plan_s[j]) + float(j)


@njit(cache=True)
def _arc_length(U, Pw, p, u, table_u, table_s, gl_x, gl_w, work, nodes, d):
    """``CurveGeometry.arc_length`` at one parameter: the table's length up to the piece
    that holds ``u`` plus 10-point Gauss-Legendre from the piece's start, summed left to
    right as the reference sums them. The nodes go through the batch kernel in one call
    (a call per node costs more than its evaluation); ``nodes`` (n_gauss,) and ``d``
    (2, n_gauss, n_axes) are scratch."""
    j = np.searchsorted(table_u, u, side="right") - 1
    j = min(max(j, 0), table_u.shape[0] - 2)
    a = table_u[j]
    half = 0.5 * (u - a)
    mid = 0.5 * (u + a)
    for i in range(gl_x.shape[0]):
        nodes[i] = mid + half * gl_x[i]
    dim = Pw.shape[1] - 1
    rational_derivatives_into(U, Pw, p, nodes, 1, False, d, work)
    acc = 0.0
    for i in range(nodes.shape[0]):
        n2 = 0.0
        for c in range(dim):
            n2 += d[1, i, c] * d[1, i, c]
        acc += math.sqrt(n2) * gl_w[i]
    return table_s[j] + half * acc


@njit(cache=True, inline="always")
def _admissible(U, Pw, p, uc, plan, ff, Ts, umax, thd_prev, wd_prev, tha, wa, scratch):
    """``PlannedInterpolator._excess(uc) <= 0``: the setpoint C(uc) keeps every predicted
    drive within Umax (the interpolator's model of the law and the measured state).
    ``scratch``: the point (n_axes,) and the basis scratch of ``rational_point_into``.

    Each drive is the reference's expression; ``max_j |u_j| - Umax <= 0`` is tested as
    ``|u_j| <= Umax`` for every j, stopping at the first axis that fails: the same answer
    for a finite Umax (a difference of finite doubles is <= 0 exactly when the first is <=
    the second; an infinite drive fails both ways, a NaN drive fails both ways), and the
    safety layer only runs with a finite Umax."""
    point, ndu, bl, br = scratch
    rational_point_into(U, Pw, p, uc, point, ndu, bl, br)
    for j in range(point.shape[0]):
        th = point[j]
        wd = (th - thd_prev[j]) / plan[P_KE_TS, j]
        drive = plan[P_KP, j] * (th - tha[j]) + plan[P_KD, j] * (wd - wa[j])
        if ff:
            ad = (wd - wd_prev[j]) / Ts
            drive = drive + wd / plan[P_KC, j] + plan[P_TAU, j] * ad / plan[P_KC, j]
        if not abs(drive) <= umax:
            return False
    return True


@njit(cache=True, inline="always")
def _nearest_admissible(U, Pw, p, u_plan, cand, dist, n, plan, ff, Ts, umax,
                        thd_prev, wd_prev, tha, wa, scratch):
    """Index of the admissible candidate nearest to ``u_plan`` (the first such index on a
    tie), or -1: ``argmin(where(ok, |cand - u_plan|, inf))`` of the reference, but the
    candidates are tried nearest first and the scan stops at the first distance that has
    an admissible one. The distances fall along ``cand[:33]`` (towards ``u_plan``) and rise
    along ``cand[33:n]``, so a merge of the two runs visits them in order; should rounding
    break that order (a step of a few ulps), every candidate is tried, as the reference
    does. Called once ``u_plan`` is known to be inadmissible: a candidate equal to it, or
    to an ahead candidate already tried (those capped at the next corner), is not
    evaluated again."""
    ordered = True
    for i in range(n):
        dist[i] = abs(cand[i] - u_plan)
        if not math.isfinite(dist[i]):
            ordered = False
    for i in range(32):
        if dist[i] < dist[i + 1]:
            ordered = False
    for i in range(33, n - 1):
        if dist[i] > dist[i + 1]:
            ordered = False
    if not ordered:
        best = -1
        for i in range(n):
            if (cand[i] != u_plan
                    and _admissible(U, Pw, p, cand[i], plan, ff, Ts, umax, thd_prev,
                                    wd_prev, tha, wa, scratch)
                    and (best < 0 or dist[i] < dist[best])):
                best = i
        return best
    b, a = 32, 33       # the nearest untried candidate of each run
    while b >= 0 or a < n:
        d = min(dist[b] if b >= 0 else np.inf, dist[a] if a < n else np.inf)
        lo = b
        while lo >= 0 and dist[lo] == d:
            lo -= 1
        for i in range(lo + 1, b + 1):      # this distance's candidates, by index
            if cand[i] != u_plan and _admissible(U, Pw, p, cand[i], plan, ff, Ts, umax,
                                                 thd_prev, wd_prev, tha, wa, scratch):
                return i
        hi = a
        while hi < n and dist[hi] == d:
            hi += 1
        for i in range(a, hi):              # visited in index order: cand[i - 1] was tried
            if (not (i > 33 and cand[i] == cand[i - 1])
                    and _admissible(U, Pw, p, cand[i], plan, ff, Ts, umax, thd_prev,
                                    wd_prev, tha, wa, scratch)):
                return i
        b, a = lo, hi
    return -1


@njit(cache=True)
def _safe_parameter(U, Pw, p, u0, u_plan, u_cap, ahead, plan, ff, Ts, umax,
                    thd_prev, wd_prev, tha, wa, scratch, cand, dist, n_bisect, kept):
    """``PlannedInterpolator._safe_parameter`` once ``u_plan`` is known to be
    inadmissible (the caller tries it first, inline): the admissible parameter in
    [u0, u_cap] nearest to ``u_plan`` (33 candidates back, the look-ahead ones,
    ``n_bisect`` bisections). Returns ``(u, shortened_or_lengthened)``. ``kept``
    (n_axes + 1,) receives C(u) and u where the point of the returned parameter was
    evaluated here (NaN as its last entry where it was not), so that the loop need not
    evaluate it again."""
    dim = kept.shape[0] - 1
    point = scratch[0]
    kept[dim] = np.nan
    step = max(u_plan - u0, 1e-12)
    delta = u_plan - u0            # np.linspace(u0, u_plan, 33)
    spacing = delta / 32
    for i in range(33):
        if spacing == 0:
            cand[i] = (i / 32) * delta + u0
        else:
            cand[i] = i * spacing + u0
    cand[32] = u_plan
    n = 33
    for i in range(ahead.shape[0]):
        x = u_plan + step * ahead[i]
        if u_cap < x:              # np.minimum
            x = u_cap
        if x > u_plan:
            cand[n] = x
            n += 1
    best = _nearest_admissible(U, Pw, p, u_plan, cand, dist, n, plan, ff, Ts, umax,
                               thd_prev, wd_prev, tha, wa, scratch)
    if best < 0:
        return u_plan, False       # cornered: no step helps; keep to the plan
    good = cand[best]
    bad = cand[best + 1] if cand[best] < u_plan else cand[best - 1]
    for _ in range(n_bisect):
        mid = 0.5 * (good + bad)
        if _admissible(U, Pw, p, mid, plan, ff, Ts, umax, thd_prev, wd_prev, tha, wa,
                   scratch):
            good = mid
            for c in range(dim):
                kept[c] = point[c]
            kept[dim] = mid
        else:
            bad = mid
    return good, True


@njit(cache=True, inline="always")
def _planned_step(U, Pw, p, u, sc, tables, plan, thd_prev, wd_prev, tha, wa, bounds_row,
                  work, scratch, cand, dist, kept, nodes, d2):
    """``PlannedInterpolator.step`` from ``u`` < 1: ``(u_new, feed, has_bounds)``; the
    schedule index, arc length and slow-down count advance in ``sc``; ``kept`` as in
    :func:`_safe_parameter` (its last entry NaN without the safety layer)."""
    plan_s = tables[T_PLAN_S]
    scalars = tables[T_SCALARS]
    umax, ff, Ts, safety = scalars[0], scalars[1] != 0.0, scalars[2], scalars[3] != 0.0
    last = plan_s.shape[0] - 1
    phi_prev = sc[S_PHI]
    phi = min(phi_prev + 1.0, float(last))
    u_plan, s_new = _schedule_at(phi, plan_s, tables[T_PLAN_U], tables[T_SPEED_RIGHT],
                                 tables[T_SPEED_LEFT])
    u_new = u_plan
    kept[kept.shape[0] - 1] = np.nan
    if safety:
        for j in range(tha.shape[0]):   # eq. 3.6, as ControlLaw.speed_bounds
            v = (plan[P_KP, j] * (thd_prev[j] - tha[j]) - plan[P_KD, j] * wa[j]
                 - plan[P_KA, j] * wd_prev[j])
            bounds_row[j, 0] = (-umax - v) / plan[P_KSIG, j]
            bounds_row[j, 1] = (umax - v) / plan[P_KSIG, j]
        if _admissible(U, Pw, p, u_plan, plan, ff, Ts, umax, thd_prev, wd_prev, tha, wa,
                       scratch):
            # the planned setpoint is within bounds (the common case, kept inline)
            point = scratch[0]
            dim = point.shape[0]
            for c in range(dim):
                kept[c] = point[c]
            kept[dim] = u_plan
            u_new = max(u_plan, u)
        else:
            caps = tables[T_CAPS]
            u_cap = 1.0
            for i in range(caps.shape[0]):
                if caps[i] > u:
                    u_cap = caps[i]
                    break
            u_cap = max(u_cap, u_plan)
            safe, moved = _safe_parameter(U, Pw, p, u, u_plan, u_cap, tables[T_AHEAD],
                                          plan, ff, Ts, umax, thd_prev, wd_prev, tha, wa,
                                          scratch, cand, dist, int(scalars[4]), kept)
            if moved:
                sc[S_SLOWDOWNS] += 1.0
            u_new = max(safe, u)
    if u_new != u_plan:
        s_new = _arc_length(U, Pw, p, u_new, tables[T_TABLE_U], tables[T_TABLE_S],
                            tables[T_GL_X], tables[T_GL_W], work, nodes, d2)
        phi = _schedule_index(s_new, plan_s)
        phi = min(max(phi, phi_prev), float(last))
    sc[S_PHI] = phi
    feed = max((s_new - sc[S_S]) / Ts, 5e-324)
    sc[S_S] = s_new
    return u_new, feed, safety


@njit(cache=True)
def run_loop(U, Pw, p, breaks, kind, order, feed, plan, tables, start, end,
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
    cand = np.empty(33 + tables[T_AHEAD].shape[0])
    dist = np.empty_like(cand)
    kept = np.empty(dim + 1)
    nodes = np.empty(tables[T_GL_X].shape[0])
    d2 = np.empty((2, nodes.shape[0], dim))
    scratch = (np.empty(dim), np.empty((p + 1, p + 1)), np.empty(p + 1), np.empty(p + 1))
    ndu, bl, br = scratch[1], scratch[2], scratch[3]
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
            if kind == KIND_PLANNED:
                # never backwards; a hold (u_new == u) is a valid step of this stepper
                u_new, V, has_bounds = _planned_step(U, Pw, p, u, sc, tables, plan,
                                                     thd_prev, wd_prev, tha, wa,
                                                     bounds_row, work, scratch,
                                                     cand, dist, kept, nodes, d2)
            else:
                _derivatives(U, Pw, p, u, order, d3, work)
                V, A = _plan_feed(kind, feed, d, thd_prev, wd_prev, tha, wa, plan,
                                  bounds_row)
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
            elif kind == KIND_PLANNED and u_new == kept[dim]:
                u = u_new           # C(u_new) was evaluated by the safety layer
                for j in range(dim):
                    thd[j] = kept[j]
            else:
                u = u_new
                rational_point_into(U, Pw, p, u, thd, ndu, bl, br)
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
