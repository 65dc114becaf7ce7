"""The removed-share curves of the table store (Banakh et al. (1999), eqs. 15-16).

:func:`mean_removed_share` is the share of sigma_V^2 the scan-mean (VAD) wind takes from
one scan's ``V'_L`` (:func:`cwproc.physics.removed_share.share_on_curve`) on the curve
of its elevation and model (:func:`cwproc.physics.removed_share.removed_share_curve`,
about 0.6 s of correlation functions), computed once and kept in memory and on disk
(:func:`cwproc.tables.store.cached_arrays`, keyed by its parameters and the hash of the
code of :mod:`cwproc.physics.removed_share`).
"""

from __future__ import annotations

import functools
import os

import numpy as np

from cwproc.physics.removed_share import (
    curve_log_x,
    curve_parameters,
    dense_grid_parameters,
    dense_reference_grid,
    removed_share_curve,
    share_on_curve,
    valid_curve,
    valid_dense_grid,
)
from cwproc.tables.store import cached_arrays, code_digest

#: the module whose code the curves depend on (:func:`cwproc.tables.store.code_digest`)
CODE_ROOT = "cwproc.physics.removed_share"


@functools.lru_cache(maxsize=16)
def stored_curve(
    phi_deg: float, model: str, cache_dir: str | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cwproc.physics.removed_share.removed_share_curve`, computed once per
    elevation (degrees) and model and kept on disk in ``cache_dir`` (default
    :func:`cwproc.tables.store.default_cache_dir`)."""
    params = curve_parameters(phi_deg, model) | {"code": code_digest(CODE_ROOT)}

    def compute() -> dict[str, np.ndarray]:
        return {"share": removed_share_curve(phi_deg, model)[1]}

    def valid(arrays: dict[str, np.ndarray]) -> bool:
        return valid_curve(arrays.get("share"))

    share = cached_arrays("removed-share", params, compute, valid, cache_dir)["share"]
    return curve_log_x(), share


def mean_removed_share(
    ratio: np.ndarray,
    phi_deg: float,
    model: str,
    mu: np.ndarray | float = 0.0,
    cache_dir: str | os.PathLike | None = None,
) -> np.ndarray:
    """Share of sigma_V^2 the scan-mean (VAD) wind takes from one scan's V'_L.

    :func:`cwproc.physics.removed_share.share_on_curve` at ``ratio = R'/L_V`` and
    ``mu = U/V_s`` on the stored curve of ``phi_deg`` (degrees, rounded to 0.01) and
    ``model``; the curve is kept in the cache folder ``cache_dir`` (default
    :func:`cwproc.tables.store.default_cache_dir`, as the A-tables).
    """
    folder = None if cache_dir is None else os.fspath(cache_dir)
    curve = stored_curve(round(float(phi_deg), 2), model, folder)
    return share_on_curve(curve, ratio, mu)


@functools.lru_cache(maxsize=64)
def stored_dense_grid(ref_lags: int, setting: tuple) -> np.ndarray:
    """:func:`cwproc.physics.removed_share.dense_reference_grid`, kept on disk in
    :func:`cwproc.tables.store.default_cache_dir` (3-6 s of correlations per
    ``(lags, N, T_int/T_scan, phi, model)``, otherwise paid by every run of a circle of
    more than 60 rays); pass it as ``dense_reference`` of
    :func:`cwproc.physics.removed_share.circle_removed_d`."""
    params = dense_grid_parameters(ref_lags, setting) | {"code": code_digest(CODE_ROOT)}

    def compute() -> dict[str, np.ndarray]:
        return {"grid": np.array(dense_reference_grid(ref_lags, setting))}

    def valid(arrays: dict[str, np.ndarray]) -> bool:
        return valid_dense_grid(arrays.get("grid"), ref_lags)

    grid = cached_arrays("removed-d-circle", params, compute, valid, None)["grid"]
    grid.flags.writeable = False  # shared by every caller through the cache
    return grid
