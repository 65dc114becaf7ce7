"""Dissipation rate, noise, variance and integral scale from D_L (stage ``epsilon``).

Model of the azimuth structure function (Smalikho (2020), eq. 4, generalised by
eqs. 14-15 to wind transport):

.. math::

    \\langle \\bar D_L(l\\Delta\\theta)\\rangle = \\varepsilon^{2/3} A(l\\Delta y) + 2\\sigma_e^2 ,

with ``dy = dtheta R'`` (``R' = h/tan(phi)``) and ``A`` the A-function of the probe
volume (:mod:`cwproc.physics.afunctions`, tabulated by :mod:`cwproc.physics.atable`):

- method 1, ``A = A_1 = A_perp`` (no wind transport, valid for ``mu = U/V_s << 1``);
- method 2, ``A = A_2`` of Smalikho (2020), eq. 15 with ``mu = U/V_s`` and
  ``V_s = 2 pi R'/T_scan`` (Smalikho (2020), eq. 3).

Estimates, per block of scans and height, all vectorised:

- ``epsilon`` (method 2, equal to ``epsilon_fit``) and ``epsilon_method1``: the least
  squares of ``eps^(2/3) A_i(l dy) + 2 sigma_e^2`` over all valid lags ``l = 1..L``
  (:func:`fit_structure_function`) with ``A_2`` and ``A_1``; Smalikho (2020), eq. 5 is
  its two-lag case (:func:`eq5_epsilon`). On exact 24-ray VAD statistics eq. 5 (lags 3
  and 1) scattered 68 % per block against 34 % for the least squares, and its heavy
  tail moved the mean by +8 %; ``epsilon_ratio`` is ``epsilon_method1 / epsilon`` (the
  observed counterpart of eq. 21);
- ``noise_std``: the intercept of that fit. Where it is not determined (fewer than
  three lags, negative, a standard error above half the predicted ``2 sigma_pred^2``,
  further than a factor :data:`NOISE_PLAUSIBLE` from the prediction, or below
  :data:`NOISE_DETECTABLE`) it is fixed at ``2 sigma_pred^2`` of
  ``noise_std_predicted`` (:func:`predicted_noise`, Pearson et al. (2009), eq. 3; without
  a prediction: twice its standard error decides) and flag 32 is set: ``noise_std`` is
  then the prediction, or NaN without one, never a measured 0;
- ``edr = eps^(1/3)``; standard errors of eps, sigma_V^2 and L_V by the delta method
  through the whole fit (:func:`delta_method_errors`, the covariance of ``D_L`` and the
  variance over the block's scans);
- ``A_1`` and ``A_2`` come from tables of the exact two-beam geometry (any azimuth step,
  :mod:`cwproc.physics.two_beam`, :func:`cwproc.physics.atable.geometry_correction`),
  ``A_2`` averaged over the azimuths of the pairs present (``pair_azimuth_weights``:
  sectors and gaps, :func:`_sector_evaluate`);
- ``velocity_variance``: the variance of ``V'_L`` minus ``sigma_e^2``, divided by the
  part of ``sigma_V^2`` that passes the probe, ``int int Phi_L H_par H_perp /
  int int Phi_L`` with the model's 2-D spectrum at the fitted ``L_V``
  (:func:`passed_variance`; Smalikho (2020), eqs. 16-20). Where the inertial form is
  kept (module rule below) the lost part is ``eps^(2/3) int int Phi (1 - H_par H_perp)``
  with the inertial spectrum of eq. 18 (:func:`averaging_loss`). The inertial loss must
  not be used with a long probe: a cw probe of half width 300 m (h = 500 m, seed-000
  lidar) passes only 25 % of sigma_V^2 of an L_V = 333 m field, and the inertial
  loss overestimated sigma_V^2 2.5-fold, so L_V came out too large and eps 40 % low.
  The share the block-mean VAD wind takes is that of the full circle
  (:func:`mean_removed_share`), or for sectors and gaps (:func:`partial_circle`) that of
  the azimuths present with the scans' correlation (:func:`sector_removed_share`);
- ``integral_scale``: ``L_V = c sigma_V^3 / eps``, Banakh et al. (1999), eq. 19, with the
  correlation model named by ``model`` (``c = 1.331`` for the model of Banakh et al.
  (1999), eq. 17, also used with ``model="inertial"``; ``c = 0.697`` for von Kármán).

Finite outer scale (``model="von_karman"`` or ``"exponential"``): the inertial-range
A-functions are a limit. ``eps`` and ``L_V`` are fitted together: for every candidate
``L_V`` on a geometric grid over the A-table's outer-scale range (then refined by
bisection), the least squares of eq. 4 with the model's A-functions over all valid lags
gives ``eps(L_V)`` and ``sigma_e(L_V)`` (the two-lag eq. 5 is noisier and, through the
coupling with ``L_V``, biased eps 5 % higher on the seed-000 cw simulation); the
solution is the largest
``L_V`` at which the variance of ``V'_L`` the model predicts, ``eps^(2/3)`` times
:func:`passed_variance` (the probe-passed part of ``(eps L_V / c)^(2/3)``, Banakh et al.
(1999), eq. 19), equals the measured one minus ``sigma_e^2``, interpolated in
``log L_V``. The rule of the fallback to the inertial form: it is kept where ``L_V``
cannot be determined (no positive corrected variance or no finite ``eps``), where the
root lies above the table's range, and where every length involved -- the largest
separation ``L dy (1 + mu)`` and the probe length ``probe.length_scale_m`` -- is below
2 % of the inertial ``L_V`` (there the finite-scale A-functions differ from the inertial
ones by about 1 % or less); everywhere else the finite-outer-scale A-functions are used.
When even the smallest tabulated ``L_V`` gives too much variance, the lags are beyond
the inertial range (flag 2).

cw probes (finite-outer-scale models, ``mu <= CW_EXACT_MU_MAX``): a focused cw probe is
hundreds of metres long at a few hundred metres height, so the structure function's
shape over the lags depends on ``L_V`` and fixes it; the variance condition above, fed
by the sampling error of the variance of ten scans, doubled the scatter of eps there.
These cells use the exact model of Banakh et al. (1999), eqs. 15-17 without transport
(:class:`ExactLagModel`: the correlation tensor integrated along both beams, the
transverse spacing varying along the probe): ``D_L(l) = 2 sigma_V^2 [b_0(L_V) -
b_l(L_V)] + 2 sigma_e^2`` fitted by least squares over a grid of ``L_V``
(:func:`fit_correlation_shape`), ``eps = c sigma_V^3 / L_V`` (Banakh et al. (1999), eq.
19) from the fitted pair, as in seed 000's error study. On three lags the noise is a
third parameter, so its variance is pooled (median over ``noise_window_blocks``
neighbouring blocks at a height, :func:`running_nanmedian`) and each block refitted with
it fixed. The variance of ``V'_L`` minus
``sigma_e^2`` then gives ``sigma_V^2`` through ``b_0`` and the share the N-scan VAD fit
removes, ``tr(H B_D)/(N M)`` (:func:`hat_trace_per_ray`), and ``L_V = c sigma_V^3 /
eps``. The A-functions at that ``L_V`` still give ``epsilon_method1`` and the ratio.

Flags (``turbulence_flag``, bits combine; bits 1, 2, 8, 16 make the estimates NaN):

- 1: too few pairs (``n_pairs`` < ``min_pairs`` at lag 1 or lag ``l``): no ``eps``;
- 2: lag beyond the inertial range (Smalikho (2020), after eq. 4): ``L dy (1 + mu) >
  L_V`` with the inertial model; with the finite-outer-scale models (whose A-functions
  hold at any separation) only ``L_V`` below the A-table's range: no ``eps``;
- 4: ``mu`` beyond the validity of method 1, ``eps_1/eps_2 > 1.1`` (Smalikho (2020),
  eq. 21 and its discussion): ``epsilon_method1`` is kept (its bias is the observable of
  eq. 21), ``epsilon`` stays;
- 8: fit failed (``D(l) <= D(1)``, non-finite values, no mean wind for ``mu``, a height
  or ``mu`` outside the A-table's range (the default 10-3000 m height range is widened
  to the data's heights, :func:`table_height_range`), or fewer than two lags within
  ``max_lag_deg``): no ``eps``;
- 16: partial block: the block holds fewer than half the requested scans per block
  (``n_scans < MIN_BLOCK_FRACTION * n_scans_per_block``, e.g. the 2 scans left over from
  12 scans in blocks of 10): no ``eps``. The variance of ``V'_L`` about the mean of so
  few scans lacks the scan-to-scan variance of the large eddies (seed 000's ``N``
  dependence of the errors: 33-38 % at N = 1 against 10-12 % at N = 10), so ``L_V`` and
  ``eps`` would be biased; half a block keeps the relative error within about 1.5 times
  that of a full block (REFERENCE_VALUES.md section 3: 14-16 % at N = 5);
- 32: the noise intercept is not determined; the predicted sigma_e is used (above).

``structure_function_model`` is the fitted ``eps_fit^(2/3) A_2(l dy) + 2 sigma_e^2``
(with the A-functions used for the cell) for plotting against ``structure_function``.
``transverse_resolution`` (dy), ``scan_speed`` (V_s) and ``mu`` (U/V_s) describe the
sampling geometry and regime of each cell and are auxiliary coordinates
``(time, height)`` of the product (CF).
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from cwproc.physics import spectra
from cwproc.physics.transfer import transverse
from cwproc.references import BANAKH_1999, SMALIKHO_2020

#: turbulence_flag bits
FLAG_TOO_FEW_PAIRS = 1
FLAG_BEYOND_INERTIAL = 2
FLAG_METHOD1_INVALID = 4
FLAG_FIT_FAILED = 8
FLAG_PARTIAL_BLOCK = 16
FLAG_NOISE_PREDICTED = 32

#: fewest lags for a fitted noise intercept (one residual degree of freedom for its
#: standard error; on exact-statistics 24-ray step-stare scans the three-lag sigma_e came
#: out 5-8 times too large, while 144-ray scans with noise 0.3 m/s recover it; 4 would
#: trade the second for the first, see docs/physics-epsilon.md)
MIN_NOISE_LAGS = 3
#: the noise is fitted only where the predicted 2 sigma_e^2 is at least this share of
#: the smallest structure function of the block (below it, the prediction is used)
NOISE_DETECTABLE = 0.05
#: a fitted sigma_e further than this factor from the predicted one is not kept (flag 32)
NOISE_PLAUSIBLE = 2.0

#: a block with fewer than this share of the requested scans is not estimated (flag 16)
MIN_BLOCK_FRACTION = 0.5

#: eps_1/eps_2 above which method 1 is not used (Smalikho (2020), eq. 21: 10 % bias)
METHOD1_RATIO_LIMIT = 1.1
#: lengths below this fraction of L_V keep the inertial A-functions (see module doc)
INERTIAL_FRACTION = 0.02
#: bisection steps of the outer-scale root (bracket ratio (3000/10)^(1/6) -> 0.2 %)
_BISECTIONS = 9
#: bisections from a bracket of a factor 2 on either side of a known root (-> 1.1 %)
_BISECTIONS_NEAR = 6


def eq5_epsilon(d_l: np.ndarray, d_1: np.ndarray, a_l: np.ndarray, a_1: np.ndarray) -> np.ndarray:
    """Two-lag estimate of the dissipation rate (m2 s-3), Smalikho (2020), eq. 5.

    ``eps = [(D(l) - D(1)) / (A(l dy) - A(dy))]^(3/2)``; NaN where either difference is
    not positive.

    Parameters
    ----------
    d_l, d_1 : numpy.ndarray
        Structure function at lags l and 1 (m2 s-2).
    a_l, a_1 : numpy.ndarray
        A-function at lags l and 1 (m^(2/3)).
    """
    num = d_l - d_1
    den = a_l - a_1
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = num / den
    return np.where((num > 0) & (den > 0), ratio, np.nan) ** 1.5


def _lag_sum(x: np.ndarray) -> np.ndarray:
    """Sum over the last axis (the few lags), in order.

    numpy reduces such short rows sequentially too, so the sums are the same; an
    element-wise sum over the lags is several times faster than ``x.sum(-1)`` there.
    """
    return functools.reduce(np.add, np.moveaxis(x, -1, 0), np.zeros(x.shape[:-1]))


def fit_structure_function(
    d: np.ndarray,
    a: np.ndarray,
    valid: np.ndarray,
    noise_prior: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares of ``D = eps^(2/3) A + 2 sigma_e^2`` over the lags (last axis).

    Smalikho (2020), eq. 4. The intercept ``2 sigma_e^2`` is *determined* where at least
    :data:`MIN_NOISE_LAGS` lags are valid, it exceeds twice its standard error
    (``s sqrt(sum x^2 / (n sum x^2 - (sum x)^2))``, ``s^2`` the residual variance with
    ``n - 2`` degrees of freedom), and the predicted ``2 sigma_pred^2`` is at least
    :data:`NOISE_DETECTABLE` of the smallest ``D`` (a noise far below ``D`` at the first
    lag is not measurable: the intercept then measures the sampling error of ``D`` and
    the model's shape; on exact 24-ray VAD statistics it came out 6-8 times the true
    sigma_e, and eps 22 % low). Elsewhere (insignificant, negative, or too few lags)
    the slope is refitted with the intercept fixed at ``2 sigma_pred^2`` from
    ``noise_prior`` (the noise predicted from the SNR, :mod:`cwproc.physics.noise`), or
    at 0 without a prediction; ``sigma_e`` is then the prediction, or NaN -- never a
    measured 0.

    Parameters
    ----------
    d : numpy.ndarray
        Structure function (m2 s-2), lags on the last axis.
    a : numpy.ndarray
        A-function at the same lags (m^(2/3)).
    valid : numpy.ndarray of bool
        Lags to use.
    noise_prior : numpy.ndarray, optional
        Predicted sigma_e (m s-1), shape of ``d`` without the last axis.

    Returns
    -------
    (epsilon, noise_std, determined) : tuple of numpy.ndarray
        eps (m2 s-3), sigma_e (m s-1), and whether sigma_e is the fitted one; NaN where
        fewer than two lags are valid.
    """
    w = valid & np.isfinite(d) & np.isfinite(a)
    n = _lag_sum(w.astype(float))
    x = np.where(w, a, 0.0)
    y = np.where(w, d, 0.0)
    sx, sy = _lag_sum(x), _lag_sum(y)
    sxx, sxy = _lag_sum(x * x), _lag_sum(x * y)
    with np.errstate(invalid="ignore", divide="ignore"):
        det = n * sxx - sx**2
        slope = (n * sxy - sx * sy) / det
        intercept = (sy - slope * sx) / n
        resid = np.where(w, y - slope[..., None] * x - intercept[..., None], 0.0)
        s2 = _lag_sum(resid**2) / (n - 2)
        se_intercept = np.sqrt(s2 * sxx / det)
    prior = np.full(slope.shape, np.nan) if noise_prior is None else np.asarray(noise_prior)
    # an intercept above twice its standard error is kept; where there is a prediction,
    # so is one the fit measures precisely (standard error below half the predicted
    # 2 sigma_pred^2) within a factor NOISE_PLAUSIBLE of it: judged on the fitted value
    # alone, the blocks whose intercept fell low by chance took the prediction and those
    # that rose kept theirs, and the "fitted" noise read 14-37 % high (180-ray scans)
    with np.errstate(invalid="ignore", divide="ignore"):
        pred2 = 2.0 * np.nan_to_num(prior) ** 2
        plausible = np.abs(np.log(np.maximum(intercept, 1e-300) / pred2)) <= 2.0 * math.log(
            NOISE_PLAUSIBLE
        )
        precise = np.isfinite(prior) & (2.0 * se_intercept < pred2) & plausible
        significant = (intercept > 2.0 * se_intercept) | precise
    determined = (n >= MIN_NOISE_LAGS) & (intercept > 0) & significant
    # a noise term far below the smallest structure function cannot be told from the
    # sampling error of D and the model's shape: the fitted intercept then measures
    # those, not the noise (24-ray VADs: 6-8 times the true sigma_e)
    with np.errstate(invalid="ignore"):
        smallest = functools.reduce(
            np.minimum, np.moveaxis(np.where(w, d, np.inf), -1, 0), np.full(n.shape, np.inf)
        )
        detectable = ~np.isfinite(prior) | (2.0 * prior**2 >= NOISE_DETECTABLE * smallest)
    determined = determined & detectable
    fixed = np.where(np.isfinite(prior), 2.0 * np.nan_to_num(prior) ** 2, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        fixed_slope = (sxy - fixed * sx) / sxx
    slope = np.where(determined, slope, fixed_slope)
    intercept = np.where(determined, intercept, fixed)
    ok = (n >= 2) & (slope > 0) & np.isfinite(slope)
    eps = np.where(ok, np.where(ok, slope, 1.0) ** 1.5, np.nan)
    noise = np.where(determined, np.sqrt(np.maximum(intercept, 0.0) / 2.0), prior)
    return eps, np.where(ok, noise, np.nan), determined & ok


def averaging_loss(
    probe: Any, dy: np.ndarray, range_m: np.ndarray, n_angle: int = 48, n_radius: int = 320
) -> np.ndarray:
    """Variance lost to the probe-volume averaging, per eps^(2/3) (m^(2/3)).

    ``int_0^inf int_0^inf Phi(k1, k2) [1 - H_par(k1) H_perp(k2)] dk1 dk2`` with the
    inertial 2-D spectrum of Smalikho (2020), eq. 18 and the transfer functions of eqs.
    19-20 (the quadrant integral of ``Phi`` is the variance: ``A = 2 int int Phi
    (1 - cos)``, eqs. 16-17). Polar quadrature, log-spaced in the radius, with the
    analytic ``rho^(-2/3)`` tail above 1000 cycles m-1.

    Parameters
    ----------
    probe : PulsedProbe or CWProbe
        ``probe.longitudinal(kappa, range_m)`` gives H_par.
    dy : numpy.ndarray
        Transverse sampling (m).
    range_m : numpy.ndarray
        Distance of the probe from the lidar (m), same shape as ``dy``.
    """
    dy = np.asarray(dy, dtype=float)
    shape = dy.shape
    dy_f = dy.ravel()[:, None, None]
    rng_f = np.broadcast_to(np.asarray(range_m, dtype=float), shape).ravel()[:, None, None]
    alpha = (np.arange(n_angle) + 0.5) * (np.pi / 2) / n_angle
    t = np.linspace(np.log(1e-6), np.log(1e3), n_radius)
    rho = np.exp(t)[None, None, :]
    ca, sa = np.cos(alpha)[None, :, None], np.sin(alpha)[None, :, None]
    c = spectra.exact_plane_constant()
    angular = c * (1 + (8 / 3) * sa**2)
    out = np.empty(dy_f.shape[0])
    chunk = max(1, 2_000_000 // (n_angle * n_radius))
    for i in range(0, dy_f.shape[0], chunk):  # memory-bounded chunks, each vectorised
        h = probe.longitudinal(rho * ca, rng_f[i : i + chunk]) * transverse(
            rho * sa, probe.transverse_size(dy_f[i : i + chunk])
        )
        f = angular * rho ** (-2 / 3) * (1 - h)
        radial = np.trapezoid(f, t, axis=-1)
        out[i : i + chunk] = radial.sum(axis=-1) * (np.pi / 2) / n_angle
    tail = 1.5 * 1e3 ** (-2 / 3) * c * (np.pi / 2) * (1 + (8 / 3) * 0.5)
    return (out + tail).reshape(shape)


def passed_variance(
    probe: Any,
    dy: np.ndarray,
    range_m: np.ndarray,
    model: str,
    outer_scales_m: np.ndarray,
    n_angle: int = 48,
    n_radius: int = 320,
) -> np.ndarray:
    """Variance of the probe-averaged radial velocity per eps^(2/3) (m^(2/3)).

    ``int_0^inf int_0^inf Phi_L(k1, k2) H_par(k1) H_perp(k2) dk1 dk2`` with the 2-D
    spectrum ``Phi_L = 4 [I1(kappa) - k1^2 I2(kappa)]`` of a finite-outer-scale model
    (:func:`cwproc.physics.spectra.plane_spectrum`) and the transfer functions of
    Smalikho (2020), eqs. 19-20: the limit of ``A/2`` at large separations (eqs. 16-17),
    so that the measured variance of ``V'_L`` is ``eps^(2/3)`` times this. Without the
    probe (``H = 1``) it equals ``sigma_V^2 / eps^(2/3)`` of the model (Banakh et al.
    (1999), eq. 19). ``I1`` and ``I2`` depend on ``|kappa|`` only, so the angular
    integrals of ``H`` and ``cos^2 H`` are done once per cell and combined with the
    spectrum of every outer scale by one matrix product.

    Parameters
    ----------
    probe : PulsedProbe or CWProbe
        ``probe.longitudinal(kappa, range_m)`` gives H_par.
    dy : numpy.ndarray
        Transverse sampling (m), 1-D (cells).
    range_m : numpy.ndarray
        Distance of the probe from the lidar (m), same shape as ``dy``.
    model : {"von_karman", "exponential"}
    outer_scales_m : numpy.ndarray
        L_V (m), 1-D.

    Returns
    -------
    numpy.ndarray
        Shape ``(cells, outer scales)``.
    """
    dy_f = np.asarray(dy, dtype=float).ravel()[:, None, None]
    rng_f = np.broadcast_to(np.asarray(range_m, dtype=float).ravel(), (dy_f.shape[0],))
    rng_f = rng_f[:, None, None]
    alpha = (np.arange(n_angle) + 0.5) * (np.pi / 2) / n_angle
    t = np.linspace(np.log(1e-6), np.log(1e3), n_radius)
    rho = np.exp(t)
    ca, sa = np.cos(alpha)[None, :, None], np.sin(alpha)[None, :, None]
    s0 = np.empty((dy_f.shape[0], n_radius))
    s2 = np.empty((dy_f.shape[0], n_radius))
    chunk = max(1, 2_000_000 // (n_angle * n_radius))
    for i in range(0, dy_f.shape[0], chunk):  # memory-bounded chunks, each vectorised
        r = rho[None, None, :]
        h = probe.longitudinal(r * ca, rng_f[i : i + chunk]) * transverse(
            r * sa, probe.transverse_size(dy_f[i : i + chunk])
        )
        s0[i : i + chunk] = h.sum(axis=1) * (np.pi / 2) / n_angle
        s2[i : i + chunk] = (h * ca**2).sum(axis=1) * (np.pi / 2) / n_angle
    w = np.gradient(t)  # trapezoid weights in log radius (end halves below)
    w[0] *= 0.5
    w[-1] *= 0.5
    out = np.empty((dy_f.shape[0], np.size(outer_scales_m)))
    for k, big_l in enumerate(np.atleast_1d(outer_scales_m)):
        across = spectra.plane_spectrum(0.0, rho, model, float(big_l))  # 4 I1
        along = spectra.plane_spectrum(rho, 0.0, model, float(big_l))  # 4 (I1 - rho^2 I2)
        out[:, k] = (s0 * across - s2 * (across - along)) @ (rho**2 * w)
    return out


def probe_quadrature(probe: Any, range_m: float, n: int = 40, n_fine: int = 300) -> Any:
    """Nodes and weights of the probe's weighting along the beam (for B_D across the scan).

    cw probe: the Lorentzian ``Q_s`` of Banakh et al. (1999) (centre ``probe.centre_range``,
    half width ``probe.rayleigh_half_width``), cut at the lidar, by Gauss-Legendre nodes
    equal in weight (:func:`cwproc.physics.cw_probe.lorentzian_quadrature`), with a fine quadrature
    of ``n_fine`` nodes for the same-beam variance. Pulsed probe (a few tens of metres,
    small against the scan circle): one node at the gate centre.

    Parameters
    ----------
    probe : PulsedProbe or CWProbe
    range_m : float
        Distance of the probe from the lidar (m).
    n, n_fine : int
        Nodes of the cw quadrature and of its fine (zero-lag) version.

    Returns
    -------
    cwproc.sim.turbulence.ProbeQuadrature
    """
    from cwproc.physics.correlation import ProbeQuadrature
    from cwproc.physics.cw_probe import lorentzian_quadrature

    if not is_cw_probe(probe):
        return ProbeQuadrature((float(range_m),), (1.0,))
    zc = float(probe.centre_range(range_m))
    w = float(probe.rayleigh_half_width(range_m))
    return lorentzian_quadrature(zc, w, n, n_fine)


def is_cw_probe(probe: Any) -> bool:
    """True for a focused cw probe (Lorentzian weighting with a Rayleigh half width)."""
    return hasattr(probe, "rayleigh_half_width")


def vad_removed_variance(
    probe: Any,
    range_m: np.ndarray,
    elevation_deg: float,
    n_azimuths: int,
    model: str,
    outer_scales_m: np.ndarray,
    passed: np.ndarray,
) -> np.ndarray:
    """Variance of V_D the sine (VAD) fit of one scan takes away, per eps^(2/3) (m^(2/3)).

    The deviations ``V'_L`` from the N-scan VAD fit (Smalikho (2020), eqs. 1-2) of N
    independent scans keep ``B_D(0) - tr(H B_D)/(N M)`` of the probe-passed variance,
    ``H`` the hat matrix of the fit on one scan of M rays; for the circulant ``B_D`` of a
    full scan (Banakh et al. (1999), eq. 15 without transport) ``tr(H B_D)/M`` is the
    mean over the azimuth differences ``theta_k`` of ``B_D(theta_k) (1 + 2 cos theta_k)``
    (Fourier modes 0 and +-1). This returns that mean (divide by N for the block);
    ``B_D(0)`` is ``passed``, the other ``B_D(theta_k)`` the correlation of the model
    (:func:`cwproc.sim.turbulence.circulant_correlation_row`) with the probe's weighting
    (:func:`probe_quadrature`). On the seed-000 cw lidar with N = 10 it is 4-5 % of the
    passed variance. :func:`estimate_epsilon` takes the same share from
    :class:`ExactLagModel` for cw cells; this function gives it per eps^(2/3) on the
    spectral route (``passed`` from :func:`passed_variance`) and checks the two against
    the simulator. Wind transport (mu = U/V_s) is neglected here (mu <= 0.09 for that
    lidar).

    Parameters
    ----------
    probe : PulsedProbe or CWProbe
    range_m : numpy.ndarray
        Distance of the probe from the lidar (m), 1-D (cells).
    elevation_deg : float
        Elevation of the cone (deg).
    n_azimuths : int
        Rays per scan M.
    model : {"von_karman", "exponential"}
    outer_scales_m : numpy.ndarray
        L_V (m), 1-D.
    passed : numpy.ndarray
        :func:`passed_variance` of the cells on ``outer_scales_m``, (cells, scales).

    Returns
    -------
    numpy.ndarray
        Shape ``(cells, outer scales)``.
    """
    from cwproc.physics.correlation import ScanGeometry, circulant_correlation_row

    geometry = ScanGeometry(float(elevation_deg), int(n_azimuths), 1.0)
    lags = np.arange(1, int(n_azimuths))
    full = np.array([spectra.variance_per_eps23(model, x) for x in outer_scales_m])
    out = np.empty((np.size(range_m), np.size(outer_scales_m)))
    for i, r in enumerate(np.atleast_1d(range_m)):  # one quadrature per distinct range
        rows = circulant_correlation_row(
            geometry, probe_quadrature(probe, float(r)), outer_scales_m, model, lags=lags
        )
        row = np.concatenate([np.asarray(passed[i])[:, None], full[:, None] * rows], axis=1)
        out[i] = hat_trace_per_ray(row, int(n_azimuths))
    return out


def hat_trace_per_ray(row: np.ndarray, n_azimuths: int) -> np.ndarray:
    """``tr(H B_D)/M`` of the sine (VAD) fit of one full scan of M rays, from B_D's first row.

    For a circulant ``B_D`` (full scan, no transport) the hat matrix of the fit on
    ``1, cos theta, sin theta`` projects on the Fourier modes 0 and +-1, so
    ``tr(H B_D)/M = mean_k B_D(theta_k) (1 + 2 cos theta_k)``.

    Parameters
    ----------
    row : numpy.ndarray
        ``B_D(theta_0, theta_k)`` for k = 0..M-1 on the last axis.
    n_azimuths : int
        M.
    """
    theta = 2.0 * np.pi * np.arange(n_azimuths) / n_azimuths
    return np.asarray(row) @ (1.0 + 2.0 * np.cos(theta)) / n_azimuths


@dataclass(frozen=True)
class ExactLagModel:
    """Azimuth structure function of a cw probe from the exact B_D, per unit sigma_V^2.

    Banakh et al. (1999), eqs. 15-17 without the transport term: ``D_L(l dtheta) =
    2 sigma_V^2 [b_0(L) - b_l(L)]`` with ``b_k`` the first row of ``B_D/sigma_V^2`` for the
    probe's Lorentzian weighting, integrated along both beams (the transverse spacing
    varies along a long probe, which a single spacing at the probe centre misses by
    1.4-3.8 % of A_2 for a 270 m probe).

    Attributes
    ----------
    scales : numpy.ndarray
        L_V grid (m), (K,), log-spaced.
    structure : numpy.ndarray
        ``2 (b_0 - b_l)``, l = 1..n_lags, (K, n_lags).
    passed : numpy.ndarray
        ``b_0``: the share of sigma_V^2 the probe passes, (K,).
    removed : numpy.ndarray
        ``tr(H B_D) / (M sigma_V^2)`` (:func:`hat_trace_per_ray`): what the sine fit of one
        scan removes, (K,); the N-scan fit removes this divided by N.
    """

    scales: np.ndarray
    structure: np.ndarray
    passed: np.ndarray
    removed: np.ndarray

    def interpolate(self, name: str, outer_scale_m: np.ndarray) -> np.ndarray:
        """``passed`` or ``removed`` at ``outer_scale_m``, linear in ``log L`` (clipped)."""
        x = np.log(np.clip(outer_scale_m, self.scales[0], self.scales[-1]))
        return np.interp(x, np.log(self.scales), getattr(self, name))


#: outer scales (m) of the exact cw model, log-spaced 8 % apart
EXACT_SCALES = np.geomspace(5.0, 5.0e4, 121)
#: blocks over which the cw fit pools the noise variance (median), see estimate_epsilon
NOISE_WINDOW_BLOCKS = 7
#: mu = U/V_s up to which cw cells use :class:`ExactLagModel` (transport neglected;
#: cw lidars scan fast: mu <= 0.09 for the seed-000 lidar, about 0.01 for a ZephIR)
CW_EXACT_MU_MAX = 0.1


def exact_lag_model(
    probe: Any,
    range_m: float,
    elevation_deg: float,
    azimuth_step_deg: float,
    n_lags: int,
    model: str,
    scales: np.ndarray = EXACT_SCALES,
) -> ExactLagModel:
    """:class:`ExactLagModel` of a cw probe at one range (Banakh et al. (1999), eqs. 15-17).

    Parameters
    ----------
    probe : CWProbe
    range_m : float
        Focus distance (m).
    elevation_deg, azimuth_step_deg : float
        Cone elevation and azimuth spacing of the rays (deg); the scan is taken as a
        full circle of ``round(360 / azimuth_step_deg)`` rays.
    n_lags : int
        Lags l = 1..n_lags of the structure function.
    model : {"von_karman", "exponential"}
    scales : numpy.ndarray
        L_V grid (m).
    """
    from cwproc.physics.correlation import ScanGeometry, circulant_correlation_row

    n_az = round(360.0 / float(azimuth_step_deg))
    geometry = ScanGeometry(float(elevation_deg), n_az, 1.0)
    quad = probe_quadrature(probe, float(range_m))
    rows = circulant_correlation_row(geometry, quad, scales, model, lags=np.arange(n_lags + 1))
    # the removed share varies slowly with L: every 4th scale, interpolated in log L
    coarse = scales[::4] if scales.size > 8 else scales
    full = circulant_correlation_row(geometry, quad, coarse, model)
    removed = np.interp(np.log(scales), np.log(coarse), hat_trace_per_ray(full, n_az))
    return ExactLagModel(
        scales=np.asarray(scales, dtype=float),
        structure=2.0 * (rows[:, :1] - rows[:, 1:]),
        passed=rows[:, 0],
        removed=removed,
    )


@functools.lru_cache(maxsize=64)
def _exact_lag_model_cached(
    probe: Any,
    range_m: float,
    elevation_deg: float,
    azimuth_step_deg: float,
    n_lags: int,
    model: str,
) -> ExactLagModel:
    """:func:`exact_lag_model` on :data:`EXACT_SCALES`, memoised per configuration.

    About 0.5 s per range; a batch or a day of cw files re-uses the same few ranges. The
    arrays are read-only.
    """
    lm = exact_lag_model(probe, range_m, elevation_deg, azimuth_step_deg, n_lags, model)
    for value in (lm.scales, lm.structure, lm.passed, lm.removed):
        value.setflags(write=False)
    return lm


def fit_correlation_shape(
    structure: np.ndarray,
    lag_model: np.ndarray,
    scales: np.ndarray,
    valid: np.ndarray | None = None,
    *,
    noise: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares of ``D_L(l) = sigma^2 d(l; L) [+ 2 sigma_e^2]`` over a grid of L.

    For each L of the grid the best sigma^2 (and noise term) is linear; the L of the
    smallest residual is refined by a parabola in ``log L`` and the linear part
    refitted with the model interpolated there. The shape of the model fixes L and
    the level sigma^2 (Banakh et al. (1999), eqs. 15-17, 19). With ``noise`` the
    intercept ``2 sigma_e^2`` of white estimation noise (Smalikho (2020), eq. 4) is
    fitted too where at least three lags are valid; where it comes out negative the
    fit without it is kept.

    Parameters
    ----------
    structure : numpy.ndarray
        Measured D_L (m2 s-2), shape (..., n_lags).
    lag_model : numpy.ndarray
        ``d(l; L)`` on ``scales``, shape (K, n_lags) or (..., K, n_lags).
    scales : numpy.ndarray
        The L grid (m), (K,), log-spaced.
    valid : numpy.ndarray of bool, optional
        Lags to use, shape of ``structure``.
    noise : bool
        Fit the intercept ``2 sigma_e^2`` as well.

    Returns
    -------
    (sigma2, outer_scale, noise_variance) : numpy.ndarray
        sigma_V^2 (m2 s-2), L_V (m) and sigma_e^2 (m2 s-2, 0 without the intercept),
        shape (...); NaN where fewer than two lags are valid or the fit has no
        positive level.
    """
    d = np.asarray(structure, dtype=float)
    use = np.isfinite(d) if valid is None else (np.asarray(valid, bool) & np.isfinite(d))
    d = np.where(use, d, 0.0)
    lm = np.where(use[..., None, :], lag_model, 0.0)
    lm = np.broadcast_to(lm, d.shape[:-1] + lm.shape[-2:])
    n = use.sum(axis=-1)
    sigma2, log_l, _ = _shape_fit(d, lm, use, n, scales, intercept=False)
    nv = np.zeros_like(sigma2)
    if noise:
        s2_n, log_n, c_n = _shape_fit(d, lm, use, n, scales, intercept=True)
        take = (n >= 3) & (c_n > 0) & (s2_n > 0)
        sigma2 = np.where(take, s2_n, sigma2)
        log_l = np.where(take, log_n, log_l)
        nv = np.where(take, 0.5 * c_n, 0.0)
    good = (n >= 2) & (sigma2 > 0) & np.isfinite(sigma2)
    return (
        np.where(good, sigma2, np.nan),
        np.where(good, np.exp(log_l), np.nan),
        np.where(good, nv, np.nan),
    )


def _shape_fit(
    d: np.ndarray,
    lm: np.ndarray,
    use: np.ndarray,
    n: np.ndarray,
    scales: np.ndarray,
    intercept: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid search of :func:`fit_correlation_shape`: (slope, log L, intercept)."""
    nn = np.maximum(n, 1)[..., None]
    if intercept:  # centre both sides over the valid lags
        dm = np.sum(d, axis=-1, keepdims=True) / nn
        mm = np.sum(lm, axis=-1) / nn  # (..., K)
        dc = np.where(use, d - dm, 0.0)
        lc = np.where(use[..., None, :], lm - mm[..., None], 0.0)
    else:
        dc, lc = d, lm
    dd = np.sum(lc * lc, axis=-1)  # (..., K)
    proj = np.einsum("...kl,...l->...k", lc, dc)
    with np.errstate(invalid="ignore", divide="ignore"):
        resid = np.sum(dc * dc, axis=-1)[..., None] - proj**2 / dd
    resid = np.where(np.isfinite(resid), resid, np.inf)
    k = np.argmin(resid, axis=-1)
    kk = np.clip(k, 1, scales.size - 2)
    r0, r1, r2 = (np.take_along_axis(resid, (kk + j)[..., None], -1)[..., 0] for j in (-1, 0, 1))
    with np.errstate(invalid="ignore"):
        denom = r0 - 2.0 * r1 + r2
        ok = (denom > 0) & np.isfinite(denom)
        shift = np.where(ok, 0.5 * (r0 - r2) / np.where(ok, denom, 1.0), 0.0)
    shift = np.where(k == kk, np.clip(shift, -1.0, 1.0), 0.0)
    log_s = np.log(scales)
    step = log_s[1] - log_s[0]
    log_l = log_s[k] + shift * step
    pos = (log_l - log_s[0]) / step
    i0 = np.clip(np.floor(pos).astype(int), 0, scales.size - 2)
    frac = (pos - i0)[..., None]
    m0 = np.take_along_axis(lm, i0[..., None, None], axis=-2)[..., 0, :]
    m1 = np.take_along_axis(lm, (i0 + 1)[..., None, None], axis=-2)[..., 0, :]
    model = np.where(use, m0 * (1.0 - frac) + m1 * frac, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        if intercept:
            mbar = np.sum(model, axis=-1, keepdims=True) / nn
            mc = np.where(use, model - mbar, 0.0)
            slope = np.sum(dc * mc, axis=-1) / np.sum(mc * mc, axis=-1)
            const = dm[..., 0] - slope * mbar[..., 0]
        else:
            slope = np.sum(d * model, axis=-1) / np.sum(model * model, axis=-1)
            const = np.zeros_like(slope)
    return slope, log_l, const


def _interp_log_scale(grid_m: np.ndarray, values: np.ndarray, query_m: np.ndarray) -> np.ndarray:
    """Linear interpolation in ``log L`` of ``values (cells, K)`` at ``query_m (cells, k)``."""
    lg = np.log(grid_m)
    pos = (np.log(query_m) - lg[0]) / (lg[1] - lg[0])
    i0 = np.clip(np.floor(np.nan_to_num(pos, nan=0.0)).astype(int), 0, lg.size - 2)
    frac = pos - i0
    v0 = np.take_along_axis(values, i0, axis=1)
    v1 = np.take_along_axis(values, i0 + 1, axis=1)
    return v0 + (v1 - v0) * frac


def _evaluate(table: Any, lags: np.ndarray, height: np.ndarray, mu: np.ndarray, outer) -> tuple:
    """ATable.evaluate on broadcast, flattened arguments; returns (A1, A2) in that shape."""
    args = [lags, height, mu] + ([] if outer is None else [outer])
    b = np.broadcast_arrays(*[np.asarray(x, dtype=float) for x in args])
    shape = b[0].shape
    flat = [x.ravel() for x in b]
    a1 = np.empty(flat[0].size)
    a2 = np.empty(flat[0].size)
    step = EVALUATION_CELLS * 8  # values per call: bounded working memory of the table
    for start in range(0, a1.size, step):
        part = [x[start : start + step] for x in flat]
        a1[start : start + step], a2[start : start + step] = table.evaluate(
            part[0], part[1], part[2], outer_scale_m=None if outer is None else part[3]
        )
    return a1.reshape(shape), a2.reshape(shape)


#: the A-table's default height range (m) and the smallest height it is widened to
DEFAULT_HEIGHT_RANGE_M = (10.0, 3000.0)
MIN_TABLE_HEIGHT_M = 1.0


def table_height_range(
    height_m: np.ndarray, default: tuple[float, float] = DEFAULT_HEIGHT_RANGE_M
) -> tuple[float, float]:
    """Height range (m) of the A-table: the default, widened to cover the data's heights.

    The default range is extended downwards and upwards in steps of ``HEIGHT_RATIO^4``
    (about x2.07, four table nodes) until it holds every finite height at or above
    :data:`MIN_TABLE_HEIGHT_M`, so that few distinct tables (cache files) arise; each
    step adds four height nodes, about 12 % of the default table's build time.

    Parameters
    ----------
    height_m : numpy.ndarray
        Heights of the product (m).
    default : (float, float)
        Range used when every height lies inside it.
    """
    from cwproc.physics.atable import HEIGHT_RATIO

    h = np.asarray(height_m, dtype=float)
    h = h[np.isfinite(h) & (h >= MIN_TABLE_HEIGHT_M)]
    lo, hi = (float(v) for v in default)
    if h.size == 0:
        return lo, hi
    step = HEIGHT_RATIO**4
    if h.min() < lo:
        lo = lo / step ** math.ceil(math.log(lo / h.min()) / math.log(step))
    if h.max() > hi:
        hi = hi * step ** math.ceil(math.log(h.max() / hi) / math.log(step))
    return lo, hi


def _tables(probe: Any, phi: float, dtheta: float, n_lags: int, model: str, options: dict) -> tuple:
    """The inertial A-table and, for finite-outer-scale models, the model's table."""
    from cwproc.physics.atable import get_a_table

    inertial = get_a_table(
        probe,
        phi_deg=phi,
        delta_theta_deg=dtheta,
        n_lags=n_lags,
        model="inertial",
        **{k: v for k, v in options.items() if k != "outer_scale_range_m"},
    )
    if model == "inertial":
        return inertial, None
    finite = get_a_table(
        probe, phi_deg=phi, delta_theta_deg=dtheta, n_lags=n_lags, model=model, **options
    )
    return inertial, finite


def running_nanmedian(values: np.ndarray, order: np.ndarray, window: int) -> np.ndarray:
    """Median of ``values`` over ``window`` neighbours in ``order`` (NaN skipped).

    Parameters
    ----------
    values : numpy.ndarray
        1-D.
    order : numpy.ndarray
        Position of each value in the sequence (e.g. the block index), same shape.
    window : int
        Neighbours per median, centred (shortened at the ends).
    """
    idx = np.argsort(order, kind="stable")
    half = window // 2
    padded = np.concatenate([np.full(half, np.nan), values[idx], np.full(half, np.nan)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows give NaN
        med = np.nanmedian(windows, axis=1)
    out = np.empty_like(med)
    out[idx] = med
    return out


def _variance_root(
    eps: np.ndarray, measured: np.ndarray, lm: ExactLagModel, n_scans: np.ndarray, c: float
) -> np.ndarray:
    """L_V at which the model's variance of V'_L equals the measured one (m), per cell.

    ``(eps L_V / c)^(2/3) [b_0(L_V) - tr(H B_D)/(N M sigma_V^2)] = measured``: both factors
    grow with L_V, so the root is found on the grid of ``lm`` and interpolated in
    ``log L``. NaN where ``measured`` is not positive or the root lies off the grid.
    """
    grid = lm.scales[None, :]
    kept = lm.passed[None, :] - lm.removed[None, :] / np.asarray(n_scans, float)[:, None]
    with np.errstate(invalid="ignore"):
        model = np.log((np.asarray(eps)[:, None] * grid / c) ** (2 / 3) * kept)
        target = np.log(np.asarray(measured, float))[:, None]
    above = model >= target
    j = np.argmax(above, axis=1)  # first grid node at or above the measured variance
    ok = above.any(axis=1) & (j > 0) & np.isfinite(target[:, 0])
    j = np.clip(j, 1, grid.size - 1)
    rows = np.arange(j.size)
    m0, m1 = model[rows, j - 1], model[rows, j]
    frac = np.clip((target[:, 0] - m0) / np.where(m1 > m0, m1 - m0, 1.0), 0.0, 1.0)
    log_l = np.log(lm.scales[j - 1]) + frac * np.log(lm.scales[1] / lm.scales[0])
    return np.where(ok, np.exp(log_l), np.nan)


def _fit_exact_cells(
    probe: Any,
    d: np.ndarray,
    valid: np.ndarray,
    var_raw: np.ndarray,
    n_scans: np.ndarray,
    cells: np.ndarray,
    range_m: np.ndarray,
    phi: np.ndarray,
    dtheta: np.ndarray,
    model: str,
    c_model: float,
    fit_noise: bool,
    noise_window: int,
) -> dict[str, np.ndarray]:
    """eps, sigma_e, sigma_V^2, L_V of cw cells from the exact model (:class:`ExactLagModel`).

    Shape fit (:func:`fit_correlation_shape`) gives ``sigma_fit^2`` and ``L_fit``, so
    ``eps = c sigma_fit^3 / L_fit`` (Banakh et al. (1999), eq. 19), and with
    ``fit_noise`` sigma_e from the fit's intercept ``2 sigma_e^2`` (else 0). The variance
    of ``V'_L`` minus sigma_e^2 is ``sigma_V^2 (b_0 - tr(H B_D)/(N M sigma_V^2))`` with
    ``sigma_V^2 = (eps L_V / c)^(2/3)``, solved for L_V (:func:`_variance_root`).
    """
    n_t, n_h, n_l = d.shape
    out = {
        k: np.full((n_t, n_h), np.nan)
        for k in ("epsilon", "noise_std", "velocity_variance", "integral_scale")
    }
    out["below_range"] = np.zeros((n_t, n_h), dtype=bool)
    out["structure_function_model"] = np.full(d.shape, np.nan)
    phi_b = np.broadcast_to(np.round(phi, 3)[:, None], (n_t, n_h))
    dth_b = np.broadcast_to(np.round(dtheta, 4)[:, None], (n_t, n_h))
    keys = np.stack([np.round(range_m, 3), phi_b, dth_b], axis=-1)
    n_eff = np.where(np.isfinite(n_scans) & (n_scans >= 1), n_scans, 1.0)
    for key in np.unique(keys[cells], axis=0):  # one exact model per configuration
        ti, hi_ = np.nonzero(cells & np.all(keys == key, axis=-1))
        lm = _exact_lag_model_cached(
            probe, float(key[0]), float(key[1]), float(key[2]), int(n_l), model
        )
        dc, vc = d[ti, hi_], valid[ti, hi_]
        s2, l_fit, nv = fit_correlation_shape(dc, lm.structure, lm.scales, vc, noise=fit_noise)
        if fit_noise and noise_window > 1 and ti.size > 1:
            # the noise of neighbouring blocks, pooled: 2 parameters per block, not 3
            pooled = running_nanmedian(nv, ti, noise_window)
            s2_p, l_p, _ = fit_correlation_shape(
                dc - 2.0 * pooled[:, None], lm.structure, lm.scales, vc
            )
            ok = np.isfinite(s2_p) & np.isfinite(pooled)
            s2, l_fit = np.where(ok, s2_p, s2), np.where(ok, l_p, l_fit)
            nv = np.where(ok, pooled, nv)
        with np.errstate(invalid="ignore", divide="ignore"):
            eps = c_model * s2**1.5 / l_fit
        pos = np.interp(
            np.log(np.nan_to_num(l_fit, nan=lm.scales[0])),
            np.log(lm.scales),
            np.arange(lm.scales.size),
        )
        shape = np.stack(
            [np.interp(pos, np.arange(lm.scales.size), lm.structure[:, j]) for j in range(n_l)],
            axis=-1,
        )
        noise = np.sqrt(nv)
        measured = var_raw[ti, hi_] - noise**2
        scale = _variance_root(eps, measured, lm, n_eff[ti], c_model)
        with np.errstate(invalid="ignore"):
            sig2 = (eps * scale / c_model) ** (2 / 3)
        out["epsilon"][ti, hi_] = eps
        out["noise_std"][ti, hi_] = noise
        out["velocity_variance"][ti, hi_] = sig2
        out["integral_scale"][ti, hi_] = scale
        out["below_range"][ti, hi_] = l_fit <= lm.scales[0] * (1.0 + 1e-9)
        out["structure_function_model"][ti, hi_] = s2[:, None] * shape + 2.0 * nv[:, None]
    return out


#: nodes of mu = U/V_s of :func:`mean_removed_share` (linear interpolation between them)
REMOVED_SHARE_MU = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0])
#: wind directions (from the scan's first ray) averaged in :func:`mean_removed_share`
_REMOVED_SHARE_DIRECTIONS = 4


@functools.lru_cache(maxsize=16)
def _removed_share_curve(phi_deg: float, model: str) -> tuple[np.ndarray, np.ndarray]:
    """``(log x, r(mu, x))`` of :func:`mean_removed_share` on 25 nodes of ``x = R'/L_V``.

    ``tr(H B)/M`` of the VAD hat matrix ``H = (1 + 2 cos(theta_i - theta_j))/M`` of a
    full circle of 48 point beams and the correlation tensor ``B`` of the frozen field
    at the probes' positions in the field's frame, ``R' e(theta_m) - U t_m``: the rays
    follow each other over one scan period, so the wind carries the field ``mu R'
    theta_m`` along its direction (Smalikho (2020), eq. 3: ``U T = 2 pi mu R'``);
    averaged over :data:`_REMOVED_SHARE_DIRECTIONS` wind directions.
    """
    x = np.geomspace(1e-2, 1e2, 25)
    n_az = 48
    theta = 2.0 * np.pi * np.arange(n_az) / n_az
    ph = math.radians(phi_deg)
    s = np.stack(
        [np.full(n_az, math.sin(ph)), math.cos(ph) * np.cos(theta), math.cos(ph) * np.sin(theta)],
        axis=-1,
    )
    dot = s @ s.T
    hat = (1.0 + 2.0 * np.cos(theta[:, None] - theta[None, :])) / n_az**2
    circle = np.stack([np.zeros(n_az), np.cos(theta), np.sin(theta)], -1)
    share = np.zeros((REMOVED_SHARE_MU.size, x.size))
    for i, mu in enumerate(REMOVED_SHARE_MU):
        directions = 1 if mu == 0 else _REMOVED_SHARE_DIRECTIONS
        for k in range(directions):
            a = 2.0 * np.pi * k / directions
            wind = np.array([0.0, math.cos(a), math.sin(a)])
            pos = x[:, None, None] * (circle - mu * theta[:, None] * wind)[None]
            r_vec = pos[:, :, None, :] - pos[:, None, :, :]  # (x, i, j, 3)
            r = np.linalg.norm(r_vec, axis=-1)
            f, g = spectra.correlation_functions(r, model, 1.0)
            unit = np.where(r[..., None] > 0, r_vec / np.where(r > 0, r, 1.0)[..., None], 0.0)
            proj_i = np.einsum("xijk,ik->xij", unit, s)
            proj_j = np.einsum("xijk,jk->xij", unit, s)
            b = g * dot[None] + (f - g) * proj_i * proj_j
            share[i] += np.einsum("xij,ij->x", b, hat) / directions
    return np.log(x), share


#: cells (block, height) whose A-functions or passed variances are evaluated at once:
#: the evaluations hold a few kB per cell, so a day of blocks is done in pieces
EVALUATION_CELLS = 2048


def mean_removed_share(
    ratio: np.ndarray, phi_deg: float, model: str, mu: np.ndarray | float = 0.0
) -> np.ndarray:
    """Share of sigma_V^2 the scan-mean (VAD) wind takes from one scan's V'_L.

    ``tr(H B)/(M sigma_V^2)`` of a full circle of point beams, Banakh et al. (1999),
    eqs. 15-16 with the isotropic tensor of ``model``, the rays seen at their own times
    in the field carried by the wind (:func:`_removed_share_curve`); a function of
    ``ratio = R'/L_V`` and ``mu = U/V_s`` (tabulated once per elevation and model). The
    block mean of N independent scans removes this divided by N. The probe volume is
    neglected (the share is carried by scales of the circle, far above the probe).
    Transport matters: on exact 24-ray statistics at ``mu = 3`` (R'/L_V = 0.71) the
    block-mean wind removed 2.4 % of sigma_V^2, the frozen circle predicts 5.0 %; the
    overestimate biased the variance condition and eps 8 % low.
    """
    log_x, share = _removed_share_curve(round(float(phi_deg), 2), model)
    lx = np.log(np.clip(ratio, 1e-2, 1e2))
    m = np.clip(np.nan_to_num(np.asarray(mu, float), nan=0.0), 0.0, REMOVED_SHARE_MU[-1])
    lx, m = np.broadcast_arrays(lx, m)
    j = np.clip(
        np.searchsorted(REMOVED_SHARE_MU, m, side="right") - 1, 0, REMOVED_SHARE_MU.size - 2
    )
    w = (m - REMOVED_SHARE_MU[j]) / (REMOVED_SHARE_MU[j + 1] - REMOVED_SHARE_MU[j])
    # the two bracketing mu rows interpolated in lg(R'/L_V) where each is needed only
    # (not every row everywhere: that held a (mu node, time, height, L_V) array)
    lo = np.empty(lx.shape)
    hi = np.empty(lx.shape)
    for k in np.unique(j):
        at = j == k
        lo[at] = np.interp(lx[at], log_x, share[k])
        hi[at] = np.interp(lx[at], log_x, share[k + 1])
    return (1.0 - w) * lo + w * hi


#: nodes of x = R'/L_V of :func:`sector_removed_share` (log-log interpolation)
_SECTOR_X = np.geomspace(1e-2, 1e2, 9)


@functools.lru_cache(maxsize=4)
def _correlation_curve(model: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(ln r, f, g)``: normalised correlations of ``model`` at ``r/L_V`` 1e-5 to 1e3."""
    r = np.geomspace(1e-5, 1e3, 400)
    f, g = spectra.correlation_functions(r, model, 1.0)
    return np.log(r), f, g


def _empty_runs(occupied: np.ndarray) -> np.ndarray:
    """``(cells, N_BINS)`` number of empty nodes just before each node in scan order.

    The scan moves towards decreasing node angle (``theta = sign (wind_to - beta)``).
    """
    from cwproc.physics.atable import N_BINS

    run = np.zeros(occupied.shape, dtype=int)
    still = np.ones(occupied.shape, dtype=bool)
    for j in range(1, N_BINS):
        still &= ~np.roll(occupied, -j, axis=-1)
        run += still
    return run


def partial_circle(weights: np.ndarray, step_deg: np.ndarray) -> np.ndarray:
    """``(cells,)`` whether the pairs present leave out a sector wider than the scan's step.

    An empty stretch of azimuth nodes wider than ``max(2.5 dtheta, 20 deg)``: a sector
    scan or a gap (a regular scan leaves at most ``2 dtheta`` empty, where the last and
    the first ray of a scan make no pair).
    """
    from cwproc.physics.atable import N_BINS

    w = np.asarray(weights, float)
    known = np.all(np.isfinite(w), axis=-1) & (np.nan_to_num(w).sum(-1) > 0)
    runs = _empty_runs(np.nan_to_num(w) > 1e-12).max(axis=-1, initial=0)
    widest = runs * (360.0 / N_BINS)
    return known & (widest > np.maximum(2.5 * np.asarray(step_deg, float), 20.0))


def _scan_start_phase(occupied: np.ndarray) -> np.ndarray:
    """``(cells, N_BINS)`` scan angle (rad) travelled since the scan's first node.

    The scan starts at the occupied node that follows the longest run of empty nodes.
    """
    from cwproc.physics.atable import azimuth_nodes

    run = _empty_runs(occupied)
    start = np.argmax(np.where(occupied, run, -1), axis=-1)
    th = azimuth_nodes()
    return np.mod(th[start][:, None] - th[None, :], 2.0 * np.pi)


def sector_removed_share(
    weights: np.ndarray,
    ratio: np.ndarray,
    mu: np.ndarray,
    interval: np.ndarray,
    n_scans: np.ndarray,
    phi_deg: float,
    model: str,
    chunk: int = 8,
) -> np.ndarray:
    """Share of sigma_V^2 the block-mean VAD wind takes from V'_L of a sector or gappy scan.

    Each scan's VAD fit over the azimuths present (node weights ``w_k``,
    ``pair_azimuth_weights``) projects with ``h_kl = X_k^T (sum_j w_j X_j X_j^T)^-1
    X_l``, ``X = (1, cos beta, sin beta)``; the block mean of N such fits removes
    ``[N S_0 + 2 sum_m (N - m) S_m] / N^2`` with ``S_m = sum_kl w_k w_l h_kl
    b_kl(m) / sum w`` and ``b_kl(m)`` the correlation of point beams k and l (Banakh
    et al. (1999), eqs. 15-16, isotropic tensor of ``model``) in the field carried by
    the wind: within a scan the rays follow each other (``mu R'`` per radian scanned,
    Smalikho (2020), eq. 3), and scan ``n + m`` is ``m U T_int`` further on. A full
    circle of independent scans gives :func:`mean_removed_share` over N. Exact
    statistics of a 90 deg sector scan (45 rays, 12 s apart): the fit removes 7.7 % of
    sigma_V^2 per scan, and, the scans being 1-2 L_V apart, 11-18 % of it in the block
    at mu 1-0.5 (the full circle: 4.6 %).

    Parameters
    ----------
    weights : numpy.ndarray
        ``(cells, N_BINS)`` node weights; rows that are NaN give NaN (the caller keeps
        :func:`mean_removed_share` there and for full circles, :func:`partial_circle`).
    ratio : numpy.ndarray
        ``(cells, k)`` values of ``R'/L_V``.
    mu, interval, n_scans : numpy.ndarray
        ``(cells,)``: ``U/V_s``, the time between scan starts over ``T_scan`` (the
        full-circle period of :func:`estimate_epsilon`), scans per block.
    """
    from cwproc.physics.atable import N_BINS, azimuth_nodes

    out = np.full(ratio.shape, np.nan)
    w = np.nan_to_num(np.asarray(weights, float))
    cells = np.nonzero(np.all(np.isfinite(weights), axis=-1) & (w.sum(-1) > 0))[0]
    if cells.size == 0:
        return out
    log_r, f_c, g_c = _correlation_curve(model)
    th = azimuth_nodes()
    beta = -th  # wind towards beta = 0; the frozen statistics are mirror-symmetric
    ph = math.radians(phi_deg)
    design = np.stack([np.ones(N_BINS), np.cos(beta), np.sin(beta)], -1)
    circle = np.stack([np.cos(beta), np.sin(beta), np.zeros(N_BINS)], -1)
    beam = np.stack([math.cos(ph) * circle[:, 0], math.cos(ph) * circle[:, 1]], -1)
    beam = np.concatenate([beam, np.full((N_BINS, 1), math.sin(ph))], -1)
    wind = np.array([1.0, 0.0, 0.0])
    n_max = int(np.nanmax(n_scans[cells]))
    m = np.arange(n_max)
    for i in range(0, cells.size, chunk):
        c = cells[i : i + chunk]
        wc = w[c]
        gram = np.einsum("ck,ka,kb->cab", wc, design, design)
        h = np.einsum("ka,cab,lb->ckl", design, np.linalg.pinv(gram), design)
        hw = h * wc[:, :, None] * wc[:, None, :] / wc.sum(-1)[:, None, None]
        phase = _scan_start_phase(wc > 1e-12)
        pos = circle[None] - (mu[c][:, None] * phase)[..., None] * wind  # (c, k, 3), R' units
        # only the occupied nodes (a sector's few): the others have no weight
        occupied = wc > 1e-12
        idx = np.argsort(~occupied, axis=1, kind="stable")[:, : occupied.sum(1).max()]
        rows = np.arange(c.size)[:, None]
        hw, pos, bc = (
            hw[rows[..., None], idx[:, :, None], idx[:, None, :]],
            pos[rows, idx],
            beam[idx],
        )
        shift = (mu[c] * 2.0 * np.pi * interval[c])[:, None] * m[None]  # (c, m)
        r_vec = pos[:, :, None, None, :] - pos[:, None, :, None, :]
        r_vec = r_vec - shift[:, None, None, :, None] * wind  # (c, k, l, m, 3)
        r = np.linalg.norm(r_vec, axis=-1)
        unit = r_vec / np.where(r > 0, r, 1.0)[..., None]
        proj = np.einsum("cklmi,cki->cklm", unit, bc) * np.einsum("cklmi,cli->cklm", unit, bc)
        dot = np.einsum("cki,cli->ckl", bc, bc)[..., None]
        lr = np.log(np.maximum(r[..., None] * _SECTOR_X, 1e-5))  # (c, k, l, m, x)
        f, g = np.interp(lr, log_r, f_c), np.interp(lr, log_r, g_c)
        s_m = np.einsum("ckl,cklmx->cmx", hw, g * dot[..., None] + (f - g) * proj[..., None])
        n = n_scans[c][:, None]
        mult = np.where(m[None] == 0, n, 2.0 * np.clip(n - m[None], 0.0, None)) / n**2
        share = np.einsum("cm,cmx->cx", mult, s_m)
        query = np.clip(ratio[c], _SECTOR_X[0], _SECTOR_X[-1])  # log-log interpolation
        out[c] = np.exp(_interp_log_scale(_SECTOR_X, np.log(np.maximum(share, 1e-12)), query))
    return out


def pair_weights(sf: xr.Dataset) -> np.ndarray:
    """``(time, height, node)`` azimuth-node weights of the pairs present, NaN if unknown.

    From ``pair_azimuth_weights`` of :func:`cwproc.stages.structure.azimuth_structure_function`;
    NaN (the full circle is used) for a structure function without it.
    """
    from cwproc.physics.atable import N_BINS

    if "pair_azimuth_weights" in sf:
        return sf["pair_azimuth_weights"].transpose("time", "height", ...).values.astype(float)
    return np.full((sf.sizes["time"], sf.sizes["height"], N_BINS), np.nan)


def _sector_evaluate(
    table: Any, lags: np.ndarray, height: np.ndarray, mu: np.ndarray, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A_1, A_2, ratio)`` of an inertial table for blocks ``(t, h, lag)``.

    ``A_2`` averaged over the azimuths of the pairs present (``weights``, NaN rows: the
    full circle) and ``ratio`` = that over the full-circle ``A_2`` (1 where no weights):
    the same ratio scales the finite-outer-scale ``A_2`` (whose tables carry no nodes).
    """
    a1, a2_full = _evaluate(table, lags[None, None, :], height[None, :, None], mu[:, :, None], None)
    known = np.all(np.isfinite(weights), axis=-1)
    ratio = np.ones(a2_full.shape)
    all_ti, all_hi = np.nonzero(known)
    for start in range(0, all_ti.size, EVALUATION_CELLS):  # bounded working memory
        ti = all_ti[start : start + EVALUATION_CELLS]
        hi = all_hi[start : start + EVALUATION_CELLS]
        _, part = table.evaluate(
            np.broadcast_to(lags[None, :], (ti.size, lags.size)).ravel(),
            np.repeat(height[hi], lags.size),
            np.repeat(mu[ti, hi], lags.size),
            weights=np.repeat(weights[ti, hi], lags.size, axis=0),
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio[ti, hi] = part.reshape(ti.size, lags.size) / a2_full[ti, hi]
    return a1, a2_full * ratio, ratio


def predicted_noise(sf: xr.Dataset, probe: Any) -> np.ndarray:
    """``(time, height)`` sigma_e (m s-1) predicted from the block-median SNR.

    :func:`cwproc.physics.noise.velocity_noise_std` (Pearson et al. (2009), eq. 3) with
    the points per gate, pulses per ray and velocity resolution the reader put in the
    attributes; NaN for cw probes, without SNR or without those settings.
    """
    from cwproc.physics import noise

    shape = (sf.sizes["time"], sf.sizes["height"])
    points = sf.attrs.get("points_per_gate")
    pulses = sf.attrs.get("pulses_per_ray")
    if is_cw_probe(probe) or "snr_median" not in sf or not points or not pulses:
        return np.full(shape, np.nan)
    bandwidth = noise.bandwidth_from_resolution(sf.attrs.get("velocity_resolution_m_s"))
    snr = sf["snr_median"].transpose("time", "height").values.astype(float)
    return noise.velocity_noise_std(snr, float(points), float(pulses), bandwidth)


def standard_errors(
    sf: xr.Dataset,
    lag_used: int,
    d: np.ndarray,
    eps: np.ndarray,
    sigma2: np.ndarray,
    corrected_variance: np.ndarray,
    scale: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standard errors of eps, sigma_V^2 and L_V per block from the scatter over scans.

    The first-order form kept for the exact cw cells and for structure functions
    without ``statistics_covariance``; elsewhere :func:`delta_method_errors` replaces it
    (it omits the scatter of the fitted L_V: se/sd 0.63-1.05 on exact VAD statistics).

    - eps of Smalikho (2020), eq. 5, ``eps ~ (D(l) - D(1))^(3/2)``: relative error
      ``1.5 SE(D(l) - D(1)) / (D(l) - D(1))``, ``SE`` the standard error of the block's
      per-scan differences (``structure_function_difference_se``: the scans are the
      independent samples);
    - sigma_V^2: the standard error of the variance of ``V'_L`` (its per-scan scatter)
      scaled like the variance, ``SE(var) sigma_V^2 / (var - sigma_e^2)``;
    - ``L_V = c sigma_V^3 / eps`` (Banakh et al. (1999), eq. 19): relative errors
      combined as independent, ``sqrt((1.5 r_sigma2)^2 + r_eps^2)``.

    NaN where the structure function carries no standard errors.
    """
    nan = np.full(eps.shape, np.nan)
    if "structure_function_difference_se" not in sf:
        return nan, nan, nan
    diff_se = sf["structure_function_difference_se"].transpose("time", "height", "lag").values
    var_se = sf["radial_velocity_variance_se"].transpose("time", "height").values
    with np.errstate(invalid="ignore", divide="ignore"):
        diff = d[..., lag_used - 1] - d[..., 0]
        r_eps = 1.5 * diff_se[..., lag_used - 1] / np.where(diff > 0, diff, np.nan)
        r_sig = var_se / np.where(corrected_variance > 0, corrected_variance, np.nan)
        r_scale = np.hypot(1.5 * r_sig, r_eps)
    return eps * r_eps, sigma2 * r_sig, scale * r_scale


def _product_arrays(
    e1: np.ndarray,
    e2: np.ndarray,
    efit: np.ndarray,
    noise: np.ndarray,
    sigma2: np.ndarray,
    l_v: np.ndarray,
    bad: np.ndarray,
    few_fit: np.ndarray,
    exact: np.ndarray,
    a2: np.ndarray,
    sf_model_exact: np.ndarray,
) -> dict[str, np.ndarray]:
    """The estimates as written: NaN where flagged bad, never a 0 as measured noise.

    Method 1 is written wherever both estimates exist (its validity is flag 4), with the
    observed ratio ``epsilon_method1 / epsilon`` (Smalikho (2020), eq. 21) and
    ``edr = eps^(1/3)`` (m^(2/3) s-1).
    """
    eps2 = np.where(bad, np.nan, e2)
    eps1 = np.where(bad, np.nan, e1)
    out_noise = np.where(few_fit | ~(noise > 0), np.nan, noise)
    out_fit = np.where(few_fit | bad, np.nan, efit)
    with np.errstate(invalid="ignore", divide="ignore"):
        observed = eps1 / eps2
    sf_model = out_fit[..., None] ** (2 / 3) * a2 + 2.0 * np.nan_to_num(out_noise)[..., None] ** 2
    sf_model = np.where(
        exact[..., None] & np.isfinite(out_fit)[..., None], sf_model_exact, sf_model
    )
    return {
        "epsilon": eps2,
        "epsilon_method1": eps1,
        "epsilon_ratio": observed,
        "edr": np.cbrt(eps2),
        "epsilon_fit": out_fit,
        "structure_function_model": sf_model,
        "noise_std": out_noise,
        "velocity_variance": np.where(bad | ~(sigma2 > 0), np.nan, sigma2),
        "integral_scale": np.where(bad, np.nan, l_v),
    }


def _finite_scale_inputs(
    probe: Any,
    model: str,
    options: dict,
    uniq: np.ndarray,
    inverse: np.ndarray,
    scans: np.ndarray,
    radius: np.ndarray,
    phi: np.ndarray,
    range_th: np.ndarray,
    mu_eval: np.ndarray,
    n_outer_scales: int,
    weights: np.ndarray,
    interval: np.ndarray,
    dtheta: np.ndarray,
) -> dict:
    """What the finite-outer-scale fit needs besides D and the variance (per cell).

    The probe-passed variance per eps^(2/3) of the model on a log grid of L_V (ratio
    <= 1.1), per distinct (dy, range) cell (:func:`passed_variance`), less the share
    the block-mean VAD wind removes (:func:`mean_removed_share` at the cell's ``mu``,
    divided by the scans of the block; sectors and gaps (:func:`partial_circle` of the
    ``weights`` and ``dtheta``): :func:`sector_removed_share` with the scans' ``interval``
    over T_scan); the full variance per eps^(2/3) on that grid; the coarse L_V nodes.
    """
    n_t, n_h = range_th.shape
    lo, hi = options.get("outer_scale_range_m", (10.0, 3000.0))
    scale_grid = np.geomspace(lo, hi, int(np.ceil(np.log(hi / lo) / np.log(1.1))) + 1)
    cells_u = np.nonzero(uniq[:, 0] >= 0)[0]
    passed_u = np.full((uniq.shape[0], scale_grid.size), np.nan)
    for start in range(0, cells_u.size, EVALUATION_CELLS):  # bounded working memory
        cells = cells_u[start : start + EVALUATION_CELLS]
        passed_u[cells] = passed_variance(
            probe, np.abs(uniq[cells, 0]), np.abs(uniq[cells, 1]), model, scale_grid
        )
    passed_cell = passed_u[inverse.ravel()].reshape(n_t, n_h, scale_grid.size)
    full_var = np.array([spectra.variance_per_eps23(model, x) for x in scale_grid])
    n_eff = np.where(np.isfinite(scans) & (scans >= 1), scans, 1.0)
    phi_med = float(np.nanmedian(phi))
    share = np.empty(passed_cell.shape)
    step = max(1, EVALUATION_CELLS // max(n_h, 1))  # blocks at once: bounded memory
    for t0 in range(0, n_t, step):
        rows = slice(t0, t0 + step)
        ratio_rl = radius[rows, :, None] / scale_grid[None, None, :]
        share[rows] = mean_removed_share(ratio_rl, phi_med, model, mu_eval[rows, :, None])
    share /= n_eff[:, None, None]
    ti, hi_ = np.nonzero(partial_circle(weights, np.broadcast_to(dtheta[:, None], (n_t, n_h))))
    if ti.size:
        share[ti, hi_] = sector_removed_share(
            weights[ti, hi_],
            radius[ti, hi_, None] / scale_grid[None, :],
            mu_eval[ti, hi_],
            interval[ti],
            n_eff[ti],
            phi_med,
            model,
        )
    return {
        "nodes": np.geomspace(lo, hi, n_outer_scales),
        "scale_grid": scale_grid,
        "passed": passed_cell - full_var * share,
        "full_var": full_var,
    }


def _outer_scale_root(
    table: Any,
    table_rows: np.ndarray,
    finite: dict,
    cell_sector: np.ndarray,
    passed: np.ndarray,
    dc: np.ndarray,
    vc: np.ndarray,
    var_c: np.ndarray,
    prior: np.ndarray,
    start: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(root, has_root, below)`` of the variance condition in L_V for cells ``(n,)``.

    The variance of V'_L the model predicts, eps^(2/3) times the probe-passed part of
    sigma_V^2 = (eps L_V / c)^(2/3) (Banakh et al. (1999), eq. 19; :func:`passed_variance`),
    must equal the measured one minus sigma_e^2; eps(L_V) and sigma_e(L_V) from the least
    squares of Smalikho (2020), eq. 4 with the model's A_2 over all valid lags. Coarse
    scan of ``finite["nodes"]``, then bisection of the largest sign change in log L_V;
    ``below``: even the smallest node gives too much variance (lags not inertial).
    ``table`` is the model's table at fixed cells
    (:meth:`cwproc.physics.atable.ATable.at_cells`), ``table_rows`` the rows of it to
    search. With ``start`` (a root per cell, for the small changes of
    :func:`delta_method_errors`) the scan covers ``start / 2 .. 2 start`` and fewer
    bisections reach the same bracket.
    """
    scale_grid = finite["scale_grid"]

    def residual(big_l: np.ndarray) -> np.ndarray:
        k = big_l.shape[1]
        _, f2 = table.evaluate(np.broadcast_to(big_l, (dc.shape[0], k)), table_rows, a1=False)
        f2 = f2 * cell_sector[:, None, :]
        eps_l, noise_l, _ = fit_structure_function(dc[:, None, :], f2, vc[:, None, :], prior)
        through = _interp_log_scale(scale_grid, passed, np.broadcast_to(big_l, (dc.shape[0], k)))
        with np.errstate(invalid="ignore", divide="ignore"):
            model_var = np.log(eps_l ** (2 / 3) * through)
            measured = np.log(var_c[:, None] - np.nan_to_num(noise_l, nan=0.0) ** 2)
        return np.broadcast_to(model_var - measured, (dc.shape[0], k))

    if start is None:
        nodes = np.broadcast_to(finite["nodes"], (dc.shape[0], finite["nodes"].size))
        steps = _BISECTIONS
    else:
        nodes = start[:, None] * np.array([0.5, 1.0, 2.0])
        steps = _BISECTIONS_NEAR
    resid = residual(nodes)
    sign_change = (resid[:, :-1] < 0) & (resid[:, 1:] >= 0)
    has_root = sign_change.any(axis=1)
    last = nodes.shape[1] - 2 - np.argmax(sign_change[:, ::-1], axis=1)
    cells = np.arange(last.size)
    log_lo, log_hi = np.log(nodes[cells, last]), np.log(nodes[cells, last + 1])
    r_lo = resid[np.arange(last.size), last]
    r_hi = resid[np.arange(last.size), last + 1]
    for _ in range(steps):  # fixed count: each step halves every bracket
        mid = 0.5 * (log_lo + log_hi)
        r_mid = residual(np.exp(mid)[:, None])[:, 0]
        upper = r_mid >= 0
        log_hi = np.where(upper, mid, log_hi)
        r_hi = np.where(upper, r_mid, r_hi)
        log_lo = np.where(upper, log_lo, mid)
        r_lo = np.where(upper, r_lo, r_mid)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.clip(np.nan_to_num(r_lo / (r_lo - r_hi), nan=0.5), 0.0, 1.0)
    root = np.exp(log_lo + frac * (log_hi - log_lo))
    below = ~has_root & np.all(resid > 0, axis=1)
    return root, has_root, below


def _retrieve(
    fixed: dict, d: np.ndarray, var_raw: np.ndarray, near: np.ndarray | None = None
) -> dict:
    """eps (methods 1 and 2), sigma_e, sigma_V^2 and L_V of every cell from D and the variance.

    The least squares of Smalikho (2020), eq. 4 over all valid lags with the cell's
    A-functions (:func:`fit_structure_function`); with a finite-outer-scale model, where
    a length exceeds :data:`INERTIAL_FRACTION` of the inertial L_V, the A-functions at the
    root of the variance condition (:func:`_outer_scale_root`). A pure function of ``(d,
    var_raw)`` given ``fixed`` (the A-functions, tables, noise prediction, ...), so that
    :func:`delta_method_errors` can differentiate it; ``near`` (that function's base
    roots, NaN where the finite-outer-scale fit was not used) fixes the cells of that
    fit and starts its root search there.
    """
    a1, a2 = fixed["a1"].copy(), fixed["a2"].copy()
    valid, prior, c_model = fixed["valid"], fixed["noise_pred"], fixed["c_model"]
    shape = d.shape[:2]

    def solve() -> tuple:
        e1, _, _ = fit_structure_function(d, a1, valid, prior)
        efit, noise, fitted = fit_structure_function(d, a2, valid, prior)
        return e1, efit, noise, fitted

    e1, efit, noise, fitted = solve()
    sigma2 = var_raw - np.nan_to_num(noise, nan=0.0) ** 2 + efit ** (2 / 3) * fixed["loss"]
    with np.errstate(invalid="ignore", divide="ignore"):
        l_v = np.where(sigma2 > 0, c_model * np.abs(sigma2) ** 1.5 / efit, np.nan)
    too_small = np.zeros(shape, dtype=bool)
    finite_used = np.zeros(shape, dtype=bool)
    root_cell = np.full(shape, np.nan)
    finite = fixed["finite"]
    if finite is not None:
        passed_fraction = np.full(shape, np.nan)
        need = np.isfinite(l_v) & (finite["longest"] > INERTIAL_FRACTION * l_v) & ~fixed["exact"]
        if near is not None:
            need = np.isfinite(near)
        sector = fixed["sector"]
        for key, (rows, _) in fixed["groups"].items():  # one table per configuration
            ti, hi_ = np.nonzero(need & rows[:, None])
            if ti.size == 0:
                continue
            table, rank = fixed["cell_tables"][key]
            cells = rank[ti] * shape[1] + hi_
            passed = finite["passed"][ti, hi_]
            root, use, below = _outer_scale_root(
                table,
                cells,
                finite,
                sector[ti, hi_],
                passed,
                d[ti, hi_],
                valid[ti, hi_],
                var_raw[ti, hi_],
                prior[ti, hi_][:, None],
                None if near is None else near[ti, hi_],
            )
            if np.any(use):
                tu, hu = ti[use], hi_[use]
                g1, g2 = table.evaluate(root[use][:, None], cells[use])
                a1[tu, hu] = g1[:, 0]
                a2[tu, hu] = g2[:, 0] * sector[tu, hu]
                finite_used[tu, hu] = True
                root_cell[tu, hu] = root[use]
                scale_grid = finite["scale_grid"]
                through = _interp_log_scale(scale_grid, passed[use], root[use][:, None])[:, 0]
                total = np.interp(np.log(root[use]), np.log(scale_grid), finite["full_var"])
                passed_fraction[tu, hu] = through / total
            too_small[ti[below], hi_[below]] = True
        e1, efit, noise, fitted = solve()
        sigma2 = np.where(
            finite_used,
            (var_raw - np.nan_to_num(noise, nan=0.0) ** 2) / passed_fraction,
            var_raw - np.nan_to_num(noise, nan=0.0) ** 2 + efit ** (2 / 3) * fixed["loss"],
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            l_v = np.where(sigma2 > 0, c_model * np.abs(sigma2) ** 1.5 / efit, np.nan)
    return {
        "a1": a1,
        "a2": a2,
        "e1": e1,
        "efit": efit,
        "noise": noise,
        "fitted": fitted,
        "sigma2": sigma2,
        "l_v": l_v,
        "too_small": too_small,
        "finite_used": finite_used,
        "root": root_cell,
    }


def delta_method_errors(
    fixed: dict, d: np.ndarray, var_raw: np.ndarray, cov: np.ndarray, base: dict
):
    """Standard errors of eps, sigma_V^2 and L_V by the delta method (m2 s-3, m2 s-2, m).

    The estimates are one function ``f(s)`` (:func:`_retrieve`) of the block-mean
    statistics ``s = (D_L(1), ..., D_L(L), variance of V'_L)``: eps and L_V fitted
    together, so the scatter of the fitted L_V enters the error of eps through the
    A-functions. ``SE(f) = sqrt(g^T C g)``, ``C`` the covariance of ``s`` from the
    scatter over the block's scans (``statistics_covariance`` of
    :func:`cwproc.stages.structure.block_statistics`) and ``g`` the gradient of ``f`` by
    forward differences of one standard error of each component (a secant over the
    range the sampling error spans).
    """
    n_l = d.shape[-1]
    stats = np.concatenate([d, var_raw[..., None]], axis=-1)
    step = np.sqrt(np.abs(np.diagonal(cov, axis1=-2, axis2=-1)))
    step = np.where(np.isfinite(step) & (step > 0), step, 1e-3 * np.abs(stats))
    keys = ("efit", "sigma2", "l_v")
    grad = {k: np.zeros(stats.shape) for k in keys}
    for k in range(n_l + 1):
        s_k = stats.copy()
        s_k[..., k] += step[..., k]
        res = _retrieve(fixed, s_k[..., :n_l], s_k[..., n_l], near=base["root"])
        for key in keys:
            with np.errstate(invalid="ignore"):
                grad[key][..., k] = (res[key] - base[key]) / step[..., k]
    out = []
    for key in keys:
        g = grad[key]
        with np.errstate(invalid="ignore"):
            out.append(np.sqrt(np.einsum("...i,...ij,...j->...", g, cov, g)))
    return tuple(out)


def estimate_epsilon(
    sf: xr.Dataset,
    *,
    probe: Any,
    lag_number: int,
    model: str,
    min_pairs: int = 100,
    n_outer_scales: int = 7,
    table_options: dict | None = None,
    fit_noise: bool = True,
    noise_window_blocks: int = NOISE_WINDOW_BLOCKS,
) -> xr.Dataset:
    """Dissipation rate (methods 1 and 2), noise, variance and integral scale.

    See the module docstring for the equations, the finite-outer-scale rule and the
    flags.

    Parameters
    ----------
    sf : xarray.Dataset
        Output of :func:`cwproc.stages.structure.azimuth_structure_function`.
    probe : PulsedProbe or CWProbe
        Probe volume (:func:`cwproc.pipeline.probe_from_config`).
    lag_number : int
        l of Smalikho (2020), eq. 5 (>= 2); the largest available lag is used when
        ``l dtheta`` exceeds the structure function's lags (recorded in the attrs).
    model : {"inertial", "von_karman", "exponential"}
        Spectrum model of the A-functions and of L_V (Banakh et al. (1999), eqs. 17, 19).
    min_pairs : int
        Fewest ray pairs at lags 1 and l for an estimate (flag 1 below).
    n_outer_scales : int
        Geometric nodes of L_V scanned for the root of the variance condition
        (finite-outer-scale models) before the bisection refines it.
    table_options : dict, optional
        Keyword arguments of :func:`cwproc.physics.atable.get_a_table` (``cache_dir``,
        ``height_range_m``, ``mu_max``, ``outer_scale_range_m``).
    fit_noise : bool
        Fit the noise term ``2 sigma_e^2`` in the exact cw fit (:func:`fit_correlation_shape`);
        without it ``sigma_e`` is 0 there (noise-free data, e.g. the exact V_D).
    noise_window_blocks : int
        cw fit: the noise variance is the median of the per-block estimates over this
        many neighbouring blocks at the same height (:func:`running_nanmedian`), and each
        block refitted with it fixed; 1 keeps each block's own estimate.

    Returns
    -------
    xarray.Dataset
        Turbulence product (dims ``time``, ``height``, ``lag``).
    """
    if model not in spectra.MODELS:
        raise ValueError(f"unknown model {model!r}; choose one of {', '.join(spectra.MODELS)}")
    if lag_number < 2:
        raise ValueError("lag_number must be >= 2 (Smalikho (2020), eq. 5)")
    options = dict(table_options or {})
    if "height_range_m" not in options:
        options["height_range_m"] = table_height_range(sf["height"].values)
    options.setdefault("swept", bool(int(sf.attrs.get("swept_rays", 1))))
    d = sf["structure_function"].transpose("time", "height", "lag").values.astype(float)
    pairs = sf["n_pairs"].transpose("time", "height", "lag").values
    n_t, n_h, n_l = d.shape
    height = sf["height"].values.astype(float)
    phi = sf["elevation"].values.astype(float)
    dtheta = sf["azimuth_step"].values.astype(float)
    t_scan = sf["scan_period"].values.astype(float)
    u_mean = sf["wind_speed"].transpose("time", "height").values.astype(float)
    var_raw = sf["radial_velocity_variance"].transpose("time", "height").values.astype(float)
    if "range" in sf.coords:
        rng = sf["range"].values.astype(float)
    else:
        rng = height / np.sin(np.deg2rad(np.nanmean(phi)))

    # R' = h / tan(phi) (Smalikho (2020), eq. 3) at the probe centre: R_c cos(phi), R_c
    # the centre range of the probe (the focus range, or less for a cw Lorentzian)
    centre = np.asarray(probe.centre_range(rng), dtype=float)
    radius = centre[None, :] * np.cos(np.deg2rad(phi))[:, None]
    dy = np.deg2rad(dtheta)[:, None] * radius
    v_s = 2 * np.pi * radius / t_scan[:, None]
    mu = u_mean / v_s
    mu_eval = np.nan_to_num(mu, nan=0.0)
    range_th = np.broadcast_to(rng[None, :], (n_t, n_h))

    lag_used = int(min(lag_number, n_l))
    flag = np.zeros((n_t, n_h), dtype=np.int16)
    lags = np.arange(1, n_l + 1, dtype=float)
    a1 = np.full(d.shape, np.nan)
    a2 = np.full(d.shape, np.nan)
    # one pair of A-tables per (elevation, azimuth step), evaluated for all blocks at once
    key_phi = np.round(phi, 3)
    key_dth = np.round(dtheta, 4)
    groups = {}
    # sectors and gaps: A_2 over the azimuths present relative to the full circle
    sector = np.ones(d.shape)
    weights = pair_weights(sf)
    if n_l >= 2:
        for p, q in {(p, q) for p, q in zip(key_phi, key_dth, strict=True) if np.isfinite(p + q)}:
            rows = (key_phi == p) & (key_dth == q)
            groups[(p, q)] = (rows, _tables(probe, float(p), float(q), n_l, model, options))
            a1[rows], a2[rows], sector[rows] = _sector_evaluate(
                groups[(p, q)][1][0], lags, height, mu_eval[rows], weights[rows]
            )

    valid_lag = pairs >= min_pairs
    scans = sf["n_scans"].values.astype(float) if "n_scans" in sf else np.full(n_t, np.nan)
    requested = float(
        sf["structure_function"].attrs.get("n_scans_per_block", np.nanmax(scans, initial=0.0))
    )
    partial = scans < MIN_BLOCK_FRACTION * requested
    flag |= np.where(partial[:, None], FLAG_PARTIAL_BLOCK, 0).astype(np.int16)
    few = ~(valid_lag[..., 0] & valid_lag[..., lag_used - 1])
    flag |= np.where(few, FLAG_TOO_FEW_PAIRS, 0).astype(np.int16)
    # the loss depends on (dy, range) only: compute it once per distinct pair
    # step-stare rays are not swept: no transverse averaging in the variance (eq. 20)
    dy_filter = dy if options["swept"] else np.where(np.isfinite(dy), 0.0, np.nan)
    pairs_dr = np.stack([np.round(dy_filter, 6).ravel(), np.round(range_th, 6).ravel()], axis=1)
    uniq, inverse = np.unique(np.nan_to_num(pairs_dr, nan=-1.0), axis=0, return_inverse=True)
    loss_u = np.where(
        uniq[:, 0] >= 0, averaging_loss(probe, np.abs(uniq[:, 0]), np.abs(uniq[:, 1])), np.nan
    )
    loss = loss_u[inverse.ravel()].reshape(dy.shape)
    c_model = spectra.integral_scale_coefficient("exponential" if model == "inertial" else model)
    noise_pred = predicted_noise(sf, probe)

    exact = np.zeros((n_t, n_h), dtype=bool)
    if model != "inertial" and is_cw_probe(probe) and n_l >= 2:
        with np.errstate(invalid="ignore"):
            exact = (mu <= CW_EXACT_MU_MAX) & np.isfinite(phi + dtheta)[:, None]
    finite = None
    if model != "inertial" and groups:
        # time between scan starts over T_scan (1: consecutive full circles)
        interval = np.ones(n_t)
        if "scan_interval" in sf:
            with np.errstate(invalid="ignore", divide="ignore"):
                interval = sf["scan_interval"].values.astype(float) / t_scan
            interval = np.where(np.isfinite(interval) & (interval > 0), interval, 1.0)
        finite = _finite_scale_inputs(
            probe,
            model,
            options,
            uniq,
            inverse,
            scans,
            radius,
            phi,
            range_th,
            mu_eval,
            n_outer_scales,
            weights,
            interval,
            dtheta,
        )
        probe_len = np.broadcast_to(np.asarray(probe.length_scale_m(range_th), float), (n_t, n_h))
        finite["longest"] = np.maximum(n_l * dy * (1 + mu_eval), probe_len)
    fixed = {
        "a1": a1,
        "a2": a2,
        "sector": sector,
        "valid": valid_lag,
        "noise_pred": noise_pred,
        "loss": loss,
        "c_model": c_model,
        "groups": groups,
        "cell_tables": {  # the model's tables at each group's cells (rows x heights)
            key: (
                tables[1].at_cells(lags, np.tile(height, rows.sum()), mu_eval[rows].ravel()),
                np.cumsum(rows) - 1,
            )
            for key, (rows, tables) in groups.items()
            if finite is not None
        },
        "exact": exact,
        "finite": finite,
    }
    res = _retrieve(fixed, d, var_raw)
    a1, a2 = res["a1"], res["a2"]
    e1, efit, noise, fitted = res["e1"], res["efit"], res["noise"], res["fitted"]
    sigma2, l_v, too_small = res["sigma2"], res["l_v"], res["too_small"]
    finite_used = res["finite_used"]
    e2 = efit

    sf_model_exact = np.full(d.shape, np.nan)
    if np.any(exact):
        fit = _fit_exact_cells(
            probe,
            d,
            valid_lag,
            var_raw,
            scans,
            exact,
            range_th,
            phi,
            dtheta,
            model,
            c_model,
            fit_noise,
            noise_window_blocks,
        )
        lo, hi = options.get("outer_scale_range_m", (10.0, 3000.0))
        for rows, (_, table) in groups.values():  # A-functions at L_V: method 1, the ratio
            sel = exact & rows[:, None] & np.isfinite(fit["integral_scale"])
            ti, hi_ = np.nonzero(sel)
            g1, g2 = _evaluate(
                table,
                lags[None, :],
                height[hi_][:, None],
                mu_eval[ti, hi_][:, None],
                np.clip(fit["integral_scale"][ti, hi_], lo, hi)[:, None],
            )
            a1[ti, hi_], a2[ti, hi_] = g1, g2 * sector[ti, hi_]
        e1, _, _ = fit_structure_function(d, a1, valid_lag, noise_pred)
        e2 = np.where(exact, fit["epsilon"], e2)
        efit = np.where(exact, fit["epsilon"], efit)
        noise = np.where(exact, fit["noise_std"], noise)
        # the pooled cw intercept: a zero means no intercept was fitted, not a measured 0
        fitted = np.where(exact, fit["noise_std"] > 0, fitted)
        noise = np.where(exact & ~fitted, np.nan, noise)
        sigma2 = np.where(exact, fit["velocity_variance"], sigma2)
        l_v = np.where(exact, fit["integral_scale"], l_v)
        too_small |= exact & fit["below_range"]
        sf_model_exact = fit["structure_function_model"]

    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = ((a2[..., lag_used - 1] - a2[..., 0]) / (a1[..., lag_used - 1] - a1[..., 0])) ** 1.5

    # inertial form: the largest separation L dy (1 + mu) must stay below L_V (Smalikho
    # (2020), after eq. 4). The finite-outer-scale A-functions hold at any separation: a
    # limit on the fitted L_V there only dropped the blocks whose sampling error made
    # L_V small (eps high), and biased the mean eps of 24-ray VADs 8-16 % low
    beyond = too_small
    if model == "inertial":
        beyond = beyond | (np.isfinite(l_v) & (n_l * dy * (1 + mu_eval) > l_v))
    flag |= np.where(beyond, FLAG_BEYOND_INERTIAL, 0).astype(np.int16)
    failed = ~np.isfinite(e2) | ~np.isfinite(mu) | (n_l < 2)
    flag |= np.where(failed, FLAG_FIT_FAILED, 0).astype(np.int16)
    bad = (
        flag & (FLAG_TOO_FEW_PAIRS | FLAG_BEYOND_INERTIAL | FLAG_FIT_FAILED | FLAG_PARTIAL_BLOCK)
    ) > 0
    m1_invalid = ~(ratio <= METHOD1_RATIO_LIMIT)
    flag |= np.where(m1_invalid & ~bad, FLAG_METHOD1_INVALID, 0).astype(np.int16)
    few_fit = valid_lag.sum(axis=-1) < 2
    predicted_used = ~fitted & ~few_fit & ~bad
    flag |= np.where(predicted_used, FLAG_NOISE_PREDICTED, 0).astype(np.int16)
    arrays = _product_arrays(
        e1, e2, efit, noise, sigma2, l_v, bad, few_fit, exact, a2, sf_model_exact
    )
    eps_se, sigma2_se, scale_se = standard_errors(
        sf,
        lag_used,
        d,
        arrays["epsilon"],
        arrays["velocity_variance"],
        var_raw - np.nan_to_num(noise, nan=0.0) ** 2,
        arrays["integral_scale"],
    )
    if "statistics_covariance" in sf:
        cov = sf["statistics_covariance"].transpose("time", "height", ...).values.astype(float)
        delta = delta_method_errors(fixed, d, var_raw, cov, res)
        eps_se, sigma2_se, scale_se = (
            np.where(exact | ~np.isfinite(v), old, new)
            for old, new, v in zip(
                (eps_se, sigma2_se, scale_se),
                delta,
                (arrays["epsilon"], arrays["velocity_variance"], arrays["integral_scale"]),
                strict=True,
            )
        )

    dims = ("time", "height")
    out = xr.Dataset(
        {
            "structure_function": sf["structure_function"],
            "n_pairs": sf["n_pairs"],
            **{
                k: (("time", "height", "lag") if v.ndim == 3 else dims, v)
                for k, v in arrays.items()
            },
            "noise_std_predicted": (dims, noise_pred),
            "epsilon_standard_error": (dims, eps_se),
            "velocity_variance_standard_error": (dims, sigma2_se),
            "integral_scale_standard_error": (dims, scale_se),
            "wind_speed": sf["wind_speed"],
            "n_scans": sf["n_scans"],
            "turbulence_flag": (dims, flag),
        },
        coords={
            **sf.coords,
            "scan_speed": (dims, v_s),
            "transverse_resolution": (dims, dy),
            "mu": (dims, mu),
        },
    )
    common = {
        "model": model,
        "lag_number": lag_used,
        "lag_number_requested": int(lag_number),
        "min_pairs": int(min_pairs),
        "probe": repr(probe),
    }
    out["integral_scale"].attrs["finite_outer_scale_cells"] = int(finite_used.sum())
    out["integral_scale"].attrs["exact_cw_model_cells"] = int(exact.sum())
    out["epsilon"].attrs.update(
        common,
        method="least squares of Smalikho (2020), eq. 4 over all valid lags with A_2 of "
        "eq. 15 (method 2; eq. 5 is its two-lag case); finite-outer-scale "
        f"A-functions where a length exceeds {INERTIAL_FRACTION:g} L_V; cw cells with "
        f"mu <= {CW_EXACT_MU_MAX:g}: least squares of D_L with the exact B_D of Banakh et "
        "al. (1999), eqs. 15-17, eps = c sigma_V^3 / L_V (eq. 19)",
        references=SMALIKHO_2020 + ", eqs. 4-5, 15-20",
    )
    out["epsilon_method1"].attrs.update(
        common,
        method="least squares of Smalikho (2020), eq. 4 with A_1 = A_perp (method 1); "
        "written wherever "
        f"computable, flag 4 where eps1/eps2 > {METHOD1_RATIO_LIMIT}",
    )
    out["epsilon_fit"].attrs.update(
        common, method="least squares of eps^(2/3) A_2 + 2 sigma_e^2 over all lags"
    )
    out["structure_function_model"].attrs.update(
        common,
        method="eps_fit^(2/3) A_2(l dy) + 2 sigma_e^2 with the A-functions of the cell "
        "(Smalikho (2020), eq. 4)",
    )
    out["noise_std"].attrs.update(
        method="intercept 2 sigma_e^2 of the least-squares fit, Smalikho (2020), eq. 4, "
        "where it exceeds twice its standard error or is precise and within a factor "
        f"{NOISE_PLAUSIBLE:g} of the prediction; elsewhere (flag 32) the prediction "
        "noise_std_predicted, used in the fit; NaN when neither exists"
    )
    out["velocity_variance"].attrs.update(
        method="variance of V'_L minus sigma_e^2 divided by the probe-passed share of "
        "sigma_V^2 (Smalikho (2020), eqs. 16-20; inertial form: plus the averaging loss "
        "eps^(2/3) int int Phi (1 - H_par H_perp)); cw cells: the passed share b_0 less "
        "the share the N-scan VAD fit removes, from the exact B_D"
    )
    out["integral_scale"].attrs.update(
        method=f"L_V = {c_model:.4g} sigma_V^3 / eps",
        correlation_model="exponential (Banakh et al. (1999), eq. 17)"
        if model in ("inertial", "exponential")
        else "von Karman",
        references=BANAKH_1999 + ", eq. 19",
    )
    return out
