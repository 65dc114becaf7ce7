"""Stage zephir: wind product of wind records, volume-averaging correction, TP."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.physics.volume_averaging import std_ratio_and_tp_share
from cwproc.stages.wind_records import (
    FLAG_MISSING,
    FLAG_RAIN,
    FLAG_TOO_FEW_PACKETS,
    predicted_std_ratio,
    turbulence_parameter,
    wind_record_product,
)

KW = {"min_packets": 24, "max_rain_percent": 50.0, "z_r_coefficient": 0.0013}


def _record(kind: str = "cw") -> xr.Dataset:
    times = pd.date_range("2020-01-01", periods=4, freq="10min").to_numpy()
    heights = np.array([43.0, 103.0])
    speed = np.array([[10.0, 12.0], [5.0, 6.0], [8.0, np.nan], [4.0, 4.5]])
    direction = np.array([[270.0, 270.0], [180.0, 180.0], [90.0, 90.0], [0.0, 45.0]])
    ds = xr.Dataset(
        {
            "wind_speed": (("time", "height"), speed),
            "wind_direction": (("time", "height"), direction),
            "w": (("time", "height"), np.zeros_like(speed)),
            "wind_speed_std": (("time", "height"), 0.1 * speed),
            "turbulence_intensity": (("time", "height"), np.full_like(speed, 0.1)),
            "packets": (("time", "height"), np.array([[35, 35], [10, 35], [35, 0], [35, 35]])),
            "rain_percent": (("time",), np.array([0.0, 0.0, 0.0, 80.0])),
        },
        coords={"time": times, "height": heights},
        attrs={
            "instrument_kind": kind,
            "averaging_interval_s": 600.0,
            "window_height_m": 3.0,
            "time_stamp_position": "start",
        },
    )
    return ds


def test_u_v_from_speed_and_direction():
    """Wind from 270 deg (west) blows east: u = +U, v = 0; from 180: v = +U; from 90: u = -U."""
    p = wind_record_product(_record(), **KW)
    np.testing.assert_allclose(p["u"].values[0], [10.0, 12.0], atol=1e-12)
    np.testing.assert_allclose(p["v"].values[0], [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(p["v"].values[1], [5.0, 6.0], atol=1e-12)
    np.testing.assert_allclose(p["u"].values[2, 0], -8.0, atol=1e-12)
    speed = np.hypot(p["u"], p["v"])
    np.testing.assert_allclose(speed, p["wind_speed"], rtol=1e-12)


def test_qc_flags():
    flag = wind_record_product(_record(), **KW)["qc_flag"].values
    assert flag[0].tolist() == [0, 0]
    assert flag[1, 0] == FLAG_TOO_FEW_PACKETS and flag[1, 1] == 0
    assert flag[2, 1] == FLAG_TOO_FEW_PACKETS | FLAG_MISSING
    assert flag[3].tolist() == [FLAG_RAIN, FLAG_RAIN]
    # flagged values are kept, not dropped
    assert wind_record_product(_record(), **KW)["wind_speed"].values[1, 0] == 5.0


def test_corrected_ti_is_measured_ti_over_the_model_ratio():
    """TI_corrected = TI / (sigma_lidar/sigma_cup) at h above the window (40 m, 100 m)."""
    p = wind_record_product(_record(), **KW)
    ratio, _ = std_ratio_and_tp_share(40.0, 10.0, 1.0, z_r_coefficient=0.0013)
    assert p["volume_averaging_ratio"].values[0, 0] == pytest.approx(ratio, rel=2e-3)
    ratio100, _ = std_ratio_and_tp_share(100.0, 12.0, 1.0, z_r_coefficient=0.0013)
    assert p["volume_averaging_ratio"].values[0, 1] == pytest.approx(ratio100, rel=2e-3)
    np.testing.assert_allclose(
        p["turbulence_intensity_corrected"], 0.1 / p["volume_averaging_ratio"], rtol=1e-12
    )
    # the correction raises TI (ratio < 1), more at the upper height
    assert np.all(p["turbulence_intensity_corrected"].values[:, 0] > 0.1)
    assert np.isnan(p["volume_averaging_ratio"].values[2, 1])  # missing speed


def test_three_second_scans_predict_a_lower_ratio():
    r1 = predicted_std_ratio(
        np.array([60.0]), np.array([8.0]), scan_time_s=1.0, z_r_coefficient=0.0013
    )
    r3 = predicted_std_ratio(
        np.array([60.0]), np.array([8.0]), scan_time_s=3.0, z_r_coefficient=0.0013
    )
    assert r3[0] < r1[0]


def test_interpolated_ratio_matches_direct_computation():
    h = np.array([50.0, 50.0, 120.0])
    u = np.array([3.3, 17.0, 7.7])
    got = predicted_std_ratio(h, u, scan_time_s=3.0, z_r_coefficient=0.0013)
    want = [std_ratio_and_tp_share(a, b, 3.0)[0] for a, b in zip(h, u, strict=True)]
    np.testing.assert_allclose(got, want, rtol=2e-3)


def test_pulsed_records_get_no_cw_correction():
    rec = _record(kind="pulsed").drop_vars("turbulence_intensity")
    p = wind_record_product(rec, **KW)
    assert np.all(np.isnan(p["turbulence_intensity_corrected"]))
    np.testing.assert_allclose(p["turbulence_intensity"].values[0], [0.1, 0.1])
    assert "not applicable" in p["volume_averaging_ratio"].attrs["method"]


def test_not_a_wind_record():
    with pytest.raises(CwprocError, match="wind_direction"):
        wind_record_product(_record().drop_vars("wind_direction"), **KW)


def test_real_zephir_record(real_data):
    from cwproc.io.zephir import read_zephir_csv

    rec = read_zephir_csv(real_data / "zephir/Wind10_317@Y2016_M12_D13.ZPH.csv")
    p = wind_record_product(rec, **KW)
    missing = (p["qc_flag"] & FLAG_MISSING) > 0
    # the 509 records with 9999 speeds, and 250 more whose exported w is missing
    assert int(missing.sum()) == 759
    assert int((~np.isfinite(p["w"]) & ~missing).sum()) == 0
    ratio = p["volume_averaging_ratio"].where(~missing)
    # averaging only removes variance; at 297 m the probe half width is Z_R = 150 m
    assert float(ratio.min()) > 0.3 and float(ratio.max()) < 0.9
    # decreasing with height (mean over the two days, 37 m -> 297 m)
    assert np.all(np.diff(ratio.mean("time").values) < 0)


def test_real_windcube_record(real_data):
    from cwproc.io.windcube import read_windcube_sta

    rec = read_windcube_sta(real_data / "windcube/WLS7-164_2016_11_24__00_00_00.sta")
    p = wind_record_product(rec, **KW)
    # 40 m, first record: dispersion 0.10 / speed 0.18
    assert p["turbulence_intensity"].values[0, 0] == pytest.approx(0.10 / 0.18)
    low = (rec["data_availability"] < 65).values
    assert np.all((p["qc_flag"].values[low] & FLAG_TOO_FEW_PACKETS) > 0)


def test_turbulence_parameter_is_residual_std_over_speed():
    wind = xr.Dataset(
        {
            "residual_std": (("time", "height"), np.array([[0.5, 0.2], [0.3, 0.1]])),
            "wind_speed": (("time", "height"), np.array([[10.0, 4.0], [0.0, 2.0]])),
        }
    )
    tp = turbulence_parameter(wind)
    np.testing.assert_allclose(tp.values[0], [0.05, 0.05])
    assert np.isnan(tp.values[1, 0]) and tp.values[1, 1] == pytest.approx(0.05)
    assert tp.name == "turbulence_parameter"


def test_turbulence_parameter_from_a_homodyne_vad_fit():
    """A homodyne cw scan with white noise sigma: TP = sigma / U (no turbulence)."""
    from cwproc.stages.vad import fit_vad

    rng = np.random.default_rng(4)
    n_rot, per_rot, u_true, sigma = 20, 50, 10.0, 0.3
    az = np.tile((np.arange(per_rot) + 0.5) * 360.0 / per_rot, n_rot)
    elev = np.full(az.size, 60.0)  # 30 deg from the vertical
    # wind from 250 deg: V_r = -U cos(el) cos(az - 250) (positive away)
    vr = -u_true * np.cos(np.radians(60.0)) * np.cos(np.radians(az - 250.0))
    vr = np.abs(vr + rng.normal(0.0, sigma, az.size))
    t0 = np.datetime64("2020-01-01T00:00:00")
    ds = xr.Dataset(
        {"radial_velocity": (("ray", "range"), vr[:, None])},
        coords={
            "time": ("ray", t0 + (np.arange(az.size) * 20).astype("timedelta64[ms]")),
            "azimuth": ("ray", az),
            "elevation": ("ray", elev),
            "scan": ("ray", np.repeat(np.arange(n_rot), per_rot).astype(np.int64)),
            "range": ("range", [115.47]),
        },
        attrs={"homodyne": 1, "instrument_kind": "cw"},
    )
    wind = fit_vad(ds, min_rays=20, max_gap_deg=30.0, reference_direction_deg=240.0)
    assert float(wind["wind_speed"].mean()) == pytest.approx(u_true, rel=0.02)
    tp = turbulence_parameter(wind)
    assert float(tp.mean()) == pytest.approx(sigma / u_true, rel=0.1)


@pytest.mark.parametrize(
    ("name", "value"),
    [("wind_speed", 1e308), ("wind_speed", np.inf), ("wind_speed", -50.0),
     ("wind_direction", 720.0), ("w", 99.0)],
)  # fmt: skip
def test_impossible_values_are_missing_never_good(name, value):
    """Values outside io.ranges.PHYSICAL_RANGES become missing (bit 4) (issue 17.3)."""
    from cwproc.io.zephir import with_range_screen

    rec = _record()
    rec[name].values[0, 0] = value
    screened = with_range_screen(rec)
    assert f"of {name} outside" in screened.attrs["warnings"][0]
    p = wind_record_product(screened, **KW)
    assert p["qc_flag"].values[0, 0] & FLAG_MISSING
    assert p["qc_flag"].values[0, 1] & FLAG_MISSING == 0
    good = p["qc_flag"].values == 0
    for var in ("wind_speed", "wind_direction", "u", "v", "w"):
        assert np.all(np.isfinite(p[var].values[good]))
