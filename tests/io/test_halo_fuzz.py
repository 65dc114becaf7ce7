"""Property: a damaged real .hpl file gives a valid scan dataset or an InputFileError.

Mutations of the real files (byte flips, deleted, duplicated and swapped lines,
truncation, inserted garbage) must never raise anything else (no numpy/pandas
traceback, no hang), and whatever is returned must follow the canonical schema.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.errors import InputFileError
from cwproc.io.halo import read_hpl
from cwproc.io.halo_body import content_end, single_space_ok, structure_problem, tokenize_body
from cwproc.io.halo_header import parse_hpl_header, split_header

SMALL_FILES = (
    "eriswil-2022-12-14-Stare_91_20221214_11.hpl",
    "hyytiala-2023-09-13-Stare_46_20230913_23.hpl",
    "soverato-2021-10-01-VAD_194_20210624_170110.hpl",
    "warsaw-2022-12-13-Stare_213_20221213_04.hpl",
)


@functools.cache
def original(path: Path) -> bytes:
    return path.read_bytes()


def flip_bytes(raw: bytes, positions: list[int], values: list[int]) -> bytes:
    data = bytearray(raw)
    if not data:
        return raw
    for p, v in zip(positions, values, strict=False):
        data[p % len(data)] = v
    return bytes(data)


def edit_lines(raw: bytes, op: str, i: int, j: int) -> bytes:
    lines = raw.split(b"\n")
    i %= len(lines)
    j %= len(lines)
    if op == "delete":
        del lines[i]
    elif op == "duplicate":
        lines.insert(i, lines[i])
    elif op == "swap":
        lines[i], lines[j] = lines[j], lines[i]
    elif op == "garbage":
        lines.insert(i, b"#### \xff\xfe garbage 1.0 2.0")
    return b"\n".join(lines)


mutation = st.one_of(
    st.tuples(
        st.just("flip"),
        st.lists(st.integers(0, 10**6), min_size=1, max_size=4),
        st.lists(st.integers(0, 255), min_size=1, max_size=4),
    ),
    st.tuples(
        st.sampled_from(["delete", "duplicate", "swap", "garbage"]),
        st.integers(0, 10**4),
        st.integers(0, 10**4),
    ),
    st.tuples(st.just("truncate"), st.floats(0.0, 1.0), st.just(0)),
)


def apply(raw: bytes, mut: tuple) -> bytes:
    kind, a, b = mut
    if kind == "flip":
        return flip_bytes(raw, a, b)
    if kind == "truncate":
        return raw[: int(a * len(raw))]
    return edit_lines(raw, kind, a, b)


def assert_valid_scan_dataset(ds) -> None:
    assert set(ds.dims) == {"ray", "range"}
    n, m = ds.sizes["ray"], ds.sizes["range"]
    assert n >= 1 and m >= 1
    for name in ("radial_velocity", "snr", "beta"):
        assert ds[name].shape == (n, m)
        assert np.isfinite(ds[name].values).all()
    az, el = ds["azimuth"].values, ds["elevation"].values
    assert ((az >= 0) & (az < 360)).all()
    assert (el <= 90).all() and (el >= -90).all()
    assert ds["time"].dtype == np.dtype("datetime64[ns]")
    assert not np.isnat(ds["time"].values).any()
    assert ds["scan"].dtype == np.int64 and (ds["scan"].values >= -1).all()
    assert (np.diff(ds["range"].values) > 0).all()


@pytest.mark.slow
@settings(
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
    derandomize=True,
)
@given(name=st.sampled_from(SMALL_FILES), muts=st.lists(mutation, min_size=1, max_size=3))
def test_mutated_real_file_reads_or_fails_cleanly(
    real_data: Path, tmp_path_factory, name: str, muts: list
) -> None:
    raw = original(real_data / "hpl" / name)
    for mut in muts:
        raw = apply(raw, mut)
    path = tmp_path_factory.mktemp("fuzz") / name
    path.write_bytes(raw)
    try:
        ds = read_hpl(path)
    except InputFileError as err:
        assert err.path == str(path)
        assert err.line is None or 1 <= err.line <= raw.count(b"\n") + raw.count(b"\r") + 2
        return
    assert_valid_scan_dataset(ds)


def same_columns(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    """Bitwise equality of parsed columns (NaN and the sign of zero included)."""
    return len(a) == len(b) and all(x.tobytes() == y.tobytes() for x, y in zip(a, b, strict=True))


@pytest.mark.slow
@settings(
    max_examples=200,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
    derandomize=True,
)
@given(name=st.sampled_from(SMALL_FILES), muts=st.lists(mutation, min_size=0, max_size=3))
def test_single_space_tokenizer_agrees_with_whitespace_tokenizer(
    real_data: Path, name: str, muts: list
) -> None:
    """The fast single-space parse is only trusted where it equals the ``\\s+`` parse.

    Whenever it yields a whole block structure, its columns are bitwise those of the
    reference whitespace tokenizer (the reader falls back to the latter otherwise).
    """
    raw = original(real_data / "hpl" / name)
    for mut in muts:
        raw = apply(raw, mut)
    try:
        lines, offset = split_header("x.hpl", raw)
        n_gates = parse_hpl_header("x.hpl", lines).n_gates
    except InputFileError:
        return
    body = raw[offset : content_end(raw, offset)]
    if not body or b"\x00" in body or not single_space_ok(body):
        return
    try:
        fast = tokenize_body("x.hpl", body, single_space=True)
    except InputFileError:
        return
    if structure_problem(fast, n_gates) is None:
        assert same_columns(fast, tokenize_body("x.hpl", body, single_space=False))
