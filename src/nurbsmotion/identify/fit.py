"""Fitting one axis of a log to the model of :mod:`nurbsmotion.identify.model`.

The steps (docs/identify.md):

1. An ARX regression on the position increments (the exact sampled model of a first-order
   lag, a few input taps and a sign(speed) term) gives tau, G = Ke*Kc and the Coulomb
   friction to start from.
2. The delay by a search over fractions of a sample (and a few starts of tau), then an
   output-error fit (:func:`least_squares`, Levenberg-Marquardt) of the simulated
   increments against the logged ones: tau, G, delay and Coulomb friction.
3. A mode: started from the largest peaks of the residual's smoothed spectrum above the
   rigid body's band (from the rigid fit and from the delay search's start; a few short
   fits each, the best on to convergence), kept when it lowers the residual clearly.
4. The stiction by a scan of the same residual, bounded by the breakaways (the largest
   drive an axis held at rest); the rest refitted to it and the scan repeated on the
   refit until it no longer moves the stiction.
5. Steps 2-4 again holding the stiction the last scan found, until a scan no longer moves
   it (a fixed point, :func:`fit_axis`); the least residual is kept.

The residual is on the increments ``y[k+1] - y[k]`` [pulse per sample] rather than on the
positions: the simulated speed does not drift, the position of an open-loop simulation
does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from .model import simulate

MODE_GAIN = 0.15
"""A mode is kept when it lowers the residual's sum of squares by at least this share."""

LOAD_FRACTION_RANGE = (0.05, 0.95)
"""Bounds of the load's share of the inertia where the fit takes it as a parameter (the
encoder on the load, friction on the motor)."""

MAX_DELAY_SAMPLES = 8.0
"""Largest delay searched [sample periods]."""

MODE_STARTS = 3
"""Peaks of the residual's spectrum a mode is started from (the largest, in its band)."""

MODE_SCREEN_ITERATIONS = 4
"""Iterations of each start of the mode before the best one is fitted to convergence."""

SPECTRUM_BINS = 5
"""Bins of the moving average over the residual's periodogram before its peaks are
picked. A raw periodogram's bins scatter by their own size (chi-squared with 2 degrees
of freedom), so its largest bin is often beside the mode's peak or on the rigid fit's
misfit; the average of 5 scatters sqrt(5) times less, and a mode that rings for several
of the log's 1/duration bins keeps its place."""


@dataclass
class AxisFit:
    """The fitted parameters of one axis, their standard deviations, and notes."""

    values: dict
    sigma: dict
    residual_rms: float
    residual: np.ndarray
    simulated: np.ndarray
    notes: list = field(default_factory=list)
    identified: dict = field(default_factory=dict)
    state: tuple = ()


def _residual_fn(u, dy, Ts, speed0, fixed, names):
    def fn(x):
        params = dict(fixed)
        for name, value in zip(names, x):
            params[name] = value
        params["time_constant"] = math.exp(params.pop("log_tau"))
        params["gain"] = math.exp(params.pop("log_gain"))
        if "log_omega" in params:
            params["resonance_frequency"] = math.exp(params.pop("log_omega")) / (2 * math.pi)
        params["delay"] = params.pop("delay_samples") * Ts
        y = simulate(u, Ts, params, params.pop("speed0", speed0))
        return np.diff(y) - dy
    return fn


