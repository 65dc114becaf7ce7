"""read_hpl_files (several .hpl files in one tokenizer pass) equals concat_scans of read_hpl.

Synthetic files are written with write_hpl into tmp_path; the real files are read from
real_data/hpl. "Equal" means identical datasets: same variables in the same order,
bitwise-equal values, same dtypes and attributes.
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import cwproc.io.halo_files as halo_files
from cwproc.errors import CwprocError, InputFileError
from cwproc.io.halo import read_header_and_body, read_hpl, write_hpl
from cwproc.io.halo_files import read_hpl_files
from cwproc.io.halo_header import HEADER_LINES
from cwproc.io.scan_join import concat_scans

#: a large file with pitch/roll, and one with 3-field ray lines and no final newline
REAL_SINGLE = ("User5_96_20190308_200500.hpl", "hyytiala-2023-09-13-Stare_46_20230913_23.hpl")


def vad(start: np.datetime64, seed: int, *, pitch_roll: bool = True) -> xr.Dataset:
    """A 12-ray step-stare VAD (5 s per ray, 20 gates) of a uniform wind with noise."""
    rng = np.random.default_rng(seed)
    n_rays, n_gates = 12, 20
    az = np.arange(n_rays) * 30.0
    el = 70.0
    vr = 8.0 * np.cos(np.radians(el)) * np.cos(np.radians(az - 250.0))[:, None] + rng.normal(
        0.0, 0.2, (n_rays, n_gates)
    )
    snr = rng.uniform(0.01, 0.5, (n_rays, n_gates))
    data = {
        "radial_velocity": (("ray", "range"), np.round(vr, 4)),
        "snr": (("ray", "range"), np.round(snr, 6)),
        "beta": (("ray", "range"), rng.uniform(-1e-6, 1e-5, (n_rays, n_gates))),
    }
    if pitch_roll:
        data["pitch"] = ("ray", np.full(n_rays, -0.1))
        data["roll"] = ("ray", np.full(n_rays, 0.2))
    return xr.Dataset(
        data,
        coords={
            "time": ("ray", start + np.arange(n_rays) * np.timedelta64(5, "s")),
            "azimuth": ("ray", az),
            "elevation": ("ray", np.full(n_rays, el)),
            "range": ("range", (np.arange(n_gates) + 0.5) * 30.0),
        },
        attrs={"system_id": "7", "scan_type": "VAD", "gate_length_m": 30.0},
    )


@pytest.fixture
def day(tmp_path: Path) -> list[Path]:
    """Eight VAD files, one every 2 min (the last one starts before midnight)."""
    t0 = np.datetime64("2024-06-01T23:45:00", "ns")
    paths = []
    for k in range(8):
        start = t0 + np.timedelta64(120 * k, "s")
        paths.append(write_hpl(vad(start, k), tmp_path / f"VAD_7_{k:02d}.hpl"))
    return paths


def assert_same(a: xr.Dataset, b: xr.Dataset) -> None:
    xr.testing.assert_identical(a, b)
    assert list(a.variables) == list(b.variables)
    assert a.attrs == b.attrs
    for name in a.variables:
        assert a[name].dtype == b[name].dtype
        assert a[name].values.tobytes() == b[name].values.tobytes()
        assert a[name].attrs == b[name].attrs


def reference(paths: list[Path]) -> xr.Dataset:
    return concat_scans([read_hpl(p) for p in paths])


@pytest.mark.parametrize("order", ["sorted", "reversed", "repeated"])
def test_day_equals_concat_of_single_reads(day: list[Path], order: str) -> None:
    paths = {"sorted": day, "reversed": day[::-1], "repeated": day[:3] + day[1:3]}[order]
    ds = read_hpl_files(paths)
    assert halo_files._read_together([Path(p) for p in paths]) is not None  # the fast path ran
    assert_same(ds, reference(paths))
    # physical truth: one scan per file, rays in time order, no repeated time
    assert np.unique(ds["scan"].values).size == len(dict.fromkeys(paths))
    assert (np.diff(ds["time"].values) > np.timedelta64(0, "ns")).all()


def test_compiled_tokenizer_parses_file_by_file(
    day: list[Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    if halo_files._hpltok is None:
        pytest.skip("the compiled tokenizer is not built")
    calls = []
    group_columns = halo_files._group_columns

    def spy(group: list, n_gates: int) -> object:
        calls.append(len(group))
        return group_columns(group, n_gates)

    monkeypatch.setattr(halo_files, "_group_columns", spy)
    ds = halo_files._read_together(day)
    assert ds is not None and calls == [1] * len(day)
    assert_same(ds, reference(day))


def test_pandas_batches_equal_the_compiled_tokenizer(
    day: list[Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    one = read_hpl_files(day)
    monkeypatch.setattr(halo_files, "_hpltok", None)  # as without the compiled tokenizer
    monkeypatch.setattr(halo_files, "_BATCH_BYTES", 30_000)  # about two files per batch
    calls = []
    group_columns = halo_files._group_columns

    def spy(group: list, n_gates: int) -> object:
        calls.append(len(group))
        return group_columns(group, n_gates)

    monkeypatch.setattr(halo_files, "_group_columns", spy)
    several = halo_files._read_together(day)
    assert several is not None
    assert len(calls) > 2 and sum(calls) == len(day)
    assert_same(several, one)


def test_overlapping_files_keep_the_first_ray_of_a_repeated_time(tmp_path: Path) -> None:
    """Out-of-order rays inside the record and repeated times with other data."""
    t0 = np.datetime64("2024-06-01T12:00:00", "ns")
    # s: the 2nd and 3rd overlap the 1st, the 4th starts first and repeats 11 of its times
    starts = [5, 30, 2, 0]
    paths = [
        write_hpl(vad(t0 + np.timedelta64(s, "s"), seed=k), tmp_path / f"{k}.hpl")
        for k, s in enumerate(starts)
    ]
    ds = read_hpl_files(paths)
    assert halo_files._read_together(paths) is not None  # the fast path ran
    assert_same(ds, reference(paths))
    # 12 rays from 5 s every 5 s; from 30 s 5 new, from 2 s 12 new, from 0 s 1 new
    assert ds.sizes["ray"] == 12 + 5 + 12 + 1
    assert (np.diff(ds["time"].values) > np.timedelta64(0, "ns")).all()
    first = read_hpl(paths[0])  # the repeated times keep the first file's rays
    at_first = np.isin(ds["time"].values, first["time"].values)
    np.testing.assert_array_equal(
        ds["radial_velocity"].values[at_first], first["radial_velocity"].values
    )


@pytest.mark.parametrize("eol", [b"\n", b"\r"])
def test_lf_and_lone_cr_files_equal_the_reference(day: list[Path], eol: bytes) -> None:
    for path in day:
        path.write_bytes(path.read_bytes().replace(b"\r\n", eol))
    assert_same(read_hpl_files(day), reference(day))
    assert halo_files._read_together(day) is not None  # the fast path ran


def test_mixed_line_ends_take_the_reference_path(day: list[Path]) -> None:
    lines = day[3].read_bytes().split(b"\r\n")
    day[3].write_bytes(b"\r\n".join(lines[:40]) + b"\r" + b"\n".join(lines[40:]))
    assert halo_files._read_together(day) is None  # the line count differs from the plan
    assert_same(read_hpl_files(day), reference(day))


def test_file_grown_between_the_passes_takes_the_reference_path(
    day: list[Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The file of the current hour may grow between counting its lines and parsing."""
    plan = halo_files._plan
    extra = b"\r\n".join(day[0].read_bytes().split(b"\r\n")[17:38])  # one more ray

    def plan_then_grow(paths: list[Path]) -> object:
        plans = plan(paths)
        with day[-1].open("ab") as f:
            f.write(b"\r\n" + extra)
        return plans

    monkeypatch.setattr(halo_files, "_plan", plan_then_grow)
    assert halo_files._read_together(day) is None


