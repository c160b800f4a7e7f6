"""The law of :mod:`nurbsmotion.control`, one sample of one axis, compiled: LinuxCNC's
``calc_pid`` (:func:`pid_output`), the state it leaves (:func:`pid_commit`) and its affine
form in the command (:func:`pid_affine`), on the law's numbers
(:data:`~nurbsmotion.control.PID_LAW`) and memory (:data:`~nurbsmotion.control.PID_STATE`).
Runnable as plain Python (``NUMBA_DISABLE_JIT=1``).

Glossary
--------
See :mod:`nurbsmotion.control`.
"""

from __future__ import annotations

from numba import njit

__all__ = ["pid_output", "pid_commit", "pid_affine"]


@njit(cache=True, inline="always")
def _clamp(x, limit):
    """``x`` clamped to +-limit; ``limit == 0`` means no clamp (LinuxCNC's convention)."""
    if limit != 0.0:
        if x > limit:
            return limit
        if x < -limit:
            return -limit
    return x


@njit(cache=True, inline="always")
def pid_output(law, st, j, command, feedback, feedback_velocity):
    """``calc_pid`` for axis ``j``: the output before its limit and the state it leaves.

    Nothing is changed: :func:`pid_commit` stores the returned state, so an interpolator
    may evaluate any number of candidate commands.

    Parameters
    ----------
    law : ndarray, shape (n_axes,), dtype PID_LAW
    st : ndarray, shape (n_axes,), dtype PID_STATE
        The law's memory from the previous sample.
    j : int
        Axis.
    command, feedback : float
        Commanded and measured position [pulse].
    feedback_velocity : float
        Measured velocity [pulse/s] (read only with ``law.feedback_deriv``).

    Returns
    -------
    output : float
        The drive before the limit [V].
    error, error_i, cmd_d : float
        e [pulse], errorI [pulse*s] and cmdD [pulse/s] of this sample (the new state).
    """
    g, s = law[j], st[j]
    Ts = g["period"]
    e = _clamp(command - feedback, g["maxerror"])
    db = g["deadband"]
    if e > db:
        e -= db
    elif e < -db:
        e += db
    else:
        e = 0.0
    error_i = s["error_i"]
    if e * s["limit_state"] <= 0.0:
        error_i += e * Ts
    error_i = _clamp(error_i, g["maxerrorI"])
    cmd_d = _clamp((command - s["prev_cmd"]) / Ts, g["maxcmdD"])
    cmd_dd = _clamp((cmd_d - s["cmd_d"]) / Ts, g["maxcmdDD"])
    if g["feedback_deriv"] != 0.0:
        error_d = cmd_d - feedback_velocity
    else:
        error_d = (e - s["prev_error"]) / Ts
    error_d = _clamp(error_d, g["maxerrorD"])
    out = (g["bias"] + g["Pgain"] * e + g["Igain"] * error_i + g["Dgain"] * error_d
           + g["FF0"] * command + g["FF1"] * cmd_d + g["FF2"] * cmd_dd)
    return out, e, error_i, cmd_d


@njit(cache=True, inline="always")
def pid_commit(law, st, j, command, output, error, error_i, cmd_d):
    """Store the state :func:`pid_output` returned for the command that was applied."""
    g, s = law[j], st[j]
    s["prev_error"] = error
    s["error_i"] = error_i
    s["prev_cmd"] = command
    s["cmd_d"] = cmd_d
    umax = g["maxoutput"]
    s["limit_state"] = 1.0 if output > umax else (-1.0 if output < -umax else 0.0)


@njit(cache=True, inline="always")
def pid_affine(law, st, j, feedback, feedback_velocity):
    """The output of axis ``j`` as ``slope*command + offset`` between the clamps.

    With no clamp, deadband or frozen integrator active the output of :func:`pid_output`
    is exactly affine in the command, with the slope
    ``Pgain + Igain*Ts + Dgain/Ts + FF0 + FF1/Ts + FF2/Ts^2`` > 0 for any law that moves
    the axis (the integrator's term drops while it is frozen). For PD+ in terms of the
    speed command ``wd = (command - command_prev)/(Ke*Ts)`` this is eq. 3.6 of Yeh & Sun
    (2008): ``Ksig = slope*Ke*Ts`` and ``v = slope*command_prev + offset``.

    Returns
    -------
    slope : float
        [V/pulse]
    offset : float
        [V]
    """
    g, s = law[j], st[j]
    Ts = g["period"]
    ki = g["Igain"] if s["limit_state"] == 0.0 else 0.0
    slope = (g["Pgain"] + ki * Ts + g["Dgain"] / Ts + g["FF0"] + g["FF1"] / Ts
             + g["FF2"] / (Ts * Ts))
    prev = s["prev_cmd"]
    # every term at command = 0, with the differences written about the previous command
    offset = (g["bias"] - g["Pgain"] * feedback
              + ki * (s["error_i"] - feedback * Ts)
              - g["FF1"] * prev / Ts
              - g["FF2"] * (prev / Ts + s["cmd_d"]) / Ts)
    if ki == 0.0:
        offset += g["Igain"] * s["error_i"]
    if g["feedback_deriv"] != 0.0:
        offset -= g["Dgain"] * (prev / Ts + feedback_velocity)
    else:
        offset -= g["Dgain"] * (feedback + s["prev_error"]) / Ts
    return slope, offset
