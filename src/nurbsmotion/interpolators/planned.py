"""A look-ahead interpolator that keeps every drive within its limit (beyond the paper).

Offline, before the motion (:class:`PlannedInterpolator`):

1. the drive-limited speed profile of :func:`nurbsmotion.planning.speed_profile`:
   backward/forward phase-plane passes against the feedforward drive
   ``|tau_j*xdd_j + xd_j| <= margin*Umax*Kc_j*Ke_j`` with ``V <= F`` and ``V = 0``
   at sharp corners and both ends, so the feed is already low where an axis must stop;
   the margin is ``drive_margin`` where the profile brakes and ``acceleration_margin``
   where it speeds up, and the rest of the drive is left to model error;
2. per corner-free piece, the profile in time s(t), stretched to a whole number of
   samples, then optionally smoothed by ``smoothing_passes`` moving averages of
   ``smoothing_time`` each (none by default: the safety layer bounds the drive, and
   smoothing costs 9-12 % of cycle time at 1-2 m/s on the Pi). A moving average of s(t) averages the speed and the acceleration, so a piece
   still starts and ends at rest at the same points, the acceleration becomes continuous
   (jerk-limited) after two passes, and the piece grows by ``smoothing_time`` per pass.
   The feedforward drive along a straight piece stays within the limit (it is linear in
   speed and acceleration); on curves the margin absorbs the difference;
3. s(t) sampled every Ts and mapped to the curve parameter; corners and the end are hit
   exactly;
4. a closed-loop check of the whole stepper, safety layer included: the loop is simulated
   with the model's plant and with the four plants whose tau and Kc are off by
   ``model_uncertainty`` (both signs), and wherever a drive exceeds Umax, i.e. wherever
   the safety layer was cornered, the profile's braking limit is eased off locally (a
   factor over the samples before the excess) and steps 1-3 repeat. Where the safety
   layer can keep the drive within Umax (speeding up, the feedback terms of the discrete
   PD+ loop, which lags the setpoint by about 1.5 samples) the plan is left as it is, so
   the plan may run at the full drive there; only braking needs a margin.

Online, every sample: the candidate setpoint is C(u_plan[k]) itself (not a tangent
estimate), and the drive it would cause is predicted with the PD / PD+ law and the measured
state (the exact form of eq. 3.6 of Yeh & Sun 2008; exact whatever the true plant is). If
any axis would exceed Umax, the step is changed to the admissible one nearest to the plan:
shorter where the drive pushes too hard, longer (never past the next sharp corner or the
end) where it brakes too hard, so that an axis lagging behind a braking plan is not
cornered; the schedule resumes from the reached point. The parameter never goes backwards;
the last step lands on u = 1.

Measured on the die-bonder Pi (Ts = 1 ms), defaults: cycle time 1.006, 1.032, 1.102 and
1.229 times the time-optimal bound at 0.2, 0.5, 1 and 2 m/s, zero saturated samples with
the nominal plant and with tau and Kc off by +-20 % (at most 1.281 x the bound then).

Glossary
--------
s : arc length [pulse]; u : curve parameter; F : commanded feed [pulse/s]; Ts : sample
period [s]; Umax : drive limit [V].
"""

from __future__ import annotations

import math

import numpy as np

from typing import NamedTuple

from numba import njit

from .. import closed_loop, stepping
from .._kernels import rational_derivatives_into
from ..control import pid_output, pid_state
from ..errors import InfeasibleError
from ..feed import FeedLimit
from ..geometry import _GL_W, _GL_X
from ..machine import Machine
from ..nurbs import NurbsCurve
from ..planning import SpeedProfile, speed_profile
from ..servo import ServoPlant
from .base import (Interpolator, PathData, PathScratch, path_data, path_point,
                   path_scratch, positive_feed, speed_bounds)

