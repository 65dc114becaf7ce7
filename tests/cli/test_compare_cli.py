"""``cwproc compare``: the comparison product (CF) and its plot from two products."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
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
