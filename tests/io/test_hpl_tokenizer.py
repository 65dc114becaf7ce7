"""The compiled .hpl tokenizer (cwproc/io/_hpltok.c) against its specification and pandas."""

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cwproc.io import halo, halo_body

_hpltok = pytest.importorskip(
    "cwproc.io._hpltok", reason="the optional C tokenizer was not built (setup.py)"
)

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "streamline"
NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def reference(body: bytes, n_fields: int = 5) -> np.ndarray:
    """The documented semantics in plain Python (lines at LF, CRLF, lone CR)."""
    text = body.decode("latin-1")
    lines = re.split(r"\r\n|\n|\r", text)
    if lines and lines[-1] == "":
        lines = lines[:-1]
    out = np.full((len(lines), n_fields), np.nan)
    for i, line in enumerate(lines):
        for j, token in enumerate(t for t in re.split(r"[ \t]+", line) if t):
            out[i, j] = float(token) if NUMBER.fullmatch(token) else np.inf
    return out


def c_table(body: bytes) -> np.ndarray:
    values, n_lines, bad = _hpltok.tokenize(body, 5)
    assert bad == -1
    return np.frombuffer(values, dtype=np.float64).reshape(n_lines, 5)


@pytest.mark.parametrize(
    "body",
    [
        b"",
        b"1",
        b"1 2\n",
        b"\n\n",
        b"  0 -0.2173 1.135933  7.655162E-6\r\n1\t2\r3",
        b"abc 1e400 -.5 5. +7\n1.2.3 - e5 1e",
        b"0.1000000000000000055511151231257827 123456789012345678901234567890",
        b"1e-400 4.9e-324 1.7976931348623157e308",
    ],
)
def test_examples_equal_float_of_each_token(body: bytes) -> None:
    np.testing.assert_array_equal(c_table(body), reference(body))


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.lists(st.sampled_from(list("0123456789+-.eE \t\n\rx")), max_size=80))
def test_generated_bodies_follow_the_specification(chars: list[str]) -> None:
    body = "".join(chars).encode()
    table = reference(body, 64)
    if table.shape[0] and np.isfinite(table[:, 5:]).any() | (~np.isnan(table[:, 5:])).any():
        bad = _hpltok.tokenize(body, 5)[2]
        assert bad >= 0
        first = int(np.flatnonzero(~np.isnan(table[:, 5:]).all(axis=1))[0])
        assert bad == first
        return
    np.testing.assert_array_equal(c_table(body), table[:, :5])


@settings(max_examples=200, deadline=None, derandomize=True)
@given(
    st.lists(
        st.tuples(
            st.floats(allow_nan=False, allow_infinity=False, width=64),
            st.integers(0, 17),
            st.booleans(),
        ).map(
            lambda t: (
                np.format_float_scientific(t[0], precision=t[1])
                if t[2]
                else np.format_float_positional(t[0], precision=t[1])
            )
        ),
        min_size=1,
        max_size=5,
    )
)
def test_round_trip_of_formatted_floats(tokens: list[str]) -> None:
    body = " ".join(tokens).encode()
    np.testing.assert_array_equal(c_table(body)[0, : len(tokens)], [float(t) for t in tokens])


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.lists(st.sampled_from(list("0123456789+-.eE \t\n\rx")), max_size=80))
def test_tokenize_lines_of_a_known_count_is_tokenize(chars: list[str]) -> None:
    """tokenize_lines with the body's true line count gives tokenize_body's result; with any
    other count, a count that differs from it (or the bad line), never its value."""
    body = "".join(chars).encode()
    n_true = len(reference(body, 64))
    values, got, bad = _hpltok.tokenize(body, 5)
    for n in range(n_true + 3):
        values_n, got_n, bad_n = _hpltok.tokenize_lines(body, 5, n)
        if n == n_true:
            assert (got_n, bad_n) == (got, bad)
            rows = 5 * (bad if bad >= 0 else got)
            np.testing.assert_array_equal(
                np.frombuffer(values_n, dtype=np.float64)[:rows],
                np.frombuffer(values, dtype=np.float64)[:rows],
            )
        else:
            assert bad_n >= 0 or got_n != n


def test_too_many_fields_names_the_line() -> None:
    assert _hpltok.tokenize(b"1 2 3\n1 2 3 4 5 6\n", 5)[1:] == (1, 1)