__all__ = ["PlannedInterpolator", "DEFAULT_DRIVE_MARGIN", "DEFAULT_ACCELERATION_MARGIN",
           "DEFAULT_MODEL_UNCERTAINTY", "DEFAULT_SMOOTHING_TIME"]

DEFAULT_DRIVE_MARGIN = 0.6
"""Fraction of Umax the plan may use where a drive brakes an axis, and on the maximum
velocity curve. Braking is where a model error can be cornered (the plant cannot stop in
the distance left), and a true plant with tau 20 % larger and Kc 20 % smaller than the
model needs up to 1.2/0.8 = 1.5 times the planned drive: 0.6 * 1.5 = 0.9 < 1. The
closed-loop check eases the profile further where it is still cornered. Measured on the
die-bonder Pi at 2 m/s: 0.6 gives 1.229 x the bound, 0.7 gives 1.242 and 0.8 gives 1.294
(a higher margin leaves more to the coarser easing of the check)."""

DEFAULT_ACCELERATION_MARGIN = 1.0
"""Fraction of Umax the plan may use where a drive pushes an axis along its motion. The
safety layer keeps the drive within Umax there by shortening the step (exactly, whatever
the true plant), so no margin is needed (0.9 gives 1.093 / 1.242 x the bound at 1 / 2 m/s
on the die-bonder Pi against 1.102 / 1.229: a wash)."""

DEFAULT_MODEL_UNCERTAINTY = 0.2
"""Relative error of tau and Kc (both signs) the closed-loop check guards against. Its
cost on the die-bonder Pi (cycle time / bound at 0.5, 1, 2 m/s): 1.032, 1.102, 1.229 with
0.2 against 1.022, 1.067, 1.177 with 0, which saturates 3, 9 and 11 samples when the true
plant has tau 20 % larger and Kc 20 % smaller."""

DEFAULT_SMOOTHING_TIME = 0.002
"""Width of each moving average of the profile [s]."""

# Closed-loop check: a cornered sample k is caused mostly by the braking of the dozen
# samples before it (the loop's error decays over ~10 ms), so the profile is eased off over
# [k - 12, k + 2] by a fixed factor per round (the excess of a cornered drive, often 2-5 x
# Umax, says little about how much earlier the braking must start).
_EASE_BEFORE, _EASE_AFTER, _EASE_FACTOR = 12, 2, 0.85
_OVERSAMPLE = 8  # fine time steps per sample when smoothing the profile
# Safety layer: the look-ahead candidates of a lengthened step, as multiples of the planned
# step (the compiled loop reads the same array).
_AHEAD_FACTORS = np.geomspace(0.05, 16.0, 24)
# Safety layer: bisections between the nearest admissible candidate and its inadmissible
# neighbour (the compiled loop is passed the same count); each one costs a prediction of
# the drive. The bracket of a shortened step starts at 1/32 of the planned step, so 12
# halvings leave 2^-17 of a step: on the die-bonder's Pi at 1-2 m/s and the butterfly at
# 0.2 m/s the setpoints stay within 0.17 pulse of those of 40 bisections, with the same
# cycle times (8 would move them by up to 2.8 pulses).
_BISECTIONS = 12


def _smooth(s: np.ndarray, start: float, end: float, width: int, passes: int) -> np.ndarray:
    """``passes`` moving averages of ``width`` fine samples, at rest before and after."""
    for _ in range(passes):
        padded = np.concatenate([np.full(width, start), s, np.full(width, end)])
        c = np.concatenate([[0.0], np.cumsum(padded - start)])
        s = start + (c[width:] - c[:-width]) / width
        s = s[1:]  # average over the window ending at each sample
    return s



_CHECK_SETTLE_TIME = 0.05
"""How long the offline closed-loop check goes on after the end [s]."""


