"""The campaign engine: study files, the dataset, serial = parallel = Dask, resume,
recorded errors and dead workers, and the seeded random-path sweep with invariants
recomputed from each trace."""

import math
import os
import signal
from pathlib import Path

import numpy as np
import pytest

from nurbsmotion.cli import main
from nurbsmotion.study import case as study_case
from nurbsmotion.study import dataset, execute, run as study_run
from nurbsmotion.study.dataset import read_rows
from nurbsmotion.study.execute import DASK_SETTINGS
from nurbsmotion.study.run import run_study
from nurbsmotion.study.spec import (STATUS_ERROR, STATUS_OK, WORKER_DIED, load_study,
                                    study_cases)
from nurbsmotion.errors import OutputExistsError, PathFileError
from nurbsmotion.machine import die_bonder
from nurbsmotion.paths.random_paths import FAMILIES, random_path

pa = pytest.importorskip("pyarrow")

N_SWEEP = int(os.environ.get("NURBSMOTION_CAMPAIGN_CASES", "200"))

SMALL = """
name = "small"
seed = 11
paths = ["die-bonder-pi", "broken.json"]
feeds = [1.0]
interpolators = ["taylor1", "paper"]
time_optimal_bound = false
[[random_paths]]
families = ["short_moves", "duplicated_points"]
count = 1
length = 3000
[[plants]]
name = "nominal"
[[plants]]
name = "pm20"
spread = 0.2
"""


def write_study(tmp_path, text=SMALL, name="study.toml"):
    # a path file that exists but cannot be read: its cases are recorded errors
    (tmp_path / "broken.json").write_text('{"degree": 3, "knots": [0, 1]}')
    f = tmp_path / name
    f.write_text(text)
    return f


def values(table):
    """Every column but the wall time, as Python lists (NaN made comparable)."""
    out = {}
    for c in table.column_names:
        if c not in ("case_time_s", "case_cpu_s"):
            out[c] = [("nan" if isinstance(v, float) and math.isnan(v) else v)
                      for v in table.column(c).to_pylist()]
    return out


def test_study_expands_to_the_product_and_a_seeded_sample(tmp_path):
    study = load_study(write_study(tmp_path))
    cases = study_cases(study)
    assert len(cases) == 4 * 1 * 1 * 2 * 2
    assert len({c.seed for c in cases}) == len(cases)
    assert [c.case_id for c in cases] == [f"c{i:07d}" for i in range(16)]
    sampled = study_cases(load_study(write_study(tmp_path, "sample = 5\n" + SMALL, "s.toml")))
    again = study_cases(load_study(write_study(tmp_path, "sample = 5\n" + SMALL, "t.toml")))
    assert [c.case_id for c in sampled] == [c.case_id for c in again]
    assert len(sampled) == 5 and all(c in cases for c in sampled)


@pytest.mark.parametrize("line, field", [
    ("feeds = [-1.0]", "feeds"), ("interpolators = ['fast']", "interpolator"),
    ("bogus = 1", "bogus"), ("sample = 0", "sample"),
    ("case_time_limit = -1", "case_time_limit"),
    # issue 37: a study naming a missing file ran and exited 0
    ("paths = ['die-bonder-pi', 'missing.json']", "missing.json"),
    ("paths = ['part.ngc#0']", "part.ngc#0"), ("paths = ['heart']", "heart"),
    ("machines = ['absent.toml']", "absent.toml"),
])
def test_bad_study_names_the_field(tmp_path, line, field):
    key = line.split("=")[0].strip()
    kept = [x for x in SMALL.splitlines() if x.split("=")[0].strip() != key]
    f = write_study(tmp_path, line + "\n" + "\n".join(kept))
    with pytest.raises(PathFileError, match=field):
        load_study(f)


