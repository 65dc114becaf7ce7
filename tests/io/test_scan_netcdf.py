"""Canonical scan dataset as NetCDF: round trip and schema validation on read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io import Format, detect_format, read_file
from cwproc.io.halo import read_hpl
from cwproc.io.scan_netcdf import read_scan_netcdf, write_scan_netcdf


def cw_scan(n_rays: int = 50, seed: int = 7) -> xr.Dataset:
    """A homodyne cw line-of-sight scan: 50 rays of one 1-s rotation, 3 focus ranges."""
    rng = np.random.default_rng(seed)
    az = np.arange(n_rays) * 360.0 / n_rays
    time = np.datetime64("2016-12-13T10:00:00", "ns") + (np.arange(n_rays) * 20_000_000).astype(
        "timedelta64[ns]"
    )
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), np.abs(rng.normal(5, 1, (n_rays, 3)))),
            "snr": (("ray", "range"), rng.uniform(0.5, 2.0, (n_rays, 3))),
        },
        coords={
            "time": ("ray", time),
            "azimuth": ("ray", az),
            "elevation": ("ray", np.full(n_rays, 60.0)),
            "range": ("range", [40.0, 80.0, 120.0]),
        },
        attrs={
            "instrument": "ZephIR 300",
            "instrument_kind": "cw",
            "system_id": "317",
            "homodyne": 1,
            "source_files": ["sim_a.zph", "sim_b.zph"],
            "scan_type": "conical",
            "wavelength_m": 1.575e-6,
            "z_r_coefficient": 0.0013,
            "scan_period_s": 1.0,
        },
    )


def test_cw_round_trip(tmp_path: Path) -> None:
    ds = cw_scan()
    path = write_scan_netcdf(ds, tmp_path / "cw.nc")
    back = read_scan_netcdf(path)
    for name in ("radial_velocity", "snr", "azimuth", "elevation", "range"):
        np.testing.assert_array_equal(back[name].values, ds[name].values)
    assert np.array_equal(back["time"].values, ds["time"].values)
    assert back.attrs["homodyne"] == 1
    assert back.attrs["source_files"] == ["sim_a.zph", "sim_b.zph"]
    assert back.attrs["z_r_coefficient"] == pytest.approx(0.0013)
    # a full 50-ray rotation: one scan
    assert (back["scan"].values == 0).all() and back["scan"].dtype == np.int64
    # CF attributes from the metadata table
    assert back["radial_velocity"].attrs["units"] == "m s-1"
    assert detect_format(path) == Format.SCAN_NETCDF
    assert read_file(path).sizes == {"ray": 50, "range": 3}


def test_real_hpl_round_trip(real_data: Path, tmp_path: Path) -> None:
    ds = read_hpl(real_data / "hpl" / "soverato-2021-10-01-VAD_194_20210624_170110.hpl")
    back = read_scan_netcdf(write_scan_netcdf(ds, tmp_path / "vad.nc"))
    for name in ds.variables:
        np.testing.assert_array_equal(back[name].values, ds[name].values)
    assert back.attrs["homodyne"] == 0
    assert back.attrs["source_files"] == ds.attrs["source_files"]
    assert back.attrs["focus_range_m"] == np.inf


def _write_raw(ds: xr.Dataset, path: Path) -> Path:
    ds.to_netcdf(path, engine="netcdf4")
    return path


def test_missing_variable_is_named(tmp_path: Path) -> None:
    path = _write_raw(cw_scan().drop_vars("snr"), tmp_path / "nosnr.nc")
    with pytest.raises(InputFileError, match="'snr'"):
        read_scan_netcdf(path)


def test_missing_dimension_is_named(tmp_path: Path) -> None:
    ds = cw_scan().rename({"ray": "profile"})
    with pytest.raises(InputFileError, match="'ray'"):
        read_scan_netcdf(_write_raw(ds, tmp_path / "nodim.nc"))


def test_wrong_dimensions_are_named(tmp_path: Path) -> None:
    ds = cw_scan()
    ds["snr"] = (("range", "ray"), ds["snr"].values.T)
    with pytest.raises(InputFileError, match="'snr' has dimensions"):
        read_scan_netcdf(_write_raw(ds, tmp_path / "transposed.nc"))


def test_missing_homodyne_attribute(tmp_path: Path) -> None:
    ds = cw_scan()
    del ds.attrs["homodyne"]
    with pytest.raises(InputFileError, match="'homodyne'"):
        read_scan_netcdf(_write_raw(ds, tmp_path / "noattr.nc"))


@pytest.mark.parametrize(("value", "expected"), [("false", 0), ("TRUE", 1), ("0", 0), (1, 1)])
def test_homodyne_attribute_is_read_as_int(tmp_path: Path, value: object, expected: int) -> None:
    ds = cw_scan()
    ds.attrs["homodyne"] = value
    back = read_scan_netcdf(_write_raw(ds, tmp_path / "spelled.nc"))
    assert back.attrs["homodyne"] == expected and type(back.attrs["homodyne"]) is int


def test_unreadable_homodyne_attribute(tmp_path: Path) -> None:
    ds = cw_scan()
    ds.attrs["homodyne"] = "yes"
    with pytest.raises(InputFileError, match="homodyne is 'yes': expected 0/1, true/false"):
        read_scan_netcdf(_write_raw(ds, tmp_path / "yes.nc"))


def test_not_netcdf(tmp_path: Path) -> None:
    path = tmp_path / "x.nc"
    path.write_bytes(b"CDF\x01 garbage that is not netcdf")
    with pytest.raises(InputFileError, match="not a readable NetCDF"):
        read_scan_netcdf(path)


def test_write_refuses_dataset_without_schema(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="'radial_velocity'"):
        write_scan_netcdf(cw_scan().drop_vars("radial_velocity"), tmp_path / "bad.nc")
    assert not (tmp_path / "bad.nc").exists()


def test_netcdf_scans_identified_in_two_threads_are_read_under_the_lock(tmp_path, monkeypatch):
    """libnetcdf and HDF5 are not thread-safe: ``retrieve`` identifies its inputs in two
    threads, and two NetCDF scans opened at once crashed the process (a segmentation
    fault in CI). Every open holds ``NETCDF_LOCK``, and the items are those of a serial
    read."""
    import threading

    import cwproc.io.scan_netcdf as scan_netcdf
    from cwproc.config import load_config
    from cwproc.io import NETCDF_LOCK
    from cwproc.pipeline import retrieve

    paths = [write_scan_netcdf(cw_scan(seed=k), tmp_path / f"scan_{k}.nc") for k in range(8)]
    held: list[bool] = []
    real_open = scan_netcdf.xr.open_dataset

    def checked_open(*args, **kwargs):
        free: list[bool] = []
        probe = threading.Thread(target=lambda: free.append(NETCDF_LOCK.acquire(blocking=False)))
        probe.start()
        probe.join()
        if free[0]:
            NETCDF_LOCK.release()
        held.append(not free[0])
        return real_open(*args, **kwargs)

    monkeypatch.setattr(scan_netcdf.xr, "open_dataset", checked_open)
    config = load_config("banakh1999")  # reads scan_netcdf files
    got = list(retrieve.read_inputs(paths, config, threads=2))
    assert len(held) == len(paths) and all(held)
    assert [p for p, _ in got] == paths
    for path, item in got:
        assert not isinstance(item, Exception), item
        assert item.dataset.identical(read_scan_netcdf(path))
