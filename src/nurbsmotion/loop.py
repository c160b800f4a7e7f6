"""The closed loop: interpolator, control law, saturation and plant, one sample at a time.

At sample k (t = k*Ts), in this order (SPEC sections 1 and 4):

1. the plant's position tha[k] is measured, and the speed wa[k] (encoder differencing,
   or the true motor speed);
2. the interpolator reads that :class:`~nurbsmotion.interpolators.LoopState` and returns
   the setpoint thd[k] (sample 0 is the path's start, the loop starts at rest there);
3. the control law gives u[k]; the actuator applies clip(u[k], -Umax, Umax) over
   [k*Ts, (k+1)*Ts), and the plant advances exactly (zero-order hold).

After the setpoint reaches the end, the loop goes on holding it for ``settle_time`` so the
stop and its transient are part of the trace.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .control import ControlLaw
from .budget import MAX_SAMPLES, check_samples, estimate_samples
from .errors import InfeasibleError, InvalidArgumentError
from .interpolators import (Interpolator, LoopState, PaperInterpolator,
                            PlannedInterpolator, Status, TaylorInterpolator,
                            make_interpolator)
from .machine import Machine
from .nurbs import NurbsCurve
from .servo import ServoPlant
from .stability import check_closed_loop_stable

__all__ = ["Trace", "simulate", "run", "check_run_arguments", "to_pulses"]


def to_pulses(curve: NurbsCurve, machine: Machine) -> NurbsCurve:
    """The path in the machine's pulses (a path in ``"mm"`` is scaled by pulses per mm)."""
    factor = machine.pulses_per_unit(curve.units)
    if factor == 1.0:
        return curve
    return curve.scaled(factor, units="pulse")


@dataclass(frozen=True, eq=False)
class Trace:
    """Everything the loop did, one row per sample k (t = k*Ts).

    Attributes
    ----------
    t : ndarray, shape (n_samples,)
        Sample times [s].
    u : ndarray, shape (n_samples,)
        Curve parameter of the setpoint.
    position_command : ndarray, shape (n_samples, n_axes)
        thd[k] [pulse].
    position : ndarray, shape (n_samples, n_axes)
        tha[k], measured before u[k] is applied [pulse].
    speed_command : ndarray, shape (n_samples, n_axes)
        wd[k] [rad/s].
    speed : ndarray, shape (n_samples, n_axes)
        wa[k] as the controller measured it [rad/s].
    drive : ndarray, shape (n_samples, n_axes)
        u[k] before clipping [V].
    drive_applied : ndarray, shape (n_samples, n_axes)
        u[k] after clipping [V].
    feed : ndarray, shape (n_samples,)
        Feed the interpolator commanded for the step into sample k [pulse/s].
    speed_bounds : ndarray, shape (n_samples, n_axes, 2) or None
        ``[wmin, wmax]`` of eq. 3.6 [rad/s] where the interpolator computes them
        (NaN at samples where it did not).
    finished_index : int
        First sample whose setpoint is the path's end.
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        The machine model.
    interpolator : str
        Name of the interpolator.
    """

    t: np.ndarray
    u: np.ndarray
    position_command: np.ndarray
    position: np.ndarray
    speed_command: np.ndarray
    speed: np.ndarray
    drive: np.ndarray
    drive_applied: np.ndarray
    feed: np.ndarray
    speed_bounds: np.ndarray | None
    finished_index: int
    curve: NurbsCurve
    machine: Machine
    interpolator: str

    @property
    def cycle_time(self) -> float:
        """Time at which the setpoint first reaches the path's end [s]."""
        return float(self.t[self.finished_index])

    def metrics(self):
        """The SPEC section 9 figures (:class:`nurbsmotion.metrics.Metrics`)."""
        from .metrics import trace_metrics

        return trace_metrics(self)

    def plot(self, out_dir, **kwargs):
        """Write the run's figures as PNG files (see :func:`nurbsmotion.plots.plot_trace`)."""
        from .plots import plot_trace

        return plot_trace(self, out_dir, **kwargs)