@pytest.mark.parametrize("order", ["sorted", "reversed"])
def test_peak_memory_is_about_the_arrays(tmp_path: Path, order: str) -> None:
    """Python and numpy allocations (tracemalloc) while reading a day: the record's arrays,
    one file's data and small change, not a second copy of the arrays (files given in
    reverse fill the record in time order: nothing to reorder)."""
    if halo_files._hpltok is None:
        pytest.skip("the bound holds for the compiled tokenizer (pandas parses batches)")
    t0 = np.datetime64("2024-06-01T00:00:00", "ns")
    n_gates = 400
    paths = []
    for k in range(16):
        ds = vad(t0 + np.timedelta64(120 * k, "s"), k)
        ds = ds.isel(range=np.arange(n_gates) % ds.sizes["range"])
        ds = ds.assign_coords(range=(np.arange(n_gates) + 0.5) * 30.0)
        paths.append(write_hpl(ds, tmp_path / f"{k:02d}.hpl"))
    read_hpl_files(paths[:1])  # imports and caches outside the measurement
    if order == "reversed":
        paths = paths[::-1]
    tracemalloc.start()
    try:
        ds = read_hpl_files(paths)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    arrays = ds.nbytes
    one_file = max(p.stat().st_size for p in paths)
    assert arrays > 1_000_000
    # the arrays, one file's bytes and its parsed numbers (5 doubles a line, about 1.2
    # times the bytes) with the checks' temporaries, 0.5 MB of bookkeeping (measured:
    # 2.5 MB in all); the reader that concatenated batches peaked at 9.1 MB
    assert peak < arrays + 4 * one_file + 500_000, (peak, arrays, one_file)


