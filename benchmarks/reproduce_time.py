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
from _common import run_python, table


def reproduce(out: Path, cache: str, figures: bool) -> float:
    argv = ["reproduce", "--out", str(out)] + ([] if figures else ["--no-figures"])
    code = f"from nurbsmotion.cli import main; raise SystemExit(main({argv!r}))"
    return run_python(code, NUMBA_CACHE_DIR=cache, MPLBACKEND="Agg")[0]


def main(repeats: int = 2) -> str:
    rows = []
    for figures in (False, True):
        cold, warm = [], []
        for _ in range(repeats):
            with tempfile.TemporaryDirectory() as cache, \
                    tempfile.TemporaryDirectory() as out:
                cold.append(reproduce(Path(out) / "cold", cache, figures))
                warm.append(reproduce(Path(out) / "warm", cache, figures))
        rows.append(["`nurbsmotion reproduce" + ("" if figures else " --no-figures") + "`",
                     f"{statistics.median(cold):.2f}", f"{statistics.median(warm):.2f}"])
    text = ("### `nurbsmotion reproduce`: wall time of a fresh process\n\n"
            + table(["command", "cold numba cache [s]", "warm numba cache [s]"], rows)
            + f"\n\nMedians of {repeats} runs each.\n")
    print(text)
    return text


if __name__ == "__main__":
    main()
