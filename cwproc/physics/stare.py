"""Vertical-velocity statistics and the dissipation rate from vertical stares.

A vertically pointing Doppler lidar measures ``w`` at every gate, once per ray. Over a
time window of ``T`` seconds the air advected past the beam by the horizontal wind ``U``
is ``L_1 = U T`` long; one ray averages ``L_N = U t`` (``t``: the ray's accumulation
time). Within the inertial subrange the one-sided one-dimensional spectrum of ``w``
along the advection direction is ``F(k) = a eps^(2/3) k^(-5/3)`` (k in rad m-1), and the
variance of the rays in the window is O'Connor et al. (2010), eqs. 1-4:

.. math::

    \\sigma_w^2 = \\int_{2\\pi/L_1}^{2\\pi/L_N} F(k)\\,dk
        = \\frac{3a}{2}\\Big(\\frac{\\varepsilon}{2\\pi}\\Big)^{2/3}
          \\big(L_1^{2/3} - L_N^{2/3}\\big),\\qquad
    \\varepsilon = 2\\pi\\Big(\\frac{2}{3a}\\Big)^{3/2}\\sigma_w^3
          \\big(L_1^{2/3} - L_N^{2/3}\\big)^{-3/2}.

cwproc keeps this estimator and replaces the sharp band limits by the filters that make
them (all in :func:`band_variance_factor`): the mean removed over the window
(``1 - sinc^2(k L_1/2)``), the boxcar of the ray (``sinc^2(k L_N/2)``) and the pulsed
range weighting along the beam (the Gaussian pulse ``Delta_p`` and the range window
``Delta_R`` of Smalikho (2020), eq. 19, acting on the vertical wavenumber ``k_z`` of the
isotropic tensor, :func:`gate_transfer_ratio`). ``w`` along the horizontal advection is
a *transverse* component, so ``a`` is the transverse constant ``a_T = (4/3) a_L`` with
the longitudinal ``a_L`` that gives ``D_L = C_K eps^(2/3) r^(2/3)``, ``C_K = 2`` (the
constant of the rest of cwproc, Smalikho (2020), eq. 12): ``a_T = 0.664``. O'Connor
et al. (2010) and doppy use ``a = 0.55``, which gives a dissipation rate
``(0.664/0.55)^(3/2) = 1.33`` times larger for the same variance.

The instrumental noise adds ``sigma_e^2`` to the variance of the rays; it is removed
with the Pearson et al. (2009) prediction from the SNR
(:func:`cwproc.physics.noise.velocity_noise_std`), as O'Connor et al. (2010), section 3
do with their noise estimate.

References: O'Connor, E. J., Illingworth, A. J., Brooks, I. M., Westbrook, C. D.,
Hogan, R. J., Davies, F. and Brooks, B. J. (2010), A method for estimating the turbulent
kinetic energy dissipation rate from a vertically pointing Doppler lidar, and
independent evaluation from balloon-borne in situ measurements, J. Atmos. Oceanic
Technol. 27, 1652-1664.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.special import gamma

from cwproc.references import OCONNOR_2010

__all__ = ["OCONNOR_2010"]


#: Kolmogorov constant of the longitudinal structure function, D_L = C_K eps^(2/3) r^(2/3)
#: (Smalikho (2020), eq. 12; the constant of cwproc's simulated fields)
C_K = 2.0
#: int_0^inf (1 - cos x) x^(-5/3) dx = Gamma(1/3) cos(pi/3) / (2/3)
_COSINE_INTEGRAL = float(gamma(1.0 / 3.0) * math.cos(math.pi / 3.0) / (2.0 / 3.0))
#: one-sided longitudinal 1-D spectrum constant a_L (rad m-1): D_L = 2 a_L I r^(2/3)
A_LONGITUDINAL = C_K / (2.0 * _COSINE_INTEGRAL)
#: transverse 1-D spectrum constant a_T = 4/3 a_L: w sampled along the horizontal wind
A_TRANSVERSE = 4.0 / 3.0 * A_LONGITUDINAL
#: the constant a used by O'Connor et al. (2010) and doppy
A_OCONNOR = 0.55

#: wavenumber nodes per decade of the numerical integrals
_NODES_PER_DECADE = 48


def gate_transfer(kz: np.ndarray, delta_p_m: float, delta_r_m: float) -> np.ndarray:
    """|H(k_z)|^2 of the pulsed range weighting (k_z in rad m-1).

    ``exp(-(Delta_p k/2)^2) sinc(Delta_R k/2)`` squared: the Fourier transform of the
    Gaussian pulse convolved with the range window (Smalikho (2020), eq. 19 with the pi
    of the Gaussian term; :func:`cwproc.sim.pulsed.pulsed_range_weight`).
    """
    k = np.asarray(kz, dtype=float)
    return np.exp(-0.5 * (delta_p_m * k) ** 2) * np.sinc(delta_r_m * k / (2 * np.pi)) ** 2


def gate_transfer_ratio(kx: ArrayLike, delta_p_m: float, delta_r_m: float) -> np.ndarray:
    """Share of the transverse 1-D spectrum of w at ``k_x`` that a range gate keeps.

    The isotropic inertial-range tensor ``Phi_33 ~ k^(-11/3) (1 - k_z^2/k^2)`` is
    integrated over ``k_y`` analytically
    (``int (q^2 + y^2)^(-s) dy = sqrt(pi) Gamma(s - 1/2)/Gamma(s) q^(1-2s)``) and over
    ``k_z`` numerically, with and without :func:`gate_transfer`; the ratio is 1 for
    ``k_x Delta << 1`` and falls off for eddies shorter than the gate.

    Parameters
    ----------
    kx : array_like
        Wavenumbers along the advection direction (rad m-1), > 0.
    delta_p_m, delta_r_m : float
        Pulse and range-window lengths (m).
    """
    kx = np.atleast_1d(np.asarray(kx, dtype=float))
    if delta_p_m <= 0 and delta_r_m <= 0:
        return np.ones_like(kx)
    # k_z / k_x on a log grid from 1e-4 to 1e4 (the integrand falls as k_z^(-8/3))
    t = np.logspace(-4, 4, 8 * _NODES_PER_DECADE + 1)
    kz = kx[:, None] * t[None, :]
    q2 = kx[:, None] ** 2 + kz**2
    c1 = math.sqrt(math.pi) * gamma(4 / 3) / gamma(11 / 6)
    c2 = math.sqrt(math.pi) * gamma(7 / 3) / gamma(17 / 6)
    integrand = c1 * q2 ** (-4 / 3) - c2 * kz**2 * q2 ** (-7 / 3)
    weight = integrand * kz  # d k_z = k_z d ln t
    filtered = np.trapezoid(weight * gate_transfer(kz, delta_p_m, delta_r_m), np.log(t), axis=1)
    return filtered / np.trapezoid(weight, np.log(t), axis=1)


def mean_removed_filter(
    k: np.ndarray, l1_m: np.ndarray, n_rays: int | None = None, spacing_m: np.ndarray | None = None
) -> np.ndarray:
    """Share of the spectrum at ``k`` (rad m-1) kept by the variance about a window mean.

    Continuous record of length ``L_1``: ``1 - sinc^2(k L_1/2)``. ``n`` rays ``Delta`` apart
    (the window mean of ``n`` samples): ``1 - F_n(k Delta)`` with the Fejer kernel
    ``F_n = sin^2(n k Delta/2) / (n^2 sin^2(k Delta/2))``, exact for the expected variance
    of ``n`` samples about their mean, ``E[(1/n) sum (w_i - w_bar)^2] = int S(k) (1 - F_n)
    dk``; it tends to the continuous form for ``n -> inf`` at ``n Delta = L_1``. Beyond
    ``k Delta = 2 pi x 16`` the kernel is replaced by its period mean ``1/n`` (the
    integrand there is smooth apart from the kernel's oscillation).

    Parameters
    ----------
    k : numpy.ndarray
        ``(K,)`` wavenumbers (rad m-1).
    l1_m : numpy.ndarray
        ``(C,)`` window lengths ``L_1 = U T`` (m).
    n_rays : int, optional
        Rays per window; ``None``: a continuous record.
    spacing_m : numpy.ndarray, optional
        ``(C,)`` distance ``U dt`` between consecutive rays (m), with ``n_rays``.

    Returns
    -------
    numpy.ndarray
        ``(C, K)``.
    """
    if n_rays is None:
        return 1.0 - np.sinc(k[None, :] * l1_m[:, None] / (2 * np.pi)) ** 2
    half = k[None, :] * np.asarray(spacing_m, dtype=float)[:, None] / 2  # k Delta / 2
    num = np.sin(n_rays * half)
    den = n_rays * np.sin(half)
    with np.errstate(invalid="ignore", divide="ignore"):
        kernel = np.where(np.abs(den) > 1e-9 * n_rays, (num / den) ** 2, 1.0)
    kernel = np.where(half < np.pi * 16, kernel, 1.0 / n_rays)
    return 1.0 - kernel


def band_variance_factor(
    l1_m: ArrayLike,
    ln_m: ArrayLike,
    delta_p_m: float = 0.0,
    delta_r_m: float = 0.0,
    a: float = A_TRANSVERSE,
    *,
    n_rays: int | None = None,
    ray_spacing_m: ArrayLike | None = None,
) -> np.ndarray:
    """``G = sigma_w^2 / eps^(2/3)`` (m^(4/3)) of the rays of one window.

    ``G = int_0^inf a k^(-5/3) [1 - W(k)] sinc^2(k L_N/2) R(k) dk``: the O'Connor et al.
    (2010), eq. 3 integral with the filters of the window mean (``1 - W``,
    :func:`mean_removed_filter`: continuous, or ``n`` discrete rays), the ray and the
    range gate (``R``, :func:`gate_transfer_ratio`) in place of its sharp limits (module
    docstring). ``sinc(x) = sin(x)/x``.

    Parameters
    ----------
    l1_m, ln_m : array_like
        ``L_1 = U T`` and ``L_N = U t`` (m), broadcastable.
    delta_p_m, delta_r_m : float
        Pulse and range-window lengths (m); 0 and 0: no range-gate averaging.
    a : float
        One-sided transverse 1-D spectrum constant.
    n_rays : int, optional
        Rays of a window (their mean removed); ``None``: a continuous record.
    ray_spacing_m : array_like, optional
        ``U dt`` between consecutive rays (m), broadcastable with ``l1_m``; needed with
        ``n_rays``.

    Returns
    -------
    numpy.ndarray
        ``G`` (m^(4/3)), NaN where ``L_1`` or ``L_N`` is not finite and positive.
    """
    spacing = l1_m if ray_spacing_m is None else ray_spacing_m
    l1, ln, dx = np.broadcast_arrays(
        np.asarray(l1_m, float), np.asarray(ln_m, float), np.asarray(spacing, float)
    )
    good = np.isfinite(l1) & np.isfinite(ln) & (l1 > 0) & (ln > 0) & np.isfinite(dx)
    out = np.full(l1.shape, np.nan)
    if not good.any():
        return out
    lo, hi = l1[good], ln[good]
    # k from 1e-3/L_1 to 1e3/min(L_N, gate): beyond, the integrand is negligible
    small = np.minimum(hi, max(delta_p_m, delta_r_m, 1e-9)) if delta_r_m > 0 else hi
    k_min, k_max = 1e-3 / lo.max(), 1e3 / small.min()
    per_decade = _NODES_PER_DECADE if n_rays is None else 4 * _NODES_PER_DECADE
    n = math.ceil(math.log10(k_max / k_min) * per_decade) + 1
    k = np.logspace(math.log10(k_min), math.log10(k_max), n)
    ratio = gate_transfer_ratio(k, delta_p_m, delta_r_m)
    window = mean_removed_filter(k, lo, n_rays, dx[good])
    ray = np.sinc(k[None, :] * hi[:, None] / (2 * np.pi)) ** 2
    integrand = a * k ** (-2 / 3) * ratio * window * ray  # k^(-5/3) dk = k^(-2/3) d ln k
    out[good] = np.trapezoid(integrand, np.log(k), axis=1)
    return out


def window_moments(
    w: np.ndarray, window: np.ndarray, n_windows: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Count, mean, variance and skewness of ``w`` per window and gate (NaN skipped).

    Parameters
    ----------
    w : numpy.ndarray
        ``(ray, gate)`` vertical velocity (m s-1), NaN where screened.
    window : numpy.ndarray of int
        ``(ray,)`` window index of each ray, 0 .. n_windows-1.
    n_windows : int

    Returns
    -------
    count, mean, variance, skewness : numpy.ndarray
        ``(window, gate)``; variance ``sum (w - mean)^2 / n`` (the window mean removed,
        the ``1 - sinc^2`` filter of :func:`band_variance_factor`), skewness
        ``m_3 / m_2^(3/2)``; NaN where fewer than 2 (skewness 3) valid rays.
    """
    valid = np.isfinite(w)
    x = np.where(valid, w, 0.0)
    shape = (n_windows, w.shape[1])

    def total(values: np.ndarray) -> np.ndarray:
        out = np.zeros(shape)
        np.add.at(out, window, values)
        return out

    count = total(valid.astype(float))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total(x) / count
        dev = np.where(valid, w - mean[window], 0.0)
        m2 = total(dev**2) / count
        m3 = total(dev**3) / count
        skew = m3 / m2**1.5
    mean = np.where(count >= 1, mean, np.nan)
    var = np.where(count >= 2, m2, np.nan)
    skew = np.where((count >= 3) & (m2 > 0), skew, np.nan)
    return count.astype(np.int64), mean, var, skew


def window_mean(values: np.ndarray, window: np.ndarray, n_windows: int) -> np.ndarray:
    """Mean of ``values`` ``(ray, gate)`` per window (NaN skipped; NaN when none)."""
    valid = np.isfinite(values)
    total = np.zeros((n_windows, values.shape[1]))
    count = np.zeros_like(total)
    np.add.at(total, window, np.where(valid, values, 0.0))
    np.add.at(count, window, valid.astype(float))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan)


