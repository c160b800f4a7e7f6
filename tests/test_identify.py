"""``nurbsmotion identify`` and ``excite`` (issue 34), against an independent simulator.

The logs come from tests/identify_reference.py (scipy's ``solve_ivp`` with events at the
stops, written from the physics: not the project's loop, not the fit's model), with encoder
counts and Gaussian noise, under the drive of :func:`nurbsmotion.identify.excitation`.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest

from identify_reference import simulate_log

from nurbsmotion.cli import main
from nurbsmotion.errors import PathFileError
from nurbsmotion.identify import (excitation, excitation_gcode, identify, log_from_arrays,
                                  read_log, write_excitation_csv)
from nurbsmotion.machine import die_bonder, load_machine
from nurbsmotion.identify.model import simulate

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

KE = 1591.5494
TS = 1e-3
RIGID = {"time_constant": 0.31, "gain": 2506.17 * KE, "coulomb_friction": 0.3,
         "stiction": 0.4}
TWO_MASS = {"time_constant": 0.135, "gain": 3156.23 * KE, "resonance_frequency": 100.0,
            "resonance_damping": 0.02, "load_fraction": 0.3, "encoder_on": "motor"}
DELAY = 0.5e-3


def _log(axes, drive, delay=DELAY, noise=0.3):
    y = np.column_stack([simulate_log(a, drive[:, j], TS, delay=delay, encoder="counts",
                                      noise=noise, seed=j, rtol=1e-9)
                         for j, a in enumerate(axes)])
    return log_from_arrays(drive, y, TS)


@pytest.fixture(scope="module")
def excited():
    """The die-bonder's excitation; x a rigid axis with friction, y a two-mass axis."""
    machine = die_bonder()
    _, drive = excitation(machine)
    log = _log([RIGID, TWO_MASS], drive)
    return machine, drive, log, identify(log, machine)


def test_model_matches_the_solve_ivp_reference():
    """The fit's closed-form model against solve_ivp: friction, stiction, a fractional
    delay; a mode read on the motor and on the load."""
    rng = np.random.default_rng(3)
    u = np.repeat(rng.uniform(-2.0, 2.0, 40), 25)
    for axis, coupling in ((dict(RIGID), 0.0), (dict(TWO_MASS), 0.3 / 0.7),
                           (dict(TWO_MASS, encoder_on="load"), -1.0)):
        for delay in (0.0, 0.37e-3, 1.6e-3):
            ref = simulate_log(axis, u, TS, delay=delay)
            ours = simulate(u, TS, dict(axis, delay=delay, coupling=coupling))
            assert np.max(np.abs(ours - ref)) <= 1e-8 * np.max(np.abs(ref)) + 1e-6


FRICTION = {"coulomb_friction": 0.3, "stiction": 0.4}


def _plant_positions(axis, u, delay):
    """The encoder's reading under the project's plant (nurbsmotion.plant), at the
    sample instants [pulse]."""
    from nurbsmotion.plant import make_stage, stage_response

    lam = axis["load_fraction"]
    wn = 2 * math.pi * axis["resonance_frequency"]
    effects = {"encoder": "exact", "measurement_noise": 0.0, "seed": 0, "delay": delay,
               "dac_bits": None, "axes": [{
                   "coulomb_friction": axis["coulomb_friction"],
                   "stiction": axis["stiction"], "disturbance": [],
                   "resonance_frequency": axis["resonance_frequency"],
                   # the plant's damping ratio is the twist's whole one (docs/model.md)
                   "resonance_damping": axis["resonance_damping"]
                   + 1 / (2 * wn * axis["time_constant"]),
                   "load_fraction": lam, "encoder_on": axis["encoder_on"]}]}
    stage = make_stage(effects, [axis["time_constant"]], [axis["gain"] / KE], [KE], 10.0, TS)
    x, _ = stage_response(stage, u[:, None])
    reads = lam if axis["encoder_on"] == "motor" else -(1 - lam)
    return (x[:, 0, 1] + reads * x[:, 0, 2])[:-1]


