"""The online step of ``planned`` (the package docstring, steps 1-4): :func:`online_step`
steers every axis along the plan with the identified plant, the governed clock and the stop
guards, and :func:`planned_step` turns its drives into the loop law's setpoints
(:func:`_setpoint_for`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ... import stepping
from ...control.step import pid_affine, pid_output
from .disturbance import (REJECTION_POLE, ROUNDING_FLOOR, _direction, _for_direction, _hold,
                          _made, _observe, _rejected)
from .governor import _demand, _rate_room, _support_at, _window_rate
from .guards import _guarded, _short_of_stop
from .mode_law import DOB_ROW
from .shaper import twist_at
from .identify import (LAW_ROWS, _delayed_zoh, _estimated_delayed_plant,
                       _estimated_plant, _identify, _landing_gains, _landing_law, _plant_part,
                       _pole_gains)
from .rest_observer import observer_gains, reading_pole

__all__ = ["online_step", "planned_step", "LANDING_ROWS"]

LANDING_ROWS = 8 + LAW_ROWS
"""Rows of the landing's state per axis (:func:`online_step`, step 3'): 1 once the landing
has begun, the law placed then on the identified plant (:func:`.identify._landing_law`,
rows 1-13), the integral of the error beyond the reading's band [pulse*samples], the
sign of the error at which the axis was last found stuck beyond :data:`HOLD_PULSES` of the
end (0: not since the integral's last reset; the stick-slip rule of step 3'), then the
rest law's observer (:data:`OBSERVER_ROW`)."""

OBSERVER_ROW = 3 + LAW_ROWS
"""The landing's rows from here: its speed observer on a reading not exact
(:mod:`.rest_observer`, step 3' of :func:`online_step`): the plant's speed [rad/s] and position [pulse] estimated at the last
sample, its two gains (speed, position) on the reading's innovation, and 1 on the
landing's first sample (the estimate is the reading's, not yet advanced)."""

HOLD_PULSES = 0.5
"""Beyond the reading's band, how far from the end [pulse] an axis held at rest by a drive
(stuck by friction the model does not know) is left alone by the landing's integral: half
a pulse, the rounding of the commanded position. Within it, the axis not moving and its
drive at least the law's at the hold's edge (k_theta*(band + HOLD_PULSES): more than the
error asks, so something the model does not know holds it), the integral holds (it would
otherwise wind the drive through zero to the opposite breakaway and hunt, stick-slip,
about the end); beyond it the integral goes on until the axis breaks away, and once the
error has crossed the end the integral, which carried the axis over it, is reset to zero
(the Coulomb friction and the law's damping stop it). A frictionless axis never rests
beyond it nor under such a drive, so on the model's own plant neither rule acts."""


@njit(cache=True)
def _plan_speed_at(drive_speed, drive_accel, phi, j, a, log_a, b0):
    """The plan's speed [rad/s] of axis j at clock ``phi`` [samples]: the model's plant
    from the plan's speed at sample i = floor(phi) under its drive there, over the fraction
    f = phi - i of a sample (ZOH, exact between samples: ``w(i + f) = a^f*w[i]
    + b0*(1 - a^f)/(1 - a)*u[i]``, with ``w[i] = Kc*V[i]``, ``Kc = b0/(1 - a)`` and
    ``u[i] = V[i] + A[i]``, the plan's drive parts; ``log_a = log(a)``)."""
    n = drive_speed.shape[0]
    i = min(int(phi), n - 1)
    f = phi - i if i < n - 1 else 0.0
    w_i = b0 / (1.0 - a) * drive_speed[i, j]
    if f <= 0.0:
        return w_i
    g = -math.expm1(f * log_a)                   # 1 - a^f
    return (1.0 - g) * w_i + b0 * g / (1.0 - a) * (drive_speed[i, j] + drive_accel[i, j])


