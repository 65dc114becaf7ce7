"""Meteo-2 ultrasonic weather station (IAO SB RAS, Tomsk, ~10.7 Hz) text logs.

No real Meteo-2 file or format description is public (FORMATS.md section 4.6), so
cwproc defines the text layout below, writes it (:func:`write_meteo2`, used by the
simulator) and reads it (:func:`read_meteo2`), with every layout choice configurable
in ``[reader.meteo2]`` (preset ``configs/meteo2.toml``) so that a real export can be
read by configuration once one is obtained.

Layout (``docs/sonic.md``)::

    # cwproc meteo2 v1
    # instrument: Meteo-2 ultrasonic weather station (IAO SB RAS)
    # station: Tomsk
    # time: UTC
    time,u,v,w,t,diag
    2014-06-01T00:00:00.000,1.234,-0.567,0.089,12.34,0

* first line ``# cwproc meteo2`` (what :func:`cwproc.io.sniff_format` recognises);
  further ``# key: value`` lines become dataset attributes;
* one header row of column names, then one sample per line, ``,``-separated;
* ``time``: ISO 8601 (``T`` or space, any number of fractional digits) in UTC unless
  ``utc_offset_hours`` says otherwise; or ``time_format = "epoch"``: seconds since
  1970-01-01 UTC;
* ``u``, ``v``, ``w``: wind components (m s-1) in the instrument frame (x, y, z axes
  of the sonic array); ``t``: sonic temperature (degC); ``diag``: status word, 0 good;
* missing values: empty field, ``NaN`` or ``NAN``.

The sample rate is measured from the time stamps (never assumed): Meteo-2 samples at
about 10.7 Hz, Gladkikh et al. (2014), section 1.

This module also holds the helpers that every sonic reader uses to build the
canonical sonic dataset (:func:`sonic_dataset`): time ordering, duplicates, gaps,
spikes and flags are detected and reported there, never silently repaired.
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import CwprocError, InputFileError
from cwproc.io.netcdf import write_bytes_atomic
from cwproc.io.ranges import outside_physical_range
from cwproc.io.records import out_of_sequence
from cwproc.io.schema import with_canonical_attrs
from cwproc.io.timecheck import check_times, epoch_seconds_to_times

INSTRUMENT = "Meteo-2 ultrasonic weather station (IAO SB RAS)"
MAGIC = "# cwproc meteo2"

#: the measured variables of the canonical sonic dataset, in reading order
SONIC_FIELDS = ("u", "v", "w", "temperature", "diagnostic")

#: canonical name -> column name in the file (default layout)
DEFAULT_COLUMNS: dict[str, str] = {
    "time": "time",
    **dict(zip(SONIC_FIELDS, ("u", "v", "w", "t", "diag"), strict=True)),
}

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

_NA = ["", "NaN", "NAN", "nan", "NA"]
#: texts read as a missing value
NA_TEXT = _NA

READER_OPTIONS = {
    "delimiter",
    "columns",
    "time_format",
    "utc_offset_hours",
    "comment",
    "frame",
    "spike_threshold",
}


# --------------------------------------------------------------------------------------
# shared helpers of the sonic readers
# --------------------------------------------------------------------------------------


def check_options(path: str | os.PathLike, options: Mapping[str, Any], known: set[str]) -> None:
    """Reject unknown reader options with a message naming the file."""
    unknown = sorted(set(options) - known)
    if unknown:
        raise InputFileError(
            path,
            f"unknown reader option {unknown[0]!r}; known: {', '.join(sorted(known))}",
        )


def column_map(
    path: str | os.PathLike, options: Mapping[str, Any], defaults: Mapping[str, str]
) -> dict[str, str]:
    """Canonical name -> column name: the reader option ``columns`` merged over ``defaults``.

    Raises
    ------
    InputFileError
        ``columns`` is not a table or names an unknown canonical variable.
    """
    cols = dict(defaults)
    user = options.get("columns", {})
    if not isinstance(user, Mapping):
        raise InputFileError(path, "reader option 'columns' must be a table")
    unknown = sorted(set(user) - set(defaults))
    if unknown:
        raise InputFileError(path, f"reader option columns: unknown name {unknown[0]!r}")
    cols.update({str(k): str(v) for k, v in user.items()})
    return cols


def option_number(path: str | os.PathLike, options: Mapping[str, Any], key: str, default: float):
    """A finite numeric reader option (or its default)."""
    value = options.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        raise InputFileError(path, f"reader option {key!r} must be a finite number")
    return float(value)


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
    from cwproc.io.averaged import averaged_table_reason, refuse_averaged_table

    refuse_averaged_table(path, averaged_table_reason(times=time))
    t = np.asarray(time).astype("datetime64[ns]")
    if t.size == 0:
        raise InputFileError(path, "no data records")
    if np.isnat(t).any():
        raise InputFileError(path, "time stamp missing", int(np.flatnonzero(np.isnat(t))[0]))
    notes = list(warnings)
    keep, counts = _time_order(t.astype(np.int64), notes)
    t_ns = t.astype(np.int64)[keep]
    rate = sampling_rate_hz if sampling_rate_hz is not None else measure_sampling_rate(t_ns)
    if not np.isfinite(rate) or rate <= 0:
        raise InputFileError(path, "fewer than two distinct time stamps: no sampling rate")
    dt = np.diff(t_ns) * 1e-9
    gap = dt > 1.5 / rate
    n_gaps = int(gap.sum())
    missing = float(np.sum(dt[gap] - 1.0 / rate))
    if n_gaps:
        notes.append(f"{n_gaps} gap(s) in the time stamps, {missing:.3f} s missing in total")
    data = _within_physical_range(
        {
            **{c: np.asarray(wind[c], float)[keep] for c in ("u", "v", "w")},
            "temperature": np.asarray(temperature, float)[keep],
        },
        notes,
    )
    diag_f = np.asarray(diagnostic)[keep].astype(float)
    with np.errstate(invalid="ignore"):
        usable = np.isfinite(diag_f) & (np.abs(diag_f) < 2.0**62)
    diag = np.where(usable, diag_f, -1).astype(np.int64)
    flag, flag_counts = _sample_flags(data, diag, rate, spike_threshold, notes)
    ds = xr.Dataset(
        {
            **{k: (("time",), val) for k, val in data.items()},
            "diagnostic": (("time",), diag),
            "sample_flag": (("time",), flag),
        },
        coords={"time": (("time",), t_ns.astype("datetime64[ns]"))},
    )
    ds.attrs.update(dict(attrs or {}))
    ds.attrs.update(
        {
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
    )
    return with_canonical_attrs(ds, "sonic")


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


def first_bad_row(raw: pd.Series, parsed: np.ndarray) -> int | None:
    """Index of the first row whose text is present but did not parse, else None."""
    text = raw.astype("string").str.strip()
    present = text.notna() & ~text.isin(_NA).fillna(False)
    bad = present.to_numpy(dtype=bool) & ~np.isfinite(parsed) & ~_is_inf_text(text)
    idx = np.flatnonzero(bad)
    return int(idx[0]) if idx.size else None


def _is_inf_text(text: pd.Series) -> np.ndarray:
    low = text.str.lower().str.lstrip("+-")
    return low.isin(["inf", "infinity"]).fillna(False).to_numpy(dtype=bool)


def numeric_column(
    path: str | os.PathLike, frame: pd.DataFrame, column: str, first_line: int
) -> np.ndarray:
    """A column as float; a non-numeric entry raises InputFileError with its line."""
    raw = frame[column]
    if pd.api.types.is_numeric_dtype(raw):
        return raw.to_numpy(dtype=float, na_value=np.nan)
    parsed = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float, na_value=np.nan).copy()
    suspect = np.flatnonzero(np.isnan(parsed) & raw.notna().to_numpy())
    if suspect.size == 0:
        return parsed
    # only the rows that did not parse are examined as text
    sub = raw.iloc[suspect].astype("string").str.strip()
    retry = pd.to_numeric(sub, errors="coerce").to_numpy(dtype=float, na_value=np.nan)
    parsed[suspect] = retry
    bad = first_bad_row(sub, retry)
    if bad is not None:
        i = int(suspect[bad])
        raise InputFileError(
            path, f"column {column!r}: {raw.iloc[i]!r} is not a number", first_line + i
        )
    return parsed


_LINE_RE = re.compile(r"line (\d+)")


def read_table(
    path: str | os.PathLike, text: str, *, delimiter: str, skip: int, names: list[str] | None
) -> pd.DataFrame:
    """Parse delimited text with pandas; tokenising errors name the file line.

    Parameters
    ----------
    text : str
        The part of the file after ``skip`` lines.
    skip : int
        Lines before ``text`` (for line numbers).
    names : list of str, optional
        Column names (then ``text`` has no header row).
    """
    try:
        return pd.read_csv(
            io.StringIO(text),
            sep=delimiter,
            header=None if names is not None else 0,
            names=names,
            keep_default_na=False,
            na_values=_NA,
            skip_blank_lines=False,
            engine="c",
            low_memory=False,
        )
    except pd.errors.ParserError as exc:
        m = _LINE_RE.search(str(exc))
        line = skip + int(m.group(1)) if m else None
        detail = str(exc).split("C error:")[-1].strip()
        raise InputFileError(path, f"malformed data line: {detail}", line) from None
    except (ValueError, pd.errors.EmptyDataError) as exc:
        raise InputFileError(path, f"cannot parse the data: {exc}", skip + 1) from None


def parse_times(
    path: str | os.PathLike, raw: pd.Series, first_line: int, *, fmt: str = "ISO8601"
) -> np.ndarray:
    """Parse time stamps (flexible fractional seconds); a bad one names its line."""
    parsed = _to_utc(raw, fmt)
    missing = np.flatnonzero(parsed.isna().to_numpy())
    if missing.size:
        # retry only the failures, stripped of blanks and quotes
        text = raw.iloc[missing].astype("string").str.strip().str.strip('"')
        retry = _to_utc(text, fmt)
        bad = np.flatnonzero(retry.isna().to_numpy())
        if bad.size:
            i = int(missing[bad[0]])
            raise InputFileError(path, f"bad time stamp {raw.iloc[i]!r}", first_line + i)
        parsed.iloc[missing] = retry.to_numpy()
    return check_times(path, parsed.to_numpy(), first_line, written=raw.astype(str).to_numpy())


def _to_utc(raw: pd.Series, fmt: str) -> pd.Series:
    """Parse stamps to naive UTC (stamps with an explicit offset are converted)."""
    if not pd.api.types.is_string_dtype(raw) and not pd.api.types.is_object_dtype(raw):
        raw = raw.astype(str)  # numbers parsed with a format: pandas wants text
    try:
        parsed = pd.to_datetime(raw, format=fmt, errors="coerce", utc=True)
    except (ValueError, OverflowError, TypeError):
        parsed = pd.to_datetime(
            pd.Series(raw).map(lambda v: pd.to_datetime(v, errors="coerce", utc=True)),
            utc=True,
        )
    return pd.Series(parsed).dt.tz_localize(None).reset_index(drop=True)


def read_bytes(path: str | os.PathLike) -> bytes:
    """The whole file as bytes; I/O errors and a NUL byte (binary data) name the file."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    if b"\x00" in raw:
        line = raw[: raw.index(b"\x00")].count(b"\n") + 1
        raise InputFileError(path, "binary data (NUL byte) in a text file", line)
    return raw


