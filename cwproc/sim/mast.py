"""Virtual truth for lidar against sonic: one frozen field, a virtual lidar and a mast sonic.

The von Kármán field of :mod:`cwproc.sim.field3d` (dissipation rate eps, integral scale
L_V), carried by the mean wind (Taylor), is scanned by the virtual Stream Line of
:func:`cwproc.sim.pulsed.sample_conical_scans` and sampled, at the same times, by a
point sonic on a mast inside the scan cone: u(t) = <V> + v'(x_mast - <V> t), the
convention of :func:`cwproc.sim.pulsed.sweep_mean_radial`. Both instruments see the
same eps, so the lidar/sonic ratio of ``cwproc compare`` has a known answer (1), and each
dissipation rate has its truth (the field's eps).

The field is a two-level grid (fine spacing for the sonic's inertial range, a coarse
level ``coarse_factor`` times larger for scales up to and beyond L_V); velocity
fluctuations smaller than about two fine spacings are absent, so the sonic's structure
function follows r^(2/3) only from a few spacings up (the typing finds where).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.io.halo import write_hpl
from cwproc.io.meteo2 import write_meteo2
from cwproc.physics.geometry import wind_components
from cwproc.sim.field3d import FrozenField, von_karman_field
from cwproc.sim.output import write_truth
from cwproc.sim.pulsed import sample_conical_scans


@dataclass(frozen=True)
class MastCase:
    """A virtual lidar + mast record.

    Attributes
    ----------
    start : str
        ISO UTC start of both records.
    hours : float
        Record length (h).
    epsilon, integral_scale_m : float
        Dissipation rate (m2 s-3) and L_V (m) of the field.
    wind_speed, wind_direction_deg : float
        Mean horizontal wind (m s-1) and the direction it blows from (degree).
    mast_height_m : float
        Height of the sonic (m above the lidar); the mast stands at the lidar (inside
        its cone at every height the cone reaches).
    sonic_rate_hz : float
        Sampling rate of the sonic (Hz).
    field_spacing_m, field_shape, coarse_factor : float, tuple, int
        Fine grid of the field and the factor of its coarse level.
    elevation_deg, rays_per_scan, scan_period_s, gate_length_m, n_gates, noise_std
        The lidar (Stream Line geometry of :class:`cwproc.sim.sample_data.StreamLineSpec`).
    seed : int
        Seed of the field; the lidar noise uses ``seed + 1``.
    """

    start: str = "2024-06-01T00:00:00"
    hours: float = 1.0
    epsilon: float = 0.01
    integral_scale_m: float = 60.0
    wind_speed: float = 6.0
    wind_direction_deg: float = 240.0
    mast_height_m: float = 26.0
    sonic_rate_hz: float = 10.0
    field_spacing_m: float = 1.0
    field_shape: tuple[int, int, int] = (128, 128, 64)
    coarse_factor: int = 16
    elevation_deg: float = 35.3
    rays_per_scan: int = 60
    scan_period_s: float = 36.0
    gate_length_m: float = 30.0
    n_gates: int = 3
    noise_std: float = 0.05
    seed: int = 1


def case_field(case: MastCase) -> FrozenField:
    """The frozen field of ``case``."""
    return von_karman_field(
        case.field_shape,
        case.field_spacing_m,
        epsilon=case.epsilon,
        integral_scale_m=case.integral_scale_m,
        seed=case.seed,
        coarse_factor=case.coarse_factor,
    )


def sample_mast_sonic(
    field: FrozenField,
    *,
    position_m: tuple[float, float, float],
    wind_speed_m_s: float,
    wind_direction_deg: float,
    start_time: str,
    duration_s: float,
    rate_hz: float,
    vertical_wind_m_s: float = 0.0,
) -> xr.Dataset:
    """A point sonic at ``position_m`` in the frozen field carried by the mean wind.

    u(t) = <V> + v'(x - <V> t), t from ``start_time`` (s); components along east,
    north, up (the instrument's x axis points east: ``orientation_deg`` 90).

    Returns
    -------
    xarray.Dataset
        Canonical sonic dataset (``u``, ``v``, ``w``, ``temperature`` 15 degC,
        ``diagnostic`` 0), attrs ``sampling_rate_hz``, ``orientation_deg``.
    """
    n = int(np.floor(duration_s * rate_hz + 1e-9))
    t = np.arange(n) / rate_hz
    wind = np.array([*wind_components(wind_speed_m_s, wind_direction_deg), vertical_wind_m_s])
    xyz = np.asarray(position_m, dtype=float)[None, :] - wind[None, :] * t[:, None]
    vel = field.interpolate_points(xyz) + wind[None, :]
    time = np.datetime64(start_time, "ns") + np.rint(t * 1e9).astype("timedelta64[ns]")
    return xr.Dataset(
        {
            "u": (("time",), vel[:, 0]),
            "v": (("time",), vel[:, 1]),
            "w": (("time",), vel[:, 2]),
            "temperature": (("time",), np.full(n, 15.0)),
            "diagnostic": (("time",), np.zeros(n, dtype=np.int64)),
        },
        coords={"time": (("time",), time)},
        attrs={
            "instrument": "cwproc virtual mast sonic",
            "frame": "x east, y north, z up",
            "orientation_deg": 90.0,
            "sampling_rate_hz": float(rate_hz),
        },
    )


def write_mast_case(outdir: str | os.PathLike, case: MastCase) -> dict[str, list[Path] | Path]:
    """Write the lidar's ``.hpl`` files (one per 10 min), the mast's Meteo-2 file and
    ``truth.json`` into ``outdir/lidar``, ``outdir/mast`` and ``outdir``."""
    out = Path(outdir)
    (out / "lidar").mkdir(parents=True, exist_ok=True)
    (out / "mast").mkdir(parents=True, exist_ok=True)
    field = case_field(case)
    duration = case.hours * 3600.0
    n_scans = int(duration // case.scan_period_s)
    per_file = max(1, int(600.0 // case.scan_period_s))
    rng = np.random.default_rng(case.seed + 1)
    ranges = (np.arange(case.n_gates) + 0.5) * case.gate_length_m
    lidar_files = []
    for first in range(0, n_scans, per_file):
        ds = sample_conical_scans(
            field,
            elevation_deg=case.elevation_deg,
            ranges_m=ranges,
            rays_per_scan=case.rays_per_scan,
            scan_period_s=case.scan_period_s,
            n_scans=min(per_file, n_scans - first),
            wind_speed_m_s=case.wind_speed,
            wind_direction_deg=case.wind_direction_deg,
            noise_std_m_s=case.noise_std,
            seed=case.seed + 1,
            start_time=case.start,
            delta_r_m=case.gate_length_m,
            range_step_m=case.gate_length_m / 10.0,
            first_scan=first,
            noise_rng=rng,
        )
        ds.attrs.update(system_id="999")
        ds["beta"] = (("ray", "range"), np.full(ds["radial_velocity"].shape, 1.0e-6))
        stamp = np.datetime_as_string(ds["time"].values[0], unit="s").replace("-", "")
        stamp = stamp.replace(":", "").replace("T", "_")
        lidar_files.append(write_hpl(ds, out / "lidar" / f"User1_999_{stamp}.hpl"))
    sonic = sample_mast_sonic(
        field,
        position_m=(0.0, 0.0, case.mast_height_m),
        wind_speed_m_s=case.wind_speed,
        wind_direction_deg=case.wind_direction_deg,
        start_time=case.start,
        duration_s=duration,
        rate_hz=case.sonic_rate_hz,
    )
    day = case.start[:10].replace("-", "")
    mast = out / "mast" / f"meteo2_mast_{day}.txt"
    write_meteo2(sonic, mast, station="virtual mast", decimals=4)
    truth = write_truth(
        out / "truth.json",
        {**asdict(case), "field_shape": list(case.field_shape)},
        sort_keys=False,
    )
    return {"lidar": lidar_files, "mast": mast, "truth": truth}


def field_structure_functions(
    field: FrozenField,
    lags_m: np.ndarray,
    *,
    direction_deg: float,
    height_m: float,
    n_points: int = 20000,
    seed: int = 0,
) -> np.ndarray:
    """The field's own structure functions along the wind at one height (m2 s-2).

    D_i(r) = <[v_i(x + r e) - v_i(x)]^2> over ``n_points`` random points x of the plane
    z = ``height_m`` (the periodic grid is homogeneous in x, y), e the direction the wind
    blows towards, for the longitudinal (along e), transverse (horizontal, across e) and
    vertical components: the structure functions a sonic on this grid sees by Taylor's
    hypothesis, grid resolution included (the nominal eps^(2/3) C r^(2/3) lacks the
    variance of the scales the grid does not hold).

    Returns
    -------
    numpy.ndarray, shape (3, len(lags_m))
    """
    rng = np.random.default_rng(seed)
    ext = field.extent_m
    x, y = rng.uniform(0, ext[0], n_points), rng.uniform(0, ext[1], n_points)
    base = np.column_stack([x, y, np.full(n_points, height_m)])
    e = np.array([*wind_components(1.0, direction_deg), 0.0])
    across = np.array([-e[1], e[0], 0.0])
    v0 = field.interpolate_points(base)
    out = np.empty((3, np.size(lags_m)))
    for j, r in enumerate(np.asarray(lags_m, dtype=float)):
        dv = field.interpolate_points(base + r * e) - v0
        out[0, j] = np.mean((dv @ e) ** 2)
        out[1, j] = np.mean((dv @ across) ** 2)
        out[2, j] = np.mean(dv[:, 2] ** 2)
    return out
