"""The landing's law of ``planned`` on an axis whose model declares a mode (issue 33):
the gains of :func:`.identify._landing_law`'s law placed on the model *with* its mode, its
delay and the law's own integral and speed estimate, robust to the true mode, tau and Kc
off the model's (:func:`mode_landing_law`, docs/model.md#planned-on-a-real-machine).

The law of the rigid landing (:func:`.identify._landing_gains`) puts the poles of the
rigid plant at ``tracking_pole``; the mode then sits in the loop unplaced, and on a
lightly damped mode (100 Hz, damping 0.02, model 90 Hz) that landing limit-cycled at
rest. Here the law's structure is kept (the state after the drive in flight, predicted
from the last position increment through the rigid model, and the integral of the error)
and its three gains are chosen for the loop *with* the mode: the closed loop of that law
on the sampled two-mass axis (:func:`landing_loop`, ``scipy.linalg.expm`` of the
continuous model :func:`nurbsmotion.plant.continuous_model`, the drive arriving the model's
delay late) is formed at every corner of the model's uncertainty (:data:`MODEL_SPREAD`),
and the gains minimise the largest pole radius over all corners (Nelder-Mead on the
logarithms of the gains, from the rigid placement slowed along the pole's path).

On a reading that is not exact (encoder counts, measurement noise: the landing's band > 0)
the law's speed from the last position increment turns a count, or the noise, into a
speed of a count per sample: on a fast sampled axis (Ts 0.1-0.5 ms) the designed law
answered one count with 1-4.5 V and chattered at rest up to its drive limit (item 4 of
issue 33: cases 12, 18, 81). There the landing takes its speed from the observer the rigid
axes use (:mod:`.rest_observer`: the model's rigid plant advanced by the drives applied and
corrected by a share of the reading's innovation), and the law's gains are designed with
that observer inside the loop (:func:`observer_landing_loop`) on the same corners. An
observer filters a count the more the slower it is, but its lag slows the landing the
mode allows (on die-bonder-real, at 0.7 the best radius over the corners is 0.992, 0.914
without): the slowest observer is taken whose law is no slower than the law without it
or the machine's own loop, whichever is slower (:func:`_axis_law`), and stable too at
the reading gains a quantiser can have and, its integral held, at every share of the
drive that friction the model does not know lets through (:func:`observer_is_robust`);
where none is, the law without it is kept (:func:`mode_rest_observer`). The corners are
sampled once per model axis and every design evaluates their loops as one stack.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ...errors import InfeasibleError
from ...machine import Machine
from ...plant import continuous_model
from ...plant.linear import linear_loop_poles, split_sample
from .disturbance import observer_gains as disturbance_gains
from .identify import LAW_ROWS, _landing_law, _pole_gains
from .rest_observer import QUANTISER_GAIN, REST_OBSERVER_ROWS, observer_gains

__all__ = ["mode_landing_law", "landing_loop", "observer_landing_loop", "mode_rest_observer",
           "observer_is_robust", "DRIVE_SHARES", "tracking_observer_loop",
           "mode_disturbance_observer", "DOB_POLES", "DOB_ROW",
           "sampled_axis", "uncertainty_corners", "MODEL_SPREAD", "MODE_LAW_ROWS"]

MODEL_SPREAD = 0.10
"""How far the true axis may be off the model the law is designed on: tau and Kc within
x[1 - s, 1 + s] of the model's, and the model's mode frequency within x[1 - s, 1 + s] of
the true one (issue 33: "known to the model within 10 %"), so the true frequency within
[f/(1 + s), f/(1 - s)] of the model's f."""

DOB_ROW = 1 + LAW_ROWS + 2
"""The plan's ``mode_law`` row from which the tracking's disturbance observer designed
with the mode is (:func:`mode_disturbance_observer`): 1 where it is (0: none), then its
gains ``(L_w, L_th, L_d)`` (:func:`.disturbance.observer_gains` at the designed pole)."""

MODE_LAW_ROWS = DOB_ROW + 4
"""Rows per axis of the plan's ``mode_law``: 1 where the laws below replace the landing's
and the tracking's laws on the identified plant (0: both rigid, unchanged), then
:func:`_landing_law`'s rows (the model's rigid plant, the landing's gains designed with the
mode), then the tracking's gains ``(k_theta, k_w)`` designed with the mode, then the
tracking's disturbance observer (:data:`DOB_ROW`)."""

