"""The trace file of a run, ``trace.csv`` or ``trace.parquet`` (columns: see
:mod:`nurbsmotion.report`): :class:`TraceWriter` writes a streamed run's blocks as they come,
:func:`write_trace` a whole :class:`~nurbsmotion.loop.Trace`, and
:func:`estimate_trace_bytes` tells its size before any work.

The trace is written in chunks of :data:`TRACE_CHUNK_ROWS` rows by pyarrow (imported
when a trace is written), so neither its text nor a copy of all its columns is ever held
in memory.
"""

from __future__ import annotations

import io
import os
import sys
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, NamedTuple

import numpy as np

from .._runtime.io import atomic_output
from ..errors import InvalidArgumentError
from ..limits import TRACE_FORMATS

if TYPE_CHECKING:
    from ..units import OutputUnits

__all__ = ["TRACE_FORMATS", "TRACE_FILES", "TRACE_CHUNK_ROWS", "trace_columns", "TraceWriter",
           "write_trace", "write_trace_csv", "estimate_trace_bytes", "trace_rows"]

TRACE_FILES = {fmt: f"trace.{fmt}" for fmt in TRACE_FORMATS}
"""Trace format -> file name."""

TRACE_CHUNK_ROWS = 4_096
"""Rows converted and written at a time (a few chunks are in flight: about 1 MB each
for two axes)."""



@dataclass(frozen=True)
class _Column:
    """One trace column: its name, how to read rows ``idx`` of it from a trace block
    (a :class:`~nurbsmotion.loop.Trace` or a :class:`_Block`), its unit and what it is
    (docs/formats.md; the CSV's metadata file)."""

    name: str
    read: Callable[[object, np.ndarray], np.ndarray]
    unit: str
    description: str


class _Block(NamedTuple):
    """Rows of a streamed run under the :class:`~nurbsmotion.loop.Trace` names."""

    t: np.ndarray
    u: np.ndarray
    position_command: np.ndarray
    position: np.ndarray
    drive: np.ndarray
    drive_applied: np.ndarray
    speed_bounds: np.ndarray | None
    position_measured: np.ndarray | None = None


def _columns(machine, with_bounds: bool, units: OutputUnits | None,
             with_measured: bool = False) -> list[_Column]:
    """The trace file's columns, in order (see the module docstring); ``a_meas`` (and
    ``a_meas_L``) only for a run on a true plant whose reading is not its position."""
    cols = [_Column("t", lambda b, i: b.t[i], "s", "sample time"),
            _Column("u", lambda b, i: b.u[i], "1", "curve parameter of the setpoint")]
    Ke = machine.Ke
    for j, a in enumerate(machine.axis_names):
        cols += [
            _Column(f"{a}_cmd", lambda b, i, j=j: b.position_command[i, j], "pulse",
                    f"setpoint of axis {a}"),
            _Column(f"{a}_act", lambda b, i, j=j: b.position[i, j], "pulse",
                    f"actual position of axis {a}"),
            _Column(f"{a}_drive", lambda b, i, j=j: b.drive[i, j], "V",
                    f"drive before clipping of axis {a}"),
            _Column(f"{a}_drive_applied", lambda b, i, j=j: b.drive_applied[i, j], "V",
                    f"drive after clipping to +-Umax of axis {a}")]
        if with_bounds:
            cols += [_Column(f"{a}_speed_{side}",
                             lambda b, i, j=j, s=s: b.speed_bounds[i, j, s] * Ke[j], "pulse/s",
                             f"eq. 3.6 {word} speed bound of axis {a}")
                     for s, side, word in ((0, "min", "lower"), (1, "max", "upper"))]
    if with_measured:  # after the existing columns: their places are a contract
        cols += [_Column(f"{a}_meas", lambda b, i, j=j: b.position_measured[i, j], "pulse",
                         f"position the controller read of axis {a}")
                 for j, a in enumerate(machine.axis_names)]
    if units is None:
        return cols
    # each axis in its own unit: a rotary axis in degrees, the others in the report unit
    axis_units, axis_factor = units.axis_units, units.axis_factor
    for j, a in enumerate(machine.axis_names):
        L, k = axis_units[j], float(axis_factor[j])
        cols += [_Column(f"{a}_cmd_{L}", lambda b, i, j=j, k=k: b.position_command[i, j] * k,
                         L, f"setpoint of axis {a}"),
                 _Column(f"{a}_act_{L}", lambda b, i, j=j, k=k: b.position[i, j] * k,
                         L, f"actual position of axis {a}")]
        if with_bounds:
            cols += [_Column(f"{a}_speed_{side}_{L}_per_s",
                             lambda b, i, j=j, k=k, s=s: b.speed_bounds[i, j, s] * Ke[j] * k,
                             f"{L}/s", f"eq. 3.6 {word} speed bound of axis {a}")
                     for s, side, word in ((0, "min", "lower"), (1, "max", "upper"))]
    if with_measured:
        for j, a in enumerate(machine.axis_names):
            L, k = axis_units[j], float(axis_factor[j])
            cols.append(_Column(f"{a}_meas_{L}",
                                lambda b, i, j=j, k=k: b.position_measured[i, j] * k,
                                L, f"position the controller read of axis {a}"))
    return cols


