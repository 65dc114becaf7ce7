"""``cwproc.retrieve`` and ``cwproc.write`` of datasets, and the instrument's defaults
when no configuration is given (issue 33)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import cwproc
from cwproc.config import default_preset, preset_names
from cwproc.io import Format
from cwproc.metadata import DATASET_VARIABLES
from cwproc.pipeline.retrieve import _KIND_VARIABLES, dataset_format
from cwproc.pipeline.write import IN_MEMORY_CHECKSUM

SAMPLES = Path(__file__).resolve().parents[1] / "sample_data"
STREAMLINE = SAMPLES / "streamline"
METEO2 = SAMPLES / "sonic" / "meteo2_2024_06_01_1200.txt"
ZEPHIR = SAMPLES / "zephir" / "Wind10_999@Y2024_M06_D01.ZPH.csv"


def assert_same(a: xr.Dataset, b: xr.Dataset) -> None:
    assert set(a.data_vars) == set(b.data_vars)
    for name in a.variables:
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=str(name))
        assert a[name].attrs.get("units") == b[name].attrs.get("units"), name


@pytest.fixture(scope="module")
def from_files() -> cwproc.Retrieval:
    return cwproc.retrieve(STREAMLINE, "streamline")


def test_retrieve_of_datasets_gives_the_products_of_the_files(from_files):
    per_file = [cwproc.read(f) for f in sorted(STREAMLINE.glob("*.hpl"))]
    for data in (cwproc.read(STREAMLINE / "*.hpl"), per_file):
        result = cwproc.retrieve(data, "streamline")
        (unit,) = result.units.values()
        assert unit.inputs[0].parent == Path("<in-memory>")
        for name in ("wind", "turbulence"):
            assert_same(result[name], from_files[name])
    assert result["wind"].sizes["time"] == 12


def test_no_configuration_takes_each_instruments_preset(from_files):
    result = cwproc.retrieve([STREAMLINE, METEO2, ZEPHIR])
    presets = {u.kind: u.config.source for u in result.units.values()}
    assert presets == {
        "scan": "<preset streamline>",
        "sonic": "<preset meteo2>",
        "wind_record": "<preset zephir300>",
    }
    assert result.config is None and "config per unit" in repr(result)
    notes = [n for n in result.notes if n.startswith("no configuration given")]
    assert len(notes) == 3 and any(f"preset meteo2 for {METEO2}" in n for n in notes)
    assert_same(result["turbulence"], from_files["turbulence"])
    sonic = cwproc.retrieve(METEO2, "meteo2")
    assert_same(result["sf"], sonic["sf"])
    alone = cwproc.retrieve(cwproc.read(METEO2))
    assert next(iter(alone.units.values())).config.source == "<preset meteo2>"
    assert "preset meteo2 for <in-memory>/meteo2_2024_06_01_1200.txt" in alone.notes[0]


def test_write_takes_a_retrieval_a_unit_a_dataset_or_a_mapping(tmp_path):
    result = cwproc.retrieve(cwproc.read(STREAMLINE / "*.hpl"), "streamline")
    files = cwproc.write(result, tmp_path / "all")
    assert sorted(p.name for p in files) == [
        "streamline_999_20240601_turbulence.nc",
        "streamline_999_20240601_wind.nc",
    ]
    with xr.open_dataset(files[0]) as written:
        sums = json.loads(written.attrs["input_sha256"])
        assert list(sums.values()) == [IN_MEMORY_CHECKSUM]
        assert "streamline" in written.attrs["cwproc_config"]
    (unit,) = result.units.values()
    assert len(cwproc.write(unit, tmp_path / "unit")) == 2
    wind = cwproc.stages.fit_vad(cwproc.read(STREAMLINE / "*.hpl"))
    (path,) = cwproc.write(wind, tmp_path / "one", product="wind", config="streamline")
    assert path.name == "VAD_999_20240601_120000_wind.nc"
    with xr.open_dataset(path) as written:
        assert written["u"].attrs["units"] == "m s-1"
        assert written.attrs["title"].startswith("cwproc ")
    (again,) = cwproc.write({"wind": wind}, tmp_path / "map")
    assert again.name == path.name
    with pytest.raises(cwproc.CwprocError, match="needs product=, the product it is: wind"):
        cwproc.write(wind, tmp_path)
    with pytest.raises(cwproc.CwprocError, match="unknown product 'winds'"):
        cwproc.write(wind, tmp_path, product="winds")
    with pytest.raises(TypeError, match=r"cwproc\.write takes what cwproc\.retrieve returned"):
        cwproc.write([wind], tmp_path)


def test_retrieve_names_what_it_cannot_take():
    with pytest.raises(cwproc.CwprocError, match=r"^dataset 0: not a dataset cwproc reads"):
        cwproc.retrieve(xr.Dataset({"u": ("x", [1.0])}))
    with pytest.raises(TypeError, match=r"takes a path .*, not int"):
        cwproc.retrieve(3)
    with pytest.raises(TypeError, match="the sequence holds a int"):
        cwproc.retrieve([STREAMLINE, 3])


def test_every_format_has_a_default_preset_and_datasets_tell_their_format():
    for fmt in Format:
        assert default_preset(fmt.value, {}) in preset_names(), fmt
    assert default_preset("scan_netcdf", {"instrument_kind": "cw"}) == "banakh1999"
    assert default_preset("scan_netcdf", {"instrument_kind": "cw", "instrument": "ZephIR 300"}) == (
        "zephir300"
    )
    for kind, names in _KIND_VARIABLES.items():
        assert set(names) <= set(DATASET_VARIABLES[kind]), kind
    expected = {
        STREAMLINE / "VAD_999_20240601_120000.hpl": Format.HPL,
        METEO2: Format.METEO2,
        ZEPHIR: Format.ZEPHIR_CSV,
        SAMPLES / "sonic" / "TOA5_999.ts_data_2024_06_01_1200.dat": Format.TOA5,
        SAMPLES / "sonic" / "TOB1_999.ts_data_2024_06_01_1200.dat": Format.TOB1,
        SAMPLES / "sonic" / "2024-06-01T120000_AIU-0999.data": Format.GHG,
        SAMPLES / "windcube_rtd" / "WLS7-999_2024_06_01__00_10_00.rtd": Format.WINDCUBE_RTD,
        SAMPLES / "windcube" / "WLS7-999_2024_06_01__00_00_00.sta": Format.WINDCUBE_STA,
    }
    for path, fmt in expected.items():
        assert dataset_format(cwproc.read(path)) is fmt, path
