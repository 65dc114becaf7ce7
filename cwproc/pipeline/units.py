"""Inputs and product units: reading one file, grouping files into units, reading again.

A *product unit* is what makes one set of products: the scan files of one instrument
and UTC day, the sonic samples of one logger and UTC day, or one wind-record file.
Every input is read on its own (a bad file fails alone, with one line naming the file,
the line and the problem); :func:`unit_key` names the unit and its products.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import os
import re
import stat
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np
import xarray as xr

from cwproc.config import Config
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import KIND, FileIdentity, Format, detect_format, get_identifier, get_reader
from cwproc.io.netcdf import sha256_file
from cwproc.io.scans import concat_scans
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


@dataclass
class ProductUnit:
    """Inputs that make one set of products (e.g. one instrument-day of scans)."""

    key: str
    kind: str
    inputs: list[InputFile] = field(default_factory=list)
    #: one line per input left out when its data were read (damaged beyond its header)
    failures: list[str] = field(default_factory=list)


def format_mismatch(path: str | os.PathLike, fmt: Format, config: Config) -> str:
    """Why ``config`` does not read a file of format ``fmt`` ('' when it does).

    A configuration that pins ``[instrument] format`` (a preset for one instrument)
    reads files of that format only; ``cwproc retrieve`` and ``cwproc batch`` skip the
    others with this line, naming the file and the format. A Stream Line background
    file belongs to a configuration that reads ``.hpl`` files.
    """
    pinned = config.instrument.format
    if pinned == "auto" or fmt.value == pinned:
        return ""
    if fmt is Format.HALO_BACKGROUND and pinned == Format.HPL.value:
        return ""  # read with the .hpl files beside it (stage background), never refused
    return f"{os.fspath(path)}: a {fmt.value} file, but the configuration reads only {pinned}"


#: the kind of instrument of a format whose files come from one kind only
_FORMAT_KIND = {
    Format.HPL: "pulsed",
    Format.WINDCUBE_STA: "pulsed",
    Format.WINDCUBE_RTD: "pulsed",
    Format.ZEPHIR_CSV: "cw",
}
#: ``instrument_kind`` attribute of scans -> the kind of ``[instrument] kind``
_SCAN_KIND = {"streamline": "pulsed", "pulsed": "pulsed", "cw": "cw"}
#: a preset of each kind, named in the message
_PRESET_OF_KIND = {"pulsed": "streamline", "cw": "zephir300"}


def instrument_mismatch(item: InputFile, config: Config) -> str:
    """Why ``config`` describes another instrument than the one of ``item`` ('' if not).

    A lidar file (Stream Line ``.hpl``, WindCube: pulsed; ZephIR: cw; scan NetCDF: its
    ``instrument_kind``) read with a configuration of another ``[instrument] kind``
    (e.g. ``-c zephir300``, a cw lidar, on ``.hpl`` files) would be processed with the
    wrong probe volume and presets: it is a failure naming the file and both
    instruments. The defaults (no ``-c``) read every file, as do sonic logs under any
    configuration (their analysis uses no lidar setting).
    """
    if config.source == "<defaults>" or KIND.get(item.format) not in ("scan", "wind_record"):
        return ""
    attrs = getattr(held_or_identity(item), "attrs", {}) or {}
    declared = str(attrs.get("instrument_kind", "")).strip().lower()
    kind = _FORMAT_KIND.get(item.format) or _SCAN_KIND.get(declared)
    if kind is None or kind == config.instrument.kind:
        return ""
    made_by = str(attrs.get("instrument", "")) or item.format.value
    preset = _PRESET_OF_KIND.get(kind, "")
    return (
        f"{os.fspath(item.path)}: a file of a {kind} lidar ({made_by}), but configuration "
        f"{config.source} describes {config.instrument.name} ({config.instrument.kind}"
        f"{' lidar' if config.instrument.kind != 'sonic' else ''}); use a configuration "
        f"for its instrument{f' (e.g. -c {preset})' if preset else ''}"
    )


def other_formats_note(paths: list[str], formats: list[str], pinned: str) -> str:
    """One note for every file skipped because the configuration reads another format.

    ``"7 files of other instruments skipped (ghg, toa5 in sample_data/sonic; zephir_csv
    in sample_data/zephir): the configuration reads hpl only"``: the formats (with their
    count when more than one file) and the folders they were found in, in place of one
    line per file (:func:`format_mismatch` words a file named on the command line).
    """
    counts = Counter(formats)
    kinds = ", ".join(f"{n} {f}" if n > 1 else f for f, n in sorted(counts.items()))
    folders = sorted({os.path.dirname(os.fspath(p)) or "." for p in paths})
    shown = ", ".join(folders[:3]) + (f" and {len(folders) - 3} more" if len(folders) > 3 else "")
    return (
        f"{len(paths)} file{'s' if len(paths) != 1 else ''} of other instruments skipped "
        f"({kinds} in {shown}): "
        f"the configuration reads {pinned} only"
    )


def no_input_of_format(n_skipped: int, pinned: str) -> str:
    """The failure of a run whose every input is of a format the configuration does not read."""
    return (
        f"none of the inputs is a {pinned} file, the only format the configuration reads "
        f"({n_skipped} file(s) of other formats skipped); use a configuration for their "
        'instrument, or one with [instrument] format = "auto"'
    )


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
        path=path, format=fmt, sha256=sha, dataset=ds, start=_start(ds), signature=signature
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
        start=_start(identity),
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


def _times(ds: xr.Dataset | FileIdentity) -> np.ndarray:
    """The times of a dataset or of a file's identity (empty when it has none)."""
    if isinstance(ds, FileIdentity):
        return ds.time
    return ds["time"].values if "time" in ds.variables else np.array([], "datetime64[ns]")


