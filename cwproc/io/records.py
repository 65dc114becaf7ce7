"""Sequences of logger records: times that break them, binary records off their boundaries.

Shared by the sonic readers (:func:`out_of_sequence`, applied by
:func:`cwproc.io.sonic_samples.sonic_dataset` to every sonic file) and the TOB1 reader
(:func:`misaligned_from`, :func:`realigned_records`); issue 34.3.
"""

from __future__ import annotations

import os

import numpy as np

from cwproc.errors import InputFileError

#: records in the running median of :func:`out_of_sequence`: bursts of up to half as
#: many damaged records in a row are told from the sequence around them
SEQUENCE_WINDOW = 51
#: a gap longer than this (s) separates runs of records; a run shorter than
#: :data:`SEQUENCE_WINDOW` apart from the file's main run lies outside its span
SPAN_GAP_S = 3600.0


def out_of_sequence(time_ns: np.ndarray) -> np.ndarray:
    """Records whose time breaks the file's sequence or lies outside its own span.

    A logger writes its records in time order. A record is out of sequence when its
    time is more than ``max(2 s, SEQUENCE_WINDOW typical intervals)`` from the running
    median of the :data:`SEQUENCE_WINDOW` record times around it (in a sequence that runs
    forward the median is the record's own time, gaps or not: only records that break
    it differ). Of the rest, records further than :data:`SPAN_GAP_S` from the file's
    main run (its longest) in runs of fewer than :data:`SEQUENCE_WINDOW` records lie
    outside the file's span: garbage with believable times (ten such records of a
    TOB1 file made ten day products, issue 34.3). A file whose times run forward
    without such a gap is not examined further (the usual case costs one ``diff``).

    Parameters
    ----------
    time_ns : ndarray of int64
        Time stamps (ns), file order.

    Returns
    -------
    ndarray of bool
    """
    t = np.asarray(time_ns, dtype=np.int64)
    out = np.zeros(t.size, dtype=bool)
    if t.size < 3:
        return out
    dt = np.diff(t)
    if np.all((dt >= 0) & (dt <= SPAN_GAP_S * 1e9)):
        return out
    from scipy.ndimage import median_filter

    positive = dt[dt > 0]
    step_s = float(np.median(positive)) * 1e-9 if positive.size else 0.0
    secs = (t - np.median(t)).astype(np.float64) * 1e-9
    med = median_filter(secs, size=SEQUENCE_WINDOW, mode="nearest")
    out = np.abs(secs - med) > max(2.0, SEQUENCE_WINDOW * step_s)
    good = np.flatnonzero(~out)
    if good.size == 0:
        return out
    breaks = np.flatnonzero(np.abs(np.diff(secs[good])) > SPAN_GAP_S) + 1
    runs = np.split(good, breaks)
    main = max(range(len(runs)), key=lambda k: runs[k].size)
    for k, run in enumerate(runs):
        if k != main and run.size < SEQUENCE_WINDOW:
            out[run] = True
    return out


def misaligned_from(record: np.ndarray) -> int | None:
    """Index of the first record read off its boundary in a binary file, or ``None``.

    Bytes inserted into or lost from a TOB1 file shift every later record: its fields
    become garbage, the RECORD counter included, whose steps are then no longer 1 except
    by chance. Lost records and logger restarts break the counting once and it resumes
    (step 1 again); garbage never resumes. The data are off their boundaries from the
    first break after which fewer than half of the steps are 1; the record before that
    break is counted in, as the shift may start inside it, after its RECORD field.

    Parameters
    ----------
    record : ndarray of int
        The RECORD field, file order.
    """
    step = np.diff(np.asarray(record, dtype=np.int64))
    if step.size == 0:
        return None
    ok = (step == 1).astype(float)
    # share of unit steps from each step to the end
    tail_share = np.cumsum(ok[::-1])[::-1] / np.arange(ok.size, 0, -1)
    broken = np.flatnonzero((ok == 0) & (tail_share < 0.5))
    if broken.size == 0:
        return None
    # the record before the break may hold the inserted bytes after its RECORD field
    return int(broken[0])


#: records read at a candidate boundary to tell whether it is one (RECORD counting up)
RESYNC_PROBE = 32
#: damaged places a TOB1 body is read past; beyond, the rest is dropped (with a note)
MAX_RESYNCS = 100


def realigned_records(
    path: str | os.PathLike, data: bytes, dtype: np.dtype, offset: int, notes: list[str]
) -> tuple[np.ndarray, int]:
    """The records of a TOB1 body, read again on their boundaries after bytes inserted
    or lost (issue 34.3), and the bytes of a partial last record.

    Where the RECORD numbers stop counting up (:func:`misaligned_from`), the record
    there may hold the damage: it is dropped, and the next position (up to two record
    lengths on) from which :data:`RESYNC_PROBE` records count up by one, continuing the
    numbers before the damage (up to two records lost), is where reading resumes. Each
    resumption is a note naming the byte, the bytes skipped and the records lost; only
    when no boundary is found are the remaining records dropped, with a note too (three
    bytes inserted mid-file dropped the rest of the file).

    Raises
    ------
    InputFileError
        The RECORD numbers never count up from the first record: not TOB1 records.
    """
    size = dtype.itemsize
    pieces: list[np.ndarray] = []
    start = 0
    while True:
        n = (len(data) - start) // size
        records = np.frombuffer(data, dtype=dtype, count=n, offset=start)
        shifted = misaligned_from(records["RECORD"]) if n else None
        if shifted is None:
            pieces.append(records)
            extra = len(data) - start - n * size
            break
        if shifted == 0 and not pieces:
            raise InputFileError(
                path, "RECORD numbers never count up: not TOB1 records", 1, unit="record"
            )
        pieces.append(records[:shifted])
        bad_at = start + shifted * size
        last = int(records["RECORD"][shifted - 1]) if shifted else None
        resume = _next_boundary(data, dtype, bad_at, last) if len(pieces) <= MAX_RESYNCS else None
        done = sum(p.size for p in pieces)
        if resume is None:
            notes.append(
                f"records {done + 1}-{done + n - shifted} dropped: from byte "
                f"{offset + bad_at} the RECORD numbers stop counting up and no record "
                "boundary was found again (bytes inserted or lost)"
            )
            extra = 0
            break
        first = int(np.frombuffer(data, dtype=dtype, count=1, offset=resume)["RECORD"][0])
        lost = first - last - 1 if last is not None else 0
        notes.append(
            f"bytes inserted or lost near byte {offset + bad_at}: {resume - bad_at} byte(s) "
            f"skipped, {lost} record(s) lost, reading resumed on the record boundaries "
            f"(RECORD {first})"
        )
        start = resume
    return np.concatenate(pieces) if len(pieces) > 1 else pieces[0], extra


def _next_boundary(data: bytes, dtype: np.dtype, bad_at: int, last: int | None) -> int | None:
    """The first byte after ``bad_at`` where records count up again from ``last``."""
    size = dtype.itemsize
    for skip in range(1, 2 * size + 1):
        at = bad_at + skip
        m = min(RESYNC_PROBE, (len(data) - at) // size)
        if m < 2:
            return None
        probe = np.frombuffer(data, dtype=dtype, count=m, offset=at)["RECORD"].astype(np.int64)
        if last is not None and not 0 < probe[0] - last <= 3:
            continue
        if np.all(np.diff(probe) == 1):
            return at
    return None
