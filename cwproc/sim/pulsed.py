"""Pulsed coherent Doppler lidar (Stream Line) scanning a frozen turbulent field.

The lidar sits at ``lidar_position_m`` and rotates its beam at elevation ``phi``
through 360 deg every ``scan_period_s`` (continuous scanning). Each ray accumulates
over one azimuth step while the beam moves (the transverse averaging that gives
``H_perp = sinc^2(pi dy kappa_2)``, Smalikho (2020), eq. 20), and each range gate is the
radial velocity weighted along the beam by the pulsed range weighting

.. math::

    Q(s) = \\frac{1}{2\\Delta R}\\left[
        \\operatorname{erf}\\frac{s + \\Delta R/2}{\\Delta p}
      - \\operatorname{erf}\\frac{s - \\Delta R/2}{\\Delta p}\\right],

a Gaussian pulse ``exp(-s^2/Delta_p^2)`` convolved with the rectangular range window
of length ``Delta_R``. Its Fourier transform (kappa in cycles per metre) is
``exp(-(pi Delta_p kappa)^2) sinc(pi Delta_R kappa)``, whose square is the physical
longitudinal transfer function of Smalikho (2020), eq. 19 (with the pi of the Gaussian
term, which the printed equation lacks); ``Delta_p = c sigma_p/2``,
``Delta_R = c T_w/2``, Stream Line 15.3 m and 18 m.

The frozen field is carried by the mean wind (Taylor's hypothesis, Smalikho (2020),
eq. 7): the velocity at point ``x`` and time ``t`` is ``U + v'(x - U t)``. White noise
of standard deviation ``sigma_e`` is added to every estimate (Smalikho (2020), eq. 4).
The result is the canonical scan dataset of ``docs/DEVELOPING.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import xarray as xr
from scipy.special import erf

from cwproc.physics import noise
from cwproc.physics.constants import STREAMLINE_DELTA_P_M, STREAMLINE_DELTA_R_M
from cwproc.physics.geometry import beam_unit_vector, wind_components
from cwproc.sim.field3d import FrozenField

try:  # the compiled sampler (setup.py); numpy does the same without it
    from cwproc.sim import _trilinear
except ImportError:  # pragma: no cover - depends on the build
    _trilinear = None

#: points of the range weighting beyond the rectangular window, in units of Delta_p
_GAUSS_TAIL = 3.0
#: largest number of field points interpolated at once (memory bound)
_CHUNK_POINTS = 2_000_000


def pulsed_range_weight(s_m: np.ndarray, delta_p_m: float, delta_r_m: float) -> np.ndarray:
    """Range weighting Q(s) of a pulsed lidar gate (1/m), s from the gate centre (m).

    Gaussian pulse ``exp(-s^2/Delta_p^2)/(sqrt(pi) Delta_p)`` convolved with a
    rectangular window of length ``Delta_R``; integrates to 1. Its Fourier transform
    squared is the longitudinal transfer function of Smalikho (2020), eq. 19 (physical
    form, with pi in the Gaussian term).

    Parameters
    ----------
    s_m : numpy.ndarray
        Distance from the gate centre along the beam (m).
    delta_p_m : float
        Delta_p = c sigma_p / 2 (m).
    delta_r_m : float
        Delta_R = c T_w / 2 (m).
    """
    s = np.asarray(s_m, dtype=float)
    return (erf((s + delta_r_m / 2) / delta_p_m) - erf((s - delta_r_m / 2) / delta_p_m)) / (
        2 * delta_r_m
    )


def range_quadrature(
    delta_p_m: float, delta_r_m: float, step_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (m) and weights (sum 1) of the range weighting, out to 3 Delta_p past the window."""
    half = delta_r_m / 2 + _GAUSS_TAIL * delta_p_m
    n = int(np.ceil(half / step_m))
    s = np.arange(-n, n + 1) * step_m
    w = pulsed_range_weight(s, delta_p_m, delta_r_m)
    return s, w / w.sum()


