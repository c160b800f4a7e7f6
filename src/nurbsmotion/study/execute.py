"""Where a study's cases run: serially, on local worker processes, or on a Dask cluster.

:func:`_execute` hands out the cases and yields their rows in the order they finish.
Before any case runs, the compiled kernels the cases use are loaded once per process
(:func:`_warm_up`). The local pool (:class:`_LocalWorkers`) and the Dask executor
(:func:`_execute_dask`) are both fed by one scheduler, :class:`_Planner`, which keeps each
path's cases on one worker (its tables are built once) and steals the tail to balance
them; a case whose worker dies twice is recorded as :data:`WORKER_DIED`. dask is imported
only when used.
"""

from __future__ import annotations

import math
import os
import pickle
import time
from collections import deque
from typing import Callable, Iterable

from ..errors import InvalidArgumentError
from .case import _case_columns, _cpu_limit, _path_key, case_trace, run_case
from .spec import STATUS_ERROR, WORKER_DIED, Case, PlantGroup

__all__ = ["DASK_SETTINGS"]


def _execute(cases: list[Case], workers: int | None, scheduler,
             function: Callable | None = None) -> Iterable[dict]:
    """Rows of ``function`` (:func:`run_case` by default) over ``cases``, in the order
    they finish: serially, on ``workers`` local processes, or on a Dask ``scheduler``.

    Before any case runs, the compiled kernels the cases use are loaded (or compiled) once
    per process (:func:`_warm_up`): here before local workers are forked (they inherit
    them), in every Dask worker when it joins (:func:`_dask_warm_up`).
    """
    function = function or run_case
    if not cases:
        return iter(())
    if scheduler is not None:
        return _execute_dask(cases, scheduler, function)
    n = (os.cpu_count() or 1) if workers is None else int(workers)
    if n < 1:
        raise InvalidArgumentError(f"workers must be >= 1, got {workers!r}")
    _warm_up(cases)
    if n == 1:
        return (function(c) for c in cases)
    return _execute_pool(cases, n, function)


_WARMED: set = set()
"""(interpolator, machine, base folder) of the kernels this process has loaded."""


def _warm_up(cases: list[Case]) -> None:
    """Load the compiled kernels of every (interpolator, machine) of ``cases`` into this
    process: one short random move each (``short_moves``, seed 0, nominal plant, index
    -1: no case of the study; its figures are discarded), so that no case's time includes
    loading or compiling them and forked workers start with them loaded. Errors are left
    to the cases to record."""
    from dataclasses import replace

    for c in cases:
        key = (c.interpolator, c.machine, c.base_dir)
        if key in _WARMED:
            continue
        _WARMED.add(key)
        probe = replace(c, index=-1, path="random:short_moves", path_family="short_moves",
                        path_seed=0, length=2e4, plant=PlantGroup("nominal"))
        try:
            with _cpu_limit(c.time_limit):
                case_trace(probe)
        except Exception:  # noqa: BLE001 - the real cases record their own errors
            pass


def _run_batch(function: Callable, batch: list[Case]) -> bytes:
    """A Dask task: the rows of ``batch``, pickled together. Dask measures (``sizeof``)
    and serializes a task's result on the worker, and the scheduler forwards it: a bytes
    object costs it next to nothing, a list of dicts of some 70 keys each is walked key by
    key (about a millisecond of the worker's CPU time for a task's rows)."""
    return pickle.dumps([function(c) for c in batch], protocol=pickle.HIGHEST_PROTOCOL)


_CHUNK_SECONDS = 0.25
"""Measured work [CPU s] given to a worker at a time (at least one case), its rows sent
back together: an exchange with a local worker cost about a millisecond of CPU time
(measured on a 2-core virtual machine), 2-5 % of a 20-50 ms case."""

_DASK_CHUNK_SECONDS = 1.0
"""The same for a Dask task, which costs the scheduler, the worker and this process
several milliseconds of CPU time (about 3 ms in the client and a LocalCluster's
scheduler, 2.5 ms in the worker, measured on 200 tasks of 50 rows on a 2-core VM)."""

