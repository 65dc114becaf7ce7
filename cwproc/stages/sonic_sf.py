"""Structure-function types of sonic-anemometer wind components (Gladkikh et al. (2014)).

Stage ``sonic_sf``: sonic dataset (dim ``time``) -> SF product (dims ``window``,
``component``). For every analysis window (10 min by default) and every wind
component (longitudinal V_1, transverse V_2, vertical V_3):

1. rotate the instrument-frame (u, v) into the window's mean-wind direction
   (Gladkikh et al. (2014), section 1: V_1 along the mean horizontal wind, V_2
   across it, V_3 = w);
2. remove a centred running mean (1 min by default) from every component;
3. compute the structure function of every lag j = 1..K (K = {max_lag_fraction N},
   N = {window_s f_d}) by FFT, Gladkikh et al. (2014), eq. 2, skipping missing
   samples pairwise (O(N log N));
4. convert time lags into spatial lags r_j = j V_h / f_d (Taylor) and normalise by
   the value at the lag nearest r_N = 1 m, Gladkikh et al. (2014), eq. 3;
5. fit, in x = lg(r/r_N), y = lg D_n, the three model types of Gladkikh et al.
   (2014), eqs. 4-6, growing r_max while the determination coefficient
   k_d >= k_dL (0.99850);
6. decide the type with the rules of the paper plus the two rules the paper leaves
   unstated (precedence among nested types; how r_p and r_l are found), which are
   described in ``docs/sonic.md`` and in :func:`decide_types`.

Windows are skipped (``sf_type`` 0, reason in ``window_flag``) when too few valid
samples remain, when r_min = V_h/f_d > r_N (very strong wind: Gladkikh et al.
(2014) do not analyse them) or when even the largest lag is shorter than r_N (calm:
the normalisation lag cannot be reached). Samples that are not finite or that the
reader flagged (``sample_flag`` != 0: diagnostic, spike) are treated as missing;
they are never interpolated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.metadata import described
from cwproc.stages.sonic_fits import (
    TypeDecision,
    fit_curves,
    grow_polynomial_fit,
    lag_at,
    precedence_type,
    running_sums,
    type3_tail,
)

COMPONENTS = ("longitudinal", "transverse", "vertical")

#: window_flag values (bits)
FLAG_FEW_SAMPLES = 1
FLAG_STRONG_WIND = 2
FLAG_CALM = 4


# -- windows and preprocessing ---------------------------------------------------------


def grid_windows(
    time: np.ndarray,
    values: np.ndarray,
    valid: np.ndarray,
    *,
    window_s: float = 600.0,
    rate_hz: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Place samples on a regular grid of ``window_s`` windows aligned to UTC multiples.

    Parameters
    ----------
    time : ndarray of datetime64
        Sample times (UTC), any order.
    values : ndarray, shape (3, n)
        u, v, w (m s-1).
    valid : ndarray of bool, shape (3, n)
        Which samples may be used.
    window_s : float
        Window length (s).
    rate_hz : float
        Sampling rate f_d (Hz).

    Returns
    -------
    starts : ndarray of datetime64[ns], shape (W,)
        Window start times.
    grid : ndarray, shape (W, 3, N)
        Values on the grid; NaN where no valid sample fell.
    counts : ndarray of int, shape (W,)
        Number of grid slots holding a valid sample of every component.
    """
    t_ns = time.astype("datetime64[ns]", copy=False).view(np.int64)
    win_ns = round(window_s * 1e9)
    n_slots = int(np.floor(window_s * rate_hz + 1e-9))
    widx = np.floor_divide(t_ns, win_ns)
    if widx.size and not np.any(widx[1:] < widx[:-1]):  # time order (a reader's output)
        first = np.flatnonzero(np.concatenate([[True], widx[1:] != widx[:-1]]))
        uniq = widx[first]
        inverse = np.repeat(np.arange(first.size), np.diff(np.append(first, widx.size)))
    else:
        uniq, inverse = np.unique(widx, return_inverse=True)
    slot = np.rint((t_ns - widx * win_ns) * 1e-9 * rate_hz).astype(np.int64)
    inside = slot < n_slots
    grid = np.full((uniq.size, 3, n_slots), np.nan)
    place = inverse * (3 * n_slots) + slot  # flat index of (window, u, slot); v, w follow
    for c in range(3):
        keep = inside & valid[c]
        if keep.all():
            grid.reshape(-1)[place + c * n_slots] = values[c]
        else:
            grid.reshape(-1)[place[keep] + c * n_slots] = values[c, keep]
    counts = np.all(np.isfinite(grid), axis=1).sum(axis=1)
    starts = (uniq * win_ns).astype("datetime64[ns]")
    return starts, grid, counts