SLOWING = np.geomspace(1e-3, 1.0, 13)
"""The starting point's search: the rigid placement's gains (k_theta, k_w, k_i) scaled by
(s, s^1/2, s^3/2), the way they scale as the placed pole approaches 1 (``1 - pole``
squared, to the first power and cubed over the plant's gains, :func:`_landing_gains`), for
s over three decades; the best of these starts the descent."""

MAX_DESCENT = 2000
"""Nelder-Mead's largest number of iterations (it converges in about 200)."""


def sampled_axis(tau: float, Kc: float, Ke: float, sample_period: float, delay: float,
                 frequency: float = 0.0, damping: float = 0.0, load_fraction: float = 0.5):
    """The axis sampled over one period with its drive ``delay`` samples late
    (0 <= delay < 1): ``x[k+1] = Phi x[k] + g1 u[k-1] + g0 u[k]``.

    Parameters
    ----------
    tau : float
        Time constant [s].
    Kc, Ke : float
        Electrical [(rad/s)/V] and mechanical [pulse/rad] gains.
    sample_period : float
        Ts [s].
    delay : float
        The drive's delay [samples], in [0, 1).
    frequency, damping, load_fraction : float
        The two-mass mode [Hz], its damping ratio and the load's share of the inertia
        (frequency 0: rigid).

    Returns
    -------
    Phi : ndarray, shape (nx, nx)
    g1, g0 : ndarray, shape (nx,)
        [pulse/V, (rad/s)/V per state]; nx = 2 (``[w, theta]``) rigid, 4
        (``[w_motor, theta_motor, w_load, theta_load]``) with a mode.
    """
    A, B = continuous_model(tau, Kc, Ke, frequency, damping, load_fraction)
    return split_sample(A, B, delay * sample_period, (1.0 - delay) * sample_period)


def _law_rows(law: np.ndarray):
    """The landing law (:func:`_landing_law`'s rows) as linear forms on
    ``(th[k], th[k-1], u[k-1], u[k-2])``: the drive's (without the integral), the error's
    (``e = -(predicted position)`` about the end) and the integral's gain."""
    al, cl, g0w, g0th, g1w, g1th, ah, b0h, ch, b1h, kt, kw, ki = law[:LAW_ROWS]
    w_last = np.array([1.0, -1.0, -g0th, -g1th]) / cl
    w_land = al * w_last + np.array([0.0, 0.0, g0w, g1w])
    e = -(np.array([1.0, 0.0, b1h, 0.0]) + ch * w_land)
    w_pred = ah * w_land + np.array([0.0, 0.0, b0h, 0.0])
    return kt * e - kw * w_pred, e, ki


def landing_loop(law: np.ndarray, axis, encoder_on: str = "motor",
                 integral: bool = True) -> np.ndarray:
    """The transition matrix of the landing's linear closed loop (no band, clip or
    quantiser): the sampled ``axis`` (:func:`sampled_axis`) under the law ``law``
    (:func:`_landing_law`'s rows, applied as :func:`.step.online_step` applies them) about
    the end. State ``[x (nx), th[k-1], u[k-1], u[k-2], z]``; its eigenvalues are the
    loop's poles. ``integral=False``: the tracking's loop about the plan (the same law
    without the integral, :func:`.step.online_step` step 3), the state without z.
    ``axis`` may be a stack of axes (``Phi`` of shape (..., nx, nx), ``g1`` and ``g0``
    (..., nx)): one loop per axis.

    Returns
    -------
    ndarray, shape (..., nx + 4, nx + 4), or (..., nx + 3, nx + 3) without the integral
    """
    Phi, g1, g0 = axis
    nx = Phi.shape[-1]
    pos = np.zeros(nx)
    pos[1 if (nx == 2 or encoder_on == "motor") else 3] = 1.0
    uc, ec, ki = _law_rows(law)
    n = nx + 4
    U = np.zeros(n)
    E = np.zeros(n)
    U[:nx], U[nx:nx + 3], U[nx + 3] = uc[0] * pos, uc[1:], ki
    E[:nx], E[nx:nx + 3] = ec[0] * pos, ec[1:]
    T = np.zeros(Phi.shape[:-2] + (n, n))
    T[..., :nx, :nx] = Phi
    T[..., :nx, nx + 1] += g1
    T[..., :nx, :] += g0[..., :, None] * U
    T[..., nx, :nx] = pos
    T[..., nx + 1, :] = U
    T[..., nx + 2, nx + 1] = 1.0
    T[..., nx + 3, :] = E
    T[..., nx + 3, nx + 3] += 1.0
    return T if integral else T[..., :nx + 3, :nx + 3]


