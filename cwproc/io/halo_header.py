"""Halo Photonics Stream Line ``.hpl`` files: the 17-line header.

The layout is described in ``real_data/FORMATS.md`` section 1: lines 1-11 are
``key: value`` pairs (:data:`_HEADER_KEYS`), then the range formula, the instrument
spectral width (on some firmware) and the descriptions of the ray and gate lines.
Header numbers may use a decimal comma (``30,0``, ``14:00:01,23``); ``No. of rays in
file`` (or ``No. of waypoints in file``) is unreliable and only kept as an attribute.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np

from cwproc.errors import InputFileError
from cwproc.io.timecheck import check_times, check_year

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
#: the keys of each header line, lower case (compared without case)
_HEADER_KEYS_LOWER = tuple(frozenset(k.lower() for k in keys) for keys in _HEADER_KEYS)

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


def parse_hpl_header(path: str | os.PathLike, lines: list[str]) -> HplHeader:
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
    values, rays_key = _keyed_values(path, lines)

    def field(i: int, convert, what: str):
        return _header_field(path, values, i, convert, what)

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
    m = _START_TIME.match(values[9])
    if m is not None:  # the year as an integer, before any date is built from it
        check_year(path, int(m.group(1)), 10, values[9])
    start = field(9, parse_start_time, "a time 'yyyymmdd HH:MM:SS.ss'")
    check_times(path, np.array([start]), 10, written=[values[9]])
    resolution = field(10, _number, "a number")
    formula = lines[11].strip()
    divisor, step = _range_formula(path, formula)
    _check_data_line_keys(path, lines)
    spectral_width = _spectral_width(path, lines[16].strip())
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


def _keyed_values(path: str | os.PathLike, lines: list[str]) -> tuple[list[str], str]:
    """The values of the 11 ``key: value`` lines, and the key of line 7 as written.

    Raises
    ------
    InputFileError
        A line does not start with its key (names the line).
    """
    values: list[str] = []
    rays_key = ""
    for i, keys in enumerate(_HEADER_KEYS):
        line = lines[i]
        key, sep, value = line.partition(":")
        key = key.strip()
        if not sep or key.lower() not in _HEADER_KEYS_LOWER[i]:
            expected = " or ".join(f"'{k}:'" for k in keys)
            raise InputFileError(
                path, f"header line should start with {expected}, found {line[:40]!r}", i + 1
            )
        if i == 6:
            rays_key = key
        values.append(value.strip())
    return values, rays_key


def _header_field(path: str | os.PathLike, values: list[str], i: int, convert, what: str):
    """``convert(values[i])``; a value it refuses raises :class:`InputFileError` naming
    the key, the value, what it should be (``what``) and the line."""
    try:
        return convert(values[i])
    except (ValueError, OverflowError):
        raise InputFileError(
            path, f"{_HEADER_KEYS[i][0]}: {values[i]!r} is not {what}", i + 1
        ) from None


def _range_formula(path: str | os.PathLike, formula: str) -> tuple[float | None, float | None]:
    """Divisor and step (m) of an overlapping-gate range formula (line 12); both None for
    the standard ``(range gate + 0.5) * Gate length``.

    Raises
    ------
    InputFileError
        The formula is neither, or its numbers are implausible.
    """
    if _RANGE_STANDARD.match(formula) is not None:
        return None, None
    m = _RANGE_OVERLAPPING.match(formula)
    if m is None:
        raise InputFileError(
            path, f"unknown range formula {formula[:80]!r} (line 12 of the header)", 12
        )
    divisor, step = _number(m.group(1)), _number(m.group(2))
    if not (0 < divisor < 10 and 0 < step < 100):
        raise InputFileError(path, f"implausible range formula {formula!r}", 12)
    return divisor, step


def _check_data_line_keys(path: str | os.PathLike, lines: list[str]) -> None:
    """Lines 13 and 15 start as a Stream Line writes them (``Data line 1:``, ``2:``)."""
    for number, prefix in ((13, "Data line 1:"), (15, "Data line 2:")):
        if not lines[number - 1].startswith(prefix):
            raise InputFileError(
                path,
                f"header line should start with {prefix!r}, found {lines[number - 1][:40]!r}",
                number,
            )


def _spectral_width(path: str | os.PathLike, last: str) -> float | None:
    """The instrument spectral width (m s-1) of the last header line (``****`` alone:
    None).

    Raises
    ------
    InputFileError
        The line is not ``****``, nor ``**** Instrument spectral width = <number>``.
    """
    if not last.startswith("****"):
        raise InputFileError(path, f"header should end with a '****' line, found {last[:40]!r}", 17)
    if last == "****":
        return None
    m = _SPECTRAL_WIDTH.match(last)
    try:
        spectral_width = _number(m.group(1)) if m else None
    except ValueError:
        spectral_width = None
    if spectral_width is None:
        raise InputFileError(path, f"unexpected end-of-header line {last[:60]!r}", 17)
    return spectral_width


LINE_END = re.compile(rb"\r\n|\n|\r")


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
        m = LINE_END.search(raw, pos)
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
