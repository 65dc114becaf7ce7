"""Leosphere WindCube ``.rtd`` real-time files (one line per line of sight) -> beam record.

A WindCube profiler points its beam in turn at four azimuths on a cone of half-angle
``ScanAngle`` from the zenith (0, 90, 180, 270 deg, the ``Position`` column) and, from
v2 on, straight up (``V``), about one second per line of sight (Doppler beam swinging,
DBS). The ``.rtd`` file holds every line of sight: time, position and, per altitude, the
radial velocity, its dispersion (v2/v2.1) or the spectral width (v1) and the CNR.

Three layouts (``real_data/FORMATS.md`` §3 and the .rtd section):

* **v2 and v2.1** (``HeaderSize=N``, software 1.x/2.x and ``WF 2.x``) [seen, WF 2.2.1]:
  ``Timestamp`` (``yyyy/mm/dd HH:MM:SS.ss``, UTC), ``Position``, ``Temperature``,
  ``Wiper Count``, then per altitude ``<H>m CNR (dB)``, ``<H>m Radial Wind Speed
  (m/s)``, ``<H>m Radial Wind Speed Dispersion (m/s)``, ``<H>m Wind Speed (m/s)``,
  ``<H>m Wind Direction (°)``, ``<H>m X-wind (m/s)``, ``<H>m Y-wind (m/s)``,
  ``<H>m Z-wind (m/s)`` and an empty column. WF 2.x writes ``NA`` for the settings it
  does not report, ``ScanAngle`` included, and ``999.00`` for a missing temperature.
* **v1** (``HeaderLength=N``, software 3.x) [inferred, no real file]: ``Date``
  (``dd/mm/yyyy HH:MM:SS.ss``), ``Position`` (azimuth, deg), ``Temperature``,
  ``Wiper`` (``On``/``Off``), then eight columns per altitude of which the first is the
  CNR, the second the spectral width and the fourth the radial velocity: the column
  offsets of e-WindLidar/Lidaco's ``Windcubev1`` reader, the only public description
  found. The block is matched by position to ``Altitudes(m)=``; the other five columns
  are not read.

The radial velocity is positive away from the lidar: on the vertical beam it equals the
file's ``Z-wind`` (upward), e.g. 6.28 and 6.278 m/s on line 43 of the real file.

The beams' elevation is ``90 - ScanAngle``; a header without a scan angle (``NA``)
takes the reader option ``scan_angle_deg`` or, without it, the nominal 28 deg of the
WindCube v2/v2.1 (``attrs["scan_angle_source"]`` says which, and a warning is kept).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import ConfigError, InputFileError
from cwproc.io.timecheck import check_times
from cwproc.io.windcube import (
    MISSING_FIELDS,
    MISSING_HEADER_VALUES,
    header_altitudes,
    header_value,
    parse_windcube_header,
    record_table,
    utc_offset,
)
from cwproc.io.zephir import increasing_utc_times, read_latin1_lines, wind_record_dataset

#: nominal cone half-angle from the zenith of the WindCube v2/v2.1 (deg), used when the
#: header says ``ScanAngle (°)=NA`` and no reader option gives it
NOMINAL_SCAN_ANGLE_DEG = 28.0

#: v2/v2.1 per-altitude column suffix -> canonical name
LONG_BEAM_COLUMNS: dict[str, str] = {
    "CNR (dB)": "cnr",
    "Radial Wind Speed (m/s)": "radial_velocity",
    "Radial Wind Speed Dispersion (m/s)": "radial_velocity_dispersion",
    "Wind Speed (m/s)": "wind_speed",
    "Wind Direction (°)": "wind_direction",
    "X-wind (m/s)": "u_instrument",
    "Y-wind (m/s)": "v_instrument",
    "Z-wind (m/s)": "w",
}
#: v1: offset in the 8-column altitude block -> canonical name (Lidaco's offsets)
V1_BLOCK_OFFSETS: dict[int, str] = {0: "cnr", 1: "spectral_broadening", 3: "radial_velocity"}
V1_BLOCK_SIZE = 8

_LONG_RE = re.compile(r"^(?P<height>\d+(?:\.\d+)?)m (?P<suffix>.+)$")
_TIME_FORMATS = {"Timestamp": "%Y/%m/%d %H:%M:%S.%f", "Date": "%d/%m/%Y %H:%M:%S.%f"}
_RECORD_NAMES = ("Position", "Temperature")


def is_rtd_column_line(line: str) -> bool:
    """Whether a column-header line is that of an ``.rtd`` file (``Position`` second)."""
    names = line.split("\t")
    return len(names) > 2 and names[0].strip() in _TIME_FORMATS and names[1].strip() == "Position"


def _check_options(scan_angle_deg: object, utc_offset_hours: object, unknown: dict) -> None:
    source = "[reader.windcube_rtd]"
    if unknown:
        raise ConfigError(
            source,
            sorted(unknown)[0],
            "unknown reader option; known: scan_angle_deg, utc_offset_hours",
        )
    for key, value, low, high in (
        ("scan_angle_deg", scan_angle_deg, 1.0, 60.0),
        ("utc_offset_hours", utc_offset_hours, -14.0, 14.0),
    ):
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(source, key, f"must be a number, got {value!r}")
        if not low <= float(value) <= high:
            raise ConfigError(source, key, f"must be in [{low:g}, {high:g}]")


def read_windcube_rtd(
    path: str | os.PathLike,
    *,
    scan_angle_deg: float | None = None,
    utc_offset_hours: float | None = None,
    **options: Any,
) -> xr.Dataset:
    """Read a WindCube ``.rtd`` real-time file (v1, v2 or v2.1 layout) into a beam record.

    Parameters
    ----------
    path : path
        The ``.rtd`` file.
    scan_angle_deg : float, optional
        Cone half-angle from the zenith (deg), overriding the header (needed when the
        header says ``NA``; default then 28 deg); ``[reader.windcube_rtd]``.
    utc_offset_hours : float, optional
        Offset of the stamps from UTC (h), overriding ``timezone=``.
    **options
        Any other key is a :class:`cwproc.errors.ConfigError`.

    Returns
    -------
    xarray.Dataset
        dims ``(time, height)``, one ``time`` per line of sight (UTC, as stamped);
        per line ``beam`` ("0", "90", "180", "270", "V"), ``beam_azimuth`` (deg,
        clockwise from north; 0 for V), ``beam_elevation`` (deg), ``internal_temperature``,
        ``wiper_count`` or ``wiper_on``; per altitude ``radial_velocity`` (m s-1,
        positive away), ``cnr`` (dB), ``radial_velocity_dispersion`` (v2) or
        ``spectral_broadening`` (v1), and the instrument's own per-line reconstruction
        where written (``wind_speed``, ``wind_direction``, ``u_instrument``,
        ``v_instrument``, ``w``). attrs: ``format`` "windcube_rtd", ``instrument``
        (model and software), ``rtd_layout``, ``scan_angle_deg``,
        ``scan_angle_source``, ``n_missing``.

    Raises
    ------
    InputFileError
        Not an ``.rtd`` file, a column block incomplete, a record with the wrong number
        of fields, a bad number or time, stamps that do not increase.
    """
    _check_options(scan_angle_deg, utc_offset_hours, options)
    path = Path(path)
    lines = read_latin1_lines(path)
    if lines[-1] == "":
        lines.pop()
    column_line, items = parse_windcube_header(path, lines)
    names = _column_names(path, lines[column_line - 1], column_line)
    layout = "v1" if names[0].strip() == "Date" else "v2/v2.1"
    if layout != "v1":
        heights, hcols = _long_layout(path, names, column_line)
    else:
        heights, hcols = _v1_layout(path, names, column_line, header_altitudes(path, items))
    table = record_table(path, lines[column_line:], names, column_line)
    first = column_line + 1
    offset, sync = utc_offset(path, items, utc_offset_hours)
    stamps = _times(path, table[0], _TIME_FORMATS[names[0].strip()], first)
    times = increasing_utc_times(path, stamps, offset, first)
    angle, source = _scan_angle(items, scan_angle_deg)
    beam, azimuth, elevation = _beams(path, table[1], angle, first)
    heights_sorted = np.array(sorted(heights), dtype=float)
    data_vars, n_missing = _beam_variables(path, table, names, hcols, heights_sorted, first)
    data_vars.update(beam=(("time",), beam), beam_azimuth=(("time",), azimuth))
    data_vars["beam_elevation"] = (("time",), elevation)
    data_vars.update(_line_variables(path, table, names, first))
    attrs = _rtd_attrs(path, items, layout, angle, source)
    steps = np.diff(times).astype(float) / 1e9
    attrs.update(
        line_of_sight_interval_s=float(np.median(steps)) if steps.size else np.nan,
        utc_offset_applied_h=offset,
        time_sync=sync,
        n_missing=n_missing,
    )
    return wind_record_dataset(data_vars, times, heights_sorted, attrs)


def _column_names(path: Path, line: str, number: int) -> list[str]:
    """The TAB-separated column names of the ``.rtd`` column header ``line``.

    Raises
    ------
    InputFileError
        The line is not an ``.rtd`` column header (``Timestamp`` or ``Date``, then
        ``Position``).
    """
    names = line.split("\t")
    if not is_rtd_column_line(line):
        raise InputFileError(
            path,
            f"expected the .rtd column header ('Timestamp' or 'Date', then 'Position', "
            f"TAB-separated) on line {number}, found {names[0][:40]!r}",
            number,
        )
    return names


def _long_layout(
    path: Path, names: list[str], line: int
) -> tuple[list[float], dict[tuple[str, float], int]]:
    """v2/v2.1: ``<H>m <suffix>`` columns -> heights and ``(variable, height) -> column``."""
    heights: list[float] = []
    columns: dict[tuple[str, float], int] = {}
    for i, name in enumerate(names):
        m = _LONG_RE.match(name.strip())
        if m and m.group("suffix") in LONG_BEAM_COLUMNS:
            h = float(m.group("height"))
            if h not in heights:
                heights.append(h)
            columns[(LONG_BEAM_COLUMNS[m.group("suffix")], h)] = i
    if not heights:
        raise InputFileError(path, "no per-altitude columns ('<H>m Radial Wind Speed')", line)
    present = {
        suffix for suffix, var in LONG_BEAM_COLUMNS.items() if any(v == var for v, _ in columns)
    }
    for h in heights:
        for need in sorted(present | {"CNR (dB)", "Radial Wind Speed (m/s)"}):
            if (LONG_BEAM_COLUMNS[need], h) not in columns:
                raise InputFileError(path, f"altitude {h:g} m lacks the column {need}", line)
    return heights, columns


def _v1_layout(
    path: Path, names: list[str], line: int, altitudes: np.ndarray | None
) -> tuple[list[float], dict[tuple[str, float], int]]:
    """v1: 8-column blocks after the 4 record columns, matched to ``Altitudes(m)=``."""
    if altitudes is None:
        raise InputFileError(path, "no 'Altitudes(m)=' in the header to match the columns to")
    n_named = len(names) - 4 - (0 if names[-1].strip() else 1)  # a trailing TAB allowed
    if n_named != V1_BLOCK_SIZE * altitudes.size:
        raise InputFileError(
            path,
            f"{n_named} altitude columns, expected {V1_BLOCK_SIZE} for each of the "
            f"{altitudes.size} altitudes of the header",
            line,
        )
    columns = {
        (var, float(h)): 4 + k * V1_BLOCK_SIZE + off
        for k, h in enumerate(altitudes)
        for off, var in V1_BLOCK_OFFSETS.items()
    }
    return [float(h) for h in altitudes], columns


def _times(path: Path, stamps: pd.Series, fmt: str, first_line: int) -> np.ndarray:
    stamps = stamps.str.strip()
    times = pd.to_datetime(stamps, format=fmt, errors="coerce")
    bad = np.flatnonzero(times.isna().to_numpy())
    if bad.size:
        row = int(bad[0])
        raise InputFileError(path, f"time {stamps.iloc[row]!r} is not a date", first_line + row)
    return check_times(path, times.to_numpy(dtype="datetime64[ns]"), first_line)


def _scan_angle(items: dict[str, str], option: float | None) -> tuple[float, str]:
    """Cone half-angle from the zenith (deg) and where it comes from."""
    if option is not None:
        return float(option), "reader option scan_angle_deg"
    value = header_value(items, "ScanAngle (°)", "ScanAngle(°)")
    if value is not None:
        try:
            return float(value), "header"
        except ValueError:
            pass
    return NOMINAL_SCAN_ANGLE_DEG, "nominal: the header gives none"


def _beams(
    path: Path, positions: pd.Series, scan_angle: float, first_line: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Beam label, azimuth (deg) and elevation (deg) of each line of sight."""
    label = positions.str.strip().to_numpy(dtype=str)
    vertical = label == "V"
    azimuth = pd.to_numeric(pd.Series(label), errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~vertical & ~np.isfinite(azimuth))
    if bad.size:
        row = int(bad[0])
        raise InputFileError(
            path, f"Position {str(label[row])!r} is neither an azimuth nor 'V'", first_line + row
        )
    azimuth = np.where(vertical, 0.0, azimuth % 360.0)
    label = np.where(vertical, "V", np.array([f"{a:g}" for a in azimuth]))
    elevation = np.where(vertical, 90.0, 90.0 - scan_angle)
    return label, azimuth, elevation