def observer_landing_loop(law: np.ndarray, axis, observer_pole: float,
                          encoder_on: str = "motor", reading_gain: float = 1.0) -> np.ndarray:
    """The transition matrix of the landing's linear closed loop with its speed from the
    observer (:func:`.step.online_step` step 3' on a reading not exact,
    :func:`.rest_observer.observer_gains` at ``observer_pole`` on the law's rigid plant
    ``law[0:2]``), about the end, no band, clip or quantiser. With ``u1 = u[k-1]``,
    ``u2 = u[k-2]`` and the reading ``y = theta_encoder[k]``:

        th_p = th_hat + c*w_hat + g0th*u1 + g1th*u2,  w_p = a*w_hat + g0w*u1 + g1w*u2
        w_hat' = w_p + m_w*(y - th_p),  th_hat' = th_p + m_theta*(y - th_p)
        e = -(y + c_h*w_hat' + b1_h*u1),  u = k_theta*e - k_w*(a_h*w_hat' + b0_h*u1) + k_i*z
        z' = z + e

    State ``[x (nx), u1, u2, z, w_hat, th_hat]``; its eigenvalues are the loop's poles.
    ``reading_gain`` N: the reading ``N*theta_encoder`` (a quantiser's describing-function
    gain, :data:`.rest_observer.QUANTISER_GAIN`: a limit cycle through the counts needs
    the loop unstable at some N the quantiser can have).

    ``axis`` may be a stack of axes, as for :func:`landing_loop`.

    Returns
    -------
    ndarray, shape (..., nx + 5, nx + 5)
    """
    Phi, g1, g0 = axis
    nx = Phi.shape[-1]
    al, cl, g0w, g0th, g1w, g1th, ah, b0h, ch, b1h, kt, kw, ki = law[:LAW_ROWS]
    m_w, m_th = observer_gains(al, cl, observer_pole)
    n = nx + 5
    iu1, iu2, iz, iw, ith = nx, nx + 1, nx + 2, nx + 3, nx + 4
    y = np.zeros(n)
    y[1 if (nx == 2 or encoder_on == "motor") else 3] = reading_gain
    th_p = np.zeros(n)
    th_p[ith], th_p[iw], th_p[iu1], th_p[iu2] = 1.0, cl, g0th, g1th
    w_p = np.zeros(n)
    w_p[iw], w_p[iu1], w_p[iu2] = al, g0w, g1w
    w_new = w_p + m_w * (y - th_p)
    th_new = th_p + m_th * (y - th_p)
    u1 = np.zeros(n)
    u1[iu1] = 1.0
    e = -(y + ch * w_new + b1h * u1)
    z = np.zeros(n)
    z[iz] = 1.0
    u = kt * e - kw * (ah * w_new + b0h * u1) + ki * z
    T = np.zeros(Phi.shape[:-2] + (n, n))
    T[..., :nx, :nx] = Phi
    T[..., :nx, iu1] += g1
    T[..., :nx, :] += g0[..., :, None] * u
    T[..., iu1, :] = u
    T[..., iu2, :] = u1
    T[..., iz, :] = z + e
    T[..., iw, :] = w_new
    T[..., ith, :] = th_new
    return T