def sample_conical_scans(
    field: FrozenField,
    *,
    elevation_deg: float,
    ranges_m: Sequence[float] | np.ndarray,
    rays_per_scan: int,
    scan_period_s: float,
    n_scans: int,
    wind_speed_m_s: float,
    wind_direction_deg: float,
    noise_std_m_s: float,
    seed: int,
    vertical_wind_m_s: float = 0.0,
    delta_p_m: float = STREAMLINE_DELTA_P_M,
    delta_r_m: float = STREAMLINE_DELTA_R_M,
    start_azimuth_deg: float = 0.0,
    clockwise: bool = True,
    start_time: str | np.datetime64 = "2024-01-01T00:00:00",
    sweep_points: int = 4,
    sweep_advection: bool = True,
    range_step_m: float | None = None,
    snr: float | None = None,
    lidar_position_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    first_scan: int = 0,
    noise_rng: np.random.Generator | None = None,
) -> xr.Dataset:
    """Conical scans of a pulsed lidar through a frozen field advected by the mean wind.

    Parameters
    ----------
    field : FrozenField
        Turbulent fluctuations (zero mean), e.g. from
        :func:`cwproc.sim.field3d.von_karman_field`.
    elevation_deg : float
        Elevation phi of the beam (deg).
    ranges_m : sequence of float
        Gate centres along the beam (m).
    rays_per_scan : int
        M, rays per 360 deg rotation; the azimuth step is 360/M deg.
    scan_period_s : float
        Duration T_scan of one rotation (s); rotation is continuous.
    n_scans : int
        Number of rotations.
    wind_speed_m_s, wind_direction_deg, vertical_wind_m_s : float
        Mean horizontal wind (m s-1), its direction (from, deg), mean vertical wind (m s-1).
    noise_std_m_s, seed : float, int
        sigma_e, standard deviation of the white estimation noise (m s-1); its seed.
    delta_p_m, delta_r_m : float
        Pulse and window lengths of the range weighting (m), Smalikho (2020), eq. 19.
    start_azimuth_deg, clockwise, start_time : float, bool, str or numpy.datetime64
        Azimuth (deg) and UTC time of the start of the first ray; direction of rotation.
    sweep_points : int
        Beam positions averaged across each ray's azimuth step (Smalikho (2020), eq. 20).
    sweep_advection : bool
        ``True`` (physical): the field moves with the wind while the beam sweeps across
        the ray. ``False``: the sweep is taken at the ray's centre time (averaged over
        the arc ``dy`` only), the model of Smalikho (2020), eq. 15.
    range_step_m : float, optional
        Spacing of the range weighting's nodes (m); default the field spacing.
    snr : float, optional
        Linear SNR written to the dataset (constant); by default the one at which the
        settings predict ``noise_std_m_s`` (:func:`cwproc.physics.noise.snr_for_noise_std`).
    lidar_position_m : tuple of float
        (x, y, z) of the lidar in the field (m).
    first_scan, noise_rng : int, numpy.random.Generator, optional
        A piece of a long series: its first scan and the series' noise generator.

    Returns
    -------
    xarray.Dataset
        Canonical scan dataset (``ray``, ``range``), Stream Line attrs, truth ``sim_*``.
    """
    ranges = np.asarray(ranges_m, dtype=float)
    _check_scan_arguments(
        rays_per_scan, n_scans, sweep_points, scan_period_s, noise_std_m_s, ranges
    )
    step = field.spacing_m if range_step_m is None else float(range_step_m)
    mean_wind = np.array([*wind_components(wind_speed_m_s, wind_direction_deg), vertical_wind_m_s])
    rays = _ConicalRays.of(
        (first_scan, n_scans, rays_per_scan, sweep_points),
        scan_period_s,
        (start_time, start_azimuth_deg, 1.0 if clockwise else -1.0),
    )
    velocity = probe_averaged_velocity(
        field,
        rays.sweep_times,
        rays.sweep_azimuths,
        elevation_deg=elevation_deg,
        ranges_m=ranges,
        range_quadrature_nodes=range_quadrature(delta_p_m, delta_r_m, step),
        mean_wind=mean_wind,
        sweep_advection=sweep_advection,
        lidar_position_m=lidar_position_m,
    )
    rng = np.random.default_rng(seed) if noise_rng is None else noise_rng
    velocity += noise_std_m_s * rng.standard_normal(velocity.shape)
    truth = {
        **field_truth(field),
        "sim_noise_std": float(noise_std_m_s),
        "sim_noise_seed": int(seed),
        "sim_wind_speed": float(wind_speed_m_s),
        "sim_wind_direction_deg": float(wind_direction_deg),
        "sim_vertical_wind": float(vertical_wind_m_s),
        "sim_scan_period_s": float(scan_period_s),
    }
    return streamline_scans(
        velocity,
        times=rays.times,
        azimuth=rays.azimuths,
        elevation_deg=elevation_deg,
        ranges_m=ranges,
        scan=rays.scan,
        snr=snr,
        delta_p_m=delta_p_m,
        delta_r_m=delta_r_m,
        truth=truth,
    )


