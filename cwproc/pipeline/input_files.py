"""One input file: its format, checksum and dataset, read once and read again unchanged.

Every input is read on its own (a bad file fails alone, with one line naming the file,
the line and the problem). A file known from its header (``.hpl``) may be identified
first and read when its unit runs; :func:`load_item` reads a file again only when it is
unchanged since its checksum was taken (:func:`file_signature`).
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import xarray as xr

from cwproc.config import Config
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import FileIdentity, Format, detect_format, get_identifier, get_reader
from cwproc.io.netcdf import sha256_file
from cwproc.io.timecheck import set_plausible_window


@dataclass
class InputFile:
    """One input: its path, format, checksum and (once read) dataset."""

    path: Path
    format: Format
    #: SHA-256 of the file; None until its data are read when it was identified by its
    #: header alone (``read_input(..., checksum=False)``): taken by that read then
    sha256: str | None
    dataset: xr.Dataset | None = None
    #: the UTC day this item holds when a file crossing midnight was split (sonic)
    day: str | None = None
    #: time of its first ray (scan files; orders the files of a streamed day)
    start: np.datetime64 | None = None
    #: what the header says (attributes, first time) when the data are not read yet
    identity: FileIdentity | None = None
    #: the file's :func:`file_signature` when ``sha256`` was computed, or when it was
    #: identified if ``sha256`` is not taken yet (None: unknown)
    signature: tuple[int, ...] | None = None


def reader_options(config: Config, fmt: Format) -> dict:
    """Options of the reader of ``fmt`` from the ``[reader.<format>]`` config table."""
    return dict(config.reader.get(fmt.value, {}))


def apply_time_window(config: Config) -> None:
    """Make the configuration's plausible window of input times the readers' (issue 34.1).

    ``[instrument] earliest_date`` and ``latest_date`` (see
    :func:`cwproc.io.timecheck.set_plausible_window`); called before each file is
    examined or read, so that every reader in this process (batch workers included)
    checks its times against the configuration being run.
    """
    set_plausible_window(config.instrument.earliest_date, config.instrument.latest_date)


def read_input(
    path: str | os.PathLike,
    config: Config,
    *,
    identify_only: bool = False,
    checksum: bool = True,
    examined: Examined | None = None,
) -> InputFile:
    """Detect the format of one file, checksum it and read it.

    With ``identify_only``, a format with a header-only identifier (``.hpl``) is not
    read: the item gets ``identity`` (attributes and first time, enough for
    :func:`unit_key`) and no dataset, and its data are read when its unit is processed.
    A header the identifier cannot take is read whole (and its error reported). Such an
    item is also left without its checksum when ``checksum`` is false (``sha256`` None,
    its :func:`file_signature` kept): the read of its data takes it
    (:func:`load_item`, :func:`cwproc.pipeline.stream_read.planned_chunks`), so that a
    day of files is read once less. ``examined``: what :func:`identify_input` found of the
    file (its format and signature), not looked for again.

    Raises
    ------
    InputFileError
        Whatever the reader found wrong with the file.
    """
    path = Path(path)
    fmt, signature = examined if examined is not None else _examined(path, config)
    if identify_only:
        item = _identified(path, fmt, signature, config, checksum)
        if item is not None:
            return item
    sha = _checksum(path)
    if fmt is Format.HALO_BACKGROUND:  # read by correct_background for the scans beside it
        return InputFile(path=path, format=fmt, sha256=sha, signature=signature)
    ds = get_reader(fmt)(path, **reader_options(config, fmt))
    return InputFile(
        path=path, format=fmt, sha256=sha, dataset=ds, start=first_time(ds), signature=signature
    )


class Examined(NamedTuple):
    """What examining a file found: its format and :func:`file_signature`."""

    format: Format
    signature: tuple[int, ...]


def identify_input(path: str | os.PathLike, config: Config) -> InputFile | Examined:
    """``read_input(path, config, identify_only=True, checksum=False)`` when that reads
    the file's header alone; else what examining the file found (:class:`Examined`),
    for ``read_input(path, config, examined=...)``, which reads it whole (the same item).

    Read whole: a format without a header-only identifier, a format with reader options,
    a header the identifier cannot take (its reader words the problem) and a Stream Line
    background file (checksummed whole). What it does costs a few Python-level steps
    and one small read, so :func:`cwproc.pipeline.retrieve.read_inputs` runs it in the
    caller's thread.

    Raises
    ------
    InputFileError
        The file cannot be examined, or is not a regular file, or its format is unknown.
    """
    path = Path(path)
    examined = _examined(path, config)
    item = _identified(path, *examined, config, checksum=False)
    return examined if item is None else item


def _examined(path: Path, config: Config) -> Examined:
    """The format of a regular file (detected unless pinned) and its :func:`file_signature`."""
    apply_time_window(config)
    try:
        mode = path.stat().st_mode
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        kind = "a folder" if stat.S_ISDIR(mode) else "a pipe, socket or device"
        raise InputFileError(path, f"not a regular file ({kind}); cwproc reads files")
    fmt = (
        detect_format(path)
        if config.instrument.format == "auto"
        else _pinned_format(path, Format(config.instrument.format))
    )
    try:
        signature = file_signature(path)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    return Examined(fmt, signature)


def _pinned_format(path: Path, pinned: Format) -> Format:
    """``pinned``, except a Stream Line background file under a configuration that
    reads ``.hpl`` (it goes with the scans beside it; read as a ``.hpl`` it failed)."""
    if pinned is not Format.HPL:
        return pinned
    try:
        fmt = detect_format(path)
    except InputFileError:
        return pinned  # the .hpl reader words what is wrong
    return Format.HALO_BACKGROUND if fmt is Format.HALO_BACKGROUND else pinned


def _identified(
    path: Path, fmt: Format, signature: tuple[int, ...], config: Config, checksum: bool
) -> InputFile | None:
    """The item of a file identified by its header (None: it must be read whole)."""
    if fmt is Format.HALO_BACKGROUND or reader_options(config, fmt):
        return None
    identify = get_identifier(fmt)
    if identify is None:
        return None
    try:
        identity = identify(path)
    except CwprocError:
        return None  # read whole: its reader words the problem
    return InputFile(
        path=path,
        format=fmt,
        sha256=_checksum(path) if checksum else None,
        identity=identity,
        start=first_time(identity),
        signature=signature,
    )


def _checksum(path: Path) -> str:
    """:func:`cwproc.io.netcdf.sha256_file`, its ``OSError`` an :class:`InputFileError`."""
    try:
        return sha256_file(path)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None


def file_signature(path: str | os.PathLike) -> tuple[int, ...]:
    """Device, inode, size and modification and change times (ns) of a file.

    A file whose signature is the one it had when its checksum was taken has not been
    written since (any write moves the change time, which no user call can set back),
    so it is read again without a second checksum.

    Raises
    ------
    OSError
        The file cannot be found or examined.
    """
    st = os.stat(path)
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def held_or_identity(item: InputFile) -> xr.Dataset | FileIdentity | None:
    """The dataset of an input when held, else what its header said (attributes)."""
    return item.dataset if item.dataset is not None else item.identity


def input_times(ds: xr.Dataset | FileIdentity) -> np.ndarray:
    """The times of a dataset or of a file's identity (empty when it has none)."""
    if isinstance(ds, FileIdentity):
        return ds.time
    return ds["time"].values if "time" in ds.variables else np.array([], "datetime64[ns]")


