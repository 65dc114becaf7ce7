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

import os
import sys
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc import progress
from cwproc.io.halo import write_hpl
from cwproc.io.meteo2 import write_meteo2
from cwproc.physics.geometry import wind_components
from cwproc.physics.spectra import variance_from
from cwproc.sim.field3d import FrozenField, grid_variance, von_karman_field
from cwproc.sim.output import fresh_folder, write_truth
from cwproc.sim.pulsed import sample_conical_scans
from cwproc.sim.sonic import simulate_sonic_dataset
from cwproc.sim.specs import SonicSpec, StreamLineSpec, WindRecordSpec
from cwproc.sim.windcube_samples import write_windcube_rtd_samples, write_windcube_variants


def streamline_field(spec: StreamLineSpec) -> FrozenField:
    """The frozen von Karman field of ``spec`` (its epsilon, L_V, grid and seed)."""
    return von_karman_field(
        spec.field_shape,
        spec.field_spacing_m,
        epsilon=spec.epsilon,
        integral_scale_m=spec.integral_scale_m,
        seed=spec.seed,
    )


def simulate_streamline(
    spec: StreamLineSpec,
    *,
    field: FrozenField | None = None,
    first_scan: int = 0,
    n_scans: int | None = None,
    noise_rng: np.random.Generator | None = None,
) -> xr.Dataset:
    """The Stream Line VAD series of ``spec`` (or scans of it) as one canonical scan dataset.

    Parameters
    ----------
    spec : StreamLineSpec
    field : FrozenField, optional
        The field of ``spec`` (:func:`streamline_field`), when already made.
    first_scan, n_scans : int, optional
        The scans ``first_scan .. first_scan + n_scans - 1`` of the series (default:
        all of them).
    noise_rng : numpy.random.Generator, optional
        The noise generator of the series (default: a new one from ``spec.seed + 1``);
        scans made piece by piece with one generator get the noise of the whole series.

    Returns
    -------
    xarray.Dataset
        Canonical scan dataset (dims ``ray``, ``range``), the truth in ``sim_*`` attrs.
    """
    ds = sample_conical_scans(
        streamline_field(spec) if field is None else field,
        elevation_deg=spec.elevation_deg,
        ranges_m=spec.ranges_m,
        rays_per_scan=spec.rays_per_scan,
        scan_period_s=spec.scan_period_s,
        n_scans=spec.n_scans if n_scans is None else n_scans,
        wind_speed_m_s=spec.wind_speed,
        wind_direction_deg=spec.wind_direction_deg,
        noise_std_m_s=spec.noise_std,
        seed=spec.seed + 1,
        start_time=spec.start,
        snr=spec.snr,
        delta_r_m=spec.gate_length_m,
        range_step_m=spec.range_step_m,
        first_scan=first_scan,
        noise_rng=noise_rng,
    )
    ds.attrs.update(system_id="999", gate_length_m=float(spec.gate_length_m))
    ds["beta"] = (("ray", "range"), np.full(ds["radial_velocity"].shape, 1.0e-6))
    return ds


def streamline_files(spec: StreamLineSpec) -> Iterator[xr.Dataset]:
    """The series of ``spec`` file by file (``scans_per_file`` scans each, scans numbered
    from 0 in each), made piece by piece from one field and one noise generator: the
    same values as :func:`simulate_streamline` split by :func:`split_files`, in the
    memory of one file."""
    field = streamline_field(spec)
    rng = np.random.default_rng(spec.seed + 1)
    for first in range(0, spec.n_scans, spec.scans_per_file):
        n = min(spec.scans_per_file, spec.n_scans - first)
        ds = simulate_streamline(spec, field=field, first_scan=first, n_scans=n, noise_rng=rng)
        yield ds.assign_coords(scan=ds["scan"] - first)


