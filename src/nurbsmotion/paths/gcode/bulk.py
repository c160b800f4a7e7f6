"""Runs of plain G-code lines applied in bulk: the words of a run as one array per kind
(:class:`_RunColumns`), the modal state along it (:class:`_RunState`), and the reader's
methods that apply the rows :meth:`_Reader.read` would take on its lean path, giving the
same pieces, feeds, lines and errors as one line at a time. A part of
:class:`~nurbsmotion.paths.gcode.reader._Reader`.
"""

from __future__ import annotations

import numpy as np

from ..pieces import PieceChain
from .codes import _AXES, _MOTION, MAX_COORDINATE, MIN_MOVE
from .ngc import Rows


class _Bulk:
    """The reader's bulk path (mixed into :class:`~nurbsmotion.paths.gcode.reader._Reader`)."""

    # -- runs of plain lines, in bulk
    def read_rows(self, rows: Rows) -> bool:
        """Process a run of plain lines (:class:`ngc.Rows`); return False when the program
        ends. The rows that :meth:`read` takes on its lean path (G0/G1 with axis and F
        words under G90 and G94, no offset, no open G5.2/G6.2 block) are applied in bulk
        (:class:`_RunState`); every other row goes through :meth:`read`, after which the
        bulk state is checked against the reader's and recomputed where they differ."""
        table = rows.table
        if self.rapids_as_path:  # rare (a program of rapids only) and small: line by line
            return all(self.read(table.block(r)) for r in range(rows.start, rows.stop))
        run = _RunColumns(table, rows.start, rows.stop)
        state = None
        s = 0
        while s < run.n:
            if self.lean():
                if state is None or not state.agrees(self, s):  # first, or read() did otherwise
                    state = _RunState(self, run, s, run.n if state is None else run.next_other(s))
                t = state.next_stop(s)
                if t > s:
                    self.apply_rows(run, state, s, t)
                    s = t
                    if s == run.n:
                        break
            if not self.read(table.block(rows.start + s)):
                return False
            s += 1
        return True

    def lean(self) -> bool:
        """Whether :meth:`read`'s lean path (and so :meth:`read_rows`'s bulk) applies."""
        return (self.block is None and self.units is not None and self.absolute
                and not self.inverse_time and not self.per_rev and self.identity_frame()
                and self.comp is None and self.comp_exit is None)

    def apply_rows(self, run: "_RunColumns", state: "_RunState", s: int, t: int) -> None:
        """Apply rows ``s .. t - 1`` of a run as :meth:`read` would, one by one."""
        i, k = state.pieces.searchsorted((s, t)).tolist()
        pieces = state.pieces[i:k]
        i, k = state.breaks.searchsorted((s, t)).tolist()
        parts = [pieces] if i == k else np.split(pieces, pieces.searchsorted(state.breaks[i:k]))
        for n, part in enumerate(parts):  # a rapid or a move of another axis ends the contour
            if n:
                self.line = int(run.line[state.breaks[i + n - 1]])
                self.end_contour()
            if len(part):
                rel = part - state.s  # rows of line pieces, relative to the state's first
                ends_at = rel + 1
                if self.chain is None:
                    self.chain = PieceChain(self.path_of(state.position(int(rel[0]))))
                ends = np.empty((len(rel), len(self.axes)))
                for c, axis in enumerate(self.axes):
                    ends[:, c] = state.column(axis, ends_at)
                self.chain.add_lines(ends)
                self.piece_feeds.frombytes(state.feed[ends_at].tobytes())
                self.piece_lines.frombytes(run.line[part].tobytes())
        j0, j = s - state.s, t - state.s
        for i, col in state._columns.items():
            if not self.moved[i] or (i not in self.axes and i not in self.fed_outside):
                changed = col[j0 + 1: j + 1] != col[j0: j]
                if changed.any():
                    self.moved[i] = True
                    fed = changed & (state.motion[j0 + 1: j + 1] == 1.0)
                    if i not in self.axes and fed.any():
                        self.fed_outside.setdefault(i, int(run.line[s + int(np.argmax(fed))]))
        self.pos = state.position(j)
        self.feed = float(state.feed[j])
        if state.motion[j] >= 0:
            self.motion = "G1" if state.motion[j] else "G0"
        self.line = int(run.line[t - 1])
        self.f_on_line = bool(run.has_feed[t - 1])
        if run.has_axis[s:t].any():
            self._g5_pq = None


