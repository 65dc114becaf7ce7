"""Halo Photonics Stream Line ``.hpl`` files: reader and writer.

The layout is described in ``real_data/FORMATS.md`` section 1: a header of 17 lines,
then one block per ray, made of one *ray line* (decimal hours, azimuth, elevation and,
on most instruments, pitch and roll) and ``Number of gates`` *gate lines* (gate index,
Doppler velocity, intensity = SNR + 1, attenuated backscatter and, when spectral width
is switched on, the spectral width).

:func:`read_hpl` parses the whole body with one call of the pandas C tokenizer, checks
the block structure with array operations, and only when a check fails walks the
offending ray block line by line to name the first bad line. :func:`read_hpl_files`
reads many files (a day of scans) into one dataset with one tokenizer call per batch
of files. :func:`write_hpl` writes a canonical scan dataset back in the instrument's
layout (used by the simulator and the benchmarks).

Notes
-----
* **Time.** The ray line gives decimal hours since 00:00 UTC of the date in
  ``Start time`` (the file states no zone; UTC in practice). A file that crosses
  midnight has hours >= 24 or wraps back to 0; a wrap (a step back of more than
  12 h) adds 24 h to the rays after it, and a first ray more than 12 h before the
  start time belongs to the next day. Times are rounded to the microsecond.
* **Angles.** Azimuth is clockwise from north, returned in [0, 360) (``360.00`` -> 0).
  An elevation above 90 deg (beam over the zenith, e.g. ``180.01``) is the direction
  azimuth + 180 deg at elevation 180 deg - el. ``-0.00`` becomes 0.
* **Sign.** Doppler velocity is positive away from the lidar (the Halo convention).
* **Missing data.** There is no fill value: every gate has numbers; noise gates have
  intensity close to 1 (SNR close to 0) and must be screened by SNR downstream.
* **Header quirks.** ``No. of rays in file`` (or ``No. of waypoints in file``) is
  unreliable and only kept as an attribute; the column count of the first gate line
  (4 or 5), not the header, says whether spectral width is present; header numbers may
  use a decimal comma (``30,0``, ``14:00:01,23``).
"""

from __future__ import annotations

import csv
import io
import itertools
import os
import re
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import ConfigError, CwprocError, InputFileError
from cwproc.io import FileIdentity
from cwproc.io.netcdf import write_bytes_atomic
from cwproc.io.schema import with_canonical_attrs
from cwproc.io.timecheck import check_times

try:  # the optional compiled tokenizer (setup.py); pandas does the same work without it
    from cwproc.io import _hpltok
except ImportError:
    _hpltok = None

INSTRUMENT = "Halo Photonics Stream Line"
INSTRUMENT_KIND = "streamline"

#: number of header lines of every .hpl file
HEADER_LINES = 17

#: focus range written by the instrument for a collimated beam (infinite focus)
FOCUS_INFINITY = 65535

#: keys of header lines 1-11, in order (line 7 has two spellings)
_HEADER_KEYS: tuple[tuple[str, ...], ...] = (
    ("Filename",),
    ("System ID",),
    ("Number of gates",),
    ("Range gate length (m)",),
    ("Gate length (pts)",),
    ("Pulses/ray",),
    ("No. of rays in file", "No. of waypoints in file"),
    ("Scan type",),
    ("Focus range",),
    ("Start time",),
    ("Resolution (m/s)",),
)

_RANGE_STANDARD = re.compile(
    r"^(Altitude|Range) of measurement \(center of gate\) = "
    r"\(range gate \+ 0[.,]5\) \* Gate length$"
)
_RANGE_OVERLAPPING = re.compile(
    r"^(?:Altitude|Range) of measurement \(center of gate\) = Gate length / "
    r"(\d+(?:[.,]\d+)?) \+ \(range gate x (\d+(?:[.,]\d+)?)\)$"
)
_START_TIME = re.compile(r"^(\d{4})(\d{2})(\d{2}) (\d{1,2}):(\d{2}):(\d{2}(?:[.,]\d*)?)$")
_SPECTRAL_WIDTH = re.compile(r"^\*{4}\s*Instrument spectral width\s*=\s*(\S+)\s*$")

#: longest range gate accepted (m): Stream Line gates are 3-60 m; 1e308 gave infinite heights
_MAX_GATE_LENGTH_M = 1000.0
#: largest gate count accepted (guards against a garbled header asking for absurd memory)
_MAX_GATES = 100_000

#: bodies larger than this (bytes) are parsed in parallel chunks (not smaller: batch runs
#: already read several files at once, and threads would oversubscribe the cores)
_PARALLEL_BYTES = 8 << 20

#: hours of a step back in decimal time that marks a wrap at midnight
_WRAP_HOURS = 12.0


@dataclass(frozen=True)
class HplHeader:
    """The parsed 17-line header of a ``.hpl`` file (units in the field names)."""

    filename: str
    system_id: str
    n_gates: int
    gate_length_m: float
    points_per_gate: int
    pulses_per_ray: int
    rays_in_file: int
    rays_key: str
    scan_type: str
    focus_range_m: float
    start_time: np.datetime64
    velocity_resolution_m_s: float
    range_formula: str
    #: overlapping gates: range = gate_length / divisor + gate * step_m
    range_divisor: float | None
    range_step_m: float | None
    instrument_spectral_width_m_s: float | None

    def gate_ranges(self) -> np.ndarray:
        """Range of each gate centre (m) from the header's range formula."""
        gate = np.arange(self.n_gates, dtype=np.float64)
        if self.range_divisor is None:
            return (gate + 0.5) * self.gate_length_m
        return self.gate_length_m / self.range_divisor + gate * float(self.range_step_m)


# --------------------------------------------------------------------------------------
# header
# --------------------------------------------------------------------------------------


def _number(text: str) -> float:
    """A header number, accepting a decimal comma (``30,0``); ValueError otherwise."""
    value = float(text.strip().replace(",", "."))
    if not np.isfinite(value):
        raise ValueError(text)
    return value


def _integer(text: str) -> int:
    text = text.strip()
    if not re.fullmatch(r"[+]?\d+", text):
        raise ValueError(text)
    return int(text)


def parse_start_time(text: str) -> np.datetime64:
    """``yyyymmdd HH:MM:SS.ss`` (decimal point or comma) -> datetime64[us]; ValueError."""
    m = _START_TIME.match(text.strip())
    if m is None:
        raise ValueError(text)
    year, month, day, hour, minute = (int(g) for g in m.groups()[:5])
    second = float(m.group(6).replace(",", "."))
    if not (1 <= month <= 12 and hour < 24 and minute < 60 and second < 61):
        raise ValueError(text)
    date = np.datetime64(f"{year:04d}-{month:02d}-{day:02d}", "D")  # ValueError if bad day
    micro = round((hour * 3600 + minute * 60 + second) * 1e6)
    return date.astype("datetime64[us]") + np.timedelta64(micro, "us")


