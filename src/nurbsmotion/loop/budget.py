"""Work estimates: how many samples a command will compute, refused beyond a limit.

A move's duration is at least its length over the feed, so a run of a path of length L
at feed F with sample period Ts computes at least ``L / (F*Ts)`` samples, and a trace
holds :func:`bytes_per_sample` bytes for each. A typo in a feed (``--feed 1``: one pulse
per second, a 28-hour move) would otherwise fill the memory; it is refused in one line
before any work, naming the estimate and the option that raises the limit.

Glossary
--------
L : path length [path units]; F : feed [path units/s]; Ts : sample period [s].
"""

from __future__ import annotations

import math

from ..errors import WorkLimitError
from ..limits import MAX_SAMPLES

__all__ = ["MAX_SAMPLES", "bytes_per_sample", "estimate_samples", "check_samples"]


def bytes_per_sample(n_axes: int) -> int:
    """Memory of one trace sample [byte]: u and feed, then per axis the commanded and
    actual position and speed, drive before and after clipping, and two speed bounds."""
    return 8 * (2 + 8 * n_axes)


def estimate_samples(length: float, feed: float, period: float) -> float:
    """Least number of samples to cover ``length`` at ``feed`` every ``period`` seconds:
    ``L / (F*Ts)`` (``inf`` where that overflows)."""
    with_period = feed * period
    if not with_period > 0:
        return math.inf
    n = length / with_period
    return n if math.isfinite(n) else math.inf


def check_samples(samples: float, *, limit: int = MAX_SAMPLES, n_axes: int = 1,
                  what: str = "the move", option: str = "max_samples") -> None:
    """Raise :class:`WorkLimitError` if ``samples`` exceeds ``limit``.

    Parameters
    ----------
    samples : float
        The estimate (:func:`estimate_samples`).
    limit : int
        The most samples allowed.
    n_axes : int
        Axes of the trace, for the memory estimate.
    what : str
        What the samples are of, for the message.
    option : str
        The option (or keyword) that raises the limit, for the message.
    """
    if samples <= limit:
        return
    memory = samples * bytes_per_sample(n_axes)
    raise WorkLimitError(
        f"{what} would take at least {samples:.3g} samples (about {memory / 1e9:.3g} GB of "
        f"memory), more than the limit of {limit:.3g}; check the feed and period, or raise "
        f"the limit with {option}"
    )
