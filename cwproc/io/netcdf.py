"""Files written whole or not at all: NetCDF staging and publishing, atomic bytes, checksums.

A file is written to a temporary in the target directory and renamed into place only
when complete, so a killed run never leaves a half-written file. The products layer
(:mod:`cwproc.products.writer`) adds the CF/ACDD metadata and provenance.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.errors import ProductError
from cwproc.io.identity import NETCDF_LOCK

_CHUNK = 1 << 20


def sha256_file(path: str | os.PathLike) -> str:
    """SHA-256 hex digest of a file, read in 1 MiB chunks."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(_CHUNK), b""):
            digest.update(block)
    return digest.hexdigest()


def _clean_attr(value: object) -> object:
    """Make an attribute value writable by netCDF4 (no None, bools as ints, dicts as JSON)."""
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return int(value)
    if isinstance(value, Mapping):
        return json.dumps(value, sort_keys=True, default=str)
    if isinstance(value, list | tuple) and any(isinstance(v, str) for v in value):
        return ", ".join(str(v) for v in value)
    return value


def encoding_for(ds: xr.Dataset, compression_level: int = 4) -> dict[str, dict[str, object]]:
    """Per-variable NetCDF encoding: compression, fill values, CF time units."""
    enc: dict[str, dict[str, object]] = {}
    for name, var in ds.variables.items():
        e: dict[str, object] = {}
        if np.issubdtype(var.dtype, np.datetime64):
            # a product may ask for its own time unit (Cloudnet: hours since midnight)
            e["units"] = var.encoding.get("units", "seconds since 1970-01-01 00:00:00")
            e["calendar"] = "standard"
            e["dtype"] = "float64"
            if name in ds.coords:
                e["_FillValue"] = None
        elif np.issubdtype(var.dtype, np.floating):
            e["_FillValue"] = np.nan if name not in ds.coords else None
        elif var.dtype.kind in "iub" and name not in ds.coords:
            e["_FillValue"] = None
        if var.ndim > 0 and compression_level > 0 and var.dtype.kind in "fiu":
            e["zlib"] = True
            e["complevel"] = compression_level
        enc[str(name)] = e
    return enc


def stage_netcdf(ds: xr.Dataset, path: str | os.PathLike, *, compression_level: int = 4) -> Path:
    """Write ``ds`` completely to a temporary file beside ``path``; returns the temporary.

    The temporary (``.<name>.<random>.tmp``, mode from the umask, fsynced) becomes the
    product by :func:`publish`; a killed run leaves only such hidden temporaries, which
    the next run removes (:func:`cwproc.batch.remove_leftover_temporaries`).

    Raises
    ------
    ProductError
        The directory cannot be written (read-only, full, missing).
    """
    path = Path(path)
    ds = ds.copy()
    ds.attrs = {k: _clean_attr(v) for k, v in ds.attrs.items()}
    for name in ds.variables:
        ds[name].attrs = {k: _clean_attr(v) for k, v in ds[name].attrs.items()}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(path.parent)  # of any writer killed earlier
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise ProductError(f"{path}: cannot write product: {exc.strerror or exc}") from None
    try:
        with NETCDF_LOCK:
            ds.to_netcdf(
                tmp,
                format="NETCDF4",
                engine="netcdf4",
                encoding=encoding_for(ds, compression_level),
            )
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, umask_mode())
    except OSError as exc:
        _unlink_quietly(tmp)
        raise ProductError(f"{path}: cannot write product: {exc.strerror or exc}") from None
    except RuntimeError as exc:  # the netCDF/HDF5 library's errors (e.g. a full disk)
        _unlink_quietly(tmp)
        free = _free_bytes(path.parent)
        hint = " (the disk is full)" if free is not None and free < 1 << 20 else ""
        raise ProductError(f"{path}: cannot write product: {exc}{hint}") from None
    except BaseException:
        _unlink_quietly(tmp)
        raise
    return Path(tmp)


def publish(staged: Sequence[tuple[Path, Path]]) -> list[Path]:
    """Rename staged temporaries onto their products, all or (on failure) none.

    ``staged``: ``(temporary, product)`` pairs of :func:`stage_netcdf`. The renames are
    atomic each; they run only after every product of a unit was written, so a full
    disk or a kill while writing never publishes half a unit.
    """
    for tmp, path in staged:
        try:
            os.replace(tmp, path)
        except OSError as exc:
            for other, _ in staged:
                _unlink_quietly(os.fspath(other))
            raise ProductError(f"{path}: cannot write product: {exc.strerror or exc}") from None
    return [path for _, path in staged]