def _kept(first: int, n: int, every: int, finished: int, last: bool) -> np.ndarray:
    """Rows (0 .. n-1) of samples ``first .. first+n-1`` a trace file keeps: every
    ``every``-th sample, the one where the end is reached and, in the run's last block,
    the last one."""
    if every < 1:
        raise InvalidArgumentError(f"trace_every must be >= 1, got {every}")
    if every == 1:
        return np.arange(n)
    keep = np.arange((-first) % every, n, every)
    extra = [finished - first] if 0 <= finished - first < n else []
    if last and n:
        extra.append(n - 1)
    return np.union1d(keep, extra).astype(np.int64)


def trace_rows(trace, every: int = 1) -> np.ndarray:
    """Sample indices a trace file keeps: every ``every``-th, plus the sample where the
    end is reached and the last one, shape (m,)."""
    return _kept(0, len(trace.t), every, trace.finished_index, True)


def trace_columns(trace, units: OutputUnits | None = None) -> tuple[list[str], np.ndarray]:
    """Header and data of the trace file, shape (n_samples, n_columns) (small traces; the
    writers stream instead); with ``units``, the lengths also in its axes' units."""
    cols = _columns(trace.machine, trace.speed_bounds is not None, units,
                    trace.position_measured is not None)
    idx = np.arange(len(trace.t))
    return [c.name for c in cols], np.column_stack([c.read(trace, idx) for c in cols])


def _chunks(rows: np.ndarray):
    """Row selections of :data:`TRACE_CHUNK_ROWS` rows: slices where ``rows`` is every
    row (views, no copy), index arrays otherwise."""
    every_row = len(rows) == 0 or (rows[-1] - rows[0] == len(rows) - 1)
    for start in range(0, len(rows), TRACE_CHUNK_ROWS):
        if every_row:
            yield slice(int(rows[start]), int(rows[min(start + TRACE_CHUNK_ROWS,
                                                          len(rows)) - 1]) + 1)
        else:
            yield rows[start:start + TRACE_CHUNK_ROWS]


def _chunk_table(cols, block, idx):
    import pyarrow as pa

    return pa.table({c.name: np.ascontiguousarray(c.read(block, idx), dtype=float)
                     for c in cols})


def _csv_bytes(cols, block, idx, handle=None) -> bytes | None:
    """CSV text of rows ``idx`` of ``block``, or None once written to ``handle``."""
    import pyarrow.csv as pacsv

    buffer = io.BytesIO() if handle is None else handle
    pacsv.write_csv(_chunk_table(cols, block, idx), buffer,
                    write_options=pacsv.WriteOptions(include_header=False,
                                                     quoting_style="none"))
    return buffer.getvalue() if handle is None else None


def _rows_in(idx) -> int:
    return idx.stop - idx.start if isinstance(idx, slice) else len(idx)


