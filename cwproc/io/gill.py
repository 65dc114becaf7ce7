"""Gill WindMaster / R3 UVW ASCII logs (FORMATS.md section 4.4; no real file is public).

Documented UVW line [doc]::

    <STX>Q,+000.30,+000.21,-000.43,M,+345.68,+023.51,00,<ETX>1F

node address, U, V, W, units flag (``M`` m/s; ``N`` knots, ``P`` mph, ``K`` km/h,
``F`` ft/min are converted), speed of sound (m s-1), sonic temperature (degC), status
(hex, ``00`` good), framed by STX (0x02) ... ETX (0x03) and a two-hex-digit XOR
checksum of the bytes between them. STX/ETX/checksum may be absent (logger already
stripped them). A logged variant starts with a logger time field and may append
analogue channels: ``00.011,A,+000.03,...,00,+2.4225,...``; the leading field is
dropped (it is seconds within the minute, not a full time).

The lines carry **no absolute time**: options ``start_time`` (ISO, UTC) and
``sampling_rate_hz`` are required, and sample i is at start_time + i / rate.

Gill's U/V axes and signs depend on the configured alignment, so they are options:
``u_sign``, ``v_sign`` (+1 or -1) and ``swap_uv`` map the output onto the right-handed
instrument frame (u, v, w) that cwproc stores. A checksum mismatch or a non-zero status
sets ``diagnostic`` (checksum mismatch: 256 + status) and so ``sample_flag`` bit 1.
"""

from __future__ import annotations

import io
import os
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io.sonic_samples import SPIKE_THRESHOLD, sonic_dataset
from cwproc.io.sonic_text import check_options, option_number, read_text
from cwproc.io.timecheck import check_times

OPTIONS = {
    "start_time",
    "sampling_rate_hz",
    "u_sign",
    "v_sign",
    "swap_uv",
    "frame",
    "spike_threshold",
}

#: units flag -> factor to m s-1
UNIT_FACTORS = {"M": 1.0, "N": 0.514444, "P": 0.44704, "K": 1.0 / 3.6, "F": 0.00508}

#: diagnostic value added when the checksum does not match
CHECKSUM_MISMATCH = 256


def xor_checksum(payloads: pd.Series) -> np.ndarray:
    """XOR of the bytes of each payload (the text between STX and ETX).

    The XOR runs over code points: a character beyond one byte (damage, a wrong file)
    gives a value above 255 that matches no two-hex-digit checksum.
    """
    out = np.zeros(len(payloads), dtype=np.int64)
    width = int(payloads.str.len().max() or 0)
    if width == 0:
        return out
    padded = payloads.str.pad(width, side="right", fillchar="\x00")
    codes = np.frombuffer("".join(padded).encode("utf-32-le"), dtype=np.uint32)
    return np.bitwise_xor.reduce(codes.reshape(len(payloads), width), axis=1).astype(np.int64)


