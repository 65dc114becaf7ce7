"""ZephIR 300 cw lidar: Waltz / "CSV Converter" export of a ``.ZPH`` file -> wind record.

Layout (``real_data/FORMATS.md`` §2): ``;`` separators, decimal commas, Latin-1 text.

* line 1: metadata, ``Key: value`` items separated by ``;`` (``Unit: 317``,
  ``Time sync: UTC +1,0 hrs``, ``Time stamps indicate the beginning of the averaging
  period``, ``38m is a fixed reference measurement``,
  ``ZephIR window height above ground: 3,0m``, ...);
* line 2: column names; the last is ``Checksum:`` with an encoded blob glued on;
* lines 3...: one record per averaging period: ``Reference``, ``Time and Date``
  (``dd.mm.yyyy HH:MM:SS`` in the local time of "Time sync"), ``Timestamp (s)``, flags,
  pod and met columns, then one group of 8 columns per height, highest first
  (``Packets in Average at 297m`` ... ``TI at 297m``), and the ``Checksum`` field.

Two variants: 10-min averages (``Wind10_*.ZPH.csv``, ``Proportion Of Packets With
Rain (%)``) and 1-s records (``Wind_*.ZPH.csv``, a ``Raining`` 0/1 column and
``Packets in Average at MET``; no real file of this kind was available, the layout is
the one documented in FORMATS.md §2.2).

Notes
-----
Time stamps are converted to UTC by subtracting the "Time sync" offset; whether a
stamp marks the start or the end of its averaging period is kept in the attrs
(``time_stamp_position``), the stamp itself is not shifted. The missing-value codes
``9999`` and ``9998`` (any number of decimals) become NaN and are counted in
``attrs["n_missing_9999"]`` and ``attrs["n_missing_9998"]``.

The ``Checksum`` field is not checked. It is not a checksum of the record: every
character of it maps one-to-one onto printable text (the header blob decodes to extra
column names such as ``Points in Fit at 297m``, ``Cloud Scaling``, ``Backscatter``,
the record blobs to ``;``-separated numbers with ``9999`` codes), i.e. it is an
obfuscated copy of hidden columns whose encoding is undocumented, so no integrity
check can be derived from it.
"""

from __future__ import annotations

import csv
import io
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import ConfigError, InputFileError
from cwproc.io.ranges import range_warnings, screen_physical_range
from cwproc.io.schema import with_canonical_attrs
from cwproc.io.timecheck import check_times

#: per-height column prefix -> canonical variable name (8 columns per height)
HEIGHT_COLUMNS: dict[str, str] = {
    "Packets in Average": "packets",
    "Wind Direction (deg)": "wind_direction",
    "Horizontal Wind Speed (m/s)": "wind_speed",
    "Horizontal Wind Speed Min (m/s)": "wind_speed_min",
    "Horizontal Wind Speed Max (m/s)": "wind_speed_max",
    "Horizontal Wind Speed Std. Dev. (m/s)": "wind_speed_std",
    "Vertical Wind Speed (m/s)": "w",
    "TI": "turbulence_intensity",
}

#: per-record numeric column -> canonical variable name
RECORD_COLUMNS: dict[str, str] = {
    "Reference": "record_id",
    "Timestamp (s)": "instrument_timestamp",
    "Battery (V)": "battery_voltage",
    "Generator (V)": "generator_voltage",
    "Upper Temp. (C)": "pod_upper_temperature",
    "Lower Temp. (C)": "pod_lower_temperature",
    "Pod Humidity (%)": "pod_humidity",
    "ZephIR Bearing (deg)": "bearing",
    "Tilt (deg)": "tilt",
    "Air Temp. (C)": "air_temperature",
    "Pressure (mbar)": "air_pressure",
    "Humidity (%)": "relative_humidity",
    "MET Wind Speed (m/s)": "met_wind_speed",
    "MET Direction (deg)": "met_wind_direction",
    "Proportion Of Packets With Rain (%)": "rain_percent",
    "Raining": "raining",
    "Packets in Average at MET": "met_packets",
}

#: per-record text columns -> canonical name
TEXT_COLUMNS: dict[str, str] = {"Info. Flags": "info_flags", "Status Flags": "status_flags"}

#: columns whose value is an identifier, never a missing-value code
_NO_SENTINEL = {"Reference", "Timestamp (s)"}

