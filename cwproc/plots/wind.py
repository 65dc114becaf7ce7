"""Wind quicklooks: the wind product (``wind``) and one scan's VAD fit (``vad``).

``wind``: time-height of the horizontal wind speed with direction barbs and of w, or
profiles for a product of one scan. ``vad``: the radial velocities of one scan against
azimuth with the fitted VAD curve and the residuals.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.errors import ProductError
from cwproc.physics.geometry import radial_velocity
from cwproc.plots.axes import profile, time_height_mesh
from cwproc.plots.figure import (
    DIVERGING,
    FIGSIZE,
    SEQUENTIAL,
    axis_label,
    one_time_step,
    pyplot,
    refuse_empty,
    time_text,
)


def plot_wind(ds: xr.Dataset):
    """Time-height of horizontal wind speed with direction barbs, and of w.

    A product of one time step (one scan) is drawn as profiles of speed, direction
    and w instead: a time-height picture of one column has no width.
    """
    plt = pyplot()
    refuse_empty(ds, ("wind_speed",), "wind")
    if one_time_step(ds):
        return _plot_wind_profiles(ds)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=FIGSIZE, sharex=True, constrained_layout=True)
    time_height_mesh(
        ax1, ds["wind_speed"], cmap=SEQUENTIAL, label=axis_label(ds["wind_speed"], "wind speed")
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

    time_height_mesh(
        ax2, w, cmap=DIVERGING, norm=Normalize(-lim, lim), label=axis_label(w, "vertical wind")
    )
    ax2.set_title("vertical wind w")
    ax2.set_xlabel("time (UTC)")
    return fig


def _plot_wind_profiles(ds: xr.Dataset):
    """Profiles of speed, direction and w of a one-scan wind product."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=FIGSIZE, sharey=True, constrained_layout=True)
    profile(axes[0], ds["wind_speed"], label="wind speed")
    axes[0].set_xlabel("horizontal wind speed (m s$^{-1}$)")
    profile(axes[1], ds["wind_direction"], label="direction", color="C1")
    axes[1].set_xlabel("wind direction (degree, from)")
    profile(axes[2], ds["w"], label="w", color="C2")
    axes[2].axvline(0.0, color="0.4", lw=0.8)
    axes[2].set_xlabel("vertical wind w (m s$^{-1}$)")
    for ax in axes[1:]:
        ax.set_ylabel("")
    fig.suptitle(f"wind profile, {time_text(ds)} (one time step)")
    return fig


def plot_vad_fit(
    scans: xr.Dataset, wind: xr.Dataset, *, scan: int | None = None, height: float | None = None
):
    """One scan's radial velocities against azimuth with the fitted VAD curve and residuals."""
    plt = pyplot()
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
