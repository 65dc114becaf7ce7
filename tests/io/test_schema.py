"""The canonical attributes are attached on read (issue 16): every reader, one table."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cwproc.config import load_config
from cwproc.io import KIND, detect_format, read_file
from cwproc.io.halo import read_hpl
from cwproc.io.halo_files import read_hpl_files
from cwproc.io.scan_netcdf import read_scan_netcdf, write_scan_netcdf
from cwproc.metadata.canonical import DATASET_VARIABLES, SCAN_VARIABLES, attach_attrs

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data"
HPL = sorted((SAMPLE / "streamline").glob("*.hpl"))


def test_read_hpl_attaches_units():
    ds = read_hpl(HPL[0])
    assert ds["radial_velocity"].attrs["units"] == "m s-1"
    assert ds["azimuth"].attrs["units"] == "degree"
    assert ds["range"].attrs["units"] == "m"
    assert ds["snr"].attrs["units"] == "1"
    assert "units" not in ds["time"].attrs  # datetime64: the encoding sets them
    # what the scan bookkeeping did is kept beside the declared attributes
    assert "method" in ds["scan"].attrs and ds["scan"].attrs["units"] == "1"


def test_read_hpl_files_fast_path_equals_the_reference_path():
    together = read_hpl_files(HPL)
    assert together["radial_velocity"].attrs["units"] == "m s-1"
    for name in together.variables:
        assert together[name].attrs == read_hpl_files(HPL[:1])[name].attrs, name


@pytest.mark.parametrize(
    ("folder", "config"),
    [
        ("streamline", "site.toml"),
        ("zephir", "zephir300"),
        ("windcube", "windcube"),
        ("sonic", "sonic.toml"),
    ],
)
def test_every_variable_every_reader_returns_has_declared_units(folder, config):
    cfg = load_config(SAMPLE / config if config.endswith(".toml") else config)
    for path in sorted((SAMPLE / folder).iterdir()):
        fmt = detect_format(path)
        ds = read_file(path, **cfg.reader.get(fmt.value, {}))
        table = DATASET_VARIABLES[KIND[fmt]]
        for name in ds.variables:
            assert name in table, (path.name, name)
            if ds[name].dtype.kind != "M":
                assert ds[name].attrs["units"] == table[name].units, (path.name, name)
            assert ds[name].attrs["long_name"] == table[name].long_name, (path.name, name)


def test_sonic_components_are_named_in_the_instrument_frame():
    cfg = load_config(SAMPLE / "sonic.toml")
    path = next(p for p in sorted((SAMPLE / "sonic").iterdir()) if p.name.startswith("TOA5"))
    ds = read_file(path, **cfg.reader.get("toa5", {}))
    assert "instrument frame" in ds["u"].attrs["long_name"]
    assert "standard_name" not in ds["u"].attrs  # not eastward_wind: the frame is the sonic's


def test_scan_netcdf_round_trip_keeps_the_declared_attributes(tmp_path):
    ds = read_hpl(HPL[0])
    back = read_scan_netcdf(write_scan_netcdf(ds, tmp_path / "scan.nc"))
    for name in ("radial_velocity", "snr", "beta", "azimuth", "elevation", "range"):
        assert back[name].attrs["units"] == SCAN_VARIABLES[name].units, name


def test_declared_attributes_replace_what_was_set_and_the_rest_is_kept():
    ds = xr.Dataset(
        {"radial_velocity": ("ray", np.zeros(3), {"units": "km/h", "method": "m"})},
        coords={"time": ("ray", np.array([0, 1, 2], "datetime64[s]").astype("datetime64[ns]"))},
    )
    out = attach_attrs(ds, SCAN_VARIABLES)
    assert out["radial_velocity"].attrs["units"] == "m s-1"
    assert out["radial_velocity"].attrs["method"] == "m"
    assert ds["radial_velocity"].attrs["units"] == "km/h"  # the input is not changed
