"""The kinds of quicklook, the variables each needs, and :func:`render`.

:data:`KINDS` maps a ``kind`` (``cwproc plot --kind``) to its drawing function and the
variables the product must hold; :func:`render` checks them, draws and saves the PNG;
:func:`default_kind` picks the kind a product is best shown by.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import xarray as xr

from cwproc.errors import ProductError
from cwproc.plots.figure import save_png
from cwproc.plots.l1 import L1_VARIABLES, plot_doppler_lidar
from cwproc.plots.montecarlo import plot_montecarlo
from cwproc.plots.sf_types import plot_sf_types, plot_sf_window
from cwproc.plots.stare import STARE_VARIABLES, plot_stare
from cwproc.plots.turbulence import plot_epsilon, plot_structure_function
from cwproc.plots.wind import plot_wind

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
    "doppler-lidar": (plot_doppler_lidar, L1_VARIABLES),
    "stare": (plot_stare, STARE_VARIABLES),
}


def default_kind(ds: xr.Dataset) -> str:
    """The quicklook a product is best shown by (``cwproc plot`` without ``--kind``).

    A stare product is drawn as ``stare``, the L1 product as ``doppler-lidar``; then the
    first of Monte-Carlo, epsilon, wind and sf-types whose variables ``ds`` holds.

    Raises
    ------
    ProductError
        ``ds`` holds the variables of none of them.
    """
    for kind in ("stare", "doppler-lidar", "montecarlo", "epsilon", "wind", "sf-types"):
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