_MIN_CHUNK_SHARE = 0.1
"""The smallest chunk toward the end, as a share of a full one (at least one case): the
last chunks are cut to balance the workers, but an exchange costs the same for a few
milliseconds of cases as for a full chunk (a Dask task of one 20 ms case: about 5 ms of
CPU time in the scheduler, the worker and this process)."""

_DASK_WORKERS_SECONDS = 5.0
"""How often a campaign on Dask asks the scheduler which workers it has [s]: a worker
that joins gets work within this time, and the campaign does not add a round trip
through the scheduler (whose answer grows with the cluster) to every task."""

_TAIL_SECONDS = 0.05
"""Once every path has been given out, a worker is sent its next chunk before it ends
the one it runs only if its cases are shorter than this [CPU s]: a long case sent ahead
could no longer go to a worker that runs out of work."""


def _execute_pool(cases: list[Case], n_workers: int, function: Callable) -> Iterable[dict]:
    """Rows of ``function`` over ``cases`` on ``n_workers`` local processes
    (:class:`_LocalWorkers`), in the order they finish. Ctrl-C, SIGTERM or an error here
    stops the workers at once (the cases in flight are dropped: resume runs them)."""
    pool = _LocalWorkers(cases, n_workers, function)
    finished = False
    try:
        yield from pool.rows()
        finished = True
    finally:
        pool.close(wait=finished)


class _Slot:
    """What :class:`_Planner` knows of a worker: ``own``, the cases given to it and not
    sent yet; ``sent``, the cases sent to it, in order (the first one running); ``warm``,
    the paths whose tables it has built; ``retry``, a case it runs again alone;
    ``chunks``, the sizes of the chunks in flight."""

    def __init__(self):
        self.own: deque = deque()
        self.sent: deque = deque()
        self.warm: set = set()
        self.retry: Case | None = None
        self.chunks: deque = deque()


