"""Step 6 of the plan (:mod:`.plan`): short moves re-timed from stop to stop by sequential
linear programming over the drives and the plant's sampled states (:func:`_shorten_pieces`,
:func:`_shorten`, :func:`_shorten_at`; HiGHS warm-started through :class:`_WarmProgram`), and
the path tolerance it may use (:data:`nurbsmotion.limits.DEFAULT_PATH_TOLERANCE`,
:func:`move_tolerance`).
"""

from __future__ import annotations

import math

import numpy as np

from ...feed import FeedLimit
from ...limits import DEFAULT_PATH_TOLERANCE, SHORT_MOVE_SAMPLES  # noqa: F401  (step 6's
# default path tolerance and short-move length, read here as before; defined in limits)
from ...machine import Machine
from ...nurbs import NurbsCurve
from ...servo import ServoPlant, zoh_coefficients
from .inverse import END_REST, LEAD, PRECOMPENSATION_TOLERANCE
from .landing import FEED_SLACK, _feed_at, _nearest_forward, _Span


CHECK_POINTS = 32
"""Most points per sample at which step 6 checks a move's distance to the path (as many
as put the path's chord between two of them within the tolerance at the feed; the
linear programs hold the samples, the half samples and the points found off the path)."""

SHORTEN_ROUNDS = 24
"""Most linear programs step 6 solves for one arrival sample (each re-linearises the path
at the motion's nearest points)."""

SHORTEN_STALL = 8
"""Step 6 gives up an arrival sample when this many rounds in a row bring the motion's
farthest point from the path no nearer than the nearest it has been."""

SHORTEN_START = 1
"""Step 6 starts its search for a piece's arrival this many samples after the piece's
continuous time-optimal duration (rounded up; :func:`planning.speed_profile` before any
easing), not at the plan's arrival, and runs down from there to that duration; where
none is found at the start, down from the plan's arrival: a short move's earliest
arrival lies within a sample or two of that duration, and each sample it need not step
down from costs one or more linear programs (on six 60-120 mm free-form moves at 1.7 m/s
the plan arrived 1-10 samples later, and the search from there took 10-71 programs; on
the first 300 cases of ``benchmarks/planner_sweep.py``, searched all the way down, 11 of
294 pieces arrived a sample before the duration rounded up, and one two samples before)."""

SHORTEN_BELOW_ROUNDS = 2
"""Most linear programs step 6 solves, per trust region, for an arrival sample before the
piece's continuous time-optimal duration (rounded up to whole samples): the plant then
has to leave the path by up to the path tolerance to arrive sooner, which the first
program, started from the motion found a sample later and compressed by one, finds at
once or, after one re-linearisation, in the second; past that the rounds only spend
programs on a sample that a motion on the path cannot have. The second only where the
first program's largest normal offset E is within the tolerance (its motion then strays
between the held points, which a re-linearisation may mend): an E beyond it says that
even the linearised path is not followed that fast. On cases 0-189 of
``benchmarks/planner_sweep.py`` 79 such second programs (after a first E of 1.9 to 2,500
times the tolerance) found no motion, and the 4 motions found below the duration were
found by the first program (E at most 0.094 times the tolerance)."""

DEFAULT_SHORTEN_WORK = 3e5
"""How much simplex work step 6 may spend on a piece, per sample of the piece's plan
(a user parameter, ``shorten_work`` of :func:`.plan.plan_motion`), counted in pivots
times the rows of the program pivoted (:class:`_Work`): a pivot's CPU time grows with the
program's rows, and so the count follows the CPU time (correlation 0.96 over the 695
programs of cases 0-119 of ``benchmarks/planner_sweep.py``, 5e-8 to 1e-7 s a pivot-row on
the project's machine), but it is the same on any machine and at any load, so the plan is
too. Where the budget runs out, the piece keeps the earliest arrival found so far (the
plan's own if none) and the plan says so (:attr:`.plan.MotionPlan.shorten_status`).
The default keeps a 3-axis move of 60-120 samples, whose programs have 2,400-8,000 rows,
to about 1-2 s of CPU: on cases 0-119 of the sweep the largest planning time falls from
10.3 to 2.0 s and 10 plans meet the budget, 4 of them arriving later (1, 1, 2 and 5
samples); benchmarks/planner_sweep_plan_only.md has the 20 slowest cases."""


def move_tolerance(path_tolerance: float) -> float:
    """The least displacement [pulse] that counts as a move of an axis in a plan: the
    pre-compensation's tolerance or ``path_tolerance``, whichever is larger (the plan's
    position, inverted through the sampled plant's zero near -1, wavers by a fraction of
    a pulse, and a short move's plan may leave the path, and pass its end, by the path
    tolerance)."""
    return max(PRECOMPENSATION_TOLERANCE, path_tolerance)


def _normal_directions(tangent: np.ndarray) -> np.ndarray:
    """Unit directions normal to each unit ``tangent`` (m, n_axes), shape (m, r, n_axes):
    an orthonormal basis of the normal space (the other columns of the Householder
    reflection that takes the first axis to the tangent) and, where it is a plane, its
    two diagonals (a regular octagon: a point whose offsets along all of them are within
    E lies within E/cos(pi/8) = 1.08 E of the path)."""
    m, n_axes = tangent.shape
    v = tangent.copy()
    v[:, 0] += np.where(tangent[:, 0] >= 0, 1.0, -1.0)
    scale = 1.0 / (1.0 + np.abs(tangent[:, 0]))
    H = np.eye(n_axes)[None] - scale[:, None, None] * v[:, :, None] * v[:, None, :]
    basis = np.swapaxes(H[:, :, 1:], 1, 2)
    if n_axes != 3:
        return basis
    diagonals = np.stack([basis[:, 0] + basis[:, 1], basis[:, 0] - basis[:, 1]], axis=1)
    return np.concatenate([basis, diagonals / math.sqrt(2.0)], axis=1)


