"""Sonic turbulence product: eps, variances, TKE, u_*, integral scales and EC flags.

Stage ``sonic_turbulence``: sonic dataset (dim ``time``) -> product (dims ``window``,
``component``), one row per averaging window (30 min by default, aligned to UTC
multiples). Per window:

1. despike every component (Vickers & Mahrt (1997): 3.5 sigma for u and v, 5.0 sigma for
   w as EddyPro; or Mauder et al. (2013), eq. 1;
   :mod:`cwproc.physics.sonic_turbulence`); a window with more than 1 % spikes in a
   component gets window_flag bit 2 (the hard flag of Vickers & Mahrt (1997));
2. double rotation (Wilczak et al. (2001), eqs. 22-23), planar fit (eqs. 39-45, one
   plane for all windows of the dataset) or none;
3. type the structure functions of the despiked, rotated series with the sf-type
   stage (:func:`cwproc.stages.sonic_sf.structure_function_types`, Gladkikh et al.
   (2014), its own 1-min running mean) over the same window;
4. detrend (linear or block mean) and compute variances, TKE, u_*, integral time and
   length scales with their random errors (Lenschow et al. (1994));
5. eps of each component from the lags of its typed fit whose local slope
   d lg D / d lg r is within ``slope_tolerance`` of 2/3 (the inertial range: all of a
   type-1 fit with mu near 2/3, the linear tail of type 3 when gamma is near 2/3, the
   part of a parabola (type 2 or the head of type 3) around its tangent of slope
   2/3); no such range of at least ``min_inertial_points`` lags: no eps and
   ``epsilon_flag`` says why. Standard error from ``n_sub`` sub-windows (batch means);
6. the longitudinal spectrum over the same range as a check (``epsilon_spectrum``);
7. steady state of <u'w'> and ITC of sigma_w/u_* (Foken & Wichura (1996), models of
   Foken et al. (2004) and Thomas & Foken (2002)) and the 0-1-2 flag (Mauder & Foken
   (2004)); the ITC of sigma_u/u_* is reported beside it, outside the flag.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.metadata import described
from cwproc.physics import dissipation
from cwproc.physics import sonic_turbulence as st
from cwproc.physics.structure_functions import structure_function_fft
from cwproc.stages.sonic_sf import (
    COMPONENTS,
    geographic_wind_direction,
    grid_windows,
    structure_function_types,
)

#: window_flag bits
FLAG_FEW_SAMPLES = 1
FLAG_SPIKES = 2
FLAG_NO_EPSILON = 4
FLAG_ITC_UNTESTED = 8
FLAG_SPECTRUM_DISAGREES = 16

#: epsilon_flag values (per window and component)
EPS_OK = 0
EPS_UNTYPED = 1
EPS_NO_INERTIAL_RANGE = 2

#: the constant of D_ii = C eps^(2/3) r^(2/3) of each component (longitudinal first)
SF_CONSTANTS = (st.C2_LONGITUDINAL, st.C2_TRANSVERSE, st.C2_TRANSVERSE)


def _despike(
    x: np.ndarray, method: str, rate: float, component: int
) -> tuple[np.ndarray, np.ndarray]:
    """Despike one component (0 u, 1 v, 2 w): VM97 at 3.5 sigma, 5.0 sigma for w."""
    if method == "vickers_mahrt":
        factor = st.VM97_FACTOR_W if component == 2 else st.VM97_FACTOR
        return st.despike_vickers_mahrt(x, rate, factor=factor)
    if method == "mauder":
        return st.despike_mauder(x)
    if method == "none":
        return x, np.zeros(x.size, dtype=bool)
    raise CwprocError(f"sonic despike method {method!r}: use vickers_mahrt, mauder or none")


def _typed_slope(sf: xr.Dataset, w: int, c: int, r: np.ndarray) -> np.ndarray:
    """Local slope of the typed fit of window ``w``, component ``c`` at lags r (NaN beyond)."""
    t = int(sf["sf_type"].values[w, c])
    if t == 0:
        return np.full(r.size, np.nan)
    g = {k: float(sf[f"sf_{k}"].values[w, c]) for k in ("mu", "a1", "a2", "d1", "d2", "gamma")}
    coef = {"mu": g["mu"], "a1": g["a1"], "a2": g["a2"], "d1": g["d1"], "d2": g["d2"]}
    coef["gamma"] = g["gamma"]
    coef["x_s"] = float(np.log10(sf["r_s"].values[w, c])) if t == 3 else np.nan
    x = np.log10(r / float(sf["sf_type"].attrs.get("normalisation_lag_m", 1.0)))
    slope = st.local_slope(x, t, coef)
    return np.where(r <= float(sf["r_max"].values[w, c]), slope, np.nan)


def _window_statistics(
    x: np.ndarray, temp: np.ndarray | None, rate: float, p: SonicTurbulenceSettings
) -> dict[str, object]:
    """Variances, fluxes, u_*, scales and tests of one rotated window x (3, N)."""
    t_avg = x.shape[1] / rate
    fl = np.stack([st.detrend(x[c], p.detrend) for c in range(3)])
    var = np.array([np.nanmean(fl[c] ** 2) for c in range(3)])
    t_int = np.array([st.integral_time_scale(fl[c], rate) for c in range(3)])
    var_err = np.array([st.variance_random_error(var[c], t_int[c], t_avg) for c in range(3)])
    uw, vw = np.nanmean(fl[0] * fl[2]), np.nanmean(fl[1] * fl[2])
    ustar = st.friction_velocity(uw, vw)
    r_uw = uw / np.sqrt(var[0] * var[2]) if var[0] > 0 and var[2] > 0 else np.nan
    uw_err = st.covariance_random_error(uw, r_uw, max(t_int[0], t_int[2]), t_avg)
    speed = float(np.nanmean(x[0]))
    zl = np.nan
    if temp is not None and p.height_m is not None:
        tf = st.detrend(temp, p.detrend)
        zl = st.obukhov_stability(
            p.height_m, ustar, np.nanmean(fl[2] * tf), np.nanmean(temp) + 273.15
        )
    elif p.height_m is not None:
        zl = 0.0  # no sonic temperature: neutral assumed (documented)
    itc, itc_u = np.nan, np.nan
    if p.height_m is not None and ustar > 0:
        itc = st.itc_deviation(
            np.sqrt(var[2]) / ustar,
            st.itc_model_sigma_w(zl, p.height_m, p.latitude_deg, ustar),
        )
        # reported, not in the flag (EddyPro's flag of tau takes the worse of the two)
        itc_u = st.itc_deviation(
            np.sqrt(var[0]) / ustar, st.itc_model_sigma_u(zl, p.latitude_deg, ustar)
        )
    rn = st.stationarity_deviation(fl[0], fl[2], p.n_sub)
    return {
        "fluct": fl,
        "variance": var,
        "variance_error": var_err,
        "t_int": t_int,
        "length_scale": t_int * speed,
        "ustar": ustar,
        "ustar_error": 0.25 * ustar * uw_err / abs(uw) if uw != 0 else np.nan,
        "speed": speed,
        "zl": zl,
        "itc": itc,
        "itc_u": itc_u,
        "rn": rn,
        "flag012": st.foken_flag(rn, itc),
    }


def _epsilon(
    fl: np.ndarray, r: np.ndarray, slopes: list[np.ndarray], p: SonicTurbulenceSettings
) -> dict[str, np.ndarray]:
    """eps per component from the inertial lags of the typed fits, errors by batch means."""
    n_lag = r.size
    d, _ = structure_function_fft(fl, n_lag)
    n_sub = p.n_sub
    sub_len = fl.shape[1] // n_sub
    sub_lags = min(n_lag, sub_len // 2)
    subs = fl[:, : sub_len * n_sub].reshape(3, n_sub, sub_len)
    d_sub, _ = structure_function_fft(subs, sub_lags)
    out = {k: np.full(3, np.nan) for k in ("eps", "err", "r_lo", "r_hi")}
    out["flag"] = np.zeros(3, dtype=np.int8)
    for c in range(3):
        if not np.isfinite(slopes[c]).any():
            out["flag"][c] = EPS_UNTYPED
            continue
        lags = st.inertial_lags(
            slopes[c], tolerance=p.slope_tolerance, min_points=p.min_inertial_points
        )
        if not lags.any():
            out["flag"][c] = EPS_NO_INERTIAL_RANGE
            continue
        e23 = dissipation.epsilon23_from_sf(r[lags], d[c][lags], SF_CONSTANTS[c])
        sub = lags[:sub_lags]
        e23_sub = (
            np.array(
                [
                    dissipation.epsilon23_from_sf(
                        r[:sub_lags][sub], d_sub[c, i][sub], SF_CONSTANTS[c]
                    )
                    for i in range(n_sub)
                ]
            )
            if sub.any()
            else np.full(n_sub, np.nan)
        )
        se23 = np.nanstd(e23_sub, ddof=1) / np.sqrt(np.isfinite(e23_sub).sum())
        out["eps"][c], out["err"][c] = dissipation.epsilon_from_structure_function_2_3(e23, se23)
        out["r_lo"][c], out["r_hi"][c] = r[lags][0], r[lags][-1]
    return out


def _combine(eps: np.ndarray, err: np.ndarray) -> tuple[float, float]:
    """Inverse-variance weighted mean of the component estimates and its error."""
    ok = np.isfinite(eps) & np.isfinite(err) & (err > 0)
    if not ok.any():
        return float("nan"), float("nan")
    wgt = 1.0 / err[ok] ** 2
    return float(np.sum(wgt * eps[ok]) / wgt.sum()), float(1.0 / np.sqrt(wgt.sum()))


@described("sonic_turbulence")
def sonic_turbulence(
    sonic: xr.Dataset,
    *,
    window_s: float = 1800.0,
    despike: str = "vickers_mahrt",
    rotation: str = "double",
    detrend: str = "linear",
    height_m: float | None = None,
    latitude_deg: float = 52.0,
    slope_tolerance: float = 0.1,
    min_inertial_points: int = 5,
    n_sub: int = 6,
    min_valid_fraction: float = 0.9,
    max_spike_fraction: float = 0.01,
    typing: dict | None = None,
) -> xr.Dataset:
    """The sonic turbulence product of a sonic dataset (method in the module doc).

    Parameters
    ----------
    sonic : xarray.Dataset
        Canonical sonic dataset: ``u``, ``v``, ``w`` (m s-1), optional ``temperature``
        (degC) and ``sample_flag``, attr ``sampling_rate_hz``.
    window_s : float
        Averaging window (s).
    despike : str
        ``"vickers_mahrt"``, ``"mauder"`` or ``"none"``.
    rotation : str
        ``"double"``, ``"planar_fit"`` (one plane fitted to the means of all windows of
        ``sonic``: give it days, not one window) or ``"none"``.
    detrend : str
        ``"linear"`` or ``"mean"``.
    height_m : float, optional
        Measurement height above the displacement height (m); without it the ITC test
        is not made (window_flag bit 8).
    latitude_deg : float
        Latitude (degree) for the Coriolis parameter of the ITC model.
    slope_tolerance : float
        Largest |d lg D/d lg r - 2/3| of an inertial-range lag.
    min_inertial_points : int
        Fewest lags of an inertial range.
    n_sub : int
        Sub-windows of the steady-state test and of the batch-means error of eps.
    min_valid_fraction : float
        Windows with fewer valid samples are not analysed (window_flag bit 1).
    max_spike_fraction : float
        Spike fraction above which window_flag bit 2 is set.
    typing : dict, optional
        Parameters of :func:`cwproc.stages.sonic_sf.structure_function_types` (besides
        ``window_s``).

    Returns
    -------
    xarray.Dataset
    """
    rate = _sampling_rate(sonic, rotation)
    params = SonicTurbulenceSettings(
        detrend, height_m, latitude_deg, slope_tolerance, min_inertial_points, n_sub
    )
    starts, grid3, temp_grid, valid_fraction = _gridded(sonic, window_s, rate)
    rotated, spike_fraction, angles, mean_uv = _despiked_rotated(grid3, despike, rotation, rate)
    sf = _typed(rotated, starts, rate, window_s, typing or {})
    analysed = valid_fraction >= min_valid_fraction
    result = _analyse_windows((starts, rotated, temp_grid), analysed, sf, rate, params)
    result["window_flag"][~analysed] |= FLAG_FEW_SAMPLES
    result["window_flag"][analysed & np.any(spike_fraction > max_spike_fraction, axis=1)] |= (
        FLAG_SPIKES
    )
    direction = geographic_wind_direction(
        mean_uv[:, 0], mean_uv[:, 1], float(sonic.attrs.get("orientation_deg", 0.0))
    )
    settings = {
        "window_s": window_s,
        "despike": despike,
        "rotation": rotation,
        **dataclasses.asdict(params),
        "height_m": "unknown" if height_m is None else height_m,
        "sampling_rate_hz": rate,
    }
    return _dataset(
        starts, result, spike_fraction, angles, direction, valid_fraction, settings, sonic
    )


@dataclass(frozen=True)
class SonicTurbulenceSettings:
    """The settings of the analysis of each window (:func:`sonic_turbulence`, whose
    parameters of the same names they are)."""

    #: ``"linear"`` or ``"mean"``
    detrend: str
    #: measurement height above the displacement height (m); None: no ITC test
    height_m: float | None
    #: latitude (degree) for the Coriolis parameter of the ITC model
    latitude_deg: float
    #: largest |d lg D/d lg r - 2/3| of an inertial-range lag
    slope_tolerance: float
    #: fewest lags of an inertial range
    min_inertial_points: int
    #: sub-windows of the steady-state test and of the batch-means error of eps
    n_sub: int


def _sampling_rate(sonic: xr.Dataset, rotation: str) -> float:
    """The sampling rate (Hz) of ``sonic``, which must have samples; a known rotation."""
    rate = float(sonic.attrs.get("sampling_rate_hz", np.nan))
    if not np.isfinite(rate) or rate <= 0:
        raise CwprocError("sonic dataset has no valid sampling_rate_hz attribute")
    if sonic.sizes.get("time", 0) == 0:
        raise CwprocError("sonic dataset has no samples")
    if rotation not in ("double", "planar_fit", "none"):
        raise CwprocError(f"sonic rotation {rotation!r}: use double, planar_fit or none")
    return rate


def _analyse_windows(
    windows: tuple[np.ndarray, np.ndarray, np.ndarray | None],
    analysed: np.ndarray,
    sf: xr.Dataset,
    rate: float,
    params: SonicTurbulenceSettings,
) -> dict[str, np.ndarray]:
    """The rows of every window (:func:`_analyse_window`); ``windows``: the starts, the
    rotated (W, 3, N) grid and the (W, N) temperature grid (or None); only the windows
    ``analysed`` (enough valid samples) are filled."""
    starts, rotated, temp_grid = windows
    sf_index = {np.datetime64(t, "ns"): i for i, t in enumerate(sf["time"].values)}
    result = _empty_result(starts.size)
    for w in np.flatnonzero(analysed).tolist():
        temp = temp_grid[w] if temp_grid is not None else None
        i = sf_index.get(np.datetime64(starts[w], "ns"))
        _analyse_window(result, w, rotated[w], temp, sf, i, rate, params)
    return result


def _gridded(
    sonic: xr.Dataset, window_s: float, rate: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """Window starts, (W, 3, N) grid of u, v, w, (W, N) temperature grid, valid fraction."""
    names = ["u", "v", "w"] + (["temperature"] if "temperature" in sonic else [])
    values = np.stack([np.asarray(sonic[n].values, dtype=float) for n in names])
    valid = np.isfinite(values)
    if "sample_flag" in sonic:
        valid &= (np.asarray(sonic["sample_flag"].values) == 0)[None, :]
    time = sonic["time"].values
    starts, grid3, counts = grid_windows(
        time, values[:3], valid[:3], window_s=window_s, rate_hz=rate
    )
    temp_grid = None
    if len(names) == 4:
        _, tg, _ = grid_windows(
            time,
            np.stack([values[3]] * 3),
            np.stack([valid[3]] * 3),
            window_s=window_s,
            rate_hz=rate,
        )
        temp_grid = tg[:, 0]
    return starts, grid3, temp_grid, counts / grid3.shape[2]


def _despiked_rotated(
    grid3: np.ndarray, despike: str, rotation: str, rate: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Despike and rotate every window: rotated grid, spike fraction, angles, mean u, v."""
    n_win = grid3.shape[0]
    rotated = np.full_like(grid3, np.nan)
    spike_fraction = np.full((n_win, 3), np.nan)
    angles = np.full((n_win, 2), np.nan)
    mean_uv = np.full((n_win, 2), np.nan)
    clean = np.empty_like(grid3)
    for w in range(n_win):
        for c in range(3):
            clean[w, c], spikes = _despike(grid3[w, c], despike, rate, c)
            spike_fraction[w, c] = spikes.sum() / max(np.isfinite(grid3[w, c]).sum(), 1)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows
        means = np.nanmean(clean, axis=2)  # (W, 3)
    mean_uv[:] = means[:, :2]
    plane = None
    if rotation == "planar_fit":
        try:
            plane = st.planar_fit(means[:, 0], means[:, 1], means[:, 2])
        except ValueError as exc:
            raise CwprocError(f"sonic rotation planar_fit: {exc}") from None
    for w in range(n_win):
        if rotation == "none" or not np.isfinite(clean[w]).any():
            rotated[w] = clean[w]
            continue
        if plane is None:
            *rot, yaw, pitch = st.double_rotation(*clean[w])
        else:
            *rot, yaw, pitch = st.planar_fit_rotation(*clean[w], *plane)
        rotated[w], angles[w] = np.stack(rot), (yaw, pitch)
    return rotated, spike_fraction, angles, mean_uv


