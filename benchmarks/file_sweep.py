"""``planned`` on the files users have, on random machines: the G-code and DXF corpus of
the test suite (``tests/data/corpus``: LinuxCNC's own programs, CAM output, ezdxf's and
others' drawings; origins in its ``SOURCES.md``).

Each file is read for the ``xy`` and the ``xyz`` machine (where it has a path for it), and
each of its first two contours is run on a machine of its own
(:func:`nurbsmotion.random_machines.random_machine`: Ts 0.1-2 ms, tau 2-100 ms, PD+, PD or
a LinuxCNC pid with integrator, deadband and clamp) with a pulse of 0.1, 1 or 10 um, at a
feed of 5-300 mm/s or, for half of the contours that have one, the file's own F words,
and a corner tolerance of 0 (twice as often), 10 um, 0.1 mm or 0.5 mm. Reported: the
runs refused (a move over the sample limit is refused before any work, by design),
saturated samples, runs that did not settle, the contour error against the tolerance
(issue 10, item 5: at most eps + 5 um), move-and-settle against the time-optimal bound,
and the time to plan and run. This sweep found the speed profile's stall where an axis
settles within a grid step, the drive easing's quadratic interval look-up, corner blends
over more pieces than they checked (beyond eps, and easings that ran away), blends
slower than stopping, a drive excess of 1e-8 that wandered until the move was refused,
and a program of 3,000 pieces planned in 335 s (see RESULTS.md, seventh and eighth
sessions).

Note: the bound is the continuous one of SPEC section 9; on programs of many tiny
segments with exact stops (``flowsnake.ngc`` at Ts = 2 ms: 3,072 corners, 1.5 pulses a
piece) no sampled motion comes near it (``nurbsmotion bound --sampled``).

Run: python benchmarks/file_sweep.py (``FILE_SWEEP_DRAWS=n``: each contour on n machines,
the first one always the same; ``FILE_SWEEP_FILES=corpus|linuxcnc_tp|all``: which files,
LinuxCNC's trajectory-planner test programs being ``corpus/linuxcnc_tp``; ``all`` also
takes ``corpus/linuxcnc_ccomp``, LinuxCNC's cutter compensation tests)

The commands as a user types them (``FILE_SWEEP_MODE=commands``, issue 36): every file
through ``nurbsmotion contours FILE`` with no flag, then ``bound FILE#1`` (and, with
``FILE_SWEEP_RUN=1``, ``run FILE#1 --no-figures --no-trace``) on a machine with the axes the
file moves (``die-bonder`` for XY, ``examples/gantry3.toml`` for XYZ,
``examples/gantry4a.toml`` for XYZA, else the die-bonder's X axis under each name, a
rotary one with 1,000 pulses per degree), at the file's own F words (``--feed 50mm/s``
where it has none). Tabulated per file: listed, bound or ran, or the one-line refusal;
the table goes to ``benchmarks/file_sweep_commands.md``. Above it, issue 36's measure: of
the files a user would run (those LinuxCNC's own interpreter, ``rs274 -g``, produces motion
from without an error, and the drawings ezdxf reads), how many list and run without a flag;
and every file not run, with its refusal and LinuxCNC's verdict (:func:`linuxcnc_verdict`).
Each command is stopped after ``CASE_SECONDS`` of CPU time (not wall-clock time).
"""

from __future__ import annotations

import collections
import itertools
import os
import re
import shutil
import signal
import subprocess
import tempfile
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

import _common  # puts src/ on the path
from nurbsmotion import units
from nurbsmotion.errors import NurbsmotionError, WorkLimitError
from nurbsmotion.loop import run, to_pulses
from nurbsmotion.paths.files import load_contours
from nurbsmotion.planning import time_optimal_bound
from nurbsmotion.random_machines import random_machine

CORPUS = Path(__file__).resolve().parents[1] / "tests" / "data" / "corpus"

DRAWS = int(os.environ.get("FILE_SWEEP_DRAWS", "1"))
"""Machines (with pulse, feed and tolerance) each contour is run on."""

MAX_SAMPLES = 400_000
"""Longer moves are refused before any work (a :class:`WorkLimitError`, counted apart)."""

TOLERANCES_MM = (0.0, 0.0, 0.01, 0.1, 0.5)
"""The corner tolerances drawn from [mm]."""

