"""Meteo-2 ultrasonic weather station (IAO SB RAS, Tomsk, ~10.7 Hz) text logs.

No real Meteo-2 file or format description is public (FORMATS.md section 4.6), so
cwproc defines the text layout below, writes it (:func:`write_meteo2`, used by the
simulator) and reads it (:func:`read_meteo2`), with every layout choice configurable
in ``[reader.meteo2]`` (preset ``configs/meteo2.toml``) so that a real export can be
read by configuration once one is obtained.

Layout (``docs/sonic.md``)::

    # cwproc meteo2 v1
    # instrument: Meteo-2 ultrasonic weather station (IAO SB RAS)
    # station: Tomsk
    # time: UTC
    time,u,v,w,t,diag
    2014-06-01T00:00:00.000,1.234,-0.567,0.089,12.34,0

* first line ``# cwproc meteo2`` (what :func:`cwproc.io.sniff_format` recognises);
  further ``# key: value`` lines become dataset attributes;
* one header row of column names, then one sample per line, ``,``-separated;
* ``time``: ISO 8601 (``T`` or space, any number of fractional digits) in UTC unless
  ``utc_offset_hours`` says otherwise; or ``time_format = "epoch"``: seconds since
  1970-01-01 UTC;
* ``u``, ``v``, ``w``: wind components (m s-1) in the instrument frame (x, y, z axes
  of the sonic array); ``t``: sonic temperature (degC); ``diag``: status word, 0 good;
* missing values: empty field, ``NaN`` or ``NAN``.

The sample rate is measured from the time stamps (never assumed): Meteo-2 samples at
about 10.7 Hz, Gladkikh et al. (2014), section 1. The text helpers shared by the sonic
readers are :mod:`cwproc.io.sonic_text`; the dataset they build,
:mod:`cwproc.io.sonic_samples`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import CwprocError, InputFileError
from cwproc.io.netcdf import write_bytes_atomic
from cwproc.io.sonic_samples import SONIC_FIELDS, SPIKE_THRESHOLD, sonic_dataset
from cwproc.io.sonic_text import (
    blank_row,
    check_options,
    column_map,
    numeric_column,
    option_number,
    parse_times,
    read_table,
    read_text,
)
from cwproc.io.timecheck import epoch_seconds_to_times

INSTRUMENT = "Meteo-2 ultrasonic weather station (IAO SB RAS)"


MAGIC = "# cwproc meteo2"


#: canonical name -> column name in the file (default layout)
DEFAULT_COLUMNS: dict[str, str] = {
    "time": "time",
    **dict(zip(SONIC_FIELDS, ("u", "v", "w", "t", "diag"), strict=True)),
}


READER_OPTIONS = {
    "delimiter",
    "columns",
    "time_format",
    "utc_offset_hours",
    "comment",
    "frame",
    "spike_threshold",
}


def read_meteo2(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read a Meteo-2 text log (cwproc layout, module docstring) into a sonic dataset.

    Parameters
    ----------
    path : path
    delimiter : str, optional
        Field separator (default ``","``).
    columns : dict, optional
        Canonical name (``time``, ``u``, ``v``, ``w``, ``temperature``,
        ``diagnostic``) -> column name in the file; merged over :data:`DEFAULT_COLUMNS`.
    time_format : {"iso", "epoch"}, optional
        ISO 8601 stamps (default) or seconds since 1970-01-01.
    utc_offset_hours : float, optional
        Offset of the logger clock from UTC (h): UTC = stamp - offset. Default 0.
    comment : str, optional
        Prefix of header comment lines (default ``"#"``).
    frame : str, optional
        Description of the (u, v, w) frame (attr).
    spike_threshold : float, optional
        Spike threshold (robust std), default 6.

    Returns
    -------
    xarray.Dataset
        Canonical sonic dataset (``sampling_rate_hz`` measured, about 10.7 Hz).

    Raises
    ------
    InputFileError
        File, line and problem.
    """
    settings = meteo2_options(path, options)
    lines = read_text(path).splitlines(keepends=True)
    header_attrs, n_comment = header_comments(lines, settings.comment)
    if n_comment >= len(lines):
        raise InputFileError(path, "no column header line", n_comment + 1)
    notes: list[str] = []
    if _cut_last_line(lines, n_comment, settings.delimiter):
        notes.append(
            f"line {len(lines)}: last line cut short (no end of line, fewer fields than "
            "the header; a file still being written?): dropped"
        )
        lines = lines[:-1]
    frame = _data_table(path, lines, n_comment, settings)
    first = n_comment + 2  # the first data line (1-based), after the column header
    cols = settings.columns
    vals = {k: numeric_column(path, frame, cols[k], first) for k in ("u", "v", "w")}
    return sonic_dataset(
        path,
        _stamps(path, frame, settings, first),
        vals,
        _optional_column(path, frame, cols["temperature"], first, np.nan),
        _optional_column(path, frame, cols["diagnostic"], first, 0.0),
        instrument=INSTRUMENT,
        frame=settings.frame,
        attrs=header_attrs,
        warnings=notes,
        spike_threshold=settings.spike_threshold,
    )


