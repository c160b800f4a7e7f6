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
``real=True`` the machine as it is (issue 32, in the ranges of issue 33's item 4) is drawn
too, from a stream of its own:

- the position read in whole counts of 0.1-10 um (log-uniform ``pulse_length_um``; in the
  loop a count is one pulse, so the count's size against the motion is Ke, drawn above,
  and the size in um sets only the length units), 0-0.5 count of noise (standard
  deviation), 0-0.6 Ts of delay, a 12-, 14-, 16-bit or no DAC;
- per axis, Coulomb friction 0-5 % of Umax and stiction up to 3 % of Umax above it;
- on half the axes a mode of :data:`MODE_FREQUENCIES` (log-uniform) with damping 0.01-0.1
  above the axis's own viscous share ``1/(4*pi*f*tau)`` (at the frequency
  :data:`MODEL_MODE_ERROR` lower); a mode that share would damp critically leaves the
  axis rigid; load fraction 0.2-0.8, encoder on the motor or the load.

A draw whose loop is unstable with its delay (the machine refuses it) or with its modes
(:meth:`nurbsmotion.machine.Machine.mode_loop_poles`: no interpolator could settle on it)
is drawn again: a machine's maker tunes its gains for its delay and its mechanics.
:func:`random_model` gives what the controller of such a machine knows of it.

Glossary
--------
Ts : sample period [s]; Umax : drive limit [V]; tau : time constant [s]; f : mode
frequency [Hz].
"""

from __future__ import annotations

import warnings

import numpy as np

from .control import PidGains
from .errors import InvalidArgumentError, InvalidMachineError
from .machine import Axis, Machine, UnstableModeWarning

__all__ = ["random_machine", "random_model", "MODE_FREQUENCIES", "MODEL_MODE_ERROR"]

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


MODE_FREQUENCIES = (30.0, 300.0)
"""Range of a random real axis's mode [Hz] (log-uniform; issue 33, item 4)."""

MODEL_MODE_ERROR = 0.1
"""A known mode is known to the model within this relative error of its frequency."""


def _lowest_damping(frequency: float, time_constant: float) -> float:
    """The least damping ratio a two-mass axis of this mode and tau has: the axis's own
    viscous damping (:class:`nurbsmotion.machine.Axis`)."""
    return 1.0 / (4.0 * np.pi * frequency * time_constant)


def _draw_effects(machine: Machine, rng: np.random.Generator) -> Machine:
    """``machine`` as it is (issue 32), effects drawn from ``rng`` (module docstring);
    raises :class:`InvalidMachineError` for a draw whose loop is unstable with its delay
    (the machine refuses it) or its modes (:meth:`Machine.mode_loop_poles`)."""
    from dataclasses import replace

    umax, Ts = machine.max_drive, machine.sample_period
    axes = []
    for a in machine.axes:
        coulomb = float(rng.uniform(0.0, 0.05)) * umax
        keys = {"coulomb_friction": coulomb,
                "stiction": coulomb + float(rng.uniform(0.0, 0.03)) * umax}
        if rng.random() < 0.5:
            f = float(np.exp(rng.uniform(*np.log(MODE_FREQUENCIES))))
            # the axis's own viscous damping is part of the mode's (at the frequency
            # MODEL_MODE_ERROR lower, so that a model that far off is an axis too); a
            # mode it would damp critically is no mode: the axis stays rigid
            damping = (_lowest_damping((1.0 - MODEL_MODE_ERROR) * f, a.time_constant)
                       + float(rng.uniform(0.01, 0.1)))
            shares = (float(rng.uniform(0.2, 0.8)), str(rng.choice(["motor", "load"])))
            if damping < 1.0:
                keys.update(resonance_frequency=f, resonance_damping=damping,
                            load_fraction=shares[0], encoder_on=shares[1])
        axes.append(replace(a, **keys))
    with warnings.catch_warnings():  # a draw unstable with its modes is drawn again
        warnings.simplefilter("ignore", UnstableModeWarning)
        real = machine.with_options(
            axes=tuple(axes), encoder="counts",
            pulse_length_um=float(np.exp(rng.uniform(np.log(0.1), np.log(10.0)))),
            measurement_noise=float(rng.uniform(0.0, 0.5)), seed=int(rng.integers(0, 2**31)),
            dac_bits=[12, 14, 16, None][int(rng.integers(0, 4))],
            delay=float(rng.uniform(0.0, 0.6)) * Ts)
    radius = max(float(np.max(np.abs(p))) for p in real.mode_loop_poles())
    if not radius < 1.0:
        raise InvalidMachineError(f"the loop with its modes has a pole of radius {radius:g}")
    return real


def random_model(machine: Machine, seed) -> Machine:
    """What the controller and the planner of a random real machine are told of it
    (issue 33, item 4): its reading (counts, their size, noise), delay and DAC as they
    are; no friction; each mode, with probability 1/2, unknown (a rigid axis) or known
    with its damping, load fraction and encoder but a frequency off by a factor drawn in
    ``1 +- MODEL_MODE_ERROR``.

    Parameters
    ----------
    machine : Machine
        A machine of :func:`random_machine` with ``real=True``.
    seed : int, sequence of int or numpy.random.SeedSequence
        The same seed and machine give the same model.

    Returns
    -------
    Machine
    """
    from dataclasses import replace

    rng = np.random.default_rng(seed)
    axes = []
    for a in machine.axes:
        keys = dict(coulomb_friction=0.0, stiction=0.0, disturbance=())
        known = bool(rng.random() < 0.5)
        factor = float(rng.uniform(1.0 - MODEL_MODE_ERROR, 1.0 + MODEL_MODE_ERROR))
        if a.resonance_frequency and known:
            keys["resonance_frequency"] = a.resonance_frequency * factor
        elif a.resonance_frequency:
            keys.update(resonance_frequency=0.0, resonance_damping=0.0, load_fraction=0.5,
                        encoder_on="motor")
        axes.append(replace(a, **keys))
    with warnings.catch_warnings():  # the true machine is stable with its modes; a
        # model whose mode is off by up to MODEL_MODE_ERROR need not be (what it knows)
        warnings.simplefilter("ignore", UnstableModeWarning)
        return machine.with_options(axes=tuple(axes))


def random_machine(seed, n_axes: int = 2, *, real: bool = False) -> Machine:
    """A seeded random stable machine (module docstring).

    Parameters
    ----------
    seed : int, sequence of int or numpy.random.SeedSequence
        The same seed gives the same machine.
    n_axes : int
        1 to 3 axes (named x, y, z).
    real : bool
        Also draw the machine as it is (module docstring), from a generator of its own
        (the same seed gives the same axes and gains as without).

    Raises
    ------
    InvalidArgumentError
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
        break
    else:
        raise RuntimeError(f"no stable machine in {MAX_DRAWS} draws")  # pragma: no cover
    for _ in range(MAX_DRAWS):
        try:
            return _draw_effects(machine, effects_rng)
        except InvalidMachineError:
            continue
    raise RuntimeError(f"no stable machine in {MAX_DRAWS} draws")  # pragma: no cover