CASE_SECONDS = 120
"""A run still planning after this much CPU time of its worker process [s] is stopped and
counted apart (``timed out``; a compiled call is not interrupted, so such a run is counted
when that call returns). CPU time, not wall-clock time: on a shared machine under a load of
8 the wall clock stopped runs of 6-20 s of CPU (issue 36)."""


class _TimedOut(Exception):
    pass


def _alarm(signum, frame):
    raise _TimedOut


def _limit(seconds: float) -> None:
    """Raise :class:`_TimedOut` in this process after ``seconds`` of its CPU time (0: no
    limit); the handler is installed by :func:`_install_limit`."""
    signal.setitimer(signal.ITIMER_PROF, seconds)


def _install_limit() -> None:
    signal.signal(signal.SIGPROF, _alarm)


AXES = tuple(os.environ.get("FILE_SWEEP_AXES", "xy,xyz").split(","))
"""The machines' axes each file is read for; ``file``: every axis the file moves, with no
flag (as ``nurbsmotion contours FILE`` lists it), on a machine with that many axes."""

FILES = os.environ.get("FILE_SWEEP_FILES", "all")
"""Which files: ``corpus`` (the corpus' own folder), ``linuxcnc_tp`` (LinuxCNC's
trajectory-planner test programs, ``corpus/linuxcnc_tp``) or ``all`` (those and
``corpus/linuxcnc_ccomp``, LinuxCNC's cutter compensation tests)."""


def cases() -> list[tuple]:
    folders = {"corpus": [CORPUS], "linuxcnc_tp": [CORPUS / "linuxcnc_tp"],
               "all": [CORPUS, CORPUS / "linuxcnc_tp", CORPUS / "linuxcnc_ccomp"]}[FILES]
    files = sorted(f for folder in folders for f in folder.iterdir()
                   if f.is_file() and f.suffix.lower() not in (".md", ".tbl"))
    return [(i, f, axes) for i, f in enumerate(files) for axes in AXES]


def one_file(case: tuple) -> list[dict]:
    """Every row of one file read for one set of axes."""
    index, file, axes = case
    warnings.simplefilter("ignore")  # the readers' notes on skipped words
    _install_limit()
    try:
        contours = load_contours(file, axes=None if axes == "file" else axes)
    except NurbsmotionError as exc:
        return [dict(file=file.name, axes=axes, status="not read",
                     error=f"{type(exc).__name__}: {exc}")]
    rows = []
    for (k, contour), draw in itertools.product(enumerate(contours[:2]), range(DRAWS)):
        n_axes = contour.curve.n_axes
        if n_axes > 3 or set(contours[0].axes or "") & set("ABC"):  # random machines: 1-3 linear axes
            rows.append(dict(file=file.name, axes=axes, contour=k + 1, draw=draw, status="not run",
                             error=f"axes {contour.axes}: no random machine has them"))
            continue
        seed = [index, k, n_axes] + ([draw] if draw else [])
        rng = np.random.default_rng(seed)
        m = random_machine(seed, n_axes)
        m = m.with_options(pulse_length_um=float(rng.choice([0.1, 1.0, 10.0])))
        pulse = m.pulse_length_um
        feed = float(np.exp(rng.uniform(np.log(5.0), np.log(300.0)))) * 1e3 / pulse
        own_feed = contour.feed is not None and rng.random() < 0.5
        if own_feed:
            feed = units.feed_in_pulses(contour.feed, contour.curve, m)
        eps = float(rng.choice(TOLERANCES_MM)) * 1e3 / pulse
        row = dict(file=file.name, axes=axes, contour=k + 1, draw=draw, controller=m.controller,
                   sample_period=m.sample_period, pulse_um=pulse, own_feed=own_feed,
                   eps_um=eps * pulse, status="ran")
        t0 = time.perf_counter()
        _limit(CASE_SECONDS)
        try:
            path = to_pulses(contour.curve, m)
            bound = time_optimal_bound(path, m, feed)
            trace = run(path, m, feed, "planned", max_samples=MAX_SAMPLES,
                        interpolator_options={"corner_tolerance": eps} if eps else None)
            metrics = trace.metrics()
            row.update(
                success=bool(trace.success), message=trace.message,
                saturated=metrics.total_saturated_samples,
                contour_um=metrics.max_contour_error * pulse,
                ratio=(metrics.settle_time_s / bound if trace.success else float("nan")))
        except _TimedOut:
            row.update(status="timed out", error=f"still running after {CASE_SECONDS} s of CPU")
        except WorkLimitError as exc:
            row.update(status="over the sample limit", error=str(exc))
        except NurbsmotionError as exc:
            row.update(status="refused", error=f"{type(exc).__name__}: {exc}")
        except Exception:  # noqa: BLE001 - a crash is what the sweep is for
            row.update(status="crashed", error=traceback.format_exc(limit=3))
        finally:
            _limit(0)
        row["seconds"] = time.perf_counter() - t0
        rows.append(row)
    return rows


