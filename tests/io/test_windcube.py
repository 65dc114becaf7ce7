"""WindCube v1 .sta reader: both header generations, spot checks, damaged files."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.errors import InputFileError
from cwproc.io.windcube import read_windcube_sta

sys.path.insert(0, str(Path(__file__).resolve().parent))
from byte_mutations import mutated, mutation_ops

V1 = "windcube/WLS7-164_2016_11_24__00_00_00.sta"
V3 = "windcube/WLS7-72_2016_12_06__00_00_00.sta"


def test_version_1_file(real_data):
    ds = read_windcube_sta(real_data / V1)
    assert ds.sizes == {"time": 144, "height": 10}
    np.testing.assert_array_equal(ds["height"], [40, 58, 78, 98, 118, 133, 158, 198, 248, 290])
    # "2016/11/24 00:10" ... "2016/11/25 00:00", timezone=UTC+0, end of interval
    assert ds["time"].values[0] == np.datetime64("2016-11-24T00:10")
    assert ds["time"].values[-1] == np.datetime64("2016-11-25T00:00")
    assert ds.attrs["time_stamp_position"] == "end"
    assert ds.attrs["averaging_interval_s"] == 600.0
    assert ds.attrs["utc_offset_applied_h"] == 0.0 and ds.attrs["time_sync"] == "from file"
    assert ds.attrs["system_id"] == "WLS7-164"
    assert ds.attrs["scan_angle_deg"] == 28.0
    # line 43: 24.60 NaN NaN NaN 0 NaN | 0.18 0.10 0.00 0.48 118.0 -0.03 0.06 -11.0 -12.6 1.26 100
    r = ds.isel(time=0)
    assert r["internal_temperature"] == pytest.approx(24.6)
    assert np.isnan(r["air_temperature"]) and np.isnan(r["battery_voltage"])
    h40 = r.sel(height=40.0)
    expected = {
        "wind_speed": 0.18,
        "wind_speed_std": 0.10,
        "wind_speed_min": 0.0,
        "wind_speed_max": 0.48,
        "wind_direction": 118.0,
        "w": -0.03,
        "w_std": 0.06,
        "cnr": -11.0,
        "cnr_min": -12.6,
        "spectral_broadening": 1.26,
        "data_availability": 100.0,
    }
    for name, value in expected.items():
        assert h40[name] == pytest.approx(value), name
    assert r.sel(height=58.0)["wind_direction"] == pytest.approx(339.3)
    # last line, 290 m block: 9.53 0.82 6.57 11.74 65.1 0.27 0.50 -16.1 -20.3 1.34 100
    last = ds.isel(time=-1).sel(height=290.0)
    assert last["wind_speed"] == pytest.approx(9.53)
    assert last["wind_speed_max"] == pytest.approx(11.74)
    assert last["wind_direction"] == pytest.approx(65.1)


def test_version_3_file(real_data):
    ds = read_windcube_sta(real_data / V3)
    assert ds.sizes == {"time": 144, "height": 10}
    np.testing.assert_array_equal(ds["height"], [40, 60, 80, 100, 120, 135, 160, 200, 250, 300])
    assert ds["time"].values[0] == np.datetime64("2016-12-06T00:10")
    assert ds["time"].values[-1] == np.datetime64("2016-12-07T00:00")
    assert ds.attrs["time_sync"] == "absent"
    assert ds.attrs["scan_angle_deg"] == pytest.approx(27.8)
    # line 58: 06/12/2016 00:10:00 0 1.54 | 4.80 0.70 6.82 2.87 178.5 -4.766 0.708 0.127
    #          0.536 -0.760 0.233 8.15 1.01 11.30 4.86 1.025 0.242 100.00
    r = ds.isel(time=0)
    assert r["air_temperature"] == pytest.approx(1.54)
    h40 = r.sel(height=40.0)
    expected = {
        "wind_speed": 4.80,
        "wind_speed_std": 0.70,
        "wind_speed_max": 6.82,
        "wind_speed_min": 2.87,
        "wind_direction": 178.5,
        "u_instrument": -4.766,
        "v_instrument": 0.127,
        "w": -0.760,
        "w_std": 0.233,
        "cnr": 8.15,
        "cnr_max": 11.30,
        "spectral_broadening": 1.025,
        "data_availability": 100.0,
    }
    for name, value in expected.items():
        assert h40[name] == pytest.approx(value), name
    assert r.sel(height=60.0)["wind_speed"] == pytest.approx(4.94)
    assert r.sel(height=60.0)["wind_direction"] == pytest.approx(176.5)
    # um = Vhm cos(Azim), vm = Vhm sin(Azim) in the file (basis of the direction reading)
    ok = np.isfinite(ds["u_instrument"]) & (ds["wind_speed"] > 2)
    az = np.radians(ds["wind_direction"].where(ok))
    np.testing.assert_allclose(
        (ds["wind_speed"] * np.cos(az)).where(ok).values,
        ds["u_instrument"].where(ok).values,
        atol=0.25,
    )


def test_utc_offset_option(real_data):
    ds = read_windcube_sta(real_data / V3, utc_offset_hours=1.0)
    assert ds["time"].values[0] == np.datetime64("2016-12-05T23:10")


def _damaged(tmp_path: Path, real_data: Path, name: str, edit) -> Path:
    text = (real_data / name).read_bytes().decode("latin-1")
    out = tmp_path / "damaged.sta"
    out.write_bytes(edit(text).encode("latin-1"))
    return out


def _expect(path: Path, line: int | None, words: str) -> None:
    with pytest.raises(InputFileError) as info:
        read_windcube_sta(path)
    assert info.value.path == str(path)
    assert info.value.line == line
    assert words in info.value.problem


def _lines(edit_line):
    def edit(text):
        lines = text.split("\n")
        edit_line(lines)
        return "\n".join(lines)

    return edit


def test_empty(tmp_path):
    (tmp_path / "e.sta").write_bytes(b"\n")
    _expect(tmp_path / "e.sta", None, "empty")


def test_other_format(real_data):
    _expect(real_data / "zephir/Wind10_317@Y2016_M12_D13.ZPH.csv", 1, "HeaderSize")


def test_wrong_header_length(tmp_path, real_data):
    def edit(lines):
        lines[0] = "HeaderSize=38"

    _expect(_damaged(tmp_path, real_data, V1, _lines(edit)), 40, "expected the column header")


def test_wrong_separator(tmp_path, real_data):
    path = _damaged(tmp_path, real_data, V1, lambda t: t.replace("\t", ";"))
    _expect(path, 42, "TAB-separated")


def test_missing_altitude_column(tmp_path, real_data):
    def edit(lines):
        lines[41] = lines[41].replace("98m CNR min (dB)", "98m CNR lowest (dB)")

    _expect(_damaged(tmp_path, real_data, V1, _lines(edit)), 42, "altitude 98 m lacks")


def test_version_3_block_out_of_order(tmp_path, real_data):
    def edit(lines):
        lines[56] = lines[56].replace("Azim3\tum3", "um3\tAzim3")

    _expect(_damaged(tmp_path, real_data, V3, _lines(edit)), 57, "height block 3")


def test_truncated(tmp_path, real_data):
    path = _damaged(tmp_path, real_data, V3, lambda t: t[: len(t) - 500])
    _expect(path, 201, "truncated")


def test_bad_number(tmp_path, real_data):
    def edit(lines):
        lines[99] = lines[99].replace("\t0.", "\t0.x", 1)

    _expect(_damaged(tmp_path, real_data, V1, _lines(edit)), 100, "is not a number")


def test_bad_time(tmp_path, real_data):
    def edit(lines):
        lines[70] = "2016/13/24" + lines[70][10:]

    _expect(_damaged(tmp_path, real_data, V1, _lines(edit)), 71, "is not a date")


@settings(
    max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    ops=mutation_ops(b"\t\n.=0123456789 xN-\xb0m"),
    version=st.sampled_from([V1, V3]),
)
def test_mutated_files_give_a_dataset_or_input_file_error(
    tmp_path_factory, real_data, ops, version
):
    lines = (real_data / version).read_bytes().split(b"\n")
    n = 45 if version == V1 else 60  # header + a few records keeps the test fast
    data = bytearray(b"\n".join(lines[:n]) + b"\n")
    data = mutated(bytes(data), ops)
    path = tmp_path_factory.mktemp("mut") / "m.sta"
    path.write_bytes(bytes(data))
    try:
        ds = read_windcube_sta(path)
    except InputFileError as err:
        assert err.path == str(path) and err.problem
    else:
        assert set(ds.dims) == {"time", "height"}
        assert ds.sizes["height"] >= 1 and ds.sizes["time"] >= 1
        assert np.all(np.diff(ds["time"].values) > np.timedelta64(0, "ns"))


def test_reader_options_are_validated(real_data):
    from cwproc.errors import ConfigError

    with pytest.raises(ConfigError, match=r"\[reader.windcube_sta\]: decimal: unknown"):
        read_windcube_sta(real_data / V1, decimal=",")


# --- WindCube v2/v2.1 generations, missing values, one-minute statistics (issue 32) ---

V21 = "windcube/WLS71460_2022_01_11__21_20_00.sta"
SAMPLE = Path(__file__).resolve().parents[2] / "sample_data"


@pytest.mark.parametrize(
    ("name", "model"),
    [(V1, "WindCube v2"), (V3, "WindCube v1"), (V21, "WindCube v2.1")],
)
def test_model_is_named_from_the_header_generation_and_software(real_data, name, model):
    """HeaderLength/short names = v1 (Lidaco's Windcubev1), HeaderSize = v2, WF 2.x = v2.1."""
    ds = read_windcube_sta(real_data / name)
    assert ds.attrs["instrument_model"] == model
    assert ds.attrs["instrument"].startswith(f"Leosphere {model} (software ")


def test_wf_2_file_with_scan_angle_na_reads(real_data):
    """ScanAngle (°)=NA is a missing attribute; every wind of this day is NaN in the file."""
    ds = read_windcube_sta(real_data / V21)
    assert ds.sizes == {"time": 3, "height": 9}
    np.testing.assert_array_equal(ds["height"], [40, 60, 80, 100, 120, 140, 160, 180, 200])
    assert "scan_angle_deg" not in ds.attrs
    assert "ScanAngle (°)" in ds.attrs["header_items_not_reported"]
    assert ds["time"].values[0] == np.datetime64("2022-01-11T21:20")
    assert bool(np.isnan(ds["wind_speed"]).all())
    # line 43, 40 m: CNR -32.31, CNR min -97.92, availability 0.00
    assert ds["cnr"].isel(time=0).sel(height=40.0) == pytest.approx(-32.31)
    assert ds["data_availability"].isel(time=0).sel(height=40.0) == 0.0


def test_na_header_value_with_a_good_file_body_reads_and_retrieves(tmp_path, real_data):
    """The v1.1.13 day with only its ScanAngle set to NA gives the same winds."""
    text = (real_data / V1).read_bytes().decode("latin-1")
    assert "ScanAngle (°)=28.000" in text
    path = tmp_path / "na.sta"
    path.write_bytes(text.replace("ScanAngle (°)=28.000", "ScanAngle (°)=NA").encode("latin-1"))
    ds, ref = read_windcube_sta(path), read_windcube_sta(real_data / V1)
    assert "scan_angle_deg" not in ds.attrs
    np.testing.assert_array_equal(ds["wind_speed"].values, ref["wind_speed"].values)
    from cwproc.stages.wind_records import wind_record_product

    product = wind_record_product(ds)
    assert np.isfinite(product["u"].values).sum() == np.isfinite(ref["wind_speed"].values).sum()


@pytest.mark.parametrize("token", ["NA", "-", "", "nan"])
def test_missing_value_tokens_in_the_body_are_missing(tmp_path, real_data, token):
    def edit(lines):
        fields = lines[42].split("\t")
        fields[7] = token  # 40m Wind Speed (m/s) of the first record
        lines[42] = "\t".join(fields)

    ref = read_windcube_sta(real_data / V1)
    ds = read_windcube_sta(_damaged(tmp_path, real_data, V1, _lines(edit)))
    assert np.isnan(ds["wind_speed"].isel(time=0).sel(height=40.0))
    assert ds.attrs["n_missing"] == ref.attrs["n_missing"] + 1


def test_samples_of_every_generation(tmp_path):
    """The shipped samples: v1 (3.x), v2 (1.x), v2.1 with NA and gaps, one-minute .stdsta."""
    folder = SAMPLE / "windcube"
    models = {
        "WLS7-099_2024_06_01__00_00_00.sta": ("WindCube v1", 600.0),
        "WLS7-999_2024_06_01__00_00_00.sta": ("WindCube v2", 600.0),
        "WLS71999_2024_06_01__00_00_00.sta": ("WindCube v2.1", 600.0),
        "WLS71999_2024_06_01__06_00_00.stdsta": ("WindCube v2.1", 60.0),
    }
    for name, (model, interval) in models.items():
        ds = read_windcube_sta(folder / name)
        assert ds.attrs["instrument_model"] == model, name
        assert ds.attrs["averaging_interval_s"] == interval, name
    gaps = read_windcube_sta(folder / "WLS71999_2024_06_01__00_00_00.sta")
    text = (folder / "WLS71999_2024_06_01__00_00_00.sta").read_bytes().decode("latin-1")
    body = [f for line in text.split("\n")[17:] for f in line.split("\t")]
    # the gaps are written NA, - and nothing (besides the empty column ending each block)
    assert "NA" in body and "-" in body
    assert gaps.attrs["n_missing"] > 0
    assert "scan_angle_deg" not in gaps.attrs
