"""LI-COR GHG ``.data`` text files (SMARTFlux / LI-7500RS with a sonic on the Aux inputs).

Layout as seen in the real fragment (FORMATS.md section 4.3): TAB-separated, LF;
metadata lines ``Key:<TAB>value`` (``Model:``, ``SN:``, ``Timezone:``, ...), one
``DATAH`` line with the column names, then ``DATA`` lines. ``Seconds`` (Unix time,
**UTC**) + ``Nanoseconds`` give the time; ``Date``/``Time`` are local time (``Timezone``)
and are not used. The sonic enters on analogue Aux channels: ``Aux 1 - U (m/s)``,
``Aux 2 - V (m/s)``, ``Aux 3 - W (m/s)``, ``Aux 4 - SOS (m/s)``; the last column
``CHK`` is a checksum.

Sonic temperature is computed from the speed of sound c: T_s = c^2/403 - 273.15
(degC; c^2 = 403 T_s for dry air, Kaimal and Gaynor (1991)). The Aux inputs carry no
sonic diagnostic, so ``diagnostic`` is 0 and ``attrs["diagnostic_source"]`` says so.
"""

from __future__ import annotations

import os
import zipfile
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io.sonic_samples import SPIKE_THRESHOLD, sonic_dataset
from cwproc.io.sonic_text import (
    check_options,
    column_map,
    numeric_column,
    option_number,
    read_table,
    read_text,
)
from cwproc.io.timecheck import epoch_seconds_to_times

#: origin of the Seconds column of LI-COR .data files (Unix time)
UNIX_EPOCH = np.datetime64("1970-01-01T00:00:00", "ns")

DEFAULT_COLUMNS: dict[str, str] = {
    "u": "Aux 1 - U (m/s)",
    "v": "Aux 2 - V (m/s)",
    "w": "Aux 3 - W (m/s)",
    "speed_of_sound": "Aux 4 - SOS (m/s)",
}

OPTIONS = {"columns", "frame", "spike_threshold"}

#: c^2 = GAMMA_R T_s (m2 s-2 K-1), Kaimal and Gaynor (1991)
SOS_COEFFICIENT = 403.0


def sonic_temperature_from_sos(sos: np.ndarray) -> np.ndarray:
    """Sonic temperature (degC) from the speed of sound c (m s-1): c^2/403 - 273.15."""
    return np.asarray(sos, dtype=float) ** 2 / SOS_COEFFICIENT - 273.15


#: largest .data member read from a .ghg archive (bytes; a half-hour file is ~30 MB)
GHG_MAX_BYTES = 512 << 20
#: zip compression methods the standard library reads
_ZIP_METHODS = (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA)
#: largest compression ratio accepted (a "zip bomb" beyond it is refused)
GHG_MAX_RATIO = 200


