"""SNR of Stream Line scans corrected with the background files.

Each ray is matched to the background file of its hour: the nearest background measured
at or before the ray (as the Stream Line measures it at the start of each hour), no older
than ``max_age_h``. The physics is in :mod:`cwproc.physics.snr_background` (Manninen et al.
(2016); Vakkari et al. (2019)); this module matches the rays to the background datasets
it is given (read by :mod:`cwproc.pipeline.background_files`; a stage does no I/O) and builds
the dataset. The SNR as the instrument gave it stays in ``snr_uncorrected``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr

from cwproc.metadata import described
from cwproc.physics.snr_background import MIN_FIT_RANGE_M, corrected_snr, fit_background_shape

METHOD = (
    "Manninen et al. (2016) and Vakkari et al. (2019): background profile of the hour "
    "replaced by a smooth fit ({models}), then the noise floor (a line in range fitted to "
    "the signal-free gates of each ray) divided out; snr_uncorrected is the instrument's"
)


def match_rays(
    ray_time: np.ndarray, background_time: np.ndarray, max_age_h: float | None
) -> np.ndarray:
    """Index of the background of each ray: the latest at or before it, -1 when none.

    Parameters
    ----------
    ray_time, background_time : numpy.ndarray of datetime64
        ``background_time`` sorted ascending.
    max_age_h : float or None
        Backgrounds older than this (hours) before the ray are not used; None: any age.
    """
    rt = np.asarray(ray_time, dtype="datetime64[ns]")
    bt = np.asarray(background_time, dtype="datetime64[ns]")
    idx = np.searchsorted(bt, rt, side="right") - 1
    if max_age_h is not None and bt.size:
        age_h = (rt - bt[np.clip(idx, 0, None)]) / np.timedelta64(3600, "s")
        idx = np.where(age_h <= max_age_h, idx, -1)
    return np.where(np.isnat(rt), -1, idx)


@described(None)
def correct_snr(
    scans: xr.Dataset,
    backgrounds: Sequence[xr.Dataset],
    *,
    max_age_h: float | None = 2.0,
    min_range_m: float = MIN_FIT_RANGE_M,
    notes: list[str] | None = None,
) -> xr.Dataset:
    """Scan dataset with ``snr`` corrected by the matched background files.

    Parameters
    ----------
    scans : xarray.Dataset
        Canonical scan dataset with ``snr(ray, range)`` and ``range`` (m).
    backgrounds : sequence of xarray.Dataset
        :func:`cwproc.io.halo_background.read_halo_background` datasets. A background
        with fewer gates than the scans is not used (noted); one with more is cut to the
        scans' gates (the instrument writes the background of its largest gate count).
    max_age_h : float or None
        Oldest background (hours before a ray) that may correct it.
    min_range_m : float
        Gates nearer than this are left out of the fits (m).
    notes : list of str, optional
        Receives what was done and what could not be done.

    Returns
    -------
    xarray.Dataset
        ``snr`` corrected where a background matched (else unchanged), ``snr_uncorrected``,
        ``background_time(ray)`` (NaT: no background) and ``noise_floor(ray)`` (median
        over range of the fitted floor F, intensity units; NaN: not corrected); attributes
        ``snr_correction`` (method), ``background_files``.
    """
    rng = np.asarray(scans["range"].values, dtype=float)
    n_gates = rng.size
    usable = []
    for bg in backgrounds:
        if bg.sizes["range"] < n_gates:
            if notes is not None:
                notes.append(
                    f"background file {bg.attrs['source_files'][0]} not used: "
                    f"{bg.sizes['range']} gates, the scans have {n_gates}"
                )
            continue
        usable.append(bg.isel(range=slice(0, n_gates)))
    usable.sort(key=lambda b: b["time"].values)
    snr0 = np.asarray(scans["snr"].values, dtype=float)
    snr = snr0.copy()
    times = np.array([b["time"].values for b in usable], dtype="datetime64[ns]")
    idx = match_rays(scans["time"].values, times, max_age_h)
    floor_median = np.full(snr.shape[0], np.nan)
    models, used, done_k = [], [], []
    for k in np.unique(idx[idx >= 0]):
        rays = np.flatnonzero(idx == k)
        measured = np.asarray(usable[k]["background"].values, dtype=float)
        try:
            fitted, model = fit_background_shape(measured, rng, min_range_m=min_range_m)
        except ValueError as exc:
            if notes is not None:
                notes.append(f"{usable[k].attrs['source_files'][0]}: {exc}; SNR not corrected")
            continue
        corr, floor, _ = corrected_snr(
            snr0[rays] + 1.0, rng, measured, fitted, min_range_m=min_range_m
        )
        snr[rays] = corr
        fitted_rows = np.isfinite(floor).any(axis=1)  # rays with too few noise gates: NaN
        floor_median[rays[fitted_rows]] = np.nanmedian(floor[fitted_rows], axis=1)
        models.append(model)
        used.append(usable[k].attrs["source_files"][0])
        done_k.append(k)
    done = np.isin(idx, done_k)
    bg_time = np.full(idx.shape, np.datetime64("NaT"), dtype="datetime64[ns]")
    bg_time[done] = times[idx[done]]
    out = scans.assign(
        snr=(scans["snr"].dims, snr, scans["snr"].attrs),
        snr_uncorrected=(scans["snr"].dims, snr0),
        background_time=("ray", bg_time),
        noise_floor=("ray", floor_median),
    )
    out.attrs = dict(scans.attrs)
    out.attrs["snr_correction"] = (
        METHOD.format(models=", ".join(sorted(set(models)))) if used else "none"
    )
    out.attrs["background_files"] = sorted(set(used))
    if notes is not None:
        notes.append(correction_summary(done, used, idx))
    return out


def correction_summary(done: np.ndarray, used: list[str], idx: np.ndarray) -> str:
    n, n_done = done.size, int(done.sum())
    if n_done == 0:
        why = " (no readable one measured at most max_age_h before them)" if (idx < 0).all() else ""
        return f"SNR not corrected: none of {n} rays has a usable background file{why}"
    return (
        f"SNR of {n_done} of {n} rays corrected with {len(set(used))} background file(s) "
        "(Manninen et al. (2016), Vakkari et al. (2019))"
    )