def _start(ds: xr.Dataset | FileIdentity) -> np.datetime64 | None:
    """The earliest valid time of a dataset (None when it has none)."""
    t = _times(ds)
    t = t[~np.isnat(t)]
    return t.min() if t.size else None


def _day(ds: xr.Dataset | FileIdentity) -> str:
    t = _times(ds)
    t = t[~np.isnat(t)]
    if t.size == 0:
        return "nodate"
    return np.datetime_as_string(np.min(t), unit="D").replace("-", "")


#: characters kept in a part of a product name; anything else becomes "-"
_NAME_CHARS = re.compile(r"[^A-Za-z0-9._+@-]+")
#: longest part of a product name taken from a file (characters)
NAME_PART_MAX = 40


def name_part(text: object, default: str = "x") -> str:
    """A safe part of a product file name built from untrusted text (a header value).

    Only letters, digits and ``._+@-`` are kept (other runs become ``-``, leading dots
    and dashes are dropped), and the part is cut to ``NAME_PART_MAX``
    characters: a ``System ID`` of ``../../tmp/pwned``, a NUL or 300 characters can
    neither leave the output folder nor make an invalid file name.
    """
    part = _NAME_CHARS.sub("-", str(text)).lstrip(".-")[:NAME_PART_MAX].rstrip(".-")
    return part or default


def _sonic_station(ds: xr.Dataset) -> str:
    """The logger or instrument identity a sonic file states ('' when none)."""
    for key in ("toa5_station", "tob1_station", "ghg_instrument", "ghg_serial_number"):
        value = str(ds.attrs.get(key, "")).strip()
        if value:
            return value
    return str(ds.attrs.get("meteo2_station", "")).strip()


#: attributes that identify the logger of a sonic file, per identity field (issue 34.2)
_SONIC_IDENTITY_ATTRS: dict[str, tuple[str, ...]] = {
    "serial": ("toa5_serial", "tob1_serial", "ghg_serial_number", "meteo2_serial"),
    "program": ("toa5_program", "tob1_program", "ghg_software_version", "meteo2_program"),
    "table": ("toa5_table", "tob1_table", "meteo2_table"),
}


def sonic_identity(item: InputFile) -> tuple[tuple[str, str], ...]:
    """Everything that identifies the logger of a sonic input, as ``(field, value)`` pairs.

    The station (TOA5/TOB1 station name, GHG instrument, Meteo-2 ``# station:``), the
    logger's serial number, its program, the data table, and the folder the file is in:
    two loggers that share a station name (or one header in two folders) are two
    instruments, never one (issue 34.2). Empty for other kinds of input.
    """
    ds = held_or_identity(item)
    if KIND[item.format] != "sonic" or ds is None:
        return ()
    parts = [("station", _sonic_station(ds))]
    for name, keys in _SONIC_IDENTITY_ATTRS.items():
        values = (str(ds.attrs.get(k, "")).strip() for k in keys)
        parts.append((name, next((v for v in values if v), "")))
    parts.append(("folder", os.fspath(Path(item.path).absolute().parent)))
    return tuple(parts)


def sonic_span(item: InputFile) -> tuple[str, str]:
    """First and last time of a sonic input's held data (ISO, UTC; '' when unknown)."""
    ds = item.dataset
    if KIND[item.format] != "sonic" or ds is None or "time" not in ds.variables:
        return "", ""
    t = np.asarray(ds["time"].values)
    t = t[~np.isnat(t)] if np.issubdtype(t.dtype, np.datetime64) else t[:0]
    if t.size == 0:
        return "", ""
    return tuple(str(np.datetime_as_string(x, unit="ms")) for x in (t.min(), t.max()))


