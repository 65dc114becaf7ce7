"""Campbell Scientific logger files: TOA5 (ASCII) sonic records, and what TOB1 shares.

Formats as seen in the real files (FORMATS.md section 4.1-4.2):

* **TOA5**: CSV, every header field quoted, CRLF. Line 1 environment (``"TOA5",
  station, logger, serial, OS, program, signature, table``), line 2 field names,
  line 3 units, line 4 processing (``Smp``), then data rows
  ``"yyyy-mm-dd HH:MM:SS[.f]",RECORD,v1,...``. Trailing zeros of the fractional
  seconds are dropped (``12:45:00.05``, ``12:45:00.1``, ``13:00:00``): parsed with a
  flexible fractional part. Missing values ``"NAN"``; ``INF``/``-INF`` can occur.
* **TOB1**: five such ASCII header lines (the fifth gives the data types, e.g.
  ``ULONG``, ``IEEE4``, ``FP2``), then fixed-size little-endian records without
  separators; SECONDS counts from 1990-01-01 00:00:00 plus NANOSECONDS. A partial
  trailing record (a cut file) is ignored and reported. Read by
  :mod:`cwproc.io.campbell_tob1` with the header fields, units and dataset of this
  module.

Time stamps are **logger time**; the files state no time zone. UTC = stamp -
``utc_offset_hours`` (option ``[reader.toa5]`` / ``[reader.tob1]``, default 0).
RECORD numbers that do not increase by one (lost records, logger restarts) are
reported in ``attrs["warnings"]``.

CSAT3 conventions [doc]: (Ux, Uy, Uz) is a right-handed instrument frame with Ux along
the boom into the array; ``Ts`` is sonic temperature (degC); ``diag_csat`` is 0 when
good, any other value is flagged (``sample_flag`` bit 1).
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import Any, BinaryIO

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io.averaged import averaged_table_reason, refuse_averaged_table
from cwproc.io.sonic_samples import SONIC_FIELDS, SPIKE_THRESHOLD, sonic_dataset
from cwproc.io.sonic_text import (
    NA_TEXT,
    blank_row,
    check_options,
    column_map,
    decode_text,
    numeric_column,
    option_number,
    parse_times,
    read_bytes,
    read_table,
)
from cwproc.io.timecheck import check_times, plausible_years

INSTRUMENT = "Campbell Scientific CSAT3 (logger {logger}, table {table})"
FRAME = "CSAT3 instrument frame: Ux along the boom into the array, Uy to its left, Uz up"

#: canonical name -> Campbell field name (CSAT3 defaults)
DEFAULT_COLUMNS: dict[str, str] = dict(
    zip(SONIC_FIELDS, ("Ux", "Uy", "Uz", "Ts", "diag_csat"), strict=True)
)

OPTIONS = {"utc_offset_hours", "columns", "frame", "spike_threshold"}


def header_fields(path: str | os.PathLike, line: str, number: int) -> list[str]:
    """The quoted, comma-separated fields of header line ``number`` (TOA5 and TOB1).

    Raises
    ------
    InputFileError
        The line is not CSV (names the line).
    """
    try:
        fields = next(csv.reader([line.rstrip("\r\n")]))
    except (csv.Error, StopIteration):
        raise InputFileError(path, "unreadable header line", number) from None
    return [f.strip() for f in fields]


def record_warnings(record: np.ndarray) -> list[str]:
    """Describe RECORD numbers that do not step by one (lost records, restarts)."""
    step = np.diff(np.asarray(record, dtype=float))
    notes = []
    lost = step > 1
    if lost.any():
        notes.append(
            f"RECORD jumps at {int(lost.sum())} place(s): {int(np.sum(step[lost] - 1))} "
            "record(s) missing"
        )
    back = step < 1
    if back.any():
        notes.append(f"RECORD restarts or repeats at {int(back.sum())} place(s)")
    return notes


def to_celsius(values: np.ndarray, unit: str) -> np.ndarray:
    """Sonic temperature in degC from a field whose unit line says ``unit`` (K or degC)."""
    return values - 273.15 if unit.strip().upper() == "K" else values


def campbell_dataset(
    path: str | os.PathLike,
    options: Mapping[str, Any],
    env: Sequence[str],
    times: np.ndarray,
    vals: Mapping[str, np.ndarray],
    temp: np.ndarray,
    diag: np.ndarray,
    attrs: dict[str, Any],
    notes: list[str],
) -> xr.Dataset:
    """The canonical sonic dataset of a TOA5 or TOB1 file (shared tail of both readers)."""
    return sonic_dataset(
        path,
        times,
        vals,
        temp,
        diag,
        instrument=INSTRUMENT.format(logger=env[2], table=env[7]),
        frame=str(options.get("frame", FRAME)),
        attrs=attrs,
        warnings=notes,
        spike_threshold=option_number(path, options, "spike_threshold", SPIKE_THRESHOLD),
    )


def read_toa5(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read a Campbell TOA5 file of high-rate sonic data into a sonic dataset.

    Parameters
    ----------
    path : path
    utc_offset_hours : float, optional
        Logger clock minus UTC (h); default 0 (logger time taken as UTC).
    columns : dict, optional
        Canonical name (``u``, ``v``, ``w``, ``temperature``, ``diagnostic``) -> field
        name; defaults are the CSAT3 names ``Ux``, ``Uy``, ``Uz``, ``Ts``, ``diag_csat``.
    frame : str, optional
        Description of the frame (attr).
    spike_threshold : float, optional
        Spike threshold (robust std), default 6.

    Returns
    -------
    xarray.Dataset
        Canonical sonic dataset; ``sampling_rate_hz`` measured (20 Hz for the real
        CSAT3 files); the header values in ``toa5_*`` attrs.

    Raises
    ------
    InputFileError
        File, line and problem.
    """
    check_options(path, options, OPTIONS)
    cols = column_map(path, options, DEFAULT_COLUMNS)
    offset_h = option_number(path, options, "utc_offset_hours", 0.0)
    _refuse_statistics_header(path, cols)
    try:
        with open(path, "rb") as fh:
            parsed = toa5_fast(path, fh, cols)
    except (OSError, InputFileError):  # worded by the checking reader, after its NUL check
        parsed = None
    if parsed is None:  # anything but the plain layout: the checking reader below
        parsed = _toa5_checked(path, read_bytes(path), cols)
    env, names, units, times, columns = parsed
    times = check_times(path, times - np.timedelta64(round(offset_h * 3600e9), "ns"), 5)
    unit = dict(zip(names, units, strict=True))
    vals = {k: columns[cols[k]] for k in ("u", "v", "w")}
    n = times.size
    temp = (
        to_celsius(columns[cols["temperature"]], unit[cols["temperature"]])
        if cols["temperature"] in columns
        else np.full(n, np.nan)
    )
    diag = columns[cols["diagnostic"]] if cols["diagnostic"] in columns else np.zeros(n)
    notes = []
    if "RECORD" in columns and np.isfinite(columns["RECORD"]).all():
        notes = record_warnings(columns["RECORD"])
    env = env + [""] * (8 - len(env))
    attrs = {
        "toa5_station": env[1],
        "toa5_logger": env[2],
        "toa5_serial": env[3],
        "toa5_os": env[4],
        "toa5_program": env[5],
        "toa5_signature": env[6],
        "toa5_table": env[7],
        "time_reference": f"logger time minus {offset_h:g} h",
    }
    return campbell_dataset(path, options, env, times, vals, temp, diag, attrs, notes)


