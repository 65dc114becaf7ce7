"""Exact lag model of a cw probe: the two-beam B_D of Banakh et al. (1999), eqs. 15-17.

A focused cw probe is hundreds of metres long, so the azimuth structure function's
shape over the lags depends on ``L_V``: ``D_L(l) = 2 sigma_V^2 [b_0(L_V) - b_l(L_V)]
+ 2 sigma_e^2`` with ``b_k`` the correlation of the probe-averaged radial velocities of
two beams ``k`` steps apart (:class:`ExactLagModel`, :func:`exact_lag_model`), fitted
over a grid of ``L_V`` (:func:`fit_correlation_shape`); the share of sigma_V^2 the sine
(VAD) fit removes is ``tr(H B_D)/M`` (:func:`hat_trace_per_ray`,
:func:`vad_removed_variance`). Pure numpy.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from cwproc.physics import spectra
from cwproc.physics.correlation import ProbeQuadrature, ScanGeometry, circulant_correlation_row
from cwproc.physics.cw_probe import lorentzian_quadrature


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
    cwproc.physics.correlation.ProbeQuadrature
    """

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
    (:func:`cwproc.physics.correlation.circulant_correlation_row`) with the probe's weighting
    (:func:`probe_quadrature`). On the cw lidar of Banakh et al. (1999) with N = 10 it is
    4-5 % of the passed variance. :func:`cwproc.stages.epsilon.estimate_epsilon` takes the
    same share from :class:`ExactLagModel` for cw cells; this function gives it per eps^(2/3) on the
    spectral route (``passed`` from :func:`cwproc.physics.probe_variance.passed_variance`)
    and checks the two against the simulator. Wind transport (mu = U/V_s) is neglected here
    (mu <= 0.09 for that lidar).

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
        :func:`cwproc.physics.probe_variance.passed_variance` of the cells on
        ``outer_scales_m``, (cells, scales).

    Returns
    -------
    numpy.ndarray
        Shape ``(cells, outer scales)``.
    """

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
def exact_lag_model_cached(*configuration: Any) -> ExactLagModel:
    """:func:`exact_lag_model` on :data:`EXACT_SCALES`, memoised per configuration.

    ``configuration``: ``(probe, range_m, elevation_deg, azimuth_step_deg, n_lags,
    model)``, the positional arguments of :func:`exact_lag_model` (hashable).

    About 0.5 s per range; a batch or a day of cw files re-uses the same few ranges. The
    arrays are read-only.
    """
    lm = exact_lag_model(*configuration)
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


def variance_root(
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