def _typed(
    rotated: np.ndarray, starts: np.ndarray, rate: float, window_s: float, typing: dict
) -> xr.Dataset:
    """The SF types of the despiked, rotated windows (stage sf-type, the same windows)."""
    n_slots = rotated.shape[2]
    t_ns = starts[:, None] + (np.arange(n_slots) * (1e9 / rate)).astype("timedelta64[ns]")
    ok_t = np.all(np.isfinite(rotated), axis=1)
    typed_in = xr.Dataset(
        {k: (("time",), rotated[:, i][ok_t]) for i, k in enumerate(("u", "v", "w"))},
        coords={"time": (("time",), t_ns[ok_t])},
        attrs={"sampling_rate_hz": rate},
    )
    return structure_function_types(typed_in, window_s=window_s, **typing)


def _analyse_window(
    result: dict[str, np.ndarray],
    w: int,
    x: np.ndarray,
    temp: np.ndarray | None,
    sf: xr.Dataset,
    i: int | None,
    rate: float,
    params: SonicTurbulenceSettings,
) -> None:
    """Fill row ``w`` of ``result``: statistics, eps from the typed SF ``i``, flags."""
    s = _window_statistics(x, temp, rate, params)
    for key in ("variance", "variance_error", "t_int", "length_scale"):
        result[key][w] = s[key]
    for key in ("ustar", "ustar_error", "speed", "zl", "itc", "itc_u", "rn", "flag012"):
        result[key][w] = s[key]
    result["tke"][w] = 0.5 * np.sum(s["variance"])
    result["tke_error"][w] = 0.5 * np.sqrt(np.sum(s["variance_error"] ** 2))
    if i is None:
        result["eps_flag"][w] = EPS_UNTYPED
    else:
        r = np.asarray(sf["lag_distance"].values[i], dtype=float)
        slopes = [_typed_slope(sf, i, c, r) for c in range(3)]
        result["sf_type"][w] = sf["sf_type"].values[i]
        e = _epsilon(s["fluct"], r, slopes, params)
        result["eps_c"][w], result["eps_c_err"][w] = e["eps"], e["err"]
        result["r_lo"][w], result["r_hi"][w] = e["r_lo"], e["r_hi"]
        result["eps_flag"][w] = e["flag"]
        result["eps"][w], result["eps_err"][w] = _combine(e["eps"], e["err"])
        if np.isfinite(e["r_lo"][0]):
            k_range = (2 * np.pi / e["r_hi"][0], 2 * np.pi / e["r_lo"][0])
            result["eps_spec"][w] = dissipation.epsilon_from_inertial_spectrum(
                st.interpolate_gaps(s["fluct"][0], ~np.isfinite(s["fluct"][0])),
                rate,
                s["speed"],
                k_range,
            )
    if not np.isfinite(result["eps"][w]):
        result["window_flag"][w] |= FLAG_NO_EPSILON
    if not np.isfinite(s["itc"]):
        result["window_flag"][w] |= FLAG_ITC_UNTESTED
    ratio = result["eps_spec"][w] / result["eps_c"][w, 0]
    if np.isfinite(ratio) and not 0.5 <= ratio <= 2.0:
        result["window_flag"][w] |= FLAG_SPECTRUM_DISAGREES


