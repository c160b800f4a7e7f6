"""Run every benchmark and write benchmarks/RESULTS.md.

    python benchmarks/run_all.py            # everything (a few minutes; geomdl dominates)
    python benchmarks/run_all.py --quick    # fewer repeats

Each script also runs on its own (``python benchmarks/<name>.py``).
"""

from __future__ import annotations

import argparse
import datetime
import sys
import time
from pathlib import Path

import _common
import compile_cost
import figure_time
import long_run
import loop_throughput
import memory
import nurbs_eval
import reproduce_time

HERE = Path(__file__).resolve().parent


def _toppra_section(repeats: int) -> str:
    """The TOPP-RA comparison, if its benchmark-only dependency is installed."""
    try:
        import toppra  # noqa: F401
    except ImportError:
        return ("### Look-ahead planning against TOPP-RA\n\nSkipped: `pip install toppra` "
                "to run it (a benchmark-only dependency).\n")
    import toppra_compare

    return toppra_compare.main(repeats=repeats)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    parser.add_argument("--out", default=str(HERE / "RESULTS.md"), help="Markdown file")
    args = parser.parse_args(argv)
    q = args.quick
    machine = _common.machine_description()
    t0 = time.perf_counter()
    sections = [
        loop_throughput.main(repeats=5 if q else 15),
        memory.main(),  # before geomdl's million-row lists grow this process
        long_run.main(repeats=1 if q else 2),
        nurbs_eval.main(repeats=3 if q else 7, geomdl_repeats=1 if q else 3),
        compile_cost.main(repeats=1 if q else 3),
        reproduce_time.main(repeats=1 if q else 2),
        figure_time.main(repeats=1 if q else 3),
        _toppra_section(repeats=1 if q else 3),
    ]
    took = time.perf_counter() - t0
    command = "python benchmarks/run_all.py" + (" --quick" if q else "")
    head = (
        "# Benchmark results\n\n"
        f"Produced by `{command}` on {datetime.date.today().isoformat()} "
        f"in {took:.0f} s.\n\n"
        f"Machine: {machine}. One process per measurement (numba kernels single-threaded); "
        "the machine is shared, so the load average above says how much the figures "
        "may be depressed.\n"
    )
    text = head + "\n" + "\n".join(sections)
    Path(args.out).write_text(text)
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