class _Planner:
    """Which cases a worker runs next, so that each path's tables are built once.

    The cases are grouped by path (:func:`_path_key`; the groups in the order of their
    first case). A worker that needs work takes the next path whole. When none is left,
    it takes the last cases another worker holds and has not started (:meth:`_steal`):
    as many as balance the two, counting that it builds the path's tables again, and
    none when that would not end sooner, so that the workers finish together without
    building a path's tables twice for a few cases. The case time and the tables' time
    are measured from the rows so far (``case_cpu_s``). A worker is given about
    ``chunk_seconds`` of work at a time, less toward the end: the rest of a path, and
    whole paths after it while they fit (their tables counted).
    """

    def __init__(self, cases: list[Case], chunk_seconds: float = _CHUNK_SECONDS):
        self.chunk_seconds = chunk_seconds
        groups: dict = {}
        for c in cases:
            groups.setdefault(_path_key(c), []).append(c)
        self.paths = deque(groups.values())
        self.left = len(cases)  # cases not sent yet
        self.path_cpu: dict = {}  # path key -> [sum, count]: CPU s of its warm cases
        self.cpu = [0.0, 0, 0.0, 0]  # CPU s and count of the cold cases, of the warm ones
        self.cold: set = set()  # ids of cases sent to a worker without the path's tables

    def case_time(self, key) -> float | None:
        """Expected CPU time of a case on path ``key`` once its tables exist [s]: the
        mean over its cases so far, shrunk toward the mean over all paths as if that
        were two more of them (a path's cases differ by feed and interpolator: its first
        few say little)."""
        if not self.cpu[3]:
            return None
        total, n = self.path_cpu.get(key, (0.0, 0))
        return (total + 2 * self.cpu[2] / self.cpu[3]) / (n + 2)

    def table_time(self) -> float:
        """Expected extra CPU time of the first case of a path on a worker [s]."""
        if not (self.cpu[1] and self.cpu[3]):
            return 0.0
        return max(0.0, self.cpu[0] / self.cpu[1] - self.cpu[2] / self.cpu[3])

    def record(self, case: Case, row: dict) -> None:
        """Learn from a finished case's row."""
        cold = case.case_id in self.cold
        self.cold.discard(case.case_id)
        cpu = row.get("case_cpu_s")
        if not isinstance(cpu, float) or not math.isfinite(cpu):
            return
        if cold:
            self.cpu[0] += cpu
            self.cpu[1] += 1
        else:
            self.cpu[2] += cpu
            self.cpu[3] += 1
            entry = self.path_cpu.setdefault(_path_key(case), [0.0, 0])
            entry[0] += cpu
            entry[1] += 1

    def ahead(self, slot: _Slot) -> bool:
        """Whether ``slot`` should hold a chunk beyond the one it runs: yes while paths
        are left to give out, or while its cases are short; at the end, a long case sent
        ahead could no longer go to a worker that runs out of work."""
        if self.paths:
            return True
        queue = slot.own or slot.sent
        c = self.case_time(_path_key(queue[-1])) if queue else None
        return c is None or c <= _TAIL_SECONDS

    def fill(self, slot: _Slot, slots: list[_Slot]) -> Iterable[list[Case]]:
        """The chunks to send ``slot`` now (each taken by :meth:`next_chunk`): until it
        holds one beyond the one it runs (see :meth:`ahead`), or nothing is left for it."""
        while len(slot.chunks) < (2 if self.ahead(slot) else 1):
            chunk = self.next_chunk(slot, slots)
            if not chunk:
                return
            yield chunk

    def next_chunk(self, slot: _Slot, slots: list[_Slot]) -> list[Case]:
        """The next cases for ``slot`` (moved to its ``sent``), or ``[]``: all given out,
        or the rest is better left where it is."""
        if not slot.own:
            if self.paths:
                slot.own.extend(self.paths.popleft())
            elif not self._steal(slot, slots):
                return []
        c = self.case_time(_path_key(slot.own[0]))
        table = self.table_time()
        # No more than a share of the work left, the tables of the paths not given out
        # counted (guided self-scheduling): the chunks shrink toward the end, where their
        # cases could no longer be shared out; but not below a tenth of a full chunk,
        # whose exchange would then cost more than the last imbalance it can save.
        left = self.left * (c or 0.0) + len(self.paths) * table
        seconds = max(min(self.chunk_seconds, left / (4 * len(slots))),
                      self.chunk_seconds * _MIN_CHUNK_SHARE)
        size = 1 if not c else max(1, min(len(slot.own), int(seconds / c)))
        chunk = [slot.own.popleft() for _ in range(size)]
        # A path that ends within the chunk leaves room for the next paths, whole, while
        # their cases and tables fit too: a campaign of paths with a few short cases each
        # is not sent a path at a time.
        spent = size * (c or 0.0)
        while c and not slot.own and self.paths:
            key = _path_key(self.paths[0][0])
            n, c_next = len(self.paths[0]), self.case_time(key)
            extra = table + n * c_next  # a path not given out yet: no worker has its tables
            if spent + extra > seconds:
                break
            chunk += self.paths.popleft()
            spent += extra
        self.left -= len(chunk)
        for case in chunk:
            key = _path_key(case)
            if key not in slot.warm:
                slot.warm.add(key)
                self.cold.add(case.case_id)
        slot.sent.extend(chunk)
        slot.chunks.append(len(chunk))
        return chunk

    def _steal(self, thief: _Slot, slots: list[_Slot]) -> bool:
        """Move to ``thief`` the last unstarted cases of the worker with the most work
        left: ``h`` of the ``k`` it holds (``s`` more sent to it) such that both end
        together, ``T + h c = (k + s - h) c + T'`` (``c`` a case's time on that path,
        ``T`` the thief's cost of building the path's tables, 0 if it has them, ``T'``
        the same for the other worker if its first case on the path is still running),
        when ``h >= 1``; one case when that is a close call (at least two unstarted cases
        and half ``T`` of work left there): the estimates are rough, and an idle worker
        risks only ``T``."""
        table = self.table_time()
        best, best_work = None, 0.0
        for w in slots:
            if w is thief or not w.own:
                continue
            c = self.case_time(_path_key(w.own[-1]))
            building = table if any(x.case_id in self.cold for x in w.sent) else 0.0
            work = (len(w.own) + len(w.sent)) * (c if c is not None else 1.0) + building
            if work > best_work:
                best, best_work, best_building = w, work, building
        if best is None:
            return False
        key = _path_key(best.own[-1])
        k, s = len(best.own), len(best.sent)
        c = self.case_time(key)
        mine = 0.0 if key in thief.warm else table
        h = min(k, int((k + s + ((best_building - mine) / c if c else 0.0)) / 2 + 0.5))
        if h < 1 and k >= 2 and best_work >= mine / 2:
            h = 1  # a close call: the estimates are rough, being idle is sure
        if h < 1:
            return False
        stolen = [best.own.pop() for _ in range(h)]
        thief.own.extend(reversed(stolen))
        return True


