"""The day's scan decisions: rays grouped by scan, the conical elevation, the azimuth step.

Numpy only, so that the decisions a day run in chunks must take once for the whole day
(``ScanChain.decisions``, :mod:`cwproc.pipeline.scan_chain`) use physics, not stage
internals; the stages ``vad``, ``qc`` and ``structure`` take the same functions:

- :func:`scan_layout`: the rays of each 360-degree rotation as rows of a padded index
  table (:class:`ScanLayout`);
- :func:`select_conical_scans`: the scans at the most common conical elevation (the
  VAD model, Smalikho (2020), eq. 1, needs ``phi`` strictly between 0 and 90 degrees);
- :func:`azimuth_step`: the step dtheta between rays and the rotation sense, from which
  the azimuth structure function takes its lags (Smalikho (2020), eq. 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cwproc.errors import CwprocError

__all__ = [
    "CONICAL_ELEVATION_RANGE_DEG",
    "ELEVATION_TOLERANCE_DEG",
    "ScanLayout",
    "azimuth_step",
    "scan_layout",
    "select_conical_scans",
    "wrapped_azimuth_difference",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


#: elevations (deg) that count as conical scans; outside, w or u, v are not determined
CONICAL_ELEVATION_RANGE_DEG = (1.0, 89.0)
#: scans whose elevation differs from the selected one by more than this are left out
ELEVATION_TOLERANCE_DEG = 0.5


@dataclass(frozen=True)
class ScanLayout:
    """Rays of each scan as rows of a padded index table.

    Attributes
    ----------
    scan_ids : ndarray, shape (n_scan,)
        The scan numbers, increasing.
    index : ndarray, shape (n_scan, max_rays)
        Ray indices into the scan dataset; ``-1`` pads scans with fewer rays.
    """

    scan_ids: NDArray[np.int64]
    index: NDArray[np.int64]

    @property
    def present(self) -> BoolArray:
        """True where ``index`` names a ray (not padding)."""
        return self.index >= 0

    def take(self, values: np.ndarray, fill: float = np.nan) -> np.ndarray:
        """Gather ``values[ray, ...]`` into ``(scan, ray in scan, ...)``, padding with fill."""
        out = np.asarray(values)[np.maximum(self.index, 0)]
        if out.dtype.kind == "f":
            pad = ~self.present
            out[pad] = fill
        return out

    def subset(self, rows: slice) -> ScanLayout:
        """The layout of a contiguous block of scans."""
        return ScanLayout(self.scan_ids[rows], self.index[rows])


def scan_layout(scan: np.ndarray, keep: BoolArray | None = None) -> ScanLayout:
    """Group ray indices by scan number (rays with ``scan < 0`` or ``~keep`` left out).

    The day's decision of the ``vad`` stage, taken by ``ScanChain.decisions``
    (:mod:`cwproc.pipeline.scan_chain`).

    Parameters
    ----------
    scan : ndarray, shape (n_ray,)
        Scan index of each ray (``-1`` = no conical scan).
    keep : ndarray of bool, optional
        Rays to consider.

    Returns
    -------
    ScanLayout
    """
    scan = np.asarray(scan).astype(np.int64)
    use = scan >= 0
    if keep is not None:
        use &= keep
    rays = np.flatnonzero(use)
    order = rays[np.argsort(scan[rays], kind="stable")]
    ids, starts, counts = np.unique(scan[order], return_index=True, return_counts=True)
    index = np.full((ids.size, int(counts.max()) if ids.size else 0), -1, dtype=np.int64)
    if ids.size:
        position = np.arange(order.size) - np.repeat(starts, counts)
        index[np.repeat(np.arange(ids.size), counts), position] = order
    return ScanLayout(ids.astype(np.int64), index)


def select_conical_scans(
    layout: ScanLayout, elevation_deg: FloatArray
) -> tuple[ScanLayout, float, FloatArray, int]:
    """Keep the scans at the most common conical elevation.

    The day's decision of the ``vad`` stage, taken by ``ScanChain.decisions``
    (:mod:`cwproc.pipeline.scan_chain`):
    a day run in chunks must keep the elevation and the scans of the whole day.

    A scan is conical when its median elevation lies in ``CONICAL_ELEVATION_RANGE_DEG``.
    The most common elevation (rounded to 0.1 deg) is chosen; scans within
    ``ELEVATION_TOLERANCE_DEG`` of it are kept.

    Returns
    -------
    (layout, elevation_deg, scan_elevations_deg, n_other_elevation)

    Raises
    ------
    CwprocError
        No conical scan at all (e.g. a vertical stare file).
    """
    per_scan = np.nanmedian(layout.take(elevation_deg), axis=1) if layout.index.size else []
    per_scan = np.asarray(per_scan, dtype=float)
    lo, hi = CONICAL_ELEVATION_RANGE_DEG
    conical = (per_scan >= lo) & (per_scan <= hi)
    if not conical.any():
        raise CwprocError(
            "The input has no conical scan (no 360-degree rotation at an elevation between "
            f"{lo:g} and {hi:g} degrees), so no wind profile can be fitted; a vertical stare "
            "or an RHI file cannot give a VAD wind."
        )
    values, counts = np.unique(np.round(per_scan[conical], 1), return_counts=True)
    chosen = float(values[np.argmax(counts)])
    keep = conical & (np.abs(per_scan - chosen) <= ELEVATION_TOLERANCE_DEG)
    n_other = int(conical.sum() - keep.sum())
    rows = np.flatnonzero(keep)
    return (
        ScanLayout(layout.scan_ids[rows], layout.index[rows]),
        chosen,
        per_scan[rows],
        n_other,
    )


def wrapped_azimuth_difference(a_deg: np.ndarray, b_deg: np.ndarray) -> np.ndarray:
    """``a - b`` wrapped into [-180, 180) degrees."""
    return (np.asarray(a_deg) - np.asarray(b_deg) + 180.0) % 360.0 - 180.0


def azimuth_step(azimuth_deg: np.ndarray, scan: np.ndarray) -> tuple[float, float]:
    """Azimuth step dtheta (deg) and rotation sign from consecutive rays of the same scan.

    The day's decision of the ``structure`` stage, taken by ``ScanChain.decisions``
    (:mod:`cwproc.pipeline.scan_chain`): a day run in chunks must find the step of the whole day.

    Parameters
    ----------
    azimuth_deg : numpy.ndarray
        Ray azimuths (deg) in time order.
    scan : numpy.ndarray
        Scan index of each ray.

    Returns
    -------
    (dtheta_deg, sign) : tuple of float
        Median absolute step (deg) and +1 for clockwise (increasing azimuth), -1 otherwise.
    """
    same = scan[1:] == scan[:-1]
    d = wrapped_azimuth_difference(azimuth_deg[1:], azimuth_deg[:-1])[same]
    d = d[np.abs(d) > 1e-6]
    if d.size == 0:
        raise CwprocError("cannot determine the azimuth step: no scan has two distinct rays")
    return float(np.median(np.abs(d))), float(np.sign(np.median(d)))