def streamline_truth(spec: StreamLineSpec) -> dict[str, object]:
    """The truth of a simulated series (what ``cwproc retrieve`` should recover).

    ``velocity_variance_m2_s2`` is sigma_V^2 of the von Karman model; the periodic
    grid of the field holds somewhat less (``grid_velocity_variance_m2_s2``, the
    variance of the horizontal components the grid resolves).
    """

    u, v = wind_components(spec.wind_speed, spec.wind_direction_deg)
    grid = grid_variance(
        spec.field_shape, spec.field_spacing_m, spec.epsilon, spec.integral_scale_m
    )
    spec_dict = asdict(spec)
    spec_dict["field_shape"] = list(spec.field_shape)
    if spec.range_step_m is None:  # the field spacing: the truth reads as it always did
        del spec_dict["range_step_m"]
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
            variance_from(spec.epsilon, spec.integral_scale_m, "von_karman")
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

    folder = fresh_folder(folder, "*.hpl")
    n_files = -(-spec.n_scans // spec.scans_per_file)
    files = progress.track(streamline_files(spec), desc="scans", total=n_files, unit="file")
    written = [write_hpl(part, folder / hpl_file_name(part)) for part in files]
    written.append(write_truth(truth_path, streamline_truth(spec)))
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


# --------------------------------------------------------------------------------------
# wind records (ZephIR 300, WindCube v1): 10-min statistics of a known profile
# --------------------------------------------------------------------------------------


def _wind_records(spec: WindRecordSpec) -> dict[str, np.ndarray]:
    """Per record and height: speed, its std, min, max, direction, w, packets."""
    rng = np.random.default_rng(spec.seed)
    speed, direction = spec.profile()
    shape = (spec.n_records, speed.size)
    sigma = spec.turbulence_intensity * speed
    mean = speed + rng.normal(0.0, 1.0, shape) * sigma / np.sqrt(spec.n_samples) * 4.0
    std = sigma * (1.0 + 0.1 * rng.normal(0.0, 1.0, shape))
    return {
        "speed": mean,
        "std": np.abs(std),
        "min": mean - 2.5 * np.abs(std),
        "max": mean + 2.5 * np.abs(std),
        "direction": (direction + rng.normal(0.0, 3.0, shape)) % 360.0,
        "w": rng.normal(0.0, 0.05, shape),
        "packets": rng.integers(34, 38, shape),
    }


def _decimal_comma(value: float, decimals: int) -> str:
    return f"{value:.{decimals}f}".replace(".", ",")


def write_zephir_csv(
    spec: WindRecordSpec,
    path: str | os.PathLike,
    *,
    interval_s: int = 600,
    line_end: str = "\r\n",
) -> Path:
    """A ZephIR 300 Waltz "CSV Converter" export: 10-min (``Wind10_*.ZPH.csv``) or 1-s.

    Semicolon-separated, decimal commas; the header items, the column names and
    the trailing ``Checksum`` field of the real exports (FORMATS.md section 2), with
    heights from the top down as the instrument writes them. ``interval_s = 1`` writes
    the 1-s layout (FORMATS.md section 2.2: ``Raining`` 0/1 in place of the rain
    proportion, and ``Packets in Average at MET``); ``line_end`` may be CRLF, LF or CR
    alone (exports edited on old Macs end lines with CR).
    """
    rec = _wind_records(spec)
    order = np.argsort(spec.heights_m)[::-1]
    heights = [round(spec.heights_m[k]) for k in order]
    header = (
        "CSV Converter: v1,114;Filter: v1,026;Averager: v1,009;File system version: v4;"
        "Unit: 999;Time sync: UTC +0,0 hrs;Time stamps indicate the beginning of the "
        "averaging period;The GPS field contains latitude and longitude coordinates in "
        "decimal degrees (positive sign indicates North or East);ZephIR window height "
        "above ground: 1,0m;Measurement heights: " + " ".join(f"{h}m" for h in heights)
    )
    names = [
        "Reference",
        "Time and Date",
        "Timestamp (s)",
        "Info. Flags",
        "Status Flags",
        "Battery (V)",
        "Air Temp. (C)",
        "Pressure (mbar)",
        "Humidity (%)",
        "Proportion Of Packets With Rain (%)" if interval_s > 1 else "Raining",
    ]
    if interval_s == 1:
        names.append("Packets in Average at MET")
    per_height = [
        "Packets in Average",
        "Wind Direction (deg)",
        "Horizontal Wind Speed (m/s)",
        "Horizontal Wind Speed Min (m/s)",
        "Horizontal Wind Speed Max (m/s)",
        "Horizontal Wind Speed Std. Dev. (m/s)",
        "Vertical Wind Speed (m/s)",
        "TI",
    ]
    for h in heights:
        names += [f"{n} at {h}m" for n in per_height]
    names.append("Checksum:cwproc-sample")
    t0 = np.datetime64(spec.start, "s")
    lines = [header, ";".join(names)]
    for r in range(spec.n_records):
        t = t0 + np.timedelta64(interval_s * r, "s")
        stamp = str(t.astype(object).strftime("%d.%m.%Y %H:%M:%S"))
        row = [
            str(22000000 + r),
            stamp,
            str(int((t - np.datetime64("2001-01-01T00:00:00", "s")).astype(int))),
            "I-net Shutter-Open",
            "Modem",
            "12,100",
            "15,000",
            "1005,000",
            "60,000",
            "0",
        ]
        if interval_s == 1:
            row.append("1")
        for k in order:
            sp = rec["speed"][r, k]
            row += [
                str(int(rec["packets"][r, k])),
                _decimal_comma(rec["direction"][r, k], 3),
                _decimal_comma(sp, 3),
                _decimal_comma(rec["min"][r, k], 3),
                _decimal_comma(rec["max"][r, k], 3),
                _decimal_comma(rec["std"][r, k], 3),
                _decimal_comma(rec["w"][r, k], 3),
                _decimal_comma(rec["std"][r, k] / sp, 6),
            ]
        row.append("0")
        lines.append(";".join(row))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes((line_end.join(lines) + line_end).encode("latin-1"))
    return path


def write_windcube_sta(spec: WindRecordSpec, path: str | os.PathLike) -> Path:
    """A WindCube v1 (software 1.x) ``.sta`` 10-min statistics file.

    Latin-1, TAB-separated, ``HeaderSize=N`` and the header items of the real files
    (FORMATS.md section 3); stamps mark the end of each interval; every height block
    ends with an empty column.
    """
    rec = _wind_records(spec)
    deg = "\xb0"
    items = [
        "Version=1.1.13",
        "ID System=WLS7-999",
        "ID Client=cwproc",
        "Location=cwproc virtual site",
        "GPS Location=Lat:56.480000N, Long:85.100000E",
        "Comments=simulated by cwproc.sim.sample_data",
        "FCR Option=OFF",
        "timezone=UTC+0",
        "********************",
        "Wavelength (nm)=1543.000",
        f"ScanAngle ({deg})=30.000",
        f"DirectionOffset ({deg})=0.000",
        "CNRThreshold=-23.000",
        "Altitudes (m)=\t" + "\t".join(f"{h:.0f}" for h in spec.heights_m),
        "********************",
    ]
    per_height = [
        "Wind Speed (m/s)",
        "Wind Speed Dispersion (m/s)",
        "Wind Speed min (m/s)",
        "Wind Speed max (m/s)",
        f"Wind Direction ({deg})",
        "Z-wind (m/s)",
        "Z-wind Dispersion (m/s)",
        "CNR (dB)",
        "CNR min (dB)",
        "Dopp Spect Broad (m/s)",
        "Data Availability (%)",
    ]
    names = [
        "Timestamp (end of interval)",
        f"Int Temp ({deg}C)",
        f"Ext Temp ({deg}C)",
        "Pressure (hPa)",
        "Rel Humidity (%)",
        "Wiper count",
        "Vbatt (V)",
    ]
    for h in spec.heights_m:
        names += [f"{h:.0f}m {n}" for n in per_height] + [""]
    t0 = np.datetime64(spec.start, "s")
    lines = [f"HeaderSize={len(items)}", *items, "\t".join(names)]
    for r in range(spec.n_records):
        t = t0 + np.timedelta64(600 * (r + 1), "s")
        row = [str(t.astype(object).strftime("%Y/%m/%d %H:%M")), "25.00", "15.00"]
        row += ["1005.0", "60.0", "0", "12.1"]
        for k in range(len(spec.heights_m)):
            row += [
                f"{rec['speed'][r, k]:.2f}",
                f"{rec['std'][r, k]:.2f}",
                f"{max(rec['min'][r, k], 0.0):.2f}",
                f"{rec['max'][r, k]:.2f}",
                f"{rec['direction'][r, k]:.1f}",
                f"{rec['w'][r, k]:.2f}",
                "0.10",
                f"{-12.0 - 0.02 * spec.heights_m[k]:.1f}",
                f"{-14.0 - 0.02 * spec.heights_m[k]:.1f}",
                "1.20",
                "100",
                "",
            ]
        lines.append("\t".join(row))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode("latin-1"))
    return path


