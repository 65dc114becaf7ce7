"""Virtual continuous-wave (cw) Doppler lidar: Doppler spectra and the centroid estimate.

Banakh et al. (1999), eqs. 2-14: the probe-volume weighting Q_s, the Doppler spectrum
W_s of eq. 3 built from the radial velocities along the beam, the centroid velocity
estimator of eq. 4 under conditions (5)-(10), the exclusion of spectra whose peak lies
below 1 m s-1, and homodyne detection (only |V_r| is measured).

Q_s as printed in Banakh et al. (1999) after eq. 3 lacks a square: with z_d = k0 a0^2,
k0 = 2 pi / lambda, the weight is
Q_s(z) = {pi z_d [(1 - z/R)^2 + (z/z_d)^2]}^(-1), a Lorentzian centred at
z_c = R / (1 + (R/z_d)^2) with half width w = z_R / (1 + (R/z_d)^2),
z_R = lambda R^2 / (2 pi a0^2) (the paper's Delta z equals pi z_R). The part behind
the lidar (z < 0, up to 9 % at R = 1000 m) is cut and Q_s renormalised.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc import progress
from cwproc.io.scan_netcdf import write_scan_netcdf
from cwproc.physics.correlation import (
    CorrelationModel,
    ScanGeometry,
    wind_vector,
)
from cwproc.physics.cw_probe import cw_probe_quadrature, focal_parameter, probe_grid
from cwproc.physics.dissipation import epsilon_from_integral_scale
from cwproc.physics.geometry import beam_unit_vector_une
from cwproc.sim.output import fresh_folder, write_truth
from cwproc.sim.turbulence import (
    along_beam_fluctuations,
    probe_weighted_moments,
    scan_cholesky,
    simulate_scan_velocities,
)

try:  # optional C extension (setup.py): the sums of _sinc2_sum, the same numbers
    from cwproc.sim import _sinc2
except ImportError:  # pragma: no cover - depends on the build
    _sinc2 = None

#: exclusion threshold of Banakh et al. (1999), section 3: spectra with k_max dV < 1 m/s
MIN_PEAK_VELOCITY = 1.0
#: along-beam points (scans x spectra x probe points) whose spectra are made at once
_POINTS_PER_BLOCK = 1_000_000


# --------------------------------------------------------------------------------------
# Doppler spectra and the centroid estimator
# --------------------------------------------------------------------------------------


def doppler_spectrum(
    radial_velocity: np.ndarray,
    q: np.ndarray,
    *,
    resolution: float,
    n_channels: int,
    first_channel_velocity: float = 0.0,
    homodyne: bool = True,
) -> np.ndarray:
    """Doppler spectrum W_s(k dV), Banakh et al. (1999), eq. 3.

    W_s(k) = sum_i q_i sinc^2{pi (k - V_r,i / dV)}, sum_i q_i = 1 (the factor dr/dV of
    eq. 3 with q_i = dr Q_s(dr i)); homodyne: V_r,i -> |V_r,i|.

    Parameters
    ----------
    radial_velocity : numpy.ndarray
        V_r along the beam, shape (..., M') (m s-1).
    q : numpy.ndarray
        Weights, shape (M',).
    resolution : float
        dV (m s-1).
    n_channels : int
        M_D.
    first_channel_velocity : float
        Velocity of channel 0 (m s-1); 0 for a homodyne system.
    homodyne : bool

    Returns
    -------
    numpy.ndarray
        Shape (..., M_D), in units of 1/(channel): sum over channels ~ 1.
    """
    v = np.abs(radial_velocity) if homodyne else np.asarray(radial_velocity, dtype=float)
    x = (v - first_channel_velocity) / resolution  # (..., M')
    lead, n_points = x.shape[:-1], x.shape[-1]
    x = x.reshape(-1, n_points)
    out = np.empty((x.shape[0], n_channels))
    for start in range(0, x.shape[0], _SPECTRA_PER_BLOCK):
        block = slice(start, start + _SPECTRA_PER_BLOCK)
        out[block] = _sinc2_sum(x[block], q, n_channels)
    return out.reshape(*lead, n_channels)


#: spectra computed together by :func:`_sinc2_sum` (their channels stay in the cache)
_SPECTRA_PER_BLOCK = 256
#: whether :func:`_sinc2_sum` uses the C extension when it is built (tests compare both)
_use_extension = True


def _sinc2_sum(x: np.ndarray, q: np.ndarray, n_channels: int) -> np.ndarray:
    """sum_i q_i sinc^2{pi (k - x_i)} for k = 0..n_channels-1, x of shape (N, M').

    For integer k, sin^2{pi (k - x)} = sin^2(pi x), so each term is
    a_i / (k - x_i)^2 with a_i = q_i sin^2(pi x_i) / pi^2: one subtraction, product and
    division per channel and point, the sines taken once per point, of x_i less its
    nearest integer (Banakh et al. (1999), eq. 3). A spectrum with a point exactly on a
    channel (0/0 there) is summed with numpy's sinc instead. The sums run in the
    optional C extension ``cwproc.sim._sinc2`` when it is built (the same operations in
    the same order: the same numbers, about 3x faster), else in numpy.
    """
    k = np.arange(n_channels, dtype=float)
    a = q * (np.sin(np.pi * (x - np.round(x))) / np.pi) ** 2  # exact reduction of the sine
    total = np.zeros((x.shape[0], n_channels))
    if _sinc2 is not None and _use_extension:
        x = np.ascontiguousarray(x, dtype=np.float64)
        a = np.ascontiguousarray(a, dtype=np.float64)
        _sinc2.sum(x, a, x.shape[0], x.shape[1], n_channels, total)
    else:
        term = np.empty_like(total)
        with np.errstate(divide="ignore", invalid="ignore"):
            for i in range(x.shape[1]):
                np.subtract(k, x[:, i : i + 1], out=term)
                np.multiply(term, term, out=term)
                np.divide(a[:, i : i + 1], term, out=term)
                total += term
    bad = ~np.isfinite(total).all(axis=1)
    if bad.any():
        total[bad] = np.einsum("nik,i->nk", np.sinc(k - x[bad][..., None]) ** 2, q)
    return total


@dataclass(frozen=True)
class CentroidResult:
    """Output of :func:`centroid_velocity` (arrays of the leading shape).

    Attributes
    ----------
    velocity : numpy.ndarray
        V_D (m s-1), NaN where excluded.
    valid : numpy.ndarray
        bool: the peak is not below 1 m s-1 (and the window holds at least one channel
        either side).
    width : numpy.ndarray
        sigma_s, :func:`spectral_width` (m s-1).
    full_window : numpy.ndarray
        bool: the window k1 dV >> sigma_s of condition (10) fitted inside the channels
        (conditions 5-6); False where the coarser estimate with k1 <= k_max was used.
    """

    velocity: np.ndarray
    valid: np.ndarray
    width: np.ndarray
    full_window: np.ndarray


def spectral_width(spectrum: np.ndarray, resolution: float) -> np.ndarray:
    """Effective width sigma_s of a Doppler spectrum (m s-1), Banakh et al. (1999), eq. 7.

    Half the distance between the 16th and 84th percentiles of the spectral
    distribution (a robust second moment: the sinc^2 tails of eq. 3 give the plain
    second moment no finite limit).

    Parameters
    ----------
    spectrum : numpy.ndarray
        Shape (..., M_D).
    resolution : float
        dV (m s-1).
    """
    cdf = np.cumsum(spectrum, axis=-1)
    cdf = cdf / cdf[..., -1:]
    k16 = np.argmax(cdf >= 0.16, axis=-1)
    k84 = np.argmax(cdf >= 0.84, axis=-1)
    return 0.5 * (k84 - k16) * resolution


def centroid_velocity(
    spectrum: np.ndarray,
    *,
    resolution: float,
    first_channel_velocity: float = 0.0,
    width_factor: float = 6.0,
    min_half_window: int = 5,
    min_peak_velocity: float = MIN_PEAK_VELOCITY,
) -> CentroidResult:
    """Centroid velocity estimate V_D of a Doppler spectrum, Banakh et al. (1999), eq. 4.

    V_D = dV [k_max + sum_{k=-k1}^{k1} k W(k_max + k) / S^], S^ = sum W(k_max + k).
    sigma_s is :func:`spectral_width`; k1 = max(min_half_window,
    ceil(width_factor sigma_s / dV)) so that sigma_s << k1 dV (condition 10) and the
    window holds the sinc^2 side lobes of eq. 3 (their asymmetric truncation biases a
    narrow window by up to dV/5). Where conditions (5) k1 <= k_max or (6)
    k_max + k1 <= M_D - 1 would fail, k1 is reduced to fit (the paper's coarser
    estimate, flagged in ``full_window``). A spectrum is valid when its peak velocity
    |dV k_max| is not below ``min_peak_velocity`` (section 3: near-zero peaks are
    dropped because the sign and the estimate are unreliable there).

    Parameters
    ----------
    spectrum : numpy.ndarray
        Shape (..., M_D).
    resolution : float
        dV (m s-1).
    first_channel_velocity : float
        Velocity of channel 0 (m s-1).
    width_factor : float
        k1 dV / sigma_s.
    min_half_window : int
        Smallest k1 (channels).
    min_peak_velocity : float
        Exclusion threshold (m s-1).

    Returns
    -------
    CentroidResult
    """
    w = np.asarray(spectrum, dtype=float)
    n_channels = w.shape[-1]
    kmax = np.argmax(w, axis=-1)
    sigma_s = spectral_width(w, resolution)
    wanted = np.maximum(min_half_window, np.ceil(width_factor * sigma_s / resolution)).astype(int)
    # conditions (5), (6): the window must stay inside the channels; where it cannot,
    # the paper's coarser estimate with k1 <= k_max is used and flagged
    k1 = np.minimum(wanted, np.minimum(kmax, n_channels - 1 - kmax))
    k = np.arange(n_channels)
    offset = k - kmax[..., None]
    window = np.abs(offset) <= k1[..., None]
    s_hat = np.sum(np.where(window, w, 0.0), axis=-1)
    first = np.sum(np.where(window, offset * w, 0.0), axis=-1)
    velocity = first_channel_velocity + resolution * (kmax + first / s_hat)
    peak_velocity = first_channel_velocity + resolution * kmax
    valid = (k1 >= 1) & (np.abs(peak_velocity) >= min_peak_velocity)
    return CentroidResult(np.where(valid, velocity, np.nan), valid, sigma_s, k1 == wanted)


# --------------------------------------------------------------------------------------
# cw scans -> canonical scan dataset
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CWLidar:
    """A cw conically scanning lidar (geometry, optics, spectral processing).

    Attributes
    ----------
    name : str
    wavelength_m, beam_radius_m : float
        lambda and a0 (m).
    elevation_deg : float
        phi, beam elevation (deg); Banakh et al. (1999): 30, ZephIR: 60 (30 deg from vertical).
    scan_period_s : float
        T (s); Banakh et al. (1999): 7, ZephIR: 1.
    spectra_per_scan : int
        T / t0; Banakh et al. (1999): 140 (t0 = 50 ms), ZephIR: 50.
    velocity_resolution_m_s : float
        dV (m s-1).
    n_channels : int
        M_D.
    homodyne : bool
    """

    name: str = "cw Doppler lidar (Banakh et al. 1999)"
    wavelength_m: float = 10.6e-6
    beam_radius_m: float = 0.075
    elevation_deg: float = 30.0
    scan_period_s: float = 7.0
    spectra_per_scan: int = 140
    velocity_resolution_m_s: float = 0.1
    n_channels: int = 256
    homodyne: bool = True

    @property
    def first_channel_velocity(self) -> float:
        """Velocity of channel 0 (m s-1): 0 for a homodyne system (|V_r|), and for a
        heterodyne one (signed V_r) the channels span -M_D dV / 2 ... +M_D dV / 2."""
        return 0.0 if self.homodyne else -0.5 * self.n_channels * self.velocity_resolution_m_s

    @property
    def z_r_coefficient(self) -> float:
        """c of z_R = c R^2 (1/m)."""
        return 1.0 / focal_parameter(self.wavelength_m, self.beam_radius_m)

    @property
    def geometry(self) -> ScanGeometry:
        return ScanGeometry(self.elevation_deg, self.spectra_per_scan, self.scan_period_s)


#: ZephIR 300: 1.575 um, Z_R = 0.0013 R^2 -> a0 = sqrt(lambda/(2 pi 0.0013)), 1 s rotation,
#: 50 line-of-sight spectra per rotation, 30 deg from vertical (Wagner et al. (DTU))
ZEPHIR = CWLidar(
    name="ZephIR 300 (cwproc simulator)",
    wavelength_m=1.575e-6,
    beam_radius_m=float(np.sqrt(1.575e-6 / (2.0 * np.pi * 0.0013))),
    elevation_deg=60.0,
    scan_period_s=1.0,
    spectra_per_scan=50,
    velocity_resolution_m_s=0.1,
    n_channels=256,
    homodyne=True,
)


def along_beam_offsets(
    focus_range: float, elevation_deg: float, n_azimuths: int, dr: float
) -> np.ndarray:
    """Start index N_m of spectrum m in the along-beam series, Banakh et al. (1999), eq. 14.

    N_m = [2 R cos(phi) (m - 1) dtheta / dr], m = 1..M (as printed).
    """
    dtheta = 2.0 * np.pi / n_azimuths
    m = np.arange(n_azimuths)
    return np.floor(2.0 * focus_range * np.cos(np.deg2rad(elevation_deg)) * m * dtheta / dr).astype(
        int
    )


def simulate_cw_height(
    rng: np.random.Generator,
    lidar: CWLidar,
    *,
    height_m: float,
    wind_speed: float,
    wind_direction_deg: float,
    sigma2: float,
    outer_scale_m: float,
    n_scans: int,
    model: CorrelationModel = "exponential",
    quadrature_nodes: int = 40,
) -> tuple[np.ndarray, np.ndarray]:
    """Centroid velocities of ``n_scans`` independent scans at one height.

    V_r(dr i, m) = V_D(m) + Delta V_r(dr i) (Banakh et al. (1999), eqs. 13-14) with
    V_D by Cholesky (eqs. 15, 20-21) and Delta V_r from an along-beam FFT series
    (eq. 23); spectra by eq. 3 and velocities by eq. 4.

    Returns
    -------
    (velocity, truth) : numpy.ndarray
        velocity: centroid estimates (NaN where excluded), shape (n_scans, M);
        truth: the probe-averaged signed radial velocity V_D, same shape (m s-1).
    """
    geometry = lidar.geometry
    focus = height_m / np.sin(np.deg2rad(lidar.elevation_deg))
    wind = wind_vector(wind_speed, wind_direction_deg)
    quad = cw_probe_quadrature(focus, lidar.wavelength_m, lidar.beam_radius_m, quadrature_nodes)
    factor = scan_cholesky(geometry, quad, float(outer_scale_m), tuple(wind), model)
    s = beam_unit_vector_une(geometry.azimuth_deg, lidar.elevation_deg)
    vd = s @ wind + simulate_scan_velocities(rng, factor, sigma2, (n_scans,))
    dr, q = probe_grid(focus, lidar.wavelength_m, lidar.beam_radius_m)
    offsets = along_beam_offsets(focus, lidar.elevation_deg, geometry.n_azimuths, dr)
    n = int(offsets[-1] + q.size + 1)
    series = along_beam_fluctuations(rng, n, dr, sigma2, outer_scale_m, (n_scans,), model)
    mean, _ = probe_weighted_moments(series, q, offsets)
    idx = offsets[:, None] + np.arange(q.size)[None, :]
    velocity = np.empty_like(vd)
    per_block = max(1, _POINTS_PER_BLOCK // idx.size)
    for start in range(0, n_scans, per_block):  # all the scans of a block at once
        scans = slice(start, start + per_block)
        dv = series[scans][:, idx] - mean[scans][:, :, None]  # eq. 14
        vr = vd[scans][:, :, None] + dv  # eq. 13
        spec = doppler_spectrum(
            vr,
            q,
            resolution=lidar.velocity_resolution_m_s,
            n_channels=lidar.n_channels,
            first_channel_velocity=lidar.first_channel_velocity,
            homodyne=lidar.homodyne,
        )
        velocity[scans] = centroid_velocity(
            spec,
            resolution=lidar.velocity_resolution_m_s,
            first_channel_velocity=lidar.first_channel_velocity,
        ).velocity
    return velocity, vd


def simulate_cw_scans(
    rng: np.random.Generator,
    lidar: CWLidar,
    *,
    heights_m: np.ndarray,
    wind_speed: np.ndarray,
    wind_direction_deg: float,
    sigma2: np.ndarray,
    outer_scale_m: np.ndarray,
    n_scans: int,
    start: np.datetime64,
    model: CorrelationModel = "exponential",
) -> tuple[xr.Dataset, np.ndarray]:
    """cw line-of-sight scans as a canonical scan dataset (homodyne: |V_r|).

    Every height is scanned with the same ray times (as if the focus were switched
    instantly; Banakh et al. (1999) simulate each height independently). The
    ``range`` dimension holds the focus distances R = h / sin(phi). A
    ``reference_direction(ray)`` (a wind vane: true direction + 5 deg rms noise)
    lets the homodyne VAD fit resolve the 180 deg ambiguity.

    Returns
    -------
    (dataset, truth) : xarray.Dataset, numpy.ndarray
        The scan dataset and the true signed V_D, shape (ray, range).
    """
    heights_m = np.atleast_1d(np.asarray(heights_m, dtype=float))
    m = lidar.spectra_per_scan
    n_rays = n_scans * m
    velocity = np.empty((n_rays, heights_m.size))
    truth = np.empty_like(velocity)
    for j, h in progress.track(list(enumerate(heights_m)), desc="heights", unit="height"):
        vel, vd = simulate_cw_height(
            rng,
            lidar,
            height_m=float(h),
            wind_speed=float(np.atleast_1d(wind_speed)[j % np.size(wind_speed)]),
            wind_direction_deg=wind_direction_deg,
            sigma2=float(np.atleast_1d(sigma2)[j % np.size(sigma2)]),
            outer_scale_m=float(np.atleast_1d(outer_scale_m)[j % np.size(outer_scale_m)]),
            n_scans=n_scans,
            model=model,
        )
        velocity[:, j] = vel.ravel()
        truth[:, j] = vd.ravel()
    # a wind vane next to the lidar (as the ZephIR's met station): it resolves the
    # 180 deg ambiguity of the homodyne VAD fit; 5 deg rms error
    vane = (wind_direction_deg + 5.0 * rng.standard_normal(n_rays)) % 360.0
    t0 = lidar.scan_period_s / m
    time = np.datetime64(start, "ns") + np.round(np.arange(n_rays) * t0 * 1e9).astype(
        "timedelta64[ns]"
    )
    azimuth = np.tile(lidar.geometry.azimuth_deg, n_scans)
    ds = xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), velocity),
            "snr": (("ray", "range"), np.where(np.isfinite(velocity), 100.0, 0.0)),
            "reference_direction": (("ray",), vane),
        },
        coords={
            "time": ("ray", time),
            "azimuth": ("ray", azimuth),
            "elevation": ("ray", np.full(n_rays, lidar.elevation_deg)),
            "range": ("range", heights_m / np.sin(np.deg2rad(lidar.elevation_deg))),
            "scan": ("ray", np.repeat(np.arange(n_scans), m).astype("int64")),
        },
        attrs={
            "instrument": lidar.name,
            "instrument_kind": "cw",
            "system_id": "sim",
            "source_files": [],
            "scan_type": "VAD",
            "gate_length_m": 0.0,
            "homodyne": int(lidar.homodyne),
            "wavelength_m": lidar.wavelength_m,
            "beam_radius_m": lidar.beam_radius_m,
            "z_r_coefficient": lidar.z_r_coefficient,
            "scan_period_s": lidar.scan_period_s,
            "velocity_resolution_m_s": lidar.velocity_resolution_m_s,
        },
    )
    return ds, truth


def write_cw_series(
    folder: str | os.PathLike,
    truth_path: str | os.PathLike,
    rng: np.random.Generator,
    lidar: CWLidar,
    *,
    heights_m: np.ndarray,
    wind_speed: np.ndarray,
    wind_direction_deg: float,
    sigma2: np.ndarray,
    outer_scale_m: np.ndarray,
    n_scans: int,
    start: np.datetime64,
    scans_per_file: int = 10,
) -> list[Path]:
    """Simulate cw scans and write them as cwproc scan NetCDF files plus a truth JSON.

    Parameters
    ----------
    folder : path
        Folder of the line-of-sight files ``cw_<yyyymmdd>_<hhmmss>.nc`` (created; old
        ``cw_*.nc`` files in it are removed).
    truth_path : path
        Truth JSON (profiles of U, sigma_V^2, L_V, epsilon); keep it out of ``folder``.
    scans_per_file : int
        Scans per NetCDF file.
    Other parameters
        As :func:`simulate_cw_scans`.

    Returns
    -------
    list of pathlib.Path
        Files written, truth last.
    """

    folder = fresh_folder(folder, "cw_*.nc")
    ds, _ = simulate_cw_scans(
        rng,
        lidar,
        heights_m=heights_m,
        wind_speed=wind_speed,
        wind_direction_deg=wind_direction_deg,
        sigma2=sigma2,
        outer_scale_m=outer_scale_m,
        n_scans=n_scans,
        start=start,
    )
    written = []
    block = ds["scan"].values // scans_per_file
    for k in np.unique(block):
        part = ds.isel(ray=np.flatnonzero(block == k))
        part = part.assign_coords(scan=part["scan"] - part["scan"].values[0])
        stamp = np.datetime_as_string(part["time"].values[0], unit="s")
        name = "cw_" + stamp.replace("-", "").replace(":", "").replace("T", "_") + ".nc"
        part.attrs["source_files"] = [name]
        written.append(write_scan_netcdf(part, folder / name))
    h = np.atleast_1d(np.asarray(heights_m, dtype=float))
    full = [
        np.broadcast_to(np.asarray(x, dtype=float), h.shape)
        for x in (wind_speed, sigma2, outer_scale_m)
    ]
    truth = {
        "description": "truth of a simulated cw lidar series (cwproc virtual instrument)",
        "instrument": lidar.name,
        "heights_m": h.tolist(),
        "focus_range_m": (h / np.sin(np.deg2rad(lidar.elevation_deg))).tolist(),
        "wind_speed_m_s": full[0].tolist(),
        "wind_direction_deg": float(wind_direction_deg),
        "velocity_variance_m2_s2": full[1].tolist(),
        "integral_scale_m": full[2].tolist(),
        "epsilon_m2_s3": epsilon_from_integral_scale(full[1], full[2]).tolist(),
        "correlation_model": "Banakh et al. (1999), eq. 17",
        "n_scans": int(n_scans),
        "scan_period_s": lidar.scan_period_s,
        "homodyne": bool(lidar.homodyne),
    }
    written.append(write_truth(truth_path, truth))
    return written