def _label(row: dict) -> str:
    draw = f" draw {row['draw']}" if row.get("draw") else ""
    return f"{row['file']} {row['axes']}#{row.get('contour', '')}{draw}"


def report(rows: list[dict]) -> None:
    print("rows:", dict(collections.Counter(r["status"] for r in rows)))
    for r in rows:
        if r["status"] in ("refused", "crashed", "timed out"):
            print(f"  {_label(r)}: {r['error']}")
    ran = [r for r in rows if r["status"] == "ran"]
    if not ran:
        return
    beyond = [r for r in ran if r["contour_um"] > r["eps_um"] + 5.0]

    def pct(key):
        return _common.spread([r[key] for r in ran])

    print("\n| runs | saturated | not settled | contour > eps + 5 um | settle / bound median "
          "/ 95 % / max | plan and run [s] median / 95 % / max |")
    print("|---|---|---|---|---|---|")
    print(f"| {len(ran)} | {sum(r['saturated'] > 0 for r in ran)} | "
          f"{sum(not r['success'] for r in ran)} | {len(beyond)} | {pct('ratio')} | "
          f"{pct('seconds')} |")
    for key, label in (("ratio", "slowest against the bound"), ("seconds", "longest")):
        worst = sorted(ran, key=lambda r: -np.nan_to_num(r[key]))[:4]
        print(f"{label}:", ", ".join(
            f"{_label(r)} (Ts {r['sample_period'] * 1e3:g} ms, "
            f"eps {r['eps_um']:g} um): {r[key]:.3g}" for r in worst))
    for r in beyond:
        print(f"contour beyond eps + 5 um: {_label(r)}: "
              f"{r['contour_um']:.3g} um (eps {r['eps_um']:g} um)")


MACHINES = {"XY": None, "XYZ": _common.ROOT / "examples" / "gantry3.toml",
            "XYZA": _common.ROOT / "examples" / "gantry4a.toml"}
"""The machine each file's axes run on in the commands sweep (None: the default)."""

COMMANDS_TABLE = Path(__file__).resolve().parent / "file_sweep_commands.md"


def _machine_for(axes: str, folder: Path) -> Path | None:
    """A machine file with one axis per letter of ``axes`` (see the module docstring)."""
    if axes in MACHINES:
        return MACHINES[axes]
    from nurbsmotion.machine import die_bonder

    data = die_bonder().to_dict()
    x = data["axes"][0]
    data["name"] = f"sweep-{axes.lower()}"
    data["axes"] = [dict(x, name=a.lower(), **({"pulses_per_degree": 1000.0} if a in "ABC" else {}))
                    for a in axes]
    path = folder / f"{axes.lower()}.json"
    import json

    path.write_text(json.dumps(data))
    return path


def _command(argv: list) -> tuple[int, str, str]:
    """``nurbsmotion ARGV`` in this process: exit code, stdout, stderr."""
    import contextlib
    import io

    from nurbsmotion.cli import main as cli

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = cli([str(a) for a in argv])
        except SystemExit as exc:  # argparse
            code = exc.code if isinstance(exc.code, int) else 2
    return code, out.getvalue(), err.getvalue()


def _reason(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip() and "Warning" not in ln]
    text = lines[-1] if lines else "no message"
    return text.replace(f"{_common.ROOT}/", "").replace("|", "/")[:400]


