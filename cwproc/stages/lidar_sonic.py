"""Lidar against sonic: the lidar's eps at a mast height matched to the sonic's windows.

Stage ``lidar_sonic``: (lidar turbulence product, sonic turbulence product, height H)
-> comparison dataset (dim ``window``). For every sonic window [t0, t0 + T):

1. the lidar height nearest H is taken (its height and |Delta h| are recorded; more
   than ``max_height_offset_m`` away: error);
2. the lidar blocks whose time lies in the window and whose ``turbulence_flag`` has
   none of the bits of ``exclude_flag_mask`` (default 1, 2, 8, 16, 64: too few pairs, a
   lag beyond the inertial range, a failed fit, a partial block, an unresolved integral
   scale; bits 4 (method 1 only) and 32 (noise from the SNR prediction) leave epsilon
   usable) are averaged: eps_L = mean of the blocks,
   s.e. = sqrt(sum s.e._b^2) / n (independent blocks);
3. the ratio q = eps_L / eps_S with the relative errors combined in quadrature,
   s.e.(q)/q = sqrt((s.e._L/eps_L)^2 + (s.e._S/eps_S)^2);
4. the summary over matched windows: the geometric mean of q with the standard error of
   the mean of ln q, the median of q and the standard deviation of lg q.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.metadata import described

#: turbulence_flag bits of the lidar product that exclude a block (see the module doc)
EXCLUDE_FLAG_MASK = 1 | 2 | 8 | 16 | 64

#: sonic variables carried into the comparison (stability and wind for the ratio plots)
_SONIC_CARRIED = {
    "mean_wind_speed": "mean_wind_speed",
    "stability_parameter": "stability_parameter",
    "foken_flag": "foken_flag",
}


def _lidar_column(lidar: xr.Dataset, height_m: float, max_offset: float) -> tuple[int, float]:
    """Index and height of the lidar gate nearest ``height_m``."""
    if "epsilon" not in lidar or "height" not in lidar.coords:
        raise CwprocError("the lidar product has no epsilon on a height coordinate")
    heights = np.asarray(lidar["height"].values, dtype=float)
    k = int(np.nanargmin(np.abs(heights - height_m)))
    if abs(heights[k] - height_m) > max_offset:
        raise CwprocError(
            f"the lidar's nearest height to {height_m:g} m is {heights[k]:g} m, more than "
            f"{max_offset:g} m away"
        )
    return k, float(heights[k])


def _block_means(
    t_lidar: np.ndarray, eps: np.ndarray, err: np.ndarray, starts: np.ndarray, window_ns: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean eps, its standard error and the number of blocks per window."""
    n_win = starts.size
    mean, se, count = np.full(n_win, np.nan), np.full(n_win, np.nan), np.zeros(n_win, int)
    t0 = starts.astype("datetime64[ns]").view(np.int64)
    tl = t_lidar.astype("datetime64[ns]").view(np.int64)
    for w in range(n_win):
        sel = (tl >= t0[w]) & (tl < t0[w] + window_ns) & np.isfinite(eps)
        n = int(sel.sum())
        if n:
            count[w] = n
            mean[w] = float(np.mean(eps[sel]))
            e = err[sel]
            se[w] = (
                float(np.sqrt(np.sum(e[np.isfinite(e)] ** 2)) / n)
                if np.isfinite(e).any()
                else np.nan
            )
    return mean, se, count


def ratio_summary(ratio: np.ndarray, ratio_err: np.ndarray) -> dict[str, float]:
    """Geometric mean of q with the s.e. of mean ln q, median, s.d. of lg q, count."""
    q = ratio[np.isfinite(ratio) & (ratio > 0)]
    if q.size == 0:
        return {"n_pairs": 0}
    ln = np.log(q)
    se = float(np.std(ln, ddof=1) / np.sqrt(q.size)) if q.size > 1 else float("nan")
    return {
        "n_pairs": int(q.size),
        "ratio_geometric_mean": float(np.exp(ln.mean())),
        "ratio_geometric_mean_relative_error": se,
        "ratio_median": float(np.median(q)),
        "log10_ratio_std": float(np.std(np.log10(q), ddof=1)) if q.size > 1 else float("nan"),
    }


