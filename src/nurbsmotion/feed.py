"""The programmed feed along a path: a piecewise-constant speed limit in the curve parameter.

A G-code program gives a feed (F) per move; after its moves are joined into one path
(:mod:`nurbsmotion.paths.gcode`), move k occupies ``[breakpoints[k], breakpoints[k+1]]`` of
the curve parameter and may not be run faster than ``speeds[k]``. :class:`FeedLimit` holds
that as data, so the planners and interpolators can read ``V <= F(u)``.

Glossary
--------
u : curve parameter in [0, 1]; F : feed limit [path units / s] (or pulse/s once scaled
with :meth:`FeedLimit.scaled`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InvalidFeedError

__all__ = ["FeedLimit", "InvalidFeedError"]




@dataclass(frozen=True, eq=False)
class FeedLimit:
    """A speed limit that is constant on each interval of the curve parameter.

    Parameters
    ----------
    breakpoints : array_like, shape (n + 1,)
        Strictly increasing, from 0 to 1: interval k is ``[breakpoints[k], breakpoints[k+1]]``.
    speeds : array_like, shape (n,)
        Largest speed on each interval [path units / s], finite and > 0.

    Notes
    -----
    At an interior breakpoint the limit is the lower of its two intervals, so a speed
    that respects ``F(u)`` at every ``u`` respects both moves' feeds.

    Raises
    ------
    InvalidFeedError
        Naming the bad entry.
    """

    breakpoints: np.ndarray
    speeds: np.ndarray

    def __post_init__(self):
        b = np.array(self.breakpoints, dtype=float).ravel()
        v = np.array(self.speeds, dtype=float).ravel()
        if b.size != v.size + 1 or v.size == 0:
            raise InvalidFeedError(f"a feed limit needs n + 1 breakpoints for n >= 1 speeds, got "
                                   f"{b.size} breakpoints and {v.size} speeds")
        if b[0] != 0.0 or b[-1] != 1.0 or np.any(np.diff(b) <= 0) or not np.all(np.isfinite(b)):
            raise InvalidFeedError(f"feed-limit breakpoints must rise strictly from 0 to 1, got "
                                   f"{b[:6].tolist()}{' ...' if b.size > 6 else ''}")
        bad = ~(np.isfinite(v) & (v > 0))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise InvalidFeedError(f"feed-limit speed {i} is {v[i]!r}; speeds must be finite and > 0")
        b.flags.writeable = False
        v.flags.writeable = False
        object.__setattr__(self, "breakpoints", b)
        object.__setattr__(self, "speeds", v)

    @classmethod
    def constant(cls, speed: float) -> "FeedLimit":
        """The same limit along the whole path."""
        return cls(np.array([0.0, 1.0]), np.array([float(speed)]))

    @property
    def lowest(self) -> float:
        """The lowest speed anywhere [path units / s]."""
        return float(np.min(self.speeds))

    @property
    def highest(self) -> float:
        """The highest speed anywhere [path units / s]."""
        return float(np.max(self.speeds))

    def __call__(self, u) -> np.ndarray:
        """The limit at each ``u`` in [0, 1] (the lower one at a breakpoint), shape of ``u``."""
        uu = np.asarray(u, dtype=float)
        flat = np.clip(uu.ravel(), 0.0, 1.0)
        v = self.speeds
        right = np.clip(np.searchsorted(self.breakpoints, flat, side="right") - 1, 0, v.size - 1)
        left = np.clip(np.searchsorted(self.breakpoints, flat, side="left") - 1, 0, v.size - 1)
        out = np.minimum(v[right], v[left])
        return out.reshape(uu.shape) if uu.ndim else float(out[0])

    def capped(self, cap: float) -> "FeedLimit":
        """The lower of this limit and ``cap`` on every interval (same units)."""
        c = float(cap)
        if not (np.isfinite(c) and c > 0):
            raise InvalidFeedError(f"feed cap must be finite and > 0, got {cap!r}")
        return FeedLimit(self.breakpoints, np.minimum(self.speeds, c))

    def scaled(self, factor: float) -> "FeedLimit":
        """Every speed times ``factor`` (a unit change, e.g. mm/s -> pulse/s)."""
        k = float(factor)
        if not (np.isfinite(k) and k > 0):
            raise InvalidFeedError(f"feed scale factor must be finite and > 0, got {factor!r}")
        return FeedLimit(self.breakpoints, self.speeds * k)

    def duration(self, curve) -> float:
        """Time to run ``curve`` at exactly this limit everywhere [s] (no acceleration)."""
        s = curve.arc_length(self.breakpoints)
        return float(np.sum(np.diff(s) / self.speeds))

    def __repr__(self) -> str:
        return (f"FeedLimit({self.speeds.size} intervals, {self.lowest:.6g} .. "
                f"{self.highest:.6g} per s)")