@dataclass(frozen=True)
class Meteo2Options:
    """The ``[reader.meteo2]`` options of :func:`read_meteo2`, checked."""

    #: field separator
    delimiter: str
    #: prefix of the header comment lines
    comment: str
    #: canonical name -> column name in the file
    columns: dict[str, str]
    #: ``"iso"`` (ISO 8601 stamps) or ``"epoch"`` (seconds since 1970-01-01)
    time_format: str
    #: offset of the logger clock from UTC (h): UTC = stamp - offset
    utc_offset_hours: float
    #: spike threshold (robust std)
    spike_threshold: float
    #: description of the (u, v, w) frame
    frame: str


def meteo2_options(path: str | os.PathLike, options: Mapping[str, Any]) -> Meteo2Options:
    """The reader options of :func:`read_meteo2` checked, with their defaults.

    Raises
    ------
    InputFileError
        An unknown option, or an option of the wrong type or value (names the file).
    """
    check_options(path, options, READER_OPTIONS)
    columns = column_map(path, options, DEFAULT_COLUMNS)
    time_format = options.get("time_format", "iso")
    if time_format not in ("iso", "epoch"):
        raise InputFileError(path, "reader option 'time_format' must be 'iso' or 'epoch'")
    return Meteo2Options(
        delimiter=str(options.get("delimiter", ",")),
        comment=str(options.get("comment", "#")),
        columns=columns,
        time_format=time_format,
        utc_offset_hours=option_number(path, options, "utc_offset_hours", 0.0),
        spike_threshold=option_number(path, options, "spike_threshold", SPIKE_THRESHOLD),
        frame=str(options.get("frame", "instrument x, y, z axes of the Meteo-2 array")),
    )


def header_comments(lines: Sequence[str], comment: str) -> tuple[dict[str, str], int]:
    """The ``# key: value`` lines at the top of a file, as ``meteo2_<key>`` attributes,
    and the number of comment lines (the column header follows them)."""
    attrs: dict[str, str] = {}
    n_comment = 0
    for line in lines:
        if not line.startswith(comment):
            break
        body = line[len(comment) :].strip()
        key, sep, value = body.partition(":")
        if sep and key.strip() and " " not in key.strip():
            attrs[f"meteo2_{key.strip()}"] = value.strip()
        n_comment += 1
    return attrs, n_comment