@njit(cache=True)
def online_step(plan, state, position, umax, out_setpoint):
    """One sample of the planned interpolator (module docstring, steps 1-4).

    Plain loops over floats and float arrays, so that numba compiles it unchanged.

    Parameters
    ----------
    plan : PlannedPlan
        Read: ``position`` theta_ff, shape (n, n_axes) [pulse]; ``drive_speed`` and
        ``drive_accel``, shape (n, n_axes), the feedforward drive's speed part w_ff/Kc and
        acceleration part (w_ff[k+1]-w_ff[k])/b0 [V] (u_ff is their sum at rate 1);
        ``a, b0, c, b1``, shape (n_axes,), the model's ZOH plant
        (:func:`.inverse.axis_zoh`); ``log_a``, shape (n_axes,), log(a), for the plan's
        speed between samples (:func:`_plan_speed_at`); ``headroom``, the fraction of
        Umax the governor keeps for the feedback; ``rate_gain``, the largest change of
        the rate per sample (``1 - rate_gain`` is the tracking pole); ``rest``, the plan
        sample from which the plan rests on the end (from there on the landing's law with
        its integral, step 3', :func:`.identify._landing_law`); ``guards`` and ``guard_offsets``, shapes (n_guards, 4) and
        (n_axes + 1,), where the plant must be able to stop (:func:`_stop_guards`: while
        the clock lies between two plan samples that a guard both holds, the drive keeps
        the plant able to stop before its position, :func:`_short_of_stop`);
        ``dead_zone``, the identification's dead zone [pulse] (:func:`_identify`,
        :func:`reading_knowledge`); ``landing_band`` [pulse], ``landing_pole`` and
        ``delay`` [samples], the landing's law (step 3'); ``mode_law``, shape
        (MODE_LAW_ROWS, n_axes), per axis whose model declares a mode the landing's
        law and the tracking's gains designed with the mode
        (:func:`.mode_law.mode_landing_law`), used on the model's plant in place of the
        identified plant's laws (zeros: a rigid axis, the identified plant's);
        ``rest_observer``, shape (REST_OBSERVER_ROWS, n_axes), per rigid axis whose model's
        reading is not exact 1 and the pole of the landing's speed observer
        (:func:`.rest_observer.rest_observer`; zeros: the speed from the last increment).
    state : PlannedState
        Read: ``phi[0]``, the plan's clock at this sample [samples]; ``rate[0]``, the
        clock's rate over the last sample, in (0, 1]; ``excess[0]``, how far the last
        sample's drive demand exceeded Umax (relative; 0 if not); ``support``, shape
        (n_axes, SUPPORT_DIRECTIONS), per axis the support function of the plan's drive
        parts from the window's end (:data:`RATE_WINDOW` samples after the clock's) up to
        the next stop (:func:`_support_at`; zero when the window reaches the plan's end);
        ``slope`` and ``offset``, shape (n_axes,), the law's affine form at this sample:
        u[k] = slope*thd[k] + offset [V/pulse, V]. In/out: ``est``, shape (EST_ROWS, n_axes),
        the plant's identified sampled model and its covariance (:func:`_identify`);
        ``hist``, shape (HIST_ROWS, n_axes), the identification's memory
        (:func:`_identify`; row 0 is the drive applied at the last sample, which the
        caller corrects if the law produced another); ``landing``, shape
        (:data:`LANDING_ROWS`, n_axes), the landing's plant, gains and integral (step 3').
        Scratch: ``gains``, shape (2, n_axes), the estimated plant's ga and gv
        (:func:`_gains`). Written: ``drive``, shape (n_axes,), the drive [V]
        the setpoint produces.
    position : ndarray, shape (n_axes,)
        tha[k], measured [pulse].
    umax : float
        Umax [V].
    out_setpoint : ndarray, shape (n_axes,)
        Written: thd[k] [pulse].

    Returns
    -------
    phi_next, rate, excess : float
        The clock at the next sample, the rate used over this sample, and how far this
        sample's drive demand exceeded Umax.
    """
    phi, rate, excess_prev = state.phi[0], state.rate[0], state.excess[0]
    est, hist, support, gains = state.est, state.hist, state.support, state.gains
    slope, offset, out_drive = state.slope, state.offset, state.drive
    landing, dob = state.landing, state.disturbance
    observer = plan.disturbance_observer
    plan_position, plan_drive_speed = plan.position, plan.drive_speed
    plan_drive_accel = plan.drive_accel
    a, b0, c, b1, log_a = plan.a, plan.b0, plan.c, plan.b1, plan.log_a
    headroom, rate_gain, rest = plan.headroom, plan.rate_gain, plan.rest
    guards, guard_offsets, dead_zone = plan.guards, plan.guard_offsets, plan.dead_zone
    bisections, gain_range = plan.rate_bisections, plan.gain_range
    delay, band = plan.delay, plan.landing_band
    n = plan_position.shape[0]
    n_axes = position.shape[0]
    i0 = min(int(phi), n - 1)
    i1 = min(i0 + 1, n - 1)
    f = phi - i0 if i1 > i0 else 0.0
    # 1a'. with plan.disturbance_observer (opt-in), the disturbance observer first, on
    # the model's plant (:func:`.disturbance._observe`): on a rigid axis deadbeat; on an
    # axis whose model declares a mode, where its design with the mode found one
    # (:func:`.mode_law.mode_disturbance_observer`), at that design's pole, on the
    # reading less the model's twist under the plan's drive, at the clock the reading's
    # plant is at (the drive reaches it `delay` samples late)
    d_most = 0.0
    has_twist = plan.twist.shape[0] > 0
    for j in range(n_axes):
        moded_dob = (observer and plan.mode_law[0, j] != 0.0
                     and plan.mode_law[DOB_ROW, j] != 0.0)
        if (observer and plan.mode_law[0, j] == 0.0) or moded_dob:
            g0w, g0th, g1w, g1th = _delayed_zoh(a[j], b0[j], c[j], b1[j], delay)
            if moded_dob:
                tw_read, tw_last = 0.0, 0.0
                if has_twist:
                    tw_read = twist_at(plan.twist, phi - delay * rate, j)
                    tw_last = twist_at(plan.twist, phi - (1.0 + delay) * rate, j)
                nu = _observe(dob, j, position[j] - tw_read,
                              position[j] - hist[2, j] - (tw_read - tw_last), hist, a[j],
                              b0[j], c[j], b1[j], g0w, g0th, g1w, g1th,
                              plan.mode_law[DOB_ROW + 1:DOB_ROW + 4], dead_zone)
                d_most = max(d_most, abs(dob[0, j]))
                continue   # no deadbeat rejection on a mode: it would ring it
            nu = _observe(dob, j, position[j], position[j] - hist[2, j], hist, a[j], b0[j],
                          c[j], b1[j], g0w, g0th, g1w, g1th, plan.disturbance_gain,
                          dead_zone)
            if nu != 0.0:
                # the deviation the observer found, at the state the next drive meets
                if delay > 0.0:
                    ah, b0h, ch, b1h = _plant_part(a[j], b0[j], c[j], b1[j], delay)
                else:
                    ah, b0h, ch, b1h = 1.0, 0.0, 0.0, 0.0
                _made(dob, j, nu, plan.disturbance_gain, ah, b0h, ch, b1h)
            d_most = max(d_most, abs(dob[0, j]))
    # the drive the governor may plan with: Umax less the largest disturbance fed forward
    room = umax - d_most
    # 1a. identify the plant's exact sampled model from the measured positions and the
    # drives applied (recursive least squares, see :func:`_identify`)
    r_tail = 1.0
    for j in range(n_axes):
        ga, gv = _identify(est, hist, j, position[j], a[j], b0[j], c[j], b1[j],
                           dead_zone, gain_range, rate_gain)
        gains[0, j] = ga
        gains[1, j] = gv
        # 2a. the largest uniform rate at which the estimated plant can follow the plan
        # from the window's end to the next stop: |ga*A*r^2 + gv*V*r| <= (1 - headroom)*Umax
        # at every sample there; the plan itself may use the full drive, the headroom
        # applies beyond the model
        limit = max((1.0 - headroom) * room, _demand(support, j, 1.0, 1.0))
        if _demand(support, j, ga, gv) > limit:
            lo, hi = 0.0, 1.0
            for _ in range(bisections):
                mid = 0.5 * (lo + hi)
                if _demand(support, j, ga * mid * mid, gv * mid) > limit:
                    hi = mid
                else:
                    lo = mid
            r_tail = min(r_tail, lo)
    # 2b. sample by sample over the window, slowing down only as late as the drive can
    target = _window_rate(i0, r_tail, gains, a, plan_drive_speed, plan_drive_accel,
                          headroom, room, plan.rate_window)
    # 2c. governor: towards that rate, slower after a drive demand beyond Umax, changing
    # no faster than the drive left at the clock can change the plant's speed
    if excess_prev > 0.0:
        target = min(target, rate * (1.0 - rate_gain * excess_prev))
    down, up = rate_gain, rate_gain
    for j in range(n_axes):
        A = plan_drive_accel[i0, j] * (1.0 - f) + plan_drive_accel[i1, j] * f
        V = plan_drive_speed[i0, j] * (1.0 - f) + plan_drive_speed[i1, j] * f
        cost = gains[0, j] * abs(V) / (1.0 - a[j])
        if cost > 0.0:
            limit = max((1.0 - headroom) * room, abs(A + V))
            slow, fast = _rate_room(gains[0, j] * A * rate * rate + gains[1, j] * V * rate,
                                    V, limit)
            down = min(down, slow / cost)
            up = min(up, fast / cost)
    rate_old = rate
    if target < rate:
        rate = max(target, rate - down, rate_gain)
    else:
        rate = min(target, rate + up)
    # the plant's speed moves from the old rate's to the new one over the sample: the
    # clock advances by their mean
    phi_next = min(phi + 0.5 * (rate_old + rate), n - 1.0)
    excess = 0.0
    for j in range(n_axes):
        # 1b. deviation from the plan's state: position measured; the plant's speed from
        # its last position increment and the drives that made it (hist rows 3, 0 and 1,
        # :func:`_identify`) through the identified plant (exact when it is the true
        # one), with the drive it gets besides the one asked for (a load, friction while
        # the axis moves one way: the regression's delta = (p1 + p2 + p3)*d [pulse])
        th = plan_position[i0, j] * (1.0 - f) + plan_position[i1, j] * f
        moded = plan.mode_law[0, j] != 0.0
        moded_dob = observer and moded and plan.mode_law[DOB_ROW, j] != 0.0
        estimated = (observer and not moded) or moded_dob   # the observer's d serves it
        # the disturbance observer acts in the tracking (the landing has its integral)
        tracked = observer and not moded and phi < rest
        if moded:
            # a mode declared: the model's plant, the laws designed with its mode on it
            # (:func:`.mode_law.mode_landing_law`; a rigid regression reads the mode's
            # twist as a plant that is none); the drive it gets besides the one asked
            # for the observer's, where it has one (:func:`.mode_law.mode_disturbance_observer`)
            ae, b0e, ce, b1e = a[j], b0[j], c[j], b1[j]
            d = dob[0, j] if moded_dob else 0.0
        else:
            if delay > 0.0:
                ae, b0e, ce, b1e = _estimated_delayed_plant(est, j, a[j], b0[j], c[j],
                                                            b1[j], gains[0, j], gain_range)
            else:
                ae, b0e, ce, b1e = _estimated_plant(est, j, b0[j], gains[0, j])
            d = est[4, j] / (b1e + ce * b0e - ae * b1e)
            if tracked and dob[1, j] != 0.0:
                # the observer's, once it has seen a disturbance: on the model's plant
                ae, b0e, ce, b1e = a[j], b0[j], c[j], b1[j]
                d = dob[0, j]
        u1, u2 = hist[0, j] + d, hist[1, j] + d
        g0w, g0th, g1w, g1th = _delayed_zoh(ae, b0e, ce, b1e, delay)
        # a mode declared: what the encoder reads of the model's twist under the plan's
        # drive is taken off the reading (.shaper.encoder_offset), so the feedback acts
        # on the deviation from the model's own response, not on the twist it plans
        tw_now, tw_step = 0.0, 0.0
        if moded and plan.twist.shape[0] > 0:
            # with plan.disturbance_observer (opt-in), at the clock the reading's plant
            # is at: the drive reaches it `delay` samples late (read at the plan's clock,
            # on die-bonder-real the twist's half-sample lead left 278 um of contour on
            # the Pi at 1 m/s without friction; by default the plan's clock still: alone,
            # on item 4's known modes it flipped as many runs to unsettled as to settled,
            # docs/model.md#planned-on-a-real-machine)
            lag = delay if observer else 0.0
            tw_now = twist_at(plan.twist, phi - lag * rate_old, j)
            tw_step = tw_now - twist_at(plan.twist, phi - (1.0 + lag) * rate_old, j)
        w_last = (hist[3, j] - tw_step - g0th * u1 - g1th * u2) / ce
        w_now = ae * w_last + g0w * u1 + g1w * u2
        th_now = position[j] - tw_now
        if tracked and dob[1, j] != 0.0:
            w_now, th_now = dob[9, j], dob[10, j]   # the observer's state (.disturbance)
        if delay > 0.0:
            # the state this sample's drive will meet, `delay` samples on, the last
            # drive acting meanwhile: from there the drive acts for a whole sample, so the
            # deviation dynamics, the feedback's gains and the stop guards are the
            # undelayed plant's (a predictor: the plan's state at the clock is where the
            # drive starts, and the run follows the plan `delay` late)
            ah, b0h, ch, b1h = _plant_part(ae, b0e, ce, b1e, delay)
            th_now += ch * w_now + b1h * u1
            w_now = ah * w_now + b0h * u1
        e_th = th - th_now
        w_ref = _plan_speed_at(plan_drive_speed, plan_drive_accel, phi, j, a[j], log_a[j],
                               b0[j])
        e_w = w_ref * rate_old - w_now
        # 3. drive: the estimated plant's drive from the plan's speed at the clock (at the
        # rate it had) to its speed at the next clock (at the new rate), plus feedback;
        # clipped
        if phi >= rest:
            # 3'. landing (docs/model.md#planned-on-a-real-machine): the plan rests on the
            # end. At the hand-over the identified plant is frozen (the move excited it;
            # at rest nothing does, and the estimate would drift on the reading) and the
            # law placed on it (:func:`.identify._landing_law`): the state the drive will
            # meet, the model's delay on, and an integral of the error beyond what the
            # reading can tell (plan.landing_band: a count's edge or the noise is neither
            # chased nor integrated), poles at plan.landing_pole
            rested = plan.rest_observer.shape[1] > 0 and plan.rest_observer[0, j] != 0.0
            if landing[0, j] == 0.0:
                landing[0, j] = 1.0
                pole = plan.landing_pole
                if moded:
                    # a mode declared: the law designed with it on the model
                    # (:func:`.mode_law.mode_landing_law`), not the identified plant's
                    landing[1:LAW_ROWS + 1, j] = plan.mode_law[1:LAW_ROWS + 1, j]
                else:
                    if rested:
                        # a reading not exact: no faster than lets the reading's own
                        # change between two samples (twice the band) move the drive
                        # by the governor's headroom at most
                        # (:func:`.rest_observer.reading_pole`; a count flipped by the
                        # noise swung the drive of a fast sampled axis between the limits)
                        pole = reading_pole(ae, b0e, ce, b1e, delay, pole,
                                            plan.rest_observer[1, j], 2.0 * band,
                                            headroom * umax)
                    _landing_law(ae, b0e, ce, b1e, delay, pole, landing[1:LAW_ROWS + 1, j])
                if estimated and dob[1, j] != 0.0:
                    # the observer's estimate for an axis at rest handed to the
                    # integral (:func:`.disturbance._for_direction`: the part of d
                    # that is no friction; at rest friction holds, it does not
                    # push: handing over the sliding estimate, Coulomb included,
                    # pushed the axis past the end, the Pi at 2 m/s 10 x the bound)
                    landing[14, j] = -_for_direction(dob, j, 0.0) / landing[13, j]
                if rested:
                    # the observer starts on the reading and the speed of the last
                    # increment and drives (the tracking's w_now), its gains on the
                    # identified plant (:func:`.rest_observer.observer_gains`), its poles
                    # the machine's loop's but no slower than the law's (a slower one let
                    # the landing swing, or run away on a machine whose loop is slow)
                    w0 = ((hist[3, j] - landing[4, j] * hist[0, j]
                           - landing[6, j] * hist[1, j]) / landing[2, j])
                    w0 = (landing[1, j] * w0 + landing[3, j] * hist[0, j]
                          + landing[5, j] * hist[1, j])
                    landing[OBSERVER_ROW, j] = w0
                    landing[OBSERVER_ROW + 1, j] = position[j]
                    m_w, m_th = observer_gains(landing[1, j], landing[2, j],
                                               min(plan.rest_observer[1, j], pole))
                    landing[OBSERVER_ROW + 2, j] = m_w
                    landing[OBSERVER_ROW + 3, j] = m_th
                    landing[OBSERVER_ROW + 4, j] = 1.0   # first sample: no prediction
            # the speed from the last position increment and the drives that made it,
            # then the state after the drive in flight
            al, cl, g0w, g0th = landing[1, j], landing[2, j], landing[3, j], landing[4, j]
            g1w, g1th = landing[5, j], landing[6, j]
            k_e, k_s, k_z = landing[11, j], landing[12, j], landing[13, j]
            if rested:
                # a reading not exact: the plant's speed from an observer on the frozen
                # identified plant, its last estimate advanced by the drives applied and
                # corrected by the reading (:func:`.rest_observer.observer_gains`), not from
                # one increment (a count flipped by the noise read as a speed of a count
                # per sample, a kick of the law's whole speed gain)
                w_hat = landing[OBSERVER_ROW, j]
                th_hat = landing[OBSERVER_ROW + 1, j]
                if landing[OBSERVER_ROW + 4, j] == 0.0:
                    th_hat += cl * w_hat + g0th * hist[0, j] + g1th * hist[1, j]
                    w_hat = al * w_hat + g0w * hist[0, j] + g1w * hist[1, j]
                landing[OBSERVER_ROW + 4, j] = 0.0
                innovation = position[j] - th_hat
                w_hat += landing[OBSERVER_ROW + 2, j] * innovation
                th_hat += landing[OBSERVER_ROW + 3, j] * innovation
                landing[OBSERVER_ROW, j] = w_hat
                landing[OBSERVER_ROW + 1, j] = th_hat
                w_land = w_hat
            else:
                w_last = (hist[3, j] - g0th * hist[0, j] - g1th * hist[1, j]) / cl
                w_land = al * w_last + g0w * hist[0, j] + g1w * hist[1, j]
            e_end = plan_position[n - 1, j] - (position[j] + landing[9, j] * w_land
                                               + landing[10, j] * hist[0, j])
            w_land = landing[7, j] * w_land + landing[8, j] * hist[0, j]
            e_end -= min(max(e_end, -band), band)
            u = k_e * e_end - k_s * w_land + k_z * landing[14, j]
            # stick-slip (:data:`HOLD_PULSES`): the axis is gripped when its reading moved
            # by no more than the reading alone can (twice the band; 0 on an exact one)
            # under a drive beyond the law's at the hold's edge, and drives that would
            # have moved it from rest by more than that on the model; then its error is
            # the measured one (the model's prediction of the drive in flight moving it
            # is what the friction holds back)
            hold = band + HOLD_PULSES
            e_int = e_end
            push = g0th * hist[0, j] + g1th * hist[1, j]
            if (abs(hist[3, j]) <= 2.0 * band and abs(u) >= k_e * hold
                    and abs(push) > 2.0 * band):
                e_meas = plan_position[n - 1, j] - position[j]
                if abs(e_meas) <= hold:
                    e_int = 0.0   # held within the hold: the integral holds
                else:
                    e_int = e_meas - min(max(e_meas, -band), band)
                    landing[15, j] = 1.0 if e_meas > 0.0 else -1.0
            elif landing[15, j] * e_end < 0.0:
                # it broke away and crossed the end since it was gripped beyond the hold:
                # the integral that broke it away and carried it over is spent
                landing[14, j] = 0.0
                landing[15, j] = 0.0
                u = k_e * e_end - k_s * w_land
            # the integral (z[k+1] = z[k] + e[k], :func:`.identify._landing_gains`) only
            # while the drive is within Umax (no wind-up); the rest law's, as LinuxCNC's
            # pid, with this sample's error in it
            if abs(u) <= umax:
                landing[14, j] += e_int
        else:
            w_next = _plan_speed_at(plan_drive_speed, plan_drive_accel, phi_next, j, a[j],
                                    log_a[j], b0[j])
            uf = (w_next * rate - ae * w_ref * rate_old) / b0e
            if moded:
                kpe, kde = plan.mode_law[LAW_ROWS + 1, j], plan.mode_law[LAW_ROWS + 2, j]
            else:
                kpe, kde = _pole_gains(ae, b0e, ce, b1e, 1.0 - rate_gain)
            if observer and not moded:
                # the deviation the disturbance made before the observer had it is
                # rejected at REJECTION_POLE, the rest (the plan's) at the tracking pole
                kf_th, kf_w = _pole_gains(a[j], b0[j], c[j], b1[j], REJECTION_POLE)
                u = (uf + kpe * (e_th - dob[11, j]) + kde * (e_w - dob[12, j])
                     + _rejected(dob, j, a[j], b0[j], c[j], b1[j], kf_th, kf_w))
            else:
                u = uf + kpe * e_th + kde * e_w
            if estimated:
                # the disturbance fed forward (plan.disturbance_observer; on an axis with
                # a mode its own observer's, the hold's integral at the mode law's
                # landing gain): the estimate
                # for the direction the plan moves the axis in at the next clock, where
                # the plan rests it the axis' own (friction acts until it stops), and at
                # rest held short of the plan the error's integral
                # (:mod:`.disturbance`)
                ke_ts = b1[j] * (1.0 - a[j]) / b0[j] + c[j]   # Ke*Ts [pulse/(rad/s)]
                sigma = _direction(w_next, ke_ts)
                if sigma == 0.0:
                    sigma = _direction(w_now, ke_ts)
                d_ff = _for_direction(dob, j, sigma)
                if sigma == 0.0:
                    k_i = (plan.mode_law[13, j] if moded else
                           _landing_gains(a[j], b0[j], c[j], b1[j], 1.0 - rate_gain)[2])
                    _hold(dob, j, e_th, hist[3, j], k_i, max(band, ROUNDING_FLOOR))
                    d_ff = dob[0, j]
                u -= d_ff
        if abs(u) > umax:
            excess = max(excess, abs(u) / umax - 1.0)
            u = umax if u > 0 else -umax
        # 3b. never past a stop: the drive leaves the plant able to stop before the
        # positions the plan guards at both ends of the clock's sample, braking at Umax
        # from the next sample on; the side the plant moves towards last
        lo_g, hi_g = guard_offsets[j], guard_offsets[j + 1]
        hi = max(_guarded(guards, lo_g, hi_g, i0, 1.0),
                 _guarded(guards, lo_g, hi_g, i1, 1.0))
        lo = min(_guarded(guards, lo_g, hi_g, i0, -1.0),
                 _guarded(guards, lo_g, hi_g, i1, -1.0))
        # (in the landing only on an exact reading, an immediate drive and a rigid
        # model: the end's guard read on a count or noise past it would brake at Umax,
        # it brakes a plant with no delay, and its speed estimate is the rigid plant's,
        # which a mode's twist throws: it held the landing against the end, 2,766
        # samples at Umax in one run)
        guarded = phi < rest or (band == 0.0 and delay == 0.0 and not moded)
        for side in (-1.0, 1.0) if w_now >= 0.0 else (1.0, -1.0):
            target = hi if side > 0.0 else lo
            if guarded and math.isfinite(target):
                u = _short_of_stop(u, th_now, w_now, target, side, ae, b0e, ce, b1e,
                                   umax, bisections, d)
        hist[5, j] = hist[1, j]
        hist[1, j] = hist[0, j]
        hist[0, j] = u
        # 4. the setpoint that produces exactly this drive
        out_drive[j] = u
        out_setpoint[j] = (u - offset[j]) / slope[j]
    return phi_next, rate, excess