def test_rows_errors_resume_and_no_rewrite(tmp_path):
    study = load_study(write_study(tmp_path))
    out = tmp_path / "out"
    cases = study_cases(study)
    first = run_study(study, out, workers=1, progress=False, cases=cases[:6])
    assert first.computed == 6
    parts = {p: p.read_bytes() for p in (out / "rows").glob("part-*.parquet")}
    with pytest.raises(OutputExistsError):
        run_study(study, out, workers=1, progress=False)
    second = run_study(study, out, workers=1, progress=False, resume=True)
    assert second.computed == len(cases) - 6 and second.skipped == 6
    for p, data in parts.items():  # finished rows never rewritten
        assert p.read_bytes() == data
    table = read_rows(out)
    assert table.column("case_id").to_pylist() == [c.case_id for c in cases]
    rows = table.to_pylist()
    broken = [r for r in rows if r["path"] == "broken.json"]
    assert broken and all(r["status"] == STATUS_ERROR and r["error_type"] == "PathFileError"
                          and "broken.json" in r["error_message"] for r in broken)
    # A repeated control point thrice: C'(u) = 0, refused today (recorded, typed).
    for r in rows:
        if r["path_family"] == "duplicated_points" and r["status"] == STATUS_ERROR:
            assert r["error_type"] == "InvalidCurveError"
    ok = [r for r in rows if r["status"] == STATUS_OK]
    assert ok and all(r["saturated_samples_x"] >= 0 and r["max_drive_ratio_y"] > 0 for r in ok)
    assert all(r["plant"] != "nominal" or r["tau_scale_x"] == 1.0 for r in ok)
    # Same plant draws for the same case seed, different across cases.
    pm = [r["tau_scale_x"] for r in ok if r["plant"] == "pm20"]
    assert len(set(pm)) == len(pm) and all(0.8 <= v <= 1.2 for v in pm)
    digest = (out / "digest.md").read_text()
    assert "Failing cases" in digest and "--case c0000" in digest
    (out / "rows" / ".part-killed.parquet.tmp").write_bytes(b"half a file")
    third = run_study(study, out, workers=1, progress=False, resume=True)
    assert third.computed == 0
    assert not list((out / "rows").glob(".part-*"))  # a part cut short by a kill is dropped


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="needs setitimer")
def test_a_runaway_case_is_stopped_and_recorded(tmp_path, monkeypatch):
    from nurbsmotion.errors import WorkLimitError

    with pytest.raises(WorkLimitError, match="case_time_limit"):
        with study_case._cpu_limit(0.2):
            while True:
                pass
    study = load_study(write_study(tmp_path, "case_time_limit = 0.2\n" + SMALL))
    case = study_cases(study)[0]
    assert case.time_limit == 0.2

    def forever(case):
        while True:
            pass

    monkeypatch.setattr(study_case, "case_trace", forever)
    row = study_case.run_case(case)
    assert row["status"] == STATUS_ERROR and row["error_type"] == "WorkLimitError"
    assert 0.1 <= row["case_cpu_s"] < 5


def test_a_folder_in_use_is_refused(tmp_path):
    study = load_study(write_study(tmp_path))
    out = tmp_path / "out"
    with dataset._locked(out):
        with pytest.raises(OutputExistsError, match="another running campaign"):
            run_study(study, out, workers=1, progress=False, resume=True)
        with pytest.raises(OutputExistsError, match="another running campaign"):
            run_study(study, out, workers=1, progress=False, overwrite=True)


def _plan(cases, n_workers, case_cpu, table_cpu):
    """The cases each of ``n_workers`` runs when fed by the planner, simulated in CPU
    time: a case takes ``case_cpu`` [s] (ten times that on the last path, so that the
    end is uneven), plus ``table_cpu`` on a worker that has not run its path before.
    Returns the cases per worker and when each worker ran out of work."""
    import heapq

    planner = execute._Planner(cases)
    slots = [execute._Slot() for _ in range(n_workers)]
    slow = study_case._path_key(cases[-1])
    built = [set() for _ in slots]
    ran = [[] for _ in slots]
    end = [0.0] * n_workers
    events = [(0.0, k) for k in range(n_workers)]
    while events:
        t, k = heapq.heappop(events)
        if not slots[k].sent and not planner.next_chunk(slots[k], slots):
            end[k] = t
            continue
        case = slots[k].sent.popleft()
        key = study_case._path_key(case)
        cpu = case_cpu * (10 if key == slow else 1)
        cpu += table_cpu if key not in built[k] else 0.0
        built[k].add(key)
        planner.record(case, {"case_cpu_s": cpu})
        ran[k].append(case)
        heapq.heappush(events, (t + cpu, k))
    return ran, end


