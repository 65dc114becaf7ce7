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


#: narrower ranges of some quantities for one kind of dataset (issue 34.5). Wind
#: records (ZephIR 300 and WindCube v1 exports) are 10-min means: a mean vertical wind
#: beyond +-10 m s-1 over ten minutes is not atmospheric (the strongest convective
#: updraughts of the boundary layer average a few m s-1 over such a period; +-60 m s-1,
#: the bound of single sonic samples, let w = -50 m s-1 through as good), nor a mean
#: horizontal speed beyond 90 m s-1 (the strongest 10-min sustained winds measured, in
#: tropical cyclones, stay below it)
KIND_RANGES: dict[str, dict[str, tuple[float, float]]] = {
    "wind_record": {
        "w": (-10.0, 10.0),
        "wind_speed": (0.0, 90.0),
    },
}


def ranges_for(kind: str | None = None) -> dict[str, tuple[float, float]]:
    """The physical ranges of a kind of dataset: :data:`PHYSICAL_RANGES` narrowed by
    :data:`KIND_RANGES` (``None``: the general ones)."""
    return {**PHYSICAL_RANGES, **KIND_RANGES.get(kind or "", {})}


def outside_physical_range(name: str, values: np.ndarray, kind: str | None = None) -> np.ndarray:
    """Where ``values`` of variable ``name`` are finite but impossible, or infinite.

    NaN is left alone (already missing); variables without a declared range give all
    False. ``kind``: the dataset's kind (its narrower ranges, :func:`ranges_for`).
    """
    values = np.asarray(values, dtype=float)
    ranges = ranges_for(kind)
    if name not in ranges:
        return np.zeros(values.shape, dtype=bool)
    low, high = ranges[name]
    with np.errstate(invalid="ignore"):
        return ~np.isnan(values) & (~np.isfinite(values) | (values < low) | (values > high))


def screen_physical_range(
    ds: xr.Dataset, kind: str | None = None
) -> tuple[xr.Dataset, dict[str, int]]:
    """Replace values outside the ranges of ``kind`` (:func:`ranges_for`), and every
    infinite value of any float variable, by NaN.

    Applied by the readers to what they take from a file, so that every reader treats
    ``inf`` alike: missing, counted (the ZephIR reader refused a file for one ``inf``,
    the WindCube reader kept it). Returns the screened dataset and, per variable, how
    many values were replaced (only variables with any); a reader reports the counts in
    ``attrs["warnings"]``.
    """
    out = ds.copy()
    counts: dict[str, int] = {}
    ranges = ranges_for(kind)
    for name in out.data_vars:
        if name in ranges or out[name].dtype.kind != "f":
            continue
        values = out[name].values
        infinite = np.isinf(values)
        if infinite.any():
            counts[str(name)] = int(np.count_nonzero(infinite))
            out[name] = out[name].copy(data=np.where(infinite, np.nan, values))
    for name, (low, high) in ranges.items():
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


def range_warnings(counts: Mapping[str, int], kind: str | None = None) -> list[str]:
    """One line per variable of :func:`screen_physical_range`'s counts."""
    ranges = ranges_for(kind)
    return [
        f"{n} value(s) of {name} outside {ranges[name][0]:g}..{ranges[name][1]:g} or not "
        "finite: set to missing"
        if name in ranges
        else f"{n} infinite value(s) of {name}: set to missing"
        for name, n in counts.items()
    ]
