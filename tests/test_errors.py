"""One rule for errors (:mod:`nurbsmotion.errors`): a bad argument raises an
:class:`InvalidArgumentError` (or one of its kind), work that valid arguments cannot do an
:class:`InfeasibleError`; and one default interpolator for the library and the command.

The calls below are the library's entry points with one bad argument each, and requests
that are valid but impossible; the source scan holds new code to the rule.
"""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion import stepping
from nurbsmotion.errors import (InfeasibleError, InvalidArgumentError, InvalidFeedError,
                                NurbsmotionError)
from nurbsmotion.interpolators import (DEFAULT_INTERPOLATOR, LOOP_METHODS, TaylorInterpolator,
                                       make_interpolator, make_open_loop)
from nurbsmotion.interpolators.planned import PlannedInterpolator
from nurbsmotion.interpolators.planned.plan import plan_motion
from nurbsmotion.interpolators.replay import ReplayInterpolator
from nurbsmotion.loop import run, simulate
from nurbsmotion.machine import die_bonder
from nurbsmotion.planning import sampled_stop_bound, speed_profile, time_optimal_bound

SRC = Path(__file__).resolve().parents[1] / "src" / "nurbsmotion"
PI = nm.make_die_bonder_pi()
LINE = nm.make_line([0.0, 0.0], [3000.0, 4000.0])
MACHINE = die_bonder()

BAD_ARGUMENTS = {
    "feed 0 (planned)": (lambda: PlannedInterpolator(PI, MACHINE, 0.0), InvalidFeedError),
    "feed NaN (bound)": (lambda: time_optimal_bound(PI, MACHINE, math.nan), InvalidFeedError),
    "feed text (bound)": (lambda: time_optimal_bound(PI, MACHINE, "fast"), InvalidFeedError),
    "feed -5 (taylor)": (lambda: TaylorInterpolator(LINE, 1e-3, -5.0), InvalidFeedError),
    "feed True (taylor)": (lambda: TaylorInterpolator(LINE, 1e-3, True), InvalidFeedError),
    "feed function 0": (lambda: TaylorInterpolator(LINE, 1e-3, lambda u: 0.0),
                        InvalidFeedError),
    "Taylor order 3": (lambda: TaylorInterpolator(LINE, 1e-3, 1e5, order=3),
                       InvalidArgumentError),
    "sample period 0": (lambda: TaylorInterpolator(LINE, 0.0, 1e5), InvalidArgumentError),
    "not a curve": (lambda: TaylorInterpolator("line", 1e-3, 1e5), InvalidArgumentError),
    "tracking pole 1.5": (lambda: PlannedInterpolator(PI, MACHINE, 1e6, tracking_pole=1.5),
                          InvalidArgumentError),
    "corner tolerance -1": (lambda: plan_motion(PI, MACHINE, 1e6, corner_tolerance=-1.0),
                            InvalidArgumentError),
    "path tolerance NaN": (lambda: plan_motion(PI, MACHINE, 1e6, path_tolerance=math.nan),
                           InvalidArgumentError),
    "drive fraction 2": (lambda: plan_motion(PI, MACHINE, 1e6, drive_fraction=2.0),
                         InvalidArgumentError),
    "profile grid 5": (lambda: speed_profile(PI, MACHINE, 1e6, grid_size=5),
                       InvalidArgumentError),
    "settle window -1 (sampled bound)": (
        lambda: sampled_stop_bound(PI, MACHINE, settle_window=-1.0), InvalidArgumentError),
    "replay not from 0": (lambda: ReplayInterpolator(LINE, 1e-3, [0.5, 1.0]),
                          InvalidArgumentError),
    "simulate a name": (lambda: simulate("paper", MACHINE), InvalidArgumentError),
    "simulate settle time -1": (
        lambda: simulate(TaylorInterpolator(LINE, 1e-3, 1e5), MACHINE, settle_time=-1.0),
        InvalidArgumentError),
    "sample periods differ": (
        lambda: simulate(TaylorInterpolator(LINE, 2e-3, 1e5), MACHINE), InvalidArgumentError),
    "unknown loop interpolator": (lambda: make_interpolator("fast", LINE, MACHINE, 1e5),
                                  InvalidArgumentError),
    "unknown open-loop method": (lambda: make_open_loop("fast", LINE, 1e-3, 1e5),
                                 InvalidArgumentError),
    "run without a machine": (lambda: run(LINE, None, 1e5), InvalidArgumentError),
    "arc length beyond the path": (lambda: LINE.parameter_at(2 * LINE.length),
                                   InvalidArgumentError),
    "step registered from sample 2": (
        lambda: stepping.register(tuple, lambda *a: None, first_sample=2),
        InvalidArgumentError),
}
"""A call with one bad argument, and the error type it must raise."""

