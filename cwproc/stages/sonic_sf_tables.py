"""Summary tables of the sonic SF product: type occurrence and parameter statistics.

The tables of Gladkikh et al. (2014): Table 2 (:func:`type_occurrence`) and Tables 3-5
(:func:`parameter_statistics`), computed from the product of
:func:`cwproc.stages.sonic_sf.structure_function_types`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.stages.sonic_sf import FLAG_FEW_SAMPLES

__all__ = ["TYPE_PARAMETERS", "parameter_statistics", "type_occurrence"]

#: parameters summarised per type (Tables 3-5)
TYPE_PARAMETERS = {
    1: ("sf_mu", "r_max"),
    2: ("sf_a1", "sf_a2", "r_max"),
    3: ("sf_d1", "sf_d2", "sf_gamma", "r_max"),
}


def type_occurrence(sf: xr.Dataset) -> pd.DataFrame:
    """Occurrence of each type per component (%), Gladkikh et al. (2014), Table 2.

    The denominator is every window with enough valid samples (window_flag without
    bit 1), i.e. the observation time, as in the paper; windows skipped for strong
    wind or calm count as observed but untyped.

    Returns
    -------
    pandas.DataFrame
        index component; columns ``windows``, ``all_types_pct``, ``type1_pct``,
        ``type2_pct``, ``type3_pct``.
    """
    observed = (np.asarray(sf["window_flag"].values) & FLAG_FEW_SAMPLES) == 0
    types = np.asarray(sf["sf_type"].values)[observed]
    n = int(observed.sum())
    rows = []
    for k, comp in enumerate(sf["component"].values):
        t = types[:, k]
        share = [100.0 * np.mean(t == m) if n else np.nan for m in (1, 2, 3)]
        rows.append(
            {
                "component": str(comp),
                "windows": n,
                "all_types_pct": float(np.nansum(share)) if n else np.nan,
                "type1_pct": share[0],
                "type2_pct": share[1],
                "type3_pct": share[2],
            }
        )
    return pd.DataFrame(rows).set_index("component")


def parameter_statistics(sf: xr.Dataset) -> pd.DataFrame:
    """Means and medians of the fitted parameters per type and component (Tables 3-5).

    Gladkikh et al. (2014), Tables 3 (type 1: mu, r_max), 4 (type 2: a1, a2, r_max)
    and 5 (type 3: d1, d2, gamma, r_max).

    Returns
    -------
    pandas.DataFrame
        columns ``type``, ``component``, ``parameter``, ``count``, ``mean``, ``median``.
    """
    rows = []
    types = np.asarray(sf["sf_type"].values)
    for t, names in TYPE_PARAMETERS.items():
        for k, comp in enumerate(sf["component"].values):
            sel = types[:, k] == t
            for name in names:
                vals = np.asarray(sf[name].values)[sel, k]
                vals = vals[np.isfinite(vals)]
                rows.append(
                    {
                        "type": t,
                        "component": str(comp),
                        "parameter": name,
                        "count": int(vals.size),
                        "mean": float(np.mean(vals)) if vals.size else np.nan,
                        "median": float(np.median(vals)) if vals.size else np.nan,
                    }
                )
    return pd.DataFrame(rows)