def test_pitch_roll_in_some_files_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    t0 = np.datetime64("2024-06-01T12:00:00", "ns")
    paths = [
        write_hpl(
            vad(t0 + np.timedelta64(120 * k, "s"), k, pitch_roll=k >= 2), tmp_path / f"{k}.hpl"
        )
        for k in range(4)
    ]
    monkeypatch.setattr(halo_files, "_BATCH_BYTES", 20_000)  # batches differ in layout
    ds = read_hpl_files(paths)
    assert_same(ds, reference(paths))
    assert np.isnan(ds["pitch"].values[:24]).all() and (ds["pitch"].values[24:] == -0.1).all()


def test_real_files_of_different_grids_fail_like_concat(real_data: Path) -> None:
    paths = [
        real_data / "hpl" / "eriswil-2022-12-14-Stare_91_20221214_11.hpl",
        real_data / "hpl" / "soverato-2021-10-01-VAD_194_20210624_170110.hpl",
    ]
    with pytest.raises(CwprocError) as ref:
        reference(paths)
    with pytest.raises(CwprocError) as got:
        read_hpl_files(paths)
    assert str(got.value) == str(ref.value)


@pytest.mark.parametrize("name", REAL_SINGLE)
def test_single_real_file_equals_read_hpl(real_data: Path, name: str) -> None:
    path = real_data / "hpl" / name
    assert_same(read_hpl_files([path]), reference([path]))


def test_damaged_file_in_a_day_names_its_line(day: list[Path]) -> None:
    lines = day[5].read_bytes().split(b"\r\n")
    lines[30] = lines[30].replace(b".", b",", 1)  # a decimal comma in a gate line
    day[5].write_bytes(b"\r\n".join(lines))
    with pytest.raises(InputFileError) as single:
        read_hpl(day[5])
    with pytest.raises(InputFileError) as several:
        read_hpl_files(day)
    assert several.value.line == single.value.line == 31
    assert str(several.value) == str(single.value)


def test_no_files_is_an_error() -> None:
    with pytest.raises(CwprocError, match="no scan datasets"):
        read_hpl_files([])


@pytest.mark.parametrize("chunk", [1, 7, 4096, 1 << 20])
def test_joined_bodies_read_like_one_joined_buffer(day: list[Path], chunk: int) -> None:
    bodies = [read_header_and_body(p)[1].rstrip() for p in day[:3]]
    expected = b"\r\n".join(bodies)
    reader = halo_files._JoinedBodies([memoryview(body) for body in bodies])
    parts = []
    while block := reader.read(chunk):
        parts.append(block)
    assert b"".join(parts) == expected
    assert all(len(p) == chunk for p in parts[:-1])  # full reads until the end


@pytest.mark.parametrize(
    "tail, kept",
    [(b"", b""), (b"\r\n", b"\r\n"), (b"  \r\n", b"  \r\n"), (b"\n", b"\n"), (b"\r\n\r\n", b"")],
)
def test_body_keeps_one_final_line_end_only(
    day: list[Path], tmp_path: Path, tail: bytes, kept: bytes
) -> None:
    text = day[0].read_bytes().rstrip()
    path = tmp_path / "t.hpl"
    path.write_bytes(text + tail)
    lines, body = read_header_and_body(path)
    assert len(lines) == HEADER_LINES
    assert body == text.split(b"\r\n", HEADER_LINES)[-1] + kept


def test_plan_checksum_is_taken_where_it_is_asked_for(
    day: list[Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A plan's SHA-256 is that of the whole file as read (header and data lines, blank
    lines after the data included), hashed when first asked for, in the asking thread
    (a streamed day's reading thread only reads and parses), and once."""
    import hashlib
    import threading

    from cwproc.io.netcdf import sha256_file

    path = day[0]
    path.write_bytes(path.read_bytes() + b"\r\n\r\n")  # blank lines: the body is cut
    hashed_in: list[str] = []
    real = hashlib.sha256

    def counted(*args):
        hashed_in.append(threading.current_thread().name)
        return real(*args)

    monkeypatch.setattr(halo_files.hashlib, "sha256", counted)
    plan = halo_files.plan_hpl_file(path, checksum=True, keep_body=True)
    assert plan is not None and not hashed_in
    worker = threading.Thread(target=lambda: plan.sha256, name="asker")
    worker.start()
    worker.join()
    assert hashed_in == ["asker"]
    monkeypatch.setattr(halo_files.hashlib, "sha256", real)
    assert plan.sha256 == sha256_file(path) and hashed_in == ["asker"]
    assert halo_files.plan_hpl_file(path).sha256 is None


def test_plan_takes_the_header_the_identity_parsed(day: list[Path]) -> None:
    """A plan given the file's identity (read_hpl_identity) takes its header and data
    offset from it, and is the plan of a fresh read: the same header, offset, lines,
    layout and checksum."""
    from cwproc.io.halo import read_hpl_identity

    identity = read_hpl_identity(day[3])
    assert identity.header is not None and identity.offset is not None
    fresh = halo_files.plan_hpl_file(day[3], checksum=True)
    known = halo_files.plan_hpl_file(day[3], checksum=True, identity=identity)
    assert known == fresh and known.sha256 == fresh.sha256
    assert known.header is identity.header