def one_file_commands(file: Path) -> dict:
    """``contours`` then ``bound`` (and ``run``) of contour 1 of one file."""
    warnings.simplefilter("ignore")
    _install_limit()
    row = dict(file=file.relative_to(CORPUS).as_posix(), listed="", axes="", contours=0,
               bound="", ran="", reason="")
    t0 = time.process_time()
    code, out, err = _command(["contours", file])
    if code != 0:
        row.update(listed="refused", reason=_reason(err))
        return row
    match = re.search(r"^axes: ([A-Z]+)", out, flags=re.MULTILINE)
    row.update(listed="yes", axes=match.group(1) if match else "XY",
               contours=int(re.search(r": (\d+) contour", out).group(1)))
    programmed = "| none |" not in out.splitlines()[4] if len(out.splitlines()) > 4 else False
    with tempfile.TemporaryDirectory() as tmp:
        machine = _machine_for(row["axes"], Path(tmp))
        common = [f"{file}#1"] + (["--machine", machine] if machine else []) \
            + ([] if programmed else ["--feed", "50mm/s"])
        for command, key, extra in (("bound", "bound", []),
                                    ("run", "ran", ["--no-figures", "--no-trace", "--out",
                                                    Path(tmp) / "out", "--quiet"])):
            if command == "run" and not (RUN and row["bound"] == "yes"):
                continue
            started = time.process_time()
            _limit(CASE_SECONDS)
            try:
                code, out, err = _command([command] + common + extra)
            except _TimedOut:
                code, err = 1, f"still running after {CASE_SECONDS} s of CPU"
            except Exception:  # noqa: BLE001 - a crash is what the sweep is for
                code, err = 1, "CRASH " + traceback.format_exc(limit=2).strip().splitlines()[-1]
            finally:
                _limit(0)
            row[key] = "yes" if code == 0 else "refused"
            if code != 0 and time.process_time() - started >= CASE_SECONDS:
                # the timer stopped the command (which reports an interruption): not a refusal
                row[key], err = "timed out", f"still running after {CASE_SECONDS} s of CPU (CASE_SECONDS)"
            if code != 0:
                row["reason"] = f"{command}: {_reason(err)}"
                break
    row["cpu_s"] = time.process_time() - t0
    return row


RUN = os.environ.get("FILE_SWEEP_RUN", "0") == "1"

_FEED_CALL = re.compile(r"\b(?:STRAIGHT_FEED|ARC_FEED|NURBS_[A-Z0-9_]*FEED|STRAIGHT_PROBE|RIGID_TAP)\(")
"""A canonical call of ``rs274 -g`` that moves at a feed (lines, arcs, NURBS, probing,
rigid tapping)."""


def linuxcnc_verdict(file: Path) -> tuple[bool | None, str]:
    """What LinuxCNC itself makes of a file nurbsmotion does not run, on one line.

    A G-code program goes through LinuxCNC's standalone interpreter, ``rs274 -t TABLE -g
    FILE`` (Debian's ``linuxcnc-uspace``, as LinuxCNC's own interpreter tests run it), with
    the tool table beside the program (``<name>.tbl``) or one of tools 1-99 of diameter 0
    and length 0 (a tool change moves nothing). A drawing goes through ezdxf's recover
    mode, as a CAD program would open it. Returns whether LinuxCNC (CAD) produces motion
    (contours) from it, None when the tool is not installed, and what it did.
    """
    if file.suffix.lower() == ".dxf":
        try:
            import ezdxf.recover

            doc, _ = ezdxf.recover.readfile(file)
        except Exception as exc:  # noqa: BLE001 - any reason is the verdict
            return False, f"ezdxf's recover mode: {' '.join(str(exc).split())[:120]}"
        kinds = {"LINE", "ARC", "CIRCLE", "ELLIPSE", "SPLINE", "LWPOLYLINE", "POLYLINE"}
        n = sum(e.dxftype() in kinds for e in doc.modelspace())
        return n > 0, f"ezdxf's recover mode: {n} path entities"
    exe = shutil.which("rs274")
    if exe is None:
        return None, "rs274 (linuxcnc-uspace) not installed"
    with tempfile.TemporaryDirectory() as tmp:  # rs274 writes its parameter file there
        table = file.with_suffix(".tbl")
        if not table.exists():
            table = Path(tmp) / "tools.tbl"
            table.write_text("".join(f"T{n} P{n} D0 Z0 ;\n" for n in range(1, 100)))
        r = subprocess.run([exe, "-t", str(table), "-g", str(file)], stdin=subprocess.DEVNULL,
                           capture_output=True, text=True, errors="replace", timeout=300, cwd=tmp)
    feeds = len(_FEED_CALL.findall(r.stdout))
    if r.returncode != 0:
        said = [ln.strip() for ln in r.stderr.splitlines() if ln.strip() and ln.strip() != "executing"]
        where = f" at `{said[1][:60]}`" if len(said) > 1 else ""
        after = f", after {feeds} feed move{'' if feeds == 1 else 's'}" if feeds else ""
        return False, f"LinuxCNC's rs274: {said[0] if said else 'failed'}{where}{after}"
    if feeds == 0:
        return False, "LinuxCNC's rs274: no feed move"
    return True, f"LinuxCNC's rs274: {feeds} feed moves"