def decode_text(raw: bytes) -> str:
    """Bytes as text: UTF-8, falling back to Latin-1."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def read_text(path: str | os.PathLike) -> str:
    """The whole file as text (UTF-8, falling back to Latin-1); I/O errors name the file."""
    return decode_text(read_bytes(path))


def blank_row(path: str | os.PathLike, frame: pd.DataFrame, first_line: int) -> None:
    """Raise on a completely empty data row (a blank line inside the data)."""
    empty = frame.isna().all(axis=1).to_numpy()
    if empty.any():
        i = int(np.flatnonzero(empty)[0])
        raise InputFileError(path, "empty data line", first_line + i)


# --------------------------------------------------------------------------------------
# Meteo-2
# --------------------------------------------------------------------------------------


def read_meteo2(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read a Meteo-2 text log (cwproc layout, module docstring) into a sonic dataset.

    Parameters
    ----------
    path : path
    delimiter : str, optional
        Field separator (default ``","``).
    columns : dict, optional
        Canonical name (``time``, ``u``, ``v``, ``w``, ``temperature``,
        ``diagnostic``) -> column name in the file; merged over :data:`DEFAULT_COLUMNS`.
    time_format : {"iso", "epoch"}, optional
        ISO 8601 stamps (default) or seconds since 1970-01-01.
    utc_offset_hours : float, optional
        Offset of the logger clock from UTC (h): UTC = stamp - offset. Default 0.
    comment : str, optional
        Prefix of header comment lines (default ``"#"``).
    frame : str, optional
        Description of the (u, v, w) frame (attr).
    spike_threshold : float, optional
        Spike threshold (robust std), default 6.

    Returns
    -------
    xarray.Dataset
        Canonical sonic dataset (``sampling_rate_hz`` measured, about 10.7 Hz).

    Raises
    ------
    InputFileError
        File, line and problem.
    """
    check_options(path, options, READER_OPTIONS)
    delimiter = str(options.get("delimiter", ","))
    comment = str(options.get("comment", "#"))
    cols = column_map(path, options, DEFAULT_COLUMNS)
    time_format = options.get("time_format", "iso")
    if time_format not in ("iso", "epoch"):
        raise InputFileError(path, "reader option 'time_format' must be 'iso' or 'epoch'")
    offset_h = option_number(path, options, "utc_offset_hours", 0.0)
    spike_threshold = option_number(path, options, "spike_threshold", SPIKE_THRESHOLD)

    text = read_text(path)
    lines = text.splitlines(keepends=True)
    header_attrs: dict[str, str] = {}
    n_comment = 0
    for line in lines:
        if not line.startswith(comment):
            break
        body = line[len(comment) :].strip()
        key, sep, value = body.partition(":")
        if sep and key.strip() and " " not in key.strip():
            header_attrs[f"meteo2_{key.strip()}"] = value.strip()
        n_comment += 1
    if n_comment >= len(lines):
        raise InputFileError(path, "no column header line", n_comment + 1)
    header_line = n_comment + 1
    notes = []
    if _cut_last_line(lines, n_comment, delimiter):
        notes.append(
            f"line {len(lines)}: last line cut short (no end of line, fewer fields than "
            "the header; a file still being written?): dropped"
        )
        lines = lines[:-1]
    frame = read_table(
        path, "".join(lines[n_comment:]), delimiter=delimiter, skip=n_comment, names=None
    )
    frame.columns = [str(c).strip() for c in frame.columns]
    for name in ("time", "u", "v", "w"):
        if cols[name] not in frame.columns:
            raise InputFileError(
                path,
                f"no column {cols[name]!r} ({name}) in the header; found "
                f"{', '.join(frame.columns)}",
                header_line,
            )
    if len(frame) == 0:
        raise InputFileError(path, "no data records", header_line + 1)
    first = header_line + 1
    blank_row(path, frame, first)
    if time_format == "iso":
        times = parse_times(path, frame[cols["time"]], first)
    else:
        secs = numeric_column(path, frame, cols["time"], first)
        bad = np.flatnonzero(~np.isfinite(secs))
        if bad.size:
            raise InputFileError(path, "missing time stamp", first + int(bad[0]))
        whole = np.floor(secs)
        times = epoch_seconds_to_times(
            path, whole, np.rint((secs - whole) * 1e9), np.datetime64(0, "ns"), first
        )
    times = times - np.timedelta64(round(offset_h * 3600e9), "ns")
    vals = {k: numeric_column(path, frame, cols[k], first) for k in ("u", "v", "w")}
    n = len(frame)
    temp = (
        numeric_column(path, frame, cols["temperature"], first)
        if cols["temperature"] in frame.columns
        else np.full(n, np.nan)
    )
    if cols["diagnostic"] in frame.columns:
        diag = numeric_column(path, frame, cols["diagnostic"], first)
    else:
        diag = np.zeros(n)
    return sonic_dataset(
        path,
        times,
        vals,
        temp,
        diag,
        instrument=INSTRUMENT,
        frame=str(options.get("frame", "instrument x, y, z axes of the Meteo-2 array")),
        attrs=header_attrs,
        warnings=notes,
        spike_threshold=spike_threshold,
    )


