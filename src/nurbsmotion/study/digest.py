"""A campaign's digest: each group's figures summarised, and its failing cases.

:func:`make_digest` takes the dataset's table (per group of interpolator, feed and plant: the
min / median / 95th percentile / max of :data:`SUMMARY_FIGURES`, and every failing case
with the command that reproduces it); :func:`write_digest` writes it as ``digest.json``
and ``digest.md``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .spec import STATUS_OK, Study

__all__ = ["SUMMARY_FIGURES", "make_digest", "write_digest", "digest_markdown"]

SUMMARY_FIGURES = ("cycle_time_ratio", "max_contour_error", "max_following_error",
                   "max_drive_ratio", "saturated_samples", "move_and_settle_ratio",
                   "end_overshoot", "corner_overshoot")
"""Figures the digest summarises per group (per-axis ones as the largest or, for
``saturated_samples``, the sum over the axes)."""

_QUANTILES = (("min", 0.0), ("median", 0.5), ("p95", 0.95), ("max", 1.0))


_PER_AXIS_FIGURES = ("max_following_error", "max_drive_ratio", "saturated_samples")


def _figure(table, name: str) -> np.ndarray:
    """Column ``name`` per row [its unit]; a per-axis figure as its largest value over
    the axes (for ``saturated_samples``, the sum)."""
    if name not in _PER_AXIS_FIGURES:
        return np.asarray(table.column(name).to_numpy(zero_copy_only=False), float)
    values = np.array([np.asarray(table.column(c).to_numpy(zero_copy_only=False), float)
                       for c in table.column_names if c.startswith(name + "_")])
    with np.errstate(all="ignore"):
        if name == "saturated_samples":
            return np.sum(np.nan_to_num(values), axis=0)
        return np.max(np.where(np.isnan(values), -np.inf, values), axis=0)


def make_digest(table, study: Study, out_dir: str | os.PathLike = ".") -> dict:
    """Per group (interpolator x feed x plant) the min / median / 95th percentile / max
    of :data:`SUMMARY_FIGURES` over its successful cases, and every failing case with
    the command that reproduces it.

    Percentiles are sample values (the smallest value with at least that share of the
    group's cases at or below it), so ``inf`` (a motion that never settled) is kept.
    """
    study_file = study.source or "STUDY.toml"
    ok = np.array([s == STATUS_OK for s in table.column("status").to_pylist()])
    keys = list(zip(table.column("interpolator").to_pylist(),
                    table.column("feed_value").to_pylist(),
                    table.column("plant").to_pylist()))
    figures = {name: _figure(table, name) for name in SUMMARY_FIGURES}
    groups = []
    for key in sorted(set(keys)):
        member = np.array([k == key for k in keys])
        sel = member & ok
        entry = {"interpolator": key[0], "feed": key[1], "feed_unit": study.feed_unit,
                 "plant": key[2], "cases": int(member.sum()), "ok": int(sel.sum()),
                 "failed": int((member & ~ok).sum()), "figures": {}}
        if sel.any():
            for name, values in figures.items():
                v = values[sel]
                entry["figures"][name] = {q: float(np.quantile(v, p, method="inverted_cdf"))
                                          for q, p in _QUANTILES}
        groups.append(entry)
    failing = []
    cols = ["case_id", "path", "feed_value", "machine", "plant", "interpolator",
            "error_type", "error_message"]
    data = {c: table.column(c).to_pylist() for c in cols}
    for i in np.flatnonzero(~ok):
        case = {c: data[c][i] for c in cols}
        case["reproduce"] = (f"nurbsmotion campaign {study_file} --out {out_dir} "
                             f"--case {case['case_id']}")
        failing.append(case)
    return {"study": study.name, "cases": int(len(ok)), "ok": int(ok.sum()),
            "failed": int((~ok).sum()), "groups": groups, "failing_cases": failing}


digest = make_digest
"""The old name of :func:`make_digest`, kept for ``from nurbsmotion.study.digest import
digest`` and ``nurbsmotion.campaign.digest`` (not in ``__all__``): on the package
:mod:`nurbsmotion.study` a function ``digest`` was hidden by this module's own name."""


def write_digest(data: dict, out_dir: str | os.PathLike) -> tuple[Path, Path]:
    """Write ``digest.json`` and ``digest.md`` into ``out_dir`` (through temporary names)."""
    from ..report import write_json

    out = Path(out_dir)
    tmp = out / ".digest.json.tmp"
    write_json(data, tmp)
    os.replace(tmp, out / "digest.json")
    tmp = out / ".digest.md.tmp"
    tmp.write_text(digest_markdown(data))
    os.replace(tmp, out / "digest.md")
    return out / "digest.json", out / "digest.md"


def digest_markdown(data: dict) -> str:
    """The digest as Markdown: one table per figure, rows per group."""
    lines = [f"# Study {data['study']}: {data['cases']} cases, {data['ok']} ok, "
             f"{data['failed']} failed", ""]
    for name in SUMMARY_FIGURES:
        lines += [f"## {name}", "",
                  "| interpolator | feed | plant | ok / cases | min | median | 95th | max |",
                  "|---|---|---|---|---|---|---|---|"]
        for g in data["groups"]:
            q = g["figures"].get(name)
            cells = [f"{q[k]:.4g}" for k, _ in _QUANTILES] if q else ["–"] * 4
            lines.append(f"| {g['interpolator']} | {g['feed']:g} {g['feed_unit']} | "
                         f"{g['plant']} | {g['ok']} / {g['cases']} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Failing cases", ""]
    if not data["failing_cases"]:
        lines.append("None.")
    for c in data["failing_cases"]:
        lines.append(f"- `{c['case_id']}` {c['path']} at {c['feed_value']:g}, {c['machine']}, "
                     f"plant {c['plant']}, {c['interpolator']}: {c['error_type']}: "
                     f"{(c['error_message'] or '').splitlines()[0] if c['error_message'] else ''}"
                     f" — reproduce: `{c['reproduce']}`")
    return "\n".join(lines) + "\n"
