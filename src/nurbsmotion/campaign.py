"""Studies: many runs (paths x feeds x machines x true plants x interpolators), in parallel,
into a Parquet dataset, with a digest.

A study file (TOML, schema in ``docs/campaign.md``) lists the values of each factor;
:func:`study_cases` expands them into :class:`Case` objects, every combination or a seeded
sample of them. :func:`run_case` runs one case and returns its row: every
``summary.json`` key (per-axis values flattened to ``key_<axis>``), the case parameters,
its seed, and ``status`` (``"ok"`` or ``"error"``, with the error's type and message).
:func:`run_study` runs all unfinished cases — serially, on local processes, or on a Dask
cluster — and appends the finished rows to ``OUT/rows/part-*.parquet`` (a part file is
written once, under a temporary name, and never rewritten), so a campaign that stops for
any reason resumes where it was. :func:`digest` summarises the dataset.

Every random draw of a case (its random path, its random plant) comes from seeds derived
from the study's seed and the case's index, never from a worker, so the rows are the same
bit for bit however the cases are spread (only ``case_time_s`` and ``case_cpu_s``, the
case's wall and CPU time, differ).

pyarrow, dask and tqdm are imported only when used.
"""

from __future__ import annotations

import math
import os
import pickle
import sys
import time
import uuid
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from itertools import product
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from ._runtime.io import write_output
from .errors import InvalidArgumentError, PathFileError
from .interpolators import LOOP_METHODS
from .machine import Machine, load_machine
from .metrics import SETTLE_WINDOW

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["Study", "Case", "load_study", "study_cases", "run_case", "run_study",
           "read_rows", "digest", "write_digest", "case_trace", "find_case", "STATUS_OK",
           "STATUS_ERROR", "WORKER_DIED", "DASK_SETTINGS"]

STATUS_OK, STATUS_ERROR = "ok", "error"
WORKER_DIED = "WorkerDied"
"""``error_type`` of a case whose worker process died twice while running it."""

FEED_UNITS = ("pulse/s", "path/s", "um/s", "mm/s", "m/s", "mm/min")
"""Units of a study's ``feeds``: a case's feed is ``run --feed`` with the value and this
unit (``50mm/s``), converted by :func:`nurbsmotion.run_input.run_feed`; ``path/s`` is a
bare number, in the path's own units per second."""

CASE_TIME_LIMIT = 300.0
"""Default CPU time a case may use [s] (a study's ``case_time_limit``): about thirty times
the longest case of the die-bonder study, so that a case that would run away (a path whose
tables do not converge) is stopped and recorded instead of holding a worker for ever."""

SUMMARY_FIGURES = ("cycle_time_ratio", "max_contour_error", "max_following_error",
                   "max_drive_ratio", "saturated_samples", "move_and_settle_ratio",
                   "end_overshoot", "corner_overshoot")
"""Figures the digest summarises per group (per-axis ones as the largest or, for
``saturated_samples``, the sum over the axes)."""


# ----------------------------------------------------------------------------- study
@dataclass(frozen=True)
class PlantGroup:
    """True-plant scales of one plant group.

    ``tau_scale`` and ``Kc_scale`` multiply the model's tau and Kc (scalar or one per
    axis); with ``spread > 0`` each of them is instead drawn per axis and per case from
    uniform(1 - spread, 1 + spread) with the case's seed (docs/model.md#beyond-the-paper: the mismatch).
    """

    name: str
    tau_scale: tuple = (1.0,)
    Kc_scale: tuple = (1.0,)
    spread: float = 0.0
    effects: tuple = ()
    """``(key, value)`` pairs of the machine as it is (issue 32) the true plant has on top
    of the machine's: machine-level keys (``encoder``, ``measurement_noise``, ``seed``,
    ``delay``, ``dac_bits``) and per-axis keys set on every axis (``coulomb_friction``,
    ``stiction``, ``resonance_frequency``, ``resonance_damping``, ``load_fraction``,
    ``encoder_on``): a study sweeps delay, friction or a mode with one plant group per
    value."""


@dataclass(frozen=True)
class RandomPaths:
    """``count`` random paths of each of ``families`` (see
    :mod:`nurbsmotion.paths.random_paths`), each with ``n_axes`` axes and extent
    ``length`` [pulse]."""

    families: tuple
    count: int
    n_axes: int = 2
    length: float = 2e4


@dataclass(frozen=True)
class Study:
    """A validated study file (see ``docs/campaign.md``)."""

    name: str
    seed: int
    paths: tuple
    random_paths: tuple
    feeds: tuple
    feed_unit: str
    machines: tuple
    plants: tuple
    interpolators: tuple
    sample: int | None = None
    settle_time: float = 0.05
    settle_window: float = SETTLE_WINDOW
    bound: bool = True
    case_time_limit: float | None = CASE_TIME_LIMIT
    source: str | None = None
    base_dir: str = "."


@dataclass(frozen=True)
class Case:
    """One run of a study; ``index`` is its place in the full product (its id is
    ``"c"`` + index), ``seed`` its own seed."""

    index: int
    path: str
    path_family: str | None
    path_seed: int | None
    n_axes: int
    length: float
    feed_value: float
    feed_unit: str
    machine: str
    plant: PlantGroup
    interpolator: str
    seed: int
    settle_time: float
    settle_window: float
    bound: bool = True
    base_dir: str = "."
    time_limit: float | None = CASE_TIME_LIMIT

    @property
    def case_id(self) -> str:
        return f"c{self.index:07d}"


_STUDY_KEYS = {"name", "seed", "paths", "random_paths", "feeds", "feed_unit", "machines",
               "plants", "interpolators", "sample", "settle_time", "settle_window",
               "time_optimal_bound", "case_time_limit"}


def load_study(file: str | os.PathLike) -> Study:
    """Read and validate a study file (TOML).

    Raises
    ------
    PathFileError
        Naming the file and the bad field.
    """
    path = Path(file)
    if not path.is_file():
        raise PathFileError("no such study file", str(file))
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise PathFileError(f"invalid TOML: {exc}", str(path)) from None
    try:
        return _study_from_dict(data, str(path), str(path.parent.resolve()))
    except (ValueError, TypeError, KeyError) as exc:
        if isinstance(exc, PathFileError):
            raise
        msg = exc.args[0] if exc.args else exc
        raise PathFileError(str(msg), str(path)) from None


