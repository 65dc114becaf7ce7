"""The closed forms of the dissipation rate eps (m2 s-3), one per method.

Each function's name says the method; the stages that estimate eps call them:

- :func:`epsilon_from_integral_scale`: ``eps = c sigma_V^3 / L_V`` of a finite-outer-
  scale spectrum (Banakh et al. (1999), eq. 19); the conical-scan fits of
  :func:`cwproc.stages.epsilon.estimate_epsilon` and the simulators;
- :func:`oconnor_epsilon`: the vertical stare with sharp band limits (O'Connor et al.
  (2010), eq. 4);
- :func:`epsilon_from_band_variance`: the same with the filters that make the band
  (:func:`cwproc.physics.stare.band_variance_factor`), the stare stage's estimator;
- :func:`stare_epsilon_standard_error`: its standard error (O'Connor et al. (2010),
  section 4);
- :func:`epsilon23_from_sf` and :func:`epsilon_from_structure_function_2_3`: the
  two-thirds law of a sonic structure function (Pope (2000), eq. 6.28);
- :func:`epsilon_from_inertial_spectrum`: the -5/3 law of a sonic spectrum (Pope
  (2000), eq. 6.246).

The estimate of eps from lidar azimuth structure functions with the probe-volume
averaging (Smalikho (2020)) is the stage :func:`cwproc.stages.epsilon.estimate_epsilon`;
its bias ratio of method 1 over method 2 is :mod:`cwproc.physics.epsilon_bias`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cwproc.physics.sonic_turbulence import C1_LONGITUDINAL
from cwproc.physics.spectra import Model, integral_scale_coefficient
from cwproc.physics.stare import A_OCONNOR

__all__ = [
    "epsilon23_from_sf",
    "epsilon_from_band_variance",
    "epsilon_from_inertial_spectrum",
    "epsilon_from_integral_scale",
    "epsilon_from_structure_function_2_3",
    "oconnor_epsilon",
    "stare_epsilon_standard_error",
]


def epsilon_from_integral_scale(
    sigma2: ArrayLike, outer_scale_m: ArrayLike, model: Model = "exponential"
) -> np.ndarray:
    """``eps = c sigma_V^3 / L_V`` (m2 s-3), Banakh et al. (1999), eq. 19."""
    return (
        integral_scale_coefficient(model)
        * np.asarray(sigma2, float) ** 1.5
        / np.asarray(outer_scale_m, float)
    )


def oconnor_epsilon(
    variance: ArrayLike,
    l1_m: ArrayLike,
    ln_m: ArrayLike,
    a: float = A_OCONNOR,
) -> np.ndarray:
    """Dissipation rate (m2 s-3) of O'Connor et al. (2010), eq. 4 (sharp band limits).

    ``eps = 2 pi (2/(3a))^(3/2) sigma^3 (L_1^(2/3) - L_N^(2/3))^(-3/2)``; NaN where the
    variance is not positive or ``L_1 <= L_N``.

    Parameters
    ----------
    variance : array_like
        Variance of w over the window (m2 s-2), noise removed.
    l1_m, ln_m : array_like
        ``L_1 = U T`` and ``L_N = U t`` (m).
    a : float
        One-sided 1-D spectrum constant (0.55 in O'Connor et al. (2010)).
    """
    var = np.asarray(variance, dtype=float)
    band = np.asarray(l1_m, dtype=float) ** (2 / 3) - np.asarray(ln_m, dtype=float) ** (2 / 3)
    with np.errstate(invalid="ignore", divide="ignore"):
        eps = 2 * np.pi * (2 / (3 * a)) ** 1.5 * var**1.5 * band**-1.5
    return np.where((var > 0) & (band > 0), eps, np.nan)


def epsilon_from_band_variance(variance: ArrayLike, factor: ArrayLike) -> np.ndarray:
    """``eps = (sigma_v^2 / G)^(3/2)`` (m2 s-3); NaN where the variance is not positive.

    O'Connor et al. (2010), eq. 4 with ``G`` of :func:`cwproc.physics.stare.band_variance_factor`.
    """
    var = np.asarray(variance, dtype=float)
    g = np.asarray(factor, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        eps = (var / g) ** 1.5
    return np.where((var > 0) & (g > 0), eps, np.nan)


def stare_epsilon_standard_error(
    epsilon: np.ndarray,
    variance: np.ndarray,
    variance_se: np.ndarray,
    wind_speed: np.ndarray,
    wind_speed_error: np.ndarray,
) -> np.ndarray:
    """Standard error of eps (m2 s-3): the variance's and the wind's parts combined.

    ``eps ~ sigma^3 / (U T)`` for ``L_1 >> L_N``, so
    ``SE(eps)/eps = sqrt((1.5 SE(sigma^2)/sigma^2)^2 + (SE(U)/U)^2)``
    (O'Connor et al. (2010), section 4, errors of sigma_w and of U propagated).
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        rel_var = 1.5 * np.asarray(variance_se) / np.asarray(variance)
        rel_wind = np.asarray(wind_speed_error) / np.asarray(wind_speed)
        rel_wind = np.where(np.isfinite(rel_wind), rel_wind, 0.0)
        return np.asarray(epsilon) * np.hypot(rel_var, rel_wind)


def epsilon23_from_sf(r: np.ndarray, d: np.ndarray, constant: float) -> float:
    """eps^(2/3) from D(r) = C eps^(2/3) r^(2/3) over the lags given (m^(4/3) s-2).

    The least-squares fit of lg D with the slope fixed at 2/3: the geometric mean of
    D / (C r^(2/3)) (Pope (2000), eq. 6.28).
    """
    ok = np.isfinite(d) & (d > 0) & (r > 0)
    if not ok.any():
        return float("nan")
    return float(np.exp(np.mean(np.log(d[ok] / (constant * r[ok] ** (2.0 / 3.0))))))


def epsilon_from_structure_function_2_3(eps23: float, eps23_se: float) -> tuple[float, float]:
    """eps (m2 s-3) and its standard error from eps^(2/3) of the two-thirds law.

    ``D(r) = C eps^(2/3) r^(2/3)`` (Pope (2000), eq. 6.28) gives eps^(2/3)
    (:func:`epsilon23_from_sf`); ``eps = (eps^(2/3))^(3/2)`` and, by the delta method,
    ``SE(eps) = 1.5 (eps^(2/3))^(1/2) SE(eps^(2/3))``.

    Parameters
    ----------
    eps23 : float
        eps^(2/3) (m^(4/3) s-2).
    eps23_se : float
        Its standard error (m^(4/3) s-2).
    """
    return eps23**1.5, 1.5 * eps23**0.5 * eps23_se


def epsilon_from_inertial_spectrum(
    x: np.ndarray, rate_hz: float, speed: float, k_range: tuple[float, float]
) -> float:
    """eps (m2 s-3) from the inertial range of the longitudinal spectrum.

    E_11(k) = C_1 eps^(2/3) k^(-5/3) (Pope (2000), eq. 6.246) with k = 2 pi f / U
    (Taylor), the one-sided periodogram of the detrended series, averaged in lg k over
    ``k_range`` (rad m-1), cut at a quarter of the Nyquist wavenumber pi f_s / U (above
    it aliasing lifts the spectrum of a sampled -5/3 process).
    """
    x = np.where(np.isfinite(x), x, 0.0)
    n = x.size
    if n < 8 or speed <= 0:
        return float("nan")
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)[1:]
    p = (np.abs(np.fft.rfft(x))[1:] ** 2) * 2.0 / (n * rate_hz)  # S(f), m2 s-2 Hz-1
    k = 2.0 * np.pi * f / speed
    e = p * speed / (2.0 * np.pi)  # E(k) = S(f) U / (2 pi)
    k_top = min(k_range[1], 0.25 * np.pi * rate_hz / speed)
    sel = (k >= k_range[0]) & (k <= k_top)
    if sel.sum() < 8:
        return float("nan")
    e23 = np.exp(np.mean(np.log(e[sel] * k[sel] ** (5.0 / 3.0) / C1_LONGITUDINAL)))
    # the mean of ln of a chi-square(2) periodogram ordinate is ln(mean) - Euler's gamma
    return float((e23 * np.exp(np.euler_gamma)) ** 1.5)