def least_squares(fn, x0, bounds, max_iterations: int = 60, **_ignored):
    """Levenberg-Marquardt on the normal equations, bounds by projection.

    scipy's ``least_squares`` factors the tall Jacobian (n_samples x a few) by SVD or QR
    every iteration, which under a multithreaded BLAS on a busy machine cost 0.1 s each;
    the few parameters here need only ``J^T J``. Same result fields (``x``, ``fun``,
    ``cost`` = half the sum of squares, ``jac``, ``nfev``).
    """
    lower, upper = (np.asarray(b, dtype=float) for b in bounds)
    x = np.clip(np.asarray(x0, dtype=float), lower, upper)
    r = fn(x)
    cost = float(r @ r)
    nfev = 1
    lam = 1e-3
    J = None
    # A parameter its bounds hold (lower == upper, as a log's initial speed at rest) has
    # no column: its finite difference would step outside them (the speed off 0 jumps the
    # model from stuck to sliding) and cost a simulation for nothing.
    held = lower == upper
    for _ in range(max_iterations):
        J = np.zeros((r.size, x.size))
        for i in range(x.size):
            if held[i]:
                continue
            h = 1e-6 * max(abs(x[i]), 1.0)
            xi = x.copy()
            xi[i] = x[i] + h if x[i] + h <= upper[i] else x[i] - h
            try:
                J[:, i] = (fn(xi) - r) / (xi[i] - x[i])
            except ArithmeticError:  # at the edge of a double: no slope to follow
                J[:, i] = 0.0
            nfev += 1
        A = J.T @ J
        g = J.T @ r
        scale = np.diag(A).copy()
        scale[scale <= 0] = 1.0
        # Parameters held at a bound by the gradient leave the step (an active set):
        # projecting a coupled step would spoil the others.
        free = ~(((x <= lower) & (g > 0)) | ((x >= upper) & (g < 0)) | held)
        improved = False
        done = False
        for _ in range(12):
            dx = np.zeros_like(x)
            try:
                dx[free] = -np.linalg.solve((A + lam * np.diag(scale))[np.ix_(free, free)],
                                            g[free])
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            xn = np.clip(x + dx, lower, upper)
            try:
                rn = fn(xn)
            except ArithmeticError:  # a step beyond a double: exp of a log-parameter
                lam *= 4.0           # overflowed, or underflowed to a zero gain
                continue
            nfev += 1
            with np.errstate(over="ignore", invalid="ignore"):
                cn = float(rn @ rn)  # inf or NaN: no better
            if cn < cost:
                done = cost - cn <= 1e-12 * cost or np.all(
                    np.abs(xn - x) <= 1e-10 * np.maximum(np.abs(x), 1.0))
                x, r, cost = xn, rn, cn
                lam = max(lam / 3.0, 1e-12)
                improved = True
                break
            lam *= 4.0
        if not improved or done:
            break
    return SimpleNamespace(x=x, fun=r, cost=0.5 * cost, jac=J, nfev=nfev)


def _arx(u, dy, Ts, max_taps=6):
    """tau, G and F from ``dy[k+1] = a dy[k] + sum_i b_i u[k+1-i] - cf sign(dy[k])``."""
    n = len(dy)
    taps = min(max_taps, max(n - 3, 1))
    rows = np.arange(taps, n - 1)
    moving = np.abs(dy) > 1.5
    sign = np.where(moving, np.sign(dy), 0.0)
    cols = [dy[rows]] + [u[rows + 1 - i] for i in range(taps)] + [-sign[rows]]
    A = np.column_stack(cols)
    b = dy[rows + 1]
    coef, *_ = np.linalg.lstsq(A, b, rcond=None)
    a = coef[0]
    bsum = float(np.sum(coef[1:taps + 1]))
    if not (0.0 < a < 1.0) or bsum <= 0:
        return None
    tau = -Ts / math.log(a)
    gain = bsum / ((1.0 - a) * Ts)
    friction = max(float(coef[-1]) / bsum, 0.0)
    return tau, gain, friction


def _breakaways(u, y, Ts, noise):
    """Drive bounds of the stiction from the rests in the log: the largest |u| an axis at
    rest held (lower bound) and the |u| at which it left each rest (upper bounds)."""
    dy = np.diff(y)
    still = np.abs(dy) <= 1.0 + 4.0 * noise
    held, moved = [], []
    k = 0
    n = len(dy)
    while k < n:
        if not still[k]:
            k += 1
            continue
        j = k
        while j < n and still[j]:
            j += 1
        if j - k >= 5 and j < n:  # a rest of 5 samples or more, then a move
            window = u[k:j]
            held.append(float(np.max(np.abs(window))))
            moved.append(float(abs(u[j - 1]) if j >= 1 else abs(u[j])))
        k = j
    return held, moved


