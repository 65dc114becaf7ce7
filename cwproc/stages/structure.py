"""Azimuth structure function of the radial velocity (stage ``structure``).

For every height and every block of N consecutive conical scans, Smalikho (2020),
eqs. 1-2:

.. math::

    V'_L(\\theta_m; n) = V_L(\\theta_m; n) - \\mathbf S(\\theta_m)\\cdot\\langle\\mathbf V\\rangle_N

    \\bar D_L(l\\Delta\\theta) = \\Big\\langle \\frac{1}{M-l}\\sum_{m=0}^{M-l-1}
        [V'_L(\\theta_m + l\\Delta\\theta; n) - V'_L(\\theta_m; n)]^2 \\Big\\rangle_N,
    \\qquad l = 1 \\dots L,\\ l\\Delta\\theta \\le \\text{max\\_lag\\_deg},

with ``<V>_N`` the mean of the N per-scan VAD wind vectors of the block (stage
``vad``). Rays are placed on the azimuth grid ``theta_m = theta_0 + m dtheta`` of their
own scan (``m`` counted in the direction of rotation from the scan's first ray), so
pairs are ``l`` steps apart both in azimuth and in time, whatever the start azimuth and
the direction of rotation. Missing or flagged rays (``qc_flag_radial != 0``) are
skipped pairwise; the average over the block pools all valid pairs (equal to eq. 2
when none is missing) and their number is kept as ``n_pairs``.

The block also yields what the dissipation-rate stage needs: the variance of
``V'_L`` (for sigma_V^2), the azimuth step dtheta, the scan period T_scan (from the ray
times) and the block-mean horizontal wind speed U.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.io.scan_join import is_homodyne
from cwproc.metadata import described
from cwproc.physics.atable_interp import N_BINS, azimuth_nodes
from cwproc.physics.block_stats import (
    WindRefit,
    block_statistics,
    block_sum,
    finite_columns,
    group_median,
    pair_azimuth_weights,
)
from cwproc.physics.geometry import beam_unit_vector, radial_velocity, speed_and_direction
from cwproc.physics.scan_layout import azimuth_step, wrapped_azimuth_difference
from cwproc.stages.scan_guard import require_distinct_scans

#: largest relative mismatch (m) between wind-product gate ranges and scan gate ranges
_RANGE_TOLERANCE_M = 0.5
#: values of V'_L held at once (memory bound: 4e6 x 8 bytes)
_CHUNK_VALUES = 4_000_000
#: homodyne: spectra with |V_r| below this are dropped (Banakh et al. (1999), section 3)
HOMODYNE_MIN_SPEED = 1.0
#: homodyne: rays need |S . <V>_N| >= 1 m/s + this many sigma' (see homodyne_radial_velocity)
HOMODYNE_SIGMAS = 3.0
#: instrument settings passed on to the turbulence product (noise prediction)
INSTRUMENT_SETTINGS = ("points_per_gate", "pulses_per_ray", "velocity_resolution_m_s", "scan_type")
#: fewest lags a coarse scan (24-72 rays) gets, beyond max_lag_deg if need be: eq. 5
#: needs lags 1 and l >= 2, the least-squares fit of eq. 4 three lags for two parameters
MIN_LAGS = 3
#: largest lag angle ever used (deg): the chord 2 R' sin(l dtheta / 2) reaches the radius
#: R' of the scan circle at 60 deg, beyond the integral scale at every height the product
#: serves, and the time between the rays (a sixth of a rotation) approaches the block's
#: stationarity scale; the exact two-beam model (cwproc.physics.two_beam) holds at any lag
MAX_LAG_LIMIT_DEG = 60.0


def azimuth_index(
    azimuth_deg: np.ndarray, first_azimuth_deg: np.ndarray, dtheta_deg: float, sign: float
) -> np.ndarray:
    """Index m of each ray on its scan's grid theta_0 + sign m dtheta (Smalikho (2020), eq. 2)."""
    offset = (sign * (np.asarray(azimuth_deg) - np.asarray(first_azimuth_deg))) % 360.0
    return np.rint(offset / dtheta_deg).astype(np.int64)