def _data_table(
    path: str | os.PathLike, lines: Sequence[str], n_comment: int, settings: Meteo2Options
) -> pd.DataFrame:
    """The column header and data lines as a table, its needed columns present and no
    data line blank."""
    header_line = n_comment + 1
    frame = read_table(
        path, "".join(lines[n_comment:]), delimiter=settings.delimiter, skip=n_comment, names=None
    )
    frame.columns = [str(c).strip() for c in frame.columns]
    cols = settings.columns
    for name in ("time", "u", "v", "w"):
        if cols[name] not in frame.columns:
            raise InputFileError(
                path,
                f"no column {cols[name]!r} ({name}) in the header; found "
                f"{', '.join(frame.columns)}",
                header_line,
            )
    if len(frame) == 0:
        raise InputFileError(path, "no data records", header_line + 1)
    blank_row(path, frame, header_line + 1)
    return frame


def _stamps(
    path: str | os.PathLike, frame: pd.DataFrame, settings: Meteo2Options, first: int
) -> np.ndarray:
    """UTC time of each sample (datetime64[ns]): ISO or epoch stamps less the clock offset."""
    column = settings.columns["time"]
    if settings.time_format == "iso":
        times = parse_times(path, frame[column], first)
    else:
        secs = numeric_column(path, frame, column, first)
        bad = np.flatnonzero(~np.isfinite(secs))
        if bad.size:
            raise InputFileError(path, "missing time stamp", first + int(bad[0]))
        whole = np.floor(secs)
        times = epoch_seconds_to_times(
            path, whole, np.rint((secs - whole) * 1e9), np.datetime64(0, "ns"), first
        )
    return times - np.timedelta64(round(settings.utc_offset_hours * 3600e9), "ns")


def _optional_column(
    path: str | os.PathLike, frame: pd.DataFrame, column: str, first: int, fill: float
) -> np.ndarray:
    """A numeric column, or ``fill`` for every sample when the file has no such column."""
    if column in frame.columns:
        return numeric_column(path, frame, column, first)
    return np.full(len(frame), fill)


def _cut_last_line(lines: list[str], n_comment: int, delimiter: str) -> bool:
    """Whether the last data line was cut while being written: no end of line and fewer
    fields than the column header (a cut ``2024-06-01`` stamp read as midnight)."""
    if len(lines) <= n_comment + 2 or lines[-1].endswith(("\n", "\r")):
        return False
    return lines[-1].count(delimiter) < lines[n_comment].count(delimiter)


def write_meteo2(
    ds: xr.Dataset,
    path: str | os.PathLike,
    *,
    station: str = "",
    decimals: int = 3,
) -> None:
    """Write a sonic dataset in the cwproc Meteo-2 layout (module docstring).

    Parameters
    ----------
    ds : xarray.Dataset
        ``time`` (UTC), ``u``, ``v``, ``w`` (m s-1), optional ``temperature`` (degC)
        and ``diagnostic``.
    path : path
        Output file, written through an unpredictable temporary in its folder (mode from
        the umask), then renamed: a killed run leaves no half-written file, and the stale
        temporaries of an earlier killed run are removed.
    station : str
        Written to the ``# station:`` header line.
    decimals : int
        Decimal places of the wind components and temperature.
    """
    n = ds.sizes["time"]
    t = np.datetime_as_string(ds["time"].values.astype("datetime64[ms]"), unit="ms")
    frame = pd.DataFrame(
        {
            "time": t,
            "u": ds["u"].values,
            "v": ds["v"].values,
            "w": ds["w"].values,
            "t": ds["temperature"].values if "temperature" in ds else np.full(n, np.nan),
            "diag": ds["diagnostic"].values if "diagnostic" in ds else np.zeros(n, int),
        }
    )
    head = (
        f"{MAGIC} v1\n# instrument: {INSTRUMENT}\n# station: {station}\n# time: UTC\n"
        "# units: u v w m/s, t degC, diag 0=good\n"
    )
    text = head + frame.to_csv(index=False, float_format=f"%.{decimals}f", na_rep="NaN")
    path = Path(path)
    try:
        write_bytes_atomic(path, text.encode("utf-8"))
    except OSError as exc:
        raise CwprocError(f"write_meteo2 {path}: cannot write: {exc.strerror or exc}") from None