def _study_from_dict(data: dict, source: str, base_dir: str) -> Study:
    unknown = set(data) - _STUDY_KEYS
    if unknown:
        raise InvalidArgumentError(f"unknown study field(s) {sorted(unknown)}; expected "
                         f"{sorted(_STUDY_KEYS)}")
    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InvalidArgumentError(f"seed must be an integer >= 0, got {seed!r}")
    paths = tuple(_strings(data.get("paths", []), "paths"))
    random_paths = tuple(_random_paths(e, i) for i, e in enumerate(data.get("random_paths", [])))
    if not paths and not random_paths:
        raise InvalidArgumentError("the study has no paths: give 'paths' or '[[random_paths]]'")
    feeds = data.get("feeds")
    if not isinstance(feeds, list) or not feeds or not all(
            _is_number(f) and math.isfinite(f) and f > 0 for f in feeds):
        raise InvalidArgumentError(f"feeds must be a non-empty list of numbers > 0, got {feeds!r}")
    feed_unit = data.get("feed_unit", "m/s")
    if feed_unit not in FEED_UNITS:
        raise InvalidArgumentError(f"feed_unit {feed_unit!r} unknown; choose from {list(FEED_UNITS)}")
    for p in paths:
        _check_path_file(p, base_dir)
    machines = tuple(_strings(data.get("machines", ["die-bonder"]), "machines"))
    for m in machines:  # read now: a bad machine file is refused before any case runs
        try:
            _machine(m, base_dir)
        except (ValueError, OSError) as exc:
            raise InvalidArgumentError(f"machines: {m!r}: {exc}") from None
    plants = tuple(_plant(e, i) for i, e in enumerate(data.get("plants", [{"name": "nominal"}])))
    if len({p.name for p in plants}) != len(plants):
        raise InvalidArgumentError("plant names must be unique")
    interpolators = tuple(_strings(data.get("interpolators", ["paper"]), "interpolators"))
    for name in interpolators:
        if name not in LOOP_METHODS:
            raise InvalidArgumentError(f"unknown interpolator {name!r}; choose from {list(LOOP_METHODS)}")
    sample = data.get("sample")
    if sample is not None and (isinstance(sample, bool) or not isinstance(sample, int)
                               or sample < 1):
        raise InvalidArgumentError(f"sample must be an integer >= 1 (cases drawn), got {sample!r}")
    settle_time = _positive_number(data.get("settle_time", 0.05), "settle_time", zero=True)
    settle_window = _positive_number(data.get("settle_window", SETTLE_WINDOW), "settle_window")
    limit = data.get("case_time_limit", CASE_TIME_LIMIT)
    if limit is not False:
        limit = _positive_number(limit, "case_time_limit (CPU seconds, or false)")
    bound = data.get("time_optimal_bound", True)
    if not isinstance(bound, bool):
        raise InvalidArgumentError(f"time_optimal_bound must be true or false, got {bound!r}")
    return Study(name=str(data.get("name", Path(source).stem)), seed=seed, paths=paths,
                 random_paths=random_paths, feeds=tuple(float(f) for f in feeds),
                 feed_unit=feed_unit, machines=machines, plants=plants,
                 interpolators=interpolators, sample=sample, settle_time=settle_time,
                 settle_window=settle_window, bound=bound, case_time_limit=limit or None,
                 source=source, base_dir=base_dir)


def _check_path_file(spec: str, base_dir: str) -> None:
    """A study's path: a built-in name, or a path file (relative to the study) that
    exists and has a path file's ending; ``FILE#k`` picks a contour."""
    from .nurbs import BUILTIN_PATHS
    from .paths import PATH_FILE_SUFFIXES

    name, _, k = spec.partition("#")
    if name in BUILTIN_PATHS and not k:
        return
    file = Path(base_dir) / name
    if Path(name).suffix.lower() not in PATH_FILE_SUFFIXES:
        raise InvalidArgumentError(f"paths: {spec!r} is neither a built-in path "
                         f"({', '.join(BUILTIN_PATHS)}) nor a path file "
                         f"({', '.join(PATH_FILE_SUFFIXES)})")
    if not file.is_file():
        raise InvalidArgumentError(f"paths: {spec!r}: no such file {str(file)!r}")
    if k and not (k.isdigit() and int(k) >= 1):
        raise InvalidArgumentError(f"paths: {spec!r}: the contour after '#' must be a number >= 1")


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _positive_number(x, name: str, zero: bool = False) -> float:
    if not (_is_number(x) and math.isfinite(x) and (x >= 0 if zero else x > 0)):
        raise InvalidArgumentError(f"{name} must be a finite number {'>=' if zero else '>'} 0, got {x!r}")
    return float(x)


def _strings(value, name: str) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise InvalidArgumentError(f"{name} must be a list of non-empty strings, got {value!r}")
    return value


def _random_paths(entry, i: int) -> RandomPaths:
    from .paths.random_paths import FAMILIES

    where = f"random_paths[{i}]"
    if not isinstance(entry, dict):
        raise InvalidArgumentError(f"{where} must be a table")
    unknown = set(entry) - {"families", "count", "n_axes", "length"}
    if unknown:
        raise InvalidArgumentError(f"{where}: unknown field(s) {sorted(unknown)}")
    families = entry.get("families", "all")
    families = list(FAMILIES) if families == "all" else _strings(families, f"{where}.families")
    for f in families:
        if f not in FAMILIES:
            raise InvalidArgumentError(f"{where}: unknown family {f!r}; choose from {sorted(FAMILIES)}")
    count = entry.get("count", 1)
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise InvalidArgumentError(f"{where}.count must be an integer >= 1, got {count!r}")
    n_axes = entry.get("n_axes", 2)
    if n_axes not in (2, 3) or isinstance(n_axes, bool):
        raise InvalidArgumentError(f"{where}.n_axes must be 2 or 3, got {n_axes!r}")
    length = _positive_number(entry.get("length", 2e4), f"{where}.length")
    return RandomPaths(tuple(families), count, n_axes, length)


def _plant(entry, i: int) -> PlantGroup:
    where = f"plants[{i}]"
    if not isinstance(entry, dict) or not isinstance(entry.get("name"), str):
        raise InvalidArgumentError(f"{where} must be a table with a 'name'")
    from .machine import AXIS_EFFECT_KEYS, MACHINE_EFFECT_KEYS

    effect_keys = (set(MACHINE_EFFECT_KEYS) | set(AXIS_EFFECT_KEYS)) - {"disturbance"}
    unknown = set(entry) - {"name", "tau_scale", "Kc_scale", "spread"} - effect_keys
    if unknown:
        raise InvalidArgumentError(f"{where}: unknown field(s) {sorted(unknown)}")
    scales = []
    for key in ("tau_scale", "Kc_scale"):
        v = entry.get(key, 1.0)
        v = v if isinstance(v, list) else [v]
        if not v or not all(_is_number(x) and math.isfinite(x) and x > 0 for x in v):
            raise InvalidArgumentError(f"{where}.{key} must be a number > 0 or one per axis, got {v!r}")
        scales.append(tuple(float(x) for x in v))
    spread = entry.get("spread", 0.0)
    if not (_is_number(spread) and 0 <= spread < 1):
        raise InvalidArgumentError(f"{where}.spread must be in [0, 1), got {spread!r}")
    effects = tuple(sorted((k, entry[k]) for k in effect_keys if k in entry))
    for k, v in effects:
        if isinstance(v, (list, dict)):
            raise InvalidArgumentError(f"{where}.{k} must be one value (it applies to every axis), "
                             f"got {v!r}")
    return PlantGroup(entry["name"], scales[0], scales[1], float(spread), effects)


def _seed(*words: int) -> int:
    """A 63-bit seed derived from ``words`` (numpy's SeedSequence): the same everywhere."""
    return int(np.random.SeedSequence(list(words)).generate_state(1, np.uint64)[0] >> 1)


