"""One case of a study: its path, feed and true plant, its run, and its row.

:func:`case_trace` builds and runs a case's loop as ``nurbsmotion run`` would (the path
in pulses, the feed by :func:`nurbsmotion.study.run_input.run_feed`, the true plant scaled
by the case's plant group); :func:`run_case` turns it into one row of the dataset, or an
error row, under the case's CPU-time limit. A worker keeps what its cases share: each
path with its arc-length tables, a path's error, and the time-optimal bounds.
"""

from __future__ import annotations

import math
import time
from contextlib import contextmanager
from dataclasses import replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import InvalidArgumentError
from ..machine import Machine
from ..units import Scale
from .spec import STATUS_ERROR, STATUS_OK, Case, PlantGroup, _machine

__all__ = ["case_trace", "run_case"]


@lru_cache(maxsize=64)
def _contour(path: str, family: str | None, path_seed: int | None, n_axes: int,
             length: float, base_dir: str, machine_spec: str, tool_table: str | None = None):
    """The case's path and its programmed feed (a ``Contour``; kept per worker: its
    arc-length table serves every case on it), read on the machine ``machine_spec`` by
    the function ``nurbsmotion run`` reads its path with
    (:func:`nurbsmotion.study.run_input.load_run_contour`: G-code and DXF on its axes,
    rotary axes rescaled, runs of CAM chords joined within the default path tolerance).
    A random path (``family``) is made, not read: it is used as drawn. ``tool_table``:
    the study's ``tool_table`` (relative to ``base_dir``), for G-code programs."""
    if family is not None:
        from ..paths import Contour
        from ..paths.random_paths import random_path

        return Contour(random_path(family, path_seed, n_axes, length), None, path)
    from ..nurbs import BUILTIN_PATHS
    from .run_input import load_run_contour

    spec = path if path.split("#")[0] in BUILTIN_PATHS else str(Path(base_dir) / path)
    table = None if tool_table is None else str(Path(base_dir) / tool_table)
    if table is not None and Path(spec.split("#")[0]).suffix.lower() in ("", ".dxf", ".json", ".toml"):
        table = None  # the study's tool table is for its G-code programs (not built-ins, DXF, NURBS)
    return load_run_contour(spec, _machine(machine_spec, base_dir), tool_table=table)


_PATH_ERRORS: dict = {}
"""Per worker: why a path could not be built (it fails the same way for all its cases)."""


def _path(case: Case, machine: Machine):
    """The case's path with its programmed feed and its arc-length tables
    (:func:`_contour`, kept per worker); a path that could not be built, or whose tables
    took more than the case's time limit, fails the worker's other cases on it at once,
    with the same error."""
    from ..planning import check_path_size

    key = _path_key(case) + (case.machine, case.tool_table)
    if key in _PATH_ERRORS:
        raise _PATH_ERRORS[key]
    try:
        contour = _contour(*key)
        pulses = _pulses(key, Scale.of(contour.curve, machine).factor)
        check_path_size(pulses)  # counted from the knots, before the tables
        pulses.length  # the tables every interpolator and figure reads
    except Exception as exc:
        _PATH_ERRORS[key] = exc
        raise
    return contour, pulses


@lru_cache(maxsize=64)
def _pulses(key: tuple, per_unit: float):
    """The path of ``_contour(*key)`` in pulses (``per_unit`` pulses per path unit), kept
    per worker with its arc-length tables."""
    contour = _contour(*key)
    return contour.curve if per_unit == 1.0 else contour.curve.scaled(per_unit,
                                                                       units="pulse")


def _feed_text(case: Case):
    """The case's feed as ``run --feed`` takes it: a text with the study's unit
    (``"50mm/s"``), or a bare number in the path's units per second (``path/s``)."""
    if case.feed_unit == "path/s":
        return case.feed_value
    return f"{case.feed_value!r}{case.feed_unit}"


def _plant_scales(case: Case, n_axes: int) -> tuple[np.ndarray, np.ndarray]:
    """tau and Kc scale factors per axis, shape (n_axes,) each."""
    g = case.plant
    if g.spread > 0:
        rng = np.random.default_rng(case.seed)
        s = rng.uniform(1 - g.spread, 1 + g.spread, (2, n_axes))
        return s[0], s[1]
    out = []
    for v in (g.tau_scale, g.Kc_scale):
        if len(v) not in (1, n_axes):
            raise InvalidArgumentError(f"plant {g.name!r}: {len(v)} scale factors for {n_axes} axes")
        out.append(np.broadcast_to(np.array(v), (n_axes,)).copy())
    return out[0], out[1]


def _true_machine(machine: Machine, group: PlantGroup) -> Machine:
    """``machine`` with the plant group's effect keys (per-axis keys on every axis),
    validated as a machine (a delay its loop cannot take is refused, naming the poles)."""
    if not group.effects:
        return machine
    from dataclasses import replace

    from ..machine import AXIS_EFFECT_KEYS

    keys = dict(group.effects)
    axis_keys = {k: v for k, v in keys.items() if k in AXIS_EFFECT_KEYS}
    machine_keys = {k: v for k, v in keys.items() if k not in AXIS_EFFECT_KEYS}
    return machine.with_options(axes=tuple(replace(a, **axis_keys) for a in machine.axes),
                                **machine_keys)


