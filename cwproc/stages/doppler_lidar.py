"""Stage ``doppler_lidar``: the Level-1 stare product (beta, depolarisation, screening).

The vertical stares of an instrument-day become one ``(time, range)`` product like the
ACTRIS Cloudnet ``doppler-lidar`` file: the background-corrected SNR (and the
instrument's, ``snr_uncorrected``), the radial velocity, the attenuated backscatter
beta with the telescope focus function (:mod:`cwproc.physics.backscatter`), the
depolarisation ratio when cross-polarised rays are given, the standard error of each,
and a screening flag.

Screening (:func:`screening_flags`) uses intensity and velocity together, the principle
of the Cloudnet noise mask (doppy 0.5) with cwproc's own statistics: noise SNR is
Gaussian about 0 with a standard deviation ``s`` measured on each ray (Manninen et al.
(2016): after the background correction the noise floor is flat), and noise velocities
are spread over the whole velocity search band, so the local median absolute deviation
(MAD) of velocity, its *texture*, is of the order of metres per second where there is
only noise and a few tenths where there is signal. A gate is signal when

* its box mean SNR exceeds ``snr_sigma`` standard errors of the noise (``s /
  sqrt(n_box)``), or
* its SNR is positive and its velocity texture is below ``texture_max_m_s`` (a weak
  signal whose velocities agree with their neighbours', e.g. the aerosol top),

and it is not in the near range (the first ``near_range_m``, three pulse lengths, as
Cloudnet). Velocity is kept where the gate is signal and the texture is below the
threshold.

Depolarisation: the paired cross ray's background-corrected SNR gets its noise floor
refitted on the co ray's noise gates (:func:`refit_cross_floor`), since the cross ray's
own signal-free-gate search takes its weak (delta times the co) layer for floor.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import xarray as xr
from scipy.ndimage import maximum_filter1d, median_filter, uniform_filter

from cwproc.metadata import described
from cwproc.physics.backscatter import (
    LidarConstants,
    attenuated_backscatter,
    depolarisation_ratio,
)
from cwproc.physics.snr_background import fit_noise_floor
from cwproc.stages.stare import noise_std_per_ray

#: flag bits of ``doppler_lidar_flag``
FLAG_NEAR_RANGE = 1
FLAG_LOW_SNR = 2
FLAG_VELOCITY_TEXTURE = 4
FLAG_NOT_FINITE = 8
FLAG_NO_CROSS = 16
#: the mask bits that make a gate noise whatever its other tests say
_ALWAYS_NOISE = FLAG_NEAR_RANGE | FLAG_NOT_FINITE
#: global attributes of the scans carried into the product
CARRIED_ATTRS = ("snr_correction", "background_files", "focus_range_m", "pulses_per_ray")


@dataclass(frozen=True)
class DopplerLidarOptions:
    """Settings of the L1 product (the ``[doppler_lidar]`` configuration section)."""

    constants: LidarConstants = field(default_factory=LidarConstants)
    #: gates nearer than this (m) are flagged (outgoing pulse; 3 pulse lengths)
    near_range_m: float = 90.0
    #: box of the local statistics: rays (time) x gates (range)
    box_rays: int = 5
    box_gates: int = 3
    #: box-mean SNR above this many noise standard errors is signal
    snr_sigma: float = 5.0
    #: velocity texture (local MAD, m s-1) below which a gate's velocities agree
    texture_max_m_s: float = 1.0
    #: polariser bleed-through b of the depolarisation ratio
    bleed_through: float = 0.0
    #: a cross ray pairs with a co ray within this many median co-ray intervals
    max_pair_intervals: float = 2.0
    #: pulse repetition frequency (Hz), for the accumulation time of a ray
    prf_hz: float = 15000.0
    #: and with the same pointing within this angle (deg)
    max_pair_angle_deg: float = 1.0


def ray_noise_std(
    snr: np.ndarray, range_m: np.ndarray, near_range_m: float, *, centred: bool = False
) -> np.ndarray:
    """Standard deviation of the noise SNR of each ray (rays, range) -> (rays,).

    Signal only adds to the SNR, so the values below the noise's centre are noise alone,
    however many gates hold signal: ``sd = median(c - x | x < c) / 0.6745`` (the median
    of a half-normal), over the gates beyond ``near_range_m``. The centre ``c`` is 0 for
    a background-corrected SNR (``centred``: Manninen et al. (2016) flatten the noise
    floor to intensity 1), else the median of the ray iterated three times on the values
    within 3 robust sd of it (the noise's when most gates are noise). A ray with fewer
    than 5 values below its centre gives NaN.
    """
    x = np.asarray(snr, dtype=float)[:, np.asarray(range_m) >= near_range_m]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        if centred:
            centre = np.zeros((x.shape[0], 1))
        else:
            keep = np.isfinite(x)
            for _ in range(3):
                y = np.where(keep, x, np.nan)
                centre = np.nanmedian(y, axis=1, keepdims=True)
                mad = 1.4826 * np.nanmedian(np.abs(y - centre), axis=1, keepdims=True)
                keep = np.isfinite(x) & (np.abs(x - centre) <= 3.0 * mad)
        below = np.isfinite(x) & (x < centre)
        sd = np.nanmedian(np.where(below, centre - x, np.nan), axis=1) / 0.6745
    return np.where(below.sum(axis=1) >= 5, sd, np.nan)


def velocity_texture(velocity: np.ndarray, box: tuple[int, int]) -> np.ndarray:
    """Local median absolute deviation of velocity over a (rays, gates) box (m s-1)."""
    v = np.asarray(velocity, dtype=float)
    v = np.where(np.isfinite(v), v, 0.0)
    med = median_filter(v, size=box, mode="nearest")
    return median_filter(np.abs(v - med), size=box, mode="nearest")


def screening_flags(
    snr: np.ndarray,
    velocity: np.ndarray,
    range_m: np.ndarray,
    noise_std: np.ndarray,
    options: DopplerLidarOptions = DopplerLidarOptions(),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flag bits of every gate and the beta and velocity masks (True: noise).

    Parameters
    ----------
    snr, velocity : numpy.ndarray
        (rays, range) background-corrected SNR and radial velocity (m s-1).
    range_m : numpy.ndarray
        Gate distances (m).
    noise_std : numpy.ndarray
        (rays,) noise SNR standard deviation (:func:`ray_noise_std`).

    Returns
    -------
    flags : numpy.ndarray of int
        Bits: 1 near range, 2 box-mean SNR below ``snr_sigma`` noise standard errors,
        4 velocity texture above ``texture_max_m_s``, 8 SNR or velocity not finite.
    beta_mask, velocity_mask : numpy.ndarray of bool
        Gates that are noise for beta (see the module docstring), and for velocity
        (those and every gate with bit 4).
    """
    s = np.asarray(snr, dtype=float)
    v = np.asarray(velocity, dtype=float)
    box = (int(options.box_rays), int(options.box_gates))
    finite = np.isfinite(s) & np.isfinite(v)
    box_mean = uniform_filter(np.where(finite, s, 0.0), size=box, mode="nearest")
    threshold = (
        options.snr_sigma * np.asarray(noise_std, dtype=float)[:, None] / np.sqrt(box[0] * box[1])
    )
    with np.errstate(invalid="ignore"):
        low = ~(box_mean > threshold)
    textured = velocity_texture(v, box) > options.texture_max_m_s
    flags = np.zeros(s.shape, dtype=np.int16)
    flags[:, np.asarray(range_m) < options.near_range_m] |= FLAG_NEAR_RANGE
    flags[low] |= FLAG_LOW_SNR
    flags[textured] |= FLAG_VELOCITY_TEXTURE
    flags[~finite] |= FLAG_NOT_FINITE
    with np.errstate(invalid="ignore"):
        weak_but_coherent = (s > 0) & ~textured
    signal = (~low | weak_but_coherent) & ((flags & _ALWAYS_NOISE) == 0)
    return flags, ~signal, ~signal | textured


def pair_rays(
    co_time: np.ndarray,
    co_pointing: np.ndarray,
    cross_time: np.ndarray,
    cross_pointing: np.ndarray,
    max_dt: np.timedelta64,
    max_angle_deg: float,
) -> np.ndarray:
    """Index of the cross-polarised ray paired with each co-polarised ray (-1: none).

    The nearest cross ray in time, when it is within ``max_dt`` and points the same way
    (elevation and azimuth within ``max_angle_deg``; ``*_pointing`` are (rays, 2)
    arrays of elevation and azimuth in degrees, azimuth ignored for vertical rays).
    """
    ct = np.asarray(co_time, dtype="datetime64[ns]")
    xt = np.asarray(cross_time, dtype="datetime64[ns]")
    if xt.size == 0:
        return np.full(ct.size, -1)
    order = np.argsort(xt, kind="stable")
    xs = xt[order]
    pos = np.searchsorted(xs, ct)
    before = np.clip(pos - 1, 0, xs.size - 1)
    after = np.clip(pos, 0, xs.size - 1)
    nearer_after = np.abs(xs[after] - ct) < np.abs(xs[before] - ct)
    nearest = np.where(nearer_after, after, before)
    idx = order[nearest]
    close = np.abs(xs[nearest] - ct) <= max_dt
    cp, xp = np.asarray(co_pointing, dtype=float), np.asarray(cross_pointing, dtype=float)[idx]
    d_el = np.abs(cp[:, 0] - xp[:, 0])
    d_az = np.abs((cp[:, 1] - xp[:, 1] + 180.0) % 360.0 - 180.0)
    vertical = np.abs(cp[:, 0] - 90.0) < max_angle_deg
    same = (d_el <= max_angle_deg) & (vertical | (d_az <= max_angle_deg))
    return np.where(close & same, idx, -1)


def refit_cross_floor(
    snr_cross: np.ndarray,
    snr_co: np.ndarray,
    co_signal: np.ndarray,
    range_m: np.ndarray,
    options: DopplerLidarOptions = DopplerLidarOptions(),
    *,
    widen_gates: int = 2,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Background-corrected cross SNR with its noise floor refitted on gates free of
    co-polarised signal.

    The cross channel's signal is ``delta`` times the co channel's (Vakkari et al.
    (2021), eq. 1), so it is weaker by ``delta`` and its own per-gate search for
    signal-free gates (Manninen et al. (2016), step 2) takes much of it for noise floor:
    the floor comes out high and the cross SNR, hence ``delta``, low (on pairs
    re-measured from the Eriswil stare, ``SNR_x - delta SNR_co`` was -4 and -8 standard
    errors at delta 0.1 and 0.3). A gate without co signal has no cross signal either,
    so the floor ``F = a + b r`` of Manninen et al. (2016) is fitted again to
    ``1 + SNR_x`` on the gates where the co ray shows no signal: not signal by the
    screening (``co_signal``), widened by ``widen_gates`` on each side, and a box-mean co
    SNR (the screening's box) not above 0, which also leaves out the weak co signal
    below the screening's threshold (the co and cross noise are independent, so
    choosing gates by the co SNR does not bias the cross noise there); beyond
    ``near_range_m``. Then ``SNR_x' = (1 + SNR_x) / F - 1``. Rays with fewer than
    ``MIN_NOISE_GATES`` such gates keep their SNR.

    Parameters
    ----------
    snr_cross, snr_co : numpy.ndarray
        (rays, range) corrected cross SNR on the co rays' grid and the co SNR.
    co_signal : numpy.ndarray of bool
        (rays, range) the co gates the screening calls signal.
    range_m : numpy.ndarray
        Gate distances (m).
    options : DopplerLidarOptions
        The screening box and ``near_range_m``.

    Returns
    -------
    snr : numpy.ndarray
        The refitted cross SNR.
    floor : numpy.ndarray
        (rays,) median of the refitted floor over range (NaN: not refitted).
    floor_se : numpy.ndarray
        (rays, range) standard error of the refitted floor (0: not refitted), an error
        common to the gates of a ray that the cross SNR's noise sd does not hold (large
        where the floor is extrapolated, e.g. a layer filling most of the ray).
    """
    x = np.asarray(snr_cross, dtype=float)
    co = np.asarray(snr_co, dtype=float)
    r = np.asarray(range_m, dtype=float)
    box = (int(options.box_rays), int(options.box_gates))
    box_mean = uniform_filter(np.where(np.isfinite(co), co, 0.0), size=box, mode="nearest")
    signal = maximum_filter1d(
        np.asarray(co_signal, dtype=bool).astype(np.uint8), 2 * widen_gates + 1, axis=1
    ).astype(bool) | ~(box_mean <= 0.0)
    noise = ~signal & (r >= options.near_range_m)[None, :] & np.isfinite(x)
    floor, _ = fit_noise_floor(1.0 + x, r, noise)
    fitted = np.isfinite(floor).all(axis=1)
    out = np.where(fitted[:, None], (1.0 + x) / floor - 1.0, x)
    return out, np.where(fitted, np.median(floor, axis=1), np.nan), _line_se(x, r, noise, floor)


def _line_se(x: np.ndarray, r: np.ndarray, noise: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Standard error of a least-squares line at every gate, ``s sqrt(1/n + (r -
    r_mean)^2 / S_rr)`` with ``s`` the residual sd over the ``noise`` gates (0 where
    the line was not fitted)."""
    n = noise.sum(axis=1).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        resid = np.where(noise, 1.0 + x - floor, 0.0)
        s = np.sqrt((resid**2).sum(axis=1) / (n - 2.0))
        r_mean = (noise * r).sum(axis=1) / n
        s_rr = (noise * (r[None, :] - r_mean[:, None]) ** 2).sum(axis=1)
        se = s[:, None] * np.sqrt(
            1.0 / n[:, None] + (r[None, :] - r_mean[:, None]) ** 2 / s_rr[:, None]
        )
    return np.where(np.isfinite(se), se, 0.0)


def _corrected(ds: xr.Dataset) -> bool:
    """Whether every ray's SNR was background-corrected (its noise centred on 0)."""
    if "background_time" not in ds:
        return False
    return bool((~np.isnat(np.asarray(ds["background_time"].values))).all())


def pair_tolerance(co: xr.Dataset, options: DopplerLidarOptions) -> np.timedelta64:
    """Largest time between paired rays: ``max_pair_intervals`` times the median
    interval of the co rays, or of one ray's accumulation time (pulses per ray / PRF)
    when the co rays are fewer than two (an hourly file cut to one ray)."""
    dt = np.diff(np.sort(np.asarray(co["time"].values, dtype="datetime64[ns]")))
    if dt.size:
        step = float(np.median(dt) / np.timedelta64(1, "s"))
    else:
        step = float(co.attrs.get("pulses_per_ray", 0) or 0) / options.prf_hz
    return np.timedelta64(round(step * options.max_pair_intervals * 1e9), "ns")


def _pointing(ds: xr.Dataset) -> np.ndarray:
    return np.column_stack(
        [np.asarray(ds["elevation"].values, float), np.asarray(ds["azimuth"].values, float)]
    )


@described("doppler_lidar")
def doppler_lidar_product(
    stares: xr.Dataset,
    cross: xr.Dataset | None = None,
    options: DopplerLidarOptions = DopplerLidarOptions(),
    notes: list[str] | None = None,
) -> xr.Dataset:
    """The L1 product of the vertical stares of an instrument-day.

    Parameters
    ----------
    stares : xarray.Dataset
        Canonical scan dataset of the co-polarised (or only) stare rays, its ``snr``
        background-corrected when background files were found (``snr_uncorrected``
        then holds the instrument's).
    cross : xarray.Dataset, optional
        The cross-polarised stare rays (their own background correction applied), paired
        with ``stares`` by time and pointing (:func:`pair_rays`).
    options : DopplerLidarOptions
    notes : list of str, optional
        Receives how many rays were paired.

    Returns
    -------
    xarray.Dataset
        dims ``(time, range)``: ``snr``, ``snr_uncorrected``, ``snr_error``,
        ``radial_velocity``, ``radial_velocity_error`` (Pearson et al. (2009), eq. 3, from
        the SNR; NaN where it is not positive), ``beta``, ``beta_error``, ``beta_screened``,
        ``radial_velocity_screened``, ``doppler_lidar_flag``; with ``cross``:
        ``snr_cross``, ``beta_cross``, ``depolarisation``, ``depolarisation_error``,
        ``depolarisation_screened``; coords ``height(range)``, ``elevation(time)``,
        ``azimuth(time)``, ``background_time(time)`` when corrected.
    """
    rng = np.asarray(stares["range"].values, dtype=float)
    snr = np.asarray(stares["snr"].values, dtype=float)
    vel = np.asarray(stares["radial_velocity"].values, dtype=float)
    focus = float(stares.attrs.get("focus_range_m", np.inf) or np.inf)
    noise = ray_noise_std(snr, rng, options.near_range_m, centred=_corrected(stares))
    flags, beta_mask, vel_mask = screening_flags(snr, vel, rng, noise, options)
    beta = attenuated_backscatter(snr, rng, focus, options.constants)
    unit_beta = attenuated_backscatter(np.ones(1), rng, focus, options.constants)
    beta_err = noise[:, None] * unit_beta[None, :]
    el = np.asarray(stares["elevation"].values, dtype=float)
    height = rng * np.sin(np.deg2rad(float(np.nanmedian(el)) if el.size else 90.0))
    snr0 = stares["snr_uncorrected"].values if "snr_uncorrected" in stares else snr
    dims = ("time", "range")
    data = {
        "snr": (dims, snr),
        "snr_uncorrected": (dims, np.asarray(snr0, dtype=float)),
        "snr_error": ("time", noise),
        "radial_velocity": (dims, vel),
        "radial_velocity_screened": (dims, np.where(vel_mask, np.nan, vel)),
        "radial_velocity_error": (dims, noise_std_per_ray(stares)),
        "beta": (dims, beta),
        "beta_screened": (dims, np.where(beta_mask, np.nan, beta)),
        "beta_error": (dims, np.broadcast_to(beta_err, beta.shape).copy()),
        "doppler_lidar_flag": (dims, flags),
    }
    if cross is not None:
        extra = _cross_variables(stares, cross, snr, noise, rng, focus, beta_mask, options, notes)
        data["doppler_lidar_flag"] = (dims, flags | extra.pop("doppler_lidar_flag")[1])
        data.update(extra)
    coords = {
        "time": ("time", stares["time"].values),
        "range": ("range", rng),
        "height": ("range", height),
        "elevation": ("time", el),
        "azimuth": ("time", np.asarray(stares["azimuth"].values, dtype=float)),
    }
    if "background_time" in stares:
        data["background_time"] = ("time", stares["background_time"].values)
    out = xr.Dataset(data, coords=coords)
    out.attrs = {k: stares.attrs[k] for k in CARRIED_ATTRS if k in stares.attrs}
    out.attrs.update(_method_attrs(options, focus))
    if cross is not None:  # the cross-polarised files and the backgrounds that corrected them
        out.attrs["cross_files"] = list(
            cross.attrs.get("cross_files", cross.attrs.get("source_files", []))
        )
        out.attrs["cross_background_files"] = list(cross.attrs.get("background_files", []))
    return out


def _cross_variables(
    co: xr.Dataset,
    cross: xr.Dataset,
    snr: np.ndarray,
    noise: np.ndarray,
    rng: np.ndarray,
    focus: float,
    beta_mask: np.ndarray,
    options: DopplerLidarOptions,
    notes: list[str] | None,
) -> dict[str, tuple]:
    """Cross-polarised SNR, beta and the depolarisation ratio on the co rays' grid."""
    dims = ("time", "range")
    n_rays, n_gates = snr.shape
    x_rng = np.asarray(cross["range"].values, dtype=float)
    snr_x = np.full(snr.shape, np.nan)
    noise_x = np.full((n_rays, 1), np.nan)
    floor_x = np.full(n_rays, np.nan)
    floor_se = np.zeros(snr.shape)
    idx = np.full(n_rays, -1)
    if x_rng.shape == rng.shape and np.allclose(x_rng, rng, atol=1.0):
        max_dt = pair_tolerance(co, options)
        idx = pair_rays(
            co["time"].values,
            _pointing(co),
            cross["time"].values,
            _pointing(cross),
            max_dt,
            options.max_pair_angle_deg,
        )
        got = idx >= 0
        x_snr = np.asarray(cross["snr"].values, dtype=float)
        snr_x[got] = x_snr[idx[got]]
        centred = _corrected(cross)
        if centred and got.any():  # the co channel's noise gates are the cross channel's
            refit, floor, floor_se = refit_cross_floor(snr_x, snr, ~beta_mask, rng, options)
            snr_x[got], floor_x[got] = refit[got], floor[got]
        noise_x = ray_noise_std(snr_x, rng, options.near_range_m, centred=centred)[:, None]
        noise_x = np.sqrt(noise_x**2 + floor_se**2)
    elif notes is not None:
        notes.append(
            f"depolarisation not computed: the cross-polarised rays have {x_rng.size} gates "
            f"(or other ranges), the co-polarised {n_gates}"
        )
    delta, delta_se = depolarisation_ratio(
        snr, snr_x, noise[:, None], noise_x, options.bleed_through
    )
    unpaired = idx < 0
    flags = np.zeros((n_rays, n_gates), dtype=np.int16)
    flags[unpaired, :] = FLAG_NO_CROSS
    if notes is not None:
        notes.append(
            f"depolarisation: {int((~unpaired).sum())} of {n_rays} co-polarised stare rays "
            f"paired with a cross-polarised ray (Vakkari et al. (2021))"
        )
    beta_x = attenuated_backscatter(snr_x, rng, focus, options.constants)
    return {
        "snr_cross": (dims, snr_x),
        "beta_cross": (dims, beta_x),
        "depolarisation": (dims, delta),
        "depolarisation_error": (dims, delta_se),
        "depolarisation_screened": (dims, np.where(beta_mask | unpaired[:, None], np.nan, delta)),
        "cross_time": ("time", _paired_times(cross, idx)),
        "cross_floor_refit": ("time", floor_x),
        "doppler_lidar_flag": (dims, flags),
    }


def _paired_times(cross: xr.Dataset, idx: np.ndarray) -> np.ndarray:
    t = np.full(idx.shape, np.datetime64("NaT"), dtype="datetime64[ns]")
    got = idx >= 0
    t[got] = np.asarray(cross["time"].values, dtype="datetime64[ns]")[idx[got]]
    return t


def _method_attrs(options: DopplerLidarOptions, focus: float) -> dict[str, object]:
    c = options.constants
    return {
        "beta_method": (
            "heterodyne lidar equation solved for beta with the focus function of a "
            "focused Gaussian beam (Pentikäinen et al. (2020), eqs. 1-3); uncalibrated "
            "instrument constants"
        ),
        "lidar_wavelength_m": c.wavelength_m,
        "lidar_receiver_bandwidth_hz": c.receiver_bandwidth_hz,
        "lidar_pulse_energy_j": c.pulse_energy_j,
        "lidar_effective_diameter_m": c.effective_diameter_m,
        "lidar_quantum_efficiency": c.quantum_efficiency,
        "telescope_focus_m": focus if np.isfinite(focus) else -1.0,
        "screening_method": (
            f"signal: box ({options.box_rays} rays x {options.box_gates} gates) mean SNR "
            f"> {options.snr_sigma:g} noise standard errors, or SNR > 0 with velocity "
            f"texture (box MAD) < {options.texture_max_m_s:g} m s-1; not within "
            f"{options.near_range_m:g} m; velocity also needs the texture test "
            "(principle of the Cloudnet/doppy noise mask on intensity and velocity; noise "
            "statistics of Manninen et al. (2016))"
        ),
        "polariser_bleed_through": options.bleed_through,
    }
