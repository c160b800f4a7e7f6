"""Start-up cost of the command's refusals and help (issue 37: "every size limit checked
where it is known ..., in one line, within a second"): CPU time, including Python's
start-up, of every refusal of benchmarks/size_limits.md, of a refused sample period
(``interpolate --sample-period 1e-9``, and ``run`` on a machine file whose
``sample_period`` is 1e-9 s), and of ``--help`` of the command and of each subcommand.

Each command runs ``--repeats`` times in a fresh process (``python -m nurbsmotion``); the
table gives the least and the median CPU time (user + system of the child: the machine is
shared, wall times mean little), the exit code and the start of the message. The path
files are those of benchmarks/size_limits.py (``--points`` points each). Usage::

    python benchmarks/startup.py [--points 1000000] [--repeats 3] [--src SRC]
        [--before SRC] [--skip-gcode] [--markdown FILE]

``--src`` measures another checkout's ``src`` folder (its ``nurbsmotion``); ``--before``
another one beside it, the two runs of each command alternating (same files, same load),
in two more columns.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import SRC
from size_limits import write_files

SUBCOMMANDS = ("interpolate", "run", "bound", "contours", "reproduce", "campaign",
               "identify", "excite")


def commands(tmp: Path, files: dict, skip_gcode: bool) -> list[tuple[str, list[str]]]:
    """(label, argv) of every command measured."""
    out = []
    for name in ("wave.json", "zigzag.json", "zigzag.ngc", "zigzag.dxf", "lines.dxf"):
        if skip_gcode and name.endswith(".ngc"):
            continue
        for command in ("run", "bound") + (("interpolate", "contours")
                                            if name.endswith(".dxf") else ()):
            argv = [command, str(files[name])] + (["--feed", "100mm/s"]
                                                  if command != "contours" else [])
            if command in ("run", "interpolate"):
                argv += ["--out", str(tmp / f"{command}_{name}")]
            if command == "run":
                argv += ["--no-figures", "--quiet"]
            out.append((f"{command} {name}", argv))
    tiny = tmp / "tiny_ts.toml"
    text = (SRC.parent / "examples" / "die_bonder.toml").read_text()
    tiny.write_text(text.replace("sample_period = 0.001", "sample_period = 1e-9"))
    out.append(("interpolate --sample-period 1e-9",
                ["interpolate", "die-bonder-pi", "--feed", "100mm/s", "--sample-period",
                 "1e-9", "--out", str(tmp / "ts")]))
    out.append(("run, machine Ts 1e-9 s",
                ["run", "die-bonder-pi", "--feed", "100mm/s", "--machine", str(tiny),
                 "--out", str(tmp / "ts_run"), "--no-figures", "--quiet"]))
    out.append(("--help", ["--help"]))
    out += [(f"{c} --help", [c, "--help"]) for c in SUBCOMMANDS]
    return out


def cpu_of(argv: list[str], src: Path) -> tuple[float, int, str]:
    """(CPU seconds, exit code, last line of stderr or first of stdout) of ``python -m
    nurbsmotion ARGV`` in a fresh process importing ``src``'s nurbsmotion."""
    env = dict(os.environ, PYTHONPATH=str(src), MPLBACKEND="Agg")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, "-m", "nurbsmotion", *argv], capture_output=True,
                         text=True, env=env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    err = out.stderr.strip().splitlines()
    message = err[-1] if err else (out.stdout.strip().splitlines() or [""])[0]
    return cpu, out.returncode, message


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=1_000_000)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--src", type=Path, default=SRC, help="the src folder to measure")
    p.add_argument("--before", type=Path, help="a src folder to compare with, run alternately")
    p.add_argument("--skip-gcode", action="store_true",
                   help="leave out zigzag.ngc (its reading, not start-up, takes seconds)")
    p.add_argument("--markdown", help="also write the table to this Markdown file")
    args = p.parse_args()
    head = ["| command | CPU least [s] | CPU median [s] | exit | message |",
            "|---|---|---|---|---|"]
    if args.before:
        head = ["| command | before: CPU least [s] | before: median [s] | CPU least [s] | "
                "CPU median [s] | exit | message |", "|---|---|---|---|---|---|---|"]
    print("\n".join(head), flush=True)
    rows = []
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        files = write_files(tmp, args.points)
        for label, argv in commands(tmp, files, args.skip_gcode):
            results, before = [], []
            for _ in range(args.repeats):
                if args.before:
                    before.append(cpu_of(argv, args.before.resolve())[0])
                results.append(cpu_of(argv, args.src.resolve()))
            cpus = [r[0] for r in results]
            message = results[-1][2].replace(str(tmp), "TMP").replace("|", "/")
            then = (f" {min(before):.2f} | {statistics.median(before):.2f} |"
                    if args.before else "")
            row = (f"| {label} |{then} {min(cpus):.2f} | {statistics.median(cpus):.2f} | "
                   f"{results[-1][1]} | {message[:110]} |")
            rows.append(row)
            print(row, flush=True)
    load_end = os.getloadavg()
    note = (f"`python benchmarks/startup.py --points {args.points} --repeats {args.repeats}"
            f"{' --skip-gcode' if args.skip_gcode else ''}"
            f"{' --before ' + str(args.before) if args.before else ''}`; load average "
            f"{load[0]:.2f} at the start, {load_end[0]:.2f} at the end, "
            f"{os.cpu_count()} cores; CPU = user + system of each command.")
    print("\n" + note)
    if args.markdown:
        Path(args.markdown).write_text("\n".join([note, ""] + head + rows) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
