"""Vertical stares (and a daily cycle of stares and VADs) of the virtual Stream Line.

A vertical stare sees ``w`` of the frozen field carried past the beam by the mean wind
(Taylor's hypothesis, Smalikho (2020), eq. 7): the ray of duration ``t`` averages the
field over ``sub_points`` instants of its dwell and, along the beam, with the pulsed
range weighting of :func:`cwproc.sim.pulsed.range_quadrature`. The cycle writes, every
``vad_every_s`` seconds, one VAD (:func:`cwproc.sim.pulsed.sample_conical_scans`) of the
*same* field at the same clock, so the VAD (Smalikho (2020)) and stare (O'Connor et al.
(2010)) dissipation rates can be compared with each other and with the truth.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.sim.field3d import FrozenField
from cwproc.sim.pulsed import (
    range_quadrature,
    sample_conical_scans,
    streamline_scans,
    wind_components,
)

#: field points interpolated at once (memory bound)
_CHUNK_POINTS = 2_000_000


def sample_vertical_stare(
    field: FrozenField,
    *,
    ranges_m: np.ndarray,
    n_rays: int,
    ray_duration_s: float,
    wind_speed_m_s: float,
    wind_direction_deg: float,
    noise_std_m_s: float,
    seed: int,
    start_offset_s: float = 0.0,
    start_time: str | np.datetime64 = "2024-01-01T00:00:00",
    sub_points: int = 4,
    delta_p_m: float = 15.3,
    delta_r_m: float = 18.0,
    snr: float = 0.05,
    pulses_per_ray: int = 20000,
) -> xr.Dataset:
    """Vertical stare rays through a frozen field advected by the mean wind.

    Parameters
    ----------
    field : FrozenField
    ranges_m : numpy.ndarray
        Gate centres (m), straight up.
    n_rays : int
        Consecutive rays, each ``ray_duration_s`` long (s).
    wind_speed_m_s, wind_direction_deg : float
        Mean horizontal wind (m s-1, from deg).
    noise_std_m_s : float
        White estimation noise sigma_e (m s-1).
    seed : int
        Seed of the noise.
    start_offset_s : float
        Clock of the first ray's start (s from ``start_time``): the field has moved
        ``U start_offset_s`` by then.
    sub_points : int
        Instants averaged within each ray's dwell.
    delta_p_m, delta_r_m : float
        Range weighting (m), Smalikho (2020), eq. 19.
    snr : float
        Linear SNR written.
    pulses_per_ray : int
        Written to the attributes; the ray duration is ``pulses / 15 kHz`` on a Stream
        Line, so choose them consistent (20000 pulses: 1.33 s).

    Returns
    -------
    xarray.Dataset
        Canonical scan dataset, ``scan_type`` "Stare", elevation 90 deg.
    """
    ranges = np.asarray(ranges_m, dtype=float)
    s_nodes, s_weights = range_quadrature(delta_p_m, delta_r_m, field.spacing_m)
    u0, v0 = wind_components(wind_speed_m_s, wind_direction_deg)
    t_centre = start_offset_s + (np.arange(n_rays) + 0.5) * ray_duration_s
    sub = ((np.arange(sub_points) + 0.5) / sub_points - 0.5) * ray_duration_s
    z = ranges[:, None] + s_nodes[None, :]  # (G, P)
    per_ray = sub_points * z.size
    chunk = max(1, _CHUNK_POINTS // per_ray)
    w = np.empty((n_rays, ranges.size))
    for start in range(0, n_rays, chunk):
        t = t_centre[start : start + chunk, None] + sub[None, :]  # (r, J)
        x = (-u0 * t)[:, :, None, None] + 0 * z[None, None]
        y = (-v0 * t)[:, :, None, None] + 0 * z[None, None]
        zz = np.broadcast_to(z[None, None], x.shape)
        vel = field.interpolate(x, y, zz)[2]  # w: (r, J, G, P)
        w[start : start + chunk] = np.einsum("rjgp,p->rg", vel, s_weights) / sub_points
    w = w + noise_std_m_s * np.random.default_rng(seed).standard_normal(w.shape)
    t0 = np.datetime64(start_time, "ns")
    times = t0 + np.round(t_centre * 1e9).astype("timedelta64[ns]")
    ds = streamline_scans(
        w,
        times=times,
        azimuth=np.zeros(n_rays),
        elevation_deg=90.0,
        ranges_m=ranges,
        scan=np.full(n_rays, -1, dtype=np.int64),
        snr=snr,
        delta_p_m=delta_p_m,
        delta_r_m=delta_r_m,
        truth={
            "sim_epsilon": field.epsilon,
            "sim_integral_scale_m": field.integral_scale_m,
            "sim_noise_std": float(noise_std_m_s),
            "sim_wind_speed": float(wind_speed_m_s),
            "sim_wind_direction_deg": float(wind_direction_deg),
        },
    )
    ds.attrs.update(scan_type="Stare", pulses_per_ray=int(pulses_per_ray))
    return ds


def daily_cycle(
    field: FrozenField,
    *,
    hours: float,
    vad_every_s: float,
    vad_rays: int,
    vad_period_s: float,
    vad_elevation_deg: float,
    ranges_m: np.ndarray,
    ray_duration_s: float,
    wind_speed_m_s: float,
    wind_direction_deg: float,
    noise_std_m_s: float,
    seed: int,
    start_time: str = "2024-01-01T00:00:00",
    snr: float = 0.05,
    pulses_per_ray: int = 20000,
) -> list[xr.Dataset]:
    """A Stream Line cycle: a VAD every ``vad_every_s`` s, vertical stares in between.

    Each VAD (``vad_rays`` rays in ``vad_period_s``, at ``vad_elevation_deg``) and each
    stare segment is one dataset (one file), all from ``field`` on one clock.

    Returns
    -------
    list of xarray.Dataset
        In time order: VAD, stare, VAD, stare, ...
    """
    total = hours * 3600.0
    if not (vad_every_s > vad_period_s and total > 0):
        raise ValueError("the VAD interval must exceed the VAD's duration, hours > 0")
    u0, v0 = wind_components(wind_speed_m_s, wind_direction_deg)
    out: list[xr.Dataset] = []
    k = 0
    for t_vad in np.arange(0.0, total, vad_every_s):
        vad = sample_conical_scans(
            field,
            elevation_deg=vad_elevation_deg,
            ranges_m=np.asarray(ranges_m) / np.sin(np.deg2rad(vad_elevation_deg)),
            rays_per_scan=vad_rays,
            scan_period_s=vad_period_s,
            n_scans=1,
            wind_speed_m_s=wind_speed_m_s,
            wind_direction_deg=wind_direction_deg,
            noise_std_m_s=noise_std_m_s,
            seed=seed + 2 * k + 1,
            start_time=np.datetime64(start_time, "ns") + np.timedelta64(int(t_vad * 1e9), "ns"),
            snr=snr,
            lidar_position_m=(-u0 * t_vad, -v0 * t_vad, 0.0),
        )
        out.append(vad)
        stare_start = t_vad + vad_period_s
        n_rays = int((min(t_vad + vad_every_s, total) - stare_start) // ray_duration_s)
        if n_rays >= 1:
            out.append(
                sample_vertical_stare(
                    field,
                    ranges_m=np.asarray(ranges_m),
                    n_rays=n_rays,
                    ray_duration_s=ray_duration_s,
                    wind_speed_m_s=wind_speed_m_s,
                    wind_direction_deg=wind_direction_deg,
                    noise_std_m_s=noise_std_m_s,
                    seed=seed + 2 * k + 2,
                    start_offset_s=stare_start,
                    start_time=start_time,
                    snr=snr,
                    pulses_per_ray=pulses_per_ray,
                )
            )
        k += 1
    for ds in out:
        ds.attrs["system_id"] = "999"
    return out
