"""What a file is (format, instrument, geometry, time span): the lines of ``cwproc info``."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.io import KIND, Format, detect_format, is_product_layout, read_file
from cwproc.io.scan_join import is_homodyne

if TYPE_CHECKING:
    from cwproc.config import Config

#: human names of the formats
FORMAT_NAMES: dict[Format, str] = {
    Format.HPL: "Halo Photonics Stream Line .hpl",
    Format.SCAN_NETCDF: "cwproc scan dataset (NetCDF)",
    Format.ZEPHIR_CSV: "ZephIR 300 CSV export",
    Format.WINDCUBE_STA: "WindCube .sta/.stdsta statistics",
    Format.WINDCUBE_RTD: "WindCube .rtd real-time lines of sight",
    Format.TOA5: "Campbell Scientific TOA5",
    Format.TOB1: "Campbell Scientific TOB1",
    Format.GHG: "LI-COR GHG .data",
    Format.METEO2: "Meteo-2 sonic log",
    Format.GILL: "Gill UVW ASCII",
    Format.HALO_BACKGROUND: "Halo Photonics Stream Line background profile",
}

#: elevations differing by less than this (deg) are listed as one
_ELEVATION_BIN_DEG = 0.1


def _iso(t: np.datetime64) -> str:
    return np.datetime_as_string(t, unit="ms") + "Z"


def time_span(time: np.ndarray) -> str:
    """``start - end (duration)`` of a datetime64 array, NaT ignored."""
    t = np.asarray(time)
    t = t[~np.isnat(t)] if np.issubdtype(t.dtype, np.datetime64) else t
    if t.size == 0 or not np.issubdtype(t.dtype, np.datetime64):
        return "none"
    start, end = t.min(), t.max()
    seconds = (end - start) / np.timedelta64(1, "s")
    if seconds >= 3600:
        length = f"{seconds / 3600:.2f} h"
    elif seconds >= 60:
        length = f"{seconds / 60:.1f} min"
    else:
        length = f"{seconds:.1f} s"
    return f"{_iso(start)} - {_iso(end)} ({length})"


def azimuth_coverage(azimuth: np.ndarray) -> float:
    """Angle (deg) of the circle covered by the azimuths: 360 minus the largest gap."""
    az = np.unique(np.mod(np.asarray(azimuth, dtype=float), 360.0))
    az = az[np.isfinite(az)]
    if az.size < 2:
        return 0.0
    gaps = np.diff(np.r_[az, az[0] + 360.0])
    return float(360.0 - gaps.max())


def elevation_summary(elevation: np.ndarray) -> str:
    """The distinct elevations (deg), or their range when there are many."""
    el = np.asarray(elevation, dtype=float)
    el = el[np.isfinite(el)]
    if el.size == 0:
        return "none"
    distinct = np.unique(np.round(el / _ELEVATION_BIN_DEG) * _ELEVATION_BIN_DEG)
    if distinct.size <= 6:
        return ", ".join(f"{e:.2f}" for e in distinct + 0.0) + " deg"
    return f"{el.min():.2f} - {el.max():.2f} deg ({distinct.size} distinct)"


def describe_scan(ds: xr.Dataset) -> list[str]:
    """Lines describing a canonical scan dataset (rays, gates, geometry, scans)."""
    attrs = ds.attrs
    n_rays, n_gates = int(ds.sizes.get("ray", 0)), int(ds.sizes.get("range", 0))
    rng = np.asarray(ds["range"].values, dtype=float)
    gate = attrs.get("gate_length_m")
    gate_text = f" x {float(gate):g} m" if gate is not None else ""
    range_text = f" ({rng.min():g} - {rng.max():g} m)" if rng.size else ""
    scan = np.asarray(ds["scan"].values) if "scan" in ds.coords else np.full(n_rays, -1)
    scans = np.unique(scan[scan >= 0])
    in_none = int((scan < 0).sum())
    if scans.size:
        per_scan = np.bincount(scan[scan >= 0])[scans]
        scan_text = (
            f"{scans.size} conical scan(s), {int(np.median(per_scan))} rays per scan "
            f"(median); {in_none} ray(s) in no scan"
        )
    else:
        scan_text = f"no conical scan; {in_none} ray(s) in no scan"
    from cwproc.pipeline import count_stare_rays

    n_stare = count_stare_rays(ds)
    if n_stare:
        scan_text += f" ({n_stare} vertical stare ray(s): stare product)"
    az = np.asarray(ds["azimuth"].values, dtype=float)
    az_text = (
        f"{np.nanmin(az):.2f} - {np.nanmax(az):.2f} deg, coverage {azimuth_coverage(az):.1f} deg"
        if az.size
        else "none"
    )
    optional = [v for v in ("beta", "spectral_width", "pitch", "roll") if v in ds]
    lines = [
        f"  instrument    {attrs.get('instrument', '?')} ({attrs.get('instrument_kind', '?')}), "
        f"system id {attrs.get('system_id', '?')}" + (", homodyne" if is_homodyne(ds) else ""),
        f"  scan type     {attrs.get('scan_type', '?')}",
        f"  rays          {n_rays}",
        f"  gates         {n_gates}{gate_text}{range_text}",
        f"  time          {time_span(ds['time'].values)}",
        f"  elevation     {elevation_summary(ds['elevation'].values)}",
        f"  azimuth       {az_text}",
        f"  scans         {scan_text}",
    ]
    if optional:
        lines.append(f"  also          {', '.join(optional)}")
    return lines


def describe_background(ds: xr.Dataset) -> list[str]:
    """Lines describing a Stream Line background file (gates, time, values)."""
    values = np.asarray(ds["background"].values, dtype=float)
    return [
        "  kind          background (corrects the SNR of the scans beside it; not a product input)",
        f"  time          {_iso(np.datetime64(ds['time'].values))}",
        f"  gates         {values.size} ({ds.attrs.get('layout', '?')} layout)",
        f"  background    min {values.min():.6g}, median {np.median(values):.6g}, "
        f"max {values.max():.6g}",
    ]


def describe_dataset(ds: xr.Dataset) -> list[str]:
    """Lines describing any other dataset: dims, time span, variables."""
    dims = ", ".join(f"{k}={v}" for k, v in ds.sizes.items())
    lines = [f"  dims          {dims}"]
    if "time" in ds.variables:
        lines.append(f"  time          {time_span(ds['time'].values)}")
    for key in ("instrument", "sampling_rate_hz", "frame"):
        if key in ds.attrs:
            lines.append(f"  {key:<13} {ds.attrs[key]}")
    lines += describe_wind_record(ds)
    names = sorted(str(v) for v in ds.data_vars)
    lines.append(f"  variables     {len(names)}: {', '.join(names)}")
    return lines


def describe_wind_record(ds: xr.Dataset) -> list[str]:
    """The averaging of instrument statistics, and a WindCube's beams and scan angle."""
    lines = []
    attrs = ds.attrs
    if "averaging_interval_s" in attrs:
        lines.append(f"  averaging     {float(attrs['averaging_interval_s']):g} s statistics")
    if attrs.get("format") == "windcube_sta":
        angle = attrs.get("scan_angle_deg")
        shown = f"{float(angle):g} deg" if angle is not None else "not reported in the header"
        lines.append(f"  scan angle    {shown}")
    if attrs.get("format") == "windcube_rtd" and "beam" in ds:
        labels, counts = np.unique(ds["beam"].values, return_counts=True)
        order = sorted(
            range(labels.size),
            key=lambda i: (labels[i] == "V", float(labels[i]) if labels[i] != "V" else 0.0),
        )
        beams = ", ".join(f"{labels[i]}: {counts[i]}" for i in order)
        lines.append(
            f"  beams         {beams} (a line of sight every "
            f"{float(attrs.get('line_of_sight_interval_s', np.nan)):.3g} s; "
            f"{attrs.get('rtd_layout', '?')} layout)"
        )
        lines.append(
            f"  scan angle    {float(attrs['scan_angle_deg']):g} deg from the zenith "
            f"({attrs.get('scan_angle_source', '?')})"
        )
    return lines


