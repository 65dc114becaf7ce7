"""One checked conversion of instrument times: plausible dates or a clear error.

Instrument clocks and damaged files produce times no instrument measured: a flipped
year in a header, a seconds counter of 99999999999999 (which wraps when converted to
nanoseconds), the zero padding of a logger file (its epoch, 1990-01-01). Every reader
passes its times through :func:`check_times` (datetime64 values) or converts epoch
seconds with :func:`epoch_seconds_to_times`, so that such a time is an error naming
the file and the line (or record) instead of a product for a bogus day.

Times are checked **before** any conversion to nanoseconds: datetime64[ns] holds only
the years 1677-2262, and a year such as 2590 converted to it wraps silently to 2005
(issue 34.1). :func:`check_times` compares in the unit the parser produced,
:func:`check_year` compares a parsed year as an integer, and the error quotes the
stamp as written in the file when the reader gives it.

The plausible window is from :data:`EARLIEST` (no coherent Doppler lidar or sonic
file cwproc reads predates it) to two days after the present (clocks a little ahead).
A configuration can widen it (``[instrument] earliest_date`` and ``latest_date``),
for archives of older instruments or simulated futures: :func:`set_plausible_window`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from cwproc.errors import InputFileError

#: earliest plausible measurement time (UTC)
EARLIEST = np.datetime64("1995-01-01T00:00:00", "ns")
#: how far ahead of the present a clock may be
AHEAD = np.timedelta64(2, "D")


#: the window set by the configuration: (earliest, latest or None for now + AHEAD)
_window: tuple[np.datetime64, np.datetime64 | None] = (EARLIEST, None)

#: how the message tells the user to widen the window
WIDEN_HINT = "widen with [instrument] earliest_date / latest_date"


def set_plausible_window(earliest: str | None = None, latest: str | None = None) -> None:
    """Set the plausible window of every reader in this process (the configuration's).

    Parameters
    ----------
    earliest : str or None
        ISO date (``"1990-01-01"``); None or ``""``: :data:`EARLIEST`.
    latest : str or None
        ISO date; None or ``""``: the present plus :data:`AHEAD`.
    """
    global _window
    low = np.datetime64(earliest, "s").astype("datetime64[ns]") if earliest else EARLIEST
    high = np.datetime64(latest, "s").astype("datetime64[ns]") if latest else None
    _window = (low, high)


def earliest_plausible() -> np.datetime64:
    """The start of the plausible window (datetime64[ns])."""
    return _window[0]


def latest_plausible() -> np.datetime64:
    """The end of the plausible window: the configured date, else now plus :data:`AHEAD`."""
    return _window[1] if _window[1] is not None else np.datetime64("now", "ns") + AHEAD


def window_text() -> str:
    """The plausible window in words, for messages."""
    high = _window[1]
    end = "now + 2 days" if high is None else np.datetime_as_string(high, unit="D")
    return f"{np.datetime_as_string(earliest_plausible(), unit='D')} .. {end}"


def _bounds_in(unit_dtype: np.dtype) -> tuple[np.datetime64, np.datetime64]:
    """The window in ``unit_dtype``'s own unit (seconds when it has none)."""
    unit = np.datetime_data(unit_dtype)[0]
    if unit == "generic":
        unit = "s"
    low = earliest_plausible().astype("datetime64[s]").astype(f"datetime64[{unit}]")
    high = latest_plausible().astype("datetime64[s]").astype(f"datetime64[{unit}]")
    return low, high


def first_implausible(times: np.ndarray) -> int | None:
    """Index of the first time outside the plausible window (NaT ignored), or ``None``.

    Compared in the unit of ``times`` (never converted to nanoseconds first: a year
    beyond 2262 would wrap).
    """
    t = np.asarray(times)
    if t.dtype.kind != "M":
        t = t.astype("datetime64[s]")
    low, high = _bounds_in(t.dtype)
    valid = ~np.isnat(t)
    bad = np.flatnonzero(valid & ((t < low) | (t > high)))
    return int(bad[0]) if bad.size else None


def plausible_years() -> tuple[int, int]:
    """First and last calendar year of the plausible window (integers)."""
    low = int(str(np.datetime_as_string(earliest_plausible(), unit="Y")))
    high = int(str(np.datetime_as_string(latest_plausible(), unit="Y")))
    return low, high


def check_year(
    path: str | os.PathLike, year: int, line: int | None, written: str, *, unit: str = "line"
) -> None:
    """Refuse a parsed calendar year outside the plausible window, as an integer.

    Called by readers that parse the year themselves, before they build any datetime
    from it. ``written`` is the stamp as the file writes it (quoted in the message).
    """
    low, high = plausible_years()
    if not low <= int(year) <= high:
        raise InputFileError(
            path,
            f"time {written.strip()!r} is outside the plausible range {window_text()} "
            f"({WIDEN_HINT})",
            line,
            unit=unit,
        )


def check_times(
    path: str | os.PathLike,
    times: np.ndarray,
    first_line: int | None,
    *,
    unit: str = "line",
    written: Sequence[str] | None = None,
) -> np.ndarray:
    """``times`` as datetime64[ns] if all are plausible; else an error naming the line.

    Parameters
    ----------
    path : path
        The file (for the message).
    times : ndarray of datetime64
        One time per record, in file order, in the unit the parser gave (checked in
        that unit, converted to nanoseconds only when plausible).
    first_line : int or None
        Line (or record) number of the first time; the error names ``first_line + i``.
    unit : str
        ``"line"`` or ``"record"`` (binary files).
    written : sequence of str, optional
        The stamps as written in the file; the error quotes the bad one.

    Raises
    ------
    InputFileError
        A time before the start of the plausible window or after its end.
    """
    t = np.asarray(times)
    i = first_implausible(t)
    if i is not None:
        stamp = (
            repr(str(written[i]).strip())
            if written is not None
            else np.datetime_as_string(t[i], unit="s")
        )
        raise InputFileError(
            path,
            f"time {stamp} is outside the plausible range {window_text()} ({WIDEN_HINT})",
            None if first_line is None else first_line + i,
            unit=unit,
        )
    return t.astype("datetime64[ns]")


def epoch_seconds_to_times(
    path: str | os.PathLike,
    seconds: np.ndarray,
    nanoseconds: np.ndarray,
    epoch: np.datetime64,
    first_line: int,
    *,
    unit: str = "line",
) -> np.ndarray:
    """``epoch + seconds + nanoseconds`` as datetime64[ns], checked before converting.

    The seconds are compared with the plausible window first, so a huge counter is an
    error instead of wrapping around the 64-bit nanosecond range.
    """
    secs = np.asarray(seconds, dtype=np.float64)
    low = (earliest_plausible() - epoch) / np.timedelta64(1, "s")
    high = (latest_plausible() - epoch) / np.timedelta64(1, "s")
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~np.isfinite(secs) | (secs < low) | (secs > high))
    if bad.size:
        i = int(bad[0])
        raise InputFileError(
            path,
            f"time counter {secs[i]:.0f} s after {np.datetime_as_string(epoch, unit='D')} is "
            f"outside the plausible range {window_text()} ({WIDEN_HINT})",
            first_line + i,
            unit=unit,
        )
    ns = secs.astype(np.int64) * 1_000_000_000 + np.asarray(nanoseconds).astype(np.int64)
    return np.datetime64(epoch, "ns") + ns.astype("timedelta64[ns]")