def _cut_last_line(lines: list[str], n_comment: int, delimiter: str) -> bool:
    """Whether the last data line was cut while being written: no end of line and fewer
    fields than the column header (a cut ``2024-06-01`` stamp read as midnight)."""
    if len(lines) <= n_comment + 2 or lines[-1].endswith(("\n", "\r")):
        return False
    return lines[-1].count(delimiter) < lines[n_comment].count(delimiter)


def write_meteo2(
    ds: xr.Dataset,
    path: str | os.PathLike,
    *,
    station: str = "",
    decimals: int = 3,
) -> None:
    """Write a sonic dataset in the cwproc Meteo-2 layout (module docstring).

    Parameters
    ----------
    ds : xarray.Dataset
        ``time`` (UTC), ``u``, ``v``, ``w`` (m s-1), optional ``temperature`` (degC)
        and ``diagnostic``.
    path : path
        Output file, written through an unpredictable temporary in its folder (mode from
        the umask), then renamed: a killed run leaves no half-written file, and the stale
        temporaries of an earlier killed run are removed.
    station : str
        Written to the ``# station:`` header line.
    decimals : int
        Decimal places of the wind components and temperature.
    """
    n = ds.sizes["time"]
    t = np.datetime_as_string(ds["time"].values.astype("datetime64[ms]"), unit="ms")
    frame = pd.DataFrame(
        {
            "time": t,
            "u": ds["u"].values,
            "v": ds["v"].values,
            "w": ds["w"].values,
            "t": ds["temperature"].values if "temperature" in ds else np.full(n, np.nan),
            "diag": ds["diagnostic"].values if "diagnostic" in ds else np.zeros(n, int),
        }
    )
    head = (
        f"{MAGIC} v1\n# instrument: {INSTRUMENT}\n# station: {station}\n# time: UTC\n"
        "# units: u v w m/s, t degC, diag 0=good\n"
    )
    text = head + frame.to_csv(index=False, float_format=f"%.{decimals}f", na_rep="NaN")
    path = Path(path)
    try:
        write_bytes_atomic(path, text.encode("utf-8"))
    except OSError as exc:
        raise CwprocError(f"write_meteo2 {path}: cannot write: {exc.strerror or exc}") from None
