"""Shared helpers of the benchmark scripts: timing medians, subprocesses, the machine."""

from __future__ import annotations

import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
if str(SRC) not in sys.path:
    sys.path.insert(0, str(SRC))  # run from a checkout without installing


PEAK_MB = r"""
def peak_mb():
    # VmHWM starts afresh at exec; ru_maxrss may keep the forking parent's peak.
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    import resource
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
"""
"""Source of ``peak_mb()``, the peak resident set size of the process [MB], for the
child scripts of the benchmarks."""


def median_time(fn, repeats: int, warmup: int = 1) -> tuple[float, list[float]]:
    """Median wall time of ``fn()`` over ``repeats`` calls after ``warmup`` calls [s]."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times


def python_env(**extra: str) -> dict:
    """Environment for a child Python that imports this checkout's nurbsmotion."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC)] + [p for p in
                                                       [env.get("PYTHONPATH")] if p])
    env.update(extra)
    return env


def run_python(code: str, **extra_env: str) -> tuple[float, str]:
    """Run ``python -c code`` in a fresh process; (wall time [s], its stdout)."""
    wall, _, out = run_python_timed(code, **extra_env)
    return wall, out


def run_python_timed(code: str, **extra_env: str) -> tuple[float, float, str]:
    """Run ``python -c code`` in a fresh process; (wall time [s], its CPU time, user +
    system [s], its stdout). The CPU time hardly depends on what else the machine runs."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code], env=python_env(**extra_env),
                          capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if done.returncode != 0:
        raise RuntimeError(f"child failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return wall, cpu, done.stdout


def cold_and_warm(measure, repeats: int) -> tuple[list, list]:
    """``measure(cache_dir)`` on an empty numba cache folder (cold), then again on the
    same folder (warm), ``repeats`` times; the two lists of results."""
    cold, warm = [], []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as cache:
            cold.append(measure(cache))
            warm.append(measure(cache))
    return cold, warm


def machine_description() -> str:
    """One line: CPU model, core count, load, Python and library versions."""
    import numba
    import numpy
    import scipy

    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return (f"{cpu}, {os.cpu_count()} cores, load average {load} at the start; "
            f"Python {platform.python_version()}, numpy {numpy.__version__}, "
            f"scipy {scipy.__version__}, numba {numba.__version__}")


def section(title: str, header: list[str], rows: list[list], note: str = "",
            intro: str = "") -> str:
    """A Markdown section (heading, optional intro, table, note), printed and returned."""
    text = f"### {title}\n\n" + (intro + "\n\n" if intro else "") + table(header, rows)
    text += ("\n\n" + note if note else "") + "\n"
    print(text)
    return text


def table(header: list[str], rows: list[list]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def spread(values) -> str:
    """``"median / 95 % / max"`` of ``values`` (NaN ignored), three significant digits:
    the distribution columns of the sweeps."""
    import numpy as np

    v = np.asarray(values, dtype=float)
    return " / ".join(f"{x:.3g}" for x in np.nanpercentile(v, [50, 95, 100]))