class _CsvChunks:
    """CSV text of the chunks, formatted on a few threads (pyarrow releases the GIL)
    and written in order; at most ``workers + 1`` chunks are held at a time."""

    def __init__(self, handle, cols, progress, workers: int):
        from concurrent.futures import ThreadPoolExecutor

        # pyarrow quotes header names; the header is written here, unquoted, as csv
        # readers and the contract expect.
        handle.write((",".join(c.name for c in cols) + "\n").encode())
        self.handle, self.cols, self.progress = handle, cols, progress
        self.workers = workers
        self.pool = ThreadPoolExecutor(workers) if workers else None
        self.pending: deque = deque()

    def write(self, block, rows: np.ndarray) -> None:
        for idx in _chunks(rows):
            if self.pool is None:  # straight to the file: no copy of the text is held
                _csv_bytes(self.cols, block, idx, self.handle)
                if self.progress is not None:
                    self.progress(_rows_in(idx))
                continue
            self.pending.append((_rows_in(idx),
                                 self.pool.submit(_csv_bytes, self.cols, block, idx)))
            self._drain(self.workers)

    def _drain(self, limit: int) -> None:
        while len(self.pending) > limit:
            n, future = self.pending.popleft()
            self.handle.write(future.result())
            if self.progress is not None:
                self.progress(n)

    def close(self, completed: bool) -> None:
        try:
            if completed:
                self._drain(0)
        finally:
            if self.pool is not None:
                self.pool.shutdown(cancel_futures=True)


class _ParquetChunks:
    """Parquet row groups of the chunks: plain byte-stream-split doubles with zstd (float
    columns gain nothing from dictionaries, which cost most of the time)."""

    def __init__(self, handle, cols, progress, workers: int):
        self.handle, self.cols, self.progress = handle, cols, progress
        self.writer = None

    def write(self, block, rows: np.ndarray) -> None:
        import pyarrow.parquet as pq

        for idx in _chunks(rows):
            table = _chunk_table(self.cols, block, idx)
            if self.writer is None:
                self.writer = pq.ParquetWriter(self.handle, table.schema,
                                               use_dictionary=False, compression="zstd",
                                               column_encoding="BYTE_STREAM_SPLIT")
            self.writer.write_table(table)
            if self.progress is not None:
                self.progress(_rows_in(idx))

    def close(self, completed: bool) -> None:
        if self.writer is not None:
            self.writer.close()


class TraceWriter:
    """The trace file, written as the rows come, atomically: a temporary file in the
    target's folder, renamed to ``path`` when the ``with`` block ends normally (removed
    when it raises).

    Parameters
    ----------
    path : path-like
        Target file (``trace.csv`` or ``trace.parquet``).
    machine : Machine
        The run's machine (axis names, Ke).
    fmt : {"csv", "parquet"}
        CSV (shortest text that reads back to the same double) or Parquet.
    every : int
        Keep one row in ``every`` (see :func:`trace_rows`).
    units : OutputUnits, optional
        The run's units on the way out (:attr:`nurbsmotion.job.RunResult.output_units`):
        the added length columns, each axis in its unit (``mm``, ``in``, ``deg``); none
        without it.
    overwrite : bool
        Replace an existing file.
    progress : callable, optional
        Called with the number of rows written after each chunk.
    threads : int, optional
        Threads formatting CSV chunks; by default two (one where fewer cores); 0 formats
        them in the calling thread (a sink that already runs beside the loop).
    metadata : bool
        Also write a CSV file's CSV-on-the-Web metadata beside it,
        ``trace.csv-metadata.json``: each column's unit and meaning
        (:func:`~nurbsmotion.report.export.save_csv_metadata`), once the file is complete.

    Use as a context manager; :meth:`add` is a sink of
    :func:`nurbsmotion.loop.simulate_streamed`.
    """

    def __init__(self, path, machine, *, fmt: str = "csv", every: int = 1,
                 units: OutputUnits | None = None, overwrite: bool = False,
                 progress: Callable[[int], None] | None = None, threads: int | None = None,
                 metadata: bool = False):
        if fmt not in TRACE_FORMATS:
            raise InvalidArgumentError(f"trace format must be one of {TRACE_FORMATS}, got {fmt!r}")
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise InvalidArgumentError(f"trace_every must be an integer >= 1, got {every!r}")
        self.path, self.machine, self.fmt, self.every = Path(path), machine, fmt, every
        self.units = units
        self.overwrite, self.progress = overwrite, progress
        if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int)
                                    or threads < 0):
            raise InvalidArgumentError(f"threads must be an integer >= 0, got {threads!r}")
        self.threads = max(1, min(2, os.cpu_count() or 1)) if threads is None else threads
        self.rows_written = 0
        self.metadata = metadata and fmt == "csv"
        self._cols = None  # the columns, known from the first block
        self._first = None  # (columns, block, kept rows) of the first block, for the size
        self._row_bytes = 0.0
        self._output = self._handle = self._chunks = None

    def __enter__(self) -> "TraceWriter":
        self._output = atomic_output(self.path, overwrite=self.overwrite, binary=True)
        self._handle = self._output.__enter__()
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        try:
            if self._chunks is not None:
                self._chunks.close(exc_type is None)
        except BaseException:
            self._output.__exit__(*sys.exc_info())
            raise
        suppressed = bool(self._output.__exit__(exc_type, exc, tb))
        if exc_type is None and self.metadata and self._cols is not None:
            from .export import CsvColumn, save_csv_metadata

            save_csv_metadata(self.path, [CsvColumn(c.name, c.unit, c.description)
                                          for c in self._cols],
                              title=f"nurbsmotion run trace on {self.machine.name}",
                              overwrite=self.overwrite)
        return suppressed

    def bytes_per_row(self) -> float:
        """Bytes a row of the file takes, estimated from the first block's rows (0 before
        any); formatted on the first call only."""
        if self._first is not None:
            self._row_bytes, self._first = _bytes_per_row(self.fmt, *self._first), None
        return self._row_bytes

    def add(self, first: int, rows, finished: int, last: bool) -> None:
        """Write the kept ones of a block of samples ``first ..``: ``rows`` a
        :class:`nurbsmotion.loop.closed_loop.Rows`, ``finished`` the first sample at the
        path's end (-1: none yet), ``last`` whether no rows follow (a sink of
        :func:`nurbsmotion.loop.simulate_streamed`)."""
        times = (first + np.arange(len(rows.u))) * self.machine.sample_period
        self._write(_Block(times, rows.u, rows.command, rows.position, rows.drive,
                           rows.drive_applied, rows.bounds if rows.bounds.shape[0] else None,
                           rows.measured if rows.measured.shape[0] else None),
                    first, finished, last)

    def _write(self, block, first: int, finished: int, last: bool) -> None:
        """:meth:`add` of a block under the :class:`~nurbsmotion.loop.Trace` names."""
        if self._handle is None:
            raise RuntimeError("a TraceWriter writes inside its with block only")
        kept = _kept(first, len(block.u), self.every, finished, last)
        if self._chunks is None:
            cols = _columns(self.machine, block.speed_bounds is not None, self.units,
                            getattr(block, "position_measured", None) is not None)
            make = _CsvChunks if self.fmt == "csv" else _ParquetChunks
            self._chunks = make(self._handle, cols, self.progress, self.threads)
            self._cols, self._first = cols, (cols, block, kept)
        self._chunks.write(block, kept)
        self.rows_written += len(kept)


