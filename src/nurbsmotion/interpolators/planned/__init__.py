"""The ``planned`` interpolator: plan the actual motion, then steer the plant along it.

Offline (:func:`.plan.plan_motion`): the actual position of every sample,
time-optimal within the drive limit of the model's ZOH plant, on the path (or within the
corner tolerance of it), at rest at both ends and at every stop corner, together with the
feedforward drive u_ff[k] and plant state x_ff[k] = (w_ff, theta_ff) that make the model's
plant follow it exactly.

Online, every sample (:func:`online_step`, plain scalar/array code that numba compiles):

1. the plant's exact sampled model (pole a, and the drive's effect on the next two
   position increments, b1 and beta = c*b0 - a*b1) is identified by recursive least
   squares from the positions measured and the drives applied, starting from the model
   (:func:`_identify`; a linear regression exact for any tau and Kc); the deviation
   from the plan's state is the measured position's, and the speed's through the
   identified plant from the last position increment and drive;
2. a time-scaling governor advances the plan's clock by ``rate`` in (0, 1] samples. The
   *estimated* plant follows the plan at rate r with the drive ``ga*A*r^2 + gv*V*r``
   (A, V: the acceleration and speed parts of the plan's drive), which must stay within
   ``1 - drive_headroom`` of Umax (never below the plan's own use). Over the next
   :data:`RATE_WINDOW` plan samples a backward pass finds the largest rate of each sample
   from which the clock can still be slowed to the next samples' rates with the drive
   that is left (:func:`_window_rate`: slowing the clock slows the plant, and costs
   drive); beyond the window, up to the next stop, one uniform rate bounds it (the
   support function of the plan's drive there, :func:`_demand`). The governor moves the
   rate towards the window's, lowered further after a sample whose drive demand exceeded
   Umax, by at most ``1 - tracking_pole`` and at most what the drive left at the clock
   can change; the clock advances by the mean of the old and the new rate (the plant's
   speed moves between them over the sample). A weaker plant is thus slowed down where it
   must be, just before it accelerates or brakes, not over the whole way to the next stop;
3. the drive is the identified plant's drive from the plan's speed at the clock (times the
   rate it had) to the plan's speed at the next clock (times the new rate), both exact
   between samples (:func:`_plan_speed_at`), plus a state feedback on the deviation whose
   gains put both poles of the *identified* plant's deviation dynamics at
   ``tracking_pole`` (:func:`_pole_gains`; the identification regresses increments with
   an unknown drive, so a load or friction while the axis moves one way does not throw
   the estimate, and the speed estimate and the stop guards take that drive). With a
   known delay (under one sample) the deviation is taken at the state the drive will
   meet, predicted over the delay: the run is the plan, the delay late. Once the plan's
   clock has reached the plan's rest on the end, the identified plant is frozen and a law
   with an integral lands the axis on the end (step 3' of :func:`online_step`,
   :func:`.identify._landing_law`), on the error beyond what the reading can tell (half
   a count and 3 sigma of the noise). On an axis whose model declares a mode, both laws
   run on the model's plant with gains designed with the mode, its delay and the law's own
   speed estimate, stable with tau, Kc and the mode each 10 % off
   (:func:`.mode_law.mode_landing_law`). On a rigid axis whose model's reading is not
   exact (counts, noise), the landing's speed comes from an observer whose poles are the
   machine's own loop's slowest (:func:`.rest_observer.rest_observer`), not from one
   increment, and the landing's poles are slowed where the reading's own change between
   two samples would otherwise move the drive by more than the governor's headroom
   (:func:`.rest_observer.reading_pole`); on an axis with a mode and such a reading, from an observer designed into
   the mode law's loop where that law is no slower and stable through the counts
   (:func:`.mode_law.mode_rest_observer`). The drive is
   clipped to +-Umax: *every drive is within the limit by construction*, whatever the
   true plant. Once the plan moves an axis only towards a stop (a stop corner or the
   end), the drive also leaves the identified plant able to stop before it, braking at
   Umax from the next sample on, and keeps it so until the plan moves the axis on past
   it or the next stop comes (:func:`_stop_guards`, :func:`_short_of_stop`; the plan's
   own braking never needs more, so on the model's plant it changes nothing): a plant
   weaker or stronger than the model does not pass the end point or a stop corner;
4. the loop's law is affine in the setpoint between its clamps,
   ``u = slope*thd + offset`` with slope > 0 (:func:`nurbsmotion.control.pid_affine`,
   from the law's memory and the measured state), so the setpoint that produces exactly
   that drive is ``thd = (u - offset) / slope``; where a clamp or the deadband of the law
   (LinuxCNC ``pid``'s maxerror, deadband, ...) makes the drive differ, the setpoint is
   solved for on the law's own output (:func:`nurbsmotion.control.pid_output`, continuous
   and nondecreasing in the setpoint), and where a clamp makes that drive unreachable,
   moved until the output is within Umax (:func:`_setpoint_for`). Setpoints lead the path
   and need not lie on it; the actual position is what must.

Every sample's status says whether the governor slowed the plan or the drive was clipped
(``LIMITED``). The move is finished (``FINISHED``: the setpoint has arrived) once the
plan's clock reaches the plan's rest on the end; the step goes on steering after that
until the run ends.

Glossary
--------
u : drive [V] (and, for a :class:`Setpoint`, the curve parameter); thd : setpoint [pulse];
tha : measured position [pulse]; w : motor speed [rad/s]; Ts : sample period [s].

One module per idea: :mod:`.plan` (the offline plan, its steps 1-6 in its docstring) with
:mod:`.blend` (steps 1-2), :mod:`.inverse` (3), :mod:`.landing` (5) and :mod:`.shorten`
(6); the online step :mod:`.step` with :mod:`.identify` (its step 1), :mod:`.governor` (2)
and :mod:`.guards` (3), :mod:`.disturbance` (3, opt-in: a deadbeat disturbance observer fed
forward, its deviation rejected deadbeat), :mod:`.mode_law` and :mod:`.rest_observer` (3');
:mod:`.interpolator`:
the plan and state the step reads, and the interpolator, which registers the step with the
loop.
"""

from __future__ import annotations

from .governor import RATE_BISECTIONS, RATE_WINDOW, SUPPORT_BLOCK, SUPPORT_DIRECTIONS
from .identify import GAIN_RANGE, reading_knowledge
from .interpolator import (DEFAULT_DRIVE_HEADROOM, DEFAULT_TRACKING_POLE, PlannedInterpolator,
                           PlannedPlan, PlannedState, machine_knowledge)
from .plan import MotionPlan, plan_motion
from .step import DRIVE_MATCH, LANDING_ROWS, online_step, planned_step

__all__ = ["PlannedInterpolator", "PlannedPlan", "PlannedState", "online_step",
           "planned_step", "reading_knowledge", "machine_knowledge", "MotionPlan",
           "plan_motion",
           "DEFAULT_TRACKING_POLE", "DEFAULT_DRIVE_HEADROOM", "SUPPORT_DIRECTIONS",
           "SUPPORT_BLOCK", "RATE_WINDOW", "RATE_BISECTIONS", "GAIN_RANGE", "DRIVE_MATCH",
           "LANDING_ROWS"]
