"""Quicklook of the Doppler lidar L1 product: beta, depolarisation and velocity.

Time-height panels as Cloudnet draws its ``doppler-lidar`` files: beta on a **fixed**
logarithmic range (1e-7 to 1e-4 m-1 sr-1, so that days compare), the depolarisation ratio
on 0-0.5 and the screened radial velocity on a diverging scale (the kind
``doppler-lidar`` of ``cwproc plot``).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.plots.axes import time_height_mesh
from cwproc.plots.figure import (
    DIVERGING,
    FIGSIZE,
    MISSING,
    SEQUENTIAL,
    SEQUENTIAL_LOG,
    pyplot,
)

#: beta colour range of the quicklook (m-1 sr-1), Cloudnet's for Doppler lidars
BETA_RANGE = (1e-7, 1e-4)


#: depolarisation ratio colour range
DEPOLARISATION_RANGE = (0.0, 0.5)


#: velocity colour range (m s-1)
VELOCITY_RANGE = (-2.0, 2.0)


#: variables the quicklook needs
L1_VARIABLES = ("beta_screened", "radial_velocity_screened", "doppler_lidar_flag")


def is_l1_product(ds: xr.Dataset) -> bool:
    """Whether ``ds`` is the L1 product (:mod:`cwproc.stages.doppler_lidar`)."""
    return all(v in ds.variables for v in L1_VARIABLES)


def _field(ds: xr.Dataset, name: str) -> xr.DataArray:
    """(time, height) view of a (time, range) variable, height as the vertical axis."""
    da = ds[name].transpose("time", "range")
    return xr.DataArray(
        np.asarray(da.values, dtype=float),
        dims=("time", "height"),
        coords={"time": ds["time"].values, "height": ds["height"].values},
    )


def plot_doppler_lidar(ds: xr.Dataset):
    """Figure of beta (log, fixed range), depolarisation (when present) and velocity."""
    from matplotlib.colors import LogNorm, Normalize

    plt = pyplot()
    panels = [("beta_screened", "attenuated backscatter (m-1 sr-1)")]
    if "depolarisation_screened" in ds:
        panels.append(("depolarisation_screened", "depolarisation ratio"))
    panels.append(("radial_velocity_screened", "radial velocity (m s-1)"))
    fig, axes = plt.subplots(
        len(panels),
        1,
        figsize=(FIGSIZE[0], 2.6 * len(panels)),
        sharex=True,
        constrained_layout=True,
    )
    for ax, (name, label) in zip(np.atleast_1d(axes), panels, strict=True):
        field = _field(ds, name)
        if name == "beta_screened":
            norm, cmap, extend = LogNorm(*BETA_RANGE), SEQUENTIAL_LOG, "both"
            field = field.where(field > 0)
        elif name == "depolarisation_screened":
            norm, cmap, extend = Normalize(*DEPOLARISATION_RANGE), SEQUENTIAL, "max"
        else:
            norm, cmap, extend = Normalize(*VELOCITY_RANGE), DIVERGING, "both"
        ax.set_facecolor(MISSING)
        time_height_mesh(ax, field, cmap=cmap, norm=norm, label=label, extend=extend)
        ax.set_title(label)
    fig.suptitle(f"Doppler lidar L1 {ds.attrs.get('id', '')!s}".strip())
    return fig