def variance_form_traces(times_s: np.ndarray, group: np.ndarray) -> tuple[float, float, float]:
    """Traces of the mean of window variances of Gaussian rays, per eps^(2/3) U^(2/3).

    The mean over ``k`` variance windows of the variance of their ``n_s`` rays about each
    window's mean is the quadratic form ``V = w^T A w``, ``A`` block-diagonal with
    ``(I - 1 1^T/n_s) / (k n_s)``. For Gaussian ``w`` of covariance ``Sigma = a B + b I``
    (``B_ij = -D_T(|t_i - t_j|)/2`` per ``a = (eps U)^(2/3)``, the inertial transverse
    structure function ``D_T = (4/3) C_K eps^(2/3) r^(2/3)`` at ``r = U |t_i - t_j|``;
    ``b = sigma_e^2`` the white noise), ``Var(V) = 2 tr(A Sigma A Sigma)
    = 2 (a^2 T_2 + 2 a b T_1 + b^2 T_0)`` (the variance of a Gaussian quadratic form).

    Parameters
    ----------
    times_s : numpy.ndarray
        ``(n,)`` ray times (s) of one product window.
    group : numpy.ndarray of int
        ``(n,)`` variance window of each ray; windows with fewer than 3 rays are left
        out, as the estimator leaves them out.

    Returns
    -------
    t0, t1, t2 : float
        ``tr(A A)``, ``tr(A A B)``, ``tr(A B A B)`` (``B`` in s^(2/3)); NaN without a
        window of 3 rays.
    """
    _, inverse, counts = np.unique(group, return_inverse=True, return_counts=True)
    keep = counts[inverse] >= 3
    if not keep.any():
        return math.nan, math.nan, math.nan
    t = np.asarray(times_s, dtype=float)[keep]
    g = inverse[keep]
    n_s = np.bincount(g)
    k = np.count_nonzero(n_s)
    same = g[:, None] == g[None, :]
    n_row = n_s[g].astype(float)
    a = np.where(same, -1.0 / n_row[:, None], 0.0)
    a[np.diag_indices_from(a)] += 1.0
    a /= k * n_row[:, None]
    b = -0.5 * (4.0 / 3.0) * C_K * np.abs(t[:, None] - t[None, :]) ** (2 / 3)
    ab = a @ b
    return float(np.sum(a * a)), float(np.sum(a * ab.T)), float(np.sum(ab * ab.T))


