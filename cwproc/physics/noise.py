"""Predicted random error of a pulsed coherent Doppler lidar's radial velocity.

The standard deviation ``sigma_e`` of one radial-velocity estimate, from the
signal-to-noise ratio and the instrument's settings, in the form of Pearson et al.
(2009), eq. 3 (after the Cramer-Rao-type approximation of Rye and Hardesty (1993)):

.. math::

    \\sigma_e = 2\\Big(\\frac{\\sqrt{\\pi}}{\\alpha}\\Big)^{1/2}
        \\frac{\\Delta v}{\\sqrt{N_p}}\\Big(1 + \\frac{\\alpha}{2\\pi}\\Big),\\qquad
    \\alpha = \\frac{\\mathrm{SNR}}{\\sqrt{2\\pi}\\,\\Delta v / B},\\qquad
    N_p = M\\,n\\,\\mathrm{SNR},

with ``Delta v`` the spectral width of the signal (m s-1), ``B`` the velocity bandwidth
(m s-1, twice the Nyquist velocity), ``M`` the digitiser points per range gate and
``n`` the pulses accumulated per ray. Limits (tested): ``sigma_e ~ 1/SNR`` at low SNR;
at high SNR the speckle floor ``sqrt(Delta v B / (pi^(3/2) sqrt(2 pi) M n))``;
``sigma_e ~ n^(-1/2)`` at any SNR.

Halo Stream Line: ``B = 1024 x`` the header's ``Resolution (m/s)`` (the Doppler
spectrum of 1024 bins; 0.0382 m s-1 gives 39.1 m s-1, close to ``lambda f_s / 2 =
38.4 m s-1`` of a 1.5 um lidar sampling at 50 MHz). ``Delta v = 1.5 m s-1`` is the
width of a Stream Line's aerosol return (pulse-limited; the range 1-2 m s-1 is used by
Pearson et al. (2009) and O'Connor et al. (2010)).

References: Rye, B. J. and Hardesty, R. M. (1993), Discrete spectral peak estimation in
incoherent backscatter heterodyne lidar. I, IEEE Trans. Geosci. Remote Sens. 31,
16-27; Pearson, G., Davies, F. and Collier, C. (2009), An analysis of the performance of
the UFAM pulsed Doppler lidar for observing the boundary layer, J. Atmos. Oceanic
Technol. 26, 240-250.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

#: spectral width of the aerosol return of a Stream Line (m s-1), Pearson et al. (2009)
SPECTRAL_WIDTH_M_S = 1.5
#: Doppler spectrum bins of a Halo Stream Line (velocity bandwidth = bins x resolution)
HALO_SPECTRUM_BINS = 1024
#: velocity bandwidth (m s-1) when the resolution is unknown: lambda f_s / 2, 1.5 um, 50 MHz
DEFAULT_BANDWIDTH_M_S = 38.4


def bandwidth_from_resolution(
    resolution_m_s: float | None, bins: int = HALO_SPECTRUM_BINS
) -> float:
    """Velocity bandwidth ``B`` (m s-1) from the Doppler bin width (m s-1).

    ``B = bins x resolution``; :data:`DEFAULT_BANDWIDTH_M_S` when the resolution is
    unknown, not finite or not positive.
    """
    if resolution_m_s is None or not math.isfinite(resolution_m_s) or resolution_m_s <= 0:
        return DEFAULT_BANDWIDTH_M_S
    return float(bins) * float(resolution_m_s)


def _check_settings(
    points_per_gate: float, pulses_per_ray: float, bandwidth_m_s: float, width_m_s: float
) -> None:
    """Raise ``ValueError`` naming the first instrument setting that is not finite and > 0."""
    for name, value in (
        ("points_per_gate", points_per_gate),
        ("pulses_per_ray", pulses_per_ray),
        ("bandwidth_m_s", bandwidth_m_s),
        ("spectral_width_m_s", width_m_s),
    ):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be finite and > 0, got {value!r}")


def velocity_noise_std(
    snr: ArrayLike,
    points_per_gate: float,
    pulses_per_ray: float,
    bandwidth_m_s: float = DEFAULT_BANDWIDTH_M_S,
    spectral_width_m_s: float = SPECTRAL_WIDTH_M_S,
) -> np.ndarray:
    """Predicted standard deviation ``sigma_e`` (m s-1) of one radial velocity.

    Pearson et al. (2009), eq. 3 (module docstring). NaN where ``snr`` is not positive
    or not finite.

    Parameters
    ----------
    snr : array_like
        Signal-to-noise ratio (linear, Halo ``intensity - 1``).
    points_per_gate : float
        ``M``, digitiser points per range gate (Halo ``Gate length (pts)``).
    pulses_per_ray : float
        ``n``, pulses accumulated per ray (Halo ``Pulses/ray``).
    bandwidth_m_s : float
        ``B`` (m s-1), :func:`bandwidth_from_resolution`.
    spectral_width_m_s : float
        ``Delta v`` (m s-1) of the signal.
    """
    _check_settings(points_per_gate, pulses_per_ray, bandwidth_m_s, spectral_width_m_s)
    s = np.asarray(snr, dtype=float)
    good = np.isfinite(s) & (s > 0)
    s = np.where(good, s, 1.0)
    alpha = s / (math.sqrt(2.0 * math.pi) * spectral_width_m_s / bandwidth_m_s)
    n_p = points_per_gate * pulses_per_ray * s
    sigma = (
        2.0
        * np.sqrt(math.sqrt(math.pi) / alpha)
        * spectral_width_m_s
        / np.sqrt(n_p)
        * (1.0 + alpha / (2.0 * math.pi))
    )
    return np.where(good, sigma, np.nan)


#: the SNR of a simulated return whose noise is at or below the speckle floor (the
#: prediction there is within 0.5 % of the floor for a Stream Line)
SNR_STRONG = 1.0e3


def snr_for_noise_std(
    sigma_e: float,
    points_per_gate: float,
    pulses_per_ray: float,
    bandwidth_m_s: float = DEFAULT_BANDWIDTH_M_S,
    spectral_width_m_s: float = SPECTRAL_WIDTH_M_S,
) -> float:
    """The SNR (linear) at which :func:`velocity_noise_std` predicts ``sigma_e`` (m s-1).

    Pearson et al. (2009), eq. 3 is ``sigma_e = K / SNR + F`` with
    ``K = 2 pi^(1/4) Delta v / sqrt(a M n)``, ``a = B / (sqrt(2 pi) Delta v)`` and the
    speckle floor ``F = K a / (2 pi)``, so ``SNR = K / (sigma_e - F)``; a virtual lidar
    writes it beside velocities with noise ``sigma_e``, so that its SNR and its noise
    agree as a real lidar's do. :data:`SNR_STRONG` where ``sigma_e`` is at or below the
    floor.
    """
    _check_settings(points_per_gate, pulses_per_ray, bandwidth_m_s, spectral_width_m_s)
    a = bandwidth_m_s / (math.sqrt(2.0 * math.pi) * spectral_width_m_s)
    k = 2.0 * math.pi**0.25 * spectral_width_m_s / math.sqrt(a * points_per_gate * pulses_per_ray)
    excess = float(sigma_e) - k * a / (2.0 * math.pi)
    return k / excess if excess > k / SNR_STRONG else SNR_STRONG


def speckle_floor(
    points_per_gate: float,
    pulses_per_ray: float,
    bandwidth_m_s: float = DEFAULT_BANDWIDTH_M_S,
    spectral_width_m_s: float = SPECTRAL_WIDTH_M_S,
) -> float:
    """High-SNR limit of :func:`velocity_noise_std` (m s-1).

    ``sqrt(Delta v B / (pi^(3/2) sqrt(2 pi) M n))``: the speckle (fading) limit of the
    accumulated estimate, independent of the SNR.
    """
    return math.sqrt(
        spectral_width_m_s
        * bandwidth_m_s
        / (math.pi**1.5 * math.sqrt(2.0 * math.pi) * points_per_gate * pulses_per_ray)
    )


#: fewest cells (block x height) whose intercept measures the noise for a calibration
CALIBRATION_MIN_CELLS = 10
#: standard error of the median over that of the mean of Gaussian values, sqrt(pi / 2)
#: (the median's asymptotic efficiency 2/pi), and the MAD's factor to a standard deviation
_MEDIAN_SE_FACTOR = math.sqrt(math.pi / 2.0)
_MAD_TO_SD = 1.4826


def noise_calibration(
    intercept: ArrayLike, intercept_se: ArrayLike, predicted: ArrayLike
) -> tuple[float, float, int]:
    """The factor ``k`` of the SNR prediction of sigma_e that the structure function measures.

    Each cell's free intercept ``b = 2 sigma_e^2`` of Smalikho (2020), eq. 4
    (:func:`cwproc.physics.structure_fit.free_intercept`) with its standard error ``s_b``,
    against the predicted ``2 sigma_pred^2`` (:func:`velocity_noise_std`, Pearson et al.
    (2009), eq. 3): ``q = b / (2 sigma_pred^2)`` estimates ``k^2`` with error
    ``s_q = s_b / (2 sigma_pred^2)``. Over all cells of an instrument and day with a
    finite, positive ``s_q``, ``k^2`` is the median of ``q`` (robust to the few cells
    whose intercept the model's shape at the first lags moves). Neither weighted by
    ``1 / s_q^2`` nor selected by ``s_q``: the jackknife ``s_b`` of a block is smaller
    where its intercept is larger (correlation -0.2 to -0.3 on exact 72-ray statistics),
    and the weighting read ``k`` 6-12 % high there, the selection 5 % high; its standard
    error ``sqrt(pi / 2) 1.4826 MAD / sqrt(n)`` (that of the median of Gaussian values),
    and ``k = sqrt(k^2)`` with ``SE(k) = SE(k^2) / (2 k)``.

    Parameters
    ----------
    intercept, intercept_se : array_like
        Free intercepts and their standard errors (m2 s-2), any shape.
    predicted : array_like
        Predicted sigma_e (m s-1), same shape.

    Returns
    -------
    (k, se_k, n) : tuple
        The factor (sigma_e over the prediction, 1), its standard error and the cells
        used; ``(nan, nan, n)`` with fewer than :data:`CALIBRATION_MIN_CELLS` cells.
    """
    b = np.ravel(np.asarray(intercept, dtype=float))
    s = np.ravel(np.asarray(intercept_se, dtype=float))
    p2 = 2.0 * np.ravel(np.asarray(predicted, dtype=float)) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        q, s_q = b / p2, s / p2
    ok = np.isfinite(q) & np.isfinite(s_q) & (s_q > 0)
    if ok.sum() < CALIBRATION_MIN_CELLS:
        return math.nan, math.nan, int(ok.sum())
    n = int(ok.sum())
    k2 = float(np.median(q[ok]))
    mad = float(np.median(np.abs(q[ok] - k2)))
    se_k2 = _MEDIAN_SE_FACTOR * _MAD_TO_SD * mad / math.sqrt(n)
    if not k2 > 0:
        return math.nan, math.nan, n
    k = math.sqrt(k2)
    return k, se_k2 / (2.0 * k), n
