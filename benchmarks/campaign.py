"""Campaign throughput: serial, 2 local workers, a 2-worker Dask LocalCluster; engine
overhead per case.

Runs the same cases of a study (by default ``benchmarks/die_bonder_study.toml``, its first
``--cases`` cases) three ways into temporary folders and reports cases per second, the
1 -> 2 worker scaling (target >= 1.8x on 2 free cores), and the engine's own cost per
case: serial wall time minus the cases' own time (``case_time_s``, measured inside
:func:`nurbsmotion.campaign.run_case`), as a share of the cases' time (target <= 5 %).
Every worker pays its own start (imports, compiled-kernel cache) once; the local pool's
workers are forks of the (warm) parent, the Dask workers fresh interpreters, so the Dask
cluster is timed twice: the first run with that start, the second without. The machine's load is printed: on a shared machine the scaling
reads low.

    python benchmarks/campaign.py [--study FILE] [--cases 1000]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import _common  # noqa: F401  (puts src/ on the path)

from nurbsmotion import campaign
from nurbsmotion.campaign import load_study, read_rows, run_study, study_cases


def timed(study, cases, **options) -> tuple[float, float, int]:
    """Wall time [s], summed case time [s] and rows of one run into a fresh folder, with
    this process's per-path caches emptied (forked workers would inherit them)."""
    for cached in (campaign._curve, campaign._bound_of):
        cached.cache_clear()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        run_study(study, Path(tmp) / "out", progress=False, cases=cases, **options)
        wall = time.perf_counter() - t0
        table = read_rows(Path(tmp) / "out")
        return wall, float(sum(table.column("case_time_s").to_pylist())), len(table)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--study", default=str(Path(__file__).with_name("die_bonder_study.toml")))
    p.add_argument("--cases", type=int, default=1000)
    args = p.parse_args()
    study = load_study(args.study)
    cases = study_cases(study)[: args.cases]
    print(f"{len(cases)} cases of {args.study}; load average before: {os.getloadavg()}")
    # Warm the compiled-kernel cache so that no configuration pays the compilation.
    timed(study, cases[:1], workers=1)
    serial, case_time, n = timed(study, cases, workers=1)
    overhead = (serial - case_time) / case_time
    print(f"serial: {serial:.1f} s, {n / serial:.2f} cases/s; cases' own time "
          f"{case_time:.1f} s; engine overhead {overhead:.1%} of the case time")
    local2, _, _ = timed(study, cases, workers=2)
    print(f"2 local workers: {local2:.1f} s, {n / local2:.2f} cases/s, scaling "
          f"{serial / local2:.2f}x")
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        print("dask.distributed not installed: no LocalCluster figure")
    else:
        with LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            cold, _, _ = timed(study, cases, scheduler=client)
            # Its workers are fresh interpreters (the pool's are forks of this warm one):
            # the second run shows the throughput once imports and kernels are loaded.
            warm, _, _ = timed(study, cases, scheduler=client)
        print(f"2-worker Dask LocalCluster: first run {cold:.1f} s (workers loading "
              f"nurbsmotion and its compiled kernels), then {warm:.1f} s, "
              f"{n / warm:.2f} cases/s, scaling {serial / warm:.2f}x")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
