"""Physically possible values: the readers' screen of what they take from a file."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import xarray as xr

#: physically possible values of what readers take from instrument files, per canonical
#: variable (inclusive, in the variable's units). A value outside, or not finite, is a
#: damaged or impossible record: :func:`screen_physical_range` replaces it by NaN (so a
#: stage flags it as missing, never as good) and counts it. Limits are generous (the
#: strongest surface winds, Doppler velocities far beyond any lidar's bandwidth).
PHYSICAL_RANGES: dict[str, tuple[float, float]] = {
    "wind_speed": (0.0, 120.0),
    "wind_speed_min": (0.0, 120.0),
    "wind_speed_max": (0.0, 120.0),
    "wind_speed_std": (0.0, 60.0),
    "wind_direction": (0.0, 360.0),
    "u": (-120.0, 120.0),
    "v": (-120.0, 120.0),
    "w": (-60.0, 60.0),
    "radial_velocity": (-120.0, 120.0),
    "turbulence_intensity": (0.0, 10.0),
    "temperature": (-90.0, 70.0),
    "data_availability": (0.0, 100.0),
    "rain_percent": (0.0, 100.0),
    "packets": (0.0, 1.0e6),
}


def outside_physical_range(name: str, values: np.ndarray) -> np.ndarray:
    """Where ``values`` of variable ``name`` are finite but impossible, or infinite.

    NaN is left alone (already missing); variables without a declared range give all
    False.
    """
    values = np.asarray(values, dtype=float)
    if name not in PHYSICAL_RANGES:
        return np.zeros(values.shape, dtype=bool)
    low, high = PHYSICAL_RANGES[name]
    with np.errstate(invalid="ignore"):
        return ~np.isnan(values) & (~np.isfinite(values) | (values < low) | (values > high))


def screen_physical_range(ds: xr.Dataset) -> tuple[xr.Dataset, dict[str, int]]:
    """Replace values outside :data:`PHYSICAL_RANGES` (or not finite) by NaN.

    Applied by the readers to what they take from a file. Returns the screened dataset
    and, per variable, how many values were replaced (only variables with any); a
    reader reports the counts in ``attrs["warnings"]``.
    """
    out = ds.copy()
    counts: dict[str, int] = {}
    for name, (low, high) in PHYSICAL_RANGES.items():
        if name not in out or out[name].dtype.kind not in "fiu":
            continue
        values = out[name].values.astype(float)
        with np.errstate(invalid="ignore"):
            bad = ~np.isfinite(values) | (values < low) | (values > high)
        had_value = ~np.isnan(values)
        n = int(np.count_nonzero(bad & had_value))
        if n:
            counts[name] = n
            out[name] = out[name].copy(data=np.where(bad, np.nan, values))
    return out, counts


def range_warnings(counts: Mapping[str, int]) -> list[str]:
    """One line per variable of :func:`screen_physical_range`'s counts."""
    return [
        f"{n} value(s) of {name} outside {PHYSICAL_RANGES[name][0]:g}.."
        f"{PHYSICAL_RANGES[name][1]:g} or not finite: set to missing"
        for name, n in counts.items()
    ]
