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

A draw whose sampled loop is unstable (the machine refuses it) is drawn again. With
``real=True`` the machine as it is (counts, noise, delay, DAC, friction, a mode; issue 32)
is drawn too, from a stream of its own.
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


def _with_effects(machine: Machine, rng: np.random.Generator) -> Machine:
    """``machine`` as it is (issue 32): effects drawn from ``rng`` (module docstring)."""
    from dataclasses import replace

    umax, Ts = machine.max_drive, machine.sample_period
    axes = []
    for a in machine.axes:
        coulomb = float(rng.uniform(0.0, 0.05)) * umax
        keys = {"coulomb_friction": coulomb,
                "stiction": coulomb + float(rng.uniform(0.0, 0.03)) * umax}
        if rng.random() < 0.5:
            f = float(np.exp(rng.uniform(np.log(20.0), np.log(200.0))))
            lowest = 1.0 / (4.0 * np.pi * f * a.time_constant)
            keys.update(resonance_frequency=f,
                        resonance_damping=min(max(float(rng.uniform(0.01, 0.1)),
                                                  1.01 * lowest), 0.99),
                        load_fraction=float(rng.uniform(0.2, 0.8)),
                        encoder_on=str(rng.choice(["motor", "load"])))
        axes.append(replace(a, **keys))
    delay = float(rng.uniform(0.0, 0.5)) * Ts
    options = dict(axes=tuple(axes), encoder=str(rng.choice(["exact", "counts"])),
                   measurement_noise=float(rng.uniform(0.0, 1.0)),
                   seed=int(rng.integers(0, 2**31)),
                   dac_bits=[12, 14, 16, None][int(rng.integers(0, 4))])
    for _ in range(8):  # a delay its loop cannot take is halved until it can
        try:
            return machine.with_options(delay=delay, **options)
        except InvalidMachineError:
            delay *= 0.5
    return machine.with_options(delay=0.0, **options)


def random_machine(seed, n_axes: int = 2, *, real: bool = False) -> Machine:
    """A seeded random stable machine (module docstring).

    Parameters
    ----------
    seed : int, sequence of int or numpy.random.SeedSequence
        The same seed gives the same machine.
    n_axes : int
        1 to 3 axes (named x, y, z).
    real : bool
        Also draw the machine as it is (issue 32), from a generator of its own (the same
        seed gives the same axes and gains as without): the position read in counts or
        exactly, 0-1 pulse of noise, 0-0.5 Ts of delay (halved until the loop takes it),
        a 12-, 14-, 16-bit or no DAC; per axis Coulomb friction 0-5 % of Umax and
        stiction up to 3 % of Umax above it, and on half the axes a 20-200 Hz mode
        (damping 0.01-0.1, load fraction 0.2-0.8, encoder on the motor or the load).

    Raises
    ------
    ValueError
        For ``n_axes`` outside 1-3.
    """
    if n_axes not in (1, 2, 3):
        raise InvalidArgumentError(f"random machines have 1 to 3 axes, got {n_axes!r}")
    rng = np.random.default_rng(seed)
    # the effects' own stream (spawning does not draw from rng): same axes either way
    effects_rng = np.random.default_rng(rng.bit_generator.seed_seq.spawn(1)[0])
    for _ in range(MAX_DRAWS):
        try:
            machine = _draw(rng, n_axes)
        except InvalidMachineError:
            continue
        if not real:
            return machine
        return _with_effects(machine, effects_rng)
    raise RuntimeError(f"no stable machine in {MAX_DRAWS} draws")  # pragma: no cover