_TIME_COLUMN = "Time and Date"
_TIME_FORMATS = ("%d.%m.%Y %H:%M:%S", "%d/%m/%Y %H:%M:%S", "%d.%m.%Y %H:%M")
_HEIGHT_RE = re.compile(r"^(?P<prefix>.+) at (?P<height>\d+(?:[.,]\d+)?)m$")
_SYNC_RE = re.compile(r"UTC\s*([+-])\s*(\d+(?:[.,]\d+)?)\s*h", re.IGNORECASE)
_NUMBER_RE = re.compile(r"(\d+(?:[.,]\d+)?)")
_HEADER_LINES = 2


#: records averaged over at least this long (s) take the narrower ranges of means
#: (:data:`cwproc.io.ranges.KIND_RANGES` ``"wind_record"``); 1-s ZephIR records and the
#: single lines of sight of a WindCube ``.rtd`` keep the ranges of single values
MEAN_RECORD_MIN_S = 60.0


def with_range_screen(ds: xr.Dataset) -> xr.Dataset:
    """Impossible values of a wind record and infinite ones as missing, reported.

    Records averaged over :data:`MEAN_RECORD_MIN_S` or longer (``averaging_interval_s``)
    are screened with the ranges of means (:func:`cwproc.io.ranges.ranges_for`
    ``"wind_record"``: w within +-10 m s-1 over ten minutes); faster records (1-s ZephIR,
    ``.rtd`` lines of sight, no stated interval) with those of single values.
    """
    interval = ds.attrs.get("averaging_interval_s")
    try:
        mean = interval is not None and float(interval) >= MEAN_RECORD_MIN_S
    except (TypeError, ValueError):
        mean = False
    kind = "wind_record" if mean else None
    screened, counts = screen_physical_range(ds, kind)
    if counts:
        screened.attrs["warnings"] = [
            *ds.attrs.get("warnings", []),
            *range_warnings(counts, kind),
        ]
    return screened


def read_latin1_lines(path: Path) -> list[str]:
    """The lines of a Latin-1 text file (CRLF, LF or CR-only ends), the last one possibly empty.

    Raises
    ------
    InputFileError
        The file cannot be read or holds only white space.
    """
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    if not raw.strip():
        raise InputFileError(path, "file is empty")
    return raw.decode("latin-1").replace("\r\n", "\n").replace("\r", "\n").split("\n")


def increasing_utc_times(
    path: Path, stamps: np.ndarray, offset_h: float, first_line: int
) -> np.ndarray:
    """Stamps of ``offset_h`` hours from UTC as UTC; each must follow the previous one.

    Raises
    ------
    InputFileError
        A stamp does not increase over the previous record (line named).
    """
    times = stamps - np.timedelta64(round(offset_h * 3600e9), "ns")
    back = np.flatnonzero(np.diff(times) <= np.timedelta64(0, "ns"))
    if back.size:
        raise InputFileError(
            path,
            "time stamp does not increase over the previous record",
            first_line + int(back[0]) + 1,
        )
    return times


def wind_record_dataset(
    data_vars: dict[str, Any], times: np.ndarray, heights: np.ndarray, attrs: dict[str, Any]
) -> xr.Dataset:
    """The canonical wind-record dataset: impossible values screened, attributes attached."""
    ds = xr.Dataset(data_vars, coords={"time": times, "height": heights}, attrs=attrs)
    return with_canonical_attrs(with_range_screen(ds), "wind_record")


def _number(text: str) -> float:
    return float(text.replace(",", "."))


def check_reader_options(
    fmt: str, utc_offset_hours: object, unknown: dict[str, Any]
) -> float | None:
    """Validate the ``[reader.<fmt>]`` options of the wind-record readers.

    Returns
    -------
    float or None
        ``utc_offset_hours`` as a float (h), or None when not given.

    Raises
    ------
    ConfigError
        An unknown option, or an offset that is not a number in [-14, 14] h.
    """
    source = f"[reader.{fmt}]"
    if unknown:
        key = sorted(unknown)[0]
        raise ConfigError(source, key, "unknown reader option; known: utc_offset_hours")
    if utc_offset_hours is None:
        return None
    if isinstance(utc_offset_hours, bool) or not isinstance(utc_offset_hours, int | float):
        raise ConfigError(source, "utc_offset_hours", f"must be a number, got {utc_offset_hours!r}")
    if not -14.0 <= float(utc_offset_hours) <= 14.0:
        raise ConfigError(source, "utc_offset_hours", "must be in [-14, 14] hours")
    return float(utc_offset_hours)