@pytest.mark.parametrize("encoder_on", ["motor", "load"])
def test_friction_acts_on_the_motor_as_in_the_plant(encoder_on):
    """A two-mass axis with friction: the fit's model against the project's plant (the
    motor sticks, its load swings on it, the spring breaks it away) and against the
    solve_ivp reference, under the die-bonder's excitation and a fractional delay."""
    axis = dict(TWO_MASS, **FRICTION, encoder_on=encoder_on)
    lam = axis["load_fraction"]
    coupling = lam / (1 - lam) if encoder_on == "motor" else -1.0
    _, drive = excitation(die_bonder())
    u = drive[:, 1]
    for delay in (0.0, 0.37e-3, 1.6e-3):
        ours = simulate(u, TS, dict(axis, delay=delay, coupling=coupling))
        plant = _plant_positions(axis, u, delay)
        assert np.max(np.abs(ours - plant)) <= 1e-9 * np.max(np.abs(plant)) + 1e-6
    ref = simulate_log(axis, u, TS, delay=0.37e-3)
    ours = simulate(u, TS, dict(axis, delay=0.37e-3, coupling=coupling))
    # The reference finds every stop; the model (as the plant) checks every eighth of the
    # mode's period, so a graze shorter than that is missed: RMS per sample, not a max.
    assert np.sqrt(np.mean(np.square(np.diff(ours) - np.diff(ref)))) <= 0.1


@pytest.mark.parametrize("encoder_on", ["motor", "load"])
def test_two_mass_axis_with_friction_within_the_targets(encoder_on):
    """Friction on the motor of a two-mass axis read on the motor or on the load: every
    target of issue 34 on the independent simulator's log. (On the load, a fit holding
    the stiction at the Coulomb friction ran off to tau at its bound.)"""
    machine = die_bonder()
    _, drive = excitation(machine)
    truth = dict(TWO_MASS, **FRICTION, encoder_on=encoder_on)
    result = identify(_log([RIGID, truth], drive), machine)
    ax = result.axes[1]
    est = ax.estimates
    assert est["time_constant"].value == pytest.approx(truth["time_constant"], rel=0.02)
    assert est["electrical_gain"].value * KE == pytest.approx(truth["gain"], rel=0.02)
    assert abs(est["delay"].value - DELAY) <= 0.1 * TS
    assert est["coulomb_friction"].value == pytest.approx(0.3, rel=0.10)
    assert est["resonance_frequency"].value == pytest.approx(100.0, rel=0.02)
    assert est["resonance_damping"].value == pytest.approx(0.02, rel=0.30)
    assert est["load_fraction"].value == pytest.approx(0.3, abs=0.05)
    assert ax.encoder_on == encoder_on

def test_rigid_axis_within_the_targets(excited):
    _, _, _, result = excited
    est = result.axes[0].estimates
    assert est["time_constant"].value == pytest.approx(RIGID["time_constant"], rel=0.02)
    assert est["electrical_gain"].value == pytest.approx(2506.17, rel=0.02)
    assert abs(est["delay"].value - DELAY) <= 0.1 * TS
    assert est["coulomb_friction"].value == pytest.approx(0.3, rel=0.10)
    assert "resonance_frequency" not in est
    assert result.axes[0].mechanical_gain == pytest.approx(KE)
    # The uncertainty is a standard deviation: finite, small against the value.
    assert 0 < est["time_constant"].sigma < 0.02 * est["time_constant"].value


def test_mode_within_the_targets(excited):
    _, _, _, result = excited
    ax = result.axes[1]
    est = ax.estimates
    assert est["time_constant"].value == pytest.approx(0.135, rel=0.02)
    assert est["electrical_gain"].value == pytest.approx(3156.23, rel=0.02)
    assert abs(est["delay"].value - DELAY) <= 0.1 * TS
    assert est["resonance_frequency"].value == pytest.approx(100.0, rel=0.02)
    assert est["resonance_damping"].value == pytest.approx(0.02, rel=0.30)
    assert est["load_fraction"].value == pytest.approx(0.3, abs=0.05)
    assert ax.encoder_on == "motor"
    assert abs(result.delay.value - DELAY) <= 0.1 * TS


def test_refit_of_a_refit_is_stable(excited):
    """A log of the identified machine (same simulator, same drive) identifies the same
    machine."""
    machine, drive, _, first = excited
    axes = []
    for a in first.axes:
        e = a.estimates
        axis = {"time_constant": e["time_constant"].value,
                "gain": e["electrical_gain"].value * a.mechanical_gain}
        for key in ("coulomb_friction", "stiction", "resonance_frequency",
                    "resonance_damping", "load_fraction"):
            if key in e:
                axis[key] = e[key].value
        if a.encoder_on:
            axis["encoder_on"] = a.encoder_on
        axes.append(axis)
    second = identify(_log(axes, drive, delay=first.delay.value), machine)
    for a, b in zip(first.axes, second.axes):
        assert set(a.estimates) == set(b.estimates)
        for key in ("time_constant", "electrical_gain"):
            assert b.estimates[key].value == pytest.approx(a.estimates[key].value, rel=0.02)
    assert abs(second.delay.value - first.delay.value) <= 0.1 * TS


