"""Work in forked processes: a worker forked early that prepares, then runs one call
(:class:`ForkedWorker`), and a list of calls shared between this process and forked ones
(:func:`call_forked`) (private).

Why: a command's figures need matplotlib (a few tenths of a second to import) and the
path's figure data before the run's trace exists, and drawing them is CPU work that a
second core can share. A process forked before the run imports and prepares on the other
core while the run goes on here; when the trace is there it is sent over a pipe and the
figures are drawn there, split between that process and one it forks, while this one
writes the trace file and the summary. ``reproduce`` shares its comparisons' figures the
same way (:func:`call_forked`): one mechanism for both.

Both need ``os.fork`` (Linux, macOS); without it the calls run here, one after the other,
with the same results. A forked process never returns into its parent's stack: it ends
with ``os._exit`` (no ``finally`` of the caller, no atexit handler, no buffered output of
the parent written twice). It ignores SIGINT (the parent, which gets the terminal's
Ctrl-C, ends it) and takes SIGTERM's default action. An exception in a forked call is sent
back and raised again by the caller, with the forked process's traceback as a note.
"""

from __future__ import annotations

import gc
import os
import pickle
import signal
import struct
import sys
from typing import Any, Callable, Sequence

__all__ = ["ForkedWorker", "call_forked", "can_fork", "usable_cpus"]

_HEADER = struct.Struct("<Q")  # the length of a message [byte]


def can_fork() -> bool:
    """This platform forks (``os.fork`` exists)."""
    return hasattr(os, "fork")


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity where the platform tells it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def _write_all(fd: int, data) -> None:
    view = memoryview(data).cast("B")
    while view:
        view = view[os.write(fd, view):]


def _read_exact(fd: int, n: int) -> bytes | None:
    """``n`` bytes from ``fd``, or None at the end of the pipe before them."""
    parts, got = [], 0
    while got < n:
        chunk = os.read(fd, min(n - got, 1 << 24))
        if not chunk:
            return None
        parts.append(chunk)
        got += len(chunk)
    return b"".join(parts)


def _send(fd: int, payload: bytes) -> None:
    _write_all(fd, _HEADER.pack(len(payload)))
    _write_all(fd, payload)


def _receive(fd: int) -> bytes | None:
    """One message, or None when the writer ended without sending one."""
    header = _read_exact(fd, _HEADER.size)
    return None if header is None else _read_exact(fd, _HEADER.unpack(header)[0])


def _outcome(call: Callable[[], Any]) -> tuple[bool, Any]:
    """``(True, result)`` of ``call()`` or ``(False, (exception, traceback text))``."""
    try:
        return True, call()
    except BaseException as exc:  # sent to the caller, which raises it again
        import traceback

        return False, (exc, "".join(traceback.format_exception(exc)))


def _pickled_outcome(outcome: tuple[bool, Any]) -> bytes:
    """``outcome`` pickled, checked to unpickle (an exception class whose constructor
    takes other arguments than its ``args`` pickles but does not unpickle)."""
    try:
        data = pickle.dumps(outcome, protocol=pickle.HIGHEST_PROTOCOL)
        pickle.loads(data)
        return data
    except Exception as exc:  # an unpicklable result or exception: its text
        ok, value = outcome
        text = value[1] if not ok else f"its result could not be sent back: {exc!r}"
        return pickle.dumps((False, (RuntimeError(text), text)))


def _reraise(value) -> None:
    exc, text = value
    if hasattr(exc, "add_note"):
        exc.add_note(f"in the forked process:\n{text}")
    raise exc