def commands_main() -> None:
    from multiprocessing import Pool

    folders = {"corpus": [CORPUS], "linuxcnc_tp": [CORPUS / "linuxcnc_tp"],
               "all": [CORPUS, CORPUS / "linuxcnc_tp", CORPUS / "linuxcnc_ccomp"]}[FILES]
    files = sorted(f for folder in folders for f in folder.iterdir()
                   if f.is_file() and f.suffix.lower() not in (".md", ".tbl"))
    t0 = time.perf_counter()
    with Pool(int(os.environ.get("FILE_SWEEP_PROCESSES", "2"))) as pool:
        rows = pool.map(one_file_commands, files, chunksize=1)
    listed = sum(r["listed"] == "yes" for r in rows)
    bound = sum(r["bound"] == "yes" for r in rows)
    ran = sum(r["ran"] == "yes" for r in rows)
    timed_out = sum("timed out" in (r["bound"], r["ran"]) for r in rows)
    done = "ran" if RUN else "bound"
    for r in rows:  # what LinuxCNC (or CAD) makes of every file not run here
        r["moves"], r["linuxcnc"] = (True, "") if r[done] == "yes" else \
            linuxcnc_verdict(CORPUS / r["file"])
    users = [r for r in rows if r["moves"] is not False]  # the files a user would run
    refused_too = len(rows) - len(users)
    lines = [
        "# The file sweep as a user types the commands (benchmarks/file_sweep.py, "
        "FILE_SWEEP_MODE=commands)", "",
        f"Files: {len(rows)} (`tests/data/corpus`, its `linuxcnc_tp` folder: LinuxCNC's "
        f"trajectory-planner test programs, and `linuxcnc_ccomp`: its cutter compensation tests); "
        f"listed by `contours` with no flag: {listed}; "
        f"`bound` of contour 1 on a machine with the file's axes: {bound}"
        + (f"; `run` of contour 1: {ran}" if RUN else " (`run` not asked: FILE_SWEEP_RUN=1)")
        + f"; stopped at the sweep's limit of {CASE_SECONDS} s of CPU: {timed_out}"
        + f". CPU time {sum(r.get('cpu_s', 0.0) for r in rows):.0f} s.", "",
        f"Issue 36's measure, the files a user would run: {len(users)} of the {len(rows)}, those "
        f"LinuxCNC's own interpreter (`rs274 -g`) produces motion from without an error and the "
        f"drawings ezdxf reads (its recover mode, as CAD programs open them); the other "
        f"{refused_too} are programs LinuxCNC refuses too or that move nothing, refused here "
        f"with the reason in the table. Of the {len(users)}: "
        f"{sum(r['listed'] == 'yes' for r in users)} list and "
        f"{sum(r[done] == 'yes' for r in users)} {'run' if RUN else 'bound'} without a flag. "
        "Every file not run, with nurbsmotion's one-line refusal and LinuxCNC's verdict:", ""]
    for r in rows:
        if r[done] != "yes":
            lines.append(f"- `{r['file']}`: {r['reason'] or 'not run'} — {r['linuxcnc']}"
                         + ("" if r["moves"] is not False else " (not a file a user would run)"))
    lines += ["", "| file | listed | axes | contours | bound | run | refusal |",
              "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['file']} | {r['listed']} | {r['axes']} | {r['contours'] or ''} | "
                     f"{r['bound']} | {r['ran']} | {r['reason']} |")
    COMMANDS_TABLE.write_text("\n".join(lines) + "\n")
    print("\n".join(line for line in lines if not line.startswith("|")))
    print(f"{len(rows)} files in {time.perf_counter() - t0:.0f} s -> {COMMANDS_TABLE}")


def main():
    from multiprocessing import Pool

    t0 = time.perf_counter()
    with Pool(min(os.cpu_count() or 1, 8)) as pool:
        rows = [row for out in pool.map(one_file, cases(), chunksize=1) for row in out]
    report(rows)
    print(f"\n{len(rows)} rows in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    commands_main() if os.environ.get("FILE_SWEEP_MODE") == "commands" else main()
