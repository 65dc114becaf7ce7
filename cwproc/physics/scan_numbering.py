"""Scan numbering: which 360 degree rotation of a conical scan each ray belongs to.

The structure function and the VAD fit of Smalikho (2020), eqs. 1-2, work on the
rays of one full rotation of the cone (azimuth theta_m = m dtheta at a fixed
elevation phi). :func:`scan_indices` recovers the rotations from the pointing angles
and times alone (numpy only); :func:`cwproc.io.scan_join.assign_scans` sets them on a scan
dataset and :func:`cwproc.io.scan_join.concat_scans` numbers the datasets of several files
joined in time order.

Method
------
Consecutive rays (in time order) are *linked* when both are below
``max_elevation_deg``, their elevations agree within ``elevation_tolerance_deg``,
the azimuth step between them (wrapped into (-180, 180) deg) is at least
``min_step_deg`` and not 180 deg, the time step is at most ``max_gap_s``, and the step
turns the same way as the previous linked step. A chain of linked rays is a *sweep*.
Along a sweep the turned angle is accumulated; a ray belongs to rotation
``floor((turned + step/2) / 360)`` of the sweep (``step``: the mean azimuth step of the
sweep, so that the ray that closes the circle, e.g. 359.99 deg after a start at 0,
opens the next rotation). Every (sweep, rotation) pair gets the next scan index.
Sweeps with fewer than ``min_rays`` rays (and stares, vertical rays, constant azimuth)
get scan ``-1``.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Sequence

import numpy as np

#: scan_type words that declare a conical scan (a 2-ray sweep is then accepted)
_CONICAL_WORDS = re.compile(r"\b(VAD|PPI|conical|DBS)\b", re.IGNORECASE)


def azimuth_steps(azimuth: np.ndarray) -> np.ndarray:
    """Signed azimuth change between consecutive rays, wrapped into [-180, 180) deg."""
    az = np.asarray(azimuth, dtype=np.float64)
    return np.mod(np.diff(az) + 180.0, 360.0) - 180.0


def sweep_links(
    time_s: np.ndarray,
    azimuth: np.ndarray,
    elevation: np.ndarray,
    *,
    max_elevation_deg: float,
    elevation_tolerance_deg: float,
    min_step_deg: float,
    max_gap_s: float,
    breaks: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Whether each ray continues the sweep of the ray before it, and the step (deg).

    Parameters
    ----------
    time_s : ndarray
        Ray times (s), increasing.
    azimuth, elevation : ndarray
        Pointing (deg).
    max_elevation_deg, elevation_tolerance_deg, min_step_deg, max_gap_s : float
        See the module docstring.
    breaks : ndarray of int, optional
        Rays that start a sweep whatever their pointing, as ray 0 does (the first ray of
        each file of a run of files numbered file by file, :func:`scan_indices_of_runs`).

    Returns
    -------
    link : ndarray of bool, shape (n,)
        ``link[i]``: ray i continues the sweep of ray i-1 (``link[0]`` is False).
    step : ndarray, shape (n,)
        Signed azimuth step from ray i-1 to ray i (deg; 0 for ray 0).
    """
    n = len(azimuth)
    if n < 2:
        return np.zeros(n, dtype=bool), np.zeros(n)
    el = np.asarray(elevation, dtype=np.float64)
    conical = np.isfinite(el) & (el < max_elevation_deg) & np.isfinite(azimuth)
    step = np.concatenate([[0.0], azimuth_steps(azimuth)])
    size = np.abs(step)
    candidate = np.zeros(n, dtype=bool)
    candidate[1:] = (
        conical[1:]
        & conical[:-1]
        & (np.abs(np.diff(el)) <= elevation_tolerance_deg)
        & (size[1:] >= min_step_deg)
        & (size[1:] < 180.0 - 1e-6)
        & (np.diff(time_s) <= max_gap_s)
        & (np.diff(time_s) >= 0)
    )
    if breaks is not None:
        candidate[breaks] = False
        step[breaks] = 0.0
    # a reversal of the turning direction starts a new sweep
    reversal = np.zeros(n, dtype=bool)
    reversal[2:] = candidate[2:] & candidate[1:-1] & (np.sign(step[2:]) != np.sign(step[1:-1]))
    return candidate & ~reversal, step


def rotation_index(link: np.ndarray, step: np.ndarray, min_rays: int) -> np.ndarray:
    """Scan index of each ray from the sweep links (see the module docstring).

    Parameters
    ----------
    link : ndarray of bool
        From :func:`sweep_links`.
    step : ndarray
        Signed azimuth steps (deg).
    min_rays : int or ndarray of int
        Shortest sweep that counts as a conical scan (per ray: that of a sweep's first
        ray counts).

    Returns
    -------
    ndarray of int64
        0, 1, 2, ... in time order; -1 for rays in no conical scan.
    """
    n = len(link)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    sweep = np.cumsum(~link) - 1
    length = np.bincount(sweep)
    turned_all = np.cumsum(np.where(link, np.abs(step), 0.0))
    starts = np.flatnonzero(~link)
    turned = turned_all - turned_all[starts][sweep]
    total = turned_all[np.r_[starts[1:] - 1, n - 1]] - turned_all[starts]
    mean_step = total / np.maximum(length - 1, 1)
    rotation = np.floor((turned + 0.5 * mean_step[sweep]) / 360.0).astype(np.int64)
    shortest = np.maximum(np.asarray(min_rays), 2)
    valid = length[sweep] >= (shortest[starts][sweep] if shortest.ndim else shortest)
    scan = np.full(n, -1, dtype=np.int64)
    if valid.any():
        key = sweep[valid].astype(np.int64) * (1 << 32) + rotation[valid]
        _, ids = np.unique(key, return_inverse=True)
        scan[valid] = ids
    return scan