def simulate(
    interpolator: Interpolator,
    machine: Machine,
    *,
    plant: ServoPlant | None = None,
    settle_time: float = 0.05,
    max_samples: int | None = None,
    compiled: bool = True,
) -> Trace:
    """Run the closed loop from the path's start until ``settle_time`` after its end.

    Parameters
    ----------
    interpolator : Interpolator
        Any stepper; its curve must be in pulses (see :func:`to_pulses`).
    machine : Machine
        Gains, Umax and Ts of the controller (and the model of the plant).
    plant : ServoPlant, optional
        The true plant, when it differs from the model (e.g. tau and Kc off by 20 %);
        ``ServoPlant.of_machine(machine, start)`` by default.
    settle_time : float
        How long to go on holding the end point after the setpoint reaches it [s].
    max_samples : int, optional
        Safety limit against a stalled interpolator; by default twenty times the
        interpolator's :meth:`~nurbsmotion.interpolators.Interpolator.nominal_duration`
        plus ten seconds (or, where it has none, ten times the time at the slowest
        axis's full-drive speed plus ten seconds).
    compiled : bool
        Run the compiled loop (:mod:`nurbsmotion._loop_kernel`) where the interpolator
        has one: ``taylor1`` / ``taylor2`` at a constant feed, ``paper`` and ``planned``.
        It gives the
        same trace as the readable reference loop, which ``compiled=False`` (and any other
        interpolator) runs.

    Returns
    -------
    Trace

    Raises
    ------
    InfeasibleError
        If the interpolator cannot advance, or the end is not reached in ``max_samples``.
    """
    curve = interpolator.curve
    machine.check_path(curve.n_axes)
    Ts = machine.sample_period
    if abs(interpolator.sample_period - Ts) > 1e-15 * Ts:
        raise ValueError(f"interpolator sample period {interpolator.sample_period} s differs "
                         f"from the machine's {Ts} s")
    if not (math.isfinite(settle_time) and settle_time >= 0):
        raise ValueError(f"settle_time must be finite and >= 0, got {settle_time!r}")
    start = _start_point(interpolator, curve)
    if plant is None:
        plant = _model_plant(interpolator, machine, start)
    if max_samples is None:
        duration = interpolator.nominal_duration()
        if duration is None:
            slowest = (float(np.min(machine.max_axis_speed))
                       if math.isfinite(machine.max_drive) else 1e300)
            duration = curve.length / max(slowest, 1e-300)
            max_samples = int(10 * duration / Ts + 10 / Ts) + 10
        else:
            max_samples = int(20 * duration / Ts + 10 / Ts) + 10
    n_settle = int(round(settle_time / Ts))
    compiled_feed = _compiled_feed(interpolator) if compiled else None
    if compiled_feed is not None:
        return _simulate_compiled(interpolator, compiled_feed, machine, plant, start,
                                  n_settle, max_samples)
    law = ControlLaw(machine)
    encoder = machine.speed_measurement == "encoder"
    Ke_Ts = machine.Ke * Ts

    interpolator.reset()
    thd_prev = start.copy()
    wd_prev = np.zeros(machine.n_axes)
    tha_prev = plant.position.copy()
    rows_u, rows = [], []
    bounds_rows: list = []
    any_bounds = False
    finished_index = None
    k = 0
    while True:
        tha = plant.position.copy()
        wa = (tha - tha_prev) / Ke_Ts if encoder else plant.speed.copy()
        if k == 0:
            u_k, thd, feed, bounds = 0.0, start, 0.0, None
        else:
            sp = interpolator.step(LoopState(k, thd_prev, wd_prev, tha, wa))
            u_k, thd, feed, bounds = sp.u, sp.position, sp.feed, sp.speed_bounds
            if sp.status is Status.FINISHED and finished_index is None:
                finished_index = k
        drive, wd = law.drive(thd, thd_prev, wd_prev, tha, wa)
        applied = plant.saturate(drive)
        rows_u.append((u_k, feed))
        rows.append((thd, tha, wd, wa, drive, applied))
        bounds_rows.append(bounds)
        any_bounds |= bounds is not None
        plant.step(applied)
        thd_prev, wd_prev, tha_prev = thd, wd, tha
        if finished_index is not None and k >= finished_index + n_settle:
            break
        k += 1
        if k >= max_samples:
            raise InfeasibleError(
                f"{interpolator.name}: the path's end was not reached within {max_samples} "
                f"samples ({max_samples * Ts:g} s; u = {u_k:.6g})"
            )

    cols = [np.array(c) for c in zip(*rows)]
    u_arr, feed_arr = np.array(rows_u).T
    speed_bounds = None
    if any_bounds:
        nan = np.full((machine.n_axes, 2), np.nan)
        speed_bounds = np.array([nan if b is None else b for b in bounds_rows])
    return Trace(
        t=np.arange(len(u_arr)) * Ts,
        u=u_arr,
        position_command=cols[0],
        position=cols[1],
        speed_command=cols[2],
        speed=cols[3],
        drive=cols[4],
        drive_applied=cols[5],
        feed=feed_arr,
        speed_bounds=speed_bounds,
        finished_index=int(finished_index),
        curve=curve,
        machine=machine,
        interpolator=interpolator.name,
    )


