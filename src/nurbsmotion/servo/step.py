"""One exact zero-order-hold step of the servo plant of :mod:`nurbsmotion.servo`
(:func:`plant_step`), and :meth:`~nurbsmotion.servo.ServoPlant.response`'s loop, compiled
(runnable as plain Python, ``NUMBA_DISABLE_JIT=1``).

Glossary
--------
See :mod:`nurbsmotion.servo`.
"""

from __future__ import annotations

from numba import njit

__all__ = ["plant_step"]


@njit(cache=True)
def _respond(Ad, Bd, drive, max_drive, w, th):
    """:meth:`ServoPlant.response`'s loop, compiled: ``w[k + 1]``, ``th[k + 1]`` (each
    (n_samples + 1, n_axes), row 0 the start) from row k under ``drive[k]`` clipped to
    +-``max_drive`` (as :meth:`ServoPlant.saturate`), sample by sample."""
    for k in range(drive.shape[0]):
        for j in range(drive.shape[1]):
            applied = drive[k, j]
            if applied > max_drive:
                applied = max_drive
            elif applied < -max_drive:
                applied = -max_drive
            w[k + 1, j], th[k + 1, j] = plant_step(Ad, Bd, j, w[k, j], th[k, j], applied)


@njit(cache=True, inline="always")
def plant_step(Ad, Bd, j, speed, position, drive_applied):
    """One exact ZOH step of axis ``j``: ``(speed, position)`` one sample later.

    ``Ad``, ``Bd`` of shapes (n_axes, 2, 2) and (n_axes, 2); speed w [rad/s], position
    theta [pulse], the (clipped) drive held over the sample [V]."""
    w = Ad[j, 0, 0] * speed + Ad[j, 0, 1] * position + Bd[j, 0] * drive_applied
    th = Ad[j, 1, 0] * speed + Ad[j, 1, 1] * position + Bd[j, 1] * drive_applied
    return w, th
