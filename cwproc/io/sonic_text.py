"""Text logs of sonic anemometers: reader options, delimited tables, numbers, stamps.

Shared by the text readers (Meteo-2, Campbell TOA5, LI-COR GHG, Gill): the reader
options every one of them takes (:func:`check_options`, :func:`column_map`,
:func:`option_number`), the file as text (:func:`read_text`), its delimited table
(:func:`read_table`), and its numeric columns and time stamps
(:func:`numeric_column`, :func:`parse_times`). Every problem raises
:class:`cwproc.errors.InputFileError` naming the file and the line.
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from cwproc.errors import InputFileError
from cwproc.io.timecheck import check_times

_NA = ["", "NaN", "NAN", "nan", "NA"]


#: texts read as a missing value
NA_TEXT = _NA


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


def first_unparsed_row(raw: pd.Series, parsed: np.ndarray) -> int | None:
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
    bad = first_unparsed_row(sub, retry)
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