def parse_header(path: str | os.PathLike, lines: list[str]) -> HplHeader:
    """Parse and validate the 17 header lines.

    Parameters
    ----------
    path : path-like
        The file (for error messages).
    lines : list of str
        The first 17 lines, without line terminators.

    Raises
    ------
    InputFileError
        A key is missing or garbled, a value is not a number, or a fixed line is
        not what a Stream Line writes; the message names the 1-based line.
    """
    values: list[str] = []
    rays_key = ""
    for i, keys in enumerate(_HEADER_KEYS):
        line = lines[i]
        key, sep, value = line.partition(":")
        key = key.strip()
        if not sep or key.lower() not in {k.lower() for k in keys}:
            expected = " or ".join(f"'{k}:'" for k in keys)
            raise InputFileError(
                path, f"header line should start with {expected}, found {line[:40]!r}", i + 1
            )
        if i == 6:
            rays_key = key
        values.append(value.strip())

    def field(i: int, convert, what: str):
        try:
            return convert(values[i])
        except (ValueError, OverflowError):
            raise InputFileError(
                path, f"{_HEADER_KEYS[i][0]}: {values[i]!r} is not {what}", i + 1
            ) from None

    n_gates = field(2, _integer, "a whole number")
    if not 1 <= n_gates <= _MAX_GATES:
        raise InputFileError(path, f"Number of gates: {n_gates} is out of range", 3)
    gate_length = field(3, _number, "a number")
    if not 0 < gate_length <= _MAX_GATE_LENGTH_M:
        raise InputFileError(
            path,
            f"Range gate length (m): {values[3]!r} must be > 0 and <= {_MAX_GATE_LENGTH_M:g}",
            4,
        )
    points = field(4, _integer, "a whole number")
    pulses = field(5, _integer, "a whole number")
    rays = field(6, _integer, "a whole number")
    focus = field(8, _number, "a number")
    start = field(9, parse_start_time, "a time 'yyyymmdd HH:MM:SS.ss'")
    check_times(path, np.array([start]), 10)
    resolution = field(10, _number, "a number")

    formula = lines[11].strip()
    divisor = step = None
    if _RANGE_STANDARD.match(formula) is None:
        m = _RANGE_OVERLAPPING.match(formula)
        if m is None:
            raise InputFileError(
                path, f"unknown range formula {formula[:80]!r} (line 12 of the header)", 12
            )
        divisor, step = _number(m.group(1)), _number(m.group(2))
        if not (0 < divisor < 10 and 0 < step < 100):
            raise InputFileError(path, f"implausible range formula {formula!r}", 12)
    for number, prefix in ((13, "Data line 1:"), (15, "Data line 2:")):
        if not lines[number - 1].startswith(prefix):
            raise InputFileError(
                path,
                f"header line should start with {prefix!r}, found {lines[number - 1][:40]!r}",
                number,
            )
    last = lines[16].strip()
    if not last.startswith("****"):
        raise InputFileError(path, f"header should end with a '****' line, found {last[:40]!r}", 17)
    spectral_width = None
    if last != "****":
        m = _SPECTRAL_WIDTH.match(last)
        try:
            spectral_width = _number(m.group(1)) if m else None
        except ValueError:
            spectral_width = None
        if spectral_width is None:
            raise InputFileError(path, f"unexpected end-of-header line {last[:60]!r}", 17)
    return HplHeader(
        filename=values[0],
        system_id=values[1],
        n_gates=n_gates,
        gate_length_m=gate_length,
        points_per_gate=points,
        pulses_per_ray=pulses,
        rays_in_file=rays,
        rays_key=rays_key,
        scan_type=values[7],
        focus_range_m=float("inf") if focus == FOCUS_INFINITY else focus,
        start_time=start,
        velocity_resolution_m_s=resolution,
        range_formula=formula,
        range_divisor=divisor,
        range_step_m=step,
        instrument_spectral_width_m_s=spectral_width,
    )


_EOL = re.compile(rb"\r\n|\n|\r")


def split_header(path: str | os.PathLike, raw: bytes) -> tuple[list[str], int]:
    """The 17 header lines (decoded) and the byte offset where the body starts.

    Raises
    ------
    InputFileError
        Empty file, not a ``.hpl`` file, or fewer than 17 lines.
    """
    if not raw or raw.isspace():  # isspace stops at the first non-blank byte (no copy)
        raise InputFileError(path, "file is empty", 1)
    if not raw.startswith(b"Filename:"):
        raise InputFileError(
            path, "not a Halo .hpl file (the first line does not start with 'Filename:')", 1
        )
    lines: list[str] = []
    pos = 0
    for _ in range(HEADER_LINES):
        m = _EOL.search(raw, pos)
        end = m.start() if m else len(raw)
        lines.append(raw[pos:end].decode("latin-1"))
        if m is None:
            pos = len(raw)
            break
        pos = m.end()
    if len(lines) < HEADER_LINES:
        raise InputFileError(
            path, f"header ends after {len(lines)} lines; a .hpl header has 17", len(lines)
        )
    return lines, pos


# --------------------------------------------------------------------------------------
# body
# --------------------------------------------------------------------------------------


def content_end(raw: bytes, start: int = 0) -> int:
    """Offset just after the last non-blank byte of ``raw[start:]`` (``start`` if none).

    Equivalent to ``start + len(raw[start:].rstrip())`` but only looks at the end of
    the data (doubling tails), so the body is not copied twice to drop a final newline.
    """
    end = len(raw)
    tail = 64
    while end > start:
        lo = max(start, end - tail)
        kept = len(raw[lo:end].rstrip())
        if kept:
            return lo + kept
        end = lo
        tail *= 2
    return start


#: fields per line that the single-space tokenizer keeps: 5 and the empty field after a
#: trailing space (a sixth number is an error, found by :func:`_tokenize`)
_SPACE_FIELDS = 6


