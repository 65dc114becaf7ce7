"""WindCube .rtd reader: the real WF 2.2.1 file, the v1/v2/v2.1 samples, damaged files."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.errors import ConfigError, InputFileError
from cwproc.io import Format, detect_format
from cwproc.io.windcube_rtd import read_windcube_rtd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from byte_mutations import mutated, mutation_ops

REAL = "windcube/WLS71460_2022_01_11__21_04_17.rtd"
SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "windcube_rtd"


@pytest.fixture(scope="module")
def real(real_data):
    return read_windcube_rtd(real_data / REAL)


def test_real_file_lines_of_sight(real, real_data):
    assert detect_format(real_data / REAL) is Format.WINDCUBE_RTD
    assert real.sizes == {"time": 3439, "height": 9}
    np.testing.assert_array_equal(real["height"], [40, 60, 80, 100, 120, 140, 160, 180, 200])
    assert real["time"].values[0] == np.datetime64("2022-01-11T21:04:17.790")
    assert real["time"].values[-1] == np.datetime64("2022-01-11T21:50:08.190")
    labels, counts = np.unique(real["beam"].values, return_counts=True)
    assert dict(zip(labels, counts, strict=True)) == {
        "0": 688,
        "90": 688,
        "180": 688,
        "270": 687,
        "V": 688,
    }
    a = real.attrs
    assert a["instrument_model"] == "WindCube v2.1" and a["system_id"] == "WLS71460"
    assert a["scan_angle_source"].startswith("nominal") and a["scan_angle_deg"] == 28.0
    assert any("ScanAngle NA" in w for w in a["warnings"])
    assert a["line_of_sight_interval_s"] == pytest.approx(0.8)
    # line 43 (V beam), 40 m: CNR -30.63, RWS 6.28, dispersion 0.02, Z-wind 6.278
    first = real.isel(time=0).sel(height=40.0)
    assert first["beam"] == "V" and first["beam_elevation"] == 90.0
    assert first["cnr"] == pytest.approx(-30.63)
    assert first["radial_velocity"] == pytest.approx(6.28)
    assert first["radial_velocity_dispersion"] == pytest.approx(0.02)
    # the radial velocity is positive away (up on V): it equals the Z-wind there
    vertical = real["beam"] == "V"
    np.testing.assert_allclose(
        real["radial_velocity"].where(vertical), real["w"].where(vertical), atol=0.006
    )
    # line 44, 0 deg beam, 40 m: -36.33 dB, 11.26 m/s; elevation 90 - 28
    second = real.isel(time=1).sel(height=40.0)
    assert second["beam"] == "0" and second["beam_elevation"] == 62.0
    assert second["radial_velocity"] == pytest.approx(11.26)
    # Temperature 999.00 is the missing-value code
    assert bool(np.isnan(real["internal_temperature"]).all())


def test_scan_angle_option_sets_the_elevation(real_data):
    ds = read_windcube_rtd(real_data / REAL, scan_angle_deg=30.0)
    assert ds.attrs["scan_angle_source"] == "reader option scan_angle_deg"
    assert set(np.unique(ds["beam_elevation"].values)) == {60.0, 90.0}


@pytest.mark.parametrize(
    ("name", "layout", "model", "beams"),
    [
        ("WLS71999_2024_06_01__00_00_00.rtd", "v2/v2.1", "WindCube v2.1", 5),
        ("WLS7-999_2024_06_01__00_10_00.rtd", "v2/v2.1", "WindCube v2", 5),
        ("WLS7-099_2024_06_01__00_12_00.rtd", "v1", "WindCube v1", 4),
    ],
)
def test_samples_of_the_three_layouts(name, layout, model, beams):
    ds = read_windcube_rtd(SAMPLE / name)
    assert ds.attrs["rtd_layout"] == layout and ds.attrs["instrument_model"] == model
    assert np.unique(ds["beam"].values).size == beams
    assert ds.attrs["scan_angle_deg"] == 28.0
    # the mean radial velocity of each inclined beam is the projection of the true
    # wind (8 m/s from 240 deg: u = 6.93, v = 4.0 m/s): V_r = sin(28)(u sin az + v cos az)
    u, v = 8 * np.sin(np.radians(60.0)), 8 * np.cos(np.radians(60.0))
    for az in (0.0, 90.0, 180.0, 270.0):
        mean = ds["radial_velocity"].where(ds["beam_azimuth"] == az).where(ds["beam"] != "V").mean()
        proj = np.sin(np.radians(28.0)) * (u * np.sin(np.radians(az)) + v * np.cos(np.radians(az)))
        # three standard errors of a mean over T of a velocity with sigma_V = 1.13 m/s
        # (epsilon 0.01, L_V 100 m) and integral time L_V / U: 3 sigma sqrt(2 L / (U T))
        duration = float(ds["time"][-1] - ds["time"][0]) / 1e9
        tolerance = 3 * 1.13 * np.sqrt(2 * 100.0 / (8.0 * duration))
        assert float(mean) == pytest.approx(proj, abs=tolerance), (name, az)


def _expect(path: Path, line: int | None, words: str) -> None:
    with pytest.raises(InputFileError) as info:
        read_windcube_rtd(path)
    assert info.value.path == str(path)
    assert info.value.line == line
    assert words in info.value.problem


def _edited(tmp_path: Path, name: str, edit) -> Path:
    lines = (SAMPLE / name).read_bytes().decode("latin-1").split("\n")
    edit(lines)
    out = tmp_path / "damaged.rtd"
    out.write_bytes("\n".join(lines).encode("latin-1"))
    return out


def test_bad_position(tmp_path):
    def edit(lines):
        fields = lines[30].split("\t")
        fields[1] = "N"
        lines[30] = "\t".join(fields)

    _expect(_edited(tmp_path, "WLS71999_2024_06_01__00_00_00.rtd", edit), 31, "Position 'N'")


def test_bad_number_and_missing_tokens(tmp_path):
    name = "WLS71999_2024_06_01__00_00_00.rtd"

    def bad(lines):
        fields = lines[30].split("\t")
        fields[5] = "1.2x"
        lines[30] = "\t".join(fields)

    _expect(_edited(tmp_path, name, bad), 31, "is not a number")
    for token in ("NA", "-", ""):

        def missing(lines, token=token):
            fields = lines[30].split("\t")
            fields[5] = token
            lines[30] = "\t".join(fields)

        ds = read_windcube_rtd(_edited(tmp_path, name, missing))
        assert np.isnan(ds["radial_velocity"].values[30 - 24, 0])


def test_truncated_record(tmp_path):
    def edit(lines):
        lines[-2] = lines[-2][:40]

    path = _edited(tmp_path, "WLS71999_2024_06_01__00_00_00.rtd", edit)
    with pytest.raises(InputFileError, match="truncated"):
        read_windcube_rtd(path)


def test_v1_block_count_must_match_the_altitudes(tmp_path):
    def edit(lines):
        lines[9] = lines[9] + "\t220"  # one altitude more than the column blocks

    path = _edited(tmp_path, "WLS7-099_2024_06_01__00_12_00.rtd", edit)
    _expect(path, 12, "expected 8 for each of the 4 altitudes")


def test_reader_options_are_validated(real_data):
    with pytest.raises(ConfigError, match="unknown reader option"):
        read_windcube_rtd(SAMPLE / "WLS71999_2024_06_01__00_00_00.rtd", decimal=",")
    with pytest.raises(ConfigError, match="scan_angle_deg"):
        read_windcube_rtd(SAMPLE / "WLS71999_2024_06_01__00_00_00.rtd", scan_angle_deg=80.0)


def test_sta_reader_is_not_confused_with_rtd():
    sta = SAMPLE / "WLS71999_2024_06_01__00_00_00.sta"
    assert detect_format(sta) is Format.WINDCUBE_STA


@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    ops=mutation_ops(b"\t\n.=0123456789 xNAV-/:\xb0m"),
    name=st.sampled_from(
        ["WLS71999_2024_06_01__00_00_00.rtd", "WLS7-099_2024_06_01__00_12_00.rtd"]
    ),
)
def test_mutated_files_give_a_dataset_or_input_file_error(tmp_path_factory, ops, name):
    lines = (SAMPLE / name).read_bytes().split(b"\n")
    data = bytearray(b"\n".join(lines[:40]) + b"\n")
    data = mutated(bytes(data), ops)
    path = tmp_path_factory.mktemp("mut") / "m.rtd"
    path.write_bytes(bytes(data))
    try:
        ds = read_windcube_rtd(path)
    except InputFileError as err:
        assert err.path == str(path) and err.problem
    else:
        assert set(ds.dims) == {"time", "height"}
        assert np.all(np.diff(ds["time"].values) > np.timedelta64(0, "ns"))