def _start_point(interpolator: Interpolator, curve: NurbsCurve) -> np.ndarray:
    """``curve(0.0)`` (a copy), kept on the interpolator for the next run of its curve."""
    cached = interpolator.__dict__.get("_loop_start")
    if cached is None or cached[0] is not curve:
        cached = (curve, curve(0.0))
        interpolator._loop_start = cached
    return cached[1].copy()


def _model_plant(interpolator: Interpolator, machine: Machine,
                 start: np.ndarray) -> ServoPlant:
    """``ServoPlant.of_machine(machine, start)``; a copy of the one made for the last run
    with this machine (its ZOH matrices are only read), kept on the interpolator."""
    cached = interpolator.__dict__.get("_loop_plant")
    if cached is None or cached[0] is not machine:
        cached = (machine, ServoPlant.of_machine(machine, start))
        interpolator._loop_plant = cached
    return cached[1].at_rest(start)


_NO_TABLES: tuple = ()
_KERNEL = None


def _kernel():
    """:mod:`nurbsmotion._loop_kernel`, imported on first use (it loads numba)."""
    global _KERNEL
    if _KERNEL is None:
        from . import _loop_kernel
        _KERNEL = _loop_kernel
    return _KERNEL


def _compiled_feed(interpolator: Interpolator):
    """``(kind, feed, plan, tables)`` of the compiled loop for this interpolator, or
    ``None`` (see :mod:`nurbsmotion._loop_kernel`; a new kind of feed planner registers
    here).

    Only the exact classes qualify: a subclass may override the step.
    """
    kern = _kernel()

    if type(interpolator) is PlannedInterpolator:
        return kern.KIND_PLANNED, interpolator.feed, *_planned_tables(interpolator)
    global _NO_TABLES
    if not _NO_TABLES:
        _NO_TABLES = tuple(np.empty(0) for _ in range(kern.N_TABLES))
    no_tables = _NO_TABLES
    if type(interpolator) is TaylorInterpolator and interpolator._constant_feed is not None:
        return kern.KIND_CONSTANT, interpolator._constant_feed, np.empty((0, 0)), no_tables
    if type(interpolator) is PaperInterpolator:
        law = interpolator.law
        m = interpolator.machine
        rows = np.array([m.Kp, m.Kd, law._ka * np.ones(m.n_axes), law.drive_per_speed, m.Ke,
                         np.full(m.n_axes, m.max_drive)], dtype=float)
        return kern.KIND_PAPER, interpolator.feed, rows, no_tables
    return None


def _planned_tables(interpolator: PlannedInterpolator):
    """``plan`` and ``tables`` of :data:`nurbsmotion._loop_kernel.KIND_PLANNED`: the
    interpolator's model of the law per axis, its schedule and the arc-length table.

    Packed once per schedule and kept on the interpolator (a short run costs less than
    packing them): reused while the objects they come from are the same ones (a new
    schedule, curve, machine or safety switch packs them again; the kernel only reads
    them)."""
    key = (interpolator.plan_s, interpolator.plan_u, interpolator._speed_right,
           interpolator._speed_left, interpolator._caps, interpolator.curve,
           interpolator.machine, interpolator.law, interpolator.safety_layer,
           interpolator.sample_period)
    cached = interpolator.__dict__.get("_compiled_tables")
    if cached is not None and all(a is b for a, b in zip(cached[0], key)):
        return cached[1]
    packed = _pack_planned_tables(interpolator)
    interpolator._compiled_tables = (key, packed)
    return packed


