"""read_hpl_files (several .hpl files in one tokenizer pass) equals concat_scans of read_hpl.

Synthetic files are written with write_hpl into tmp_path; the real files are read from
real_data/hpl. "Equal" means identical datasets: same variables in the same order,
bitwise-equal values, same dtypes and attributes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import cwproc.io.halo_files as halo_files
from cwproc.errors import CwprocError, InputFileError
from cwproc.io.halo import read_header_and_body, read_hpl, write_hpl
from cwproc.io.halo_body import line_ends
from cwproc.io.halo_files import read_hpl_files
from cwproc.io.halo_header import HEADER_LINES
from cwproc.io.scans import concat_scans

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


def test_several_batches_equal_one(day: list[Path], monkeypatch: pytest.MonkeyPatch) -> None:
    one = read_hpl_files(day)
    monkeypatch.setattr(halo_files, "_BATCH_BYTES", 30_000)  # about two files per batch
    calls = []
    batch_arrays = halo_files._batch_arrays

    def spy(batch: list, n_gates: int) -> object:
        calls.append(len(batch))
        return batch_arrays(batch, n_gates)

    monkeypatch.setattr(halo_files, "_batch_arrays", spy)
    several = halo_files._read_together(day)
    assert several is not None
    assert len(calls) > 2 and sum(calls) == len(day)
    assert_same(several, one)


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


@pytest.mark.parametrize(
    "body",
    [b"a", b"a\r\nb\r\nc", b"a\nb\nc", b"a\rb\rc", b"a\r\nb\rc\nd", b"\r\n\r\na", b"a\r\r\nb"],
)
def test_line_ends_count_lines_like_splitlines(body: bytes) -> None:
    n_lines, lone_cr = line_ends(body)
    assert n_lines == len(body.splitlines())
    assert lone_cr == (body.replace(b"\r\n", b"").count(b"\r") > 0)


@pytest.mark.parametrize("chunk", [1, 7, 4096, 1 << 20])
def test_joined_bodies_read_like_one_joined_buffer(day: list[Path], chunk: int) -> None:
    bodies = [halo_files._load_body(p) for p in day[:3]]
    expected = b"\r\n".join(item.body[: item.end] for item in bodies)
    reader = halo_files._JoinedBodies(bodies)
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
