"""The identification figure: measured against simulated response (private; matplotlib is
imported here, never by the library's import)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._runtime.io import atomic_output

IDENTIFY_FIGURE = "identify.png"
"""File name of the figure :meth:`nurbsmotion.identify.Identification.plot` writes."""


def plot_identification(result, out, *, overwrite: bool = False) -> Path:
    """Per axis: the logged and the fitted machine's position [pulse] and speed [pulse/s]
    under the logged drive, and the drive [V]; written to ``out/identify.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    log = result.log
    n = len(result.axes)
    fig, axs = plt.subplots(3, n, figsize=(6 * n, 8), sharex=True, squeeze=False)
    t = log.time
    for j, a in enumerate(result.axes):
        y = log.position[:, j]
        ys = a.simulated
        axs[0, j].plot(t, y, label="measured", lw=1.0)
        axs[0, j].plot(t, ys, "--", label="fitted machine", lw=1.0)
        axs[0, j].set_ylabel("position [pulse]")
        axs[0, j].set_title(f"axis {a.name}: residual RMS {a.residual_rms:.3g} pulse/sample")
        axs[0, j].legend(loc="best", fontsize=8)
        axs[1, j].plot(t[1:], np.diff(y) / log.sample_period, lw=0.8, label="measured")
        axs[1, j].plot(t[1:], np.diff(ys) / log.sample_period, "--", lw=0.8,
                       label="fitted machine")
        axs[1, j].set_ylabel("speed [pulse/s]")
        axs[2, j].plot(t, log.drive[:, j], lw=0.8, color="k")
        axs[2, j].set_ylabel("drive [V]")
        axs[2, j].set_xlabel("t [s]")
    fig.tight_layout()
    path = Path(out) / IDENTIFY_FIGURE
    with atomic_output(path, overwrite=overwrite, binary=True) as handle:
        fig.savefig(handle, format="png", dpi=100)
    plt.close(fig)
    return path
