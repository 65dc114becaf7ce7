"""DBS statistics of WindCube .rtd lines of sight: cycles, flags, and TI against the truth
of the virtual WindCube (mean +- standard error over realisations)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cwproc.io.windcube_rtd import read_windcube_rtd
from cwproc.sim.windcube import WindCubeSpec, bias_table, ti_trials
from cwproc.stages.dbs import (
    FLAG_INHOMOGENEOUS,
    FLAG_LOW_CNR,
    beam_cycles,
    dbs_statistics,
)

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data"
RTD = SAMPLE / "windcube_rtd" / "WLS71999_2024_06_01__00_00_00.rtd"


def test_beam_cycles_are_complete_sequences():
    beams = np.array(["90", "180", "270", "V", "0", "90", "180", "270", "V", "0", "90"])
    np.testing.assert_array_equal(beam_cycles(beams), [4])
    v1 = np.array(["0", "90", "180", "270", "0", "90", "270", "0", "90", "180", "270"])
    np.testing.assert_array_equal(beam_cycles(v1), [0, 7])


def test_sample_statistics_and_the_truth_of_its_series():
    stats = dbs_statistics(read_windcube_rtd(RTD), integral_scale_m=100.0).isel(time=0)
    truth = json.loads((SAMPLE / "windcube_rtd_truth.json").read_text())
    assert int(stats["dbs_flag"].max()) == 0
    assert float(stats["n_cycles"].min()) == 150  # 750 lines of sight, 5 per cycle
    # one 10-min realisation: the mean wind within 0.3 m/s of the mast's (turbulence
    # sigma ~1 m/s over the 100 m beam spread), the corrected TI within 25 %
    np.testing.assert_allclose(stats["wind_speed"], truth["mast_wind_speed_m_s"], atol=0.3)
    np.testing.assert_allclose(
        stats["turbulence_intensity_corrected"], truth["mast_turbulence_intensity"], rtol=0.25
    )
    # the measured DBS TI is well above it (cross-contamination, Sathe et al. (2011))
    assert np.all(
        stats["turbulence_intensity"] > 1.2 * np.array(truth["mast_turbulence_intensity"])
    )


def test_v1_cycle_without_vertical_beam():
    ds = read_windcube_rtd(SAMPLE / "windcube_rtd" / "WLS7-099_2024_06_01__00_12_00.rtd")
    stats = dbs_statistics(ds, window_s=120.0)
    assert stats.sizes["time"] == 1
    assert np.all(np.isfinite(stats["turbulence_intensity_corrected"]))
    assert np.all(np.isnan(stats["w_mismatch"]))  # no vertical beam to compare with


def test_inhomogeneous_flow_is_flagged():
    """A mean offset of the inclined beams (flow not the same across the cone, as over a
    hill) makes w of the inclined beams differ from the vertical beam's: bit 4."""
    ds = read_windcube_rtd(RTD)
    inclined = ds["beam"] != "V"
    ds["radial_velocity"] = ds["radial_velocity"] + 0.5 * inclined
    flag = dbs_statistics(ds)["dbs_flag"].values
    assert np.all(flag & FLAG_INHOMOGENEOUS)


def test_real_file_low_cnr_is_missing_and_flagged(real_data):
    """The real WF 2.2.1 day: CNR about -30 dB, below the -23 dB threshold everywhere."""
    ds = read_windcube_rtd(real_data / "windcube/WLS71460_2022_01_11__21_04_17.rtd")
    stats = dbs_statistics(ds)
    assert stats.sizes["time"] == 6  # 21:00-21:10 ... 21:50-22:00
    assert np.all(stats["dbs_flag"].values & FLAG_LOW_CNR)
    assert bool(np.isnan(stats["turbulence_intensity_corrected"]).all())


