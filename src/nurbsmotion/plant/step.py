"""One sample of the plant stage for every axis: the DAC, the delay line, the load
steps and each interval of constant drive (:func:`sample_step`, run by the compiled
loop), and the stage open loop under a drive sequence (:func:`stage_response`) (the
model: :mod:`nurbsmotion.plant`).

Glossary
--------
See :mod:`nurbsmotion.plant`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .two_mass import NO_COEFFICIENTS, TOOL, _coefficient_row, _params, _slide
from .friction import _advance_events, _friction_quiet
from .stage import PlantStage, PlantState, new_plant_state

__all__ = ["sample_step", "stage_arrays", "stage_response"]

@njit(cache=True)
def sample_step(P, C, F, DT, DD, dac_step, dac_levels, delay_samples, split, Ts, X, D, LINE,
                ND, k, drive, row, series):
    """Every axis over sample k: the DAC on its drive ``drive[row, j]`` [V] (clipped),
    the delay line, the load steps, and each interval of constant drive advanced exactly:
    by the precomputed coefficients when the axis has no friction or no friction event
    in it (:func:`_friction_quiet`), else by :func:`_advance_events`. The arguments
    before ``k`` are :func:`stage_arrays` (the stage's and its state's arrays and
    numbers); ``series`` (SCRATCH,) scratch.

    One call per sample for all axes, not inlined, and the axes' numbers go to the
    functions it calls as tuples: an array handed to a compiled function (inlined or
    not) costs an atomic reference count at the call and at the return, which here
    would cost more than the plant's arithmetic."""
    length = LINE.shape[1]  # delay_samples + 2: one wrap of an index suffices
    now = k % length  # one division per sample (an integer division costs tens of cycles)
    i_new = now - delay_samples
    if i_new < 0:
        i_new += length
    i_old = i_new - 1
    if i_old < 0:
        i_old += length
    t0 = k * Ts
    q = dac_step
    for j in range(X.shape[0]):
        applied = drive[row, j]
        if q > 0.0:
            level = math.floor(applied / q + 0.5)
            level = min(max(level, -dac_levels), dac_levels - 1.0)
            applied = level * q
        LINE[j, now] = applied
        new = LINE[j, i_new]
        old = LINE[j, i_old]
        p = _params(P, j)
        x = (X[j, 0], X[j, 1], X[j, 2], X[j, 3])
        d = D[j]
        friction = F[j]
        t = 0.0
        while t < Ts:
            if t < split:
                seg_start, seg_end, seg_which, u = 0.0, split, 0, old
            else:
                seg_start, seg_end, u = split, Ts, new
                seg_which = 1 if split > 0.0 else 0
            i = ND[j]
            at = DT[j, i] - t0
            if at <= t:  # a load step due now (or, by rounding, a hair before)
                ND[j] = i + 1
                continue
            load = DD[j, i - 1] if i > 0 else 0.0
            end = min(seg_end, at)
            which = seg_which if (t == seg_start and end == seg_end) else -1
            v = u + load
            h = end - t
            if which >= 0:
                cf = _coefficient_row(C, j, which)
                if not friction:  # the common case
                    x = _slide(p, cf, x, v)
                else:
                    quiet, x = _friction_quiet(p, cf, x, d, v, h)
                    if not quiet:
                        x, d = _advance_events(p, cf, friction, x, d, v, h, which, series)
            else:
                x, d = _advance_events(p, NO_COEFFICIENTS, friction, x, d, v, h, which,
                                       series)
            t = end
        X[j, 0] = x[0]
        X[j, 1] = x[1]
        X[j, 2] = x[2]
        X[j, 3] = x[3]
        D[j] = d


def stage_arrays(stage: "PlantStage", pstate: "PlantState") -> tuple:
    """The first arguments of :func:`sample_step`, from a stage and its state."""
    return (stage.param, stage.coef, stage.friction, stage.disturbance_time,
            stage.disturbance_drive, stage.dac_step, stage.dac_levels,
            stage.delay_samples, stage.split, stage.sample_period, pstate.x,
            pstate.direction, pstate.line, pstate.next_disturbance)


def stage_response(stage: PlantStage, drive, position=None):
    """Run the stage open loop under a drive sequence (tests, studies).

    Parameters
    ----------
    drive : ndarray, shape (n_samples, n_axes)
        Applied drive per sample [V] (before the DAC and the delay).
    position : array_like, shape (n_axes,), optional
        Start at rest [pulse]; 0 by default.

    Returns
    -------
    x : ndarray, shape (n_samples + 1, n_axes, 4)
        The state ``[w_cm, theta_cm, delta, delta']`` at every sample instant.
    tool : ndarray, shape (n_samples + 1, n_axes)
        The load's (the tool's) position [pulse].
    """
    drive = np.asarray(drive, dtype=float)
    n_axes = stage.param.shape[0]
    start = np.zeros(n_axes) if position is None else np.asarray(position, float)
    pstate = new_plant_state(stage, start)
    xs = np.empty((drive.shape[0] + 1, n_axes, 4))
    xs[0] = pstate.x
    args = stage_arrays(stage, pstate)
    for k in range(drive.shape[0]):
        sample_step(*args, k, drive, k, pstate.scratch)
        xs[k + 1] = pstate.x
    tool = xs[:, :, 1] + stage.param[:, TOOL] * xs[:, :, 2]
    return xs, tool