@njit(cache=True)
def _law_output(law, law_state, j, command, position, velocity):
    """The law's output [V] for a candidate setpoint (:func:`nurbsmotion.control.pid_output`
    compiled once here, not inlined at every call of :func:`_within_limit`)."""
    return pid_output(law, law_state, j, command, position, velocity)[0]


DRIVE_MATCH = 1e-6
"""The law's output for a setpoint counts as the drive asked of it within this fraction
of Umax: the affine form's rounding (its terms reach thousands of volts that cancel, as
``FF2*command/Ts^2`` does) stays far below it, a deadband's or a clamp's effect far above;
beyond it the setpoint is solved for on the law itself (:func:`_setpoint_for`)."""


@njit(cache=True)
def _setpoint_for(law, law_state, j, command, drive, position, velocity, match=DRIVE_MATCH):
    """The setpoint of axis ``j`` at which the law, as it computes (clamps, deadband and
    frozen integrator included), outputs ``drive`` [V] (within +-Umax): ``command``, the
    affine form's setpoint, where that is exact (always for PD and PD+). Otherwise the
    law's output, continuous and nondecreasing in the setpoint (every gain >= 0, every
    clamp and the deadband monotone), is bracketed away from ``command`` and bisected;
    where no setpoint gives ``drive`` (a clamp flattens the output short of it), the
    setpoint nearest ``command`` whose drive is within Umax (:func:`_within_limit`).
    ``match``: :data:`DRIVE_MATCH` by default, the plan's ``drive_match``.
    Returns ``(setpoint, found)``."""
    umax = law[j]["maxoutput"]
    out = _law_output(law, law_state, j, command, position, velocity)
    if abs(out - drive) <= match * umax:
        if abs(out) <= umax:
            return command, True
        return _within_limit(law, law_state, j, command, position, velocity)
    sign = 1.0 if out < drive else -1.0
    step = abs(command - position) + 1.0
    near, far = command, command + sign * step
    tries = 0
    while sign * (_law_output(law, law_state, j, far, position, velocity) - drive) < 0.0:
        tries += 1
        if tries > 60:
            return _within_limit(law, law_state, j, command, position, velocity)
        near = far
        step *= 2.0
        far = command + sign * step
    for _ in range(60):
        mid = 0.5 * (near + far)
        if sign * (_law_output(law, law_state, j, mid, position, velocity) - drive) < 0.0:
            near = mid
        else:
            far = mid
    return _within_limit(law, law_state, j, near, position, velocity)