def _empty_result(n_win: int) -> dict[str, np.ndarray]:
    nan1, nan3 = np.full(n_win, np.nan), np.full((n_win, 3), np.nan)
    return {
        "variance": nan3.copy(),
        "variance_error": nan3.copy(),
        "t_int": nan3.copy(),
        "length_scale": nan3.copy(),
        "eps_c": nan3.copy(),
        "eps_c_err": nan3.copy(),
        "r_lo": nan3.copy(),
        "r_hi": nan3.copy(),
        "eps_flag": np.full((n_win, 3), EPS_UNTYPED, dtype=np.int8),
        "sf_type": np.zeros((n_win, 3), dtype=np.int8),
        **{k: nan1.copy() for k in ("ustar", "ustar_error", "speed", "zl", "itc", "itc_u", "rn")},
        **{k: nan1.copy() for k in ("tke", "tke_error", "eps", "eps_err", "eps_spec")},
        "flag012": np.full(n_win, 2, dtype=np.int8),
        "window_flag": np.zeros(n_win, dtype=np.int8),
    }


def _dataset(
    starts: np.ndarray,
    res: dict[str, np.ndarray],
    spike_fraction: np.ndarray,
    angles: np.ndarray,
    direction: np.ndarray,
    valid_fraction: np.ndarray,
    settings: dict,
    sonic: xr.Dataset,
) -> xr.Dataset:
    wc, w1 = ("window", "component"), ("window",)
    ds = xr.Dataset(
        {
            "mean_wind_speed": (w1, res["speed"]),
            "wind_direction": (w1, direction),
            "yaw_angle": (w1, angles[:, 0]),
            "pitch_angle": (w1, angles[:, 1]),
            "velocity_variance": (wc, res["variance"]),
            "velocity_variance_error": (wc, res["variance_error"]),
            "tke": (w1, res["tke"]),
            "tke_error": (w1, res["tke_error"]),
            "friction_velocity": (w1, res["ustar"]),
            "friction_velocity_error": (w1, res["ustar_error"]),
            "integral_time_scale": (wc, res["t_int"]),
            "integral_length_scale": (wc, res["length_scale"]),
            "sf_type": (wc, res["sf_type"]),
            "inertial_range_min": (wc, res["r_lo"]),
            "inertial_range_max": (wc, res["r_hi"]),
            "epsilon_component": (wc, res["eps_c"]),
            "epsilon_component_error": (wc, res["eps_c_err"]),
            "epsilon_flag": (wc, res["eps_flag"]),
            "epsilon": (w1, res["eps"]),
            "epsilon_error": (w1, res["eps_err"]),
            "epsilon_spectrum": (w1, res["eps_spec"]),
            "spike_fraction": (wc, spike_fraction),
            "stability_parameter": (w1, res["zl"]),
            "stationarity_deviation": (w1, res["rn"]),
            "itc_deviation": (w1, res["itc"]),
            "itc_deviation_u": (w1, res["itc_u"]),
            "foken_flag": (w1, res["flag012"]),
            "window_flag": (w1, res["window_flag"]),
            "valid_fraction": (w1, valid_fraction),
        },
        coords={
            "time": (w1, starts),
            "component": (("component",), np.array(COMPONENTS)),
        },
    )
    ds["epsilon"].attrs["method"] = (
        "inverse-variance weighted mean of the component estimates from the inertial range "
        "of their second-order structure functions (fitting range from the SF type)"
    )
    ds.attrs.update(
        {
            "sampling_rate_hz": settings["sampling_rate_hz"],
            "window_s": settings["window_s"],
            "instrument": str(sonic.attrs.get("instrument", "")),
            "sonic_turbulence_parameters": str(settings),
        }
    )
    return ds