def parse_metadata_line(path: str | os.PathLike, line: str) -> dict[str, Any]:
    """Attributes from line 1 of a ZephIR export.

    Parameters
    ----------
    path : path
        The file (for error messages).
    line : str
        The first line.

    Returns
    -------
    dict
        ``system_id``, ``utc_offset_h`` (None when the line has no "Time sync"),
        ``time_stamp_position`` ("start", "end" or "unknown"), ``reference_height_m``,
        ``window_height_m`` and the software versions, where present.

    Raises
    ------
    InputFileError
        Line 1 is not ZephIR metadata.
    """
    items = [item.strip() for item in line.split(";")]
    if not any(i.startswith(("CSV Converter", "Unit:", "Time sync")) for i in items):
        raise InputFileError(
            path, "line 1 is not ZephIR metadata (no 'CSV Converter', 'Unit:' or 'Time sync')", 1
        )
    attrs: dict[str, Any] = {"utc_offset_h": None, "time_stamp_position": "unknown"}
    for item in items:
        key, sep, value = item.partition(":")
        value = value.strip()
        low = item.lower()
        if sep and key == "Unit":
            attrs["system_id"] = value
        elif sep and key == "Time sync":
            m = _SYNC_RE.search(value)
            if m is None:
                raise InputFileError(path, f"cannot read the time offset in {item!r}", 1)
            attrs["utc_offset_h"] = (1 if m.group(1) == "+" else -1) * _number(m.group(2))
        elif sep and key in ("CSV Converter", "Filter", "Averager", "File system version"):
            attrs[key.lower().replace(" version", "").replace(" ", "_") + "_version"] = value
        elif "time stamps indicate" in low:
            if "beginning" in low or "start" in low:
                attrs["time_stamp_position"] = "start"
            elif "end" in low:
                attrs["time_stamp_position"] = "end"
        elif "fixed reference measurement" in low:
            m = _NUMBER_RE.search(item)
            if m:
                attrs["reference_height_m"] = _number(m.group(1))
        elif "window height" in low and sep:
            m = _NUMBER_RE.search(value)
            if m:
                attrs["window_height_m"] = _number(m.group(1))
    return attrs


def parse_header_line(path: str | os.PathLike, line: str) -> dict[str, Any]:
    """Column layout from line 2: height groups, record columns, the checksum column.

    Returns
    -------
    dict
        ``names`` (list of column names, the checksum blob cut off), ``heights``
        (list of floats in file order), ``height_columns`` ({(name, height): index}),
        ``record_columns`` ({name: index}), ``ignored`` (names not used).

    Raises
    ------
    InputFileError
        No ``Time and Date`` or ``Checksum`` column, or a height lacking one of its 8
        columns.
    """
    names = line.split(";")
    if _TIME_COLUMN not in names:
        raise InputFileError(
            path,
            f"header line has no {_TIME_COLUMN!r} column (is the separator ';'?)",
            2,
        )
    if not names[-1].startswith("Checksum"):
        raise InputFileError(path, "header line does not end with the 'Checksum' column", 2)
    names[-1] = "Checksum"
    heights: list[float] = []
    height_columns: dict[tuple[str, float], int] = {}
    record_columns: dict[str, int] = {}
    ignored = []
    for i, name in enumerate(names):
        m = _HEIGHT_RE.match(name)
        if name in RECORD_COLUMNS or name in TEXT_COLUMNS or name in (_TIME_COLUMN, "GPS"):
            record_columns[name] = i
        elif m and m.group("prefix") in HEIGHT_COLUMNS:
            h = _number(m.group("height"))
            if h not in heights:
                heights.append(h)
            key = (HEIGHT_COLUMNS[m.group("prefix")], h)
            if key in height_columns:
                raise InputFileError(path, f"column {name!r} appears twice", 2)
            height_columns[key] = i
        elif name != "Checksum":
            ignored.append(name)
    if not heights:
        raise InputFileError(path, "header line has no 'Horizontal Wind Speed ... at <H>m'", 2)
    for h in heights:
        missing = [p for p, v in HEIGHT_COLUMNS.items() if (v, h) not in height_columns]
        if missing:
            raise InputFileError(
                path, f"height {h:g} m lacks the column(s) {', '.join(missing)}", 2
            )
    return {
        "names": names,
        "heights": heights,
        "height_columns": height_columns,
        "record_columns": record_columns,
        "ignored": ignored,
    }


