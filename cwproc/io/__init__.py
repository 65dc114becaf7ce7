"""Readers of instrument files (one module per format), giving the canonical datasets.

:func:`detect_format` recognises a file by its content (not its name) and
:func:`read_file` dispatches to the reader of that format. Every reader has the signature
``read_<format>(path, **options) -> xarray.Dataset`` and returns one of the
canonical datasets (scan, wind-record or sonic), raising
:class:`cwproc.errors.InputFileError` (file, line, problem) on bad input.
"""

from __future__ import annotations

import importlib
import os
import stat
from collections.abc import Iterable
from typing import Any

import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io.identity import KIND, NETCDF_LOCK, FileIdentity, Format

__all__ = [
    "IDENTIFIERS",
    "KIND",
    "NETCDF_LOCK",
    "READERS",
    "SCAN_DIMS",
    "FileIdentity",
    "Format",
    "detect_format",
    "get_identifier",
    "get_reader",
    "is_cwproc_product",
    "is_product_layout",
    "is_regular_file",
    "read_file",
    "sniff_format",
]

#: format -> "module:function" of its reader
READERS: dict[Format, str] = {
    Format.HPL: "cwproc.io.halo:read_hpl",
    Format.SCAN_NETCDF: "cwproc.io.scan_netcdf:read_scan_netcdf",
    Format.ZEPHIR_CSV: "cwproc.io.zephir:read_zephir_csv",
    Format.WINDCUBE_STA: "cwproc.io.windcube:read_windcube_sta",
    Format.WINDCUBE_RTD: "cwproc.io.windcube_rtd:read_windcube_rtd",
    Format.TOA5: "cwproc.io.campbell:read_toa5",
    Format.TOB1: "cwproc.io.campbell_tob1:read_tob1",
    Format.GHG: "cwproc.io.licor:read_ghg",
    Format.METEO2: "cwproc.io.meteo2:read_meteo2",
    Format.GILL: "cwproc.io.gill:read_gill",
    Format.HALO_BACKGROUND: "cwproc.io.halo_background:read_halo_background",
}


#: format -> "module:function" that tells from a file's header alone what it is (its
#: unit: instrument, identity, day) without reading its data; formats not listed are read
IDENTIFIERS: dict[Format, str] = {
    Format.HPL: "cwproc.io.halo:read_hpl_identity",
}

_HEAD_BYTES = 4096


def sniff_format(head: bytes) -> Format | None:
    """The format of a file from its first bytes, or ``None`` when not recognised."""
    if (
        head.startswith(b"\x89HDF\r\n\x1a\n")
        or head.startswith(b"CDF\x01")
        or head.startswith(b"CDF\x02")
    ):
        return Format.SCAN_NETCDF
    if head.startswith(b"PK\x03\x04") and b".data" in head:
        return Format.GHG  # a LI-COR .ghg archive (a zip holding the .data file)
    text = head.decode("latin-1")
    first = text.split("\n", 1)[0]
    if first.startswith("Filename:"):
        return Format.HPL
    if first.startswith('"TOA5"'):
        return Format.TOA5
    if first.startswith('"TOB1"'):
        return Format.TOB1
    if first.startswith(("HeaderSize=", "HeaderLength=")):
        if any(
            line.startswith(("Timestamp\tPosition\t", "Date\tPosition\t"))
            for line in text.split("\n")
        ):
            return Format.WINDCUBE_RTD
        return Format.WINDCUBE_STA
    if "CSV Converter" in first or ("Time and Date" in text and ";" in text):
        return Format.ZEPHIR_CSV
    if first.startswith("Model:") or "\nDATAH\t" in text:
        return Format.GHG
    if first.startswith("# cwproc meteo2") or first.startswith("#meteo2"):
        return Format.METEO2
    stripped = first.lstrip("\x02")
    if len(stripped) > 2 and stripped[1] == "," and stripped[0].isalpha() and ",M," in stripped:
        return Format.GILL
    from cwproc.io.halo_background import is_background_text

    if is_background_text(head):
        return Format.HALO_BACKGROUND
    return None


def detect_format(path: str | os.PathLike) -> Format:
    """Recognise the format of ``path`` from its content.

    Raises
    ------
    InputFileError
        The file cannot be read, is empty, or is of no format cwproc reads.
    """
    if not is_regular_file(path):
        raise InputFileError(path, "not a regular file (a folder, pipe, socket or device)")
    try:
        with open(path, "rb") as fh:
            head = fh.read(_HEAD_BYTES)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    if not head:
        raise InputFileError(path, "file is empty")
    fmt = sniff_format(head)
    if fmt is None:
        raise InputFileError(path, "not a format cwproc reads (unrecognised first line)", 1)
    return fmt


def is_regular_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a regular file (opening a FIFO or a device would block)."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return True  # let the open() that follows report the problem with its reason


#: dimensions of a scan dataset (the canonical schema of the readers), which is an input
SCAN_DIMS = frozenset({"ray", "range"})


def is_product_layout(attrs: Iterable[str], dims: Iterable[str]) -> bool:
    """Whether global attribute names and dimension names are those of a cwproc product.

    A product has the global attribute ``cwproc_version`` and is not laid out as a scan
    dataset (dimensions ``ray`` and ``range``; cwproc's scan NetCDF files are inputs).
    The stare product has a ``ray`` dimension (``w_ray(ray, height)``) but no ``range``.
    """
    return "cwproc_version" in set(attrs) and not SCAN_DIMS <= set(dims)


def is_cwproc_product(path: str | os.PathLike) -> bool:
    """True when ``path`` is a product cwproc wrote (not an instrument file).

    See :func:`is_product_layout`. Products found among the inputs are skipped by
    ``retrieve``, ``sf-type`` and ``batch``.
    """
    if not is_regular_file(path):
        return False
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError:
        return False
    if sniff_format(head) is not Format.SCAN_NETCDF:
        return False
    import netCDF4

    try:
        with NETCDF_LOCK, netCDF4.Dataset(path) as nc:
            return is_product_layout(nc.ncattrs(), nc.dimensions)
    except OSError:
        return False


def get_reader(fmt: Format | str):
    """The reader function of a format."""
    module_name, func = READERS[Format(fmt)].split(":")
    return getattr(importlib.import_module(module_name), func)


def get_identifier(fmt: Format | str):
    """The header-only identifier of a format (see ``IDENTIFIERS``), None when it has none."""
    target = IDENTIFIERS.get(Format(fmt))
    if target is None:
        return None
    module_name, func = target.split(":")
    return getattr(importlib.import_module(module_name), func)


def read_file(
    path: str | os.PathLike, fmt: Format | str | None = None, **options: Any
) -> xr.Dataset:
    """Read one file with the reader of its format (detected when ``fmt`` is None)."""
    fmt = detect_format(path) if fmt in (None, "auto") else Format(fmt)
    return get_reader(fmt)(path, **options)