def _pack_planned_tables(interpolator: PlannedInterpolator):
    from . import _loop_kernel as kern
    from .geometry import _GL_W, _GL_X
    from .interpolators.planned import _AHEAD_FACTORS, _BISECTIONS

    law, m = interpolator.law, interpolator.machine
    n = m.n_axes
    plan = np.empty((7, n))
    plan[kern.P_KP], plan[kern.P_KD], plan[kern.P_KE_TS] = m.Kp, m.Kd, law._Ke_Ts
    plan[kern.P_KC], plan[kern.P_TAU], plan[kern.P_KA] = m.Kc, m.tau, law._ka
    plan[kern.P_KSIG] = law.drive_per_speed
    geometry = interpolator.curve.geometry
    safety = interpolator.safety_layer and math.isfinite(m.max_drive)
    tables = [None] * kern.N_TABLES
    tables[kern.T_PLAN_S] = interpolator.plan_s
    tables[kern.T_PLAN_U] = interpolator.plan_u
    tables[kern.T_SPEED_RIGHT] = interpolator._speed_right
    tables[kern.T_SPEED_LEFT] = interpolator._speed_left
    tables[kern.T_CAPS] = interpolator._caps
    tables[kern.T_TABLE_U] = geometry._u
    tables[kern.T_TABLE_S] = geometry._s
    tables[kern.T_GL_X] = _GL_X
    tables[kern.T_GL_W] = _GL_W
    tables[kern.T_AHEAD] = _AHEAD_FACTORS
    tables[kern.T_SCALARS] = np.array([m.max_drive, 1.0 if law.feedforward else 0.0,
                                       interpolator.sample_period, 1.0 if safety else 0.0,
                                       float(_BISECTIONS)])
    return plan, tuple(np.ascontiguousarray(t, dtype=float) for t in tables)


def _machine_args(interpolator: Interpolator, machine: Machine) -> tuple:
    """The machine's arguments of :func:`nurbsmotion._loop_kernel.run_loop` (Kp .. PD+),
    kept on the interpolator for the next run on the same (frozen) machine."""
    cached = interpolator.__dict__.get("_loop_machine")
    if cached is None or cached[0] is not machine:
        Ts = machine.sample_period
        cached = (machine, (machine.Kp, machine.Kd, machine.Kc, machine.tau,
                            machine.Ke * Ts, Ts, machine.controller == "pd+"))
        interpolator._loop_machine = cached
    return cached[1]


def _simulate_compiled(interpolator, compiled_feed, machine, plant, start, n_settle,
                       max_samples) -> Trace:
    """:func:`simulate` through the compiled loop (``compiled_feed`` from
    :func:`_compiled_feed`); the same trace as the reference."""
    kern = _kernel()

    kind, feed, plan, tables = compiled_feed
    curve = interpolator.curve
    n_axes = curve.n_axes
    Ts = machine.sample_period
    interpolator.reset()
    # A first guess of the rows (capped, should a tiny feed promise an endless run); the
    # kernel stops when they are full and is resumed on grown rows.
    duration = interpolator.nominal_duration()
    if duration is None:
        duration = curve.length / feed
    guess = min(1.2 * duration / Ts + n_settle + 64, 1 << 22)
    capacity = max(1, int(min(max_samples, guess)))
    record_bounds = (kind == kern.KIND_PAPER
                     or (kind == kern.KIND_PLANNED and tables[kern.T_SCALARS][3] != 0.0))
    shape = (capacity, n_axes)
    rows = {
        "u": np.empty(capacity), "feed": np.empty(capacity),
        "thd": np.empty(shape), "tha": np.empty(shape), "wd": np.empty(shape),
        "wa": np.empty(shape), "drive": np.empty(shape), "applied": np.empty(shape),
        "bounds": np.empty((capacity if record_bounds else 0, n_axes, 2)),
    }
    sc = np.zeros(kern.N_STATE)
    sc[kern.S_FINISHED] = -1.0
    ax = np.empty((5, n_axes))
    ax[kern.A_THD] = start
    ax[kern.A_WD] = 0.0
    ax[kern.A_THA] = plant.position
    ax[kern.A_W] = plant.speed
    ax[kern.A_TH] = plant.position
    Ad, Bd = np.ascontiguousarray(plant._Ad), np.ascontiguousarray(plant._Bd)
    fixed = (curve.knots, curve._homogeneous, curve.degree, interpolator._breaks, kind,
             interpolator.order, float(feed), plan, tables, start, interpolator._end,
             *_machine_args(interpolator, machine), float(plant.max_drive), Ad, Bd,
             machine.speed_measurement == "encoder", n_settle, int(max_samples))
    while True:
        code = kern.run_loop(*fixed, sc, ax, *rows.values(), record_bounds)
        if code != kern.FULL:
            break
        capacity = min(2 * capacity, int(max_samples) + 1)
        for name, arr in rows.items():
            if arr.shape[0] > 0:
                arr.resize((capacity,) + arr.shape[1:], refcheck=False)
    k, u = int(sc[kern.S_K]), float(sc[kern.S_U])
    interpolator.u = u
    if kind == kern.KIND_PLANNED:
        interpolator._phi, interpolator._s = float(sc[kern.S_PHI]), float(sc[kern.S_S])
        interpolator.slowdowns = int(sc[kern.S_SLOWDOWNS])
    if code == kern.CANNOT_ADVANCE:
        raise InfeasibleError(
            f"{interpolator.name} interpolator cannot advance from u = {u:.9g} "
            f"(parameter step {float(sc[kern.S_ERR_DU])!r}, feed {float(sc[kern.S_ERR_FEED])!r})"
        )
    if code == kern.TOO_MANY_SAMPLES:
        raise InfeasibleError(
            f"{interpolator.name}: the path's end was not reached within {max_samples} "
            f"samples ({max_samples * Ts:g} s; u = {u:.6g})"
        )
    plant.speed, plant.position = ax[kern.A_W].copy(), ax[kern.A_TH].copy()
    for name, arr in rows.items():
        if arr.shape[0] > 0:
            arr.resize((k,) + arr.shape[1:], refcheck=False)
    return Trace(
        t=np.arange(k) * Ts,
        u=rows["u"],
        position_command=rows["thd"],
        position=rows["tha"],
        speed_command=rows["wd"],
        speed=rows["wa"],
        drive=rows["drive"],
        drive_applied=rows["applied"],
        feed=rows["feed"],
        speed_bounds=rows["bounds"] if record_bounds else None,
        finished_index=int(sc[kern.S_FINISHED]),
        curve=curve,
        machine=machine,
        interpolator=interpolator.name,
    )