class _LocalWorker(_Slot):
    """A local worker process and the pipe to it."""

    def __init__(self, index: int, parent: int, function: Callable):
        super().__init__()
        self.index, self.parent, self.function = index, parent, function
        self.start()

    def start(self) -> None:
        """A fresh process (forked where the platform forks: it inherits the loaded
        kernels) with no path tables yet."""
        ctx = _mp_context()
        self.conn, child = ctx.Pipe()
        self.running = ctx.RawValue("q", 0)  # place in its chunk of the case it runs
        self.process = ctx.Process(target=_worker_loop,
                                   args=(child, self.running, self.parent, self.function),
                                   daemon=True, name=f"nurbsmotion-campaign-{self.index}")
        self.process.start()
        child.close()
        self.warm = set()

    def send(self, chunk: list[Case]) -> None:
        try:
            self.conn.send(chunk)
        except OSError:  # it died: its sentinel says so next
            pass


def _worker_loop(conn, running, parent: int, function: Callable) -> None:
    """In a local worker: run the cases of each chunk received (``running`` holding the
    place of the case it runs, for the campaign to know which one killed it) and send
    back the chunk's rows together, each ``("row", row)``, or ``("error", message)``
    when ``function`` raised or its row could not be sent; until ``None`` or the pipe
    closes."""
    _worker_start(parent)
    while True:
        try:
            chunk = conn.recv()
        except (EOFError, OSError):
            return
        if chunk is None:
            return
        out = []
        for k, case in enumerate(chunk):
            running.value = k
            try:
                out.append(("row", function(case)))
            except Exception as exc:  # noqa: BLE001 - reported as the case's row
                out.append(("error", f"{type(exc).__name__}: {exc}"))
        try:
            try:
                conn.send(out)
            except (pickle.PicklingError, TypeError, AttributeError):
                conn.send([_sendable(m) for m in out])
        except (BrokenPipeError, EOFError, OSError):
            return


def _sendable(message: tuple) -> tuple:
    """``message``, or an error message if it cannot be pickled."""
    try:
        pickle.dumps(message)
    except Exception as exc:  # noqa: BLE001
        return ("error", f"{type(exc).__name__}: {exc}")
    return message


