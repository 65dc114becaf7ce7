"""The writer of every cwproc product: CF-1.10 and ACDD-1.3 attributes, provenance, atomic.

Global attributes record the cwproc version, the full configuration used and the
SHA-256 checksum of every input file; the file itself is written through a temporary
and renamed into place (:mod:`cwproc.io.netcdf`).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import uuid
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc._version import __version__
from cwproc.config import OutputConfig
from cwproc.io import NETCDF_LOCK
from cwproc.io.netcdf import sha256_file, stage_netcdf, write_netcdf_atomic
from cwproc.metadata.products import apply_metadata

CONVENTIONS = "CF-1.10, ACDD-1.3"

#: value of ACDD attributes the user did not configure ([output] table of the config)
NOT_SPECIFIED = "not specified"


def _iso(value: np.datetime64) -> str:
    return np.datetime_as_string(np.datetime64(value, "s"), unit="s") + "Z"


def global_attributes(
    ds: xr.Dataset,
    *,
    title: str,
    summary: str,
    inputs: Sequence[str | os.PathLike] = (),
    checksums: Mapping[str, str] | None = None,
    config_toml: str = "",
    references: str = "",
    keywords: str = "",
    extra: Mapping[str, object] | None = None,
) -> dict[str, object]:
    """ACDD-1.3 and provenance global attributes for a product.

    Parameters
    ----------
    ds : xarray.Dataset
        The product (its ``time`` and ``height`` coordinates give the coverage).
    title, summary : str
        ACDD title and summary.
    inputs : sequence of paths
        Input files; their SHA-256 checksums are recorded (computed here unless
        ``checksums`` already has them).
    checksums : mapping, optional
        Precomputed ``{path: sha256}``.
    config_toml : str
        The full configuration used, as TOML text.
    references : str
        Papers whose equations the product implements.
    keywords : str
        Comma-separated keywords.
    extra : mapping, optional
        More global attributes (e.g. instrument attributes of the input).
    """
    names, sums = _input_checksums(inputs, checksums)
    attrs = _provenance_attributes(title, summary, keywords, references, names, sums, config_toml)
    attrs.update(_time_coverage(ds))
    attrs.update(_vertical_coverage(ds))
    if extra:
        attrs.update({k: v for k, v in extra.items() if v is not None})
    return attrs


def _provenance_attributes(
    title: str,
    summary: str,
    keywords: str,
    references: str,
    names: list[str],
    sums: dict[str, str],
    config_toml: str,
) -> dict[str, object]:
    """The ACDD-1.3 attributes that do not depend on the data: what, who, when (now,
    UTC) and from which inputs and configuration."""
    now = _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    return {
        "Conventions": CONVENTIONS,
        "title": title,
        "summary": summary,
        "keywords": keywords or "Doppler lidar, wind, turbulence, dissipation rate",
        "keywords_vocabulary": "free text",
        "naming_authority": "org.cwproc",
        "source": "cwproc " + __version__,
        "processing_level": "L2",
        "product_version": __version__,
        "cwproc_version": __version__,
        "history": f"{now} created by cwproc {__version__}",
        "references": references,
        "date_created": now,
        "date_modified": now,
        "date_issued": now,
        "date_metadata_modified": now,
        "standard_name_vocabulary": "CF Standard Name Table v93",
        "license": "Data license as agreed with the data provider",
        "acknowledgement": "Processed with cwproc",
        "creator_type": "person",
        "creator_name": NOT_SPECIFIED,
        "creator_email": NOT_SPECIFIED,
        "creator_url": NOT_SPECIFIED,
        "creator_institution": NOT_SPECIFIED,
        "institution": NOT_SPECIFIED,
        "project": NOT_SPECIFIED,
        "publisher_name": NOT_SPECIFIED,
        "publisher_email": NOT_SPECIFIED,
        "publisher_url": NOT_SPECIFIED,
        "publisher_institution": NOT_SPECIFIED,
        "publisher_type": "institution",
        "instrument": NOT_SPECIFIED,
        "cdm_data_type": "Profile",
        "comment": (
            "Produced by cwproc from the files listed in input_files (SHA-256 checksums in "
            "input_sha256) with the configuration in cwproc_config; methods, parameters and "
            "references of each variable are in its attributes."
        ),
        "metadata_link": "https://pypi.org/project/cwproc/",
        "input_files": ", ".join(names),
        "input_sha256": json.dumps(sums, sort_keys=True),
        "cwproc_config": config_toml,
    }


def _input_checksums(
    inputs: Sequence[str | os.PathLike], checksums: Mapping[str, str] | None
) -> tuple[list[str], dict[str, str]]:
    """File names of the inputs and ``{path: sha256}`` of each (``checksums`` first,
    the others computed)."""
    sums = dict(checksums or {})
    names = []
    for p in inputs:
        key = os.fspath(p)
        if key not in sums:
            sums[key] = sha256_file(key)
        names.append(os.path.basename(key))
    return names, sums


def _time_coverage(ds: xr.Dataset) -> dict[str, object]:
    """ACDD ``time_coverage_*`` of the product's valid times ({} without times)."""
    attrs: dict[str, object] = {}
    if "time" not in ds.variables or ds["time"].size == 0:
        return attrs
    t = np.ravel(ds["time"].values)
    t = t[~np.isnat(t)] if np.issubdtype(t.dtype, np.datetime64) else t
    if len(t) and np.issubdtype(np.asarray(t).dtype, np.datetime64):
        start, end = np.min(t), np.max(t)
        attrs["time_coverage_start"] = _iso(start)
        attrs["time_coverage_end"] = _iso(end)
        seconds = int((end - start) / np.timedelta64(1, "s"))
        attrs["time_coverage_duration"] = f"PT{seconds}S"
        if len(t) > 1:
            step = np.median(np.diff(np.sort(t))) / np.timedelta64(1, "s")
            attrs["time_coverage_resolution"] = f"PT{float(step):g}S"
    return attrs