@pytest.mark.slow
def test_corrected_ti_is_unbiased_and_the_measured_one_is_not():
    """12 realisations of 10 min (3 fields x 4 lidar positions) of the virtual WindCube.

    Measured TI (std of the DBS along-wind component / mean speed): +27 to +44 % (the
    cross-contamination of Sathe et al. (2011) outweighs the probe's averaging); all
    corrections: within 10 % of the true TI of a point mast at the lidar, and within
    3.5 standard errors of it. Figures with 32 realisations: docs/windcube.md.
    """
    spec = WindCubeSpec()
    trials = ti_trials(spec, [100, 101, 102], [(0.0, 600.0 * k, 0.0) for k in range(4)])
    table = bias_table(trials)
    truth = trials["truth_ti"].mean(axis=0)
    raw, raw_se = table["turbulence_intensity"]
    assert np.all(raw > 0.2 * truth) and np.all(raw > 5 * raw_se)
    bias, se = table["turbulence_intensity_corrected"]
    assert np.all(np.abs(bias) < 0.1 * truth)
    assert np.all(np.abs(bias) < 3.5 * se + 0.005)
    # the .rtd mean wind is the mast's; the .sta averages the scalar speeds (higher)
    speed, speed_se = table["rtd_speed"]
    assert np.all(np.abs(speed) < 3 * speed_se + 0.05)
    # the variances of u and v: measured about twice the truth (cross-contamination),
    # corrected within 15 %; w from the vertical beam: measured low (the probe), corrected
    # within 10 % (the generator's field lacks scales below ~2 grid steps, 5 m, which the
    # continuous model of the probe correction removes: it overcorrects by ~5 %)
    for c, low, high in (("u", 0.15, 1.3), ("v", 0.15, 1.3), ("w", 0.10, None)):
        truth_var = trials[f"truth_{c}_variance"].mean(axis=0)
        bias, se = table[f"{c}_variance"]
        assert np.all(np.abs(bias) < low * truth_var + 2 * se), c
        measured = trials[f"{c}_variance_measured"].mean(axis=0)
        if high is not None:
            assert np.all(measured > high * truth_var), c
        else:
            assert np.all(measured < truth_var), c
    # paired: the mean of the scalar speeds exceeds the speed of the mean wind
    diff = trials["sta_speed"] - trials["rtd_speed"]
    assert np.all(diff.mean(axis=0) > 3 * diff.std(axis=0, ddof=1) / np.sqrt(diff.shape[0]))


def test_retrieve_writes_the_rtd_and_the_sta_of_one_period_side_by_side(tmp_path):
    """``retrieve -c windcube`` on the .rtd sample folder: one product per file, the .rtd
    product (DBS, corrected TI) beside the instrument's .sta of the same 10 min."""
    import xarray as xr
    from click.testing import CliRunner

    from cwproc.cli import main

    res = CliRunner().invoke(
        main, ["retrieve", "-c", "windcube", str(SAMPLE / "windcube_rtd"), "-o", str(tmp_path)]
    )
    assert res.exit_code == 0, res.output
    assert "4 input(s), 4 product(s) written, 0 failure(s)" in res.output
    stem = "windcube_rtd_WLS71999_2024_06_01__00_00_00"
    rtd = xr.open_dataset(tmp_path / f"{stem}_rtd_wind.nc")
    sta = xr.open_dataset(tmp_path / f"{stem}_wind.nc")
    np.testing.assert_array_equal(rtd["time"].values, sta["time"].values)  # 00:10, end
    truth = json.loads((SAMPLE / "windcube_rtd_truth.json").read_text())
    # the two mean winds agree within the .sta's scalar averaging (+0.1 to +0.15 m/s)
    diff = sta["wind_speed"].values[0] - rtd["wind_speed"].values[0]
    assert np.all((diff > 0) & (diff < 0.3))
    assert np.all(rtd["dbs_flag"].values == 0)
    corrected = rtd["turbulence_intensity_corrected"].values[0]
    np.testing.assert_allclose(corrected, truth["mast_turbulence_intensity"], rtol=0.25)
    assert "noise" in rtd["turbulence_intensity_corrected"].attrs["method"]
