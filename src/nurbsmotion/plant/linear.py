"""The axis's linear continuous model and the poles of its closed loop with its delay
and its mode (no clamps, friction or quantisers): what a machine is refused for (the
model: :mod:`nurbsmotion.plant`).

Glossary
--------
See :mod:`nurbsmotion.plant`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["continuous_model", "linear_loop_poles", "split_sample", "x_minus_one_minus_exp"]


def x_minus_one_minus_exp(x: float) -> float:
    """``x - (1 - exp(-x))`` for x > 0, accurate to rounding: the series
    ``sum_{n>=2} (-1)^n x^n / n!`` below 0.5 (where the difference cancels), else direct."""
    if x >= 0.5:
        return x + math.expm1(-x)
    term = x * x / 2.0
    total = 0.0
    n = 2
    while abs(term) > 1e-17 * x * x:
        total += term
        n += 1
        term *= -x / n
    return total


def _mode(tau: float, lam: float, frequency: float, damping: float):
    """``(sig, w2, c)``: the mode's decay rate zeta*wn [1/s], wn^2 [1/s^2] and the
    damper ``c = mu*(2*zeta*wn - 1/tau)`` (normalised so that viscous damping is 1)."""
    wn = 2.0 * math.pi * frequency
    mu = lam * (1.0 - lam) * tau
    return damping * wn, wn * wn, mu * (2.0 * damping * wn - 1.0 / tau), mu


def split_delay(delay: float, sample_period: float) -> tuple[int, float]:
    """A delay [s] as whole samples and the rest [s], ``delay = whole*Ts + split`` with
    ``0 <= split < Ts``; a rest within 1e-12 Ts of 0 or of Ts is rounded to the whole
    sample (a delay given as ``k*Ts`` in floating point is k whole samples)."""
    Ts = float(sample_period)
    whole = int(math.floor(delay / Ts))
    split = delay - whole * Ts
    if split <= 1e-12 * Ts:
        split = 0.0
    elif split >= Ts * (1.0 - 1e-12):
        whole, split = whole + 1, 0.0
    return whole, split

def continuous_model(tau: float, Kc: float, Ke: float, resonance_frequency: float = 0.0,
                     resonance_damping: float = 0.0, load_fraction: float = 0.5):
    """The axis's linear continuous model in physical coordinates
    ``[w_motor, theta_motor, w_load, theta_load]`` (speeds [rad/s], positions [pulse]):
    ``(A, B)``, shapes (4, 4) and (4,), input the drive [V]. A rigid axis is two equal
    halves locked together (returned as the 2-state ``[w, theta]``)."""
    if resonance_frequency <= 0:
        return (np.array([[-1.0 / tau, 0.0], [Ke, 0.0]]), np.array([Kc / tau, 0.0]))
    lam = load_fraction
    sig, w2, c, mu = _mode(tau, lam, resonance_frequency, resonance_damping)
    k = w2 * mu
    Jm, Jl = (1.0 - lam) * tau, lam * tau
    bm, bl = 1.0 - lam, lam
    # spring on the angle difference [rad] = (theta_m - theta_l)/Ke
    A = np.array([[-(bm + c) / Jm, -k / (Ke * Jm), c / Jm, k / (Ke * Jm)],
                  [Ke, 0.0, 0.0, 0.0],
                  [c / Jl, k / (Ke * Jl), -(bl + c) / Jl, -k / (Ke * Jl)],
                  [0.0, 0.0, Ke, 0.0]])
    B = np.array([Kc / Jm, 0.0, 0.0, 0.0])
    return A, B


def split_sample(A: np.ndarray, B: np.ndarray, first: float, second: float):
    """The linear plant ``x' = A x + B u`` sampled over a period ``first + second`` [s]
    whose drive changes ``first`` into it (a delay's split): ``x[k+1] = Phi x[k] +
    g1 u[k-1] + g0 u[k]`` (``scipy.linalg.expm`` of the augmented matrix on each part).

    Returns
    -------
    Phi : ndarray, shape (nx, nx)
    g1, g0 : ndarray, shape (nx,)
        Zero ``g1`` when ``first`` is 0.
    """
    from scipy.linalg import expm

    nx = A.shape[0]

    def zoh(h):
        M = np.zeros((nx + 1, nx + 1))
        M[:nx, :nx], M[:nx, nx] = A, B
        E = expm(M * h)
        return E[:nx, :nx], E[:nx, nx]

    P1, G1 = zoh(first) if first > 0 else (np.eye(nx), np.zeros(nx))
    P2, G2 = zoh(second)
    return P2 @ P1, P2 @ G1, G2


def linear_loop_poles(gains, tau: float, Kc: float, Ke: float, sample_period: float,
                      feedback_deriv: bool, delay: float = 0.0,
                      resonance_frequency: float = 0.0, resonance_damping: float = 0.0,
                      load_fraction: float = 0.5, encoder_on: str = "motor") -> np.ndarray:
    """Poles of one axis's closed loop, linear (no clamps, friction or quantisers), with
    its delay and its mode: the sampled plant over the two intervals of a sample
    (``scipy.linalg.expm`` of the augmented matrix), the drives on their way as states,
    and the law of :func:`nurbsmotion.control.loop_poles`.

    Returns
    -------
    ndarray, complex
    """
    A, B = continuous_model(tau, Kc, Ke, resonance_frequency, resonance_damping,
                            load_fraction)
    nx = A.shape[0]
    pos = np.zeros(nx)
    spd = np.zeros(nx)
    if nx == 2 or encoder_on == "motor":
        pos[1], spd[0] = 1.0, Ke
    else:
        pos[3], spd[2] = 1.0, Ke
    Ts = float(sample_period)
    whole, split = split_delay(delay, Ts)
    Phi, g1, g0 = split_sample(A, B, split, Ts - split)
    P, I, D = gains.Pgain, gains.Igain, gains.Dgain
    nd = whole + 1  # d_1 .. d_{n+1}: drives of samples k-1 .. k-n-1
    # state z = [x (nx), y_prev, errorI, d_1 .. d_nd]
    nz = nx + 2 + nd
    law = np.zeros(nz)
    if feedback_deriv:
        law[:nx] = -D * spd - (P + I * Ts) * pos
    else:
        law[:nx] = -(P + I * Ts + D / Ts) * pos
        law[nx] = D / Ts
    law[nx + 1] = I

    def drive_of(m):  # the row giving u[k - m]
        row = np.zeros(nz)
        if m == 0:
            row[:] = law
        else:
            row[nx + 1 + m] = 1.0
        return row

    T = np.zeros((nz, nz))
    T[:nx, :nx] = Phi
    T[:nx] += np.outer(g1, drive_of(whole + 1)) + np.outer(g0, drive_of(whole))
    T[nx, :nx] = pos
    T[nx + 1, :nx] = -Ts * pos
    T[nx + 1, nx + 1] = 1.0
    T[nx + 2] = law
    for i in range(1, nd):
        T[nx + 2 + i, nx + 1 + i] = 1.0
    keep = list(range(nx))
    if not feedback_deriv:
        keep.append(nx)
    if I != 0.0:
        keep.append(nx + 1)
    keep += list(range(nx + 2, nz))
    return np.linalg.eigvals(T[np.ix_(keep, keep)])
