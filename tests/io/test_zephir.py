"""ZephIR Waltz CSV reader: the real 10-min export, a constructed 1-s export, damaged files."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from cwproc.errors import InputFileError
from cwproc.io.zephir import HEIGHT_COLUMNS, read_zephir_csv

sys.path.insert(0, str(Path(__file__).resolve().parent))
from byte_mutations import mutated, mutation_ops

REAL = "zephir/Wind10_317@Y2016_M12_D13.ZPH.csv"


@pytest.fixture(scope="module")
def real(real_data):
    return read_zephir_csv(real_data / REAL)


def test_real_file_heights_times_and_attrs(real):
    np.testing.assert_array_equal(real["height"], [37, 38, 57, 77, 117, 137, 157, 197, 247, 297])
    assert real.sizes == {"time": 288, "height": 10}
    # "13.12.2016 00:00:00" with "Time sync: UTC +1,0 hrs" -> 2016-12-12 23:00 UTC
    assert real["time"].values[0] == np.datetime64("2016-12-12T23:00:00")
    assert real["time"].values[-1] == np.datetime64("2016-12-14T22:50:00")
    a = real.attrs
    assert a["utc_offset_applied_h"] == 1.0
    assert a["time_stamp_position"] == "start"
    assert a["averaging_interval_s"] == 600.0
    assert a["system_id"] == "317"
    assert a["reference_height_m"] == 38.0
    assert a["window_height_m"] == 3.0
    assert a["instrument_kind"] == "cw" and a["homodyne"] == 1
    # counted from the text: 509 "9999", 3054 "9999,000" (3563) and 250 "9998,000"
    assert a["n_missing_9999"] == 3563
    assert a["n_missing_9998"] == 250


def test_real_file_values_match_the_text(real):
    # line 3: ...;0;36;19,162;5,039;4,109;5,909;0,444;-0,165;0,09593122;... (297 m)
    first = real.isel(time=0).sel(height=297.0)
    assert first["packets"] == 36
    assert first["wind_direction"] == pytest.approx(19.162)
    assert first["wind_speed"] == pytest.approx(5.039)
    assert first["wind_speed_min"] == pytest.approx(4.109)
    assert first["wind_speed_max"] == pytest.approx(5.909)
    assert first["wind_speed_std"] == pytest.approx(0.444)
    assert first["w"] == pytest.approx(-0.165)
    assert first["turbulence_intensity"] == pytest.approx(0.09593122)
    # 37 m is the last group of line 3: 35;350,313;2,458;1,975;2,863;0,232;-0,005;0,09403165
    low = real.isel(time=0).sel(height=37.0)
    assert low["wind_direction"] == pytest.approx(350.313)
    assert low["wind_speed"] == pytest.approx(2.458)
    # met columns of line 3: 11,767 V; 311,066 deg; tilt 1; 2,950 C; 992,800 mbar; 0,000 %;
    # 1,778 m/s; 159,542 deg; rain 0; GPS "51,31546 9,16535"
    rec = real.isel(time=0)
    assert rec["battery_voltage"] == pytest.approx(11.767)
    assert rec["bearing"] == pytest.approx(311.066)
    assert rec["tilt"] == 1.0
    assert rec["air_temperature"] == pytest.approx(2.95)
    assert rec["air_pressure"] == pytest.approx(992.8)
    assert rec["relative_humidity"] == 0.0
    assert rec["met_wind_speed"] == pytest.approx(1.778)
    assert rec["met_wind_direction"] == pytest.approx(159.542)
    assert rec["rain_percent"] == 0.0
    assert rec["latitude"] == pytest.approx(51.31546)
    assert rec["longitude"] == pytest.approx(9.16535)
    assert str(rec["info_flags"].values) == "I-net Shutter-Open"
    # line 15 (02:00 local): 117 m reads 36;9999,000;...;9999 -> NaN, packets kept
    r15 = real.sel(time=np.datetime64("2016-12-13T01:00:00"), height=117.0)
    assert r15["packets"] == 36
    assert np.isnan(r15["wind_speed"]) and np.isnan(r15["turbulence_intensity"])
    # line 89 (14:20 local): vertical speed 9998,000 at 297 m, horizontal 6,103
    r89 = real.sel(time=np.datetime64("2016-12-13T13:20:00"), height=297.0)
    assert np.isnan(r89["w"]) and r89["wind_speed"] == pytest.approx(6.103)
    assert real.sel(time=np.datetime64("2016-12-13T13:20:00"))["rain_percent"] == 2.0
    # last line: 14.12.2016 23:50:00; 297 m: 35;151,378;6,271
    last = real.isel(time=-1).sel(height=297.0)
    assert last["wind_direction"] == pytest.approx(151.378)
    assert last["wind_speed"] == pytest.approx(6.271)


# ------------------------------------------------------------------------- constructed files

HEIGHTS_1S = (100, 80, 40)  # highest first, as the instrument writes them


def _line1(sync: str = "Time sync: UTC +2,0 hrs") -> str:
    return (
        "CSV Converter: v1,114;Unit: 999;"
        + sync
        + ";Time stamps indicate the end of the averaging period;40m is a fixed reference "
        "measurement;ZephIR window height above ground: 1,5m;Measurement heights: 100m 80m 40m"
    )


def _header() -> list[str]:
    cols = [
        "Reference",
        "Time and Date",
        "Timestamp (s)",
        "Info. Flags",
        "Status Flags",
        "Battery (V)",
        "GPS",
        "Tilt (deg)",
        "Air Temp. (C)",
        "Pressure (mbar)",
        "Humidity (%)",
        "Raining",
        "Packets in Average at MET",
    ]
    for h in HEIGHTS_1S:
        cols += [f"{p} at {h}m" for p in HEIGHT_COLUMNS]
    return [*cols, "Checksum:XYZ~blob"]


def _record(i: int, speed: float) -> list[str]:
    values = [
        str(1000 + i),
        f"01.06.2020 12:00:{i:02d}",
        str(660_000_000 + i),
        "I-net",
        "Modem",
        "12,100",
        "55,5 12,25",
        "0",
        "15,250",
        "1013,000",
        "70,000",
        "1" if i == 2 else "0",
        "1",
    ]
    for j, _h in enumerate(HEIGHTS_1S):
        s = speed - j
        group = ["1", "270,000", f"{s:.3f}", f"{s:.3f}", f"{s:.3f}", "0,000", "0,100", "0"]
        if i == 1 and j == 2:
            group[2] = "9999,000"
        values += [v.replace(".", ",") for v in group]
    return [*values, "q`5>N>?"]


def build_1s_file(path: Path, n: int = 4, sync: str = "Time sync: UTC +2,0 hrs") -> Path:
    """A 1-s export laid out as FORMATS.md §2.2 describes it."""
    lines = [_line1(sync), ";".join(_header())]
    lines += [";".join(_record(i, 8.0 + i)) for i in range(n)]
    path.write_text("\n".join(lines) + "\n", encoding="latin-1")
    return path


def test_constructed_1s_file(tmp_path):
    ds = read_zephir_csv(build_1s_file(tmp_path / "Wind_999@Y2020_M06_D01.ZPH.csv"))
    assert ds.attrs["file_variant"] == "1s"
    assert ds.attrs["averaging_interval_s"] == 1.0
    assert ds.attrs["time_stamp_position"] == "end"
    assert ds.attrs["utc_offset_applied_h"] == 2.0
    assert ds.attrs["window_height_m"] == 1.5
    np.testing.assert_array_equal(ds["height"], [40, 80, 100])
    assert ds["time"].values[0] == np.datetime64("2020-06-01T10:00:00")
    np.testing.assert_allclose(ds["wind_speed"].sel(height=100.0), [8, 9, 10, 11])
    np.testing.assert_allclose(ds["wind_speed"].sel(height=80.0), [7, 8, 9, 10])
    assert np.isnan(ds["wind_speed"].sel(height=40.0).values[1])
    np.testing.assert_array_equal(ds["raining"], [0, 0, 1, 0])
    np.testing.assert_array_equal(ds["met_packets"], [1, 1, 1, 1])
    assert ds.attrs["n_missing_9999"] == 1


def test_missing_time_sync_assumes_utc_and_says_so(tmp_path):
    path = build_1s_file(tmp_path / "Wind_x.ZPH.csv", sync="Filter: v1,026")
    ds = read_zephir_csv(path)
    assert ds.attrs["time_sync"] == "absent"
    assert ds["time"].values[0] == np.datetime64("2020-06-01T12:00:00")
    ds = read_zephir_csv(path, utc_offset_hours=-3.0)
    assert ds["time"].values[0] == np.datetime64("2020-06-01T15:00:00")


# ------------------------------------------------------------------------- damaged files


def _damage(tmp_path: Path, real_data: Path, edit) -> Path:
    text = (real_data / REAL).read_text(encoding="latin-1")
    out = tmp_path / "damaged.ZPH.csv"
    out.write_text(edit(text), encoding="latin-1")
    return out


def _expect(path: Path, line: int | None, words: str) -> None:
    with pytest.raises(InputFileError) as info:
        read_zephir_csv(path)
    err = info.value
    assert err.path == str(path)
    assert err.line == line
    assert words in err.problem


def test_empty_file(tmp_path):
    (tmp_path / "e.csv").write_bytes(b"")
    _expect(tmp_path / "e.csv", None, "empty")


def test_other_format(tmp_path, real_data):
    path = real_data / "windcube/WLS7-164_2016_11_24__00_00_00.sta"
    _expect(path, 1, "not ZephIR metadata")


def test_wrong_separator(tmp_path, real_data):
    def edit(text):
        head, rest = text.split("\n", 1)
        return head + "\n" + rest.replace(";", "\t")

    _expect(_damage(tmp_path, real_data, edit), 2, "separator")


def test_missing_height_group_column(tmp_path, real_data):
    def edit(text):
        lines = text.split("\n")
        lines[1] = lines[1].replace("TI at 157m", "Turbulence at 157m")
        return "\n".join(lines)

    _expect(_damage(tmp_path, real_data, edit), 2, "height 157 m lacks the column(s) TI")


def _cut_last_record(text: str, keep: int) -> str:
    start = text.rstrip("\n").rfind("\n") + 1
    return text[: start + keep]


def test_truncated_file_in_the_numbers(tmp_path, real_data):
    path = _damage(tmp_path, real_data, lambda t: _cut_last_record(t, 300))
    _expect(path, 290, "truncated")


def test_truncated_file_in_the_checksum_blob(tmp_path, real_data):
    path = _damage(tmp_path, real_data, lambda t: t[:-40])
    _expect(path, 290, "no end of line")


def test_bad_number(tmp_path, real_data):
    def edit(text):
        lines = text.split("\n")
        lines[9] = lines[9].replace(";11,", ";1x1,", 1)
        return "\n".join(lines)

    _expect(_damage(tmp_path, real_data, edit), 10, "is not a number")


def test_bad_time(tmp_path, real_data):
    def edit(text):
        lines = text.split("\n")
        lines[20] = lines[20].replace(".12.2016", ".13.2016", 1)
        return "\n".join(lines)

    _expect(_damage(tmp_path, real_data, edit), 21, "is not dd.mm.yyyy")


def test_header_only(tmp_path, real_data):
    path = _damage(tmp_path, real_data, lambda t: "\n".join(t.split("\n")[:2]) + "\n")
    _expect(path, 2, "no data records")


# ------------------------------------------------------------------------- mutations

_BASE = None


def _base_bytes(tmp_path_factory) -> bytes:
    global _BASE
    if _BASE is None:
        path = build_1s_file(tmp_path_factory.mktemp("zbase") / "Wind_1.ZPH.csv", n=6)
        _BASE = path.read_bytes()
    return _BASE


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(ops=mutation_ops(b";,.:0123456789 \nx-9\t\xb0"))
def test_mutated_files_give_a_dataset_or_input_file_error(tmp_path_factory, ops):
    data = bytearray(_base_bytes(tmp_path_factory))
    data = mutated(bytes(data), ops)
    path = tmp_path_factory.mktemp("mut") / "Wind_m.ZPH.csv"
    path.write_bytes(bytes(data))
    try:
        ds = read_zephir_csv(path)
    except InputFileError as err:
        assert err.path == str(path) and err.problem
    else:
        assert set(ds.dims) == {"time", "height"}
        assert ds.sizes["height"] >= 1 and ds.sizes["time"] >= 1
        assert np.all(np.diff(ds["time"].values) > np.timedelta64(0, "ns"))


def test_reader_options_are_validated(tmp_path):
    from cwproc.errors import ConfigError

    path = build_1s_file(tmp_path / "Wind_o.ZPH.csv")
    with pytest.raises(ConfigError, match=r"\[reader.zephir_csv\]: separator: unknown"):
        read_zephir_csv(path, separator=",")
    with pytest.raises(ConfigError, match="utc_offset_hours: must be a number"):
        read_zephir_csv(path, utc_offset_hours="+1")
    with pytest.raises(ConfigError, match=r"in \[-14, 14\]"):
        read_zephir_csv(path, utc_offset_hours=30)


@pytest.mark.parametrize("line_end", [b"\r", b"\r\n"])
def test_any_line_ends_read_the_same(tmp_path, real_data, real, line_end):
    """CR-only (classic Mac) and CRLF exports read as the LF original, not 'truncated'."""
    raw = (real_data / REAL).read_bytes()
    assert b"\r" not in raw
    path = tmp_path / "Wind10_317@Y2016_M12_D13.ZPH.csv"
    path.write_bytes(raw.replace(b"\n", line_end))
    ds = read_zephir_csv(path)
    np.testing.assert_array_equal(ds["wind_speed"].values, real["wind_speed"].values)
    np.testing.assert_array_equal(ds["time"].values, real["time"].values)


def test_one_second_sample_with_cr_line_ends():
    sample = Path(__file__).resolve().parents[2] / "sample_data" / "zephir"
    path = sample / "Wind_999@Y2024_M06_D01.ZPH.csv"
    raw = path.read_bytes()
    assert b"\r" in raw and b"\n" not in raw
    ds = read_zephir_csv(path)
    assert ds.attrs["file_variant"] == "1s" and ds.attrs["averaging_interval_s"] == 1.0
    assert {"raining", "met_packets"} <= set(ds.data_vars)
    assert ds.sizes["time"] == 36
