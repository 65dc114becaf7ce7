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

from cwproc.io.halo import write_hpl
from cwproc.physics.constants import STREAMLINE_DELTA_P_M, STREAMLINE_DELTA_R_M
from cwproc.physics.geometry import wind_components
from cwproc.physics.noise import bandwidth_from_resolution, velocity_noise_std
from cwproc.sim.exact_gaussian import pulse_range_nodes, structure_functions
from cwproc.sim.field3d import FrozenField
from cwproc.sim.output import fresh_folder, write_truth
from cwproc.sim.pulsed import range_quadrature, sample_conical_scans, streamline_scans
from cwproc.sim.sample_data import noise_from_snr, streamline_field, streamline_truth

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
    delta_p_m: float = STREAMLINE_DELTA_P_M,
    delta_r_m: float = STREAMLINE_DELTA_R_M,
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
    stare_noise_std_m_s: float | None = None,
) -> list[xr.Dataset]:
    """A Stream Line cycle: a VAD every ``vad_every_s`` s, vertical stares in between.

    Each VAD (``vad_rays`` rays in ``vad_period_s``, at ``vad_elevation_deg``) and each
    stare segment is one dataset (one file), all from ``field`` on one clock.

    ``noise_std_m_s`` is the noise of the VAD rays, ``stare_noise_std_m_s`` that of the
    stare rays (default: the same).

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
            ranges_m=np.asarray(ranges_m),
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
                    noise_std_m_s=(
                        noise_std_m_s if stare_noise_std_m_s is None else stare_noise_std_m_s
                    ),
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


def _w_structure(r_x: np.ndarray, r_z: np.ndarray, model: str, outer_scale_m: float) -> np.ndarray:
    """``D_33`` per eps^(2/3) (m^(2/3)) at separations ``(r_x, 0, r_z)`` (m).

    ``D_33 = D_perp + (D_par - D_perp) (r_z/r)^2``, the isotropic tensor of Banakh et al.
    (1999), eq. 16 in structure-function form; inertial: ``D_par = 2 r^(2/3)``,
    ``D_perp = 4/3 D_par`` (Smalikho (2020), eq. 12).
    """

    r = np.hypot(r_x, r_z)
    if model == "inertial":
        d_par = 2.0 * r ** (2 / 3)
        d_perp = 4.0 / 3.0 * d_par
    else:
        d_par, d_perp = structure_functions(r, model, outer_scale_m)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos2 = np.where(r > 0, (r_z / np.where(r > 0, r, 1.0)) ** 2, 0.0)
    return d_perp + (d_par - d_perp) * cos2


def stare_covariance(
    n_rays: int,
    *,
    ray_duration_s: float,
    wind_speed_m_s: float,
    model: str = "inertial",
    outer_scale_m: float = 1000.0,
    delta_p_m: float = STREAMLINE_DELTA_P_M,
    delta_r_m: float = STREAMLINE_DELTA_R_M,
    sub_points: int = 6,
    range_step_m: float = 3.0,
    ray_interval_s: float | None = None,
) -> np.ndarray:
    """Covariance per eps^(2/3) of the ray- and gate-averaged w of ``n_rays`` stare rays.

    ``B(i, k) = B_0 - (1/2) <D_33(U (t_i - t_k + tau - tau'), s - s')>``, averaged over
    ``sub_points`` instants ``tau`` of each ray's dwell (``ray_duration_s``) and the
    pulsed range weighting ``s`` (:func:`cwproc.sim.exact_gaussian.pulse_range_nodes`), rays
    ``ray_interval_s`` apart (default: back to back, a sparse stare when longer, e.g.
    one ray every 25 s between VADs); Toeplitz in ``i - k``. The
    constant ``B_0`` (the largest half structure function) keeps the matrix positive
    definite; the variances about a window mean do not depend on it (a pure Kolmogorov
    field has no finite variance).
    """

    s, ws = pulse_range_nodes(delta_p_m, delta_r_m, range_step_m)
    tau = ((np.arange(sub_points) + 0.5) / sub_points - 0.5) * ray_duration_s
    dtau = (tau[:, None] - tau[None, :]).ravel()
    ds = (s[:, None] - s[None, :]).ravel()
    wpair = (ws[:, None] * ws[None, :]).ravel()
    step = ray_duration_s if ray_interval_s is None else ray_interval_s
    lags = np.arange(n_rays) * step
    half = np.empty(n_rays)
    for j, lag in enumerate(lags):  # one lag at a time: (sub^2, nodes^2) points
        rx = wind_speed_m_s * (lag + dtau)[:, None]
        d = _w_structure(rx, ds[None, :], model, outer_scale_m)
        half[j] = 0.5 * np.mean(d @ wpair)
    b0 = half.max() * 1.05
    index = np.abs(np.arange(n_rays)[:, None] - np.arange(n_rays)[None, :])
    return b0 - half[index]


def gaussian_stares(
    n_windows: int,
    n_rays: int,
    *,
    epsilon: float,
    noise_std_m_s: float,
    seed: int,
    **covariance_options: float | str,
) -> np.ndarray:
    """``(n_windows, n_rays)`` independent windows of stare w with exact statistics.

    Gaussian vectors with covariance ``eps^(2/3)`` :func:`stare_covariance` plus white
    noise ``sigma_e`` (m s-1): the truth of a stare eps retrieval with no grid and no
    periodic box.
    """
    cov = stare_covariance(n_rays, **covariance_options)  # type: ignore[arg-type]
    factor = np.linalg.cholesky(cov + 1e-9 * np.trace(cov) / n_rays * np.eye(n_rays))
    rng = np.random.default_rng(seed)
    w = epsilon ** (1 / 3) * rng.standard_normal((n_windows, n_rays)) @ factor.T
    return w + noise_std_m_s * rng.standard_normal(w.shape)


def stare_windows_dataset(
    w: np.ndarray,
    snr: float,
    *,
    window_s: float = 300.0,
    ray_s: float = 20000 / 15000.0,
    range_m: float = 300.0,
    ray_interval_s: float | None = None,
    gate_length_m: float = 18.0,
    pulses_per_ray: int = 20000,
) -> xr.Dataset:
    """Windows of stare rays ``w`` ``(n_windows, n_rays)`` (m s-1) as a Stream Line scan
    dataset of one gate at ``range_m``: window ``k`` starts at ``k window_s``, its rays
    are ``ray_s`` long (20000 pulses at 15 kHz) and ``ray_interval_s`` apart (default
    ``ray_s``), vertical, at the linear ``snr``; the header's ``gate_length_m`` and its
    points per gate (3 m per point).

    What :func:`gaussian_stares` draws, ready for :func:`cwproc.stages.stare.stare_product`.
    """
    n_win, n_ray = w.shape
    step = ray_s if ray_interval_s is None else ray_interval_s
    seconds = np.arange(n_win)[:, None] * window_s + (np.arange(n_ray)[None, :] + 0.5) * step
    times = np.datetime64("2024-01-01T00:00", "ns") + np.round(seconds.ravel() * 1e9).astype(
        "timedelta64[ns]"
    )
    ds = streamline_scans(
        w.reshape(-1, 1),
        times=times,
        azimuth=np.zeros(times.size),
        elevation_deg=90.0,
        ranges_m=np.array([range_m]),
        scan=np.full(times.size, -1),
        snr=snr,
        delta_p_m=15.3,
        delta_r_m=gate_length_m,
        truth={},
    )
    ds.attrs.update(
        points_per_gate=round(gate_length_m / 3.0),
        pulses_per_ray=int(pulses_per_ray),
        scan_type="Stare",
        gate_length_m=float(gate_length_m),
    )
    return ds


def stare_noise_std(snr: float, points_per_gate: int, pulses_per_ray: int) -> float:
    """sigma_e (m s-1) of a simulated stare ray: Pearson et al. (2009), eq. 3.

    The prediction the stare stage removes (:func:`cwproc.physics.noise.velocity_noise_std`,
    velocity resolution 0.0382 m s-1), so the virtual instrument's noise is the one its
    header and SNR declare.
    """

    return float(
        velocity_noise_std(snr, points_per_gate, pulses_per_ray, bandwidth_from_resolution(0.0382))
    )


def write_stare_series(
    folder,
    truth_path,
    spec,
    *,
    scan: str,
    hours: float,
    vad_every_s: float = 900.0,
    pulses_per_ray: int = 20000,
    prf_hz: float = 15000.0,
) -> list:
    """Write simulated stares (``scan="stare"``) or a daily cycle (``"mixed"``) as .hpl.

    Parameters
    ----------
    folder, truth_path : path
        Folder of the ``.hpl`` files (old ones removed) and the truth JSON.
    spec : cwproc.sim.sample_data.StreamLineSpec
        Field, wind, VAD geometry and SNR (``n_scans`` is ignored).
    scan : {"stare", "mixed"}
        Stares only (one file per hour, as the Stream Line writes them), or a VAD every
        ``vad_every_s`` s with stares in between (one file per VAD and per stare).
    hours : float
        Length of the series (h).
    pulses_per_ray, prf_hz : int, float
        Stare rays last ``pulses_per_ray / prf_hz`` s.

    Returns
    -------
    list of pathlib.Path
        The files written, truth last.
    """

    folder = fresh_folder(folder, "*.hpl")
    field = streamline_field(spec)
    ray_s = pulses_per_ray / prf_hz
    stare_noise = stare_noise_std(spec.snr, round(spec.gate_length_m / 3), pulses_per_ray)
    if scan == "stare":
        parts = [
            sample_vertical_stare(
                field,
                ranges_m=spec.ranges_m,
                n_rays=int(min(3600.0, hours * 3600.0 - h * 3600.0) // ray_s),
                ray_duration_s=ray_s,
                wind_speed_m_s=spec.wind_speed,
                wind_direction_deg=spec.wind_direction_deg,
                noise_std_m_s=stare_noise,
                seed=spec.seed + 1 + h,
                start_offset_s=h * 3600.0,
                start_time=spec.start,
                snr=spec.snr,
                pulses_per_ray=pulses_per_ray,
            )
            for h in range(int(np.ceil(hours)))
        ]
    elif scan == "mixed":
        parts = daily_cycle(
            field,
            hours=hours,
            vad_every_s=vad_every_s,
            vad_rays=spec.rays_per_scan,
            vad_period_s=spec.scan_period_s,
            vad_elevation_deg=spec.elevation_deg,
            ranges_m=spec.ranges_m,
            ray_duration_s=ray_s,
            wind_speed_m_s=spec.wind_speed,
            wind_direction_deg=spec.wind_direction_deg,
            noise_std_m_s=noise_from_snr(spec.snr),
            seed=spec.seed + 1,
            start_time=spec.start,
            snr=spec.snr,
            pulses_per_ray=pulses_per_ray,
            stare_noise_std_m_s=stare_noise,
        )
    else:
        raise ValueError(f"scan must be 'stare' or 'mixed', got {scan!r}")
    written = []
    for part in parts:
        part.attrs.update(
            system_id="999",
            points_per_gate=round(spec.gate_length_m / 3),
            gate_length_m=float(spec.gate_length_m),
        )
        kind = "Stare" if part.attrs.get("scan_type") == "Stare" else "VAD"
        stamp = np.datetime_as_string(part["time"].values[0], unit="s")
        stamp = stamp.replace("-", "").replace(":", "").replace("T", "_")
        written.append(write_hpl(part, folder / f"{kind}_999_{stamp}.hpl"))
    truth = streamline_truth(spec)
    truth.update(
        description=f"truth of a simulated Stream Line {scan} series (cwproc virtual instrument)",
        scan=scan,
        stare_ray_duration_s=ray_s,
        stare_noise_std_m_s=stare_noise,
        stare_heights_m=[round(float(h), 3) for h in spec.ranges_m],
    )
    if scan == "mixed":
        truth["vad_every_s"] = float(vad_every_s)
    written.append(write_truth(truth_path, truth))
    return written


def exact_stare_trial(
    *,
    gate_length_m: float,
    ray_interval_s: float,
    n_windows: int,
    epsilon: float = 0.01,
    wind_speed_m_s: float = 5.0,
    snr: float = 0.05,
    window_s: float = 300.0,
    pulses_per_ray: int = 20000,
    prf_hz: float = 15000.0,
    seed: int = 29,
    min_rays_per_variance_window: int = 4,
) -> dict[str, np.ndarray | float]:
    """Stare eps of ``n_windows`` independent exact-statistics windows against the truth.

    The rays sample the way the instrument does: Gaussian w with the exact covariance of
    the Kolmogorov field averaged over the pulsed weighting of a ``gate_length_m`` gate
    (Delta_p 15.3 m) and over each ray's dwell ``pulses_per_ray / prf_hz``, carried past
    at ``wind_speed_m_s``, a ray every ``ray_interval_s``; white noise of the sigma_e the
    header's SNR predicts (Pearson et al. (2009), eq. 3). The file says only its gate
    length: the retrieval (:func:`cwproc.stages.stare.stare_product`, default options)
    takes the probe and the variance windows (at least ``min_rays_per_variance_window``
    rays) from it.

    Returns
    -------
    dict
        ``ratio`` (eps_hat / eps per window), ``se_ratio`` (reported standard error /
        eps), the product's ``variance_window_s`` and ``probe_delta_r_m``.
    """
    from cwproc.stages.stare import StareOptions, stare_product

    ray_s = pulses_per_ray / prf_hz
    n_rays = int(window_s // ray_interval_s)
    noise = stare_noise_std(snr, round(gate_length_m / 3.0), pulses_per_ray)
    w = gaussian_stares(
        n_windows,
        n_rays,
        epsilon=epsilon,
        noise_std_m_s=noise,
        seed=seed,
        ray_duration_s=ray_s,
        ray_interval_s=ray_interval_s,
        wind_speed_m_s=wind_speed_m_s,
        delta_r_m=gate_length_m,
    )
    ds = stare_windows_dataset(
        w,
        snr,
        window_s=window_s,
        ray_s=ray_s,
        ray_interval_s=ray_interval_s,
        gate_length_m=gate_length_m,
        pulses_per_ray=pulses_per_ray,
    )
    wind = xr.Dataset(
        {"wind_speed": (("time", "height"), np.full((2, 2), wind_speed_m_s))},
        coords={
            "time": np.array(["2024-01-01", "2024-01-09"], dtype="datetime64[ns]"),
            "height": [0.0, 1000.0],
        },
    )
    options = StareOptions(
        prf_hz=prf_hz,
        window_s=window_s,
        min_rays_per_variance_window=min_rays_per_variance_window,
    )
    product = stare_product(ds, wind, options)
    return {
        "ratio": product["epsilon_stare"].values[:, 0] / epsilon,
        "se_ratio": product["epsilon_stare_standard_error"].values[:, 0] / epsilon,
        "variance_window_s": float(product.attrs["variance_window_s"]),
        "probe_delta_r_m": float(product.attrs["probe_delta_r_m"]),
    }