def run(curve: NurbsCurve, machine: Machine, feed: float, interpolator: str = "paper",
        *, max_samples: int = MAX_SAMPLES, **simulate_options) -> Trace:
    """Run a path on a machine with a named interpolator.

    Parameters
    ----------
    curve : NurbsCurve
        The path, in any unit the machine knows (converted with :func:`to_pulses`).
    machine : Machine
    feed : float
        Commanded feed F [pulse/s].
    interpolator : str
        One of :data:`nurbsmotion.interpolators.LOOP_METHODS`.
    max_samples : int
        Refuse (:class:`~nurbsmotion.errors.WorkLimitError`) a move that would take more
        samples than this, before any work (:data:`nurbsmotion.budget.MAX_SAMPLES`).
    **simulate_options
        Passed to :func:`simulate` (``plant``, ``settle_time``, ``compiled``).

    Raises
    ------
    InvalidArgumentError, InvalidMachineError, WorkLimitError
        From :func:`check_run_arguments`, before any work.
    InfeasibleError
        If the interpolator cannot advance, or the loop diverges.
    """
    check_run_arguments(curve, machine, feed, max_samples)
    path = to_pulses(curve, machine)
    trace = simulate(make_interpolator(interpolator, path, machine, feed), machine,
                     **simulate_options)
    if not (np.all(np.isfinite(trace.position)) and np.all(np.isfinite(trace.drive))):
        raise InfeasibleError(
            f"the closed loop diverged (non-finite positions or drives) running "
            f"{interpolator} on machine {machine.name!r}")
    return trace


def check_run_arguments(curve, machine, feed, max_samples: int = MAX_SAMPLES, *,
                        option: str = "max_samples") -> None:
    """The checks :func:`run` makes before any work: typed errors naming the value.

    ``curve`` must be a :class:`NurbsCurve` and ``machine`` a :class:`Machine` with a
    stable closed loop (:func:`nurbsmotion.stability.check_closed_loop_stable`); ``feed``
    a finite number > 0 [pulse/s]; and the move at most ``max_samples`` samples long
    (:func:`nurbsmotion.budget.check_samples`; ``option`` names the way to raise it).
    """
    if not isinstance(curve, NurbsCurve):
        raise InvalidArgumentError(f"curve must be a NurbsCurve, got {curve!r:.60}")
    if not isinstance(machine, Machine):
        raise InvalidArgumentError(f"machine must be a Machine, got {machine!r:.60}")
    if isinstance(feed, (bool, np.bool_)) or not isinstance(feed, (int, float, np.integer,
                                                                 np.floating)):
        raise InvalidArgumentError(f"feed must be a number [pulse/s], got {feed!r:.60}")
    if not (math.isfinite(feed) and feed > 0):
        raise InvalidArgumentError(f"feed must be finite and > 0 [pulse/s], got {feed!r}")
    check_closed_loop_stable(machine)
    length = curve.length * machine.pulses_per_unit(curve.units)  # [pulse], cached
    check_samples(estimate_samples(length, float(feed), machine.sample_period),
                  limit=max_samples, n_axes=curve.n_axes,
                  what=f"a {length:.6g}-pulse move at {feed:g} pulse/s with Ts = "
                       f"{machine.sample_period:g} s", option=option)