def _refuse_statistics_header(path: str | os.PathLike, cols: Mapping[str, str]) -> None:
    """Refuse a TOA5 table of statistics (averages, fluxes) from its four header lines.

    See :mod:`cwproc.io.averaged`; a header that cannot be read is left to the reader.
    """
    try:
        with open(path, "rb") as fh:
            head = [fh.readline().decode("latin-1") for _ in range(4)]
    except OSError:
        return
    if not head[0].startswith('"TOA5"') or not head[3].strip():
        return
    try:
        rows = list(csv.reader(line.strip() for line in head[1:4]))
    except csv.Error:  # a damaged header: the reader words it
        return
    if len(rows) < 3:
        return
    names, processing = rows[0], rows[2]
    wind = [cols[k] for k in ("u", "v", "w") if cols[k] in names]
    refuse_averaged_table(
        path, averaged_table_reason(names=names, processing=processing, wind_fields=wind)
    )


def _toa5_header(
    path: str | os.PathLike, lines: Sequence[str], cols: Mapping[str, str], n_lines: int
) -> tuple[list[str], list[str], list[str]]:
    """Environment, field names and units of a TOA5 header (lines 1-3), checked.

    ``n_lines`` is the number of lines of the whole file (a header alone has no data).
    """
    if n_lines < 4 or not lines[0].startswith('"TOA5"'):
        raise InputFileError(path, 'not a TOA5 file (line 1 must start with "TOA5")', 1)
    env = header_fields(path, lines[0], 1)
    names = header_fields(path, lines[1], 2)
    units = header_fields(path, lines[2], 3)
    if len(units) != len(names):
        raise InputFileError(path, f"{len(units)} units for {len(names)} fields", 3)
    if "TIMESTAMP" not in names:
        raise InputFileError(path, "no TIMESTAMP field", 2)
    for key in ("u", "v", "w"):
        if cols[key] not in names:
            raise InputFileError(path, f"no field {cols[key]!r} ({key})", 2)
    if n_lines == 4:
        raise InputFileError(path, "no data records", 5)
    return env, names, units