_AXIS_OF_CODE = np.full(256, -1, dtype=np.int64)  # ASCII letter -> axis index (X..W), else -1
_AXIS_OF_CODE[[ord(a) for a in _AXES]] = np.arange(len(_AXES))
_OTHER_MOTION = np.array(sorted(set(_MOTION) - {0.0, 1.0}))


class _RunColumns:
    """The words of a run of plain lines (:class:`ngc.Rows`) as one array per kind, for
    :meth:`_Reader.read_rows`; NaN where a row has no such word.

    Attributes
    ----------
    n : int
        Rows.
    line : ndarray of int64, shape (n,)
    motion : ndarray, shape (n,)
        0 or 1 where a row's one G word is G0 or G1, -1 where it is another motion (G2,
        G5.2, ...), NaN where the row leaves the motion mode as it is (to :meth:`read`).
    feed : ndarray, shape (n,)
        The F word [program units / min].
    axis : dict of int to ndarray, shape (n,)
        The words of each axis (index into X..W) that occurs in the run.
    has_axis, has_feed : ndarray of bool, shape (n,)
    ok : ndarray of bool, shape (n,)
        Rows that :meth:`_Reader.read` reads on its lean path when the reader's state
        allows: no M word, at most one G word (G0 or G1), only axis and F words, every
        value in range. Other rows go through :meth:`_Reader.read`.
    """

    def __init__(self, table, start: int, stop: int):
        n = self.n = stop - start
        offsets = table.offsets[start: stop + 1]
        code = table.letter[offsets[0]: offsets[-1]]
        value = table.value[offsets[0]: offsets[-1]]
        row = np.repeat(np.arange(n), np.diff(offsets))
        self.line = table.line[start:stop]
        is_g, is_m, is_f = code == ord("G"), code == ord("M"), code == ord("F")
        axis = _AXIS_OF_CODE[code]
        is_axis = axis >= 0
        count = lambda mask: np.bincount(row[mask], minlength=n)  # noqa: E731
        n_g = count(is_g)
        g = np.full(n, np.nan)
        g[row[is_g]] = value[is_g]
        one_g = n_g == 1
        lean_g = one_g & ((g == 0.0) | (g == 1.0))
        self.motion = np.full(n, np.nan)
        self.motion[lean_g] = g[lean_g]
        self.motion[one_g & np.isin(g, _OTHER_MOTION)] = -1.0
        self.feed = np.full(n, np.nan)
        self.feed[row[is_f]] = value[is_f]
        self.has_feed = ~np.isnan(self.feed)
        self.axis = {}
        for i in np.unique(axis[is_axis]).tolist():
            column = self.axis[i] = np.full(n, np.nan)
            at = axis == i
            column[row[at]] = value[at]
        self.has_axis = count(is_axis) > 0
        out_of_range = (is_axis & ~(np.abs(value) <= MAX_COORDINATE)) | (
            is_f & ~((value >= 0) & (value <= MAX_COORDINATE)))
        self.ok = ((n_g == 0) | lean_g) & (count(is_m) == 0) & (count(~(is_g | is_f | is_axis)) == 0) \
            & (count(out_of_range) == 0)
        self._other = np.append(np.flatnonzero(~self.ok), n)

    def next_other(self, s: int) -> int:
        """The first row at or after ``s`` that is not ``ok`` (``n`` if none)."""
        return int(self._other[np.searchsorted(self._other, s)])