def read_gill(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read a Gill UVW ASCII log into a sonic dataset.

    Parameters
    ----------
    path : path
    start_time : str
        Time of the first line (ISO 8601, UTC). Required.
    sampling_rate_hz : float
        Output rate of the anemometer (Hz). Required.
    u_sign, v_sign : float, optional
        +1 (default) or -1: sign applied to U and V.
    swap_uv : bool, optional
        Exchange U and V (after the signs), default false.
    frame : str, optional
        Description of the frame.
    spike_threshold : float, optional
        Spike threshold (robust std).

    Raises
    ------
    InputFileError
        Missing options, or file, line and problem.
    """
    check_options(path, options, OPTIONS)
    start, rate, signs, swap = _timing_and_axes(path, options)
    lines = pd.Series(read_text(path).splitlines(), dtype="string")
    while len(lines) and not lines.iloc[-1].strip():
        lines = lines.iloc[:-1]
    if len(lines) == 0:
        raise InputFileError(path, "no data lines", 1)
    payload, diag_extra = _payloads(lines)
    table, offset = _field_table(path, payload, len(lines))
    num, factor, status = _fields(path, table, offset)
    u = signs[0] * num["u"] * factor
    v = signs[1] * num["v"] * factor
    if swap:
        u, v = v, u
    n = len(table)
    times = start + np.rint(np.arange(n) * (1e9 / rate)).astype("timedelta64[ns]")
    return sonic_dataset(
        path,
        times,
        {"u": u, "v": v, "w": num["w"] * factor},
        num["t"],
        status + diag_extra,
        instrument="Gill ultrasonic anemometer (UVW ASCII)",
        frame=str(options.get("frame", "Gill UVW axes mapped by u_sign, v_sign, swap_uv")),
        attrs={
            "gill_checksum_mismatches": int(np.sum(diag_extra > 0)),
            "time_reference": "start_time + line index / sampling_rate_hz (configured)",
            "speed_of_sound_mean_m_s": float(np.nanmean(num["sos"])),
        },
        spike_threshold=option_number(path, options, "spike_threshold", SPIKE_THRESHOLD),
        sampling_rate_hz=rate,
    )


def _timing_and_axes(
    path: str | os.PathLike, options: dict[str, Any]
) -> tuple[np.datetime64, float, list[float], bool]:
    """``start_time``, ``sampling_rate_hz`` (Hz), the signs of U and V and ``swap_uv``."""
    if "start_time" not in options or "sampling_rate_hz" not in options:
        raise InputFileError(
            path,
            "Gill UVW lines carry no time: set [reader.gill] start_time and sampling_rate_hz",
        )
    written = str(options["start_time"])
    try:  # parsed in its own unit (not nanoseconds: a year beyond 2262 would wrap)
        start = np.datetime64(written.replace("Z", ""))
    except ValueError:
        raise InputFileError(path, "reader option start_time is not an ISO time") from None
    start = check_times(path, np.array([start]), None, written=[written])[0]
    rate = option_number(path, options, "sampling_rate_hz", 0.0)
    if rate <= 0:
        raise InputFileError(path, "reader option sampling_rate_hz must be > 0")
    signs = [option_number(path, options, k, 1.0) for k in ("u_sign", "v_sign")]
    if any(s not in (1.0, -1.0) for s in signs):
        raise InputFileError(path, "reader options u_sign and v_sign must be +1 or -1")
    swap = options.get("swap_uv", False)
    if not isinstance(swap, bool):
        raise InputFileError(path, "reader option swap_uv must be true or false")
    return start, rate, signs, swap


def _payloads(lines: pd.Series) -> tuple[pd.Series, np.ndarray]:
    """The text between STX and ETX of each line, and the checksum-mismatch diagnostic."""
    body = lines.str.lstrip("\x02")
    framed = body.str.contains("\x03", regex=False).to_numpy(dtype=bool)
    parts = body.str.partition("\x03")
    payload, check = parts[0], parts[2].str.strip()
    diag_extra = np.zeros(len(lines), dtype=np.int64)
    if framed.any():
        given = pd.to_numeric(
            check.where(check.str.fullmatch(r"[0-9A-Fa-f]{2}").fillna(False)).map(
                lambda s: int(s, 16), na_action="ignore"
            ),
            errors="coerce",
        ).to_numpy(dtype=float, na_value=np.nan)
        computed = xor_checksum(payload)
        diag_extra = np.where(framed & (given != computed), CHECKSUM_MISMATCH, 0)
    return payload.str.rstrip(","), diag_extra


def _field_table(
    path: str | os.PathLike, payload: pd.Series, n_lines: int
) -> tuple[pd.DataFrame, int]:
    """The payloads split at commas, and the column of the node letter (0 or 1)."""
    n_fields = (payload.str.count(",") + 1).to_numpy()
    wrong = np.flatnonzero(n_fields != n_fields[0])
    if wrong.size:
        i = int(wrong[0])
        raise InputFileError(
            path, f"line has {n_fields[i]} fields, the first line {n_fields[0]}", i + 1
        )
    try:
        table = pd.read_csv(
            io.StringIO("\n".join(payload.tolist()) + "\n"),
            header=None,
            dtype=str,
            keep_default_na=False,
            skip_blank_lines=False,
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        raise InputFileError(path, f"malformed data: {exc}", 1) from None
    if len(table) != n_lines:
        raise InputFileError(path, "malformed data (quote or line structure)", 1)
    first = table.iloc[0, 0].strip() if table.shape[1] else ""
    offset = 0 if first[:1].isalpha() else 1
    if table.shape[1] < offset + 8:
        raise InputFileError(path, f"{table.shape[1]} fields, expected at least {offset + 8}", 1)
    node = table.iloc[:, offset].str.strip()
    bad = np.flatnonzero(~node.str.fullmatch(r"[A-Za-z]").fillna(False).to_numpy(dtype=bool))
    if bad.size:
        raise InputFileError(path, "no node-address letter where expected", int(bad[0]) + 1)
    return table, offset


def _fields(
    path: str | os.PathLike, table: pd.DataFrame, offset: int
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """The numeric fields (U, V, W, speed of sound, temperature), unit factors, status."""
    num = {}
    for name, col in (("u", 1), ("v", 2), ("w", 3), ("sos", 5), ("t", 6)):
        raw = table.iloc[:, offset + col].str.strip()
        vals = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float, na_value=np.nan)
        wrong = np.flatnonzero(~np.isfinite(vals) & (raw.str.len().fillna(0) > 0).to_numpy())
        if wrong.size:
            i = int(wrong[0])
            raise InputFileError(path, f"{name} field {raw.iloc[i]!r} is not a number", i + 1)
        num[name] = vals
    unit = table.iloc[:, offset + 4].str.strip()
    factor = unit.map(UNIT_FACTORS).to_numpy(dtype=float, na_value=np.nan)
    wrong = np.flatnonzero(~np.isfinite(factor))
    if wrong.size:
        i = int(wrong[0])
        raise InputFileError(path, f"unknown units flag {unit.iloc[i]!r}", i + 1)
    status_txt = table.iloc[:, offset + 7].str.strip()
    status = status_txt.map(
        lambda s: int(s, 16) if s and all(c in "0123456789abcdefABCDEF" for c in s) else -1
    ).to_numpy(dtype=np.int64)
    wrong = np.flatnonzero(status < 0)
    if wrong.size:
        i = int(wrong[0])
        raise InputFileError(path, f"status field {status_txt.iloc[i]!r} is not hex", i + 1)
    return num, factor, status
