"""The cells (block, height) of a structure function: statistics and sampling geometry.

``R' = h / tan(phi)`` at the probe centre, ``dy = dtheta R'``, ``V_s = 2 pi R'/T_scan``
and ``mu = U/V_s`` (Smalikho (2020), eq. 3), the statistics ``D_L`` and the variance of
``V'_L`` as arrays, the azimuth weights of the pairs present, and the noise predicted
from the SNR (the prior of the noise term of Smalikho (2020), eq. 4).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from cwproc.physics import noise
from cwproc.physics.atable_interp import N_BINS
from cwproc.physics.exact_lag import is_cw_probe
from cwproc.physics.removed_share import partial_circle


@dataclass(frozen=True)
class Cells:
    """Statistics and sampling geometry of the cells ``(time, height)``.

    Attributes
    ----------
    d : (time, height, lag) structure function ``D_L`` (m2 s-2).
    pairs : (time, height, lag) ray pairs per lag.
    var_raw : (time, height) variance of ``V'_L`` (m2 s-2).
    height : (height,) heights (m).
    phi, dtheta, t_scan : (time,) elevation (deg), azimuth step (deg), scan period (s).
    range_m : (time, height) distance of the probe from the lidar (m).
    radius : (time, height) ``R' = R_c cos(phi)`` (m), ``R_c`` the probe centre's range.
    dy, v_s, mu : (time, height) ``dtheta R'`` (m), ``2 pi R'/T_scan`` (m s-1), ``U/V_s``.
    mu_eval : ``mu`` with NaN as 0 (for evaluations).
    scans : (time,) scans per block; ``requested`` the scans per block asked for.
    interval : (time,) time between scan starts over ``T_scan`` (1: consecutive circles).
    weights : (time, height, N_BINS) azimuth-node weights of the lag-1 pairs (the rays
        of the scan: sectors and gaps), NaN if unknown.
    lag_weights : (time, height, lag, N_BINS) the same for the pairs of each lag (their
        mean of ``A_2``), NaN if unknown.
    """

    d: np.ndarray
    pairs: np.ndarray
    var_raw: np.ndarray
    height: np.ndarray
    phi: np.ndarray
    dtheta: np.ndarray
    t_scan: np.ndarray
    range_m: np.ndarray
    radius: np.ndarray
    dy: np.ndarray
    v_s: np.ndarray
    mu: np.ndarray
    mu_eval: np.ndarray
    scans: np.ndarray
    requested: float
    interval: np.ndarray
    weights: np.ndarray
    lag_weights: np.ndarray

    @property
    def n_lags(self) -> int:
        """Lags of the structure function."""
        return self.d.shape[-1]

    @functools.cached_property
    def partial(self) -> np.ndarray:
        """``(time, height)``: the cells whose pairs leave out a sector (sector scans and
        gaps, :func:`cwproc.physics.removed_share.partial_circle` of ``weights`` and
        ``dtheta``); computed once, for the several parts of the fit that ask."""
        n_t, n_h = self.range_m.shape
        dtheta = np.broadcast_to(np.asarray(self.dtheta, float)[:, None], (n_t, n_h))
        return partial_circle(self.weights, dtheta)


def cell_inputs(sf: xr.Dataset, probe: Any) -> Cells:
    """The :class:`Cells` of a structure function (:mod:`cwproc.stages.structure`).

    Parameters
    ----------
    sf : xarray.Dataset
        Output of :func:`cwproc.stages.structure.azimuth_structure_function`.
    probe : PulsedProbe or CWProbe
        Probe volume; ``probe.centre_range`` gives the probe centre.
    """
    d = sf["structure_function"].transpose("time", "height", "lag").values.astype(float)
    n_t, n_h, _ = d.shape
    lag_weights = pair_weights(sf)
    height = sf["height"].values.astype(float)
    phi = sf["elevation"].values.astype(float)
    dtheta = sf["azimuth_step"].values.astype(float)
    t_scan = sf["scan_period"].values.astype(float)
    u_mean = sf["wind_speed"].transpose("time", "height").values.astype(float)
    if "range" in sf.coords:
        rng = sf["range"].values.astype(float)
    else:
        rng = height / np.sin(np.deg2rad(np.nanmean(phi)))
    # R' = h / tan(phi) (Smalikho (2020), eq. 3) at the probe centre: R_c cos(phi), R_c
    # the centre range of the probe (the focus range, or less for a cw Lorentzian)
    centre = np.asarray(probe.centre_range(rng), dtype=float)
    radius = centre[None, :] * np.cos(np.deg2rad(phi))[:, None]
    v_s = 2 * np.pi * radius / t_scan[:, None]
    mu = u_mean / v_s
    scans = sf["n_scans"].values.astype(float) if "n_scans" in sf else np.full(n_t, np.nan)
    requested = float(
        sf["structure_function"].attrs.get("n_scans_per_block", np.nanmax(scans, initial=0.0))
    )
    interval = np.ones(n_t)
    if "scan_interval" in sf:
        with np.errstate(invalid="ignore", divide="ignore"):
            interval = sf["scan_interval"].values.astype(float) / t_scan
        interval = np.where(np.isfinite(interval) & (interval > 0), interval, 1.0)
    return Cells(
        d=d,
        pairs=sf["n_pairs"].transpose("time", "height", "lag").values,
        var_raw=sf["radial_velocity_variance"].transpose("time", "height").values.astype(float),
        height=height,
        phi=phi,
        dtheta=dtheta,
        t_scan=t_scan,
        range_m=np.broadcast_to(rng[None, :], (n_t, n_h)),
        radius=radius,
        dy=np.deg2rad(dtheta)[:, None] * radius,
        v_s=v_s,
        mu=mu,
        mu_eval=np.nan_to_num(mu, nan=0.0),
        scans=scans,
        requested=requested,
        interval=interval,
        weights=lag_weights[:, :, 0, :],
        lag_weights=lag_weights,
    )


def pair_weights(sf: xr.Dataset) -> np.ndarray:
    """``(time, height, lag, node)`` azimuth-node weights of the pairs present, NaN if unknown.

    From ``pair_azimuth_weights`` of :func:`cwproc.stages.structure.azimuth_structure_function`
    (per lag); weights without a ``lag`` dimension (lag-1 pairs) serve every lag; NaN (the
    full circle is used) for a structure function without them.
    """
    n_l = sf.sizes["lag"]
    if "pair_azimuth_weights" not in sf:
        return np.full((sf.sizes["time"], sf.sizes["height"], n_l, N_BINS), np.nan)
    weights = sf["pair_azimuth_weights"]
    if "lag" not in weights.dims:
        weights = weights.expand_dims(lag=sf["lag"].values)
    return np.asarray(weights.transpose("time", "height", "lag", ...).values)


def predicted_noise(sf: xr.Dataset, probe: Any) -> np.ndarray:
    """``(time, height)`` sigma_e (m s-1) predicted from the block-median SNR.

    :func:`cwproc.physics.noise.velocity_noise_std` (Pearson et al. (2009), eq. 3) with
    the points per gate, pulses per ray and velocity resolution the reader put in the
    attributes; NaN for cw probes, without SNR or without those settings.
    """
    shape = (sf.sizes["time"], sf.sizes["height"])
    points = sf.attrs.get("points_per_gate")
    pulses = sf.attrs.get("pulses_per_ray")
    if is_cw_probe(probe) or "snr_median" not in sf or not points or not pulses:
        return np.full(shape, np.nan)
    bandwidth = noise.bandwidth_from_resolution(sf.attrs.get("velocity_resolution_m_s"))
    snr = sf["snr_median"].transpose("time", "height").values.astype(float)
    return noise.velocity_noise_std(snr, float(points), float(pulses), bandwidth)


def statistics_covariance(sf: xr.Dataset) -> np.ndarray | None:
    """``(time, height, lag + 1, lag + 1)`` covariance of the block-mean ``D_L`` and variance.

    ``statistics_covariance`` of :func:`cwproc.physics.block_stats.block_statistics`
    (m4 s-4; the jackknife over the block's scans), as float64; None when the
    structure function does not carry it.
    """
    if "statistics_covariance" not in sf:
        return None
    return sf["statistics_covariance"].transpose("time", "height", ...).values.astype(float)