class _RunState:
    """The reader's state through rows ``s .. e - 1`` of a run as :meth:`_Reader.read`'s
    lean path leaves it, from the reader's state now; rows that are not ``ok`` count with
    their own G0/G1/motion, F and axis words (:meth:`agrees` checks that after
    :meth:`_Reader.read` has read them). Entry ``j`` of the arrays is the state before
    row ``s + j``.

    Attributes
    ----------
    motion : ndarray, shape (e - s + 1,)
        0 (G0), 1 (G1) or -1 (another motion mode, or none).
    feed : ndarray, shape (e - s + 1,)
        [output units / min]
    stops : ndarray of int64
        Rows (absolute in the run) that the bulk cannot apply: not ``ok``, an axis move
        under a motion other than G0/G1, a G1 of path and other axes together, a G1
        without a feed; ``e`` last.
    pieces, breaks : ndarray of int64
        Rows that add a line piece; rows that end the contour (a rapid that moves, a G1
        of an axis outside the path only).
    """

    def __init__(self, reader: "_Bulk", run: _RunColumns, s: int, e: int):
        self.s, self.e = s, e
        self.k, self.scale = list(reader.lengths()), reader.scale()
        self.start = list(reader.pos)
        self.motion = _forward_fill(run.motion[s:e], {"G0": 0.0, "G1": 1.0}.get(reader.motion, -1.0))
        self.feed = _forward_fill(run.feed[s:e] * self.scale, reader.feed)
        self._columns = {i: _forward_fill(col[s:e] * self.k[i], self.start[i]) for i, col in run.axis.items()}
        moves_path, moves_other = np.zeros(e - s, dtype=bool), np.zeros(e - s, dtype=bool)
        squared = np.zeros(e - s)  # [output units^2]
        for i, col in self._columns.items():
            moved = col[1:] != col[:-1]
            if i in reader.axes:
                moves_path |= moved
                squared += (col[1:] - col[:-1]) ** 2
            else:
                moves_other |= moved
        moves_path &= ~(squared < MIN_MOVE ** 2)  # as _Reader.travel: LinuxCNC drops it
        travel, motion = run.has_axis[s:e], self.motion[1:]
        g0, g1 = travel & (motion == 0.0), travel & (motion == 1.0)
        stop = ~run.ok[s:e] | (travel & ~(g0 | g1)) | (g1 & moves_path & (moves_other | (self.feed[1:] <= 0)))
        self.stops = np.append(s + np.flatnonzero(stop), e)
        self.pieces = s + np.flatnonzero(g1 & moves_path & ~stop)
        self.breaks = s + np.flatnonzero((g0 & (moves_path | moves_other)) | (g1 & moves_other & ~moves_path))

    def column(self, i: int, rows: np.ndarray):
        """Axis ``i`` before the rows ``rows`` (relative to ``s``) [output units]: an array,
        or its start value where the run never moves it (no array of the whole run per
        call: a stretch between two stop rows costs its own rows only)."""
        col = self._columns.get(i)
        return col[rows] if col is not None else self.start[i]

    def position(self, j: int) -> list:
        """X..W before row ``s + j`` [output units]."""
        pos = list(self.start)
        for i, col in self._columns.items():
            pos[i] = float(col[j])
        return pos

    def agrees(self, reader: "_Bulk", s: int) -> bool:
        """Whether the reader's state before row ``s`` is this one's."""
        if not self.s <= s < self.e:
            return False
        j = s - self.s
        return (reader.pos == self.position(j) and reader.feed == self.feed[j]
                and {"G0": 0.0, "G1": 1.0}.get(reader.motion, -1.0) == self.motion[j]
                and reader.lengths() == self.k and reader.scale() == self.scale)

    def next_stop(self, s: int) -> int:
        return int(self.stops[np.searchsorted(self.stops, s)])


def _forward_fill(values: np.ndarray, first: float) -> np.ndarray:
    """``first`` followed by ``values`` (shape (m,)) with each NaN replaced by the last
    number before it; shape (m + 1,)."""
    full = np.concatenate([[first], values])
    index = np.where(np.isnan(full), 0, np.arange(len(full)))
    np.maximum.accumulate(index, out=index)
    return full[index]