@dataclass(frozen=True)
class _ConicalRays:
    """The rays of continuous rotations (:func:`sample_conical_scans`): the times (s from
    the series' start) and azimuths (deg) of the ``J`` beam positions across each ray's
    azimuth step (Smalikho (2020), eq. 20), ``(rays, J)``; each ray's centre time (UTC),
    azimuth (deg, in [0, 360)) and scan number."""

    sweep_times: np.ndarray
    sweep_azimuths: np.ndarray
    times: np.ndarray
    azimuths: np.ndarray
    scan: np.ndarray

    @classmethod
    def of(
        cls,
        counts: tuple[int, int, int, int],
        scan_period_s: float,
        start: tuple[str | np.datetime64, float, float],
    ) -> _ConicalRays:
        """``counts``: first scan, scans, rays per scan and sweep points J; ``start``: the
        UTC time and azimuth (deg) of the first ray's start and the sense of rotation
        (+1 clockwise)."""
        first_scan, n_scans, rays_per_scan, sweep_points = counts
        start_time, start_azimuth_deg, sign = start
        n_rays = rays_per_scan * n_scans
        first_ray = first_scan * rays_per_scan
        t_centre = (np.arange(first_ray, first_ray + n_rays) + 0.5) * scan_period_s / rays_per_scan
        sub = ((np.arange(sweep_points) + 0.5) / sweep_points - 0.5) * scan_period_s / rays_per_scan
        ray_times = t_centre[:, None] + sub[None, :]  # (rays, J): the sweep of each ray
        return cls(
            sweep_times=ray_times,
            sweep_azimuths=start_azimuth_deg + sign * 360.0 * ray_times / scan_period_s,
            times=np.datetime64(start_time, "ns")
            + np.round(t_centre * 1e9).astype("timedelta64[ns]"),
            azimuths=(start_azimuth_deg + sign * 360.0 * t_centre / scan_period_s) % 360.0,
            scan=(first_scan + np.arange(n_rays) // rays_per_scan).astype(np.int64),
        )


def _check_scan_arguments(
    rays_per_scan: int,
    n_scans: int,
    sweep_points: int,
    scan_period_s: float,
    noise_std_m_s: float,
    ranges: np.ndarray,
) -> None:
    """ValueError for arguments :func:`sample_conical_scans` cannot scan with."""
    if not (rays_per_scan >= 3 and n_scans >= 1 and sweep_points >= 1 and scan_period_s > 0):
        raise ValueError("rays_per_scan >= 3, n_scans, sweep_points >= 1, scan_period_s > 0")
    if not (noise_std_m_s >= 0 and ranges.size >= 1):
        raise ValueError("noise_std_m_s >= 0 and at least one range needed")


def field_truth(field: FrozenField) -> dict[str, float | int]:
    """The ``sim_*`` attributes that describe the simulated turbulent field."""
    return {
        "sim_epsilon": field.epsilon,
        "sim_integral_scale_m": field.integral_scale_m,
        "sim_field_seed": field.seed,
        "sim_field_spacing_m": field.spacing_m,
    }


def probe_averaged_velocity(
    field: FrozenField,
    ray_times: np.ndarray,
    ray_azimuths: np.ndarray,
    *,
    elevation_deg: float,
    ranges_m: np.ndarray,
    range_quadrature_nodes: tuple[np.ndarray, np.ndarray],
    mean_wind: np.ndarray,
    sweep_advection: bool,
    lidar_position_m: tuple[float, float, float],
) -> np.ndarray:
    """Radial velocity of each ray and gate, averaged over the probe volume (m s-1).

    The beam positions of a ray (``ray_times``, ``ray_azimuths``: shape (rays, J), J
    positions across its azimuth step) sample the frozen field moved by ``mean_wind``;
    the range weighting is the quadrature ``(nodes, weights)`` of
    :func:`range_quadrature` (Smalikho (2020), eqs. 19-20). The field is sampled once
    per ray at the distinct distances of all gates' nodes (:func:`beam_distances`:
    gates whose nodes coincide, as with a node step that divides the gate length, share
    them) and averaged over the J positions first (:func:`sweep_mean_radial`); each
    gate is then the weighted sum of its nodes. Memory-bounded chunks of rays.

    Returns
    -------
    numpy.ndarray
        Shape (rays, gates).
    """
    s_nodes, s_weights = range_quadrature_nodes
    dist, index = beam_distances(ranges_m, s_nodes)
    n_rays, sweep_points = ray_times.shape
    rays_per_chunk = max(1, _CHUNK_POINTS // (sweep_points * dist.size))
    velocity = np.empty((n_rays, ranges_m.size))
    for start in range(0, n_rays, rays_per_chunk):
        t = ray_times[start : start + rays_per_chunk]  # (r, J)
        beam = beam_unit_vector(ray_azimuths[start : start + rays_per_chunk], elevation_deg)
        t_adv = t if sweep_advection else np.broadcast_to(t.mean(axis=1, keepdims=True), t.shape)
        along = sweep_mean_radial(field, beam, t_adv, dist, mean_wind, lidar_position_m)
        mean = np.mean(beam @ mean_wind, axis=1)  # (r,): S.<V>, averaged over the sweep
        velocity[start : start + rays_per_chunk] = along[:, index] @ s_weights + mean[:, None]
    return velocity


def beam_distances(ranges_m: np.ndarray, s_nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct distances (m) of every gate's range nodes, and each node's place among them.

    Returns
    -------
    (distances, index) : numpy.ndarray
        Sorted distinct ``ranges_m[g] + s_nodes[p]`` (U,), and ``index`` (G, P) with
        ``distances[index[g, p]] == ranges_m[g] + s_nodes[p]``.
    """
    dist = np.asarray(ranges_m, dtype=float)[:, None] + np.asarray(s_nodes)[None, :]
    unique, index = np.unique(dist, return_inverse=True)
    return unique, index.reshape(dist.shape)


def sweep_mean_radial(
    field: FrozenField,
    beams: np.ndarray,
    times: np.ndarray,
    dist_m: np.ndarray,
    mean_wind: np.ndarray,
    origin_m: tuple[float, float, float],
) -> np.ndarray:
    """The turbulent radial velocity along each ray, averaged over its sweep (m s-1).

    ``(1/J) sum_j S_rj . v'(x0 + S_rj d_u - <V> t_rj)``: the frozen fluctuation field
    carried by the mean wind (Taylor; Smalikho (2020), eq. 7), seen along the beam
    ``S_rj`` (``beams``: (R, J, 3) east, north, up) at times ``t_rj`` (``times``: (R, J),
    s) and distances ``d_u`` (``dist_m``: (U,), m); the sweep average of the
    transverse averaging (Smalikho (2020), eq. 20). By the compiled
    ``cwproc.sim._trilinear.radial`` (two threads) when built, else in numpy.

    Returns
    -------
    numpy.ndarray
        Shape (R, U).
    """
    n_rays, n_sweep = times.shape
    origin = np.asarray(origin_m, dtype=float)
    wind = np.asarray(mean_wind, dtype=float)
    if _trilinear is None:
        xyz = origin + beams[:, None] * dist_m[None, :, None, None] - wind * times[:, None, :, None]
        vel = field.interpolate_points(xyz)  # (R, U, J, 3)
        return np.einsum("rujc,rjc->ru", vel, beams) / n_sweep
    out = np.zeros((n_rays, dist_m.size))
    beams = np.ascontiguousarray(beams, dtype=float)
    times = np.ascontiguousarray(times, dtype=float)
    dist = np.ascontiguousarray(dist_m, dtype=float)
    for table, (nx, ny, nz), dx in field.levels:
        part = np.empty_like(out)

        def run(sl: slice, table=table, shape=(nx, ny, nz), dx=dx, part=part) -> None:
            _trilinear.radial(
                table, *shape, dx, origin, wind, beams[sl], times[sl], n_sweep, dist, part[sl]
            )

        half = (n_rays + 1) // 2
        with ThreadPoolExecutor(2) as pool:
            list(pool.map(run, [slice(0, half), slice(half, n_rays)]))
        out += part
    return out


def streamline_scans(
    velocity: np.ndarray,
    *,
    times: np.ndarray,
    azimuth: np.ndarray,
    elevation_deg: float,
    ranges_m: np.ndarray,
    scan: np.ndarray,
    snr: float | None,
    delta_p_m: float,
    delta_r_m: float,
    truth: dict[str, object],
    stepped: bool = False,
    pulses_per_ray: int = 10000,
) -> xr.Dataset:
    """The canonical scan dataset of simulated Stream Line rays (``velocity``: ray x gate).

    Attributes are those of a Stream Line (gate length, points per gate, pulses per ray,
    velocity resolution, the range weighting's Delta_p and Delta_R) plus the simulation
    truth ``truth`` (``sim_*`` attributes); ``stepped``: a step-stare VAD (the beam still
    during each ray), named as the Halo names it (``Scan type: VAD - stepped``);
    ``pulses_per_ray``: the header's ``Pulses/ray`` (a stare ray dwells pulses / PRF).
    ``snr`` None: the SNR at which these settings predict the noise of the truth
    (``sim_noise_std``; Pearson et al. (2009), eq. 3,
    :func:`cwproc.physics.noise.snr_for_noise_std`).
    """
    n_rays = velocity.shape[0]
    settings = {
        "points_per_gate": max(1, round(delta_r_m / 3.0)),
        "pulses_per_ray": int(pulses_per_ray),
        "velocity_resolution_m_s": 0.0382,
    }
    if snr is None:
        snr = noise.snr_for_noise_std(
            float(truth["sim_noise_std"]),
            settings["points_per_gate"],
            settings["pulses_per_ray"],
            noise.bandwidth_from_resolution(settings["velocity_resolution_m_s"]),
        )
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), velocity),
            "snr": (("ray", "range"), np.full(velocity.shape, float(snr))),
        },
        coords={
            "time": ("ray", times),
            "azimuth": ("ray", azimuth),
            "elevation": ("ray", np.full(n_rays, float(elevation_deg))),
            "range": ("range", np.asarray(ranges_m, dtype=float)),
            "scan": ("ray", scan),
        },
        attrs={
            "instrument": "Halo Photonics Stream Line",
            "instrument_kind": "streamline",
            "system_id": "sim",
            "source_files": [],
            "scan_type": "VAD - stepped" if stepped else "VAD",
            "gate_length_m": float(delta_r_m),
            "homodyne": 0,
            **settings,
            "focus_range_m": 65535.0,
            "delta_p_m": float(delta_p_m),
            "delta_r_m": float(delta_r_m),
            **truth,
        },
    )
