"""Quicklooks of the sonic structure-function types (:mod:`cwproc.stages.sonic_sf`).

``sf-types``: the share of windows of each type per wind component. ``sf-window``: one
window's normalised structure function in lg-lg axes with its fit and r_max.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.plots.axes import log_ticks
from cwproc.plots.figure import FIGSIZE, pyplot, refuse_empty


def plot_sf_types(ds: xr.Dataset):
    """Occurrence of each structure-function type per wind component (bar chart)."""
    plt = pyplot()
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
    plt = pyplot()
    if window is None:
        typed = np.flatnonzero((ds["sf_type"] > 0).any("component").values)
        window = int(typed[0]) if typed.size else 0
    w = ds.isel(window=window)
    refuse_empty(w, ("normalised_sf",), "sf-window")
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
            log_ticks(axis, float(v.min()), float(v.max()))
    ax.set_xlabel("lag r (m)")
    ax.set_ylabel("normalised structure function D(r)/D(r$_S$)")
    t = np.datetime_as_string(w["time"].values, unit="m") if "time" in w else str(window)
    ax.set_title(f"window {window} ({t}): dotted lines mark r$_{{max}}$")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    return fig
