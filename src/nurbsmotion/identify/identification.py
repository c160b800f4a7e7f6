"""A machine identified from its log: :func:`identify` and its result.

:func:`identify` fits each axis of a :class:`~nurbsmotion.identify.log.Log` (by
:func:`nurbsmotion.identify.fit.fit_axis`) and returns an :class:`Identification`: per
parameter the estimate and its standard deviation, the fit's residual, what the log cannot
identify and why, and the machine file they make with a base machine's gains
(:meth:`Identification.to_machine_dict`, :func:`write_identification`). Only Ke*Kc is seen
in a log of drive and position; Ke comes from the base machine and Kc is the product
divided by it. (Part of :mod:`nurbsmotion.identify`, which re-exports the public names.)

Glossary
--------
tau : time constant [s]; Kc : electrical gain [(rad/s)/V]; Ke : mechanical gain
[pulse/rad]; G = Ke*Kc : speed per volt [pulse/s/V]; Ts : sample period [s]; u : drive
[V]; y : encoder reading [pulse].
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._runtime.io import json_safe, write_output
from ..errors import InvalidArgumentError, PathFileError
from ..machine import Machine
from .log import Log, read_log

__all__ = ["Estimate", "AxisIdentification", "Identification", "identify",
           "write_identification", "TAU_SPREAD", "DEFAULT_MECHANICAL_GAIN"]

# -- the result ------------------------------------------------------------------------


@dataclass(frozen=True)
class Estimate:
    """One identified parameter: its value and standard deviation (NaN where the fit
    gives none), in the unit of its machine-file key."""

    value: float
    sigma: float
    unit: str

    def to_dict(self) -> dict:
        return {"value": self.value, "sigma": None if math.isnan(self.sigma) else self.sigma,
                "unit": self.unit}


@dataclass(frozen=True)
class AxisIdentification:
    """The identification of one axis.

    Attributes
    ----------
    name : str
    estimates : dict of str to Estimate
        By machine-file key: ``time_constant`` [s], ``electrical_gain`` [(rad/s)/V],
        ``delay`` [s], ``coulomb_friction`` and ``stiction`` [V], and where a mode was
        found ``resonance_frequency`` [Hz], ``resonance_damping``, ``load_fraction``.
        Only what the log identifies.
    mechanical_gain : float
        Ke [pulse/rad], from the base machine (a log cannot tell Ke from Kc).
    encoder_on : str or None
        ``"motor"`` or ``"load"`` where a mode was found.
    residual_rms : float
        RMS of the fit's residual on the increments [pulse per sample].
    simulated : ndarray, shape (n_samples,)
        The fitted model's response to the logged drive [pulse].
    notes : list of str
        What the log cannot identify, and why.
    """

    name: str
    estimates: dict
    mechanical_gain: float
    encoder_on: str | None
    residual_rms: float
    simulated: np.ndarray
    notes: tuple


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`: per axis the estimates, the machine-level ones, and
    the machine file they make (with a base machine's gains)."""

    axes: tuple
    delay: Estimate
    encoder: str
    measurement_noise: float
    log: Log
    base: Machine | None
    notes: tuple
    seconds: float

    def to_machine_dict(self) -> dict:
        """The machine file as a dict (issue 32's keys). Gains, drive limit, sample
        period and the rest come from the base machine; without one, the axes have no
        gains (and the file is not a runnable machine until they are added)."""
        base = self.base
        data = base.to_dict() if base is not None else {
            "name": "identified", "max_drive": math.inf,
            "sample_period": self.log.sample_period, "controller": "pd+",
            "speed_measurement": "encoder", "pulse_length_um": 1.0,
            "axes": [{"name": a.name} for a in self.axes]}
        data["name"] = f"{data['name']}-identified"
        data["delay"] = self.delay.value
        data["encoder"] = self.encoder
        data["measurement_noise"] = self.measurement_noise
        for entry, ax in zip(data["axes"], self.axes):
            est = ax.estimates
            entry["time_constant"] = est["time_constant"].value
            entry["electrical_gain"] = est["electrical_gain"].value
            entry["mechanical_gain"] = ax.mechanical_gain
            for key in ("coulomb_friction", "stiction", "resonance_frequency",
                        "resonance_damping", "load_fraction"):
                if key in est:
                    entry[key] = est[key].value
            if "resonance_damping" in est:
                # The machine file's resonance_damping is the twist's whole damping ratio
                # (docs/model.md section 11), which includes the axis's own viscous
                # damping split by inertia, 1/(2*wn*tau); the fit's is the spring-damper's.
                wn = 2.0 * math.pi * est["resonance_frequency"].value
                entry["resonance_damping"] += 1.0 / (2.0 * wn * entry["time_constant"])
            if ax.encoder_on is not None:
                entry["encoder_on"] = ax.encoder_on
        return data

    @property
    def machine(self) -> Machine:
        """The identified machine as a :class:`Machine` (needs a base machine for the
        gains). Only the keys :class:`Machine` knows are kept: the others are in
        :meth:`to_machine_dict`."""
        if self.base is None:
            raise InvalidArgumentError("the identified machine needs a base machine for "
                                       "its gains: identify(log, base=...)")
        data = self.to_machine_dict()
        known = set(Machine.__dataclass_fields__) - {"_arrays"}
        keep = {k: v for k, v in data.items() if k in known}
        from ..machine import Axis

        axis_keys = set(Axis.__dataclass_fields__)
        keep["axes"] = [{k: v for k, v in a.items() if k in axis_keys} for a in data["axes"]]
        return Machine.from_dict(keep)

    def to_dict(self) -> dict:
        """``identify.json``: every estimate with its uncertainty, residual and notes."""
        return {
            "source": self.log.source,
            "columns": self.log.columns,
            "sample_period_s": self.log.sample_period,
            "duration_s": self.log.duration,
            "samples": self.log.n_samples,
            "base_machine": None if self.base is None else self.base.name,
            "delay": self.delay.to_dict(),
            "encoder": self.encoder,
            "measurement_noise": {"value": self.measurement_noise, "unit": "pulse"},
            "axes": {a.name: {
                "estimates": {k: e.to_dict() for k, e in a.estimates.items()},
                "mechanical_gain": {"value": a.mechanical_gain, "unit": "pulse/rad",
                                    "from": "base machine"},
                "encoder_on": a.encoder_on,
                "residual_rms": {"value": a.residual_rms, "unit": "pulse per sample"},
                "notes": list(a.notes)} for a in self.axes},
            "notes": list(self.notes),
            "seconds": self.seconds,
        }

    def to_toml(self) -> str:
        """The machine file's text: :meth:`to_machine_dict` with each estimate's
        uncertainty, the residual and the notes in comments at its head."""
        import tomli_w

        lines = [f"# Identified by nurbsmotion identify from {self.log.source}",
                 f"# ({self.log.n_samples} samples every {self.log.sample_period:g} s"
                 + (f"; gains from base machine {self.base.name!r}" if self.base else
                    "; no base machine: add the gains") + ")",
                 f"# delay = {_shown(self.delay)}"]
        for a in self.axes:
            lines.append(f"# axis {a.name}: residual RMS {a.residual_rms:.4g} pulse per "
                         f"sample; Ke {a.mechanical_gain:.8g} pulse/rad from the base")
            for key, e in a.estimates.items():
                lines.append(f"#   {key} = {_shown(e)}")
            for note in a.notes:
                lines.append(f"#   not identified: {note}")
        for note in self.notes:
            lines.append(f"# note: {note}")
        data = _finite(self.to_machine_dict())
        return "\n".join(lines) + "\n\n" + tomli_w.dumps(data)

    def plot(self, out, *, overwrite: bool = False):
        """Write ``identify.png``: measured against simulated response (matplotlib is
        imported here)."""
        from .plot import plot_identification

        return plot_identification(self, out, overwrite=overwrite)


