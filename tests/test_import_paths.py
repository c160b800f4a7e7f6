"""Old import paths keep working after a module moved (issue 31): each old path gives
the very objects of the new one."""

import importlib


def _same(old: str, new: str, names) -> None:
    old_module, new_module = importlib.import_module(old), importlib.import_module(new)
    for name in names:
        assert getattr(old_module, name) is getattr(new_module, name), name


def test_loop():
    # nurbsmotion.loop became a package: its results moved to loop.trace, and the run
    # functions stay in the package itself.
    import nurbsmotion.loop as loop

    _same("nurbsmotion.loop", "nurbsmotion.loop.trace", ["Trace", "RunOutcome", "SetpointSeries"])
    assert set(loop.__all__) <= set(dir(loop))


def test_export():
    from nurbsmotion.report import export

    _same("nurbsmotion.export", "nurbsmotion.report.export", export.__all__)


def test_report():
    # the trace file's writer moved to report.trace_file; nurbsmotion.report keeps its names
    from nurbsmotion.report import trace_file

    _same("nurbsmotion.report", "nurbsmotion.report.trace_file", trace_file.__all__[:2] + trace_file.__all__[3:])


def test_plots():
    # plots.py became a package (canvas, events, figures); its public names stay here
    import nurbsmotion.plots as plots

    _same("nurbsmotion.plots", "nurbsmotion.plots.figures",
          set(plots.__all__) - {"settling_time", "MAX_EVENT_WINDOWS"})
    _same("nurbsmotion.plots", "nurbsmotion.plots.events", ["settling_time", "MAX_EVENT_WINDOWS"])
