"""Damaged copies of every shipped sample, through every reader (issue 17, Show).

The damage is generated here (committed generators, never committed damaged files):
cut at any byte, bytes flipped, a line duplicated or deleted, a number replaced by an
absurd one, junk appended or inserted. Whatever the damage, reading a file

- raises :class:`cwproc.errors.CwprocError` (one line naming the file) or succeeds;
- never raises anything else (a traceback) and never says "internal error";
- when it succeeds, gives no value outside the physical ranges of its kind
  (:func:`cwproc.io.ranges.ranges_for`),
  no time outside the plausible window of :mod:`cwproc.io.timecheck` and no time
  outside the undamaged file's own time span (junk after the data made products of
  1990-01-01 and other days the file never held);

and ``cwproc retrieve`` on it writes nothing outside ``-o``, and in what it writes no
value outside its physical range and no missing value carries a good ``qc_flag``.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cwproc.cli import main
from cwproc.errors import CwprocError
from cwproc.io import read_file
from cwproc.io.ranges import ranges_for
from cwproc.io.timecheck import first_implausible

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"
#: every shipped instrument sample with the reader options its format needs
FILES = {
    "hpl": (SAMPLE / "streamline" / "VAD_999_20240601_120000.hpl", {}),
    "zephir": (SAMPLE / "zephir" / "Wind10_999@Y2024_M06_D01.ZPH.csv", {}),
    "windcube": (SAMPLE / "windcube" / "WLS7-999_2024_06_01__00_00_00.sta", {}),
    "toa5": (SAMPLE / "sonic" / "TOA5_999.ts_data_2024_06_01_1200.dat", {}),
    "tob1": (SAMPLE / "sonic" / "TOB1_999.ts_data_2024_06_01_1200.dat", {}),
    "ghg": (SAMPLE / "sonic" / "2024-06-01T120000_AIU-0999.data", {}),
    "meteo2": (SAMPLE / "sonic" / "meteo2_2024_06_01_1200.txt", {}),
    "gill": (
        SAMPLE / "sonic" / "gill_2024_06_01_1200.txt",
        {"start_time": "2024-06-01T12:00:00", "sampling_rate_hz": 10.0},
    ),
}


@pytest.fixture(scope="session")
def scan_netcdf_sample(tmp_path_factory) -> Path:
    """A scan NetCDF file of the first Stream Line sample (none ships)."""
    from cwproc.io.halo import read_hpl
    from cwproc.io.scan_netcdf import write_scan_netcdf

    path = tmp_path_factory.mktemp("scan-netcdf") / "sample.nc"
    return write_scan_netcdf(read_hpl(FILES["hpl"][0]), path)


#: bytes kept of each sample (the damage is anywhere in them; reading stays fast)
KEEP = 60_000

NUMBER = re.compile(rb"-?\d+\.\d+")


def damage(raw: bytes, kind: int, where: float, junk: bytes) -> bytes:
    """One kind of damage at relative position ``where`` of ``raw``."""
    at = int(where * max(len(raw) - 1, 0))
    if kind == 0:  # cut (a file still being written, a full disk)
        return raw[:at]
    if kind == 1:  # flipped bytes
        return raw[:at] + bytes(b ^ 0x5A for b in raw[at : at + 8]) + raw[at + 8 :]
    if kind == 2:  # a line deleted
        start = raw.rfind(b"\n", 0, at) + 1
        end = raw.find(b"\n", at)
        return raw[:start] + (raw[end + 1 :] if end >= 0 else b"")
    if kind == 3:  # a line duplicated
        start = raw.rfind(b"\n", 0, at) + 1
        end = raw.find(b"\n", at)
        line = raw[start : end + 1] if end >= 0 else raw[start:]
        return raw[:start] + line + raw[start:]
    if kind == 6:  # bytes inserted (a TOB1 file written by two programs at once)
        return raw[:at] + junk + raw[at:]
    if kind == 4:  # a number replaced by an absurd one
        numbers = list(NUMBER.finditer(raw))
        if not numbers:
            return raw
        m = numbers[int(where * (len(numbers) - 1))]
        return raw[: m.start()] + b"1e308" + raw[m.end() :]
    return raw + junk  # junk appended (zero padding, a second program's output)


#: slack (s) of the time-span check: a damaged last record may be read to its end
SPAN_SLACK = np.timedelta64(1, "s")


def sample_bytes(name: str) -> bytes:
    """The part of a sample that is damaged (all of a binary TOB1 log)."""
    path, _ = FILES[name]
    return path.read_bytes()[:KEEP] if path.suffix != ".dat" else path.read_bytes()


@functools.cache
def own_time_span(name: str) -> tuple[np.datetime64, np.datetime64]:
    """First and last time of the whole undamaged sample (the damaged bytes are a prefix
    of it, so their span lies within this one)."""
    if name == "scan_netcdf":
        name = "hpl"
    path, options = FILES[name]
    times = read_file(path, **options)["time"].values
    return times.min(), times.max()


#: the dataset kind of each sample (its physical ranges: :func:`ranges_for`)
KINDS = {"hpl": "scan", "scan_netcdf": "scan", "zephir": "wind_record", "windcube": "wind_record"}


def check_dataset(ds, name: str) -> None:
    for var, (low, high) in ranges_for(KINDS.get(name, "sonic")).items():
        if var in ds and ds[var].dtype.kind == "f":
            values = ds[var].values
            finite = values[np.isfinite(values)]
            assert np.all((finite >= low) & (finite <= high)), var
    if "time" in ds.coords or "time" in ds:
        times = ds["time"].values
        assert first_implausible(times) is None
        times = times[~np.isnat(times)]
        first, last = own_time_span(name)
        assert times.size == 0 or (
            times.min() >= first - SPAN_SLACK and times.max() <= last + SPAN_SLACK
        ), f"{name}: times {times.min()} .. {times.max()} outside the file's {first} .. {last}"


@pytest.mark.parametrize("name", [*sorted(FILES), "scan_netcdf"])
@settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    kind=st.integers(0, 6),
    where=st.floats(0.0, 1.0),
    junk=st.binary(min_size=1, max_size=64),
)
# a NUL at 7/8 of the scan NetCDF: netCDF4 raised AttributeError ("Can't open HDF5
# attribute"), which escaped the reader
@example(kind=4, where=0.875, junk=b"\x00")
def test_damaged_file_is_an_error_or_a_sane_dataset(
    tmp_path, scan_netcdf_sample, name, kind, where, junk
):
    path, options = FILES.get(name, (scan_netcdf_sample, {}))
    raw = path.read_bytes() if name == "scan_netcdf" else sample_bytes(name)
    bad = tmp_path / f"damaged{path.suffix}"
    bad.write_bytes(damage(raw, kind, where, junk))
    try:
        ds = read_file(bad, **options)
    except CwprocError as exc:
        text = str(exc)
        assert "internal error" not in text
        assert "\n" not in text and len(text) < 1000
        return
    check_dataset(ds, name)


def check_product(path: Path, name: str) -> None:
    """A product written from damaged inputs: values in range, and every cell whose wind
    is missing carries a non-zero ``qc_flag`` (the real ZephIR product had 250 cells of
    NaN ``w`` flagged good, issue 17.3); times within the inputs' own span."""
    with xr.open_dataset(path) as ds:
        check_dataset(ds.drop_vars("time_bounds", errors="ignore"), name)
        if "qc_flag" not in ds:
            return
        good = ds["qc_flag"].values == 0
        for var in ("u", "v", "w", "wind_speed", "wind_direction"):
            if var in ds and ds[var].dims == ds["qc_flag"].dims:
                missing = ~np.isfinite(ds[var].values)
                assert not (missing & good).any(), f"{path.name}: NaN {var} with qc_flag 0"


@pytest.mark.parametrize(
    ("name", "preset"), [("hpl", "streamline"), ("zephir", "zephir300"), ("windcube", "windcube")]
)
def test_retrieve_on_damaged_copies_writes_only_inside_the_output(tmp_path, name, preset):
    path, _ = FILES[name]
    raw = path.read_bytes()
    folder = tmp_path / "in"
    folder.mkdir()
    for k in range(6):
        (folder / f"{k}_{path.name}").write_bytes(damage(raw, k, 0.37, b"\x00junk\n"))
    out = tmp_path / "deep" / "out"
    result = CliRunner().invoke(main, ["retrieve", str(folder), "-o", str(out), "-c", preset])
    assert result.exit_code in (0, 1), result.output
    assert "Traceback" not in result.output and "internal error" not in result.output
    written = [p for p in tmp_path.rglob("*.nc")]
    assert all(p.parent == out for p in written)
    for product in written:
        check_product(product, name)