def _numbers(path: Path, text: pd.DataFrame, first_line: int) -> np.ndarray:
    """Fields as floats; ``NaN``, ``NA``, ``-`` and empty fields are missing."""
    text = text.apply(lambda col: col.str.strip())
    values = text.apply(pd.to_numeric, errors="coerce").to_numpy(dtype=float)
    raw = text.to_numpy()
    bad = np.isnan(values) & ~np.isin(raw, list(MISSING_FIELDS))
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise InputFileError(
            path,
            f"column {text.columns[col]!r}: {raw[row, col]!r} is not a number",
            first_line + int(row),
        )
    return values


def _beam_variables(
    path: Path,
    table: pd.DataFrame,
    names: list[str],
    hcols: dict[tuple[str, float], int],
    heights: np.ndarray,
    first: int,
) -> tuple[dict[str, Any], int]:
    """Per line and altitude variables, and the number of missing values among them."""
    variables = list(dict.fromkeys(v for v, _ in hcols))
    used = [hcols[(v, h)] for v in variables for h in heights]
    sub = table[used]
    sub.columns = [f"{names[i].strip() or 'column'} [{i + 1}]" for i in used]
    values = _numbers(path, sub, first)
    nh = heights.size
    data_vars = {
        var: (("time", "height"), values[:, k * nh : (k + 1) * nh])
        for k, var in enumerate(variables)
    }
    return data_vars, int(np.isnan(values).sum())