def _wanted(names: Sequence[str], cols: Mapping[str, str]) -> list[str]:
    """The numeric fields the sonic dataset uses, in file order."""
    keys = {cols[k] for k in ("u", "v", "w", "temperature", "diagnostic")} | {"RECORD"}
    return [name for name in names if name in keys]


def _toa5_checked(
    path: str | os.PathLike, raw: bytes, cols: Mapping[str, str]
) -> tuple[list[str], list[str], list[str], np.ndarray, dict[str, np.ndarray]]:
    """Header, logger-time stamps and numeric fields of any TOA5 text, every line checked.

    The general reader: any line ending, any encoding, quoted or bare fields; every
    problem names its line (field count, bad number, bad time stamp, blank line).
    """
    text = decode_text(raw)
    lines = text.splitlines(keepends=True)
    env, names, units = _toa5_header(path, lines, cols, len(lines))
    body = "".join(lines[4:])
    counts = pd.Series(lines[4:]).str.count(",").to_numpy()
    wrong = np.flatnonzero(counts != len(names) - 1)
    if wrong.size:
        i = int(wrong[0])
        raise InputFileError(
            path, f"data line has {counts[i] + 1} fields, expected {len(names)}", 5 + i
        )
    frame = read_table(path, body, delimiter=",", skip=4, names=names)
    blank_row(path, frame, 5)
    times = parse_times(path, frame["TIMESTAMP"], 5)
    columns = {name: numeric_column(path, frame, name, 5) for name in _wanted(names, cols)}
    return env, names, units, times, columns


def toa5_fast(
    path: str | os.PathLike, source: bytes | BinaryIO, cols: Mapping[str, str]
) -> tuple[list[str], list[str], list[str], np.ndarray, dict[str, np.ndarray]] | None:
    """The same as :func:`_toa5_checked` for a plain TOA5 file, several times faster.

    Plain: LF or CRLF line ends, an ASCII body, every data line with the header's
    number of fields and a quoted ``"yyyy-mm-dd HH:MM:SS[.f]"`` stamp first (the
    logger's own layout, FORMATS.md section 4.1). The stamps are decoded from the
    bytes (:func:`toa5_stamps`) and only the fields the dataset uses are parsed, by
    pandas' C parser with float dtypes. Returns None when the file is not plain or a
    field does not parse, and the caller reads it with the checking reader, which
    names the line of the problem; results are identical where both apply.

    ``source`` is the file's bytes or the file open in binary mode; an open file is
    read block by block (:data:`SCAN_BYTES`), never whole: a day's file (62 MB at
    10.7 Hz) would be fresh memory the kernel zeroes before it is read into.
    """
    head = source[:HEADER_BYTES] if isinstance(source, bytes) else source.read(HEADER_BYTES)
    ends = []
    pos = 0
    for _ in range(4):
        pos = head.find(b"\n", pos) + 1
        if pos == 0:
            return None
        ends.append(pos)
    try:
        header = [head[a:b].decode("utf-8") for a, b in zip([0, *ends[:3]], ends, strict=True)]
    except UnicodeDecodeError:
        return None
    if any(len(line.splitlines()) != 1 for line in header) or b"\x00" in head[: ends[3]]:
        return None
    env, names, units = _toa5_header(path, header, cols, 5)
    if len(set(names)) != len(names) or names[0] != "TIMESTAMP":
        return None
    layout = _scan_body(_body_blocks(source, ends[3]), len(names))
    if layout is None:
        return None
    newlines, first, last, windows = layout
    if newlines.size == 0 or np.any(last > newlines) or np.any(first[1:] < newlines[:-1]):
        return None
    times = toa5_stamps(windows, first - np.concatenate([[0], newlines[:-1] + 1]))
    if times is None:
        return None
    wanted = _wanted(names, cols)
    frame = _parse_fields(source, ends[3], names, wanted)
    if frame is None or len(frame) != times.size:
        return None
    columns = {name: frame[name].to_numpy(dtype=float) for name in wanted}
    return env, names, units, check_times(path, times, 5), columns


