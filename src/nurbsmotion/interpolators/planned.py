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

from ..control import ControlLaw
from ..errors import InfeasibleError
from ..machine import Machine
from ..nurbs import NurbsCurve
from ..planning import SpeedProfile, speed_profile
from .base import Interpolator, LoopState, Setpoint, Status

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


class PlannedInterpolator(Interpolator):
    """Look-ahead, jerk-limited, drive-limited interpolation with a real-time safety layer.

    Parameters
    ----------
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        The model the plan and the safety layer use (gains, tau, Kc, Ke, Umax, Ts).
    feed : float
        Commanded feed F [pulse/s], the speed limit along the path.
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

    def __init__(self, curve: NurbsCurve, machine: Machine, feed: float, *,
                 drive_margin: float = DEFAULT_DRIVE_MARGIN,
                 acceleration_margin: float = DEFAULT_ACCELERATION_MARGIN,
                 smoothing_time: float = DEFAULT_SMOOTHING_TIME, smoothing_passes: int = 0,
                 grid_size: int = 4000, max_samples: int = 10_000_000,
                 safety_layer: bool = True, check_iterations: int = 12,
                 model_uncertainty: float = DEFAULT_MODEL_UNCERTAINTY):
        machine.check_path(curve.n_axes)
        F = float(feed)
        if not (math.isfinite(F) and F > 0):
            raise InfeasibleError(f"feed must be finite and > 0, got {feed!r} pulse/s")
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
        self.law = ControlLaw(machine)
        super().__init__(curve, machine.sample_period)
        self.acceleration_margin = float(acceleration_margin)
        if not (0 < self.acceleration_margin <= 1):
            raise ValueError(f"acceleration_margin must lie in (0, 1], got {acceleration_margin!r}")
        self.profile = None
        if machine.max_drive == math.inf:
            # An ideal drive: only the feed limits the speed (accelerations are unbounded,
            # the smoothing alone shapes them).
            self._set_plan(self._schedule_unlimited(F, max_samples))
        else:
            self._plan_checked(F, grid_size, max_samples, check_iterations)
        self._caps = np.concatenate([curve.sharp_corners(), [1.0]])
        self.reset()

    def _plan_checked(self, F: float, grid_size: int, max_samples: int,
                      iterations: int) -> None:
        """Plan, run this stepper (safety layer included) in the closed loop of the model
        and of the mismatched plants, and ease the profile off before every sample where a
        drive exceeded Umax (where the safety layer was cornered); repeat."""
        from ..loop import simulate
        from ..servo import ServoPlant

        curve, m = self.curve, self.machine
        L = curve.length
        d = self.model_uncertainty
        plants = [(1.0 + a * d, 1.0 + b * d) for a, b in ((1, -1), (1, 1), (-1, -1), (-1, 1))]
        plants = ([(1.0, 1.0)] + plants) if d > 0 else [(1.0, 1.0)]
        n_grid = int(min(200_000, max(2000, 4 * L / (F * self.sample_period))))
        s_grid = np.linspace(0.0, L, n_grid)
        scale = np.ones(n_grid)
        self._caps = np.concatenate([curve.sharp_corners(), [1.0]])
        start = curve(0.0)
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
            bad_s = []
            for ts, ks in plants:
                plant = ServoPlant.of_machine(m, start, time_constant_scale=ts,
                                              electrical_gain_scale=ks)
                trace = simulate(self, m, plant=plant)
                over = np.nonzero(np.max(np.abs(trace.drive), axis=1) > m.max_drive)[0]
                if over.size:
                    s_tr = curve.arc_length(trace.u)
                    last = trace.finished_index
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
        self.reset()

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

    @property
    def planned_duration(self) -> float:
        """Time the schedule takes to reach the end, without safety slow-downs [s]."""
        return (len(self.plan_u) - 1) * self.sample_period

    def nominal_duration(self) -> float:
        return self.planned_duration

    # ---------------------------------------------------------------- online stepping
    def reset(self) -> None:
        self.u = 0.0
        self._phi = 0.0
        self._s = 0.0
        self.slowdowns = 0

    def _plan_step(self, state):  # pragma: no cover - step() is overridden
        raise NotImplementedError

    def _excess(self, u: np.ndarray, state: LoopState) -> np.ndarray:
        """max_j |u_j[k]| - Umax for candidate parameters ``u``, shape (n,) [V]."""
        drive, _ = self.law.drive(self.curve(u), state.position_command_prev,
                                  state.speed_command_prev, state.position, state.speed)
        return np.max(np.abs(drive), axis=-1) - self.machine.max_drive

    def _safe_parameter(self, u_plan: float, state: LoopState, u_cap: float) -> float:
        """The admissible parameter in [self.u, u_cap] nearest to ``u_plan``: its exact
        setpoint keeps every drive within Umax (predicted with the control law and the
        measured state, eq. 3.6). ``u_plan`` itself when it is within bounds or nothing in
        the range is.

        A shorter step than planned lowers the drive along the motion; a longer one (up to
        ``u_cap``, the next sharp corner or the end) lowers the braking drive, so an axis that
        lags behind a braking plan is not cornered: the setpoint goes ahead instead.
        """
        if self._excess(np.array([u_plan]), state)[0] <= 0.0:
            return u_plan
        u0 = self.u
        step = max(u_plan - u0, 1e-12)
        back = np.linspace(u0, u_plan, 33)
        ahead = np.minimum(u_plan + step * _AHEAD_FACTORS, u_cap)
        cand = np.concatenate([back, ahead[ahead > u_plan]])
        ok = self._excess(cand, state) <= 0.0
        if not np.any(ok):
            return u_plan  # cornered: no step helps; keep to the plan
        i = int(np.argmin(np.where(ok, np.abs(cand - u_plan), np.inf)))
        good = float(cand[i])
        bad = float(cand[i + 1]) if cand[i] < u_plan else float(cand[i - 1])
        for _ in range(_BISECTIONS):
            mid = 0.5 * (good + bad)
            if self._excess(np.array([mid]), state)[0] <= 0.0:
                good = mid
            else:
                bad = mid
        self.slowdowns += 1
        return good

    def _set_plan(self, plan_s: np.ndarray) -> None:
        """The schedule: arc length and parameter per sample, and ds/du at both sides of
        every planned parameter for the local inverse of :meth:`_at`."""
        self.plan_s = plan_s
        self.plan_u = self._parameters(plan_s)
        self._index = np.arange(len(plan_s), dtype=float)
        self._speed_right = np.linalg.norm(self.curve(self.plan_u, 1), axis=1)
        self._speed_left = np.linalg.norm(self.curve(self.plan_u, 1, "left"), axis=1)

    def _at(self, phi: float) -> tuple[float, float]:
        """(u, s) at the fractional schedule index ``phi`` (exact at whole indices).

        Between two planned samples u(s) is the cubic Hermite interpolant with the exact
        end slopes du/ds = 1/|C'(u)| (one-sided inward: corners and the end are planned
        samples): O(step^4) accurate, and never beyond the bracketing samples."""
        k = int(math.floor(phi))
        if phi == k or self.plan_s[k + 1] == self.plan_s[k]:
            return float(self.plan_u[k]), float(self.plan_s[k])
        s0, s1 = float(self.plan_s[k]), float(self.plan_s[k + 1])
        u0, u1 = float(self.plan_u[k]), float(self.plan_u[k + 1])
        h = s1 - s0
        t = phi - k  # the schedule is linear in phi between samples
        m0, m1 = h / self._speed_right[k], h / self._speed_left[k + 1]
        u = ((2 * t**3 - 3 * t**2 + 1) * u0 + (t**3 - 2 * t**2 + t) * m0
             + (-2 * t**3 + 3 * t**2) * u1 + (t**3 - t**2) * m1)
        return min(max(u, u0), u1), s0 + t * h

    def step(self, state: LoopState | None = None) -> Setpoint:
        """The next setpoint; ``state`` (the measured loop state) enables the safety layer.

        The schedule runs on a fractional sample index: normally it advances by one planned
        sample per step; after the safety layer has shortened a step, the index is set to
        the point reached, so that the schedule goes on from there at the planned pace
        (a shortened step slows the motion, it never makes it jump).
        """
        if self.finished:
            return Setpoint(1.0, self._end, 0.0, Status.FINISHED)
        last = len(self.plan_u) - 1
        phi = min(self._phi + 1.0, float(last))
        u_plan, s_new = self._at(phi)
        u_new = u_plan
        bounds = None
        if state is not None and math.isfinite(self.machine.max_drive) and self.safety_layer:
            bounds = self.law.speed_bounds(state.position_command_prev,
                                           state.speed_command_prev, state.position,
                                           state.speed)
            caps = self._caps[self._caps > self.u]
            u_cap = max(float(caps[0]) if caps.size else 1.0, u_plan)
            u_new = max(self._safe_parameter(u_plan, state, u_cap), self.u)
        if u_new != u_plan:
            s_new = float(self.curve.arc_length(u_new))
            phi = float(np.interp(s_new, self.plan_s, self._index))
            phi = min(max(phi, self._phi), float(last))
        self._phi = phi
        # the feed of this step: arc length covered over Ts (a hold reports the smallest
        # positive feed, so that the fluctuation metric shows it as a 100 % drop)
        feed = max((s_new - self._s) / self.sample_period, 5e-324)
        self._s = s_new
        if u_new >= 1.0:
            self.u = 1.0
            return Setpoint(1.0, self._end, feed, Status.FINISHED, bounds)
        self.u = u_new
        return Setpoint(self.u, self.curve(self.u), feed, Status.WORKING, bounds)
