"""Standard errors of eps, sigma_V^2 and L_V (stage ``epsilon``).

From the scatter of the block's statistics over its scans: the delta method through the
whole fit (:func:`covariance_errors`, :mod:`cwproc.physics.delta_method`) where the
structure function carries their covariance, else the first-order form (:func:`standard_errors`).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.physics.delta_method import delta_method_errors
from cwproc.physics.removed_share import MAX_SECTOR_RAYS
from cwproc.physics.scan_transport import transport_mu, transport_weight
from cwproc.stages.epsilon.cells import Cells
from cwproc.stages.epsilon.outer_scale import fit_cells
from cwproc.stages.epsilon.records import CellEstimates, FitSetup
from cwproc.tables.removed_share import mean_removed_share
from cwproc.tables.scan_factor import circle_variance_factor


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
    without ``statistics_covariance``; elsewhere :func:`covariance_errors` replaces it
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


def covariance_errors(
    setup: FitSetup, d: np.ndarray, var_raw: np.ndarray, cov: np.ndarray, base: CellEstimates
) -> tuple[np.ndarray, ...]:
    """Standard errors of eps, sigma_V^2 and L_V by the delta method (m2 s-3, m2 s-2, m).

    The estimates are one function ``f(s)``
    (:func:`cwproc.stages.epsilon.outer_scale.fit_cells`) of the block-mean statistics
    ``s = (D_L(1), ..., D_L(L), variance of V'_L)``: eps and L_V fitted together, so
    the scatter of the fitted L_V enters the error of eps through the
    A-functions. ``SE(f) = sqrt(g^T C g)``, ``C`` the covariance of ``s`` from the
    jackknife over the block's scans (``statistics_covariance`` of
    :func:`cwproc.physics.block_stats.block_statistics`) and ``g`` the gradient of ``f`` by
    central differences of three tenths of a standard error either side of each
    component (:data:`cwproc.physics.delta_method.STEP_FRACTION`).

    The effective number of independent samples is that of the scans, never of the
    rays: ``C`` is the empirical covariance of the per-scan vector over the block's
    ``N`` scans, so the correlation of the lags within a scan (sectors included) is in
    it as measured, and ``N_eff = N / (1 + 2 sum_k (1 - k/N) rho_k)`` (the variance of a
    mean of correlated samples, Bayley and Hammersley (1946)) with ``rho_k`` the
    correlation of the per-scan statistics ``k`` scans apart, which the jackknife takes
    as 0. The scan geometry gives ``rho_k`` exactly
    (:func:`cwproc.physics.scan_correlation.correlation_inflation`, checked against the
    exact covariance of the generator's swept, probe-averaged rays): in 90 and 180 deg
    sectors at mu 0.5-1, with and without fly-back, the scans are carried 1-3 ``L_V``
    apart, the ``D_L`` factor is 1.000-1.01 (the differences of close rays decorrelate
    within tens of metres) and only the variance's, 1.04-1.6 of the per-scan scatter,
    matters; the variance's jackknife refits the block-mean wind without each scan and
    is already that conservative (scaled by the factor, se/sd of sigma_V^2 and L_V of the
    90 deg sector at mu 0.5 went from 1.16-1.24 to 1.30-1.34), so ``C`` is kept. Measured
    se/sd (eps / sigma_V^2 / L_V, 100 blocks, exact statistics): 90 deg sector at mu 0.5,
    1, 2 with a 3 s fly-back 1.10/1.17/1.24, 0.91/0.91/0.87, 0.97/1.02/0.95, back to back
    1.01/1.18/1.19, 0.94/0.98/0.94, 0.97/1.04/1.01 (``bench_epsilon_accuracy.py --case
    sector [--sector-fly-back 0]``); at mu 1 on two more seeds each of 90 and 180 deg,
    with and without fly-back, 0.78-1.11 / 0.91-1.14 / 0.81-1.10
    (``bench_epsilon_noise.py --row sector``).
    """
    n_l = d.shape[-1]
    stats = np.concatenate([d, var_raw[..., None]], axis=-1)
    near_parts: dict = {}  # the L_V-only parts at the base roots' first nodes, once

    def estimates(s: np.ndarray) -> dict[str, np.ndarray]:
        near, slope = base.root, base.root_slope
        fit = fit_cells(setup, s[..., :n_l], s[..., n_l], near, False, slope, near_parts)
        return fit.arrays()

    keys = ("efit", "sigma2", "l_v")
    return delta_method_errors(estimates, stats, cov, base.arrays(), keys)


def block_errors(
    sf: xr.Dataset,
    lag_used: int,
    setup: FitSetup,
    d: np.ndarray,
    var_raw: np.ndarray,
    arrays: dict[str, np.ndarray],
    noise: np.ndarray,
    base: CellEstimates,
    cov: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standard errors of eps, sigma_V^2 and L_V (m2 s-3, m2 s-2, m) of the product.

    :func:`covariance_errors` where ``sf`` carries ``statistics_covariance`` (``cov``,
    :func:`cwproc.stages.epsilon.cells.statistics_covariance`), except
    in the exact cw cells (``setup.exact``) and where an estimate is NaN, which keep
    :func:`standard_errors`. ``base`` is the result of
    :func:`cwproc.stages.epsilon.outer_scale.fit_cells` at the measured statistics,
    ``noise`` the sigma_e of the product (m s-1).
    """
    values = (arrays["epsilon"], arrays["velocity_variance"], arrays["integral_scale"])
    first = standard_errors(
        sf,
        lag_used,
        d,
        values[0],
        values[1],
        var_raw - np.nan_to_num(noise, nan=0.0) ** 2,
        values[2],
    )
    if cov is None:
        return first
    delta = covariance_errors(setup, d, var_raw, cov, base)
    return tuple(
        np.where(setup.exact | ~np.isfinite(v), old, new)
        for old, new, v in zip(first, delta, values, strict=True)
    )


def correlated_scans_covariance(
    sf: xr.Dataset, cells: Cells, cov: np.ndarray | None, l_v: np.ndarray, model: str
) -> np.ndarray | None:
    """``cov`` with the variance's entries scaled for the correlation of consecutive scans.

    The refit jackknife of the variance of ``V'_L``
    (:func:`cwproc.physics.block_stats.jackknife_covariance`) takes the scans as
    independent. In the field the wind carries, consecutive full circles share eddies
    where the end of one scan and the start of the next see nearly the same air: at ``mu
    = U/V_s`` near 1 the beam moves with the wind at one azimuth (the cusp of its path
    through the field), and when that azimuth is the seam between two scans they sample
    the same air over several rays. The factor ``f`` by which the variance of the block
    mean exceeds the jackknife's expectation, over the same ratio with the scans
    independent (:func:`cwproc.tables.scan_factor.circle_variance_factor`: the
    Gaussian fourth moments of the rays of point beams at their times, exact for the
    jackknife as it is computed, the wind refitted without each scan), multiplies the
    variance's variance and ``sqrt(f)`` its covariances with the ``D_L``. Full circles of
    up to ``MAX_SECTOR_RAYS`` rays (the step-stare VADs), ``R'/L_V`` of the block's
    fitted ``L_V`` (``l_v``, m), ``mu`` of the transport (the measured one less its
    turbulent bias), the block's start angle (``scan_start_angle``; without it the mean
    over the angles). 24-ray VAD, ``mu`` 1, ``R'/L_V`` 0.71: ``f`` 1.02-1.2 over the start
    angle, mean 1.07; 1.03-1.07 at ``mu`` 3. The ``D_L`` (differences of close rays)
    are left alone: their factors are 1.00-1.04. Sectors and longer circles keep ``cov``
    (the sectors' variance jackknife already read 0.9-1.2 of the scatter).
    """
    if cov is None:
        return None
    n_t, n_h = cells.var_raw.shape
    with np.errstate(invalid="ignore", divide="ignore"):
        rays = np.rint(360.0 / cells.dtheta)
    circle = ~cells.partial & np.isfinite(rays)[:, None] & (rays <= MAX_SECTOR_RAYS)[:, None]
    circle &= np.isfinite(l_v) & (l_v > 0)
    if not circle.any():
        return cov
    t_idx, h_idx = np.nonzero(circle)
    phi, model_c = float(np.nanmedian(cells.phi)), str(model)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = cells.radius[t_idx, h_idx] / l_v[t_idx, h_idx]
    scans = np.where(np.isfinite(cells.scans), cells.scans, 1.0)[t_idx]
    model_t = model_c if model_c != "inertial" else "von_karman"
    mu_m, var, v_s = (a[t_idx, h_idx] for a in (cells.mu_eval, cells.var_raw, cells.v_s))
    # the transport must be measured: the turbulent scatter of mu at rest (rms of each
    # horizontal component of the block-mean wind over V_s, transport_mu) ramps it in
    # from 2 to 4 of those
    share = mean_removed_share(np.clip(ratio, 1e-3, None)[:, None], phi, model_t, 0.0)
    mu_t = transport_mu(mu_m, share, var, v_s, scans, phi)[:, 0]
    weight = transport_weight(mu_m, share, var, v_s, scans, phi)[:, 0]
    angle = np.full(t_idx.size, np.nan)
    if "scan_start_angle" in sf:
        angle = sf["scan_start_angle"].transpose("time", "height").values[t_idx, h_idx]
    factor = circle_variance_factor(
        rays[t_idx], scans, cells.interval[t_idx], mu_t, ratio, angle, phi, model_c
    )
    root = np.ones((n_t, n_h))
    root[t_idx, h_idx] = np.sqrt(1.0 + weight * (factor - 1.0))
    out = cov.copy()
    out[..., -1, :] *= root[..., None]
    out[..., :, -1] *= root[..., None]
    return out