class PlannedPlan(NamedTuple):
    """The schedule and the safety layer's data (see :class:`PlannedInterpolator`)."""

    path: PathData
    plan_s: np.ndarray          # (n,) arc length per planned sample [pulse]
    plan_u: np.ndarray          # (n,) curve parameter per planned sample
    speed_right: np.ndarray     # (n,) |C'(u)| from the right [pulse]
    speed_left: np.ndarray      # (n,) |C'(u)| from the left [pulse]
    caps: np.ndarray            # sharp corners and 1: a lengthened step stops there
    table_u: np.ndarray         # arc-length table of CurveGeometry: piece starts
    table_s: np.ndarray         # and cumulative lengths [pulse]
    gl_x: np.ndarray            # Gauss-Legendre nodes and weights on [-1, 1]
    gl_w: np.ndarray
    ahead: np.ndarray           # look-ahead candidates, multiples of the planned step
    mechanical_gain: np.ndarray  # Ke per axis [pulse/rad]
    safety: bool
    bisections: int


class PlannedState(NamedTuple):
    """The online state: the parameter reached, the fractional schedule index and the
    arc length reached [pulse] (shape (1,) each), and scratch."""

    u: np.ndarray
    phi: np.ndarray
    s: np.ndarray
    scratch: PathScratch
    candidates: np.ndarray
    distances: np.ndarray
    kept: np.ndarray            # (n_axes + 1,): C(u) and u last evaluated by the layer
    nodes: np.ndarray           # Gauss nodes of one arc-length evaluation
    node_derivatives: np.ndarray