def tracking_observer_loop(law: np.ndarray, plant, gains, axis,
                           encoder_on: str = "motor") -> np.ndarray:
    """The transition matrix of the tracking's linear closed loop about the plan with the
    disturbance observer (:func:`.step.online_step` steps 1a' and 3 on an axis whose model
    declares a mode; no dead zone, clip or quantiser; the reading less the model's twist
    under the plan's drive, so about the plan the deviation of the encoder's own reading).
    ``law``: :func:`_landing_law`'s rows with the tracking's gains in rows 10-11 (row 12
    unused); ``plant``: the model's rigid ZOH plant ``(a, b0, c, b1)``; ``gains``: the
    observer's ``(L_w, L_th, L_d)`` (:func:`.disturbance.observer_gains`). With ``u1 =
    u[k-1]``, ``u2 = u[k-2]`` (the drives applied), the reading ``y = theta_encoder[k]``:

        th_p = th_hat + c*w_hat + g0th*u1 + g1th*u2 + b1*d,  w_p = a*w_hat + g0w*u1
               + g1w*u2 + b0*d,  nu = y - th_p
        w_hat' = w_p + L_w*nu,  th_hat' = th_p + L_th*nu,  d' = d + L_d*nu
        v1, v2 = u1 + d', u2 + d'   (the drives the plant got, the estimate in them)
        w = a*(y - th[k-1] - g0th*v1 - g1th*v2)/c + g0w*v1 + g1w*v2
        u = -k_theta*(y + c_h*w + b1_h*v1) - k_w*(a_h*w + b0_h*v1) - d'

    (the tracking's speed from the last increment and the drives that made it, the state
    after the drive in flight, the estimate fed forward). State ``[x (nx), th[k-1], u1,
    u2, w_hat, th_hat, d]``; its eigenvalues are the loop's poles. ``axis`` may be a stack
    of axes (:func:`landing_loop`).

    Returns
    -------
    ndarray, shape (..., nx + 6, nx + 6)
    """
    Phi, g1, g0 = axis
    nx = Phi.shape[-1]
    al, cl, g0w, g0th, g1w, g1th, ah, b0h, ch, b1h, kt, kw = law[:12]
    a, b0, c, b1 = plant
    l_w, l_th, l_d = gains
    n = nx + 6
    ith1, iu1, iu2, iw, ith, i_d = range(nx, n)
    eye = np.eye(n)
    y = np.zeros(n)
    y[1 if (nx == 2 or encoder_on == "motor") else 3] = 1.0
    u1, u2 = eye[iu1], eye[iu2]
    th_p = eye[ith] + c * eye[iw] + g0th * u1 + g1th * u2 + b1 * eye[i_d]
    w_p = a * eye[iw] + g0w * u1 + g1w * u2 + b0 * eye[i_d]
    nu = y - th_p
    d_new = eye[i_d] + l_d * nu
    v1, v2 = u1 + d_new, u2 + d_new
    w = al * (y - eye[ith1] - g0th * v1 - g1th * v2) / cl + g0w * v1 + g1w * v2
    u = -kt * (y + ch * w + b1h * v1) - kw * (ah * w + b0h * v1) - d_new
    T = np.zeros(Phi.shape[:-2] + (n, n))
    T[..., :nx, :nx] = Phi
    T[..., :nx, iu1] += g1
    T[..., :nx, :] += g0[..., :, None] * u
    T[..., ith1, :] = y
    T[..., iu1, :] = u
    T[..., iu2, :] = u1
    T[..., iw, :] = w_p + l_w * nu
    T[..., ith, :] = th_p + l_th * nu
    T[..., i_d, :] = d_new
    return T


def uncertainty_corners(tau, Kc, Ke, sample_period, delay, frequency, damping,
                        load_fraction, spread=MODEL_SPREAD) -> list:
    """The sampled axes (:func:`sampled_axis`) at every corner and centre of the model's
    uncertainty: tau and Kc at x(1 - spread), 1, (1 + spread), the mode at f/(1 + spread),
    f, f/(1 - spread) (27 axes)."""
    Phi, g1, g0 = _stacked_corners(tau, Kc, Ke, sample_period, delay, frequency, damping,
                                   load_fraction, spread)
    return [(Phi[i], g1[i], g0[i]) for i in range(len(Phi))]


@functools.lru_cache(maxsize=64)
def _stacked_corners(tau, Kc, Ke, sample_period, delay, frequency, damping, load_fraction,
                     spread=MODEL_SPREAD):
    """:func:`uncertainty_corners` as one stack ``(Phi, g1, g0)``, shapes (27, nx, nx),
    (27, nx), (27, nx), computed once per model axis (each corner is two matrix
    exponentials; a design evaluates the loop on them thousands of times)."""
    axes = [sampled_axis(tau * ft, Kc * fk, Ke, sample_period, delay, frequency * ff,
                         damping, load_fraction)
            for ft in (1.0 - spread, 1.0, 1.0 + spread)
            for fk in (1.0 - spread, 1.0, 1.0 + spread)
            for ff in (1.0 / (1.0 + spread), 1.0, 1.0 / (1.0 - spread))]
    out = tuple(np.stack([ax[i] for ax in axes]) for i in range(3))
    for arr in out:
        arr.flags.writeable = False  # shared by every design of this axis
    return out


def _radius(law, corners, encoder_on, integral=True, observer_pole=None,
            reading_gain=1.0) -> float:
    """The largest pole radius of the landing's (or tracking's) loop over a stack of
    sampled axes ``corners`` (one ``eigvals`` call on the stack)."""
    if observer_pole is None:
        loops = landing_loop(law, corners, encoder_on, integral)
    else:
        loops = observer_landing_loop(law, corners, observer_pole, encoder_on, reading_gain)
    if not np.isfinite(loops).all():  # gains beyond a double: unstable
        return math.inf
    return float(np.max(np.abs(np.linalg.eigvals(loops))))


