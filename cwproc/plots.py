"""Quicklooks of cwproc products (matplotlib, PNG).

Each ``plot_*`` function takes a product Dataset and returns a matplotlib Figure;
:func:`render` picks the function for a ``kind`` and checks that the product holds the
variables it needs, raising :class:`cwproc.errors.ProductError` with the missing names
otherwise. Colour maps are perceptually uniform and readable with colour-vision
deficiencies (cividis, viridis; RdBu_r for signed quantities); missing data are
drawn as gaps (grey background), never as zeros. A picture with nothing to draw
(every value missing) is refused with a :class:`ProductError` naming the reason; a
product of one time step is drawn as profiles.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.errors import ProductError
from cwproc.io.netcdf import remove_stale_temporaries, umask_mode
from cwproc.physics.geometry import radial_velocity
from cwproc.plot_axes import epsilon_range, whole_utc_day

#: figure size in inches and resolution of every quicklook
FIGSIZE = (10.0, 6.0)
DPI = 100

SEQUENTIAL = "cividis"
SEQUENTIAL_LOG = "viridis"
DIVERGING = "RdBu_r"
#: background of time-height panels: where a value is missing (also white of RdBu_r)
MISSING = "0.8"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _units(da: xr.DataArray) -> str:
    units = da.attrs.get("units", "")
    return f" ({units})" if units and units != "1" else ""


def _label(da: xr.DataArray, fallback: str) -> str:
    return str(da.attrs.get("long_name", fallback)) + _units(da)


def _time_height_mesh(ax, ds: xr.DataArray, *, cmap: str, norm=None, label: str, extend="neither"):
    """pcolormesh of a (time, height) field with at least two time steps; NaN stays blank."""
    plt = _pyplot()
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


def _log_tick_values(vmin: float, vmax: float) -> np.ndarray:
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


def _sci_label(value: float, _pos: int | None = None) -> str:
    """``6e-3`` as $6\\times10^{-3}$ and ``1e-2`` as $10^{-2}$ (every tick labelled)."""
    exponent = int(np.floor(np.log10(value) + 1e-9))
    mantissa = value / 10.0**exponent
    if abs(mantissa - 1.0) < 1e-6:
        return f"$10^{{{exponent}}}$"
    return f"${mantissa:.2g}\\times10^{{{exponent}}}$"


def _tick_labeller(ticks: np.ndarray):
    """Plain numbers (percent, metres) where they read well, powers of ten otherwise."""
    plain = bool(ticks.size) and ticks.min() >= 0.1 and ticks.max() < 1e5
    return (lambda v, _pos=None: f"{v:g}") if plain else _sci_label


def _labelled_colorbar(cbar_or_axis, ticks: np.ndarray, label) -> bool:
    """Put ``ticks`` with their labels on a colour bar; False (nothing done) for an axis."""
    from matplotlib.colorbar import Colorbar
    from matplotlib.ticker import NullLocator

    if not isinstance(cbar_or_axis, Colorbar):
        return False
    cbar_or_axis.set_ticks(ticks, labels=[label(t) for t in ticks])
    cbar_or_axis.ax.yaxis.set_minor_locator(NullLocator())
    return True


def _log_ticks(cbar_or_axis, vmin: float, vmax: float) -> None:
    """Label a log axis or colour bar with at least four ticks where possible.

    Matplotlib labels only the powers of ten (and a few minor ticks), which leaves two
    labels on a colour bar spanning about a decade.
    """
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    if not (vmin > 0 and vmax > vmin):
        return
    ticks = _log_tick_values(vmin, vmax)
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


def _all_missing(da: xr.DataArray) -> bool:
    return not np.isfinite(np.asarray(da.values, dtype=float)).any()


def _refuse_empty(ds: xr.Dataset, names: tuple[str, ...], kind: str) -> None:
    """Refuse to draw a picture whose variables hold no finite value."""
    if all(_all_missing(ds[n]) for n in names):
        raise ProductError(
            f"cannot draw '{kind}': {' and '.join(names)} "
            f"{'holds' if len(names) == 1 else 'hold'} no finite value "
            "(every estimate of the product is missing)"
        )


def _one_time_step(ds: xr.Dataset) -> bool:
    return "time" in ds.dims and ds.sizes["time"] == 1


def _time_text(ds: xr.Dataset) -> str:
    return np.datetime_as_string(ds["time"].values.ravel()[0], unit="m") + " UTC"


def _profile(ax, da: xr.DataArray, *, label: str, log: bool = False, **style):
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


def plot_wind(ds: xr.Dataset):
    """Time-height of horizontal wind speed with direction barbs, and of w.

    A product of one time step (one scan) is drawn as profiles of speed, direction
    and w instead: a time-height picture of one column has no width.
    """
    plt = _pyplot()
    _refuse_empty(ds, ("wind_speed",), "wind")
    if _one_time_step(ds):
        return _plot_wind_profiles(ds)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=FIGSIZE, sharex=True, constrained_layout=True)
    _time_height_mesh(
        ax1, ds["wind_speed"], cmap=SEQUENTIAL, label=_label(ds["wind_speed"], "wind speed")
    )
    # barbs on a thinned grid (at most ~25 x 15), only where the wind is defined
    nt, nh = ds.sizes["time"], ds.sizes["height"]
    st, sh = max(1, nt // 25), max(1, nh // 15)
    sub = ds.isel(time=slice(None, None, st), height=slice(None, None, sh))
    u = sub["u"].transpose("height", "time").values
    v = sub["v"].transpose("height", "time").values
    tt, hh = np.meshgrid(sub["time"].values, sub["height"].values)
    ok = np.isfinite(u) & np.isfinite(v)
    if ok.any():
        # barbs in knots-free convention: full barb = 10 m/s, half = 5 m/s
        ax1.barbs(
            tt[ok],
            hh[ok],
            u[ok],
            v[ok],
            length=5,
            linewidth=0.6,
            barb_increments={"half": 5, "full": 10, "flag": 50},
        )
    ax1.set_title("horizontal wind speed (barbs: direction, full barb = 10 m s$^{-1}$)")
    w = ds["w"]
    lim = float(np.nanmax(np.abs(w.values))) if np.isfinite(w.values).any() else 1.0
    from matplotlib.colors import Normalize

    _time_height_mesh(
        ax2, w, cmap=DIVERGING, norm=Normalize(-lim, lim), label=_label(w, "vertical wind")
    )
    ax2.set_title("vertical wind w")
    ax2.set_xlabel("time (UTC)")
    return fig


def _plot_wind_profiles(ds: xr.Dataset):
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=FIGSIZE, sharey=True, constrained_layout=True)
    _profile(axes[0], ds["wind_speed"], label="wind speed")
    axes[0].set_xlabel("horizontal wind speed (m s$^{-1}$)")
    _profile(axes[1], ds["wind_direction"], label="direction", color="C1")
    axes[1].set_xlabel("wind direction (degree, from)")
    _profile(axes[2], ds["w"], label="w", color="C2")
    axes[2].axvline(0.0, color="0.4", lw=0.8)
    axes[2].set_xlabel("vertical wind w (m s$^{-1}$)")
    for ax in axes[1:]:
        ax.set_ylabel("")
    fig.suptitle(f"wind profile, {_time_text(ds)} (one time step)")
    return fig


def _ratio_shown(ds: xr.Dataset) -> xr.DataArray:
    """eps1/eps2 only where method 1 has an estimate (its flag 4 leaves it empty)."""
    ratio = ds["epsilon_ratio"]
    if "epsilon_method1" in ds:
        ratio = ratio.where(np.isfinite(ds["epsilon_method1"]))
    return ratio


def _plot_epsilon_profiles(ds: xr.Dataset):
    plt = _pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=FIGSIZE, sharey=True, constrained_layout=True)
    eps = ds["epsilon"].where(ds["epsilon"] > 0)
    _profile(ax1, eps, label="$\\varepsilon$ (method 2)", log=True)
    if "epsilon_method1" in ds and not _all_missing(ds["epsilon_method1"]):
        eps1 = ds["epsilon_method1"].where(ds["epsilon_method1"] > 0)
        _profile(
            ax1,
            eps1,
            label="$\\varepsilon_1$ (method 1)",
            color="C1",
            marker="s",
            ls="--",
            mfc="none",
        )
    shown = [ds[n].values for n in ("epsilon", "epsilon_method1") if n in ds]
    finite = np.concatenate([v[np.isfinite(v) & (v > 0)] for v in shown])
    _log_ticks(ax1.xaxis, float(finite.min()), float(finite.max()))
    ax1.set_xlabel("dissipation rate (m$^2$ s$^{-3}$)")
    ax1.legend()
    ratio = _ratio_shown(ds)
    if _all_missing(ratio):
        ax2.text(
            0.5,
            0.5,
            "no method-1 estimate\n(mu beyond method 1 at every height)",
            ha="center",
            va="center",
            transform=ax2.transAxes,
        )
    else:
        _profile(ax2, ratio, label="$\\varepsilon_1/\\varepsilon_2$", color="C3")
    ax2.axvline(1.0, color="0.4", lw=0.8)
    ax2.set_xlabel("bias of method 1: $\\varepsilon_1/\\varepsilon_2$")
    ax2.set_ylabel("")
    fig.suptitle(f"dissipation rate, block at {_time_text(ds)} (one time step)")
    return fig


def plot_epsilon(ds: xr.Dataset, *, eps_range: tuple[float, float] | None = None):
    """Time-height of the dissipation rate (method 2, log scale) and of eps1/eps2.

    The colours of epsilon span ``eps_range`` (m2 s-3; default
    :data:`cwproc.plot_axes.EPSILON_RANGE`, the same for every file) and the time axis
    the whole UTC day of the data. eps1/eps2 is drawn only where method 1 has an
    estimate. A product of one block is drawn as profiles instead.
    """
    plt = _pyplot()
    from matplotlib.colors import LogNorm, TwoSlopeNorm

    lo, hi = epsilon_range(eps_range)
    _refuse_empty(ds, ("epsilon",), "epsilon")
    if _one_time_step(ds):
        return _plot_epsilon_profiles(ds)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=FIGSIZE, sharex=True, constrained_layout=True)
    eps = ds["epsilon"].where(ds["epsilon"] > 0)
    eps.attrs = {"long_name": "dissipation rate", "units": ds["epsilon"].attrs.get("units", "")}
    norm = LogNorm(lo, hi)  # values beyond the fixed range: the end colours, pointed ends
    label = _label(eps, "dissipation rate")
    cbar = _time_height_mesh(ax1, eps, cmap=SEQUENTIAL_LOG, norm=norm, label=label, extend="both")
    _log_ticks(cbar, lo, hi)
    ax1.set_title("dissipation rate $\\varepsilon$ (method 2: volume averaging + wind transport)")
    ratio = _ratio_shown(ds)
    finite_ratio = ratio.values[np.isfinite(ratio.values)]
    vmin = min(0.5, float(finite_ratio.min())) if finite_ratio.size else 0.5
    vmax = max(1.5, float(finite_ratio.max())) if finite_ratio.size else 2.0
    _time_height_mesh(
        ax2,
        ratio,
        cmap=DIVERGING,
        norm=TwoSlopeNorm(vcenter=1.0, vmin=vmin, vmax=vmax),
        label="$\\varepsilon_1/\\varepsilon_2$",
    )
    title = "bias of method 1 (no wind transport): $\\varepsilon_1/\\varepsilon_2$"
    if not finite_ratio.size:
        title += " - no method-1 estimate (mu too large)"
    ax2.set_title(title)
    whole_utc_day(ax2, ds["time"].values)  # both panels: they share the time axis
    return fig


def plot_structure_function(ds: xr.Dataset, *, time_index: int = 0, height: float | None = None):
    """D_L against lag for one block and height, with the fitted model and the noise floor."""
    plt = _pyplot()
    blk = ds.isel(time=time_index)
    if height is None:
        finite = np.isfinite(blk["epsilon"].values)
        idx = int(np.flatnonzero(finite)[len(np.flatnonzero(finite)) // 2]) if finite.any() else 0
        blk = blk.isel(height=idx)
    else:
        blk = blk.sel(height=height, method="nearest")
    if _all_missing(blk["structure_function"]):
        raise ProductError(
            f"cannot draw 'structure': no structure function at time index {time_index}, "
            f"height {float(blk['height']):.0f} m (no ray pairs there)"
        )
    fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
    lag = blk["lag"].values
    dy = float(blk["transverse_resolution"]) if "transverse_resolution" in blk else np.nan
    x = lag * dy if np.isfinite(dy) else lag
    ax.plot(x, blk["structure_function"].values, "o", label="measured $D_L$")
    if "structure_function_model" in blk:
        ax.plot(x, blk["structure_function_model"].values, "-", label="fitted model")
    if "noise_std" in blk and np.isfinite(float(blk["noise_std"])):
        floor = 2 * float(blk["noise_std"]) ** 2
        ax.axhline(floor, ls="--", color="0.4", label="noise floor $2\\sigma_e^2$")
    ax.set_xlabel("transverse lag $l\\Delta y$ (m)" if np.isfinite(dy) else "lag number l")
    ax.set_ylabel("$D_L$ (m$^2$ s$^{-2}$)")
    t = np.datetime_as_string(blk["time"].values, unit="m")
    eps = float(blk["epsilon"]) if "epsilon" in blk else np.nan
    ax.set_title(
        f"azimuth structure function, {t} UTC, h = {float(blk['height']):.0f} m, "
        f"$\\varepsilon$ = {eps:.2e} m$^2$ s$^{{-3}}$"
    )
    ax.legend()
    ax.grid(alpha=0.3)
    return fig


def plot_vad_fit(
    scans: xr.Dataset, wind: xr.Dataset, *, scan: int | None = None, height: float | None = None
):
    """One scan's radial velocities against azimuth with the fitted VAD curve and residuals."""
    plt = _pyplot()
    if scan is None:
        scan = int(wind["scan"].values[len(wind["scan"]) // 2])
    row = wind.where(wind["scan"] == scan, drop=True).isel(time=0)
    if height is None:
        height = float(row["height"].values[len(row["height"]) // 4])
    row = row.sel(height=height, method="nearest")
    gate = int(np.argmin(np.abs(scans["range"].values - float(row["range"]))))
    rays = scans.where(scans["scan"] == scan, drop=True).isel(range=gate)
    az = rays["azimuth"].values
    vr = rays["radial_velocity"].values
    good = np.ones_like(vr, dtype=bool)
    if "qc_flag_radial" in rays:
        good = rays["qc_flag_radial"].values == 0
    if not np.isfinite(float(row["u"])) or not np.isfinite(vr[good]).any():
        raise ProductError(
            f"cannot draw 'vad': scan {scan} has no VAD fit at h = {float(row['height']):.0f} m "
            f"(qc_flag {int(row['qc_flag']) if 'qc_flag' in row else 'unknown'})"
        )
    wind = (float(row["u"]), float(row["v"]), float(row["w"]))
    theta = np.radians(np.linspace(0, 360, 361))
    model = radial_velocity(*wind, np.degrees(theta), float(row["elevation"]))
    fitted = radial_velocity(*wind, az, float(row["elevation"]))
    fig, (ax1, ax2) = plt.subplots(
        2,
        1,
        figsize=FIGSIZE,
        sharex=True,
        gridspec_kw={"height_ratios": [3, 1]},
        constrained_layout=True,
    )
    ax1.plot(az[good], vr[good], "o", label="radial velocity (used)")
    if (~good).any():
        ax1.plot(az[~good], vr[~good], "x", color="0.5", label="screened out")
    ax1.plot(np.degrees(theta), model, "-", label="VAD fit")
    ax1.set_ylabel("radial velocity (m s$^{-1}$)")
    ax1.set_title(
        f"scan {scan}, h = {float(row['height']):.0f} m: U = {float(row['wind_speed']):.2f} "
        f"m s$^{{-1}}$ from {float(row['wind_direction']):.0f}°, w = {float(row['w']):.2f} "
        "m s$^{-1}$"
    )
    ax1.legend()
    ax2.axhline(0, color="0.4", lw=0.8)
    ax2.plot(az[good], (vr - fitted)[good], "o")
    ax2.set_xlabel("azimuth (degree from north)")
    ax2.set_ylabel("residual (m s$^{-1}$)")
    ax2.set_xlim(0, 360)
    return fig


def plot_sf_types(ds: xr.Dataset):
    """Occurrence of each structure-function type per wind component (bar chart)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
    comps = [str(c) for c in ds["component"].values]
    types = [0, 1, 2, 3]
    names = ["none", "type 1 (line)", "type 2 (parabola)", "type 3 (parabola + line)"]
    width = 0.2
    sf = ds["sf_type"]
    for k, (t, name) in enumerate(zip(types, names, strict=True)):
        share = [(sf.sel(component=c) == t).mean().item() * 100 for c in ds["component"].values]
        ax.bar(np.arange(len(comps)) + (k - 1.5) * width, share, width, label=name)
    ax.set_xticks(np.arange(len(comps)), comps)
    ax.set_ylabel("share of windows (%)")
    ax.set_title(f"structure-function types, {ds.sizes['window']} windows")
    ax.legend()
    return fig


def plot_sf_window(ds: xr.Dataset, *, window: int | None = None, component: str | None = None):
    """One window's normalised structure function in lg-lg axes with its fit and r_max."""
    plt = _pyplot()
    if window is None:
        typed = np.flatnonzero((ds["sf_type"] > 0).any("component").values)
        window = int(typed[0]) if typed.size else 0
    w = ds.isel(window=window)
    _refuse_empty(w, ("normalised_sf",), "sf-window")
    comps = [str(c) for c in w["component"].values] if component is None else [component]
    fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
    for c in comps:
        wc = w.sel(component=c)
        r = wc["lag_distance"].values
        d = wc["normalised_sf"].values
        (line,) = ax.loglog(r, d, ".", ms=3, label=f"{c}: type {int(wc['sf_type'])}")
        if "normalised_sf_fit" in wc:
            ax.loglog(r, wc["normalised_sf_fit"].values, "-", color=line.get_color())
        if np.isfinite(float(wc["r_max"])):
            ax.axvline(float(wc["r_max"]), ls=":", color=line.get_color())
    for axis, values in ((ax.xaxis, w["lag_distance"]), (ax.yaxis, w["normalised_sf"])):
        v = np.asarray(values.values, dtype=float)
        v = v[np.isfinite(v) & (v > 0)]
        if v.size:
            _log_ticks(axis, float(v.min()), float(v.max()))
    ax.set_xlabel("lag r (m)")
    ax.set_ylabel("normalised structure function D(r)/D(r$_S$)")
    t = np.datetime_as_string(w["time"].values, unit="m") if "time" in w else str(window)
    ax.set_title(f"window {window} ({t}): dotted lines mark r$_{{max}}$")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    return fig


def plot_montecarlo(ds: xr.Dataset):
    """Relative RMS errors of epsilon, variance and integral scale against N, per height.

    Log-log axes: the errors fall as N^(-1/2) (a straight line), and the large errors
    of N = 1 do not squash the rest of a panel.
    """
    names = [
        ("epsilon_rel_error", "$\\sigma_\\varepsilon$"),
        ("variance_rel_error", "$\\sigma_{\\sigma_V^2}$"),
        ("integral_scale_rel_error", "$\\sigma_{L_V}$"),
    ]
    plt = _pyplot()
    _refuse_empty(ds, tuple(n for n, _ in names), "montecarlo")
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.5), sharex=True, constrained_layout=True)
    cmap = plt.get_cmap(SEQUENTIAL_LOG)
    heights = ds["height"].values
    for ax, (name, label) in zip(axes, names, strict=True):
        for k, h in enumerate(heights):
            ax.plot(
                ds["n_scans"].values,
                100 * ds[name].sel(height=h).values,
                "o-",
                color=cmap(k / max(1, len(heights) - 1)),
                label=f"{h:.0f} m",
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        n = [int(k) for k in ds["n_scans"].values]
        shown = [k for k in n if k <= 6 or k % 2 == 0 or k == n[-1]]  # 9, 10 would touch
        ax.set_xticks(shown, [str(k) for k in shown])
        ax.minorticks_off()
        values = 100 * ds[name].values
        finite = values[np.isfinite(values) & (values > 0)]
        if finite.size:
            _log_ticks(ax.yaxis, float(finite.min()), float(finite.max()))
        ax.set_xlabel("number of scans N")
        ax.set_ylabel(f"{label} (%)")
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(title="height")
    title = "Monte-Carlo relative errors (Banakh et al. (1999))"
    if "realisations" in ds.attrs:
        title += f", {ds.attrs['realisations']} realisations"
    fig.suptitle(title)
    return fig


#: kind -> (function, variables the product must have)
KINDS: dict[str, tuple[Callable, tuple[str, ...]]] = {
    "wind": (plot_wind, ("u", "v", "w", "wind_speed")),
    "epsilon": (plot_epsilon, ("epsilon", "epsilon_ratio")),
    "structure": (plot_structure_function, ("structure_function", "epsilon")),
    "sf-types": (plot_sf_types, ("sf_type",)),
    "sf-window": (plot_sf_window, ("sf_type", "normalised_sf", "lag_distance", "r_max")),
    "montecarlo": (
        plot_montecarlo,
        ("epsilon_rel_error", "variance_rel_error", "integral_scale_rel_error"),
    ),
}


def default_kind(ds: xr.Dataset) -> str:
    """The quicklook a product is best shown by."""
    for kind in ("montecarlo", "epsilon", "wind", "sf-types"):
        if all(v in ds.variables for v in KINDS[kind][1]):
            return kind
    raise ProductError(
        "not a cwproc product this command can plot (no wind, epsilon, sonic SF or "
        "Monte-Carlo variables)"
    )


def check_variables(ds: xr.Dataset, kind: str, source: str = "product") -> None:
    """Raise ProductError naming the variables ``kind`` needs and ``ds`` lacks."""
    missing = [v for v in KINDS[kind][1] if v not in ds.variables]
    if missing:
        raise ProductError(
            f"{source}: cannot draw '{kind}': missing variable(s) {', '.join(missing)}"
        )


def render(
    ds: xr.Dataset, kind: str, out: str | os.PathLike, *, source: str = "product", **options
) -> Path:
    """Draw ``kind`` of ``ds`` into the PNG ``out`` (written atomically)."""
    check_variables(ds, kind, source)
    try:
        fig = KINDS[kind][0](ds, **options)
    except ProductError as exc:  # a picture refused: say of which file
        raise ProductError(f"{source}: {exc}") from None
    return save_png(fig, out)


def save_png(fig, out: str | os.PathLike) -> Path:
    """Save a figure as PNG through a temporary file, then close it."""
    plt = _pyplot()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(out.parent)  # of a plot killed earlier
    tmp = None
    try:  # an unpredictable name created exclusively: no planted symlink is followed
        fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
        with os.fdopen(fd, "wb") as fh:
            fig.savefig(fh, dpi=DPI, format="png")
        os.chmod(tmp, umask_mode())
        os.replace(tmp, out)
    except OSError as exc:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise ProductError(f"{out}: cannot write picture: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)
    return out


# ------------------------------------------------------------------ stare quicklook

#: at most this many rays drawn as columns of the per-ray w panel (every k-th ray beyond)
MAX_RAY_COLUMNS = 2000
#: a step between rays longer than this many median steps is drawn as a gap
RAY_GAP_FACTOR = 3.0
#: variables of the stare quicklook; refused when none holds a finite value
STARE_VARIABLES = ("w_mean", "w_variance_corrected", "epsilon_stare")


def is_stare_product(ds: xr.Dataset) -> bool:
    """Whether ``ds`` is a stare product (``cwproc.stages.stare``)."""
    return all(v in ds.variables for v in STARE_VARIABLES)


def _positive_log_norm(values: np.ndarray):
    """LogNorm over the 2-98 % range of the positive finite values (None: there are none)."""
    from matplotlib.colors import LogNorm

    finite = values[np.isfinite(values) & (values > 0)]
    if not finite.size:
        return None
    lo, hi = (float(v) for v in np.percentile(finite, [2, 98]))
    if not hi > lo:
        lo, hi = lo / 2.0, hi * 2.0
    return LogNorm(lo, hi)


def _w_per_ray(ds: xr.Dataset) -> tuple[xr.DataArray, int] | None:
    """``w_ray`` as a (time, height) field of every k-th ray, gaps as NaN columns.

    At most :data:`MAX_RAY_COLUMNS` rays are kept (every k-th, k returned); a step
    between kept rays longer than :data:`RAY_GAP_FACTOR` median steps (the VADs of a
    mixed day, a stop of the instrument) gets a NaN column so that it shows as a gap.
    None when the product has no ``w_ray`` or fewer than two rays.
    """
    if "w_ray" not in ds or "ray_time" not in ds.coords or ds.sizes.get("ray", 0) < 2:
        return None
    step = max(1, int(np.ceil(ds.sizes["ray"] / MAX_RAY_COLUMNS)))
    sub = ds["w_ray"].isel(ray=slice(None, None, step)).transpose("ray", "height")
    t = sub["ray_time"].values.astype("datetime64[ns]")
    values = np.asarray(sub.values, dtype=float)
    dt = np.diff(t).astype(np.int64)
    if dt.size:
        gaps = np.flatnonzero(dt > RAY_GAP_FACTOR * max(float(np.median(dt)), 1.0))
        t = np.insert(t, gaps + 1, t[gaps] + (t[gaps + 1] - t[gaps]) // 2)
        values = np.insert(values, gaps + 1, np.nan, axis=0)
    field = xr.DataArray(
        values,
        dims=("time", "height"),
        coords={"time": t, "height": ds["height"].values},
        attrs=dict(ds["w_ray"].attrs),
    )
    return field, step


def _stare_flag_reason(ds: xr.Dataset) -> str:
    """Why ``epsilon_stare`` is missing everywhere, from the bits of ``stare_flag``."""
    if "stare_flag" not in ds:
        return "no estimate"
    flags = np.bitwise_or.reduce(np.asarray(ds["stare_flag"].values, dtype=np.int64).ravel())
    reasons = {
        1: "no VAD wind this day (flag 1)",
        2: "too few rays (flag 2)",
        4: "variance not above the noise (flag 4)",
    }
    named = [text for bit, text in reasons.items() if flags & bit]
    return ", ".join(named) or "no estimate"


def _few_log_ticks(cbar_or_axis, vmin: float, vmax: float, max_ticks: int = 4) -> None:
    """At most ``max_ticks`` labelled ticks on the log colour bar or axis of a small panel.

    The ticks of :func:`_log_tick_values` (1-2-5 or 1..9 per decade), every n-th kept.
    """
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator

    if not (vmin > 0 and vmax > vmin):
        return
    ticks = _log_tick_values(vmin, vmax)
    if ticks.size > max_ticks:
        ticks = ticks[:: int(np.ceil(ticks.size / max_ticks))]
    label = _tick_labeller(ticks)
    if _labelled_colorbar(cbar_or_axis, ticks, label):
        return
    cbar_or_axis.set_major_locator(FixedLocator(ticks))
    cbar_or_axis.set_major_formatter(FuncFormatter(label))
    cbar_or_axis.set_minor_locator(NullLocator())


def _stare_log_panel(ax, da: xr.DataArray, *, title: str, label: str, reason: str) -> None:
    """A time-height panel of a positive field on a log colour scale, or the reason why not."""
    positive = da.where(da > 0)
    norm = _positive_log_norm(np.asarray(positive.values, dtype=float))
    ax.set_title(title)
    if norm is None:
        ax.set_facecolor(MISSING)
        ax.text(0.5, 0.5, f"no value: {reason}", ha="center", va="center", transform=ax.transAxes)
        h = np.asarray(da["height"].values, dtype=float)
        ax.set_ylim(float(h.min()), float(h.max()))
        return
    cbar = _time_height_mesh(ax, positive, cmap=SEQUENTIAL_LOG, norm=norm, label=label)
    _few_log_ticks(cbar, float(norm.vmin), float(norm.vmax))


def _plot_stare_profiles(ds: xr.Dataset):
    """Profiles of w_mean, sigma_w^2 and eps_stare of a stare product of one window."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=FIGSIZE, sharey=True, constrained_layout=True)
    _profile(axes[0], ds["w_mean"], label="w")
    axes[0].axvline(0.0, color="0.4", lw=0.8)
    axes[0].set_xlabel("mean w (m s$^{-1}$)")
    for ax, name, text, colour in (
        (axes[1], "w_variance_corrected", "$\\sigma_w^2$, noise removed (m$^2$ s$^{-2}$)", "C1"),
        (axes[2], "epsilon_stare", "dissipation rate (m$^2$ s$^{-3}$)", "C2"),
    ):
        da = ds[name].where(ds[name] > 0)
        if _all_missing(da):
            reason = _stare_flag_reason(ds) if name == "epsilon_stare" else "noise only"
            ax.text(
                0.5, 0.5, f"no value:\n{reason}", ha="center", va="center", transform=ax.transAxes
            )
        else:
            _profile(ax, da, label=name, log=True, color=colour)
            finite = da.values[np.isfinite(da.values)]
            _few_log_ticks(ax.xaxis, float(finite.min()), float(finite.max()))
        ax.set_xlabel(text)
        ax.set_ylabel("")
    fig.suptitle(f"vertical stare, window at {_time_text(ds)} (one time step)")
    return fig


def plot_stare(ds: xr.Dataset):
    """Time-height of w (every ray, else the window mean), sigma_w^2 and eps_stare.

    sigma_w^2 (``w_variance_corrected``, noise removed) and ``epsilon_stare`` (O'Connor
    et al. (2010)) on log colour scales; a panel with no positive value says why (the
    bits of ``stare_flag``: no VAD wind, too few rays, noise only). Refused when none
    of w_mean, sigma_w^2 and eps holds a finite value; a product of one window is
    drawn as profiles.
    """
    from matplotlib.colors import Normalize

    plt = _pyplot()
    _refuse_empty(ds, STARE_VARIABLES, "stare")
    if _one_time_step(ds):
        return _plot_stare_profiles(ds)
    fig, axes = plt.subplots(3, 1, figsize=FIGSIZE, sharex=True, constrained_layout=True)
    per_ray = _w_per_ray(ds)
    w, title = (
        (ds["w_mean"], f"mean w over {ds.attrs.get('window_s', '?')} s windows")
        if per_ray is None
        else (per_ray[0], "w of every ray" if per_ray[1] == 1 else f"w of one ray in {per_ray[1]}")
    )
    finite = np.abs(w.values[np.isfinite(w.values)])
    lim = float(np.percentile(finite, 99)) if finite.size else 1.0
    _time_height_mesh(axes[0], w, cmap=DIVERGING, norm=Normalize(-lim, lim), label="w (m s$^{-1}$)")
    axes[0].set_title(title)
    _stare_log_panel(
        axes[1],
        ds["w_variance_corrected"],
        title="variance of w, instrumental noise removed",
        label="$\\sigma_w^2$ (m$^2$ s$^{-2}$)",
        reason="the variance is not above the noise",
    )
    _stare_log_panel(
        axes[2],
        ds["epsilon_stare"],
        title="dissipation rate $\\varepsilon$ from the stares (O'Connor et al. (2010))",
        label="$\\varepsilon$ (m$^2$ s$^{-3}$)",
        reason=_stare_flag_reason(ds),
    )
    for ax in axes:  # three panels: the long label of the other kinds would overlap
        ax.set_ylabel("height (m)")
    axes[2].set_xlabel("time (UTC)")
    return fig


KINDS["stare"] = (plot_stare, STARE_VARIABLES)