def _shown(e: Estimate) -> str:
    s = "" if math.isnan(e.sigma) else f" +- {e.sigma:.3g}"
    return f"{e.value:.6g}{s} {e.unit}".rstrip()


def _finite(data):
    """``inf`` as TOML writes it is fine; NaN is not a value a machine file holds."""
    if isinstance(data, dict):
        return {k: _finite(v) for k, v in data.items() if not (isinstance(v, float)
                                                               and math.isnan(v))}
    if isinstance(data, list):
        return [_finite(v) for v in data]
    return data


# -- identification --------------------------------------------------------------------


TAU_SPREAD = 0.05
"""A time constant whose standard deviation exceeds this share of it is reported as poorly
identified."""

DEFAULT_MECHANICAL_GAIN = 10_000 / (2 * math.pi)
"""Ke [pulse/rad] without a base machine: 10,000 pulses per revolution (the die-bonder's)."""


def identify(log, base: Machine | None = None, *, max_drive: float | None = None
             ) -> Identification:
    """Identify a machine from a log of drive and encoder position.

    Parameters
    ----------
    log : Log or path-like
        A :class:`Log`, or a log file read with :func:`read_log` (with the base's axes).
    base : Machine, optional
        Ke per axis, the gains, the drive limit and the sample period of the machine file;
        its tau and Kc start the fit where the log says little.
    max_drive : float, optional
        Umax [V] bounding the friction; the base's, or the log's largest |drive|.

    Returns
    -------
    Identification

    Raises
    ------
    PathFileError, InvalidArgumentError
        A bad log (see :func:`read_log`), or a log whose axes are not the base's.
    """
    from .fit import fit_axis

    started = time.perf_counter()
    if not isinstance(log, Log):
        log = read_log(log, None if base is None else base.axis_names,
                       pulse_length_um=1.0 if base is None else base.pulse_length_um)
    if base is not None and tuple(log.axis_names) != tuple(base.axis_names):
        raise InvalidArgumentError(f"the log's axes {', '.join(log.axis_names)} are not the "
                                   f"base machine's {', '.join(base.axis_names)}")
    Ts = log.sample_period
    umax = max_drive if max_drive is not None else (
        base.max_drive if base is not None and math.isfinite(base.max_drive)
        else float(np.max(np.abs(log.drive))))
    counts = bool(np.all(log.position == np.round(log.position)))
    notes = []
    axes = []
    delays, delay_sig = [], []
    noise_vars = []
    for j, name in enumerate(log.axis_names):
        u = log.drive[:, j]
        y = log.position[:, j]
        dy = np.diff(y)
        if np.all(np.abs(dy) <= 1.0):
            raise PathFileError(f"column {log.columns.get(f'{name}_pos', name + '_pos')!r}: "
                                "the axis never moved more than a count per sample; "
                                "nothing can be identified", log.source)
        Ke = base.Ke[j] if base is not None else DEFAULT_MECHANICAL_GAIN
        start = None if base is None else {"time_constant": base.tau[j],
                                           "gain": base.Kc[j] * base.Ke[j]}
        fit = fit_axis(u, y, Ts, max_drive=umax, base=start)
        v, s = fit.values, fit.sigma
        est = {"time_constant": Estimate(v["time_constant"], s["time_constant"], "s"),
               "electrical_gain": Estimate(v["gain"] / Ke, s["gain"] / Ke, "(rad/s)/V"),
               "delay": Estimate(v["delay"], s["delay"], "s")}
        if fit.identified["coulomb_friction"]:
            est["coulomb_friction"] = Estimate(v["coulomb_friction"],
                                               s["coulomb_friction"], "V")
        if fit.identified["stiction"]:
            est["stiction"] = Estimate(v["stiction"], s["stiction"], "V")
        encoder_on = None
        axis_notes = list(fit.notes)
        spread = s["time_constant"] / v["time_constant"]
        if not spread <= TAU_SPREAD:
            axis_notes.append(
                f"time_constant and electrical_gain: poorly identified (tau +- {spread:.0%}):"
                " the log's moves are short against tau, so only Kc/tau (the acceleration "
                "per volt) is sharp; log longer moves (more --travel in excite, or its "
                "G-code variant in closed loop)")
        if fit.identified["resonance"]:
            est["resonance_frequency"] = Estimate(v["resonance_frequency"],
                                                  s["resonance_frequency"], "Hz")
            est["resonance_damping"] = Estimate(v["resonance_damping"],
                                                s["resonance_damping"], "")
            c, sc = v["coupling"], s["coupling"]
            if c > 0:
                encoder_on = "motor"
                share = c / (1 + c)
                est["load_fraction"] = Estimate(share, sc / (1 + c) ** 2, "")
            elif "load_fraction" in v:  # from the motor's stops (friction on the motor)
                encoder_on = "load"
                est["load_fraction"] = Estimate(v["load_fraction"], s["load_fraction"], "")
            else:
                encoder_on = "load"
                axis_notes.append(f"load_fraction: not identifiable with the encoder on the "
                                  f"load (the mode's coupling {c:.3g} is about -1 whatever "
                                  "the share); the machine file keeps the default")
        axis_notes.append("mechanical_gain: a log of drive and position shows only Ke*Kc; "
                          "Ke is the base machine's" if base is not None else
                          "mechanical_gain: a log shows only Ke*Kc; Ke is taken as 10,000 "
                          "pulse/rev without a base machine")
        delays.append(v["delay"])
        delay_sig.append(s["delay"])
        # The increments' residual holds the reading noise twice, and a count's rounding.
        noise_vars.append(max(fit.residual_rms ** 2 / 2 - (1 / 12 if counts else 0.0), 0.0))
        axes.append(AxisIdentification(name, est, float(Ke), encoder_on, fit.residual_rms,
                                       fit.simulated, tuple(axis_notes)))
    d = float(np.mean(delays))
    sd = float(math.sqrt(np.sum(np.square(delay_sig)))) / len(delays)
    if len(delays) > 1 and np.ptp(delays) > 0.1 * Ts:
        notes.append(f"the axes' delays differ ({', '.join(f'{x:.4g}' for x in delays)} s); "
                     "the machine file's one delay is their mean")
    if base is not None and abs(base.sample_period - Ts) > 1e-9 * Ts:
        notes.append(f"the log is sampled every {Ts:g} s and the base machine's controller "
                     f"every {base.sample_period:g} s; the plant is continuous, the "
                     "machine file keeps the base's period")
    notes.append("dac_bits: not identifiable from a log of the drive command; not written")
    noise = float(math.sqrt(min(noise_vars)))
    return Identification(tuple(axes), Estimate(d, sd, "s"), "counts" if counts else "exact",
                          noise, log, base, tuple(notes), time.perf_counter() - started)


def write_identification(result: Identification, out, *, figure: bool = True,
                         overwrite: bool = False) -> list:
    """Write ``result``'s machine file ``out`` (TOML), ``identify.json`` beside it and the
    figure ``identify.png``; nothing is overwritten unless asked."""
    out = Path(out)
    folder = out.parent
    written = [write_output(out, lambda h: h.write(result.to_toml()), overwrite=overwrite)]
    written.append(write_output(folder / "identify.json",
                                lambda h: json.dump(json_safe(result.to_dict()), h,
                                                    indent=2),
                                overwrite=overwrite))
    if figure:
        written.append(result.plot(folder, overwrite=overwrite))
    return written
