"""The canonical sonic dataset, built from the columns a sonic reader parsed.

Every sonic reader (Meteo-2, Campbell TOA5/TOB1, LI-COR GHG, Gill) hands its time
stamps and columns to :func:`sonic_dataset`: time ordering, duplicates, gaps, spikes
and flags are detected and reported there, never silently repaired. The sampling rate
is measured from the stamps (:func:`measure_sampling_rate`), never assumed.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io.ranges import outside_physical_range
from cwproc.io.records import out_of_sequence
from cwproc.io.schema import with_canonical_attrs

#: the measured variables of the canonical sonic dataset, in reading order
SONIC_FIELDS = ("u", "v", "w", "temperature", "diagnostic")


#: sample_flag bits
FLAG_DIAGNOSTIC = 1


FLAG_SPIKE = 2


FLAG_NOT_FINITE = 4


#: default spike threshold: |x - 1-s running median| in robust std about the 1-min mean
SPIKE_THRESHOLD = 6.0


#: running-median width for spike detection (s)
SPIKE_WINDOW_S = 1.0


#: running-mean width of the spike scale (s)
SPIKE_SCALE_S = 60.0


def measure_sampling_rate(time_ns: np.ndarray) -> float:
    """Sampling rate (Hz) measured from sorted time stamps, leaving gaps out.

    The rate is (number of regular intervals) / (their total duration), where an
    interval is regular when it is positive and shorter than 1.5 times the median
    interval; stamp jitter averages out.

    Parameters
    ----------
    time_ns : ndarray of int64
        Sorted time stamps (ns).

    Returns
    -------
    float
        Hz; NaN with fewer than two distinct stamps.
    """
    dt = np.diff(time_ns.astype(np.int64))
    dt = dt[dt > 0]
    if dt.size == 0:
        return float("nan")
    regular = dt[dt < 1.5 * np.median(dt)]
    return float(regular.size / (regular.sum() * 1e-9))


#: a stamp farther than this many typical intervals from both neighbours is stray
STRAY_INTERVALS = 10


def stray_stamps(time_ns: np.ndarray) -> np.ndarray:
    """Records whose time stamp alone is wrong (a damaged record, file order).

    A stamp is stray when it lies more than :data:`STRAY_INTERVALS` typical sampling
    intervals from both neighbours while the neighbours are within that distance of each
    other, in time order: the series runs on around it, so the stamp, not the clock, is
    wrong (a flipped byte of a TOB1 SECONDS field gave a sample 20 years early). The first
    and last records are judged against the two records next to them. Gaps, restarts
    and out-of-order blocks of more than one record are left alone.

    Parameters
    ----------
    time_ns : ndarray of int64
        Time stamps (ns), file order.

    Returns
    -------
    ndarray of bool
    """
    t = np.asarray(time_ns, dtype=np.int64)
    stray = np.zeros(t.size, dtype=bool)
    if t.size < 3:
        return stray
    dt = np.diff(t)
    positive = dt[dt > 0]
    if positive.size == 0:
        return stray
    limit = STRAY_INTERVALS * float(np.median(positive))
    far = np.abs(dt.astype(float)) > limit  # far[i]: t[i + 1] is far from t[i]
    bridge = t[2:] - t[:-2]
    joined = (bridge > 0) & (bridge <= limit)  # t[i] and t[i + 2] agree
    stray[1:-1] = far[:-1] & far[1:] & joined
    stray[0] = far[0] and 0 < t[2] - t[1] <= limit
    stray[-1] = far[-1] and 0 < t[-2] - t[-3] <= limit
    return stray


def spike_mask(x: np.ndarray, width: int, threshold: float, scale_width: int) -> np.ndarray:
    """Samples that depart from the centred running median by more than ``threshold``.

    A spike is a sample farther than ``threshold`` robust standard deviations from the
    running median of ``width`` samples (1 s), where the robust standard deviation is
    1.4826 median|x - running mean of ``scale_width`` samples| (1 min) over the whole
    series: turbulent gusts move the 1-s median with them, a spike does not. NaN is
    never a spike.

    Parameters
    ----------
    x : ndarray
        Series (any unit).
    width : int
        Running-median width (samples).
    threshold : float
        In robust standard deviations (default 6: no flag in the real 20 Hz CSAT3 file,
        whose largest departure is 3.1).
    scale_width : int
        Running-mean width of the scale (samples).
    """
    x = np.asarray(x, dtype=float)
    series = pd.Series(x)
    width = max(width, 3) | 1
    if np.isinf(x).any():
        return _spike_mask_everywhere(series, width, threshold, scale_width)
    finite = np.isfinite(x)
    if not finite.any():
        return np.zeros(x.shape, dtype=bool)
    mean = series.rolling(max(scale_width, 3), center=True, min_periods=1).mean().to_numpy()
    limit = threshold * _robust_scale(np.abs(x - mean)[finite])
    # |x - median| <= max - min of the window <= that of the three blocks of ``width``
    # samples around it: the median is needed only where this exceeds the limit (a few
    # samples of a day)
    with np.errstate(invalid="ignore"):
        candidates = np.flatnonzero(finite & (_block_span(x, width) >= limit))
    out = np.zeros(x.shape, dtype=bool)
    if candidates.size:
        padded = np.concatenate([np.full(width // 2, np.nan), x, np.full(width // 2, np.nan)])
        windows = np.lib.stride_tricks.sliding_window_view(padded, width)[candidates]
        med = np.nanmedian(windows, axis=1)
        out[candidates] = np.abs(x[candidates] - med) > limit
    return out


def _block_span(x: np.ndarray, width: int) -> np.ndarray:
    """Per sample, max - min (NaN left out) over its block of ``width`` samples and the
    two neighbouring blocks: at least the range of any centred window of ``width``."""
    n_blocks = -(-x.size // width)
    blocks = np.full(n_blocks * width, np.nan)
    blocks[: x.size] = x
    blocks = blocks.reshape(n_blocks, width)
    hi, lo = np.fmax.reduce(blocks, axis=1), np.fmin.reduce(blocks, axis=1)
    hi = np.fmax(np.fmax(hi, np.append(hi[1:], np.nan)), np.insert(hi[:-1], 0, np.nan))
    lo = np.fmin(np.fmin(lo, np.append(lo[1:], np.nan)), np.insert(lo[:-1], 0, np.nan))
    return np.repeat(hi - lo, width)[: x.size]


def _robust_scale(spread: np.ndarray) -> float:
    """1.4826 median of |departures| (robust standard deviation), never zero."""
    scale = 1.4826 * np.median(spread)
    return float(scale) if scale != 0 else float(np.finfo(float).tiny)


def _spike_mask_everywhere(
    series: pd.Series, width: int, threshold: float, scale_width: int
) -> np.ndarray:
    """:func:`spike_mask` with the running median at every sample (infinite values)."""
    x = series.to_numpy()
    med = series.rolling(width, center=True, min_periods=1).median().to_numpy()
    mean = series.rolling(max(scale_width, 3), center=True, min_periods=1).mean().to_numpy()
    resid = np.abs(x - med)
    spread = np.abs(x - mean)
    finite = np.isfinite(resid) & np.isfinite(spread)
    if not finite.any():
        return np.zeros(x.shape, dtype=bool)
    scale = _robust_scale(spread[finite])
    with np.errstate(invalid="ignore"):
        return finite & (resid > threshold * scale)


def sonic_dataset(
    path: str | os.PathLike,
    time: np.ndarray,
    wind: Mapping[str, np.ndarray],
    temperature: np.ndarray,
    diagnostic: np.ndarray,
    *,
    instrument: str,
    frame: str,
    attrs: Mapping[str, Any] | None = None,
    warnings: Sequence[str] = (),
    spike_threshold: float = SPIKE_THRESHOLD,
    sampling_rate_hz: float | None = None,
) -> xr.Dataset:
    """Build the canonical sonic dataset, detecting and reporting time and data problems.

    Out-of-order stamps are put in time order and exact duplicates are dropped (first
    kept); gaps (intervals > 1.5 / f) are counted; samples with a non-zero diagnostic,
    spikes (:func:`spike_mask`) and non-finite values are flagged in ``sample_flag``
    (bits 1, 2, 4) and left untouched. Every such finding is counted in the attrs and
    described in ``attrs["warnings"]``. Nothing is interpolated.

    Parameters
    ----------
    path : path
        The file (for messages).
    time : ndarray of datetime64
        UTC stamps, file order.
    wind : mapping
        ``u``, ``v``, ``w``: wind components (m s-1, instrument frame); other keys
        are ignored.
    temperature : ndarray
        Sonic temperature (degC).
    diagnostic : ndarray of int
        Instrument status word, 0 = good.
    instrument, frame : str
        Instrument name and description of the (u, v, w) frame.
    attrs : mapping, optional
        More attributes (header values).
    warnings : sequence of str
        Reader-specific warnings to report as well.
    spike_threshold : float
        Spike threshold (robust std).
    sampling_rate_hz : float, optional
        Use this rate (Hz) instead of measuring it (formats without time stamps).

    Raises
    ------
    InputFileError
        No samples, or fewer than two distinct time stamps.
    """
    notes = list(warnings)
    t = _checked_stamps(path, time).astype(np.int64)
    keep, counts = _time_order(t, notes)
    t_ns = t[keep]
    rate = sampling_rate_hz if sampling_rate_hz is not None else measure_sampling_rate(t_ns)
    if not np.isfinite(rate) or rate <= 0:
        raise InputFileError(path, "fewer than two distinct time stamps: no sampling rate")
    n_gaps, missing = _gaps(t_ns, rate, notes)
    values = {c: np.asarray(wind[c], float)[keep] for c in ("u", "v", "w")}
    values["temperature"] = np.asarray(temperature, float)[keep]
    data = _within_physical_range(values, notes)
    diag = _status_words(np.asarray(diagnostic)[keep])
    flag, flag_counts = _sample_flags(data, diag, rate, spike_threshold, notes)
    variables = {k: (("time",), val) for k, val in data.items()}
    variables.update(diagnostic=(("time",), diag), sample_flag=(("time",), flag))
    ds = xr.Dataset(variables, coords={"time": (("time",), t_ns.astype("datetime64[ns]"))})
    ds.attrs = {
        **dict(attrs or {}),
        "instrument": instrument,
        "frame": frame,
        "sampling_rate_hz": float(rate),
        "source_files": [os.path.basename(os.fspath(path))],
        "n_gaps": n_gaps,
        "gap_seconds": missing,
        **counts,
        **flag_counts,
        "warnings": notes,
    }
    return with_canonical_attrs(ds, "sonic")


def _checked_stamps(path: str | os.PathLike, time: np.ndarray) -> np.ndarray:
    """The stamps as datetime64[ns]; a file of averages (not samples), no samples or a
    missing stamp raise :class:`InputFileError`."""
    from cwproc.io.averaged import averaged_table_reason, refuse_averaged_table

    refuse_averaged_table(path, averaged_table_reason(times=time))
    t = np.asarray(time).astype("datetime64[ns]")
    if t.size == 0:
        raise InputFileError(path, "no data records")
    if np.isnat(t).any():
        raise InputFileError(path, "time stamp missing", int(np.flatnonzero(np.isnat(t))[0]))
    return t


def _gaps(t_ns: np.ndarray, rate: float, notes: list[str]) -> tuple[int, float]:
    """Intervals longer than 1.5 sample periods: their number and the time missing (s),
    described in ``notes``."""
    dt = np.diff(t_ns) * 1e-9
    gap = dt > 1.5 / rate
    n_gaps = int(gap.sum())
    missing = float(np.sum(dt[gap] - 1.0 / rate))
    if n_gaps:
        notes.append(f"{n_gaps} gap(s) in the time stamps, {missing:.3f} s missing in total")
    return n_gaps, missing


def _status_words(diagnostic: np.ndarray) -> np.ndarray:
    """Diagnostic words as int64; a missing or non-integer word becomes -1 (not good)."""
    diag_f = diagnostic.astype(float)
    with np.errstate(invalid="ignore"):
        usable = np.isfinite(diag_f) & (np.abs(diag_f) < 2.0**62)
    return np.where(usable, diag_f, -1).astype(np.int64)


def _time_order(t_ns: np.ndarray, notes: list[str]) -> tuple[np.ndarray, dict[str, int]]:
    """Indices of the samples to keep, in time order, and the counts of what was found.

    Records out of the file's sequence or span (:func:`out_of_sequence`) and stray
    stamps (far from both neighbours, which agree) are dropped, the rest put in time
    order, exact duplicates dropped (first kept); each finding is described in
    ``notes``.
    """
    refused = out_of_sequence(t_ns)
    if refused.any():
        first = int(np.argmax(refused))
        stamp = np.datetime_as_string(np.datetime64(int(t_ns[first]), "ns"), unit="s")
        notes.append(
            f"{int(refused.sum())} record(s) whose time breaks the file's sequence or lies "
            f"outside its span refused (first: record {first + 1}, {stamp})"
        )
    stray = stray_stamps(t_ns) & ~refused
    if stray.any():
        notes.append(
            f"{int(stray.sum())} time stamp(s) far from both neighbours, which agree with "
            f"each other (a damaged record; first at record {int(np.argmax(stray)) + 1}): "
            "dropped"
        )
    valid = np.flatnonzero(~stray & ~refused)
    n_back = int(np.sum(np.diff(t_ns[valid]) < 0))
    order = valid[np.argsort(t_ns[valid], kind="stable")]
    dup = np.concatenate([[False], np.diff(t_ns[order]) == 0])
    n_dup = int(dup.sum())
    if n_back:
        notes.append(f"{n_back} time stamp(s) out of order: samples put in time order")
    if n_dup:
        notes.append(f"{n_dup} duplicated time stamp(s): later copies dropped")
    return order[~dup], {
        "n_out_of_order": n_back,
        "n_duplicates": n_dup,
        "n_out_of_sequence": int(refused.sum()),
    }


def _within_physical_range(data: dict[str, np.ndarray], notes: list[str]) -> dict[str, np.ndarray]:
    """Impossible values set to missing (they get sample flag 4), reported in ``notes``."""
    out = dict(data)
    for name, values in data.items():
        bad = outside_physical_range(name, values)
        if bad.any():
            notes.append(
                f"{int(bad.sum())} value(s) of {name} outside its physical range: set to missing"
            )
            out[name] = np.where(bad, np.nan, values)
    return out


def _sample_flags(
    data: dict[str, np.ndarray],
    diag: np.ndarray,
    rate: float,
    spike_threshold: float,
    notes: list[str],
) -> tuple[np.ndarray, dict[str, int]]:
    """``sample_flag`` (bits 1 diagnostic, 2 spike, 4 not finite) and the counts."""
    flag = np.zeros(diag.size, dtype=np.int8)
    flag[diag != 0] |= FLAG_DIAGNOSTIC
    width = round(SPIKE_WINDOW_S * rate)
    n_spikes = 0
    for name in ("u", "v", "w"):
        x = data[name]
        flag[~np.isfinite(x)] |= FLAG_NOT_FINITE
        spikes = spike_mask(x, width, spike_threshold, round(SPIKE_SCALE_S * rate))
        n_spikes += int(spikes.sum())
        flag[spikes] |= FLAG_SPIKE
    n_diag = int(np.sum(diag != 0))
    n_nonfinite = int(np.sum((flag & FLAG_NOT_FINITE) > 0))
    if n_diag:
        notes.append(f"{n_diag} sample(s) with a non-zero diagnostic word")
    if n_spikes:
        notes.append(f"{n_spikes} spike value(s) flagged (threshold {spike_threshold:g} std)")
    if n_nonfinite:
        notes.append(f"{n_nonfinite} sample(s) with a missing or non-finite wind component")
    return flag, {"n_spikes": n_spikes, "n_diagnostic": n_diag, "n_not_finite": n_nonfinite}