class PlannedInterpolator(Interpolator):
    """Look-ahead, jerk-limited, drive-limited interpolation with a real-time safety layer.

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        The model the plan and the safety layer use (gains, tau, Kc, Ke, Umax, Ts).
    feed : float or FeedLimit
        Commanded feed F [pulse/s], the speed limit along the path (per piece: a
        :class:`nurbsmotion.feed.FeedLimit`).
    drive_margin : float
        Fraction of Umax, in (0, 1], the planned drive may use where it brakes an axis and
        on the maximum velocity curve (:data:`DEFAULT_DRIVE_MARGIN`). The rest is left to
        model error. Smaller is safer and slower.
    acceleration_margin : float
        Fraction of Umax, in (0, 1], the planned drive may use where it pushes an axis
        along its motion (:data:`DEFAULT_ACCELERATION_MARGIN`).
    smoothing_time : float
        Width of each moving average of the profile [s], >= 0 (rounded to Ts/8).
    smoothing_passes : int
        Number of moving averages (2 makes the acceleration continuous). None by default:
        the safety layer keeps the feedback terms within the drive, and two passes of
        2 ms cost 9-12 % of cycle time at 1-2 m/s on the die-bonder Pi (1.197 and 1.373 x
        the bound against 1.102 and 1.229), for a max contour error of 94-125 pulses
        instead of 198-220.
    grid_size : int
        Arc-length grid points of the offline profile.
    check_iterations : int
        Rounds of the offline closed-loop check: this stepper, safety layer included, is
        run in the loop of the model's plant and of the mismatched plants
        (``model_uncertainty``), and wherever a drive exceeds Umax the profile is eased off
        over the dozen samples before and replanned.
    model_uncertainty : float
        Relative error of tau and Kc, in [0, 1), the check guards against: the plants with
        tau and Kc scaled by ``1 +- model_uncertainty`` (four combinations) are simulated
        beside the model's (:data:`DEFAULT_MODEL_UNCERTAINTY`); 0 checks the model only.
    safety_layer : bool
        Shorten a step online when the exact predicted drive would exceed Umax (on by
        default; off only to study the plan alone).
    max_samples : int
        A plan longer than this many samples is refused (the drive is too weak or the feed
        too low for the path).

    Raises
    ------
    InfeasibleError
        If the feed is not finite and > 0, the drive cannot move along the path, or the
        plan would take more than ``max_samples`` samples.
    """

    name = "planned"
    order = 2
    records_bounds = True

    def __init__(self, curve: NurbsCurve, machine: Machine, feed: float, *,
                 drive_margin: float = DEFAULT_DRIVE_MARGIN,
                 acceleration_margin: float = DEFAULT_ACCELERATION_MARGIN,
                 smoothing_time: float = DEFAULT_SMOOTHING_TIME, smoothing_passes: int = 0,
                 grid_size: int = 4000, max_samples: int = 10_000_000,
                 safety_layer: bool = True, check_iterations: int = 12,
                 model_uncertainty: float = DEFAULT_MODEL_UNCERTAINTY):
        machine.check_path(curve.n_axes)
        # a per-piece limit goes to the speed profile; the lowest feed sizes the grids
        F = feed if isinstance(feed, FeedLimit) else positive_feed(feed)
        F_low = F.lowest if isinstance(F, FeedLimit) else F
        if not (0 < drive_margin <= 1):
            raise ValueError(f"drive_margin must lie in (0, 1], got {drive_margin!r}")
        if not (math.isfinite(smoothing_time) and smoothing_time >= 0):
            raise ValueError(f"smoothing_time must be finite and >= 0, got {smoothing_time!r}")
        if int(smoothing_passes) < 0:
            raise ValueError(f"smoothing_passes must be >= 0, got {smoothing_passes!r}")
        self.feed = F
        self.machine = machine
        self.drive_margin = float(drive_margin)
        self.smoothing_time = float(smoothing_time)
        self.smoothing_passes = int(smoothing_passes)
        self.safety_layer = bool(safety_layer)
        if not (0 <= model_uncertainty < 1):
            raise ValueError(f"model_uncertainty must lie in [0, 1), got {model_uncertainty!r}")
        self.model_uncertainty = float(model_uncertainty)
        super().__init__(curve, machine.sample_period)
        self.acceleration_margin = float(acceleration_margin)
        if not (0 < self.acceleration_margin <= 1):
            raise ValueError(f"acceleration_margin must lie in (0, 1], got {acceleration_margin!r}")
        self.profile = None
        self._caps = np.concatenate([curve.sharp_corners(), [1.0]])
        if machine.max_drive == math.inf:
            # An ideal drive: only the feed limits the speed (accelerations are unbounded,
            # the smoothing alone shapes them).
            self._set_plan(self._schedule_unlimited(F_low, max_samples))
        else:
            self._plan_checked(F, grid_size, max_samples, check_iterations)

    def _plan_checked(self, F: float, grid_size: int, max_samples: int,
                      iterations: int) -> None:
        """Plan, run this stepper (safety layer included) in the closed loop of the model
        and of the mismatched plants, and ease the profile off before every sample where a
        drive exceeded Umax (where the safety layer was cornered); repeat."""
        curve, m = self.curve, self.machine
        L = curve.length
        d = self.model_uncertainty
        plants = [(1.0 + a * d, 1.0 + b * d) for a, b in ((1, -1), (1, 1), (-1, -1), (-1, 1))]
        plants = ([(1.0, 1.0)] + plants) if d > 0 else [(1.0, 1.0)]
        F_low = F.lowest if isinstance(F, FeedLimit) else F
        n_grid = int(min(200_000, max(2000, 4 * L / (F_low * self.sample_period))))
        s_grid = np.linspace(0.0, L, n_grid)
        scale = np.ones(n_grid)
        start = curve(0.0)
        law = m.law()
        n_settle = int(round(_CHECK_SETTLE_TIME / self.sample_period))
        for it in range(iterations + 1):
            cur = scale.copy()
            self.profile = speed_profile(
                curve, m, F, drive_fraction=self.drive_margin,
                acceleration_fraction=self.acceleration_margin,
                drive_scale=lambda s: np.interp(s, s_grid, cur),
                # Cornering is a braking failure: ease the deceleration limit only, so the
                # profile still speeds up at the full acceleration margin until it meets
                # the earlier braking (easing both costs 1-2 samples at 1-2 m/s on the Pi).
                acceleration_scale=np.ones_like,
                grid_size=grid_size)
            self._set_plan(self._schedule(self.profile, max_samples))
            if it == iterations or not self.safety_layer:
                break
            n_plan = len(self.plan.plan_u)
            settling = closed_loop.Settling(self.plan.path.end, math.inf, n_settle, 0,
                                            n_settle, 20 * n_plan + 10 * n_settle)
            bad_s = []
            for ts, ks in plants:
                plant = ServoPlant.of_machine(m, start, time_constant_scale=ts,
                                              electrical_gain_scale=ks)
                code, rows, loop = closed_loop.run(
                    self.plan, self.new_state(), law, pid_state(start), plant,
                    m.speed_measurement == "encoder", start, settling, False,
                    n_plan + n_settle + 1)
                if code != closed_loop.DONE:
                    raise InfeasibleError("planned: the closed-loop check of the plan did "
                                          f"not reach the end (u = {loop.u[0]:.6g})")
                over = np.nonzero(np.max(np.abs(rows.drive), axis=1) > m.max_drive)[0]
                if over.size:
                    s_tr = curve.arc_length(rows.u)
                    last = int(loop.finished[0])
                    for k in over:
                        lo = float(s_tr[max(min(k, last) - _EASE_BEFORE, 0)])
                        hi = float(s_tr[min(k + _EASE_AFTER, last)])
                        bad_s.append((lo, hi))
                    break  # replan before trying the other plants
            if not bad_s:
                break
            for lo, hi in bad_s:
                sel = (s_grid >= lo) & (s_grid <= hi)
                scale[sel] = np.minimum(scale[sel], cur[sel] * _EASE_FACTOR)

    # ---------------------------------------------------------------- offline plan
    def _piece_samples(self, t: np.ndarray, s: np.ndarray, max_samples: int) -> np.ndarray:
        """s sampled every Ts along one piece (t from 0), stretched and smoothed."""
        Ts = self.sample_period
        dt = Ts / _OVERSAMPLE
        T = float(t[-1])
        n = max(1, int(math.ceil(T / Ts - 1e-9))) * _OVERSAMPLE
        width = int(round(self.smoothing_time / dt))
        total = n + self.smoothing_passes * width
        if total // _OVERSAMPLE > max_samples:
            raise InfeasibleError(
                f"the plan needs more than {max_samples} samples "
                f"({total * dt:.6g} s for one piece of the path); the drive is too weak or "
                "the feed too low for this path"
            )
        tf = np.arange(n + 1) * (T / n)  # stretched time: slower by at most one sample
        sf = np.interp(tf, t, s)
        if width > 0 and self.smoothing_passes > 0:
            sf = _smooth(sf, float(s[0]), float(s[-1]), width, self.smoothing_passes)
        # the smoothed piece has total + 1 fine points; fine index 0 is the piece's start
        idx = np.arange(0, total + 1, _OVERSAMPLE)
        out = sf[idx]
        out[-1] = s[-1]
        return np.maximum.accumulate(out)

    def _schedule(self, profile: SpeedProfile, max_samples: int) -> np.ndarray:
        parts = [np.array([0.0])]
        for (s, _, _), t in zip(profile.pieces, profile.piece_times()):
            if not np.all(np.isfinite(t)):
                raise InfeasibleError("the speed profile stops inside a piece of the path; "
                                      "the drive cannot move it there")
            parts.append(self._piece_samples(t, s, max_samples)[1:])
        return np.concatenate(parts)

    def _schedule_unlimited(self, F: float, max_samples: int) -> np.ndarray:
        ends = np.concatenate([[0.0], self.curve.sharp_corners(), [1.0]])
        s_ends = self.curve.arc_length(ends)
        parts = [np.array([0.0])]
        for s0, s1 in zip(s_ends[:-1], s_ends[1:]):
            t = np.array([0.0, (s1 - s0) / F])
            parts.append(self._piece_samples(t, np.array([s0, s1]), max_samples)[1:])
        return np.concatenate(parts)

    def _parameters(self, s_plan: np.ndarray) -> np.ndarray:
        """Curve parameter of every planned sample; corners and the end exactly."""
        curve = self.curve
        L = curve.length
        u = curve.parameter_at(np.clip(s_plan, 0.0, L))
        corners = curve.sharp_corners()
        if corners.size:
            s_c = curve.arc_length(corners)
            for uc, sc in zip(corners, s_c):
                u[np.abs(s_plan - sc) <= 1e-9 * L] = uc
        u[0] = 0.0
        u[-1] = 1.0
        return np.maximum.accumulate(u)


    def _set_plan(self, plan_s: np.ndarray) -> None:
        """The schedule as the step reads it: arc length and parameter per sample, |C'| at
        both sides of every planned parameter (for the local inverse of
        :func:`_schedule_at`), and what the safety layer needs."""
        curve, m = self.curve, self.machine
        plan_u = self._parameters(plan_s)
        geometry = curve.geometry
        self.plan = PlannedPlan(
            path=path_data(curve, self.order), plan_s=plan_s, plan_u=plan_u,
            speed_right=np.linalg.norm(curve(plan_u, 1), axis=1),
            speed_left=np.linalg.norm(curve(plan_u, 1, "left"), axis=1),
            caps=self._caps, table_u=geometry._u, table_s=geometry._s, gl_x=_GL_X,
            gl_w=_GL_W, ahead=_AHEAD_FACTORS, mechanical_gain=np.array(m.Ke, dtype=float),
            safety=bool(self.safety_layer and math.isfinite(m.max_drive)),
            bisections=_BISECTIONS)

    @property
    def plan_s(self) -> np.ndarray:
        """Arc length of every planned sample [pulse], shape (n_samples,)."""
        return self.plan.plan_s

    @property
    def plan_u(self) -> np.ndarray:
        """Curve parameter of every planned sample, shape (n_samples,)."""
        return self.plan.plan_u

    @property
    def planned_duration(self) -> float:
        """Time the schedule takes to reach the end, without safety slow-downs [s]."""
        return (len(self.plan.plan_u) - 1) * self.sample_period

    def nominal_duration(self) -> float:
        return self.planned_duration

    def new_state(self) -> PlannedState:
        p = self.plan
        n_axes = self.curve.n_axes
        n_gauss = p.gl_x.shape[0]
        n_cand = 33 + p.ahead.shape[0]
        return PlannedState(np.zeros(1), np.zeros(1), np.zeros(1), path_scratch(p.path),
                            np.empty(n_cand),
                            np.empty(n_cand), np.empty(n_axes + 1), np.empty(n_gauss),
                            np.empty((2, n_gauss, n_axes)))