def open_product(path: str | os.PathLike) -> xr.Dataset | None:
    """The file as a cwproc product (a NetCDF written by cwproc), or None if it is not one."""
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            if is_product_layout(ds.attrs, ds.dims):
                return ds.load()
    except (OSError, ValueError):
        return None
    return None


def describe_product_file(path: str | os.PathLike, ds: xr.Dataset) -> list[str]:
    """Lines describing a cwproc product: title, provenance, dims, time span, variables."""
    lines = [
        f"{os.fspath(path)}",
        "  format        cwproc product (NetCDF, CF-1.10 / ACDD-1.3)",
        f"  title         {ds.attrs.get('title', '')}",
        f"  made by       cwproc {ds.attrs.get('cwproc_version', '?')} from "
        f"{ds.attrs.get('input_files', '?')}",
    ]
    return lines + describe_dataset(ds)


def damaged_background(path: str | os.PathLike) -> None:
    """Raise the reader's error for a file named like a background file that is damaged.

    The content sniffer does not recognise a damaged background file, and "not a
    format cwproc reads" would hide the line at fault; a file that is not named
    ``*Background_DDMMYY-HHMMSS.txt``, or that reads, returns silently.
    """
    from cwproc.io.halo_background import NAME_TIME, read_halo_background

    if NAME_TIME.search(os.path.basename(os.fspath(path))) is None:
        return
    read_halo_background(path)


def describe_file(path: str | os.PathLike, config: Config | None = None) -> list[str]:
    """What a file is, as printable lines (the first line is the path).

    ``config`` gives the reader options of the file's format (its ``[reader.<format>]``
    table, e.g. the start time and rate of a Gill log, which has no time of its own),
    as ``cwproc retrieve -c`` reads the file; None reads with the readers' defaults.

    Raises
    ------
    CwprocError
        The file cannot be read (unknown format, damaged, no reader in this build).
    """
    try:
        fmt = detect_format(path)
    except CwprocError:
        damaged_background(path)  # a damaged background file: its own line and problem
        raise
    if fmt is Format.SCAN_NETCDF:
        product = open_product(path)
        if product is not None:
            return describe_product_file(path, product)
    try:
        ds = read_file(path, fmt, **(dict(config.reader.get(fmt.value, {})) if config else {}))
    except ImportError:
        raise CwprocError(f"{path}: no reader for format {fmt.value} in this build") from None
    header = [f"{os.fspath(path)}", f"  format        {fmt.value} ({FORMAT_NAMES[fmt]})"]
    if KIND[fmt] == "scan":
        return header + describe_scan(ds)
    if KIND[fmt] == "background":
        return header + describe_background(ds)
    return [*header, f"  kind          {KIND[fmt]}", *describe_dataset(ds)]