def _spectrum_peaks(spectrum, freqs, band, count: int = MODE_STARTS) -> list:
    """The frequencies [Hz] of the ``count`` largest local maxima of the periodogram
    ``spectrum`` (at ``freqs``) within ``band`` (a boolean mask), once smoothed over
    :data:`SPECTRUM_BINS`; each peak more than that many bins from a larger one."""
    width = SPECTRUM_BINS
    smooth = np.convolve(spectrum, np.ones(width) / width, mode="same")
    index = np.flatnonzero(band)
    peaks = []
    for i in index[np.argsort(smooth[index])[::-1]]:
        if len(peaks) == count:
            break
        if all(abs(i - j) > width for j in peaks) and smooth[i] >= np.max(
                smooth[max(i - width, 0):i + width + 1]):
            peaks.append(int(i))
    if not peaks:
        peaks = [int(index[np.argmax(smooth[index])])]
    return [float(freqs[i]) for i in peaks]


def _plateau(values, costs, at) -> tuple[float, float]:
    """The range of ``values`` around ``at`` whose ``costs`` equal the least (to a
    relative 1e-9): the values of a parameter that the residual cannot tell apart."""
    order = np.argsort(values, kind="stable")
    v = np.asarray(values, dtype=float)[order]
    c = np.asarray(costs, dtype=float)[order]
    flat = c <= c.min() * (1.0 + 1e-9) + 1e-300
    i = int(np.flatnonzero(flat & (v == at))[0]) if np.any(flat & (v == at)) else int(
        np.argmin(c))
    lo = hi = i
    while lo > 0 and flat[lo - 1]:
        lo -= 1
    while hi < v.size - 1 and flat[hi + 1]:
        hi += 1
    return float(v[lo]), float(v[hi])


def _real_mode(mode, rigid, lower, upper) -> bool:
    """A mode is kept when it lowers the residual clearly (by :data:`MODE_GAIN`, and the
    rigid fit's residual is above rounding), couples into the reading, and its frequency
    and damping are not at their bounds."""
    rms = math.sqrt(2 * rigid.cost / max(rigid.fun.size, 1))
    omega, zeta, coupling = mode.x[-3:]
    inside = all(lo + 1e-6 * max(1.0, abs(lo)) < v < hi - 1e-6 * max(1.0, abs(hi))
                 for v, lo, hi in zip(mode.x[-3:-1], lower[-3:-1], upper[-3:-1]))
    return bool(mode.cost < (1 - MODE_GAIN) * rigid.cost and rms > 1e-3
                and abs(coupling) > 0.02 and inside)


REST_SAMPLES = 10
"""Readings at the head of a log that :func:`_starts_at_rest` looks at."""


def _starts_at_rest(y) -> bool:
    """Whether the log starts at rest: its first :data:`REST_SAMPLES` readings move less
    than a count plus 4 standard deviations of the difference of two readings (the
    noise estimated from the scatter of their increments)."""
    head = np.asarray(y[:REST_SAMPLES + 1], dtype=float)
    if head.size < 3:
        return False
    return abs(head[-1] - head[0]) <= 1.0 + 4.0 * math.sqrt(2.0) * _head_noise(y)


def _head_noise(y) -> float:
    """The reading noise [pulse] estimated from the scatter of the increments of the
    first :data:`REST_SAMPLES` readings (of a log that starts at rest)."""
    head = np.asarray(y[:REST_SAMPLES + 1], dtype=float)
    return float(np.std(np.diff(head))) / math.sqrt(2.0) if head.size >= 3 else 0.0


SCREEN_SAMPLES = 6_000
"""The structure of the model (delay start, friction, mode, stiction) is chosen on the
log's first this many samples; a longer log then refines the parameters in a few
iterations on all of it."""


STICTION_PASSES = 3
"""Fits at most per axis with friction, each holding the stiction the previous one's scan
found (see :func:`fit_axis`)."""