def _rigid_law(tau, Kc, Ke, sample_period, delay, pole):
    """The model's rigid ZOH plant ``(a, b0, c, b1)`` and the rigid landing's law
    (:func:`_landing_law`'s rows at ``pole``): the prediction rows every design keeps and
    the gains its descent starts from."""
    a = math.exp(-sample_period / tau)
    b0 = Kc * (1.0 - a)
    c = Ke * tau * (1.0 - a)
    b1 = Ke * Kc * sample_period - c * Kc
    law = np.zeros(LAW_ROWS)
    _landing_law(a, b0, c, b1, delay, pole, law)
    return (a, b0, c, b1), law


def _descend(radius, rigid, powers, frequency, damping, tau, Kc):
    """The gains (each keeping the rigid placement's sign) minimising ``radius`` by
    Nelder-Mead on their logarithms, from the best of the rigid placement slowed along the
    pole's path (:data:`SLOWING`); raises InfeasibleError where the best is not < 1."""
    from scipy.optimize import minimize

    # in the gains' logarithms, each keeping the rigid placement's sign (a slow plant's
    # placement can ask for a negative gain: its logarithm was NaN, a crash in eigvals)
    signs = np.where(rigid < 0.0, -1.0, 1.0)

    def of_log(log_gains):
        return radius(signs * np.exp(log_gains))

    starts = [np.log(np.abs(rigid) * s ** powers) for s in SLOWING]
    best = minimize(of_log, min(starts, key=of_log), method="Nelder-Mead",
                    options=dict(xatol=1e-4, fatol=1e-6, maxiter=MAX_DESCENT))
    worst = of_log(best.x)
    if not worst < 1.0:
        raise InfeasibleError(
            f"no {'landing' if len(rigid) == 3 else 'tracking'} law of planned's form "
            f"is stable on the {frequency:g} Hz mode (damping {damping:g}) with tau = "
            f"{tau:g} s, Kc = {Kc:g} and the mode each +-{MODEL_SPREAD:.0%}: its best "
            f"largest pole radius is {worst:.4g}")
    return signs * np.exp(best.x), worst


@functools.lru_cache(maxsize=64)
def _landing_design(tau, Kc, Ke, sample_period, delay, frequency, damping, load_fraction,
                    encoder_on, pole, observer_pole=None):
    """The landing's law designed with the mode (its speed from the last increment, or
    from the observer at ``observer_pole``): ``(law rows, worst radius)``."""
    _, law = _rigid_law(tau, Kc, Ke, sample_period, delay, pole)
    rigid = law[10:13].copy()
    corners = _stacked_corners(tau, Kc, Ke, sample_period, delay, frequency, damping,
                               load_fraction)

    def radius(gains):
        law[10:13] = gains
        return _radius(law, corners, encoder_on, observer_pole=observer_pole)

    landing, worst = _descend(radius, rigid, np.array([1.0, 0.5, 1.5]), frequency,
                              damping, tau, Kc)
    law[10:13] = landing
    law.flags.writeable = False
    return law, worst


@functools.lru_cache(maxsize=64)
def _tracking_design(tau, Kc, Ke, sample_period, delay, frequency, damping, load_fraction,
                     encoder_on, pole):
    """The tracking's two gains designed with the mode: the landing's law without the
    integral (so without its observer, which only the landing has), from the rigid
    placement of both poles at ``pole`` (:func:`_pole_gains`): ``(gains, worst radius)``."""
    (a, b0, c, b1), track = _rigid_law(tau, Kc, Ke, sample_period, delay, pole)
    corners = _stacked_corners(tau, Kc, Ke, sample_period, delay, frequency, damping,
                               load_fraction)

    def track_radius(gains):
        track[10:12] = gains
        return _radius(track, corners, encoder_on, integral=False)

    return _descend(track_radius, np.array(_pole_gains(a, b0, c, b1, pole)),
                    np.array([1.0, 0.5]), frequency, damping, tau, Kc)


def _designed(tau, Kc, Ke, sample_period, delay, frequency, damping, load_fraction,
              encoder_on, pole, observer_pole=None):
    """The landing's law (rows, :func:`_landing_law`'s) and the tracking's gains designed
    with the mode, as one row tuple, and their worst radii over the corners."""
    args = (tau, Kc, Ke, sample_period, delay, frequency, damping, load_fraction,
            encoder_on, pole)
    law, worst = _landing_design(*args, observer_pole)
    gains, track_worst = _tracking_design(*args)
    return tuple(law) + tuple(gains), worst, track_worst