def rotate_to_mean_wind(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotate (u, v, w) of each window into longitudinal, transverse, vertical components.

    V_1 points along the window-mean horizontal wind, V_2 90 degrees to its left,
    V_3 = w, Gladkikh et al. (2014), section 1.

    Parameters
    ----------
    grid : ndarray, shape (W, 3, N)
        u, v, w (m s-1) per window, NaN for missing samples.

    Returns
    -------
    rotated : ndarray, shape (W, 3, N)
        V_1, V_2, V_3 (m s-1).
    mean_speed : ndarray, shape (W,)
        V_h, the mean horizontal wind speed (m s-1): modulus of the mean vector.
    """
    mu, mv = window_mean_wind(grid)
    speed = np.hypot(mu, mv)
    safe = np.where(speed > 0, speed, 1.0)
    cos, sin = (mu / safe)[:, None], (mv / safe)[:, None]
    out = np.empty_like(grid)
    out[:, 0] = grid[:, 0] * cos + grid[:, 1] * sin
    out[:, 1] = -grid[:, 0] * sin + grid[:, 1] * cos
    out[:, 2] = grid[:, 2]
    return out, speed


def window_mean_wind(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean u and v (m s-1, instrument frame) of each window over its valid samples.

    Parameters
    ----------
    grid : ndarray, shape (W, 3, N)
        u, v, w (m s-1) per window, NaN for missing samples.
    """
    ok = np.isfinite(grid[:, 0]) & np.isfinite(grid[:, 1])
    count = ok.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mu = np.where(ok, grid[:, 0], 0.0).sum(axis=1) / count
        mv = np.where(ok, grid[:, 1], 0.0).sum(axis=1) / count
    return mu, mv


def geographic_wind_direction(
    mean_u: np.ndarray, mean_v: np.ndarray, orientation_deg: float = 0.0
) -> np.ndarray:
    """Direction the mean wind blows from, degrees clockwise from north, in [0, 360).

    The instrument frame is right-handed with z up: +y lies 90 degrees anticlockwise
    (seen from above) of +x, whose azimuth is ``orientation_deg`` (clockwise from
    north). The wind blows towards the azimuth ``orientation_deg - atan2(v, u)``; it
    comes from the opposite direction.

    Parameters
    ----------
    mean_u, mean_v : ndarray
        Mean wind components along x and y of the instrument frame (m s-1).
    orientation_deg : float
        Azimuth of +x (degree clockwise from north).

    Returns
    -------
    ndarray
        Wind direction "from" (degree); NaN where the mean wind is zero or missing.
    """
    toward = orientation_deg - np.degrees(np.arctan2(mean_v, mean_u))
    calm = ~(np.hypot(mean_u, mean_v) > 0)
    return np.where(calm, np.nan, np.mod(toward + 180.0, 360.0))


def remove_running_mean(x: np.ndarray, width: int) -> np.ndarray:
    """Subtract a centred running mean of ``width`` samples along the last axis.

    Missing samples (NaN) are left out of the mean and stay NaN; near the ends of the
    window the mean is taken over the part of the running window that exists.
    Gladkikh et al. (2014), section 1 (1-min running mean).

    Parameters
    ----------
    x : ndarray, shape (..., N)
    width : int
        Running-mean width (samples, >= 1).

    Returns
    -------
    ndarray, same shape as ``x``.
    """
    finite = np.isfinite(x)
    complete = bool(finite.all())
    filled = x if complete else np.where(finite, x, 0.0)
    n = x.shape[-1]
    csum = np.zeros((*x.shape[:-1], n + 1))
    np.cumsum(filled, axis=-1, out=csum[..., 1:])
    idx = np.arange(n)
    lo = np.clip(idx - width // 2, 0, n)
    hi = np.clip(idx - width // 2 + width, 0, n)
    if complete:  # the counts are the window lengths (the same numbers, not summed)
        cnt = (hi - lo).astype(float)
    else:
        ccnt = np.zeros((*x.shape[:-1], n + 1))
        np.cumsum(finite, axis=-1, out=ccnt[..., 1:])
        cnt = ccnt[..., hi] - ccnt[..., lo]
    # in place (a day of windows is ~20 MB per temporary): mean = (csum_hi - csum_lo) / cnt
    mean = csum[..., hi]
    mean -= csum[..., lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean /= cnt
    if complete:
        return np.subtract(x, mean, out=mean)
    np.subtract(x, mean, out=mean)
    mean[~finite] = np.nan
    return mean


def next_fast_len(n: int) -> int:
    """The smallest 5-smooth number (2^a 3^b 5^c) >= n: a fast real FFT length.

    The same length as ``scipy.fft.next_fast_len(n, real=True)``; numpy's FFT (the
    same pocketfft) is used so that sf-type does not pay scipy's import.
    """
    best = 1 << max(int(n - 1).bit_length(), 0)
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            p235 = p35 << max(int(-(-n // p35) - 1).bit_length(), 0)  # smallest 2^a p35 >= n
            best = min(best, p235)
            p35 *= 3
        p5 *= 5
    return best


def structure_function_fft(x: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Structure function D(j) for lags j = 1..max_lag by FFT, missing samples pairwise.

    D(j) = (1/N_j) sum_m [x(m + j) - x(m)]^2 over the N_j pairs in which both samples
    exist, Gladkikh et al. (2014), eq. 2, evaluated through three correlation sums
    (each one FFT product), O(N log N).

    Parameters
    ----------
    x : ndarray, shape (..., N)
        Series (m s-1); NaN marks missing samples.
    max_lag : int
        Largest lag K (samples).

    Returns
    -------
    d : ndarray, shape (..., K)
        D(j) (m2 s-2), NaN where no pair exists.
    pairs : ndarray, shape (..., K)
        N_j, the number of pairs.
    """
    n = x.shape[-1]
    finite = np.isfinite(x)
    # no sample missing: one transform of the mask serves every series (same values)
    complete = bool(finite.all())
    m = finite.astype(float)
    a = x if complete else np.where(finite, x, 0.0)
    nfft = next_fast_len(n + max_lag + 1)
    fm = np.fft.rfft(m[(0,) * (m.ndim - 1)] if complete else m, nfft, axis=-1)
    fa = np.fft.rfft(a, nfft, axis=-1)
    fs = np.fft.rfft(a * a, nfft, axis=-1)
    del m, a

    def corr(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        # sum_i p_i q_{i+j} for j = 1..max_lag (the lags copied out of the transform)
        product = np.conj(p)
        product = np.multiply(product, q, out=product if product.shape == q.shape else None)
        return np.fft.irfft(product, nfft, axis=-1)[..., 1 : max_lag + 1].copy()

    pairs = np.rint(corr(fm, fm))
    if complete:
        pairs = np.broadcast_to(pairs, (*x.shape[:-1], max_lag))
    squares = corr(fm, fs)
    squares += corr(fs, fm)
    del fs
    cross = corr(fa, fa)
    del fa
    cross *= 2.0
    squares -= cross
    with np.errstate(invalid="ignore", divide="ignore"):
        squares /= pairs
    d = np.where(pairs > 0, np.maximum(squares, 0.0), np.nan)
    return d, pairs


# -- type decision ---------------------------------------------------------------------


def decide_types(
    r: np.ndarray,
    y: np.ndarray,
    *,
    r_norm: float = 1.0,
    kd_threshold: float = 0.99850,
    precedence_tolerance: float = 0.05,
    min_points: int = 5,
    curvature_tolerance: float = 0.03,
) -> TypeDecision:
    """Type 1, 2 or 3 (or 0) of normalised structure functions, Gladkikh et al. (2014).

    Fits (x = lg(r/r_N), y = lg D_n), all grown from r_min (the first lag) with
    :func:`grow_polynomial_fit`:

    * type 1: line y = b + mu x up to r_max1, eq. 4;
    * type 2: parabola y = a0 + a1 x + a2 x^2 up to r_max2, eq. 5;
    * type 3: the parabola up to r_p = r_max2 (the paper does not say how r_p is
      found: here, the end of the parabola grown from r_min), then a line
      y = c + gamma x grown from the smallest candidate start r_l >= r_p
      (:func:`cwproc.stages.sonic_fits.type3_tail`) for which the type-3 rules of the
      paper hold: Delta_B/Delta_A < 0.25 with Delta_B = r_l - r_p,
      Delta_A = r_max - r_l + r_p - r_min, and r_p - r_min <= r_max - r_l, eq. 6;
      otherwise the SF is type 2 with r_max = r_p.

    A type whose r_max < r_N (1 m) is rejected. Precedence (not stated in the paper,
    whose models are nested): the candidate with the largest r_max wins, except that a
    simpler type (1 < 2 < 3) is taken whenever lg r_max(simpler) >= lg r_max(best) -
    ``precedence_tolerance``; and a type-2 decision falls back to type 1 (with the
    line's own r_max) when the parabola is not significantly curved: its quadratic
    term changes lg D by less than ``curvature_tolerance`` decades over its range,
    |a2| (x_max - x_min)^2 / 8 < curvature_tolerance (the largest departure of a
    parabola from its least-squares line is about that much).

    Parameters
    ----------
    r : ndarray, shape (S, K)
        Lags r_j (m), increasing along the last axis.
    y : ndarray, shape (S, K)
        lg of the normalised structure function; NaN where unusable.
    r_norm : float
        r_N (m).
    kd_threshold : float
        k_dL.
    precedence_tolerance : float
        Tolerance in decades of r_max (see above).
    min_points : int
        Fewest lags in any fit (and in each part of a type-3 fit).
    curvature_tolerance : float
        Decades (see above).

    Returns
    -------
    TypeDecision
    """
    n_series = r.shape[0]
    x = np.log10(r / r_norm)
    sums = running_sums(x, y, 2)
    zero = np.zeros(n_series, dtype=np.int64)
    line = grow_polynomial_fit(sums, zero, 1, kd_threshold=kd_threshold, min_points=min_points)
    para = grow_polynomial_fit(sums, zero, 2, kd_threshold=kd_threshold, min_points=min_points)
    r_p = lag_at(r, para.end)
    tail, tail_start = type3_tail(
        r, sums, para.end, kd_threshold=kd_threshold, min_points=min_points
    )
    # candidates, rejection r_max < r_N, precedence
    r_max = np.stack([lag_at(r, line.end), r_p, lag_at(r, tail.end)], axis=1)  # types 1-3
    r_max = np.where(r_max >= r_norm, r_max, np.nan)
    with np.errstate(invalid="ignore"):
        span = np.log10(r_p / r[:, 0])
        flat = np.abs(para.coef[:, 2]) * span**2 / 8.0 < curvature_tolerance
    sf_type = precedence_type(r_max, flat, precedence_tolerance)
    chosen_rmax = np.where(
        sf_type > 0, r_max[np.arange(n_series), np.clip(sf_type - 1, 0, 2)], np.nan
    )
    kd = np.select(
        [sf_type == 1, sf_type == 2, sf_type == 3],
        [line.kd, para.kd, np.fmin(para.kd, tail.kd)],
        np.nan,
    )
    return TypeDecision(
        sf_type=sf_type,
        r_max=chosen_rmax,
        kd=kd,
        line=line,
        parabola=para,
        tail=tail,
        r_p=r_p,
        r_l=lag_at(r, tail_start),
        type3_ok=tail.end >= 0,
    )


# -- the stage -------------------------------------------------------------------------

#: D(r_N) below this (m2 s-2; a 1e-5 m/s rms increment, far below any sonic's
#: resolution) means a numerically constant component: it is not typed
D_FLOOR = 1e-10

#: windows typed together (memory bound: one day of 10-min windows at a time)
WINDOW_BATCH = 144
#: windows detrended and transformed together (:func:`_window_structure_functions`)
FFT_WINDOWS = 16


def window_batches(
    time: np.ndarray, window_s: float = 600.0, batch: int = WINDOW_BATCH
) -> list[np.ndarray]:
    """Sample indices of consecutive groups of at most ``batch`` analysis windows."""
    t_ns = time.astype("datetime64[ns]").astype(np.int64)
    widx = np.floor_divide(t_ns, round(window_s * 1e9))
    uniq = np.unique(widx)
    if uniq.size <= batch:
        return [np.arange(t_ns.size)]
    group = np.searchsorted(uniq, widx) // batch
    order = np.argsort(group, kind="stable")
    bounds = np.searchsorted(group[order], np.arange(1, group.max() + 1))
    return np.split(order, bounds)


@described("sf")
def structure_function_types(
    sonic: xr.Dataset,
    *,
    window_s: float = 600.0,
    running_mean_s: float = 60.0,
    max_lag_fraction: float = 0.1,
    kd_threshold: float = 0.99850,
    normalisation_lag_m: float = 1.0,
    precedence_tolerance: float = 0.05,
    min_fit_points: int = 5,
    min_valid_fraction: float = 0.9,
    curvature_tolerance: float = 0.03,
    orientation_deg: float = 0.0,
) -> xr.Dataset:
    """Structure-function types and fitted parameters per window and wind component.

    Gladkikh et al. (2014), eqs. 2-6 (method in the module docstring).

    Parameters
    ----------
    sonic : xarray.Dataset
        Canonical sonic dataset: ``u``, ``v``, ``w`` (m s-1) on ``time`` (UTC), attr
        ``sampling_rate_hz`` (f_d, Hz); optional ``sample_flag`` (non-zero: unusable).
    window_s : float
        Analysis window Delta t (s), 600 in the paper.
    running_mean_s : float
        Width of the running mean removed first (s), 60 in the paper.
    max_lag_fraction : float
        Largest lag as a fraction of the window (0.1 in the paper).
    kd_threshold : float
        k_dL, the determination-coefficient threshold (0.99850 in the paper).
    normalisation_lag_m : float
        r_N (m): normalisation lag of eq. 3, unit of x = lg(r/r_N), smallest accepted
        r_max and largest accepted r_min (1 m in the paper).
    precedence_tolerance : float
        Decades of r_max within which the simpler type wins (see :func:`decide_types`).
    min_fit_points : int
        Fewest lags in a fit (and in each part of a type-3 fit).
    min_valid_fraction : float
        Windows with a smaller fraction of valid samples are skipped (window_flag 1).
    curvature_tolerance : float
        Decades of lg D below which a parabola counts as a line (:func:`decide_types`).
    orientation_deg : float
        Azimuth of the +x (u) axis of the instrument frame, degree clockwise from
        north: gives ``wind_direction``, the window-mean wind direction in the
        geographic frame (:func:`geographic_wind_direction`). The types and every
        other variable are invariant under it (the components are taken along and
        across the mean wind).

    Returns
    -------
    xarray.Dataset
        dims ``window``, ``component`` (and ``sf_lag`` for the normalised SF itself);
        see ``docs/sonic.md`` for every variable.

    Raises
    ------
    CwprocError
        The dataset has no sampling rate, or no window could be formed.
    """
    rate = float(sonic.attrs.get("sampling_rate_hz", np.nan))
    if not np.isfinite(rate) or rate <= 0:
        raise CwprocError("sonic dataset has no valid sampling_rate_hz attribute")
    if sonic.sizes.get("time", 0) == 0:
        raise CwprocError("sonic dataset has no samples")
    n_slots = int(np.floor(window_s * rate + 1e-9))
    n_lags = int(np.floor(max_lag_fraction * n_slots + 1e-9))
    if n_lags < min_fit_points + 1:
        raise CwprocError(
            f"window of {window_s} s at {rate:g} Hz gives only {n_lags} lags; "
            f"at least {min_fit_points + 1} are needed"
        )
    kwargs = {
        "window_s": window_s,
        "running_mean_s": running_mean_s,
        "max_lag_fraction": max_lag_fraction,
        "kd_threshold": kd_threshold,
        "normalisation_lag_m": normalisation_lag_m,
        "precedence_tolerance": precedence_tolerance,
        "min_fit_points": min_fit_points,
        "min_valid_fraction": min_valid_fraction,
        "curvature_tolerance": curvature_tolerance,
        "orientation_deg": orientation_deg,
    }
    batches = window_batches(sonic["time"].values, window_s, WINDOW_BATCH)
    if len(batches) > 1:
        # bounded memory: at most WINDOW_BATCH windows (a day) of grids and FFTs at once
        parts = [structure_function_types(sonic.isel(time=b), **kwargs) for b in batches]
        return xr.concat(parts, dim="window", combine_attrs="override")
    return _type_windows(sonic, kwargs, rate=rate, n_slots=n_slots, n_lags=n_lags)


@dataclass(frozen=True)
class _Windows:
    """The structure functions of one batch of windows (steps 1-4 of the module doc)."""

    #: window start times, shape (W,)
    starts: np.ndarray
    #: V_h (m s-1) and the fraction of valid samples, shape (W,)
    speed: np.ndarray
    valid_fraction: np.ndarray
    #: direction of the mean wind (degree from north, "from"), shape (W,)
    direction: np.ndarray
    #: window_flag, shape (W,)
    flag: np.ndarray
    #: spatial lags r_j = j V_h / f_d (m), shape (W, K)
    r: np.ndarray
    #: index of the lag nearest r_N, shape (W,)
    jn: np.ndarray
    #: D(r_N) (m2 s-2, NaN: untyped), shape (W, 3); D / D(r_N) and N_j, shape (W, 3, K)
    d_norm: np.ndarray
    dn: np.ndarray
    pairs: np.ndarray


def _window_structure_functions(
    sonic: xr.Dataset, params: dict[str, float], *, rate: float, n_slots: int, n_lags: int
) -> _Windows:
    """Grid, rotate, detrend and FFT the windows of ``sonic``; flag and normalise (eq. 3)."""
    r_norm = params["normalisation_lag_m"]
    values = np.stack([np.asarray(sonic[c].values, dtype=float) for c in ("u", "v", "w")])
    valid = np.isfinite(values)
    if "sample_flag" in sonic:
        valid &= (np.asarray(sonic["sample_flag"].values) == 0)[None, :]
    starts, grid, counts = grid_windows(
        sonic["time"].values, values, valid, window_s=params["window_s"], rate_hz=rate
    )
    del values, valid
    direction = geographic_wind_direction(*window_mean_wind(grid), params["orientation_deg"])
    width = max(round(params["running_mean_s"] * rate), 1)
    shape = (starts.size, 3, n_lags)
    speed, d, pairs = np.empty(starts.size), np.empty(shape), np.empty(shape)
    # FFT_WINDOWS windows at a time, each on its own (any grouping): small temporaries
    for lo in range(0, starts.size, FFT_WINDOWS):
        part = slice(lo, lo + FFT_WINDOWS)
        rotated, speed[part] = rotate_to_mean_wind(grid[part])
        d[part], pairs[part] = structure_function_fft(remove_running_mean(rotated, width), n_lags)
    valid_fraction = counts / n_slots
    j = np.arange(1, n_lags + 1)
    r_win = speed[:, None] * j[None, :] / rate  # (W, K)
    flag = np.zeros(starts.size, dtype=np.int8)
    flag[valid_fraction < params["min_valid_fraction"]] |= FLAG_FEW_SAMPLES
    flag[r_win[:, 0] > r_norm] |= FLAG_STRONG_WIND
    flag[r_win[:, -1] < r_norm] |= FLAG_CALM

    jn = np.argmin(np.abs(r_win - r_norm), axis=1)
    d_norm = np.take_along_axis(d, jn[:, None, None], axis=2)[..., 0]  # (W, 3)
    # a numerically constant component (no turbulent fluctuation) cannot be typed
    d_norm = np.where(d_norm > D_FLOOR, d_norm, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        dn = d / d_norm[..., None]
    return _Windows(starts, speed, valid_fraction, direction, flag, r_win, jn, d_norm, dn, pairs)


def _type_windows(
    sonic: xr.Dataset, params: dict[str, float], *, rate: float, n_slots: int, n_lags: int
) -> xr.Dataset:
    """The SF product of one batch of windows (steps 1-6 of the module doc)."""
    r_norm = params["normalisation_lag_m"]
    win = _window_structure_functions(sonic, params, rate=rate, n_slots=n_slots, n_lags=n_lags)
    n_win = win.starts.size
    with np.errstate(invalid="ignore", divide="ignore"):
        y = np.where(win.dn > 0, np.log10(win.dn), np.nan)
    analysed = np.repeat(win.flag == 0, 3)
    r_s = np.repeat(win.r, 3, axis=0)
    y_s = y.reshape(n_win * 3, n_lags)
    y_s = np.where(analysed[:, None], y_s, np.nan)
    safe_r = np.where(r_s > 0, r_s, np.nan)
    dec = decide_types(
        np.where(np.isfinite(safe_r), safe_r, 1.0),
        y_s,
        r_norm=r_norm,
        kd_threshold=params["kd_threshold"],
        precedence_tolerance=params["precedence_tolerance"],
        min_points=params["min_fit_points"],
        curvature_tolerance=params["curvature_tolerance"],
    )
    sf_type = np.where(analysed, dec.sf_type, 0).astype(np.int8)
    x_s = np.log10(np.where(np.isfinite(safe_r), safe_r, 1.0) / r_norm)
    fit_curve = fit_curves(x_s, dec, sf_type, r_norm)
    fit_curve = np.where(r_s <= np.where(sf_type > 0, dec.r_max, -1.0)[:, None], fit_curve, np.nan)
    typed = _type_variables(dec, sf_type, analysed, win.d_norm.reshape(-1), (n_win, 3))
    return _sf_dataset(
        sonic,
        win,
        typed,
        fit=(10.0 ** fit_curve.reshape(n_win, 3, n_lags)).astype(np.float32),
        params={**params, "sampling_rate_hz": rate},
    )


def _type_variables(
    dec: TypeDecision,
    sf_type: np.ndarray,
    analysed: np.ndarray,
    d_norm: np.ndarray,
    shape: tuple[int, int],
) -> dict[str, np.ndarray]:
    """The (window, component) variables of the types: coefficients of eqs. 4-6, r_max,
    r_p, r_l, r_s, k_d and the structure constant 10^beta D(r_N) (NaN where untyped)."""

    def per(v: np.ndarray, t: int | None = None) -> np.ndarray:
        v = np.where(analysed if t is None else (sf_type == t), v, np.nan)
        return v.reshape(shape)

    lc, pc, tc = dec.line.coef, dec.parabola.coef, dec.tail.coef
    t3 = sf_type == 3
    r_s_transition = np.where(t3, 0.5 * (dec.r_p + dec.r_l), np.nan)
    beta = np.select([sf_type == 1, sf_type == 2, t3], [lc[:, 0], pc[:, 0], pc[:, 0]], np.nan)
    structure_constant = 10.0**beta * d_norm
    return {
        "sf_type": sf_type.reshape(shape),
        "sf_b": per(lc[:, 0], 1),
        "sf_mu": per(lc[:, 1], 1),
        "sf_a0": per(pc[:, 0], 2),
        "sf_a1": per(pc[:, 1], 2),
        "sf_a2": per(pc[:, 2], 2),
        "sf_d0": per(pc[:, 0], 3),
        "sf_d1": per(pc[:, 1], 3),
        "sf_d2": per(pc[:, 2], 3),
        "sf_c": per(tc[:, 0], 3),
        "sf_gamma": per(tc[:, 1], 3),
        "r_max": per(np.where(sf_type > 0, dec.r_max, np.nan)),
        "r_p": per(dec.r_p, 3),
        "r_l": per(dec.r_l, 3),
        "r_s": per(r_s_transition, 3),
        "k_d": per(np.where(sf_type > 0, dec.kd, np.nan)),
        "structure_constant": per(np.where(sf_type > 0, structure_constant, np.nan)),
    }


def _sf_dataset(
    sonic: xr.Dataset,
    win: _Windows,
    typed: dict[str, np.ndarray],
    *,
    fit: np.ndarray,
    params: dict[str, float],
) -> xr.Dataset:
    """The SF product dataset of one batch of windows (see ``docs/sonic.md``)."""
    dims = ("window", "component")
    per_lag = ("window", "component", "sf_lag")
    ok = win.flag == 0
    n_lags = win.r.shape[1]
    ds = xr.Dataset(
        {
            **{name: (dims, value) for name, value in typed.items()},
            "sf_at_normalisation_lag": (dims, np.where(ok[:, None], win.d_norm, np.nan)),
            "r_min": (("window",), win.r[:, 0]),
            "r_normalisation": (
                ("window",),
                np.take_along_axis(win.r, win.jn[:, None], axis=1)[:, 0],
            ),
            "mean_horizontal_wind": (("window",), win.speed),
            "wind_direction": (("window",), win.direction),
            "valid_fraction": (("window",), win.valid_fraction),
            "window_flag": (("window",), win.flag),
            "lag_distance": (("window", "sf_lag"), win.r),
            "normalised_sf": (
                per_lag,
                np.where(ok[:, None, None], win.dn, np.nan).astype(np.float32),
            ),
            "normalised_sf_fit": (per_lag, fit),
            "n_pairs": (per_lag, win.pairs.astype(np.int32)),
        },
        coords={
            "time": (("window",), win.starts),
            "component": (("component",), np.array(COMPONENTS)),
            "sf_lag": (("sf_lag",), np.arange(1, n_lags + 1).astype(np.int32)),
        },
    )
    method = (
        "1-min running mean removed, FFT structure function (eq. 2), normalised at the "
        "lag nearest r_N (eq. 3), lg-lg fits grown while k_d >= k_dL (eqs. 4-6); "
        "precedence: simplest type within precedence_tolerance decades of the largest "
        "r_max; r_p = end of the parabola grown from r_min, r_l = smallest start >= r_p "
        "meeting the type-3 rules"
    )
    ds["sf_type"].attrs.update({"method": method, **params})
    ds.attrs.update(
        {
            "sampling_rate_hz": params["sampling_rate_hz"],
            "instrument": str(sonic.attrs.get("instrument", "")),
            "frame": str(sonic.attrs.get("frame", "")),
            "sonic_sf_parameters": params,
        }
    )
    return ds


# -- summaries (Gladkikh et al. (2014), Tables 2-5) ------------------------------------

#: parameters summarised per type (Tables 3-5)
TYPE_PARAMETERS = {
    1: ("sf_mu", "r_max"),
    2: ("sf_a1", "sf_a2", "r_max"),
    3: ("sf_d1", "sf_d2", "sf_gamma", "r_max"),
}


def type_occurrence(sf: xr.Dataset) -> pd.DataFrame:
    """Occurrence of each type per component (%), Gladkikh et al. (2014), Table 2.

    The denominator is every window with enough valid samples (window_flag without
    bit 1), i.e. the observation time, as in the paper; windows skipped for strong
    wind or calm count as observed but untyped.

    Returns
    -------
    pandas.DataFrame
        index component; columns ``windows``, ``all_types_pct``, ``type1_pct``,
        ``type2_pct``, ``type3_pct``.
    """
    observed = (np.asarray(sf["window_flag"].values) & FLAG_FEW_SAMPLES) == 0
    types = np.asarray(sf["sf_type"].values)[observed]
    n = int(observed.sum())
    rows = []
    for k, comp in enumerate(sf["component"].values):
        t = types[:, k]
        share = [100.0 * np.mean(t == m) if n else np.nan for m in (1, 2, 3)]
        rows.append(
            {
                "component": str(comp),
                "windows": n,
                "all_types_pct": float(np.nansum(share)) if n else np.nan,
                "type1_pct": share[0],
                "type2_pct": share[1],
                "type3_pct": share[2],
            }
        )
    return pd.DataFrame(rows).set_index("component")


def parameter_statistics(sf: xr.Dataset) -> pd.DataFrame:
    """Means and medians of the fitted parameters per type and component (Tables 3-5).

    Gladkikh et al. (2014), Tables 3 (type 1: mu, r_max), 4 (type 2: a1, a2, r_max)
    and 5 (type 3: d1, d2, gamma, r_max).

    Returns
    -------
    pandas.DataFrame
        columns ``type``, ``component``, ``parameter``, ``count``, ``mean``, ``median``.
    """
    rows = []
    types = np.asarray(sf["sf_type"].values)
    for t, names in TYPE_PARAMETERS.items():
        for k, comp in enumerate(sf["component"].values):
            sel = types[:, k] == t
            for name in names:
                vals = np.asarray(sf[name].values)[sel, k]
                vals = vals[np.isfinite(vals)]
                rows.append(
                    {
                        "type": t,
                        "component": str(comp),
                        "parameter": name,
                        "count": int(vals.size),
                        "mean": float(np.mean(vals)) if vals.size else np.nan,
                        "median": float(np.median(vals)) if vals.size else np.nan,
                    }
                )
    return pd.DataFrame(rows)
