"""Discrete PD and PD+ control laws (SPEC section 4) and the speed bound they imply.

The law at sample k (eq. 3.3 of Yeh & Sun 2008, with Ke restored), per axis::

    wd[k] = (thd[k] - thd[k-1]) / (Ke*Ts)          commanded motor speed [rad/s]
    ad[k] = (wd[k] - wd[k-1]) / Ts                 commanded motor acceleration [rad/s^2]
    u[k]  = Kp*(thd[k] - tha[k]) + Kd*(wd[k] - wa[k]) + wd[k]/Kc + tau*ad[k]/Kc     (PD+)
    u[k]  = Kp*(thd[k] - tha[k]) + Kd*(wd[k] - wa[k])                               (PD)

Given the past, u[k] is affine in the new speed command: ``u[k] = Ksig*wd[k] + v[k]``
(section 3.2), which gives the bound of eq. 3.6 on wd[k] for ``|u[k]| <= Umax``.

Glossary
--------
thd : commanded position [pulse]; tha : measured position [pulse]; wd, wa : commanded and
measured motor speed [rad/s]; u : drive [V]; Ksig : drive per unit speed command
[V/(rad/s)]; v : the part of u fixed by the past [V].
"""

from __future__ import annotations

import numpy as np

from .machine import Machine

__all__ = ["ControlLaw"]


class ControlLaw:
    """The discrete control law of a machine, vectorised over its axes.

    Parameters
    ----------
    machine : Machine
        Gains, plant parameters, Ts and the law (``machine.controller``).
    """

    def __init__(self, machine: Machine):
        self.machine = machine
        Ts = machine.sample_period
        self.feedforward = machine.controller == "pd+"
        self._Ke_Ts = machine.Ke * Ts
        ff = 1.0 if self.feedforward else 0.0
        # Section 3.2 with Ke: Ksig = Kp*Ke*Ts + Kd + 1/Kc + tau/(Kc*Ts) for PD+.
        self.drive_per_speed = (
            machine.Kp * machine.Ke * Ts
            + machine.Kd
            + ff * (1.0 / machine.Kc + machine.tau / (machine.Kc * Ts))
        )
        self._ka = ff * machine.tau / (machine.Kc * Ts)

    def speed_command(self, position_command, position_command_prev):
        """wd[k] [rad/s], shape (n_axes,) (or broadcast), from successive setpoints [pulse]."""
        return (np.asarray(position_command) - position_command_prev) / self._Ke_Ts

    def drive(self, position_command, position_command_prev, speed_command_prev, position, speed):
        """u[k] before saturation, eq. 3.3 (PD+) or eq. 2.4 (PD).

        Parameters
        ----------
        position_command : ndarray, shape (n_axes,)
            thd[k] [pulse].
        position_command_prev : ndarray, shape (n_axes,)
            thd[k-1] [pulse].
        speed_command_prev : ndarray, shape (n_axes,)
            wd[k-1] [rad/s].
        position : ndarray, shape (n_axes,)
            tha[k] [pulse].
        speed : ndarray, shape (n_axes,)
            wa[k] [rad/s].

        Returns
        -------
        drive : ndarray, shape (n_axes,)
            u[k] [V].
        speed_command : ndarray, shape (n_axes,)
            wd[k] [rad/s].
        """
        m = self.machine
        wd = self.speed_command(position_command, position_command_prev)
        u = m.Kp * (position_command - position) + m.Kd * (wd - speed)
        if self.feedforward:
            ad = (wd - speed_command_prev) / m.sample_period
            u = u + wd / m.Kc + m.tau * ad / m.Kc
        return u, wd

    def drive_offset(self, position_command_prev, speed_command_prev, position, speed):
        """v[k] of section 3.2, so that ``u[k] = drive_per_speed*wd[k] + v[k]`` [V]."""
        m = self.machine
        return (
            m.Kp * (position_command_prev - position)
            - m.Kd * speed
            - self._ka * speed_command_prev
        )

    def speed_bounds(self, position_command_prev, speed_command_prev, position, speed,
                     max_drive=None):
        """Eq. 3.6: the range of wd[k] that keeps ``|u[k]| <= Umax``.

        Returns
        -------
        ndarray, shape (n_axes, 2)
            ``[wmin, wmax]`` per axis [rad/s]; multiply by Ke for pulse/s.
        """
        umax = self.machine.max_drive if max_drive is None else max_drive
        v = self.drive_offset(position_command_prev, speed_command_prev, position, speed)
        return np.stack([(-umax - v), (umax - v)], axis=-1) / self.drive_per_speed[:, None]