def test_workers_keep_a_path_and_finish_together(tmp_path):
    study = load_study(write_study(tmp_path, SWEEP_BATCHES))
    cases = study_cases(study)
    n_paths = len({study_case._path_key(c) for c in cases})

    def splits(ran):  # paths run by more than one worker, counted once per extra worker
        return sum(len({study_case._path_key(c) for c in r}) for r in ran) - n_paths

    for n_workers in (2, 3):
        for case_cpu, table_cpu in ((0.1, 0.0), (0.1, 0.5), (0.01, 1.0)):
            ran, end = _plan(cases, n_workers, case_cpu, table_cpu)
            assert sorted(c.index for r in ran for c in r) == [c.index for c in cases]
            if table_cpu > 20 * case_cpu:  # never worth building a path's tables twice
                assert splits(ran) == 0
            else:  # the slow last path is shared out, and the workers end together
                assert 1 <= splits(ran) <= 2 * n_workers
                assert max(end) - min(end) <= table_cpu + 2 * 10 * case_cpu + 1e-9


SWEEP_BATCHES = """
feeds = [0.2, 0.5, 1.0]
interpolators = ["paper", "planned"]
[[random_paths]]
families = "all"
count = 2
[[plants]]
name = "nominal"
[[plants]]
name = "pm20"
spread = 0.2
"""


_ORPHAN_SCRIPT = """
import os, sys, time
from nurbsmotion.study import execute, spec
def wait(case):
    os.write(1, f"{os.getpid()}\\n".encode())  # one write: print() makes two, which interleave
    time.sleep(120)
cases = spec.study_cases(spec.load_study(sys.argv[1]))[:4]
for row in execute._execute_pool(cases, 2, wait):
    pass
"""