OBSERVER_HALVINGS = 4
"""The observer's poles tried (:func:`_axis_law`): the step's own (``min(loop, pole)``)
and that halved up to this many times less one, slowest first."""


READING_GAINS = (1.0 / (1.0 + MODEL_SPREAD), QUANTISER_GAIN * (1.0 + MODEL_SPREAD))
"""The reading's gains at which an observed landing must be stable on every corner as
well (:func:`_axis_law`): a quantiser's describing-function gain is at most
:data:`.rest_observer.QUANTISER_GAIN` (4/pi), with the model's spread either way (a limit
cycle through the counts needs the loop unstable at some gain the quantiser can have)."""


DRIVE_SHARES = np.geomspace(0.01, 1.0, 15)
"""The shares of the drive that reach the plant at which an observed landing, its
integral held, must be stable on every corner as well (:func:`observer_is_robust`):
Coulomb friction and stiction the model does not know pass only part of the drive (a
sector nonlinearity of gain in (0, 1]: its describing function on the drive), while the
observer predicts the whole drive. As the share falls the loop's poles tend to the
plant's own and to those of the law and the observer on a plant that does not move (the
observer's prediction closing the loop alone); 1 % already shows those (issue 33 item 4,
case 183: an observed landing stable at a share of 1 had a real pole at -1.09 / -1.17 /
-1.20 at 0.3 / 0.1 / 0.01, and alternated its drive every sample against the friction at
rest). Fifteen shares, evenly in the logarithm: the poles move continuously with the
share. The integral is held in this check: with it, a slow plant's landing is
conditionally stable, unstable at small shares by a slow growth (case 12's y: 1.3e-4 per
sample at 1 % *without* an observer, 2.5e-4 with one at 0.35), the law's own whether or
not an observer feeds it, and the stick-slip that the landing's hold rule acts on
(:data:`.step.HOLD_PULSES`); what the observer alone adds, a fast oscillation of the law
and the observer on a plant friction holds (case 183's pole beyond -1, integral held or
not), is what this refuses."""


def _machine_loop_radius(machine: Machine, j: int) -> float:
    """The largest pole radius of the machine's own rigid loop on axis ``j`` (its law,
    plant and delay), as :func:`.rest_observer.rest_observer` computes it."""
    ax, gains = machine.axes[j], machine.pid_gains[j]
    poles = linear_loop_poles(gains, ax.time_constant, ax.electrical_gain,
                              ax.mechanical_gain, machine.sample_period,
                              machine.speed_measurement == "true", machine.delay)
    return float(np.max(np.abs(poles)))


def _landing_or_none(*args):
    """:func:`_landing_design`, or None where no law of its form is stable on every
    corner."""
    try:
        return _landing_design(*args)
    except InfeasibleError:
        return None


def observer_is_robust(law, corners, observer_pole, encoder_on) -> bool:
    """Whether the observed landing (``law``'s rows, its observer at ``observer_pole``) is
    stable on every sampled axis of the stack ``corners`` at every reading gain of
    :data:`READING_GAINS` (the counts), and, its integral held, at every drive share of
    :data:`DRIVE_SHARES` (the friction), each alone."""
    if any(_radius(law, corners, encoder_on, observer_pole=observer_pole,
                   reading_gain=gain) >= 1.0 for gain in READING_GAINS):
        return False
    Phi, g1, g0 = corners
    shares = DRIVE_SHARES[:, None, None]
    shared = (np.broadcast_to(Phi, (len(DRIVE_SHARES),) + Phi.shape).reshape(
                  (-1,) + Phi.shape[1:]),
              (shares * g1).reshape((-1, g1.shape[-1])),
              (shares * g0).reshape((-1, g0.shape[-1])))
    held = np.array(law, dtype=float)
    held[12] = 0.0  # k_i: the integral held, its state dropped below
    iz = Phi.shape[-1] + 2
    loops = observer_landing_loop(held, shared, observer_pole, encoder_on)
    loops = np.delete(np.delete(loops, iz, axis=-1), iz, axis=-2)
    return bool(np.isfinite(loops).all()
                and np.max(np.abs(np.linalg.eigvals(loops))) < 1.0)


