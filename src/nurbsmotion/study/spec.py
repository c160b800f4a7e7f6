"""A study: what it varies and how it expands into cases.

A study file (TOML, schema in ``docs/campaign.md``) lists the values of each factor (paths,
random path families, feeds, machines, true plants, interpolators); :func:`load_study`
reads and validates it into a :class:`Study`, and :func:`study_cases` expands it into
:class:`Case` objects, every combination or a seeded sample of them. Every random draw of
a case comes from seeds derived from the study's seed and the case's index
(:func:`_seed`), never from a worker. Also the row statuses every part of a study shares.
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from functools import lru_cache
from itertools import product
from pathlib import Path

import numpy as np

from ..errors import InvalidArgumentError, PathFileError
from ..interpolators import LOOP_METHODS
from ..machine import Machine, load_machine
from ..metrics import SETTLE_WINDOW

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["Study", "Case", "PlantGroup", "RandomPaths", "load_study", "study_cases",
           "find_case", "STATUS_OK", "STATUS_ERROR", "WORKER_DIED", "FEED_UNITS",
           "CASE_TIME_LIMIT"]

STATUS_OK, STATUS_ERROR = "ok", "error"
WORKER_DIED = "WorkerDied"
"""``error_type`` of a case whose worker process died twice while running it."""

FEED_UNITS = ("pulse/s", "path/s", "um/s", "mm/s", "m/s", "mm/min")
"""Units of a study's ``feeds``: a case's feed is ``run --feed`` with the value and this
unit (``50mm/s``), converted by :func:`nurbsmotion.study.run_input.run_feed`; ``path/s`` is a
bare number, in the path's own units per second."""

CASE_TIME_LIMIT = 300.0
"""Default CPU time a case may use [s] (a study's ``case_time_limit``): about thirty times
the longest case of the die-bonder study, so that a case that would run away (a path whose
tables do not converge) is stopped and recorded instead of holding a worker for ever."""


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
    tool_table: str | None = None
    """A LinuxCNC tool table (relative to the study file) for the cutter radius
    compensation of the study's G-code programs (``run --tool-table``)."""


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
    tool_table: str | None = None

    @property
    def case_id(self) -> str:
        return f"c{self.index:07d}"


_STUDY_KEYS = {"name", "seed", "paths", "random_paths", "feeds", "feed_unit", "machines",
               "plants", "interpolators", "sample", "settle_time", "settle_window",
               "time_optimal_bound", "case_time_limit", "tool_table"}


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
    tool_table = data.get("tool_table")
    if tool_table is not None:
        if not isinstance(tool_table, str) or not (Path(base_dir) / tool_table).is_file():
            raise InvalidArgumentError(f"tool_table {tool_table!r} must name a LinuxCNC tool table "
                                       "(.tbl) file, relative to the study file")
    bound = data.get("time_optimal_bound", True)
    if not isinstance(bound, bool):
        raise InvalidArgumentError(f"time_optimal_bound must be true or false, got {bound!r}")
    return Study(name=str(data.get("name", Path(source).stem)), seed=seed, paths=paths,
                 random_paths=random_paths, feeds=tuple(float(f) for f in feeds),
                 feed_unit=feed_unit, machines=machines, plants=plants,
                 interpolators=interpolators, sample=sample, settle_time=settle_time,
                 settle_window=settle_window, bound=bound, case_time_limit=limit or None,
                 source=source, base_dir=base_dir, tool_table=tool_table)


def _check_path_file(spec: str, base_dir: str) -> None:
    """A study's path: a built-in name, or a path file (relative to the study) that
    exists and has a path file's ending; ``FILE#k`` picks a contour."""
    from ..nurbs import BUILTIN_PATHS
    from ..paths import PATH_FILE_SUFFIXES

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
    from ..paths.random_paths import FAMILIES

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
    from ..machine import AXIS_EFFECT_KEYS, MACHINE_EFFECT_KEYS

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
                          study.case_time_limit, study.tool_table))
        index += 1
    if study.sample is not None and study.sample < len(cases):
        pick = np.random.default_rng(_seed(study.seed, 3)).choice(
            len(cases), size=study.sample, replace=False)
        cases = [cases[i] for i in np.sort(pick)]
    return cases


@lru_cache(maxsize=16)
def _machine(spec: str, base_dir: str) -> Machine:
    from ..machine import BUILTIN_MACHINES

    if spec in BUILTIN_MACHINES:
        return load_machine(spec)
    return load_machine(Path(base_dir) / spec)


def find_case(study: Study, case_id: str) -> Case:
    """The case of ``study`` with id ``case_id`` (e.g. ``"c0000042"``)."""
    from dataclasses import replace

    for c in study_cases(replace(study, sample=None)):
        if c.case_id == case_id:
            return c
    raise KeyError(f"no case {case_id!r} in study {study.name!r}")
