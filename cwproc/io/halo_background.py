"""Reader of Halo Photonics Stream Line background files (``Background_DDMMYY-HHMMSS.txt``).

The Stream Line measures its detector background (no laser pulse) and writes one value
per range gate to a file named after the UTC time of the measurement. ``.hpl`` files
give the intensity as SNR + 1 = P / P_bg of this background (Manninen et al. (2016);
Vakkari et al. (2019)), so the background of the hour lets the SNR be corrected
(:mod:`cwproc.stages.snr_correction`).

Two layouts exist (``FORMATS.md`` section 1.7 of the real sample files):

* one value per line, CRLF, e.g. ``16794008.750000``;
* all values joined with no separator (Hyytiala, newer firmware); every value has
  exactly six decimals, so the text is split after each ``.dddddd``.

Decimal commas (``16794008,750000``) are accepted in the one-per-line layout, as
some Stream Line software versions write them in the ``.hpl`` headers.
"""

from __future__ import annotations

import datetime as _dt
import os
import re
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.errors import InputFileError

#: the time in a background file name (``Background_141222-000013.txt``: DDMMYY-HHMMSS)
NAME_TIME = re.compile(r"Background_(\d{6}-\d{6})(?:\.txt)?$", re.IGNORECASE)
#: one value of the joined layout: digits, a point and exactly six decimals
_JOINED_VALUE = re.compile(rb"-?\d+\.\d{6}")
#: one value of the line layout (point or comma decimal separator)
_LINE_VALUE = re.compile(rb"[+-]?\d+(?:[.,]\d+)?(?:[eE][+-]?\d+)?")
#: a line of the line layout, for recognising the format (decimals required)
_SNIFF_LINE = re.compile(rb"\d+[.,]\d+")
#: the joined layout, possibly cut at the end
_SNIFF_JOINED = re.compile(rb"(?:\d+\.\d{6})+\d*\.?\d*")
#: a head this long may end inside a line (cwproc.io reads 4096 bytes to recognise files)
_SNIFF_FULL = 4096
#: largest background file read (bytes); 10000 gates x 20 characters is 200 kB
MAX_BYTES = 1 << 20


def background_time(path: str | os.PathLike) -> np.datetime64:
    """UTC time of a background measurement from its file name.

    Raises
    ------
    InputFileError
        The name holds no ``Background_DDMMYY-HHMMSS`` or not a valid date.
    """
    name = Path(path).name
    match = NAME_TIME.search(name)
    if match is None:
        raise InputFileError(
            path, "file name holds no time 'Background_DDMMYY-HHMMSS' (Stream Line background)"
        )
    try:
        when = _dt.datetime.strptime(match.group(1), "%d%m%y-%H%M%S")
    except ValueError:
        raise InputFileError(
            path, f"file name time {match.group(1)!r} is not a valid DDMMYY-HHMMSS date"
        ) from None
    return np.datetime64(when, "ns")


def is_background_text(head: bytes) -> bool:
    """Whether the first bytes of a file look like a Stream Line background file.

    Either at least two lines, every complete line of ``head`` one number with decimals
    (CRLF layout), or one run of at least two numbers with six decimals joined without
    separators (joined layout; ``head`` may cut its last number).
    """
    text = head.strip()
    if b"\n" in text:
        lines = text.split(b"\n")
        if len(head) >= _SNIFF_FULL:  # the last line may be cut by the head
            lines = lines[:-1]
        return len(lines) >= 2 and all(_SNIFF_LINE.fullmatch(ln.strip()) for ln in lines)
    return bool(_SNIFF_JOINED.fullmatch(text)) and text.count(b".") >= 2


def parse_background(data: bytes, path: str | os.PathLike = "<bytes>") -> np.ndarray:
    """The per-gate background values of a background file's content.

    Parameters
    ----------
    data : bytes
        The whole file.
    path : path
        The file, for error messages.

    Returns
    -------
    numpy.ndarray
        Background per range gate (detector counts, dimensionless), float64.

    Raises
    ------
    InputFileError
        Empty file, a line that is not one number (file, line and text named), a joined
        run that does not split into ``.dddddd`` values, or a non-finite or negative value.
    """
    text = data.strip()
    if not text:
        raise InputFileError(path, "background file is empty")
    lines = b"\n" in text
    values = _parse_lines(text, path) if lines else _parse_joined(text, path)
    bad = np.flatnonzero(~np.isfinite(values) | (values < 0))
    if bad.size:
        i = int(bad[0])
        raise InputFileError(
            path,
            f"gate {i}: background {float(values[i])!r} is not a finite value >= 0",
            i + 1 if lines else 1,
        )
    return values


def _parse_lines(text: bytes, path: str | os.PathLike) -> np.ndarray:
    lines = text.split(b"\n")
    out = np.empty(len(lines))
    for number, raw in enumerate(lines, start=1):
        item = raw.strip()
        if not _LINE_VALUE.fullmatch(item):
            shown = item[:40].decode("latin-1")
            raise InputFileError(
                path, f"expected one background value per line, got {shown!r}", number
            )
        out[number - 1] = float(item.replace(b",", b"."))
    return out


def _parse_joined(text: bytes, path: str | os.PathLike) -> np.ndarray:
    pieces = _JOINED_VALUE.findall(text)
    used = sum(len(p) for p in pieces)
    if not pieces or used != len(text):
        pos = 0
        for p in pieces:  # where the joined run stops being .dddddd values
            if not text.startswith(p, pos):
                break
            pos += len(p)
        shown = text[pos : pos + 30].decode("latin-1")
        raise InputFileError(
            path,
            f"byte {pos + 1}: joined background values do not split into numbers with six "
            f"decimals at {shown!r}",
            1,
        )
    return np.array([float(p) for p in pieces])


def read_halo_background(path: str | os.PathLike) -> xr.Dataset:
    """Read one Stream Line background file.

    Parameters
    ----------
    path : path
        ``Background_DDMMYY-HHMMSS.txt`` (any prefix before ``Background_`` is allowed).

    Returns
    -------
    xarray.Dataset
        ``background(range)`` (detector counts per gate, dimensionless), the scalar
        coordinate ``time`` (UTC, from the file name) and the gate index ``gate(range)``
        (the file gives no gate length, so no range in metres); attributes
        ``source_files``, ``layout`` ("lines" or "joined") and ``instrument``.

    Raises
    ------
    InputFileError
        Unreadable, too large or damaged file, or a name without the time.
    """
    when = background_time(path)
    try:
        size = os.path.getsize(path)
        if size > MAX_BYTES:
            raise InputFileError(
                path, f"{size} bytes is too large for a background file (> {MAX_BYTES})"
            )
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    values = parse_background(data, path)
    layout = "lines" if b"\n" in data.strip() else "joined"
    return xr.Dataset(
        {"background": ("range", values, {"long_name": "detector background", "units": "1"})},
        coords={"time": when, "gate": ("range", np.arange(values.size))},
        attrs={
            "instrument": "Halo Photonics Stream Line",
            "instrument_kind": "streamline",
            "source_files": [Path(path).name],
            "layout": layout,
        },
    )