def first_time(ds: xr.Dataset | FileIdentity) -> np.datetime64 | None:
    """The earliest valid time of a dataset (None when it has none)."""
    t = input_times(ds)
    t = t[~np.isnat(t)]
    return t.min() if t.size else None


def load_item(item: InputFile, config: Config) -> xr.Dataset | None:
    """The dataset of ``item``: the one held, else the file read again (not stored).

    The file is checksummed once per run: read again unchanged (its
    :func:`file_signature` is the one taken with the checksum) it is only parsed;
    otherwise its checksum is taken again and compared. An item identified by its
    header without a checksum gets it here, from the file as read
    (:func:`checksummed_read`).

    Raises
    ------
    CwprocError
        The input changed or vanished since it was first read (its checksum differs).
    """
    if item.dataset is not None:
        return item.dataset
    if item.sha256 is None:
        ds = checksummed_read(item, config)
    else:
        ds = unchanged_read(item, config)
    if ds is None:
        again = read_input(item.path, config)
        if again.sha256 != item.sha256:
            raise CwprocError(f"{item.path}: changed while cwproc was running; run again")
        ds = again.dataset
    if item.day is not None and ds is not None:
        days = ds["time"].values.astype("datetime64[D]")
        ds = ds.isel(time=np.flatnonzero(days == np.datetime64(item.day, "D")))
    return ds


def checksummed_read(item: InputFile, config: Config) -> xr.Dataset:
    """The dataset of an input identified by its header alone, and its checksum
    (``item.sha256``), when the file is as it was identified (same
    :func:`file_signature` before the checksum and after the read).

    Raises
    ------
    CwprocError
        The file changed or vanished since it was identified: what was grouped by its
        header may not be what it holds now.
    InputFileError
        Whatever the reader found wrong with the file.
    """
    changed = CwprocError(f"{item.path}: changed while cwproc was running; run again")
    try:
        unchanged = file_signature(item.path) == item.signature
        sha = sha256_file(item.path) if unchanged else None
    except OSError:
        raise changed from None
    ds = unchanged_read(item, config) if unchanged else None  # signature before and after
    if ds is None:
        raise changed
    item.sha256 = sha
    return ds


def unchanged_read(item: InputFile, config: Config) -> xr.Dataset | None:
    """The dataset of ``item`` read from its file when the file is unchanged since its
    checksum was taken (same :func:`file_signature` before and after the read); None
    when it may have changed (the caller compares checksums).

    Raises
    ------
    InputFileError
        Whatever the reader found wrong with the file.
    """
    if item.signature is None:
        return None
    try:
        if file_signature(item.path) != item.signature:
            return None
    except OSError:
        return None  # vanished: read_input words it
    apply_time_window(config)
    ds = get_reader(item.format)(item.path, **reader_options(config, item.format))
    try:
        return ds if file_signature(item.path) == item.signature else None
    except OSError:
        return None
