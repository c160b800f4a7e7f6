"""A campaign's dataset on disk: Parquet part files, the lock and the outputs.

Rows are appended as part files ``OUT/rows/part-*.parquet`` (:func:`_write_part`: written
once, under a temporary name, and never rewritten) with one schema (:func:`_schema`);
:func:`read_rows` reads them back as one table. ``OUT/.lock`` (:func:`_locked`) keeps a
second campaign out of a folder being written; :func:`_remove_outputs` removes what a
campaign wrote (``--overwrite``). pyarrow is imported only when used.
"""

from __future__ import annotations

import os
import time
import uuid
from contextlib import contextmanager
from pathlib import Path

from .spec import Study, _machine

__all__ = ["read_rows", "CAMPAIGN_OUTPUTS"]


def _schema(study: Study):
    """The dataset's columns (the same in every part file)."""
    import pyarrow as pa

    from ..report import SUMMARY_KEYS

    axes = []
    for m in study.machines:
        axes += [a for a in _machine(m, study.base_dir).axis_names if a not in axes]
    per_axis = {"max_following_error", "rms_following_error", "max_drive_ratio",
                "saturated_samples", "cornered_samples"}
    int_keys = {"steps", "saturated_samples", "limited_samples", "cornered_samples"}
    bool_keys = {"settled", "success"}
    text_keys = {"interpolator", "machine", "path", "message"}
    fields = [("case_id", pa.string()), ("case_index", pa.int64()), ("seed", pa.int64()),
              ("status", pa.string()), ("error_type", pa.string()),
              ("error_message", pa.string()), ("attempts", pa.int64()),
              ("path", pa.string()), ("path_family", pa.string()),
              ("path_seed", pa.int64()), ("n_axes", pa.int64()), ("feed_value", pa.float64()),
              ("feed_unit", pa.string()), ("machine", pa.string()), ("plant", pa.string()),
              ("interpolator", pa.string())]
    fields += [(f"{s}_scale_{a}", pa.float64()) for a in axes for s in ("tau", "Kc")]
    taken = {f for f, _ in fields}
    for key in SUMMARY_KEYS:
        typ = pa.int64() if key in int_keys else pa.bool_() if key in bool_keys else \
            pa.string() if key in text_keys else pa.float64()
        if key in per_axis:
            fields += [(f"{key}_{a}", typ) for a in axes]
        elif key not in taken:
            fields.append((key, typ))
    fields += [("case_time_s", pa.float64()), ("case_cpu_s", pa.float64())]
    return pa.schema(fields)


def _write_part(rows: list[dict], rows_dir: Path, schema) -> Path:
    """Write ``rows`` as a new part file (temporary name, then renamed: a part file is
    either complete or absent)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist(rows, schema=schema)
    name = f"part-{time.strftime('%Y%m%dT%H%M%S')}-{uuid.uuid4().hex[:8]}.parquet"
    tmp = rows_dir / f".{name}.tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, rows_dir / name)
    return rows_dir / name


def read_rows(out_dir: str | os.PathLike):
    """All finished rows of a campaign as a pyarrow Table, sorted by case index (the
    columns of every part file: a column added by a newer version is null in the rows of
    parts written before it)."""
    import pyarrow as pa
    import pyarrow.dataset as ds
    import pyarrow.parquet as pq

    rows_dir = Path(out_dir) / "rows"
    files = sorted(str(p) for p in rows_dir.glob("part-*.parquet"))
    if not files:
        return None
    schema = pa.unify_schemas([pq.read_schema(f) for f in files])
    table = ds.dataset(files, schema=schema, format="parquet").to_table()
    return table.sort_by("case_index")

_LOCK = ".lock"

CAMPAIGN_OUTPUTS = ("study.toml", "digest.md", "digest.json")
"""Files a campaign writes at the top of its folder (besides ``rows/`` and the case
folders ``cNNNNNNN/`` of ``--case``)."""


def _remove_outputs(out: Path) -> None:
    """Remove what a campaign wrote into ``out`` (``--overwrite``): its files, its part
    files and the run outputs of its case folders; a folder is removed once empty. A
    file the campaign does not write is left where it is."""
    from ..plots import TRACE_FIGURES

    for name in CAMPAIGN_OUTPUTS + (".digest.json.tmp", ".digest.md.tmp"):
        if (out / name).is_file():
            (out / name).unlink()
    rows = out / "rows"
    if rows.is_dir():
        for p in [*rows.glob("part-*.parquet"), *rows.glob(".part-*.tmp")]:
            p.unlink()
    cases = [p for p in out.glob("c*") if p.is_dir() and len(p.name) == 8
             and p.name[1:].isdigit()]
    for folder in cases:
        for name in ("trace.csv", "summary.json", *TRACE_FIGURES):
            if (folder / name).is_file():
                (folder / name).unlink()
    for folder in [rows, *cases]:
        try:
            folder.rmdir()
        except OSError:  # holds a file of the user's (or is absent)
            pass



@contextmanager
def _locked(out: Path):
    """Hold ``OUT/.lock`` (an advisory ``flock``, POSIX) while a campaign writes into
    ``out``: a second campaign into the same folder is refused instead of running the same
    cases twice. The lock goes with the process that holds it, however it ends."""
    from ..errors import OutputExistsError

    out.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    with open(out / _LOCK, "a") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise OutputExistsError(f"{out} is being written by another running "
                                    "campaign") from None
        yield


def _finished_ids(out: Path) -> set:
    table = read_rows(out)
    return set() if table is None else set(table.column("case_id").to_pylist())


class _RowWriter:
    def __init__(self, rows_dir, schema, flush_rows, flush_seconds):
        self.rows_dir, self.schema = rows_dir, schema
        self.flush_rows, self.flush_seconds = flush_rows, flush_seconds
        self.pending: list[dict] = []
        self.written = 0
        self.last = time.monotonic()

    def add(self, row: dict) -> None:
        self.pending.append(row)
        if (len(self.pending) >= self.flush_rows
                or time.monotonic() - self.last >= self.flush_seconds):
            self.flush()

    def flush(self) -> None:
        if self.pending:
            _write_part(self.pending, self.rows_dir, self.schema)
            self.written += len(self.pending)
            self.pending = []
        self.last = time.monotonic()
