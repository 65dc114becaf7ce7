"""Quicklook of the L1 product: beta on the fixed log range, depolarisation, velocity."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

pytest.importorskip("matplotlib")

from cwproc.cli import main
from cwproc.plots.l1 import BETA_RANGE, plot_doppler_lidar


def product(with_cross: bool = True) -> xr.Dataset:
    n, g = 40, 12
    t = np.datetime64("2024-06-01T12:00", "ns") + np.arange(n) * np.timedelta64(2, "s")
    r = (np.arange(g) + 0.5) * 30.0
    beta = np.full((n, g), 2e-6)
    data = {
        "beta_screened": (("time", "range"), beta),
        "radial_velocity_screened": (("time", "range"), np.zeros((n, g))),
        "doppler_lidar_flag": (("time", "range"), np.zeros((n, g), dtype=np.int16)),
    }
    if with_cross:
        data["depolarisation_screened"] = (("time", "range"), np.full((n, g), 0.2))
    return xr.Dataset(data, coords={"time": t, "range": r, "height": ("range", r)})


def test_panels_and_the_fixed_beta_range():
    from matplotlib.collections import QuadMesh

    def meshes_of(fig):
        panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
        return [c for ax in panels for c in ax.collections if isinstance(c, QuadMesh)]

    meshes = meshes_of(plot_doppler_lidar(product()))
    assert len(meshes) == 3
    assert (meshes[0].norm.vmin, meshes[0].norm.vmax) == BETA_RANGE  # Cloudnet's fixed range
    assert (meshes[1].norm.vmin, meshes[1].norm.vmax) == (0.0, 0.5)
    assert len(meshes_of(plot_doppler_lidar(product(False)))) == 2


def test_plot_command_recognises_the_l1_product(tmp_path):
    src = tmp_path / "x_doppler_lidar.nc"
    product().to_netcdf(src)
    res = CliRunner().invoke(main, ["plot", str(src), "-o", str(tmp_path / "q.png")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "q.png").stat().st_size > 10_000


def test_the_l1_product_is_drawn_as_doppler_lidar_by_default():
    from cwproc import plots

    assert plots.default_kind(product()) == "doppler-lidar"
    assert plots.default_kind(product(with_cross=False)) == "doppler-lidar"
