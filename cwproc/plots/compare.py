"""The lidar-against-sonic picture: eps scatter on log axes, ratio vs stability and wind.

Three panels of a comparison product (:mod:`cwproc.stages.lidar_sonic`): lidar eps
against sonic eps on log axes with their standard errors as error bars and the 1:1
line; the ratio (log axis, with its error) against the sonic's stability z/L; the ratio
against the sonic's mean wind speed.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.errors import ProductError
from cwproc.plots.figure import pyplot, save_png


def plot_comparison(ds: xr.Dataset):
    """The figure of a comparison product (ProductError when no window is matched)."""
    eps_l = np.asarray(ds["lidar_epsilon"].values, dtype=float)
    eps_s = np.asarray(ds["sonic_epsilon"].values, dtype=float)
    ok = np.isfinite(eps_l) & np.isfinite(eps_s) & (eps_l > 0) & (eps_s > 0)
    if not ok.any():
        raise ProductError("no window has both a lidar and a sonic dissipation rate")
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(15.0, 5.0))
    ax = axes[0]
    ax.errorbar(
        eps_s[ok],
        eps_l[ok],
        xerr=np.nan_to_num(ds["sonic_epsilon_standard_error"].values[ok]),
        yerr=np.nan_to_num(ds["lidar_epsilon_standard_error"].values[ok]),
        fmt="o",
        ms=4,
        capsize=2,
    )
    lo = 0.5 * min(eps_s[ok].min(), eps_l[ok].min())
    hi = 2.0 * max(eps_s[ok].max(), eps_l[ok].max())
    ax.plot([lo, hi], [lo, hi], "k--", lw=1, label="1:1")
    ax.set(xscale="log", yscale="log", xlim=(lo, hi), ylim=(lo, hi))
    ax.set_xlabel("sonic epsilon (m2 s-3)")
    ax.set_ylabel(f"lidar epsilon at {float(ds['lidar_height']):.1f} m (m2 s-3)")
    ax.legend()
    ratio = np.asarray(ds["lidar_sonic_epsilon_ratio"].values, dtype=float)
    rerr = np.nan_to_num(np.asarray(ds["lidar_sonic_epsilon_ratio_error"].values, dtype=float))
    for ax, name, label in (
        (axes[1], "stability_parameter", "sonic z/L"),
        (axes[2], "mean_wind_speed", "sonic mean wind speed (m s-1)"),
    ):
        x = np.asarray(ds[name].values, dtype=float) if name in ds else np.full(ratio.size, np.nan)
        sel = ok & np.isfinite(x)
        if sel.any():
            ax.errorbar(x[sel], ratio[sel], yerr=rerr[sel], fmt="o", ms=4, capsize=2)
        else:
            ax.text(0.5, 0.5, f"no {label}", transform=ax.transAxes, ha="center")
        ax.axhline(1.0, color="k", ls="--", lw=1)
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("lidar / sonic epsilon")
    n = int(ds.attrs.get("summary_n_pairs", ok.sum()))
    gm = ds.attrs.get("summary_ratio_geometric_mean", np.nan)
    fig.suptitle(f"lidar vs sonic epsilon: {n} windows, geometric-mean ratio {gm:.3g}")
    fig.tight_layout()
    return fig


def write_comparison_png(ds: xr.Dataset, out: str | os.PathLike) -> Path:
    """Draw :func:`plot_comparison` into ``out`` (PNG, written atomically)."""
    return save_png(plot_comparison(ds), out)