def _read_table(body: bytes | io.RawIOBase, *, single_space: bool) -> pd.DataFrame:
    """Parse body lines with the pandas C tokenizer (5 or, see below, 6 columns).

    ``body`` is the data or a binary file object that reads it.

    ``single_space``: the body has no TAB, so fields are split at single spaces with
    ``skipinitialspace`` (leading, repeated and trailing spaces as in the instrument
    files; about 15 % faster than the regular-expression separator ``\\s+``, which
    pandas maps to its whitespace tokenizer). A trailing space gives an empty sixth
    field. Otherwise ``\\s+`` with 5 columns.
    """
    layout = (
        {"sep": " ", "skipinitialspace": True, "names": range(_SPACE_FIELDS)}
        if single_space
        else {"sep": r"\s+", "names": range(5)}
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return pd.read_csv(
            io.BytesIO(body) if isinstance(body, bytes) else body,
            header=None,
            engine="c",
            skip_blank_lines=False,
            quoting=csv.QUOTE_NONE,
            # bytes go to the tokenizer as they are (a non-UTF-8 encoding would make
            # pandas decode and re-encode the whole body); a field that is not valid
            # UTF-8 stays a string (surrogate escapes) and so becomes +inf, no number
            encoding_errors="surrogateescape",
            keep_default_na=False,
            na_values=[""],
            low_memory=False,
            **layout,
        )


def _chunks(body: bytes, n_chunks: int) -> list[tuple[int, int]]:
    """Byte spans of ``body`` cut at line starts into about ``n_chunks`` equal parts."""
    if n_chunks <= 1 or b"\n" not in body:
        return [(0, len(body))]
    cuts = [0]
    for k in range(1, n_chunks):
        nl = body.find(b"\n", k * len(body) // n_chunks)
        if nl < 0 or nl + 1 >= len(body):
            break
        if nl + 1 > cuts[-1]:
            cuts.append(nl + 1)
    cuts.append(len(body))
    return list(itertools.pairwise(cuts))


def _tokenize(
    path: str | os.PathLike, body: bytes, *, single_space: bool | None = None
) -> list[np.ndarray]:
    """The 5 fields of every body line as 5 float columns (NaN where a line is shorter).

    A field that is not a finite number (``abc``, ``nan``, ``inf``) is +inf, so that
    the structure check can tell it from a missing field; a line with more than 5
    fields raises here. The compiled tokenizer ``cwproc.io._hpltok`` does the work when
    it was built (``setup.py``: an optional extension; every value equals
    ``float(token)``, about twice the speed of pandas); otherwise the pandas C tokenizer
    (single-space separator when :func:`_single_space_ok`, see :func:`_read_table`); very
    large bodies are cut at line starts and parsed in threads (the tokenizer releases the
    GIL). The columns
    may be read-only or strided views (of one float table up to ``_TABLE_ROWS``
    lines, else of the parser's columns).
    """
    if _hpltok is not None:
        values, n_lines, bad_line = _hpltok.tokenize(body, 5)
        if bad_line < 0:  # else the pandas tokenizer below names the line and its fields
            table = np.frombuffer(values, dtype=np.float64).reshape(n_lines, 5)
            return [table[:, j] for j in range(5)]
    if single_space is None:
        single_space = _single_space_ok(body)
    workers = min(os.cpu_count() or 1, max(1, len(body) // _PARALLEL_BYTES))
    spans = _chunks(body, workers)

    def parse(span: tuple[int, int]) -> pd.DataFrame:
        return _read_table(body[span[0] : span[1]], single_space=single_space)

    try:
        if len(spans) == 1:
            frames = [_read_table(body, single_space=single_space)]
        else:
            with ThreadPoolExecutor(len(spans)) as pool:
                frames = list(pool.map(parse, spans))
    except pd.errors.ParserError as exc:
        if single_space:  # name the line exactly as the whitespace tokenizer does
            return _tokenize(path, body, single_space=False)
        m = re.search(r"Expected \d+ fields in line (\d+), saw (\d+)", str(exc))
        if m is None:
            raise InputFileError(
                path, f"cannot parse the data lines ({exc})", HEADER_LINES + 1
            ) from None
        # which chunk failed: re-parse the chunks one by one (error path only)
        for start, end in spans:
            try:
                _read_table(body[start:end], single_space=False)
            except pd.errors.ParserError as chunk_exc:
                m = re.search(r"Expected \d+ fields in line (\d+), saw (\d+)", str(chunk_exc))
                if m is None:
                    break
                before = body.count(b"\n", 0, start)
                raise InputFileError(
                    path,
                    f"line has {m.group(2)} fields; ray lines have 3 or 5, gate lines 4 or 5",
                    HEADER_LINES + before + int(m.group(1)),
                ) from None
        raise InputFileError(
            path, f"cannot parse the data lines ({exc})", HEADER_LINES + 1
        ) from None
    except (ValueError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise InputFileError(
            path, f"cannot parse the data lines ({exc})", HEADER_LINES + 1
        ) from None
    if sum(len(frame) for frame in frames) <= _TABLE_ROWS:
        tables = [_float_table(frame) for frame in frames]
        table = tables[0] if len(tables) == 1 else np.concatenate(tables)
        columns = [table[:, j] for j in range(table.shape[1])]
    else:
        parts = [[_float_column(frame[name]) for name in frame.columns] for frame in frames]
        columns = [p[0] if len(p) == 1 else np.concatenate(p) for p in zip(*parts, strict=True)]
    if len(columns) > 5 and not np.isnan(columns[5]).all():
        return _tokenize(path, body, single_space=False)  # the reference names the line
    return columns[:5]


#: parsed tables up to this many lines become one float array (one call, one copy);
#: longer ones are taken column by column (no copy of the parser's columns)
_TABLE_ROWS = 100_000


def _float_table(frame: pd.DataFrame) -> np.ndarray:
    """The parsed lines as a float array (line, field); see :func:`_float_column`.

    One copy of the parser's columns (measured: fewer page faults than keeping the
    columns, whose memory is then freed and reused at once).
    """
    if all(dtype.kind == "f" for dtype in frame.dtypes):
        return frame.to_numpy(dtype=np.float64)
    return np.column_stack([_float_column(frame[name]) for name in frame.columns])


def _float_column(col: pd.Series) -> np.ndarray:
    """A parsed column as float64; a field that is there but no number becomes +inf."""
    if col.dtype.kind in "fiu":
        return col.to_numpy(dtype=np.float64)
    numbers = pd.to_numeric(col, errors="coerce")
    values = numbers.to_numpy(dtype=np.float64, na_value=np.nan, copy=True)
    values[col.notna().to_numpy() & np.isnan(values)] = np.inf
    return values


def _fields_of_row(columns: list[np.ndarray], row: int) -> int:
    """Number of leading finite fields of one body row (0 when there is no such row)."""
    if row >= columns[0].size:
        return 0
    count = 0
    for col in columns:
        if not np.isfinite(col[row]):
            break
        count += 1
    return count


def line_ends(body: bytes) -> tuple[int, bool]:
    """Number of lines of a body without a final line end, and whether a CR stands alone.

    Line ends are CRLF, LF or a lone CR (as for the tokenizer). Counted with numpy
    (several times faster than ``bytes.count``).
    """
    data = np.frombuffer(body, dtype=np.uint8)
    cr = np.flatnonzero(data == 13)
    lf = int(np.count_nonzero(data == 10))
    follows = cr + 1
    crlf = int(np.count_nonzero(data[follows[follows < data.size]] == 10))
    return lf + cr.size - crlf + 1, crlf != cr.size


def _single_space_ok(body: bytes) -> bool:
    """Whether the single-space tokenizer applies: no TAB and no lone CR line end.

    (pandas' ``skipinitialspace`` takes the leading space of a line that follows a lone
    CR as a separator.)
    """
    if b"\t" in body:
        return False
    if b"\r" not in body:  # LF files: no CR at all (memchr, no numpy pass)
        return True
    data = np.frombuffer(body, dtype=np.uint8)
    follows = np.flatnonzero(data == 13) + 1
    return bool(follows[-1] < data.size and (data[follows] == 10).all())


def structure_problem(
    columns: list[np.ndarray], n_gates: int
) -> tuple[int, int, int | None, int | None] | None:
    """Where the ray/gate block structure of the parsed body breaks, or ``None``.

    Returns
    -------
    tuple or None
        ``(start_row, n_gates, ray_fields, gate_fields)``: the arguments after
        ``body`` of :func:`diagnose` for the ray block to walk (field counts ``None``
        when the first rows do not even say them); ``None`` when every block is whole.
    """
    ray_fields = _fields_of_row(columns, 0)
    gate_fields = _fields_of_row(columns, 1)
    if ray_fields not in (3, 5) or gate_fields not in (4, 5):
        return 0, n_gates, None, None
    block = n_gates + 1
    bad = first_bad_row(columns, n_gates, ray_fields, gate_fields)
    if bad >= 0:
        return (bad // block) * block, n_gates, ray_fields, gate_fields
    n_rows = columns[0].size
    if n_rows % block:
        return (n_rows // block) * block, n_gates, ray_fields, gate_fields
    return None


def first_bad_row(
    columns: list[np.ndarray], n_gates: int, ray_fields: int, gate_fields: int
) -> int:
    """Index of the first body row that breaks the ray/gate block structure, or -1.

    A row is good when exactly its first ``ray_fields`` (ray rows, every
    ``n_gates + 1``-th row) or ``gate_fields`` (gate rows) fields are present, all of them
    finite numbers (``+inf`` marks a field that is no number, see :func:`_tokenize`),
    and, for a gate row, when its gate index equals its position in the block.
    Rows of an incomplete last block are checked as far as they go.
    """
    n_rows = columns[0].size
    block = n_gates + 1
    n_blocks = -(-n_rows // block)
    pad = n_blocks * block - n_rows
    ok = np.ones((n_blocks, block), dtype=bool)
    index = np.arange(-1, n_gates, dtype=np.float64)
    for j, col in enumerate(columns):
        if pad:
            filler = np.where(j < gate_fields, 0.0, np.nan) * np.ones(pad)
            if j == 0:
                filler = np.tile(index, n_blocks)[n_rows:]
            col = np.concatenate([col, filler])
        grid = col.reshape(n_blocks, block)
        ok[:, 0] &= np.isfinite(grid[:, 0]) if j < ray_fields else np.isnan(grid[:, 0])
        gates = grid[:, 1:]
        ok[:, 1:] &= np.isfinite(gates) if j < gate_fields else np.isnan(gates)
        if j == 0:
            ok[:, 1:] &= gates == index[1:]
    bad = np.flatnonzero(~ok.ravel())
    return int(bad[0]) if bad.size else -1


_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _is_number(token: bytes) -> bool:
    """Whether a token is a finite decimal number as the instrument writes them."""
    return _NUMBER.fullmatch(token) is not None and bool(np.isfinite(float(token)))


#: added to the error of a bad last line when the file does not end with a line end
_CUT_HINT = (
    "; the file ends inside this line: it was cut short (a broken copy, or the file of "
    "the current hour still being written)"
)


def diagnose(
    path: str | os.PathLike,
    body: bytes,
    start_row: int,
    n_gates: int,
    ray_fields: int | None,
    gate_fields: int | None,
) -> InputFileError:
    """Name the first bad line of the ray block that starts at body row ``start_row``.

    Only called when the vectorised structure check failed: walks one ray block
    (``n_gates + 1`` lines) and returns the error to raise. ``ray_fields`` and
    ``gate_fields`` are the field counts of the file (``None``: not known yet, 3 or 5
    and 4 or 5 are accepted).
    """
    lines = body.splitlines()
    block = n_gates + 1
    first = HEADER_LINES + 1  # file line number of body row 0
    ray_ok = (3, 5) if ray_fields is None else (ray_fields,)
    gate_ok = (4, 5) if gate_fields is None else (gate_fields,)
    cut_short = not body.endswith((b"\n", b"\r"))
    for row in range(start_row, min(start_row + block, len(lines))):
        line_no = first + row
        tokens = lines[row].split()
        pos = row - start_row
        # the last line of a file without a final line end: a file cut off mid-line
        cut = _CUT_HINT if cut_short and row == len(lines) - 1 else ""
        if not tokens:
            return InputFileError(path, "empty line inside the data", line_no)
        bad = [t for t in tokens if not _is_number(t)]
        if bad:
            token = bad[0].decode("latin-1")
            return InputFileError(path, f"field {token[:20]!r} is not a number{cut}", line_no)
        if pos == 0:
            if b"." not in tokens[0]:
                restart = (
                    ": the gate index restarts without a ray line"
                    if row and tokens[0] == b"0"
                    else ""
                )
                return InputFileError(
                    path,
                    f"expected a ray line (decimal time, azimuth, elevation) "
                    f"{f'after {n_gates} gate lines ' if row else ''}but found gate index "
                    f"{tokens[0].decode('latin-1')}{restart}",
                    line_no,
                )
            if len(tokens) not in ray_ok:
                return InputFileError(
                    path,
                    f"ray line has {len(tokens)} fields, expected "
                    + " or ".join(map(str, ray_ok))
                    + cut,
                    line_no,
                )
            continue
        gate = pos - 1
        if b"." in tokens[0] and len(tokens) in (3, 5):
            return InputFileError(
                path,
                f"ray line after only {gate} of {n_gates} gate lines (Number of gates: {n_gates})",
                line_no,
            )
        if len(tokens) not in gate_ok:
            return InputFileError(
                path,
                f"gate line has {len(tokens)} fields, expected "
                + " or ".join(map(str, gate_ok))
                + cut,
                line_no,
            )
        if b"." in tokens[0] or float(tokens[0]) != gate:
            index = tokens[0].decode("latin-1")
            hint = ": the gate index restarts without a ray line" if index == "0" else ""
            return InputFileError(
                path, f"gate index {index} where {gate} was expected{hint}", line_no
            )
        if gate_fields is None:
            gate_ok = (len(tokens),)
        if ray_fields is None:
            ray_ok = (len(lines[start_row].split()),)
    n_rows = len(lines)
    if start_row + block > n_rows:
        got = n_rows - start_row - 1
        return InputFileError(
            path,
            f"last ray is truncated: {got} of {n_gates} gate lines after its ray line "
            "(file cut short, or Number of gates does not match the data)",
            first + start_row,
        )
    return InputFileError(path, "inconsistent ray block", first + start_row)


#: bytes read first for the header (a Stream Line header is about 1 kB)
_HEAD_BYTES = 1 << 16


def read_header_and_body(path: Path) -> tuple[list[str], bytes]:
    """The 17 header lines and the data lines of a file, each read once from disk.

    The body is read straight after the header (no copy of the whole file); it keeps
    a final line end (and spaces before it), which the tokenizer ignores, but not
    further blank lines.

    Raises
    ------
    InputFileError
        The file cannot be read, or its header is cut short (see :func:`split_header`).
    """
    try:
        with path.open("rb") as f:
            head = f.read(_HEAD_BYTES)
            try:
                lines, offset = split_header(path, head)
            except InputFileError:
                if len(head) < _HEAD_BYTES:
                    raise
                lines, offset = split_header(path, head + f.read())  # huge header lines
            f.seek(offset)
            body = f.read()
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    end = content_end(body)
    tail = body[end:]
    if tail.lstrip(b" ") not in (b"", b"\n", b"\r\n", b"\r"):
        body = body[:end]  # blank lines after the data: drop them (copies the body)
    return lines, body


def decimal_hours_to_time(hours: np.ndarray, start_time: np.datetime64) -> np.ndarray:
    """UTC times from Halo decimal hours since 00:00 of the start date.

    Parameters
    ----------
    hours : ndarray
        Decimal time of each ray (h).
    start_time : datetime64
        ``Start time`` of the header.

    Returns
    -------
    ndarray of datetime64[ns]
        Monotonic across midnight: a step back of more than 12 h adds 24 h to the
        following rays, and a first ray more than 12 h before the start time of day
        is on the next day. Rounded to the microsecond.
    """
    day = start_time.astype("datetime64[D]")
    start_hours = (start_time - day) / np.timedelta64(1, "h")
    hours = np.asarray(hours, dtype=np.float64)
    wraps = np.concatenate([[0], np.cumsum(np.diff(hours) < -_WRAP_HOURS)])
    offset = 24.0 * wraps
    if hours.size and hours[0] < start_hours - _WRAP_HOURS:
        offset = offset + 24.0
    micro = np.rint((hours + offset) * 3.6e9).astype(np.int64)
    return (day.astype("datetime64[us]") + micro.astype("timedelta64[us]")).astype("datetime64[ns]")


def normalise_pointing(azimuth: np.ndarray, elevation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Beam direction with elevation <= 90 deg and azimuth in [0, 360) (degrees).

    An elevation above 90 deg points over the zenith: the same direction is azimuth
    + 180 deg at elevation 180 deg - el. ``-0.00`` becomes 0 and 360 becomes 0.
    """
    azimuth = np.asarray(azimuth, dtype=np.float64)
    elevation = np.asarray(elevation, dtype=np.float64)
    over = elevation > 90.0
    azimuth = np.where(over, azimuth + 180.0, azimuth)
    elevation = np.where(over, 180.0 - elevation, elevation) + 0.0
    azimuth = np.mod(azimuth, 360.0) + 0.0
    azimuth = np.where(azimuth >= 360.0, azimuth - 360.0, azimuth)
    return azimuth, elevation


def _check_options(options: dict) -> None:
    if options:
        raise ConfigError(
            "[reader.hpl]", ", ".join(sorted(options)), "the .hpl reader takes no options"
        )


def read_hpl(path: str | os.PathLike, **options: object) -> xr.Dataset:
    """Read a Halo Photonics Stream Line ``.hpl`` file into a canonical scan dataset.

    Parameters
    ----------
    path : path-like
        The ``.hpl`` file (any variant of ``real_data/FORMATS.md`` section 1: Stare,
        VAD, user scans; 3- or 5-field ray lines; 4- or 5-column gate lines; CRLF, LF
        or CR; with or without a final newline).
    **options
        ``[reader.hpl]`` configuration table; the reader takes no options (any key
        raises :class:`cwproc.errors.ConfigError`).

    Returns
    -------
    xarray.Dataset
        Dims ``ray``, ``range``; coords ``time`` (UTC), ``azimuth`` (deg, [0, 360)),
        ``elevation`` (deg), ``range`` (m, gate centre), ``scan``; data
        ``radial_velocity`` (m s-1, positive away from the lidar), ``snr`` (intensity
        - 1), ``beta`` (m-1 sr-1), ``spectral_width`` (m s-1, when present), ``pitch``
        and ``roll`` (deg, when present); header values in ``attrs``.

    Raises
    ------
    InputFileError
        Empty file, another format, garbled header, non-numeric field, a gate count
        that does not match the body, a gate index that restarts without a ray line,
        a truncated last ray: the message names the file and the 1-based line.
    """
    _check_options(options)
    path = Path(path)
    lines, body = read_header_and_body(path)
    header = parse_header(path, lines)
    if content_end(body) == 0:
        raise InputFileError(path, "no data after the header", HEADER_LINES + 1)
    nul = body.find(b"\x00")
    if nul >= 0:
        line = HEADER_LINES + 1 + len(_EOL.findall(body, 0, nul))
        raise InputFileError(path, "NUL byte in the data", line)

    n_gates = header.n_gates
    # the pandas tokenizer's layout (decided lazily when the compiled one is there)
    single_space = None if _hpltok is not None else _single_space_ok(body)
    columns = _tokenize(path, body, single_space=single_space)
    problem = structure_problem(columns, n_gates)
    if problem is not None and single_space:  # judge damage with the reference tokenizer
        columns = _tokenize(path, body, single_space=False)
        problem = structure_problem(columns, n_gates)
    if problem is not None:
        raise diagnose(path, body, *problem)
    n_rows = columns[0].size
    block = n_gates + 1
    ray_fields = _fields_of_row(columns, 0)
    gate_fields = _fields_of_row(columns, 1)
    n_rays = n_rows // block
    grids = [col.reshape(n_rays, block) for col in columns]
    rays = np.column_stack([g[:, 0] for g in grids])
    ray_lines = HEADER_LINES + 1 + np.arange(n_rays) * block
    _check_rays(path, rays, ray_lines)

    time = decimal_hours_to_time(rays[:, 0], header.start_time)
    azimuth, elevation = normalise_pointing(rays[:, 1], rays[:, 2])
    gates = {"radial_velocity": grids[1], "snr": grids[2], "beta": grids[3]}
    if gate_fields == 5:
        gates["spectral_width"] = grids[4]
    per_ray = {"pitch": rays[:, 3], "roll": rays[:, 4]} if ray_fields == 5 else {}
    from cwproc.io.scans import scan_indices

    scan, scan_attrs = scan_indices(time, azimuth, elevation, scan_type=header.scan_type)
    ds = scan_dataset(
        gates,
        per_ray,
        time=time,
        azimuth=azimuth,
        elevation=elevation,
        ranges=header.gate_ranges(),
        scan=(scan, scan_attrs),
        attrs=_attrs(path, header),
    )
    return with_canonical_attrs(ds, "scan")


def read_hpl_identity(path: str | os.PathLike) -> FileIdentity:
    """What a ``.hpl`` file is, from its header and first ray line only (no data).

    For grouping files into product units without reading them (instrument, system
    id, UTC day): the attributes :func:`read_hpl` gives and a ``time(ray)`` of the first
    ray alone (the earliest: ray times run forward, across midnight too, see
    :func:`decimal_hours_to_time`). The data are checked when the file is read.

    Raises
    ------
    InputFileError
        The file cannot be read, its header is garbled, or no ray line follows it.
    """
    path = Path(path)
    try:
        with path.open("rb") as f:
            head = f.read(_HEAD_BYTES)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    lines, offset = split_header(path, head)
    header = parse_header(path, lines)
    first = head[offset:].lstrip(b"\r\n").split(b"\n", 1)[0].split(b"\r", 1)[0].split()
    try:
        hours = float(first[0])
    except (IndexError, ValueError):
        raise InputFileError(path, "no ray line after the header", HEADER_LINES + 1) from None
    time = decimal_hours_to_time(np.array([hours]), header.start_time)
    return FileIdentity(attrs=_attrs(path, header), time=time)


def scan_dataset(
    gates: dict[str, np.ndarray],
    per_ray: dict[str, np.ndarray],
    *,
    time: np.ndarray,
    azimuth: np.ndarray,
    elevation: np.ndarray,
    ranges: np.ndarray,
    scan: tuple[np.ndarray, dict[str, object]],
    attrs: dict[str, object],
) -> xr.Dataset:
    """The canonical scan dataset from parsed arrays, built from ``xarray.Variable``s.

    Parameters
    ----------
    gates : dict of ndarray
        ``radial_velocity`` (m s-1), ``snr`` given as the file's intensity (SNR + 1,
        converted here), ``beta`` (m-1 sr-1), optional ``spectral_width`` (m s-1): each
        of shape (ray, 1 + gate), column 0 (the ray line's field) is dropped.
    per_ray : dict of ndarray
        ``pitch`` and ``roll`` (deg) when the ray lines have them.
    time, azimuth, elevation : ndarray
        Per-ray coordinates (datetime64[ns]; deg).
    ranges : ndarray
        Gate centres (m).
    scan : (ndarray, dict)
        Scan index of each ray and its attributes.
    attrs : dict
        Dataset attributes.
    """
    ray_range = ("ray", "range")
    variables: dict[str, xr.Variable] = {}
    for name, grid in gates.items():
        values = grid[:, 1:] - 1.0 if name == "snr" else np.ascontiguousarray(grid[:, 1:])
        variables[name] = xr.Variable(ray_range, values)
    for name, values in per_ray.items():
        variables[name] = xr.Variable(("ray",), np.array(values, dtype=np.float64))
    coords = {
        "time": xr.Variable(("ray",), time),
        "azimuth": xr.Variable(("ray",), azimuth),
        "elevation": xr.Variable(("ray",), elevation),
        "range": xr.Variable(("range",), ranges),
        "scan": xr.Variable(("ray",), scan[0], scan[1]),
    }
    return xr.Dataset(variables, coords=coords, attrs=attrs)


def _bad_ray(rays: np.ndarray) -> tuple[int, str] | None:
    """First ray whose decimal time or pointing no instrument writes, and the problem."""
    checks = (
        ((rays[:, 0] < 0) | (rays[:, 0] >= 48), "decimal time {} h is outside 0-48 h", 0),
        ((rays[:, 1] < -360) | (rays[:, 1] > 720), "azimuth {} deg is out of range", 1),
        ((rays[:, 2] < -90) | (rays[:, 2] > 270), "elevation {} deg is out of range", 2),
    )
    for bad, message, column in checks:
        idx = np.flatnonzero(bad)
        if idx.size:
            i = int(idx[0])
            return i, message.format(rays[i, column])
    return None


def _check_rays(path: str | os.PathLike, rays: np.ndarray, ray_lines: np.ndarray) -> None:
    """Decimal time and pointing angles within what an instrument can write."""
    bad = _bad_ray(rays)
    if bad is not None:
        raise InputFileError(path, bad[1], int(ray_lines[bad[0]]))


def _attrs(path: Path, header: HplHeader) -> dict[str, object]:
    attrs: dict[str, object] = {
        "instrument": INSTRUMENT,
        "instrument_kind": INSTRUMENT_KIND,
        "system_id": header.system_id,
        "source_files": [path.name],
        "scan_type": header.scan_type,
        "gate_length_m": header.gate_length_m,
        "homodyne": 0,
        "points_per_gate": header.points_per_gate,
        "pulses_per_ray": header.pulses_per_ray,
        "focus_range_m": header.focus_range_m,
        "velocity_resolution_m_s": header.velocity_resolution_m_s,
        "header_filename": header.filename,
        "header_start_time": np.datetime_as_string(header.start_time, unit="ms") + "Z",
        "header_rays_in_file": header.rays_in_file,
        "range_formula": header.range_formula,
    }
    if header.instrument_spectral_width_m_s is not None:
        attrs["instrument_spectral_width_m_s"] = header.instrument_spectral_width_m_s
    return attrs


# --------------------------------------------------------------------------------------
# several files
# --------------------------------------------------------------------------------------

#: bodies joined for one tokenizer call in :func:`read_hpl_files` (bytes): large enough
#: to amortise the per-call cost, small enough to bound the tokenizer's working memory
_BATCH_BYTES = 16 << 20


@dataclass(frozen=True)
class _Body:
    """One file's header and data lines, as :func:`read_hpl_files` needs them."""

    path: Path
    header: HplHeader
    #: the data lines are ``body[:end]`` (no final line end, no blank tail)
    body: bytes
    end: int
    n_lines: int
    single_space: bool


def _load_body(path: Path) -> _Body | None:
    """Header and body of a file, or ``None`` when anything is off (no raise)."""
    try:
        lines, body = read_header_and_body(path)
        header = parse_header(path, lines)
    except InputFileError:
        return None
    end = content_end(body)
    if end == 0 or body.find(b"\x00", 0, end) >= 0:
        return None
    n_lines, lone_cr = line_ends(memoryview(body)[:end])
    return _Body(
        path=path,
        header=header,
        body=body,
        end=end,
        n_lines=n_lines,
        single_space=not lone_cr and body.find(b"\t", 0, end) < 0,
    )


class _JoinedBodies(io.RawIOBase):
    """A read-only binary file over the data lines of several files joined by CRLF.

    Serves the tokenizer's reads from the files' own buffers, so that a day of files
    is never copied into one large joined buffer.
    """

    def __init__(self, bodies: list[_Body]) -> None:
        super().__init__()
        self._pieces: list[memoryview] = []
        for item in bodies:
            if self._pieces:
                self._pieces.append(memoryview(b"\r\n"))
            self._pieces.append(memoryview(item.body)[: item.end])
        self._index = 0
        self._offset = 0

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: bytearray | memoryview) -> int:
        out = memoryview(buffer).cast("B")
        n = 0
        while n < len(out) and self._index < len(self._pieces):
            piece = self._pieces[self._index]
            take = min(len(out) - n, len(piece) - self._offset)
            out[n : n + take] = piece[self._offset : self._offset + take]
            n += take
            self._offset += take
            if self._offset == len(piece):
                self._index += 1
                self._offset = 0
        return n


def _batch_columns(batch: list[_Body], n_gates: int) -> list[np.ndarray] | None:
    """The 5 columns of a batch's bodies, parsed in one call; ``None`` if not whole."""
    if _hpltok is not None:
        tables = []
        for item in batch:
            values, n_lines, bad_line = _hpltok.tokenize(memoryview(item.body)[: item.end], 5)
            if bad_line >= 0 or n_lines != item.n_lines:
                return None
            tables.append(np.frombuffer(values, dtype=np.float64).reshape(n_lines, 5))
        table = tables[0] if len(tables) == 1 else np.concatenate(tables)
        columns = [table[:, j] for j in range(5)]
        return None if structure_problem(columns, n_gates) is not None else columns
    if not all(item.single_space for item in batch):
        return None
    try:
        frame = _read_table(_JoinedBodies(batch), single_space=True)
    except (pd.errors.ParserError, ValueError, UnicodeDecodeError, pd.errors.EmptyDataError):
        return None
    if frame.shape[1] != _SPACE_FIELDS or len(frame) != sum(item.n_lines for item in batch):
        return None
    columns = [_float_column(frame[name]) for name in frame.columns]
    if not np.isnan(columns[5]).all():
        return None
    columns = columns[:5]
    if structure_problem(columns, n_gates) is not None:
        return None
    return columns


def _same_layout(first: HplHeader, item: _Body) -> bool:
    """Whether a file can be parsed with the first one: same gates, range grid, system."""
    header = item.header
    return (
        header.n_gates == first.n_gates
        and header.gate_length_m == first.gate_length_m
        and header.range_divisor == first.range_divisor
        and header.range_step_m == first.range_step_m
        and header.system_id == first.system_id
        and item.n_lines % (first.n_gates + 1) == 0
    )


@dataclass(frozen=True)
class _BatchArrays:
    """The per-ray arrays of one batch of files (rays in file order)."""

    layout: tuple[int, int]  # fields of the ray lines and of the gate lines
    variables: dict[str, np.ndarray]  # canonical names, ray first
    time: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray


def _batch_arrays(batch: list[_Body], n_gates: int) -> _BatchArrays | None:
    """Parse one batch and keep only its dataset arrays; ``None`` if anything is off."""
    columns = _batch_columns(batch, n_gates)
    if columns is None:
        return None
    ray_fields, gate_fields = _fields_of_row(columns, 0), _fields_of_row(columns, 1)
    block = n_gates + 1
    grids = [col.reshape(-1, block) for col in columns]
    rays = np.column_stack([g[:, 0] for g in grids])
    if _bad_ray(rays) is not None:
        return None
    counts = [item.n_lines // block for item in batch]
    ends = np.cumsum(counts)
    time = np.concatenate(
        [
            decimal_hours_to_time(rays[end - count : end, 0], item.header.start_time)
            for item, count, end in zip(batch, counts, ends, strict=True)
        ]
    )
    azimuth, elevation = normalise_pointing(rays[:, 1], rays[:, 2])
    variables = {
        "radial_velocity": np.ascontiguousarray(grids[1][:, 1:]),
        "snr": grids[2][:, 1:] - 1.0,
        "beta": np.ascontiguousarray(grids[3][:, 1:]),
    }
    if gate_fields == 5:
        variables["spectral_width"] = np.ascontiguousarray(grids[4][:, 1:])
    if ray_fields == 5:
        variables["pitch"] = rays[:, 3].copy()
        variables["roll"] = rays[:, 4].copy()
    return _BatchArrays((ray_fields, gate_fields), variables, time, azimuth, elevation)


def _add_batch(batch: list[_Body], n_gates: int, done: list[_BatchArrays]) -> bool:
    """Parse a batch onto ``done``; False on damage or a layout unlike the first batch's
    (e.g. pitch and roll in some files only)."""
    arrays = _batch_arrays(batch, n_gates)
    if arrays is None or (done and arrays.layout != done[0].layout):
        return False
    done.append(arrays)
    return True


def _read_together(paths: list[Path]) -> xr.Dataset | None:
    """The fast path of :func:`read_hpl_files`, or ``None`` to take the reference path.

    Files are read and parsed batch by batch (about ``_BATCH_BYTES`` of data each);
    only the dataset arrays of a batch are kept, so the peak memory is the result
    plus one batch.
    """
    from cwproc.io.scans import joined_attrs, time_sorted_scans

    first: HplHeader | None = None
    scan_types: list[str] = []
    done: list[_BatchArrays] = []
    batch: list[_Body] = []
    size = 0
    for path in paths:
        item = _load_body(path)
        if item is None:
            return None
        if first is None:
            first = item.header
        if not _same_layout(first, item):
            return None
        scan_types.append(item.header.scan_type)
        if batch and size + item.end > _BATCH_BYTES:
            if not _add_batch(batch, first.n_gates, done):
                return None
            batch, size = [], 0
        batch.append(item)
        size += item.end
    if first is None or not _add_batch(batch, first.n_gates, done):
        return None
    ray_range = ("ray", "range")
    variables = {
        name: (
            ray_range if values.ndim == 2 else ("ray",),
            np.concatenate([b.variables[name] for b in done]) if len(done) > 1 else values,
            {},
        )
        for name, values in done[0].variables.items()
    }
    attrs = joined_attrs(_attrs(paths[0], first), [path.name for path in paths], scan_types)
    return time_sorted_scans(
        variables,
        fixed={},
        time=np.concatenate([b.time for b in done]),
        azimuth=np.concatenate([b.azimuth for b in done]),
        elevation=np.concatenate([b.elevation for b in done]),
        ranges=first.gate_ranges(),
        attrs=attrs,
        coord_attrs={},
    )


def read_hpl_files(paths: list[str | os.PathLike], **options: object) -> xr.Dataset:
    """Several ``.hpl`` files (e.g. a day of VAD scans) as one scan dataset.

    The result is exactly ``concat_scans([read_hpl(p) for p in paths])`` (rays sorted
    by time, repeated times dropped, ``scan`` assigned over the whole record), built
    without one dataset per file. When every file has the same gates, range grid,
    system id and field layout, the files are read in batches of about 16 MB of data,
    each batch parsed by one tokenizer call (served from the files' buffers, no joined
    copy) and checked as a whole, and only its dataset arrays are kept (the peak
    memory is about that of the reference path). Anything else (different layouts,
    any damage) takes the reference path file by file, which raises the exact error
    of the first bad file. Measured on a synthetic day of 720 files
    (``benchmarks/bench_read_hpl.py``): 2-3 times faster than the reference path.

    Parameters
    ----------
    paths : list of path-like
        The files, in any order.
    **options
        ``[reader.hpl]`` table (the reader takes no options; any key raises
        :class:`cwproc.errors.ConfigError`).

    Raises
    ------
    InputFileError
        A file is damaged (as :func:`read_hpl`).
    CwprocError
        No files, or files that cannot be concatenated (as
        :func:`cwproc.io.scans.concat_scans`).
    """
    _check_options(options)
    paths = [Path(p) for p in paths]
    if paths:
        together = _read_together(paths)
        if together is not None:
            return together
    from cwproc.io.scans import concat_scans

    return concat_scans([read_hpl(path) for path in paths])


# --------------------------------------------------------------------------------------
# writer
# --------------------------------------------------------------------------------------


def _beta_strings(beta: np.ndarray) -> np.ndarray:
    """Backscatter as the instrument prints it: ``1.569249E-6`` (no exponent padding)."""
    s = np.char.mod("%.6E", beta)
    s = np.char.replace(s, "E+0", "E")
    s = np.char.replace(s, "E+", "E")
    s = np.char.replace(s, "E-0", "E-")
    return s


def hpl_text(ds: xr.Dataset, filename: str) -> str:
    """The ``.hpl`` text (CRLF line ends) of a canonical scan dataset.

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical scan dataset; ``range`` must be (gate + 0.5) x ``gate_length_m``.
    filename : str
        Name written on the ``Filename:`` line.

    Raises
    ------
    CwprocError
        The range grid is not the Stream Line grid, there are no rays, or a value is
        not finite (the format has no fill value).
    """
    n_rays = int(ds.sizes["ray"])
    n_gates = int(ds.sizes["range"])
    if n_rays == 0:
        raise CwprocError(f"write_hpl {filename}: the dataset has no rays")
    ranges = np.asarray(ds["range"].values, dtype=np.float64)
    gate_length = float(ds.attrs.get("gate_length_m", 2.0 * ranges[0]))
    if not np.allclose(ranges, (np.arange(n_gates) + 0.5) * gate_length, rtol=0, atol=1e-6):
        raise CwprocError(
            f"write_hpl {filename}: range is not (gate + 0.5) x gate length "
            f"{gate_length} m, the Stream Line grid"
        )
    for name in (
        "radial_velocity",
        "snr",
        "beta",
        "spectral_width",
        "pitch",
        "roll",
        "azimuth",
        "elevation",
    ):
        if name in ds.variables and not np.isfinite(ds[name].values).all():
            raise CwprocError(
                f"write_hpl {filename}: {name} has non-finite values; the .hpl format has "
                "no fill value"
            )
    times = ds["time"].values.astype("datetime64[us]")
    if np.isnat(times).any():
        raise CwprocError(f"write_hpl {filename}: time has missing values")
    day = times.min().astype("datetime64[D]")
    hours = (times - day.astype("datetime64[us]")).astype(np.int64) / 3.6e9
    az = np.asarray(ds["azimuth"].values, dtype=np.float64)
    el = np.asarray(ds["elevation"].values, dtype=np.float64)
    has_pr = "pitch" in ds and "roll" in ds
    has_sw = "spectral_width" in ds
    focus = float(ds.attrs.get("focus_range_m", float("inf")))
    focus_text = str(FOCUS_INFINITY) if not np.isfinite(focus) else f"{focus:g}"
    start = np.datetime_as_string(times[0], unit="ms")
    start_text = start[:10].replace("-", "") + " " + start[11:22]
    scan_type = str(ds.attrs.get("scan_type", "VAD"))
    which = "Altitude" if scan_type.startswith("Stare") else "Range"
    res = float(ds.attrs.get("velocity_resolution_m_s", 0.0382))
    spectral = ds.attrs.get("instrument_spectral_width_m_s")
    header = [
        f"Filename:\t{filename}",
        f"System ID:\t{ds.attrs.get('system_id', '0')}",
        f"Number of gates:\t{n_gates}",
        f"Range gate length (m):\t{gate_length:.1f}",
        f"Gate length (pts):\t{int(ds.attrs.get('points_per_gate', round(gate_length / 3)))}",
        f"Pulses/ray:\t{int(ds.attrs.get('pulses_per_ray', 10000))}",
        f"No. of rays in file:\t{n_rays}",
        f"Scan type:\t{scan_type}",
        f"Focus range:\t{focus_text}",
        f"Start time:\t{start_text}",
        f"Resolution (m/s):\t{res:g}",
        f"{which} of measurement (center of gate) = (range gate + 0.5) * Gate length",
        "Data line 1: Decimal time (hours)  Azimuth (degrees)  Elevation (degrees)"
        + (" Pitch (degrees) Roll (degrees)" if has_pr else ""),
        "f9.6,1x,f6.2,1x,f6.2",
        "Data line 2: Range Gate  Doppler (m/s)  Intensity (SNR + 1)  Beta (m-1 sr-1)"
        + (" Spectral Width" if has_sw else ""),
        "i3,1x,f6.4,1x,f8.6,1x,e12.6" + (",1x,f6.4" if has_sw else "") + " - repeat for no. gates",
        "****" + (f" Instrument spectral width = {float(spectral):.6f}" if spectral else ""),
    ]
    ray = np.char.add(np.char.mod("%.8f", hours), np.char.mod(" %6.2f", az))
    ray = np.char.add(ray, np.char.mod(" %6.2f", el))
    if has_pr:
        ray = np.char.add(ray, np.char.mod(" %.2f", ds["pitch"].values))
        ray = np.char.add(ray, np.char.mod(" %.2f", ds["roll"].values))
    beta = ds["beta"].values if "beta" in ds else np.zeros((n_rays, n_gates))
    index = np.char.mod("%3d", np.arange(n_gates))
    gate = np.char.add(
        np.broadcast_to(index, (n_rays, n_gates)),
        np.char.mod(" %.4f", ds["radial_velocity"].values),
    )
    gate = np.char.add(gate, np.char.mod(" %.6f", ds["snr"].values + 1.0))
    gate = np.char.add(gate, np.char.mod(" %12s", _beta_strings(beta)))
    if has_sw:
        gate = np.char.add(gate, np.char.mod(" %.4f ", ds["spectral_width"].values))
    block = np.concatenate([ray[:, None], gate], axis=1)
    return "\r\n".join(header) + "\r\n" + "\r\n".join(block.ravel().tolist()) + "\r\n"


def write_hpl(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write a canonical scan dataset as a Stream Line ``.hpl`` file.

    The layout is the instrument's: 17 header lines, CRLF line ends, ray lines
    ``hours az el [pitch roll]`` with 8-decimal hours, gate lines
    ``i3 doppler intensity beta [spectral_width]`` with the backscatter right-aligned
    in 12 characters (two spaces before a positive value, one before a negative one).
    Times are written as decimal hours since 00:00 of the first ray's day (hours
    >= 24 after midnight).

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical scan dataset (``snr`` is written as intensity = snr + 1).
    path : path-like
        Output file; its name goes on the ``Filename:`` line.

    Returns
    -------
    pathlib.Path
        The path written (through a temporary file renamed into place, so a killed
        run leaves no half-written file).
    """
    path = Path(path)
    data = hpl_text(ds, path.name).encode("ascii")
    try:
        write_bytes_atomic(path, data)
    except OSError as exc:
        raise CwprocError(f"write_hpl {path}: cannot write: {exc.strerror or exc}") from None
    return path
