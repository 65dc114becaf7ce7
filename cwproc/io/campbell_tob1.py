"""Campbell Scientific TOB1 files: binary sonic records after five ASCII header lines.

The header is that of a TOA5 file (:mod:`cwproc.io.campbell`: environment, field
names, units, processing) plus a fifth line of data types (``ULONG``, ``IEEE4``,
``FP2``, ...); then fixed-size little-endian records without separators. SECONDS
counts from 1990-01-01 00:00:00 (logger time) plus NANOSECONDS. A partial trailing
record (a cut file) is ignored and reported; records off their boundaries are
realigned on their RECORD numbers (:func:`cwproc.io.records.realigned_records`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io.averaged import averaged_table_reason, refuse_averaged_table
from cwproc.io.campbell import (
    DEFAULT_COLUMNS,
    OPTIONS,
    campbell_dataset,
    header_fields,
    record_warnings,
    to_celsius,
)
from cwproc.io.records import realigned_records
from cwproc.io.sonic_text import check_options, column_map, option_number
from cwproc.io.timecheck import epoch_seconds_to_times

#: TOB1 data types -> numpy dtypes (FP2 is Campbell's 2-byte float, big-endian)
TOB1_TYPES: dict[str, str] = {
    "IEEE4": "<f4",
    "IEEE4L": "<f4",
    "IEEE8": "<f8",
    "IEEE8L": "<f8",
    "ULONG": "<u4",
    "UINT4": "<u4",
    "LONG": "<i4",
    "INT4": "<i4",
    "SHORT": "<i2",
    "INT2": "<i2",
    "USHORT": "<u2",
    "UINT2": "<u2",
    "BOOL": "<i4",
    "BOOL4": "<i4",
    "BOOL2": "<i2",
    "BOOL8": "u1",
    "FP2": ">u2",
}


#: TOB1 epoch: SECONDS count from this instant (logger time)
TOB1_EPOCH = np.datetime64("1990-01-01T00:00:00", "ns")


def _refuse_statistics(
    path: str | os.PathLike, line4: str, names: list[str], cols: Mapping[str, str]
) -> None:
    """Refuse a TOB1 table of statistics from its processing line and field names."""
    wind = [cols[k] for k in ("u", "v", "w") if cols[k] in names]
    try:
        processing = header_fields(path, line4, 4)
    except InputFileError:  # line 4 is not read otherwise: its damage is no refusal
        processing = []
    refuse_averaged_table(
        path, averaged_table_reason(names=names, processing=processing, wind_fields=wind)
    )


def decode_fp2(raw: np.ndarray) -> np.ndarray:
    """Decode Campbell FP2 two-byte floats (already read as big-endian uint16).

    Bit 15 sign, bits 13-14 the negative decimal exponent, bits 0-12 the mantissa;
    0x1FFF is +INF, 0x9FFF is -INF and 0x9FFE is NaN [doc, Campbell manuals].
    """
    raw = raw.astype(np.uint16)
    sign = np.where(raw & 0x8000, -1.0, 1.0)
    exponent = (raw >> 13) & 0x3
    mantissa = (raw & 0x1FFF).astype(float)
    out = sign * mantissa / 10.0**exponent
    out = np.where(raw == 0x1FFF, np.inf, out)
    out = np.where(raw == 0x9FFF, -np.inf, out)
    return np.where(raw == 0x9FFE, np.nan, out)


def tob1_dtype(path: str | os.PathLike, names: list[str], types: list[str]) -> np.dtype:
    """The numpy record dtype of a TOB1 file from its header lines 2 and 5."""
    if len(types) != len(names):
        raise InputFileError(path, f"{len(types)} data types for {len(names)} fields", 5)
    fields = []
    for name, t in zip(names, types, strict=True):
        key = t.strip().upper()
        if key.startswith("ASCII(") and key.endswith(")") and key[6:-1].isdigit():
            fields.append((name, f"S{int(key[6:-1])}"))
        elif key in TOB1_TYPES:
            fields.append((name, TOB1_TYPES[key]))
        else:
            raise InputFileError(path, f"unknown TOB1 data type {t!r} of field {name!r}", 5)
    try:
        return np.dtype(fields)
    except (TypeError, ValueError) as exc:
        raise InputFileError(path, f"bad field list: {exc}", 2) from None


def _tob1_column(path: str | os.PathLike, records: np.ndarray, name: str, type_: str) -> np.ndarray:
    col = records[name]
    if type_.strip().upper() == "FP2":
        return decode_fp2(col)
    if col.dtype.kind == "S":
        raise InputFileError(path, f"field {name!r} is text ({type_}), not a number", 5)
    with np.errstate(invalid="ignore"):
        return col.astype(float)


def read_tob1(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read a Campbell TOB1 binary file of high-rate sonic data into a sonic dataset.

    Parameters are those of :func:`read_toa5`. Time = 1990-01-01 + SECONDS +
    NANOSECONDS (logger time) - ``utc_offset_hours``.

    Raises
    ------
    InputFileError
        Header problems name the header line; data problems name the record number
        (1-based, ``record N``).
    """
    check_options(path, options, OPTIONS)
    cols = column_map(path, options, DEFAULT_COLUMNS)
    offset_h = option_number(path, options, "utc_offset_hours", 0.0)
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    header, pos = _tob1_header(path, raw)
    env = header_fields(path, header[0], 1)
    names = header_fields(path, header[1], 2)
    units = header_fields(path, header[2], 3)
    types = header_fields(path, header[4], 5)
    _refuse_statistics(path, header[3], names, cols)
    dtype = tob1_dtype(path, names, types)
    for key in ("SECONDS", "NANOSECONDS"):
        if key not in names:
            raise InputFileError(path, f"no {key} field", 2)
    for key in ("u", "v", "w"):
        if cols[key] not in names:
            raise InputFileError(path, f"no field {cols[key]!r} ({key})", 2)
    notes: list[str] = []
    records, extra = _tob1_records(path, raw[pos:], dtype, pos, notes)
    n_rec = records.size
    typ = dict(zip(names, types, strict=True))
    times = _tob1_times(path, records, typ) - np.timedelta64(round(offset_h * 3600e9), "ns")
    vals = {k: _tob1_column(path, records, cols[k], typ[cols[k]]) for k in ("u", "v", "w")}
    unit = dict(zip(names, (units + [""] * len(names))[: len(names)], strict=True))
    temp = (
        to_celsius(
            _tob1_column(path, records, cols["temperature"], typ[cols["temperature"]]),
            unit[cols["temperature"]],
        )
        if cols["temperature"] in names
        else np.full(n_rec, np.nan)
    )
    diag = (
        _tob1_column(path, records, cols["diagnostic"], typ[cols["diagnostic"]])
        if cols["diagnostic"] in names
        else np.zeros(n_rec)
    )
    if "RECORD" in names and records["RECORD"].dtype.kind in "iu":
        notes.extend(record_warnings(records["RECORD"]))
    env = env + [""] * (8 - len(env))
    attrs = {
        "tob1_station": env[1],
        "tob1_logger": env[2],
        "tob1_serial": env[3],
        "tob1_os": env[4],
        "tob1_program": env[5],
        "tob1_signature": env[6],
        "tob1_table": env[7],
        "partial_record_bytes": int(extra),
        "time_reference": f"logger time minus {offset_h:g} h",
    }
    return campbell_dataset(path, options, env, times, vals, temp, diag, attrs, notes)


