"""The plant as it is on a machine: encoder counts, noise, delay, DAC, friction, load steps
and a two-mass resonance, as data for the one compiled loop.

An ideal machine's plant is the rigid axis of docs/model.md#servo-axis, read exactly, driven at
once (:mod:`nurbsmotion.servo`). A machine with any of the keys of issue 32 (see
:class:`nurbsmotion.machine.Machine` and :class:`~nurbsmotion.machine.Axis`) gets a plant
*stage* (:class:`PlantStage`, numbers only) that :func:`nurbsmotion.loop.closed_loop.run_samples`
runs in place of :func:`nurbsmotion.servo.plant_step`. Everything in it is exact, never
sub-stepped:

**Two-mass axis.** The motor (inertia share ``1 - lam``) and the load (``lam``, the
``load_fraction``) are joined by a spring and a damper; the viscous damping is split in
proportion to the inertia, so that the centre-of-mass motion obeys exactly the axis's
``tau*dw/dt = -w + Kc*v``, ``dtheta/dt = Ke*w``, and the relative coordinate
``delta = theta_motor - theta_load`` [pulse] is a decoupled damped oscillator::

    delta'' + 2*zeta*wn*delta' + wn^2*delta = Ke*Kc/((1 - lam)*tau) * v

with ``wn = 2*pi*resonance_frequency`` and ``zeta = resonance_damping`` exactly (the
damper is ``c = mu*(2*zeta*wn - 1/tau)``, ``mu = lam*(1 - lam)*tau``, which needs
``zeta >= 1/(2*wn*tau)``). The state per axis is ``x = [w_cm, theta_cm, delta, delta']``;
the motor is at ``theta_cm + lam*delta``, the load (the tool) at
``theta_cm - (1 - lam)*delta``. A rigid axis has ``delta = 0``. Both blocks have closed
forms for any interval (:func:`.two_mass._coefficients`); those of the two fixed intervals of a
sample are computed once.

**Delay.** The drive of sample k reaches the plant ``delay`` later:
``delay = n*Ts + h1``, so over ``[k*Ts, k*Ts + h1)`` the plant sees the drive of sample
``k - n - 1`` and over ``[k*Ts + h1, (k+1)*Ts)`` that of sample ``k - n`` (0 before the
start). Each of the two intervals is advanced exactly.

**Friction** acts on the motor (bearing, screw and guide friction reflected to it), as an
equivalent drive: sliding, ``v = u + d - coulomb*sign(w_motor)``; at rest, the motor
stays at rest while the net drive on it (drive, load step, spring and damper) is within
``max(stiction, coulomb)`` [V]. Between events the motion is the exact linear solution;
the instant the motor speed reaches zero inside an interval is found in closed form on a
rigid axis and by a safeguarded root find (Illinois regula falsi on the exact solution,
bracketed by checks every eighth of the mode's period) on a two-mass one; the breakaway of
a stuck two-mass motor (whose load still swings on the spring) likewise.

**Load steps** (``[[axes.disturbance]]``) add their drive from their instant ``at`` on,
splitting the interval they fall in.

**Measurement.** The controller reads the encoder's mass (motor or load): its position
plus seeded Gaussian noise (a counter-based generator: the draw of sample k, axis j
depends on ``seed``, k and j only) and, with ``encoder = "counts"``, in whole counts
zeroed at the start, ``start + floor(theta - start)``; its speed is differenced from
those readings (or, with ``speed_measurement = "true"``, the encoder mass's true speed).

**DAC.** The clipped drive is quantised to ``dac_bits`` over ``[-Umax, Umax)``: step
``q = 2*Umax/2**dac_bits``, levels ``q*i`` with ``-2**(bits-1) <= i < 2**(bits-1)``,
rounded to the nearest.

Glossary
--------
tau [s], Kc [(rad/s)/V], Ke [pulse/rad] : the axis (docs/model.md#servo-axis); lam : load fraction;
wn [rad/s], zeta : the mode; v : net drive [V]; h : an interval [s]; Ts : sample period.

The modules:

- :mod:`.two_mass`: the axis, rigid or two-mass, advanced exactly over an interval;
- :mod:`.friction`: stops and breakaways inside an interval (the friction element);
- :mod:`.stage`: the stage and its state as data, made from a machine's effect keys;
- :mod:`.step`: one sample of every axis (DAC, delay line, load steps) for the loop,
  and the stage open loop;
- :mod:`.sensor`: what the controller reads (noise, counts);
- :mod:`.linear`: the linear model and the closed loop's poles with delay and mode.
"""

from __future__ import annotations

from .._runtime.lazy import lazy_names

_LAZY = {
    "MAX_EVENTS": "friction", "SCRATCH": "friction", "TAYLOR_TERMS": "friction",
    "continuous_model": "linear", "linear_loop_poles": "linear",
    "x_minus_one_minus_exp": "linear",
    "measure": "sensor", "noise_draw": "sensor", "positions": "sensor",
    "IdleStage": "stage", "PlantStage": "stage", "PlantState": "stage",
    "inactive_stage": "stage", "is_active": "stage", "make_stage": "stage",
    "new_plant_state": "stage",
    "sample_step": "step", "stage_arrays": "step", "stage_response": "step",
    "N_COEF": "two_mass", "N_PARAM": "two_mass", "oscillator": "two_mass",
}
"""Public name -> the module of this package that holds it, loaded on first use (PEP 562):
a machine is checked with :mod:`.linear` alone, without numba, which the other modules
load."""

__all__ = ["oscillator", "PlantStage", "IdleStage", "is_active", "PlantState", "make_stage",
           "inactive_stage", "new_plant_state", "linear_loop_poles", "continuous_model",
           "stage_response", "stage_arrays", "sample_step", "measure", "noise_draw",
           "positions", "x_minus_one_minus_exp", "MAX_EVENTS", "SCRATCH", "TAYLOR_TERMS",
           "N_PARAM", "N_COEF"]

__getattr__, __dir__ = lazy_names(__name__, _LAZY)