STICTION_SHIFT = 1e-3
"""A scan that moves the stiction by less than this share of Umax ends the passes (the
share below which a friction is taken as zero, as in :func:`_fit_once`)."""


def fit_axis(u: np.ndarray, y: np.ndarray, Ts: float, *, noise: float = 0.0,
             max_drive: float = 10.0, base: dict | None = None,
             screen: int | None = SCREEN_SAMPLES) -> AxisFit:
    """Fit one axis (see the module docstring).

    The stiction is not a parameter of the least-squares fits (the residual steps with
    it: an axis held at rest breaks away only where the drive crosses it), but it shapes
    every stop and breakaway, and on a two-mass axis the motor stops every half period
    of the mode: a fit holding the stiction at the Coulomb friction bends tau, Ke*Kc and
    the friction to mimic it, and can run off (tau at its bound). So the fit is a fixed
    point in the stiction: the whole fit is repeated holding the stiction the previous
    fit's scan found, while that scan moves it by more than :data:`STICTION_SHIFT` of
    Umax (at most
    :data:`STICTION_PASSES` fits), and the fit with the least residual is kept.

    Parameters
    ----------
    u : ndarray, shape (n_samples,)
        Drive [V] held over each sample.
    y : ndarray, shape (n_samples,)
        Encoder reading [pulse].
    Ts : float
        Sample period [s].
    noise : float
        A first guess of the reading noise [pulse] (for the rest detection).
    max_drive : float
        Umax [V], the bound of the friction.
    base : dict, optional
        ``time_constant`` and ``gain`` to fall back on where the data say nothing.
    screen : int, optional
        On a longer log the structure is chosen on its first this many samples
        (:data:`SCREEN_SAMPLES`); None fits the whole log.
    """
    if screen is not None and len(y) > screen:
        head = fit_axis(u[:screen], y[:screen], Ts, noise=noise, max_drive=max_drive,
                        base=base, screen=None)
        sol, names, fixed, bounds, speed0 = head.state
        fn = _residual_fn(u, np.diff(y), Ts, speed0, fixed, names)
        sol = least_squares(fn, sol.x, bounds=bounds, max_iterations=6)
        return _finish(u, y, Ts, sol, names, fixed, fn, speed0, head.notes,
                       head.identified, head.sigma["stiction"], bounds)
    # The first fit holds the stiction at the Coulomb friction (S = F while F moves);
    # the next ones hold it at the value the previous scan found (F may then move
    # below it).
    held = None
    best = fit = _fit_once(u, y, Ts, noise, max_drive, base, 0.0)
    for _ in range(STICTION_PASSES - 1):
        if not fit.identified["stiction"]:
            break
        found = fit.values["stiction"]
        if held is not None and not abs(found - held) > STICTION_SHIFT * max_drive:
            break  # the fixed point
        held = found
        # The mode shows in the spectrum whatever the stiction: a later fit looks for it
        # only where the first found it, and from its frequency (the mode search is most
        # of a fit's work).
        found_mode = best.identified["resonance"]
        sign = math.copysign(1.0, best.values["coupling"]) if found_mode else 0.0
        fit = _fit_once(u, y, Ts, noise, max_drive, base, held, sign,
                        best.values["resonance_frequency"] if found_mode else None)
        if fit.residual_rms < best.residual_rms:
            best = fit
    return best


