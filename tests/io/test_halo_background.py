"""Reader of Stream Line background files: both real layouts, damaged copies, fuzzing."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.errors import InputFileError
from cwproc.io import Format, detect_format, sniff_format
from cwproc.io.halo_background import parse_background, read_halo_background

ERISWIL = "eriswil-Background_141222-000013.txt"
HYYTIALA = "hyytiala-Background_150823-122811.txt"


@pytest.mark.realdata
def test_real_one_per_line_layout(real_data):
    path = real_data / "hpl" / "background" / ERISWIL
    ds = read_halo_background(path)
    assert detect_format(path) is Format.HALO_BACKGROUND
    assert ds.sizes["range"] == 250  # FORMATS.md 1.7 / PROVENANCE.md: 250 values, CRLF
    assert ds.attrs["layout"] == "lines"
    assert ds["time"].values == np.datetime64("2022-12-14T00:00:13")
    # first two lines of the file, as printed there
    assert ds["background"].values[0] == 610890.0
    assert ds["background"].values[1] == 14318556.375


@pytest.mark.realdata
def test_real_joined_layout(real_data):
    path = real_data / "hpl" / "background" / HYYTIALA
    ds = read_halo_background(path)
    assert detect_format(path) is Format.HALO_BACKGROUND
    assert ds.attrs["layout"] == "joined"
    # 5989 bytes split after every .dddddd: 400 values, none lost
    assert ds.sizes["range"] == 400
    assert ds["background"].values[0] == pytest.approx(575587.333333, abs=1e-6)
    assert ds["background"].values[-1] == pytest.approx(21124641.5, abs=1e-6)
    assert ds["time"].values == np.datetime64("2023-08-15T12:28:11")


@pytest.mark.realdata
def test_damaged_copies_of_the_real_files(real_data, tmp_path):
    """A character changed in line 100 of Eriswil's file; Hyytiala's cut inside a number."""
    folder = real_data / "hpl" / "background"
    lines = (folder / ERISWIL).read_bytes().split(b"\r\n")
    lines[99] = lines[99][:4] + b"x" + lines[99][5:]
    bad = tmp_path / ERISWIL
    bad.write_bytes(b"\r\n".join(lines))
    with pytest.raises(InputFileError, match=rf"{ERISWIL}:100: expected one background value"):
        read_halo_background(bad)
    joined = (folder / HYYTIALA).read_bytes()
    cut = tmp_path / HYYTIALA
    cut.write_bytes(joined[:-3])  # the last value loses 3 of its 6 decimals
    with pytest.raises(InputFileError, match=r":1: byte \d+: joined background values"):
        read_halo_background(cut)


def _write(tmp_path, text: bytes, name: str = "Background_010624-120005.txt"):
    path = tmp_path / name
    path.write_bytes(text)
    return path


def test_damaged_line_named_with_its_line_number(tmp_path):
    lines = [f"{16800000 + i}.125000" for i in range(20)]
    lines[7] = "168#3000.1"
    path = _write(tmp_path, ("\r\n".join(lines) + "\r\n").encode())
    with pytest.raises(InputFileError) as err:
        read_halo_background(path)
    assert str(err.value).startswith(f"{path}:8: ")
    assert "168#3000.1" in str(err.value)


def test_truncated_joined_file_is_refused(tmp_path):
    path = _write(tmp_path, b"575587.33333314902110.16666721118039.6")  # last value cut
    with pytest.raises(InputFileError, match=r":1: byte 29: .*six decimals at .21118039.6."):
        read_halo_background(path)


@pytest.mark.parametrize(
    ("content", "problem"),
    [(b"", "empty"), (b"\r\n \r\n", "empty"), (b"1.5\r\nnan\r\n", ":2: expected one")],
)
def test_empty_or_non_numeric(tmp_path, content, problem):
    with pytest.raises(InputFileError, match=problem):
        read_halo_background(_write(tmp_path, content))


def test_negative_background_is_refused(tmp_path):
    path = _write(tmp_path, b"10.5\r\n-3.25\r\n")
    with pytest.raises(InputFileError, match=r":2: gate 1: background -3.25"):
        read_halo_background(path)


@pytest.mark.parametrize("name", ["Background.txt", "Background_321324-250000.txt"])
def test_name_without_valid_time(tmp_path, name):
    with pytest.raises(InputFileError, match="DDMMYY-HHMMSS"):
        read_halo_background(_write(tmp_path, b"1.000000\r\n", name))


def test_decimal_comma_lines(tmp_path):
    ds = read_halo_background(_write(tmp_path, b"16794008,750000\r\n16789466,250000\r\n"))
    np.testing.assert_array_equal(ds["background"].values, [16794008.75, 16789466.25])


def test_hpl_and_sonic_text_are_not_taken_for_backgrounds():
    assert sniff_format(b"Filename:\tStare_91_20221214_11.hpl\r\n") is Format.HPL
    assert sniff_format(b"hello world\n") is None
    assert sniff_format(b"12\n13\n") is None  # integers only: no background file
    assert sniff_format(b"3.14\nhello\n") is None  # a number, then text
    assert sniff_format(b"1.500000") is None  # one number alone says nothing


values_st = st.lists(
    st.integers(min_value=0, max_value=10**9 - 1).map(lambda n: n / 8.0), min_size=1, max_size=60
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(values=values_st, joined=st.booleans())
def test_both_layouts_read_back_exactly(values, joined):
    """Any values of 6 decimals written in either layout read back unchanged."""
    texts = [f"{v:.6f}" for v in values]
    data = ("".join(texts) if joined else "\r\n".join(texts) + "\r\n").encode()
    np.testing.assert_array_equal(parse_background(data), values)
    assert sniff_format(data[:4096]) is Format.HALO_BACKGROUND or len(values) == 1


@settings(max_examples=80, deadline=None)
@given(data=st.binary(max_size=200))
def test_arbitrary_bytes_give_values_or_a_clear_error(data):
    """Garbage never raises anything but InputFileError naming the file."""
    try:
        values = parse_background(data, "x/Background_010624-120005.txt")
    except InputFileError as exc:
        assert str(exc).startswith("x/Background_010624-120005.txt")
    else:
        assert values.size >= 1 and np.all(np.isfinite(values)) and np.all(values >= 0)
