"""Gill UVW ASCII reader (documented layout, FORMATS.md section 4.4; no real file exists)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.errors import InputFileError
from cwproc.io import Format, detect_format
from cwproc.io.gill import read_gill, xor_checksum

OPTS = {"start_time": "2020-05-01T12:00:00", "sampling_rate_hz": 20.0}

FIXTURE_CHECK = HealthCheck.function_scoped_fixture


def _framed(payload: str) -> str:
    cs = xor_checksum(pd.Series([payload], dtype="string"))[0]
    return f"\x02{payload}\x03{cs:02X}\r\n"


def _file(tmp_path, n=200, seed=0, framed=True) -> tuple:
    rng = np.random.default_rng(seed)
    u, v, w = 2 + rng.standard_normal(n), -1 + rng.standard_normal(n), rng.standard_normal(n)
    out = []
    for a, b, c in zip(u, v, w, strict=True):
        payload = f"Q,{a:+07.2f},{b:+07.2f},{c:+07.2f},M,+345.68,+023.51,00,"
        out.append(_framed(payload) if framed else payload + "\r\n")
    p = tmp_path / "gill.txt"
    p.write_text("".join(out), encoding="latin-1", newline="")
    return p, np.round(u, 2), np.round(v, 2), np.round(w, 2)


def test_documented_example_checksum():
    # XOR of "Q,+000.30,..." computed independently byte by byte
    payload = "Q,+000.30,+000.21,-000.43,M,+345.68,+023.51,00,"
    ref = 0
    for ch in payload.encode():
        ref ^= ch
    assert xor_checksum(pd.Series([payload], dtype="string"))[0] == ref


def test_framed_lines_read_with_configured_clock(tmp_path):
    p, u, _v, w = _file(tmp_path)
    assert detect_format(p) == Format.GILL
    ds = read_gill(p, **OPTS)
    assert ds.sizes["time"] == 200
    np.testing.assert_allclose(ds["u"].values, u)
    np.testing.assert_allclose(ds["w"].values, w)
    assert float(ds["temperature"][0]) == pytest.approx(23.51)
    assert str(ds["time"].values[1]) == "2020-05-01T12:00:00.050000000"
    assert ds.attrs["sampling_rate_hz"] == 20.0
    assert ds.attrs["gill_checksum_mismatches"] == 0 and int(ds["sample_flag"].sum()) == 0


def test_axis_convention_options(tmp_path):
    p, u, v, _ = _file(tmp_path, framed=False)
    ds = read_gill(p, **OPTS, u_sign=-1, swap_uv=True)
    np.testing.assert_allclose(ds["u"].values, v)
    np.testing.assert_allclose(ds["v"].values, -u)


def test_checksum_mismatch_and_status_are_flagged(tmp_path):
    p, *_ = _file(tmp_path, n=50)
    lines = p.read_text(encoding="latin-1").splitlines(keepends=True)
    lines[3] = lines[3].replace("+345.68", "+345.69")  # payload changed, checksum not
    lines[7] = _framed("Q,+001.00,+000.50,+000.10,M,+345.68,+023.51,0A,")
    p.write_text("".join(lines), encoding="latin-1", newline="")
    ds = read_gill(p, **OPTS)
    assert ds["diagnostic"].values[3] == 256 and ds["diagnostic"].values[7] == 10
    assert ds["sample_flag"].values[3] & 1 and ds["sample_flag"].values[7] & 1
    assert ds.attrs["gill_checksum_mismatches"] == 1


def test_logged_variant_with_time_prefix_and_units(tmp_path):
    p = tmp_path / "logged.txt"
    p.write_text(
        "00.011,A,+000.03,+000.00,-000.01,M,+348.85,+028.97,00,+2.4225,+2.4225,+0.6750,39\n"
        "00.061,A,+003.60,+000.00,-000.01,K,+348.85,+028.97,00,+2.4225,+2.4225,+0.6750,39\n"
    )
    ds = read_gill(p, **OPTS)
    assert ds["u"].values == pytest.approx([0.03, 1.0])  # 3.6 km/h = 1 m/s


def test_errors(tmp_path):
    p, *_ = _file(tmp_path, n=20, framed=False)
    with pytest.raises(InputFileError, match="start_time"):
        read_gill(p)
    lines = p.read_text().splitlines(keepends=True)
    lines[5] = lines[5].replace(",M,", ",X,")
    p.write_text("".join(lines))
    with pytest.raises(InputFileError, match="units flag") as err:
        read_gill(p, **OPTS)
    assert err.value.line == 6
    lines[5] = "Q,+0a0.30,+000.21,-000.43,M,+345.68,+023.51,00,\r\n"
    p.write_text("".join(lines))
    with pytest.raises(InputFileError, match="not a number") as err:
        read_gill(p, **OPTS)
    assert err.value.line == 6


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_mutated_gill_gives_dataset_or_input_file_error(tmp_path, data):
    p, *_ = _file(tmp_path, n=30)
    blob = bytearray(p.read_bytes())
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(blob) - 1))
        blob[i] = data.draw(st.sampled_from(list(b"0123456789,.+-QMK\r\n\x02\x03 x")))
    p.write_bytes(bytes(blob[: data.draw(st.integers(0, len(blob)))]))
    try:
        ds = read_gill(p, **OPTS)
    except InputFileError:
        return
    assert isinstance(ds, xr.Dataset) and ds.sizes["time"] > 0


def test_character_beyond_one_byte_is_a_checksum_mismatch_not_a_crash(tmp_path):
    """Junk bytes \\xc4\\x80 (U+0100 in UTF-8) after a framed line raised
    UnicodeEncodeError from the checksum (found by tests/test_damaged_inputs.py)."""
    payloads = pd.Series(["Q,+001.00,-002.00", "Q,+001.00,-002.0\u0100"], dtype="string")
    sums = xor_checksum(payloads)
    expected = 0
    for b in b"Q,+001.00,-002.00":
        expected ^= b
    assert sums[0] == expected
    assert sums[1] > 255  # matches no two-hex-digit checksum: flagged as a mismatch