def declares_conical(scan_type: object) -> bool:
    """Whether a header ``scan_type`` names a conical scan (VAD, PPI, DBS)."""
    return bool(_CONICAL_WORDS.search(str(scan_type or "")))


def scan_indices(
    time: np.ndarray,
    azimuth: np.ndarray,
    elevation: np.ndarray,
    *,
    scan_type: object = None,
    max_elevation_deg: float = 89.0,
    elevation_tolerance_deg: float = 0.5,
    min_step_deg: float = 0.2,
    max_gap_s: float = 120.0,
    min_rays: int | None = None,
) -> tuple[np.ndarray, dict[str, object]]:
    """Scan index of each ray from plain arrays, and the attributes that record the method.

    Parameters are those of :func:`assign_scans`; ``time`` is datetime64, ``scan_type``
    the header's scan type (used only for the default of ``min_rays``).

    Returns
    -------
    scan : ndarray of int64
        0, 1, ... in time order, -1 for rays in no conical scan.
    attrs : dict
        Method, parameters and reference, for ``scan.attrs``.
    """
    if min_rays is None:
        min_rays = 2 if declares_conical(scan_type) else 3
    time = np.asarray(time)
    n = time.size
    order = np.argsort(time, kind="stable")
    time_s = (time[order] - time[order][0]) / np.timedelta64(1, "s") if n else np.zeros(0)
    link, step = sweep_links(
        time_s,
        np.asarray(azimuth, dtype=np.float64)[order],
        np.asarray(elevation, dtype=np.float64)[order],
        max_elevation_deg=max_elevation_deg,
        elevation_tolerance_deg=elevation_tolerance_deg,
        min_step_deg=min_step_deg,
        max_gap_s=max_gap_s,
    )
    scan = np.empty(n, dtype=np.int64)
    scan[order] = rotation_index(link, step, min_rays)
    attrs = {
        "method": (
            "consecutive rays at one elevation turning one way form a sweep; "
            "the turned azimuth angle divided by 360 deg gives the rotation"
        ),
        "max_elevation_deg": max_elevation_deg,
        "elevation_tolerance_deg": elevation_tolerance_deg,
        "min_step_deg": min_step_deg,
        "max_gap_s": max_gap_s,
        "min_rays": min_rays,
    }
    return scan, attrs


def scan_indices_of_runs(
    time: np.ndarray,
    azimuth: np.ndarray,
    elevation: np.ndarray,
    bounds: Sequence[int],
    scan_types: Sequence[object],
) -> list[np.ndarray]:
    """:func:`scan_indices` (default parameters) of each run of rays on its own.

    The files of a record read at once (:func:`cwproc.io.halo_files.read_hpl_run`)
    are numbered as each file's own dataset numbers them, in one pass over the record
    instead of one per file: a run's first ray starts a sweep (``breaks`` of
    :func:`sweep_links`), a sweep counts with the ``min_rays`` of its run's
    ``scan_type``, and each run's indices start at 0. With ``time`` strictly increasing
    (rays in time order within and across the runs) the result is, run by run,
    exactly that of :func:`scan_indices`.

    Parameters
    ----------
    time : ndarray of datetime64
        Ray times, strictly increasing.
    azimuth, elevation : ndarray
        Pointing (deg).
    bounds : sequence of int
        Run ``k`` is rays ``bounds[k]:bounds[k + 1]`` (``bounds[0] == 0``, ``bounds[-1]``
        the number of rays).
    scan_types : sequence
        Header ``scan_type`` of each run.

    Returns
    -------
    list of ndarray of int64
        Scan index of each ray of each run (0, 1, ... in time order, -1 for rays in no
        conical scan).

    Raises
    ------
    ValueError
        ``time`` is not strictly increasing, or ``bounds`` and ``scan_types`` do not
        describe the rays.
    """
    time = np.asarray(time)
    edges = np.asarray(bounds, dtype=np.int64)
    n = time.size
    if edges.size != len(scan_types) + 1 or edges[0] != 0 or edges[-1] != n:
        raise ValueError("bounds must run from 0 to the number of rays, one run a scan type")
    if np.any(np.diff(edges) < 0) or not bool(np.all(time[1:] > time[:-1])):
        raise ValueError("runs and times must be in order (time strictly increasing)")
    lengths = np.diff(edges)
    starts = edges[:-1][lengths > 0]
    origin = np.repeat(time[starts], lengths[lengths > 0])
    time_s = (time - origin) / np.timedelta64(1, "s")
    link, step = sweep_links(
        time_s,
        np.asarray(azimuth, dtype=np.float64),
        np.asarray(elevation, dtype=np.float64),
        max_elevation_deg=89.0,
        elevation_tolerance_deg=0.5,
        min_step_deg=0.2,
        max_gap_s=120.0,
        breaks=starts,
    )
    min_rays = np.repeat([2 if declares_conical(t) else 3 for t in scan_types], lengths)
    scan = rotation_index(link, step, min_rays)
    runs = []
    for a, b in itertools.pairwise(edges):
        own = scan[a:b]
        first = own[own >= 0][:1]  # indices rise with time: the run's first is its least
        runs.append(np.where(own >= 0, own - first, -1) if first.size else own)
    return runs
