"""identify on logs made by the project's own plant stage (issue 34 with issue 32's keys):
the machine a log came from, with encoder counts, a fractional delay and Coulomb friction
with stiction, is found again within the issue's tolerances, and the identified machine
is a valid :class:`~nurbsmotion.machine.Machine` carrying those keys.

The log is the open-loop response of :func:`nurbsmotion.plant.stage_response` (the exact
plant of docs/model.md section 11) to :func:`nurbsmotion.identify.excitation`, read in
whole counts as the controller reads it. (The independent reference for the fit's model
is the solve_ivp simulator of tests/test_identify.py.)
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from nurbsmotion.identify import excitation, identify, log_from_arrays
from nurbsmotion.machine import Machine, die_bonder
from nurbsmotion.plant import make_stage, stage_response


def _true_machine(tau_scale, kc_scale, delay, coulomb, stiction) -> Machine:
    base = die_bonder()
    axes = tuple(replace(a, time_constant=a.time_constant * t,
                         electrical_gain=a.electrical_gain * k,
                         coulomb_friction=coulomb, stiction=stiction)
                 for a, t, k in zip(base.axes, tau_scale, kc_scale))
    return base.with_options(axes=axes, delay=delay, encoder="counts")


def _log(machine: Machine):
    _, drive = excitation(die_bonder())
    stage = make_stage(machine.effects(), machine.tau, machine.Kc, machine.Ke,
                       machine.max_drive, machine.sample_period)
    _, tool = stage_response(stage, drive)  # rigid axes: the tool is the motor
    counts = np.floor(tool[:-1] - tool[0]) + tool[0]
    return log_from_arrays(drive, counts, machine.sample_period, machine.axis_names)


@pytest.mark.parametrize("tau_scale, kc_scale, delay, coulomb, stiction", [
    ((1.0, 1.0), (1.0, 1.0), 0.5e-3, 0.3, 0.4),
    ((1.15, 0.9), (0.92, 1.1), 0.23e-3, 0.2, 0.25),
])
def test_identify_finds_the_plant_stage_machine(tau_scale, kc_scale, delay, coulomb,
                                                 stiction):
    true = _true_machine(tau_scale, kc_scale, delay, coulomb, stiction)
    result = identify(_log(true), die_bonder())
    Ts = true.sample_period
    assert abs(result.delay.value - delay) <= 0.1 * Ts
    for ax, axis in zip(result.axes, true.axes):
        est = ax.estimates
        assert est["time_constant"].value == pytest.approx(axis.time_constant, rel=0.02)
        assert est["electrical_gain"].value == pytest.approx(axis.electrical_gain, rel=0.02)
        assert est["coulomb_friction"].value == pytest.approx(coulomb, rel=0.10)
    machine = result.machine  # every key of issue 32 that was identified, validated
    assert machine.delay == pytest.approx(result.delay.value)
    assert [a.coulomb_friction for a in machine.axes] == pytest.approx(
        [ax.estimates["coulomb_friction"].value for ax in result.axes])
    assert Machine.from_dict(machine.to_dict()) == machine