def _tob1_header(path: str | os.PathLike, raw: bytes) -> tuple[list[str], int]:
    """The 5 ASCII header lines of a TOB1 file (line ends kept) and the offset of its
    first binary record.

    Raises
    ------
    InputFileError
        The file ends inside the header, or line 1 is not a TOB1 environment line.
    """
    pos = 0
    header: list[str] = []
    for number in range(1, 6):
        end = raw.find(b"\n", pos)
        if end < 0:
            raise InputFileError(path, "file ends inside the 5-line ASCII header", number)
        header.append(raw[pos : end + 1].decode("latin-1"))
        pos = end + 1
    if not header[0].startswith('"TOB1"'):
        raise InputFileError(path, 'not a TOB1 file (line 1 must start with "TOB1")', 1)
    return header, pos


def _tob1_records(
    path: str | os.PathLike, data: bytes, dtype: np.dtype, pos: int, notes: list[str]
) -> tuple[np.ndarray, int]:
    """The binary records of a TOB1 file (realigned on their ``RECORD`` numbers when the
    file has them) and the bytes of a cut last record, noted in ``notes``.

    Raises
    ------
    InputFileError
        Not one complete record.
    """
    n_rec, extra = divmod(len(data), dtype.itemsize)
    if n_rec == 0:
        raise InputFileError(path, "no complete data record", 1, unit="record")
    if dtype.names is not None and "RECORD" in dtype.names and dtype["RECORD"].kind in "iu":
        records, extra = realigned_records(path, data, dtype, pos, notes)
    else:
        records = np.frombuffer(data[: n_rec * dtype.itemsize], dtype=dtype)
    if extra:
        notes.append(
            f"partial trailing record ({extra} of {dtype.itemsize} bytes) ignored: the file was cut"
        )
    return records, extra


def _tob1_times(path: str | os.PathLike, records: np.ndarray, typ: dict[str, str]) -> np.ndarray:
    """Logger time of each record: 1990-01-01 + SECONDS + NANOSECONDS (datetime64[ns]).

    Raises
    ------
    InputFileError
        A field is not a number, or a count is not valid (names the record).
    """
    for key in ("SECONDS", "NANOSECONDS"):
        field = records[key]
        if field.dtype.kind not in "iuf":
            raise InputFileError(path, f"{key} has type {typ[key]}, not a number", 5)
        if field.dtype.kind == "f":
            with np.errstate(invalid="ignore"):
                wrong = np.flatnonzero(~np.isfinite(field) | (np.abs(field) > 2.0**40))
            if wrong.size:
                raise InputFileError(
                    path, f"{key} is not a valid count", int(wrong[0]) + 1, unit="record"
                )
    nanos = records["NANOSECONDS"].astype(np.int64)
    bad = np.flatnonzero((nanos < 0) | (nanos >= 1_000_000_000))
    if bad.size:
        raise InputFileError(
            path, f"NANOSECONDS {nanos[bad[0]]} out of range", int(bad[0]) + 1, unit="record"
        )
    return epoch_seconds_to_times(path, records["SECONDS"], nanos, TOB1_EPOCH, 1, unit="record")
