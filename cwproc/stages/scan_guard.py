"""Refuse scan datasets whose scan numbers collide across files (the ``xr.concat`` trap).

Every file's scans are numbered from 0 (:func:`cwproc.io.scan_join.assign_scans`), so
``xarray.concat([read(a), read(b)], "ray")`` keeps two numberings: the VAD fit then
merges scan ``k`` of each file into one rotation (the two sample ``.hpl`` files of six
scans each give 6 wind rows instead of 12), and the structure function and epsilon built
on it are wrong without any error. The right join renumbers the scans over the whole
record: :func:`cwproc.read` of several files, or :func:`cwproc.io.scan_join.concat_scans`.

:func:`require_distinct_scans` checks, in time order and among the rays of a scan
(``scan >= 0``), the invariants that the numbering guarantees (Smalikho (2020),
eqs. 1-2: one scan is one rotation of the cone, turning one way):

(a) the scan numbers never decrease (several files of several scans each);
(b) two consecutive rays of one scan are at most ``max_gap_s`` apart (the numbering's
    own rule, ``max_gap_s`` of :func:`cwproc.physics.scan_numbering.scan_indices`);
(c) the azimuth turned within one scan is at most one full turn plus its largest step
    (one scan per file, files back to back: every ray is scan 0).

Data numbered by cwproc never trip them; the cost is one pass over the rays (the sort
is skipped when the times are in order, as a reader returns them).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError

#: largest time between consecutive rays of one scan (s): ``scan_indices``' default
MAX_GAP_S = 120.0
#: slack (deg) on the turned angle of one scan, for rounding of the recorded azimuths
_TURN_SLACK_DEG = 1e-6


def require_distinct_scans(ds: xr.Dataset, *, stage: str, max_gap_s: float = MAX_GAP_S) -> None:
    """Raise when the scan numbers of ``ds`` cannot come from one numbering of one record.

    Parameters
    ----------
    ds : xarray.Dataset
        A scan dataset with ``time``, ``azimuth`` and ``scan`` on ``ray``; a dataset
        without ``scan`` (nothing to check) passes.
    stage : str
        The stage asking, first word of the message (e.g. ``"fit_vad"``).
    max_gap_s : float
        Largest time between consecutive rays of one scan (s).

    Raises
    ------
    CwprocError
        The scans collide. The message names the scan, the time spans its rays fall in,
        and the fix: ``"fit_vad: scan 0 holds rays of 12:00:00-12:03:20 and
        12:03:36-12:06:56: datasets joined with xarray.concat keep each file's scan
        numbers (every file numbers from 0); join the files with cwproc.read([...]) or
        cwproc.concat_scans([...])"``.
    """
    if "scan" not in ds.variables or "time" not in ds.variables or ds.sizes.get("ray", 0) < 2:
        return
    scan = np.asarray(ds.variables["scan"].values)
    time = np.asarray(ds.variables["time"].values)
    if scan.ndim != 1 or time.shape != scan.shape or time.dtype.kind != "M":
        return
    keep = scan >= 0
    rays: np.ndarray | slice = slice(None)  # the rays checked, in time order
    if not keep.all():
        rays = np.flatnonzero(keep)
        scan, time = scan[rays], time[rays]
    tns = time.astype("datetime64[ns]", copy=False).view(np.int64)
    if tns.size and np.any(tns[1:] < tns[:-1]):
        order = np.argsort(tns, kind="stable")
        scan, tns = scan[order], tns[order]
        rays = order if isinstance(rays, slice) else rays[order]
    if scan.size < 2:
        return
    step = np.diff(scan)
    bad = np.flatnonzero(step < 0)
    if bad.size:  # (a) a later ray in an earlier scan
        _refuse(stage, scan, tns, int(scan[bad[0] + 1]), "")
    same = step == 0
    gap = np.flatnonzero(same & (np.diff(tns) > max_gap_s * 1e9))
    if gap.size:  # (b) one scan in two stretches of time
        _refuse(stage, scan, tns, int(scan[gap[0]]), f" (more than {max_gap_s:g} s apart)")
    if "azimuth" in ds.variables:
        azimuth = np.asarray(ds.variables["azimuth"].values, dtype=np.float64)[rays]
        turned = _over_turned(scan, azimuth, same)
        if turned is not None:  # (c) more than one rotation in one scan
            why = " (more than one full turn of the azimuth)"
            _refuse(stage, scan, tns, int(scan[turned]), why, split=turned)


def _over_turned(scan: np.ndarray, azimuth: np.ndarray, same: np.ndarray) -> int | None:
    """The first ray that starts a second turn within its scan, or None.

    A scan turns by more than 360 deg plus its largest step when it holds several
    rotations; the ray returned is the first whose turned angle from the scan's first
    ray reaches 360 deg less half the scan's median step (the ray that would open the
    next rotation). ``scan`` is non-decreasing; ``same[i]`` says rays ``i`` and
    ``i + 1`` share a scan.
    """
    turn = np.abs(np.mod(np.diff(azimuth) + 180.0, 360.0) - 180.0)
    turn = np.where(same & np.isfinite(turn), turn, 0.0)
    starts = np.flatnonzero(np.r_[True, ~same])  # first ray of each scan
    padded = np.r_[turn, 0.0]  # the step out of a scan's last ray is 0
    total = np.add.reduceat(padded, starts)
    largest = np.maximum.reduceat(padded, starts)
    over = np.flatnonzero(total > 360.0 + largest + _TURN_SLACK_DEG)
    if not over.size:
        return None
    first = starts[over[0]]
    last = starts[over[0] + 1] if over[0] + 1 < starts.size else scan.size
    steps = turn[first : last - 1]
    cumulative = np.r_[0.0, np.cumsum(steps)]
    half = 0.5 * float(np.median(steps[steps > 0])) if np.any(steps > 0) else 0.0
    return int(first + np.argmax(cumulative >= 360.0 - half))


def _refuse(
    stage: str, scan: np.ndarray, tns: np.ndarray, bad: int, why: str, split: int | None = None
) -> None:
    """Raise the message of a collision in scan ``bad`` (rays in time order).

    The rays of ``bad`` are shown as the stretches of time they fall in; one stretch
    is cut at ray ``split`` when given, else at its largest time step.
    """
    of = np.flatnonzero(scan == bad)
    breaks = np.flatnonzero(np.diff(of) > 1) + 1 if of.size > 1 else np.zeros(0, int)
    runs = np.split(of, breaks)
    if len(runs) == 1 and of.size > 1:
        if split is None:
            k = int(np.argmax(np.diff(tns[of]))) + 1
        else:
            k = int(np.searchsorted(of, split))
        runs = [of[:k], of[k:]]
    spans = " and ".join(_span(tns[r]) for r in runs[:3] if r.size)
    more = f" (+{len(runs) - 3} more)" if len(runs) > 3 else ""
    raise CwprocError(
        f"{stage}: scan {bad} holds rays of {spans}{more}{why}: datasets joined with "
        "xarray.concat keep each file's scan numbers (every file numbers from 0); join "
        "the files with cwproc.read([...]) or cwproc.concat_scans([...])"
    )


def _span(tns: np.ndarray) -> str:
    """``"12:00:00-12:03:20"``: first and last time (UTC) of a stretch of rays (with the
    dates when it crosses midnight)."""
    first, last = (
        np.datetime_as_string(np.datetime64(int(t), "ns"), unit="s") for t in tns[[0, -1]]
    )
    if first[:10] == last[:10]:
        return f"{first[11:]}-{last[11:]}"
    return f"{first.replace('T', ' ')}-{last.replace('T', ' ')}"