#: bytes of a TOA5 file in which its four header lines must end (else the checking
#: reader reads it)
HEADER_BYTES = 1 << 16


def _body_blocks(source: bytes | BinaryIO, start: int) -> Iterator[tuple[int, np.ndarray]]:
    """``(offset, bytes)`` of the body from byte ``start`` on, in blocks of
    :data:`SCAN_BYTES` followed by the next :data:`STAMP_WIDTH` bytes (fewer at the
    end); an open file is read into one reused buffer."""
    if isinstance(source, bytes):
        body = np.frombuffer(source, dtype=np.uint8, offset=start)
        for lo in range(0, body.size, SCAN_BYTES):
            yield lo, body[lo : lo + SCAN_BYTES + STAMP_WIDTH]
        return
    buffer = np.empty(SCAN_BYTES + STAMP_WIDTH, dtype=np.uint8)
    lo = 0
    while True:
        source.seek(start + lo)
        n = source.readinto(memoryview(buffer))
        if not n:
            return
        yield lo, buffer[:n]
        lo += SCAN_BYTES


def _parse_fields(
    raw: bytes | BinaryIO, start: int, names: list[str], wanted: list[str]
) -> pd.DataFrame | None:
    """The ``wanted`` fields of the TOA5 data lines that begin at byte ``start`` of
    ``raw`` (bytes or an open file), as float64 (None if one does not parse).

    The parser reads from ``start`` of the file or of a buffer sharing ``raw`` (no copy
    of the body) and tokenizes it in chunks (``low_memory``: the same values, as every dtype is
    given, with a third of the memory of a whole-file token table).
    """
    buffer = io.BytesIO(raw) if isinstance(raw, bytes) else raw
    buffer.seek(start)
    try:
        return pd.read_csv(
            buffer,
            header=None,
            names=names,
            usecols=wanted,
            dtype=dict.fromkeys(wanted, np.float64),
            keep_default_na=False,
            na_values=NA_TEXT,
            engine="c",
            low_memory=True,
        )
    except (ValueError, pd.errors.ParserError):
        return None


#: bytes of a TOA5 body scanned at once: the temporaries of a scan stay in the
#: processor's cache and are reused, where whole-body ones (62 MB each for a day at
#: 10.7 Hz) are fresh memory the kernel zeroes, each time
SCAN_BYTES = 1 << 20


