"""One registry of named interpolators (:func:`nurbsmotion.stepping.register` with a
name): it gives the factory, the names the loop and the command offer, and the made-up
plan a cold first run compiles from; an interpolator registered from outside the package
runs in the loop like the built-in ones."""

from __future__ import annotations

import numpy as np
import pytest

import nurbsmotion as nm
from nurbsmotion import stepping
from nurbsmotion.errors import InvalidArgumentError
from nurbsmotion.interpolators import (LOOP_METHODS, OPEN_LOOP_METHODS, make_interpolator,
                                       make_open_loop)
from nurbsmotion.interpolators.taylor import TaylorInterpolator, TaylorPlan, taylor_step
from nurbsmotion.loop import run
from nurbsmotion.machine import die_bonder


def test_the_names_come_from_the_registrations():
    """The names the command offers (nurbsmotion.limits, which loads no interpolator) are
    the registered ones, in their order."""
    assert LOOP_METHODS == ("taylor1", "taylor2", "paper", "planned")
    assert OPEN_LOOP_METHODS == ("uniform", "taylor1", "taylor2")
    assert stepping.interpolator_names() == LOOP_METHODS
    assert stepping.interpolator_names(open_loop=True) == OPEN_LOOP_METHODS
    for name in LOOP_METHODS:
        named = stepping.named(name)
        assert named.example is not None, name  # a cold first run compiles its loop
        plan, _ = named.example(3)
        assert type(plan) is named.plan_type


def test_the_command_offers_the_registered_names(capsys):
    from nurbsmotion.cli import main

    with pytest.raises(SystemExit):
        main(["run", "--help"])
    assert "{" + ",".join(LOOP_METHODS) + "}" in capsys.readouterr().out


def test_unknown_names_and_options_are_refused():
    curve, machine = nm.make_die_bonder_pi(), die_bonder()
    with pytest.raises(InvalidArgumentError, match="choose from"):
        make_interpolator("nope", curve, machine, 1e6)
    with pytest.raises(InvalidArgumentError, match="takes no options"):
        make_interpolator("paper", curve, machine, 1e6, corner_tolerance=1.0)
    with pytest.raises(InvalidArgumentError, match="choose from"):
        make_open_loop("paper", curve, 1e-3, 1e6)  # closed loop only


def test_an_interpolator_registered_from_outside_runs_in_the_loop():
    """A new name over an existing plan type and step: one call, and the factory, the
    names and the loop know it."""

    def make(curve, machine, feed):
        return TaylorInterpolator(curve, machine.sample_period, feed, order=1)

    stepping.register(TaylorPlan, taylor_step, name="test-taylor", make=make)
    try:
        assert "test-taylor" in stepping.interpolator_names()
        curve, machine = nm.make_die_bonder_pi(), die_bonder()
        mine = run(curve, machine, 1e6, "test-taylor")
        reference = run(curve, machine, 1e6, "taylor1")
        np.testing.assert_array_equal(mine.position, reference.position)
    finally:
        del stepping._NAMED["test-taylor"]
    assert "test-taylor" not in stepping.interpolator_names()
