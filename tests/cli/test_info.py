"""``cwproc info`` through click's CliRunner."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.cli.describe import azimuth_coverage, describe_scan, elevation_summary
from cwproc.io.halo import read_hpl, write_hpl
from cwproc.io.scan_join import assign_scans


def run(*args: str):
    return CliRunner().invoke(main, ["info", *args])


@pytest.fixture(scope="module")
def hpl(real_data: Path) -> Path:
    return real_data / "hpl"


def test_real_vad_file(hpl: Path) -> None:
    path = hpl / "soverato-2021-10-01-VAD_194_20210624_170110.hpl"
    result = run(str(path))
    assert result.exit_code == 0, result.output
    out = result.output
    assert out.splitlines()[0] == str(path)
    assert "hpl (Halo Photonics Stream Line .hpl)" in out
    assert "system id 194" in out
    assert "scan type     VAD" in out
    assert "rays          2\n" in out
    assert "gates         400 x 30 m (15 - 11985 m)" in out
    # rays at 17.02071944 h and 17.02200833 h
    assert "2021-06-24T17:01:14.589Z - 2021-06-24T17:01:19.229Z (4.6 s)" in out
    assert "elevation     75.00 deg" in out
    assert "coverage 60.0 deg" in out  # azimuths 0 and 60.01
    assert "1 conical scan(s)" in out


def test_stare_and_user_scan(hpl: Path) -> None:
    result = run(
        str(hpl / "User5_96_20190308_200500.hpl"),
        str(hpl / "hyytiala-2023-09-13-Stare_46_20230913_23.hpl"),
    )
    assert result.exit_code == 0, result.output
    assert "rays          528" in result.output
    assert "no conical scan; 528 ray(s) in no scan" in result.output
    assert "rays          1\n" in result.output
    assert "scan type     Stare" in result.output


def test_corrupt_file_one_error_line_and_others_still_listed(hpl: Path) -> None:
    good = hpl / "eriswil-2022-12-14-Stare_91_20221214_11.hpl"
    bad = hpl / "CORRUPT_warsaw-2021-10-01-Stare_213_20211001_18.hpl"
    result = CliRunner().invoke(main, ["info", str(bad), str(good)])
    assert result.exit_code == 1
    errors = [ln for ln in result.stderr.splitlines() if ln]
    assert errors == [errors[0]] and errors[0].startswith(f"error: {bad}:3019: ")
    assert str(good) in result.stdout and "system id 91" in result.stdout
    assert "Traceback" not in result.output


def test_unknown_and_missing_files(tmp_path: Path) -> None:
    junk = tmp_path / "notes.txt"
    junk.write_text("hello\n")
    result = run(str(junk), str(tmp_path / "missing.hpl"))
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert lines[0] == f"error: {junk}:1: not a format cwproc reads (unrecognised first line)"
    assert lines[1].startswith(f"error: {tmp_path / 'missing.hpl'}: cannot read")
    assert result.stdout == ""


def test_other_format_lists_dims_time_and_variables(real_data: Path) -> None:
    path = real_data / "zephir" / "Wind10_317@Y2016_M12_D13.ZPH.csv"
    result = run(str(path))
    if result.exit_code != 0 and "no reader" in result.stderr:
        pytest.skip("the ZephIR reader is not in this build yet")
    assert result.exit_code == 0, result.output
    assert "kind          wind_record" in result.output
    assert "dims          time=" in result.output
    assert "variables" in result.output


def test_synthetic_vad_day_counts_scans(tmp_path: Path) -> None:
    """3 rotations of a 24-ray step-stare VAD at 70 deg, written as a real .hpl."""
    n = 72
    rng = np.random.default_rng(5)
    ds = xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), rng.normal(size=(n, 10))),
            "snr": (("ray", "range"), rng.uniform(0, 1, (n, 10))),
            "beta": (("ray", "range"), rng.uniform(1e-7, 1e-5, (n, 10))),
        },
        coords={
            "time": (
                "ray",
                np.datetime64("2024-01-01T00:00", "ns")
                + (np.arange(n) * 2_000_000_000).astype("timedelta64[ns]"),
            ),
            "azimuth": ("ray", np.mod(np.arange(n) * 15.0, 360.0)),
            "elevation": ("ray", np.full(n, 70.0)),
            "range": ("range", (np.arange(10) + 0.5) * 30.0),
        },
        attrs={"system_id": "7", "scan_type": "VAD", "gate_length_m": 30.0},
    )
    path = write_hpl(assign_scans(ds), tmp_path / "VAD_7_20240101_000000.hpl")
    result = run(str(path))
    assert result.exit_code == 0, result.output
    assert "3 conical scan(s), 24 rays per scan (median); 0 ray(s) in no scan" in result.output
    assert "coverage 345.0 deg" in result.output
    assert describe_scan(read_hpl(path))[2] == "  rays          72"


def test_azimuth_coverage_and_elevations() -> None:
    assert azimuth_coverage(np.arange(0, 360, 15.0)) == pytest.approx(345.0)
    assert azimuth_coverage(np.array([350.0, 10.0])) == pytest.approx(20.0)
    assert azimuth_coverage(np.array([42.0])) == 0.0
    assert elevation_summary(np.array([75.0, 75.01, 35.0])) == "35.00, 75.00 deg"
    assert elevation_summary(np.linspace(0, 45, 10)) == "0.00 - 45.00 deg (10 distinct)"


def test_no_arguments_is_a_usage_error() -> None:
    result = run()
    assert result.exit_code == 2


def test_scan_netcdf_file(tmp_path: Path) -> None:
    from cwproc.io.scan_netcdf import write_scan_netcdf

    n = 50
    ds = xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), np.ones((n, 3))),
            "snr": (("ray", "range"), np.ones((n, 3))),
        },
        coords={
            "time": (
                "ray",
                np.datetime64("2016-12-13T10:00", "ns")
                + (np.arange(n) * 20_000_000).astype("timedelta64[ns]"),
            ),
            "azimuth": ("ray", np.arange(n) * 7.2),
            "elevation": ("ray", np.full(n, 60.0)),
            "range": ("range", [40.0, 80.0, 120.0]),
        },
        attrs={
            "instrument": "ZephIR 300",
            "instrument_kind": "cw",
            "homodyne": 1,
            "system_id": "317",
            "scan_type": "conical",
        },
    )
    path = write_scan_netcdf(ds, tmp_path / "cw.nc")
    result = run(str(path))
    assert result.exit_code == 0, result.output
    assert "scan_netcdf (cwproc scan dataset (NetCDF))" in result.output
    assert "ZephIR 300 (cw), system id 317, homodyne" in result.output
    assert "1 conical scan(s), 50 rays per scan" in result.output
    assert "(1.0 s)" in result.output  # 50 rays 20 ms apart: 0.98 s