# ------------------------------------------------------------------ the online step
@njit(cache=True)
def _schedule_at(phi, plan_s, plan_u, speed_right, speed_left):
    """``(u, s)`` at the fractional schedule index ``phi`` (exact at whole indices).

    Between two planned samples u(s) is the cubic Hermite interpolant with the exact end
    slopes du/ds = 1/|C'(u)| (one-sided inward: corners and the end are planned samples):
    O(step^4) accurate, and never beyond the bracketing samples."""
    k = int(math.floor(phi))
    if phi == k or plan_s[k + 1] == plan_s[k]:
        return plan_u[k], plan_s[k]
    s0, s1 = plan_s[k], plan_s[k + 1]
    u0, u1 = plan_u[k], plan_u[k + 1]
    h = s1 - s0
    t = phi - k  # the schedule is linear in phi between samples
    m0, m1 = h / speed_right[k], h / speed_left[k + 1]
    t2 = t * t
    t3 = t2 * t
    u = ((2 * t3 - 3 * t2 + 1) * u0 + (t3 - 2 * t2 + t) * m0
         + (-2 * t3 + 3 * t2) * u1 + (t3 - t2) * m1)
    return min(max(u, u0), u1), s0 + t * h


@njit(cache=True)
def _schedule_index(s, plan_s):
    """The fractional schedule index of arc length ``s`` (linear between samples)."""
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
    return j + (s - plan_s[j]) / (plan_s[j + 1] - plan_s[j])