@pytest.mark.skipif(os.name != "posix", reason="needs fork and SIGKILL")
@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGINT])
def test_workers_end_with_a_killed_or_interrupted_campaign(tmp_path, how):
    """Killed, the campaign cannot stop its workers: they notice and exit; interrupted
    (Ctrl-C), it stops them at once rather than waiting for the cases in flight."""
    import subprocess
    import sys
    import time

    script = tmp_path / "campaign.py"
    script.write_text(_ORPHAN_SCRIPT)
    stderr = tmp_path / "stderr.txt"
    with stderr.open("w") as err:
        proc = subprocess.Popen([sys.executable, str(script), str(write_study(tmp_path))],
                                stdout=subprocess.PIPE, stderr=err, text=True,
                                env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)))
    workers: set = set()
    for _ in range(10):  # the two workers' pids
        line = proc.stdout.readline()
        if not line:  # the campaign failed: say why
            pytest.fail(f"the campaign ended (exit {proc.wait(timeout=30)}) before both "
                        f"workers started; its stderr:\n{stderr.read_text()[-3000:]}")
        if line.strip():
            workers.add(int(line))
        if len(workers) == 2:
            break
    assert len(workers) == 2
    proc.send_signal(how)
    proc.wait(timeout=30)

    def alive(pid):
        try:
            return Path(f"/proc/{pid}/stat").read_text().split()[2] not in "ZX"
        except OSError:
            return False

    deadline = time.monotonic() + 10
    while any(map(alive, workers)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not any(map(alive, workers))


def test_a_case_reruns_with_its_run_output(tmp_path):
    f = write_study(tmp_path)
    out = tmp_path / "out"
    study = load_study(f)
    run_study(study, out, workers=1, progress=False, cases=study_cases(study)[:2])
    row = read_rows(out).to_pylist()[1]
    assert main(["campaign", str(f), "--out", str(out), "--case", row["case_id"],
                 "--no-figures"]) == 0
    import json

    summary = json.loads((out / row["case_id"] / "summary.json").read_text())
    assert summary["max_contour_error"] == row["max_contour_error"]
    assert summary["saturated_samples"]["x"] == row["saturated_samples_x"]
    trace = out / row["case_id"] / "trace.csv"
    # its columns' units beside it, as `run` writes them: the header's names, in order
    meta = json.loads((out / row["case_id"] / "trace.csv-metadata.json").read_text())
    header = trace.read_text().splitlines()[0].split(",")
    assert [c["name"] for c in meta["tableSchema"]["columns"]] == header


def test_ctrl_c_leaves_a_resumable_dataset(tmp_path, monkeypatch):
    study = load_study(write_study(tmp_path))
    out = tmp_path / "out"
    real = study_case.run_case
    calls = []

    def interrupted(case):
        calls.append(case)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(case)

    monkeypatch.setattr(study_run, "run_case", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_study(study, out, workers=1, progress=False)
    assert len(read_rows(out)) == 3
    monkeypatch.setattr(study_run, "run_case", real)
    done = run_study(study, out, workers=1, progress=False, resume=True)
    assert done.computed == len(study_cases(study)) - 3


def _suicidal_trace(case):
    """Kills its own process for one case, runs the others normally."""
    if case.index == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    return _REAL_CASE_TRACE(case)


_REAL_CASE_TRACE = study_case.case_trace


@pytest.mark.skipif(os.name != "posix", reason="needs fork and SIGKILL")
def test_a_dying_worker_is_retried_once_then_recorded(tmp_path, monkeypatch):
    import multiprocessing

    if multiprocessing.get_start_method() != "fork":
        pytest.skip("the patched case needs forked workers")
    study = load_study(write_study(tmp_path))
    monkeypatch.setattr(study_case, "case_trace", _suicidal_trace)
    out = tmp_path / "out"
    run_study(study, out, workers=2, progress=False, cases=study_cases(study)[:5])
    rows = {r["case_index"]: r for r in read_rows(out).to_pylist()}
    assert sorted(rows) == [0, 1, 2, 3, 4]
    assert rows[2]["error_type"] == WORKER_DIED and rows[2]["attempts"] == 2
    assert all(rows[i]["error_type"] != WORKER_DIED for i in (0, 1, 3, 4))


def test_serial_pool_and_dask_give_the_same_rows(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    study = load_study(write_study(tmp_path))
    cases = study_cases(study)[:6]
    tables = {}
    tables["serial"] = read_rows(run_study(study, tmp_path / "a", workers=1, progress=False,
                                           cases=cases).out_dir)
    tables["pool"] = read_rows(run_study(study, tmp_path / "b", workers=2, progress=False,
                                         cases=cases).out_dir)
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        tables["dask"] = read_rows(run_study(study, tmp_path / "c", scheduler=client,
                                             progress=False, cases=cases).out_dir)
    ref = values(tables["serial"])
    assert len(ref["case_id"]) == 6
    for name in ("pool", "dask"):
        assert values(tables[name]) == ref, name


def test_the_documented_dask_settings_are_dask_settings():
    """DASK_SETTINGS are settings Dask knows (a value of None unsets one), of the type of
    its defaults, and the configuration file docs/campaign.md gives the scheduler and
    workers."""
    dask = pytest.importorskip("dask")
    pytest.importorskip("dask.distributed")
    import re

    import yaml

    for key, value in DASK_SETTINGS.items():
        default = dask.config.get(key)  # KeyError if Dask does not know it
        assert value is None or type(default) is type(value), key
    text = (Path(__file__).parents[1] / "docs" / "campaign.md").read_text()
    documented = yaml.safe_load(re.search(r"<<'EOF'\n(.*?)\nEOF\n", text, re.S).group(1))
    for key, value in DASK_SETTINGS.items():
        assert dask.config.get(key, config=documented) == value, key


# ------------------------------------------------------------------ random-path sweep
def _three_axis_machine(tmp_path) -> Path:
    import tomli_w

    data = die_bonder().to_dict()
    z = dict(data["axes"][1], name="z")
    data["axes"] = list(data["axes"]) + [z]
    data["name"] = "die-bonder-z"
    f = tmp_path / "xyz.toml"
    f.write_text(tomli_w.dumps(data))
    return f


def check_case(case) -> dict:
    """Run a case and check, from its trace alone, what every interpolator promises:
    the drive is the PD+ law of the trace's own columns, the plant moved as the exact
    first-order ZOH of the applied drive, the parameter never goes back, the setpoint is
    on the path and ends at its end (for ``planned``, whose setpoints lead the path:
    every drive within Umax and the motion at rest on the end), the contour error never
    exceeds the distance to the setpoint."""
    row = study_case._case_columns(case)
    try:
        trace, data, tau_s, kc_s = study_case.case_trace(case)
    except Exception as exc:  # refused curves are recorded, as the engine does
        row.update(status=STATUS_ERROR, error_type=type(exc).__name__,
                   error_message=str(exc))
        return row
    m = trace.machine
    Ts, Ke, Kc, tau = m.sample_period, m.Ke, m.Kc, m.tau
    thd, tha, u_drive = trace.position_command, trace.position, trace.drive
    prev = np.vstack([tha[:1], thd[:-1]])  # before sample 0: at rest on the start
    wd = (thd - prev) / (Ke * Ts)
    wd_prev = np.vstack([np.zeros((1, m.n_axes)), wd[:-1]])
    wa = (tha - np.vstack([tha[:1], tha[:-1]])) / (Ke * Ts)
    law = (m.Kp * (thd - tha) + m.Kd * (wd - wa) + wd / Kc + tau * (wd - wd_prev) / (Ts * Kc))
    scale = 1e-9 * (1 + np.abs(law).max())
    problems = []
    if not np.allclose(u_drive, law, rtol=1e-9, atol=scale):
        problems.append("drive differs from the law")
    if not np.array_equal(trace.drive_applied, np.clip(u_drive, -m.max_drive, m.max_drive)):
        problems.append("applied drive is not the clipped drive")
    # Exact ZOH of tau*dw/dt = -w + Kc*u, dtheta/dt = Ke*w with the true plant's numbers.
    t_true, k_true = tau * tau_s, Kc * kc_s
    a = np.exp(-Ts / t_true)
    w = np.zeros(m.n_axes)
    th = tha[0].copy()
    worst = 0.0
    for k in range(len(tha) - 1):
        ua = trace.drive_applied[k]
        th = th + Ke * (t_true * (1 - a) * w + k_true * ua * (Ts - t_true * (1 - a)))
        w = a * w + (1 - a) * k_true * ua
        worst = max(worst, float(np.max(np.abs(th - tha[k + 1]))))
    if worst > 1e-6 * (1 + np.abs(tha).max()):
        problems.append(f"plant differs from the exact ZOH by {worst:g} pulse")
    if np.any(np.diff(trace.u) < 0):
        problems.append("parameter went back")
    end = trace.curve(1.0)
    f = trace.finished_index
    if case.interpolator == "planned":
        # setpoints lead the path by design: the actual motion is what must be right —
        # every drive within Umax, at rest on the end point
        if np.any(np.abs(u_drive) > m.max_drive):
            problems.append("planned drive beyond Umax")
        if np.linalg.norm(tha[-1] - end) > trace.settle_window:
            problems.append("planned motion does not end at the path's end")
    else:
        if not (np.all(trace.u[f:] == 1.0) and np.allclose(thd[f:], end, rtol=0, atol=1e-6)):
            problems.append("setpoint does not end at the path's end")
        on_path = np.linalg.norm(trace.curve(np.clip(trace.u, 0, 1)) - thd, axis=1)
        if on_path.max() > 1e-6 * (1 + np.abs(end).max()):
            problems.append(f"setpoint off the path by {on_path.max():g}")
    # the nearest point is at most as far as the path's point of the sample's parameter
    # (the setpoint's own for every interpolator but planned, whose setpoints lead the path
    # and whose parameter is that of its planned position)
    distance = np.linalg.norm(trace.curve(np.clip(trace.u, 0, 1)) - tha, axis=1)
    if data["max_contour_error"] > distance.max() + 1e-9:
        problems.append("contour error exceeds the distance to the path point of the "
                        "sample's parameter")
    if not all(np.isfinite(v) for v in (data["max_contour_error"], data["cycle_time_s"])):
        problems.append("non-finite figure")
    row.update(status=STATUS_OK if not problems else STATUS_ERROR,
               error_type=None if not problems else "InvariantViolated",
               error_message="; ".join(problems) or None)
    return row


SWEEP = """
name = "sweep"
seed = 20261124
feeds = [0.2, 1.0]
machines = ["die-bonder", "{machine3}"]
interpolators = {interpolators}
time_optimal_bound = false
settle_time = 0.02
sample = {cases}
[[random_paths]]
families = "all"
count = 1
n_axes = 2
length = 2500
[[random_paths]]
families = "all"
count = 1
n_axes = 3
length = 2500
[[plants]]
name = "nominal"
[[plants]]
name = "pm20"
spread = 0.2
"""


@pytest.mark.parametrize("interpolators, cases", [
    (["taylor1", "taylor2", "paper"], N_SWEEP),
    (["planned"], max(2, N_SWEEP // 50)),  # its planning costs seconds a case
])
def test_random_families_keep_every_interpolator_invariant(tmp_path, interpolators, cases):
    machine3 = _three_axis_machine(tmp_path)
    text = SWEEP.format(machine3=machine3.name, interpolators=interpolators, cases=cases)
    study = load_study(write_study(tmp_path, text, "sweep.toml"))
    cases = study_cases(study)
    if len(cases) >= 150:  # a sample this large holds every family
        assert {c.path_family for c in cases} == set(FAMILIES)
    rows = list(execute._execute(cases, None, None, check_case))
    assert len(rows) == len(cases) == study.sample
    bad = [(r["case_id"], r["path_family"], r["interpolator"], r["error_message"])
           for r in rows if r["error_type"] == "InvariantViolated"]
    assert not bad, bad
    # Only the refused zero-speed curves may fail, and only with InvalidCurveError
    # (until NurbsCurve accepts isolated zero-speed points).
    for r in rows:
        if r["status"] != STATUS_OK:
            assert r["path_family"] == "duplicated_points", r
            assert r["error_type"] == "InvalidCurveError", r


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_random_paths_are_seeded(family):
    from nurbsmotion.errors import InvalidCurveError

    for seed in range(3):
        for n_axes in (2, 3):
            try:
                a = random_path(family, seed, n_axes)
            except InvalidCurveError:
                assert family == "duplicated_points"
                continue
            b = random_path(family, seed, n_axes)
            assert a == b and a.n_axes == n_axes


def test_family_shapes():
    from nurbsmotion.planning import time_optimal_bound

    u = np.linspace(0, 1, 200_001)
    for seed in range(2):
        cusp = random_path("near_cusps", seed)
        k = cusp.curvature(u)
        assert 1 / k.max() < 1.0  # a turn tighter than one pulse ...
        assert not np.any(np.isclose(u[np.argmax(k)], cusp.breakpoints))  # ... inside a span
        near = random_path("near_corners", seed)
        angles = np.degrees(near.turning_angle(near.sharp_corners()))
        assert angles.size >= 2 and np.all(angles < 2.0)
        closed = random_path("closed", seed, 3)
        assert np.array_equal(closed(0.0), closed(1.0))
        tiny = random_path("tiny_spans", seed)
        assert np.min(np.diff(tiny.breakpoints)) == pytest.approx(1e-6, rel=1e-6)
        short = random_path("short_moves", seed)
        assert time_optimal_bound(short, die_bonder(), 1e6) < 0.05


def test_the_example_study_runs(tmp_path):
    example = Path(__file__).resolve().parents[1] / "examples" / "study.toml"
    study = load_study(example)
    cases = study_cases(study)
    assert len(cases) == (1 + 4 * 2) * 2 * 1 * 3 * 2
    assert main(["campaign", str(example), "--out", str(tmp_path), "--case", "c0000000",
                 "--no-figures"]) == 0
    assert (tmp_path / "c0000000" / "summary.json").is_file()


# ----------------------------------------------------------------------------- as `run`
STUDY_FILES = """
name = "units"
paths = ["inch.json", "mm.json", "prog.ngc", "drawing.dxf"]
feeds = [{feed}]
feed_unit = "{unit}"
interpolators = ["taylor1", "paper"]
"""


def _unit_paths(tmp_path):
    """A path in inches, one in mm, a G-code program with its own F words and a DXF
    drawing (in mm), each a few mm long."""
    import json

    from nurbsmotion.nurbs import NurbsCurve
    from nurbsmotion.paths import save_path

    (tmp_path / "inch.json").write_text(json.dumps(
        {"units": "in", "degree": 2, "knots": [0, 0, 0, 0.5, 1, 1, 1],
         "control_points": [[0, 0], [0.2, 0], [0.4, 0.2], [0.4, 0.4]]}))
    (tmp_path / "mm.json").write_text(json.dumps(
        {"units": "mm", "degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1],
         "control_points": [[0, 0], [4, 0], [4, 6], [9, 6]]}))
    (tmp_path / "prog.ngc").write_text(
        "G21 G90 G17\nG0 X0 Y0\nG1 X8 Y0 F300\nG1 X8 Y5 F120\nM2\n")
    arc = NurbsCurve(2, [0, 0, 0, 1, 1, 1], [[0, 0], [6, 0], [6, 6]], [1, 2 ** -0.5, 1],
                     units="mm")
    save_path(arc, tmp_path / "drawing.dxf")


@pytest.mark.parametrize("feed, unit, cli_feed", [
    (20.0, "mm/s", "20mm/s"), (1.5, "m/s", "1.5m/s"), (3000.0, "mm/min", "3000mm/min"),
])
def test_a_study_runs_every_path_as_run_does(tmp_path, feed, unit, cli_feed):
    """Regression: a study converted its feed to pulse/s and handed it to run() as a
    number in the path's units, so every path drawn in mm (or inches, G-code, DXF) ran
    1000x (25400x) too fast; and it ignored a G-code program's F words."""
    import json

    _unit_paths(tmp_path)
    study = load_study(write_study(tmp_path, STUDY_FILES.format(feed=feed, unit=unit)))
    result = run_study(study, tmp_path / "out", workers=1, progress=False)
    rows = read_rows(tmp_path / "out").to_pylist()
    assert result.failed == 0 and len(rows) == 8
    for row in rows:
        out = tmp_path / f"run-{row['case_id']}"
        assert main(["run", str(tmp_path / row["path"]), "--feed", cli_feed,
                     "--interpolator", row["interpolator"], "--no-figures", "--no-trace",
                     "--quiet", "--out", str(out)]) == 0
        ran = json.loads((out / "summary.json").read_text())
        for key in ("cycle_time_s", "max_contour_error", "time_optimal_bound_s", "feed",
                    "settle_time_s"):
            assert row[key] == pytest.approx(ran[key], rel=1e-12), (row["path"], key)
        # Independently of `run`: the motion takes at least the path's length at the
        # feed (the lower of the study's and the program's where the file has F words).
        machine = die_bonder()
        contour = study_case._contour(row["path"], None, None, 0, 0.0, str(tmp_path),
                                      "die-bonder")
        per_unit = machine.pulses_per_unit(contour.curve.units)
        speed = feed * {"mm/s": 1.0, "m/s": 1e3, "mm/min": 1 / 60}[unit] \
            * machine.pulses_per_unit("mm")
        if contour.feed is not None:
            fastest = min(speed, contour.feed.highest * per_unit)
        else:
            fastest = speed
        least = contour.curve.length * per_unit / fastest
        assert row["time_optimal_bound_s"] >= least * (1 - 1e-9)
        assert row["cycle_time_s"] >= least - 2 * machine.sample_period


CHORD_STUDY = """
name = "cam chords"
paths = ["cam.ngc"]
feeds = [100]
feed_unit = "mm/s"
interpolators = ["paper", "planned"]
"""


def test_a_study_joins_cam_chords_as_run_does(tmp_path, capsys):
    """Regression (issue 37): a study read a CAM program's 300 chords as 300 corners
    while ``run`` joins them within the path tolerance, so the same case gave another
    path and another time. Every row equals ``run`` of its case, and the motion is the
    joined one: near the length at the feed, which stopping at 300 corners is far from
    (``bound --path-tolerance 0``)."""
    import json

    from test_chords import wave

    V = wave(300)
    (tmp_path / "cam.ngc").write_text(
        "G21 G90 G17\nG0 X0 Y0\nF6000\n"
        + "".join(f"G1 X{x:.4f} Y{y:.4f}\n" for x, y in V[1:]) + "M2\n")
    study = load_study(write_study(tmp_path, CHORD_STUDY))
    result = run_study(study, tmp_path / "out", workers=1, progress=False)
    rows = read_rows(tmp_path / "out").to_pylist()
    assert result.failed == 0 and len(rows) == 2
    length = float(np.sum(np.linalg.norm(np.diff(V, axis=0), axis=1)))  # [mm]
    for row in rows:
        out = tmp_path / f"run-{row['case_id']}"
        assert main(["run", str(tmp_path / "cam.ngc"), "--feed", "100mm/s",
                     "--interpolator", row["interpolator"], "--no-figures", "--no-trace",
                     "--quiet", "--out", str(out)]) == 0
        ran = json.loads((out / "summary.json").read_text())
        assert ran["chords_joined"] == 300
        for key in ("cycle_time_s", "max_contour_error", "time_optimal_bound_s", "feed",
                    "settle_time_s"):
            assert row[key] == pytest.approx(ran[key], rel=1e-12), (row["interpolator"], key)
        assert length / 100.0 <= row["time_optimal_bound_s"] <= 1.05 * length / 100.0
    capsys.readouterr()
    assert main(["bound", str(tmp_path / "cam.ngc"), "--path-tolerance", "0"]) == 0
    assert float(capsys.readouterr().out) > 2 * rows[0]["time_optimal_bound_s"]


def test_a_bad_study_is_refused_before_any_case_runs(tmp_path, capsys, monkeypatch):
    """Issue 37: a study naming a missing path file exited 0 (its cases were errors)."""
    def never(case):
        raise AssertionError("a case ran")

    # run_case and the warm-up each call the case_trace of their own module
    monkeypatch.setattr(study_case, "case_trace", never)
    monkeypatch.setattr(execute, "case_trace", never)
    (tmp_path / "part.ngc").write_text("G21\nG1 X1 F60\nM2\n")
    f = write_study(tmp_path, SMALL.replace('"broken.json"', '"part.ngc", "gone.ngc"'))
    assert main(["campaign", str(f), "--out", str(tmp_path / "out"), "--workers", "1",
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "gone.ngc" in err[0] and str(f) in err[0]
    assert not (tmp_path / "out").exists()


def test_campaign_out_must_name_a_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    f = write_study(tmp_path)
    for out in ("", " "):
        assert main(["campaign", str(f), "--out", out]) == 2
        assert "--out" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.json", "study.toml"]


def test_overwrite_removes_the_earlier_campaign_and_nothing_else(tmp_path):
    study = load_study(write_study(tmp_path))
    out = tmp_path / "out"
    run_study(study, out, workers=1, progress=False, cases=study_cases(study)[:2])
    (out / "c0000000").mkdir()
    (out / "c0000000" / "summary.json").write_text("{}")
    (out / "notes.txt").write_text("mine")
    (out / "rows" / "mine.csv").write_text("mine")
    before = set(p.name for p in (out / "rows").glob("part-*"))
    run_study(study, out, workers=1, progress=False, overwrite=True,
              cases=study_cases(study)[2:3])
    assert (out / "notes.txt").read_text() == "mine" and (out / "rows" / "mine.csv").exists()
    assert not (out / "c0000000").exists()
    assert not before & set(p.name for p in (out / "rows").glob("part-*"))
    assert read_rows(out).column("case_id").to_pylist() == ["c0000002"]
