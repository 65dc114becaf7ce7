"""The eight ways a good-looking product could be false (issue 34), each on a generated file.

Every input here is made by the test from the shipped (simulated) samples or from
scratch; no real instrument file is copied into the project.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cwproc.errors import InputFileError
from cwproc.io import read_file
from cwproc.io.timecheck import set_plausible_window

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"

#: sample, and how its time stamps write the year 2024 (replaced by another year)
DATED = {
    "hpl": (SAMPLE / "streamline" / "VAD_999_20240601_120000.hpl", [b"Start time:\t2024"]),
    "zephir": (SAMPLE / "zephir" / "Wind10_999@Y2024_M06_D01.ZPH.csv", [b".2024 "]),
    "windcube": (SAMPLE / "windcube" / "WLS7-999_2024_06_01__00_00_00.sta", [b"\n2024/"]),
    "toa5": (SAMPLE / "sonic" / "TOA5_999.ts_data_2024_06_01_1200.dat", [b'"2024-']),
    "meteo2": (SAMPLE / "sonic" / "meteo2_2024_06_01_1200.txt", [b"\n2024-"]),
}


@pytest.fixture(autouse=True)
def _default_window():
    set_plausible_window()
    yield
    set_plausible_window()


def redated(name: str, year: int, tmp_path: Path) -> Path:
    """The sample ``name`` with the year of every time stamp replaced by ``year``."""
    path, patterns = DATED[name]
    raw = path.read_bytes()
    for p in patterns:
        raw = raw.replace(p, p.replace(b"2024", str(year).encode()))
    out = tmp_path / path.name
    out.write_bytes(raw)
    return out


# -- 34.1 dates checked as written, before any conversion -----------------------------


@pytest.mark.parametrize("name", sorted(DATED))
@pytest.mark.parametrize("year", [1430, 1600, 2300, 2590])
def test_a_year_beyond_the_nanosecond_range_is_refused_as_written(tmp_path, name, year):
    """Years 1410-1441 and 2580-2610 wrapped to 2004-2005 through datetime64[ns]
    (``.hpl`` starting in 2590 gave ``..._20051111_wind.nc``); 1600 and 2300 were
    refused with the wrapped date in the message. Now: refused, the year as written."""
    with pytest.raises(InputFileError, match="outside the plausible range") as err:
        read_file(redated(name, year, tmp_path))
    assert str(year) in str(err.value)
    assert "2005" not in str(err.value) and "2004" not in str(err.value)


def test_the_configuration_widens_the_window(tmp_path):
    """A 1990 file is refused by default and read once the configuration widens it."""
    old = redated("toa5", 1990, tmp_path)
    with pytest.raises(InputFileError, match="'1990-06-01 12:00:00'"):
        read_file(old)
    set_plausible_window("1985-01-01")
    ds = read_file(old)
    assert str(ds["time"].values[0]).startswith("1990-06-01T12:00")


def test_the_window_keys_are_validated():
    from cwproc.config import Config
    from cwproc.errors import ConfigError

    assert Config().replace(instrument={"earliest_date": "1980-01-01"}).instrument
    for bad in ("1980", "2590-01-01", "1600-01-01", "1980-02-30"):
        with pytest.raises(ConfigError, match="earliest_date"):
            Config().replace(instrument={"earliest_date": bad})


# -- 34.4 the body is looked at before it is read -------------------------------------


@pytest.mark.parametrize("data_bytes", [5_000, 3_000_000])
def test_a_sparse_2gb_file_behind_a_valid_header_is_refused_unread(tmp_path, data_bytes):
    """2 GB of holes after a valid ``.hpl`` header (and after 3 MB of good rays) took
    4.3 GB of memory and 73 s before it was refused; now a few sampled reads."""
    import resource
    import time

    raw = DATED["hpl"][0].read_bytes()
    path = tmp_path / "sparse.hpl"
    with open(path, "wb") as f:
        while f.tell() < data_bytes:
            f.write(raw if f.tell() == 0 else raw[raw.index(b"****\r\n") + 6 :])
        f.truncate(2 << 30)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.process_time()
    with pytest.raises(InputFileError, match=r"NUL byte at byte \d+ .* refused unread"):
        read_file(path)
    assert time.process_time() - start < 5.0
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 200_000  # kB


# -- 34.6 one rule for the summary and the exit status --------------------------------


def _failures_said(stdout: str) -> int:
    import re

    return int(re.search(r"(\d+) failure\(s\)", stdout).group(1))


@pytest.mark.parametrize(
    "extra, failures",
    [
        ("background", 0),  # goes with the .hpl beside it: a note, not an error
        ("zephir", 1),  # another instrument's file named on the command line
        ("garbage", 1),  # pinned .hpl, not a .hpl
    ],
)
def test_the_summary_and_the_exit_status_agree(tmp_path, extra, failures):
    """A background file given with a configuration that reads only ``.hpl`` printed an
    error, "0 failure(s)" and exited 1. Now every error line printed is counted in the
    summary, and the exit status is 1 exactly when that count is not 0."""
    from click.testing import CliRunner

    from cwproc.cli import main

    other = {
        "background": ("Background_010624-120005.txt", b"1000.0\r\n" * 200),
        "zephir": ("w.csv", (SAMPLE / "zephir" / "Wind10_999@Y2024_M06_D01.ZPH.csv").read_bytes()),
        "garbage": ("g.hpl", b"not a lidar file\n"),
    }[extra]
    path = tmp_path / other[0]
    path.write_bytes(other[1])
    args = ["retrieve", str(path), str(DATED["hpl"][0]), "-c", "streamline", "-o"]
    result = CliRunner().invoke(main, [*args, str(tmp_path / "out")])
    assert _failures_said(result.stdout) == failures
    assert result.stderr.count("error: ") == failures
    assert result.exit_code == (1 if failures else 0)
    assert "2 input(s), 2 product(s) written" in result.stdout


@pytest.mark.parametrize("damaged", [False, True])
def test_batch_counts_every_error_line_in_its_summary(tmp_path, damaged):
    """The same rule for ``cwproc batch``: its summary ends with the count of the
    ``error:`` lines printed, and the exit status is 1 exactly when it is not 0."""
    from click.testing import CliRunner

    from cwproc.cli import main

    inputs = tmp_path / "in"
    inputs.mkdir()
    (inputs / DATED["hpl"][0].name).write_bytes(DATED["hpl"][0].read_bytes())
    if damaged:
        (inputs / "VAD_999_20240602_120000.hpl").write_bytes(b"Filename:\tcut\n")
    args = ["batch", str(inputs), str(tmp_path / "out"), "-c", "streamline"]
    result = CliRunner().invoke(main, args)
    said = _failures_said(result.stdout)
    assert said == result.stderr.count("error: ") == int(damaged)
    assert result.exit_code == (1 if said else 0)


# -- 34.2 a logger is everything that identifies it -----------------------------------

TOA5 = SAMPLE / "sonic" / "TOA5_999.ts_data_2024_06_01_1200.dat"


def other_logger(serial: str = "999", shift: float = 1.0) -> bytes:
    """The TOA5 sample as another logger would write it: serial ``serial``, and ``Ux``
    (third field) ``shift`` m/s higher over the same times (overlapping, other data)."""
    lines = TOA5.read_bytes().split(b"\n")
    lines[0] = lines[0].replace(b'"CR3000","999"', f'"CR3000","{serial}"'.encode())
    for i in range(4, len(lines)):
        fields = lines[i].split(b",")
        if len(fields) > 2:
            fields[2] = f"{float(fields[2]) + shift:.4f}".encode()
            lines[i] = b",".join(fields)
    return b"\n".join(lines)


def _retrieve(tmp_path, *inputs):
    from click.testing import CliRunner

    from cwproc.cli import main

    out = tmp_path / "out"
    args = ["retrieve", *map(str, inputs), "-c", str(SAMPLE / "sonic.toml"), "-o", str(out)]
    return CliRunner().invoke(main, args), out


@pytest.mark.parametrize("layout", ["two serials, one folder", "one header, two folders"])
def test_two_loggers_of_one_station_name_are_never_merged(tmp_path, layout):
    """Two loggers with the station name of their header in common, overlapping in time
    with different data, were merged into one product marked good."""
    import xarray as xr

    a, b = tmp_path / "a" / "x.dat", tmp_path / ("a" if "serial" in layout else "b") / "y.dat"
    for p in (a, b):
        p.parent.mkdir(exist_ok=True)
    a.write_bytes(TOA5.read_bytes())
    b.write_bytes(other_logger("1234" if "serial" in layout else "999"))
    result, out = _retrieve(tmp_path, a, b)
    assert result.exit_code == 0, result.output
    products = sorted(out.glob("*_sf.nc"))
    assert len(products) == 2
    assert "loggers share the unit toa5_999_20240601" in result.stderr
    assert ("serial" if "serial" in layout else "folder") in result.stderr
    _retrieve(tmp_path / "alone", a)
    (single,) = (tmp_path / "alone" / "out").glob("*_sf.nc")
    own = out / (
        "toa5_999-999_20240601_sf.nc" if "serial" in layout else "toa5_999-a_20240601_sf.nc"
    )
    with xr.open_dataset(single) as one, xr.open_dataset(own) as kept:
        # the first logger's product is what its file alone gives: nothing of the other
        np.testing.assert_array_equal(
            kept["mean_horizontal_wind"].values, one["mean_horizontal_wind"].values
        )
    (other,) = set(products) - {own}
    with xr.open_dataset(other) as moved, xr.open_dataset(own) as kept:
        shift = moved["mean_horizontal_wind"].values - kept["mean_horizontal_wind"].values
        assert np.nanmean(shift) > 0.3  # Ux + 1 m/s of the second logger, its own product


def test_one_logger_in_daily_folders_stays_one_unit(tmp_path):
    """Folders alone tell loggers apart only where their times overlap: one logger's
    files kept one folder a day (the file that crosses midnight in the day before's)
    make one unit a day, as before."""
    from cwproc.config import Config
    from cwproc.pipeline import group_units, read_input

    header, records = tob1_parts()
    half = records.size // 2
    first, second = tmp_path / "d1" / "a.dat", tmp_path / "d2" / "b.dat"
    for path, part in ((first, records[:half]), (second, records[half:])):
        path.parent.mkdir()
        path.write_bytes(header + part.tobytes())
    notes: list[str] = []
    units = group_units([read_input(p, Config()) for p in (first, second)], notes)
    assert [u.key for u in units] == ["tob1_999_20240601"] and notes == []
    (tmp_path / "d2" / "c.dat").write_bytes(header + records[half - 10 :].tobytes())
    items = [read_input(p, Config()) for p in (first, tmp_path / "d2" / "c.dat")]
    assert len(group_units(items, notes)) == 2 and "differ in folder" in notes[0]


def test_batch_keeps_two_loggers_apart_and_notes_it(tmp_path):
    from cwproc.batch import run_batch
    from cwproc.config import load_config

    inputs = tmp_path / "in"
    inputs.mkdir()
    (inputs / "x.dat").write_bytes(TOA5.read_bytes())
    (inputs / "y.dat").write_bytes(other_logger("1234"))
    report = run_batch(inputs, tmp_path / "out", load_config(str(SAMPLE / "sonic.toml")))
    assert report.ok, report.failure_lines()
    keys = sorted(o.key for o in report.processed)
    assert keys == ["toa5_999-1234_20240601", "toa5_999-999_20240601"]
    assert any("differ in serial (1234; 999)" in n for n in report.notes())


# -- 34.3 records out of the file's sequence or span are refused, counted -------------

TOB1 = SAMPLE / "sonic" / "TOB1_999.ts_data_2024_06_01_1200.dat"


def tob1_parts() -> tuple[bytes, np.ndarray]:
    """The TOB1 sample's header bytes and its records (their dtype from the header)."""
    from cwproc.io.campbell_tob1 import tob1_dtype

    raw = TOB1.read_bytes()
    lines = raw.split(b"\n", 5)
    header = b"\n".join(lines[:5]) + b"\n"
    fields = [f.strip('"') for f in lines[1].decode().strip().split(",")]
    types = [f.strip('"') for f in lines[4].decode().strip().split(",")]
    records = np.frombuffer(raw[len(header) :], dtype=tob1_dtype("x", fields, types)).copy()
    return header, records


@pytest.mark.parametrize("where", ["end", "middle"])
def test_garbage_records_with_believable_times_invent_no_day(tmp_path, where):
    """Ten garbage records of a TOB1 file, each with a believable time on another day,
    made ten extra day products (exit 0). Now they are refused, with a count."""
    from click.testing import CliRunner

    from cwproc.cli import main

    header, records = tob1_parts()
    garbage = records[:10].copy()
    garbage["SECONDS"] = records["SECONDS"][0] + 86_400 * np.arange(1, 11)
    garbage["RECORD"] = records["RECORD"][-1] + 1 + np.arange(10)
    body = (
        np.concatenate([records, garbage])
        if where == "end"
        else np.concatenate([records[:3000], garbage, records[3000:]])
    )
    path = tmp_path / "TOB1_garbage.dat"
    path.write_bytes(header + body.tobytes())
    ds = read_file(path)
    assert ds.sizes["time"] == records.size
    assert np.unique(ds["time"].values.astype("datetime64[D]")).tolist() == [
        np.datetime64("2024-06-01", "D")
    ]
    assert any(w.startswith("10 record(s) whose time breaks") for w in ds.attrs["warnings"])
    out = tmp_path / "out"
    args = ["retrieve", str(path), "-c", str(SAMPLE / "sonic.toml"), "-o", str(out)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert [p.name for p in out.glob("*_sf.nc")] == ["tob1_999_20240601_sf.nc"]


@pytest.mark.parametrize("n_bytes", [1, 3, 31])
def test_bytes_inserted_mid_file_do_not_drop_the_rest(tmp_path, n_bytes):
    """Three bytes inserted mid-file dropped the rest of a TOB1 file without a note; now
    the record that holds them is lost and reading resumes, with a note."""
    raw = TOB1.read_bytes()
    header, records = tob1_parts()
    at = len(header) + 32 * 2000 + 17  # inside record 2001
    path = tmp_path / "TOB1_inserted.dat"
    path.write_bytes(raw[:at] + b"\xa5" * n_bytes + raw[at:])
    ds = read_file(path)
    assert ds.sizes["time"] == records.size - 1
    assert any(
        f"{32 + n_bytes} byte(s) skipped, 1 record(s) lost" in w for w in ds.attrs["warnings"]
    )


# -- 34.5 physical ranges per quantity and instrument; missing cells; inf --------------

#: wind-record samples: (path, separator, first data line index, the column of w at the
#: first height, the column of the horizontal speed at the first height)
RECORDS = {
    "zephir": (DATED["zephir"][0], b";", 2, 16, 12),
    "windcube": (DATED["windcube"][0], b"\t", 17, 12, 7),
}


def edited_record(name: str, tmp_path: Path, column: int, text: bytes, row: int = 3) -> Path:
    """The wind-record sample ``name`` with field ``column`` of data row ``row`` set to
    ``text`` (0-based field; rows counted from the first data line)."""
    path, sep, first, _, _ = RECORDS[name]
    lines = path.read_bytes().split(b"\n")
    fields = lines[first + row].split(sep)
    fields[column] = text
    lines[first + row] = sep.join(fields)
    out = tmp_path / path.name
    out.write_bytes(b"\n".join(lines))
    return out


def _decimal(name: str, value: str) -> bytes:
    return (value.replace(".", ",") if name == "zephir" else value).encode()


@pytest.mark.parametrize("name", sorted(RECORDS))
def test_an_impossible_mean_vertical_wind_is_missing_not_good(tmp_path, name):
    """w = -50 m s-1 (within the +-60 of single sonic samples) was written as good by the
    ZephIR and WindCube readers; a 10-min mean is bounded by +-10 m s-1."""
    from cwproc.io.ranges import ranges_for

    assert ranges_for("wind_record")["w"] == (-10.0, 10.0)
    whole = read_file(RECORDS[name][0])
    ds = read_file(edited_record(name, tmp_path, RECORDS[name][3], _decimal(name, "-50.0")))
    w = ds["w"].values
    assert np.count_nonzero(np.isnan(w)) == np.count_nonzero(np.isnan(whole["w"].values)) + 1
    assert np.nanmax(np.abs(w)) <= 10.0
    assert any("value(s) of w outside -10..10" in m for m in ds.attrs["warnings"])


@pytest.mark.parametrize("name", sorted(RECORDS))
@pytest.mark.parametrize("cell", [b"", b"inf", b"-inf"])
def test_one_missing_or_infinite_cell_is_one_missing_value(tmp_path, name, cell):
    """One empty cell made the ZephIR reader refuse a whole day; ``inf`` was an error for
    one reader and a value for the other. Now both: that value missing, the rest read."""
    whole = read_file(RECORDS[name][0])
    ds = read_file(edited_record(name, tmp_path, RECORDS[name][4], cell))
    speed = ds["wind_speed"].values
    assert speed.shape == whole["wind_speed"].values.shape
    assert (
        np.count_nonzero(np.isnan(speed))
        == np.count_nonzero(np.isnan(whole["wind_speed"].values)) + 1
    )
    assert np.all(np.isfinite(speed) | np.isnan(speed))
    if cell:
        assert any("wind_speed" in m and "not finite" in m for m in ds.attrs["warnings"])


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    name=st.sampled_from(sorted(DATED)),
    year=st.one_of(st.integers(1000, 1994), st.integers(2100, 9999)),
)
def test_any_year_outside_the_window_is_refused_as_written(name, year):
    """Property of 34.1 over every text reader: a year outside the plausible window is
    refused, the message quoting the year as written, wrapped or not through 64-bit
    nanoseconds (their range is 1677-2262, the wrap period 584 years)."""
    import tempfile

    set_plausible_window()
    with tempfile.TemporaryDirectory() as tmp:
        with pytest.raises(InputFileError, match="outside the plausible range") as err:
            read_file(redated(name, year, Path(tmp)))
    assert str(year) in str(err.value)


@pytest.mark.parametrize(
    ("interval", "kept"), [(1.0, True), (None, True), (60.0, False), (600.0, False)]
)
def test_the_ranges_of_means_apply_to_averaged_records_only(interval, kept):
    """w = 18 m s-1 is impossible as a 1- or 10-min mean but a possible single value: the
    1-s ZephIR records and the .rtd lines of sight (the real WindCube .rtd has a 1-Hz
    Z-wind of 18 m s-1 at -30 dB CNR) keep it; 60 s and longer averages lose it."""
    import xarray as xr

    from cwproc.io.zephir import with_range_screen

    attrs = {} if interval is None else {"averaging_interval_s": interval}
    ds = xr.Dataset({"w": (("time",), np.array([0.5, 18.0, -70.0]))}, attrs=attrs)
    w = with_range_screen(ds)["w"].values
    assert np.isnan(w[2])  # beyond the +-60 of any single value
    assert np.isfinite(w[1]) == kept
