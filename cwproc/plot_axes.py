"""Fixed scales of the quicklooks, so that two days' pictures can be compared.

The dissipation rate is drawn on one log colour range, :data:`EPSILON_RANGE`, whatever
the file holds (values beyond it take the end colours, and the colour bar's pointed ends
say so), and time-height pictures span the whole UTC day(s) of their data, 00-24 UTC,
rather than the data alone. ``cwproc plot --eps-range LO HI`` changes the range.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cwproc.errors import ProductError

#: colour range of epsilon quicklooks (m2 s-3): from calm nights to strong convection
EPSILON_RANGE: tuple[float, float] = (1e-5, 1e-1)

_DAY = np.timedelta64(1, "D")


def epsilon_range(value: tuple[float, float] | None) -> tuple[float, float]:
    """The colour range of an epsilon picture: ``value``, or :data:`EPSILON_RANGE`.

    Raises
    ------
    ProductError
        The range is not two positive numbers, the first below the second.
    """
    lo, hi = EPSILON_RANGE if value is None else (float(value[0]), float(value[1]))
    if not (0 < lo < hi < np.inf):
        raise ProductError(
            f"epsilon range {lo:g} .. {hi:g}: needs two positive values, the first smaller"
        )
    return lo, hi


def utc_day_limits(times: np.ndarray) -> tuple[np.datetime64, np.datetime64]:
    """00 UTC of the first day of ``times`` and 00 UTC of the day after the last.

    Raises
    ------
    ProductError
        ``times`` holds no valid time.
    """
    t = np.asarray(times, dtype="datetime64[ns]")
    t = t[~np.isnat(t)]
    if not t.size:
        raise ProductError("no valid time to draw")
    first = t.min().astype("datetime64[D]")
    last = t.max().astype("datetime64[D]")
    return first.astype("datetime64[ns]"), (last + _DAY).astype("datetime64[ns]")


def whole_utc_day(ax: Any, times: np.ndarray) -> None:
    """Show the whole UTC day(s) of ``times`` on the time axis of ``ax`` (ticks every 3 h).

    The axis label names the day, so that the ticks need only the hour.
    """
    import matplotlib.dates as mdates

    start, end = utc_day_limits(times)
    ax.set_xlim(start, end)
    days = int((end - start) / _DAY)
    ax.xaxis.set_major_locator(mdates.HourLocator(byhour=range(0, 24, 3 * days)))
    ax.xaxis.set_minor_locator(mdates.HourLocator())
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%H:%M" if days == 1 else "%d %H:%M"))
    day = str(start.astype("datetime64[D]"))
    if days > 1:
        day += f" - {(end - _DAY).astype('datetime64[D]')}"
    ax.set_xlabel(f"time (UTC), {day}")
