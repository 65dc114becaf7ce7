"""One checked conversion of instrument times: plausible dates or a clear error.

Instrument clocks and damaged files produce times no instrument measured: a flipped
year in a header, a seconds counter of 99999999999999 (which wraps when converted to
nanoseconds), the zero padding of a logger file (its epoch, 1990-01-01). Every reader
passes its times through :func:`check_times` (datetime64 values) or converts epoch
seconds with :func:`epoch_seconds_to_times`, so that such a time is an error naming
the file and the line (or record) instead of a product for a bogus day.

The plausible window is from :data:`EARLIEST` (no coherent Doppler lidar or sonic
file cwproc reads predates it) to two days after the present (clocks a little ahead).
"""

from __future__ import annotations

import os

import numpy as np

from cwproc.errors import InputFileError

#: earliest plausible measurement time (UTC)
EARLIEST = np.datetime64("1995-01-01T00:00:00", "ns")
#: how far ahead of the present a clock may be
AHEAD = np.timedelta64(2, "D")


def latest_plausible() -> np.datetime64:
    """The present (UTC) plus :data:`AHEAD`."""
    return np.datetime64("now", "ns") + AHEAD


def first_implausible(times: np.ndarray) -> int | None:
    """Index of the first time outside the plausible window (NaT ignored), or ``None``."""
    t = np.asarray(times).astype("datetime64[ns]")
    valid = ~np.isnat(t)
    bad = np.flatnonzero(valid & ((t < EARLIEST) | (t > latest_plausible())))
    return int(bad[0]) if bad.size else None


def check_times(
    path: str | os.PathLike,
    times: np.ndarray,
    first_line: int | None,
    *,
    unit: str = "line",
) -> np.ndarray:
    """``times`` as datetime64[ns] if all are plausible; else an error naming the line.

    Parameters
    ----------
    path : path
        The file (for the message).
    times : ndarray of datetime64
        One time per record, in file order.
    first_line : int or None
        Line (or record) number of the first time; the error names ``first_line + i``.
    unit : str
        ``"line"`` or ``"record"`` (binary files).

    Raises
    ------
    InputFileError
        A time before :data:`EARLIEST` or after the present plus :data:`AHEAD`.
    """
    t = np.asarray(times).astype("datetime64[ns]")
    i = first_implausible(t)
    if i is not None:
        stamp = np.datetime_as_string(t[i], unit="s")
        raise InputFileError(
            path,
            f"time {stamp} is outside the plausible range "
            f"{np.datetime_as_string(EARLIEST, unit='D')} .. now + 2 days",
            None if first_line is None else first_line + i,
            unit=unit,
        )
    return t


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
    low = (EARLIEST - epoch) / np.timedelta64(1, "s")
    high = (latest_plausible() - epoch) / np.timedelta64(1, "s")
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~np.isfinite(secs) | (secs < low) | (secs > high))
    if bad.size:
        i = int(bad[0])
        raise InputFileError(
            path,
            f"time counter {secs[i]:.0f} s after {np.datetime_as_string(epoch, unit='D')} is "
            f"outside the plausible range {np.datetime_as_string(EARLIEST, unit='D')} .. "
            "now + 2 days",
            first_line + i,
            unit=unit,
        )
    ns = secs.astype(np.int64) * 1_000_000_000 + np.asarray(nanoseconds).astype(np.int64)
    return np.datetime64(epoch, "ns") + ns.astype("timedelta64[ns]")