def discard(staged: Sequence[tuple[Path, Path]]) -> None:
    """Remove staged temporaries that will not be published."""
    for tmp, _ in staged:
        _unlink_quietly(os.fspath(tmp))


def write_netcdf_atomic(
    ds: xr.Dataset, path: str | os.PathLike, *, compression_level: int = 4
) -> Path:
    """Write ``ds`` to ``path`` through a temporary file in the same directory.

    Raises
    ------
    ProductError
        The directory cannot be written (read-only, full, missing).
    """
    path = Path(path)
    return publish([(stage_netcdf(ds, path, compression_level=compression_level), path)])[0]


#: extensions of the files whose temporaries :func:`remove_stale_temporaries` removes
_TEMP_EXTENSIONS = ("nc", "png", "hpl", "txt", "csv", "json")
#: a product temporary older than this (s) belongs to no live run of retrieve or sf-type
STALE_TEMPORARY_S = 3600.0


def remove_stale_temporaries(
    outdir: str | os.PathLike, older_than_s: float = STALE_TEMPORARY_S
) -> list[Path]:
    """Delete temporaries of cwproc's writers (``.<name>.<ext>.<random>.tmp``, products,
    pictures and simulated files) that a killed run left in ``outdir``.

    Commands other than ``batch`` hold no lock, so only temporaries older than
    ``older_than_s`` are removed (a live run renames its temporaries within seconds);
    ``batch`` removes them all under its lock.
    """
    removed = []
    now = time.time()
    candidates = [p for ext in _TEMP_EXTENSIONS for p in Path(outdir).glob(f".*.{ext}.*.tmp")]
    for path in candidates:
        try:
            if path.is_file() and now - path.stat().st_mtime > older_than_s:
                path.unlink()
                removed.append(path)
        except FileNotFoundError:
            continue
    return removed


def write_bytes_atomic(
    path: str | os.PathLike, data: bytes | Iterable[bytes], *, fsync: bool = False
) -> Path:
    """Write ``data`` to ``path`` whole or not at all; returns ``path``.

    ``data`` is the bytes, or an iterable of pieces written one after the other (a
    large text need not exist whole in memory: the ledger's snapshot).

    The bytes go to an unpredictable temporary created exclusively beside ``path``
    (:func:`tempfile.mkstemp`: no planted symlink is followed), get the umask's mode
    (:func:`umask_mode`), optionally reach the disk (``fsync``), and are renamed onto
    ``path``; a killed run leaves only a hidden ``.<name>.<random>.tmp``, which
    :func:`remove_stale_temporaries` removes. Stale temporaries of earlier runs in the
    folder are removed first.

    Raises
    ------
    OSError
        The folder cannot be written; no temporary is left behind. Callers name the
        file and the command in their own error.
    """
    path = Path(path)
    remove_stale_temporaries(path.parent)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            if isinstance(data, bytes | bytearray | memoryview):
                fh.write(data)
            else:
                for piece in data:
                    fh.write(piece)
            if fsync:
                fh.flush()
                os.fsync(fh.fileno())
        os.chmod(tmp, umask_mode())
        os.replace(tmp, path)
    except BaseException:
        _unlink_quietly(tmp)
        raise
    return path


def umask_mode(mode: int = 0o666) -> int:
    """``mode`` restricted by the process umask: what ``open()`` would have given.

    Temporary files (:func:`tempfile.mkstemp`) are created 0600; a product renamed from
    one keeps that mode, which a shared archive, a web server or THREDDS cannot read.
    """
    current = os.umask(0o022)
    os.umask(current)
    return mode & ~current


def _free_bytes(folder: Path) -> int | None:
    """Free bytes of the filesystem of ``folder`` (``None`` if unknown)."""
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return None


def _unlink_quietly(path: str) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        return


def read_product(path: str | os.PathLike) -> xr.Dataset:
    """Open a cwproc product fully into memory (the file is closed on return)."""
    with NETCDF_LOCK, xr.open_dataset(path, engine="netcdf4") as ds:
        return ds.load()
