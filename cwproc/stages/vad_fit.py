"""Moved to :mod:`cwproc.physics.vad_least_squares` (issue 33): re-exported until D."""

from __future__ import annotations

from cwproc.physics.vad_least_squares import (  # moved (issue 33): remove in stream D
    HOMODYNE_BLOCK_ELEMENTS,
    HOMODYNE_MAX_ITERATIONS,
    MAX_CONDITION,
    PACK_FRACTION,
    BatchedFit,
    BoolArray,
    FloatArray,
    fit_homodyne,
    fit_least_absolute,
    fit_linear,
    fit_scans,
    group_linear_residuals,
    homodyne_global_start,
    inverse_3x3,
    linear_residuals,
    linear_start,
    ray_rows,
    row_residuals,
)

__all__ = [
    "HOMODYNE_BLOCK_ELEMENTS",
    "HOMODYNE_MAX_ITERATIONS",
    "MAX_CONDITION",
    "PACK_FRACTION",
    "BatchedFit",
    "BoolArray",
    "FloatArray",
    "fit_homodyne",
    "fit_least_absolute",
    "fit_linear",
    "fit_scans",
    "group_linear_residuals",
    "homodyne_global_start",
    "inverse_3x3",
    "linear_residuals",
    "linear_start",
    "ray_rows",
    "row_residuals",
]