@njit(cache=True)
def _within_limit(law, law_state, j, command, position, velocity):
    """The setpoint of axis ``j`` nearest to ``command`` whose drive, as the law computes
    it (clamps included), is within Umax: ``command`` itself when the affine form was
    exact (always for PD and PD+). The law's output rises with the command, so the
    search widens away from the limit it exceeds, then bisects. Returns
    ``(setpoint, found)``."""
    umax = law[j]["maxoutput"]
    out = _law_output(law, law_state, j, command, position, velocity)
    if abs(out) <= umax:
        return command, True
    sign = 1.0 if out > 0 else -1.0
    # widen until the output is no longer beyond the limit it exceeds (it may then lie
    # anywhere below it, even beyond the other limit), then bisect to that limit
    step = abs(command - position) + 1.0
    good = command - sign * step
    tries = 0
    while sign * _law_output(law, law_state, j, good, position, velocity) > umax:
        tries += 1
        if tries > 60:
            return command, False
        step *= 2.0
        good = command - sign * step
    bad = command
    for _ in range(60):
        mid = 0.5 * (good + bad)
        if sign * _law_output(law, law_state, j, mid, position, velocity) <= umax:
            good = mid
        else:
            bad = mid
    if abs(_law_output(law, law_state, j, good, position, velocity)) > umax:
        return command, False  # the law jumps over the whole band: no admissible setpoint
    return good, True


