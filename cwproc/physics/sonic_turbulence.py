"""Eddy-covariance screening and turbulence statistics of one sonic-anemometer window.

Pure numpy functions on the samples of one averaging window (typically 30 min):

* coordinate rotation: double rotation (Kaimal & Finnigan (1994); Wilczak et al.
  (2001), eqs. 22-23: yaw into the mean wind, then pitch until the mean w vanishes) or
  planar fit (Wilczak et al. (2001), eqs. 39-45);
* despiking: Vickers & Mahrt (1997) (moving-window mean +/- k sigma, runs of at most
  three points, k raised each pass) or Mauder et al. (2013), eq. 1 (median +/- q
  MAD/0.6745); constants as in EddyPro's engine (``TestSpikeDetection``,
  ``TestSpikeDetectionMauder13``) and checked against EC-PeT (docs/sonic.md);
* detrending: linear least squares or block mean;
* the dissipation rate from the inertial range of the second-order structure function,
  D_ii(r) = C_ii eps^(2/3) r^(2/3) with C_11 = C_2 = 2.0 and C_22 = C_33 = 4/3 C_2
  (Pope (2000), eqs. 6.28-6.30), and from the longitudinal spectrum
  E_11(k) = C_1 eps^(2/3) k^(-5/3), C_1 = 18/55 * 1.5 (Pope (2000), eq. 6.246);
* integral time scale (autocorrelation integrated to its first zero, Kaimal &
  Finnigan (1994)), the random error of a variance, sqrt(2 T / T_avg) (Lenschow et al.
  (1994)), friction velocity (Weber (1999));
* the steady-state test and the integral turbulence characteristics of Foken &
  Wichura (1996) with the ITC models of Foken et al. (2004), ch. 9, and Thomas & Foken
  (2002), and the 0-1-2 flag of Mauder & Foken (2004).
"""

from __future__ import annotations

import numpy as np

#: Kolmogorov constant of the longitudinal second-order structure function, C_2
#: (Pope (2000), eq. 6.30; Sreenivasan (1995))
C2_LONGITUDINAL = 2.0
#: transverse structure-function constant, 4/3 C_2 (isotropy, Pope (2000), eq. 6.29)
C2_TRANSVERSE = 4.0 / 3.0 * C2_LONGITUDINAL
#: longitudinal one-dimensional spectrum constant C_1 = 18/55 C, C = 1.5 (Pope (2000),
#: eq. 6.246)
C1_LONGITUDINAL = 18.0 / 55.0 * 1.5
#: von Karman constant and gravity
VON_KARMAN = 0.4
GRAVITY = 9.81
#: Earth's angular velocity (rad s-1)
OMEGA_EARTH = 7.2921e-5

#: Vickers & Mahrt (1997), spike test: moving window L1 = 5 min; first-pass threshold
#: 3.5 sigma, raised by 0.1 sigma each pass until a pass finds no new spike; only runs
#: of at most 3 consecutive outliers are spikes; more than 1 % spikes is a hard flag.
#: The numbers are those of EddyPro's engine (TestSpikeDetection: lim_step = 0.1,
#: max_pass = 10; GUI defaults sr_num_spk = 3, sr_lim_u = 3.5, sr_lim_w = 5.0,
#: sr_lim_hf = 1 %) and of EC-PeT (L1 = 300 s, 3.5 sigma, 3 points, 1 %); 5.0 sigma for
#: w, whose tails are wider, is EddyPro's default, kept here (docs/sonic.md).
VM97_WINDOW_S = 300.0
VM97_FACTOR = 3.5
VM97_FACTOR_W = 5.0
VM97_INCREMENT = 0.1
VM97_MAX_PASSES = 10
SPIKE_MAX_RUN = 3
SPIKE_HARD_FLAG_FRACTION = 0.01
#: Mauder et al. (2013), eq. 1: q = 7 median absolute deviations scaled by 0.6745 (the
#: MAD of a standard normal law), as EddyPro's TestSpikeDetectionMauder13 (zlim = 7)
MAUDER_Q = 7.0
MAD_NORMAL = 0.6745


# --------------------------------------------------------------------------------------
# rotation, detrending, despiking
# --------------------------------------------------------------------------------------