def tokenized_both_ways(path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[list, list]:
    _, body = halo.read_header_and_body(path)
    fast = halo_body.tokenize_body(path, body)
    monkeypatch.setattr(halo_body, "_hpltok", None)
    slow = halo_body.tokenize_body(path, body)
    monkeypatch.undo()
    return fast, slow


def test_sample_files_tokenize_as_with_pandas(monkeypatch: pytest.MonkeyPatch) -> None:
    files = sorted(SAMPLE.glob("*.hpl"))
    assert files
    for path in files:
        fast, slow = tokenized_both_ways(path, monkeypatch)
        for a, b in zip(fast, slow, strict=True):
            np.testing.assert_array_max_ulp(a[np.isfinite(b)], b[np.isfinite(b)], maxulp=1)
            np.testing.assert_array_equal(np.isnan(a), np.isnan(b))


@pytest.mark.realdata
def test_real_files_tokenize_as_with_pandas(
    real_data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    files = sorted((real_data / "hpl").glob("*.hpl"))
    assert files
    for path in files:
        fast, slow = tokenized_both_ways(path, monkeypatch)
        for a, b in zip(fast, slow, strict=True):
            finite = np.isfinite(b)
            np.testing.assert_array_max_ulp(a[finite], b[finite], maxulp=1)
            np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
            np.testing.assert_array_equal(np.isinf(a), np.isinf(b))


@st.composite
def block_tables(draw) -> tuple[np.ndarray, int, int, int]:
    """Tables of ray/gate blocks, mostly well formed, with damage sprinkled in: a
    missing or extra field, a field that is no number (+inf), a wrong gate index."""
    n_gates = draw(st.integers(1, 6))
    ray_fields = draw(st.sampled_from([3, 5]))
    gate_fields = draw(st.sampled_from([4, 5]))
    n_rows = draw(st.integers(0, 4 * (n_gates + 1) + 2))
    table = np.full((n_rows, 5), np.nan)
    position = np.arange(n_rows) % (n_gates + 1)
    for row in range(n_rows):
        present = ray_fields if position[row] == 0 else gate_fields
        table[row, :present] = draw(
            st.lists(st.floats(-1e3, 1e3), min_size=present, max_size=present)
        )
        if position[row]:
            table[row, 0] = position[row] - 1
    for _ in range(draw(st.integers(0, 3))):
        if n_rows:
            row, col = draw(st.integers(0, n_rows - 1)), draw(st.integers(0, 4))
            table[row, col] = draw(st.sampled_from([np.nan, np.inf, 7.0, 0.5]))
    return table, n_gates, ray_fields, gate_fields


@given(block_tables())
@settings(max_examples=300, deadline=None)
def test_compiled_block_check_equals_the_array_check(case) -> None:
    """The compiled structure check (one pass, without the GIL) finds the row the array
    operations find, on the compiled tokenizer's table layout."""
    table, n_gates, ray_fields, gate_fields = case
    columns = [table[:, j] for j in range(5)]
    # (an empty table's columns may have any strides: the array check takes them)
    assert table.shape[0] < 2 or halo_body._row_major_table(columns) is not None
    expected = halo_body.first_bad_row_of_columns(columns, n_gates, ray_fields, gate_fields)
    assert halo_body.first_bad_row(columns, n_gates, ray_fields, gate_fields) == expected
    got = _hpltok.first_bad_row(table, table.shape[0], 5, n_gates, ray_fields, gate_fields)
    assert got == expected


def test_block_check_takes_other_layouts_to_the_array_check() -> None:
    """Columns that are not one row-major table (pandas' own columns, a transposed
    copy) are checked by array operations, with the same result."""
    table = np.array([[1.0, 2.0, 3.0, np.nan, np.nan], [0.0, 1.0, 2.0, 3.0, np.nan]] * 2)
    apart = [np.ascontiguousarray(table[:, j]) for j in range(5)]
    assert halo_body._row_major_table(apart) is None
    assert halo_body._row_major_table([table[:, j] for j in (0, 2, 1, 3, 4)]) is None
    assert halo_body.first_bad_row(apart, 1, 3, 4) == -1
    apart[0][3] = 5.0  # gate index of the second block's gate
    assert halo_body.first_bad_row(apart, 1, 3, 4) == 3


def test_count_byte_counts_in_the_first_bytes() -> None:
    data = b"1 2\n3 4\r\n5\n\n"
    assert _hpltok.count_byte(data, len(data), ord("\n")) == data.count(b"\n")
    assert _hpltok.count_byte(data, 5, ord("\n")) == data[:5].count(b"\n")
    assert _hpltok.count_byte(data, 0, ord("\n")) == 0
    with pytest.raises(ValueError):
        _hpltok.count_byte(data, len(data) + 1, 10)
