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
   described in ``docs/sonic.md`` and in :func:`cwproc.physics.sonic_fits.decide_types`.

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
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.metadata import described
from cwproc.physics.sonic_fits import TypeDecision, decide_types, fit_curves
from cwproc.physics.structure_functions import remove_running_mean, structure_function_fft

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
        Decades of r_max within which the simpler type wins (see
        :func:`cwproc.physics.sonic_fits.decide_types`).
    min_fit_points : int
        Fewest lags in a fit (and in each part of a type-3 fit).
    min_valid_fraction : float
        Windows with a smaller fraction of valid samples are skipped (window_flag 1).
    curvature_tolerance : float
        Decades of lg D below which a parabola counts as a line
        (:func:`cwproc.physics.sonic_fits.decide_types`).
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
