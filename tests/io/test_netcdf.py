"""The product writer: atomic, provenance recorded, CF-1.10 and ACDD-1.3 compliant."""

from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from cwproc import __version__
from cwproc.config import Config, OutputConfig
from cwproc.errors import ProductError
from cwproc.io.netcdf import read_product, sha256_file
from cwproc.metadata.products import VARIABLES, apply_metadata, undeclared_variables
from cwproc.products.writer import site_attributes, write_product


def wind_like(n_time: int = 6, n_height: int = 4) -> xr.Dataset:
    rng = np.random.default_rng(1)
    t = pd.date_range("2024-03-01", periods=n_time, freq="10min").values
    h = np.arange(1, n_height + 1) * 45.0
    names = ["u", "v", "w", "wind_speed", "wind_direction", "u_error", "v_error", "w_error"]
    ds = xr.Dataset(
        {k: (("time", "height"), rng.normal(size=(n_time, n_height))) for k in names},
        coords={"time": t, "height": h, "range": ("height", h / np.sin(np.radians(60)))},
    )
    ds["n_rays"] = (("time", "height"), np.full((n_time, n_height), 24, dtype=np.int32))
    ds["qc_flag"] = (("time", "height"), np.zeros((n_time, n_height), dtype=np.int8))
    ds["u"][0, 0] = np.nan
    return ds


def test_round_trip_keeps_values_nan_and_metadata(tmp_path):
    ds = wind_like()
    src = tmp_path / "input.hpl"
    src.write_bytes(b"some bytes")
    path = write_product(
        ds,
        tmp_path / "p.nc",
        product="wind",
        title="t",
        summary="s",
        inputs=[src],
        config_toml="[qc]\n",
    )
    back = read_product(path)
    np.testing.assert_array_equal(back["u"].values, ds["u"].values)  # NaN survives
    assert back["u"].attrs["standard_name"] == "eastward_wind"
    assert back["u"].attrs["units"] == "m s-1"
    assert back["wind_direction"].attrs["standard_name"] == "wind_from_direction"
    assert back.attrs["Conventions"] == "CF-1.10, ACDD-1.3"
    assert back.attrs["cwproc_version"] == __version__
    assert json.loads(back.attrs["input_sha256"]) == {os.fspath(src): sha256_file(src)}
    assert back.attrs["cwproc_config"] == "[qc]\n"
    assert back.attrs["time_coverage_resolution"] == "PT600S"
    assert (back["time"].values == ds["time"].values).all()


def test_killed_write_leaves_nothing(tmp_path, monkeypatch):
    ds = wind_like()

    def boom(self, *args, **kwargs):
        raise KeyboardInterrupt  # as if the run were killed mid-write

    monkeypatch.setattr(xr.Dataset, "to_netcdf", boom)
    with pytest.raises(KeyboardInterrupt):
        write_product(ds, tmp_path / "p.nc", product="wind", title="t", summary="s")
    assert list(tmp_path.iterdir()) == []


def test_unwritable_directory_is_a_clear_product_error(tmp_path):
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    with pytest.raises(ProductError, match="cannot write product"):
        write_product(wind_like(), blocker / "p.nc", product="wind", title="t", summary="s")


def test_every_declared_variable_has_units_and_long_name():
    for name, meta in VARIABLES.items():
        assert meta.long_name, name
        if meta.standard_name != "time":  # datetimes: units set by the encoding
            assert meta.units is not None, name


def test_apply_metadata_marks_flags_and_counts():
    out = apply_metadata(wind_like(), product="wind")
    assert out["qc_flag"].attrs["coverage_content_type"] == "qualityInformation"
    assert out["n_rays"].attrs["standard_name"] == "number_of_observations"
    assert out["height"].attrs["coverage_content_type"] == "coordinate"
    assert undeclared_variables(out) == []


def test_product_is_cf_and_acdd_compliant(tmp_path, compliance):
    out = OutputConfig(
        institution="IAO SB RAS",
        creator_name="A. Lidar",
        project="test",
        latitude=56.48,
        longitude=85.05,
        altitude_m=160.0,
    )
    cfg = Config(output=out)
    path = write_product(
        wind_like(),
        tmp_path / "wind.nc",
        product="wind",
        title="cwproc wind",
        summary="test product",
        config_toml=cfg.to_toml(),
        extra_attrs=site_attributes(cfg.output),
    )
    high, acdd = compliance(path)
    assert high == []
    assert acdd >= 0.90
