"""The results of a run (:mod:`nurbsmotion.loop`): :class:`RunOutcome`, what a closed-loop
run did without its rows (a streamed run's result); :class:`Trace`, the same with every
sample's row (position, speed, drive, feed, status, ...), with ``.metrics()``,
``.at_rest()`` and ``.plot()`` handing it to :mod:`nurbsmotion.metrics` and
:mod:`nurbsmotion.plots`; and :class:`SetpointSeries`, the setpoints of an open-loop
interpolation. Data only: the runs that make them are in :mod:`nurbsmotion.loop`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..machine import Machine
from ..nurbs import NurbsCurve

__all__ = ["RunOutcome", "Trace", "SetpointSeries"]


@dataclass(frozen=True, eq=False)
class RunOutcome:
    """What a closed-loop run did, without its rows: the result of a streamed run
    (:func:`simulate_streamed`, whose rows went to a sink), and the first attributes of
    a :class:`Trace`.

    Attributes
    ----------
    n_samples : int
        Samples run.
    finished_index : int
        First sample whose setpoint is the path's end.
    settled_index : int or None
        First sample from which the actual position stays within ``settle_window`` of the
        end point to the end of the run, or ``None`` if it did not settle.
    settle_window : float
        The settle window [pulse].
    success : bool
        The motion settled at the end with every drive within Umax.
    message : str
        What happened, in one line.
    curve : NurbsCurve
        The path [pulse].
    machine : Machine
        The machine model.
    interpolator : str
        Name of the interpolator.
    notes : tuple of str
        What the interpolator says of how it ran the path (its ``notes``, e.g. that the
        ``planned`` motion stops at the sharp corners because rounding them within the
        corner tolerance would not arrive sooner); also at the end of ``message``.
    hold_samples : int
        The samples the run went on after it had settled (:data:`HOLD_TIME`), 0 on an
        ideal plant by default.
    """

    n_samples: int
    finished_index: int
    settled_index: int | None
    settle_window: float
    success: bool
    message: str
    curve: NurbsCurve
    machine: Machine
    interpolator: str
    notes: tuple
    hold_samples: int

    @property
    def cycle_time(self) -> float:
        """Time at which the setpoint first reaches the path's end [s]."""
        return self.finished_index * self.machine.sample_period


@dataclass(frozen=True, eq=False)
class Trace(RunOutcome):
    """Everything the loop did, one row per sample k (t = k*Ts): the attributes of
    :class:`RunOutcome` (``n_samples``, ``finished_index``, ``settled_index``,
    ``settle_window``, ``success``, ``message``, ``curve``, ``machine``,
    ``interpolator``, ``notes``, ``hold_samples``), and the rows.

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
    status : ndarray, shape (n_samples,), int8
        What the interpolator did at each sample (:class:`nurbsmotion.stepping.Status`):
        working, finished, limited (a step changed to keep the drive within Umax) or
        cornered (no admissible step: the drive exceeds Umax).
    position_measured : ndarray, shape (n_samples, n_axes), or None
        What the controller read of the position [pulse] on a true plant with effects
        (counts, noise, the encoder on the motor of a two-mass axis); ``position`` is then
        the tool's true position. ``None`` on an ideal plant, where the two are one.
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
    status: np.ndarray
    position_measured: np.ndarray | None = None

    def metrics(self):
        """The docs/model.md#run-figures figures (:class:`nurbsmotion.metrics.Metrics`)."""
        from ..metrics import trace_metrics

        return trace_metrics(self)

    def at_rest(self, window: int | None = None):
        """What the machine did at rest and at its peaks, on the tool's true position
        (:class:`nurbsmotion.metrics.AtRest`)."""
        from ..metrics import trace_at_rest

        return trace_at_rest(self, window)

    def plot(self, out_dir, **kwargs):
        """Write the run's figures as PNG files (see :func:`nurbsmotion.plots.plot_trace`)."""
        from ..plots import plot_trace

        return plot_trace(self, out_dir, **kwargs)


@dataclass(frozen=True)
class SetpointSeries:
    """The setpoint stream of an open-loop interpolation, one row per sample.

    Attributes
    ----------
    t : ndarray, shape (n_samples,)
        Sample times k*Ts [s]; row 0 is the start, at rest.
    u : ndarray, shape (n_samples,)
        Curve parameter.
    position : ndarray, shape (n_samples, n_axes)
        Setpoints C(u) [path units].
    feed : ndarray, shape (n_samples,)
        Feed commanded for the step into each sample [path units/s] (0 at row 0).
    sample_period : float
        Ts [s].
    finished_index : int
        First row at the path's end.
    """

    t: np.ndarray
    u: np.ndarray
    position: np.ndarray
    feed: np.ndarray
    sample_period: float
    finished_index: int

    @property
    def cycle_time(self) -> float:
        """Time at which the setpoint first reaches the path's end [s]."""
        return float(self.t[self.finished_index])

    def feed_fluctuation(self) -> tuple[float, float]:
        """docs/model.md#run-figures: ``(|thd[k] - thd[k-1]|/Ts - Vcmd[k]) / Vcmd[k]``, (max |.|, RMS).

        Taken over the full steps 1 .. finished_index - 1: the last step is cut short to
        land on the end exactly, so it is not a fluctuation.
        """
        from ..metrics import feed_fluctuation

        return feed_fluctuation(self.position, self.feed, self.sample_period,
                                self.finished_index)

    def plot(self, out_dir, **kwargs):
        """Write ``setpoints.png`` (see :func:`nurbsmotion.plots.plot_setpoints`)."""
        from ..plots import plot_setpoints

        return plot_setpoints(self, out_dir, **kwargs)