def test_exact_plant_is_recovered_to_rounding():
    """The project's exact ZOH plant (no friction, no delay, exact positions): tau and Kc
    to 1e-6, no delay, no friction, no mode."""
    machine = die_bonder()
    _, drive = excitation(machine)
    _, position = machine.plant().response(drive, position=[0.0, 0.0])
    result = identify(log_from_arrays(drive, position[:-1], TS), machine)
    for a, tau, kc in zip(result.axes, machine.tau, machine.Kc):
        assert a.estimates["time_constant"].value == pytest.approx(tau, rel=1e-6)
        assert a.estimates["electrical_gain"].value == pytest.approx(kc, rel=1e-6)
        assert a.estimates["delay"].value <= 1e-6 * TS
        assert a.estimates["coulomb_friction"].value <= 1e-6
        assert "resonance_frequency" not in a.estimates
    assert result.encoder == "exact"


def test_machine_file_round_trip(excited, tmp_path):
    machine, _, _, result = excited
    data = tomllib.loads(result.to_toml())
    assert data["delay"] == pytest.approx(result.delay.value)
    assert data["encoder"] == "exact"  # noise on the counts
    x, y = data["axes"]
    assert x["time_constant"] == pytest.approx(result.axes[0].estimates["time_constant"].value)
    assert x["coulomb_friction"] == pytest.approx(0.3, rel=0.1)
    assert x["position_gain"] == machine.axes[0].position_gain  # gains from the base
    assert y["resonance_frequency"] == pytest.approx(100.0, rel=0.02)
    assert y["encoder_on"] == "motor"
    assert "dac_bits" not in data
    # The keys Machine has today load as a Machine.
    m = result.machine
    assert m.tau[0] == pytest.approx(x["time_constant"])
    assert m.Kc[1] == pytest.approx(y["electrical_gain"])
    loaded = load_machine(_write(tmp_path / "m.toml", result.to_toml()))
    assert loaded.tau[0] == pytest.approx(x["time_constant"])
    assert loaded.delay == pytest.approx(result.delay.value)
    # the machine's resonance_damping is the twist's whole ratio: the fit's
    # spring-damper ratio plus the axis's own viscous share 1/(2*wn*tau)
    est = result.axes[1].estimates
    wn = 2 * np.pi * est["resonance_frequency"].value
    assert loaded.axes[1].resonance_damping == pytest.approx(
        est["resonance_damping"].value + 1 / (2 * wn * est["time_constant"].value))


def _write(path, text):
    path.write_text(text)
    return path


def test_one_way_motion_says_friction_is_not_identifiable():
    machine = die_bonder()
    drive = np.zeros((1500, 2))
    drive[100:, :] = np.repeat(np.random.default_rng(1).uniform(1.0, 3.0, 28), 50)[:, None]
    log = _log([RIGID, RIGID], drive, noise=0.0)
    result = identify(log, machine)
    ax = result.axes[0]
    assert "coulomb_friction" not in ax.estimates
    assert any("never reversed" in n for n in ax.notes)
    assert "coulomb_friction" not in tomllib.loads(result.to_toml())["axes"][0]


def test_excitation_within_the_limits():
    machine = die_bonder()
    t, drive = excitation(machine, travel=5000.0)
    assert drive.shape == (len(t), 2)
    assert np.max(np.abs(drive)) <= machine.max_drive
    for j in range(2):
        y = simulate(drive[:, j], TS, {"time_constant": machine.tau[j],
                                       "gain": machine.Kc[j] * machine.Ke[j], "delay": 0.0})
        assert np.max(np.abs(y)) <= 5000.0
        assert np.any(drive[:, j] > 0) and np.any(drive[:, j] < 0)
    text = excitation_gcode(machine)
    assert text.startswith("(") and "G91" in text and text.rstrip().endswith("M2")


def _csv(path, log, names=("t", "x_drive", "x_pos", "y_drive", "y_pos")):
    cols = [log.time, log.drive[:, 0], log.position[:, 0], log.drive[:, 1],
            log.position[:, 1]]
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(names),
               comments="", fmt="%.17g")
    return path