def _fit_once(u, y, Ts, noise, max_drive, base, stiction, mode_sign=None,
              mode_frequency=None) -> AxisFit:
    """One fit of :func:`fit_axis`, holding the stiction at ``stiction`` [V] (read as
    the Coulomb friction where below it) until its scan at the end. ``mode_sign``: None
    searches a mode with the encoder on the motor and on the load; 1.0 or -1.0 only
    there (+1 the motor); 0.0 searches none. ``mode_frequency`` [Hz]: the mode is started
    there alone, not from the residual spectrum's peaks."""
    notes: list[str] = []
    dy = np.diff(y)
    speed0 = 0.0
    if np.all(np.abs(dy[:3]) > 1.0 + 4.0 * noise) and np.ptp(np.sign(dy[:3])) == 0:
        speed0 = float(dy[0]) / Ts
    start = _arx(u, dy, Ts)
    if start is None:
        if base is None:
            start = (0.1, 1e6, 0.0)
        else:
            start = (base["time_constant"], base["gain"], 0.0)
        notes.append("the ARX start failed (a < 0 or a >= 1): started from the base machine")
    tau0, gain0, friction0 = start
    tau0 = min(max(tau0, 5 * Ts), 1e4 * Ts)

    moving = np.abs(dy) > 1.0 + 4.0 * noise
    direction = np.sign(dy[moving])
    reversals = int(np.count_nonzero(np.diff(direction) != 0)) if direction.size else 0
    both_ways = direction.size > 0 and np.any(direction > 0) and np.any(direction < 0)
    friction_ok = bool(both_ways and reversals >= 2)
    friction_zero = False

    # speed0: the speed at the log's first sample [pulse/s], fitted with the rest (a log
    # need not start at rest).
    names = ["log_tau", "log_gain", "delay_samples", "speed0"]
    x0 = [math.log(tau0), math.log(gain0), 0.0, speed0]
    lower = [math.log(Ts), -np.inf, 0.0, -np.inf]
    upper = [math.log(1e6 * Ts), np.inf, MAX_DELAY_SAMPLES, np.inf]
    if _starts_at_rest(y):
        # A log that starts at rest has no initial speed to fit: free, speed0 jumps the
        # model between stuck and sliding at 0 (with friction), and its finite-difference
        # derivative misleads the fit into a valley of its own.
        lower[3] = upper[3] = 0.0
    fixed = {"stiction": stiction}  # the stiction is scanned once the rest is fitted
    if friction_ok:
        names.append("coulomb_friction")
        x0.append(min(friction0, 0.5 * max_drive))
        lower.append(0.0)
        upper.append(max_drive)
    else:
        fixed["coulomb_friction"] = 0.0
        notes.append("coulomb_friction and stiction: not identifiable, the axis never "
                     "reversed its motion (a constant friction is then the same as a drive "
                     "offset); use a log with moves both ways")

    # The delay and tau: the best of a few starts (the residual has local minima a sample
    # apart in the delay; a mode can mislead the ARX start of tau).
    taus = [tau0] + ([base["time_constant"]] if base is not None else []) + [
        tau0 * 3.0, tau0 * 10.0]
    best = None
    for tau_start in taus:
        gain_start = gain0 if base is None or tau_start == tau0 else base["gain"]
        for d in (0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0):
            x = list(x0)
            x[0] = math.log(min(max(tau_start, 5 * Ts), 1e4 * Ts))
            x[1] = math.log(gain_start)
            x[2] = d
            r = _residual_fn(u, dy, Ts, speed0, fixed, names)(np.array(x))
            cost = float(r @ r)
            if best is None or cost < best[0]:
                best = (cost, x)
    x0 = best[1]
    # First the linear part alone (smooth in every parameter), then with the friction,
    # whose sticking makes the residual kink: started near its optimum, the fit stays in
    # the right valley.
    linear = names[:4]
    fn = _residual_fn(u, dy, Ts, speed0, dict(fixed, coulomb_friction=0.0, stiction=0.0),
                      linear)
    sol = least_squares(fn, x0[:4], bounds=(lower[:4], upper[:4]))
    if friction_ok:
        fn = _residual_fn(u, dy, Ts, speed0, fixed, names)
        tries = [least_squares(fn, list(sol.x) + [f], bounds=(lower, upper))
                 for f in sorted({0.0, x0[4]})]
        # and from the delay search's start itself (the ARX's tau, gain and friction):
        # on an axis whose friction holds it at rest for long, the frictionless fit
        # bends tau to mimic the rests, and the fit from there can run off to the
        # integrator (tau at its bound, only gain/tau sharp).
        tries.append(least_squares(fn, x0, bounds=(lower, upper)))
        sol = min(tries, key=lambda t: t.cost)

    # A mode: started at the residual spectrum's largest peaks above the rigid body's
    # band (a few short fits each), the best one fitted on to convergence.
    mode_sol = None
    residual = sol.fun
    n = residual.size
    if n >= 64 and (mode_sign is None or mode_sign != 0.0):
        spectrum = np.abs(np.fft.rfft(residual * np.hanning(n))) ** 2
        freqs = np.fft.rfftfreq(n, Ts)
        # A strong mode can pull the rigid fit's tau to a few samples (and its delay
        # up), mimicking the mode's fast rise: the rigid body's band then reaches from
        # the longer of its tau and the delay search's start, and the mode is started
        # from both (and from the ARX's friction: with friction, a strong mode misleads
        # the rigid fit, tau run off to its bound).
        tau_rigid = max(math.exp(sol.x[0]), math.exp(x0[0]))
        band = (freqs > max(5.0 / (2 * math.pi * tau_rigid), 5.0)) & (
            freqs < 0.45 / Ts)
        if np.any(band):
            best_mode = None
            rigid_starts = [list(sol.x)] + ([list(x0)] if list(x0) != list(sol.x) else [])
            signs = (1.0, -1.0) if mode_sign is None else (mode_sign,)
            peaks = ([mode_frequency] if mode_frequency is not None else
                     _spectrum_peaks(spectrum, freqs, band))
            starts = [(r0, f0, c0) for f0 in peaks for r0 in rigid_starts for c0 in signs]
            for rigid0, f0, coupling0 in starts:
                # The friction acts on the motor: with the encoder on the load (coupling
                # about -1) the motor's share of the twist, hence the load fraction, is a
                # parameter of its own (on the motor it is the coupling's c / (1 + c)).
                share = friction_ok and coupling0 < 0
                m_names = names + (["load_fraction"] if share else []) + [
                    "log_omega", "resonance_damping", "coupling"]
                mx0 = rigid0 + ([0.5] if share else []) + [
                    math.log(2 * math.pi * f0), 0.05, coupling0]
                m_lower = lower + ([LOAD_FRACTION_RANGE[0]] if share else []) + [
                    math.log(2 * math.pi * 2.0), 1e-3, -1.5]
                m_upper = upper + ([LOAD_FRACTION_RANGE[1]] if share else []) + [
                    math.log(2 * math.pi * 0.5 / Ts), 0.5, 20.0]
                m_fn = _residual_fn(u, dy, Ts, speed0, fixed, m_names)
                try:
                    m_sol = least_squares(m_fn, mx0, bounds=(m_lower, m_upper),
                                          max_iterations=MODE_SCREEN_ITERATIONS)
                except ValueError:
                    continue
                if best_mode is None or m_sol.cost < best_mode[0].cost:
                    best_mode = (m_sol, m_names, m_lower, m_upper)
            if best_mode is not None:  # the better start, on to convergence
                m_sol, m_names, m_lower, m_upper = best_mode
                m_fn = _residual_fn(u, dy, Ts, speed0, fixed, m_names)
                best_mode = (least_squares(m_fn, m_sol.x, bounds=(m_lower, m_upper),
                                           max_iterations=40), m_names, m_lower, m_upper)
            if best_mode is not None and _real_mode(best_mode[0], sol, best_mode[2],
                                                    best_mode[3]):
                mode_sol = best_mode
            else:
                gain_share = 0.0 if best_mode is None else 1 - best_mode[0].cost / sol.cost
                notes.append(
                    f"resonance: none found below {0.5 / Ts:g} Hz (a mode lowers the "
                    f"residual by {gain_share:.1%}, less than {MODE_GAIN:.0%}): the axis "
                    "is rigid in this band, or the log did not excite its mode")
    bounds = (lower, upper)
    if mode_sol is not None:
        sol, names, m_lower, m_upper = mode_sol
        bounds = (m_lower, m_upper)
        fn = _residual_fn(u, dy, Ts, speed0, fixed, names)

    if friction_ok:
        # A friction the data cannot tell from zero (below 3 standard deviations, or
        # 0.1 % of Umax) is zero: a small spurious one would stick the model at rests.
        i = names.index("coulomb_friction")
        r = sol.fun
        cov = np.linalg.pinv(sol.jac.T @ sol.jac) * float(r @ r) / max(r.size - len(names), 1)
        sigma_f = math.sqrt(max(cov[i, i], 0.0))
        if sol.x[i] <= max(3.0 * sigma_f, 1e-3 * max_drive):
            notes.append(f"coulomb_friction: none found ({sol.x[i]:.3g} +- {sigma_f:.2g} V, "
                         "not above its noise); written as 0")
            # (and the load fraction, which only the friction on the motor shows)
            drop = [i] + ([names.index("load_fraction")] if "load_fraction" in names else [])
            x = np.delete(sol.x, drop)
            names = [name for k, name in enumerate(names) if k not in drop]
            lo, hi = (np.delete(np.asarray(b, dtype=float), drop) for b in bounds)
            bounds = (list(lo), list(hi))
            fixed = dict(fixed, coulomb_friction=0.0, stiction=0.0)
            fn = _residual_fn(u, dy, Ts, speed0, fixed, names)
            sol = least_squares(fn, x, bounds=bounds, max_iterations=20)
            friction_ok = False
            friction_zero = True

    values = dict(zip(names, sol.x))
    # Stiction: the breakaways bound it; the residual picks within the bounds.
    identified = {"time_constant": True, "gain": True, "delay": True,
                  "coulomb_friction": friction_ok or friction_zero, "stiction": False,
                  "resonance": mode_sol is not None}
    stiction_sigma = math.nan
    friction = values.get("coulomb_friction", fixed.get("coulomb_friction", 0.0))
    # The rests: within a count and 4 standard deviations of the reading noise, measured
    # at the head of a log that starts at rest, else the fit's residual (rms / sqrt(2));
    # an early fit's residual, many counts, would take slow moves for rests (and their
    # drives, volts above the friction, for the stiction's lower bound).
    noise = max(noise, _head_noise(y) if _starts_at_rest(y) else
                math.sqrt(sol.cost / max(sol.fun.size, 1)))
    held, moved = _breakaways(u, y, Ts, noise)
    if friction_ok and held:
        # The largest drive an axis held at rest bounds the stiction from below (within
        # the rest detection's threshold); the residual picks it on a grid above it,
        # the rest is refitted to it, and the grid scanned again on the refit, until
        # the scan no longer moves it (by STICTION_SHIFT of Umax; at most
        # STICTION_PASSES scans): a scan on parameters bent to the stiction held before
        # finds that stiction again.
        i_f = names.index("coulomb_friction")
        current = max(stiction, float(sol.x[i_f]))
        for _ in range(STICTION_PASSES):
            friction = float(sol.x[i_f])
            hi = min(max(max(held), max(moved, default=0.0)) + 0.05 * max_drive, max_drive)
            grid = np.linspace(friction, max(hi, friction + 1e-3 * max_drive), 31)

            def cost_of(s):
                r = _residual_fn(u, dy, Ts, speed0, dict(fixed, stiction=float(s)),
                                 names)(sol.x)
                return float(r @ r)
            costs = [cost_of(s) for s in grid]
            i = int(np.argmin(costs))
            step = float(grid[1] - grid[0])
            fine = np.linspace(max(grid[i] - step, friction), grid[i] + step, 21)
            fine_costs = [cost_of(s) for s in fine]
            fixed["stiction"] = float(fine[int(np.argmin(fine_costs))])
            lo_s, hi_s = _plateau(np.concatenate([grid, fine]),
                                  np.concatenate([costs, fine_costs]), fixed["stiction"])
            # The stiction's spread: the grid's step, or the plateau of stictions that fit
            # the log equally (a rigid axis breaks away only where the drive from rest
            # crosses it: between two such drives every stiction fits alike), as a
            # uniform distribution's.
            stiction_sigma = max(float(fine[1] - fine[0]), (hi_s - lo_s) / math.sqrt(12.0))
            identified["stiction"] = True
            flat_from_friction = (lo_s <= friction
                                  and hi_s - friction > STICTION_SHIFT * max_drive)
            fn = _residual_fn(u, dy, Ts, speed0, fixed, names)
            found = max(fixed["stiction"], friction)
            if not abs(found - current) > STICTION_SHIFT * max_drive:
                break
            # the rest refitted to the stiction found, from where it is
            sol = least_squares(fn, sol.x, bounds=bounds, max_iterations=20)
            current = max(fixed["stiction"], float(sol.x[i_f]))
        if flat_from_friction:
            # Every stiction from the Coulomb friction up fits alike: the log holds no
            # breakaway from rest at a drive in between, so it cannot tell S from F.
            identified["stiction"] = False
            notes.append(
                f"stiction: not identifiable from this log, any value from the Coulomb "
                f"friction {friction:.3g} V to {hi_s:.3g} V fits it alike (no breakaway "
                "from rest at a drive in between: its drive steps from rest past them); "
                "not written (the plant then takes it as the Coulomb friction); log a "
                "slower drive ramp from rest")
    elif friction_ok:
        notes.append("stiction: not identifiable, the axis never left a rest (of 5 samples "
                     "or more) in the log; add a slow drive ramp from rest")
    return _finish(u, y, Ts, sol, names, fixed, fn, speed0, notes, identified,
                   stiction_sigma, bounds)


