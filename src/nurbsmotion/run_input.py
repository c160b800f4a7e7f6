"""What a run of a named path reads, at its old import path: the code lives in
:mod:`nurbsmotion.study.run_input`; this module re-exports its public names."""

from .study.run_input import load_run_contour, path_axes, programmed_feed, run_feed

__all__ = ["path_axes", "load_run_contour", "programmed_feed", "run_feed"]
