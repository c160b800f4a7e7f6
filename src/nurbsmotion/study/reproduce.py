"""The paper's experiment on built-in defaults (``nurbsmotion reproduce``).

The die-bonder Pi move at F = 0.2, 0.5 and 1.0 m/s and the butterfly at 0.05, 0.1 and
0.2 m/s on the die-bonder preset, each with constant-feed Taylor interpolation (first
order, eq. 3.2: the interpolator the paper's algorithm reduces to when nothing saturates),
with the paper's saturation-aware algorithm, and with this project's look-ahead planner. Writes the analogues of the paper's
Fig. 5-7 for every path and feed, and a Markdown and a JSON table of the docs/model.md#run-figures
figures of every run.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .._runtime.io import write_output
from ..job import Job
from ..loop import Trace
from ..machine import Machine, die_bonder
from ..nurbs import builtin_path
from ..report import check_writable, markdown_table, write_json

__all__ = ["PAPER_EXPERIMENT", "ExperimentResult", "run_experiment", "reproduce_outputs"]

PAPER_EXPERIMENT = {
    "die-bonder-pi": (0.2, 0.5, 1.0),
    "butterfly": (0.05, 0.1, 0.2),
}
"""Built-in path name -> commanded feeds [m/s]."""

PAPER_INTERPOLATORS = ("taylor1", "paper", "planned")
"""Constant feed, the paper's algorithm, and this project's look-ahead planner."""


@dataclass(frozen=True)
class ExperimentResult:
    """Rows of the table (one ``summary.json`` dict per run, plus ``feed_m_s``), the
    traces by (path, feed [m/s], interpolator), and the files written."""

    rows: list
    traces: dict
    files: list


def reproduce_outputs(machine: Machine | None = None, experiment=None,
                      figures: bool = True) -> list[str]:
    """Names of every file :func:`run_experiment` writes with these arguments."""
    machine = machine or die_bonder()
    names = ["table.md", "table.json"]
    if figures:
        from ..plots import comparison_figures

        for name, feeds in (experiment or PAPER_EXPERIMENT).items():
            for feed_m_s in feeds:
                names += comparison_figures(_figure_prefix(name, feed_m_s),
                                            machine.axis_names)
    return names


def _figure_prefix(name: str, feed_m_s: float) -> str:
    return f"{name}_{feed_m_s:g}ms"


def run_experiment(out_dir, *, machine: Machine | None = None, experiment=None,
                   interpolators=PAPER_INTERPOLATORS, overwrite: bool = False,
                   figures: bool = True,
                   progress: Callable[[int, int, str], None] | None = None
                   ) -> ExperimentResult:
    """Run the experiment (``nurbsmotion reproduce``) and write ``table.md``,
    ``table.json`` and the figures.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created). Existing outputs are not overwritten unless
        ``overwrite``.
    machine : Machine, optional
        The die-bonder preset by default.
    experiment : dict, optional
        Path name -> feeds [m/s]; :data:`PAPER_EXPERIMENT` by default.
    interpolators : sequence of str
        Interpolators to compare.
    overwrite : bool
        Replace existing outputs.
    figures : bool
        Write the figures of every path and feed.
    progress : callable, optional
        ``progress(done, total, label)`` after each run and each set of figures.
    """
    machine = machine or die_bonder()
    experiment = experiment or PAPER_EXPERIMENT
    out = Path(out_dir)
    check_writable([out / f for f in reproduce_outputs(machine, experiment, figures)],
                   overwrite)
    out.mkdir(parents=True, exist_ok=True)
    total = sum(len(f) for f in experiment.values()) * (len(interpolators) + bool(figures))
    done = 0

    def step(label: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total, label)

    rows, traces, files = [], {}, []
    jobs, labels = [], []  # the figures of each path and feed
    for name, feeds in experiment.items():
        path = Job(builtin_path(name), machine, None, name=name)  # the feed comes per feed
        path.pulses  # converted once, so its geometry serves every feed and interpolator
        for feed_m_s in feeds:
            feed = feed_m_s * path.scale.pulses_per("m")
            job = path.with_options(feed=(feed, "pulse"))
            job = job.with_options(time_optimal_bound=job.bound())  # one per path and feed
            group: dict[str, Trace] = {}
            for method in interpolators:
                result = job.with_options(interpolator=method).run()
                group[method] = traces[(name, feed_m_s, method)] = result.trace
                rows.append({"path": name, "feed_m_s": feed_m_s, **result.summary()})
                step(f"{name} {feed_m_s:g} m/s {method}")
            if figures:  # drawn once every run is done, in worker processes
                jobs.append((group, out, _figure_prefix(name, feed_m_s),
                             {"feed": feed, "length_unit": job.scale.output.unit}))
                labels.append(f"{name} {feed_m_s:g} m/s figures")
    if jobs:
        from ..plots import plot_comparisons

        files += plot_comparisons(jobs, done=lambda index: step(labels[index]))
    files.append(write_json(rows, out / "table.json", overwrite=overwrite))
    table = markdown_table(rows)
    files.append(write_output(out / "table.md", lambda h: h.write(table), overwrite=overwrite))
    return ExperimentResult(rows, traces, files)


reproduce = run_experiment
"""The old name of :func:`run_experiment`, kept for ``from nurbsmotion.study.reproduce
import reproduce`` and ``nurbsmotion.experiments.reproduce`` (not in ``__all__``): on the
package :mod:`nurbsmotion.study` a function ``reproduce`` was hidden by this module's own
name."""
