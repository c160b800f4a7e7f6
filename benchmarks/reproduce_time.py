"""Wall time of ``nurbsmotion reproduce`` in a fresh process, cold and warm.

Cold: ``NUMBA_CACHE_DIR`` is an empty folder, so the kernels compile; warm: the same folder
again, so they load from it. Timed with and without the figures (``--no-figures``), which
take most of the time and do not depend on the kernels.

    python benchmarks/reproduce_time.py
"""

from __future__ import annotations

import statistics
import tempfile
from pathlib import Path

import _common  # noqa: F401  (puts src/ on the path)
from _common import cold_and_warm, run_python, section


def reproduce(cache: str, figures: bool) -> float:
    """Wall time [s] of one ``reproduce`` into a fresh output folder."""
    with tempfile.TemporaryDirectory() as out:
        argv = ["reproduce", "--out", str(Path(out) / "results")]
        argv += [] if figures else ["--no-figures"]
        code = f"from nurbsmotion.cli import main; raise SystemExit(main({argv!r}))"
        return run_python(code, NUMBA_CACHE_DIR=cache, MPLBACKEND="Agg")[0]


def main(repeats: int = 2) -> str:
    rows = []
    for figures in (False, True):
        cold, warm = cold_and_warm(lambda cache: reproduce(cache, figures), repeats)
        rows.append(["`nurbsmotion reproduce" + ("" if figures else " --no-figures") + "`",
                     f"{statistics.median(cold):.2f}", f"{statistics.median(warm):.2f}"])
    return section("`nurbsmotion reproduce`: wall time of a fresh process",
                   ["command", "cold numba cache [s]", "warm numba cache [s]"], rows,
                   f"Medians of {repeats} runs each.")


if __name__ == "__main__":
    main()
