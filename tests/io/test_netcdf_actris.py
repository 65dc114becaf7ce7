"""ACTRIS/Cloudnet conventions of the products: file_uuid, source_file_uuids,
instrument_pid, one file per instrument, day and product."""

from __future__ import annotations

import shutil
import uuid
from pathlib import Path

import numpy as np
import xarray as xr
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.halo import read_hpl, write_hpl
from cwproc.io.netcdf import read_product
from cwproc.io.scan_netcdf import write_scan_netcdf

REPO = Path(__file__).resolve().parents[2]
SAMPLES = sorted((REPO / "sample_data" / "streamline").glob("*.hpl"))


def retrieve(*args) -> str:
    res = CliRunner().invoke(main, ["retrieve", *map(str, args)])
    assert res.exit_code == 0, res.output
    return res.output


def test_every_written_file_has_its_own_uuid4_and_hpl_inputs_no_source_uuids(tmp_path):
    data = tmp_path / "in"
    data.mkdir()
    for p in SAMPLES:
        shutil.copy(p, data)
    retrieve(data, "-o", tmp_path / "a")
    retrieve(data, "-o", tmp_path / "b")
    ids = []
    for folder in ("a", "b"):
        for product in sorted((tmp_path / folder).glob("*.nc")):
            attrs = read_product(product).attrs
            ids.append(attrs["file_uuid"])
            assert uuid.UUID(attrs["file_uuid"]).version == 4
            # .hpl inputs carry no uuid: they are identified by input_sha256
            assert "source_file_uuids" not in attrs
            assert "VAD_999_20240601_120000.hpl" in attrs["input_sha256"]
    assert len(ids) == 4 and len(set(ids)) == 4  # same inputs, new file: new uuid


def test_products_of_netcdf_inputs_name_their_uuids(tmp_path):
    data = tmp_path / "in"
    data.mkdir()
    written = []
    for p in SAMPLES:
        written.append(write_scan_netcdf(read_hpl(p), data / (p.stem + ".nc")))
    sources = [xr.open_dataset(w).attrs["file_uuid"] for w in written]
    assert len(set(sources)) == 2
    retrieve(data, "-o", tmp_path / "out")
    for product in (tmp_path / "out").glob("*.nc"):
        attrs = read_product(product).attrs
        assert attrs["source_file_uuids"] == ", ".join(sources)
        assert attrs["file_uuid"] not in sources


def test_instrument_pid_and_serial_when_configured(tmp_path):
    data = tmp_path / "in"
    data.mkdir()
    shutil.copy(SAMPLES[0], data)
    cfg = tmp_path / "c.toml"
    pid = "https://hdl.handle.net/21.12132/3.191564170f8a4686"
    cfg.write_text(f'[output]\ninstrument_pid = "{pid}"\ninstrument_serial_number = "999"\n')
    retrieve(data, "-c", cfg, "-o", tmp_path / "out")
    retrieve(data, "-o", tmp_path / "plain")
    for product in (tmp_path / "out").glob("*.nc"):
        attrs = read_product(product).attrs
        assert attrs["instrument_pid"] == pid and attrs["instrument_serial_number"] == "999"
    for product in (tmp_path / "plain").glob("*.nc"):
        assert "instrument_pid" not in read_product(product).attrs


def _shifted(ds: xr.Dataset, days: int, system_id: str) -> xr.Dataset:
    out = ds.assign_coords(time=ds["time"] + np.timedelta64(days, "D"))
    out.attrs = dict(ds.attrs, system_id=system_id)
    return out


def test_one_file_per_instrument_day_and_product(tmp_path):
    """Two instruments x two days, each day in two files: 4 wind products, named so."""
    data = tmp_path / "in"
    data.mkdir()
    for p in SAMPLES:  # the two sample files are one instrument-day (12:00 and 12:03)
        ds = read_hpl(p)
        for days, system in [(0, "999"), (1, "999"), (0, "12"), (1, "12")]:
            name = f"VAD_{system}_{p.stem.split('_', 2)[2]}_{days}.hpl"
            write_hpl(_shifted(ds, days, system), data / name)
    cfg = tmp_path / "c.toml"
    cfg.write_text("[turbulence]\nenabled = false\n")
    retrieve(data, "-c", cfg, "-o", tmp_path / "out")
    retrieve(data, "-c", cfg, "-o", tmp_path / "out")  # again: replaced, not added
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert names == [
        "streamline_12_20240601_wind.nc",
        "streamline_12_20240602_wind.nc",
        "streamline_999_20240601_wind.nc",
        "streamline_999_20240602_wind.nc",
    ]
    for name in names:
        attrs = read_product(tmp_path / "out" / name).attrs
        assert attrs["system_id"] == name.split("_")[1]
        assert attrs["time_coverage_start"][:10].replace("-", "") == name.split("_")[2]
        assert len(attrs["input_files"].split(", ")) == 2  # both files of the day