def wind_records_truth(spec: WindRecordSpec) -> dict[str, object]:
    """The profile behind the wind-record samples."""
    speed, direction = spec.profile()
    return {
        "spec": asdict(spec),
        "heights_m": list(spec.heights_m),
        "wind_speed_m_s": [round(float(x), 4) for x in speed],
        "wind_direction_deg": [round(float(x), 3) for x in direction],
    }


# --------------------------------------------------------------------------------------
# sonic logs: one synthetic 10-min record (cwproc.sim.sonic) in each logger format
# --------------------------------------------------------------------------------------


def simulate_sonic(spec: SonicSpec, rate_hz: float | None = None) -> xr.Dataset:
    """The record of ``spec`` at ``rate_hz`` (default the spec's)."""

    return simulate_sonic_dataset(
        hours=spec.minutes / 60.0,
        sf_type=spec.sf_type,
        seed=spec.seed,
        speed=spec.speed,
        direction_deg=spec.direction_deg,
        rate_hz=rate_hz or spec.rate_hz,
        start=spec.start,
    )


def _campbell_stamps(time: np.ndarray) -> list[str]:
    """TOA5 stamps: trailing zeros of the fraction dropped, as the loggers write them."""
    out = []
    for t in np.datetime_as_string(time.astype("datetime64[ms]"), unit="ms"):
        day, clock = t.split("T")
        whole, frac = clock.split(".")
        frac = frac.rstrip("0")
        out.append(f'"{day} {whole}{"." + frac if frac else ""}"')
    return out