@njit(cache=True)
def _arc_length(plan, u, state):
    """:meth:`nurbsmotion.geometry.CurveGeometry.arc_length` at one parameter: the table's
    length up to the piece that holds ``u`` plus 10-point Gauss-Legendre from the piece's
    start."""
    path = plan.path
    table_u = plan.table_u
    j = np.searchsorted(table_u, u, side="right") - 1
    j = min(max(j, 0), table_u.shape[0] - 2)
    a = table_u[j]
    half = 0.5 * (u - a)
    mid = 0.5 * (u + a)
    nodes, d = state.nodes, state.node_derivatives
    for i in range(plan.gl_x.shape[0]):
        nodes[i] = mid + half * plan.gl_x[i]
    rational_derivatives_into(path.knots, path.points, path.degree, nodes, 1, False, d,
                              state.scratch.work)
    dim = d.shape[2]
    acc = 0.0
    for i in range(nodes.shape[0]):
        n2 = 0.0
        for c in range(dim):
            n2 += d[1, i, c] * d[1, i, c]
        acc += math.sqrt(n2) * plan.gl_w[i]
    return plan.table_s[j] + half * acc


@njit(cache=True)
def _admissible(plan, uc, law, law_state, position, velocity, state):
    """The setpoint C(uc) keeps every predicted drive within Umax (the loop's law from
    its memory and the measured state, :func:`nurbsmotion.control.pid_output`); C(uc) is
    left in ``state.scratch.point``."""
    point = state.scratch.point
    path_point(plan.path, uc, point, state.scratch)
    umax = law[0]["maxoutput"]
    for j in range(point.shape[0]):
        drive = pid_output(law, law_state, j, point[j], position[j], velocity[j])[0]
        if not abs(drive) <= umax:
            return False
    return True