def _to_numbers(path: str | os.PathLike, table: pd.DataFrame, first_line: int) -> np.ndarray:
    """Decimal-comma strings -> floats (empty fields NaN); a non-number is an error."""
    text = table.apply(lambda col: col.str.strip().str.replace(",", ".", regex=False))
    values = text.apply(pd.to_numeric, errors="coerce")
    bad = values.isna().to_numpy() & (text.to_numpy() != "")
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise InputFileError(
            path,
            f"column {table.columns[col]!r}: {table.iat[row, col]!r} is not a number",
            first_line + int(row),
        )
    # an empty field is a missing value (NaN): one empty cell refused the whole day
    return values.to_numpy(dtype=float)


def _parse_times(path: str | os.PathLike, stamps: pd.Series, first_line: int) -> np.ndarray:
    stamps = stamps.str.strip()
    for fmt in _TIME_FORMATS:
        times = pd.to_datetime(stamps, format=fmt, errors="coerce")
        if not times.isna().any():
            return check_times(path, times.to_numpy(), first_line, written=stamps.to_numpy())
    times = pd.to_datetime(stamps, format=_TIME_FORMATS[0], errors="coerce")
    row = int(np.flatnonzero(times.isna().to_numpy())[0])
    raise InputFileError(
        path, f"time {stamps.iloc[row]!r} is not dd.mm.yyyy HH:MM:SS", first_line + row
    )


def _check_field_counts(path: str | os.PathLike, lines: list[str], n_columns: int) -> None:
    """Every record must have the header's number of ``;``-separated fields."""
    counts = pd.Series(lines, dtype=object).str.count(";").to_numpy() + 1
    bad = np.flatnonzero(counts != n_columns)
    if bad.size:
        i = int(bad[0])
        problem = f"record has {counts[i]} fields, expected {n_columns}"
        if i == len(lines) - 1 and counts[i] < n_columns:
            problem += " (file truncated?)"
        raise InputFileError(path, problem, _HEADER_LINES + 1 + i)


def _read_columns(text: str, columns: list[int], *, numeric: bool) -> pd.DataFrame:
    """Selected columns of the records with the C parser (no quoting, no NA guessing)."""
    options: dict[str, Any] = {"dtype": np.float64, "decimal": ","} if numeric else {"dtype": str}
    return pd.read_csv(
        io.StringIO(text),
        sep=";",
        header=None,
        usecols=columns,
        quoting=csv.QUOTE_NONE,
        keep_default_na=False,
        na_values=[],
        na_filter=numeric,
        engine="c",
        **options,
    )[columns]


def _numeric_values(
    path: str | os.PathLike, text: str, columns: list[int], names: list[str], first_line: int
) -> np.ndarray:
    """The numeric columns as floats (empty: NaN); a field that is no number is an error."""
    try:
        values = _read_columns(text, columns, numeric=True).to_numpy(dtype=float)
    except (ValueError, pd.errors.ParserError):
        # slow path: finds the offending line (or accepts '.' decimals the fast one refused)
        table = _read_columns(text, columns, numeric=False)
        table.columns = [names[c] for c in columns]
        values = _to_numbers(path, table, first_line)
    return values  # inf: set to missing and counted by the range screen, as every reader


def _variant(names: list[str], path: str | os.PathLike) -> tuple[str, float]:
    if "Raining" in names or Path(path).name.startswith("Wind_"):
        return "1s", 1.0
    return "10min", 600.0


