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


@pytest.mark.slow
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


@pytest.mark.slow
def test_simulate_montecarlo_writes_table_netcdf_and_png(tmp_path):
    cfg = tmp_path / "mc.toml"
    cfg.write_text(
        "[instrument]\nkind = 'cw'\nwavelength_m = 10.6e-6\nbeam_radius_m = 0.075\n"
        "[simulation]\nheights_m = [100.0, 300.0]\nwind_speed_m_s = [7.77, 9.14]\n"
        "sigma_v_m_s = [1.20, 1.11]\nouter_scale_m = [200.0, 300.0]\nmax_scans = 3\n"
        "realisations = 40\nspectrum_time_s = 0.1\n"
    )
    res = run("simulate", "montecarlo", "-o", str(tmp_path / "out"), "-c", str(cfg), "--seed", "4")
    assert res.exit_code == 0, res.output
    assert "relative RMS error of epsilon" in res.output
    ds = xr.open_dataset(tmp_path / "out" / "montecarlo_banakh1999.nc")
    for name in ("epsilon_rel_error", "variance_rel_error", "integral_scale_rel_error"):
        assert ds[name].dims == ("n_scans", "height")
        assert ds[name].attrs["units"] == "1"
        assert np.all(ds[name].values > 0)
    assert ds["n_scans"].values.tolist() == [1, 2, 3]
    assert ds.attrs["realisations"] == 40
    ds.close()
    assert (tmp_path / "out" / "montecarlo_banakh1999.png").stat().st_size > 1000


def test_simulate_montecarlo_rejects_a_bad_config(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[simulation]\nheights_m = [100.0]\n")
    res = CliRunner().invoke(main, ["simulate", "montecarlo", "-o", str(tmp_path), "-c", str(cfg)])
    assert res.exit_code == 2
    assert "simulation.wind_speed_m_s" in res.output


@pytest.mark.slow
def test_retrieve_on_the_sample_data_recovers_the_truth(tmp_path):
    """The README's main job: mean wind and epsilon of sample_data/streamline.

    Wind: mean over gates and blocks within 0.5 m/s (sigma_V = 1.3 m/s turbulence
    averaged over 24 gates x 12 scans of a field with L_V = 150 m). epsilon: one block
    of 10 scans has a relative error of 10-20 % per height (the Monte-Carlo study);
    the median over the gates beyond 240 m, where the transverse spacing (>= 7 m) is
    resolved by the 8-m grid of the simulated field, is within 30 %.
    """
    from cwproc.config import load_config
    from cwproc.pipeline import retrieve_files

    truth = json.loads((SAMPLE / "streamline_truth.json").read_text())
    files = sorted((SAMPLE / "streamline").glob("*.hpl"))
    report = retrieve_files(files, tmp_path, load_config(None))
    assert report.ok, report.failures
    wind = xr.open_dataset(next(tmp_path.glob("*_wind.nc")))
    assert float(wind["u"].mean()) == pytest.approx(truth["u_m_s"], abs=0.5)
    assert float(wind["v"].mean()) == pytest.approx(truth["v_m_s"], abs=0.5)
    turb = xr.open_dataset(next(tmp_path.glob("*_turbulence.nc")))
    eps = turb["epsilon"].where(turb["range"] >= 240.0).values
    ratio = np.nanmedian(eps) / truth["epsilon_m2_s3"]
    assert 0.7 < ratio < 1.3
    wind.close()
    turb.close()


@pytest.fixture(scope="module")
def cw_products(tmp_path_factory):
    """30 scans (3 blocks of 10) of the seed-000 cw lidar at its six heights, homodyne,
    written as scan NetCDF files and retrieved with the preset banakh1999."""
    from cwproc.config import load_config
    from cwproc.pipeline import retrieve_files
    from cwproc.sim.cw import write_cw_series
    from cwproc.sim.montecarlo import lidar_from_config

    base = tmp_path_factory.mktemp("cw")
    cfg = load_config("banakh1999")
    sim = cfg.simulation
    written = write_cw_series(
        base / "data",
        base / "truth" / "truth.json",
        np.random.default_rng(8),
        lidar_from_config(sim, 10.6e-6, 0.075),
        heights_m=np.array(sim.heights_m),
        wind_speed=np.array(sim.wind_speed_m_s),
        wind_direction_deg=sim.wind_direction_deg,
        sigma2=np.array(sim.sigma_v_m_s) ** 2,
        outer_scale_m=np.array(sim.outer_scale_m),
        n_scans=30,
        start=np.datetime64("2024-01-01T00:00:00"),
    )
    report = retrieve_files(written[:-1], base / "out", cfg)
    assert report.ok, report.failures
    truth = json.loads(written[-1].read_text())
    return base / "out", truth


#: relative rms error of eps from one block of N = 10 simulated homodyne cw scans at the
#: six heights (python benchmarks/bench_cw_epsilon_bias.py --blocks 36 --homodyne); the
#: Monte-Carlo study's 10-12 % is for the exact V_D, the centroid estimates of the
#: simulated spectra add to it
CW_BLOCK_ERROR = np.array([0.17, 0.13, 0.14, 0.16, 0.25, 0.24])


@pytest.mark.slow
def test_cw_simulation_feeds_retrieve_and_recovers_wind_and_epsilon(cw_products):
    """Simulated cw files read back by ``retrieve``: wind and eps at all six heights.

    Three blocks per height (18 estimates): each within 3 block errors of the truth,
    the mean of the three blocks at each height within 3 errors of that mean, and the
    mean over all 18 within 2.5 errors of the mean (unbiased; the fit of round 1 read
    1.11-1.17 on average and would fail it).
    """
    out, truth = cw_products
    wind = xr.open_dataset(next(out.glob("*_wind.nc")))
    speed = wind["wind_speed"].mean("time").values
    assert speed == pytest.approx(truth["wind_speed_m_s"], abs=0.6)
    direction = wind["wind_direction"].mean("time").values
    assert direction == pytest.approx([truth["wind_direction_deg"]] * 6, abs=6.0)
    turb = xr.open_dataset(next(out.glob("*_turbulence.nc")))
    assert turb.sizes["time"] == 3 and turb.sizes["height"] == 6
    ratio = turb["epsilon"].values / np.array(truth["epsilon_m2_s3"])[None, :]
    assert np.all(np.isfinite(ratio))
    assert np.all(np.abs(ratio - 1) < 3 * CW_BLOCK_ERROR), ratio
    assert np.all(np.abs(ratio.mean(axis=0) - 1) < 3 * CW_BLOCK_ERROR / np.sqrt(3)), ratio
    pooled = np.sqrt(np.mean(CW_BLOCK_ERROR**2))
    assert abs(ratio.mean() - 1) < 2.5 * pooled / np.sqrt(ratio.size), ratio
    wind.close()
    turb.close()


def test_simulate_lidar_reports_an_unwritable_output_in_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    res = CliRunner().invoke(
        main, ["simulate", "lidar", "-o", str(blocker / "sub"), "--hours", "0.01"]
    )
    assert res.exit_code == 1
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:")
    assert "Traceback" not in res.output
