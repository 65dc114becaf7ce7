"""Quicklook of a Monte-Carlo error study (``cwproc simulate montecarlo``).

Relative RMS errors of epsilon, of the variance and of the integral scale against the
number of scans N, one line per height (Banakh et al. (1999)).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.plots.axes import log_ticks
from cwproc.plots.figure import SEQUENTIAL_LOG, pyplot, refuse_empty


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
    plt = pyplot()
    refuse_empty(ds, tuple(n for n, _ in names), "montecarlo")
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
            log_ticks(ax.yaxis, float(finite.min()), float(finite.max()))
        ax.set_xlabel("number of scans N")
        ax.set_ylabel(f"{label} (%)")
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(title="height")
    title = "Monte-Carlo relative errors (Banakh et al. (1999))"
    if "realisations" in ds.attrs:
        title += f", {ds.attrs['realisations']} realisations"
    fig.suptitle(title)
    return fig