def study_cases(study: Study) -> list[Case]:
    """The study's cases, in the order of the full product (paths, feeds, machines,
    plants, interpolators; a path runs only on machines with its number of axes), or the
    seeded sample of ``study.sample`` of them (kept in that order)."""
    paths = [(p, None, None, 0, 0.0) for p in study.paths]
    k = 0
    for group in study.random_paths:
        for family in group.families:
            for _ in range(group.count):
                paths.append((f"random:{family}", family, _seed(study.seed, 1, k),
                              group.n_axes, group.length))
                k += 1
    axes_of_machine = {m: _machine(m, study.base_dir).n_axes for m in study.machines}
    cases = []
    index = 0
    for (path, family, path_seed, n_axes, length), feed, machine, plant, interp in product(
            paths, study.feeds, study.machines, study.plants, study.interpolators):
        if family is not None and n_axes != axes_of_machine[machine]:
            continue
        cases.append(Case(index, path, family, path_seed, n_axes or axes_of_machine[machine],
                          length, feed, study.feed_unit, machine, plant, interp,
                          _seed(study.seed, 2, index), study.settle_time,
                          study.settle_window, study.bound, study.base_dir,
                          study.case_time_limit))
        index += 1
    if study.sample is not None and study.sample < len(cases):
        pick = np.random.default_rng(_seed(study.seed, 3)).choice(
            len(cases), size=study.sample, replace=False)
        cases = [cases[i] for i in np.sort(pick)]
    return cases


# ----------------------------------------------------------------------------- one case
@lru_cache(maxsize=16)
def _machine(spec: str, base_dir: str) -> Machine:
    from .machine import BUILTIN_MACHINES

    if spec in BUILTIN_MACHINES:
        return load_machine(spec)
    return load_machine(Path(base_dir) / spec)


@lru_cache(maxsize=64)
def _contour(path: str, family: str | None, path_seed: int | None, n_axes: int,
             length: float, base_dir: str, axes: str):
    """The case's path and its programmed feed (a ``Contour``; kept per worker: its
    arc-length table serves every case on it), read as ``nurbsmotion run`` reads it
    (:func:`nurbsmotion.run_input.load_run_contour`; G-code and DXF on ``axes``)."""
    if family is not None:
        from .paths import Contour
        from .paths.random_paths import random_path

        return Contour(random_path(family, path_seed, n_axes, length), None, path)
    from .nurbs import BUILTIN_PATHS
    from .paths import resolve_contour

    spec = path if path.split("#")[0] in BUILTIN_PATHS else str(Path(base_dir) / path)
    return resolve_contour(spec, axes=axes)


_PATH_ERRORS: dict = {}
"""Per worker: why a path could not be built (it fails the same way for all its cases)."""


def _path(case: Case, machine: Machine):
    """The case's path with its programmed feed and its arc-length tables
    (:func:`_contour`, kept per worker); a path that could not be built, or whose tables
    took more than the case's time limit, fails the worker's other cases on it at once,
    with the same error."""
    from .planning import check_path_size
    from .run_input import path_axes

    key = _path_key(case) + (path_axes(machine),)
    if key in _PATH_ERRORS:
        raise _PATH_ERRORS[key]
    try:
        contour = _contour(*key)
        pulses = _pulses(key, machine.pulses_per_unit(contour.curve.units))
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

    from .machine import AXIS_EFFECT_KEYS

    keys = dict(group.effects)
    axis_keys = {k: v for k, v in keys.items() if k in AXIS_EFFECT_KEYS}
    machine_keys = {k: v for k, v in keys.items() if k not in AXIS_EFFECT_KEYS}
    return machine.with_options(axes=tuple(replace(a, **axis_keys) for a in machine.axes),
                                **machine_keys)


def case_trace(case: Case):
    """Run one case: ``(trace, summary dict, tau scales, Kc scales)``.

    The one function that builds and runs a case's loop (adapt it when the loop's API
    changes).
    """
    from .loop import run
    from .metrics import trace_metrics
    from .report import summary
    from .servo import ServoPlant

    from .run_input import run_feed

    machine = _machine(case.machine, case.base_dir)
    contour, pulses = _path(case, machine)
    machine.check_path(contour.curve.n_axes)
    # What `nurbsmotion run PATH --feed F` runs: the path in pulses, the feed in pulse/s
    # (per piece where the file programs one, capped by the study's feed).
    feed = run_feed(_feed_text(case), contour, machine)
    tau_s, kc_s = _plant_scales(case, machine.n_axes)
    plant = ServoPlant.of_machine(_true_machine(machine, case.plant), pulses(0.0),
                                  time_constant_scale=tau_s, electrical_gain_scale=kc_s)
    trace = run(pulses, machine, feed, case.interpolator, plant=plant,
                settle_time=case.settle_time, settle_window=case.settle_window)
    metrics = trace_metrics(trace, settle_window=case.settle_window)
    bound = _bound(case, pulses, machine, feed) if case.bound else math.nan
    extra = None
    if plant.effects is not None:  # what the machine did at rest (issue 32); added keys
        rest = trace.at_rest().to_dict()
        extra = {"hold_window_s": rest.pop("window_s"), **rest}
    data = summary(metrics, interpolator=case.interpolator,
                   feed=feed if isinstance(feed, (int, float)) else feed.highest,
                   machine=machine.name, path=case.path, time_optimal_bound=bound, extra=extra)
    return trace, data, tau_s, kc_s


_BOUNDS: dict = {}
"""Per worker: the time-optimal bound of (path, machine, feed) [s]."""


def _bound(case: Case, path, machine: Machine, feed) -> float:
    """The time-optimal bound [s] of ``path`` [pulse] at ``feed`` [pulse/s]; it depends on
    the path, the model and the feed only, so a worker keeps it for the case's other
    plants and interpolators."""
    from .planning import time_optimal_bound

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
    from .errors import WorkLimitError

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


# ----------------------------------------------------------------------------- dataset
def _schema(study: Study):
    """The dataset's columns (the same in every part file)."""
    import pyarrow as pa

    from .report import SUMMARY_KEYS

    axes = []
    for m in study.machines:
        axes += [a for a in _machine(m, study.base_dir).axis_names if a not in axes]
    per_axis = {"max_following_error", "rms_following_error", "max_drive_ratio",
                "saturated_samples", "cornered_samples"}
    int_keys = {"steps", "saturated_samples", "limited_samples", "cornered_samples"}
    bool_keys = {"settled", "success"}
    text_keys = {"interpolator", "machine", "path", "message"}
    fields = [("case_id", pa.string()), ("case_index", pa.int64()), ("seed", pa.int64()),
              ("status", pa.string()), ("error_type", pa.string()),
              ("error_message", pa.string()), ("attempts", pa.int64()),
              ("path", pa.string()), ("path_family", pa.string()),
              ("path_seed", pa.int64()), ("n_axes", pa.int64()), ("feed_value", pa.float64()),
              ("feed_unit", pa.string()), ("machine", pa.string()), ("plant", pa.string()),
              ("interpolator", pa.string())]
    fields += [(f"{s}_scale_{a}", pa.float64()) for a in axes for s in ("tau", "Kc")]
    taken = {f for f, _ in fields}
    for key in SUMMARY_KEYS:
        typ = pa.int64() if key in int_keys else pa.bool_() if key in bool_keys else \
            pa.string() if key in text_keys else pa.float64()
        if key in per_axis:
            fields += [(f"{key}_{a}", typ) for a in axes]
        elif key not in taken:
            fields.append((key, typ))
    fields += [("case_time_s", pa.float64()), ("case_cpu_s", pa.float64())]
    return pa.schema(fields)


