"""Figures of a run, written as PNG files (docs/model.md#run-figures; Figs. 5-7 of Yeh & Sun (2008)).

matplotlib is imported inside the functions, so ``import nurbsmotion`` never imports it.
Figures are built as :class:`matplotlib.figure.Figure` objects on an Agg canvas, without
pyplot: no global figure registry, no backend to select, nothing left open afterwards.
Every file is written through a temporary name and renamed when complete.

The package holds the canvas (:mod:`._canvas`: figure, saving, labels, legends, fitting
a view), the events and zoom windows a figure looks at (:mod:`.events`) and the figures
themselves (:mod:`.figures`); the public names are re-exported here.

What every figure follows:

- lengths in one report unit ``L`` (``"mm"`` or ``"in"``,
  :func:`nurbsmotion.units.report_unit`), speeds in ``L/s``, time in s, drive in V;
- every axis of the machine for drive and speed;
- the drive axis is framed on ±Umax (:data:`DRIVE_FRAME` × Umax); what lies outside is
  clipped, marked with triangles on the frame's edge, and its peak is written in the
  panel's title, so one outlier never sets the range;
- beside the whole run, time windows around the events that matter: the start, each
  sharp corner (at most :data:`MAX_EVENT_WINDOWS` of them, those with the largest drive),
  or, on a path without corners, the sample of largest drive, and the stop. A window spans
  the slowest axis's 2 % settling time of the closed loop after the event and half of it
  before (:func:`settling_time`, from the model: no tuned constant);
- legends sit outside the data (below the panels or at their right).

Glossary
--------
thd, tha : commanded and actual axis positions [pulse]; wd : commanded axis speed [rad/s];
wmin, wmax : speed bounds of eq. 3.6 [rad/s]; Ke : mechanical gain [pulse/rad];
u : drive before clipping [V]; Umax : drive limit [V]; F : commanded feed [pulse/s];
Ts : sample period [s]; k : pulses per report unit [pulse/L].
"""

from __future__ import annotations

from .events import MAX_EVENT_WINDOWS, settling_time
from .figures import (
    DRIVE_FRAME,
    SETPOINT_FIGURES,
    TRACE_FIGURES,
    comparison_figures,
    plot_comparison,
    plot_comparisons,
    plot_setpoints,
    plot_trace,
    prepare_trace,
    prepare_trace_steps,
)

__all__ = ["plot_trace", "prepare_trace", "prepare_trace_steps", "plot_setpoints",
           "plot_comparison", "plot_comparisons",
           "settling_time",
           "TRACE_FIGURES", "SETPOINT_FIGURES", "DRIVE_FRAME", "MAX_EVENT_WINDOWS",
           "comparison_figures"]