def _apart_in_time(
    identities: Sequence[tuple[tuple[str, str], ...]], spans: Sequence[tuple[str, str]]
) -> bool:
    """Whether the inputs of each identity cover times no other identity's do."""
    cover: dict[tuple, list[str]] = {}
    for identity, (first, last) in zip(identities, spans, strict=True):
        if not first or not last:
            return False
        lo, hi = cover.setdefault(identity, [first, last])
        cover[identity] = [min(lo, first), max(hi, last)]
    ordered = sorted(cover.values())
    return all(a[1] < b[0] for a, b in itertools.pairwise(ordered))


def distinct_keys(
    base: str,
    identities: Sequence[tuple[tuple[str, str], ...]],
    spans: Sequence[tuple[str, str]] | None = None,
) -> tuple[dict[tuple[tuple[str, str], ...], str], str]:
    """Unit keys that keep loggers apart when several share the key ``base``.

    With one identity the key is ``base``. With several, each gets ``base`` with the
    station part followed by ``-`` and the value of the first identity field in which
    they differ (serial, then table, program, folder name; a short hash of the whole
    identity when even that is the same), and a note says so. Inputs that differ in
    their folder alone and whose times do not overlap (``spans``: first and last time
    of each input) are one logger's files kept in several folders (one a day: the file
    that crosses midnight is in the day before's): one unit.

    Returns
    -------
    (dict, str)
        Identity -> key, and the note ('' with one identity).
    """
    unique = sorted(set(identities))
    if len(unique) <= 1:
        return {i: base for i in unique}, ""
    fields = [k for k, _ in unique[0]]
    differing = [f for f in fields if len({dict(i)[f] for i in unique}) > 1]
    if differing == ["folder"] and spans is not None and _apart_in_time(identities, spans):
        return {i: base for i in unique}, ""
    field_name = next((f for f in ("serial", "table", "program", "folder") if f in differing), "")

    def token(identity: tuple[tuple[str, str], ...]) -> str:
        value = dict(identity).get(field_name, "")
        if field_name == "folder":
            value = Path(value).name
        return name_part(value, "none")

    tokens = [token(i) for i in unique]
    if len(set(tokens)) < len(tokens):  # not told apart by one field: a hash of all
        tokens = [hashlib.sha256(repr(i).encode()).hexdigest()[:8] for i in unique]
    head, _, day = base.rpartition("_")
    keys = {i: f"{head}-{t}_{day}" for i, t in zip(unique, tokens, strict=True)}
    what = ", ".join(differing) or "identity"
    told = "; ".join(", ".join(dict(i)[f] or "none" for f in differing) for i in unique)
    note = (
        f"{len(unique)} loggers share the unit {base} but differ in {what} ({told}): "
        f"kept apart as {', '.join(keys[i] for i in unique)}"
    )
    return keys, note


def unit_key(item: InputFile) -> tuple[str, str]:
    """(kind, key) of the product unit an input belongs to; the key names the products.

    Scan files group by instrument, system id and UTC day; sonic files by format, the
    station the file names (TOA5/TOB1 station, GHG instrument, Meteo-2 ``# station:``;
    else the name of its folder) and UTC day, so two loggers of one day are never
    merged; wind records are one unit each, named after their folder and file, so
    same-named files of two instruments are two units. Every part taken from a file is
    made safe by :func:`name_part`, so the key is a plain file name.
    """
    kind = KIND[item.format]
    ds = held_or_identity(item)
    assert ds is not None
    if kind == "scan":
        system = name_part(ds.attrs.get("system_id", ""))
        instrument = name_part(ds.attrs.get("instrument_kind", item.format.value))
        return kind, f"{instrument}_{system}_{_day(ds)}"
    folder = name_part(Path(item.path).absolute().parent.name, "root")
    if kind == "sonic":
        station = _sonic_station(ds)
        where = name_part(station) if station else folder
        return kind, f"{item.format.value}_{where}_{_day(ds)}"
    # a WindCube's .rtd and the .sta of the same period share the stem: two units
    rtd = "_rtd" if item.format is Format.WINDCUBE_RTD else ""
    return kind, f"{folder}_{name_part(Path(item.path).stem)}{rtd}"


def split_by_day(item: InputFile) -> list[InputFile]:
    """A sonic input as one item per UTC day of its samples (other inputs unchanged).

    Sonic products are made per day (Gladkikh et al. (2014) type 10-min windows, and a
    15-min logger file holds one and a half of them), so a file that crosses midnight
    contributes to two days.
    """
    ds = item.dataset
    if KIND[item.format] != "sonic" or ds is None or ds.sizes.get("time", 0) == 0:
        return [item]
    days = ds["time"].values.astype("datetime64[D]")
    unique = np.unique(days[~np.isnat(days)])
    if unique.size <= 1:
        return [item]
    return [
        dataclasses.replace(item, dataset=ds.isel(time=np.flatnonzero(days == day)), day=str(day))
        for day in unique
    ]