def write_trace(trace, path, *, fmt: str = "csv", every: int = 1,
                units: OutputUnits | None = None, overwrite: bool = False,
                progress: Callable[[int], None] | None = None, metadata: bool = False) -> Path:
    """Write the trace file of a :class:`~nurbsmotion.loop.Trace`, streamed in chunks,
    atomically (see :class:`TraceWriter` for the parameters)."""
    with TraceWriter(path, trace.machine, fmt=fmt, every=every, units=units,
                     overwrite=overwrite, progress=progress, metadata=metadata) as writer:
        writer._write(trace, 0, trace.finished_index, True)
    return Path(path)


def write_trace_csv(trace, path: Path, *, overwrite: bool = True, metadata: bool = False) -> Path:
    """Write ``trace.csv`` with the pulse columns only (full double precision), and with
    ``metadata`` its metadata file (see :class:`TraceWriter`)."""
    return write_trace(trace, path, overwrite=overwrite, metadata=metadata)


def estimate_trace_bytes(trace, *, fmt: str = "csv", every: int = 1,
                         units: OutputUnits | None = None) -> int:
    """Size the trace file would have [byte], from 2,000 of its rows spread over the run."""
    cols = _columns(trace.machine, trace.speed_bounds is not None, units,
                    trace.position_measured is not None)
    rows = trace_rows(trace, every)
    return int(_bytes_per_row(fmt, cols, trace, rows) * len(rows))


def _bytes_per_row(fmt: str, cols, block, rows: np.ndarray) -> float:
    """Bytes a row of the file takes, from up to 2,000 of ``rows`` of ``block``."""
    if len(rows) == 0:
        return 0.0
    sample = rows[np.linspace(0, len(rows) - 1, min(len(rows), 2000)).astype(int)]
    buffer = io.BytesIO()
    chunks = (_CsvChunks if fmt == "csv" else _ParquetChunks)(buffer, cols, None, 0)
    chunks.write(block, sample)
    chunks.close(True)
    return buffer.tell() / len(sample)
