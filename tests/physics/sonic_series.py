"""Synthetic sonic series with injected spikes and trends (numpy only).

Shared by ``test_sonic_turbulence.py``, ``test_sonic_reference.py`` and
``tools/sonic_reference_ecpet.py`` (which runs them through the reference
implementation, EC-PeT, in a separate environment without cwproc): the series must be
bit-identical in both places, so they are built here from seeded numpy generators only.
"""

from __future__ import annotations

import numpy as np

RATE = 10.0
N = 18000  # 30 min at 10 Hz


def ar1(n: int, phi: float, rng: np.random.Generator, sigma: float = 1.0) -> np.ndarray:
    """Stationary AR(1) series of standard deviation ``sigma``."""
    e = rng.standard_normal(n) * sigma * np.sqrt(1 - phi * phi)
    x = np.empty(n)
    x[0] = sigma * rng.standard_normal()
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


def with_spikes(x: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """x with 40 single spikes and 10 runs of 3 (+-10 sigma) and one 20-sample burst."""
    y, truth = x.copy(), np.zeros(x.size, dtype=bool)
    starts = rng.choice(np.arange(100, x.size - 200, 60), size=50, replace=False)
    for k, s in enumerate(starts):
        width = 1 if k < 40 else 3
        y[s : s + width] += 10.0 * np.sign(rng.standard_normal())
        truth[s : s + width] = True
    y[9000:9020] += 8.0  # a burst longer than 3 samples: not a spike (VM97)
    truth[9000:9020] = False
    return y, truth


def spiked_cases() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The despiking cases compared with the reference: name -> (series, injected).

    ``ar1_phi0.9``: the series of the despiking unit test (seed 3); ``ar1_phi0.5_trend``:
    a less correlated series on a ramp of 4 sigma over the window (seed 5), so that the
    moving window, not the window mean, has to carry the test.
    """
    rng = np.random.default_rng(3)
    y1, t1 = with_spikes(ar1(N, 0.9, rng), rng)
    rng = np.random.default_rng(5)
    x2 = ar1(N, 0.5, rng) + np.linspace(-2.0, 2.0, N)
    y2, t2 = with_spikes(x2, rng)
    return {"ar1_phi0.9": (y1, t1), "ar1_phi0.5_trend": (y2, t2)}


def flux_cases() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The steady-state cases compared with the reference: name -> (u, w).

    A steady flux (u = -0.8 w + noise, seed 11) and the same series with ramps of
    opposite or equal sign in both means (Foken & Wichura (1996): a trend in the means
    adds a covariance to the window that its 5-min sub-windows do not see), a step in
    the mean of u half way, and a flux whose correlation switches sign in the second
    half (seed 13).
    """
    rng = np.random.default_rng(11)
    w = ar1(N, 0.8, rng, 0.4)
    u = -0.8 * w + ar1(N, 0.8, rng, 0.5)
    ramp = np.linspace(-1.0, 1.0, N)
    step = np.where(np.arange(N) < N // 2, -0.5, 0.5)
    rng = np.random.default_rng(13)
    w2 = ar1(N, 0.8, rng, 0.4)
    sign = np.where(np.arange(N) < 2 * N // 3, -0.8, 0.3)
    u2 = sign * w2 + ar1(N, 0.8, rng, 0.5)
    return {
        "steady": (u, w),
        "ramp_opposite": (u + 1.5 * ramp, w - 0.3 * ramp),
        "ramp_same": (u + 1.5 * ramp, w + 0.6 * ramp),
        "step_u": (u + step, w + 0.2 * step),
        "flux_changes_sign": (u2, w2),
    }


#: (z/L, u_* m s-1) at which the ITC models are compared, latitude 52 deg N
ITC_POINTS = (
    (-2.5, 0.25),
    (-1.0, 0.3),
    (-0.5, 0.35),
    (-0.21, 0.4),
    (-0.1, 0.3),
    (0.0, 0.2),
    (0.0, 0.6),
    (0.2, 0.15),
    (0.39, 0.1),
)
ITC_LATITUDE_DEG = 52.0


def fingerprint(x: np.ndarray) -> list[float]:
    """Sum, sum of squares and three samples: checks that a series was rebuilt unchanged."""
    return [float(np.sum(x)), float(np.sum(x * x)), float(x[0]), float(x[N // 2]), float(x[-1])]
