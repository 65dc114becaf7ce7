"""The sample data shipped in ``sample_data/``: simulated Stream Line VAD files + truth.

Regenerate, deterministically (fixed seeds), with::

    python -m cwproc.sim.sample_data sample_data

This writes ``sample_data/streamline/*.hpl`` (only ``.hpl`` files, so that
``cwproc retrieve sample_data/streamline -o out/`` reads nothing else) and the truth
``sample_data/streamline_truth.json`` next to that folder.

The series is made by the virtual Stream Line: a frozen von Karman field
(:func:`cwproc.sim.field3d.von_karman_field`, the isotropic tensor of
Banakh et al. (1999), eq. 16) advected by a known mean wind and sampled by the pulsed
conical-scan sampler (:func:`cwproc.sim.pulsed.sample_conical_scans`, Smalikho (2020),
eqs. 1, 19-20), with white instrumental noise; files are written by
:func:`cwproc.io.halo.write_hpl`. ``cwproc simulate lidar`` uses the same functions.
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import xarray as xr


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
        Range gate length (m); gate centres (g + 0.5) x gate length.
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

    @property
    def ranges_m(self) -> np.ndarray:
        """Gate centres (m)."""
        return (np.arange(self.n_gates) + 0.5) * self.gate_length_m


def simulate_streamline(spec: StreamLineSpec) -> xr.Dataset:
    """The Stream Line VAD series of ``spec`` as one canonical scan dataset.

    Parameters
    ----------
    spec : StreamLineSpec

    Returns
    -------
    xarray.Dataset
        Canonical scan dataset (dims ``ray``, ``range``), the truth in ``sim_*`` attrs.
    """
    from cwproc.sim.field3d import von_karman_field
    from cwproc.sim.pulsed import sample_conical_scans

    field = von_karman_field(
        spec.field_shape,
        spec.field_spacing_m,
        epsilon=spec.epsilon,
        integral_scale_m=spec.integral_scale_m,
        seed=spec.seed,
    )
    ds = sample_conical_scans(
        field,
        elevation_deg=spec.elevation_deg,
        ranges_m=spec.ranges_m,
        rays_per_scan=spec.rays_per_scan,
        scan_period_s=spec.scan_period_s,
        n_scans=spec.n_scans,
        wind_speed_m_s=spec.wind_speed,
        wind_direction_deg=spec.wind_direction_deg,
        noise_std_m_s=spec.noise_std,
        seed=spec.seed + 1,
        start_time=spec.start,
        snr=spec.snr,
    )
    ds.attrs.update(system_id="999", gate_length_m=float(spec.gate_length_m))
    ds["beta"] = (("ray", "range"), np.full(ds["radial_velocity"].shape, 1.0e-6))
    return ds


def streamline_truth(spec: StreamLineSpec) -> dict[str, object]:
    """The truth of a simulated series (what ``cwproc retrieve`` should recover).

    ``velocity_variance_m2_s2`` is sigma_V^2 of the von Karman model; the periodic
    grid of the field holds somewhat less (``grid_velocity_variance_m2_s2``, the
    variance of the horizontal components the grid resolves).
    """
    from cwproc.sim.field3d import grid_variance
    from cwproc.sim.pulsed import wind_components
    from cwproc.sim.turbulence import variance_from_epsilon

    u, v = wind_components(spec.wind_speed, spec.wind_direction_deg)
    grid = grid_variance(
        spec.field_shape, spec.field_spacing_m, spec.epsilon, spec.integral_scale_m
    )
    spec_dict = asdict(spec)
    spec_dict["field_shape"] = list(spec.field_shape)
    return {
        "description": "truth of a simulated Stream Line VAD series (cwproc virtual instrument)",
        "spec": spec_dict,
        "u_m_s": u,
        "v_m_s": v,
        "w_m_s": 0.0,
        "wind_speed_m_s": spec.wind_speed,
        "wind_direction_deg": spec.wind_direction_deg,
        "epsilon_m2_s3": spec.epsilon,
        "integral_scale_m": spec.integral_scale_m,
        "velocity_variance_m2_s2": float(
            variance_from_epsilon(spec.epsilon, spec.integral_scale_m, "von_karman")
        ),
        "grid_velocity_variance_m2_s2": float(np.mean(grid[:2])),
        "noise_std_m_s": spec.noise_std,
        "correlation_model": "von Karman (3-D frozen field)",
        "heights_m": [
            round(float(h), 3) for h in spec.ranges_m * np.sin(np.deg2rad(spec.elevation_deg))
        ],
    }


def split_files(ds: xr.Dataset, scans_per_file: int) -> list[xr.Dataset]:
    """Split a scan dataset into one dataset per file of ``scans_per_file`` scans."""
    file_index = ds["scan"].values // scans_per_file
    out = []
    for k in np.unique(file_index):
        part = ds.isel(ray=np.flatnonzero(file_index == k))
        out.append(part.assign_coords(scan=part["scan"] - part["scan"].values[0]))
    return out


def hpl_file_name(part: xr.Dataset) -> str:
    """``VAD_<id>_<yyyymmdd>_<hhmmss>.hpl`` from the first ray time, as the instrument names it."""
    t = np.datetime_as_string(part["time"].values[0], unit="s")
    stamp = t.replace("-", "").replace(":", "").replace("T", "_")
    return f"VAD_{part.attrs['system_id']}_{stamp}.hpl"


def write_streamline_series(
    folder: str | os.PathLike, truth_path: str | os.PathLike, spec: StreamLineSpec
) -> list[Path]:
    """Simulate a Stream Line series and write it as ``.hpl`` files plus a truth JSON.

    Parameters
    ----------
    folder : path
        Folder of the ``.hpl`` files (created; old ``.hpl`` files in it are removed).
    truth_path : path
        The truth JSON (keep it outside ``folder`` so that ``retrieve`` reads only data).
    spec : StreamLineSpec

    Returns
    -------
    list of pathlib.Path
        The files written, truth last.
    """
    from cwproc.io.halo import write_hpl

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("*.hpl"):
        old.unlink()
    ds = simulate_streamline(spec)
    written = [
        write_hpl(part, folder / hpl_file_name(part))
        for part in split_files(ds, spec.scans_per_file)
    ]
    truth_path = Path(truth_path)
    truth_path.parent.mkdir(parents=True, exist_ok=True)
    truth_path.write_text(json.dumps(streamline_truth(spec), indent=2, sort_keys=True) + "\n")
    written.append(truth_path)
    return written


def noise_from_snr(snr: float) -> float:
    """Radial-velocity noise sigma_e (m s-1) of the virtual Stream Line for a linear SNR.

    An empirical weak-signal law of coherent Doppler lidars, sigma_e = 0.005 / SNR,
    limited to [0.02, 2] m s-1: 0.1 m s-1 at SNR = 0.05 (-13 dB), 0.5 m s-1 at 0.01
    (-20 dB), the Stream Line figures of Smalikho (2020) section 3 order of magnitude.
    """
    return float(np.clip(0.005 / snr, 0.02, 2.0))


#: the series shipped in sample_data/ (12 scans of 180 rays, 24 gates: about 2 MB)
SAMPLE_SPEC = StreamLineSpec()


def write_sample_data(outdir: str | os.PathLike) -> list[Path]:
    """Write ``outdir/streamline/*.hpl`` and ``outdir/streamline_truth.json``."""
    outdir = Path(outdir)
    return write_streamline_series(
        outdir / "streamline", outdir / "streamline_truth.json", SAMPLE_SPEC
    )


def main(argv: list[str] | None = None) -> int:
    """``python -m cwproc.sim.sample_data [OUTDIR]`` (default ``sample_data``)."""
    args = sys.argv[1:] if argv is None else argv
    outdir = args[0] if args else "sample_data"
    for path in write_sample_data(outdir):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