def _line_variables(
    path: Path, table: pd.DataFrame, names: list[str], first: int
) -> dict[str, Any]:
    """Per line of sight: internal temperature (999 = missing), wiper count or state."""
    out: dict[str, Any] = {}
    temp = _numbers(path, table[[2]].set_axis([names[2].strip()], axis=1), first)[:, 0]
    out["internal_temperature"] = (("time",), np.where(temp == 999.0, np.nan, temp))
    wiper = table[3].str.strip()
    if names[3].strip() == "Wiper":
        out["wiper_on"] = (("time",), (wiper.str.lower() == "on").to_numpy(dtype=np.int8))
    else:
        values = _numbers(path, table[[3]].set_axis([names[3].strip()], axis=1), first)[:, 0]
        out["wiper_count"] = (("time",), values)
    return out


def _rtd_attrs(
    path: Path, items: dict[str, str], layout: str, angle: float, source: str
) -> dict[str, Any]:
    """Dataset attributes: model, software, system, scan angle and where it comes from."""
    from cwproc.io.windcube import instrument_model

    version = header_value(items, "Version") or ""
    system_id = header_value(items, "ID System") or ""
    model = instrument_model(version, system_id, "3.x" if layout == "v1" else "1.x")
    attrs: dict[str, Any] = {
        "instrument": f"Leosphere {model}" + (f" (software {version})" if version else ""),
        "instrument_model": model,
        "software_version": version,
        "instrument_kind": "pulsed",
        "format": "windcube_rtd",
        "rtd_layout": layout,
        "source_files": [path.name],
        "homodyne": 0,
        "time_stamp_position": "line of sight",
        "system_id": system_id,
        "scan_angle_deg": angle,
        "scan_angle_source": source,
    }
    if source.startswith("nominal"):
        attrs["warnings"] = [
            f"{path.name}: the header gives no scan angle (ScanAngle NA); the nominal "
            f"{NOMINAL_SCAN_ANGLE_DEG:g} deg of the WindCube v2/v2.1 is used "
            "([reader.windcube_rtd] scan_angle_deg sets it)"
        ]
    missing = sorted(k for k, v in items.items() if v.strip() in MISSING_HEADER_VALUES - {""})
    if missing:
        attrs["header_items_not_reported"] = missing
    for key, names in (
        ("location", ("Location", "Localisation")),
        ("gps_location", ("GPS Location", "GPS Localisation")),
    ):
        value = header_value(items, *names)
        if value:
            attrs[key] = value
    return attrs