def _fork_child() -> int:
    """``os.fork`` with this process's standard streams flushed first (so that nothing
    buffered is written twice); in the child, the signals as the module says."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    # What exists now is frozen across the fork (Python's advice for a fork without exec,
    # gc.freeze): the child's collections skip every object it inherits (numba's, scipy's,
    # matplotlib's), so they neither spend its time traversing them nor touch, hence
    # copy, their pages; the parent unfreezes at once and collects as before (unless it
    # had frozen objects itself: a forked process that forks again keeps its own frozen).
    unfreeze = gc.get_freeze_count() == 0
    gc.freeze()
    try:
        pid = os.fork()
    except BaseException:
        if unfreeze:
            gc.unfreeze()
        raise
    if pid == 0:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    elif unfreeze:
        gc.unfreeze()
    return pid


def call_forked(calls: Sequence[Callable[[], Any]], processes: int,
                done: Callable[[int], None] | None = None) -> list:
    """``[call() for call in calls]``, shared between this process and ``processes - 1``
    forked ones: each takes the next call as soon as it is free, so a slow call (or a
    busy core) does not hold the others back.

    Parameters
    ----------
    calls : sequence of callable
        At most 255 calls without arguments; what they return must pickle.
    processes : int
        Processes that call them, this one included; 1 (or a platform that does not fork)
        calls them here, in order.
    done : callable, optional
        ``done(index)`` here, in the order of ``calls``, once ``calls[index]`` and every
        call before it have returned (a progress bar): between the calls this process
        takes, then as the forked processes report.

    Returns
    -------
    list
        The results in the order of ``calls``. The first call that raised (in list order)
        raises here, after every process has ended. The calls a forked process took and
        could not report (it was killed) are called here.
    """
    processes = min(int(processes), len(calls))
    outcomes: dict = {}
    reported = 0  # done() was called for calls[:reported]

    def report() -> None:
        nonlocal reported
        while done is not None and reported in outcomes and outcomes[reported][0]:
            done(reported)
            reported += 1

    if processes <= 1 or not can_fork() or len(calls) > 255:
        for index, call in enumerate(calls):
            outcomes[index] = _outcome(call)
            report()
        return _results(calls, outcomes)
    queue_r, queue_w = os.pipe()  # one byte per call: a read takes exactly one
    _write_all(queue_w, bytes(range(len(calls))))
    os.close(queue_w)
    children: dict[int, int] = {}  # read end of its reports -> pid

    def collect(wait: bool) -> None:
        """The reports of the forked processes that have one ready (with ``wait``, until
        each has ended); one message per call, ``(index, outcome)``, pickled."""
        import select

        while children:
            ready, _, _ = select.select(list(children), [], [], None if wait else 0)
            if not ready:
                return
            for fd in ready:
                message = _receive(fd)
                if message is None:  # it has ended (or was killed): reap it
                    os.close(fd)
                    os.waitpid(children.pop(fd), 0)
                    continue
                index, outcome = pickle.loads(message)
                outcomes[index] = pickle.loads(outcome)

    try:
        for _ in range(processes - 1):
            result_r, result_w = os.pipe()
            pid = _fork_child()
            if pid == 0:  # the child: take calls, report each as it returns, end
                code = 1
                try:
                    os.close(result_r)
                    for fd in children:  # the reports of its siblings are not its own
                        os.close(fd)
                    while index := os.read(queue_r, 1):
                        outcome = _pickled_outcome(_outcome(calls[index[0]]))
                        _send(result_w, pickle.dumps((index[0], outcome)))
                    code = 0
                finally:
                    os._exit(code)
            os.close(result_w)
            children[result_r] = pid
        while index := os.read(queue_r, 1):
            outcomes[index[0]] = _outcome(calls[index[0]])
            collect(wait=False)
            report()
        collect(wait=True)
    except BaseException:
        for pid in children.values():
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        raise
    finally:
        os.close(queue_r)
        for fd, pid in list(children.items()):  # after an error: what they sent, then reap
            while (message := _receive(fd)) is not None:
                index, outcome = pickle.loads(message)
                outcomes[index] = pickle.loads(outcome)
            os.close(fd)
            os.waitpid(pid, 0)
        children.clear()
    for index in range(len(calls)):
        if index not in outcomes:  # taken by a process that was ended: called here
            outcomes[index] = _outcome(calls[index])
        report()
    return _results(calls, outcomes)


def _results(calls, outcomes: dict) -> list:
    """The results of ``calls`` in order from their outcomes; the first error raised."""
    results = []
    for index in range(len(calls)):
        ok, value = outcomes[index]
        if not ok:
            _reraise(value)
        results.append(value)
    return results


def _prepare_until_called(prepare: Callable[[], Any], call_r: int) -> None:
    """``prepare()``; where it returns an iterator, its steps while nothing is waiting on
    ``call_r`` (the call, or the end of a parent that went on without one): the call is
    not held up by preparation it may no longer need."""
    steps = prepare()
    if not hasattr(steps, "__next__"):
        return
    import select

    try:
        for _ in steps:
            if select.select([call_r], [], [], 0)[0]:
                return
    finally:
        if hasattr(steps, "close"):
            steps.close()


class ForkedWorker:
    """A process forked now that runs ``prepare()`` at once, then one call sent to it
    later (:meth:`submit`), whose result :meth:`result` returns. A context manager: the
    process (and any it forked) is ended on exit if it still runs.

    Parameters
    ----------
    prepare : callable, optional
        Run in the worker right after the fork, while this process goes on: work the
        call will find done (imports, caches). Where it returns an iterator (a
        generator), the worker advances it one step at a time and stops as soon as the
        call has arrived: what was not prepared by then is the call's to do. An
        exception in it is ignored (the call meets the same problem and raises it where
        it matters).
    shared : sequence, optional
        Objects both processes hold from the fork on (a path, a machine): sent by
        reference, so the call gets the very objects ``prepare`` used (their caches
        included), not copies.
    enabled : bool
        False (or a platform that does not fork): no process; the call runs here, in
        :meth:`result`, as it does when the worker ended (was killed) before its result.
    """

    def __init__(self, prepare: Callable[[], Any] | None = None, shared: Sequence = (),
                 enabled: bool = True):
        self.pid: int | None = None
        self._shared = list(shared)
        self._call: tuple | None = None
        self._submitted = False
        self._sender = None  # the thread that writes the call into the pipe
        if not (enabled and can_fork()):
            return
        call_r, call_w = os.pipe()
        result_r, result_w = os.pipe()
        try:
            pid = _fork_child()
        except OSError:  # no process to spare: everything runs here
            for fd in (call_r, call_w, result_r, result_w):
                os.close(fd)
            return
        if pid == 0:
            code = 1
            try:
                os.setpgid(0, 0)  # a group of its own: stop() ends its forks too
                os.close(call_w)
                os.close(result_r)
                self._serve(prepare, call_r, result_w)
                code = 0
            finally:
                os._exit(code)
        try:
            os.setpgid(pid, pid)  # also here: stop() may come before the child's own
        except OSError:  # it has done it already (or ended)
            pass
        os.close(call_r)
        os.close(result_w)
        self.pid, self._call_w, self._result_r = pid, call_w, result_r

    def _serve(self, prepare, call_r: int, result_w: int) -> None:
        if prepare is not None:
            _outcome(lambda: _prepare_until_called(prepare, call_r))
        message = _receive(call_r)
        if message is None:  # the parent went on without a call
            return
        shared = self._shared

        class _Unpickler(pickle.Unpickler):
            def persistent_load(self, pid):
                return shared[pid]

        import io

        fn, args, kwargs = _Unpickler(io.BytesIO(message)).load()
        _send(result_w, _pickled_outcome(_outcome(lambda: fn(*args, **kwargs))))

    def submit(self, fn: Callable, *args, **kwargs) -> None:
        """Send ``fn(*args, **kwargs)`` to the worker; :meth:`result` calls it here
        instead when there is no worker, it has ended, or the call does not pickle (a
        local function, an open file): the same result, without the other core."""
        if self._submitted:
            raise RuntimeError("a ForkedWorker runs one call")
        self._submitted = True
        self._call = (fn, args, kwargs)
        if self.pid is None:
            return
        import io

        ids = {id(obj): n for n, obj in enumerate(self._shared)}

        class _Pickler(pickle.Pickler):
            def persistent_id(self, obj):
                return ids.get(id(obj))

        buffer = io.BytesIO()
        try:
            _Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(self._call)
        except (pickle.PicklingError, AttributeError, TypeError):  # result() calls it here
            self.stop()
            return

        def send() -> None:
            try:
                _send(self._call_w, buffer.getbuffer())
            except BrokenPipeError:  # the worker has ended: result() calls it here
                pass

        # A pipe holds 64 KiB: the rest goes while the worker reads it, which it does
        # once it has prepared; meanwhile this process goes on.
        import threading

        self._sender = threading.Thread(target=send, name="ForkedWorker.submit",
                                        daemon=True)
        self._sender.start()

    def result(self):
        """What the call returned (waiting for it); raises what it raised. A worker that
        ended without a result (killed) leaves the call to this process."""
        if not self._submitted:
            raise RuntimeError("ForkedWorker.result before submit")
        message = None
        if self.pid is not None:
            message = _receive(self._result_r)  # None when it ended without a result
            self._reap()
        fn, args, kwargs = self._call
        self._call = None
        if message is None:  # no worker, or it ended without a result: here and now
            return fn(*args, **kwargs)
        ok, value = pickle.loads(message)
        if not ok:
            _reraise(value)
        return value

    def _reap(self) -> None:
        """Wait for the worker's end (and for the call to be sent or refused)."""
        pid, self.pid = self.pid, None
        os.waitpid(pid, 0)
        if self._sender is not None:  # the worker has ended: the write has returned
            self._sender.join()
            self._sender = None
        for fd in (self._call_w, self._result_r):
            os.close(fd)

    def stop(self) -> None:
        """End the worker and what it forked, if it still runs, and reap it."""
        if self.pid is None:
            return
        try:
            os.killpg(self.pid, signal.SIGTERM)
        except (ProcessLookupError, PermissionError):
            pass
        self._reap()

    def __enter__(self) -> "ForkedWorker":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
