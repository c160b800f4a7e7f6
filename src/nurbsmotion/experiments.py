"""The paper's experiment, at its old import path: the code lives in
:mod:`nurbsmotion.study.reproduce`; this module re-exports its public names."""

from .study.reproduce import (PAPER_EXPERIMENT, PAPER_INTERPOLATORS, ExperimentResult,
                              reproduce, reproduce_outputs, run_experiment)

__all__ = ["PAPER_EXPERIMENT", "PAPER_INTERPOLATORS", "ExperimentResult", "reproduce",
           "run_experiment", "reproduce_outputs"]