def read_zephir_csv(
    path: str | os.PathLike, *, utc_offset_hours: float | None = None, **options: Any
) -> xr.Dataset:
    """Read a ZephIR Waltz CSV export (10-min or 1-s) into a wind-record dataset.

    Parameters
    ----------
    path : path
        The ``*.ZPH.csv`` file.
    utc_offset_hours : float, optional
        Offset of the stamps from UTC (h) when the file has no "Time sync" item (or to
        override it); ``[reader.zephir_csv] utc_offset_hours``.
    **options
        Any other ``[reader.zephir_csv]`` key is a :class:`ConfigError`.

    Returns
    -------
    xarray.Dataset
        dims ``(time, height)``; coords ``time`` (UTC, as stamped: see
        ``attrs["time_stamp_position"]``), ``height`` (m, ascending, as labelled in the
        column names); per height ``wind_speed``, ``wind_direction``, ``w``,
        ``wind_speed_min``, ``wind_speed_max``, ``wind_speed_std``,
        ``turbulence_intensity``, ``packets``; per time the pod and met columns
        (``air_temperature``, ``air_pressure``, ``relative_humidity``, ``tilt``,
        ``bearing``, ``met_wind_speed``, ``met_wind_direction``, ``rain_percent`` or
        ``raining``, ``latitude``, ``longitude``, ...). attrs: ``averaging_interval_s``,
        ``time_stamp_position``, ``utc_offset_applied_h``, ``system_id``,
        ``reference_height_m``, ``window_height_m``, ``n_missing_9999``,
        ``n_missing_9998``, ``instrument_kind`` "cw", ``homodyne`` 1.

    Raises
    ------
    ConfigError
        Unknown or invalid reader option.
    InputFileError
        Empty, not a ZephIR export, wrong separator, a height without its 8 columns, a
        record with the wrong number of fields (truncated), a bad number or time.
    """
    utc_offset_hours = check_reader_options("zephir_csv", utc_offset_hours, options)
    path = Path(path)
    lines = read_latin1_lines(path)
    if lines[-1] == "":
        lines.pop()
    elif len(lines) > _HEADER_LINES:
        # exports end with a newline; without it the last record (its checksum blob
        # holds no ';') may be cut anywhere
        raise InputFileError(path, "last record has no end of line (file truncated?)", len(lines))
    meta = parse_metadata_line(path, lines[0])
    if len(lines) < _HEADER_LINES:
        raise InputFileError(path, "no column-header line (file truncated?)", 1)
    layout = parse_header_line(path, lines[1])
    data_lines = _data_lines(path, lines, len(layout["names"]))
    text = "\n".join(data_lines)
    first = _HEADER_LINES + 1
    record_cols = layout["record_columns"]
    text_names = [c for c in (_TIME_COLUMN, *TEXT_COLUMNS, "GPS") if c in record_cols]
    table = _read_columns(text, [record_cols[c] for c in text_names], numeric=False)
    table.columns = text_names

    offset = meta["utc_offset_h"] if utc_offset_hours is None else float(utc_offset_hours)
    times = _parse_times(path, table[_TIME_COLUMN], first)
    times = increasing_utc_times(path, times, offset or 0.0, first)
    data_vars, n9999, n9998 = _record_variables(path, text, layout, table)
    attrs = _attrs(path, meta, layout, times, utc_offset_hours)
    attrs.update(n_missing_9999=n9999, n_missing_9998=n9998)
    heights = np.array(sorted(layout["heights"]), dtype=float)
    return wind_record_dataset(data_vars, times, heights, attrs)


def _data_lines(path: Path, lines: list[str], n_columns: int) -> list[str]:
    """The record lines after the two header lines, checked for blanks and field counts."""
    data_lines = lines[_HEADER_LINES:]
    if not data_lines:
        raise InputFileError(path, "no data records after the header", _HEADER_LINES)
    blank = [i for i, s in enumerate(data_lines) if not s.strip()]
    if blank:
        raise InputFileError(path, "blank line among the records", _HEADER_LINES + 1 + blank[0])
    _check_field_counts(path, data_lines, n_columns)
    return data_lines


