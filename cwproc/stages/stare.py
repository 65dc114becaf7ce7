"""Stare product: vertical-velocity statistics and eps from vertical stares.

Chain (:func:`stare_product`): the rays at elevation >= ``MIN_STARE_ELEVATION_DEG``
are taken from the scans of an instrument-day (:func:`split_stares`), screened for SNR,
grouped into windows of ``window_s`` seconds, and per window and gate give the mean,
variance and skewness of w, the noise variance predicted from the SNR (Pearson et al.
(2009), eq. 3), and eps of O'Connor et al. (2010) with the horizontal wind of the VADs
of the same day (:mod:`cwproc.physics.stare`). Without a wind, the w statistics are still
made and eps is NaN with flag bit 1.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.metadata import described
from cwproc.physics import dissipation, noise, stare
from cwproc.physics.geometry import height_from_range
from cwproc.physics.probe_lengths import ProbeLengths, pulsed_probe_lengths
from cwproc.stages.qc import snr_flags

#: rays at or above this elevation (deg) are vertical stares
MIN_STARE_ELEVATION_DEG = 85.0
#: flag bits of the stare product
FLAG_NO_WIND = 1
FLAG_TOO_FEW_SAMPLES = 2
FLAG_NOISE_DOMINATED = 4
FLAG_WIND_FAR = 8
#: Halo Stream Line pulse repetition frequency (Hz); 10 kHz for the XR
HALO_PRF_HZ = 15000.0
#: global attributes of the scans that the stare product keeps (the SNR correction by
#: the background files, :mod:`cwproc.stages.snr_correction`, as the wind product keeps them)
CARRIED_ATTRS = ("snr_correction", "background_files")


#: fewest rays of a variance window (see :func:`variance_window_length`)
MIN_RAYS_PER_VARIANCE_WINDOW = 4


@dataclass(frozen=True)
class StareOptions:
    """Settings of the stare product (the ``[stare]`` configuration section).

    The defaults are those of the ``streamline`` preset: its ``[stare]`` section,
    ``[qc] snr_min`` and the ``[instrument]`` pulse and gate lengths (``None``: the
    range gate length of the data and the pulse of the instrument model,
    :func:`cwproc.physics.probe_lengths.pulsed_probe_lengths`).
    """

    window_s: float = 300.0
    variance_window_s: float = 30.0
    min_samples: int = 20
    snr_min: float = 0.008
    outlier_threshold: float = 6.0
    prf_hz: float = HALO_PRF_HZ
    max_wind_gap_s: float = 3600.0
    delta_p_m: float | None = None
    delta_r_m: float | None = None
    min_rays_per_variance_window: int = MIN_RAYS_PER_VARIANCE_WINDOW


def stare_mask(ds: xr.Dataset) -> np.ndarray:
    """Rays of ``ds`` that are vertical stares (elevation >= 85 deg, < 95 deg)."""
    el = np.asarray(ds["elevation"].values, dtype=float)
    return np.isfinite(el) & (el >= MIN_STARE_ELEVATION_DEG) & (el <= 180 - MIN_STARE_ELEVATION_DEG)


def split_stares(scans: xr.Dataset) -> tuple[xr.Dataset | None, xr.Dataset | None]:
    """``(stares, others)``: the vertical rays and the rest (``None`` when there are none)."""
    vertical = stare_mask(scans)
    stares = scans.isel(ray=np.flatnonzero(vertical)) if vertical.any() else None
    others = scans.isel(ray=np.flatnonzero(~vertical)) if (~vertical).any() else None
    return stares, others


def ray_duration_s(ds: xr.Dataset, prf_hz: float = HALO_PRF_HZ) -> float:
    """Accumulation time of one ray (s): pulses per ray / PRF, else the median ray step.

    Raises
    ------
    CwprocError
        Neither the pulses per ray nor two ray times are known.
    """
    pulses = float(ds.attrs.get("pulses_per_ray", 0) or 0)
    if pulses > 0 and prf_hz > 0:
        return pulses / prf_hz
    t = np.sort(ds["time"].values.astype("datetime64[ns]").astype(np.int64)) / 1e9
    if t.size >= 2 and np.median(np.diff(t)) > 0:
        return float(np.median(np.diff(t)))
    raise CwprocError(
        "stare: the ray accumulation time is unknown (no pulses_per_ray, a single ray)"
    )


def ray_interval_s(time: np.ndarray, ray_s: float) -> float:
    """Typical time between consecutive rays (s): the median positive step, at least a ray.

    A stare interrupted by VADs keeps its own ray rate (the median ignores the gaps).
    """
    t = np.sort(time.astype("datetime64[ns]").astype(np.int64)) / 1e9
    step = np.diff(t)
    step = step[step > 0]
    return float(max(np.median(step), ray_s)) if step.size else float(ray_s)


def variance_window_length(
    interval_s: float,
    window_s: float = 300.0,
    variance_window_s: float = 30.0,
    min_rays_per_variance_window: int = MIN_RAYS_PER_VARIANCE_WINDOW,
) -> float:
    """Length T (s) of the variance windows: at least ``min_rays`` rays, a divisor of the window.

    ``T = window_s / k``, ``k = max(1, floor(window_s / max(variance_window_s,
    N x interval_s)))``, ``N = min_rays_per_variance_window``: the configured ``T``
    where the rays are dense (1.33-s rays, 30 s: 22 rays), longer where they are sparse
    (a ray every 25 s: 100 s, 4 rays, in 300-s windows), and always a whole number of
    variance windows per product window.
    With fewer than ``N`` rays a window's variance is mostly noise and sampling
    (see docs/stare.md for the rule's measured basis).
    """
    needed = max(variance_window_s, min_rays_per_variance_window * interval_s)
    k = max(1, math.floor(window_s / needed + 1e-9))
    return window_s / k


def window_index(
    time: np.ndarray, window_s: float = 300.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Window of each ray (windows of ``window_s`` s from 00:00 UTC of the first day).

    Returns
    -------
    index : numpy.ndarray of int
        Window of each ray, 0 .. n-1 (only windows holding rays are numbered).
    centre : numpy.ndarray of datetime64[ns]
        Centre time of each window.
    labels : numpy.ndarray of int
        Number of each window counted from 00:00 UTC.
    """
    t = time.astype("datetime64[ns]")
    day = t.min().astype("datetime64[D]").astype("datetime64[ns]")
    seconds = (t - day) / np.timedelta64(1, "s")
    raw = np.floor(seconds / window_s).astype(np.int64)
    labels, index = np.unique(raw, return_inverse=True)
    step = np.timedelta64(round(window_s * 1e9), "ns")
    centre = day + labels * step + step // 2
    return index.ravel(), centre, labels


def interpolate_wind(
    wind: xr.Dataset | None, time: np.ndarray, height: np.ndarray, max_gap_s: float = 3600.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Horizontal wind speed and its error at (window time, height) from VAD profiles.

    Linear in time and height between good VAD values (``qc_flag == 0``), the nearest
    value outside (as Cloudnet does for doppy's eps), per height first.

    Returns
    -------
    speed, error : numpy.ndarray
        ``(time, height)`` (m s-1); NaN where no VAD value exists.
    far : numpy.ndarray of bool
        The nearest VAD time is more than ``max_gap_s`` away.
    """
    shape = (time.size, height.size)
    nan = np.full(shape, np.nan)
    if wind is None or int(wind.sizes.get("time", 0)) == 0:
        return nan, nan.copy(), np.ones(shape, dtype=bool)
    speed = np.asarray(wind["wind_speed"].values, dtype=float)
    error = (
        np.asarray(wind["wind_speed_error"].values, dtype=float)
        if "wind_speed_error" in wind
        else np.zeros_like(speed)
    )
    good = np.isfinite(speed)
    if "qc_flag" in wind:
        good &= np.asarray(wind["qc_flag"].values) == 0
    heights = np.asarray(wind["height"].values, dtype=float)
    tw = wind["time"].values.astype("datetime64[ns]").astype(np.int64) / 1e9
    tt = time.astype("datetime64[ns]").astype(np.int64) / 1e9
    # per VAD time: the profile interpolated to the stare heights (nearest beyond)
    on_h = np.full((tw.size, height.size), np.nan)
    err_h = np.full_like(on_h, np.nan)
    for i in range(tw.size):  # one VAD profile each (tens a day)
        ok = good[i]
        if ok.sum() >= 1:
            on_h[i] = np.interp(height, heights[ok], speed[i, ok])
            err_h[i] = np.interp(height, heights[ok], np.nan_to_num(error[i, ok]))
    have = np.isfinite(on_h[:, 0])
    if not have.any():
        return nan, nan.copy(), np.ones(shape, dtype=bool)
    tv, on_h, err_h = tw[have], on_h[have], err_h[have]
    out = np.stack([np.interp(tt, tv, on_h[:, j]) for j in range(height.size)], axis=1)
    err = np.stack([np.interp(tt, tv, err_h[:, j]) for j in range(height.size)], axis=1)
    gap = np.min(np.abs(tt[:, None] - tv[None, :]), axis=1)
    far = np.broadcast_to((gap > max_gap_s)[:, None], shape).copy()
    return out, err, far


def outlier_mask(w: np.ndarray, sub: np.ndarray, n_sub: int, threshold: float = 6.0) -> np.ndarray:
    """Rays whose w is an outlier within its variance window and gate.

    ``|w - median| > threshold x max(1.4826 MAD, MIN_SPREAD_M_S)`` over the valid rays of
    the window (at least 5; fewer: nothing flagged), the robust screen of
    :mod:`cwproc.stages.qc` applied to the window instead of a VAD fit.
    """
    from cwproc.stages.qc import MAD_TO_STD, MIN_SPREAD_M_S

    order = np.argsort(sub, kind="stable")
    counts = np.bincount(sub, minlength=n_sub)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    slot = np.empty(sub.size, dtype=np.int64)
    slot[order] = np.arange(sub.size) - starts[sub[order]]
    padded = np.full((n_sub, max(int(counts.max()), 1), w.shape[1]), np.nan)
    padded[sub, slot] = w
    valid = np.sum(np.isfinite(padded), axis=1)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows: NaN, not flagged
        median = np.nanmedian(padded, axis=1)
        mad = np.nanmedian(np.abs(padded - median[:, None]), axis=1)
    spread = np.maximum(MAD_TO_STD * mad, MIN_SPREAD_M_S)
    with np.errstate(invalid="ignore"):
        far = np.abs(w - median[sub]) > threshold * spread[sub]
    return far & (valid[sub] >= 5)


def subwindow_variances(
    w: np.ndarray, sub: np.ndarray, n_sub: int, noise_var_ray: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Variance of w in every variance window (``T`` of O'Connor et al. (2010)).

    Returns
    -------
    variance, corrected, noise : numpy.ndarray
        ``(sub-window, gate)`` (m2 s-2): the variance of the ``n`` valid rays about the
        sub-window mean; that minus the noise's share of it, ``(n - 1)/n`` times the
        rays' mean predicted noise variance (white noise about the window's own mean);
        and the rays' mean noise variance. NaN with fewer than 3 valid rays.
    """
    count, _, var, _ = stare.window_moments(w, sub, n_sub)
    noise_var = stare.window_mean(np.where(np.isfinite(w), noise_var_ray, np.nan), sub, n_sub)
    keep = count >= 3
    with np.errstate(invalid="ignore", divide="ignore"):
        corrected = var - noise_var * (count - 1) / count
    return (
        np.where(keep, var, np.nan),
        np.where(keep, corrected, np.nan),
        np.where(keep, noise_var, np.nan),
    )


def group_mean_se(
    values: np.ndarray, group: np.ndarray, n_groups: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean, standard error (std/sqrt(n)) and count of the finite rows of each group."""
    finite = np.isfinite(values)
    x = np.where(finite, values, 0.0)
    n = np.zeros((n_groups, values.shape[1]))
    total = np.zeros_like(n)
    np.add.at(n, group, finite.astype(float))
    np.add.at(total, group, x)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / n
        ss = np.zeros_like(n)
        np.add.at(ss, group, np.where(finite, (values - mean[group]) ** 2, 0.0))
        se = np.sqrt(ss / (n - 1) / n)
    return (
        np.where(n >= 1, mean, np.nan),
        np.where(n >= 2, se, np.nan),
        n.astype(np.int64),
    )


def band_factor_per_window(
    rays_per_sub: np.ndarray,
    sub_window: np.ndarray,
    n_windows: int,
    speed: np.ndarray,
    *,
    ray_s: float,
    interval_s: float,
    lengths: ProbeLengths,
) -> np.ndarray:
    """Expected mean variance of a product window per eps^(2/3) (m^(4/3)), ``(window, height)``.

    The mean over the window's variance windows (those of 3 rays or more) of ``G`` of
    their ``n_s`` rays ``U interval_s`` apart, each ``U ray_s`` long, through the range
    gate (:func:`cwproc.physics.stare.band_variance_factor` with ``n_rays``).
    """
    out = np.zeros(speed.shape)
    used = rays_per_sub >= 3
    share = np.bincount(sub_window[used], minlength=n_windows).astype(float)
    finite = np.isfinite(speed) & (speed > 0)
    for n in np.unique(rays_per_sub[used]):
        weight = np.bincount(sub_window[used & (rays_per_sub == n)], minlength=n_windows)
        g = np.full(speed.shape, np.nan)
        u, inverse = np.unique(speed[finite], return_inverse=True)
        if u.size > 64:  # smooth in U: a log grid and interpolation
            grid = np.geomspace(u[0], u[-1], 64)
            values = _band_factor(grid, int(n), ray_s, interval_s, lengths)
            g[finite] = np.exp(np.interp(np.log(u), np.log(grid), np.log(values)))[inverse]
        elif u.size:
            g[finite] = _band_factor(u, int(n), ray_s, interval_s, lengths)[inverse]
        out = out + weight[:, None] * g
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(share[:, None] > 0, out / share[:, None], np.nan)


def _band_factor(
    speed: np.ndarray, n: int, ray_s: float, interval_s: float, lengths: ProbeLengths
) -> np.ndarray:
    """``G`` of ``n`` rays at the wind speeds ``speed`` (m s-1)."""
    return stare.band_variance_factor(
        speed * n * interval_s,
        speed * ray_s,
        lengths.delta_p_m,
        lengths.delta_r_m,
        n_rays=n,
        ray_spacing_m=speed * interval_s,
    )


def variance_se_per_window(
    time: np.ndarray,
    index: np.ndarray,
    sub: np.ndarray,
    n_windows: int,
    epsilon: np.ndarray,
    speed: np.ndarray,
    noise_variance: np.ndarray,
) -> np.ndarray:
    """Standard error (m2 s-2) of each window's mean variance for its eps, U and noise.

    The variance of a Gaussian quadratic form (:func:`cwproc.physics.stare.
    variance_form_traces`) over the rays of the window as they were sampled; the traces
    take every ray of the window (gates with screened rays get the same traces).
    """
    seconds = (time.astype("datetime64[ns]") - time.min()) / np.timedelta64(1, "s")
    traces = np.full((3, n_windows), np.nan)
    for j in range(n_windows):  # a few hundred windows a day, each n^2 of its rays
        rays = np.flatnonzero(index == j)
        traces[:, j] = stare.variance_form_traces(seconds[rays], sub[rays])
    t0, t1, t2 = (traces[i][:, None] for i in range(3))
    return stare.variance_standard_error(epsilon, speed, noise_variance, (t0, t1, t2))


@described("stare")
def stare_product(
    stares: xr.Dataset, wind: xr.Dataset | None = None, options: StareOptions | None = None
) -> xr.Dataset:
    """w statistics and eps per window and height from vertical stares.

    Variance windows: :func:`variance_window_length` (at least
    ``options.min_rays_per_variance_window`` rays). eps: the mean corrected variance over
    :func:`band_factor_per_window`, its standard error from
    :func:`variance_se_per_window` and the wind's error. Probe: ``Delta_R`` the data's
    range gate length and ``Delta_p`` the instrument model's unless set in ``options``
    (recorded in the attributes ``probe_*``).

    Parameters
    ----------
    stares : xarray.Dataset
        Scan dataset of vertical rays (:func:`split_stares`), rays in time order.
    wind : xarray.Dataset or None
        Wind product of the VADs of the same instrument-day (``wind_speed(time,
        height)``), or ``None``: eps is NaN and flag bit 1 set.
    options : StareOptions, optional
        Windows, screening and probe; default ``StareOptions()``, the values of the
        ``streamline`` preset.

    Returns
    -------
    xarray.Dataset
        Dims ``time`` (window centres), ``height``, ``ray``; see ``cwproc.metadata.products``.
    """
    if stares.sizes.get("ray", 0) == 0:
        raise CwprocError("stare: no vertical rays")
    options = StareOptions() if options is None else options
    lengths = pulsed_probe_lengths(stares.attrs, options.delta_p_m, options.delta_r_m)
    elevation = float(np.nanmedian(stares["elevation"].values))
    height = height_from_range(stares["range"].values.astype(float), elevation)
    w = _screened_w(stares, options.snr_min)
    time = stares["time"].values
    t_ray = ray_duration_s(stares, options.prf_hz)
    interval = ray_interval_s(time, t_ray)
    t_var = variance_window_length(
        interval, options.window_s, options.variance_window_s, options.min_rays_per_variance_window
    )
    index, centre, _ = window_index(time, options.window_s)
    n_win = centre.size
    sub_ids, sub, sub_window = _variance_windows(time, index, t_var)
    w = np.where(outlier_mask(w, sub, sub_ids.size, options.outlier_threshold), np.nan, w)
    count, mean, _, skew = stare.window_moments(w, index, n_win)
    sigma_e = noise_std_per_ray(stares)
    raw_sub, var_sub, noise_sub = subwindow_variances(w, sub, sub_ids.size, sigma_e**2)
    var_corr, _, _ = group_mean_se(var_sub, sub_window, n_win)
    var, _, _ = group_mean_se(raw_sub, sub_window, n_win)
    noise_var, _, _ = group_mean_se(noise_sub, sub_window, n_win)
    speed, speed_err, far = interpolate_wind(wind, centre, height, options.max_wind_gap_s)
    factor = band_factor_per_window(
        np.bincount(sub, minlength=sub_ids.size),
        sub_window,
        n_win,
        speed,
        ray_s=t_ray,
        interval_s=interval,
        lengths=lengths,
    )
    eps, eps_se = _stare_epsilon(
        (var_corr, noise_var), factor, (time, index, sub, n_win), (speed, speed_err)
    )
    # fewest rays: min_samples, or half of what the window holds at this ray rate
    min_rays = min(options.min_samples, max(3, math.ceil(0.5 * options.window_s / interval)))
    flag = stare_flags(count, var, var_corr, speed, far, min_rays)
    bad = (flag & (FLAG_NO_WIND | FLAG_TOO_FEW_SAMPLES | FLAG_NOISE_DOMINATED)) != 0
    return _assemble(
        stares,
        height=height,
        centre=centre,
        w_ray=w,
        values={
            "w_mean": mean,
            "w_variance": var,
            "w_variance_corrected": var_corr,
            "w_skewness": skew,
            "w_noise_variance": noise_var,
            "w_n_samples": count,
            "stare_wind_speed": speed,
            "epsilon_stare": np.where(bad, np.nan, eps),
            "epsilon_stare_standard_error": np.where(bad, np.nan, eps_se),
            "stare_flag": flag,
        },
        attrs={
            "window_s": float(options.window_s),
            "variance_window_s": float(t_var),
            "variance_window_s_configured": float(options.variance_window_s),
            "ray_duration_s": float(t_ray),
            "ray_interval_s": float(interval),
            "elevation_deg": elevation,
            **lengths.attrs(),
        },
    )


def _screened_w(stares: xr.Dataset, snr_min: float) -> np.ndarray:
    """``(ray, range)`` w (m s-1, upward) of the stares, NaN where the SNR is below
    ``snr_min`` (:func:`cwproc.stages.qc.snr_flags`) or the velocity is missing."""
    flag_radial = snr_flags(stares["snr"].values, snr_min) if "snr" in stares else 0
    velocity = stares["radial_velocity"].values.astype(float)
    w = np.where((flag_radial == 0) & np.isfinite(velocity), velocity, np.nan)
    return w * np.sign(np.sin(np.deg2rad(stares["elevation"].values)))[:, None]


def _variance_windows(
    time: np.ndarray, index: np.ndarray, t_var: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The variance windows T inside each product window (O'Connor et al. (2010), eq. 4):
    ``(ids, window of each ray, product window of each variance window)``; ``index``: the
    product window of each ray."""
    sub_raw, _, _ = window_index(time, t_var)
    sub_ids, sub = np.unique(index * (1 << 32) + sub_raw, return_inverse=True)
    return sub_ids, sub.ravel(), (sub_ids >> 32).astype(np.int64)


def _stare_epsilon(
    variances: tuple[np.ndarray, np.ndarray],
    factor: np.ndarray,
    windows: tuple[np.ndarray, np.ndarray, np.ndarray, int],
    wind: tuple[np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """eps (m2 s-3) per window and height and its standard error.

    :func:`cwproc.physics.dissipation.epsilon_from_band_variance` of the corrected
    variance, divided by the bias of the 3/2 power
    (:func:`cwproc.physics.stare.power_bias_divisor`);
    :func:`cwproc.physics.dissipation.stare_epsilon_standard_error` with the variance's
    standard error (:func:`variance_se_per_window`). ``variances``: (corrected, noise)
    variance; ``windows``: ``(time, product window, variance window of each ray, number
    of product windows)``; ``wind``: the wind speed and its error (m s-1).
    """
    var_corr, noise_var = variances
    time, index, sub, n_win = windows
    speed, speed_err = wind
    eps = dissipation.epsilon_from_band_variance(var_corr, factor)
    noise_known = np.where(np.isfinite(noise_var), noise_var, 0.0)
    var_se = variance_se_per_window(time, index, sub, n_win, eps, speed, noise_known)
    with np.errstate(invalid="ignore", divide="ignore"):
        eps = eps / stare.power_bias_divisor(var_se / var_corr)
    return eps, dissipation.stare_epsilon_standard_error(eps, var_corr, var_se, speed, speed_err)


def stare_flags(
    count: np.ndarray,
    var: np.ndarray,
    var_corr: np.ndarray,
    speed: np.ndarray,
    far: np.ndarray,
    min_rays: int,
) -> np.ndarray:
    """``stare_flag`` bits per window and height (``cwproc.metadata.products``).

    Bit 2 where a window has fewer than ``min_rays`` valid rays or no variance window of
    3 valid rays.
    """
    flag = np.zeros(var.shape, dtype=np.int8)
    flag |= np.where(~np.isfinite(speed), FLAG_NO_WIND, 0).astype(np.int8)
    # too few rays in the window, or in every one of its variance windows (< 3 each)
    few = (count < min_rays) | ~np.isfinite(var)
    flag |= np.where(few, FLAG_TOO_FEW_SAMPLES, 0).astype(np.int8)
    noisy = np.isfinite(var_corr) & ~(var_corr > 0)
    flag |= np.where(noisy, FLAG_NOISE_DOMINATED, 0).astype(np.int8)
    flag |= np.where(far & np.isfinite(speed), FLAG_WIND_FAR, 0).astype(np.int8)
    return flag


def noise_std_per_ray(ds: xr.Dataset) -> np.ndarray:
    """Predicted sigma_e (m s-1) of every ray and gate from the SNR (Pearson et al. (2009)).

    NaN everywhere when the SNR, points per gate or pulses per ray are unknown.
    """
    shape = ds["radial_velocity"].shape
    m = float(ds.attrs.get("points_per_gate", 0) or 0)
    n = float(ds.attrs.get("pulses_per_ray", 0) or 0)
    if "snr" not in ds or m <= 0 or n <= 0:
        return np.full(shape, np.nan)
    bandwidth = noise.bandwidth_from_resolution(
        float(ds.attrs.get("velocity_resolution_m_s", 0) or 0)
    )
    return noise.velocity_noise_std(ds["snr"].values, m, n, bandwidth)


def _assemble(
    stares: xr.Dataset,
    *,
    height: np.ndarray,
    centre: np.ndarray,
    w_ray: np.ndarray,
    values: dict[str, np.ndarray],
    attrs: dict[str, float],
) -> xr.Dataset:
    """The stare product dataset (metadata attached later by the writer)."""
    dims = ("time", "height")
    method = {
        "epsilon_stare": {
            "method": (
                "eps = (sigma_w^2 - sigma_e^2)^(3/2) / G^(3/2), G = int a_T k^(-5/3) "
                "[1 - sinc^2(k L_1/2)] sinc^2(k L_N/2) R_gate(k) dk, a_T = "
                f"{stare.A_TRANSVERSE:.4f}"
            ),
        }
    }
    data = {name: (dims, value, method.get(name, {})) for name, value in values.items()}
    data["w_ray"] = (("ray", "height"), w_ray, {})
    ds = xr.Dataset(
        data,
        coords={
            "time": ("time", centre.astype("datetime64[ns]")),
            "height": ("height", height),
            "ray_time": ("ray", stares["time"].values.astype("datetime64[ns]")),
        },
        attrs={
            "instrument": str(stares.attrs.get("instrument", "")),
            "system_id": str(stares.attrs.get("system_id", "")),
            **{k: stares.attrs[k] for k in CARRIED_ATTRS if k in stares.attrs},
            **attrs,
        },
    )
    return ds