def _vertical_coverage(ds: xr.Dataset) -> dict[str, object]:
    """ACDD ``geospatial_vertical_*`` of the product's heights (m; {} without heights)."""
    if "height" not in ds.coords or ds["height"].size == 0:
        return {}
    h = np.asarray(ds["height"].values, dtype=float)
    attrs: dict[str, object] = {
        "geospatial_vertical_min": float(np.nanmin(h)),
        "geospatial_vertical_max": float(np.nanmax(h)),
        "geospatial_vertical_units": "m",
        "geospatial_vertical_positive": "up",
    }
    if h.size > 1:
        attrs["geospatial_vertical_resolution"] = f"{float(np.median(np.diff(h))):g} m"
    return attrs


def source_file_uuids(inputs: Iterable[str | os.PathLike]) -> str:
    """``file_uuid`` global attributes of the NetCDF inputs, comma-separated ('' if none).

    ACTRIS/Cloudnet convention: a product names the ``file_uuid`` of every input product
    it was made from. Inputs that are not NetCDF or carry no ``file_uuid`` (instrument
    files such as ``.hpl``) are identified by their SHA-256 in ``input_sha256`` instead.
    """
    found: list[str] = []
    for path in inputs:
        try:
            with open(path, "rb") as fh:
                magic = fh.read(8)
        except OSError:
            continue
        if not (magic.startswith(b"\x89HDF") or magic.startswith(b"CDF")):
            continue
        import netCDF4

        try:
            with NETCDF_LOCK, netCDF4.Dataset(path) as nc:
                value = str(getattr(nc, "file_uuid", "")).strip()
        except OSError:
            continue
        if value and value not in found:
            found.append(value)
    return ", ".join(found)


