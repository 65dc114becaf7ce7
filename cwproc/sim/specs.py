"""The specifications of the simulated sample data (:mod:`cwproc.sim.sample_data`).

Frozen dataclasses, one per kind of sample: a Stream Line VAD series
(:class:`StreamLineSpec`), a day of 10-min wind records (:class:`WindRecordSpec`, also
used by :mod:`cwproc.sim.windcube_samples`) and a sonic record (:class:`SonicSpec`).
They live apart from the writers so that each writer module imports them without
importing the others (no import cycle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StreamLineSpec:
    """A simulated Stream Line VAD series: geometry, wind, turbulence, noise.

    Attributes
    ----------
    start : str
        ISO time of the first ray (UTC).
    n_scans : int
        Number of 360 degree scans.
    scans_per_file : int
        Scans in each ``.hpl`` file.
    rays_per_scan : int
        Rays per scan (azimuth step 360/rays_per_scan deg).
    scan_period_s : float
        Duration of one scan (s).
    elevation_deg : float
        Elevation of the cone (deg); 35.3 deg as in Smalikho (2020).
    n_gates : int
        Number of range gates.
    gate_length_m : float
        Range gate length (m); gate centres (g + 0.5) x gate length. It is also the
        probe's Delta_R = c T_w / 2 (Smalikho (2020), eq. 19), as in the written header.
    wind_speed, wind_direction_deg : float
        Mean horizontal wind (m s-1) and the direction it blows from (deg).
    epsilon : float
        Dissipation rate (m2 s-3).
    integral_scale_m : float
        Longitudinal integral scale L_V of the von Karman field (m).
    noise_std : float
        Instrumental radial-velocity noise sigma_e (m s-1).
    snr : float
        Linear SNR written to the files.
    field_spacing_m : float
        Grid spacing of the 3-D field (m).
    field_shape : tuple of int
        Grid points (x, y, z) of the periodic 3-D field.
    seed : int
        Seed of the field; the noise uses ``seed + 1``.
    range_step_m : float, optional
        Step of the nodes of the range weighting (m); the field spacing by default. A
        step that divides ``gate_length_m`` lets the gates share their nodes (the field
        is then sampled once per distance along each ray: many gates cost less).
    """

    start: str = "2024-06-01T12:00:00"
    n_scans: int = 12
    scans_per_file: int = 6
    rays_per_scan: int = 180
    scan_period_s: float = 36.0
    elevation_deg: float = 35.3
    n_gates: int = 24
    gate_length_m: float = 30.0
    wind_speed: float = 6.0
    wind_direction_deg: float = 240.0
    epsilon: float = 0.01
    integral_scale_m: float = 150.0
    noise_std: float = 0.1
    snr: float = 0.05
    field_spacing_m: float = 8.0
    field_shape: tuple[int, int, int] = (160, 160, 64)
    seed: int = 20240601
    range_step_m: float | None = None

    @property
    def ranges_m(self) -> np.ndarray:
        """Gate centres (m)."""
        return (np.arange(self.n_gates) + 0.5) * self.gate_length_m


@dataclass(frozen=True)
class WindRecordSpec:
    """A day of 10-min wind statistics of a known profile, for the wind-record samples.

    The mean wind follows a power law ``U(z) = U_ref (z / z_ref)^alpha`` and turns with
    height by ``veer_deg_per_100m``; each 10-min mean carries a random error of
    ``sigma / sqrt(n_samples)`` about it. Values are written with the files' decimals.
    """

    start: str = "2024-06-01T00:00:00"
    n_records: int = 36
    heights_m: tuple[float, ...] = (40.0, 60.0, 80.0, 100.0, 120.0, 150.0, 200.0)
    wind_speed_ref: float = 7.0
    height_ref_m: float = 100.0
    shear_exponent: float = 0.2
    direction_deg: float = 240.0
    veer_deg_per_100m: float = 5.0
    turbulence_intensity: float = 0.10
    n_samples: int = 600
    seed: int = 21

    def profile(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean speed (m s-1) and direction (deg, from) at ``heights_m``."""
        z = np.asarray(self.heights_m)
        speed = self.wind_speed_ref * (z / self.height_ref_m) ** self.shear_exponent
        direction = self.direction_deg + self.veer_deg_per_100m * (z - z[0]) / 100.0
        return speed, direction % 360.0


@dataclass(frozen=True)
class SonicSpec:
    """A synthetic sonic record with structure functions of a prescribed type.

    Made by :func:`cwproc.sim.sonic.simulate_sonic_dataset` (Gladkikh et al. (2014)
    model types); written in every sonic format cwproc reads.
    """

    start: str = "2024-06-01T12:00:00"
    minutes: float = 10.0
    rate_hz: float = 10.0
    sf_type: int = 1
    speed: float = 4.0
    direction_deg: float = 30.0
    seed: int = 5