class _LocalWorkers:
    """Local worker processes fed by a :class:`_Planner`, each a chunk ahead (so that
    it does not wait for this process) but at the very end; their rows come back one by
    one.

    A worker that dies is replaced by a fresh process, which first runs the case the dead
    one was running, alone (``attempts`` = 2); if it dies too, the case is recorded as
    :data:`WORKER_DIED`. The cases the dead worker had not started go on as before.
    """

    def __init__(self, cases: list[Case], n_workers: int, function: Callable):
        self.planner = _Planner(cases)
        self.workers = [_LocalWorker(k, os.getpid(), function)
                        for k in range(min(n_workers, len(cases)))]

    def _feed(self, w: _LocalWorker) -> None:
        """Keep ``w`` a chunk ahead (a case being retried runs alone)."""
        if w.retry is not None:
            if not w.sent:
                w.sent.append(w.retry)
                w.chunks.append(1)
                w.send([w.retry])
            return
        for chunk in self.planner.fill(w, self.workers):
            w.send(chunk)

    def rows(self) -> Iterable[dict]:
        from multiprocessing.connection import wait

        for w in self.workers:
            self._feed(w)
        while True:
            busy = [w for w in self.workers if w.sent]
            if not busy:
                return
            waiting = {}
            for w in busy:
                waiting[w.conn] = waiting[w.process.sentinel] = w
            for w in {id(waiting[r]): waiting[r] for r in wait(list(waiting))}.values():
                yield from self._receive(w)
                self._feed(w)
            for w in self.workers:  # a worker idle since the last paths ran out
                if not w.sent:
                    self._feed(w)

    def _receive(self, w: _LocalWorker) -> Iterable[dict]:
        """The rows ``w`` has sent; if it died, its replacement, and the row of a case
        that killed two processes."""
        try:
            while w.sent and w.conn.poll():
                messages = w.conn.recv()
                w.chunks.popleft()
                for kind, payload in messages:
                    case = w.sent.popleft()
                    row = payload if kind == "row" else _died(case, payload)
                    if w.retry is not None:
                        row["attempts"], w.retry = 2, None
                    self.planner.record(case, row)
                    yield row
        except (EOFError, OSError):  # it is exiting: its pipe closed first
            w.process.join(timeout=10)
        if not w.sent or w.process.is_alive():
            return
        w.process.join()
        w.conn.close()
        # The case it was running; those of its chunk before it ran, but their rows were
        # not sent: they run again, as do the ones it had not started.
        k = min(max(0, w.running.value), w.chunks[0] - 1)
        case = w.sent[k]
        del w.sent[k]
        w.own.extendleft(reversed(w.sent))
        self.planner.left += len(w.sent)
        w.sent.clear()
        w.chunks.clear()
        for c in w.own:
            self.planner.cold.discard(c.case_id)
        self.planner.cold.discard(case.case_id)
        if w.retry is not None:
            w.retry = None
            row = _died(case, "its worker process died twice while running it")
            row["attempts"] = 2
            yield row
        else:
            w.retry = case
        w.start()

    def close(self, wait: bool) -> None:
        """End the workers: asked to stop after their work (``wait``), or killed."""
        for w in self.workers:
            if wait:
                try:
                    w.conn.send(None)
                except OSError:
                    pass
            else:
                w.process.kill()
        for w in self.workers:
            w.process.join(timeout=None if wait else 5)
            if w.process.is_alive():  # pragma: no cover
                w.process.kill()
                w.process.join()
            w.conn.close()


def _worker_start(parent: int) -> None:
    """In a local worker: Ctrl-C and SIGTERM are the campaign's to handle (it stops its
    workers, :meth:`_LocalWorkers.close`), and the worker exits as soon as the campaign's
    process is gone (killed with SIGKILL, it cannot stop them, and they would wait for
    work forever)."""
    import signal
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="orphan-guard", daemon=True).start()


def _mp_context():
    import multiprocessing

    return multiprocessing.get_context()



def _died(case: Case, message: str) -> dict:
    """The row of a case whose worker did not return a row."""
    row = _case_columns(case)
    row.update(status=STATUS_ERROR, error_type=WORKER_DIED, error_message=message,
               case_time_s=math.nan, case_cpu_s=math.nan)
    return row


