"""The canonical scan dataset as NetCDF (e.g. cw lidar line-of-sight data, simulator output).

:func:`write_scan_netcdf` writes a scan dataset (docs/DEVELOPING.md, "Scan dataset")
atomically with CF attributes from :mod:`cwproc.io.schema`; :func:`read_scan_netcdf`
reads one back and validates the schema, so that a file missing a variable, a
dimension or the detection attributes fails with the file and the missing name
instead of somewhere inside a stage.

Notes
-----
* ``time`` is stored as int64 microseconds since 1970-01-01 UTC (CF), read back
  exactly as datetime64[ns] UTC.
* ``source_files`` (a list) is stored as one comma-separated string attribute.
* ``homodyne`` (0/1) and ``instrument_kind`` are required: a homodyne cw lidar
  measures only |V_r|, and treating its data as signed would corrupt every wind.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.errors import ConfigError, InputFileError
from cwproc.io.identity import NETCDF_LOCK
from cwproc.io.netcdf import write_netcdf_atomic
from cwproc.io.scan_join import assign_scans, parse_homodyne
from cwproc.io.schema import with_canonical_attrs

#: required variables and their dimensions
REQUIRED_VARIABLES: dict[str, tuple[str, ...]] = {
    "time": ("ray",),
    "azimuth": ("ray",),
    "elevation": ("ray",),
    "range": ("range",),
    "radial_velocity": ("ray", "range"),
    "snr": ("ray", "range"),
}
#: optional variables and their dimensions
OPTIONAL_VARIABLES: dict[str, tuple[str, ...]] = {
    "scan": ("ray",),
    "beta": ("ray", "range"),
    "spectral_width": ("ray", "range"),
    "pitch": ("ray",),
    "roll": ("ray",),
}
#: required global attributes
REQUIRED_ATTRS = ("instrument_kind", "homodyne")

_TIME_UNITS = "microseconds since 1970-01-01 00:00:00"

_COORDS = ("time", "azimuth", "elevation", "range", "scan")


def _split_files(value: object) -> list[str]:
    if isinstance(value, list | tuple | np.ndarray):
        return [str(v) for v in value]
    text = str(value or "")
    return [f.strip() for f in text.split(",") if f.strip()]


def validate_scan_schema(ds: xr.Dataset, path: str | os.PathLike) -> None:
    """Check the canonical scan schema; the error names the missing or wrong item.

    Raises
    ------
    InputFileError
        A dimension, required variable or required attribute is missing, a variable
        has the wrong dimensions, ``time`` is not a time, or ``homodyne`` is not 0/1.
    """
    for dim in ("ray", "range"):
        if dim not in ds.dims:
            raise InputFileError(path, f"scan dataset has no dimension {dim!r}")
    for name, dims in {**REQUIRED_VARIABLES, **OPTIONAL_VARIABLES}.items():
        if name not in ds.variables:
            if name in REQUIRED_VARIABLES:
                raise InputFileError(path, f"scan dataset has no variable {name!r}")
            continue
        if tuple(ds[name].dims) != dims:
            raise InputFileError(
                path, f"variable {name!r} has dimensions {tuple(ds[name].dims)}, expected {dims}"
            )
    if not np.issubdtype(ds["time"].dtype, np.datetime64):
        raise InputFileError(path, "variable 'time' is not a CF time (no usable units)")
    for key in REQUIRED_ATTRS:
        if key not in ds.attrs:
            raise InputFileError(path, f"scan dataset has no global attribute {key!r}")
    try:
        parse_homodyne(ds.attrs["homodyne"])
    except ValueError as exc:
        raise InputFileError(path, f"global attribute {exc}") from None


def _encode_time_exactly(ds: xr.Dataset) -> xr.Dataset:
    """``time`` as int64 microseconds since 1970 (CF), so ray times survive exactly.

    The product writer's default (float64 seconds) keeps only ~0.2 us at today's
    epoch values; line-of-sight times are kept to the microsecond the readers give.
    """
    time = ds["time"].values.astype("datetime64[us]")
    micro = (time - np.datetime64(0, "us")).astype(np.int64)
    attrs = dict(ds["time"].attrs)
    attrs.update(units=_TIME_UNITS, calendar="standard")
    return ds.assign_coords(time=("ray", micro, attrs))


def write_scan_netcdf(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write a canonical scan dataset to NetCDF-4 atomically.

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical scan dataset (``scan`` is assigned when missing).
    path : path-like
        Output file.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    InputFileError
        ``ds`` does not follow the scan schema (named as ``<dataset>``).
    ProductError
        The directory cannot be written.
    """
    validate_scan_schema(ds, "<dataset to write>")
    out = ds
    if "scan" not in out.coords:
        out = assign_scans(out)
    out = out.set_coords([c for c in _COORDS if c in out.variables])
    out = with_canonical_attrs(out, "scan")
    out = _encode_time_exactly(out)
    attrs = dict(out.attrs)
    attrs["homodyne"] = int(parse_homodyne(attrs["homodyne"]))
    attrs["source_files"] = ", ".join(_split_files(attrs.get("source_files", [])))
    attrs.setdefault("Conventions", "CF-1.10")
    attrs["file_uuid"] = str(uuid.uuid4())  # ACTRIS/Cloudnet: products name it as a source
    out.attrs = attrs
    return write_netcdf_atomic(out, path)


def read_scan_netcdf(path: str | os.PathLike, **options: object) -> xr.Dataset:
    """Read a canonical scan dataset from NetCDF and validate its schema.

    Parameters
    ----------
    path : path-like
        NetCDF file written by :func:`write_scan_netcdf` (or any file with the schema).
    **options
        ``[reader.scan_netcdf]`` configuration table; no options are defined (any key
        raises :class:`cwproc.errors.ConfigError`).

    Returns
    -------
    xarray.Dataset
        In memory (the file is closed); ``homodyne`` as int 0/1, ``source_files`` as a
        list (the file's own name when the attribute is empty), ``scan`` assigned
        when the file has none.

    Raises
    ------
    InputFileError
        Not a NetCDF file, or the schema is violated (missing variable, dimension or
        attribute, named in the message).
    """
    if options:
        raise ConfigError(
            "[reader.scan_netcdf]", ", ".join(sorted(options)), "this reader takes no options"
        )
    path = Path(path)
    try:
        with NETCDF_LOCK, xr.open_dataset(path, engine="netcdf4") as handle:
            ds = handle.load()
    except FileNotFoundError:
        raise InputFileError(path, "cannot read: no such file") from None
    except (OSError, ValueError, RuntimeError, KeyError, AttributeError) as exc:
        # netCDF4 raises AttributeError ("NetCDF: Can't open HDF5 attribute") on a
        # damaged attribute block: a damaged file, named as such
        raise InputFileError(path, f"not a readable NetCDF scan file ({exc})") from None
    validate_scan_schema(ds, path)
    ds = ds.set_coords([c for c in _COORDS if c in ds.variables])
    attrs = dict(ds.attrs)
    attrs["homodyne"] = int(parse_homodyne(attrs["homodyne"]))
    attrs["source_files"] = _split_files(attrs.get("source_files")) or [path.name]
    ds.attrs = attrs
    if "scan" not in ds.coords:
        ds = assign_scans(ds)
    else:
        ds["scan"] = ds["scan"].astype(np.int64)
    return with_canonical_attrs(ds, "scan")
