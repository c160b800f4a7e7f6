"""The excitation: a short test move that makes every parameter of
:func:`nurbsmotion.identify.identify` identifiable within the machine's limits.

:func:`excitation` makes the drive sequence (ramps, doublets, a random binary sequence,
each sized on the base machine to stay within a travel), :func:`write_excitation_csv`
writes it, and :func:`excitation_gcode` is its variant of position moves for a closed-loop
log. (Part of :mod:`nurbsmotion.identify`, which re-exports the public names.)

Glossary
--------
tau : time constant [s]; Kc : electrical gain [(rad/s)/V]; Ke : mechanical gain
[pulse/rad]; G = Ke*Kc : speed per volt [pulse/s/V]; Ts : sample period [s]; u : drive
[V]; y : encoder reading [pulse].
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from .._runtime.io import write_output
from ..errors import InvalidArgumentError
from ..machine import Machine

__all__ = ["excitation", "excitation_gcode", "write_excitation_csv", "DEFAULT_TRAVEL_MM"]


DEFAULT_TRAVEL_MM = 20.0
"""Default bound of the excitation's excursion from its start on a frictionless axis
[mm]."""


def _rigid_positions(tau: float, gain: float, drive: np.ndarray, Ts: float) -> np.ndarray:
    """Positions of a frictionless rigid axis from rest [pulse] (exact ZOH)."""
    from .model import simulate

    return simulate(drive, Ts, {"time_constant": tau, "gain": gain, "delay": 0.0})


def _doublet(level: float, width: int) -> np.ndarray:
    """+level for width samples, -level for 2 width, +level for width: the speed and the
    position come back near zero."""
    return np.concatenate([np.full(width, level), np.full(2 * width, -level),
                           np.full(width, level)])


def _returning(pieces, tau: float, gain: float, Ts: float, level: float,
               rest: np.ndarray) -> np.ndarray:
    """The pieces in a row, each followed by a move back towards the start (+-level for
    w samples each way, then a rest) where the previous ones left the axis off it, so
    that the excursions do not add up (frictionless rigid axis)."""
    seq = np.zeros(0)
    accel = gain * level / tau  # [pulse/s^2]
    for piece in pieces:
        seq = np.concatenate([seq, piece])
        y = _rigid_positions(tau, gain, np.concatenate([seq, [0.0, 0.0]]), Ts)
        off = float(y[-1] + (y[-1] - y[-2]) / Ts * tau)  # where it coasts to
        width = int(round(math.sqrt(abs(off) / accel) / Ts))
        if width >= 1:
            s = -math.copysign(level, off)
            seq = np.concatenate([seq, np.full(width, s), np.full(width, -s), rest])
    return seq


def excitation(machine: Machine, *, travel: float | None = None, seed: int = 0
               ) -> tuple[np.ndarray, np.ndarray]:
    """A drive sequence that makes every parameter of :func:`identify` identifiable.

    Per axis, all axes at once: a rest, slow drive ramps both ways from rest (the
    breakaway: stiction), doublets (+A, -2A, +A) at five levels from 5 % to 80 % of Umax in
    both orders (friction against gain, and tau from their curvature), a random binary
    sequence of short bits (the delay and a mode up to half the sample rate), and a rest.
    Each piece's length is set so that on the base machine, without friction, it moves the
    axis at most ``travel / 2``, and a slow move back after each piece brings the axis near
    its start again: the whole sequence stays within ``travel`` of it.

    Parameters
    ----------
    machine : Machine
        Its tau, Kc, Ke, Umax and Ts (an ideal drive, Umax = inf, is taken as 10 V).
    travel : float, optional
        Bound of the excursion [pulse]; default :data:`DEFAULT_TRAVEL_MM` mm.
    seed : int
        Seed of the random binary sequence.

    Returns
    -------
    time : ndarray, shape (n_samples,)
        [s].
    drive : ndarray, shape (n_samples, n_axes)
        [V], within +-Umax.
    """
    Ts = machine.sample_period
    umax = machine.max_drive if math.isfinite(machine.max_drive) else 10.0
    if travel is None:
        travel = DEFAULT_TRAVEL_MM * 1e3 / machine.pulse_length_um
    if not (math.isfinite(travel) and travel > 0):
        raise InvalidArgumentError(f"travel must be finite and > 0 [pulse], got {travel!r}")
    rng = np.random.default_rng(seed)
    columns = []
    for j in range(machine.n_axes):
        tau, gain = float(machine.tau[j]), float(machine.Kc[j] * machine.Ke[j])

        def fits(seq: np.ndarray) -> bool:
            return float(np.max(np.abs(_rigid_positions(tau, gain, seq, Ts)))) <= travel / 2

        def widest(make, lo: int = 1, hi: int | None = None) -> int:
            """The most samples n (<= hi) for which make(n) stays within the travel."""
            hi = hi or max(int(round(tau / Ts)), 2)
            if not fits(make(lo)):
                return lo
            while lo < hi:
                mid = (lo + hi + 1) // 2
                if fits(make(mid)):
                    lo = mid
                else:
                    hi = mid - 1
            return lo

        rest = np.zeros(max(int(round(0.1 / Ts)), 5))
        pieces = [rest]
        # Ramps from rest to 20 % of Umax and back, both ways: the breakaway.
        top = 0.2 * umax

        def ramp(n: int, sign: float) -> np.ndarray:
            up = np.linspace(0.0, sign * top, n + 1)[1:]
            return np.concatenate([up, up[::-1], -up, -up[::-1]])

        n_ramp = widest(lambda n: ramp(n, 1.0), lo=5, hi=max(int(round(0.3 / Ts)), 10))
        pieces += [ramp(n_ramp, 1.0), rest, ramp(n_ramp, -1.0), rest]
        for share in (0.05, 0.1, 0.2, 0.4, 0.8):
            level = share * umax
            width = widest(lambda n: _doublet(level, n), lo=2)
            pieces += [_doublet(level, width), rest[: len(rest) // 2],
                       _doublet(-level, width), rest[: len(rest) // 2]]
        # Short random bits (1-4 samples) at half of Umax, in +- pairs so that the speed
        # does not wander: the delay and a mode.
        level = 0.5 * umax
        bits = []
        while sum(len(b) for b in bits) < int(round(1.0 / Ts)):
            n = int(rng.integers(1, 5))
            s = level if rng.random() < 0.5 else -level
            bits += [np.full(n, s), np.full(n, -s)]
        prbs = np.concatenate(bits)
        while not fits(prbs) and level > 0.01 * umax:
            level *= 0.7
            prbs = prbs * 0.7
        pieces += [prbs, rest, rest]
        column = _returning(pieces, tau, gain, Ts, 0.05 * umax, rest)
        reach = float(np.max(np.abs(_rigid_positions(tau, gain, column, Ts))))
        if reach > travel:  # its shortest pieces go farther (--travel 1e-300 ran anyway)
            raise InvalidArgumentError(
                f"travel {travel:g} pulse is too short for the test move: its shortest pieces "
                f"take axis {machine.axis_names[j]!r} {reach:.4g} pulse from its start")
        columns.append(column)
    n = max(len(c) for c in columns)
    drive = np.zeros((n, machine.n_axes))
    for j, c in enumerate(columns):
        drive[: len(c), j] = c
    drive = np.clip(drive, -umax, umax)
    return np.arange(n) * Ts, drive


def write_excitation_csv(time_s: np.ndarray, drive: np.ndarray, axis_names, file, *,
                         overwrite: bool = False) -> Path:
    """``t,<a>_drive,...`` [s, V], full precision."""
    def write(handle):
        buf = io.StringIO()
        buf.write(",".join(["t"] + [f"{a}_drive" for a in axis_names]) + "\n")
        np.savetxt(buf, np.column_stack([time_s, drive]), delimiter=",",
                   fmt=["%.12g"] + ["%.17g"] * drive.shape[1])
        handle.write(buf.getvalue())
    return write_output(file, write, overwrite=overwrite)


def excitation_gcode(machine: Machine, *, travel: float | None = None) -> str:
    """G-code of position moves that make the closed-loop log identifiable: per axis,
    back-and-forth moves (reversals) at feeds from a crawl (friction, stiction) to the
    axis's top speed over the travel (gain, tau), and short fast moves (delay, a mode).
    Lengths in mm, feeds in mm/min, from the start point (G91)."""
    if travel is None:
        travel = DEFAULT_TRAVEL_MM * 1e3 / machine.pulse_length_um
    mm_per_pulse = machine.pulse_length_um * 1e-3
    span = travel / 2 * mm_per_pulse  # [mm]
    letters = [a.upper() for a in machine.axis_names]
    lines = ["(nurbsmotion excite: position moves for nurbsmotion identify)",
             "G21 G91"]
    for j, letter in enumerate(letters):
        vmax = float(machine.max_axis_speed[j]) if math.isfinite(machine.max_drive) else (
            10.0 * machine.Kc[j] * machine.Ke[j])
        top = 0.2 * vmax * mm_per_pulse * 60.0  # [mm/min]
        for share in (5e-4, 5e-3, 0.05, 0.25, 1.0):
            feed = max(top * share, 1.0)
            lines += [f"G1 {letter}{span:.4f} F{feed:.6g}", f"G1 {letter}{-span:.4f}"]
        short = span / 20
        for _ in range(5):
            lines += [f"G1 {letter}{short:.4f} F{top:.6g}", f"G1 {letter}{-short:.4f}"]
    lines.append("M2")
    return "\n".join(lines) + "\n"
