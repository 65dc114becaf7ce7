"""Product units: the inputs that make one set of products, their keys and their data.

A *product unit* is what makes one set of products: the scan files of one instrument
and UTC day, the sonic samples of one logger and UTC day, or one wind-record file;
:func:`unit_key` names the unit and its products, :func:`group_units` groups read
inputs (:mod:`cwproc.pipeline.input_files`) into units and :func:`concat_unit` joins
their datasets.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.config import Config
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import KIND, FileIdentity, Format
from cwproc.io.scan_join import concat_scans
from cwproc.pipeline.input_files import InputFile, held_or_identity, input_times, load_item


@dataclass
class ProductUnit:
    """Inputs that make one set of products (e.g. one instrument-day of scans)."""

    key: str
    kind: str
    inputs: list[InputFile] = field(default_factory=list)
    #: one line per input left out when its data were read (damaged beyond its header)
    failures: list[str] = field(default_factory=list)


def _day(ds: xr.Dataset | FileIdentity) -> str:
    t = input_times(ds)
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


def unit_label(unit: ProductUnit) -> str:
    """The input files of a unit, for messages (the first three and a count)."""
    paths = list(dict.fromkeys(os.fspath(i.path) for i in unit.inputs))
    if len(paths) <= 3:
        return ", ".join(paths)
    return ", ".join(paths[:3]) + f" (+{len(paths) - 3} more)"