def _record_variables(
    path: Path, text: str, layout: dict[str, Any], table: pd.DataFrame
) -> tuple[dict[str, Any], int, int]:
    """The variables of the records, missing-value codes as NaN, and the codes' counts.

    Returns
    -------
    data_vars : dict
        ``name -> (dims, values)``: per height (``time``, ``height``) and per record.
    n9999, n9998 : int
        How many ``9999`` and ``9998`` codes were replaced.
    """
    names: list[str] = layout["names"]
    record_cols = layout["record_columns"]
    first = _HEADER_LINES + 1
    numeric_names = [c for c in names if c in RECORD_COLUMNS and c in record_cols]
    height_items = sorted(layout["height_columns"].items(), key=lambda kv: kv[1])
    height_names = [names[i] for _, i in height_items]
    numeric_idx = [record_cols[c] for c in numeric_names] + [i for _, i in height_items]
    values = _numeric_values(path, text, numeric_idx, names, first)
    check = np.array([c not in _NO_SENTINEL for c in numeric_names + height_names])
    n9999 = int(np.sum((values == 9999.0) & check))
    n9998 = int(np.sum((values == 9998.0) & check))
    sentinel_mask = ((values == 9999.0) | (values == 9998.0)) & check
    values = np.where(sentinel_mask, np.nan, values)
    col_index = {c: j for j, c in enumerate(numeric_names + height_names)}

    heights = sorted(layout["heights"])
    data_vars: dict[str, Any] = {}
    for var in HEIGHT_COLUMNS.values():
        cols = [col_index[names[layout["height_columns"][(var, h)]]] for h in heights]
        data_vars[var] = (("time", "height"), values[:, cols])
    for col in numeric_names:
        data_vars[RECORD_COLUMNS[col]] = (("time",), values[:, col_index[col]])
    for col, var in TEXT_COLUMNS.items():
        if col in record_cols:
            data_vars[var] = (("time",), table[col].str.strip().to_numpy(dtype=str))
    if "GPS" in record_cols:
        lat, lon = _parse_gps(path, table["GPS"], first)
        data_vars["latitude"] = (("time",), lat)
        data_vars["longitude"] = (("time",), lon)
    return data_vars, n9999, n9998


def _attrs(
    path: Path,
    meta: dict[str, Any],
    layout: dict[str, Any],
    times: np.ndarray,
    utc_offset_hours: float | None,
) -> dict[str, Any]:
    """Dataset attributes: instrument, file variant, averaging interval, time sync."""
    variant, default_interval = _variant(layout["names"], path)
    steps = np.diff(times).astype("timedelta64[ns]").astype(float) / 1e9
    steps = steps[steps > 0]
    interval = float(np.median(steps)) if steps.size else default_interval
    offset = meta["utc_offset_h"] if utc_offset_hours is None else float(utc_offset_hours)
    attrs: dict[str, Any] = {
        "instrument": "ZephIR 300",
        "instrument_kind": "cw",
        "format": "zephir_csv",
        "file_variant": variant,
        "source_files": [path.name],
        "homodyne": 1,
        "cone_half_angle_deg": 30.0,
        "averaging_interval_s": interval,
        "time_stamp_position": meta["time_stamp_position"],
        "utc_offset_applied_h": float(offset or 0.0),
        "time_sync": "from file" if meta["utc_offset_h"] is not None else "absent",
        "checksum_checked": 0,
        "checksum_note": "the Checksum field is an undocumented encoding, not checkable",
        "height_datum": "as labelled in the column names (above ground)",
    }
    if utc_offset_hours is not None:
        attrs["time_sync"] = "reader option utc_offset_hours"
    for key in ("system_id", "reference_height_m", "window_height_m"):
        if key in meta:
            attrs[key] = meta[key]
    for key, value in meta.items():
        if key.endswith("_version"):
            attrs[key] = value
    if layout["ignored"]:
        attrs["ignored_columns"] = list(layout["ignored"])
    return attrs


def _parse_gps(
    path: str | os.PathLike, gps: pd.Series, first_line: int
) -> tuple[np.ndarray, np.ndarray]:
    """``"51,31546 9,16535"`` -> latitude, longitude (deg); parsed once per distinct value."""
    codes, uniques = pd.factorize(gps)
    lat_u = np.full(len(uniques), np.nan)
    lon_u = np.full(len(uniques), np.nan)
    for k, text in enumerate(uniques):  # a handful of distinct positions per file
        fields = str(text).replace(",", ".").split()
        if len(fields) == 2:
            try:
                lat_u[k], lon_u[k] = float(fields[0]), float(fields[1])
            except ValueError:
                pass
    bad = np.flatnonzero(~np.isfinite(lat_u[codes]) | ~np.isfinite(lon_u[codes]))
    if bad.size:
        row = int(bad[0])
        raise InputFileError(
            path, f"GPS field {gps.iloc[row]!r} is not 'lat lon'", first_line + row
        )
    return lat_u[codes], lon_u[codes]