def site_attributes(output: OutputConfig) -> dict[str, object]:
    """ACDD attributes from the ``[output]`` table: who made the data, where.

    Position attributes (``geospatial_lat_min`` ...) are written only when the
    configuration gives the instrument position.
    """
    attrs: dict[str, object] = {}
    for key in (
        "institution",
        "creator_name",
        "creator_email",
        "creator_url",
        "publisher_url",
        "project",
    ):
        value = getattr(output, key)
        if value:
            attrs[key] = value
    if output.instrument_pid:  # ACTRIS/Cloudnet: persistent identifier of the instrument
        attrs["instrument_pid"] = output.instrument_pid
    if output.instrument_serial_number:
        attrs["instrument_serial_number"] = output.instrument_serial_number
    if output.institution:
        attrs["creator_institution"] = output.institution
        attrs["publisher_institution"] = output.institution
        attrs["publisher_name"] = output.institution
    if output.creator_email:
        attrs["publisher_email"] = output.creator_email
    if output.site:
        attrs["platform"] = output.site
    if output.latitude is not None and output.longitude is not None:
        lat, lon = output.latitude, output.longitude
        attrs.update(
            geospatial_lat_min=lat,
            geospatial_lat_max=lat,
            geospatial_lon_min=lon,
            geospatial_lon_max=lon,
            geospatial_lat_units="degrees_north",
            geospatial_lon_units="degrees_east",
            geospatial_bounds=f"POINT({lat} {lon})",
            geospatial_bounds_crs="EPSG:4326",
        )
        if output.altitude_m is not None:
            attrs["geospatial_bounds_vertical_crs"] = "EPSG:5829"
    return attrs


def add_site_coordinates(ds: xr.Dataset, output: OutputConfig) -> xr.Dataset:
    """Scalar ``latitude``/``longitude``/``altitude`` coordinates from the ``[output]`` table.

    CF-1.10 section 5.7 scalar coordinates locate a single-site product; nothing is
    added when the configuration does not give the position.
    """
    if output.latitude is None or output.longitude is None:
        return ds
    coords = {"latitude": output.latitude, "longitude": output.longitude}
    if output.altitude_m is not None:
        coords["altitude"] = output.altitude_m
    return ds.assign_coords({k: float(v) for k, v in coords.items()})


def write_product(
    ds: xr.Dataset,
    path: str | os.PathLike,
    *,
    product: str,
    title: str,
    summary: str,
    inputs: Iterable[str | os.PathLike] = (),
    checksums: Mapping[str, str] | None = None,
    config_toml: str = "",
    references: str = "",
    keywords: str = "",
    extra_attrs: Mapping[str, object] | None = None,
    compression_level: int = 4,
    stage_only: bool = False,
) -> Path:
    """Attach CF metadata and ACDD/provenance attributes, then write atomically.

    Parameters
    ----------
    ds : xarray.Dataset
        The product.
    path : path
        Where it is written.
    product : str
        Which product ``ds`` is, one of :data:`cwproc.metadata.products.PRODUCTS`: it
        selects the declarations (:func:`cwproc.metadata.products.apply_metadata`).
    title, summary, inputs, checksums, config_toml, references, keywords, extra_attrs
        Global attributes, see :func:`global_attributes`.
    compression_level : int
        zlib level of the variables (0-9).
    stage_only : bool
        Write the staged temporary only (see Returns).

    Returns
    -------
    pathlib.Path
        The product path; with ``stage_only`` the staged temporary, which
        :func:`publish` renames onto the product (all products of a unit together).

    Raises
    ------
    CwprocError
        ``product`` is not a product the metadata declares.
    """
    out = apply_metadata(ds, product=product)
    attrs = dict(ds.attrs)
    attrs.pop("file_uuid", None)  # an input's identity is not this file's
    inputs = list(inputs)
    attrs.update(
        global_attributes(
            out,
            title=title,
            summary=summary,
            inputs=inputs,
            checksums=checksums,
            config_toml=config_toml,
            references=references,
            keywords=keywords,
            extra=extra_attrs,
        )
    )
    attrs["id"] = Path(path).stem
    # ACTRIS/Cloudnet: a new identity for every file written, and those of its input products
    attrs["file_uuid"] = str(uuid.uuid4())
    sources = source_file_uuids(inputs)
    if sources:
        attrs["source_file_uuids"] = sources
    else:
        attrs.pop("source_file_uuids", None)
    out.attrs = attrs
    if stage_only:
        return stage_netcdf(out, path, compression_level=compression_level)
    return write_netcdf_atomic(out, path, compression_level=compression_level)
