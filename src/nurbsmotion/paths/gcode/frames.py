"""Coordinate frames of the G-code reader: the G5x and G92 offsets and the XY rotation of
``G10 L2 R`` as LinuxCNC keeps them in its numbered parameters, the conversion between
program and absolute (canonical) coordinates, and the system parameters ``#<_x>`` ..
``#<_w>`` the language layer reads. A part of :class:`~nurbsmotion.paths.gcode.reader._Reader`.
"""

from __future__ import annotations

import math

import numpy as np

from .codes import _AXES


class _Frames:
    """The reader's frames (mixed into :class:`~nurbsmotion.paths.gcode.reader._Reader`)."""

    def frame(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The active G5x offset, G92 offset (X..W, [output units]) and XY rotation [deg]
        (parameters #5221.. per system, #5211.., #5210), as LinuxCNC keeps them; cached
        until a block or an assignment changes them."""
        key = (self.program.frame_version, self.frame_changes)
        if self._frame_key != key:
            self._frame = self._read_frame()
            self._frame_key = key
            g5x, g92, rot = self._frame
            self._identity = not (rot or np.any(g5x) or np.any(g92))
        return self._frame

    def identity_frame(self) -> bool:
        """Whether no offset or rotation is active (program = absolute coordinates)."""
        if self._frame_key is None or self._frame_key[0] != self.program.frame_version \
                or self._frame_key[1] != self.frame_changes:
            self.frame()
        return self._identity

    def _read_frame(self) -> tuple[np.ndarray, np.ndarray, float]:
        n = self.program.numbered
        system = int(n[5220]) or 1
        base = 5201 + 20 * system
        g92 = np.array(n[5211:5220]) if n[5210] else np.zeros(9)
        return np.array(n[base: base + 9]), g92, n[base + 9]

    def to_program(self, p) -> list:
        """Absolute (machine) coordinates X..W -> program coordinates (LinuxCNC's
        unrotate), as a new list."""
        g5x, g92, rot = self.frame()
        if self._identity:
            return list(p)
        q = np.array(p, dtype=float) - g5x
        if rot:
            c, s = math.cos(math.radians(rot)), math.sin(math.radians(rot))
            q[0], q[1] = c * q[0] + s * q[1], -s * q[0] + c * q[1]
        return (q - g92).tolist()

    def to_absolute_point(self, q: list) -> list:
        """:meth:`to_absolute` of one point X..W, as a new list."""
        self.frame()
        return list(q) if self._identity else self.to_absolute(np.array(q, dtype=float)).tolist()

    def to_absolute(self, q: np.ndarray) -> np.ndarray:
        """Program coordinates (shape (..., 9)) -> absolute: + G92, rotate XY, + G5x."""
        g5x, g92, rot = self.frame()
        if self._identity:
            return q
        p = q + g92
        if rot:
            c, s = math.cos(math.radians(rot)), math.sin(math.radians(rot))
            p = p.copy()
            p[..., 0], p[..., 1] = c * (q[..., 0] + g92[0]) - s * (q[..., 1] + g92[1]), \
                s * (q[..., 0] + g92[0]) + c * (q[..., 1] + g92[1])
        return p + g5x

    def system_parameter(self, name: str) -> float | None:
        """``#<_x>`` .. ``#<_w>`` and a few modal flags, for the language layer."""
        if len(name) == 2 and name[1].upper() in _AXES:
            i = _AXES.index(name[1].upper())
            k = 1.0 / self.scale() if self.units and i not in (3, 4, 5) else 1.0
            return float(self.to_program(self.pos)[i] * k)
        flags = {"_metric": not self.input_inch, "_imperial": bool(self.input_inch),
                 "_absolute": self.absolute, "_incremental": not self.absolute}
        if name in flags:
            return float(flags[name])
        if name == "_feed":
            return self.feed
        return None