def homodyne_radial_velocity(
    abs_vr: np.ndarray, model: np.ndarray, block: np.ndarray
) -> np.ndarray:
    """Signed radial velocity from homodyne ``|V_r|``; NaN where the sign is ambiguous.

    A homodyne lidar measures ``|V_r|`` only (Banakh et al. (1999), section 3), so the
    sign is taken from the block-mean wind model ``m = S . <V>_N``. Where ``|m|`` is not
    well above the fluctuations the folded spectrum gives ``|V_r|`` of the wrong sign or a
    centroid pulled away from 0, which inflates D_L (+81 % eps at U = 5 m/s on the cw
    simulation); and spectra with ``|V_r| < 1 m s-1`` are dropped by the instrument
    (Banakh et al. (1999), section 3: the 1 m/s exclusion), a selection by the data
    themselves. Rule: rays with ``|m| < 1 m s-1 + 3 sigma'`` are left out, ``sigma'`` the
    standard deviation of ``|V_r| sign(m) - m`` in the block and height: beyond it a
    sign error needs a 3-sigma fluctuation (Gaussian probability 0.13 %), and the
    data-dependent 1 m/s cut cannot reach the kept rays. The rule selects rays by the
    model, not by their values, so D_L and the variance of the kept rays are not biased.

    Parameters
    ----------
    abs_vr : numpy.ndarray
        ``(ray, height)`` measured ``|V_r|`` (m s-1), NaN where missing.
    model : numpy.ndarray
        ``(ray, height)`` block-mean wind projected on the beam (m s-1).
    block : numpy.ndarray
        ``(ray,)`` block index (0-based, small integers) of each ray.

    Returns
    -------
    numpy.ndarray
        Signed ``V_r`` (m s-1), NaN for the rays left out.
    """
    signed = np.abs(abs_vr) * np.sign(model)
    dev = signed - model
    ok = np.isfinite(dev)
    n_b = int(block.max()) + 1 if block.size else 0
    n = np.zeros((n_b, dev.shape[1]))
    s1 = np.zeros_like(n)
    s2 = np.zeros_like(n)
    np.add.at(n, block, ok)
    np.add.at(s1, block, np.where(ok, dev, 0.0))
    np.add.at(s2, block, np.where(ok, dev**2, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma = np.sqrt(np.maximum(s2 / n - (s1 / n) ** 2, 0.0))
    threshold = HOMODYNE_MIN_SPEED + HOMODYNE_SIGMAS * sigma[block]
    return np.where(np.abs(model) >= threshold, signed, np.nan)


def swept_rays(attrs: dict) -> bool:
    """True unless the scan is a step-stare (Halo ``Scan type`` ending in ``- stepped``).

    A continuous scan accumulates each ray while the beam sweeps its azimuth step
    (Smalikho (2020), eq. 20); a step-stare VAD holds the beam still during a ray.
    """
    return "stepped" not in str(attrs.get("scan_type", "")).lower()


def block_median(values: np.ndarray, n_scans: int) -> np.ndarray:
    """Median over scans and azimuths (axes 0, 1) within blocks of ``n_scans``, NaN skipped."""
    out = []
    for start in range(0, values.shape[0], n_scans):
        part = values[start : start + n_scans]
        out.append(_nanmedian_columns(part.reshape(-1, part.shape[-1])))
    return np.array(out)


#: the columns' medians are first sought between two bounds (exact either way) from
#: this many values up: every _MEDIAN_SAMPLE_STEP-th row gives the quantiles 1/2 -+
#: _MEDIAN_BAND (the sample's quantile scatters by 0.033 for 1800 values)
_BOUNDED_MEDIAN_MIN, _MEDIAN_SAMPLE_STEP, _MEDIAN_BAND = 1000, 8, 0.08


def _nanmedian_columns(values: np.ndarray) -> np.ndarray:
    """``numpy.nanmedian(values, axis=0)`` by partitions (NaN last), without a warning.

    The columns with the same count of numbers ``n`` (commonly all of them) are
    partitioned at once at their two middle order statistics, ``(n - 1) // 2`` and
    ``n // 2``, whose mean ``(lo + hi) / 2`` is the median as :func:`numpy.median` forms
    it (the same value); NaN for a column without a number. For the 1800 values of a
    block of 10 scans of 180 rays, the partition took half the time of a sort; from
    ``_BOUNDED_MEDIAN_MIN`` values the columns are first sought between two bounds
    (:func:`_median_within_bounds`, the same values in half the time).
    """
    n = np.count_nonzero(~np.isnan(values), axis=0)
    if values.shape[0] >= _BOUNDED_MEDIAN_MIN and values.shape[1]:  # first between bounds
        out = _median_within_bounds(values, n)
        rest = np.flatnonzero(np.isnan(out) & (n > 0))
    else:
        out, rest = np.full(values.shape[1], np.nan), np.flatnonzero(n > 0)
    for count in np.unique(n[rest]):
        columns = rest[n[rest] == count]
        part = values if columns.size == values.shape[1] else values[:, columns]
        lo, hi = (int(count) - 1) // 2, int(count) // 2
        ordered = np.partition(part, [lo, hi], axis=0)
        out[columns] = (ordered[lo] + ordered[hi]) / 2
    return out


def _median_within_bounds(values: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Median of each column of ``values`` (``n`` numbers, NaN the rest) from the values
    between two bounds.

    The bounds are the quantiles ``1/2 -+ _MEDIAN_BAND`` of every
    ``_MEDIAN_SAMPLE_STEP``-th row; with ``k`` values of a column below its lower bound,
    the two middle order statistics ``lo`` and ``hi`` of its numbers are those of rank
    ``lo - k`` and ``hi - k`` among its values between the bounds (about a sixth of
    them, sorted; NaN is never between). The same values, so the same median, as a
    partition of the whole column; NaN for a column whose middle is not between its
    bounds (a sample far off or too many NaN, rare), which the caller partitions whole.
    """
    lo, hi = (n - 1) // 2, n // 2
    sample = np.ascontiguousarray(values[::_MEDIAN_SAMPLE_STEP].T)  # (column, row)
    k_low = int(sample.shape[1] * (0.5 - _MEDIAN_BAND))
    k_high = min(int(sample.shape[1] * (0.5 + _MEDIAN_BAND)), sample.shape[1] - 1)
    sample.partition([k_low, k_high], axis=1)  # NaN last
    above_low = values >= sample[:, k_low]  # False for NaN
    below = n - np.count_nonzero(above_low, axis=0)
    inside = above_low & (values <= sample[:, k_high])
    n_in = np.count_nonzero(inside, axis=0)
    found = (n > 0) & (below <= lo) & (hi < below + n_in)
    width = max(int(n_in.max()), 2)
    packed = np.full((n.size, width), np.inf)  # each column's values inside, sorted
    first = np.cumsum(n_in) - n_in  # the values taken column by column
    at = np.arange(first[-1] + n_in[-1]) + np.repeat(np.arange(n.size) * width - first, n_in)
    packed.reshape(-1)[at] = values.T[inside.T]
    packed.sort(axis=1)
    rows = np.arange(n.size)
    low = packed[rows, np.where(found, lo - below, 0)]
    high = packed[rows, np.where(found, hi - below, 0)]
    return np.where(found, (low + high) / 2, np.nan)


def pair_node_weights(theta: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """:func:`cwproc.physics.atable_interp.azimuth_bin_weights` (``axis=1``) by sums per node.

    Each pair at ``theta`` is shared linearly between its two neighbouring nodes; the
    shares are summed with :func:`numpy.bincount`, pair by pair in the same order,
    instead of over a ``(block, height, m, N_BINS)`` array zero but for two nodes.

    Parameters
    ----------
    theta, counts : numpy.ndarray
        ``(block, m, height)`` angle of the mean wind from the scan's direction of
        motion at each pair position (rad; NaN: none) and pairs there.

    Returns
    -------
    numpy.ndarray
        ``(block, height, N_BINS)``; NaN where a block and height has no pair.
    """
    n_b, _, n_h = theta.shape
    n = np.where(np.isfinite(theta), counts, 0.0)
    pos = np.mod(np.where(n > 0, theta, 0.0), 2.0 * np.pi) / (2.0 * np.pi / N_BINS)
    floor = np.floor(pos)
    i0 = floor.astype(np.int64) % N_BINS
    frac = pos - floor
    cell = (np.arange(n_b)[:, None, None] * n_h + np.arange(n_h)[None, None, :]) * N_BINS
    nodes = np.stack([cell + i0, cell + (i0 + 1) % N_BINS], axis=-1)
    shares = np.stack([(1.0 - frac) * n, frac * n], axis=-1)
    sums = np.bincount(nodes.ravel(), shares.ravel(), minlength=n_b * n_h * N_BINS)
    total = n.sum(axis=1)[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums.reshape(n_b, n_h, N_BINS) / total


def _match_gates(scan_range: np.ndarray, wind_range: np.ndarray) -> np.ndarray:
    idx = np.clip(np.searchsorted(scan_range, wind_range), 1, max(scan_range.size - 1, 1))
    idx = (
        np.where(
            np.abs(scan_range[idx - 1] - wind_range) <= np.abs(scan_range[idx] - wind_range),
            idx - 1,
            idx,
        )
        if scan_range.size > 1
        else np.zeros(wind_range.size, dtype=np.int64)
    )
    if np.any(np.abs(scan_range[idx] - wind_range) > _RANGE_TOLERANCE_M):
        raise CwprocError(
            "the wind product's gates do not match the scan gates: cannot compute the "
            "azimuth structure function"
        )
    return idx


def lag_count(dtheta_deg: float, max_lag_deg: float, min_lags: int = MIN_LAGS) -> int:
    """Number of lags L of the structure function for the azimuth step ``dtheta_deg``.

    ``floor(max_lag_deg / dtheta)``, raised to ``min_lags`` for coarse scans (24-72 rays,
    step-stare VADs) or, where ``min_lags dtheta`` exceeds :data:`MAX_LAG_LIMIT_DEG`, to
    as many as fit within it (a 12-ray VAD: lags 30 and 60 deg, whose A_2 over the pairs
    present comes from :mod:`cwproc.physics.few_ray_sector`); 0 when not one fits. The
    exact two-beam geometry (:mod:`cwproc.physics.two_beam`) replaces the small-angle
    model of Smalikho (2020), eq. 15 that limited lags to 9 deg.
    """
    n = int(np.floor(max_lag_deg / dtheta_deg + 1e-9))
    most = int(np.floor(MAX_LAG_LIMIT_DEG / dtheta_deg + 1e-9))
    return min(max(n, int(min_lags)), most)


@described(None)
def azimuth_structure_function(
    screened_ds: xr.Dataset,
    wind: xr.Dataset,
    *,
    n_scans: int = 10,
    max_lag_deg: float = 9.0,
    min_lags: int = MIN_LAGS,
    homodyne: bool | None = None,
) -> xr.Dataset:
    """Azimuth structure function D_L(l dtheta) per block of scans and height.

    Smalikho (2020), eqs. 1-2 (see the module docstring).

    Parameters
    ----------
    screened_ds : xarray.Dataset
        Scan dataset with ``radial_velocity(ray, range)`` (m s-1), ``qc_flag_radial``
        (0 = good), coords ``time``, ``azimuth`` (deg), ``elevation`` (deg), ``scan``.
    wind : xarray.Dataset
        Wind product of stage ``vad``: dims ``(time, height)``, coords ``scan(time)``,
        ``range(height)`` (m), ``elevation(time)`` (deg); vars ``u``, ``v``, ``w``
        (m s-1).
    n_scans : int, optional
        N, scans per block (consecutive in time; a shorter last block is kept and its
        ``n_scans`` recorded).
    max_lag_deg : float, optional
        Largest azimuth lag l dtheta (deg) of dense scans (:func:`lag_count`).
    min_lags : int, optional
        Fewest lags of coarse scans (:func:`lag_count`).
    homodyne : bool, optional
        ``radial_velocity`` holds ``|V_r|`` (homodyne detection): signs are taken from
        the block-mean wind (:func:`homodyne_radial_velocity`). None: the ``homodyne``
        attribute of ``screened_ds`` (:func:`cwproc.io.scan_join.is_homodyne`).

    The defaults of ``n_scans``, ``max_lag_deg`` and ``min_lags`` are those of the
    ``streamline`` preset (``[turbulence]`` of ``cwproc/configs/streamline.toml``).

    Returns
    -------
    xarray.Dataset
        Dims ``(time, height, lag)``; coords ``time`` (block centre), ``height`` (m),
        ``range(height)`` (m), ``lag`` (1..L), ``elevation(time)`` (deg); vars
        ``structure_function`` (m2 s-2), ``n_pairs``, ``radial_velocity_variance``
        (variance of V'_L, m2 s-2, noise included), ``wind_speed`` (block-mean U,
        m s-1), ``azimuth_step`` (deg), ``scan_period`` (s), ``n_scans``.

    Raises
    ------
    CwprocError
        No ray of the scan dataset belongs to a scan of the wind product, the gates do
        not match, or the azimuth step exceeds ``max_lag_deg``.
    """
    require_distinct_scans(screened_ds, stage="azimuth_structure_function")
    _check_inputs(screened_ds, wind, n_scans)
    if not np.all(np.diff(wind["time"].values) >= np.timedelta64(0)):  # else a copy
        wind = wind.sortby("time")
    grid = ray_grid(screened_ds, wind["scan"].values.astype(np.int64), max_lag_deg, min_lags)
    gates = _match_gates(screened_ds["range"].values.astype(float), wind["range"].values)
    homodyne = is_homodyne(screened_ds) if homodyne is None else bool(homodyne)
    starts = np.arange(0, grid.n_time, n_scans)
    # block-mean wind vector <V>_N per block and height (Smalikho (2020), eq. 1)
    scan_wind = np.stack([_time_height(wind[name]).astype(float) for name in "uvw"], -1)
    mean_wind = tuple(_block_mean(scan_wind[..., i], starts) for i in range(3))
    stats = _block_statistics_by_chunk(
        screened_ds, grid, gates, mean_wind, scan_wind, n_scans=n_scans, homodyne=homodyne
    )
    times = _block_times(wind, grid, n_scans)
    out = _structure_dataset(wind, grid, mean_wind, stats, times)
    out["structure_function"].attrs.update(
        method="azimuth structure function of V_L minus the block-mean VAD wind, pairs "
        "pooled over the block, missing rays skipped pairwise",
        n_scans_per_block=int(n_scans),
        max_lag_deg=float(max_lag_deg),
    )
    out.attrs.update(
        {
            "homodyne": int(homodyne),
            "instrument": str(screened_ds.attrs.get("instrument", "")),
            "rays_per_scan": grid.n_az,
            "rotation": int(grid.sign),
            "swept_rays": int(swept_rays(screened_ds.attrs)),
            **{k: screened_ds.attrs[k] for k in INSTRUMENT_SETTINGS if k in screened_ds.attrs},
        }
    )
    return out


def _time_height(values: xr.DataArray) -> np.ndarray:
    """The values of a ``(time, height)`` variable in that order (transposed if need be)."""
    if values.dims == ("time", "height"):
        return values.values
    return values.transpose("time", "height").values


def _check_inputs(screened_ds: xr.Dataset, wind: xr.Dataset, n_scans: int) -> None:
    """Raise :class:`CwprocError` when the inputs cannot give a structure function."""
    if n_scans < 1:
        raise CwprocError(f"n_scans must be >= 1, got {n_scans}")
    for name in ("radial_velocity", "qc_flag_radial"):
        if name not in screened_ds:
            raise CwprocError(f"scan dataset has no '{name}': run the qc stage first")
    for name in ("u", "v", "w"):
        if name not in wind:
            raise CwprocError(f"wind product has no '{name}'")


@dataclass(frozen=True)
class RayGrid:
    """The rays of the wind product's scans on their azimuth grids (Smalikho (2020), eq. 2).

    Attributes
    ----------
    rays : numpy.ndarray
        Indices (into the scan dataset) of the rays used, in time order.
    scan_pos : numpy.ndarray
        Wind-product time index of each ray.
    az, el : numpy.ndarray
        Azimuth and elevation of each ray (deg).
    t_ray : numpy.ndarray
        Time of each ray (datetime64).
    dtheta, sign : float
        Azimuth step (deg) and rotation (+1 clockwise).
    n_lags, n_az : int
        Lags L and rays per rotation M.
    n_time : int
        Scans of the wind product.
    first_of : numpy.ndarray
        ``(n_time,)`` index (into ``rays``) of each scan's first ray; -1 for none.
    m : numpy.ndarray
        Index of each ray on its scan's azimuth grid.
    uniq : numpy.ndarray
        Index (into ``rays``) of the first ray of each occupied (scan, m) cell.
    """

    rays: np.ndarray
    scan_pos: np.ndarray
    az: np.ndarray
    el: np.ndarray
    t_ray: np.ndarray
    dtheta: float
    sign: float
    n_lags: int
    n_az: int
    n_time: int
    first_of: np.ndarray
    m: np.ndarray
    uniq: np.ndarray


def ray_grid(
    screened_ds: xr.Dataset, wind_scan: np.ndarray, max_lag_deg: float, min_lags: int
) -> RayGrid:
    """Place the rays of the wind's scans (``wind_scan``, time order) on azimuth grids.

    Raises
    ------
    CwprocError
        No ray belongs to a scan of the wind product, or no lag is available.
    """
    n_time = wind_scan.size
    order = np.argsort(wind_scan, kind="stable")
    ray_scan = screened_ds["scan"].values.astype(np.int64)
    pos_sorted = np.clip(np.searchsorted(wind_scan[order], ray_scan), 0, max(n_time - 1, 0))
    keep = (ray_scan >= 0) & (n_time > 0) & (wind_scan[order][pos_sorted] == ray_scan)
    if not np.any(keep):
        raise CwprocError(
            "no conical-scan ray belongs to a scan of the wind product: no structure function"
        )
    rays = np.flatnonzero(keep)
    rays = rays[np.argsort(screened_ds["time"].values[rays], kind="stable")]
    scan_pos = order[pos_sorted[rays]]  # wind time index of each kept ray
    az = screened_ds["azimuth"].values[rays].astype(float)

    dtheta, sign = azimuth_step(az, scan_pos)
    n_lags = lag_count(dtheta, max_lag_deg, min_lags)
    if n_lags < 1:
        raise CwprocError(
            f"azimuth step {dtheta:.2f} deg exceeds max_lag_deg = {max_lag_deg} deg and "
            f"{MAX_LAG_LIMIT_DEG:g} deg: no structure-function lag available"
        )
    n_az = int(np.rint(360.0 / dtheta))

    # first ray of each scan (rays are time-ordered, so np.unique's first index)
    _, first = np.unique(scan_pos, return_index=True)
    first_of = np.full(n_time, -1, dtype=np.int64)
    first_of[scan_pos[first]] = first
    m = azimuth_index(az, az[first_of[scan_pos]], dtheta, sign)
    cell = scan_pos * n_az + m
    valid_cell = m < n_az
    _, uniq = np.unique(np.where(valid_cell, cell, -1), return_index=True)
    uniq = uniq[valid_cell[uniq]]  # first ray of each occupied (scan, m) cell
    return RayGrid(
        rays=rays,
        scan_pos=scan_pos,
        az=az,
        el=screened_ds["elevation"].values[rays].astype(float),
        t_ray=screened_ds["time"].values[rays],
        dtheta=dtheta,
        sign=sign,
        n_lags=n_lags,
        n_az=n_az,
        n_time=n_time,
        first_of=first_of,
        m=m,
        uniq=uniq,
    )


def _block_mean(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Mean over the scans (axis 0) of each block, NaN skipped."""
    ok = np.isfinite(values)
    total = block_sum(np.where(ok, values, 0.0), starts)
    count = block_sum(ok.astype(float), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        return total / count


@dataclass(frozen=True)
class BlockStatistics:
    """The statistics of V'_L per block and height (:func:`_block_statistics_by_chunk`).

    ``sf``, ``pairs``, ``variance``, ``sf_se``, ``diff_se``, ``variance_se`` and
    ``covariance`` as :func:`cwproc.physics.block_stats.block_statistics` returns them
    (``(block, height[, lag[, lag]])``, m2 s-2); ``weights`` the A-table node weights of
    the pairs of each lag (:func:`cwproc.physics.block_stats.pair_azimuth_weights`);
    ``snr_median``; ``wind_to`` the mean wind's direction of motion and ``start_angle``
    the first ray's azimuth from it in the sense of rotation (deg).
    """

    sf: np.ndarray
    pairs: np.ndarray
    variance: np.ndarray
    sf_se: np.ndarray
    diff_se: np.ndarray
    variance_se: np.ndarray
    covariance: np.ndarray
    weights: np.ndarray
    snr_median: np.ndarray
    wind_to: np.ndarray
    start_angle: np.ndarray

    #: the fields :func:`cwproc.physics.block_stats.block_statistics` fills, in its order
    STATISTICS = ("sf", "pairs", "variance", "sf_se", "diff_se", "variance_se", "covariance")

    @classmethod
    def empty(
        cls, shape: tuple[int, int, int], wind_to: np.ndarray, start_angle: np.ndarray
    ) -> BlockStatistics:
        """Arrays to fill for ``shape = (blocks, heights, lags)``."""
        n_blocks, n_h, n_lags = shape
        return cls(
            sf=np.empty((n_blocks, n_h, n_lags)),
            pairs=np.empty((n_blocks, n_h, n_lags), dtype=np.int64),
            variance=np.empty((n_blocks, n_h)),
            sf_se=np.empty((n_blocks, n_h, n_lags)),
            diff_se=np.empty((n_blocks, n_h, n_lags)),
            variance_se=np.empty((n_blocks, n_h)),
            covariance=np.empty((n_blocks, n_h, n_lags + 1, n_lags + 1)),
            weights=np.full((n_blocks, n_h, n_lags, N_BINS), np.nan, dtype=np.float32),
            snr_median=np.full((n_blocks, n_h), np.nan),
            wind_to=wind_to,
            start_angle=start_angle,
        )


def _block_statistics_by_chunk(
    screened_ds: xr.Dataset,
    grid: RayGrid,
    gates: np.ndarray,
    mean_wind: tuple[np.ndarray, np.ndarray, np.ndarray],
    scan_wind: np.ndarray,
    *,
    n_scans: int,
    homodyne: bool,
) -> BlockStatistics:
    """V'_L block by block in memory-bounded chunks of blocks, each fully vectorised.

    ``scan_wind`` (scan, height, 3) are the scans' VAD winds, whose block means
    ``mean_wind`` are removed: the covariance of the statistics is the jackknife over
    the scans with that removal redone (:func:`cwproc.physics.block_stats.WindRefit`;
    homodyne data, whose signs follow the wind, keep the scatter of the scans).
    """
    u_b, v_b, w_b = mean_wind
    n_blocks, n_h = u_b.shape
    # the mean wind's direction of motion (deg from north, clockwise) per block and height
    wind_to = np.mod(speed_and_direction(u_b, v_b)[1] + 180.0, 360.0)
    first_az = np.where(grid.first_of >= 0, grid.az[np.maximum(grid.first_of, 0)], np.nan)
    first_block = first_az[np.arange(n_blocks) * n_scans]
    # the first ray's azimuth from the wind's direction of motion, in the scan's sense
    start_angle = np.mod(grid.sign * (first_block[:, None] - wind_to), 360.0)
    out = BlockStatistics.empty((n_blocks, n_h, grid.n_lags), wind_to, start_angle)
    cell_scan = grid.scan_pos[grid.uniq]
    order_cells = np.argsort(cell_scan, kind="stable")
    sorted_scan = cell_scan[order_cells]
    per_chunk = max(1, _CHUNK_VALUES // (n_scans * grid.n_az * n_h))
    for b0 in range(0, n_blocks, per_chunk):
        b1 = min(b0 + per_chunk, n_blocks)
        t0_, t1_ = b0 * n_scans, min(b1 * n_scans, grid.n_time)
        lo, hi = np.searchsorted(sorted_scan, [t0_, t1_])
        cells = grid.uniq[order_cells[lo:hi]]
        chunk = (b0, b1, t0_, t1_)
        vprime, usable, on_grid = _chunk_fluctuations(
            screened_ds, grid, gates, mean_wind, (chunk, cells), n_scans, homodyne
        )
        refit = None
        if not homodyne:
            beams = on_grid(beam_unit_vector(grid.az[cells], grid.el[cells]))
            block_winds = np.stack([u_b[b0:b1], v_b[b0:b1], w_b[b0:b1]], -1)
            refit = WindRefit(beams, scan_wind[t0_:t1_], block_winds)
        valid = finite_columns(vprime)
        stats = block_statistics(vprime, n_scans, grid.n_lags, refit, valid)
        for name, value in zip(BlockStatistics.STATISTICS, stats, strict=True):
            getattr(out, name)[b0:b1] = value
        out.weights[b0:b1] = pair_azimuth_weights(
            vprime,
            n_scans,
            first_block[b0:b1],
            grid.dtheta,
            grid.sign,
            wind_to[b0:b1],
            grid.n_lags,
            valid,
        )
        if "snr" in screened_ds:
            snr_vals = _rows_at(screened_ds["snr"].values, grid.rays[cells], gates, float)
            snr = on_grid(np.where(usable, snr_vals, np.nan))
            out.snr_median[b0:b1] = block_median(snr, n_scans)
    return out


def _chunk_fluctuations(
    screened_ds: xr.Dataset,
    grid: RayGrid,
    gates: np.ndarray,
    mean_wind: tuple[np.ndarray, np.ndarray, np.ndarray],
    chunk_cells: tuple[tuple[int, int, int, int], np.ndarray],
    n_scans: int,
    homodyne: bool,
) -> tuple[np.ndarray, np.ndarray, Callable]:
    """``(V'_L on the grid (scan, m, height), usable (cell, height), the grid placer)`` of
    the blocks ``b0 .. b1`` (scans ``t0 .. t1``) of ``chunk_cells = ((b0, b1, t0, t1),
    cells)``: the radial velocity less the block-mean VAD wind's (Smalikho (2020), eq. 1;
    homodyne data: :func:`homodyne_radial_velocity`)."""
    (b0, b1, t0_, t1_), cells = chunk_cells
    u_b, v_b, w_b = mean_wind
    n_h = u_b.shape[1]
    scan_pos, rays = grid.scan_pos, grid.rays
    vr = _rows_at(screened_ds["radial_velocity"].values, rays[cells], gates, float)
    flag = _rows_at(screened_ds["qc_flag_radial"].values, rays[cells], gates)
    usable = (flag == 0) & np.isfinite(vr)
    vr = np.where(usable, vr, np.nan)
    b = scan_pos[cells] // n_scans
    complete, on_grid = _grid_placer(scan_pos[cells] - t0_, grid.m[cells], t1_ - t0_, grid.n_az)
    if complete and t1_ - t0_ == (b1 - b0) * n_scans:  # (block, ray, height) broadcast
        rays_of = (b1 - b0, n_scans * grid.n_az, 1)
        el = grid.el[cells].reshape(rays_of)
        if np.all(el == el[:, :1]):  # one elevation per block: w sin(phi) once
            el = el[:, :1]
        model = radial_velocity(
            *(c[b0:b1, None] for c in (u_b, v_b, w_b)),
            grid.az[cells].reshape(rays_of),
            el,
        ).reshape(cells.size, n_h)
    else:
        model = radial_velocity(
            u_b[b], v_b[b], w_b[b], grid.az[cells][:, None], grid.el[cells][:, None]
        )
    if homodyne:
        vr = homodyne_radial_velocity(vr, model, b - b0)
        usable = np.isfinite(vr)
    return on_grid(vr - model), usable, on_grid


def _grid_placer(scans: np.ndarray, m: np.ndarray, n_time: int, n_az: int) -> tuple[bool, Callable]:
    """Whether the cells ``(scans, m)`` fill the grid ``(n_time, n_az)`` in order (every
    ray of every scan present, as commonly), and a function placing values ``(cell,
    ...)`` of the cells on the grid, NaN where no cell (the values themselves, reshaped,
    when they fill it)."""
    flat = scans * n_az + m
    if flat.size == n_time * n_az and np.array_equal(flat, np.arange(flat.size)):
        return True, lambda values: values.reshape(n_time, n_az, *values.shape[1:])

    def place(values: np.ndarray) -> np.ndarray:
        out = np.full((n_time, n_az, *values.shape[1:]), np.nan)
        out[scans, m] = values
        return out

    return False, place


def _rows_at(
    values: np.ndarray, rows: np.ndarray, gates: np.ndarray, dtype: type | None = None
) -> np.ndarray:
    """``values[rows][:, gates]`` (as ``dtype``) in one copy: the gates are commonly all
    of them, in order (then consecutive rows are a view, not a copy)."""
    if gates.size == values.shape[1] and np.array_equal(gates, np.arange(gates.size)):
        consecutive = rows.size > 0 and np.array_equal(rows, np.arange(rows[0], rows[-1] + 1))
        out = values[rows[0] : rows[-1] + 1] if consecutive else values[rows]
    else:
        out = values[np.ix_(rows, gates)]
    return out if dtype is None else out.astype(dtype, copy=False)


@dataclass(frozen=True)
class BlockTimes:
    """Per block: the ``centre`` time, ``scan_period`` and ``scan_interval`` (s),
    ``n_scans`` and the mean ``elevation`` (deg) (:func:`_block_times`)."""

    centre: np.ndarray
    scan_period: np.ndarray
    scan_interval: np.ndarray
    n_scans: np.ndarray
    elevation: np.ndarray


def _block_times(wind: xr.Dataset, grid: RayGrid, n_scans: int) -> BlockTimes:
    """Per block: ``centre`` time, ``scan_period`` and ``scan_interval`` (s), ``n_scans``
    and mean ``elevation`` (deg).

    Every time is taken from differences of integer nanoseconds within its block, so a
    block's values do not depend on the blocks before it: the blocks of a day reduced
    a few at a time (:func:`cwproc.pipeline.stream.run_scan_chain`) equal those of the
    whole day to the bit. The centre is the block's first wind time plus the mean offset
    of its wind times, rounded half up to the nanosecond (exact integer arithmetic).
    """
    n_time = grid.n_time
    starts = np.arange(0, n_time, n_scans)
    n_blocks = starts.size
    block_of_time = np.arange(n_time) // n_scans
    scan_pos, az, sign, dtheta = grid.scan_pos, grid.az, grid.sign, grid.dtheta
    # scan period from the ray times: median time per azimuth step, times M
    same = scan_pos[1:] == scan_pos[:-1]
    dm = (sign * wrapped_azimuth_difference(az[1:], az[:-1]) / dtheta)[same]
    dt = _nanoseconds(np.diff(grid.t_ray))[same] / 1e9
    good = (dm > 0.5) & (dt > 0)
    step_time = group_median(
        dt[good] / np.rint(dm[good]), block_of_time[scan_pos[1:][same][good]], n_blocks
    )

    wind_time = wind["time"].values.astype("datetime64[ns]")
    first = wind_time[starts]
    offset = _nanoseconds(wind_time - first[block_of_time])  # within the block, >= 0
    count = np.diff(np.append(starts, n_time))
    total = np.add.reduceat(offset, starts) if n_time else np.zeros(0, np.int64)
    centre = first + ((2 * total + count) // (2 * count)).astype("timedelta64[ns]")
    # time between the starts of consecutive scans (a sector scan's return included)
    gaps_s = _nanoseconds(np.diff(wind_time)) / 1e9
    inside = block_of_time[1:] == block_of_time[:-1]
    scan_interval = group_median(gaps_s[inside], block_of_time[1:][inside], n_blocks)
    return BlockTimes(
        centre=centre,
        scan_period=step_time * grid.n_az,
        scan_interval=scan_interval,
        n_scans=block_sum(np.ones(n_time, dtype=np.int64), starts),
        elevation=_block_mean(wind["elevation"].values.astype(float)[:, None], starts)[:, 0],
    )


def _nanoseconds(delta: np.ndarray) -> np.ndarray:
    """Time differences as int64 nanoseconds (exact)."""
    return delta.astype("timedelta64[ns]").astype(np.int64)


def _structure_dataset(
    wind: xr.Dataset,
    grid: RayGrid,
    mean_wind: tuple[np.ndarray, np.ndarray, np.ndarray],
    stats: BlockStatistics,
    times: BlockTimes,
) -> xr.Dataset:
    """The structure-function dataset of :func:`azimuth_structure_function`."""
    u_b, v_b, _ = mean_wind
    n_blocks = u_b.shape[0]
    return xr.Dataset(
        {
            "structure_function": (("time", "height", "lag"), stats.sf),
            "n_pairs": (("time", "height", "lag"), stats.pairs),
            "radial_velocity_variance": (("time", "height"), stats.variance),
            "structure_function_se": (("time", "height", "lag"), stats.sf_se),
            "structure_function_difference_se": (("time", "height", "lag"), stats.diff_se),
            "radial_velocity_variance_se": (("time", "height"), stats.variance_se),
            "statistics_covariance": (
                ("time", "height", "statistic", "statistic_b"),
                stats.covariance,
            ),
            "wind_speed": (("time", "height"), speed_and_direction(u_b, v_b)[0]),
            "wind_to_direction": (("time", "height"), np.mod(stats.wind_to, 360.0)),
            "scan_start_angle": (("time", "height"), stats.start_angle),
            "pair_azimuth_weights": (
                ("time", "height", "lag", "azimuth_node"),
                stats.weights,
            ),
            "snr_median": (("time", "height"), stats.snr_median),
            "azimuth_step": ("time", np.full(n_blocks, grid.dtheta)),
            "scan_period": ("time", times.scan_period),
            "scan_interval": ("time", times.scan_interval),
            "n_scans": ("time", times.n_scans),
        },
        coords={
            "time": ("time", times.centre),
            "height": ("height", wind["height"].values),
            "range": ("height", wind["range"].values),
            "lag": ("lag", np.arange(1, grid.n_lags + 1, dtype=np.int64)),
            "azimuth_node": ("azimuth_node", np.degrees(azimuth_nodes())),
            "elevation": ("time", times.elevation),
        },
    )