def _write_part(rows: list[dict], rows_dir: Path, schema) -> Path:
    """Write ``rows`` as a new part file (temporary name, then renamed: a part file is
    either complete or absent)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist(rows, schema=schema)
    name = f"part-{time.strftime('%Y%m%dT%H%M%S')}-{uuid.uuid4().hex[:8]}.parquet"
    tmp = rows_dir / f".{name}.tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, rows_dir / name)
    return rows_dir / name


def read_rows(out_dir: str | os.PathLike):
    """All finished rows of a campaign as a pyarrow Table, sorted by case index (the
    columns of every part file: a column added by a newer version is null in the rows of
    parts written before it)."""
    import pyarrow as pa
    import pyarrow.dataset as ds
    import pyarrow.parquet as pq

    rows_dir = Path(out_dir) / "rows"
    files = sorted(str(p) for p in rows_dir.glob("part-*.parquet"))
    if not files:
        return None
    schema = pa.unify_schemas([pq.read_schema(f) for f in files])
    table = ds.dataset(files, schema=schema, format="parquet").to_table()
    return table.sort_by("case_index")


# ----------------------------------------------------------------------------- engine
@dataclass
class CampaignResult:
    """What :func:`run_study` did."""

    out_dir: Path
    n_cases: int
    computed: int
    skipped: int
    failed: int
    wall_time_s: float
    digest: dict = field(default_factory=dict)


def run_study(study: Study, out_dir: str | os.PathLike, *, workers: int | None = None,
              scheduler: Any = None, resume: bool = False, overwrite: bool = False,
              progress: bool = True, flush_rows: int = 64, flush_seconds: float = 10.0,
              cases: list[Case] | None = None) -> CampaignResult:
    """Run a study's unfinished cases and write the dataset and digest into ``out_dir``.

    Parameters
    ----------
    study : Study
    out_dir : path
        Holds ``study.toml`` (the study run), ``rows/part-*.parquet`` and the digest
        ``digest.md`` / ``digest.json``.
    workers : int, optional
        Local worker processes (all cores by default; 1 runs in this process).
    scheduler : str or dask.distributed.Client, optional
        A Dask scheduler's address (or a client): run the cases on that cluster; results
        come back to this process, which alone writes the dataset.
    resume : bool
        Keep the finished rows in ``out_dir`` and run only the other cases.
    overwrite : bool
        First remove what an earlier campaign wrote into ``out_dir``
        (:data:`CAMPAIGN_OUTPUTS`, the part files, the case folders' run outputs); no
        other file there is touched.
    flush_rows, flush_seconds : int, float
        A part file is written every ``flush_rows`` finished rows or ``flush_seconds``.
    cases : list of Case, optional
        The cases (``study_cases(study)`` by default).

    Raises
    ------
    OutputExistsError
        ``out_dir`` holds files, and neither ``resume`` nor ``overwrite`` was asked for.
    PathFileError
        On ``resume``, if ``out_dir`` holds another study.
    KeyboardInterrupt
        After writing every finished row, so that ``resume`` goes on from there.
    """
    from .errors import OutputExistsError

    t0 = time.perf_counter()
    out = Path(out_dir)
    rows_dir = out / "rows"
    study_copy = out / "study.toml"
    held = out.exists() and any(p.name != _LOCK for p in out.iterdir())
    if held and not (overwrite or resume):
        raise OutputExistsError(f"{out} exists; resume with --resume, or pass --overwrite")
    text = Path(study.source).read_text() if study.source else ""
    if resume and not overwrite and study_copy.exists() and study_copy.read_text() != text:
        raise PathFileError(f"{out} holds the results of another study (its study.toml "
                            "differs); choose another output folder", study.source)
    with _locked(out):
        if held and overwrite:
            _remove_outputs(out)
        rows_dir.mkdir(parents=True, exist_ok=True)
        for stale in rows_dir.glob(".part-*.tmp"):  # a part being written when killed
            stale.unlink()
        write_output(study_copy, lambda h: h.write(text), overwrite=True)
        all_cases = study_cases(study) if cases is None else cases
        done = _finished_ids(out)
        todo = [c for c in all_cases if c.case_id not in done]
        writer = _RowWriter(rows_dir, _schema(study), flush_rows, flush_seconds)
        bar = _progress(len(todo), progress)
        try:
            for row in _execute(todo, workers, scheduler, run_case):
                writer.add(row)
                bar(row)
        finally:
            writer.flush()
            bar(None)
        table = read_rows(out)
        result_digest = digest(table, study, out) if table is not None else {}
        if table is not None:
            write_digest(result_digest, out)
    failed = 0 if table is None else int(
        sum(s != STATUS_OK for s in table.column("status").to_pylist()))
    return CampaignResult(out, len(all_cases), writer.written, len(all_cases) - len(todo),
                          failed, time.perf_counter() - t0, result_digest)


_LOCK = ".lock"

CAMPAIGN_OUTPUTS = ("study.toml", "digest.md", "digest.json")
"""Files a campaign writes at the top of its folder (besides ``rows/`` and the case
folders ``cNNNNNNN/`` of ``--case``)."""


def _remove_outputs(out: Path) -> None:
    """Remove what a campaign wrote into ``out`` (``--overwrite``): its files, its part
    files and the run outputs of its case folders; a folder is removed once empty. A
    file the campaign does not write is left where it is."""
    from .plots import TRACE_FIGURES

    for name in CAMPAIGN_OUTPUTS + (".digest.json.tmp", ".digest.md.tmp"):
        if (out / name).is_file():
            (out / name).unlink()
    rows = out / "rows"
    if rows.is_dir():
        for p in [*rows.glob("part-*.parquet"), *rows.glob(".part-*.tmp")]:
            p.unlink()
    cases = [p for p in out.glob("c*") if p.is_dir() and len(p.name) == 8
             and p.name[1:].isdigit()]
    for folder in cases:
        for name in ("trace.csv", "summary.json", *TRACE_FIGURES):
            if (folder / name).is_file():
                (folder / name).unlink()
    for folder in [rows, *cases]:
        try:
            folder.rmdir()
        except OSError:  # holds a file of the user's (or is absent)
            pass



@contextmanager
def _locked(out: Path):
    """Hold ``OUT/.lock`` (an advisory ``flock``, POSIX) while a campaign writes into
    ``out``: a second campaign into the same folder is refused instead of running the same
    cases twice. The lock goes with the process that holds it, however it ends."""
    from .errors import OutputExistsError

    out.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    with open(out / _LOCK, "a") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise OutputExistsError(f"{out} is being written by another running "
                                    "campaign") from None
        yield


def _finished_ids(out: Path) -> set:
    table = read_rows(out)
    return set() if table is None else set(table.column("case_id").to_pylist())


class _RowWriter:
    def __init__(self, rows_dir, schema, flush_rows, flush_seconds):
        self.rows_dir, self.schema = rows_dir, schema
        self.flush_rows, self.flush_seconds = flush_rows, flush_seconds
        self.pending: list[dict] = []
        self.written = 0
        self.last = time.monotonic()

    def add(self, row: dict) -> None:
        self.pending.append(row)
        if (len(self.pending) >= self.flush_rows
                or time.monotonic() - self.last >= self.flush_seconds):
            self.flush()

    def flush(self) -> None:
        if self.pending:
            _write_part(self.pending, self.rows_dir, self.schema)
            self.written += len(self.pending)
            self.pending = []
        self.last = time.monotonic()


def _progress(total: int, enabled: bool) -> Callable:
    """A callback per finished row (``None`` closes the bar): tqdm when importable, silent
    when stderr is not a terminal."""
    if not enabled or total == 0:
        return lambda row: None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        return lambda row: None
    bar = tqdm(total=total, unit="case", file=sys.stderr, dynamic_ncols=True, disable=None)
    failed = [0]

    def update(row):
        if row is None:
            bar.close()
            return
        failed[0] += row["status"] != STATUS_OK
        bar.set_postfix(failed=failed[0], refresh=False)
        bar.update(1)

    return update


def _execute(cases: list[Case], workers: int | None, scheduler,
             function: Callable | None = None) -> Iterable[dict]:
    """Rows of ``function`` (:func:`run_case` by default) over ``cases``, in the order
    they finish: serially, on ``workers`` local processes, or on a Dask ``scheduler``.

    Before any case runs, the compiled kernels the cases use are loaded (or compiled) once
    per process (:func:`_warm_up`): here before local workers are forked (they inherit
    them), in every Dask worker when it joins (:func:`_dask_warm_up`).
    """
    function = function or run_case
    if not cases:
        return iter(())
    if scheduler is not None:
        return _execute_dask(cases, scheduler, function)
    n = (os.cpu_count() or 1) if workers is None else int(workers)
    if n < 1:
        raise InvalidArgumentError(f"workers must be >= 1, got {workers!r}")
    _warm_up(cases)
    if n == 1:
        return (function(c) for c in cases)
    return _execute_pool(cases, n, function)


_WARMED: set = set()
"""(interpolator, machine, base folder) of the kernels this process has loaded."""


def _warm_up(cases: list[Case]) -> None:
    """Load the compiled kernels of every (interpolator, machine) of ``cases`` into this
    process: one short random move each (``short_moves``, seed 0, nominal plant, index
    -1: no case of the study; its figures are discarded), so that no case's time includes
    loading or compiling them and forked workers start with them loaded. Errors are left
    to the cases to record."""
    from dataclasses import replace

    for c in cases:
        key = (c.interpolator, c.machine, c.base_dir)
        if key in _WARMED:
            continue
        _WARMED.add(key)
        probe = replace(c, index=-1, path="random:short_moves", path_family="short_moves",
                        path_seed=0, length=2e4, plant=PlantGroup("nominal"))
        try:
            with _cpu_limit(c.time_limit):
                case_trace(probe)
        except Exception:  # noqa: BLE001 - the real cases record their own errors
            pass


def _path_key(case: Case) -> tuple:
    return (case.path, case.path_family, case.path_seed, case.n_axes, case.length,
            case.base_dir)


def _run_batch(function: Callable, batch: list[Case]) -> bytes:
    """A Dask task: the rows of ``batch``, pickled together. Dask measures (``sizeof``)
    and serializes a task's result on the worker, and the scheduler forwards it: a bytes
    object costs it next to nothing, a list of dicts of some 70 keys each is walked key by
    key (about a millisecond of the worker's CPU time for a task's rows)."""
    return pickle.dumps([function(c) for c in batch], protocol=pickle.HIGHEST_PROTOCOL)


_CHUNK_SECONDS = 0.25
"""Measured work [CPU s] given to a worker at a time (at least one case), its rows sent
back together: an exchange with a local worker cost about a millisecond of CPU time
(measured on a 2-core virtual machine), 2-5 % of a 20-50 ms case."""

_DASK_CHUNK_SECONDS = 1.0
"""The same for a Dask task, which costs the scheduler, the worker and this process
several milliseconds of CPU time (about 3 ms in the client and a LocalCluster's
scheduler, 2.5 ms in the worker, measured on 200 tasks of 50 rows on a 2-core VM)."""

_MIN_CHUNK_SHARE = 0.1
"""The smallest chunk toward the end, as a share of a full one (at least one case): the
last chunks are cut to balance the workers, but an exchange costs the same for a few
milliseconds of cases as for a full chunk (a Dask task of one 20 ms case: about 5 ms of
CPU time in the scheduler, the worker and this process)."""

_DASK_WORKERS_SECONDS = 5.0
"""How often a campaign on Dask asks the scheduler which workers it has [s]: a worker
that joins gets work within this time, and the campaign does not add a round trip
through the scheduler (whose answer grows with the cluster) to every task."""

_TAIL_SECONDS = 0.05
"""Once every path has been given out, a worker is sent its next chunk before it ends
the one it runs only if its cases are shorter than this [CPU s]: a long case sent ahead
could no longer go to a worker that runs out of work."""


def _execute_pool(cases: list[Case], n_workers: int, function: Callable) -> Iterable[dict]:
    """Rows of ``function`` over ``cases`` on ``n_workers`` local processes
    (:class:`_LocalWorkers`), in the order they finish. Ctrl-C, SIGTERM or an error here
    stops the workers at once (the cases in flight are dropped: resume runs them)."""
    pool = _LocalWorkers(cases, n_workers, function)
    finished = False
    try:
        yield from pool.rows()
        finished = True
    finally:
        pool.close(wait=finished)


class _Slot:
    """What :class:`_Planner` knows of a worker: ``own``, the cases given to it and not
    sent yet; ``sent``, the cases sent to it, in order (the first one running); ``warm``,
    the paths whose tables it has built; ``retry``, a case it runs again alone;
    ``chunks``, the sizes of the chunks in flight."""

    def __init__(self):
        self.own: deque = deque()
        self.sent: deque = deque()
        self.warm: set = set()
        self.retry: Case | None = None
        self.chunks: deque = deque()


class _Planner:
    """Which cases a worker runs next, so that each path's tables are built once.

    The cases are grouped by path (:func:`_path_key`; the groups in the order of their
    first case). A worker that needs work takes the next path whole. When none is left,
    it takes the last cases another worker holds and has not started (:meth:`_steal`):
    as many as balance the two, counting that it builds the path's tables again, and
    none when that would not end sooner, so that the workers finish together without
    building a path's tables twice for a few cases. The case time and the tables' time
    are measured from the rows so far (``case_cpu_s``). A worker is given about
    ``chunk_seconds`` of work at a time, less toward the end: the rest of a path, and
    whole paths after it while they fit (their tables counted).
    """

    def __init__(self, cases: list[Case], chunk_seconds: float = _CHUNK_SECONDS):
        self.chunk_seconds = chunk_seconds
        groups: dict = {}
        for c in cases:
            groups.setdefault(_path_key(c), []).append(c)
        self.paths = deque(groups.values())
        self.left = len(cases)  # cases not sent yet
        self.path_cpu: dict = {}  # path key -> [sum, count]: CPU s of its warm cases
        self.cpu = [0.0, 0, 0.0, 0]  # CPU s and count of the cold cases, of the warm ones
        self.cold: set = set()  # ids of cases sent to a worker without the path's tables

    def case_time(self, key) -> float | None:
        """Expected CPU time of a case on path ``key`` once its tables exist [s]: the
        mean over its cases so far, shrunk toward the mean over all paths as if that
        were two more of them (a path's cases differ by feed and interpolator: its first
        few say little)."""
        if not self.cpu[3]:
            return None
        total, n = self.path_cpu.get(key, (0.0, 0))
        return (total + 2 * self.cpu[2] / self.cpu[3]) / (n + 2)

    def table_time(self) -> float:
        """Expected extra CPU time of the first case of a path on a worker [s]."""
        if not (self.cpu[1] and self.cpu[3]):
            return 0.0
        return max(0.0, self.cpu[0] / self.cpu[1] - self.cpu[2] / self.cpu[3])

    def record(self, case: Case, row: dict) -> None:
        """Learn from a finished case's row."""
        cold = case.case_id in self.cold
        self.cold.discard(case.case_id)
        cpu = row.get("case_cpu_s")
        if not isinstance(cpu, float) or not math.isfinite(cpu):
            return
        if cold:
            self.cpu[0] += cpu
            self.cpu[1] += 1
        else:
            self.cpu[2] += cpu
            self.cpu[3] += 1
            entry = self.path_cpu.setdefault(_path_key(case), [0.0, 0])
            entry[0] += cpu
            entry[1] += 1

    def ahead(self, slot: _Slot) -> bool:
        """Whether ``slot`` should hold a chunk beyond the one it runs: yes while paths
        are left to give out, or while its cases are short; at the end, a long case sent
        ahead could no longer go to a worker that runs out of work."""
        if self.paths:
            return True
        queue = slot.own or slot.sent
        c = self.case_time(_path_key(queue[-1])) if queue else None
        return c is None or c <= _TAIL_SECONDS

    def fill(self, slot: _Slot, slots: list[_Slot]) -> Iterable[list[Case]]:
        """The chunks to send ``slot`` now (each taken by :meth:`next_chunk`): until it
        holds one beyond the one it runs (see :meth:`ahead`), or nothing is left for it."""
        while len(slot.chunks) < (2 if self.ahead(slot) else 1):
            chunk = self.next_chunk(slot, slots)
            if not chunk:
                return
            yield chunk

    def next_chunk(self, slot: _Slot, slots: list[_Slot]) -> list[Case]:
        """The next cases for ``slot`` (moved to its ``sent``), or ``[]``: all given out,
        or the rest is better left where it is."""
        if not slot.own:
            if self.paths:
                slot.own.extend(self.paths.popleft())
            elif not self._steal(slot, slots):
                return []
        c = self.case_time(_path_key(slot.own[0]))
        table = self.table_time()
        # No more than a share of the work left, the tables of the paths not given out
        # counted (guided self-scheduling): the chunks shrink toward the end, where their
        # cases could no longer be shared out; but not below a tenth of a full chunk,
        # whose exchange would then cost more than the last imbalance it can save.
        left = self.left * (c or 0.0) + len(self.paths) * table
        seconds = max(min(self.chunk_seconds, left / (4 * len(slots))),
                      self.chunk_seconds * _MIN_CHUNK_SHARE)
        size = 1 if not c else max(1, min(len(slot.own), int(seconds / c)))
        chunk = [slot.own.popleft() for _ in range(size)]
        # A path that ends within the chunk leaves room for the next paths, whole, while
        # their cases and tables fit too: a campaign of paths with a few short cases each
        # is not sent a path at a time.
        spent = size * (c or 0.0)
        while c and not slot.own and self.paths:
            key = _path_key(self.paths[0][0])
            n, c_next = len(self.paths[0]), self.case_time(key)
            extra = table + n * c_next  # a path not given out yet: no worker has its tables
            if spent + extra > seconds:
                break
            chunk += self.paths.popleft()
            spent += extra
        self.left -= len(chunk)
        for case in chunk:
            key = _path_key(case)
            if key not in slot.warm:
                slot.warm.add(key)
                self.cold.add(case.case_id)
        slot.sent.extend(chunk)
        slot.chunks.append(len(chunk))
        return chunk

    def _steal(self, thief: _Slot, slots: list[_Slot]) -> bool:
        """Move to ``thief`` the last unstarted cases of the worker with the most work
        left: ``h`` of the ``k`` it holds (``s`` more sent to it) such that both end
        together, ``T + h c = (k + s - h) c + T'`` (``c`` a case's time on that path,
        ``T`` the thief's cost of building the path's tables, 0 if it has them, ``T'``
        the same for the other worker if its first case on the path is still running),
        when ``h >= 1``; one case when that is a close call (at least two unstarted cases
        and half ``T`` of work left there): the estimates are rough, and an idle worker
        risks only ``T``."""
        table = self.table_time()
        best, best_work = None, 0.0
        for w in slots:
            if w is thief or not w.own:
                continue
            c = self.case_time(_path_key(w.own[-1]))
            building = table if any(x.case_id in self.cold for x in w.sent) else 0.0
            work = (len(w.own) + len(w.sent)) * (c if c is not None else 1.0) + building
            if work > best_work:
                best, best_work, best_building = w, work, building
        if best is None:
            return False
        key = _path_key(best.own[-1])
        k, s = len(best.own), len(best.sent)
        c = self.case_time(key)
        mine = 0.0 if key in thief.warm else table
        h = min(k, int((k + s + ((best_building - mine) / c if c else 0.0)) / 2 + 0.5))
        if h < 1 and k >= 2 and best_work >= mine / 2:
            h = 1  # a close call: the estimates are rough, being idle is sure
        if h < 1:
            return False
        stolen = [best.own.pop() for _ in range(h)]
        thief.own.extend(reversed(stolen))
        return True


class _LocalWorker(_Slot):
    """A local worker process and the pipe to it."""

    def __init__(self, index: int, parent: int, function: Callable):
        super().__init__()
        self.index, self.parent, self.function = index, parent, function
        self.start()

    def start(self) -> None:
        """A fresh process (forked where the platform forks: it inherits the loaded
        kernels) with no path tables yet."""
        ctx = _mp_context()
        self.conn, child = ctx.Pipe()
        self.running = ctx.RawValue("q", 0)  # place in its chunk of the case it runs
        self.process = ctx.Process(target=_worker_loop,
                                   args=(child, self.running, self.parent, self.function),
                                   daemon=True, name=f"nurbsmotion-campaign-{self.index}")
        self.process.start()
        child.close()
        self.warm = set()

    def send(self, chunk: list[Case]) -> None:
        try:
            self.conn.send(chunk)
        except OSError:  # it died: its sentinel says so next
            pass


def _worker_loop(conn, running, parent: int, function: Callable) -> None:
    """In a local worker: run the cases of each chunk received (``running`` holding the
    place of the case it runs, for the campaign to know which one killed it) and send
    back the chunk's rows together, each ``("row", row)``, or ``("error", message)``
    when ``function`` raised or its row could not be sent; until ``None`` or the pipe
    closes."""
    _worker_start(parent)
    while True:
        try:
            chunk = conn.recv()
        except (EOFError, OSError):
            return
        if chunk is None:
            return
        out = []
        for k, case in enumerate(chunk):
            running.value = k
            try:
                out.append(("row", function(case)))
            except Exception as exc:  # noqa: BLE001 - reported as the case's row
                out.append(("error", f"{type(exc).__name__}: {exc}"))
        try:
            try:
                conn.send(out)
            except (pickle.PicklingError, TypeError, AttributeError):
                conn.send([_sendable(m) for m in out])
        except (BrokenPipeError, EOFError, OSError):
            return


def _sendable(message: tuple) -> tuple:
    """``message``, or an error message if it cannot be pickled."""
    try:
        pickle.dumps(message)
    except Exception as exc:  # noqa: BLE001
        return ("error", f"{type(exc).__name__}: {exc}")
    return message


class _LocalWorkers:
    """Local worker processes fed by a :class:`_Planner`, each a chunk ahead (so that
    it does not wait for this process) but at the very end; their rows come back one by
    one.

    A worker that dies is replaced by a fresh process, which first runs the case the dead
    one was running, alone (``attempts`` = 2); if it dies too, the case is recorded as
    :data:`WORKER_DIED`. The cases the dead worker had not started go on as before.
    """

    def __init__(self, cases: list[Case], n_workers: int, function: Callable):
        self.planner = _Planner(cases)
        self.workers = [_LocalWorker(k, os.getpid(), function)
                        for k in range(min(n_workers, len(cases)))]

    def _feed(self, w: _LocalWorker) -> None:
        """Keep ``w`` a chunk ahead (a case being retried runs alone)."""
        if w.retry is not None:
            if not w.sent:
                w.sent.append(w.retry)
                w.chunks.append(1)
                w.send([w.retry])
            return
        for chunk in self.planner.fill(w, self.workers):
            w.send(chunk)

    def rows(self) -> Iterable[dict]:
        from multiprocessing.connection import wait

        for w in self.workers:
            self._feed(w)
        while True:
            busy = [w for w in self.workers if w.sent]
            if not busy:
                return
            waiting = {}
            for w in busy:
                waiting[w.conn] = waiting[w.process.sentinel] = w
            for w in {id(waiting[r]): waiting[r] for r in wait(list(waiting))}.values():
                yield from self._receive(w)
                self._feed(w)
            for w in self.workers:  # a worker idle since the last paths ran out
                if not w.sent:
                    self._feed(w)

    def _receive(self, w: _LocalWorker) -> Iterable[dict]:
        """The rows ``w`` has sent; if it died, its replacement, and the row of a case
        that killed two processes."""
        try:
            while w.sent and w.conn.poll():
                messages = w.conn.recv()
                w.chunks.popleft()
                for kind, payload in messages:
                    case = w.sent.popleft()
                    row = payload if kind == "row" else _died(case, payload)
                    if w.retry is not None:
                        row["attempts"], w.retry = 2, None
                    self.planner.record(case, row)
                    yield row
        except (EOFError, OSError):  # it is exiting: its pipe closed first
            w.process.join(timeout=10)
        if not w.sent or w.process.is_alive():
            return
        w.process.join()
        w.conn.close()
        # The case it was running; those of its chunk before it ran, but their rows were
        # not sent: they run again, as do the ones it had not started.
        k = min(max(0, w.running.value), w.chunks[0] - 1)
        case = w.sent[k]
        del w.sent[k]
        w.own.extendleft(reversed(w.sent))
        self.planner.left += len(w.sent)
        w.sent.clear()
        w.chunks.clear()
        for c in w.own:
            self.planner.cold.discard(c.case_id)
        self.planner.cold.discard(case.case_id)
        if w.retry is not None:
            w.retry = None
            row = _died(case, "its worker process died twice while running it")
            row["attempts"] = 2
            yield row
        else:
            w.retry = case
        w.start()

    def close(self, wait: bool) -> None:
        """End the workers: asked to stop after their work (``wait``), or killed."""
        for w in self.workers:
            if wait:
                try:
                    w.conn.send(None)
                except OSError:
                    pass
            else:
                w.process.kill()
        for w in self.workers:
            w.process.join(timeout=None if wait else 5)
            if w.process.is_alive():  # pragma: no cover
                w.process.kill()
                w.process.join()
            w.conn.close()


def _worker_start(parent: int) -> None:
    """In a local worker: Ctrl-C and SIGTERM are the campaign's to handle (it stops its
    workers, :meth:`_LocalWorkers.close`), and the worker exits as soon as the campaign's
    process is gone (killed with SIGKILL, it cannot stop them, and they would wait for
    work forever)."""
    import signal
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="orphan-guard", daemon=True).start()