def test_cli_identify_writes_the_machine_file_json_and_figure(excited, tmp_path, capsys):
    _, _, log, _ = excited
    src = _csv(tmp_path / "log.csv", log)
    out = tmp_path / "fit" / "machine.toml"
    assert main(["identify", str(src), "--out", str(out)]) == 0
    data = tomllib.loads(out.read_text())
    assert data["axes"][0]["time_constant"] == pytest.approx(0.31, rel=0.02)
    report = json.loads((out.parent / "identify.json").read_text())
    assert report["axes"]["y"]["estimates"]["resonance_frequency"]["value"] == \
        pytest.approx(100.0, rel=0.02)
    assert "residual_rms" in report["axes"]["x"]
    assert (out.parent / "identify.png").stat().st_size > 1000
    capsys.readouterr()
    assert main(["identify", str(src), "--out", str(out), "--no-figures"]) == 2
    assert "exists" in capsys.readouterr().err
    assert main(["identify", str(src), "--out", str(out), "--overwrite",
                 "--no-figures"]) == 0


def test_cli_excite(tmp_path, capsys):
    out = tmp_path / "e" / "excitation.csv"
    assert main(["excite", "--out", str(out)]) == 0
    log = read_log(out, ("x", "y"), columns={"x_pos": "x_drive", "y_pos": "y_drive"})
    assert log.sample_period == pytest.approx(1e-3)
    assert main(["excite", "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err
    assert main(["excite", "--out", str(tmp_path / "e.ngc"), "--travel", "5mm"]) == 0
    assert "X2.5000" in (tmp_path / "e.ngc").read_text()
    assert main(["excite", "--out", str(tmp_path / "e.txt")]) == 2


def _bad_log(tmp_path, mutate, header="t,x_drive,x_pos"):
    rng = np.random.default_rng(0)
    n = 200
    rows = [[f"{k * 1e-3:.6g}", f"{rng.uniform(-1, 1):.6g}", f"{k * 3}"] for k in range(n)]
    mutate(rows)
    path = tmp_path / "bad.csv"
    path.write_text(header + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    return path


@pytest.mark.parametrize("mutate, header, words", [
    (lambda r: None, "t,x_drive,x_position,y_drive,y_pos", ["x_pos", "missing"]),
    (lambda r: r[57].__setitem__(0, "0.01"), "t,x_drive,x_pos,y_drive,y_pos",
     ["'t'", "row 58", "increase"]),
    (lambda r: [row.__setitem__(1, "0.5") for row in r], "t,x_drive,x_pos,y_drive,y_pos",
     ["'x_drive'", "constant"]),
    (lambda r: r[120].__setitem__(2, "nan"), "t,x_drive,x_pos,y_drive,y_pos",
     ["'x_pos'", "row 121"]),
    (lambda r: r[9].__setitem__(2, ""), "t,x_drive,x_pos,y_drive,y_pos", ["'x_pos'", "row 10"]),
    (lambda r: r[33].__setitem__(1, "1,5V".replace(",", ";")), "t,x_drive,x_pos,y_drive,y_pos",
     ["'x_drive'", "row 34"]),
    (lambda r: None, "t,x_drive,x_pos [mm],y_drive,y_pos [pulse]", ["mixed units", "x_pos",
                                                                    "y_pos"]),
    # a literal nan is not called empty; a ragged row is named by its line
    (lambda r: r[40].__setitem__(1, "nan"), "t,x_drive,x_pos,y_drive,y_pos",
     ["'x_drive'", "row 41", "nan is not"]),
    (lambda r: r[70].append("1"), "t,x_drive,x_pos,y_drive,y_pos",
     ["row 71", "line 72", "6 cells"]),
])
def test_bad_logs_get_one_typed_line(tmp_path, capsys, mutate, header, words):
    def mutate2(rows):
        mutate(rows)
        if header.count(",") == 4:
            for row in rows:
                row += [row[1], row[2]]
    path = _bad_log(tmp_path, mutate2, header)
    assert main(["identify", str(path), "--out", str(tmp_path / "m.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("nurbsmotion identify: error:")
    for w in words:
        assert w in err
    assert not (tmp_path / "m.toml").exists()
    with pytest.raises(PathFileError):
        read_log(path, ("x", "y"))


def test_project_trace_columns_are_read(tmp_path):
    """A trace.csv of the project: <a>_drive_applied is preferred to <a>_drive, <a>_meas
    to <a>_act."""
    n = 100
    t = np.arange(n) * 1e-3
    cols = {"t": t, "u": t, "x_cmd": t, "x_act": t * 2, "x_meas": t * 3,
            "x_drive": np.sin(t), "x_drive_applied": np.cos(t)}
    path = tmp_path / "trace.csv"
    np.savetxt(path, np.column_stack(list(cols.values())), delimiter=",",
               header=",".join(cols), comments="")
    log = read_log(path)
    assert log.axis_names == ("x",)
    assert log.columns == {"t": "t", "x_drive": "x_drive_applied", "x_pos": "x_meas"}
    np.testing.assert_allclose(log.drive[:, 0], np.cos(t), rtol=1e-12)
    log = read_log(path, columns={"x_pos": "x_act"})
    np.testing.assert_allclose(log.position[:, 0], 2 * t, rtol=1e-12)
    path2 = tmp_path / "mm.csv"
    np.savetxt(path2, np.column_stack([t, np.sin(t), t]), delimiter=",",
               header="t [ms],x_drive,x_pos", comments="")
    log = read_log(path2, units="mm", pulse_length_um=1.0)
    assert log.sample_period == pytest.approx(1e-6)
    np.testing.assert_allclose(log.position[:, 0], t * 1000, rtol=1e-12)
    write_excitation_csv(t, np.sin(t)[:, None], ("x",), tmp_path / "e.csv")
    assert read_log(tmp_path / "e.csv", columns={"x_pos": "x_drive"}).n_samples == n
    assert math.isfinite(log.duration)


def _one_axis(tau, kc):
    """A one-axis base machine with tau and Kc as given (the gains matter not: excite and
    identify read tau, Kc, Ke, Umax and Ts)."""
    from nurbsmotion.machine import Axis, Machine
    return Machine((Axis("x", tau, kc, KE, 0.005, 0.01),), 10.0, TS, name="base")


@pytest.mark.parametrize("truth, base_tau, base_kc", [
    # A high friction whose stiction is well above it, on the motor of a two-mass axis:
    # a fit that held the stiction at the Coulomb friction ran off to tau at its bound.
    ({"time_constant": 0.42, "gain": 4100.0 * KE, "coulomb_friction": 0.44,
      "stiction": 0.62, "resonance_frequency": 214.0, "resonance_damping": 0.085,
      "load_fraction": 0.4, "encoder_on": "motor"}, 0.52, 4150.0),
    # A strong low mode: the rigid fit's tau collapsed to a sample and the band searched
    # for the mode started beyond it.
    ({"time_constant": 0.062, "gain": 4200.0 * KE, "resonance_frequency": 73.4,
      "resonance_damping": 0.086, "load_fraction": 0.68, "encoder_on": "motor"},
     0.080, 4000.0),
])
def test_hard_two_mass_axes_within_the_targets(truth, base_tau, base_kc):
    """Regressions of the evaluation (benchmarks/identify_eval.py) on the independent
    simulator's log, from the excitation of a base machine off by up to 30 %."""
    base = _one_axis(base_tau, base_kc)
    _, drive = excitation(base)
    delay = 1.2e-3
    y = simulate_log(truth, drive[:, 0], TS, delay=delay, encoder="counts", noise=0.2,
                     seed=3, rtol=1e-7)
    est = identify(log_from_arrays(drive, y[:, None], TS), base).axes[0].estimates
    assert est["time_constant"].value == pytest.approx(truth["time_constant"], rel=0.02)
    assert est["electrical_gain"].value * KE == pytest.approx(truth["gain"], rel=0.02)
    assert abs(est["delay"].value - delay) <= 0.1 * TS
    if truth.get("coulomb_friction", 0.0) > 0:
        assert est["coulomb_friction"].value == pytest.approx(truth["coulomb_friction"],
                                                              rel=0.10)
    assert est["resonance_frequency"].value == pytest.approx(
        truth["resonance_frequency"], rel=0.02)
    assert est["resonance_damping"].value == pytest.approx(truth["resonance_damping"],
                                                           rel=0.30)


@pytest.mark.parametrize("truth, base_tau, base_kc, delay, noise, seed", [
    # The largest bin of the rigid fit's residual periodogram lay on the rigid misfit
    # (a few Hz): the mode, started there alone, was never found, and tau came out 46 %
    # short (benchmarks/identify_eval.py seed 101).
    ({"time_constant": 0.45, "gain": 1283.9 * KE, "coulomb_friction": 0.498,
      "stiction": 0.766, "resonance_frequency": 156.2, "resonance_damping": 0.073,
      "load_fraction": 0.63, "encoder_on": "load"}, 0.496, 931.0, 1.33e-3, 0.33, 101),
    # The stiction was scanned on a fit bent to the stiction held before (the Coulomb
    # friction), found there again, and written as the Coulomb friction (31 % short),
    # tau 1.8 % off (seed 82).
    ({"time_constant": 0.3626, "gain": 2386.5 * KE, "coulomb_friction": 0.255,
      "stiction": 0.374, "resonance_frequency": 89.66, "resonance_damping": 0.0158,
      "load_fraction": 0.60, "encoder_on": "load"}, 0.312, 2139.0, 1.95e-3, 0.14, 82),
])
def test_encoder_on_the_load_with_stiction_within_the_targets(truth, base_tau, base_kc,
                                                              delay, noise, seed):
    """Two-mass axes with friction on the motor and the encoder on the load, whose
    identification missed in the evaluation: the targets, and the stiction within the
    Coulomb friction's 10 %."""
    base = _one_axis(base_tau, base_kc)
    _, drive = excitation(base, seed=seed)
    y = simulate_log(truth, drive[:, 0], TS, delay=delay, encoder="counts", noise=noise,
                     seed=seed, rtol=1e-9)
    result = identify(log_from_arrays(drive, y[:, None], TS), base)
    est = result.axes[0].estimates
    assert est["time_constant"].value == pytest.approx(truth["time_constant"], rel=0.02)
    assert est["electrical_gain"].value * KE == pytest.approx(truth["gain"], rel=0.02)
    assert abs(est["delay"].value - delay) <= 0.1 * TS
    assert est["coulomb_friction"].value == pytest.approx(truth["coulomb_friction"],
                                                          rel=0.10)
    assert est["stiction"].value == pytest.approx(truth["stiction"], rel=0.10)
    assert est["resonance_frequency"].value == pytest.approx(
        truth["resonance_frequency"], rel=0.02)
    assert est["resonance_damping"].value == pytest.approx(truth["resonance_damping"],
                                                           rel=0.30)
    assert result.axes[0].encoder_on == "load"


def test_stiction_the_log_cannot_tell_from_the_friction_is_said_not_guessed():
    """A fast rigid axis whose excitation steps from rest straight past its stiction
    (benchmarks/identify_eval.py seed 4): every stiction from the Coulomb friction up fits
    the log alike. identify wrote the Coulomb friction as the stiction (19 % short, with a
    standard deviation of 0.002 V); it must say that it cannot tell."""
    truth = {"time_constant": 0.0504, "gain": 1520.6 * KE, "coulomb_friction": 0.126,
             "stiction": 0.155}
    base = _one_axis(0.0522, 1314.6)
    _, drive = excitation(base, seed=4)
    y = simulate_log(truth, drive[:, 0], TS, delay=1.67e-3, encoder="counts", noise=0.063,
                     seed=4, rtol=1e-9)
    result = identify(log_from_arrays(drive, y[:, None], TS), base)
    ax = result.axes[0]
    assert "stiction" not in ax.estimates
    assert any(n.startswith("stiction: not identifiable") for n in ax.notes)
    assert "stiction" not in result.to_machine_dict()["axes"][0]
    assert ax.estimates["coulomb_friction"].value == pytest.approx(0.126, rel=0.10)


def test_an_axis_whose_position_ignores_its_drive_does_not_crash_the_fit():
    """y's position copied from x's under a different drive: the fit's steps run the gain
    to beyond a double (exp overflowed, or underflowed to a zero gain that the model
    divides by); such a step is a worse one, not an ArithmeticError."""
    machine = die_bonder()
    _, drive = excitation(machine)
    y = simulate_log(RIGID, drive[:, 0], TS, delay=DELAY, encoder="counts", noise=0.3,
                     seed=0, rtol=1e-9)
    result = identify(log_from_arrays(drive, np.column_stack([y, y]), TS), machine)
    assert result.axes[0].estimates["time_constant"].value == pytest.approx(0.31, rel=0.02)
    assert any(n.startswith("time_constant and electrical_gain: not identified")
               for n in result.axes[1].notes)
