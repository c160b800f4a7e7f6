"""The first ``run`` on an empty numba cache compiles its closed loop in a second process
(:mod:`nurbsmotion._runtime.precompile`, issue 9): the made-up arguments have the types a run
passes, nothing starts when the loop is cached, and Ctrl-C ends both processes."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import interrupt_command, source_env
from nurbsmotion.interpolators import LOOP_METHODS

GCODE = str(Path(__file__).resolve().parents[1] / "examples" / "butterfly.ngc") + "#2"

_RUN_SCRIPT = r"""
import sys
from nurbsmotion._runtime import precompile as _precompile
from nurbsmotion.cli import main

name, path, out = sys.argv[1:]
assert main(["run", path, "--feed", "0.05m/s", "--interpolator", name, "--no-figures",
             "--no-trace", "--quiet", "--out", out]) == 0
# an interpolator without a made-up loop (optional: it only speeds up a cold start) is
# compiled by the run itself
loop = _precompile.loop_example(name)
for kernel, args in [*([loop] if loop else []), *_precompile.examples_here(name)]:
    assert kernel.signatures == [_precompile._signature(args)], (
        kernel.py_func.__qualname__, kernel.signatures, _precompile._signature(args))
with _precompile.Precompiler(name) as second:
    assert second.process is None, "the loop is cached: no second process"
print("ok")
"""


@pytest.mark.parametrize("name, path", [*((m, "die-bonder-pi") for m in LOOP_METHODS),
                                        ("paper", GCODE)])  # G-code: a feed per piece
def test_the_made_up_arguments_have_the_types_a_run_passes(tmp_path, name, path):
    """In a fresh process, a run compiles (or loads) the loop and the kernels of
    ``examples_here`` for exactly the signatures of the made-up arguments, and no other:
    the two processes compile what the run uses; and once the loop is cached, no second
    process starts."""
    done = subprocess.run([sys.executable, "-c", _RUN_SCRIPT, name, path,
                           str(tmp_path / "run")], capture_output=True, text=True,
                          env=source_env(), timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().endswith("ok")


def _precompilers(cache: str) -> list[int]:
    """Pids of the live second processes whose numba cache is ``cache``."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            if (b"nurbsmotion._runtime.precompile" in (proc / "cmdline").read_bytes()
                    and f"NUMBA_CACHE_DIR={cache}".encode()
                    in (proc / "environ").read_bytes().split(b"\0")
                    and (proc / "stat").read_text().split()[2] not in "ZX"):
                found.append(int(proc.name))
        except OSError:
            pass
    return found


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs Linux /proc")
def test_ctrl_c_on_a_cold_start_ends_both_processes(tmp_path):
    """Interrupted while both compile, the command exits 130 with its one line, and its
    second process is gone with it."""
    cache = str(tmp_path / "cache")
    appeared = []  # when the second process was first seen [monotonic s]

    def both_compiling() -> bool:
        if not appeared and _precompilers(cache):
            appeared.append(time.monotonic())
        return bool(appeared) and time.monotonic() > appeared[0] + 0.5

    code, err = interrupt_command(["run", "die-bonder-pi", "--feed", "1m/s", "--no-figures",
                                   "--out", str(tmp_path / "o")], both_compiling,
                                  source_env(NUMBA_CACHE_DIR=cache))
    assert appeared, "no second process was started on an empty cache"
    assert code == 130
    assert err.strip().splitlines() == ["nurbsmotion run: interrupted; no output was written"]
    deadline = time.monotonic() + 10
    while _precompilers(cache) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _precompilers(cache)
    assert not (tmp_path / "o").exists()
