"""``cwproc compare``: the comparison product (CF) and its plot from two products."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.netcdf import read_product

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "stages"))
from test_lidar_sonic import lidar_product, sonic_product


def write_inputs(tmp_path: Path) -> tuple[Path, Path]:
    eps_s = np.array([1e-3, 4e-3, 2e-2, 5e-3])
    lidar, sonic = tmp_path / "lidar_turbulence.nc", tmp_path / "sonic.nc"
    lidar_product(0.7 * eps_s).to_netcdf(lidar)
    sonic_product(eps_s, 0.05 * eps_s).to_netcdf(sonic)
    return lidar, sonic


def test_compare_writes_a_compliant_product_and_a_png(tmp_path, compliance):
    lidar, sonic = write_inputs(tmp_path)
    out = tmp_path / "out"
    res = CliRunner().invoke(
        main, ["compare", str(lidar), str(sonic), "--height", "38", "-o", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert "geometric mean 0.700" in res.output
    product = out / "lidar-sonic_20240601_38m.nc"
    png = product.with_suffix(".png")
    assert png.stat().st_size > 10_000
    ds = read_product(product)
    np.testing.assert_allclose(ds["lidar_sonic_epsilon_ratio"].values, 0.7)
    assert ds["lidar_sonic_epsilon_ratio"].attrs["units"] == "1"
    high, acdd = compliance(product)
    assert high == []
    assert acdd >= 0.6


def test_a_missing_product_is_named(tmp_path):
    lidar, _ = write_inputs(tmp_path)
    res = CliRunner().invoke(
        main,
        ["compare", str(lidar), str(tmp_path / "nope.nc"), "--height", "40", "-o", str(tmp_path)],
    )
    assert res.exit_code == 1
    assert "nope.nc" in res.output and "Traceback" not in res.output


def test_simulated_lidar_and_mast_day_end_to_end(tmp_path):
    """simulate mast -> retrieve -> sonic-turbulence -> compare on one field (1 h).

    Truths (benchmarks/lidar_mast_truth.py, 6 fields): sonic eps / nominal
    0.703 +- 0.007 (the grid's own D: 0.734 +- 0.010 of nominal), lidar eps / nominal
    0.934 +- 0.027, lidar / sonic 1.33 +- 0.04; one field scatters by ~0.1-0.15."""
    runner = CliRunner()
    sim, out = tmp_path / "sim", tmp_path / "out"
    site = Path(__file__).resolve().parents[2] / "sample_data" / "site.toml"
    for args in (
        ["simulate", "mast", "-o", str(sim), "--hours", "1", "--seed", "11"],
        ["retrieve", str(sim / "lidar"), "-c", str(site), "-o", str(out), "-q"],
        ["sonic-turbulence", str(sim / "mast"), "-o", str(out), "-q", "--height", "26"],
    ):
        res = runner.invoke(main, args)
        assert res.exit_code == 0, res.output
    lidar = next(out.glob("streamline_*_turbulence.nc"))
    sonic = next(out.glob("meteo2_*_sonic-turbulence.nc"))
    res = runner.invoke(main, ["compare", str(lidar), str(sonic), "--height", "26", "-o", str(out)])
    assert res.exit_code == 0, res.output
    ds = read_product(next(out.glob("lidar-sonic_*_26m.nc")))
    assert float(ds["lidar_height"]) == pytest.approx(26.0, abs=0.1)
    sonic_q = ds["sonic_epsilon"].values / 0.01
    lidar_q = ds["lidar_epsilon"].values / 0.01
    assert np.all((sonic_q > 0.55) & (sonic_q < 0.9))
    assert np.all((lidar_q > 0.65) & (lidar_q < 1.25))
    assert 1.0 < ds.attrs["summary_ratio_geometric_mean"] < 1.8