def ghg_text(path: str | os.PathLike) -> str:
    """The text of a LI-COR ``.data`` file, or of the ``.data`` member of a ``.ghg`` zip.

    The archive is read safely: exactly one ``*.data`` member, taken by name into memory
    (nothing is extracted to disk, so no member path can escape: no zip-slip), at most
    :data:`GHG_MAX_BYTES` uncompressed and :data:`GHG_MAX_RATIO` times its compressed
    size.

    Raises
    ------
    InputFileError
        Not a readable archive, no or several ``.data`` members, a member too large.
    """
    with open(path, "rb") as fh:
        magic = fh.read(4)
    if magic != b"PK\x03\x04":
        return read_text(path)
    try:
        with zipfile.ZipFile(path) as archive:
            members = [i for i in archive.infolist() if i.filename.endswith(".data")]
            if len(members) != 1:
                names = ", ".join(i.filename for i in archive.infolist()[:5])
                raise InputFileError(
                    path, f"a .ghg archive must hold one .data file; it holds: {names}"
                )
            info = members[0]
            if info.file_size > GHG_MAX_BYTES or info.file_size > GHG_MAX_RATIO * max(
                info.compress_size, 1
            ):
                raise InputFileError(
                    path, f"{info.filename}: {info.file_size} bytes unpacked is implausible"
                )
            if info.compress_type not in _ZIP_METHODS:
                raise InputFileError(
                    path, f"{info.filename}: zip compression method {info.compress_type}"
                )
            raw = archive.read(info)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError) as exc:
        raise InputFileError(path, f"cannot read the .ghg archive: {exc}") from None
    if b"\x00" in raw:
        raise InputFileError(path, f"{info.filename}: binary data (NUL byte) in the text")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def read_ghg(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read a LI-COR GHG ``.data`` file (or a ``.ghg`` archive of one) into a sonic dataset.

    Parameters
    ----------
    path : path
    columns : dict, optional
        Canonical name (``u``, ``v``, ``w``, ``speed_of_sound``) -> column name.
    frame : str, optional
        Description of the sonic frame (attr).
    spike_threshold : float, optional
        Spike threshold (robust std).

    Returns
    -------
    xarray.Dataset
        Canonical sonic dataset; the metadata lines in ``ghg_*`` attrs.

    Raises
    ------
    InputFileError
        File, line and problem.
    """
    check_options(path, options, OPTIONS)
    cols = column_map(path, options, DEFAULT_COLUMNS)

    lines = ghg_text(path).splitlines()
    attrs, header_at = _metadata_lines(path, lines)
    names = [c.strip() for c in lines[header_at].split("\t")]
    for key in ("Seconds", "Nanoseconds", cols["u"], cols["v"], cols["w"]):
        if key not in names:
            raise InputFileError(path, f"no column {key!r} in the DATAH line", header_at + 1)
    data_lines = lines[header_at + 1 :]
    while data_lines and not data_lines[-1].strip():
        data_lines.pop()
    first = header_at + 2
    if not data_lines:
        raise InputFileError(path, "no DATA lines", first)
    _check_data_lines(path, data_lines, len(names), first)
    frame = read_table(
        path, "\n".join(data_lines) + "\n", delimiter="\t", skip=header_at + 1, names=names
    )
    secs = numeric_column(path, frame, "Seconds", first)
    nanos = numeric_column(path, frame, "Nanoseconds", first)
    bad = np.flatnonzero(~np.isfinite(secs) | ~np.isfinite(nanos) | (nanos < 0) | (nanos >= 1e9))
    if bad.size:
        raise InputFileError(path, "missing or invalid Seconds/Nanoseconds", first + int(bad[0]))
    times = epoch_seconds_to_times(path, secs, nanos, UNIX_EPOCH, first)
    vals = {k: numeric_column(path, frame, cols[k], first) for k in ("u", "v", "w")}
    n = len(frame)
    if cols["speed_of_sound"] in names:
        temp = sonic_temperature_from_sos(
            numeric_column(path, frame, cols["speed_of_sound"], first)
        )
    else:
        temp = np.full(n, np.nan)
    attrs["diagnostic_source"] = "none: the Aux inputs carry no sonic diagnostic"
    attrs["time_reference"] = "Seconds + Nanoseconds (Unix time, UTC)"
    return sonic_dataset(
        path,
        times,
        vals,
        temp,
        np.zeros(n),
        instrument=f"LI-COR {attrs.get('ghg_model', 'GHG')} with sonic on Aux inputs",
        frame=str(options.get("frame", "sonic frame as wired to Aux 1-3 (U, V, W)")),
        attrs=attrs,
        spike_threshold=option_number(path, options, "spike_threshold", SPIKE_THRESHOLD),
    )


def _metadata_lines(path: str | os.PathLike, lines: list[str]) -> tuple[dict[str, str], int]:
    """The ``Key: value`` lines before the ``DATAH`` column header, as ``ghg_<key>``
    attributes, and the index of the ``DATAH`` line.

    Raises
    ------
    InputFileError
        A line without ``Key:`` before ``DATAH``, or no ``DATAH`` line.
    """
    attrs: dict[str, str] = {}
    for i, line in enumerate(lines):
        if line.startswith("DATAH\t"):
            return attrs, i
        key, sep, value = line.partition(":")
        if not sep:
            raise InputFileError(path, "metadata line without 'Key:' before DATAH", i + 1)
        attrs["ghg_" + key.strip().lower().replace(" ", "_")] = value.strip()
    raise InputFileError(path, "no DATAH column-header line", len(lines) + 1)


def _check_data_lines(
    path: str | os.PathLike, data_lines: list[str], n_fields: int, first: int
) -> None:
    """Every line after ``DATAH`` starts with ``DATA`` and has ``n_fields`` TAB-separated
    fields (``first``: the 1-based number of the first).

    Raises
    ------
    InputFileError
        The first line that does not, named.
    """
    text = pd.Series(data_lines, dtype="string")
    not_data = np.flatnonzero(~text.str.startswith("DATA\t").to_numpy(dtype=bool))
    if not_data.size:
        raise InputFileError(path, "line does not start with DATA", first + int(not_data[0]))
    counts = text.str.count("\t").to_numpy()
    wrong = np.flatnonzero(counts != n_fields - 1)
    if wrong.size:
        i = int(wrong[0])
        raise InputFileError(
            path, f"data line has {counts[i] + 1} fields, expected {n_fields}", first + i
        )
