"""Quicklooks of cwproc products (matplotlib, PNG), one module per thing drawn.

Each ``plot_*`` function takes a product Dataset and returns a matplotlib Figure;
:func:`render` picks the function for a ``kind`` (:data:`KINDS`) and checks that the
product holds the variables it needs, raising :class:`cwproc.errors.ProductError` with
the missing names otherwise; :func:`save_png` writes a figure atomically.

Modules:

* :mod:`~cwproc.plots.figure`: figure size, colour maps, pyplot, the PNG file;
* :mod:`~cwproc.plots.axes`: time-height meshes, profiles, log ticks, fixed scales;
* :mod:`~cwproc.plots.wind`: the wind product and one scan's VAD fit;
* :mod:`~cwproc.plots.turbulence`: epsilon and the azimuth structure function;
* :mod:`~cwproc.plots.stare`: the stare product;
* :mod:`~cwproc.plots.sf_types`: the sonic structure-function types;
* :mod:`~cwproc.plots.montecarlo`: a Monte-Carlo error study;
* :mod:`~cwproc.plots.l1`: the Doppler lidar L1 product;
* :mod:`~cwproc.plots.compare`: lidar against sonic;
* :mod:`~cwproc.plots.kinds`: the kinds of ``cwproc plot`` and :func:`render`.

matplotlib is imported on first drawing, not with this package.
"""

from __future__ import annotations

from cwproc.plots.axes import EPSILON_RANGE
from cwproc.plots.compare import plot_comparison, write_comparison_png
from cwproc.plots.figure import DPI, FIGSIZE, save_png
from cwproc.plots.kinds import KINDS, check_variables, default_kind, render
from cwproc.plots.l1 import is_l1_product, plot_doppler_lidar
from cwproc.plots.montecarlo import plot_montecarlo
from cwproc.plots.sf_types import plot_sf_types, plot_sf_window
from cwproc.plots.stare import is_stare_product, plot_stare
from cwproc.plots.turbulence import plot_epsilon, plot_structure_function
from cwproc.plots.wind import plot_vad_fit, plot_wind

__all__ = [
    "DPI",
    "EPSILON_RANGE",
    "FIGSIZE",
    "KINDS",
    "check_variables",
    "default_kind",
    "is_l1_product",
    "is_stare_product",
    "plot_comparison",
    "plot_doppler_lidar",
    "plot_epsilon",
    "plot_montecarlo",
    "plot_sf_types",
    "plot_sf_window",
    "plot_stare",
    "plot_structure_function",
    "plot_vad_fit",
    "plot_wind",
    "render",
    "save_png",
    "write_comparison_png",
]