def _scan_body(
    blocks: Iterable[tuple[int, np.ndarray]], n_fields: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """The layout of the data lines of a TOA5 body, read block by block.

    Parameters
    ----------
    blocks : iterable of (int, ndarray of uint8)
        Offset in the body and bytes of consecutive blocks of :data:`SCAN_BYTES`, each
        followed by the next :data:`STAMP_WIDTH` bytes of the body (:func:`_body_blocks`).
    n_fields : int
        Fields per line.

    Returns
    -------
    tuple or None
        Offsets of the line ends (LF), of the first and of the last comma of each run of
        ``n_fields - 1`` commas, and the first :data:`STAMP_WIDTH` bytes of every line
        (zero-padded past the end), shape (lines, STAMP_WIDTH); None when the body holds
        a byte of no plain line (non-ASCII, DEL, a control character other than the line
        ends), CR other than before every LF, not ``n_fields - 1`` commas for each line,
        or does not end with a line end. Each line holds exactly its own run of commas
        when every run lies between the end of the line before and the end of its line.
    """
    per_line = n_fields - 1
    if per_line < 1:
        return None
    newlines, first, last, windows = [], [], [], []
    n_commas = n_control = n_cr = 0
    previous = 10  # the byte before the body ends the header line
    block = np.zeros(0, np.uint8)
    for lo, ahead in blocks:
        block = ahead[:SCAN_BYTES]
        if block.max() > 126:
            return None
        ends = np.flatnonzero(block == 10)
        commas = np.flatnonzero(block == 44)
        # the commas whose index in the whole body is 0 or per_line - 1 modulo per_line
        first.append(commas[(-n_commas) % per_line :: per_line] + lo)
        last.append(commas[(per_line - 1 - n_commas) % per_line :: per_line] + lo)
        newlines.append(ends + lo)
        n_commas += commas.size
        n_control += int(np.count_nonzero(block < 32))
        n_cr += int(np.count_nonzero(block[ends[ends > 0] - 1] == 13))
        n_cr += int(ends.size > 0 and ends[0] == 0 and previous == 13)  # CRLF across blocks
        starts = ends[ends < block.size - 1] + 1
        if previous == 10:
            starts = np.concatenate([[0], starts])
        padded = np.concatenate([ahead, np.zeros(STAMP_WIDTH, np.uint8)])
        windows.append(np.lib.stride_tricks.sliding_window_view(padded, STAMP_WIDTH)[starts])
        previous = int(block[-1])
    lines = np.concatenate(newlines) if newlines else np.zeros(0, np.int64)
    if block.size == 0 or previous != 10 or n_cr not in (0, lines.size):
        return None
    if n_control != lines.size + n_cr or n_commas != lines.size * per_line:
        return None
    return lines, np.concatenate(first), np.concatenate(last), np.concatenate(windows)


#: bytes of a data line examined for its stamp: '"' + 19 + '.' + 9 digits + '",'
STAMP_WIDTH = 32
#: per byte of ``"yyyy-mm-dd HH:MM:SS``: lowest allowed value and allowed span
_STAMP_LOW = np.frombuffer(b'"0000-00-00 00:00:00', dtype=np.uint8)
_STAMP_SPAN = np.where(np.frombuffer(b'"0000-00-00 00:00:00', dtype=np.uint8) == 48, 9, 0)
_STAMP_SPAN = _STAMP_SPAN.astype(np.uint8)
#: days of each month (index 1-12) in a common year
_MONTH_DAYS = np.array([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31])


def _number(w: np.ndarray, first: int, width: int) -> np.ndarray:
    """The decimal number in byte columns ``first .. first + width - 1`` (digits checked)."""
    out = np.zeros(w.shape[0], dtype=np.int64)
    for col in range(first, first + width):
        out = out * 10 + (w[:, col] - 48)
    return out


def days_from_civil(year: np.ndarray, month: np.ndarray, day: np.ndarray) -> np.ndarray:
    """Days since 1970-01-01 of proleptic Gregorian dates (Hinnant's algorithm).

    Valid for years >= 0; ``month`` 1-12, ``day`` 1-31 (not checked here).
    """
    y = year - (month <= 2)
    era = y // 400
    yoe = y - era * 400
    doy = (153 * np.where(month > 2, month - 3, month + 9) + 2) // 5 + day - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


def toa5_stamps(windows: np.ndarray, ends: np.ndarray) -> np.ndarray | None:
    """Decode quoted TOA5 stamps ``"yyyy-mm-dd HH:MM:SS[.f]",`` from the line starts.

    Parameters
    ----------
    windows : ndarray of uint8, shape (n, STAMP_WIDTH)
        The first bytes of every data line.
    ends : ndarray of int, shape (n,)
        Offset of the first comma of every line in it (the end of the stamp field).

    Returns
    -------
    ndarray of datetime64[ns] or None
        Logger time; None when any line's stamp is not exactly in this layout (1 to 9
        fractional digits, closing quote and comma) or names an impossible date or
        time, so that the caller's general parser decides and names the line.
    """
    w = np.ascontiguousarray(windows)
    n = w.shape[0]
    ends = np.asarray(ends, dtype=np.int64)
    # "yyyy-mm-dd HH:MM" (bytes 0-16) changes once a minute: decoded once per run
    words = w.view(np.uint64)
    new = np.ones(n, dtype=bool)
    new[1:] = (words[1:, 0] != words[:-1, 0]) | (words[1:, 1] != words[:-1, 1])
    new[1:] |= w[1:, 16] != w[:-1, 16]
    first = np.flatnonzero(new)
    minutes = _minute_ns(w[first])
    if minutes is None:
        return None
    tens, units = w[:, 18] - np.uint8(48), w[:, 19] - np.uint8(48)
    if np.any(w[:, 17] != ord(":")) or np.any((tens > 5) | (units > 9)):
        return None
    # the stamp closes at ends - 1: byte 20 (whole seconds) or 22-30 ('.' and 1-9 digits)
    if np.any((ends < 21) | (ends == 22) | (ends > 31)):
        return None
    dotted = ends > 21
    if np.any(w[:, 20] != np.where(dotted, np.uint8(ord(".")), np.uint8(ord('"')))):
        return None
    if np.any(np.take(w.reshape(-1), np.arange(n) * w.shape[1] + ends - 1) != ord('"')):
        return None
    frac = w[:, 21:30] - np.uint8(48)
    kept = np.take(_FRACTION_DIGITS, np.where(dotted, ends - 22, 0), axis=0)
    if np.any(kept & (frac > 9)):
        return None
    frac *= kept  # digits past the stamp's last are zeros
    nanos = eight_digits(frac[:, :8]) * 10 + frac[:, 8]
    nanos += (tens.astype(np.int64) * 10 + units) * 1_000_000_000
    nanos += np.repeat(minutes, np.diff(np.append(first, n)))
    return nanos.astype("datetime64[ns]")


#: row k: which of the nine fractional-second digits a stamp with k of them has
_FRACTION_DIGITS = np.arange(9) < np.arange(10)[:, None]


def eight_digits(digits: np.ndarray) -> np.ndarray:
    """The numbers written by rows of eight decimal digits (values 0-9, most significant
    first), each row read as one 64-bit word (little-endian: the first digit in the low
    byte) and reduced in place: pairs, then the four pairs into one number, with three
    multiplications per row (exact: every intermediate stays below 2**64).

    Parameters
    ----------
    digits : ndarray of uint8, shape (n, 8)

    Returns
    -------
    ndarray of int64, shape (n,)
    """
    v = np.ascontiguousarray(digits, dtype=np.uint8).view("<u8")[:, 0]
    v = v * np.uint64(10) + (v >> np.uint64(8))  # byte 2i: the pair 10 d_2i + d_2i+1
    low = v & np.uint64(0x000000FF000000FF)  # pairs 0 and 2
    high = (v >> np.uint64(16)) & np.uint64(0x000000FF000000FF)  # pairs 1 and 3
    v = low * np.uint64(100 + (1_000_000 << 32)) + high * np.uint64(1 + (10_000 << 32))
    return (v >> np.uint64(32)).astype(np.int64)


def _minute_ns(w: np.ndarray) -> np.ndarray | None:
    """Nanoseconds since 1970 of ``"yyyy-mm-dd HH:MM`` (bytes 0-16 of ``w``), or None
    when a byte is out of place or the date or time does not exist."""
    head = w[:, :17]
    if not np.all((head - _STAMP_LOW[:17]) <= _STAMP_SPAN[:17]):
        return None
    year, month, day = _number(w, 1, 4), _number(w, 6, 2), _number(w, 9, 2)
    hour, minute = _number(w, 12, 2), _number(w, 15, 2)
    low, high = plausible_years()
    if np.any((year < low) | (year > high)):  # as integers: 2590 in nanoseconds wraps
        return None
    leap = (year % 4 == 0) & ((year % 100 != 0) | (year % 400 == 0))
    if np.any((month < 1) | (month > 12) | (hour > 23) | (minute > 59)):
        return None
    if np.any((day < 1) | (day > _MONTH_DAYS[month] + (leap & (month == 2)))):
        return None
    days = days_from_civil(year, month, day)
    return ((days * 24 + hour) * 60 + minute) * 60_000_000_000