@njit(cache=True)
def _keep(state, u):
    """Remember the point just evaluated by :func:`_admissible` as C(u)."""
    kept = state.kept
    dim = kept.shape[0] - 1
    for c in range(dim):
        kept[c] = state.scratch.point[c]
    kept[dim] = u


@njit(cache=True)
def _nearest_admissible(plan, u_plan, n, law, law_state, position, velocity, state):
    """Index of the admissible candidate nearest to ``u_plan`` (the first on a tie), or
    -1. The distances fall along ``candidates[:33]`` (towards ``u_plan``) and rise along
    ``candidates[33:n]``, so a merge of the two runs visits them nearest first and stops
    at the first admissible one; should rounding break that order, every candidate is
    tried. ``u_plan`` itself is known to be inadmissible and is not tried again."""
    cand, dist = state.candidates, state.distances
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
                    and _admissible(plan, cand[i], law, law_state, position, velocity, state)
                    and (best < 0 or dist[i] < dist[best])):
                best = i
        return best
    b, a = 32, 33       # the nearest untried candidate of each run
    while b >= 0 or a < n:
        d = min(dist[b] if b >= 0 else np.inf, dist[a] if a < n else np.inf)
        lo = b
        while lo >= 0 and dist[lo] == d:
            lo -= 1
        for i in range(lo + 1, b + 1):
            if cand[i] != u_plan and _admissible(plan, cand[i], law, law_state, position,
                                                 velocity, state):
                return i
        hi = a
        while hi < n and dist[hi] == d:
            hi += 1
        for i in range(a, hi):
            if (not (i > 33 and cand[i] == cand[i - 1])
                    and _admissible(plan, cand[i], law, law_state, position, velocity,
                                    state)):
                return i
        b, a = lo, hi
    return -1