def variance_standard_error(
    epsilon: ArrayLike,
    wind_speed: ArrayLike,
    noise_variance: ArrayLike,
    traces: tuple[ArrayLike, ArrayLike, ArrayLike],
) -> np.ndarray:
    """Standard error (m2 s-2) of the mean window variance of Gaussian stare rays.

    ``sqrt(2 (a^2 T_2 + 2 a b T_1 + b^2 T_0))``, ``a = (eps U)^(2/3)``, ``b = sigma_e^2``
    (:func:`variance_form_traces`): the scatter a window's variance has for turbulence of
    dissipation rate ``eps`` carried past at ``U`` and white noise ``sigma_e``, whatever
    the number of variance windows (the scatter of a few windows' variances says little
    about it).
    """
    t0, t1, t2 = (np.asarray(x, dtype=float) for x in traces)
    a = (np.asarray(epsilon, float) * np.asarray(wind_speed, float)) ** (2 / 3)
    b = np.asarray(noise_variance, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.sqrt(2.0 * (a**2 * t2 + 2.0 * a * b * t1 + b**2 * t0))


def power_bias_divisor(relative_variance_se: ArrayLike) -> np.ndarray:
    """``E[(V/G)^(3/2)] / eps`` to second order: ``1 + (3/8) (SE(V)/V)^2``.

    eps from an unbiased variance ``V`` is biased high by the 3/2 power (delta method,
    second order in the relative standard error of ``V``): +1.5 % for the 30-s windows
    of a dense stare, about +10 % for four rays per window in 300 s of a sparse stare.
    Dividing by this factor makes the mean eps unbiased for Gaussian statistics.
    """
    rel = np.asarray(relative_variance_se, dtype=float)
    return 1.0 + 0.375 * np.where(np.isfinite(rel), rel, 0.0) ** 2
