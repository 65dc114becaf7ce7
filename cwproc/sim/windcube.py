"""Virtual WindCube profiler: DBS lines of sight through a frozen turbulent field.

The virtual instrument points its beam in turn at the azimuths 0, 90, 180 and 270 deg
on a cone of half-angle ``scan_angle_deg`` from the zenith and (v2, v2.1) straight up,
one line of sight every ``los_duration_s`` (0.8 s in the real WF 2.2.1 file,
``real_data/windcube``). Each line of sight gives, at every altitude ``h``, the radial
velocity at range ``h / cos(scan angle)`` (``h`` on the vertical beam) weighted along
the beam by the pulsed range weighting of :func:`cwproc.sim.pulsed.pulsed_range_weight`
(a Gaussian pulse of ``Delta_p`` convolved with a range window ``Delta_R``), in a frozen
von Karman field carried by the mean wind (Taylor's hypothesis), plus white noise whose
standard deviation follows from the CNR (:func:`cwproc.physics.noise.velocity_noise_std`,
Pearson et al. (2009), eq. 3). Each line is one instant (no accumulation time).

The probe and noise settings are assumptions of the virtual instrument, not Leosphere
figures: ``Delta_R = 20 m`` (the WindCube's 20 m range resolution), ``Delta_p = 15 m``,
and the noise of a 1 s accumulation (``pulses_per_los`` x ``points_per_gate``).

Writers: :func:`write_rtd` (v1, v2 and v2.1 layouts of :mod:`cwproc.io.windcube_rtd`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.physics.geometry import wind_components
from cwproc.physics.noise import velocity_noise_std
from cwproc.sim.field3d import FrozenField, von_karman_field
from cwproc.sim.pulsed import probe_averaged_velocity, range_quadrature

#: beam cycle of the v2/v2.1 (four inclined beams, then the vertical one) and of the v1
BEAMS_V2: tuple[str, ...] = ("0", "90", "180", "270", "V")
BEAMS_V1: tuple[str, ...] = ("0", "90", "180", "270")


@dataclass(frozen=True)
class WindCubeSpec:
    """A simulated WindCube DBS series: geometry, probe, wind, turbulence, CNR.

    Attributes
    ----------
    start : str
        ISO time of the first line of sight (UTC).
    duration_s : float
        Length of the series (s).
    heights_m : tuple of float
        Altitudes above the lidar (m).
    scan_angle_deg : float
        Cone half-angle from the zenith (deg); 28 deg on the v2/v2.1.
    los_duration_s : float
        Time between lines of sight (s).
    vertical_beam : bool
        Whether the cycle has the vertical beam (v2, v2.1) or not (v1).
    delta_p_m, delta_r_m : float
        Pulse half-width ``Delta_p = c sigma_p / 2`` and range window ``Delta_R`` (m).
    wind_speed, wind_direction_deg : float
        Mean horizontal wind (m s-1) and the direction it blows from (deg).
    epsilon : float
        Dissipation rate (m2 s-3).
    integral_scale_m : float
        Longitudinal integral scale L_V of the von Karman field (m).
    cnr_db_ground, cnr_db_per_100m : float
        CNR (dB) extrapolated to the ground and its change per 100 m of altitude.
    pulses_per_los, points_per_gate : int
        Accumulation behind one line of sight, for the noise of the CNR.
    field_spacing_m : float
        Grid spacing of the 3-D field (m): fine enough (2.5 m) for the field to hold the
        scales the probe averages out, so that the volume averaging is real.
    field_shape : tuple of int
        Grid points (x, y, z) of the periodic field.
    coarse_factor : int
        The large scales on a second grid this many times coarser (a 2.56 km box: the
        10-min path of 4.8 km at 8 m/s crosses it diagonally without retracing itself).
    seed : int
        Seed of the field; the noise uses ``seed + 1``.
    """

    start: str = "2024-06-01T00:00:00"
    duration_s: float = 600.0
    heights_m: tuple[float, ...] = (40.0, 100.0, 160.0)
    scan_angle_deg: float = 28.0
    los_duration_s: float = 0.8
    vertical_beam: bool = True
    delta_p_m: float = 15.0
    delta_r_m: float = 20.0
    wind_speed: float = 8.0
    wind_direction_deg: float = 240.0
    epsilon: float = 0.01
    integral_scale_m: float = 100.0
    cnr_db_ground: float = -12.0
    cnr_db_per_100m: float = -3.0
    pulses_per_los: int = 10000
    points_per_gate: int = 10
    field_spacing_m: float = 2.5
    field_shape: tuple[int, int, int] = (128, 128, 128)
    coarse_factor: int = 8
    seed: int = 20240602

    @property
    def beams(self) -> tuple[str, ...]:
        """The beam cycle."""
        return BEAMS_V2 if self.vertical_beam else BEAMS_V1

    @property
    def n_los(self) -> int:
        """Lines of sight in the series."""
        return round(self.duration_s / self.los_duration_s)


def windcube_field(spec: WindCubeSpec) -> FrozenField:
    """The frozen von Karman field of ``spec``."""
    return von_karman_field(
        spec.field_shape,
        spec.field_spacing_m,
        epsilon=spec.epsilon,
        integral_scale_m=spec.integral_scale_m,
        seed=spec.seed,
        coarse_factor=spec.coarse_factor,
    )


def cnr_profile(spec: WindCubeSpec) -> np.ndarray:
    """CNR (dB) at the altitudes of ``spec``: a linear decrease with height."""
    return spec.cnr_db_ground + spec.cnr_db_per_100m * np.asarray(spec.heights_m) / 100.0


def noise_std(spec: WindCubeSpec, cnr_db: np.ndarray) -> np.ndarray:
    """Radial-velocity noise sigma_e (m s-1) of one line of sight at CNR ``cnr_db``.

    Pearson et al. (2009), eq. 3 (:func:`cwproc.physics.noise.velocity_noise_std`) with
    the linear CNR as the SNR and the accumulation of ``spec``.
    """
    return velocity_noise_std(
        10.0 ** (np.asarray(cnr_db) / 10.0), spec.points_per_gate, spec.pulses_per_los
    )


def simulate_dbs(
    spec: WindCubeSpec,
    *,
    field: FrozenField | None = None,
    noise_rng: np.random.Generator | None = None,
    origin_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> xr.Dataset:
    """The lines of sight of ``spec`` in the layout of :func:`read_windcube_rtd`.

    Parameters
    ----------
    spec : WindCubeSpec
    field : FrozenField, optional
        The field (default: :func:`windcube_field`).
    noise_rng : numpy.random.Generator, optional
        Noise generator (default: from ``spec.seed + 1``).
    origin_m : tuple of float
        Position of the lidar in the field (m): another origin is another realisation of
        the same field.

    Returns
    -------
    xarray.Dataset
        dims ``(time, height)``: ``radial_velocity`` (with noise), ``radial_velocity_true``
        (probe-averaged, without noise), ``cnr``, ``noise_std``; per line ``beam``,
        ``beam_azimuth``, ``beam_elevation``. attrs: the spec as ``sim_*``.
    """
    field = windcube_field(spec) if field is None else field
    rng = np.random.default_rng(spec.seed + 1) if noise_rng is None else noise_rng
    n = spec.n_los
    beams = np.array([spec.beams[i % len(spec.beams)] for i in range(n)])
    t = np.arange(n) * spec.los_duration_s
    u, v = wind_components(spec.wind_speed, spec.wind_direction_deg)
    mean_wind = np.array([float(u), float(v), 0.0])
    heights = np.asarray(spec.heights_m, dtype=float)
    quad = range_quadrature(spec.delta_p_m, spec.delta_r_m, spec.field_spacing_m / 2)
    velocity = np.empty((n, heights.size))
    vertical = beams == "V"
    azimuth = np.where(vertical, 0.0, np.array([0.0 if b == "V" else float(b) for b in beams]))
    elevation = np.where(vertical, 90.0, 90.0 - spec.scan_angle_deg)
    for is_v in (False, True):
        rows = np.flatnonzero(vertical == is_v)
        if rows.size == 0:
            continue
        el = 90.0 if is_v else 90.0 - spec.scan_angle_deg
        ranges = heights / np.sin(np.deg2rad(el))
        velocity[rows] = probe_averaged_velocity(
            field,
            t[rows, None],
            azimuth[rows, None],
            elevation_deg=el,
            ranges_m=ranges,
            range_quadrature_nodes=quad,
            mean_wind=mean_wind,
            sweep_advection=False,
            lidar_position_m=origin_m,
        )
    cnr = np.broadcast_to(cnr_profile(spec), velocity.shape)
    sigma = noise_std(spec, cnr)
    noisy = velocity + sigma * rng.standard_normal(velocity.shape)
    times = np.datetime64(spec.start, "ns") + (t * 1e9).astype("timedelta64[ns]")
    return xr.Dataset(
        {
            "radial_velocity": (("time", "height"), noisy),
            "radial_velocity_true": (("time", "height"), velocity),
            "cnr": (("time", "height"), np.array(cnr)),
            "noise_std": (("time", "height"), sigma),
            "beam": (("time",), beams),
            "beam_azimuth": (("time",), azimuth),
            "beam_elevation": (("time",), elevation),
        },
        coords={"time": times, "height": heights},
        attrs={
            "scan_angle_deg": spec.scan_angle_deg,
            "sim_epsilon": spec.epsilon,
            "sim_integral_scale_m": spec.integral_scale_m,
            "sim_wind_speed": spec.wind_speed,
            "sim_wind_direction_deg": spec.wind_direction_deg,
        },
    )


_DEG = "\xb0"


def _rtd_header_v2(spec: WindCubeSpec, layout: str) -> list[str]:
    """Header items of a v2 (software 2.x) or v2.1 (WF 2.x, NA settings) ``.rtd``."""
    na = layout == "v2.1"
    angle = "NA" if na else f"{spec.scan_angle_deg:.3f}"
    setting = (lambda value: "NA") if na else (lambda value: value)
    return [
        f"Version={'WF 2.2.1.99999' if na else '2.0.5'}",
        f"ID System={'WLS71999' if na else 'WLS7-999'}",
        "ID Client=",
        "Location=cwproc virtual site",
        f"GPS Location=Lat:56.480000{_DEG}N, Long:85.100000{_DEG}E",
        "Comments=simulated by cwproc.sim.windcube",
        "FCR Option= OFF",
        "timezone=UTC+0",
        "********************",
        "Windcube Parameters (internal use only)",
        "********************",
        f"Pulses / Line of Sight={setting(str(spec.pulses_per_los))}",
        f"Samples / Pulse={setting(str(spec.points_per_gate))}",
        "LOS=1.25" if na else "LOS=0.80",
        f"Wavelength (nm)={setting('1543.000')}",
        f"ScanAngle ({_DEG})={angle}",
        f"DirectionOffset ({_DEG})=0",
        f"PitchAngle ({_DEG})=0.000",
        f"RollAngle ({_DEG})=0.000",
        "CNRThreshold=-23",
        "Altitudes AGL (m)=" if na else "Altitudes (m)=",
        "********************",
    ]


def _fmt(value: float, decimals: int) -> str:
    return "NaN" if not np.isfinite(value) else f"{value:.{decimals}f}"


def write_rtd(ds: xr.Dataset, spec: WindCubeSpec, path: str | os.PathLike, layout: str) -> Path:
    """Write simulated lines of sight as a WindCube ``.rtd`` file.

    Parameters
    ----------
    ds : xarray.Dataset
        :func:`simulate_dbs` output.
    spec : WindCubeSpec
    path : path
    layout : {"v1", "v2", "v2.1"}
        v2.1: ``HeaderSize``, WF software, ``NA`` settings (``ScanAngle`` included),
        ``Altitudes AGL (m)``, temperature ``999.00``; v2: the same columns with the
        settings written; v1: ``HeaderLength``, ``Date`` dd/mm/yyyy, 8 columns per
        altitude (CNR, spectral width, radial velocity at offsets 0, 1, 3; the others
        written NaN), ``Wiper`` On/Off, no vertical beam.
    """
    heights = ds["height"].values
    alt = "\t".join(f"{h:.0f}" for h in heights)
    stamps = np.datetime_as_string(ds["time"].values, unit="ms")
    vr, cnr, beams = ds["radial_velocity"].values, ds["cnr"].values, ds["beam"].values
    if layout == "v1":
        items = [
            "Version=3.1.66",
            "ID System=WLS7-099",
            "Localisation=cwproc virtual site",
            f"ScanAngle({_DEG})={spec.scan_angle_deg:.2f}",
            f"DirectionOffset({_DEG})=0.00",
            f"PitchAngle({_DEG})=0.00",
            f"RollAngle({_DEG})=0.00",
            f"NumberOfAveragedShots={spec.pulses_per_los}",
            f"Altitudes(m)=\t{alt}",
            "********************",
        ]
        names = ["Date", "Position", "Temperature", "Wiper"]
        for k in range(heights.size):
            names += [f"CNR{k + 1}", f"SW{k + 1}", f"c{k + 1}c", f"Vr{k + 1}"]
            names += [f"c{k + 1}e", f"c{k + 1}f", f"c{k + 1}g", f"c{k + 1}h"]
        head = [f"HeaderLength={len(items)}", *items, "\t".join(names)]
        rows = []
        for i, s in enumerate(stamps):
            day, clock = s.split("T")
            y, m, d = day.split("-")
            row = [f"{d}/{m}/{y} {clock[:11]}", beams[i], "25.00", "Off"]
            for k in range(heights.size):
                row += [_fmt(cnr[i, k], 2), "1.20", "NaN", _fmt(vr[i, k], 2)]
                row += ["NaN"] * 4
            rows.append("\t".join(row))
    else:
        items = _rtd_header_v2(spec, layout)
        items[-2] += "\t" + alt
        names = ["Timestamp", "Position", "Temperature", "Wiper Count"]
        suffixes = (
            "CNR (dB)",
            "Radial Wind Speed (m/s)",
            "Radial Wind Speed Dispersion (m/s)",
            "Wind Speed (m/s)",
            f"Wind Direction ({_DEG})",
            "X-wind (m/s)",
            "Y-wind (m/s)",
            "Z-wind (m/s)",
        )
        for h in heights:
            names += [f"{h:.0f}m {s}" for s in suffixes] + [""]
        head = [f"HeaderSize={len(items)}", *items, "\t".join(names)]
        temperature = "999.00" if layout == "v2.1" else "25.00"
        rows = []
        for i, s in enumerate(stamps):
            row = [s.replace("-", "/").replace("T", " ")[:22], beams[i], temperature, "0"]
            for k in range(heights.size):
                z = _fmt(vr[i, k], 3) if beams[i] == "V" else "NaN"
                row += [_fmt(cnr[i, k], 2), _fmt(vr[i, k], 2), "0.02"]
                row += ["NaN", "NaN", "NaN", "NaN", z, ""]
            rows.append("\t".join(row))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(("\n".join(head + rows) + "\n").encode("latin-1"))
    return path


def instrument_statistics(ds: xr.Dataset, interval_s: float = 600.0) -> dict[str, np.ndarray]:
    """The virtual instrument's own statistics of its lines of sight (what a ``.sta`` holds).

    Modelled on the WindCube's documented practice [assumption, no Leosphere algorithm
    text]: after every inclined line of sight the horizontal wind is reconstructed from
    the last four inclined beams (one of each azimuth, DBS:
    ``u = (V_90 - V_270) / (2 sin theta)``, ``v = (V_0 - V_180) / (2 sin theta)``); the
    interval's mean speed, its standard deviation, minimum and maximum are those of the
    reconstructed speeds; the direction is that of the mean (u, v); ``w`` and its
    standard deviation come from the vertical beam (the mean of the four inclined beams
    / cos theta without one). Stamps mark the end of each interval.

    Returns
    -------
    dict
        ``time`` (end of interval), and per (interval, height) ``speed``, ``std``,
        ``min``, ``max``, ``direction``, ``w``, ``w_std``, ``cnr``, ``cnr_min``,
        ``availability`` (%).
    """
    theta = np.deg2rad(float(ds.attrs["scan_angle_deg"]))
    beams = ds["beam"].values
    vr = ds["radial_velocity"].values
    last: dict[str, np.ndarray] = {}
    n, nh = vr.shape
    uv = np.full((n, 2), np.nan)[:, :, None] * np.ones(nh)
    for i, b in enumerate(beams):
        if b == "V":
            continue
        last[b] = vr[i]
        if len(last) == 4:
            uv[i, 0] = (last["90"] - last["270"]) / (2 * np.sin(theta))
            uv[i, 1] = (last["0"] - last["180"]) / (2 * np.sin(theta))
    t0 = ds["time"].values[0]
    seconds = (ds["time"].values - t0).astype(float) / 1e9
    window = np.floor(seconds / interval_s).astype(int)
    n_win = int(seconds[-1] // interval_s) + 1
    out = {
        k: np.full((n_win, nh), np.nan)
        for k in (
            "speed",
            "std",
            "min",
            "max",
            "direction",
            "w",
            "w_std",
            "cnr",
            "cnr_min",
            "availability",
        )
    }
    vertical = beams == "V"
    for k in range(n_win):
        rows = window == k
        u, v = uv[rows, 0], uv[rows, 1]
        good = np.isfinite(u[:, 0])
        speed = np.hypot(u[good], v[good])
        out["speed"][k] = speed.mean(axis=0)
        out["std"][k] = speed.std(axis=0, ddof=1)
        out["min"][k], out["max"][k] = speed.min(axis=0), speed.max(axis=0)
        um, vm = u[good].mean(axis=0), v[good].mean(axis=0)
        out["direction"][k] = np.rad2deg(np.arctan2(-um, -vm)) % 360.0
        if vertical.any():
            wv = vr[rows & vertical]
        else:
            inclined = vr[rows]
            inclined = inclined[: inclined.shape[0] // 4 * 4]
            wv = inclined.reshape(-1, 4, nh).mean(axis=1) / np.cos(theta)
        out["w"][k], out["w_std"][k] = wv.mean(axis=0), wv.std(axis=0, ddof=1)
        out["cnr"][k] = ds["cnr"].values[rows].mean(axis=0)
        out["cnr_min"][k] = ds["cnr"].values[rows].min(axis=0)
        expected = interval_s / float(np.median(np.diff(seconds)))
        out["availability"][k] = np.minimum(100.0, 100.0 * rows.sum() / expected)
    out["time"] = t0 + ((np.arange(n_win) + 1) * interval_s * 1e9).astype("timedelta64[ns]")
    return out


#: the .sta per-altitude columns of the HeaderSize generation (v2, v2.1)
_STA_LONG = (
    ("Wind Speed (m/s)", "speed", 2),
    ("Wind Speed Dispersion (m/s)", "std", 2),
    ("Wind Speed min (m/s)", "min", 2),
    ("Wind Speed max (m/s)", "max", 2),
    (f"Wind Direction ({_DEG})", "direction", 1),
    ("Z-wind (m/s)", "w", 2),
    ("Z-wind Dispersion (m/s)", "w_std", 2),
    ("CNR (dB)", "cnr", 1),
    ("CNR min (dB)", "cnr_min", 1),
    ("Dopp Spect Broad (m/s)", None, 2),
    ("Data Availability (%)", "availability", 0),
)
#: the .sta per-height block of the HeaderLength generation (v1), in file order
_STA_SHORT = (
    ("Vhm", "speed", 2),
    ("dVh", "std", 2),
    ("VhMax", "max", 2),
    ("VhMin", "min", 2),
    ("Azim", "direction", 1),
    ("um", "u", 3),
    ("du", "std", 3),
    ("vm", "v", 3),
    ("dv", "std", 3),
    ("wm", "w", 3),
    ("dw", "w_std", 3),
    ("CNRm", "cnr", 2),
    ("dCNR", None, 2),
    ("CNRmax", "cnr", 2),
    ("CNRmin", "cnr_min", 2),
    ("spectral_broadening", None, 3),
    ("dspectral_broadening", None, 3),
    ("Avail.", "availability", 2),
)


def write_sta(
    stats: dict[str, np.ndarray],
    heights_m: np.ndarray,
    path: str | os.PathLike,
    layout: str,
    *,
    scan_angle_deg: float = 28.0,
    missing_tokens: tuple[str, ...] = ("NaN",),
) -> Path:
    """Write statistics (:func:`instrument_statistics` keys) as a WindCube ``.sta`` file.

    Parameters
    ----------
    stats : dict
        ``time`` (end of interval) and per (interval, height) arrays.
    heights_m : array_like
        Altitudes (m).
    path : path
        The file (``.sta`` or ``.stdsta``: one layout).
    layout : {"v1", "v2", "v2.1"}
        v1: ``HeaderLength``, ``Date`` dd/mm/yyyy HH:MM:SS, short names per height index
        (software 3.x); v2: ``HeaderSize``, long names (software 1.x); v2.1: as v2 with
        the WF 2.x header (``NA`` settings, ``ScanAngle (°)=NA``, ``Altitudes AGL (m)``).
    missing_tokens : tuple of str
        How a missing value is written, in turn (``NaN``; WF 2.x files may hold ``NA``,
        ``-`` or nothing).
    """
    heights = np.asarray(heights_m, dtype=float)
    token = iter(np.resize(np.array(missing_tokens, dtype=object), 10**6))

    def cell(value: float, decimals: int) -> str:
        return next(token) if not np.isfinite(value) else f"{value:.{decimals}f}"

    if "u" not in stats:
        from cwproc.physics.geometry import wind_components as _wc

        u, v = _wc(stats["speed"], stats["direction"])
        stats = {**stats, "u": u, "v": v}
    times = stats["time"].astype("datetime64[s]").astype(object)
    if layout == "v1":
        head, rows = _sta_v1(stats, heights, times, scan_angle_deg, cell)
    else:
        head, rows = _sta_v2(stats, heights, times, scan_angle_deg, cell, na=layout == "v2.1")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(("\n".join(head + rows) + "\n").encode("latin-1"))
    return path


def _sta_v1(
    stats: dict[str, np.ndarray],
    heights: np.ndarray,
    times: np.ndarray,
    scan_angle_deg: float,
    cell: Callable[[float, int], str],
) -> tuple[list[str], list[str]]:
    """Header and data lines of a v1 ``.sta`` file (software 3.x: ``HeaderLength``,
    ``Date`` dd/mm/yyyy HH:MM:SS, short names per height index); ``cell`` writes a value."""
    alt = "\t".join(f"{h:.0f}" for h in heights)
    rows = []
    items = [
        "Version=3.1.66",
        "ID System=WLS7-099",
        "Localisation=cwproc virtual site",
        "Measurements informations :",
        "********************",
        f"ScanAngle({_DEG})={scan_angle_deg:.2f}",
        f"HeadingAngle({_DEG})=0.00",
        f"Altitudes(m)=\t{alt}",
        "********************",
    ]
    names = ["Date", "WiperCount", "Tm"]
    for k in range(heights.size):
        for name, _, _ in _STA_SHORT:
            indexed = name not in ("CNRm", "dCNR", "CNRmax", "CNRmin") and "spectral" not in name
            names.append(f"{name}{k + 1}" if indexed else name)
        names.append("")
    head = [f"HeaderLength={len(items)}", *items, "\t".join(names)]
    for r, t in enumerate(times):
        row = [t.strftime("%d/%m/%Y %H:%M:%S"), "0", "15.00"]
        for k in range(heights.size):
            for _, key, dec in _STA_SHORT:
                row.append(cell(stats[key][r, k], dec) if key else f"{0.1:.{dec}f}")
            row.append("")
        rows.append("\t".join(row))
    return head, rows


def _sta_v2(
    stats: dict[str, np.ndarray],
    heights: np.ndarray,
    times: np.ndarray,
    scan_angle_deg: float,
    cell: Callable[[float, int], str],
    *,
    na: bool,
) -> tuple[list[str], list[str]]:
    """Header and data lines of a v2 ``.sta`` file (software 1.x: ``HeaderSize``, long
    names); ``na``: the WF 2.x header of v2.1 (``NA`` settings, ``Altitudes AGL (m)``)."""
    alt = "\t".join(f"{h:.0f}" for h in heights)
    rows = []
    items = [
        f"Version={'WF 2.2.1.99999' if na else '1.1.13'}",
        f"ID System={'WLS71999' if na else 'WLS7-999'}",
        "ID Client=",
        "Location=cwproc virtual site",
        f"GPS Location=Lat:56.480000{_DEG}N, Long:85.100000{_DEG}E",
        "Comments=simulated by cwproc.sim.windcube",
        "FCR Option= OFF",
        "timezone=UTC+0",
        "********************",
        f"Pulses / Line of Sight={'NA' if na else '10000'}",
        f"Wavelength (nm)={'NA' if na else '1543.000'}",
        f"ScanAngle ({_DEG})={'NA' if na else f'{scan_angle_deg:.3f}'}",
        f"DirectionOffset ({_DEG})=0",
        f"{'Altitudes AGL (m)' if na else 'Altitudes (m)'}=\t{alt}",
        "********************",
    ]
    names = ["Timestamp (end of interval)", f"Int Temp ({_DEG}C)", f"Ext Temp ({_DEG}C)"]
    names += ["Pressure (hPa)", "Rel Humidity (%)", "Wiper count", "Vbatt (V)"]
    for h in heights:
        names += [f"{h:.0f}m {name}" for name, _, _ in _STA_LONG] + [""]
    head = [f"HeaderSize={len(items)}", *items, "\t".join(names)]
    for r, t in enumerate(times):
        row = [t.strftime("%Y/%m/%d %H:%M"), "26.10", "15.00", "1005.0", "60.0", "0"]
        row.append("NA" if na else "12.1")
        for k in range(heights.size):
            for _, key, dec in _STA_LONG:
                row.append(cell(stats[key][r, k], dec) if key else f"{1.2:.{dec}f}")
            row.append("")
        rows.append("\t".join(row))
    return head, rows


def mast_truth(
    spec: WindCubeSpec,
    field: FrozenField,
    ds: xr.Dataset,
    origin_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> dict[str, np.ndarray]:
    """A virtual met mast at the lidar: the point wind at each altitude and line time.

    Returns
    -------
    dict
        ``u``, ``v``, ``w`` (m s-1), shape (time, height): the mean wind plus the frozen
        field at ``origin + (0, 0, h) - U t`` (Taylor's hypothesis, as the lidar sees it).
    """
    u0, v0 = wind_components(spec.wind_speed, spec.wind_direction_deg)
    t = (ds["time"].values - ds["time"].values[0]).astype(float) / 1e9
    h = ds["height"].values
    x = origin_m[0] - float(u0) * t[:, None] + 0.0 * h
    y = origin_m[1] - float(v0) * t[:, None] + 0.0 * h
    z = origin_m[2] + h[None, :] + 0.0 * t[:, None]
    vel = field.interpolate(x, y, z)
    return {"u": vel[0] + float(u0), "v": vel[1] + float(v0), "w": vel[2]}


def rtd_truth(spec: WindCubeSpec, field: FrozenField, ds: xr.Dataset) -> dict[str, object]:
    """The truth of a simulated ``.rtd`` series: the virtual mast's mean wind, standard
    deviations and TI per altitude over the whole series, and the settings."""
    from dataclasses import asdict

    mast = mast_truth(spec, field, ds)
    speed = np.hypot(mast["u"], mast["v"])
    u0, v0 = wind_components(spec.wind_speed, spec.wind_direction_deg)
    spec_dict = asdict(spec)
    spec_dict["field_shape"] = list(spec.field_shape)
    spec_dict["heights_m"] = list(spec.heights_m)

    def r(a: np.ndarray) -> list[float]:
        return [round(float(x), 4) for x in a]

    return {
        "description": "truth of a simulated WindCube DBS series (cwproc virtual instrument); "
        "mast_* are the point winds at the lidar's altitudes over the series",
        "spec": spec_dict,
        "u_m_s": float(u0),
        "v_m_s": float(v0),
        "heights_m": list(spec.heights_m),
        "mast_wind_speed_m_s": r(speed.mean(axis=0)),
        "mast_u_std_m_s": r(mast["u"].std(axis=0, ddof=1)),
        "mast_v_std_m_s": r(mast["v"].std(axis=0, ddof=1)),
        "mast_w_std_m_s": r(mast["w"].std(axis=0, ddof=1)),
        "mast_speed_std_m_s": r(speed.std(axis=0, ddof=1)),
        "mast_turbulence_intensity": r(speed.std(axis=0, ddof=1) / speed.mean(axis=0)),
    }


def along_wind_truth(mast: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean speed, along-wind standard deviation and TI of a virtual mast's series
    (per height): the truth of :func:`cwproc.stages.dbs.dbs_statistics`."""
    um, vm = mast["u"].mean(axis=0), mast["v"].mean(axis=0)
    speed = np.hypot(um, vm)
    along = (mast["u"] * um + mast["v"] * vm) / speed
    std = along.std(axis=0, ddof=1)
    return speed, std, std / speed


#: the TI estimates compared with the truth by :func:`ti_trials`
TI_ESTIMATES = (
    "turbulence_intensity",
    "turbulence_intensity_noise",
    "turbulence_intensity_volume",
    "turbulence_intensity_cross",
    "turbulence_intensity_corrected",
)


def ti_trials(
    spec: WindCubeSpec, seeds: list[int], origins: list[tuple[float, float, float]]
) -> dict[str, np.ndarray]:
    """Many realisations of one 10-min DBS series: TI and mean wind, estimated and true.

    Each seed makes a field; each origin puts the lidar elsewhere in it (origins a few
    integral scales apart across the wind are nearly independent realisations). Per
    realisation and height: the TI of every estimate of :data:`TI_ESTIMATES` (from the
    lines of sight, :func:`cwproc.stages.dbs.dbs_statistics` with the spec's probe and
    integral scale), the TI and mean speed of the instrument's own statistics
    (:func:`instrument_statistics`, what its ``.sta`` holds) and of the virtual mast.

    Returns
    -------
    dict
        arrays of shape (realisations, heights): the estimates' names, ``sta_ti``,
        ``sta_speed``, ``rtd_speed``, ``truth_ti``, ``truth_speed``.
    """
    from dataclasses import replace

    from cwproc.stages.dbs import dbs_statistics

    rows: dict[str, list[np.ndarray]] = {}
    for seed in seeds:
        run = replace(spec, seed=seed)
        field = windcube_field(run)
        for origin in origins:
            ds = simulate_dbs(run, field=field, origin_m=origin)
            stats = dbs_statistics(
                ds,
                window_s=spec.duration_s,
                delta_p_m=spec.delta_p_m,
                delta_r_m=spec.delta_r_m,
                points_per_gate=spec.points_per_gate,
                pulses_per_los=spec.pulses_per_los,
                integral_scale_m=spec.integral_scale_m,
            ).isel(time=0)
            sta = instrument_statistics(ds, spec.duration_s)
            mast = mast_truth(run, field, ds, origin)
            speed, _, ti = along_wind_truth(mast)
            values = {name: stats[name].values for name in TI_ESTIMATES}
            for c in "uvw":
                values[f"{c}_variance_measured"] = stats[f"{c}_variance_measured"].values
                values[f"{c}_variance"] = stats[f"{c}_variance"].values
                values[f"truth_{c}_variance"] = mast[c].var(axis=0, ddof=1)
            values.update(
                sta_ti=sta["std"][0] / sta["speed"][0],
                sta_speed=sta["speed"][0],
                rtd_speed=stats["wind_speed"].values,
                truth_ti=ti,
                truth_speed=speed,
            )
            for name, value in values.items():
                rows.setdefault(name, []).append(np.asarray(value, dtype=float))
    return {name: np.array(value) for name, value in rows.items()}


def bias_table(trials: dict[str, np.ndarray]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per estimate: mean (estimate - truth) and its standard error over realisations,
    per height (TI estimates against ``truth_ti``, speeds against ``truth_speed``, the
    variances of ``u``, ``v``, ``w`` against ``truth_<c>_variance``)."""
    out = {}
    n = trials["truth_ti"].shape[0]
    for name, values in trials.items():
        if name.startswith("truth"):
            continue
        if name.endswith("speed"):
            truth = trials["truth_speed"]
        elif "_variance" in name:
            truth = trials[f"truth_{name[0]}_variance"]
        else:
            truth = trials["truth_ti"]
        diff = values - truth
        out[name] = (diff.mean(axis=0), diff.std(axis=0, ddof=1) / np.sqrt(n))
    return out