INFEASIBLE = {
    "planned: drive too weak": lambda: PlannedInterpolator(PI, die_bonder(max_drive=1e-12),
                                                           1e6),
    "plan longer than max_samples": lambda: PlannedInterpolator(
        PI, die_bonder(max_drive=0.01), 1e6, max_samples=100),
}
"""Valid arguments whose work cannot be done."""


@pytest.mark.parametrize("name", list(BAD_ARGUMENTS))
def test_a_bad_argument_is_an_invalid_argument_error(name):
    call, kind = BAD_ARGUMENTS[name]
    with pytest.raises(kind) as caught:
        call()
    assert isinstance(caught.value, InvalidArgumentError) or kind is not InvalidArgumentError
    assert not isinstance(caught.value, InfeasibleError), name
    assert isinstance(caught.value, (NurbsmotionError, ValueError))


@pytest.mark.parametrize("name", list(INFEASIBLE))
def test_infeasible_work_is_an_infeasible_error(name):
    with pytest.raises(InfeasibleError) as caught:
        INFEASIBLE[name]()
    assert not isinstance(caught.value, InvalidArgumentError), name


def test_both_are_value_errors_for_old_callers():
    """Code that caught ``ValueError`` (or InfeasibleError's base) still catches both."""
    assert issubclass(InvalidArgumentError, ValueError)
    assert issubclass(InfeasibleError, ValueError)
    assert issubclass(InvalidFeedError, InvalidArgumentError)


# ------------------------------------------------------------------ the source scan
def _raises():
    """``(file, line, error name, message text)`` of every ``raise Name(...)`` in src/;
    the message text is the literal parts of its first argument (f-strings included)."""
    for path in sorted(SRC.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call)
                    and isinstance(node.exc.func, ast.Name)):
                continue
            args = node.exc.args
            text = "".join(c.value for a in args[:1] for c in ast.walk(a)
                           if isinstance(c, ast.Constant) and isinstance(c.value, str))
            yield path.relative_to(SRC.parent).as_posix(), node.lineno, node.exc.func.id, text


ARGUMENT_WORDS = re.compile(r"\bmust (be|lie|have|start)\b|\bgot\b")
"""How an argument check words its message ("feed must be finite and > 0, got -1")."""


def test_infeasible_errors_are_not_argument_checks():
    wrong = [f"{f}:{line}: {text!r}" for f, line, name, text in _raises()
             if name == "InfeasibleError" and ARGUMENT_WORDS.search(text)]
    assert not wrong, ("InfeasibleError raised for what reads as an argument check "
                       "(raise InvalidArgumentError):\n" + "\n".join(wrong))


PLAIN_RAISES = {
    # module: plain ValueError/TypeError raises left, and why; never raise one.
    # internal signals, caught within the module and re-raised typed:
    "nurbsmotion/_runtime/io.py": 1,  # JSON's NaN/Infinity -> PathFileError
    "nurbsmotion/nurbs.py": 1,  # a non-number coordinate -> InvalidCurveError
    "nurbsmotion/paths/gcode/ngc.py": 1,  # a G-code expression's domain error -> PathFileError
}
"""The plain ``raise ValueError``/``raise TypeError`` statements still allowed."""


def test_no_new_plain_value_errors():
    counts: dict[str, int] = {}
    for f, _, name, _ in _raises():
        if name in ("ValueError", "TypeError"):
            counts[f] = counts.get(f, 0) + 1
    grown = {f: n for f, n in counts.items() if n > PLAIN_RAISES.get(f, 0)}
    assert not grown, (f"plain ValueError/TypeError raised in {grown}: raise a typed error "
                       "from nurbsmotion.errors (InvalidArgumentError for a bad argument)")


# ------------------------------------------------------------------ one default
def test_library_and_command_default_to_the_same_interpolator():
    import inspect

    from nurbsmotion import loop
    from nurbsmotion.cli import _parser

    assert DEFAULT_INTERPOLATOR == "planned" and DEFAULT_INTERPOLATOR in LOOP_METHODS
    for function in (loop.run, loop.run_streamed):
        default = inspect.signature(function).parameters["interpolator"].default
        assert default == DEFAULT_INTERPOLATOR, function.__name__
    args = _parser().parse_args(["run", "die-bonder-pi", "--feed", "1m/s", "--out", "x"])
    assert args.interpolator == DEFAULT_INTERPOLATOR


def test_run_without_a_name_is_the_planned_run():
    """The default is the named run, sample for sample (and no drive saturates)."""
    default = run(LINE, MACHINE, 2e5, settle_time=0.01)
    named = run(LINE, MACHINE, 2e5, "planned", settle_time=0.01)
    assert np.array_equal(default.position, named.position)
    assert np.array_equal(default.drive, named.drive)
    assert default.metrics().total_saturated_samples == 0