def _finish(u, y, Ts, sol, names, fixed, fn, speed0, notes, identified, stiction_sigma,
            bounds) -> AxisFit:
    """The estimates, their standard deviations and the simulated response."""
    i_tau = names.index("log_tau")
    lower, upper = bounds
    gain = math.exp(min(sol.x[names.index("log_gain")], 700.0))
    if (not lower[i_tau] < sol.x[i_tau] < upper[i_tau]) or not 0.0 < gain < math.inf:
        # At a bound the fit has no minimum inside, and (J^T J)^-1 no spread to give.
        notes = list(notes) + [
            f"time_constant and electrical_gain: not identified, the fit ended at a bound "
            f"(tau {math.exp(sol.x[i_tau]):.4g} s, Ke*Kc {gain:.4g} pulse/s/V): the "
            "axis's position does not follow its drive as a servo axis's would (check "
            "the columns, their units and the axis's enable)"]
    r = fn(sol.x)
    dof = max(r.size - len(names), 1)
    s2 = float(r @ r) / dof
    try:
        J = sol.jac
        cov = np.linalg.pinv(J.T @ J) * s2
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except (np.linalg.LinAlgError, ValueError):
        sig = np.full(len(names), math.nan)
    out = {}
    sigma = {}
    for name, x, sx in zip(names, sol.x, sig):
        if name == "log_tau":
            out["time_constant"] = math.exp(x)
            sigma["time_constant"] = math.exp(x) * sx
        elif name == "log_gain":
            out["gain"] = math.exp(x)
            sigma["gain"] = math.exp(x) * sx
        elif name == "log_omega":
            out["resonance_frequency"] = math.exp(x) / (2 * math.pi)
            sigma["resonance_frequency"] = math.exp(x) / (2 * math.pi) * sx
        elif name == "delay_samples":
            out["delay"] = x * Ts
            sigma["delay"] = sx * Ts
        else:
            out[name] = float(x)
            sigma[name] = float(sx)
    out["coulomb_friction"] = out.get("coulomb_friction", fixed.get("coulomb_friction", 0.0))
    out["stiction"] = max(fixed["stiction"], out["coulomb_friction"])
    sigma.setdefault("coulomb_friction", math.nan)
    sigma["stiction"] = stiction_sigma
    params = dict(out)
    y_sim = simulate(u, Ts, params, out.pop("speed0", speed0)) + y[0]
    sigma.pop("speed0", None)
    return AxisFit(values=out, sigma=sigma, residual_rms=float(np.sqrt(np.mean(r * r))),
                   residual=r, simulated=y_sim, notes=notes, identified=identified,
                   state=(sol, names, fixed, bounds, speed0))
