"""Campbell TOA5 / TOB1 readers against the real CSAT3 files (FORMATS.md section 4.1-4.2)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.errors import InputFileError
from cwproc.io import Format, campbell, detect_format
from cwproc.io.campbell import read_toa5
from cwproc.io.campbell_tob1 import decode_fp2, read_tob1

TOA5 = "sonic/TOA5_6843.ts_Above_2012_06_07_1245.dat"
TOB1 = "sonic/testing.tob"
FIXTURE_CHECK = HealthCheck.function_scoped_fixture


@pytest.fixture(scope="module")
def toa5_lines(real_data) -> list[bytes]:
    return (real_data / TOA5).read_bytes().splitlines(keepends=True)


def _write(tmp_path, lines, name="x.dat"):
    p = tmp_path / name
    p.write_bytes(b"".join(lines))
    return p


def test_real_toa5_shape_and_values(real_data):
    ds = read_toa5(real_data / TOA5)
    assert detect_format(real_data / TOA5) == Format.TOA5
    assert ds.sizes["time"] == 18000
    assert str(ds["time"].values[0]) == "2012-06-07T12:45:00.050000000"
    assert str(ds["time"].values[1]) == "2012-06-07T12:45:00.100000000"
    assert str(ds["time"].values[-1]) == "2012-06-07T13:00:00.000000000"
    # spot values from data lines 1 and 18000 of the text
    assert (ds["u"][0], ds["v"][0], ds["w"][0]) == pytest.approx((2.00875, -1.59625, -0.4375))
    assert float(ds["temperature"][0]) == pytest.approx(27.65771)
    assert float(ds["u"][-1]) == pytest.approx(0.5987501)
    assert ds.attrs["sampling_rate_hz"] == pytest.approx(20.0, rel=1e-9)
    assert ds.attrs["toa5_table"] == "ts_Above" and ds.attrs["toa5_logger"] == "CR3000"
    assert ds.attrs["warnings"] == [] and int(ds["sample_flag"].sum()) == 0
    assert np.all(ds["diagnostic"].values == 0)


def test_toa5_utc_offset(real_data):
    ds = read_toa5(real_data / TOA5, utc_offset_hours=7)
    assert str(ds["time"].values[0]) == "2012-06-07T05:45:00.050000000"


def test_toa5_nan_inf_and_record_gap_are_reported(tmp_path, toa5_lines):
    lines = toa5_lines[:400]
    lines[10] = (
        b'"2012-06-07 12:45:00.35",111850406,"NAN",-1.54425,-0.33,667.5572,8.773306,'
        b"27.69751,100.1841,0\r\n"
    )
    lines[20] = (
        b'"2012-06-07 12:45:00.85",111850416,1.9,-INF,-0.33,667.5572,8.773306,'
        b"27.69751,100.1841,0\r\n"
    )
    del lines[100:110]  # ten records lost
    ds = read_toa5(_write(tmp_path, lines))
    assert np.isnan(ds["u"].values[6])
    assert ds["sample_flag"].values[6] & 4
    # an infinite value is impossible: filled as missing and flagged (issue 17.3)
    assert np.isnan(ds["v"].values[16]) and ds["sample_flag"].values[16] & 4
    assert any("of v outside its physical range" in w for w in ds.attrs["warnings"])
    assert ds.attrs["n_not_finite"] == 2
    assert ds.attrs["n_gaps"] == 1
    assert ds.attrs["gap_seconds"] == pytest.approx(0.5, abs=1e-6)
    assert any("RECORD jumps" in w and "10 record" in w for w in ds.attrs["warnings"])


def test_toa5_out_of_order_and_duplicates_are_reported(tmp_path, toa5_lines):
    lines = toa5_lines[:200]
    lines[50], lines[51] = lines[51], lines[50]
    lines.insert(80, lines[80])
    ds = read_toa5(_write(tmp_path, lines))
    assert ds.sizes["time"] == 196
    assert ds.attrs["n_out_of_order"] == 1 and ds.attrs["n_duplicates"] == 1
    assert np.all(np.diff(ds["time"].values).astype(np.int64) > 0)


def test_toa5_spike_is_flagged_not_removed(tmp_path, toa5_lines):
    lines = toa5_lines[:2004]
    fields = lines[1000].split(b",")
    fields[2] = b"25.0"
    lines[1000] = b",".join(fields)
    ds = read_toa5(_write(tmp_path, lines))
    assert float(ds["u"][996]) == 25.0
    assert ds["sample_flag"].values[996] == 2
    assert int((ds["sample_flag"] > 0).sum()) == 1


@pytest.mark.parametrize(
    ("line_no", "text", "match"),
    [
        (
            7,
            b'"2012-06-07 12:45:00.15",111850402,2.4x,-1.799,-0.22,667.3,8.8,27.66,100.17,0\r\n',
            "not a number",
        ),
        (
            8,
            b'"2012-06-07 25:45:00.2",111850403,2.2,-1.6,-0.2,667.3,8.8,27.7,100.2,0\r\n',
            "bad time stamp",
        ),
        (9, b'"2012-06-07 12:45:00.25",111850404,2.3,-1.58\r\n', "fields"),
        (10, b"\r\n", "fields"),
    ],
)
def test_toa5_damaged_line_is_named(tmp_path, toa5_lines, line_no, text, match):
    lines = toa5_lines[:50]
    lines[line_no - 1] = text
    with pytest.raises(InputFileError, match=match) as err:
        read_toa5(_write(tmp_path, lines))
    assert err.value.line == line_no
    assert str(err.value).startswith(str(tmp_path / "x.dat") + f":{line_no}:")


def test_toa5_header_problems(tmp_path, toa5_lines):
    with pytest.raises(InputFileError, match="no data records"):
        read_toa5(_write(tmp_path, toa5_lines[:4]))
    bad = [toa5_lines[0], toa5_lines[1].replace(b'"Ux"', b'"Ua"'), *toa5_lines[2:20]]
    with pytest.raises(InputFileError, match="'Ux'") as err:
        read_toa5(_write(tmp_path, bad))
    assert err.value.line == 2
    # a column map reads renamed fields
    ds = read_toa5(_write(tmp_path, bad), columns={"u": "Ua"})
    assert ds.sizes["time"] == 16
    with pytest.raises(InputFileError, match="unknown reader option"):
        read_toa5(_write(tmp_path, toa5_lines[:20]), utc_offset=1)


def test_real_tob1_shape_values_and_partial_record(real_data):
    ds = read_tob1(real_data / TOB1)
    assert detect_format(real_data / TOB1) == Format.TOB1
    assert ds.sizes["time"] == 144
    assert ds.attrs["partial_record_bytes"] == 30
    assert any("partial trailing record" in w for w in ds.attrs["warnings"])
    assert str(ds["time"].values[0]) == "2017-08-03T00:00:00.100000000"
    assert ds.attrs["sampling_rate_hz"] == pytest.approx(10.0, rel=1e-6)
    # first record decoded by hand: 5 header lines, then <3I8f
    raw = (real_data / TOB1).read_bytes()
    start = 0
    for _ in range(5):
        start = raw.index(b"\n", start) + 1
    rec = np.frombuffer(
        raw[start : start + 44], dtype="<u4,<u4,<u4,<f4,<f4,<f4,<f4,<f4,<f4,<f4,<f4"
    )
    assert float(ds["u"][0]) == pytest.approx(float(rec["f3"][0]))
    assert float(ds["temperature"][0]) == pytest.approx(float(rec["f8"][0]))
    assert -5 < float(ds["u"].mean()) < 5 and 15 < float(ds["temperature"].mean()) < 35


def test_tob1_damaged_copies(tmp_path, real_data):
    raw = (real_data / TOB1).read_bytes()
    head_end = 0
    for _ in range(5):
        head_end = raw.index(b"\n", head_end) + 1
    # unknown data type on header line 5
    p = tmp_path / "t.tob"
    p.write_bytes(raw.replace(b'"IEEE4","IEEE4","IEEE4"', b'"IEEE4","IEEE9","IEEE4"', 1))
    with pytest.raises(InputFileError, match="IEEE9") as err:
        read_tob1(p)
    assert err.value.line == 5
    # cut inside the header
    p.write_bytes(raw[:200])
    with pytest.raises(InputFileError, match="header"):
        read_tob1(p)
    # NANOSECONDS out of range in record 3
    data = bytearray(raw)
    pos = head_end + 2 * 44 + 4
    data[pos : pos + 4] = np.array([2_000_000_000], "<u4").tobytes()
    p.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match="NANOSECONDS") as err:
        read_tob1(p)
    assert "record 3" in str(err.value)
    # whole records only: no warning
    p.write_bytes(raw[: head_end + 144 * 44])
    assert read_tob1(p).attrs["partial_record_bytes"] == 0


def test_fp2_decoding():
    raw = np.array([0x0000, 0x1FFF, 0x9FFF, 0x9FFE, 0x2000 | 1234, 0x8000 | 0x4000 | 1234])
    out = decode_fp2(raw)
    assert out[0] == 0 and out[1] == np.inf and out[2] == -np.inf and np.isnan(out[3])
    assert out[4] == pytest.approx(123.4) and out[5] == pytest.approx(-12.34)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_mutated_toa5_gives_dataset_or_input_file_error(tmp_path, toa5_lines, data):
    blob = bytearray(b"".join(toa5_lines[:60]))
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(blob) - 1))
        blob[i] = data.draw(st.sampled_from(list(b'0123456789,."-\r\nNAxe \x00')))
    cut = data.draw(st.integers(len(blob) // 2, len(blob)))
    p = tmp_path / "m.dat"
    p.write_bytes(bytes(blob[:cut]))
    try:
        ds = read_toa5(p)
    except InputFileError:
        return
    assert isinstance(ds, xr.Dataset) and ds.sizes["time"] > 0


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_mutated_tob1_gives_dataset_or_input_file_error(tmp_path, real_data, data):
    blob = bytearray((real_data / TOB1).read_bytes())
    for _ in range(data.draw(st.integers(1, 6))):
        i = data.draw(st.integers(0, len(blob) - 1))
        blob[i] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(blob)))
    p = tmp_path / "m.tob"
    p.write_bytes(bytes(blob[:cut]))
    try:
        ds = read_tob1(p)
    except InputFileError:
        return
    assert isinstance(ds, xr.Dataset) and ds.sizes["time"] > 0


def test_every_real_sonic_file_reads_through_format_detection(real_data):
    """Every data file of real_data/sonic: detected, read, expected size and sane values."""
    from cwproc.io import read_file

    expected = {
        "TOA5_6843.ts_Above_2012_06_07_1245.dat": (18000, 20.0),
        "testing.tob": (144, 10.0),
        "head_ghg.data": (2, 10.0),
    }
    files = sorted(p for p in (real_data / "sonic").iterdir() if p.suffix != ".md")
    assert {p.name for p in files} >= set(expected)
    for p in files:
        ds = read_file(p)
        n, rate = expected[p.name]
        assert ds.sizes["time"] == n, p.name
        assert ds.attrs["sampling_rate_hz"] == pytest.approx(rate, rel=1e-6), p.name
        for c in ("u", "v", "w"):
            assert np.all(np.abs(ds[c].values) < 30), (p.name, c)
        assert np.all((ds["temperature"].values > -40) & (ds["temperature"].values < 50))


def test_tob1_records_shifted_by_inserted_bytes_are_read_again_on_their_boundaries(tmp_path):
    """A "line" duplicated inside TOB1 binary data shifted every later record off its
    boundary; their garbage SECONDS fields gave samples of foreign days (2024-10-23 in a
    file of 2024-06-01, found by tests/test_damaged_inputs.py). Then the rest of the
    file was dropped (issue 34.3): now the record holding the inserted bytes is lost
    and reading resumes on the boundaries, with a note."""
    from pathlib import Path

    sample = Path(__file__).parents[2] / "sample_data/sonic/TOB1_999.ts_data_2024_06_01_1200.dat"
    raw = sample.read_bytes()
    whole = read_tob1(sample)
    header_end = 0
    for _ in range(5):
        header_end = raw.index(b"\n", header_end) + 1
    at = header_end + (len(raw) - header_end) // 3  # inside the data, a third of the way
    damaged = tmp_path / "TOB1_shifted.dat"
    damaged.write_bytes(raw[:at] + b"\x17\x2a\x05" + raw[at:])
    ds = read_tob1(damaged)
    assert ds["time"].values.min() >= whole["time"].values.min()
    assert ds["time"].values.max() <= whole["time"].values.max()
    assert ds.sizes["time"] == whole.sizes["time"] - 1  # the damaged record alone lost
    assert any("3 byte(s) skipped" in w or "byte(s) skipped, 1 record(s) lost" in w
               for w in ds.attrs["warnings"])  # fmt: skip
    kept = np.isin(whole["time"].values, ds["time"].values)
    assert np.count_nonzero(~kept) == 1
    np.testing.assert_array_equal(ds["u"].values, whole["u"].values[kept])


def test_misaligned_from_tells_garbage_from_lost_records_and_restarts():
    from cwproc.io.records import misaligned_from

    r = np.arange(200)
    assert misaligned_from(r) is None
    assert misaligned_from(np.concatenate([r[:100], r[:100]])) is None  # logger restart
    assert misaligned_from(np.concatenate([r[:100], r[120:]])) is None  # records lost
    garbage = r.copy()
    garbage[130:] = np.random.default_rng(0).integers(0, 2**31, 70)
    assert misaligned_from(garbage) == 129  # the record holding the shift is dropped too


def _checked_and_fast(path):
    """The checking reader's and the fast reader's results for one file."""
    raw = path.read_bytes()
    fast = campbell.toa5_fast(path, raw, campbell.DEFAULT_COLUMNS)
    return campbell._toa5_checked(path, raw, campbell.DEFAULT_COLUMNS), fast


def _assert_same(checked, fast):
    assert fast is not None
    assert checked[:3] == fast[:3]
    np.testing.assert_array_equal(checked[3], fast[3])
    assert checked[4].keys() == fast[4].keys()
    for name in checked[4]:
        np.testing.assert_array_equal(checked[4][name], fast[4][name])


def test_fast_toa5_reader_equals_the_checking_reader(tmp_path, toa5_lines, real_data):
    """Identical stamps and values on the real CRLF file and on an LF copy with NAN/INF,
    stamps of 0 to 9 fractional digits and a leap day."""
    _assert_same(*_checked_and_fast(real_data / TOA5))
    lines = [line.replace(b"\r\n", b"\n") for line in toa5_lines[:40]]
    stamps = [
        b'"2012-02-29 23:59:59"',
        b'"2012-02-29 23:59:59.5"',
        b'"2012-02-29 23:59:59.123456789"',
        b'"2012-03-01 00:00:00.05"',
    ]
    for i, stamp in enumerate(stamps):
        lines[4 + i] = stamp + lines[4 + i][lines[4 + i].index(b",") :]
    fields = lines[10].split(b",")
    fields[2], fields[3] = b"NAN", b"-INF"
    lines[10] = b",".join(fields)
    _assert_same(*_checked_and_fast(_write(tmp_path, lines)))


@pytest.mark.parametrize(
    "stamp",
    [
        b'"2012-02-30 12:00:00"',  # no such day
        b'"2013-02-29 12:00:00"',  # not a leap year
        b'"2012-06-07 24:00:00"',
        b'"2012-06-07T12:00:00"',
        b"2012-06-07 12:00:00",  # unquoted
        b'"2012-06-07 12:00:00."',
        b'"2012-06-07 12:00:00.1234567890"',
        b'"2012-06-07 12:00:00+01"',
    ],
)
def test_fast_toa5_reader_leaves_other_stamps_to_the_checking_reader(tmp_path, toa5_lines, stamp):
    """Any stamp outside the logger's own layout sends the file to the checking reader,
    whose result (a dataset or an error naming line 7) is what read_toa5 gives."""
    lines = list(toa5_lines[:30])
    lines[6] = stamp + lines[6][lines[6].index(b",") :]
    path = _write(tmp_path, lines)
    assert campbell.toa5_fast(path, path.read_bytes(), campbell.DEFAULT_COLUMNS) is None
    try:
        ds = read_toa5(path)
    except InputFileError as err:
        assert err.line == 7
    else:
        assert ds.sizes["time"] >= 25


def test_days_from_civil_matches_numpy():
    dates = np.arange("1995-01-01", "2101-01-01", dtype="datetime64[D]")
    ymd = np.datetime_as_string(dates).astype("U10")
    year = np.array([int(s[:4]) for s in ymd])
    month = np.array([int(s[5:7]) for s in ymd])
    day = np.array([int(s[8:]) for s in ymd])
    days = campbell.days_from_civil(year, month, day)
    np.testing.assert_array_equal(days, dates.astype(np.int64))


@pytest.mark.parametrize(
    ("old", "new"),
    [
        (b"\r\n", b"\n"),  # one LF line among CRLF lines
        (b",", b",,"),  # an extra field
        (b",", b"\x0b,"),  # a vertical tab (a line break for str.splitlines)
        (b",", b"\xc2\xb5,"),  # non-ASCII
    ],
)
def test_fast_toa5_reader_leaves_odd_lines_to_the_checking_reader(tmp_path, toa5_lines, old, new):
    lines = list(toa5_lines[:30])
    lines[9] = lines[9].replace(old, new, 1)
    path = _write(tmp_path, lines)
    assert campbell.toa5_fast(path, path.read_bytes(), campbell.DEFAULT_COLUMNS) is None
    assert campbell.toa5_fast(path, b"".join(toa5_lines[:30]), campbell.DEFAULT_COLUMNS)


def test_fast_toa5_reader_counts_the_commas_line_by_line(tmp_path, toa5_lines):
    """A field moved from one line to the next keeps the file's number of commas, and
    pandas' parse of the used fields takes both lines (the last field, unused here, is
    left empty on one; the extra field of the other is ignored): the fast reader still
    finds them, and the checking reader names line 10."""
    lines = list(toa5_lines[:30])
    lines[9] = lines[9].rsplit(b",", 1)[0] + b"\r\n"  # no diag_csat
    lines[10] = lines[10].replace(b",", b",0,", 1)  # one field more
    path = _write(tmp_path, lines)
    cols = {**campbell.DEFAULT_COLUMNS, "diagnostic": "press"}
    assert campbell.toa5_fast(path, path.read_bytes(), cols) is None
    with pytest.raises(InputFileError) as err:
        read_toa5(path, columns={"diagnostic": "press"})
    assert err.value.line == 10


def test_eight_digits_is_the_decimal_number():
    rng = np.random.default_rng(1)
    digits = rng.integers(0, 10, size=(10_000, 8)).astype(np.uint8)
    digits[0], digits[1] = 9, 0
    expected = digits.astype(np.int64) @ 10 ** np.arange(7, -1, -1)
    np.testing.assert_array_equal(campbell.eight_digits(digits), expected)
    assert campbell.eight_digits(digits[:2]).tolist() == [99_999_999, 0]


@pytest.mark.parametrize("block", [7, 64, 1000])
def test_fast_toa5_reader_is_the_same_in_any_blocks(tmp_path, monkeypatch, toa5_lines, block):
    """The body scanned in blocks of any size (CRLF split across two blocks, runs of
    commas and stamps across several), from the bytes or read from the open file, gives
    the checking reader's result, and still refuses a bare CR or a field too many."""
    monkeypatch.setattr(campbell, "SCAN_BYTES", block)
    crlf = _write(tmp_path, toa5_lines[:120], "crlf.dat")
    lf = _write(tmp_path, [line.replace(b"\r\n", b"\n") for line in toa5_lines[:120]], "lf.dat")
    for path in (crlf, lf):
        _assert_same(*_checked_and_fast(path))
        with open(path, "rb") as fh:
            _assert_same(_checked_and_fast(path)[0], campbell.toa5_fast(path, fh, DEFAULT))
    for old, new in ((b"\r\n", b"\r"), (b",", b",,")):
        lines = list(toa5_lines[:120])
        lines[60] = lines[60].replace(old, new, 1)
        path = _write(tmp_path, lines, "odd.dat")
        assert campbell.toa5_fast(path, path.read_bytes(), DEFAULT) is None
        with open(path, "rb") as fh:
            assert campbell.toa5_fast(path, fh, DEFAULT) is None


DEFAULT = campbell.DEFAULT_COLUMNS
