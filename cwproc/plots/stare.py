"""Quicklook of the stare product (:mod:`cwproc.stages.stare`).

Time-height of w (every ray, else the window mean), of sigma_w^2 with the instrumental
noise removed and of the dissipation rate of O'Connor et al. (2010), the last two on log
colour scales; profiles for a product of one window.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.plots.axes import few_log_ticks, profile, time_height_mesh
from cwproc.plots.figure import (
    DIVERGING,
    FIGSIZE,
    MISSING,
    SEQUENTIAL_LOG,
    all_missing,
    one_time_step,
    pyplot,
    refuse_empty,
    time_text,
)

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


def w_per_ray(ds: xr.Dataset) -> tuple[xr.DataArray, int] | None:
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
    cbar = time_height_mesh(ax, positive, cmap=SEQUENTIAL_LOG, norm=norm, label=label)
    few_log_ticks(cbar, float(norm.vmin), float(norm.vmax))


def _plot_stare_profiles(ds: xr.Dataset):
    """Profiles of w_mean, sigma_w^2 and eps_stare of a stare product of one window."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=FIGSIZE, sharey=True, constrained_layout=True)
    profile(axes[0], ds["w_mean"], label="w")
    axes[0].axvline(0.0, color="0.4", lw=0.8)
    axes[0].set_xlabel("mean w (m s$^{-1}$)")
    for ax, name, text, colour in (
        (axes[1], "w_variance_corrected", "$\\sigma_w^2$, noise removed (m$^2$ s$^{-2}$)", "C1"),
        (axes[2], "epsilon_stare", "dissipation rate (m$^2$ s$^{-3}$)", "C2"),
    ):
        da = ds[name].where(ds[name] > 0)
        if all_missing(da):
            reason = _stare_flag_reason(ds) if name == "epsilon_stare" else "noise only"
            ax.text(
                0.5, 0.5, f"no value:\n{reason}", ha="center", va="center", transform=ax.transAxes
            )
        else:
            profile(ax, da, label=name, log=True, color=colour)
            finite = da.values[np.isfinite(da.values)]
            few_log_ticks(ax.xaxis, float(finite.min()), float(finite.max()))
        ax.set_xlabel(text)
        ax.set_ylabel("")
    fig.suptitle(f"vertical stare, window at {time_text(ds)} (one time step)")
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

    plt = pyplot()
    refuse_empty(ds, STARE_VARIABLES, "stare")
    if one_time_step(ds):
        return _plot_stare_profiles(ds)
    fig, axes = plt.subplots(3, 1, figsize=FIGSIZE, sharex=True, constrained_layout=True)
    per_ray = w_per_ray(ds)
    w, title = (
        (ds["w_mean"], f"mean w over {ds.attrs.get('window_s', '?')} s windows")
        if per_ray is None
        else (per_ray[0], "w of every ray" if per_ray[1] == 1 else f"w of one ray in {per_ray[1]}")
    )
    finite = np.abs(w.values[np.isfinite(w.values)])
    lim = float(np.percentile(finite, 99)) if finite.size else 1.0
    time_height_mesh(axes[0], w, cmap=DIVERGING, norm=Normalize(-lim, lim), label="w (m s$^{-1}$)")
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
