"""Seeded random machines, for studies and test sweeps over plants nobody tuned for.

``random_machine(seed, n_axes=2)`` draws one stable :class:`~nurbsmotion.machine.Machine`
from ``numpy.random.default_rng(seed)`` (the same seed gives the same machine everywhere):

- sample period Ts: 0.1, 0.25, 0.5, 1 or 2 ms; drive limit Umax: 2-20 V;
- per axis, log-uniform: time constant tau 2-100 ms, Kc 20-500 (rad/s)/V, Ke 100-3000
  pulse/rad (steady speeds ``Umax*Kc*Ke`` from about 4e3 to 3e7 pulse/s);
- gains that place the continuous loop's poles at a natural frequency of 0.05-0.3 / Ts
  (at most 4 / tau) with damping 0.6-1.2: ``Kp = wn^2*tau/(Kc*Ke)``,
  ``Kd = max(2*zeta*wn*tau - 1, 0)/Kc``;
- law: PD+, PD or LinuxCNC ``pid`` (the same P and D, a feedforward of 0-100 % of PD+'s,
  an integral gain of 0, 5 or 20 % of ``Kp*wn``, and on a third of the axes each a
  0.5-pulse deadband and an integrator clamp of 5 pulse*s);
- speed measured by encoder differencing or taken true.

A draw whose sampled loop is unstable (the machine refuses it) is drawn again.
"""

from __future__ import annotations

import numpy as np

from .control import PidGains
from .errors import InvalidArgumentError, InvalidMachineError
from .machine import Axis, Machine

__all__ = ["random_machine"]

SAMPLE_PERIODS = (1e-4, 2.5e-4, 5e-4, 1e-3, 2e-3)
"""The sample periods drawn from [s]."""

MAX_DRAWS = 100
"""Draws before :func:`random_machine` gives up on finding a stable machine."""


def _draw(rng: np.random.Generator, n_axes: int) -> Machine:
    Ts = float(rng.choice(SAMPLE_PERIODS))
    controller = str(rng.choice(["pd+", "pd", "pid"]))
    axes = []
    for j in range(n_axes):
        tau, Kc, Ke = (float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
                       for lo, hi in ((2e-3, 0.1), (20.0, 500.0), (100.0, 3000.0)))
        wn = min(float(rng.uniform(0.05, 0.3)) / Ts, 4.0 / tau)
        zeta = float(rng.uniform(0.6, 1.2))
        Kp = wn**2 * tau / (Kc * Ke)
        Kd = max(2.0 * zeta * wn * tau - 1.0, 0.0) / Kc
        pid = None
        if controller == "pid":
            ff = float(rng.uniform(0.0, 1.0))
            rough = bool(rng.random() < 1 / 3)
            pid = PidGains(Pgain=Kp, Dgain=Kd / Ke,
                           Igain=Kp * wn * float(rng.choice([0.0, 0.05, 0.2])),
                           FF1=ff / (Kc * Ke), FF2=ff * tau / (Kc * Ke),
                           deadband=0.5 if rough else 0.0, maxerrorI=5.0 if rough else 0.0)
        axes.append(Axis("xyz"[j], tau, Kc, Ke, Kp, Kd, pid))
    return Machine(tuple(axes), max_drive=float(rng.uniform(2.0, 20.0)), sample_period=Ts,
                   controller=controller,
                   speed_measurement=str(rng.choice(["encoder", "true"])), name="random")


def random_machine(seed, n_axes: int = 2) -> Machine:
    """A seeded random stable machine (module docstring).

    Parameters
    ----------
    seed : int, sequence of int or numpy.random.SeedSequence
        The same seed gives the same machine.
    n_axes : int
        1 to 3 axes (named x, y, z).

    Raises
    ------
    ValueError
        For ``n_axes`` outside 1-3.
    """
    if n_axes not in (1, 2, 3):
        raise InvalidArgumentError(f"random machines have 1 to 3 axes, got {n_axes!r}")
    rng = np.random.default_rng(seed)
    for _ in range(MAX_DRAWS):
        try:
            return _draw(rng, n_axes)
        except InvalidMachineError:
            continue
    raise RuntimeError(f"no stable machine in {MAX_DRAWS} draws")  # pragma: no cover
