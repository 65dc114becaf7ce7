"""Axes of the quicklooks: time-height meshes, profiles, log ticks and the fixed scales.

The dissipation rate is drawn on one log colour range, :data:`EPSILON_RANGE`, whatever
the file holds (values beyond it take the end colours, and the colour bar's pointed ends
say so), and time-height pictures span the whole UTC day(s) of their data, 00-24 UTC,
rather than the data alone, so that two days' pictures can be compared
(``cwproc plot --eps-range LO HI`` changes the range). A log axis or colour bar gets at
least four labelled ticks where possible (:func:`log_ticks`), at most four on a small
panel (:func:`few_log_ticks`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from cwproc.errors import ProductError
from cwproc.plots.figure import MISSING, pyplot

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


def time_height_mesh(ax, ds: xr.DataArray, *, cmap: str, norm=None, label: str, extend="neither"):
    """pcolormesh of a (time, height) field with at least two time steps; NaN stays blank."""
    plt = pyplot()
    ax.set_facecolor(MISSING)
    data = np.ma.masked_invalid(ds.transpose("height", "time").values)
    mesh = ax.pcolormesh(
        ds["time"].values, ds["height"].values, data, cmap=cmap, norm=norm, shading="nearest"
    )
    cbar = plt.colorbar(mesh, ax=ax, pad=0.01, extend=extend)
    cbar.set_label(label)
    ax.set_ylabel("height above instrument (m)")
    import matplotlib.dates as mdates

    locator = mdates.AutoDateLocator()
    ax.xaxis.set_major_locator(locator)
    ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
    return cbar


def profile(ax, da: xr.DataArray, *, label: str, log: bool = False, **style):
    """A vertical profile (value against height) of a one-time-step field."""
    x = np.asarray(da.values, dtype=float).ravel()
    h = da["height"].values
    ok = np.isfinite(x)
    style = {"marker": "o", "ls": "-", "ms": 4, **style}
    ax.plot(x[ok], h[ok], label=label, **style)
    if log:
        ax.set_xscale("log")
    ax.set_ylabel("height above instrument (m)")
    ax.grid(alpha=0.3, which="both")


def log_tick_values(vmin: float, vmax: float) -> np.ndarray:
    """Ticks of a log axis over [vmin, vmax]: the powers of ten, else 1-2-5 per decade,
    else 1..9, else 1, 1.5, 2, 2.5, 3..9 -- the first that gives at least four."""
    lo, hi = np.floor(np.log10(vmin)), np.ceil(np.log10(vmax))
    decades = 10.0 ** np.arange(lo, hi + 1)
    halves = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0)
    for subs in ((1.0,), (1.0, 2.0, 5.0), tuple(range(1, 10)), halves):
        ticks = np.array([m * d for d in decades for m in subs])
        ticks = ticks[(ticks >= vmin * (1 - 1e-9)) & (ticks <= vmax * (1 + 1e-9))]
        if ticks.size >= 4:
            return ticks
    return ticks


def sci_label(value: float, _pos: int | None = None) -> str:
    """``6e-3`` as $6\\times10^{-3}$ and ``1e-2`` as $10^{-2}$ (every tick labelled)."""
    exponent = int(np.floor(np.log10(value) + 1e-9))
    mantissa = value / 10.0**exponent
    if abs(mantissa - 1.0) < 1e-6:
        return f"$10^{{{exponent}}}$"
    return f"${mantissa:.2g}\\times10^{{{exponent}}}$"


def _tick_labeller(ticks: np.ndarray):
    """Plain numbers (percent, metres) where they read well, powers of ten otherwise."""
    plain = bool(ticks.size) and ticks.min() >= 0.1 and ticks.max() < 1e5
    return (lambda v, _pos=None: f"{v:g}") if plain else sci_label


def _labelled_colorbar(cbar_or_axis, ticks: np.ndarray, label) -> bool:
    """Put ``ticks`` with their labels on a colour bar; False (nothing done) for an axis."""
    from matplotlib.colorbar import Colorbar
    from matplotlib.ticker import NullLocator

    if not isinstance(cbar_or_axis, Colorbar):
        return False
    cbar_or_axis.set_ticks(ticks, labels=[label(t) for t in ticks])
    cbar_or_axis.ax.yaxis.set_minor_locator(NullLocator())
    return True


def log_ticks(cbar_or_axis, vmin: float, vmax: float) -> None:
    """Label a log axis or colour bar with at least four ticks where possible.

    Matplotlib labels only the powers of ten (and a few minor ticks), which leaves two
    labels on a colour bar spanning about a decade.
    """
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    if not (vmin > 0 and vmax > vmin):
        return
    ticks = log_tick_values(vmin, vmax)
    label = _tick_labeller(ticks)
    if _labelled_colorbar(cbar_or_axis, ticks, label):
        return
    if cbar_or_axis.axis_name == "x":
        # labels side by side: keep those that do not touch, the rest become grid ticks
        labelled = _spaced_ticks(ticks, LABEL_GAP_DECADES * _log_span(vmin, vmax))
        cbar_or_axis.set_major_locator(FixedLocator(labelled))
        cbar_or_axis.set_minor_locator(FixedLocator(np.setdiff1d(ticks, labelled)))
        cbar_or_axis.set_minor_formatter(NullFormatter())
    else:
        cbar_or_axis.set_major_locator(FixedLocator(ticks))
        cbar_or_axis.set_minor_locator(NullLocator())
    cbar_or_axis.set_major_formatter(FuncFormatter(label))


#: smallest distance between two labels of a horizontal log axis, as a share of the
#: axis span in decades (a label such as 5x10^-3 is about a seventh of a panel wide)
LABEL_GAP_DECADES = 0.16


def _log_span(vmin: float, vmax: float) -> float:
    """Decades spanned by [vmin, vmax] with matplotlib's 5 % margins on either side."""
    return 1.1 * max(float(np.log10(vmax / vmin)), 0.05)


def _spaced_ticks(ticks: np.ndarray, min_gap: float) -> np.ndarray:
    """The ticks to label, at least ``min_gap`` decades apart: powers of ten first, then
    mantissas 2 and 5, then the others, each kept if it keeps the gap to those kept."""
    mantissa = np.round(ticks / 10.0 ** np.floor(np.log10(ticks) + 1e-9), 6)
    rank = np.where(mantissa == 1.0, 0, np.where(np.isin(mantissa, (2.0, 5.0)), 1, 2))
    kept: list[float] = []
    for t in ticks[np.argsort(rank, kind="stable")]:
        if all(abs(np.log10(t / k)) >= min_gap - 1e-12 for k in kept):
            kept.append(float(t))
    return np.sort(np.array(kept))


def few_log_ticks(cbar_or_axis, vmin: float, vmax: float, max_ticks: int = 4) -> None:
    """At most ``max_ticks`` labelled ticks on the log colour bar or axis of a small panel.

    The ticks of :func:`log_tick_values` (1-2-5 or 1..9 per decade), every n-th kept.
    """
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator

    if not (vmin > 0 and vmax > vmin):
        return
    ticks = log_tick_values(vmin, vmax)
    if ticks.size > max_ticks:
        ticks = ticks[:: int(np.ceil(ticks.size / max_ticks))]
    label = _tick_labeller(ticks)
    if _labelled_colorbar(cbar_or_axis, ticks, label):
        return
    cbar_or_axis.set_major_locator(FixedLocator(ticks))
    cbar_or_axis.set_major_formatter(FuncFormatter(label))
    cbar_or_axis.set_minor_locator(NullLocator())