@njit(cache=True)
def planned_step(plan, state, law, law_state, position, velocity, command, bounds):
    """One sample: the law's affine form from its memory and the measured state, then
    :func:`online_step`; the contract of :mod:`nurbsmotion.stepping`."""
    n_axes = command.shape[0]
    for j in range(n_axes):
        slope, offset = pid_affine(law, law_state, j, position[j], velocity[j])
        state.slope[j] = slope
        state.offset[j] = offset
        bounds[j, 0] = np.nan
        bounds[j, 1] = np.nan
    phi = state.phi[0]
    tail = int(phi) + plan.rate_window  # the window's end (:func:`_window_rate`)
    if tail < plan.position.shape[0]:
        _support_at(plan, tail, state.support)
    else:
        state.support[:] = 0.0
    phi_next, rate, excess = online_step(plan, state, position, law[0]["maxoutput"], command)
    state.phi[0] = phi_next
    state.rate[0] = rate
    state.excess[0] = excess
    status = stepping.WORKING
    for j in range(n_axes):
        setpoint, found = _setpoint_for(law, law_state, j, command[j], state.drive[j],
                                        position[j], velocity[j], plan.drive_match)
        if not found:
            status = stepping.CORNERED
        if setpoint != command[j]:
            # a clamp of the law: the identification and the speed estimate see the drive
            # the plant gets
            umax = law[j]["maxoutput"]
            out = _law_output(law, law_state, j, setpoint, position[j], velocity[j])
            state.hist[0, j] = min(max(out, -umax), umax)
        command[j] = setpoint
    n = plan.parameter.shape[0]
    i0 = min(int(phi), n - 1)
    feed = rate * plan.path_step[i0] / law[0]["period"]  # the plan's path speed at its clock
    if phi >= plan.rest:  # the plan rests on the end: the setpoint has arrived
        return 1.0, 0.0, stepping.FINISHED
    if status == stepping.WORKING and (excess > 0.0 or rate < 1.0):
        status = stepping.LIMITED
    return plan.parameter[i0], feed, status