def _partial_zoh(machine: Machine, points: int):
    """ZOH coefficients ``(a, b0, c, b1)`` over j/``points`` of a sample, j = 0 ..
    ``points``: each shape (points + 1, n_axes) (j = 0: no time, the identity)."""
    parts = [zoh_coefficients(machine.tau, machine.Kc, machine.Ke,
                              machine.sample_period * j / points)
             for j in range(1, points + 1)]
    ident = (np.ones(len(machine.tau)), *(np.zeros(len(machine.tau)),) * 3)
    return tuple(np.vstack([i, *(part[q] for part in parts)]) for q, i in enumerate(ident))


def _fine_positions(plant: ServoPlant, zoh, u: np.ndarray):
    """Speed [rad/s] and position [pulse] of the model's ``plant`` (at rest at its start)
    at every sample, each shape (N + 1, n_axes) (:meth:`ServoPlant.response`), and its
    position at every fine point (Q per sample, ``zoh`` from :func:`_partial_zoh`: each
    sample's state advanced by part of a sample), shape (N*Q + 1, n_axes), under ``u``
    (N, n_axes; u[k] held over sample k, within Umax)."""
    w, theta = plant.response(u)
    c, b1 = zoh[2], zoh[3]
    fine = (theta[:-1, None] + c[None, :-1] * w[:-1, None]
            + b1[None, :-1] * u[:, None]).reshape(-1, u.shape[1])
    return w, theta, np.vstack([fine, theta[-1:]])


def _highs():
    """The HiGHS module and its solver class: ``highspy`` (a dependency), or the same
    bindings that scipy carries for its ``linprog`` where highspy is not installed."""
    try:
        import highspy
        return highspy, highspy.Highs
    except ImportError:   # pragma: no cover - highspy is a dependency
        from scipy.optimize._highspy import _core
        return _core, _core._Highs


def _silent(Highs):
    """A HiGHS solver with its output off. HiGHS 1.16 prints its banner on the C level's
    standard output when the process makes its first solver, before any option can be set
    (it would land in the middle of a command's printed results); so the file descriptor
    is pointed at the null device for that construction alone."""
    import os
    import sys

    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no standard output to protect
        highs = Highs()
    else:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 1)
            highs = Highs()
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            os.close(null)
    highs.setOptionValue("output_flag", False)
    return highs


