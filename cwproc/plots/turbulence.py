"""Turbulence quicklooks of the conical-scan product: epsilon and the structure function.

``epsilon``: time-height of the dissipation rate (method 2, log colours on the fixed
:data:`cwproc.plots.axes.EPSILON_RANGE`) and of the bias of method 1, eps1/eps2, or
profiles for a product of one block. ``structure``: the azimuth structure function D_L
of one block and height against lag, with the fitted model and the noise floor
2 sigma_e^2 (Smalikho (2020), eq. 4).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.errors import ProductError
from cwproc.plots.axes import epsilon_range, log_ticks, profile, time_height_mesh, whole_utc_day
from cwproc.plots.figure import (
    DIVERGING,
    FIGSIZE,
    SEQUENTIAL_LOG,
    all_missing,
    axis_label,
    one_time_step,
    pyplot,
    refuse_empty,
    time_text,
)


def ratio_shown(ds: xr.Dataset) -> xr.DataArray:
    """eps1/eps2 only where method 1 has an estimate (its flag 4 leaves it empty)."""
    ratio = ds["epsilon_ratio"]
    if "epsilon_method1" in ds:
        ratio = ratio.where(np.isfinite(ds["epsilon_method1"]))
    return ratio


def _plot_epsilon_profiles(ds: xr.Dataset):
    """Profiles of eps (both methods, log axis) and eps1/eps2 of a one-block product."""
    plt = pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=FIGSIZE, sharey=True, constrained_layout=True)
    eps = ds["epsilon"].where(ds["epsilon"] > 0)
    profile(ax1, eps, label="$\\varepsilon$ (method 2)", log=True)
    if "epsilon_method1" in ds and not all_missing(ds["epsilon_method1"]):
        eps1 = ds["epsilon_method1"].where(ds["epsilon_method1"] > 0)
        profile(
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
    log_ticks(ax1.xaxis, float(finite.min()), float(finite.max()))
    ax1.set_xlabel("dissipation rate (m$^2$ s$^{-3}$)")
    ax1.legend()
    ratio = ratio_shown(ds)
    if all_missing(ratio):
        ax2.text(
            0.5,
            0.5,
            "no method-1 estimate\n(mu beyond method 1 at every height)",
            ha="center",
            va="center",
            transform=ax2.transAxes,
        )
    else:
        profile(ax2, ratio, label="$\\varepsilon_1/\\varepsilon_2$", color="C3")
    ax2.axvline(1.0, color="0.4", lw=0.8)
    ax2.set_xlabel("bias of method 1: $\\varepsilon_1/\\varepsilon_2$")
    ax2.set_ylabel("")
    fig.suptitle(f"dissipation rate, block at {time_text(ds)} (one time step)")
    return fig


def plot_epsilon(ds: xr.Dataset, *, eps_range: tuple[float, float] | None = None):
    """Time-height of the dissipation rate (method 2, log scale) and of eps1/eps2.

    The colours of epsilon span ``eps_range`` (m2 s-3; default
    :data:`cwproc.plots.axes.EPSILON_RANGE`, the same for every file) and the time axis
    the whole UTC day of the data. eps1/eps2 is drawn only where method 1 has an
    estimate. A product of one block is drawn as profiles instead.
    """
    plt = pyplot()
    from matplotlib.colors import LogNorm, TwoSlopeNorm

    lo, hi = epsilon_range(eps_range)
    refuse_empty(ds, ("epsilon",), "epsilon")
    if one_time_step(ds):
        return _plot_epsilon_profiles(ds)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=FIGSIZE, sharex=True, constrained_layout=True)
    eps = ds["epsilon"].where(ds["epsilon"] > 0)
    eps.attrs = {"long_name": "dissipation rate", "units": ds["epsilon"].attrs.get("units", "")}
    norm = LogNorm(lo, hi)  # values beyond the fixed range: the end colours, pointed ends
    label = axis_label(eps, "dissipation rate")
    cbar = time_height_mesh(ax1, eps, cmap=SEQUENTIAL_LOG, norm=norm, label=label, extend="both")
    log_ticks(cbar, lo, hi)
    ax1.set_title("dissipation rate $\\varepsilon$ (method 2: volume averaging + wind transport)")
    ratio = ratio_shown(ds)
    finite_ratio = ratio.values[np.isfinite(ratio.values)]
    vmin = min(0.5, float(finite_ratio.min())) if finite_ratio.size else 0.5
    vmax = max(1.5, float(finite_ratio.max())) if finite_ratio.size else 2.0
    time_height_mesh(
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
    plt = pyplot()
    blk = ds.isel(time=time_index)
    if height is None:
        finite = np.isfinite(blk["epsilon"].values)
        idx = int(np.flatnonzero(finite)[len(np.flatnonzero(finite)) // 2]) if finite.any() else 0
        blk = blk.isel(height=idx)
    else:
        blk = blk.sel(height=height, method="nearest")
    if all_missing(blk["structure_function"]):
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
