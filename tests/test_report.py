"""Trace files: streamed in chunks, the same numbers as the trace, in CSV and Parquet."""

import csv

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion import report
from nurbsmotion.loop import run
from nurbsmotion.machine import die_bonder
from nurbsmotion.units import OutputUnits

MM = OutputUnits("mm", 1000.0, ("mm", "mm"), np.array([1000.0, 1000.0]))
"""The die-bonder's (1-um pulses) lengths in mm, written by hand."""


@pytest.fixture(scope="module")
def trace():
    return run(nm.make_die_bonder_pi(), die_bonder(), 1e6, "paper")


def read_back(path, fmt):
    if fmt == "csv":
        with open(path) as f:
            rows = list(csv.reader(f))
        return rows[0], np.array(rows[1:], dtype=float)
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    return table.column_names, np.column_stack([c.to_numpy() for c in table.columns])


@pytest.mark.parametrize("fmt", report.TRACE_FORMATS)
@pytest.mark.parametrize("every", [1, 4])
def test_streamed_trace_holds_the_trace_exactly(trace, tmp_path, monkeypatch, fmt, every):
    monkeypatch.setattr(report.trace_file, "TRACE_CHUNK_ROWS", 7)  # many chunks, a short last one
    written = []
    path = report.write_trace(trace, tmp_path / f"trace.{fmt}", fmt=fmt, every=every,
                              units=MM, progress=written.append)
    header, data = read_back(path, fmt)
    ref_header, ref = report.trace_columns(trace, MM)
    rows = report.trace_rows(trace, every)
    assert header == ref_header
    np.testing.assert_array_equal(data, ref[rows])  # bit for bit, NaN where not computed
    assert sum(written) == len(rows) and max(written) <= 7
    assert trace.finished_index in rows and len(trace.t) - 1 in rows
    estimate = report.estimate_trace_bytes(trace, fmt=fmt, every=every, units=MM)
    if fmt == "csv":  # Parquet's per-file overhead dominates so small a file
        assert estimate == pytest.approx(path.stat().st_size, rel=0.1)


def test_trace_is_not_overwritten(trace, tmp_path):
    path = report.write_trace(trace, tmp_path / "trace.csv")
    with pytest.raises(FileExistsError):
        report.write_trace(trace, path)
    with pytest.raises(ValueError, match="trace format"):
        report.write_trace(trace, tmp_path / "t.txt", fmt="txt")
    with pytest.raises(ValueError, match="trace_every"):
        report.trace_rows(trace, 0)