class _Work:
    """Step 6's work budget for one piece (:data:`DEFAULT_SHORTEN_WORK`): ``left``
    pivot-rows (a pivot of a program of R rows counts R), and whether a program ran out
    of it (``exhausted``; the search then stops where it is)."""

    def __init__(self, left: float = math.inf):
        self.left = left
        self.exhausted = False

    def pivots(self, rows: int) -> int:
        """The most pivots a program of ``rows`` rows may take (HiGHS' iteration limit)."""
        if math.isinf(self.left):
            return 2**31 - 1
        return int(max(self.left, 0.0) // max(rows, 1))

    def spend(self, pivots: int, rows: int) -> None:
        self.left -= pivots * rows


class _WarmProgram:
    """The linear programs of one arrival sample of step 6, solved by HiGHS' dual simplex
    (Huangfu & Hall 2018, through ``highspy``), each from the last one's optimal basis:
    a round re-linearises the path at new points, which changes the numbers but not the
    shape, and the last basis is then a few tens of pivots from the new optimum instead of
    about a thousand (10-30 x fewer iterations on the rounds of a 78 mm move at 1.7 m/s,
    85 samples). A round that holds more points than the last adds rows and columns: the
    rows and columns the programs share (named by ``row_keys`` and ``col_keys``) keep
    their status, the new rows are basic (their slacks, as a cutting-plane method
    restarts its dual simplex) and the new columns at their lower bounds."""

    def __init__(self, work: "_Work | None" = None):
        self.highs = None
        self.basis = None
        self.keys = None
        self.work = work if work is not None else _Work()

    def solve(self, cost, A_ub, b_ub, A_eq, bounds, row_keys=None, col_keys=None):
        """Minimise ``cost @ x`` subject to ``A_ub @ x <= b_ub``, ``A_eq @ x = 0`` and the
        ``bounds`` (n, 2) of x; the optimal x, or None where there is none or where the
        work budget (``work``, :class:`_Work`) runs out first (``work.exhausted``).
        ``row_keys`` (rows of A_ub then A_eq,) and ``col_keys`` (n,), integers, name the
        rows and columns that the next program may share (default: by position)."""
        from scipy import sparse

        return self.solve_stacked(cost, sparse.vstack([A_ub, A_eq]).tocsc(), b_ub, bounds,
                                  row_keys, col_keys)

    def solve_stacked(self, cost, A, b_ub, bounds, row_keys=None, col_keys=None):
        """:meth:`solve` with its constraint rows stacked into one column-wise matrix
        ``A`` (``scipy.sparse`` CSC, row indices sorted): its first ``len(b_ub)`` rows are
        ``A_ub``, the rest ``A_eq``. HiGHS drops zero entries as it reads the matrix
        (``small_matrix_value``), so a matrix with or without them is the same program."""
        highspy, Highs = _highs()

        if row_keys is None:
            row_keys = np.arange(A.shape[0])
        if col_keys is None:
            col_keys = np.arange(A.shape[1])
        n_eq = A.shape[0] - len(b_ub)
        if self.highs is None:
            self.highs = _silent(Highs)
        h = self.highs
        # the arrays handed over as they are (a HighsLp's fields would copy them element
        # by element, about half a millisecond a program); every column continuous
        h.passModel(A.shape[1], A.shape[0], A.nnz, int(highspy.MatrixFormat.kColwise),
                    int(highspy.ObjSense.kMinimize), 0.0, np.asarray(cost, dtype=float),
                    np.ascontiguousarray(bounds[:, 0]), np.ascontiguousarray(bounds[:, 1]),
                    np.concatenate([np.full(len(b_ub), -highspy.kHighsInf), np.zeros(n_eq)]),
                    np.concatenate([b_ub, np.zeros(n_eq)]), A.indptr, A.indices, A.data,
                    np.zeros(A.shape[1], dtype=np.int32))
        basis = self._mapped_basis(highspy, row_keys, col_keys)
        h.setOptionValue("presolve", "off" if basis is not None else "choose")
        if basis is not None:
            h.setBasis(basis)
        rows, work = A.shape[0], self.work
        out_of_work = highspy.HighsModelStatus.kIterationLimit

        def run():
            h.setOptionValue("simplex_iteration_limit", work.pivots(rows))
            h.run()
            work.spend(h.getInfo().simplex_iteration_count, rows)
            if h.getModelStatus() == out_of_work:
                work.exhausted = True
            return not work.exhausted

        if (run() and basis is not None
                and h.getModelStatus() != highspy.HighsModelStatus.kOptimal):
            # a carried-over basis is a start, never a verdict: the program decides cold
            h.clearSolver()
            h.setOptionValue("presolve", "choose")
            run()
        if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            self.basis = None
            return None
        # (read as arrays only where a next program starts from it: the last program of
        # an arrival sample has none)
        self.basis = h.getBasis()
        self.keys = (np.asarray(row_keys), np.asarray(col_keys))
        return np.array(h.getSolution().col_value)

    def _mapped_basis(self, highspy, row_keys, col_keys):
        """The last optimal basis carried over to rows ``row_keys`` and columns
        ``col_keys``, or None (no last basis, or it shares no row)."""
        if self.basis is None:
            return None
        if isinstance(self.basis, highspy.HighsBasis):
            self.basis = tuple(np.fromiter(map(int, status), np.int8, len(keys))
                               for status, keys in ((self.basis.row_status, self.keys[0]),
                                                    (self.basis.col_status, self.keys[1])))
        kinds = list(highspy.HighsBasisStatus.__members__.values())
        basic, lower = int(highspy.HighsBasisStatus.kBasic), int(highspy.HighsBasisStatus.kLower)
        status = []
        for keys, old_keys, old, new in zip((row_keys, col_keys), self.keys, self.basis,
                                            (basic, lower)):
            if len(keys) == len(old_keys) and np.array_equal(keys, old_keys):
                status.append(old)
                continue
            order = np.argsort(old_keys, kind="stable")
            at = np.minimum(np.searchsorted(old_keys, keys, sorter=order), len(order) - 1)
            hit = old_keys[order[at]] == keys
            status.append(np.where(hit, old[order[at]], new))
        rows, cols = status
        basis = highspy.HighsBasis()
        basis.row_status = [kinds[k] for k in rows.tolist()]
        basis.col_status = [kinds[k] for k in cols.tolist()]
        basis.valid = True
        # an added row's slack is basic: as many basic as rows where the programs differ
        # by added rows and columns alone; HiGHS completes any other (an alien basis)
        basis.alien = int(np.count_nonzero(rows == basic) + np.count_nonzero(cols == basic)) \
            != len(rows)
        return basis


def _keys(f: np.ndarray, r: int, n_fixed: int, n_eq: int):
    """Names of the rows and columns of a program of :func:`_shorten_at` whose held points
    are the fine points ``f`` (m,), with ``r`` normal directions each, ``n_fixed`` drive
    and state columns and ``n_eq`` dynamics rows, in the order that builds them; the
    programs of one arrival sample share a row or a column where it has the same name
    (:class:`_WarmProgram`)."""
    f = np.asarray(f, dtype=np.int64)
    span = np.int64(16 << 32)                            # more than 16 x any fine index
    point = f[:, None] * 16 + np.arange(r)              # (m, r)
    blocks = [point.ravel(), point.ravel() + span] + [f * 16 + b * span
                                                       for b in range(2, 6)]
    blocks += [f[:-1] * 16 + 6 * span, f[:-1] * 16 + 7 * span,
               np.array([8 * span]), np.array([9 * span]), 10 * span + np.arange(n_eq)]
    cols = np.concatenate([np.arange(n_fixed), n_fixed + 1 + f, [-1]])
    return np.concatenate(blocks), cols


REACH_MARGIN = 1e-6
"""Relative margin by which an axis' displacement must exceed its reach in N samples
(:func:`_axis_reach`) before step 6 skips the arrival sample N: far above HiGHS' primal
feasibility tolerance (1e-7), within which a program a hair beyond the reach could still be
solved (on the sweep's cases the skipped samples lie 1.7 % or more beyond it)."""


def _axis_reach(zoh, N: int, limit: float) -> np.ndarray:
    """Per axis, the largest displacement [pulse] that a drive within ``limit`` [V],
    zero before :data:`LEAD` and held over each sample, can make from rest at sample 0
    to rest at sample N (``zoh``: :func:`_partial_zoh`, its last row a whole sample),
    shape (n_axes,). Every program of :func:`_shorten_at` at N puts the plant at rest on
    the piece's end at N from rest on its start under such drives, so it has no solution
    where an axis has to move farther than this.

    The plant's speed and position at N are ``w_N = g_w . u`` and ``theta_N - theta_0 =
    g_theta . u`` (``g_w[k] = a^(N-1-k) b0``, ``g_theta[k] = b1 + c (b0 + a b0 + ... +
    a^(N-2-k) b0)``); the largest ``g_theta . u`` with ``g_w . u = 0`` and ``|u| <= limit``
    is, by linear programming duality, ``limit * min over lambda of ||g_theta - lambda
    g_w||_1`` (any lambda bounds it from above), whose minimum lies at the median of the
    ratios ``g_theta / g_w`` weighted by ``|g_w|``."""
    a, b0, c, b1 = (x[-1] for x in zoh)
    steps = np.arange(N - LEAD)[::-1, None]       # samples from the drive's to N, less 1
    g_w = a[None] ** steps * b0[None]                                   # (N - LEAD, n_axes)
    before = np.cumsum(a[None] ** np.arange(N - LEAD)[:, None] * b0[None], axis=0)
    g_theta = b1[None] + c[None] * np.vstack([np.zeros((1, len(a))), before[:-1]])[::-1]
    reach = np.empty(len(a))
    for j in range(len(a)):
        weight = np.abs(g_w[:, j])
        ratio = np.divide(g_theta[:, j], g_w[:, j], out=np.zeros(N - LEAD),
                          where=weight > 0)
        order = np.argsort(ratio, kind="stable")
        total = np.cumsum(weight[order])
        lam = ratio[order][min(int(np.searchsorted(total, total[-1] / 2)), N - LEAD - 1)]
        reach[j] = limit * float(np.sum(np.abs(g_theta[:, j] - lam * g_w[:, j])))
    return reach


def _stacked_program(m: int, n_normal: int, n_var: int, col_E: int, col_step, normal,
                     along, dynamics, n_eq: int):
    """The constraint matrix of a program of :func:`_shorten_at` (``scipy.sparse`` CSC,
    shape (2*n_normal + 6*m + n_eq, n_var), zero entries left out), built from the
    entries (row, column, value) of its position rows in one step: the rows ``A_n . x -
    E <= b_n`` and ``-A_n . x - E <= -b_n`` (``normal``: the entries of A_n, its
    ``n_normal`` rows the held points' directions), ``+-A_t . x - step <= +-b_t`` (the
    |tangential step| columns ``col_step``), ``+-A_t . x`` (the trust region), ``+-(A_t[i]
    - A_t[i + 1]) . x`` (the nearest points move forward, no faster than the feed),
    ``A_t[0] . x`` and ``-A_t[m - 1] . x`` (``along``: the entries of A_t, m rows the
    tangents), then the ZOH dynamics (``dynamics``: values and (rows, columns), n_eq
    rows). The values are those of the same rows written block by block with
    ``scipy.sparse`` (a difference of two entries is the one rounding a - b)."""
    from scipy import sparse

    n_rows, n_cols, n_vals = normal
    t_rows, t_cols, t_vals = along
    vals, (eq_rows, eq_cols) = dynamics
    R = n_normal
    steps, normals = np.arange(m), np.arange(R)
    first, last = t_rows == 0, t_rows == m - 1
    down, up = t_rows < m - 1, t_rows > 0     # A_t[i] - A_t[i + 1]: rows i and i - 1
    diff = 2 * R + 4 * m
    blocks = [
        (n_rows, n_cols, n_vals), (normals, np.full(R, col_E), np.full(R, -1.0)),
        (R + n_rows, n_cols, -n_vals), (R + normals, np.full(R, col_E), np.full(R, -1.0)),
        (2 * R + t_rows, t_cols, t_vals), (2 * R + steps, col_step, np.full(m, -1.0)),
        (2 * R + m + t_rows, t_cols, -t_vals),
        (2 * R + m + steps, col_step, np.full(m, -1.0)),
        (2 * R + 2 * m + t_rows, t_cols, t_vals),
        (2 * R + 3 * m + t_rows, t_cols, -t_vals),
        (diff + t_rows[down], t_cols[down], t_vals[down]),
        (diff + t_rows[up] - 1, t_cols[up], -t_vals[up]),
        (diff + m - 1 + t_rows[down], t_cols[down], -t_vals[down]),
        (diff + m - 1 + t_rows[up] - 1, t_cols[up], t_vals[up]),
        (np.full(np.count_nonzero(first), diff + 2 * m - 2), t_cols[first], t_vals[first]),
        (np.full(np.count_nonzero(last), diff + 2 * m - 1), t_cols[last], -t_vals[last]),
        (diff + 2 * m + eq_rows, eq_cols, vals),
    ]
    rows, cols, data = (np.concatenate([b[q] for b in blocks]) for q in range(3))
    A = sparse.csc_matrix((data, (rows, cols)), shape=(diff + 2 * m + n_eq, n_var))
    A.sum_duplicates()
    A.eliminate_zeros()
    return A


def _shorten_at(curve: NurbsCurve, span: _Span, plant: ServoPlant, zoh, N: int,
                s: np.ndarray, limit: float, tolerance: float, tangent: np.ndarray, feed,
                Ts: float, wide: bool, most_rounds: int = SHORTEN_ROUNDS,
                program: "_WarmProgram | None" = None, widened: "list | None" = None,
                below: bool = False):
    """One arrival sample N of step 6 (:func:`_shorten`) along the ``span`` of the curve
    from stop to stop (the plant at rest on its start at sample 0): drives u[LEAD] .. u[N-1]
    (|u| <= ``limit`` [V]) that keep the model's ``plant`` (at rest at the start) within
    ``tolerance`` [pulse] of the curve at every fine point inside the move (``zoh`` from
    :func:`_partial_zoh`: Q points per sample, fine points LEAD*Q + 1 .. N*Q - 1), their
    nearest points moving forward no faster than ``feed`` and none past the end along
    its unit ``tangent``, and put it at rest on the end at N; ``s`` (N*Q - LEAD*Q - 1,)
    is the first guess of the nearest points' arc lengths. Returns ``(u, s)`` (u shape
    (N, n_axes), 0 before :data:`LEAD`, and s at the fine points), or None if the
    linearised programs find none.

    The programs hold the samples, the half samples and every point that a round found
    off the path (the worst of each sample interval); every fine point is checked.
    Variables: the drives, the plant's state at every sample (the ZOH dynamics are
    equality constraints; a held point's position is its sample's state advanced by its
    part of the sample, three terms), each held point's |tangential step| and the
    largest normal offset E, which is minimised (module docstring, step 6). E bounds the
    offsets along the normal directions (:func:`_normal_directions`; from 3 axes on a
    polygon around the path, which bounds the distance by ``spread*E`` only) and, for a
    point a round found farther than the tolerance, along its own offset (a cut). The trust
    region of the tangential steps is as wide as the linearisation stays within the
    tolerance, or (``wide``) as the feed goes in a sample if that is wider (where it is
    at some held point of some round, ``widened[0]`` is set True: where it never is, the
    programs of the region that is not wide are these programs again). N is given up
    where N lies before the piece's continuous duration (``below``,
    :data:`SHORTEN_BELOW_ROUNDS`) and a program leaves E beyond the tolerance, when E
    cannot reach the tolerance at its pace in the rounds left, or when
    :data:`SHORTEN_STALL` rounds in a row bring the farthest fine point no nearer (on a
    random 3-axis machine, 24 rounds of E at 0.998 against held points at 1.07: 42 s
    where this rule takes 14 s; on the sweep's 461 step-6 runs it changes no arrival)."""
    n_axes = curve.n_axes
    Q = zoh[0].shape[0] - 1
    s0, s1 = span.s0, span.s1
    start, end = curve(span.u0), curve(span.u1)
    a, b0, c, b1 = (x[-1] for x in zoh)
    n_u = n_axes * (N - LEAD)
    col_w = n_u + 2 * (np.arange(n_axes)[:, None] * (N + 1) + np.arange(N + 1))
    col_theta = col_w + 1                                   # (n_axes, N + 1)
    col_u = np.full((n_axes, N), -1)                        # before LEAD: 0, no variable
    col_u[:, LEAD:] = np.arange(n_u).reshape(n_axes, N - LEAD)
    # the ZOH dynamics from sample to sample, two rows per axis and sample
    k = np.arange(N)
    rows, cols, vals = [], [], []
    for j in range(n_axes):
        for q, (out, terms, drive) in enumerate((
                (col_w[j, 1:], [(col_w[j, :-1], -a[j])], -b0[j]),
                (col_theta[j, 1:], [(col_theta[j, :-1], -1.0), (col_w[j, :-1], -c[j])],
                 -b1[j]))):
            r = (2 * j + q) * N + k
            rows += [r, r[LEAD:]] + [r] * len(terms)
            cols += [out, col_u[j, LEAD:]] + [cc for cc, _ in terms]
            vals += [np.ones(N), np.full(N - LEAD, drive)] + [np.full(N, v)
                                                              for _, v in terms]
    dynamics = (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols)))
    n_fixed = col_theta[-1, -1] + 1
    fine = np.arange(LEAD * Q + 1, N * Q)                   # the points inside the move
    held = fine[fine % (Q // 2) == 0] - LEAD * Q - 1        # index into fine
    spread = {2: 1.0, 3: 1.0 / math.cos(math.pi / 8)}.get(n_axes, math.sqrt(n_axes - 1))
    # cuts: the unit normal offset of every point a round found farther than the
    # tolerance (renewed every round; none with 2 axes, whose normal is exact)
    cut = np.zeros((len(fine), n_axes))
    has_cut = np.zeros(len(fine), bool)
    reach, previous = 1.0, math.inf
    closest, stalled = math.inf, 0  # the least of the farthest points so far; rounds since
    program = program or _WarmProgram()
    for rounds in range(most_rounds):
        m = len(held)
        col_step = n_fixed + np.arange(m)
        col_E = n_fixed + m
        n_var = col_E + 1
        f = fine[held]
        ks, js = f // Q, f % Q                              # sample, part of it
        # position of axis j at held point i: theta[ks] + c_js*w[ks] + b1_js*u[ks]
        pos_cols = np.stack([col_theta[:, ks], col_w[:, ks], col_u[:, ks]], axis=-1)
        pos_vals = np.stack([np.ones((n_axes, m)), zoh[2][js].T, zoh[3][js].T], axis=-1)

        def entries_along(directions):
            """The nonzero entries (row, column, value) of the rows (m*r, n_var) of
            ``directions`` (m, r, n_axes) . position, row by row."""
            r = directions.shape[1]
            v = directions[..., None] * pos_vals.transpose(1, 0, 2)[:, None]
            cc = np.broadcast_to(pos_cols.transpose(1, 0, 2)[:, None], v.shape)
            rr = np.broadcast_to(np.arange(m * r).reshape(m, r)[:, :, None, None], v.shape)
            keep = (cc >= 0) & (v != 0.0)
            return rr[keep], cc[keep], v[keep]

        sh = s[held]
        p = curve.parameter_at(sh)
        point, T = curve(p), span.tangents(curve, p)
        F = np.asarray(feed(p) if isinstance(feed, FeedLimit) else np.full(m, feed))
        # the trust region: as far as the chord C(s) + T d stays within the tolerance of
        # the curve (kappa d^2/2), or as far as the feed goes in a sample (a guess
        # compressed by a sample is off by about that much), whichever is farther
        # (fmax: a stop at a point where the curve's speed is zero has no curvature)
        chord = np.sqrt(2.0 * tolerance / np.fmax(curve.curvature(p), 1e-300))
        trust = np.minimum(reach * np.maximum(chord, F * Ts * wide), s1 - s0)
        if wide and widened is not None and np.any(F * Ts > chord):
            widened[0] = True
        normals = _normal_directions(T)                     # (m, r, n_axes)
        if n_axes > 2:  # (m, r + 1, n_axes): the held points' cuts, and where a point
            # has none its first normal again (a row that changes nothing), so that the
            # program keeps its shape from round to round and is warm-started
            normals = np.concatenate([normals, np.where(
                has_cut[held][:, None], cut[held], normals[:, 0])[:, None]], axis=1)
        t_rows, t_cols, t_vals = entries_along(T[:, None, :])    # d = A_t x - b_t
        b_t = np.einsum("ij,ij->i", T, point)
        n_rows, n_cols, n_vals = entries_along(normals)
        b_n = np.einsum("iqj,ij->iq", normals, point).ravel()
        A = _stacked_program(m, len(b_n), n_var, col_E, col_step, (n_rows, n_cols, n_vals),
                             (t_rows, t_cols, t_vals), dynamics, 2 * n_axes * N)
        # the nearest points move forward, no faster than the feed, from the start
        # (sample LEAD) through every held point to the end (sample N)
        gap = np.diff(np.concatenate([[LEAD * Q], f, [N * Q]])) * Ts / Q
        travel = np.maximum(F[1:], F[:-1]) * gap[1:-1]
        ahead = sh[1:] - sh[:-1] + b_t[:-1] - b_t[1:]      # s + d nondecreasing
        b_ub = np.concatenate([b_n, -b_n, b_t, -b_t,
                               np.minimum(trust, s1 - sh) + b_t,
                               np.minimum(trust, sh - s0) - b_t,
                               ahead, travel - ahead,
                               [F[0] * gap[0] + s0 - sh[0] + b_t[0]],
                               [F[-1] * gap[-1] - s1 + sh[-1] - b_t[-1]]])
        bounds = np.empty((n_var, 2))
        bounds[:, 0], bounds[:, 1] = -np.inf, np.inf
        bounds[:n_u] = (-limit, limit)
        bounds[col_w[:, 0]] = bounds[col_w[:, -1]] = 0.0
        bounds[col_theta[:, 0], 0] = bounds[col_theta[:, 0], 1] = start
        bounds[col_theta[:, -1], 0] = bounds[col_theta[:, -1], 1] = end
        bounds[col_step] = (0.0, np.inf)
        bounds[col_E] = (0.0, np.inf)
        cost = np.zeros(n_var)
        cost[col_E] = 1.0
        # a tie-break: of the motions with the least E, the one whose nearest points
        # move least (the chord is exact there); moving all by the trust costs E/16
        cost[col_step] = tolerance / (16.0 * m * trust)
        x = program.solve_stacked(cost, A, b_ub, bounds, *_keys(f, normals.shape[1], n_fixed,
                                                                2 * n_axes * N))
        if x is None:
            return None
        u = np.zeros((N, n_axes))
        u[LEAD:] = x[:n_u].reshape(n_axes, N - LEAD).T
        positions = _fine_positions(plant, zoh, u)[2][LEAD * Q + 1:N * Q]
        guess = s.copy()
        guess[held] = np.clip(sh + np.einsum("ij,ij->i", T, positions[held] - point),
                              s0, s1)
        s_new = _nearest_forward(curve, positions, np.maximum.accumulate(guess), span)
        p_new = curve.parameter_at(s_new)
        offset = positions - curve(p_new)
        off = np.linalg.norm(offset, axis=1)
        at_end = s_new >= s1 - curve.length * 1e-12
        past = float(np.max((positions[at_end] - end) @ tangent, initial=0.0))
        # the nearest points of the samples (the start at LEAD, the end at N) move by at
        # most F*Ts + FEED_SLACK a sample: the programs hold the linearised ones to F
        at_samples = np.concatenate([[s0], s_new[Q - 1::Q], [s1]])
        fast = np.any(np.diff(at_samples) > _feed_at(feed, np.concatenate(
            [p_new[Q - 1::Q], [span.u1]])) * Ts + FEED_SLACK)
        if np.max(off) <= tolerance and past <= PRECOMPENSATION_TOLERANCE and not fast:
            return u, s_new
        farthest = float(np.max(off))
        stalled = 0 if farthest < closest else stalled + 1
        closest = min(closest, farthest)
        if stalled >= SHORTEN_STALL:
            return None
        worst = float(np.max(off[held]))
        E_now = float(x[col_E])
        left = most_rounds - 1 - rounds
        if E_now > tolerance and E_now - tolerance > left * (previous - E_now):
            return None    # at this pace the program will not come within the tolerance
        if below and E_now > tolerance:
            return None    # SHORTEN_BELOW_ROUNDS: the linearised path is not followed
        if worst > E_now * spread + tolerance / 16:
            reach *= 0.5   # the chord misled the program: a smaller step
        elif np.any(np.abs(guess[held] - sh) >= trust * (1 - 1e-6)):
            reach *= 2.0   # the chord was right, and the trust region held it back
        previous = min(previous, E_now)
        if n_axes > 2:
            T_new = span.tangents(curve, p_new)
            normal = offset - np.einsum("ij,ij->i", offset, T_new)[:, None] * T_new
            size = np.linalg.norm(normal, axis=1)
            renew = (has_cut | (off > tolerance)) & (size > 0.0)
            cut[renew] = normal[renew] / size[renew, None]
            has_cut |= renew
        # once the held points are within the tolerance, hold the worst point of each
        # sample interval that is not
        loose = np.ones(len(fine), bool)
        loose[held] = False
        bad = np.flatnonzero(loose & (off > tolerance))
        if E_now <= tolerance and bad.size:
            interval = fine[bad] // Q
            order = np.lexsort((-off[bad], interval))
            first = np.unique(interval[order], return_index=True)[1]
            held = np.union1d(held, bad[order][first])
            previous = math.inf
        s = s_new
    return None


def _shorten(curve: NurbsCurve, span: _Span, theta: np.ndarray, param: np.ndarray,
             arrival: int, machine: Machine, limit: float, tolerance: float,
             tangent: np.ndarray, feed, earliest: int | None = None,
             work: "_Work | None" = None):
    """Step 6 (module docstring): the plan ``theta`` (n, n_axes) of a move along the
    ``span`` of the curve that does not stop on the way, from rest on its start at
    sample 0 to rest on its end at ``arrival`` (<= :data:`nurbsmotion.limits.SHORT_MOVE_SAMPLES`),
    replaced by one at rest there at the earliest sample N at which a drive within
    ``limit`` [V] keeps the plant within ``tolerance`` [pulse] of the curve all along its
    motion (failing that, as near as ``theta`` is), its nearest path point moving forward
    no faster than ``feed`` and not past the end along its unit ``tangent``
    (:func:`_shorten_at`); None if none before ``arrival`` does (where the plan leaves
    the end by more than ``tolerance`` after it: none before it has settled within
    ``tolerance`` either).

    N runs down from ``arrival - 1`` while one is found (where none is, and the plan so
    leaves the end, from the first of ``arrival``, ``arrival + 1``, ... at which one
    is); given the ``earliest`` sample worth trying first (:data:`SHORTEN_START`), from
    there if one is found there within :data:`SHORTEN_STALL` rounds, down to the piece's
    continuous duration ``earliest - SHORTEN_START`` and below it by tries of
    :data:`SHORTEN_BELOW_ROUNDS` rounds; else (the probe at ``earliest`` failed) from
    the top: N = top, top - 2, top - 6, ... (steps that double) while one is found, then
    halving the gap between the earliest N found and the latest that failed (at first
    the probe), then one sample at a time from the earliest found while one is found
    (a sample that already failed from the motion found a sample later is not tried
    again; the probed N within :data:`SHORTEN_STALL` rounds only). Searching up from the
    probe instead, each N from the plan's guess, arrived 1-3 samples later on
    ``examples/study.toml``'s closed path at 1 m/s than coming down, each N from a
    motion found later.

    Why halving the gap may skip samples: the motions that the programs look for exist
    at every N from the first at which one does. A motion at rest on the end at N
    (drive 0 from N on) stays there, within the tolerance, its nearest point still,
    at N + 1 as well; so does one that waits a sample at rest on the start first (the
    drive shifted by a sample). The linearised programs do not always find one where
    one exists (a guess compressed by many samples is a poorer start than one compressed
    by one), which is why the search ends one sample at a time from the motion found a
    sample later, as coming down from the top did. On case 875 of
    ``benchmarks/planner_sweep.py`` (2 axes, probe at 64, plan at 89) coming down took
    187 programs to 66; this search takes 96 to 67 without a work budget, and arrives at
    82 instead of 87 within the default one; on the example study's closed path it
    found 51 as before (54, 52, 51 instead of 54, 53, 52, 51).

    An N at which some axis cannot move from the piece's start to its end, at rest at
    both, under drives within ``limit`` (:func:`_axis_reach`) is not tried: every
    program there would fail. The first
    guess of the nearest points is the plan's (its parameters ``param``, shape (n,)),
    compressed in time to arrive at N; each later N starts from the last motion found,
    compressed by the samples between. The programs of one N and trust region are
    warm-started (:class:`_WarmProgram`; the narrow region's first program starts cold).
    Where the ``work`` budget (:class:`_Work`) runs out, the search stops there with the
    earliest N found so far (None if none).
    Returns ``(N, y, param, w, theta, u)``, arrays of N + 1 + :data:`END_REST` samples,
    y the nearest path points of the samples."""
    work = work if work is not None else _Work()
    Ts = machine.sample_period
    start, end = curve(span.u0), curve(span.u1)
    distance = np.abs(end - start)              # each axis' displacement [pulse]
    plant = ServoPlant.of_machine(machine, start)
    grid = curve.geometry.uniform_parameters(8 * CHECK_POINTS)
    inside = grid[(grid >= span.u0) & (grid <= span.u1)]
    kappa = float(np.nanmax(curve.curvature(inside if inside.size else grid)))
    fastest = feed.highest if isinstance(feed, FeedLimit) else feed
    plan_s = np.clip(curve.arc_length(param[:arrival + 1]), span.s0, span.s1)
    nearest = curve.parameter_at(_nearest_forward(curve, theta[:arrival + 1], plan_s,
                                                  span))
    # the plan's distance from the path, at most that to the nearest points found or to
    # its desired points (on a tight curl a sample may move farther than the Newton steps
    # of _nearest_forward reach: they then find a point far from the nearest)
    to_nearest = np.linalg.norm(theta[:arrival + 1] - curve(nearest), axis=1)
    to_desired = np.linalg.norm(theta[:arrival + 1] - curve(param[:arrival + 1]), axis=1)
    own = float(np.max(np.minimum(to_nearest, to_desired)))
    # Where the landing (step 5) could not put the plan at rest exactly, what the
    # pre-compensation leaves rings about the end after the arrival: farther from it than
    # the tolerance (a short 3-axis move: 2.6 pulses at Nyquist, settled within a pulse 4
    # samples late), a plan at rest at the arrival itself, or at any sample before the
    # ringing has died down to the tolerance, is worth finding.
    off = np.flatnonzero(np.linalg.norm(theta[arrival:] - end, axis=1) > tolerance)
    settled = arrival + (int(off[-1]) + 1 if off.size else 0)

    def descend(tolerance, top):
        # fine points: the path's chord between two within the tolerance at the feed
        Q = 2 * math.ceil(fastest * Ts * math.sqrt(kappa / (8.0 * tolerance)) / 2)
        zoh = _partial_zoh(machine, int(min(max(Q, 2), CHECK_POINTS)))
        Q = zoh[0].shape[0] - 1
        known = [np.arange(arrival + 1, dtype=float), plan_s]   # times, arc lengths
        best = None
        tried = {}   # an arrival sample where none was found: from the one found at

        def found_at(N, most_rounds=SHORTEN_ROUNDS, below=False):
            # the last motion found (first: the plan) compressed in time to arrive at N
            nonlocal best
            if np.any(distance > _axis_reach(zoh, N, limit) * (1 + REACH_MARGIN)):
                return False    # an axis cannot get there by N: every program would fail
            times, s_known = known
            t = np.arange(LEAD * Q + 1, N * Q) / Q            # fine points [samples]
            guess = np.interp(LEAD + (t - LEAD) * (times[-1] - LEAD) / (N - LEAD), times,
                              s_known)
            # a trust region as wide as the feed goes in a sample, failing that as wide
            # as the linearisation stays within the tolerance
            found = None
            # (the narrow region is the fallback: it runs as many rounds; capped at
            # SHORTEN_STALL, its pace test gave up on case 88 of
            # benchmarks/planner_sweep.py, which arrived 2 samples later. Its programs
            # start cold: warm-started from the wide region's last basis, a first program
            # that the narrow region makes infeasible took HiGHS' dual simplex 2,100
            # pivots and 5 s of CPU through its unboundedness checks on case 71, where
            # presolve proves it infeasible cold in 0.13 s)
            # (where the feed never widened the wide region's trust, the narrow region's
            # programs are the same programs, solved the same way: not solved again)
            widened = [False]
            for wide in (True, False):
                if found is None and not work.exhausted and (wide or widened[0]):
                    found = _shorten_at(curve, span, plant, zoh, N,
                                        np.maximum.accumulate(guess), limit, tolerance,
                                        tangent, feed, Ts, wide, most_rounds,
                                        _WarmProgram(work), widened, below)
            if found is not None:
                best = (N, *found, zoh)
                known[:] = [np.concatenate([[float(LEAD)], t, [N]]),
                            np.concatenate([[span.s0], found[1], [span.s1]])]
            elif not work.exhausted:
                tried[N] = times[-1]    # none found from the motion arriving there
            return found is not None

        # From the estimate (a sample after the piece's continuous duration) down while
        # one is found, each from the motion found a sample later; below the continuous
        # duration only as a short try (SHORTEN_BELOW_ROUNDS). Where none is found at the
        # estimate within SHORTEN_STALL rounds (a probe: from the plan's guess, compressed
        # by several samples, a program that does not converge soon seldom does), from
        # the top down in steps that double while one is found, then halving the gap
        # between the earliest found and the latest that failed (the probe at first), and
        # from the earliest found one sample at a time as above (the _shorten docstring
        # says why that search may skip samples).
        low, probe = LEAD + 2, None
        if earliest is None:
            N, floor = top + 1, low
        else:
            # (a motion as far from the path as the plan may arrive well before the
            # continuous duration: no floor then; 5 ms for a duration of 7 ms seen)
            floor = max(earliest - SHORTEN_START, low) if tolerance <= path_tolerance else low
            N = min(max(earliest, low), top)
            if not found_at(N, SHORTEN_STALL if N < top else SHORTEN_ROUNDS):
                if N == top or work.exhausted:
                    return None    # the top, in full: no motion found to start from
                N, probe = top + 1, N

        def rounds_at(N):
            # (the rounds, and whether N lies before the continuous duration)
            if N == probe:
                return SHORTEN_STALL, False
            return (SHORTEN_ROUNDS, False) if N >= floor else (SHORTEN_BELOW_ROUNDS, True)

        if probe is not None:
            found, failed, step = top + 1, probe, 1
            while found - failed > 1 and not work.exhausted:
                N = max(found - step, failed + 1) if step else (found + failed) // 2
                if found_at(N, *rounds_at(N)):
                    found, step = N, 2 * step if step else 0
                else:
                    failed, step = N, 0
            if best is None:
                return None        # not even the top, the first tried
            N = found
        # (a sample that failed from the motion found a sample later fails again)
        while N > low and tried.get(N - 1) != N and found_at(N - 1, *rounds_at(N - 1)):
            N -= 1
        return best

    # within the path tolerance; failing that, no farther from the path than the plan;
    # failing both, a plan at rest at the arrival or later, before this one settles, if
    # this one rings about the end
    path_tolerance = tolerance
    tops = [arrival - 1] + list(range(arrival, settled))
    tries = [(top, t) for top in tops
             for t in dict.fromkeys([tolerance, max(tolerance, own)]) if t > 0]
    for top, tolerance in tries:
        best = descend(tolerance, top)
        if best is not None or work.exhausted:
            break
    if best is None:
        return None
    N, u_moving, s_fine, zoh = best
    Q = zoh[0].shape[0] - 1
    n = N + 1 + END_REST
    u = np.zeros((n, curve.n_axes))
    u[:N] = u_moving
    w, theta = (x[:-1] for x in _fine_positions(plant, zoh, u)[:2])
    w[N:], theta[N:] = 0.0, end
    y = np.broadcast_to(end, theta.shape).copy()
    new_param = np.full(n, span.u1)
    y[:LEAD + 1], new_param[:LEAD + 1] = start, span.u0
    moving = slice(LEAD + 1, N)
    new_param[moving] = curve.parameter_at(s_fine[Q - 1::Q])  # samples LEAD + 1 .. N - 1
    y[moving] = curve(new_param[moving])
    return N, y, new_param, w, theta, u


def _shorten_pieces(curve: NurbsCurve, stops: np.ndarray, corner_times: np.ndarray,
                    theta: np.ndarray, param: np.ndarray, arrival: int, machine: Machine,
                    limit: float, tolerance: float, tangent: np.ndarray, feed,
                    earliest=None, work: float = DEFAULT_SHORTEN_WORK):
    """Step 6 from stop to stop: every piece of the plan ``theta`` (n, n_axes; its
    parameters ``param`` (n,), at rest on the end at ``arrival``) between the stops at
    the curve parameters ``stops`` (n_pieces + 1,: the start, the stop corners, the end),
    where it stops at the fractional samples ``corner_times`` (n_pieces - 1,), replaced
    by :func:`_shorten`'s (at rest at its stops at sample instants), the pieces one after
    the other. None unless every piece is found and together they arrive before
    ``arrival``, or if an axis first moves after a stop (by more than
    :func:`move_tolerance` of ``tolerance``): a piece's plan drives every axis at the limit
    from its first sample, and the online step knows an axis' plant only once it has
    seen it move (on the die-bonder's Pi, whose x starts at the first corner, plants
    with tau x0.8 and Kc x1.2 then went 71 um off the arch; the plan of the whole path
    starts the x drive over the sample in which y still brakes). Each piece may spend
    ``work`` pivot-rows per sample of its plan (:data:`DEFAULT_SHORTEN_WORK`).

    Returns ``(short, exhausted)``: ``short`` is None (as above) or
    ``(N, y, param, w, theta, u, corner_times)``, the arrays as :func:`_shorten`'s, the
    corner times whole samples; ``exhausted`` says whether a piece's search stopped at its
    work budget (it then has the earliest arrival found before it ran out)."""
    edges = np.concatenate([[0.0], corner_times, [float(arrival)]])
    # the plan's samples around each piece: from the last before its first stop to the
    # first after its next (the end: all, for the ringing after it)
    first = np.floor(edges[:-1] + 1e-9).astype(int)
    after = np.append(np.ceil(edges[1:-1] - 1e-9).astype(int), arrival)
    moves = move_tolerance(tolerance)
    for a, b in zip(first[1:], after[1:]):
        before, moving = (np.ptp(theta[k:m], axis=0) > moves for k, m in ((0, a + 1),
                                                                          (a, b + 1)))
        if np.any(moving & ~before):
            return None, False
    parts = []
    exhausted = False
    for i, (a, b) in enumerate(zip(first, after)):
        last = i == len(stops) - 2
        budget = _Work(work * (b - a))
        piece = _shorten(curve, _Span.of(curve, stops[i], stops[i + 1]),
                         theta[a:] if last else theta[a:b + 1], param[a:b + 1], b - a,
                         machine, limit, tolerance,
                         tangent if last else _unit(curve(stops[i + 1], 1, "left")), feed,
                         None if earliest is None else int(earliest[i]), budget)
        exhausted |= budget.exhausted
        if piece is None:
            return None, exhausted
        parts.append(piece)
    if len(parts) == 1:
        return parts[0] + (corner_times,), exhausted
    N = sum(part[0] for part in parts)
    if N >= arrival:
        return None, exhausted
    # piece by piece, each up to its arrival; the last with its rest on the end
    cut = [part[0] for part in parts[:-1]] + [len(parts[-1][1])]
    y, param, w, theta, u = (np.concatenate([part[q][:k] for part, k in zip(parts, cut)])
                             for q in range(1, 6))
    return (N, y, param, w, theta, u,
            np.cumsum([part[0] for part in parts[:-1]]).astype(float)), exhausted


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-300)
