"""Issue 34 evaluation of ``nurbsmotion identify``: the identification error on random
machines, and the run time on a 60 s log at 1 kHz.

For each of N random one-axis machines (tests/identify_reference.py ``random_axis``: tau
0.05-0.5 s, Ke*Kc over a factor 5, Coulomb friction 0.05-0.6 V with stiction 1-1.6 times
it, half of them with a mode at 40-250 Hz, damping 0.01-0.1, load share 0.2-0.7, encoder on
the motor (70 %) or the load; two-mass axes have friction, on the motor, on half of them),
a delay of 0-2 samples, 1-pulse encoder counts and Gaussian reading noise of 0-0.5 pulse:

1. ``nurbsmotion excite`` of a base machine whose tau and Kc are off by up to +-30 % (what
   a user knows before identifying);
2. the log of the true machine under it, made by the independent ``solve_ivp`` simulator
   of the tests (not the project's loop, not the fit's model);
3. ``identify`` of the log, and the errors against the truth;
4. the refit: a log of the identified machine (the fit's own model, the same drive, counts
   and noise) identified again, and the change of tau, Kc, the delay and the mode.

Prints a Markdown table per class of machine (rigid, two-mass without friction, two-mass
with friction): the median and 95th percentile of each error and the share within the
issue's targets (tau and Kc 2 %, delay 0.1 Ts, Coulomb 10 %, mode frequency 2 %, damping
30 %; the issue sets none for the stiction, which is held to the Coulomb friction's 10 %),
the modes found and missed; then identify's time on a 60 s log (made with the fit's
own model, which only sets what the log holds).

Run: python benchmarks/identify_eval.py [N] (default 200; ``--workers``, default
NURBSMOTION_IDENTIFY_WORKERS or 2). Writes benchmarks/identify_eval.json (every row) and
benchmarks/identify_eval.md (the table). ``--seeds 82 101`` runs only those machines and
prints their rows (nothing written); ``--cache DIR`` keeps each simulated log there (most
of the run time is the solve_ivp simulation; a log is reused only for the same machine,
drive and simulator settings, so a changed excitation simulates afresh).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

from _common import ROOT  # noqa: F401  (puts src/ on the path)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from identify_reference import random_axis, simulate_log  # noqa: E402

from nurbsmotion.identify import excitation, identify, log_from_arrays  # noqa: E402
from nurbsmotion.machine import Axis, Machine  # noqa: E402

KE = 1591.5494
TS = 1e-3
GAINS = ((0.0136, 0.03), (0.00577, 0.028), (0.03, 0.05), (0.005, 0.01))


def base_machine(tau: float, kc: float) -> Machine:
    """A one-axis machine with tau and Kc as given and the first stable die-bonder-like
    gains (excite uses only tau, Kc, Ke, Umax and Ts)."""
    for kp, kd in GAINS:
        try:
            return Machine((Axis("x", tau, kc, KE, kp, kd),), 10.0, TS, name="base")
        except ValueError:
            continue
    raise RuntimeError(f"no stable gains for tau {tau}, Kc {kc}")


REFERENCE_RTOL = 1e-9
"""Relative tolerance of the reference simulator. At 1e-7 (the previous evaluations) an
integration error decided a stop near the stiction the other way on some machines, and the
log went its own way (seed 82: 73 pulses off the exact log, an increment RMS of 0.30
pulse, which the fit absorbed as a 2 % error in tau); from 1e-8 the log matches the exact
model to rounding."""

CACHE: Path | None = None
"""Folder of cached simulated logs (``--cache``), or None."""


def simulated_log(axis: dict, drive: np.ndarray, delay: float, noise: float,
                  seed: int) -> np.ndarray:
    """The reference simulator's log (tests/identify_reference.py), from :data:`CACHE`
    when the same machine, drive and settings were simulated before."""
    settings = dict(axis=axis, delay=delay, encoder="counts", noise=noise, seed=seed,
                    rtol=REFERENCE_RTOL)
    key = hashlib.sha256(json.dumps(settings, sort_keys=True).encode()
                         + np.ascontiguousarray(drive).tobytes()).hexdigest()[:20]
    file = None if CACHE is None else CACHE / f"{seed}-{key}.npy"
    if file is not None and file.exists():
        return np.load(file)
    y = simulate_log(axis, drive, TS, delay=delay, encoder="counts", noise=noise,
                     seed=seed, rtol=REFERENCE_RTOL)
    if file is not None:
        file.parent.mkdir(parents=True, exist_ok=True)
        tmp = file.with_suffix(f".{os.getpid()}.tmp.npy")
        np.save(tmp, y)
        tmp.replace(file)
    return y


def one(seed: int) -> dict:
    rng = np.random.default_rng(1000 + seed)
    axis = random_axis(rng)
    if "resonance_frequency" in axis and rng.random() < 0.5:
        axis["coulomb_friction"] = axis["stiction"] = 0.0
    delay = float(rng.uniform(0.0, 2.0)) * TS
    noise = float(rng.uniform(0.0, 0.5))
    kc = axis["gain"] / KE
    base = base_machine(axis["time_constant"] * rng.uniform(0.7, 1.3),
                        kc * rng.uniform(0.7, 1.3))
    _, drive = excitation(base, seed=seed)
    y = simulated_log(axis, drive[:, 0], delay, noise, seed)
    started = time.process_time()
    result = identify(log_from_arrays(drive, y[:, None], TS), base)
    cpu = time.process_time() - started
    est = result.axes[0].estimates
    row = {"seed": seed, "truth": axis, "delay": delay, "noise": noise, "cpu_s": cpu,
           "samples": len(y)}
    row["tau_err"] = est["time_constant"].value / axis["time_constant"] - 1
    row["kc_err"] = est["electrical_gain"].value / kc - 1
    row["delay_err_ts"] = (est["delay"].value - delay) / TS
    row["estimates"] = {key: e.value for key, e in est.items()}
    row["notes"] = list(result.axes[0].notes)
    if axis["coulomb_friction"] > 0:
        row["coulomb_err"] = (est["coulomb_friction"].value / axis["coulomb_friction"] - 1
                              if "coulomb_friction" in est else math.nan)
        row["stiction_err"] = (est["stiction"].value / axis["stiction"] - 1
                               if "stiction" in est else math.nan)
    mode = "resonance_frequency" in axis
    row["class"] = ("rigid" if not mode else
                    "two-mass, friction" if axis["coulomb_friction"] > 0 else "two-mass")
    row["mode_found"] = "resonance_frequency" in est
    if mode and row["mode_found"]:
        row["freq_err"] = est["resonance_frequency"].value / axis["resonance_frequency"] - 1
        row["damping_err"] = est["resonance_damping"].value / axis["resonance_damping"] - 1
    refit(row, result, drive[:, 0], noise, seed, base)
    return row


def refit(row: dict, result, drive: np.ndarray, noise: float, seed: int, base) -> None:
    """The issue's "a machine refit from its own refit is stable": a log of the identified
    machine under the same drive, with the same counts and noise (made with the fit's own
    model: the question is the estimator's fixed point, not the model), identified again;
    the change of each estimate from the first identification."""
    from nurbsmotion.identify.model import simulate

    ax = result.axes[0]
    est = {key: e.value for key, e in ax.estimates.items()}
    params = {"time_constant": est["time_constant"], "gain": est["electrical_gain"] * KE,
              "delay": est["delay"], "coulomb_friction": est.get("coulomb_friction", 0.0),
              "stiction": est.get("stiction", 0.0)}
    if "resonance_frequency" in est:
        lam = est.get("load_fraction", 0.5)
        params.update(resonance_frequency=est["resonance_frequency"],
                      resonance_damping=est["resonance_damping"], load_fraction=lam,
                      coupling=lam / (1 - lam) if ax.encoder_on == "motor" else -1.0)
    y = np.floor(simulate(drive, TS, params)) + np.random.default_rng(seed + 10_000).normal(
        0.0, noise, len(drive))
    again = identify(log_from_arrays(drive[:, None], y[:, None], TS), base).axes[0].estimates
    row["refit_tau"] = again["time_constant"].value / est["time_constant"] - 1
    row["refit_kc"] = again["electrical_gain"].value / est["electrical_gain"] - 1
    row["refit_delay_ts"] = (again["delay"].value - est["delay"]) / TS
    if "resonance_frequency" in est:
        row["refit_freq"] = (again["resonance_frequency"].value / est["resonance_frequency"]
                             - 1 if "resonance_frequency" in again else math.nan)


TARGETS = (("tau_err", "tau", 0.02), ("kc_err", "Kc", 0.02),
           ("delay_err_ts", "delay [Ts]", 0.1), ("coulomb_err", "Coulomb", 0.10),
           ("stiction_err", "stiction", 0.10),
           ("freq_err", "mode freq.", 0.02), ("damping_err", "damping", 0.30),
           ("refit_tau", "refit's tau", 0.02), ("refit_kc", "refit's Kc", 0.02),
           ("refit_delay_ts", "refit's delay [Ts]", 0.1),
           ("refit_freq", "refit's mode freq.", 0.02))


def table(rows: list[dict]) -> str:
    lines = ["| class | machines | quantity | median abs error | 95th pct | within target |",
             "|---|---|---|---|---|---|"]
    for cls in ("rigid", "two-mass", "two-mass, friction"):
        sub = [r for r in rows if r["class"] == cls]
        if not sub:
            continue
        for key, label, target in TARGETS:
            # an estimate the log did not identify (NaN) counts as a miss
            every = np.array([abs(r[key]) for r in sub if key in r])
            vals = every[np.isfinite(every)]
            if vals.size == 0:
                continue
            pct = "delay" not in key
            fmt = (lambda v: f"{100 * v:.2f} %") if pct else (lambda v: f"{v:.3f}")
            missing = every.size - vals.size
            lines.append(f"| {cls} | {len(sub)} | {label} | {fmt(np.median(vals))} | "
                         f"{fmt(np.percentile(vals, 95))} | "
                         f"{np.mean(np.nan_to_num(every, nan=np.inf) <= target):.0%} of "
                         f"{every.size}" + (f" ({missing} not identified)" if missing else "")
                         + " |")
        found = sum(r["mode_found"] for r in sub)
        lines.append(f"| {cls} | {len(sub)} | mode found | {found} of {len(sub)} | | |")
    return "\n".join(lines)


def timing() -> dict:
    """identify on a 60 s log at 1 kHz (a two-mass axis with friction, delay, counts and
    noise; the log made with the fit's own model)."""
    from nurbsmotion.identify.model import simulate
    from nurbsmotion.machine import die_bonder

    machine = die_bonder()
    _, drive = excitation(machine)
    reps = int(math.ceil(60.0 / (len(drive) * TS)))
    drive = np.tile(drive, (reps, 1))[: int(60.0 / TS)]
    rng = np.random.default_rng(0)
    truth = [{"time_constant": 0.31, "gain": 2506.17 * KE, "coulomb_friction": 0.3,
              "stiction": 0.4, "delay": 0.5e-3},
             {"time_constant": 0.135, "gain": 3156.23 * KE, "coulomb_friction": 0.3,
              "stiction": 0.4, "delay": 0.5e-3, "resonance_frequency": 100.0,
              "resonance_damping": 0.02, "coupling": 1.0}]
    y = np.column_stack([np.floor(simulate(drive[:, j], TS, p)) + rng.normal(0, 0.3, len(drive))
                         for j, p in enumerate(truth)])
    log = log_from_arrays(drive, y, TS)
    identify(log, machine)  # compiles or loads the kernels
    walls, cpus = [], []
    for _ in range(3):
        w, c = time.perf_counter(), time.process_time()
        identify(log, machine)
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return {"samples": len(drive), "axes": 2, "wall_s": float(np.median(walls)),
            "cpu_s": float(np.median(cpus))}


def _init(cache) -> None:
    global CACHE
    CACHE = cache


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("n", nargs="?", type=int, default=200,
                        help="random machines, seeds 0..n-1 (default 200)")
    parser.add_argument("--seeds", type=int, nargs="+",
                        help="only these seeds: print their rows, write nothing")
    parser.add_argument("--workers", type=int,
                        default=int(os.environ.get("NURBSMOTION_IDENTIFY_WORKERS", "2")))
    parser.add_argument("--cache", type=Path, help="folder of cached simulated logs")
    parser.add_argument("--resume", action="store_true",
                        help="keep the rows of identify_eval.partial.jsonl (a run cut "
                        "short, on the same code) and run only the other seeds")
    parser.add_argument("--timing-from", type=Path,
                        help="the 60 s log's timing from this JSON (a --timing-only run's) "
                        "instead of measuring it again")
    parser.add_argument("--timing-only", action="store_true",
                        help="only the 60 s log's timing, printed as JSON")
    args = parser.parse_args(argv)
    if args.timing_only:
        print(json.dumps(timing()))
        return
    seeds = args.seeds if args.seeds else list(range(args.n))
    started = time.perf_counter()
    rows = []
    partial = Path(__file__).with_suffix(".partial.jsonl")
    if args.resume and partial.exists():
        rows = [json.loads(line) for line in partial.read_text().splitlines() if line]
        done = {r["seed"] for r in rows}
        seeds = [s for s in seeds if s not in done]
    with Pool(args.workers, initializer=_init, initargs=(args.cache,)) as pool, \
            open(partial, "a" if args.resume else "w") as stream:
        for row in pool.imap(one, seeds, chunksize=1):  # each row as it comes
            rows.append(row)
            stream.write(json.dumps(row, default=float) + "\n")
            stream.flush()
    partial.unlink()
    if args.seeds:
        for r in rows:
            print(json.dumps(r, default=float))
        print(table(rows))
        return
    n = len(rows)
    print(f"{n} random machines in {time.perf_counter() - started:.0f} s "
          f"(identify: median {np.median([r['cpu_s'] for r in rows]):.2f} s CPU per "
          f"{rows[0]['samples']}-sample log)\n")
    rows.sort(key=lambda r: r["seed"])
    print(table(rows))
    t = json.loads(args.timing_from.read_text()) if args.timing_from else timing()
    print(f"\nidentify on a 60 s log at 1 kHz ({t['samples']} samples, {t['axes']} axes, "
          f"one with a mode): {t['wall_s']:.2f} s wall, {t['cpu_s']:.2f} s CPU "
          "(median of 3)")
    out = Path(__file__).with_suffix(".json")
    out.write_text(json.dumps({"rows": rows, "timing": t}, indent=1, default=float))
    write_markdown(rows, t, time.perf_counter() - started)


def write_markdown(rows: list[dict], t: dict, seconds: float) -> Path:
    """benchmarks/identify_eval.md: the table and the timing, with how they were made."""
    import subprocess

    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=Path(__file__).parent).stdout.strip()
    except OSError:
        commit = "unknown"
    cpu = np.median([r["cpu_s"] for r in rows])
    text = "\n".join([
        "# `nurbsmotion identify` on random machines (generated)",
        "",
        f"`python benchmarks/identify_eval.py {len(rows)}` on commit {commit} (plus the "
        f"working tree), {time.strftime('%Y-%m-%d', time.gmtime())}: {len(rows)} random "
        f"one-axis machines in {seconds:.0f} s; identify a median {cpu:.2f} s of CPU per "
        f"{rows[0]['samples']}-sample log. Logs from the tests' independent solve_ivp "
        "simulator (tests/identify_reference.py, rtol "
        f"{REFERENCE_RTOL:g}) with 1-pulse counts and 0-0.5 pulse of noise; targets of "
        "issue 34 (the stiction's, which the issue does not set, the Coulomb friction's). "
        "The refit rows: a log of the identified machine (the fit's own model, the same "
        "drive, counts and noise) identified again, against the first identification.",
        "",
        table(rows),
        "",
        f"identify on a 60 s log at 1 kHz ({t['samples']} samples, {t['axes']} axes, one "
        f"with a mode): {t['wall_s']:.2f} s wall, {t['cpu_s']:.2f} s CPU (median of 3).",
        ""])
    out = Path(__file__).with_suffix(".md")
    out.write_text(text)
    return out


if __name__ == "__main__":
    main()