def case_trace(case: Case):
    """Run one case: ``(trace, summary dict, tau scales, Kc scales)``.

    The case's :class:`~nurbsmotion.job.Job`: its path in pulses (kept per worker), its
    feed as ``nurbsmotion run PATH --feed F`` runs it, its true plant, and the bound kept
    per worker.
    """
    from ..job import Job
    from ..metrics import check_settle_window
    from ..servo import ServoPlant

    from .run_input import run_feed

    machine = _machine(case.machine, case.base_dir)
    contour, pulses = _path(case, machine)
    machine.check_path(contour.curve.n_axes)
    check_settle_window(case.settle_window, pulses, "settle_window")
    # What `nurbsmotion run PATH --feed F` runs: the path in pulses, the feed in pulse/s
    # (per piece where the file programs one, capped by the study's feed).
    feed = run_feed(_feed_text(case), contour, machine)
    tau_s, kc_s = _plant_scales(case, machine.n_axes)
    plant = ServoPlant.of_machine(_true_machine(machine, case.plant), pulses(0.0),
                                  time_constant_scale=tau_s, electrical_gain_scale=kc_s)
    job = Job(pulses, machine, (feed, "pulse"), case.interpolator, plant=plant,
              settle_window=case.settle_window, settle_time=case.settle_time,
              time_optimal_bound=math.nan, name=case.path)
    result = job.run()
    if case.bound:  # after the run, as it always was: a run's error comes first
        result = replace(result, bound=_bound(case, pulses, machine, job.feed_pulses))
    extra = None
    if plant.effects is not None:  # what the machine did at rest (issue 32); added keys
        extra = result.at_rest_keys(in_report_unit=False)
    return result.trace, result.summary(extra, in_report_unit=False), tau_s, kc_s


_BOUNDS: dict = {}
"""Per worker: the time-optimal bound of (path, machine, feed) [s]."""


def _bound(case: Case, path, machine: Machine, feed) -> float:
    """The time-optimal bound [s] of ``path`` [pulse] at ``feed`` [pulse/s]; it depends on
    the path, the model and the feed only, so a worker keeps it for the case's other
    plants and interpolators."""
    from ..planning import time_optimal_bound

    key = _path_key(case) + (case.machine, case.feed_value, case.feed_unit)
    if key not in _BOUNDS:
        if len(_BOUNDS) >= 256:
            _BOUNDS.clear()
        _BOUNDS[key] = time_optimal_bound(path, machine, feed)
    return _BOUNDS[key]


def run_case(case: Case) -> dict:
    """One row of the dataset: the case's parameters and seed, ``status``, and every
    ``summary.json`` key (per-axis values as ``key_<axis>``); a case that raises gives
    ``status = "error"`` with ``error_type`` and ``error_message`` instead of figures."""
    # The CPU time of this thread, not of the process: a Dask worker runs its event loop
    # (heartbeats, transfers, its profiler) beside the case, which is not the case's work.
    t0, cpu0 = time.perf_counter(), time.thread_time()
    row = _case_columns(case)
    try:
        with _cpu_limit(case.time_limit):
            _, data, tau_s, kc_s = case_trace(case)
    except Exception as exc:  # recorded, never lost: the campaign goes on
        row.update(status=STATUS_ERROR, error_type=type(exc).__name__,
                   error_message=str(exc)[:2000])
    else:
        row.update(status=STATUS_OK, error_type=None, error_message=None)
        for key, value in data.items():
            if isinstance(value, dict):
                for axis, v in value.items():
                    row[f"{key}_{axis}"] = v
            else:
                row[key] = value
        for axis, t, k in zip(_machine(case.machine, case.base_dir).axis_names, tau_s, kc_s):
            row[f"tau_scale_{axis}"], row[f"Kc_scale_{axis}"] = float(t), float(k)
    row["case_time_s"] = time.perf_counter() - t0
    row["case_cpu_s"] = time.thread_time() - cpu0
    return row


@contextmanager
def _cpu_limit(seconds: float | None):
    """Raise :class:`~nurbsmotion.errors.WorkLimitError` in this process once the block
    has used ``seconds`` of CPU time, and every CPU second after that until it ends (a
    CPU-time timer: a loaded machine does not shorten it). Python code is stopped at once,
    a compiled loop when it returns; on a platform without ``setitimer``, or off the main
    thread (a Dask worker's task), there is no limit."""
    import signal
    import threading

    if (not seconds or not hasattr(signal, "setitimer")
            or threading.current_thread() is not threading.main_thread()):
        yield
        return
    from ..errors import WorkLimitError

    def expired(signum, frame):
        raise WorkLimitError(f"the case used more than {seconds:g} s of CPU time (the "
                             "study's case_time_limit) and was stopped")

    previous = signal.signal(signal.SIGPROF, expired)
    signal.setitimer(signal.ITIMER_PROF, seconds, 1.0)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, previous)


def _case_columns(case: Case) -> dict:
    return {"case_id": case.case_id, "case_index": case.index, "seed": case.seed,
            "path": case.path, "path_family": case.path_family, "path_seed": case.path_seed,
            "n_axes": case.n_axes, "feed_value": case.feed_value, "feed_unit": case.feed_unit,
            "machine": case.machine, "plant": case.plant.name,
            "interpolator": case.interpolator, "attempts": 1}


def _path_key(case: Case) -> tuple:
    return (case.path, case.path_family, case.path_seed, case.n_axes, case.length,
            case.base_dir)
