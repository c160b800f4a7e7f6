"""A campaign: a study's unfinished cases run into its folder, then its digest.

:func:`run_study` takes the folder's lock, runs the cases not yet in the dataset (on the
executor :func:`nurbsmotion.study.execute._execute` picks), appends their rows as they
finish, and writes the digest; a campaign that stops for any reason resumes where it was.
tqdm draws the progress bar when installed.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .._runtime.io import write_output
from ..errors import PathFileError
from .case import run_case
from .dataset import _LOCK, _RowWriter, _finished_ids, _locked, _remove_outputs, _schema, read_rows
from .digest import make_digest, write_digest
from .execute import _execute
from .spec import STATUS_OK, Case, Study, study_cases

__all__ = ["CampaignResult", "run_study"]


@dataclass
class CampaignResult:
    """What :func:`run_study` did."""

    out_dir: Path
    n_cases: int
    computed: int
    skipped: int
    failed: int
    wall_time_s: float
    digest: dict = field(default_factory=dict)


def run_study(study: Study, out_dir: str | os.PathLike, *, workers: int | None = None,
              scheduler: Any = None, resume: bool = False, overwrite: bool = False,
              progress: bool = True, flush_rows: int = 64, flush_seconds: float = 10.0,
              cases: list[Case] | None = None) -> CampaignResult:
    """Run a study's unfinished cases and write the dataset and digest into ``out_dir``.

    Parameters
    ----------
    study : Study
    out_dir : path
        Holds ``study.toml`` (the study run), ``rows/part-*.parquet`` and the digest
        ``digest.md`` / ``digest.json``.
    workers : int, optional
        Local worker processes (all cores by default; 1 runs in this process).
    scheduler : str or dask.distributed.Client, optional
        A Dask scheduler's address (or a client): run the cases on that cluster; results
        come back to this process, which alone writes the dataset.
    resume : bool
        Keep the finished rows in ``out_dir`` and run only the other cases.
    overwrite : bool
        First remove what an earlier campaign wrote into ``out_dir``
        (:data:`CAMPAIGN_OUTPUTS`, the part files, the case folders' run outputs); no
        other file there is touched.
    flush_rows, flush_seconds : int, float
        A part file is written every ``flush_rows`` finished rows or ``flush_seconds``.
    cases : list of Case, optional
        The cases (``study_cases(study)`` by default).

    Raises
    ------
    OutputExistsError
        ``out_dir`` holds files, and neither ``resume`` nor ``overwrite`` was asked for.
    PathFileError
        On ``resume``, if ``out_dir`` holds another study.
    KeyboardInterrupt
        After writing every finished row, so that ``resume`` goes on from there.
    """
    from ..errors import OutputExistsError

    t0 = time.perf_counter()
    out = Path(out_dir)
    rows_dir = out / "rows"
    study_copy = out / "study.toml"
    held = out.exists() and any(p.name != _LOCK for p in out.iterdir())
    if held and not (overwrite or resume):
        raise OutputExistsError(f"{out} exists; resume with --resume, or pass --overwrite")
    text = Path(study.source).read_text() if study.source else ""
    if resume and not overwrite and study_copy.exists() and study_copy.read_text() != text:
        raise PathFileError(f"{out} holds the results of another study (its study.toml "
                            "differs); choose another output folder", study.source)
    with _locked(out):
        if held and overwrite:
            _remove_outputs(out)
        rows_dir.mkdir(parents=True, exist_ok=True)
        for stale in rows_dir.glob(".part-*.tmp"):  # a part being written when killed
            stale.unlink()
        write_output(study_copy, lambda h: h.write(text), overwrite=True)
        all_cases = study_cases(study) if cases is None else cases
        done = _finished_ids(out)
        todo = [c for c in all_cases if c.case_id not in done]
        writer = _RowWriter(rows_dir, _schema(study), flush_rows, flush_seconds)
        bar = _progress(len(todo), progress)
        try:
            for row in _execute(todo, workers, scheduler, run_case):
                writer.add(row)
                bar(row)
        finally:
            writer.flush()
            bar(None)
        table = read_rows(out)
        result_digest = make_digest(table, study, out) if table is not None else {}
        if table is not None:
            write_digest(result_digest, out)
    failed = 0 if table is None else int(
        sum(s != STATUS_OK for s in table.column("status").to_pylist()))
    return CampaignResult(out, len(all_cases), writer.written, len(all_cases) - len(todo),
                          failed, time.perf_counter() - t0, result_digest)


def _progress(total: int, enabled: bool) -> Callable:
    """A callback per finished row (``None`` closes the bar): tqdm when importable, silent
    when stderr is not a terminal."""
    if not enabled or total == 0:
        return lambda row: None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        return lambda row: None
    bar = tqdm(total=total, unit="case", file=sys.stderr, dynamic_ncols=True, disable=None)
    failed = [0]

    def update(row):
        if row is None:
            bar.close()
            return
        failed[0] += row["status"] != STATUS_OK
        bar.set_postfix(failed=failed[0], refresh=False)
        bar.update(1)

    return update