@functools.lru_cache(maxsize=64)
def _axis_law_of(args, loop, band):
    """:func:`_axis_law` on the model axis's design arguments (cached per model axis)."""
    plain = _designed(*args)
    if not band > 0.0:
        return plain, None
    pole = args[-1]
    allowed = max(loop, plain[1])
    start = min(loop, float(pole))
    candidates = [start * 0.5 ** k for k in range(OBSERVER_HALVINGS)]
    corners = _stacked_corners(*args[:8])
    # slowest first (it filters a count the most), the first that qualifies taken; the
    # fastest is no screen for the others: its descent can end worse than a slower one's
    # (case 144's y: 0.9241 at 0.0875, 0.9230 at 0.175, allowed 0.9236)
    for observer_pole in candidates:
        observed = _landing_or_none(*args, observer_pole)
        if observed is None or observed[1] > allowed:
            continue
        if observer_is_robust(observed[0], corners, observer_pole, args[8]):
            return _designed(*args, observer_pole), observer_pole
    return plain, None


def _axis_law(machine: Machine, j: int, pole: float, band: float):
    """Axis ``j``'s designed laws (:func:`_designed`'s result) and the pole of its
    landing's speed observer (None: the speed from the last increment).

    On an exact reading (``band`` 0) no observer. Otherwise the slowest observer (the
    most a count or the noise is filtered) whose law, designed with it in the loop, is
    no slower on every corner than the law without it or the machine's own loop,
    whichever is slower (the bandwidth the machine's maker gave the loop for this
    reading: the observer must not cost the landing more), and stable on every corner at
    the reading's gains :data:`READING_GAINS` and the drive's shares
    :data:`DRIVE_SHARES` too (:func:`observer_is_robust`): from the pole the step would
    take (the machine's loop's radius, no slower than ``pole``) halved up to
    :data:`OBSERVER_HALVINGS` - 1 times, the first that qualifies; none where no such
    observer is found."""
    ax = machine.axes[j]
    Ts = machine.sample_period
    args = (ax.time_constant, ax.electrical_gain, ax.mechanical_gain, Ts, machine.delay / Ts,
            ax.resonance_frequency, ax.resonance_damping, ax.load_fraction, ax.encoder_on,
            float(pole))
    loop = _machine_loop_radius(machine, j) if band > 0.0 else 0.0
    return _axis_law_of(args, loop, float(band))


def mode_rest_observer(machine: Machine, pole: float, band: float) -> np.ndarray:
    """The plan's ``rest_observer`` rows (:data:`.rest_observer.REST_OBSERVER_ROWS`,
    n_axes) of the axes whose model declares a mode: 1 and the observer's pole (at most
    ``pole``, so the step, which takes the faster of it and ``pole``, uses it) where the
    landing's law was designed with the observer (:func:`_axis_law`,
    :func:`mode_landing_law` with the same ``band``); zeros elsewhere (rigid axes:
    :func:`.rest_observer.rest_observer`'s rows).

    Parameters
    ----------
    machine : Machine
        The model machine.
    pole : float
        ``tracking_pole``.
    band : float
        The landing's band [pulse] (:func:`.identify.reading_knowledge`; 0: an exact
        reading, no observer).
    """
    out = np.zeros((REST_OBSERVER_ROWS, machine.n_axes))
    for j, ax in enumerate(machine.axes):
        if ax.resonance_frequency > 0.0 and band > 0.0:
            _, observer_pole = _axis_law(machine, j, pole, band)
            if observer_pole is not None:
                out[:, j] = (1.0, observer_pole)
    return out


def mode_landing_law(machine: Machine, pole: float, band: float = 0.0) -> np.ndarray:
    """The plan's ``mode_law`` (shape (:data:`MODE_LAW_ROWS`, n_axes)): per axis whose
    model declares a mode, 1 then the landing's law (:func:`_landing_law`'s rows: the
    model's rigid plant for the prediction, the gains designed with the mode, module
    docstring); zeros for a rigid axis (the landing's law on the identified plant at
    ``pole``, unchanged).

    Parameters
    ----------
    machine : Machine
        The model machine (its axes' tau, Kc, Ke, mode, encoder; its Ts and delay).
    pole : float
        The rigid placement's pole (``tracking_pole``), in [0, 1): the descent's start.
    band : float
        The landing's band [pulse] (:func:`.identify.reading_knowledge`): > 0 (a reading
        not exact) designs the landing's gains with its speed observer in the loop
        (:func:`observer_landing_loop`, :func:`mode_rest_observer`); 0 without.

    Raises
    ------
    InfeasibleError
        No gains of the law make every corner's loop stable (names the axis's mode and
        the best radius).
    """
    out = np.zeros((MODE_LAW_ROWS, machine.n_axes))
    observers = mode_disturbance_observer(machine, pole)
    for j, ax in enumerate(machine.axes):
        if ax.resonance_frequency > 0.0:
            (law, *_), _ = _axis_law(machine, j, pole, band)
            out[0, j] = 1.0
            out[1:DOB_ROW, j] = law
            if observers[j] is not None:
                out[DOB_ROW, j] = 1.0
                out[DOB_ROW + 1:DOB_ROW + 4, j] = observers[j][1]
    return out