DASK_SETTINGS = {"distributed.worker.profile.enabled": False,
                 "distributed.admin.tick.interval": "1s",
                 "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
"""Dask settings a campaign's cluster runs best with: ``dask.config.set(DASK_SETTINGS)``
before starting a ``LocalCluster``, or the configuration file of ``docs/campaign.md`` for
``dask scheduler`` and ``dask worker``. Every Dask worker samples its task's stack 100
times a second for the dashboard's profile (5-8 ms of its event loop's CPU time a second,
measured on a 2-core VM), and every scheduler, nanny and worker wakes 50 times a second
to time its event loop (a few ms of CPU a second each): a 2-worker LocalCluster at rest
uses 47-57 ms of CPU a second with Dask's defaults, 22-27 ms with these. And Dask's
nannies start their workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which turns off
glibc's adaptive mmap threshold: every array over 128 KiB is then mapped and unmapped
afresh, and a case took 9-13 % more CPU time than in a plain process (0.99-1.03 times
the serial run's without it, on the 1,000-case study). On a campaign's ~1 s tasks of
CPU-bound cases, none of these tells anything the task's own times do not, and the
workers then allocate as the serial and local runs do."""


def _execute_dask(cases: list[Case], scheduler, function: Callable) -> Iterable[dict]:
    """On a Dask cluster, fed by a :class:`_Planner` as the local workers are: one slot
    per worker thread, each with a task queued behind the one it runs but at the very
    end (tasks bound to that worker, but free to run on another if it leaves); rows
    gathered here as the tasks finish. A task whose worker died (Dask's
    ``KilledWorker``, after the scheduler's ``allowed-failures``) is split: each of its
    cases runs again alone, and a case whose worker dies again is recorded as
    :data:`WORKER_DIED`."""
    from dask.distributed import Client, as_completed

    client = scheduler if isinstance(scheduler, Client) else Client(scheduler)
    try:
        _dask_warm_up(client, cases)
        client.wait_for_workers(1)
        planner = _Planner(cases, _DASK_CHUNK_SECONDS)
        slots: dict = {}  # (worker address, thread) -> _Slot
        tasks: dict = {}  # future key -> (slot or None for a case alone, its cases)
        done = as_completed()

        asked = [-math.inf]  # when the scheduler was last asked for its workers

        def feed() -> None:
            if time.monotonic() - asked[0] >= _DASK_WORKERS_SECONDS:
                asked[0] = time.monotonic()
                for addr, nthreads in client.nthreads().items():
                    for k in range(nthreads):
                        slots.setdefault((addr, k), _Slot())
            order = list(slots.values())
            for (addr, _), slot in slots.items():
                for chunk in planner.fill(slot, order):
                    fut = client.submit(_run_batch, function, chunk, workers=[addr],
                                        allow_other_workers=True, retries=1, pure=False)
                    tasks[fut.key] = (slot, chunk)
                    done.add(fut)

        feed()
        for fut in done:
            slot, chunk = tasks.pop(fut.key)
            if slot is not None:
                slot.chunks.remove(len(chunk))
                ids = {c.case_id for c in chunk}
                slot.sent = deque(c for c in slot.sent if c.case_id not in ids)
            try:
                rows = pickle.loads(fut.result())
            except Exception as exc:  # KilledWorker, or a result that cannot be sent
                if len(chunk) > 1:
                    for case in chunk:
                        again = client.submit(_run_batch, function, [case], pure=False)
                        tasks[again.key] = (None, [case])
                        done.add(again)
                    rows = []
                else:
                    rows = [_died(chunk[0], f"{type(exc).__name__}: {exc}")]
                    rows[0]["attempts"] = 2
            fut.release()
            for case, row in zip(chunk, rows):
                planner.record(case, row)
                yield row
            feed()
    finally:
        if client is not scheduler:
            client.close()


def _dask_warm_up(client, cases: list[Case]) -> None:
    """Every worker of the cluster, now or when it joins, runs :func:`_warm_up` for the
    cases' interpolators and machines once (a worker plugin, run in a thread so the
    worker keeps answering the scheduler while it compiles)."""
    import asyncio

    from distributed import WorkerPlugin

    probes = list({(c.interpolator, c.machine, c.base_dir): c for c in cases}.values())

    class WarmUp(WorkerPlugin):
        async def setup(self, worker):
            await asyncio.to_thread(_warm_up, probes)

    client.register_plugin(WarmUp(), name="nurbsmotion-warm-up")
