"""Halo Stream Line .hpl reader and writer against the real files of real_data/hpl.

Expected numbers are copied from the file text (line numbers in the comments).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cwproc.errors import ConfigError, CwprocError, InputFileError
from cwproc.io import Format, detect_format
from cwproc.io.halo import decimal_hours_to_time, read_hpl, write_hpl


def hours_to_time(day: str, hours: float) -> np.datetime64:
    """Decimal hours of a ray line -> the UTC time the reader must return (to 1 us)."""
    micro = round(hours * 3600e6)
    return np.datetime64(day, "us") + np.timedelta64(micro, "us")


@pytest.fixture(scope="module")
def hpl(real_data: Path) -> Path:
    return real_data / "hpl"


# name, rays, gates, gate length, ray fields, gate fields,
# (first ray line), (first gate line values), (last gate line values)
REAL = {
    "eriswil-2022-12-14-Stare_91_20221214_11.hpl": dict(
        rays=2,
        gates=250,
        gate_m=48.0,
        pitch=True,
        sw=False,
        system="91",
        scan_type="Stare",
        day="2022-12-14",
        hours=(11.00499444, 11.00555556),
        az=(0.0, 0.0),
        el=(90.0, 90.0),
        pitch_roll=((-0.01, -0.20), (-0.01, -0.10)),
        # line 19: "  0 2.5990 1.027855  1.569249E-6"
        first_gate=(2.5990, 1.027855, 1.569249e-6, None),
        # last line: "249 16.1290 0.999339 -2.837076E-6 "
        last_gate=(16.1290, 0.999339, -2.837076e-6, None),
        attrs=dict(points_per_gate=16, pulses_per_ray=20000, velocity_resolution_m_s=0.0382),
    ),
    "hyytiala-2023-09-13-Stare_46_20230913_23.hpl": dict(
        rays=1,
        gates=320,
        gate_m=30.0,
        pitch=False,
        sw=False,
        system="46",
        scan_type="Stare",
        day="2023-09-13",
        hours=(23.252589,),
        az=(90.0,),
        el=(90.0,),
        pitch_roll=None,
        # line 19: "  0 13.8562 0.392132 -3.423260E-5"; no newline at the end of the file
        first_gate=(13.8562, 0.392132, -3.423260e-5, None),
        last_gate=(4.4158, 0.999810, -4.997926e-7, None),
        attrs=dict(points_per_gate=10, pulses_per_ray=90000, focus_range_m=2000.0),
    ),
    "soverato-2021-10-01-VAD_194_20210624_170110.hpl": dict(
        rays=2,
        gates=400,
        gate_m=30.0,
        pitch=True,
        sw=True,
        system="194",
        scan_type="VAD",
        day="2021-06-24",
        hours=(17.02071944, 17.02200833),
        az=(0.0, 60.01),
        el=(75.0, 75.0),
        pitch_roll=((-0.11, -0.51), (-0.11, -0.40)),
        # line 19: "  0 -0.5351 1.238768  1.344642E-5 0.0764 "
        first_gate=(-0.5351, 1.238768, 1.344642e-5, 0.0764),
        last_gate=(-0.8408, 0.999776, -9.631837e-7, 6.1917),
        attrs=dict(
            points_per_gate=20,
            velocity_resolution_m_s=0.0764,
            instrument_spectral_width_m_s=5.656623,
            header_rays_in_file=6,
        ),
    ),
    "warsaw-2022-12-13-Stare_213_20221213_04.hpl": dict(
        # spectral width present although the header's "Data line 2" does not announce it
        rays=2,
        gates=333,
        gate_m=30.0,
        pitch=True,
        sw=True,
        system="213",
        scan_type="Stare",
        day="2022-12-13",
        hours=(4.00648333, 4.00676389),
        # ray 1 "359.99  90.01": over the zenith -> azimuth 179.99, elevation 89.99
        az=(179.99, 0.0),
        el=(89.99, 90.0),
        pitch_roll=((-0.01, -0.40), (-0.01, -0.40)),
        first_gate=(-0.1147, 1.155508, 8.757579e-6, 0.0382),
        last_gate=(-7.2619, 0.992448, -2.164376e-5, 5.3891),
        attrs=dict(instrument_spectral_width_m_s=7.796967),
    ),
}


@pytest.mark.parametrize("name", sorted(REAL))
def test_real_file_shape_times_angles_values(hpl: Path, name: str) -> None:
    exp = REAL[name]
    ds = read_hpl(hpl / name)
    assert ds.sizes == {"ray": exp["rays"], "range": exp["gates"]}
    # range: (gate + 0.5) * gate length, exact
    np.testing.assert_array_equal(
        ds["range"].values, (np.arange(exp["gates"]) + 0.5) * exp["gate_m"]
    )
    expected_time = np.array([hours_to_time(exp["day"], h) for h in exp["hours"]])
    assert np.array_equal(ds["time"].values, expected_time.astype("datetime64[ns]"))
    assert ds["time"].dtype == np.dtype("datetime64[ns]")
    np.testing.assert_allclose(ds["azimuth"].values, exp["az"], atol=1e-9)
    np.testing.assert_allclose(ds["elevation"].values, exp["el"], atol=1e-9)
    assert ("pitch" in ds) == exp["pitch"] and ("roll" in ds) == exp["pitch"]
    if exp["pitch_roll"]:
        np.testing.assert_allclose(ds["pitch"].values, [p for p, _ in exp["pitch_roll"]])
        np.testing.assert_allclose(ds["roll"].values, [r for _, r in exp["pitch_roll"]])
    assert ("spectral_width" in ds) == exp["sw"]
    for ray, gate, values in ((0, 0, exp["first_gate"]), (-1, -1, exp["last_gate"])):
        v, intensity, beta, sw = values
        assert ds["radial_velocity"].values[ray, gate] == pytest.approx(v, abs=1e-12)
        # snr = intensity - 1 (to float rounding of the subtraction)
        assert ds["snr"].values[ray, gate] == pytest.approx(intensity - 1.0, abs=1e-12)
        assert ds["beta"].values[ray, gate] == pytest.approx(beta, rel=1e-12)
        if sw is not None:
            assert ds["spectral_width"].values[ray, gate] == pytest.approx(sw, abs=1e-12)
    assert ds.attrs["system_id"] == exp["system"]
    assert ds.attrs["scan_type"] == exp["scan_type"]
    assert ds.attrs["gate_length_m"] == exp["gate_m"]
    assert ds.attrs["instrument_kind"] == "streamline"
    assert ds.attrs["homodyne"] == 0
    assert ds.attrs["source_files"] == [name]
    for key, value in exp["attrs"].items():
        assert ds.attrs[key] == pytest.approx(value)
    assert ds["scan"].dtype == np.int64


def test_stare_rays_are_no_conical_scan(hpl: Path) -> None:
    for name in (
        "eriswil-2022-12-14-Stare_91_20221214_11.hpl",
        "warsaw-2022-12-13-Stare_213_20221213_04.hpl",
    ):
        assert (read_hpl(hpl / name)["scan"].values == -1).all()


def test_vad_file_rays_form_one_scan(hpl: Path) -> None:
    ds = read_hpl(hpl / "soverato-2021-10-01-VAD_194_20210624_170110.hpl")
    # azimuth 360.00 -> 0, then 60.01 at elevation 75: one (partial) rotation
    assert ds["scan"].values.tolist() == [0, 0]


def test_user5_stepped_scan_over_the_zenith(hpl: Path) -> None:
    ds = read_hpl(hpl / "User5_96_20190308_200500.hpl")
    assert ds.sizes == {"ray": 528, "range": 150}  # header says 16 rays: unreliable
    assert ds.attrs["header_rays_in_file"] == 16
    assert "spectral_width" not in ds and "pitch" in ds
    # LF file, 6-decimal hours: first ray "20.084231  39.81  -0.00 -0.20 0.10"
    assert ds["time"].values[0] == hours_to_time("2019-03-08", 20.084231)
    assert ds["time"].values[-1] == hours_to_time("2019-03-08", 20.390572)
    el, az = ds["elevation"].values, ds["azimuth"].values
    assert el[0] == 0.0 and not np.signbit(el[0])  # "-0.00" -> +0
    # ray 13 "320.19 142.47" -> azimuth 140.19, elevation 37.53
    assert az[12] == pytest.approx(140.19, abs=1e-9)
    assert el[12] == pytest.approx(37.53, abs=1e-9)
    # ray 17 "360.00 180.00" -> azimuth 180, elevation 0
    assert az[16] == pytest.approx(180.0, abs=1e-9) and el[16] == pytest.approx(0.0, abs=1e-9)
    # last ray "39.81 180.01" -> azimuth 219.81, elevation -0.01
    assert az[-1] == pytest.approx(219.81, abs=1e-9)
    assert el[-1] == pytest.approx(-0.01, abs=1e-9)
    assert (el <= 90).all() and (az >= 0).all() and (az < 360).all()
    # last gate line of the file: "149 2.9167 1.016713  1.031370E-6"
    assert ds["radial_velocity"].values[-1, -1] == pytest.approx(2.9167)
    # a stepped 24-point trajectory visits at most two azimuths per elevation: no cone
    assert (ds["scan"].values == -1).all()
    assert np.all(np.diff(ds["time"].values) > np.timedelta64(0, "ns"))


def test_corrupt_warsaw_restarting_gate_index_is_rejected_at_its_line(hpl: Path) -> None:
    path = hpl / "CORRUPT_warsaw-2021-10-01-Stare_213_20211001_18.hpl"
    with pytest.raises(InputFileError) as err:
        read_hpl(path)
    # ray line at 18, gates 0..2999 on lines 19..3018, index restarts at 0 on line 3019
    assert err.value.line == 3019
    assert "restarts" in err.value.problem
    assert str(err.value).startswith(f"{path}:3019:")


def test_format_detection_of_every_real_hpl(hpl: Path) -> None:
    for path in sorted(hpl.glob("*.hpl")):
        assert detect_format(path) == Format.HPL


def test_reader_takes_no_options(hpl: Path) -> None:
    with pytest.raises(ConfigError):
        read_hpl(hpl / "eriswil-2022-12-14-Stare_91_20221214_11.hpl", colour="red")


# ------------------------------------------------------------------ line endings


@pytest.mark.parametrize("eol", [b"\n", b"\r", b"\r\n"])
def test_line_end_conversions_give_identical_data(hpl: Path, tmp_path: Path, eol: bytes) -> None:
    src = hpl / "eriswil-2022-12-14-Stare_91_20221214_11.hpl"
    ref = read_hpl(src)
    text = src.read_bytes().replace(b"\r\n", b"\n").replace(b"\n", eol)
    for final in (b"", eol, eol * 3, b"  " + eol):  # with/without final newline, blank tail
        path = tmp_path / "x.hpl"
        path.write_bytes(text.rstrip() + final)
        ds = read_hpl(path)
        for name in ("radial_velocity", "snr", "beta", "time", "azimuth", "pitch"):
            np.testing.assert_array_equal(ds[name].values, ref[name].values)


def test_trailing_spaces_on_some_gate_lines_only(hpl: Path, tmp_path: Path) -> None:
    src = hpl / "eriswil-2022-12-14-Stare_91_20221214_11.hpl"
    lines = src.read_bytes().split(b"\r\n")
    # strip every trailing space, then add two to every other line
    lines = [ln.rstrip() + (b"  " if i % 2 else b"") for i, ln in enumerate(lines)]
    path = tmp_path / "x.hpl"
    path.write_bytes(b"\r\n".join(lines))
    np.testing.assert_array_equal(read_hpl(path)["beta"].values, read_hpl(src)["beta"].values)


# ------------------------------------------------------------------ damaged copies


def _lines(path: Path) -> list[bytes]:
    return path.read_bytes().split(b"\r\n")


def _write(tmp_path: Path, lines: list[bytes], name: str = "damaged.hpl") -> Path:
    path = tmp_path / name
    path.write_bytes(b"\r\n".join(lines))
    return path


@pytest.fixture()
def eriswil(hpl: Path) -> Path:
    return hpl / "eriswil-2022-12-14-Stare_91_20221214_11.hpl"


def _error(path: Path) -> InputFileError:
    with pytest.raises(InputFileError) as err:
        read_hpl(path)
    assert str(err.value).startswith(str(path))
    return err.value


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.hpl"
    path.write_bytes(b"")
    err = _error(path)
    assert err.line == 1 and "empty" in err.problem


def test_file_of_another_format(real_data: Path, tmp_path: Path) -> None:
    path = tmp_path / "toa5.hpl"
    sonic = real_data / "sonic" / "TOA5_6843.ts_Above_2012_06_07_1245.dat"
    path.write_bytes(sonic.read_bytes()[:4000])
    err = _error(path)
    assert err.line == 1 and "Filename:" in err.problem


def test_missing_file(tmp_path: Path) -> None:
    err = _error(tmp_path / "nothing.hpl")
    assert "cannot read" in err.problem


@pytest.mark.parametrize(
    ("line", "text", "needle"),
    [
        (2, b"Sistem ID:\t91", "System ID"),
        (3, b"Number of gates:\t25O", "not a whole number"),
        (3, b"Number of gates:\t0", "out of range"),
        (4, b"Range gate length (m):\tabc", "not a number"),
        (10, b"Start time:\t2022-12-14 11:00:18.99", "not a time"),
        (10, b"Start time:\t20221399 11:00:18.99", "not a time"),
        (12, b"Altitude of measurement = gate * 7", "range formula"),
        (13, b"Data lime 1: Decimal time", "Data line 1"),
        (17, b"### end", "****"),
    ],
)
def test_garbled_header_names_its_line(
    eriswil: Path, tmp_path: Path, line: int, text: bytes, needle: str
) -> None:
    lines = _lines(eriswil)
    lines[line - 1] = text
    err = _error(_write(tmp_path, lines))
    assert err.line == line
    assert needle in err.problem


def test_missing_header_line(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    del lines[6]  # "No. of rays in file:" gone: line 7 is now "Scan type:"
    err = _error(_write(tmp_path, lines))
    assert err.line == 7


def test_header_only(eriswil: Path, tmp_path: Path) -> None:
    err = _error(_write(tmp_path, _lines(eriswil)[:17]))
    assert err.line == 18 and "no data" in err.problem


def test_short_header(eriswil: Path, tmp_path: Path) -> None:
    err = _error(_write(tmp_path, _lines(eriswil)[:9]))
    assert err.line == 9 and "17" in err.problem


def test_truncated_last_ray(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    # keep the second ray line (269) and 100 of its 250 gate lines
    err = _error(_write(tmp_path, lines[: 268 + 1 + 100]))
    assert err.line == 269
    assert "truncated" in err.problem and "100 of 250" in err.problem


def test_truncated_in_the_middle_of_a_line(eriswil: Path, tmp_path: Path) -> None:
    raw = eriswil.read_bytes()
    path = tmp_path / "cut.hpl"
    cut = raw.index(b"\r\n100 ") + len(b"\r\n100 -0.1")  # inside gate 100 of ray 1
    path.write_bytes(raw[:cut])
    err = _error(path)
    assert err.line == 19 + 100
    assert "2 fields" in err.problem


@pytest.mark.parametrize(("gates", "line"), [(251, 269), (249, 268)])
def test_gate_count_not_matching_body(eriswil: Path, tmp_path: Path, gates: int, line: int) -> None:
    lines = _lines(eriswil)
    lines[2] = b"Number of gates:\t%d" % gates
    err = _error(_write(tmp_path, lines))
    # 251: the second ray line (269) comes after only 250 gates;
    # 249: line 268 (gate 249) stands where the second ray line should be
    assert err.line == line


@pytest.mark.parametrize(
    ("line", "text", "needle"),
    [
        (31, b" 12 -0.1911 1.00x513  1.0E-6", "not a number"),
        (31, b" 12 nan 1.005  1.0E-6", "not a number"),
        (31, b" 12 -0.1911 1.005  1.0E-6 NA", "not a number"),
        (31, b" 12 -0.1911 1.005  1.0E-6 #x", "not a number"),
        (31, b" 12 inf 1.005  1.0E-6", "not a number"),
        (31, b" 12 -0.1911 1.005  1.0E-6 7 8", "6 fields"),
        (31, b" 12 -0.1911 1.005", "3 fields"),
        (31, b"", "empty line"),
        (31, b" 13 -0.1911 1.005  1.0E-6", "gate index 13"),
        (18, b"11.00499444   0.00  90.00 -0.01", "ray line has 4 fields"),
        (18, b"11.00499444   0.00  9O.00 -0.01 -0.20", "not a number"),
        (18, b"71.00499444   0.00  90.00 -0.01 -0.20", "decimal time"),
        (18, b"11.00499444   0.00  390.00 -0.01 -0.20", "elevation"),
    ],
)
def test_bad_data_line_names_its_line(
    eriswil: Path, tmp_path: Path, line: int, text: bytes, needle: str
) -> None:
    lines = _lines(eriswil)
    lines[line - 1] = text
    err = _error(_write(tmp_path, lines))
    assert err.line == line
    assert needle in err.problem


def test_deleted_and_duplicated_gate_lines(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    deleted = lines[:30] + lines[31:]  # gate 12 (line 31) removed
    assert _error(_write(tmp_path, deleted, "d.hpl")).line == 31
    duplicated = lines[:31] + lines[30:]  # gate 12 twice: line 32 has index 12 again
    assert _error(_write(tmp_path, duplicated, "u.hpl")).line == 32


def test_missing_ray_line(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    del lines[268]  # the second ray line
    err = _error(_write(tmp_path, lines))
    assert err.line == 269 and "restarts" in err.problem


def test_nul_byte(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    lines[40] = lines[40][:5] + b"\x00" + lines[40][5:]
    assert _error(_write(tmp_path, lines)).line == 41


# ------------------------------------------------------------------ header variants


def test_decimal_commas_in_header(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    lines[3] = b"Range gate length (m):\t48,0"
    lines[9] = b"Start time:\t20221214 11:00:18,99"
    lines[10] = b"Resolution (m/s):\t0,0382"
    lines[16] = b"**** Instrument spectral width = 5,6"
    ds = read_hpl(_write(tmp_path, lines))
    assert ds.attrs["gate_length_m"] == 48.0
    assert ds.attrs["velocity_resolution_m_s"] == pytest.approx(0.0382)
    assert ds.attrs["instrument_spectral_width_m_s"] == pytest.approx(5.6)
    assert ds.attrs["header_start_time"] == "2022-12-14T11:00:18.990Z"


def test_waypoints_key_upper_case_id_and_overlapping_gates(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    lines[1] = b"SYSTEM ID:\t91"
    lines[6] = b"No. of waypoints in file:\t12"
    lines[11] = b"Range of measurement (center of gate) = Gate length / 2 + (range gate x 3)"
    ds = read_hpl(_write(tmp_path, lines))
    assert ds.attrs["header_rays_in_file"] == 12
    # overlapping gates: range = 48 / 2 + 3 * gate
    np.testing.assert_allclose(ds["range"].values[:3], [24.0, 27.0, 30.0])


def test_gate_index_wider_than_i3(eriswil: Path, tmp_path: Path) -> None:
    """1200 gates: indices 1000-1199 are printed 4 characters wide."""
    lines = _lines(eriswil)
    ray1 = lines[17]
    gates = [b"%3d 0.1000 1.010000  1.000000E-6" % g for g in range(1200)]
    path = _write(tmp_path, [*lines[:2], b"Number of gates:\t1200", *lines[3:17], ray1, *gates])
    ds = read_hpl(path)
    assert ds.sizes == {"ray": 1, "range": 1200}
    assert ds["range"].values[-1] == pytest.approx(1199.5 * 48)


# ------------------------------------------------------------------ time and angles


def test_midnight_wrap_to_zero_is_monotonic(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    lines[9] = b"Start time:\t20221214 23:59:58.00"
    lines[17] = b"23.99944444   0.00  90.00 -0.01 -0.20"  # 23:59:58
    lines[268] = b"0.00055556   0.00  90.00 -0.01 -0.10"  # 00:00:02.000016 next day
    ds = read_hpl(_write(tmp_path, lines))
    t = ds["time"].values
    assert t[0] == hours_to_time("2022-12-14", 23.99944444)
    assert t[1] == hours_to_time("2022-12-15", 0.00055556)
    assert t[1] > t[0]


def test_midnight_hours_above_24(eriswil: Path, tmp_path: Path) -> None:
    lines = _lines(eriswil)
    lines[9] = b"Start time:\t20221214 23:59:58.00"
    lines[17] = b"23.99944444   0.00  90.00 -0.01 -0.20"
    lines[268] = b"24.00055556   0.00  90.00 -0.01 -0.10"
    t = read_hpl(_write(tmp_path, lines))["time"].values
    assert t[1] == hours_to_time("2022-12-15", 0.00055556)


def test_file_starting_after_midnight_of_its_start_time() -> None:
    start = np.datetime64("2022-12-14T23:59:59.50", "us")
    t = decimal_hours_to_time(np.array([0.001, 0.002]), start)
    assert t[0] == hours_to_time("2022-12-15", 0.001)


# ------------------------------------------------------------------ writer


@pytest.mark.parametrize("name", [*sorted(REAL), "User5_96_20190308_200500.hpl"])
def test_write_read_round_trip(hpl: Path, tmp_path: Path, name: str) -> None:
    ds = read_hpl(hpl / name)
    out = write_hpl(ds, tmp_path / "rt.hpl")
    raw = out.read_bytes()
    assert raw.count(b"\r\n") == raw.count(b"\n")  # CRLF throughout
    assert raw.split(b"\r\n")[16].startswith(b"****")  # 17 header lines
    back = read_hpl(out)
    assert back.sizes == ds.sizes
    for var in ds.data_vars:
        np.testing.assert_allclose(back[var].values, ds[var].values, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(back["azimuth"].values, ds["azimuth"].values, atol=1e-9)
    np.testing.assert_allclose(back["elevation"].values, ds["elevation"].values, atol=1e-9)
    # 8-decimal hours: 1e-8 h = 36 us
    dt = np.abs((back["time"].values - ds["time"].values) / np.timedelta64(1, "us"))
    assert dt.max() <= 18
    np.testing.assert_array_equal(back["scan"].values, ds["scan"].values)
    for key in (
        "system_id",
        "gate_length_m",
        "points_per_gate",
        "pulses_per_ray",
        "focus_range_m",
        "velocity_resolution_m_s",
    ):
        assert back.attrs[key] == ds.attrs[key]


def test_written_lines_have_the_instrument_layout(hpl: Path, tmp_path: Path) -> None:
    src = hpl / "soverato-2021-10-01-VAD_194_20210624_170110.hpl"
    lines = write_hpl(read_hpl(src), tmp_path / "VAD.hpl").read_bytes().split(b"\r\n")
    original = src.read_bytes().split(b"\r\n")
    # the numbers of ray and gate lines are written exactly as the instrument wrote them
    # (azimuth 360.00 comes back as its normalised form 0.00)
    assert lines[17] == b"17.02071944   0.00  75.00 -0.11 -0.51"
    assert lines[18] == original[18]  # "  0 -0.5351 1.238768  1.344642E-5 0.0764 "
    assert lines[19] == original[19]
    assert lines[418] == original[418]  # the second ray line " 60.01"
    # System ID .. Pulses/ray, Scan type, Focus range, Resolution as in the original
    # (line 7 "No. of rays in file" now counts the rays actually written: 2, not 6)
    assert lines[1:6] == original[1:6]
    assert lines[7:9] == original[7:9] and lines[10] == original[10]
    assert lines[6] == b"No. of rays in file:\t2"
    assert lines[16] == original[16]  # "**** Instrument spectral width = 5.656623"


def test_writer_refuses_what_the_format_cannot_hold(hpl: Path, tmp_path: Path) -> None:
    ds = read_hpl(hpl / "soverato-2021-10-01-VAD_194_20210624_170110.hpl")
    bad = ds.copy(deep=True)
    bad["radial_velocity"][0, 3] = np.nan
    with pytest.raises(CwprocError, match="radial_velocity has non-finite"):
        write_hpl(bad, tmp_path / "nan.hpl")
    shifted = ds.assign_coords(range=ds["range"] + 7.0)
    with pytest.raises(CwprocError, match="range"):
        write_hpl(shifted, tmp_path / "grid.hpl")
    with pytest.raises(CwprocError, match="no rays"):
        write_hpl(ds.isel(ray=slice(0, 0)), tmp_path / "empty.hpl")
    assert not any(tmp_path.iterdir())


def test_parallel_chunked_parse_equals_single_and_keeps_line_numbers(
    hpl: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import cwproc.io.halo_body as halo_body

    src = hpl / "User5_96_20190308_200500.hpl"
    single = read_hpl(src)
    monkeypatch.setattr(halo_body, "_PARALLEL_BYTES", 200_000)  # 2.7 MB -> one chunk per core
    chunked = read_hpl(src)
    for name in single.variables:
        np.testing.assert_array_equal(chunked[name].values, single[name].values)
    lines = src.read_bytes().split(b"\n")
    lines[70000] += b" 7 8"  # a gate line deep in the second half gets 6 fields
    err = _error(_write(tmp_path, lines))
    assert err.line == 70001 and "6 fields" in err.problem


@pytest.mark.parametrize("value", [b"1e308", b"inf", b"0", b"-30.0", b"5000"])
def test_impossible_gate_length_names_line_4(tmp_path, value):
    """A gate length of 1e308 gave infinite heights with exit 0 (issue 17.3)."""
    sample = Path(__file__).resolve().parents[2] / "sample_data/streamline"
    raw = next(sample.glob("*.hpl")).read_bytes()
    bad = tmp_path / "bad.hpl"
    bad.write_bytes(
        raw.replace(b"Range gate length (m):\t30.0", b"Range gate length (m):\t" + value)
    )
    with pytest.raises(InputFileError, match="Range gate length") as err:
        read_hpl(bad)
    assert ":4:" in str(err.value)


def test_write_hpl_does_not_follow_a_planted_symlink(tmp_path):
    """The temporary name is unpredictable and created exclusively (issue 17.6)."""
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    target = tmp_path / "out.hpl"
    (tmp_path / ".out.hpl.tmp").symlink_to(victim)
    ds = read_hpl(
        next((Path(__file__).resolve().parents[2] / "sample_data/streamline").glob("*.hpl"))
    )
    write_hpl(ds, target)
    assert victim.read_text() == "keep me"
    assert read_hpl(target).sizes == ds.sizes


@pytest.mark.parametrize("constant", [False, True])
def test_writer_gate_lines_are_each_field_formatted_as_the_format_line_says(
    constant: bool,
) -> None:
    # the block formatter (one % per file, constant columns written into the format)
    # must give what formatting every field on its own gives: i3 f.4 f.6 e12 [f.4]
    import xarray as xr

    from cwproc.io.halo import hpl_text

    rng = np.random.default_rng(7)
    n_rays, n_gates = 5, 12
    shape = (n_rays, n_gates)
    vel = rng.normal(0, 8, shape)
    snr = np.full(shape, 0.05) if constant else rng.uniform(-0.01, 3, shape)
    beta = np.full(shape, 1e-6) if constant else 10 ** rng.uniform(-8, -3, shape)
    width = rng.uniform(0, 2, shape)
    t0 = np.datetime64("2024-01-01T00:00:00", "ns")
    ds = xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), vel),
            "snr": (("ray", "range"), snr),
            "beta": (("ray", "range"), beta),
            "spectral_width": (("ray", "range"), width),
        },
        coords={
            "time": ("ray", t0 + np.arange(n_rays) * np.timedelta64(1, "s")),
            "azimuth": ("ray", np.arange(n_rays) * 2.0),
            "elevation": ("ray", np.full(n_rays, 35.3)),
            "range": ("range", (np.arange(n_gates) + 0.5) * 30.0),
        },
        attrs={"gate_length_m": 30.0},
    )
    lines = hpl_text(ds, "x.hpl").split("\r\n")
    body = lines[lines.index("****") + 1 : -1]
    assert len(body) == n_rays * (n_gates + 1)
    for r in range(n_rays):
        for g in range(n_gates):
            e = f"{beta[r, g]:.6E}".replace("E+0", "E").replace("E+", "E").replace("E-0", "E-")
            want = f"{g:3d} {vel[r, g]:.4f} {snr[r, g] + 1:.6f} {e:>12s} {width[r, g]:.4f} "
            assert body[r * (n_gates + 1) + 1 + g] == want