def double_rotation(
    u: np.ndarray, v: np.ndarray, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """Rotate a window into the mean streamline: mean v = 0, then mean w = 0.

    Wilczak et al. (2001), eqs. 22-23 (Kaimal & Finnigan (1994)): the yaw
    gamma = atan2(v_mean, u_mean) turns u into the mean horizontal wind; the pitch
    alpha = atan2(w_mean, u1_mean) then tilts it into the mean flow.

    Parameters
    ----------
    u, v, w : ndarray, shape (N,)
        Instrument-frame components (m s-1); NaN samples are left out of the means.

    Returns
    -------
    u2, v2, w2 : ndarray
        Streamline components (m s-1).
    yaw, pitch : float
        The two angles (degree).
    """
    yaw = np.arctan2(np.nanmean(v), np.nanmean(u))
    u1 = u * np.cos(yaw) + v * np.sin(yaw)
    v1 = -u * np.sin(yaw) + v * np.cos(yaw)
    pitch = np.arctan2(np.nanmean(w), np.nanmean(u1))
    u2 = u1 * np.cos(pitch) + w * np.sin(pitch)
    w2 = -u1 * np.sin(pitch) + w * np.cos(pitch)
    return u2, v1, w2, float(np.degrees(yaw)), float(np.degrees(pitch))


def planar_fit(
    mean_u: np.ndarray, mean_v: np.ndarray, mean_w: np.ndarray
) -> tuple[np.ndarray, float]:
    """Planar fit of the window means: the unit normal of the mean-streamline plane.

    Least squares of w_mean = b0 + b1 u_mean + b2 v_mean over many windows (Wilczak et
    al. (2001), eqs. 39-40); the plane's unit normal (the new z axis, instrument frame)
    is k = (-b1, -b2, 1) / sqrt(b1^2 + b2^2 + 1) (eq. 42) and b0 the offset of w.

    Parameters
    ----------
    mean_u, mean_v, mean_w : ndarray, shape (W,)
        Window means in the instrument frame (m s-1); NaN windows are left out.

    Returns
    -------
    normal : ndarray, shape (3,)
    offset : float
        b0 (m s-1).

    Raises
    ------
    ValueError
        Fewer than 3 windows, or their mean winds do not span a plane.
    """
    ok = np.isfinite(mean_u) & np.isfinite(mean_v) & np.isfinite(mean_w)
    if ok.sum() < 3:
        raise ValueError("planar fit needs at least 3 windows")
    a = np.column_stack([np.ones(ok.sum()), mean_u[ok], mean_v[ok]])
    coef, _, rank, _ = np.linalg.lstsq(a, mean_w[ok], rcond=None)
    if rank < 3:
        raise ValueError("planar fit: the windows' mean winds do not span a plane")
    b0, b1, b2 = coef
    normal = np.array([-b1, -b2, 1.0]) / np.sqrt(b1 * b1 + b2 * b2 + 1.0)
    return normal, float(b0)


def planar_fit_rotation(
    u: np.ndarray, v: np.ndarray, w: np.ndarray, normal: np.ndarray, offset: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """Rotate a window into the planar-fit frame, then yaw into its mean wind.

    The z axis becomes ``normal`` (:func:`planar_fit`) after removing ``offset`` from w
    (Wilczak et al. (2001), eqs. 42-44: pitch then roll of the instrument); the yaw then
    turns x into the window's mean horizontal wind of the tilted plane (eq. 45), so that
    mean v = 0 and mean w is what the plane leaves (not forced to zero).

    Returns
    -------
    u2, v2, w2 : ndarray
    yaw, tilt : float
        Yaw (degree) and the angle between the instrument's z and the normal (degree).
    """
    k = np.asarray(normal, dtype=float)
    i0 = np.array([1.0, 0.0, 0.0]) - k[0] * k  # instrument x projected on the plane
    i0 /= np.linalg.norm(i0)
    j0 = np.cross(k, i0)
    x = np.stack([u, v, w - offset])
    up, vp, wp = i0 @ x, j0 @ x, k @ x
    yaw = np.arctan2(np.nanmean(vp), np.nanmean(up))
    u2 = up * np.cos(yaw) + vp * np.sin(yaw)
    v2 = -up * np.sin(yaw) + vp * np.cos(yaw)
    return u2, v2, wp, float(np.degrees(yaw)), float(np.degrees(np.arccos(np.clip(k[2], -1, 1))))


def detrend(x: np.ndarray, how: str = "linear") -> np.ndarray:
    """Fluctuations about a least-squares line (``"linear"``) or the mean (``"mean"``).

    NaN samples stay NaN and are left out of the fit.
    """
    ok = np.isfinite(x)
    if ok.sum() < 2:
        return np.full_like(x, np.nan)
    if how == "mean":
        return x - np.mean(x[ok])
    if how != "linear":
        raise ValueError(f"detrend: unknown method {how!r} (linear or mean)")
    t = np.arange(x.size, dtype=float)
    slope, intercept = np.polyfit(t[ok], x[ok], 1)
    return x - (intercept + slope * t)


def _moving_mean_std(x: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Centred moving mean and standard deviation over ``width`` samples (NaN skipped)."""
    ok = np.isfinite(x)
    xs = np.where(ok, x, 0.0)
    c0 = np.concatenate([[0.0], np.cumsum(ok)])
    c1 = np.concatenate([[0.0], np.cumsum(xs)])
    c2 = np.concatenate([[0.0], np.cumsum(xs * xs)])
    n = x.size
    idx = np.arange(n)
    lo = np.clip(idx - width // 2, 0, n)
    hi = np.clip(lo + width, 0, n)
    lo = np.clip(hi - width, 0, n)
    cnt = c0[hi] - c0[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (c1[hi] - c1[lo]) / cnt
        var = (c2[hi] - c2[lo]) / cnt - mean * mean
    return mean, np.sqrt(np.maximum(var, 0.0))


def _short_runs(mask: np.ndarray, max_run: int) -> np.ndarray:
    """The True samples of ``mask`` that belong to runs of at most ``max_run`` samples."""
    padded = np.concatenate([[False], mask, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    starts, ends = edges[::2], edges[1::2]
    out = np.zeros_like(mask)
    for s, e in zip(starts, ends, strict=True):
        if e - s <= max_run:
            out[s:e] = True
    return out


def interpolate_gaps(x: np.ndarray, gaps: np.ndarray) -> np.ndarray:
    """``x`` with the samples at ``gaps`` replaced by linear interpolation of the others."""
    out = x.copy()
    good = ~gaps & np.isfinite(x)
    if gaps.any() and good.sum() >= 2:
        t = np.arange(x.size)
        out[gaps] = np.interp(t[gaps], t[good], x[good])
    return out


def despike_vickers_mahrt(
    x: np.ndarray,
    rate_hz: float,
    *,
    window_s: float = VM97_WINDOW_S,
    factor: float = VM97_FACTOR,
    increment: float = VM97_INCREMENT,
    max_run: int = SPIKE_MAX_RUN,
    max_passes: int = VM97_MAX_PASSES,
) -> tuple[np.ndarray, np.ndarray]:
    """Despike a series by the moving-window test of Vickers & Mahrt (1997).

    A sample departing from the mean of a centred moving window of ``window_s`` (5 min;
    at the ends the first or last full window) by more than ``factor`` standard
    deviations of that window is an outlier; runs of at most ``max_run`` (3) consecutive
    outliers are spikes (longer runs are taken as physical and kept) and are replaced by
    linear interpolation. The test is repeated, with the factor raised by ``increment``
    each pass, until a pass finds no new spike or after ``max_passes`` passes (Vickers &
    Mahrt (1997), spike test: 3.5 sigma, +0.1 per pass, L1 = 5 min, runs of 3 or fewer
    points; more than 1 % spikes is their hard flag). Defaults: :data:`VM97_FACTOR`
    (u, v, T; use :data:`VM97_FACTOR_W` = 5.0 for w as EddyPro does),
    :data:`VM97_INCREMENT`, :data:`VM97_MAX_PASSES` (EddyPro's ``max_pass``).

    Verified against EC-PeT 2.1.0b1 ``ecpre.vmspike`` (tests/physics/
    test_sonic_reference.py): the same spikes, sample for sample, at 3.5 sigma.

    Parameters
    ----------
    x : ndarray, shape (N,)
        Samples (NaN: missing, not touched).
    rate_hz : float
        Sampling rate (Hz).
    window_s : float
        Moving-window length (s).
    factor : float
        First-pass threshold (standard deviations of the window).
    increment : float
        Rise of the threshold per pass (standard deviations).
    max_run : int
        Longest run of outliers that is a spike (samples).
    max_passes : int
        Most passes.

    Returns
    -------
    cleaned : ndarray
        ``x`` with spikes interpolated.
    spikes : ndarray of bool
        The samples found to be spikes.
    """
    width = max(round(window_s * rate_hz), 3)
    out = np.asarray(x, dtype=float).copy()
    spikes = np.zeros(out.size, dtype=bool)
    k = factor
    for _ in range(max_passes):
        mean, std = _moving_mean_std(out, width)
        with np.errstate(invalid="ignore"):
            outlier = np.abs(out - mean) > k * std
        new = _short_runs(outlier, max_run) & ~spikes
        if not new.any():
            break
        spikes |= new
        out = interpolate_gaps(out, new)
        k += increment
    return out, spikes


def despike_mauder(
    x: np.ndarray, *, q: float = MAUDER_Q, max_run: int = SPIKE_MAX_RUN
) -> tuple[np.ndarray, np.ndarray]:
    """Despike a series by the median absolute deviation test of Mauder et al. (2013).

    Samples outside Md - q MAD/0.6745 <= x <= Md + q MAD/0.6745 are spikes, with Md the
    median of the window and MAD the median of |x - Md| (Mauder et al. (2013), eq. 1,
    q = 7 (:data:`MAUDER_Q`); 0.6745 (:data:`MAD_NORMAL`) makes MAD/0.6745 the standard
    deviation of a normal law). As in :func:`despike_vickers_mahrt` and EddyPro's
    ``TestSpikeDetectionMauder13`` (runs of at most ``sr_num_spk`` = 3), only runs of at
    most ``max_run`` samples count as spikes; they are replaced by linear interpolation.
    One pass: the median and MAD hardly move when the few spikes are replaced.

    Verified against EC-PeT 2.1.0b1 ``ecpre.madspike`` with its threshold set to
    7/0.6745 MAD (tests/physics/test_sonic_reference.py): the same spikes, except that
    EC-PeT, having no run-length rule, also takes the samples of longer bursts.

    Returns
    -------
    cleaned, spikes : ndarray
    """
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x)
    if ok.sum() < 3:
        return x.copy(), np.zeros(x.size, dtype=bool)
    md = np.median(x[ok])
    mad = np.median(np.abs(x[ok] - md))
    with np.errstate(invalid="ignore"):
        outlier = np.abs(x - md) > q * mad / MAD_NORMAL
    spikes = _short_runs(outlier & ok, max_run)
    return interpolate_gaps(x, spikes), spikes


# --------------------------------------------------------------------------------------
# second-order statistics and their errors
# --------------------------------------------------------------------------------------


def integral_time_scale(x: np.ndarray, rate_hz: float) -> float:
    """Integral time scale T (s): the autocorrelation integrated up to its first zero.

    Kaimal & Finnigan (1994), section 2.6. Missing samples are set to zero (the
    fluctuation's mean) before the FFT autocorrelation.
    """
    x = np.where(np.isfinite(x), x, 0.0)
    n = x.size
    if n < 4 or not np.any(x):
        return float("nan")
    f = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(f * np.conj(f), 2 * n)[:n]
    acf /= acf[0]
    below = np.flatnonzero(acf <= 0)
    stop = below[0] if below.size else n
    # trapezoid from lag 0 to the first zero crossing
    return float((np.sum(acf[:stop]) - 0.5 * acf[0]) / rate_hz)


def variance_random_error(variance: float, t_int: float, t_avg: float) -> float:
    """Random error (1 sigma) of a variance: variance sqrt(2 T / T_avg).

    Lenschow et al. (1994): for T_avg >> T, the relative error of the second moment of
    a Gaussian process is sqrt(2 T / T_avg), T the integral time scale.
    """
    return float(abs(variance) * np.sqrt(2.0 * max(t_int, 0.0) / t_avg))


def covariance_random_error(cov: float, correlation: float, t_int: float, t_avg: float) -> float:
    """Random error (1 sigma) of a covariance F = <w'x'>: |F| sqrt(2T/T_avg (1 + r^-2)).

    Lenschow et al. (1994): relative error of a flux with correlation coefficient r.
    """
    if not np.isfinite(correlation) or correlation == 0:
        return float("nan")
    return float(abs(cov) * np.sqrt(2.0 * max(t_int, 0.0) / t_avg * (1.0 + correlation**-2)))


def friction_velocity(uw: float, vw: float) -> float:
    """u_* = (<u'w'>^2 + <v'w'>^2)^(1/4) (m s-1), Weber (1999)."""
    return float((uw * uw + vw * vw) ** 0.25)


# --------------------------------------------------------------------------------------
# dissipation rate
# --------------------------------------------------------------------------------------


def local_slope(x: np.ndarray, sf_type: int, coef: dict[str, float]) -> np.ndarray:
    """d lg D / d lg r of the fitted model of a structure-function type at x = lg(r/r_N).

    Gladkikh et al. (2014), eqs. 4-6: type 1 mu; type 2 a1 + 2 a2 x; type 3
    d1 + 2 d2 x up to x_s = lg(r_s/r_N), gamma beyond.
    """
    x = np.asarray(x, dtype=float)
    if sf_type == 1:
        return np.full_like(x, coef["mu"])
    if sf_type == 2:
        return coef["a1"] + 2.0 * coef["a2"] * x
    if sf_type == 3:
        return np.where(x <= coef["x_s"], coef["d1"] + 2.0 * coef["d2"] * x, coef["gamma"])
    return np.full_like(x, np.nan)


def inertial_lags(slope: np.ndarray, *, tolerance: float, min_points: int) -> np.ndarray:
    """The longest run of lags whose model slope is within ``tolerance`` of 2/3.

    Parameters
    ----------
    slope : ndarray, shape (K,)
        Local slope of the typed fit at each lag (NaN beyond the fit).
    tolerance : float
        Largest |slope - 2/3| of an inertial-range lag.
    min_points : int
        Fewest lags of an inertial range.

    Returns
    -------
    ndarray of bool, shape (K,)
        The inertial-range lags (all False when there is none).
    """
    with np.errstate(invalid="ignore"):
        near = np.abs(slope - 2.0 / 3.0) <= tolerance
    padded = np.concatenate([[False], near, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    out = np.zeros(slope.size, dtype=bool)
    if edges.size:
        lengths = edges[1::2] - edges[::2]
        best = int(np.argmax(lengths))
        if lengths[best] >= min_points:
            out[edges[2 * best] : edges[2 * best + 1]] = True
    return out


# --------------------------------------------------------------------------------------
# Foken & Wichura (1996) tests
# --------------------------------------------------------------------------------------


def stationarity_deviation(a: np.ndarray, b: np.ndarray, n_sub: int = 6) -> float:
    """Steady-state test of a covariance (%), Foken & Wichura (1996).

    RN = |<cov_i> - cov| / |cov| x 100 with cov_i the covariances of ``n_sub``
    sub-windows (5 min in 30 min), each about its own means, and cov that of the whole
    window.
    """
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 2 * n_sub:
        return float("nan")

    def cov(x: np.ndarray, y: np.ndarray, m: np.ndarray) -> float:
        return float(np.mean((x[m] - x[m].mean()) * (y[m] - y[m].mean())))

    full = cov(a, b, ok)
    parts = []
    for idx in np.array_split(np.arange(a.size), n_sub):
        m = ok[idx]
        if m.sum() >= 2:
            parts.append(cov(a[idx], b[idx], m))
    if full == 0 or not parts:
        return float("nan")
    return float(abs((np.mean(parts) - full) / full) * 100.0)


#: z+ = 1 m of the neutral ITC models (Thomas & Foken (2002))
ITC_Z_PLUS_M = 1.0


def coriolis_parameter(latitude_deg: float) -> float:
    """|f| = 2 Omega |sin(latitude)| (s-1)."""
    return float(2.0 * OMEGA_EARTH * abs(np.sin(np.radians(latitude_deg))))


def itc_model_sigma_w(z_over_l: float, z_m: float, latitude_deg: float, ustar: float) -> float:
    """Modelled sigma_w / u_* of the integral turbulence characteristics test.

    Foken et al. (2004), ch. 9, ITC model table (after Foken & Wichura (1996):
    sigma_w/u_* = c1 |z/L|^c2 with c1 = 2.0, c2 = 1/8 for z/L < -0.032), with the
    neutral range replaced by that of Thomas & Foken (2002), their eq. for w:

    * -3 < z/L <= -0.2: 2.0 |z/L|^(1/8);
    * -0.2 < z/L < 0.4: 0.21 ln(z_+ f / u_*) + 3.1, z_+ = 1 m, f the Coriolis
      parameter;
    * NaN outside (-3, 0.4) (no published model) and at the equator (f = 0).

    These are TK3's functions (Mauder & Foken (2011)) as EC-PeT 2.1.0b1 transcribes them
    (``ecpost.itc_w``), checked in tests/physics/test_sonic_reference.py. EddyPro's
    engine uses 1.3 (1 - 2 z/L)^(1/3) for z/L < -0.2 instead (Goeckede et al. (2004)).
    ``z_m`` is not used by these models (kept for the call signature).
    """
    if not np.isfinite(z_over_l) or ustar <= 0:
        return float("nan")
    if -0.2 < z_over_l < 0.4:
        f = coriolis_parameter(latitude_deg)
        return float(0.21 * np.log(ITC_Z_PLUS_M * f / ustar) + 3.1) if f > 0 else float("nan")
    if -3.0 < z_over_l <= -0.2:
        return float(2.0 * abs(z_over_l) ** (1.0 / 8.0))
    return float("nan")


def itc_model_sigma_u(z_over_l: float, latitude_deg: float, ustar: float) -> float:
    """Modelled sigma_u / u_* of the integral turbulence characteristics test.

    Foken et al. (2004), ch. 9 (Foken & Wichura (1996): c1 = 4.15, c2 = 1/8 for
    z/L < -0.032; Thomas & Foken (2002) near neutral): -3 < z/L <= -0.2:
    4.15 |z/L|^(1/8); -0.2 < z/L < 0.4:
    0.44 ln(z_+ f / u_*) + 6.3, z_+ = 1 m; NaN outside (-3, 0.4). As TK3 and EC-PeT
    (``ecpost.itc_u``) and, for these ranges, EddyPro's engine.
    """
    if not np.isfinite(z_over_l) or ustar <= 0:
        return float("nan")
    if -0.2 < z_over_l < 0.4:
        f = coriolis_parameter(latitude_deg)
        return float(0.44 * np.log(ITC_Z_PLUS_M * f / ustar) + 6.3) if f > 0 else float("nan")
    if -3.0 < z_over_l <= -0.2:
        return float(4.15 * abs(z_over_l) ** (1.0 / 8.0))
    return float("nan")


def itc_deviation(measured: float, modelled: float) -> float:
    """ITC = |(model - measured) / model| x 100 (%), Foken & Wichura (1996)."""
    if not (np.isfinite(measured) and np.isfinite(modelled)) or modelled == 0:
        return float("nan")
    return float(abs((modelled - measured) / modelled) * 100.0)


def foken_flag(stationarity_pct: float, itc_pct: float) -> int:
    """The 0-1-2 quality flag of Mauder & Foken (2004) from the two test deviations.

    0 (high quality, fundamental research): both <= 30 %; 1 (general use): both
    <= 100 %; 2 (discard) otherwise. Mauder & Foken (2004) (TK2 documentation) define it
    on the deviation classes of Foken et al. (2004), ch. 9 (1: 0-15 %, 2: 16-30 %, ...,
    5: 76-100 %, ...): 0 = both classes 1-2, 1 = both classes 1-5, 2 otherwise; this is
    EddyPro's ``GTK2Flag`` (``mauder_foken_04``), which classes the percentages after
    truncation to integers (30.9 % is class 2 there, above 30 % here). An ITC that
    cannot be evaluated (NaN: stability outside the models' range) is not held against
    the window (EddyPro gives 2); a stationarity that cannot be evaluated gives 2.
    """
    if not np.isfinite(stationarity_pct):
        return 2
    itc = itc_pct if np.isfinite(itc_pct) else 0.0
    worst = max(stationarity_pct, itc)
    if worst <= 30.0:
        return 0
    if worst <= 100.0:
        return 1
    return 2


def obukhov_stability(z_m: float, ustar: float, wt: float, t_mean_k: float) -> float:
    """z/L with L = -u_*^3 T / (kappa g <w'T'>) (sonic temperature, K)."""
    if not (np.isfinite(wt) and np.isfinite(ustar)) or ustar <= 0 or t_mean_k <= 0:
        return float("nan")
    return float(-z_m * VON_KARMAN * GRAVITY * wt / (ustar**3 * t_mean_k))