@njit(cache=True)
def _safe_parameter(plan, u0, u_plan, u_cap, law, law_state, position, velocity, state):
    """The admissible parameter in [u0, u_cap] nearest to ``u_plan`` (inadmissible):
    33 candidates back, the look-ahead ones, then bisections. Returns ``(u, found)``.

    A shorter step than planned lowers the drive along the motion; a longer one (up to
    ``u_cap``, the next sharp corner or the end) lowers the braking drive, so an axis that
    lags behind a braking plan is not cornered: the setpoint goes ahead instead."""
    cand = state.candidates
    step = max(u_plan - u0, 1e-12)
    delta = u_plan - u0
    for i in range(33):
        cand[i] = u0 + delta * (i / 32)
    cand[32] = u_plan
    n = 33
    for i in range(plan.ahead.shape[0]):
        x = min(u_plan + step * plan.ahead[i], u_cap)
        if x > u_plan:
            cand[n] = x
            n += 1
    best = _nearest_admissible(plan, u_plan, n, law, law_state, position, velocity, state)
    if best < 0:
        return u_plan, False       # cornered: no step helps; keep to the plan
    good = cand[best]
    bad = cand[best + 1] if cand[best] < u_plan else cand[best - 1]
    for _ in range(plan.bisections):
        mid = 0.5 * (good + bad)
        if _admissible(plan, mid, law, law_state, position, velocity, state):
            good = mid
            _keep(state, mid)
        else:
            bad = mid
    return good, True


@njit(cache=True)
def planned_step(plan, state, law, law_state, position, velocity, command, bounds):
    """The next setpoint: the planned sample, changed by the safety layer only where its
    exact predicted drive would exceed Umax; the contract of :mod:`nurbsmotion.stepping`.

    The schedule runs on a fractional sample index: normally it advances by one planned
    sample per step; after the safety layer has changed a step, the index is set to the
    point reached, so that the schedule goes on from there at the planned pace."""
    if state.u[0] >= 1.0:
        return stepping.hold_end(plan.path.end, command, bounds)
    u = state.u[0]
    last = plan.plan_s.shape[0] - 1
    phi_prev = state.phi[0]
    phi = min(phi_prev + 1.0, float(last))
    u_plan, s_new = _schedule_at(phi, plan.plan_s, plan.plan_u, plan.speed_right,
                                 plan.speed_left)
    u_new = u_plan
    status = stepping.WORKING
    state.kept[-1] = np.nan
    if plan.safety:
        speed_bounds(law, law_state, plan.mechanical_gain, position, velocity, bounds)
        if _admissible(plan, u_plan, law, law_state, position, velocity, state):
            _keep(state, u_plan)
            u_new = max(u_plan, u)
        else:
            u_cap = 1.0
            for i in range(plan.caps.shape[0]):
                if plan.caps[i] > u:
                    u_cap = plan.caps[i]
                    break
            u_cap = max(u_cap, u_plan)
            safe, found = _safe_parameter(plan, u, u_plan, u_cap, law, law_state, position,
                                          velocity, state)
            status = stepping.LIMITED if found else stepping.CORNERED
            u_new = max(safe, u)
    else:
        bounds[:] = np.nan
    if u_new != u_plan:
        s_new = _arc_length(plan, u_new, state)
        phi = min(max(_schedule_index(s_new, plan.plan_s), phi_prev), float(last))
    state.phi[0] = phi
    # the feed of this step: arc length covered over Ts (a hold reports the smallest
    # positive feed, so that the fluctuation metric shows it as a 100 % drop)
    feed = max((s_new - state.s[0]) / law[0]["period"], 5e-324)
    state.s[0] = s_new
    dim = command.shape[0]
    if u_new >= 1.0:
        u_new = 1.0
        for j in range(dim):
            command[j] = plan.path.end[j]
        status = stepping.FINISHED
    elif u_new == state.kept[dim]:
        for j in range(dim):
            command[j] = state.kept[j]
    else:
        path_point(plan.path, u_new, command, state.scratch)
    state.u[0] = u_new
    return u_new, feed, status


stepping.register(PlannedPlan, planned_step)
