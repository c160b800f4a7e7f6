"""What takes a run's rows as the loop makes them: the sink protocol.

A sink has one method, ``add(first, rows, finished, last)``, called with every block of
rows in order (:func:`nurbsmotion.loop.simulate_streamed`): the block's rows
(:class:`nurbsmotion.loop.closed_loop.Rows`, samples ``first`` on, arrays of their own),
the first sample whose setpoint is the path's end (-1 while there is none) and whether
this is the run's last block. The running metrics
(:class:`nurbsmotion.metrics.RunningMetrics`, :class:`nurbsmotion.metrics.RunningAtRest`)
and the trace file (:class:`nurbsmotion.report.TraceWriter`) are sinks;
:func:`fan_out` hands one block to several, :func:`nurbsmotion.loop.background_sink`
runs them on a thread beside the loop, and :class:`nurbsmotion.job.Job` takes a list.
"""

from __future__ import annotations

from typing import Callable, Iterable, Protocol, runtime_checkable

from ..errors import InvalidArgumentError

__all__ = ["Sink", "fan_out"]


@runtime_checkable
class Sink(Protocol):
    """Anything with ``add(first, rows, finished, last)`` (see the module docstring)."""

    def add(self, first: int, rows, finished: int, last: bool) -> None:
        ...


def fan_out(sinks: Iterable[Sink]) -> Callable[[int, object, int, bool], None]:
    """One callable that hands each block to every sink of ``sinks``, in their order.

    Raises
    ------
    InvalidArgumentError
        Naming the first entry that has no ``add`` method.
    """
    adds = []
    for sink in sinks:
        if not isinstance(sink, Sink):
            raise InvalidArgumentError(
                f"a sink needs a method add(first, rows, finished, last), got {sink!r:.60}")
        adds.append(sink.add)

    def add(first, rows, finished, last):
        for one in adds:
            one(first, rows, finished, last)

    return add
