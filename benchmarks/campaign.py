"""Campaign throughput: serial, 2 local workers, a 2-worker Dask LocalCluster; engine
overhead per case.

Runs the same cases of a study (by default ``benchmarks/die_bonder_study.toml``; with
``--cases N``, whole paths spread evenly over the study until N cases) three ways into
temporary folders and reports, for each, cases per second and the 1 -> 2 worker scaling
(target >= 1.8x), and the engine's own cost per case (target <= 5 % of the case's time).
The serial run is the same engine (:func:`nurbsmotion.study.run_study`) with one
worker: the cases run in this process, in the same order, with the same per-path tables.

The machine may be shared, so every figure is given twice:

- *wall*: cases / wall time, as a user sees it (``os.getloadavg()`` is printed with it);
- *load-corrected*: the wall time times the share of CPU the cases actually got
  (sum of ``case_cpu_s`` over sum of ``case_time_s``, both measured inside
  :func:`nurbsmotion.study.run_case`). Other programs' load stretches a case's wall
  time but not its CPU time, so this is the wall time the run would have taken with its
  workers on cores of their own; work the engine adds (start-up, duplicated path tables,
  the tail where a worker idles, the parent's writing) is kept in it.

The engine overhead is the CPU time of every process of the run (this one, and the
workers: local ones through ``getrusage(RUSAGE_CHILDREN)``, Dask workers asked for
theirs; a LocalCluster's scheduler and nannies run in this process) beyond the cases'
own CPU time (``case_cpu_s``, the CPU time of the thread that ran the case), per case and
as a share of the case time; the part spent in this process is given too. On Dask, much
of it is the cluster's own background work (heartbeats, monitors, the workers'
profiler), which goes by the second, not by the case: a loaded machine, stretching the
run's wall time, raises it. So the cluster's CPU time a second at rest is measured
(5 s with no task) and the overhead is also given as it would have been at the
load-corrected wall time (the measured overhead less that rate times the wall time the
load added) — an estimate; on an idle machine the two agree. *Work* is the cases' CPU time over the serial run's: above 1 when a path's
tables are built by two workers, or when two busy cores slow each other (shared caches
and memory; on a loaded machine, other programs too).

Every configuration starts with the kernels loaded: this process loads them before the
serial run (forked local workers inherit them); the Dask cluster is started and each of
its workers loads them (the engine's worker plugin) before its first timed run, and that
start-up is reported on its own line. The LocalCluster runs twice: with
:data:`nurbsmotion.study.DASK_SETTINGS` (as ``docs/campaign.md`` starts a cluster's
scheduler and workers), and with Dask's default settings.

    python benchmarks/campaign.py [--study FILE] [--cases 1000]
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

import _common  # noqa: F401  (puts src/ on the path)

from nurbsmotion.study import case as study_case
from nurbsmotion.study import execute
from nurbsmotion.study.dataset import read_rows
from nurbsmotion.study.run import run_study
from nurbsmotion.study.spec import load_study, study_cases


_REST_SECONDS = 5.0
"""How long the started LocalCluster is watched with no task [s]."""


def _cpu(who) -> float:
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


def _worker_cpu() -> float:
    """CPU time of the calling (Dask worker or nanny) process [s]."""
    return _cpu(resource.RUSAGE_SELF)


def _cluster_cpu(client) -> float:
    """CPU time of the cluster's worker processes [s] (a LocalCluster's scheduler and
    nannies run in this process)."""
    return sum(client.run(_worker_cpu).values())


def timed(study, cases, client=None, workers=None) -> dict:
    """One run into a fresh folder, with this process's per-path caches emptied (forked
    workers would inherit them): wall time, the cases' summed wall and CPU time, and the
    CPU time of every process of the run [s]."""
    study_case._BOUNDS.clear()
    for cached in (study_case._contour, study_case._pulses):
        cached.cache_clear()
    study_case._PATH_ERRORS.clear()
    if client is not None:
        client.run(lambda: [c.cache_clear() for c in (study_case._contour, study_case._pulses)])
        remote0 = _cluster_cpu(client)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        self0 = _cpu(resource.RUSAGE_SELF)
        cpu0 = self0 + _cpu(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        run_study(study, Path(tmp) / "out", progress=False, cases=cases,
                  scheduler=client, workers=workers)
        wall = time.perf_counter() - t0
        cpu = _cpu(resource.RUSAGE_SELF) + _cpu(resource.RUSAGE_CHILDREN) - cpu0
        here = _cpu(resource.RUSAGE_SELF) - self0
        table = read_rows(Path(tmp) / "out")
    if client is not None:
        cpu += _cluster_cpu(client) - remote0
    case_wall = float(np.nansum(table.column("case_time_s").to_numpy(zero_copy_only=False)))
    case_cpu = float(np.nansum(table.column("case_cpu_s").to_numpy(zero_copy_only=False)))
    if workers == 1 and client is None:  # the cases ran in this process
        here -= case_cpu
    return {"n": len(table), "wall": wall, "case_wall": case_wall, "case_cpu": case_cpu,
            "cpu": cpu, "here": here, "corrected": wall * case_cpu / case_wall,
            "load": (load, os.getloadavg()[0])}


def show(name: str, r: dict, serial: dict | None = None, rest: float | None = None) -> None:
    n = r["n"]
    over = r["cpu"] - r["case_cpu"]
    text = (f"{name}: {r['wall']:.1f} s, {n / r['wall']:.2f} cases/s wall; load-corrected "
            f"{r['corrected']:.1f} s, {n / r['corrected']:.2f} cases/s (cases got "
            f"{r['case_cpu'] / r['case_wall']:.0%} of a core); engine overhead "
            f"{over / n * 1e3:.1f} ms CPU a case = {over / r['case_cpu']:.1%} of the case "
            f"CPU time ({r['here'] / n * 1e3:.1f} ms in this process); load {r['load'][0]:.1f} -> {r['load'][1]:.1f}")
    if serial is not None:
        text += (f"; work {r['case_cpu'] / serial['case_cpu']:.3f} x serial's; scaling "
                 f"{serial['wall'] / r['wall']:.2f}x wall, "
                 f"{serial['corrected'] / r['corrected']:.2f}x load-corrected")
    if rest is not None:
        # The cluster's background work goes by the second: had the run taken its
        # load-corrected wall time, it would have cost that much less.
        idle = over - rest * (r["wall"] - r["corrected"])
        text += (f"; overhead at the load-corrected wall time {idle / n * 1e3:.1f} ms a case "
                 f"= {idle / r['case_cpu']:.1%} (the cluster at rest: {rest * 1e3:.0f} ms "
                 "CPU a second)")
    print(text, flush=True)


def spread_cases(cases, n: int):
    """Whole paths (all their cases), spread evenly over the study, until ``n`` cases."""
    groups: dict = {}
    for c in cases:
        groups.setdefault(study_case._path_key(c), []).append(c)
    groups = list(groups.values())
    if sum(map(len, groups)) <= n:
        return cases
    chosen, total = [], 0
    # the golden-ratio sequence visits the study's paths evenly at every prefix
    order = np.argsort([(k * 0.6180339887) % 1 for k in range(len(groups))], kind="stable")
    for k in order:
        if total >= n:
            break
        chosen.append(int(k))
        total += len(groups[k])
    return [c for k in sorted(chosen) for c in groups[k]]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--study", default=str(Path(__file__).with_name("die_bonder_study.toml")))
    p.add_argument("--cases", type=int, default=1000)
    p.add_argument("--no-dask", action="store_true", help="skip the LocalCluster")
    args = p.parse_args()
    study = load_study(args.study)
    cases = spread_cases(study_cases(study), args.cases)
    print(f"{len(cases)} cases of {args.study}; {os.cpu_count()} cores", flush=True)
    # Load (or compile) the kernels, and import what writes the dataset, once, so that
    # no configuration pays it (the serial run would, being first).
    execute._warm_up(cases)
    import pyarrow.dataset  # noqa: F401
    import pyarrow.parquet  # noqa: F401
    serial = timed(study, cases, workers=1)
    show("serial (1 worker, this process)", serial)
    show("2 local workers", timed(study, cases, workers=2), serial)
    if args.no_dask:
        return
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        print("dask.distributed not installed: no LocalCluster figure")
        return
    import dask

    # DASK_SETTINGS first: a nanny puts its workers' environment (Dask's default
    # MALLOC_TRIM_THRESHOLD_) into this process's os.environ, which later nannies pass on.
    for name, settings in (("DASK_SETTINGS", execute.DASK_SETTINGS), ("Dask's defaults", {})):
        cpu0 = _cpu(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        with dask.config.set(settings), LocalCluster(
                n_workers=2, processes=True, threads_per_worker=1,
                dashboard_address=None) as cluster, Client(cluster) as client:
            started = time.perf_counter() - t0
            # Its workers are fresh interpreters (the pool's are forks of this warm one):
            # each imports the library and loads the kernels from numba's cache, once.
            execute._dask_warm_up(client, cases)
            client.run(lambda: None)  # every worker has run the plugin's setup
            ready = time.perf_counter() - t0
            cpu = _cpu(resource.RUSAGE_SELF) - cpu0 + _cluster_cpu(client)
            # What the scheduler, the nannies and the workers spend with no task [CPU s/s]
            rest0, t1 = _cpu(resource.RUSAGE_SELF) + _cluster_cpu(client), time.perf_counter()
            time.sleep(_REST_SECONDS)
            rest = (_cpu(resource.RUSAGE_SELF) + _cluster_cpu(client) - rest0) / (
                time.perf_counter() - t1)
            label = f"2-worker Dask LocalCluster, {name}"
            print(f"{label}: start-up (not in its figures) {started:.1f} s to start, "
                  f"{ready:.1f} s with the kernels loaded; {cpu:.1f} s CPU in all; at rest "
                  f"{rest * 1e3:.0f} ms CPU a second", flush=True)
            show(label, timed(study, cases, client), serial, rest)
            show(f"{label}, again", timed(study, cases, client), serial, rest)


if __name__ == "__main__":
    main()
