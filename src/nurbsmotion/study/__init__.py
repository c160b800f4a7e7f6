"""Studies: many runs (paths x feeds x machines x true plants x interpolators), in parallel,
into a Parquet dataset, with a digest; and the paper's experiment.

A study file (TOML, schema in ``docs/campaign.md``) lists the values of each factor;
:func:`study_cases` expands them into :class:`Case` objects, every combination or a seeded
sample of them (:mod:`.spec`). :func:`run_case` runs one case and returns its row: every
``summary.json`` key (per-axis values flattened to ``key_<axis>``), the case parameters,
its seed, and ``status`` (``"ok"`` or ``"error"``, with the error's type and message)
(:mod:`.case`). :func:`run_study` (:mod:`.run`) runs all unfinished cases — serially, on
local processes, or on a Dask cluster (:mod:`.execute`) — and appends the finished rows to
``OUT/rows/part-*.parquet`` (:mod:`.dataset`: a part file is written once, under a
temporary name, and never rewritten), so a campaign that stops for any reason resumes
where it was. :func:`make_digest` summarises the dataset (:mod:`.digest`).

Every random draw of a case (its random path, its random plant) comes from seeds derived
from the study's seed and the case's index, never from a worker, so the rows are the same
bit for bit however the cases are spread (only ``case_time_s`` and ``case_cpu_s``, the
case's wall and CPU time, differ).

:func:`run_experiment` (:mod:`.reproduce`) runs the paper's experiment
(``nurbsmotion reproduce``); :mod:`.run_input`
reads a run's path and feed by one rule for ``nurbsmotion run`` and a study's cases.

Names load with their module on first use (PEP 562); pyarrow, dask and tqdm are imported
only when used.
"""

from .._runtime.lazy import lazy_names

_LAZY = {
    "Study": "spec", "Case": "spec", "PlantGroup": "spec", "RandomPaths": "spec",
    "load_study": "spec", "study_cases": "spec", "find_case": "spec", "STATUS_OK": "spec",
    "STATUS_ERROR": "spec", "WORKER_DIED": "spec", "FEED_UNITS": "spec",
    "CASE_TIME_LIMIT": "spec",
    "case_trace": "case", "run_case": "case",
    "read_rows": "dataset", "CAMPAIGN_OUTPUTS": "dataset",
    "DASK_SETTINGS": "execute",
    "CampaignResult": "run", "run_study": "run",
    "SUMMARY_FIGURES": "digest", "make_digest": "digest", "write_digest": "digest",
    "digest_markdown": "digest",
    "PAPER_EXPERIMENT": "reproduce", "ExperimentResult": "reproduce",
    "run_experiment": "reproduce", "reproduce_outputs": "reproduce",
}
"""Public name -> the module of this package that holds it. ``study.digest`` and
``study.reproduce`` are the modules; their functions are :func:`make_digest` and
:func:`run_experiment` (their old names, ``digest`` and ``reproduce``, which the modules'
names hid on this package, stay importable from the modules)."""

__all__ = list(_LAZY)


__getattr__, __dir__ = lazy_names(__name__, _LAZY)
