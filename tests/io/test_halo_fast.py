"""The fast paths of the .hpl reader give exactly what the reference paths give.

The reader splits fields at single spaces when it can (about 15 % faster than the
whitespace tokenizer) and finds the end of the data without copying the body; these
tests pin both to their reference definitions on the real files of real_data/hpl.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cwproc.io.halo import read_hpl
from cwproc.io.halo_body import content_end, read_body_table, single_space_ok, tokenize_body
from cwproc.io.halo_header import split_header

REAL_FILES = (
    "User5_96_20190308_200500.hpl",
    "eriswil-2022-12-14-Stare_91_20221214_11.hpl",
    "hyytiala-2023-09-13-Stare_46_20230913_23.hpl",
    "soverato-2021-10-01-VAD_194_20210624_170110.hpl",
    "warsaw-2022-12-13-Stare_213_20221213_04.hpl",
    "CORRUPT_warsaw-2021-10-01-Stare_213_20211001_18.hpl",
)


@pytest.mark.parametrize(
    "raw, start",
    [
        (b"", 0),
        (b"   \r\n\t ", 0),
        (b"abc", 0),
        (b"abc \r\n", 0),
        (b"x" * 10 + b" " * 1000 + b"\r\n", 0),  # blank tail far longer than 64 bytes
        (b"head\nbody 1 2  \n\n\n", 5),
        (b"head\n" + b" " * 500, 5),  # nothing after start
        (b"a" + b"\n" * 64, 0),  # tail of exactly 64 blank bytes
    ],
)
def test_content_end_is_the_length_after_rstrip(raw: bytes, start: int) -> None:
    assert content_end(raw, start) == start + len(raw[start:].rstrip())


@pytest.mark.parametrize("name", REAL_FILES)
def test_single_space_parse_is_bitwise_the_whitespace_parse(real_data: Path, name: str) -> None:
    raw = (real_data / "hpl" / name).read_bytes()
    _, offset = split_header(name, raw)
    body = raw[offset : content_end(raw, offset)]
    assert single_space_ok(body)  # CRLF or LF, no TAB: every real file takes the fast path
    # the single-space table itself (not tokenize_body, which would fall back on a problem):
    # 5 columns equal to the reference, and a sixth that only ever holds the empty field
    # after a trailing space
    table = read_body_table(body, single_space=True)
    assert table.shape[1] == 6 and table[5].isna().all()
    fast = [table[j].to_numpy(dtype=np.float64) for j in range(5)]
    reference = tokenize_body(name, body, single_space=False)
    assert len(reference) == 5
    for a, b in zip(fast, reference, strict=True):
        assert a.tobytes() == b.tobytes()  # NaN pattern and -0.0 included


@pytest.mark.parametrize(
    "body, expected",
    [
        (b"1 2 3\r\n  0 1 2 3\r\n", True),
        (b"1 2 3\n  0 1 2 3\n", True),
        (b"1 2 3\r  0 1 2 3\r", False),  # lone CR: skipinitialspace would misread
        (b"1 2 3\r\n  0 1 2 3\r  1 1 2 3", False),  # one stray lone CR
        (b"1\t2 3\r\n  0 1 2 3\r\n", False),  # a TAB separates fields
        (b"1 2 3\r\n  0 1 2 3\r", False),  # the last line end is a lone CR
        (b"1 2 3\n  0 1 2 3\n", True),  # LF only (no CR at all)
    ],
)
def test_single_space_only_for_space_separated_crlf_or_lf(body: bytes, expected: bool) -> None:
    assert single_space_ok(body) is expected


def test_tab_separated_fields_read_like_spaces(real_data: Path, tmp_path: Path) -> None:
    src = real_data / "hpl" / "soverato-2021-10-01-VAD_194_20210624_170110.hpl"
    raw = src.read_bytes()
    _, offset = split_header(src, raw)
    path = tmp_path / src.name
    path.write_bytes(raw[:offset] + raw[offset:].replace(b" ", b"\t"))
    ref, ds = read_hpl(src), read_hpl(path)
    for name in ("radial_velocity", "snr", "beta", "spectral_width", "time", "pitch", "roll"):
        np.testing.assert_array_equal(ds[name].values, ref[name].values)


def test_lone_cr_file_with_leading_spaces_reads_like_crlf(real_data: Path, tmp_path: Path) -> None:
    # gate lines start with two spaces ("  0 2.5990 ..."); after a lone CR the
    # single-space tokenizer would shift every field, so the reader must not use it
    src = real_data / "hpl" / "eriswil-2022-12-14-Stare_91_20221214_11.hpl"
    path = tmp_path / "cr.hpl"
    path.write_bytes(src.read_bytes().replace(b"\r\n", b"\r"))
    ref, ds = read_hpl(src), read_hpl(path)
    np.testing.assert_array_equal(ds["radial_velocity"].values, ref["radial_velocity"].values)
    np.testing.assert_array_equal(ds["beta"].values, ref["beta"].values)


@pytest.mark.parametrize(
    "extra, fields",
    [(b" 7", "6 fields"), (b" 7 ", "6 fields"), (b" 7 8", "7 fields"), (b" 7 8 ", "7 fields")],
)
def test_extra_fields_name_the_line_in_the_fast_path(
    real_data: Path, tmp_path: Path, extra: bytes, fields: str
) -> None:
    from cwproc.errors import InputFileError

    src = real_data / "hpl" / "soverato-2021-10-01-VAD_194_20210624_170110.hpl"
    lines = src.read_bytes().split(b"\r\n")
    lines[40] = lines[40].rstrip() + extra  # file line 41, a gate line with 5 numbers
    path = tmp_path / "x.hpl"
    path.write_bytes(b"\r\n".join(lines))
    with pytest.raises(InputFileError) as exc:
        read_hpl(path)
    assert exc.value.line == 41 and fields in exc.value.problem