def _mp_context():
    import multiprocessing

    return multiprocessing.get_context()



def _died(case: Case, message: str) -> dict:
    """The row of a case whose worker did not return a row."""
    row = _case_columns(case)
    row.update(status=STATUS_ERROR, error_type=WORKER_DIED, error_message=message,
               case_time_s=math.nan, case_cpu_s=math.nan)
    return row


DASK_SETTINGS = {"distributed.worker.profile.enabled": False,
                 "distributed.admin.tick.interval": "1s",
                 "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
"""Dask settings a campaign's cluster runs best with: ``dask.config.set(DASK_SETTINGS)``
before starting a ``LocalCluster``, or the configuration file of ``docs/campaign.md`` for
``dask scheduler`` and ``dask worker``. Every Dask worker samples its task's stack 100
times a second for the dashboard's profile (5-8 ms of its event loop's CPU time a second,
measured on a 2-core VM), and every scheduler, nanny and worker wakes 50 times a second
to time its event loop (a few ms of CPU a second each): a 2-worker LocalCluster at rest
uses 47-57 ms of CPU a second with Dask's defaults, 22-27 ms with these. And Dask's
nannies start their workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which turns off
glibc's adaptive mmap threshold: every array over 128 KiB is then mapped and unmapped
afresh, and a case took 9-13 % more CPU time than in a plain process (0.99-1.03 times
the serial run's without it, on the 1,000-case study). On a campaign's ~1 s tasks of
CPU-bound cases, none of these tells anything the task's own times do not, and the
workers then allocate as the serial and local runs do."""


def _execute_dask(cases: list[Case], scheduler, function: Callable) -> Iterable[dict]:
    """On a Dask cluster, fed by a :class:`_Planner` as the local workers are: one slot
    per worker thread, each with a task queued behind the one it runs but at the very
    end (tasks bound to that worker, but free to run on another if it leaves); rows
    gathered here as the tasks finish. A task whose worker died (Dask's
    ``KilledWorker``, after the scheduler's ``allowed-failures``) is split: each of its
    cases runs again alone, and a case whose worker dies again is recorded as
    :data:`WORKER_DIED`."""
    from dask.distributed import Client, as_completed

    client = scheduler if isinstance(scheduler, Client) else Client(scheduler)
    try:
        _dask_warm_up(client, cases)
        client.wait_for_workers(1)
        planner = _Planner(cases, _DASK_CHUNK_SECONDS)
        slots: dict = {}  # (worker address, thread) -> _Slot
        tasks: dict = {}  # future key -> (slot or None for a case alone, its cases)
        done = as_completed()

        asked = [-math.inf]  # when the scheduler was last asked for its workers

        def feed() -> None:
            if time.monotonic() - asked[0] >= _DASK_WORKERS_SECONDS:
                asked[0] = time.monotonic()
                for addr, nthreads in client.nthreads().items():
                    for k in range(nthreads):
                        slots.setdefault((addr, k), _Slot())
            order = list(slots.values())
            for (addr, _), slot in slots.items():
                for chunk in planner.fill(slot, order):
                    fut = client.submit(_run_batch, function, chunk, workers=[addr],
                                        allow_other_workers=True, retries=1, pure=False)
                    tasks[fut.key] = (slot, chunk)
                    done.add(fut)

        feed()
        for fut in done:
            slot, chunk = tasks.pop(fut.key)
            if slot is not None:
                slot.chunks.remove(len(chunk))
                ids = {c.case_id for c in chunk}
                slot.sent = deque(c for c in slot.sent if c.case_id not in ids)
            try:
                rows = pickle.loads(fut.result())
            except Exception as exc:  # KilledWorker, or a result that cannot be sent
                if len(chunk) > 1:
                    for case in chunk:
                        again = client.submit(_run_batch, function, [case], pure=False)
                        tasks[again.key] = (None, [case])
                        done.add(again)
                    rows = []
                else:
                    rows = [_died(chunk[0], f"{type(exc).__name__}: {exc}")]
                    rows[0]["attempts"] = 2
            fut.release()
            for case, row in zip(chunk, rows):
                planner.record(case, row)
                yield row
            feed()
    finally:
        if client is not scheduler:
            client.close()


def _dask_warm_up(client, cases: list[Case]) -> None:
    """Every worker of the cluster, now or when it joins, runs :func:`_warm_up` for the
    cases' interpolators and machines once (a worker plugin, run in a thread so the
    worker keeps answering the scheduler while it compiles)."""
    import asyncio

    from distributed import WorkerPlugin

    probes = list({(c.interpolator, c.machine, c.base_dir): c for c in cases}.values())

    class WarmUp(WorkerPlugin):
        async def setup(self, worker):
            await asyncio.to_thread(_warm_up, probes)

    client.register_plugin(WarmUp(), name="nurbsmotion-warm-up")


# ----------------------------------------------------------------------------- digest
_QUANTILES = (("min", 0.0), ("median", 0.5), ("p95", 0.95), ("max", 1.0))


_PER_AXIS_FIGURES = ("max_following_error", "max_drive_ratio", "saturated_samples")


def _figure(table, name: str) -> np.ndarray:
    """Column ``name`` per row [its unit]; a per-axis figure as its largest value over
    the axes (for ``saturated_samples``, the sum)."""
    if name not in _PER_AXIS_FIGURES:
        return np.asarray(table.column(name).to_numpy(zero_copy_only=False), float)
    values = np.array([np.asarray(table.column(c).to_numpy(zero_copy_only=False), float)
                       for c in table.column_names if c.startswith(name + "_")])
    with np.errstate(all="ignore"):
        if name == "saturated_samples":
            return np.sum(np.nan_to_num(values), axis=0)
        return np.max(np.where(np.isnan(values), -np.inf, values), axis=0)


def digest(table, study: Study, out_dir: str | os.PathLike = ".") -> dict:
    """Per group (interpolator x feed x plant) the min / median / 95th percentile / max
    of :data:`SUMMARY_FIGURES` over its successful cases, and every failing case with
    the command that reproduces it.

    Percentiles are sample values (the smallest value with at least that share of the
    group's cases at or below it), so ``inf`` (a motion that never settled) is kept.
    """
    study_file = study.source or "STUDY.toml"
    ok = np.array([s == STATUS_OK for s in table.column("status").to_pylist()])
    keys = list(zip(table.column("interpolator").to_pylist(),
                    table.column("feed_value").to_pylist(),
                    table.column("plant").to_pylist()))
    figures = {name: _figure(table, name) for name in SUMMARY_FIGURES}
    groups = []
    for key in sorted(set(keys)):
        member = np.array([k == key for k in keys])
        sel = member & ok
        entry = {"interpolator": key[0], "feed": key[1], "feed_unit": study.feed_unit,
                 "plant": key[2], "cases": int(member.sum()), "ok": int(sel.sum()),
                 "failed": int((member & ~ok).sum()), "figures": {}}
        if sel.any():
            for name, values in figures.items():
                v = values[sel]
                entry["figures"][name] = {q: float(np.quantile(v, p, method="inverted_cdf"))
                                          for q, p in _QUANTILES}
        groups.append(entry)
    failing = []
    cols = ["case_id", "path", "feed_value", "machine", "plant", "interpolator",
            "error_type", "error_message"]
    data = {c: table.column(c).to_pylist() for c in cols}
    for i in np.flatnonzero(~ok):
        case = {c: data[c][i] for c in cols}
        case["reproduce"] = (f"nurbsmotion campaign {study_file} --out {out_dir} "
                             f"--case {case['case_id']}")
        failing.append(case)
    return {"study": study.name, "cases": int(len(ok)), "ok": int(ok.sum()),
            "failed": int((~ok).sum()), "groups": groups, "failing_cases": failing}


def write_digest(data: dict, out_dir: str | os.PathLike) -> tuple[Path, Path]:
    """Write ``digest.json`` and ``digest.md`` into ``out_dir`` (through temporary names)."""
    from .report import write_json

    out = Path(out_dir)
    tmp = out / ".digest.json.tmp"
    write_json(data, tmp)
    os.replace(tmp, out / "digest.json")
    tmp = out / ".digest.md.tmp"
    tmp.write_text(digest_markdown(data))
    os.replace(tmp, out / "digest.md")
    return out / "digest.json", out / "digest.md"


def digest_markdown(data: dict) -> str:
    """The digest as Markdown: one table per figure, rows per group."""
    lines = [f"# Study {data['study']}: {data['cases']} cases, {data['ok']} ok, "
             f"{data['failed']} failed", ""]
    for name in SUMMARY_FIGURES:
        lines += [f"## {name}", "",
                  "| interpolator | feed | plant | ok / cases | min | median | 95th | max |",
                  "|---|---|---|---|---|---|---|---|"]
        for g in data["groups"]:
            q = g["figures"].get(name)
            cells = [f"{q[k]:.4g}" for k, _ in _QUANTILES] if q else ["–"] * 4
            lines.append(f"| {g['interpolator']} | {g['feed']:g} {g['feed_unit']} | "
                         f"{g['plant']} | {g['ok']} / {g['cases']} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Failing cases", ""]
    if not data["failing_cases"]:
        lines.append("None.")
    for c in data["failing_cases"]:
        lines.append(f"- `{c['case_id']}` {c['path']} at {c['feed_value']:g}, {c['machine']}, "
                     f"plant {c['plant']}, {c['interpolator']}: {c['error_type']}: "
                     f"{(c['error_message'] or '').splitlines()[0] if c['error_message'] else ''}"
                     f" — reproduce: `{c['reproduce']}`")
    return "\n".join(lines) + "\n"


def find_case(study: Study, case_id: str) -> Case:
    """The case of ``study`` with id ``case_id`` (e.g. ``"c0000042"``)."""
    from dataclasses import replace

    for c in study_cases(replace(study, sample=None)):
        if c.case_id == case_id:
            return c
    raise KeyError(f"no case {case_id!r} in study {study.name!r}")