def write_toa5(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """A Campbell TOA5 file of CSAT3 fields (quoted header, CRLF; FORMATS.md 4.1)."""
    header = [
        '"TOA5","999","CR3000","999","CR3000.Std.22","CPU:cwproc_sample.CR3","1","ts_data"',
        '"TIMESTAMP","RECORD","Ux","Uy","Uz","Ts","diag_csat"',
        '"TS","RN","m/s","m/s","m/s","C","unitless"',
        '"","","Smp","Smp","Smp","Smp","Smp"',
    ]
    rows = [
        f"{stamp},{k},{u:.4f},{v:.4f},{w:.4f},{t:.3f},{int(d)}"
        for k, (stamp, u, v, w, t, d) in enumerate(
            zip(
                _campbell_stamps(ds["time"].values),
                ds["u"].values,
                ds["v"].values,
                ds["w"].values,
                ds["temperature"].values,
                ds["diagnostic"].values,
                strict=True,
            )
        )
    ]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(("\r\n".join(header + rows) + "\r\n").encode("ascii"))
    return path


def write_tob1(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """A Campbell TOB1 file: five ASCII header lines, then little-endian binary records
    (SECONDS since 1990-01-01, NANOSECONDS, RECORD as ULONG; the fields as IEEE4)."""
    header = [
        '"TOB1","999","CR5000","999","CR5000.Std.07","CPU:cwproc_sample.CR5","1","ts_data"',
        '"SECONDS","NANOSECONDS","RECORD","Ux","Uy","Uz","Ts","diag_csat"',
        '"SECONDS","NANOSECONDS","RN","m/s","m/s","m/s","degC","unitless"',
        '"","","","Smp","Smp","Smp","Smp","Smp"',
        '"ULONG","ULONG","ULONG","IEEE4","IEEE4","IEEE4","IEEE4","IEEE4"',
    ]
    ns = (ds["time"].values - np.datetime64("1990-01-01T00:00:00", "ns")).astype(np.int64)
    dtype = np.dtype([("s", "<u4"), ("n", "<u4"), ("r", "<u4")] + [(c, "<f4") for c in "uvwtd"])
    rec = np.zeros(ds.sizes["time"], dtype=dtype)
    rec["s"], rec["n"] = ns // 1_000_000_000, ns % 1_000_000_000
    rec["r"] = np.arange(rec.size)
    for c, name in zip("uvwtd", ("u", "v", "w", "temperature", "diagnostic"), strict=True):
        rec[c] = ds[name].values
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(("\r\n".join(header) + "\r\n").encode("ascii") + rec.tobytes())
    return path


def write_ghg_data(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """A LI-COR ``.data`` file (the text inside a ``.ghg`` archive): header items, a
    ``DATAH`` line, then ``DATA`` lines with Unix Seconds + Nanoseconds (UTC)."""
    header = [
        "Model:\tLI-7500RS Open Path CO2/H2O Analyzer",
        "SN:\t75H-0999",
        "Instrument:\tAIU-0999",
        "File Type:\t2",
        "Software Version:\t8.0.0",
        "Timestamp:\t12:00:00",
        "Timezone:\tUTC",
        "DATAH\tSeconds\tNanoseconds\tDiagnostic Value\tDate\tTime\tTemperature (C)"
        "\tAux 1 - U (m/s)\tAux 2 - V (m/s)\tAux 3 - W (m/s)\tAux 4 - SOS (m/s)",
    ]
    ns = (ds["time"].values - np.datetime64("1970-01-01T00:00:00", "ns")).astype(np.int64)
    stamps = np.datetime_as_string(ds["time"].values.astype("datetime64[ms]"), unit="ms")
    sos = 331.3 * np.sqrt(1.0 + ds["temperature"].values / 273.15)
    rows = [
        f"DATA\t{n // 1_000_000_000}\t{n % 1_000_000_000}\t255\t{st[:10]}\t"
        f"{st[11:19]}:{st[20:23]}\t{t:.4f}\t{u:.5f}\t{v:.5f}\t{w:.5f}\t{c:.3f}"
        for n, st, t, u, v, w, c in zip(
            ns,
            stamps,
            ds["temperature"].values,
            ds["u"].values,
            ds["v"].values,
            ds["w"].values,
            sos,
            strict=True,
        )
    ]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(("\n".join(header + rows) + "\n").encode("ascii"))
    return path


def write_gill(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """A Gill UVW ASCII log (node Q, STX/ETX framing with the XOR checksum, CRLF).

    The lines carry no time: the reader takes ``start_time`` and ``sampling_rate_hz``
    from ``[reader.gill]`` (``sample_data/sonic.toml``).
    """
    out = []
    for u, v, w, t in zip(
        ds["u"].values, ds["v"].values, ds["w"].values, ds["temperature"].values, strict=True
    ):
        sos = 331.3 * np.sqrt(1.0 + t / 273.15)
        payload = f"Q,{u:+07.2f},{v:+07.2f},{w:+07.2f},M,{sos:+07.2f},{t:+07.2f},00,"
        check = 0
        for byte in payload.encode("ascii"):
            check ^= byte
        out.append(f"\x02{payload}\x03{check:02X}\r\n")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes("".join(out).encode("latin-1"))
    return path


def write_sonic_samples(folder: str | os.PathLike, spec: SonicSpec) -> list[Path]:
    """The sonic record of ``spec`` in the TOA5, TOB1, GHG (.data), Gill and Meteo-2
    formats (Meteo-2 at its own 10.7 Hz), plus ``truth.json`` next to the folder."""

    folder = Path(folder)
    ds = simulate_sonic(spec)
    stamp = spec.start[:10].replace("-", "_") + "_" + spec.start[11:13] + spec.start[14:16]
    written = [
        write_toa5(ds, folder / f"TOA5_999.ts_data_{stamp}.dat"),
        write_tob1(ds, folder / f"TOB1_999.ts_data_{stamp}.dat"),
        write_ghg_data(ds, folder / f"{spec.start[:10]}T{spec.start[11:13]}0000_AIU-0999.data"),
        write_gill(ds, folder / f"gill_{stamp}.txt"),
    ]
    meteo2 = folder / f"meteo2_{stamp}.txt"
    write_meteo2(simulate_sonic(spec, rate_hz=10.7), meteo2, station="cwproc sample")
    written.append(meteo2)
    return written


def write_sample_data(outdir: str | os.PathLike) -> list[Path]:
    """Write every shipped sample under ``outdir`` (see ``sample_data/README.md``).

    ``streamline/*.hpl`` + ``streamline_truth.json``; ``zephir/*.ZPH.csv`` and
    ``windcube/*.sta`` + ``wind_records_truth.json``; ``sonic/`` (TOA5, TOB1, GHG,
    Gill, Meteo-2) + ``sonic_truth.json``. Deterministic: byte-identical on every run.
    """
    outdir = Path(outdir)
    written = write_streamline_series(
        outdir / "streamline", outdir / "streamline_truth.json", SAMPLE_SPEC
    )
    records = WindRecordSpec()
    day = records.start[:10].split("-")
    written.append(
        write_zephir_csv(
            records, outdir / "zephir" / f"Wind10_999@Y{day[0]}_M{day[1]}_D{day[2]}.ZPH.csv"
        )
    )
    written.append(
        write_windcube_sta(records, outdir / "windcube" / f"WLS7-999_{'_'.join(day)}__00_00_00.sta")
    )
    written += write_windcube_variants(records, _wind_records(records), outdir / "windcube")
    written.append(
        write_zephir_csv(
            records,
            outdir / "zephir" / f"Wind_999@Y{day[0]}_M{day[1]}_D{day[2]}.ZPH.csv",
            interval_s=1,
            line_end="\r",
        )
    )
    written.append(write_truth(outdir / "wind_records_truth.json", wind_records_truth(records)))
    written += write_windcube_rtd_samples(
        outdir / "windcube_rtd", outdir / "windcube_rtd_truth.json"
    )
    sonic = SonicSpec()
    written += write_sonic_samples(outdir / "sonic", sonic)
    written.append(write_truth(outdir / "sonic_truth.json", {"spec": asdict(sonic)}))
    return written


def main(argv: list[str] | None = None) -> int:
    """``python -m cwproc.sim.sample_data [OUTDIR]`` (default ``sample_data``)."""
    args = sys.argv[1:] if argv is None else argv
    outdir = args[0] if args else "sample_data"
    for path in write_sample_data(outdir):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