def group_units(items: Iterable[InputFile], notes: list[str] | None = None) -> list[ProductUnit]:
    """Group read inputs into product units (scans and sonic data: per instrument and
    UTC day; wind records: per file), in a stable order.

    Sonic inputs that share a key but not their logger's identity
    (:func:`sonic_identity`) are kept apart (:func:`distinct_keys`); the note saying so
    is appended to ``notes`` when given.
    """
    parts = [unit_part(item) for whole in items for item in split_by_day(whole)]
    return units_of(parts, notes)


#: an input with its kind, key, :func:`sonic_identity` and :func:`sonic_span`
UnitPart = tuple[InputFile, str, str, tuple[tuple[str, str], ...], tuple[str, str]]


def unit_part(item: InputFile) -> UnitPart:
    """``(item, kind, key, identity, span)`` of an input, taken while its data are held."""
    return (item, *unit_key(item), sonic_identity(item), sonic_span(item))


def units_of(parts: Iterable[UnitPart], notes: list[str] | None = None) -> list[ProductUnit]:
    """Product units of :func:`unit_part` tuples, loggers of one key kept apart."""
    groups: dict[tuple[str, str], list[tuple[InputFile, tuple, tuple]]] = {}
    for item, kind, key, identity, span in parts:
        groups.setdefault((kind, key), []).append((item, identity, span))
    units: dict[tuple[str, str], ProductUnit] = {}
    for (kind, key), triples in groups.items():
        members = [m for m, _, _ in triples]
        identities = [i for _, i, _ in triples]
        keys, note = distinct_keys(key, identities, [s for _, _, s in triples])
        if note and notes is not None:
            notes.append(note)
        for member, identity in zip(members, identities, strict=True):
            final = keys.get(identity, key)
            units.setdefault((kind, final), ProductUnit(key=final, kind=kind)).inputs.append(member)
    return [units[k] for k in sorted(units)]


#: relative spread of the sampling rates of sonic files that may be joined into one day
SONIC_RATE_TOLERANCE = 0.01


def concat_sonic(parts: Sequence[xr.Dataset], label: str) -> xr.Dataset:
    """Join the sonic datasets of one instrument-day in time order.

    Raises
    ------
    CwprocError
        The parts have sampling rates that differ by more than 1 %.
    """
    rates = np.array([float(p.attrs["sampling_rate_hz"]) for p in parts])
    if np.ptp(rates) > SONIC_RATE_TOLERANCE * np.median(rates):
        listed = ", ".join(f"{r:g}" for r in rates)
        raise CwprocError(f"{label}: inputs have different sampling rates ({listed} Hz)")
    ds = parts[0] if len(parts) == 1 else xr.concat(parts, dim="time", combine_attrs="drop")
    # a stable sort leaves data in time order as they are: no copy of every variable
    in_order = ds.indexes["time"].is_monotonic_increasing
    ds = ds.copy(deep=False) if in_order else ds.sortby("time")
    ds.attrs = dict(parts[0].attrs)
    ds.attrs["sampling_rate_hz"] = float(np.median(rates))
    return ds


def concat_unit(unit: ProductUnit) -> xr.Dataset:
    """The datasets of a unit as one (scans and sonic days: joined in time order)."""
    datasets = [i.dataset for i in unit.inputs if i.dataset is not None]
    if unit.kind == "scan":
        return concat_scans(datasets)
    if unit.kind == "sonic":
        return concat_sonic(datasets, unit.key)
    if len(datasets) != 1:
        raise CwprocError(f"unit {unit.key}: expected one input, got {len(datasets)}")
    return datasets[0]


def load_unit(unit: ProductUnit, config: Config) -> None:
    """Read again the inputs of ``unit`` whose data were not kept (memory budget).

    Raises
    ------
    CwprocError
        An input changed or vanished since it was first read (its checksum differs).
    """
    for item in list(unit.inputs):
        if item.dataset is None:
            try:
                item.dataset = load_item(item, config)
            except InputFileError as exc:  # identified by its header, damaged beyond it
                drop_input(unit, item, exc)


def drop_input(unit: ProductUnit, item: InputFile, exc: InputFileError) -> None:
    """Leave out of ``unit`` an input whose data cannot be read; its line in ``failures``."""
    unit.inputs.remove(item)
    unit.failures.append(str(exc))


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


def unit_label(unit: ProductUnit) -> str:
    """The input files of a unit, for messages (the first three and a count)."""
    paths = list(dict.fromkeys(os.fspath(i.path) for i in unit.inputs))
    if len(paths) <= 3:
        return ", ".join(paths)
    return ", ".join(paths[:3]) + f" (+{len(paths) - 3} more)"
