"""``cwproc simulate lidar`` and ``cwproc simulate montecarlo`` end to end."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc.cli import main

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data"


def run(*args: str):
    result = CliRunner().invoke(main, list(args), catch_exceptions=False)
    return result


def test_simulate_lidar_streamline_writes_hpl_and_truth_apart(tmp_path):
    res = run(
        "simulate",
        "lidar",
        "-o",
        str(tmp_path),
        "--hours",
        "0.03",
        "--wind",
        "9",
        "--direction",
        "200",
        "--seed",
        "3",
    )
    assert res.exit_code == 0, res.output
    files = sorted((tmp_path / "data").iterdir())
    assert files and all(f.suffix == ".hpl" for f in files)
    truth = json.loads((tmp_path / "truth" / "truth.json").read_text())
    assert truth["wind_speed_m_s"] == 9.0 and truth["wind_direction_deg"] == 200.0
    from cwproc.io.halo import read_hpl

    ds = read_hpl(files[0])
    assert ds.sizes["ray"] == 3 * 180  # 0.03 h = 108 s = 3 scans of 36 s
    # wind from 200 deg: the radial velocity is largest looking downwind (azimuth 20 deg)
    vr = ds["radial_velocity"].values.mean(axis=1)
    az = ds["azimuth"].values
    downwind = np.abs(((az - 20.0 + 180.0) % 360.0) - 180.0) < 10.0
    upwind = np.abs(((az - 200.0 + 180.0) % 360.0) - 180.0) < 10.0
    assert vr[downwind].mean() > 4.0 > -4.0 > vr[upwind].mean()


def test_simulate_lidar_zephir_is_homodyne_scan_netcdf(tmp_path):
    res = run(
        "simulate",
        "lidar",
        "-o",
        str(tmp_path),
        "--instrument",
        "zephir",
        "--hours",
        "0.001",
        "--seed",
        "1",
    )
    assert res.exit_code == 0, res.output
    from cwproc.io.scan_netcdf import read_scan_netcdf

    (nc,) = sorted((tmp_path / "data").glob("*.nc"))
    ds = read_scan_netcdf(nc)
    assert ds.attrs["instrument_kind"] == "cw"
    assert int(ds.attrs["homodyne"]) == 1
    assert float(ds.attrs["z_r_coefficient"]) == pytest.approx(0.0013)
    assert ds.sizes["ray"] == 4 * 50  # 3.6 s of 1-s rotations with 50 spectra each
    v = ds["radial_velocity"].values
    assert np.all(v[np.isfinite(v)] >= 0.0)
    truth = json.loads((tmp_path / "truth" / "truth.json").read_text())
    assert truth["heights_m"][0] == 40.0


def test_simulate_montecarlo_writes_table_netcdf_and_png(tmp_path):
    cfg = tmp_path / "mc.toml"
    cfg.write_text(
        "[instrument]\nkind = 'cw'\nwavelength_m = 10.6e-6\nbeam_radius_m = 0.075\n"
        "[simulation]\nheights_m = [100.0, 300.0]\nwind_speed_m_s = [7.77, 9.14]\n"
        "sigma_v_m_s = [1.20, 1.11]\nouter_scale_m = [200.0, 300.0]\nmax_scans = 3\n"
        "realisations = 40\n"
    )
    res = run("simulate", "montecarlo", "-o", str(tmp_path / "out"), "-c", str(cfg), "--seed", "4")
    assert res.exit_code == 0, res.output
    assert "relative RMS error of epsilon" in res.output
    ds = xr.open_dataset(tmp_path / "out" / "montecarlo_seed000.nc")
    for name in ("epsilon_rel_error", "variance_rel_error", "integral_scale_rel_error"):
        assert ds[name].dims == ("n_scans", "height")
        assert ds[name].attrs["units"] == "1"
        assert np.all(ds[name].values > 0)
    assert ds["n_scans"].values.tolist() == [1, 2, 3]
    assert ds.attrs["realisations"] == 40
    ds.close()
    assert (tmp_path / "out" / "montecarlo_seed000.png").stat().st_size > 1000


def test_simulate_montecarlo_rejects_a_bad_config(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[simulation]\nheights_m = [100.0]\n")
    res = CliRunner().invoke(main, ["simulate", "montecarlo", "-o", str(tmp_path), "-c", str(cfg)])
    assert res.exit_code == 2
    assert "simulation.wind_speed_m_s" in res.output