@described("lidar_sonic")
def compare_lidar_sonic(
    lidar: xr.Dataset,
    sonic: xr.Dataset,
    *,
    height_m: float,
    max_height_offset_m: float = 25.0,
    exclude_flag_mask: int = EXCLUDE_FLAG_MASK,
) -> xr.Dataset:
    """The comparison dataset of a lidar and a sonic turbulence product (module doc).

    Parameters
    ----------
    lidar : xarray.Dataset
        Lidar turbulence product: ``epsilon`` (time, height) (m2 s-3), optional
        ``epsilon_standard_error`` and ``turbulence_flag``.
    sonic : xarray.Dataset
        Sonic turbulence product (``epsilon``, ``epsilon_error`` on ``window`` with
        ``time`` the window starts; attribute ``window_s``, the window length (s),
        else the step of ``time``).
    height_m : float
        Height of the sonic on the lidar's height axis (m).
    max_height_offset_m : float
        Largest accepted distance between H and the nearest lidar height (m).
    exclude_flag_mask : int
        ``turbulence_flag`` bits that leave a lidar block out.

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    CwprocError
        A product lacks a variable, or no lidar height is near H.
    """
    if "epsilon" not in sonic or "time" not in sonic.coords:
        raise CwprocError("the sonic product has no epsilon per window")
    window_s = _window_length(sonic)
    k, h = _lidar_column(lidar, height_m, max_height_offset_m)
    eps_l = np.asarray(lidar["epsilon"].isel(height=k).values, dtype=float)
    err_l = (
        np.asarray(lidar["epsilon_standard_error"].isel(height=k).values, dtype=float)
        if "epsilon_standard_error" in lidar
        else np.full(eps_l.shape, np.nan)
    )
    if "turbulence_flag" in lidar:
        flag = np.asarray(lidar["turbulence_flag"].isel(height=k).values).astype(np.int64)
        good = (flag & int(exclude_flag_mask)) == 0
        eps_l = np.where(good, eps_l, np.nan)
    starts = np.asarray(sonic["time"].values)
    mean_l, se_l, n_l = _block_means(
        np.asarray(lidar["time"].values), eps_l, err_l, starts, round(window_s * 1e9)
    )
    eps_s = np.asarray(sonic["epsilon"].values, dtype=float)
    se_s = np.asarray(sonic["epsilon_error"].values, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = mean_l / eps_s
        ratio_err = ratio * np.sqrt((se_l / mean_l) ** 2 + (se_s / eps_s) ** 2)
    data = {
        "lidar_epsilon": mean_l,
        "lidar_epsilon_standard_error": se_l,
        "n_lidar_blocks": n_l.astype(np.int32),
        "sonic_epsilon": eps_s,
        "sonic_epsilon_standard_error": se_s,
        "lidar_sonic_epsilon_ratio": ratio,
        "lidar_sonic_epsilon_ratio_error": ratio_err,
    }
    for src, dst in _SONIC_CARRIED.items():
        if src in sonic:
            data[dst] = sonic[src].values
    ds = xr.Dataset(
        {name: (("window",), np.asarray(v)) for name, v in data.items()},
        coords={"time": (("window",), starts)},
    )
    ds["lidar_height"] = ((), h)
    ds["lidar_sonic_epsilon_ratio"].attrs["method"] = (
        "mean of the lidar blocks in the sonic window (turbulence_flag without the bits "
        f"{int(exclude_flag_mask)}) over the sonic epsilon; error: relative errors in quadrature"
    )
    ds.attrs.update(
        {
            "comparison_height_m": height_m,
            "sonic_window_s": window_s,
            **{f"summary_{k}": v for k, v in ratio_summary(ratio, ratio_err).items()},
        }
    )
    return ds


def _window_length(sonic: xr.Dataset) -> float:
    """The sonic product's window (s), from its parameters or its time step."""
    if "window_s" in sonic.attrs:
        return float(sonic.attrs["window_s"])
    t = np.asarray(sonic["time"].values)
    if t.size > 1:
        return float(np.median(np.diff(t)) / np.timedelta64(1, "s"))
    raise CwprocError("the sonic product does not say its window length")