def mode_landing_radius(machine: Machine, pole: float, band: float = 0.0) -> list:
    """Per axis with a declared mode, the designed landing's and tracking's largest pole
    radii over the model's uncertainty corners (:func:`uncertainty_corners`; the landing's
    with its observer where :func:`mode_landing_law` designs it so); None for a rigid
    axis."""
    return [_axis_law(machine, j, pole, band)[0][1:] if ax.resonance_frequency > 0.0
            else None for j, ax in enumerate(machine.axes)]


DOB_POLES = np.round(np.arange(0.50, 0.995, 0.01), 2)
"""The disturbance observer's poles tried on an axis with a mode
(:func:`mode_disturbance_observer`): 0.50 to 0.99 by 0.01. Below 0.5 the observer's
corrections, read through the mode's twist, destabilise the tracking on die-bonder-real's
corners (0.5: largest radius 1.05); the design takes the pole of the fastest loop over the
corners, so the grid's step only bounds how near the best it lands."""


@functools.lru_cache(maxsize=64)
def _observer_design(tau, Kc, Ke, sample_period, delay, frequency, damping, load_fraction,
                     encoder_on, pole):
    """The tracking's disturbance observer designed with the mode: ``(observer pole,
    gains (L_w, L_th, L_d), worst radius)``, or None where no pole of :data:`DOB_POLES`
    keeps the tracking's loop (:func:`tracking_observer_loop`) stable on every corner."""
    args = (tau, Kc, Ke, sample_period, delay, frequency, damping, load_fraction,
            encoder_on, pole)
    plant, law = _rigid_law(tau, Kc, Ke, sample_period, delay, pole)
    gains, _ = _tracking_design(*args)
    law = law.copy()
    law[10:12] = gains
    corners = _stacked_corners(*args[:8])
    best = None
    for rho in DOB_POLES:
        g = disturbance_gains(*plant, float(rho))[:, 0]
        loops = tracking_observer_loop(law, plant, g, corners, encoder_on)
        if not np.isfinite(loops).all():
            continue
        worst = float(np.max(np.abs(np.linalg.eigvals(loops))))
        if worst < 1.0 and (best is None or worst < best[2]):
            best = (float(rho), tuple(float(v) for v in g), worst)
    return best


def mode_disturbance_observer(machine: Machine, pole: float):
    """Per axis whose model declares a mode, the tracking's disturbance observer designed
    with it: ``(observer pole, (L_w, L_th, L_d), worst radius)`` or None; None for a rigid
    axis.

    The tracking designed with the mode has no integral and a small position gain (the
    mode's to give: 0.0021 / 0.00074 V/pulse on die-bonder-real's x / y), so a drive the
    model does not know holds the axis d/k_theta off the plan (0.3 V of Coulomb friction:
    144 / 407 pulses). The observer (:func:`.disturbance._observe`: the model's rigid
    plant with a constant unknown drive d, read on the reading less the model's twist under
    the plan's drive) estimates d and the tracking feeds it forward per direction of the
    plan's motion (:func:`.disturbance._for_direction`). Its three poles are one pole
    ``rho`` of :data:`DOB_POLES`: the one whose tracking loop with the observer
    (:func:`tracking_observer_loop`), on every corner of the model's uncertainty
    (tau, Kc, the mode each +-10 %, :data:`MODEL_SPREAD`), has the smallest largest pole
    radius; none where every such loop has a pole on or outside the unit circle.

    Parameters
    ----------
    machine : Machine
        The model machine.
    pole : float
        ``tracking_pole`` (the tracking's design start, :func:`_tracking_design`).
    """
    Ts = machine.sample_period
    out = []
    for ax in machine.axes:
        if not ax.resonance_frequency > 0.0:
            out.append(None)
            continue
        out.append(_observer_design(ax.time_constant, ax.electrical_gain,
                                    ax.mechanical_gain, Ts, machine.delay / Ts,
                                    ax.resonance_frequency, ax.resonance_damping,
                                    ax.load_fraction, ax.encoder_on, float(pole)))
    return out
