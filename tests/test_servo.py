"""Plant, control law and machine: against independent references."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from nurbsmotion import InvalidMachineError, PathFileError
from nurbsmotion.machine import Axis, die_bonder, load_machine
from nurbsmotion.servo import ServoPlant


def test_zoh_plant_matches_fine_rk45_integration():
    m = die_bonder()
    rng = np.random.default_rng(1)
    drives = rng.uniform(-10, 10, size=(40, 2))
    plant = ServoPlant.of_machine(m, [100.0, -50.0])
    speed, position = plant.response(drives)
    Ts = m.sample_period
    x = np.array([0.0, 100.0, 0.0, -50.0])  # w_x, th_x, w_y, th_y

    def rhs(t, x, u):
        out = np.empty(4)
        for j in range(2):
            w = x[2 * j]
            out[2 * j] = (-w + m.Kc[j] * u[j]) / m.tau[j]
            out[2 * j + 1] = m.Ke[j] * w
        return out

    for k, u in enumerate(drives):
        x = solve_ivp(rhs, (0, Ts), x, args=(u,), method="RK45", rtol=1e-13,
                      atol=1e-12).y[:, -1]
        np.testing.assert_allclose(speed[k + 1], x[[0, 2]], rtol=1e-9)
        np.testing.assert_allclose(position[k + 1], x[[1, 3]], rtol=1e-9)


def test_plant_clips_the_drive():
    plant = ServoPlant.of_machine(die_bonder(), [0.0, 0.0])
    np.testing.assert_array_equal(plant.saturate(np.array([12.0, -30.0])), [10.0, -10.0])


def test_response_steps_the_clipped_drive_sample_by_sample():
    """``ServoPlant.response`` (its loop compiled, issue 35: 0.5 ms a call of step 6's
    rounds in Python) gives, to the last bit, the state that ``plant_step`` advances one
    sample at a time under the drive ``saturate`` clips, beyond Umax as well."""
    from nurbsmotion.servo import plant_step

    plant = ServoPlant.of_machine(die_bonder(), [3.0, -7.0])
    drive = np.random.default_rng(5).uniform(-25.0, 25.0, (300, 2))
    speed, position = plant.response(drive)
    w, th = np.zeros(2), np.array([3.0, -7.0])
    for k, u in enumerate(plant.saturate(drive)):
        for j in range(2):
            w[j], th[j] = plant_step(plant.Ad, plant.Bd, j, w[j], th[j], u[j])
        assert np.array_equal(speed[k + 1], w) and np.array_equal(position[k + 1], th)
    assert np.array_equal(plant.response(np.asfortranarray(drive))[1], position)


def test_die_bonder_preset_is_table_1():
    m = die_bonder()
    assert m.axis_names == ("x", "y")
    np.testing.assert_array_equal(m.tau, [0.31, 0.135])
    np.testing.assert_array_equal(m.Kc, [2506.17, 3156.23])
    np.testing.assert_array_equal(m.Kp, [0.0136, 0.00577])
    np.testing.assert_array_equal(m.Kd, [0.03, 0.028])
    assert (m.max_drive, m.sample_period) == (10.0, 1e-3)
    # SPEC section 2: continuous closed-loop poles about -123 +- 400j (X), -331 +- 324j (Y)
    for j, expected in enumerate((-123 + 400j, -331 + 324j)):
        a = 1 / m.tau[j]
        b = m.Kc[j] / m.tau[j]
        # s^2 + (a + b*Kd)s + b*Kp*Ke = 0 for the PD loop around the plant
        poles = np.roots([1, a + b * m.Kd[j], b * m.Kp[j] * m.Ke[j]])
        p = poles[np.argmax(poles.imag)]
        assert abs(p - expected) < 5


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("time_constant", 0.0, "time_constant must be finite and > 0, got 0.0"),
        ("electrical_gain", -1.0, "electrical_gain must be finite and > 0"),
        ("mechanical_gain", math.nan, "mechanical_gain must be finite and > 0"),
        ("position_gain", -0.1, "position_gain must be finite and >= 0"),
    ],
)
def test_axis_validation_names_the_field(field, value, message):
    kw = dict(name="x", time_constant=0.3, electrical_gain=2500.0, mechanical_gain=1591.5,
              position_gain=0.01, speed_gain=0.03)
    kw[field] = value
    with pytest.raises(InvalidMachineError, match=message):
        Axis(**kw)


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(sample_period=0.0), "sample_period must be finite and > 0, got 0.0"),
        (dict(max_drive=-10.0), "max_drive must be finite and > 0, got -10.0"),
        (dict(controller="lqr"), "controller must be one of"),
        (dict(speed_measurement="tacho"), "speed_measurement must be one of"),
    ],
)
def test_machine_validation_names_the_field(changes, message):
    with pytest.raises(InvalidMachineError, match=message):
        die_bonder(**changes)


def test_machine_rejects_a_path_with_another_axis_count():
    with pytest.raises(InvalidMachineError, match="the path has 3 axes but machine "
                                                  "'die-bonder' has 2"):
        die_bonder().check_path(3)


def test_machine_file_round_trip_and_errors(tmp_path):
    import json

    m = die_bonder(name="mine")
    f = tmp_path / "m.json"
    f.write_text(json.dumps(m.to_dict()))
    assert load_machine(f) == m
    t = tmp_path / "m.toml"
    t.write_text("""name = "bad"\nmax_drive = 10\nsample_period = 0.001\n[[axes]]\n"""
                 """name = "x"\ntime_constant = -0.3\nelectrical_gain = 2500\n"""
                 """mechanical_gain = 1591.5\nposition_gain = 0.01\nspeed_gain = 0.03\n""")
    with pytest.raises(PathFileError, match=r"m.toml: axes\[0\]: axis 'x': time_constant"):
        load_machine(t)
    t.write_text("max_drive = 10\nsample_period = \n")
    with pytest.raises(PathFileError, match="not valid TOML"):
        load_machine(t)
    with pytest.raises(PathFileError, match="no such machine file"):
        load_machine(tmp_path / "missing.toml")
